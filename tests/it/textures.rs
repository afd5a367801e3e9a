//! Texture maps end to end: MTL `map_Kd`, `map_Ks` and `map_d`, and a scene's
//! `texture` and `specular_texture`, as their authors write them, every bad input a warning (or, past the
//! memory limit, an error) naming its file and line, both backends alike,
//! reuse bit-exact on textured scenes, and Debian's textured spider.

use std::path::{Path, PathBuf};
use std::process::Output;

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::Techniques;
use retrace::scene::{load_obj_mesh, load_scene, parse_scene_str, SceneOverrides};

use crate::common::{retrace, retrace_ok, run_exact_reusing};

/// A 2 x 2 quad facing +z at z = 0, its texture once over it (`vt` at
/// line 6 to 9), using material `m` of `q.mtl`.
const QUAD: &str = "mtllib q.mtl\n\
    v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
    usemtl m\nf 1/1 2/2 3/3 4/4\n";

/// A scene looking straight at [`QUAD`] from z = 2, lit from the eye.
const SCENE: &str = "[render]\nwidth = 64\nheight = 64\nambient = [0, 0, 0]\n\
    [camera]\nposition = [0, 0, 2]\nlook_at = [0, 0, 0]\nfov = 40\n\
    [[light]]\nposition = [0, 0, 2]\n\
    [[object]]\ntype = \"mesh\"\nfile = \"q.obj\"\n";

/// A texture whose left half is red and right half blue.
fn red_blue(path: &Path) {
    image::RgbImage::from_fn(8, 8, |x, _| {
        if x < 4 {
            image::Rgb([255, 0, 0])
        } else {
            image::Rgb([0, 0, 255])
        }
    })
    .save(path)
    .unwrap();
}

/// A folder holding the quad, its MTL `mtl`, and the scene.
fn quad_folder(mtl: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("q.obj"), QUAD).unwrap();
    std::fs::write(dir.path().join("q.mtl"), mtl).unwrap();
    std::fs::write(dir.path().join("s.toml"), SCENE).unwrap();
    dir
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Renders `s.toml` in `dir` (with `flags`) to `out.png`; the image and
/// what was said.
fn render(dir: &Path, flags: &[&str]) -> (image::RgbImage, String) {
    let mut args = vec!["render", "s.toml", "-o", "out.png"];
    args.extend(flags);
    let out = retrace_ok(&args, dir);
    let image = image::open(dir.join("out.png")).unwrap().to_rgb8();
    std::fs::remove_file(dir.join("out.png")).unwrap();
    (image, stderr(&out))
}

/// The colour at the centre of the quad's left and right halves.
fn halves(image: &image::RgbImage) -> ([u8; 3], [u8; 3]) {
    (image.get_pixel(20, 32).0, image.get_pixel(44, 32).0)
}

#[test]
fn map_kd_written_with_backslashes_shows_its_texture_times_kd() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\nmap_Kd .\\maps\\red blue.png\n");
    std::fs::create_dir(dir.path().join("maps")).unwrap();
    red_blue(&dir.path().join("maps").join("red blue.png"));
    for filter in ["trilinear", "bilinear", "nearest"] {
        let (image, said) = render(dir.path(), &["--texture-filter", filter]);
        assert!(!said.contains("warning"), "{said}");
        let (left, right) = halves(&image);
        assert!(left[0] > 200 && left[2] < 20, "{filter}: left {left:?}");
        assert!(right[2] > 200 && right[0] < 20, "{filter}: right {right:?}");
    }
    // Kd multiplies the texture (the MTL's meaning).
    std::fs::write(
        dir.path().join("q.mtl"),
        "newmtl m\nKd 0.5 1 1\nmap_Kd .\\maps\\red blue.png\n",
    )
    .unwrap();
    let (image, _) = render(dir.path(), &[]);
    let (left, _) = halves(&image);
    assert!((150..200).contains(&left[0]), "{left:?}");
}

/// A texture whose left half is black and right half white.
fn black_white(path: &Path) {
    image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x < 4 { 0 } else { 255 }]))
        .save(path)
        .unwrap();
}

/// A black quad with a broad white highlight (the light is at the eye)
/// over the whole of it, its specular colour multiplied by `map_Ks`.
const SHINY: &str = "newmtl m\nKd 0 0 0\nKs 1 1 1\nNs 4\n";

