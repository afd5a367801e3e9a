//! Errors a new user meets in a scene (issue 34): each names the line of
//! the value at fault, in words about the file rather than about Rust
//! types, and blames what is at fault (the file, a flag, a material
//! library given as a scene).

use std::process::Output;

use crate::common::retrace;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn a_material_library_given_as_a_scene_names_the_model_to_render() {
    let dir = tempfile::tempdir().unwrap();
    let triangle = "v -1 0 0\nv 1 0 0\nv 0 2 0\nusemtl fur\nf 1 2 3\n";
    std::fs::write(
        dir.path().join("spider.obj"),
        format!("mtllib spider.mtl\n{triangle}"),
    )
    .unwrap();
    // Another model, using another library: not named.
    std::fs::write(
        dir.path().join("other.obj"),
        format!("mtllib other.mtl\n{triangle}"),
    )
    .unwrap();
    std::fs::write(
        dir.path().join("spider.mtl"),
        "newmtl fur\nKd 0.5 0.4 0.3\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("lone.mtl"), "newmtl fur\nKd 0.5 0.4 0.3\n").unwrap();
    for (mtl, render) in [
        ("spider.mtl", "spider.obj"),
        (
            "lone.mtl",
            "the .obj model that names it in a `mtllib` line",
        ),
    ] {
        let out = retrace(&["render", mtl, "-o", "out.png"], dir.path());
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert_eq!(
            stderr(&out),
            format!(
                "error: {mtl}: this is a material library (MTL), not a scene: render {render}, \
                 which uses it\n"
            )
        );
        assert!(!dir.path().join("out.png").exists());
    }
}
