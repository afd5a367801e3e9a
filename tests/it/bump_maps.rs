//! Bump and normal maps end to end (issue 48): MTL `map_Bump`/`bump` with
//! `-bm` and `norm`, a scene's `bump_texture`, `bump_scale` and
//! `normal_texture`; relief changes shading only where it slopes, flat
//! relief renders bit for bit as none; bad values name their file and
//! line; pan and OSTC reuse stay bit-exact on a bump-mapped scene on both
//! backends.

use std::path::{Path, PathBuf};

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::Techniques;
use retrace::scene::{load_obj_mesh, parse_scene_str, BumpMap, Scene, SceneOverrides};
use retrace::texture::TextureEncoding;

use crate::common::run_exact_reusing;

/// A 2 x 2 quad facing +z at z = 0, its texture once over it, using
/// material `m` of `q.mtl`.
const QUAD: &str = "mtllib q.mtl\n\
    v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
    usemtl m\nf 1/1 2/2 3/3 4/4\n";

/// Looking straight at [`QUAD`] from z = 2, lit from the left at a
/// grazing angle, so a slope shows.
const SCENE: &str = "[render]\nwidth = 64\nheight = 64\nambient = [0, 0, 0]\n\
    [camera]\nposition = [0, 0, 2]\nlook_at = [0, 0, 0]\nfov = 40\n\
    [[light]]\nposition = [-3, 0.5, 0.6]\n\
    [[object]]\ntype = \"mesh\"\nfile = \"q.obj\"\n";

/// A grey image, `value` everywhere; with `ridges`, its right half ridged
/// (columns alternating `value` and white, four texels wide).
fn height_png(path: &Path, value: u8, ridges: bool) {
    image::GrayImage::from_fn(64, 64, |x, _| {
        let ridge = ridges && x >= 32 && (x / 4) % 2 == 1;
        image::Luma([if ridge { 255 } else { value }])
    })
    .save(path)
    .unwrap();
}

/// A folder holding the quad with MTL `mtl`, and the scene with `extra`
/// after it.
fn folder(mtl: &str, extra: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("q.obj"), QUAD).unwrap();
    std::fs::write(dir.path().join("q.mtl"), mtl).unwrap();
    std::fs::write(dir.path().join("s.toml"), format!("{SCENE}{extra}")).unwrap();
    dir
}

fn load(dir: &Path) -> Scene {
    retrace::scene::load_scene(&dir.join("s.toml"), &SceneOverrides::default()).unwrap()
}

/// The scene's full render on `backend`, linear.
fn rendered(scene: &Scene, backend: BackendKind) -> Vec<glam::Vec3> {
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    retrace::render::render_frame(scene, &accel).0.pixels
}

#[test]
fn a_normal_map_tilts_the_shading_toward_its_red_and_green() {
    let dir = folder("newmtl m\nKd 0.8 0.8 0.8\n", "");
    let plain = rendered(&load(dir.path()), BackendKind::Embree);
    // Tilted toward -u: toward the light on the left, brighter.
    image::RgbImage::from_pixel(16, 16, image::Rgb([40, 128, 230]))
        .save(dir.path().join("n.png"))
        .unwrap();
    std::fs::write(
        dir.path().join("s.toml"),
        format!("{SCENE}material = \"t\"\n[material.t]\ndiffuse = [0.8, 0.8, 0.8]\nnormal_texture = \"n.png\"\n"),
    )
    .unwrap();
    let scene = load(dir.path());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let material = scene.materials.iter().find(|m| m.name == "t").unwrap();
    let Some(BumpMap::Normal { map }) = &material.bump_map else {
        panic!("{:?}", scene.materials)
    };
    assert_eq!(map.encoding(), TextureEncoding::Linear);
    let tilted = rendered(&scene, BackendKind::Embree);
    let centre = 32 * 64 + 32;
    assert!(
        tilted[centre].x > plain[centre].x * 1.5,
        "{} vs {}",
        tilted[centre],
        plain[centre]
    );
}

