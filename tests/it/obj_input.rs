//! OBJ and MTL files as users hand them over: elements that are not faces,
//! text that is not UTF-8, material libraries with mistakes. What can be
//! rendered around renders, with a warning naming the file and line; a model
//! with nothing to render is an error naming the file.

use std::path::Path;
use std::process::Output;

use crate::common::retrace;

/// Eight corners of a unit cube, as OBJ lines 1-8.
pub(crate) const CUBE_CORNERS: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                            v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";

pub(crate) fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(dir.join(name), bytes).unwrap();
}

/// Renders `model` (in `dir`) at 32x24 to `output`.
pub(crate) fn render(dir: &Path, model: &str, output: &str) -> Output {
    retrace(
        &[
            "render", model, "--width", "32", "--height", "24", "-o", output,
        ],
        dir,
    )
}

pub(crate) fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Renders `model` to `output`, requiring success and every `needle` in
/// its warnings; returns the image.
fn renders_warning(dir: &Path, model: &str, output: &str, needles: &[&str]) -> image::RgbImage {
    let out = render(dir, model, output);
    let err = stderr(&out);
    assert!(out.status.success(), "{model}: {err}");
    for needle in needles {
        assert!(
            err.contains(needle),
            "{model}: expected '{needle}' in: {err}"
        );
    }
    image::open(dir.join(output)).unwrap().to_rgb8()
}

/// Requires a clean failure: status 1, every needle, no panic, no image.
fn fails_with(dir: &Path, out: &Output, needles: &[&str]) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for needle in needles {
        assert!(err.contains(needle), "expected '{needle}' in: {err}");
    }
    assert!(!dir.join("out.png").exists(), "an image was written");
}

#[test]
fn a_model_of_lines_only_is_refused_naming_the_file() {
    // The cube's edges as polylines: tobj reads `l` with three or more
    // vertices as a face, which rendered the polylines as solid squares.
    let dir = tempfile::tempdir().unwrap();
    let edges = "l 1 2 3 4 1\nl 5 6 7 8 5\nl 1 5\nl 2 6\nl 3 7\nl 4 8\n";
    write(
        dir.path(),
        "edges.obj",
        format!("{CUBE_CORNERS}{edges}").as_bytes(),
    );
    let out = render(dir.path(), "edges.obj", "out.png");
    fails_with(
        dir.path(),
        &out,
        &["edges.obj", "no faces", "only points and lines"],
    );
    // Inside a scene too: the scene names no model it could render.
    let scene = "[camera]\nposition = [0, 1, 6]\nlook_at = [0, 0.5, 0]\nfov = 50\n\
                 [[object]]\ntype = \"mesh\"\nfile = \"edges.obj\"\n";
    write(dir.path(), "s.toml", scene.as_bytes());
    let out = render(dir.path(), "s.toml", "out.png");
    fails_with(dir.path(), &out, &["edges.obj", "no faces"]);
}

#[test]
fn points_and_lines_beside_faces_are_left_out_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let faces = "f 1 2 3\nf 1 3 4\n";
    // A point triple and a polyline that would each make a face of their own.
    let with = format!("{CUBE_CORNERS}{faces}p 5 6 7\nl 5 6 7 8\n");
    write(dir.path(), "with.obj", with.as_bytes());
    write(
        dir.path(),
        "without.obj",
        format!("{CUBE_CORNERS}{faces}").as_bytes(),
    );
    let image = renders_warning(
        dir.path(),
        "with.obj",
        "with.png",
        &["with.obj:11: p:", "left out (2 in the file)"],
    );
    let reference = renders_warning(dir.path(), "without.obj", "without.png", &[]);
    assert!(
        image == reference,
        "the points and lines changed the picture"
    );
}

#[test]
fn latin_1_names_are_read_with_a_warning_and_still_match() {
    // A material name in Latin-1 in both the OBJ and its MTL: the model
    // renders with that material, as the same files in UTF-8 do.
    let dir = tempfile::tempdir().unwrap();
    for (obj, mtl, name) in [
        ("latin.obj", "latin.mtl", &b"caf\xe9"[..]),
        ("utf8.obj", "utf8.mtl", "café".as_bytes()),
    ] {
        let mut text = format!("mtllib {mtl}\n{CUBE_CORNERS}usemtl ").into_bytes();
        text.extend_from_slice(name);
        text.extend_from_slice(b"\nf 1 2 3\nf 1 3 4\n");
        write(dir.path(), obj, &text);
        let mut text = b"newmtl ".to_vec();
        text.extend_from_slice(name);
        text.extend_from_slice(b"\nKd 0.9 0.1 0.1\n");
        write(dir.path(), mtl, &text);
    }
    let latin = renders_warning(
        dir.path(),
        "latin.obj",
        "latin.png",
        &[
            "latin.obj:10: not valid UTF-8",
            "latin.mtl:1: not valid UTF-8",
        ],
    );
    let utf8 = renders_warning(dir.path(), "utf8.obj", "utf8.png", &[]);
    assert!(latin == utf8, "the Latin-1 material was not applied");
}

