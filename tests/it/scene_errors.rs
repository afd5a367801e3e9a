//! Errors a new user meets in a scene (issue 34): each names the line of
//! the value at fault, in words about the file rather than about Rust
//! types, and blames what is at fault (the file, a flag, a material
//! library given as a scene).

use std::path::Path;
use std::process::Output;

use retrace::scene::{parse_scene_str, SceneOverrides};

use crate::common::retrace;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A scene that loads, every table in it; each case below breaks one line.
const SCENE: &str = "\
[render]
width = 64
height = 48
max_depth = 2

[camera]
position = [0, 1, 5]
look_at = [0, 0, 0]
fov = 60

[[light]]
position = [0, 5, 0]
intensity = 1

[material.red]
diffuse = [1, 0, 0]
shininess = 20

[[object]]
type = \"sphere\"
center = [0, 0, 0]
radius = 1
material = \"red\"

[[object]]
type = \"plane\"
point = [0, -1, 0]
normal = [0, 1, 0]
size = [4, 4]

[animation]
frames = 10

[[animation.object]]
object = \"object[0]\"
frame = 5
translate = [1, 0, 0]
";

/// [`SCENE`] with line `line` (1-based) replaced by `text`.
fn with_line(line: usize, text: &str) -> String {
    SCENE
        .lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { text } else { l })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The error of loading `text` as `s.toml`, as the command line prints it.
fn error_of(text: &str) -> String {
    parse_scene_str(text, Path::new("s.toml"), &SceneOverrides::default())
        .unwrap_err()
        .to_string()
}

#[test]
fn the_base_scene_loads() {
    parse_scene_str(SCENE, Path::new("s.toml"), &SceneOverrides::default()).unwrap();
}

#[test]
fn out_of_range_values_name_their_own_line_not_their_tables() {
    for (line, text, error) in [
        (4, "max_depth = 99", "render.max_depth: at most 16, got 99"),
        (
            9,
            "fov = 200",
            "camera.fov: field of view 200 degrees: must be a number above 0 and below 180 \
             for perspective",
        ),
        (
            13,
            "intensity = -2",
            "light[0].intensity: must be a finite number >= 0, got -2",
        ),
        (
            16,
            "diffuse = [1, -1, 0]",
            "material.red.diffuse: colour components must not be negative, got [1.0, -1.0, 0.0]",
        ),
        (
            17,
            "shininess = -1",
            "material.red.shininess: must be >= 0, got -1",
        ),
        (
            17,
            "roughness = 1.5",
            "material.red.roughness: must be within 0..1, got 1.5",
        ),
        (
            17,
            "bump_scale = inf\nbump_texture = \"h.png\"",
            "material.red.bump_scale: must be finite, got inf",
        ),
        (
            17,
            "bump_scale = 0.5",
            "material.red.bump_scale: scales a height map: give the material a `bump_texture`",
        ),
        (
            17,
            "normal_texture = \"n.png\"\nbump_texture = \"h.png\"",
            "material.red.normal_texture: a material takes a height map (`bump_texture`) or a \
             normal map (`normal_texture`), not both",
        ),
        (
            13,
            "falloff = \"linear\"",
            "light[0].falloff: unknown variant `linear`, expected `none` or `inverse-square`",
        ),
        (
            22,
            "radius = -1",
            "object[0].radius: must be above 0, got -1",
        ),
        (
            28,
            "normal = [0, 0, 0]",
            "object[1].normal: must not be zero",
        ),
        (
            29,
            "size = [4, 0]",
            "object[1].size: both sides must be above 0, got [4.0, 0.0]",
        ),
        (32, "frames = 0", "animation.frames: must be at least 1"),
        (
            37,
            "translate = [1e13, 0, 0]",
            "animation.object[0].translate: [10000000000000.0, 0.0, 0.0] lies beyond the \
             scene's extent (within ±1e12 of the origin)",
        ),
    ] {
        assert_eq!(
            error_of(&with_line(line, text)),
            format!("s.toml:{line}: {error}"),
            "{text}"
        );
    }
}

#[test]
fn a_value_left_out_is_blamed_on_its_tables_line() {
    // No radius to point at: the sphere's [[object]] header.
    assert_eq!(
        error_of(&with_line(22, "")),
        "s.toml:19: object[0].radius: required for type = \"sphere\""
    );
}