#[test]
fn mtl_height_maps_read_their_bump_multiplier_and_warn_of_what_they_cannot() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("q.obj"), QUAD).unwrap();
    height_png(&dir.path().join("h.png"), 10, true);
    image::RgbImage::from_pixel(2, 2, image::Rgb([128, 128, 255]))
        .save(dir.path().join("n.png"))
        .unwrap();
    let load = |mtl: &str| {
        std::fs::write(dir.path().join("q.mtl"), mtl).unwrap();
        let mesh = load_obj_mesh(&dir.path().join("q.obj")).unwrap();
        let material = mesh.parts[0].material.clone();
        (material.and_then(|m| m.bump_map), mesh.problems.join("\n"))
    };
    let scale = |bump: &Option<BumpMap>| match bump {
        Some(BumpMap::Height { map, scale }) => {
            assert_eq!(map.encoding(), TextureEncoding::Linear);
            *scale
        }
        other => panic!("{other:?}"),
    };
    for (line, expected) in [
        ("map_Bump -bm 0.5 h.png", 0.5),
        ("map_bump h.png", 1.0),
        ("bump -bm -2 h.png", -2.0),
    ] {
        let (bump, said) = load(&format!("newmtl m\nKd 1 1 1\n{line}\n"));
        assert_eq!(scale(&bump), expected, "{line}");
        assert!(said.is_empty(), "{line}: {said}");
    }
    // Options it does not read are left out, named with their line.
    let (bump, said) = load("newmtl m\nKd 1 1 1\nmap_Bump -s 2 2 1 -bm 0.25 -clamp on h.png\n");
    assert_eq!(scale(&bump), 0.25);
    assert!(
        said.contains("q.mtl:3: map_Bump: options -s 2 2 1 -clamp on are not supported: left out"),
        "{said}"
    );
    // A `-bm` that is no number: the material falls back, as for any
    // value that does not parse.
    for (line, why) in [
        ("map_Bump -bm abc h.png", "-bm 'abc' is not a number"),
        ("bump -bm inf h.png", "-bm 'inf' is not finite"),
        ("map_Bump -bm", "-bm needs a number"),
    ] {
        let (bump, said) = load(&format!("newmtl m\nKd 1 1 1\n{line}\n"));
        assert!(bump.is_none(), "{line}");
        let keyword = line.split(' ').next().unwrap();
        assert!(
            said.contains(&format!(
                "q.mtl:3: {keyword}: {why}; material 'm' uses the default material"
            )),
            "{line}: {said}"
        );
    }
    // `norm` is a normal map; with a height map too, the normal map wins.
    let (bump, said) = load("newmtl m\nnorm n.png\n");
    assert!(matches!(bump, Some(BumpMap::Normal { .. })), "{said}");
    let (bump, said) = load("newmtl m\nbump h.png\nnorm n.png\n");
    assert!(matches!(bump, Some(BumpMap::Normal { .. })));
    assert!(
        said.contains("q.mtl:2: bump: material 'm' has a normal map (norm) too"),
        "{said}"
    );
    // A missing file: a warning, and no relief.
    let (bump, said) = load("newmtl m\nmap_Bump -bm 0.1 none.png\n");
    assert!(bump.is_none());
    assert!(
        said.contains("q.mtl:2: map_Bump: no file 'none.png'")
            && said.contains("material 'm' is shaded without it"),
        "{said}"
    );
}

#[test]
fn relief_on_a_shape_without_texture_coordinates_is_warned_of() {
    let dir = folder("newmtl m\n", "");
    height_png(&dir.path().join("h.png"), 10, true);
    let text = format!(
        "{SCENE}material = \"t\"\n[material.t]\nbump_texture = \"h.png\"\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0, 0, -5]\nradius = 1\nmaterial = \"t\"\n"
    );
    let scene = parse_scene_str(
        &text,
        &dir.path().join("s.toml"),
        &SceneOverrides::default(),
    )
    .unwrap();
    let said = scene.warnings.join("\n");
    assert!(
        said.contains("object[1]: 'object[1]' has no texture coordinates"),
        "{said}"
    );
}