#[test]
fn material_library_mistakes_warn_with_their_line_and_fall_back_to_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let obj = |mtl: &str| format!("mtllib {mtl}\n{CUBE_CORNERS}usemtl shiny\nf 1 2 3\nf 1 3 4\n");
    write(
        dir.path(),
        "plain.obj",
        format!("{CUBE_CORNERS}f 1 2 3\nf 1 3 4\n").as_bytes(),
    );
    let plain = renders_warning(dir.path(), "plain.obj", "plain.png", &[]);
    for (case, mtl, needle) in [
        // Refused the whole model before, with no line.
        (
            "nan",
            "newmtl shiny\nKd 0.9 0.1 0.1\nNs nan\n",
            "nan.mtl:3: Ns: 'nan' is not finite",
        ),
        // Warned before, naming no line.
        (
            "word",
            "newmtl shiny\nKd 0.9 x 0.1\n",
            "word.mtl:2: Kd: 'x' is not a number",
        ),
        // Panicked inside tobj before.
        (
            "short",
            "newmtl shiny\nKd 0.9 0.1\n",
            "short.mtl:2: Kd: expected 3 number(s), got 2",
        ),
        (
            "illum",
            "newmtl shiny\nKd 0.9 0.1 0.1\nillum x\n",
            "illum.mtl:3: illum:",
        ),
    ] {
        write(
            dir.path(),
            &format!("{case}.obj"),
            obj(&format!("{case}.mtl")).as_bytes(),
        );
        write(dir.path(), &format!("{case}.mtl"), mtl.as_bytes());
        let image = renders_warning(
            dir.path(),
            &format!("{case}.obj"),
            &format!("{case}.png"),
            &[needle, "material 'shiny' uses the default material"],
        );
        assert!(image == plain, "{case}: not the default material");
    }
}

#[test]
fn usemtl_naming_no_material_warns_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj =
        format!("mtllib m.mtl\n{CUBE_CORNERS}usemtl shiny\nf 1 2 3\nusemtl nosuch\nf 1 3 4\n");
    write(dir.path(), "m.obj", obj.as_bytes());
    write(dir.path(), "m.mtl", b"newmtl shiny\nKd 0.9 0.1 0.1\n");
    let out = render(dir.path(), "m.obj", "out.png");
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("m.obj:12: usemtl: material 'nosuch' is not defined"),
        "{err}"
    );
    assert!(!err.contains("'shiny'"), "{err}");
}

/// Pixels of `a` and `b` whose channels differ by more than 8 levels.
fn differing_pixels(a: &image::RgbImage, b: &image::RgbImage) -> usize {
    a.pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0.iter().zip(q.0).any(|(&x, y)| x.abs_diff(y) > 8))
        .count()
}

#[test]
fn concave_faces_keep_their_notches_and_holes_open() {
    // Each face against the same shape in explicit triangles (the same
    // bounds, so the same framing) and against its outline filled, as a
    // fan from its first vertex filled it.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 4x4 square with a 2x2 hole, facing the camera; lines 1-8, and 9-10
    // copies of 1 and 5 as exporters write a slit (no vertex twice in a
    // face).
    let ring = "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 1 1 0\nv 3 1 0\nv 3 3 0\nv 1 3 0\n\
                v 0 0 0\nv 1 1 0\n";
    let ring_in_triangles = "f 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\n\
                             f 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";
    // An L from a corner that cannot see all of it: its fan covered part of
    // the notch (x > 1, y > 1).
    let l = "v 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\n";
    let l_in_triangles = "f 1 2 5\nf 1 5 6\nf 2 3 4\nf 2 4 5\n";
    let cases = [
        // Round the outside, in along the slit, round the hole the other
        // way, back out: the same vertex twice at each end of the slit...
        (
            "ring",
            ring,
            "f 1 2 3 4 1 5 8 7 6 5\n",
            ring_in_triangles,
            "f 1 2 3 4\n",
        ),
        // ...or its copy.
        (
            "slit",
            ring,
            "f 1 2 3 4 9 5 8 7 6 10\n",
            ring_in_triangles,
            "f 1 2 3 4\n",
        ),
        ("l", l, "f 1 2 3 4 5 6\n", l_in_triangles, "f 4 5 6 1 3\n"),
    ];
    for (name, corners, face, triangles, outline) in cases {
        for (suffix, faces) in [("", face), ("-triangles", triangles), ("-filled", outline)] {
            let file = format!("{name}{suffix}.obj");
            write(d, &file, format!("{corners}{faces}").as_bytes());
        }
        let out = render(d, &format!("{name}.obj"), &format!("{name}.png"));
        let err = stderr(&out);
        assert!(out.status.success(), "{name}: {err}");
        let image = image::open(d.join(format!("{name}.png")))
            .unwrap()
            .to_rgb8();
        let reference = renders_warning(d, &format!("{name}-triangles.obj"), "t.png", &[]);
        let filled = renders_warning(d, &format!("{name}-filled.obj"), "f.png", &[]);
        assert!(
            differing_pixels(&reference, &filled) >= 4,
            "{name}: the hole or notch does not show at this size"
        );
        assert_eq!(
            differing_pixels(&image, &reference),
            0,
            "{name}: not the shape its triangles make"
        );
        assert!(err.is_empty(), "{name}: {err}");
    }
}

#[test]
fn a_face_whose_edges_cross_warns_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    // A good quad, then a bow-tie on line 7 and another on line 8.
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 3 2 0\nf 1 2 3 4\n\
               f 1 5 2 4\nf 1 3 2 4\n";
    write(dir.path(), "bowtie.obj", obj.as_bytes());
    renders_warning(
        dir.path(),
        "bowtie.obj",
        "out.png",
        &[
            "bowtie.obj:7: f: the face's edges cross each other",
            "filled as a fan from its first vertex (2 such face(s) in the file)",
        ],
    );
}
