//! OBJ files as users hand them over: elements that are not faces. What can
//! be rendered around renders, with a warning naming the file and line; a
//! model with nothing to render is an error naming the file.

use std::path::Path;
use std::process::Output;

use crate::common::retrace;

/// Eight corners of a unit cube, as OBJ lines 1-8.
const CUBE_CORNERS: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                            v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(dir.join(name), bytes).unwrap();
}

/// Renders `model` (in `dir`) at 32x24 to `output`.
fn render(dir: &Path, model: &str, output: &str) -> Output {
    retrace(
        &[
            "render", model, "--width", "32", "--height", "24", "-o", output,
        ],
        dir,
    )
}

fn stderr(out: &Output) -> String {
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