#[test]
fn map_ks_shows_highlights_only_where_the_map_is_white_on_both_backends() {
    let dir = quad_folder(SHINY);
    black_white(&dir.path().join("bw.png"));
    for backend in ["embree", "grid"] {
        let flags = ["--backend", backend];
        // Without the map, the highlight spans both halves.
        std::fs::write(dir.path().join("q.mtl"), SHINY).unwrap();
        let (plain, said) = render(dir.path(), &flags);
        assert!(!said.contains("warning"), "{said}");
        let (left, right) = halves(&plain);
        assert!(left[0] > 150 && right[0] > 150, "{left:?} {right:?}");
        std::fs::write(dir.path().join("q.mtl"), format!("{SHINY}map_Ks bw.png\n")).unwrap();
        let (mapped, said) = render(dir.path(), &flags);
        assert!(!said.contains("warning"), "{said}");
        let (left, right) = halves(&mapped);
        assert_eq!(left, [0, 0, 0], "{backend}: a highlight on the black half");
        assert_eq!(right, halves(&plain).1, "{backend}: the white half dimmed");
        // The map takes Ks's place where the MTL gives no Ks.
        let no_ks = SHINY.replace("Ks 1 1 1\n", "");
        std::fs::write(dir.path().join("q.mtl"), format!("{no_ks}map_Ks bw.png\n")).unwrap();
        let (image, _) = render(dir.path(), &flags);
        assert!(image == mapped, "{backend}: map_Ks without Ks");
    }
}

#[test]
fn a_missing_or_corrupt_map_ks_warns_naming_the_mtl_line_and_uses_ks() {
    let dir = quad_folder(SHINY);
    let (plain, _) = render(dir.path(), &[]);
    std::fs::write(dir.path().join("garbage.png"), b"not a PNG").unwrap();
    for (file, needle) in [
        ("missing.png", "q.mtl:5: map_Ks: no file 'missing.png'"),
        ("garbage.png", "q.mtl:5: map_Ks: "),
    ] {
        std::fs::write(dir.path().join("q.mtl"), format!("{SHINY}map_Ks {file}\n")).unwrap();
        let (image, said) = render(dir.path(), &[]);
        assert!(said.contains(needle), "{file}: {said}");
        assert!(said.contains("material 'm' uses its Ks"), "{file}: {said}");
        assert!(image == plain, "{file}: not the Ks highlight");
    }
}

#[test]
fn map_d_cuts_out_clear_texels_on_both_backends_and_a_missing_one_is_a_warning() {
    let dir = quad_folder("newmtl m\nKd 0 1 0\nmap_d bw.png\n");
    black_white(&dir.path().join("bw.png"));
    for backend in ["embree", "grid"] {
        let (image, said) = render(dir.path(), &["--backend", backend]);
        assert!(!said.contains("warning"), "{backend}: {said}");
        // The black half is clear: the background shows through it.
        let (left, right) = halves(&image);
        assert_eq!(left, [0, 0, 0], "{backend}: left");
        assert!(
            right[1] > 200 && right[0] < 20,
            "{backend}: right {right:?}"
        );
    }
    std::fs::remove_file(dir.path().join("bw.png")).unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(
        said.contains("q.mtl:3: map_d: no file 'bw.png'")
            && said.contains("material 'm' is drawn whole"),
        "{said}"
    );
    let (left, right) = halves(&image);
    assert!(left == right && left[1] > 200, "{left:?} {right:?}");
}

#[test]
fn a_name_differing_in_case_is_found_with_a_warning() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\nmap_Kd Red_Blue.PNG\n");
    red_blue(&dir.path().join("red_blue.png"));
    let (image, said) = render(dir.path(), &[]);
    assert!(
        said.contains("q.mtl:3: map_Kd: 'Red_Blue.PNG' found as")
            && said.contains("(the case differs)"),
        "{said}"
    );
    assert!(halves(&image).0[0] > 200);
}