#[test]
fn type_errors_say_what_a_field_takes_in_words() {
    for (line, text, error) in [
        (
            2,
            "width = 1.5",
            "render.width: expected a whole number, got 1.5",
        ),
        (
            7,
            "position = [0, 1]",
            "camera.position: expected an array of 3 numbers, got 2 values",
        ),
        (
            9,
            "fov = \"wide\"",
            "camera.fov: expected a number, got the string \"wide\"",
        ),
        (
            13,
            "intensity = true",
            "light[0].intensity: expected a number, got true",
        ),
        (
            21,
            "center = \"origin\"",
            "object[0].center: expected an array of 3 numbers, got the string \"origin\"",
        ),
        (
            22,
            "radius = \"big\"",
            "object[0].radius: expected a number, got the string \"big\"",
        ),
        (
            23,
            "material = 5",
            "object[0].material: expected a string in quotes, got 5",
        ),
        (
            23,
            "smooth = \"yes\"",
            "object[0].smooth: expected true or false, got the string \"yes\"",
        ),
        (
            29,
            "size = [4]",
            "object[1].size: expected an array of 2 numbers, got 1 value",
        ),
        (
            32,
            "frames = -3",
            "animation.frames: expected a whole number from 0 to 4294967295, got -3",
        ),
        (
            36,
            "frame = 2.5",
            "animation.object[0].frame: expected a whole number, got 2.5",
        ),
    ] {
        assert_eq!(
            error_of(&with_line(line, text)),
            format!("s.toml:{line}: {error}"),
            "{text}"
        );
    }
    // Tables and choices, too.
    assert_eq!(
        error_of("camera = 5\n"),
        "s.toml:1: camera: expected a table, got 5"
    );
    assert_eq!(
        error_of(&with_line(8, "projection = \"fish\"")),
        "s.toml:8: camera.projection: expected one of \"perspective\", \"equal-angle\", \
         \"fisheye\", got \"fish\""
    );
    assert_eq!(
        error_of(&with_line(8, "projection = 3")),
        "s.toml:8: camera.projection: expected a string in quotes, got 3"
    );
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

#[test]
fn an_image_size_from_the_flags_alone_names_the_flags_not_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "render", "--width", "100000", "--height", "100000", "-o", "out.png",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        "error: --width 100000 --height 100000: image size 100000x100000 is too large \
         (at most 32768 pixels per side and 268435456 pixels in all)\n"
    );
    assert!(!dir.path().join("out.png").exists());
}

#[test]
fn a_scene_without_a_light_warns_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let unlit: String = SCENE
        .lines()
        .filter(|l| !l.starts_with("[[light]]") && !l.starts_with("intensity"))
        .filter(|l| *l != "position = [0, 5, 0]")
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(dir.path().join("s.toml"), unlit).unwrap();
    let out = retrace(&["render", "s.toml", "-o", "out.png"], dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        "warning: s.toml: no [[light]]: surfaces show only the ambient term \
         (render.ambient = [0.1, 0.1, 0.1]), without highlights or shadows\n"
    );
    assert!(dir.path().join("out.png").exists());
}

/// An `include` after a table, and a model `file` that is a folder, say
/// what is wrong rather than "unknown field" or "no such model file".
#[test]
fn a_late_include_and_a_folder_for_a_model_say_so() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("base.toml"), SCENE).unwrap();
    std::fs::write(
        dir.path().join("late.toml"),
        "[render]\nwidth = 32\ninclude = \"base.toml\"\n",
    )
    .unwrap();
    let out = retrace(&["render", "late.toml", "-o", "x.png"], dir.path());
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("late.toml:3") && err.contains("must come before the first table"),
        "{err}"
    );
    std::fs::create_dir(dir.path().join("models")).unwrap();
    let folder = format!("{SCENE}\n[[object]]\ntype = \"mesh\"\nfile = \"models\"\n");
    std::fs::write(dir.path().join("folder.toml"), folder).unwrap();
    let out = retrace(&["render", "folder.toml", "-o", "y.png"], dir.path());
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("a folder, not a model file"), "{err}");
    assert!(!dir.path().join("x.png").exists() && !dir.path().join("y.png").exists());
}