/// `scenes/bumped.toml` small, four samples a pixel, with `timeline`
/// (and `camera` in place of its own).
fn bumped(timeline: &str, camera: Option<&str>) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/bumped.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = match camera {
        Some(camera) => {
            let start = text.find("[camera]").unwrap();
            let end = text.find("# Low and to the left").unwrap();
            format!("{}{camera}\n{}", &text[..start], &text[end..])
        }
        None => text,
    };
    let overrides = SceneOverrides {
        width: Some(64),
        height: Some(48),
        ..SceneOverrides::default()
    };
    let mut scene = parse_scene_str(&format!("{text}\n{timeline}"), &path, &overrides).unwrap();
    scene.samples = retrace::sampling::PixelSamples::new(4).unwrap();
    // Not vacuous: the wall's height map and the floor's normal map.
    let relief: Vec<_> = scene
        .materials
        .iter()
        .filter_map(|m| m.bump_map.as_ref())
        .collect();
    assert!(
        matches!(
            relief[..],
            [BumpMap::Height { .. }, BumpMap::Normal { .. }]
                | [BumpMap::Normal { .. }, BumpMap::Height { .. }]
        ),
        "{relief:?}"
    );
    scene
}

on_every_backend! {
    a_height_map_changes_shading_where_it_slopes_and_not_where_it_is_flat(backend) {
        let plain = folder("newmtl m\nKd 0.8 0.8 0.8\n", "");
        let bumped = folder(
            "newmtl m\nKd 0.8 0.8 0.8\nmap_Bump -bm 0.05 h.png\n",
            "",
        );
        height_png(&bumped.path().join("h.png"), 100, true);
        let bumped_scene = load(bumped.path());
        assert!(bumped_scene.warnings.is_empty(), "{:?}", bumped_scene.warnings);
        let (plain, bumped) = (
            rendered(&load(plain.path()), backend),
            rendered(&bumped_scene, backend),
        );
        // The quad spans columns and rows 8 to 55; its left half is flat,
        // its right half ridged.
        let differs = |columns: std::ops::Range<usize>| {
            (12..52)
                .flat_map(|y| columns.clone().map(move |x| y * 64 + x))
                .filter(|&i| plain[i] != bumped[i])
                .count()
        };
        assert_eq!(differs(10..30), 0, "the flat half changed");
        assert!(differs(34..54) > 200, "the ridges changed {} pixels", differs(34..54));
    }

    flat_relief_renders_bit_for_bit_as_none(backend) {
        let dir = folder("newmtl m\nKd 0.8 0.8 0.8\n", "");
        // Tilted (z = -0.2 (x + y)), so its normal is no axis: one worked
        // out again from the flat relief would miss its bits.
        let tilted = QUAD
            .replace("v -1 -1 0", "v -1 -1 0.4")
            .replace("v 1 1 0", "v 1 1 -0.4");
        std::fs::write(dir.path().join("q.obj"), tilted).unwrap();
        let plain = rendered(&load(dir.path()), backend);
        height_png(&dir.path().join("h.png"), 137, false);
        // A flat normal map: (128, 128, 255) is straight out.
        image::RgbImage::from_pixel(16, 16, image::Rgb([128, 128, 255]))
            .save(dir.path().join("n.png"))
            .unwrap();
        for mtl in [
            "newmtl m\nKd 0.8 0.8 0.8\nmap_Bump -bm 3 h.png\n",
            "newmtl m\nKd 0.8 0.8 0.8\nnorm n.png\n",
        ] {
            std::fs::write(dir.path().join("q.mtl"), mtl).unwrap();
            let scene = load(dir.path());
            assert!(scene.materials.iter().any(|m| m.bump_map.is_some()), "{mtl}");
            assert!(rendered(&scene, backend) == plain, "{mtl}");
        }
    }

    ostc_over_relief_maps_reuses_bit_exactly_at_4_samples(backend) {
        let scene = bumped(
            "[animation]\nframes = 4\n\
             [[animation.object]]\nobject = \"ball\"\nframe = 0\ntranslate = [0, 0, 0]\n\
             [[animation.object]]\nobject = \"ball\"\nframe = 4\ntranslate = [-1.2, 0.2, 0]\n",
            None,
        );
        run_exact_reusing(&scene, backend, Techniques::parse("ostc").unwrap());
    }

    a_pan_over_relief_maps_reuses_bit_exactly_at_4_samples(backend) {
        let scene = bumped(
            "[animation]\nframes = 4\n\
             [[animation.camera]]\nframe = 0\nyaw = 0\n\
             [[animation.camera]]\nframe = 4\nyaw = 15\n",
            Some(
                "[camera]\nprojection = \"equal-angle\"\nposition = [1.2, 1.5, 5.5]\n\
                 yaw = 0\npitch = -8\nfov = 90",
            ),
        );
        run_exact_reusing(&scene, backend, Techniques::parse("pan").unwrap());
    }
}