#[test]
fn missing_corrupt_and_cut_short_textures_warn_naming_the_mtl_line_and_use_kd() {
    let dir = quad_folder("newmtl m\nKd 0 1 0\n");
    let (plain, _) = render(dir.path(), &[]);
    let whole = dir.path().join("whole.png");
    red_blue(&whole);
    let bytes = std::fs::read(&whole).unwrap();
    std::fs::write(dir.path().join("cut.png"), &bytes[..bytes.len() / 2]).unwrap();
    std::fs::write(dir.path().join("garbage.jpg"), b"not a JPEG at all").unwrap();
    std::fs::write(dir.path().join("empty.png"), b"").unwrap();
    for (file, needle) in [
        ("missing.png", "q.mtl:4: map_Kd: no file 'missing.png'"),
        ("garbage.jpg", "q.mtl:4: map_Kd: "),
        ("cut.png", "q.mtl:4: map_Kd: "),
        ("empty.png", "q.mtl:4: map_Kd: "),
    ] {
        std::fs::write(
            dir.path().join("q.mtl"),
            format!("# a comment\nnewmtl m\nKd 0 1 0\nmap_Kd {file}\n"),
        )
        .unwrap();
        let (image, said) = render(dir.path(), &[]);
        assert!(said.contains(needle), "{file}: {said}");
        assert!(said.contains("material 'm' uses its Kd"), "{file}: {said}");
        assert!(image == plain, "{file}: not the Kd colour");
    }
}

#[test]
fn a_one_texel_texture_is_a_flat_colour() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\nmap_Kd one.bmp\n");
    image::RgbImage::from_pixel(1, 1, image::Rgb([200, 100, 0]))
        .save(dir.path().join("one.bmp"))
        .unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(!said.contains("warning"), "{said}");
    let (left, right) = halves(&image);
    assert_eq!(left, right);
    assert!(
        left[0] > left[1] && left[1] > left[2] && left[2] == 0,
        "{left:?}"
    );
}

/// A PNG whose header says `width` x `height`, its data a stub.
fn png_header(path: &Path, width: u32, height: u32) {
    fn crc32(data: &[u8]) -> u32 {
        let mut crc = 0xffff_ffffu32;
        for &byte in data {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                let mask = (crc & 1).wrapping_neg();
                crc = (crc >> 1) ^ (0xedb8_8320 & mask);
            }
        }
        !crc
    }
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(width.to_be_bytes());
    ihdr.extend(height.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    for chunk in [ihdr, b"IDAT\x78\x9c".to_vec()] {
        bytes.extend((chunk.len() as u32 - 4).to_be_bytes());
        bytes.extend(&chunk);
        bytes.extend(crc32(&chunk).to_be_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_16384_squared_texture_is_refused_naming_the_mtl_line_until_the_limit_is_raised() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\nmap_Kd huge.png\n");
    png_header(&dir.path().join("huge.png"), 16384, 16384);
    let out = retrace(&["render", "s.toml", "-o", "out.png"], dir.path());
    let said = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("q.mtl:3: map_Kd: ")
            && said.contains("a 16384 x 16384 texture needs 1365 MB"),
        "{said}"
    );
    assert!(said.contains("--texture-memory"), "{said}");
    assert!(!said.contains("panicked"), "{said}");
    assert!(!dir.path().join("out.png").exists());
    // Allowed the memory, the header passes; the stub data then fails to
    // decode: a warning, and the quad in its Kd.
    let (_, said) = render(dir.path(), &["--texture-memory", "2048"]);
    assert!(said.contains("q.mtl:3: map_Kd: "), "{said}");
    assert!(said.contains("material 'm' uses its Kd"), "{said}");
}

#[test]
fn nan_texture_coordinates_are_refused_naming_the_obj_line() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\n");
    std::fs::write(dir.path().join("q.obj"), QUAD.replace("vt 1 1", "vt 1 nan")).unwrap();
    let out = retrace(&["render", "s.toml", "-o", "out.png"], dir.path());
    let said = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("q.obj:8: vt: coordinate 'nan' is not finite"),
        "{said}"
    );
}

