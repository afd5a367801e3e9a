//! OBJ and MTL files as other programs write them (issue 51): `Ns 0` from
//! 3ds Max, vertex colours, Blender's nameless `usemtl`, and files saved as
//! UTF-16 or with a UTF-8 byte-order mark. Each loads, with a warning
//! naming the file (and line) where something is not used as written.

use std::path::Path;

use crate::common::retrace;
use crate::obj_input::{render, stderr, write, CUBE_CORNERS};

/// A unit cube's six faces, after [`CUBE_CORNERS`].
const CUBE_FACES: &str = "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n";

/// Renders `model` to `output`, requiring success; returns the image and
/// the warnings.
fn rendered(dir: &Path, model: &str, output: &str) -> (image::RgbImage, String) {
    let out = render(dir, model, output);
    let err = stderr(&out);
    assert!(out.status.success(), "{model}: {err}");
    (image::open(dir.join(output)).unwrap().to_rgb8(), err)
}

fn mean(image: &image::RgbImage) -> f64 {
    let sum: u64 = image.as_raw().iter().map(|&b| u64::from(b)).sum();
    sum as f64 / image.as_raw().len() as f64
}

/// `text` as UTF-16 with its byte-order mark, little- or big-endian.
fn utf16(text: &str, little_endian: bool) -> Vec<u8> {
    let mut bytes = if little_endian {
        vec![0xFF, 0xFE]
    } else {
        vec![0xFE, 0xFF]
    };
    for unit in text.encode_utf16() {
        bytes.extend(if little_endian {
            unit.to_le_bytes()
        } else {
            unit.to_be_bytes()
        });
    }
    bytes
}

#[test]
fn obj_ns_0_means_no_highlight_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A strong white specular colour: with (R.V)^0 = 1 it was added to every
    // lit point, and the grey cube came out white.
    let models = [
        ("ns10", "Ks 0.9 0.9 0.9\nNs 10\n"),
        ("ns0", "Ks 0.9 0.9 0.9\nNs 0\n"),
        ("negative", "Ks 0.9 0.9 0.9\nNs -5\n"),
        ("huge", "Ks 0.9 0.9 0.9\nNs 50000\n"),
        ("matte", "Ks 0 0 0\nNs 10\n"),
    ];
    for (name, specular) in models {
        write(
            d,
            &format!("{name}.obj"),
            format!("mtllib {name}.mtl\n{CUBE_CORNERS}usemtl grey\n{CUBE_FACES}").as_bytes(),
        );
        write(
            d,
            &format!("{name}.mtl"),
            format!("newmtl grey\nKd 0.4 0.4 0.4\n{specular}").as_bytes(),
        );
    }
    let (ns10, err) = rendered(d, "ns10.obj", "ns10.png");
    assert!(!err.contains("Ns"), "an Ns in range warned: {err}");
    let (matte, _) = rendered(d, "matte.obj", "matte.png");
    let (ns0, err) = rendered(d, "ns0.obj", "ns0.png");
    assert!(
        err.contains("ns0.mtl:4: Ns 0: material 'grey'") && err.contains("no highlight"),
        "{err}"
    );
    // No highlight: the picture of the same cube with no specular colour,
    // never brighter than with a real highlight.
    assert!(
        mean(&ns0) <= mean(&ns10),
        "Ns 0 is washed out: mean {} against {} at Ns 10",
        mean(&ns0),
        mean(&ns10)
    );
    assert!(ns0 == matte, "Ns 0 is not the cube without a highlight");
    let (negative, err) = rendered(d, "negative.obj", "negative.png");
    assert!(
        err.contains("negative.mtl:4: Ns -5: material 'grey'"),
        "{err}"
    );
    assert!(
        negative == matte,
        "Ns -5 is not the cube without a highlight"
    );
    let (_, err) = rendered(d, "huge.obj", "huge.png");
    assert!(
        err.contains("huge.mtl:4: Ns 50000: material 'grey'") && err.contains("10000"),
        "{err}"
    );
}

#[test]
fn obj_vertex_colours_are_ignored_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let coloured: String = CUBE_CORNERS
        .lines()
        .map(|line| format!("{line} 1 0 0\n"))
        .collect();
    write(
        d,
        "plain.obj",
        format!("{CUBE_CORNERS}{CUBE_FACES}").as_bytes(),
    );
    write(
        d,
        "coloured.obj",
        format!("# from MeshLab\n{coloured}{CUBE_FACES}").as_bytes(),
    );
    let (plain, _) = rendered(d, "plain.obj", "plain.png");
    let (image, err) = rendered(d, "coloured.obj", "coloured.png");
    assert!(
        err.contains("coloured.obj:2: v: vertex colours") && err.contains("ignored"),
        "{err}"
    );
    assert!(image == plain, "the vertex colours changed the picture");
    let (_, err) = rendered(d, "plain.obj", "plain.png");
    assert!(!err.contains("vertex colours"), "{err}");
}