#[test]
fn coordinates_outside_0_1_repeat_the_texture() {
    let dir = quad_folder("newmtl m\nKd 1 1 1\nmap_Kd rb.png\n");
    red_blue(&dir.path().join("rb.png"));
    let (once, _) = render(dir.path(), &[]);
    // Shifted by whole turns, the same texels.
    let shifted = QUAD
        .replace("vt 0 0", "vt 3 -2")
        .replace("vt 1 0", "vt 4 -2")
        .replace("vt 1 1", "vt 4 -1")
        .replace("vt 0 1", "vt 3 -1");
    std::fs::write(dir.path().join("q.obj"), shifted).unwrap();
    let (repeated, _) = render(dir.path(), &["--texture-filter", "nearest"]);
    let (nearest_once, _) = {
        std::fs::write(dir.path().join("q.obj"), QUAD).unwrap();
        render(dir.path(), &["--texture-filter", "nearest"])
    };
    assert!(repeated == nearest_once);
    assert!(halves(&once) == halves(&repeated));
}

#[test]
fn a_scene_materials_texture_is_read_relative_to_its_file_and_warns_when_missing() {
    let dir = quad_folder("newmtl m\nKd 0 1 0\n");
    std::fs::create_dir(dir.path().join("maps")).unwrap();
    red_blue(&dir.path().join("maps").join("rb.png"));
    let scene =
        |texture: &str| format!("{SCENE}material = \"t\"\n[material.t]\ntexture = \"{texture}\"\n");
    std::fs::write(dir.path().join("s.toml"), scene("maps/rb.png")).unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(!said.contains("warning"), "{said}");
    let (left, right) = halves(&image);
    assert!(left[0] > 200 && right[2] > 200, "{left:?} {right:?}");
    // On a shape without texture coordinates, a warning.
    std::fs::write(
        dir.path().join("s.toml"),
        format!(
            "{}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, -5]\nradius = 1\n\
             material = \"t\"\n",
            scene("maps/rb.png")
        ),
    )
    .unwrap();
    let (_, said) = render(dir.path(), &[]);
    assert!(
        said.contains("s.toml:17: object[1]: 'object[1]' has no texture coordinates"),
        "{said}"
    );
    std::fs::write(dir.path().join("s.toml"), scene("maps/none.png")).unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(
        said.contains("s.toml:16: material.t.texture: no file 'maps/none.png'"),
        "{said}"
    );
    // Without its texture the material is the default grey.
    let (left, right) = halves(&image);
    assert!(
        left == right && left[0] == left[1] && left[1] == left[2],
        "{left:?}"
    );
}

#[test]
fn a_scene_materials_specular_texture_masks_its_highlight() {
    let dir = quad_folder("newmtl m\nKd 0 1 0\n");
    black_white(&dir.path().join("bw.png"));
    let scene = |fields: &str| {
        format!(
            "{SCENE}material = \"t\"\n[material.t]\ndiffuse = [0, 0, 0]\nshininess = 4\n{fields}"
        )
    };
    std::fs::write(
        dir.path().join("s.toml"),
        scene("specular_texture = \"bw.png\"\n"),
    )
    .unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(!said.contains("warning"), "{said}");
    let (left, right) = halves(&image);
    assert_eq!(left, [0, 0, 0]);
    assert!(right[0] > 150 && right[0] == right[2], "{right:?}");
    std::fs::write(
        dir.path().join("s.toml"),
        scene("specular = [1, 1, 1]\nspecular_texture = \"none.png\"\n"),
    )
    .unwrap();
    let (image, said) = render(dir.path(), &[]);
    assert!(
        said.contains("s.toml:19: material.t.specular_texture: no file 'none.png' (looked in .)"),
        "{said}"
    );
    let (left, right) = halves(&image);
    assert!(left[0] > 150 && right[0] > 150, "{left:?} {right:?}");
}

fn textured_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.toml")
}

#[test]
fn the_textured_scene_agrees_on_both_backends() {
    let scene = load_scene(
        &textured_scene(),
        &SceneOverrides {
            width: Some(160),
            height: Some(90),
            ..SceneOverrides::default()
        },
    )
    .unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let textured = scene.materials.iter().filter(|m| m.diffuse_map.is_some());
    assert_eq!(textured.count(), 3, "the floor's and each crate's");
    let embree = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
    let grid = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
    let report = retrace::lab::validate::validate(&scene, &embree, &grid, 20_000, 7, 5);
    assert!(report.passed(), "{:?}", report.failures);
    assert!(
        report.camera_rays.textured > 5_000,
        "{:?}",
        report.camera_rays
    );
    assert!(report.camera_rays.max_texcoord_ratio <= 1.0);
}

/// The textured scene with the mirror ball moving, seen from a still
/// camera (OSTC), or with the camera turning (a pan).
fn animated(timeline: &str, camera: Option<&str>) -> retrace::scene::Scene {
    let path = textured_scene();
    let text = std::fs::read_to_string(&path).unwrap();
    let text = match camera {
        Some(camera) => {
            let start = text.find("[camera]").unwrap();
            let end = text.find("[[light]]").unwrap();
            format!("{}{camera}\n{}", &text[..start], &text[end..])
        }
        None => text,
    };
    let overrides = SceneOverrides {
        width: Some(96),
        height: Some(64),
        ..SceneOverrides::default()
    };
    parse_scene_str(&format!("{text}\n{timeline}"), &path, &overrides).unwrap()
}

#[test]
fn a_moving_mirror_over_textures_reuses_bit_exactly() {
    let scene = animated(
        "[animation]\nframes = 4\n\
         [[animation.object]]\nobject = \"ball\"\nframe = 0\ntranslate = [0, 0, 0]\n\
         [[animation.object]]\nobject = \"ball\"\nframe = 4\ntranslate = [-1, 0.3, 0]\n",
        None,
    );
    run_exact_reusing(
        &scene,
        BackendKind::Embree,
        Techniques::parse("ostc").unwrap(),
    );
}

#[test]
fn a_pan_over_textures_reuses_bit_exactly() {
    let scene = animated(
        "[animation]\nframes = 4\n\
         [[animation.camera]]\nframe = 0\nyaw = 0\n\
         [[animation.camera]]\nframe = 4\nyaw = 20\n",
        Some(
            "[camera]\nprojection = \"equal-angle\"\nposition = [0, 1.6, 7]\n\
             yaw = 0\npitch = -5\nfov = 90",
        ),
    );
    run_exact_reusing(
        &scene,
        BackendKind::Embree,
        Techniques::parse("pan").unwrap(),
    );
}

/// Debian's `assimp-testmodels` (`make test` installs it): the spider
/// with its `map_Kd` JPEGs, written `.\wal67ar_small.jpg`.
#[test]
fn debians_spider_renders_with_its_textures() {
    let spider = Path::new("/usr/share/assimp/models/OBJ/spider.obj");
    if !spider.exists() {
        crate::common::skip_unless_ci(&format!(
            "{} not installed (make test-deps installs assimp-testmodels)",
            spider.display()
        ));
        return;
    }
    let model = load_obj_mesh(spider).unwrap();
    let warnings = model.warnings(spider).join("\n");
    assert!(!warnings.contains("map_Kd"), "{warnings}");
    let mut textures: Vec<String> = model
        .parts
        .iter()
        .filter_map(|p| p.material.as_ref()?.diffuse_map.as_ref())
        .map(|t| {
            t.source()
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    textures.sort();
    textures.dedup();
    // The fifth, wal69ar_small.jpg, belongs to a material no face uses.
    assert_eq!(
        textures,
        [
            "SpiderTex.jpg",
            "drkwood2.jpg",
            "engineflare1.jpg",
            "wal67ar_small.jpg",
        ]
    );
    // Rendered, its textures change the picture from the plain Kd one.
    let dir = tempfile::tempdir().unwrap();
    let overrides = ["--width", "160", "--height", "120"];
    let spider_arg = spider.to_str().unwrap();
    let render = |flags: &[&str], out: &str| {
        let mut args = vec!["render", spider_arg, "-o", out];
        args.extend(overrides);
        args.extend(flags);
        retrace_ok(&args, dir.path());
        image::open(dir.path().join(out)).unwrap().to_rgb8()
    };
    let textured = render(&[], "textured.png");
    // A limit too small for any texture leaves an error, not a picture.
    let out = retrace(
        &[
            "render",
            spider_arg,
            "-o",
            "none.png",
            "--texture-memory",
            "0",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("spider.mtl:10: map_Kd"),
        "{}",
        stderr(&out)
    );
    // The spider's pixels are brown and varied, not one grey.
    let browns = textured
        .pixels()
        .filter(|p| p.0[0] > p.0[2] + 15 && p.0[1] > p.0[2])
        .count();
    assert!(browns > 500, "{browns} brownish pixels");
}