#[test]
fn obj_nameless_usemtl_warns_and_uses_the_default_material() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "m.mtl", b"newmtl red\nKd 0.9 0.1 0.1\n");
    let obj = |selects: &str| {
        format!(
            "mtllib m.mtl\n{CUBE_CORNERS}usemtl red\nf 1 4 3 2\nf 5 6 7 8\n{selects}\n\
             f 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n"
        )
    };
    // Blender's `usemtl` with no name, with and without trailing blanks.
    write(d, "blender.obj", obj("usemtl").as_bytes());
    write(d, "blanks.obj", obj("usemtl \t ").as_bytes());
    write(d, "nosuch.obj", obj("usemtl nosuch").as_bytes());
    let (reference, _) = rendered(d, "nosuch.obj", "nosuch.png");
    for model in ["blender", "blanks"] {
        let (image, err) = rendered(d, &format!("{model}.obj"), &format!("{model}.png"));
        assert!(
            err.contains(&format!("{model}.obj:13: usemtl: no material name"))
                && err.contains("default material"),
            "{err}"
        );
        assert!(!err.contains("material '' is not defined"), "{err}");
        assert!(image == reference, "{model}: not the default material");
    }
    // Without a material library.
    write(
        d,
        "alone.obj",
        format!("{CUBE_CORNERS}usemtl\n{CUBE_FACES}").as_bytes(),
    );
    let (_, err) = rendered(d, "alone.obj", "alone.png");
    assert!(
        err.contains("alone.obj:9: usemtl: no material name"),
        "{err}"
    );
}

#[test]
fn obj_utf16_and_utf8_with_a_byte_order_mark_render_as_utf8() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = |mtl: &str| format!("mtllib {mtl}\r\n{CUBE_CORNERS}usemtl café\n{CUBE_FACES}");
    let mtl = "newmtl café\nKd 0.9 0.2 0.1\nKs 0.3 0.3 0.3\nNs 20\n";
    write(d, "utf8.obj", obj("utf8.mtl").as_bytes());
    write(d, "utf8.mtl", mtl.as_bytes());
    let (reference, _) = rendered(d, "utf8.obj", "utf8.png");
    let cases: [(&str, Vec<u8>, Vec<u8>); 3] = [
        ("le", utf16(&obj("le.mtl"), true), utf16(mtl, true)),
        ("be", utf16(&obj("be.mtl"), false), utf16(mtl, false)),
        (
            "bom8",
            [&b"\xEF\xBB\xBF"[..], obj("bom8.mtl").as_bytes()].concat(),
            [&b"\xEF\xBB\xBF"[..], mtl.as_bytes()].concat(),
        ),
    ];
    for (name, obj_bytes, mtl_bytes) in cases {
        write(d, &format!("{name}.obj"), &obj_bytes);
        write(d, &format!("{name}.mtl"), &mtl_bytes);
        let (image, err) = rendered(d, &format!("{name}.obj"), &format!("{name}.png"));
        assert!(!err.contains("warning"), "{name}: {err}");
        assert!(image == reference, "{name}: not the UTF-8 twin's picture");
    }
    // Errors keep their line numbers.
    let broken = format!("{CUBE_CORNERS}v 0 x 0\n{CUBE_FACES}");
    write(d, "broken.obj", &utf16(&broken, true));
    let out = render(d, "broken.obj", "broken.png");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("broken.obj:9:"), "{err}");
    assert!(err.contains("'x' is not a number"), "{err}");
}

/// A Z-up model (CAD, 3ds Max) stands up with `--up z`: it renders as
/// its Y-up twin does, bit for bit; a scene file is told to use `rotate`.
#[test]
fn obj_up_z_stands_a_z_up_model_as_its_y_up_twin() {
    let dir = tempfile::tempdir().unwrap();
    // A post 0.4 x 0.4 x 2, along z; its twin along y: (x, y, z) written
    // as (x, z, -y).
    let corners = |twin: bool| -> String {
        let mut text = String::new();
        for z in [0.0, 2.0] {
            for (x, y) in [(0.0, 0.0), (0.4, 0.0), (0.4, 0.4), (0.0, 0.4)] {
                let (a, b, c) = if twin { (x, z, -y) } else { (x, y, z) };
                text.push_str(&format!("v {a} {b} {c}\n"));
            }
        }
        text
    };
    write(
        dir.path(),
        "zup.obj",
        format!("{}{CUBE_FACES}", corners(false)).as_bytes(),
    );
    write(
        dir.path(),
        "yup.obj",
        format!("{}{CUBE_FACES}", corners(true)).as_bytes(),
    );
    let (twin, _) = rendered(dir.path(), "yup.obj", "yup.png");
    let lying = image::open({
        assert!(render(dir.path(), "zup.obj", "lying.png").status.success());
        dir.path().join("lying.png")
    })
    .unwrap()
    .to_rgb8();
    assert!(lying != twin, "without --up the post lies on its side");
    let out = retrace(
        &[
            "render",
            "zup.obj",
            "--up",
            "z",
            "--width",
            "32",
            "--height",
            "24",
            "-o",
            "standing.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let standing = image::open(dir.path().join("standing.png"))
        .unwrap()
        .to_rgb8();
    assert!(standing == twin, "--up z renders as the Y-up twin");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.toml");
    let refused = retrace(
        &[
            "render",
            scene.to_str().unwrap(),
            "--up",
            "z",
            "-o",
            "x.png",
        ],
        dir.path(),
    );
    let err = stderr(&refused);
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--up z") && err.contains("rotate = [-90, 0, 0]"),
        "{err}"
    );
    assert!(!dir.path().join("x.png").exists());
}
