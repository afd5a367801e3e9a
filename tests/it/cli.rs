//! The command line as a user meets it: good scenes render, bad input gets a
//! clear message naming file, line and field, a non-zero exit, no panic and
//! no output file.

use crate::common::retrace;

use std::path::{Path, PathBuf};
use std::process::Output;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const CAMERA: &str = "[camera]\nposition = [0, 1, 6]\nlook_at = [0, 0.5, 0]\nfov = 50\n";
const TRIANGLE_OBJ: &str = "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n";

struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new(files: &[(&str, &str)]) -> Case {
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in files {
            std::fs::write(dir.path().join(name), text).unwrap();
        }
        Case { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Runs `render` on `scene` into out.png plus `extra` arguments.
    fn render(&self, scene: &str, extra: &[&str]) -> Output {
        let mut args = vec!["render", scene, "-o", "out.png"];
        for (flag, default) in [("--width", "32"), ("--height", "24")] {
            if !extra.contains(&flag) {
                args.extend([flag, default]);
            }
        }
        args.extend_from_slice(extra);
        retrace(&args, self.dir.path())
    }

    /// Asserts a clean failure: exit 1, every `needle` in the message, no
    /// panic, and no output image.
    fn assert_fails(&self, out: &Output, needles: &[&str]) {
        let err = stderr(out);
        assert_eq!(out.status.code(), Some(1), "stderr: {err}");
        assert!(!err.contains("panicked"), "panic: {err}");
        for needle in needles {
            assert!(err.contains(needle), "expected '{needle}' in: {err}");
        }
        assert!(!self.path("out.png").exists(), "an output file was written");
        let leftovers: Vec<_> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    }

    fn assert_renders(&self, out: &Output) -> image::RgbImage {
        assert!(out.status.success(), "stderr: {}", stderr(out));
        let image = image::open(self.path("out.png")).unwrap().to_rgb8();
        assert_eq!(image.dimensions(), (32, 24));
        image
    }
}

#[test]
fn built_in_paper_scene_renders_without_arguments() {
    let case = Case::new(&[]);
    let out = retrace(
        &["render", "--width", "64", "--height", "48", "-o", "out.png"],
        case.dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = image::open(case.path("out.png")).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), (64, 48));
    // Sky above, a checkerboard below: the image is not one flat colour.
    let top = image.get_pixel(32, 2);
    let distinct: std::collections::HashSet<_> = image.pixels().collect();
    assert!(distinct.len() > 50, "only {} colours", distinct.len());
    assert!(top[2] > top[0], "the sky should be blue: {top:?}");
}

#[test]
fn scene_with_obj_mesh_and_tga_output() {
    let case = Case::new(&[
        ("tri.obj", TRIANGLE_OBJ),
        (
            "s.toml",
            &format!("{CAMERA}[[light]]\nposition = [2, 5, 5]\n[[object]]\ntype = \"mesh\"\nfile = \"tri.obj\"\n"),
        ),
    ]);
    let out = retrace(
        &[
            "render", "s.toml", "-o", "out.tga", "--width", "16", "--height", "12",
        ],
        case.dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = image::open(case.path("out.tga")).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), (16, 12));
    // The triangle is lit grey in the middle; the background is black.
    assert!(image.get_pixel(8, 6)[0] > 60);
    assert_eq!(image.get_pixel(0, 0)[0], 0);
}

#[test]
fn bare_obj_renders_with_framing_camera() {
    let case = Case::new(&[("tri.obj", TRIANGLE_OBJ)]);
    let image = case.assert_renders(&case.render("tri.obj", &[]));
    let centre = image.get_pixel(16, 12);
    let corner = image.get_pixel(0, 0);
    assert_ne!(centre, corner, "the model should fill the centre");
}

#[test]
fn missing_scene_file() {
    let case = Case::new(&[]);
    case.assert_fails(
        &case.render("nope.toml", &[]),
        &["nope.toml", "cannot read"],
    );
}

#[test]
fn malformed_toml_names_line_and_field() {
    let case = Case::new(&[(
        "s.toml",
        &format!("{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = \"big\"\n"),
    )]);
    case.assert_fails(
        &case.render("s.toml", &[]),
        &["s.toml:8", "object[0].radius"],
    );
    let case = Case::new(&[("s.toml", "[camera]\nposition = [0, 1\nfov = 50\n")]);
    case.assert_fails(&case.render("s.toml", &[]), &["s.toml:"]);
}

#[test]
fn unknown_material() {
    let case = Case::new(&[(
        "s.toml",
        &format!("{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"chrome\"\n"),
    )]);
    case.assert_fails(
        &case.render("s.toml", &[]),
        &[
            "s.toml:9",
            "object[0].material",
            "unknown material 'chrome'",
        ],
    );
}

#[test]
fn obj_that_does_not_parse_names_file_and_line() {
    let case = Case::new(&[("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 zero\nf 1 2 3\n")]);
    case.assert_fails(
        &case.render("bad.obj", &[]),
        &["bad.obj:3", "'zero' is not a number"],
    );
    let case = Case::new(&[("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")]);
    case.assert_fails(&case.render("bad.obj", &[]), &["bad.obj:4", "out of range"]);
    // The same errors through a scene file; a model that is not there is
    // the scene's line.
    let scene = format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"bad.obj\"\n");
    let case = Case::new(&[("s.toml", &scene), ("bad.obj", "v 0 0 0\nv 1 0 zero\n")]);
    case.assert_fails(&case.render("s.toml", &[]), &["bad.obj:2", "'zero'"]);
    let case = Case::new(&[("s.toml", &scene)]);
    case.assert_fails(
        &case.render("s.toml", &[]),
        &["s.toml:7: object[0].file", "bad.obj: no such model file"],
    );
}

#[test]
fn nan_and_inf_coordinates() {
    let case = Case::new(&[("bad.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")]);
    case.assert_fails(&case.render("bad.obj", &[]), &["bad.obj:2", "not finite"]);
    let case = Case::new(&[(
        "s.toml",
        &format!("{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, inf, 0]\nradius = 1\n"),
    )]);
    case.assert_fails(
        &case.render("s.toml", &[]),
        &["s.toml:7", "object[0].center", "finite"],
    );
}

#[test]
fn degenerate_triangles_are_skipped_with_a_warning() {
    // Triangle 2 repeats a vertex, triangle 3 is collinear.
    let obj = "v -1 0 0\nv 1 0 0\nv 0 2 0\nv 2 0 0\nf 1 2 3\nf 1 1 3\nf 1 2 4\n";
    let case = Case::new(&[("m.obj", obj)]);
    let out = case.render("m.obj", &[]);
    case.assert_renders(&out);
    assert!(
        stderr(&out).contains("dropped 2 degenerate triangle"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn a_missing_material_library_warns_and_renders() {
    let obj = format!("mtllib gone.mtl\nusemtl red\n{TRIANGLE_OBJ}");
    let case = Case::new(&[("m.obj", &obj)]);
    let out = case.render("m.obj", &[]);
    case.assert_renders(&out);
    let err = stderr(&out);
    assert!(
        err.contains("m.obj: material library not loaded (gone.mtl"),
        "{err}"
    );
    // A model that names no library says nothing about one.
    let case = Case::new(&[("m.obj", TRIANGLE_OBJ)]);
    let out = case.render("m.obj", &[]);
    case.assert_renders(&out);
    assert!(
        !stderr(&out).contains("material library"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn empty_mesh() {
    let case = Case::new(&[("empty.obj", "# nothing\nv 0 0 0\n")]);
    case.assert_fails(
        &case.render("empty.obj", &[]),
        &["empty.obj", "no triangles"],
    );
    // Inside a scene a model with faces, all of them degenerate, is only a
    // warning: the rest still renders. (One with no faces at all is an
    // error, as on its own: obj_input.rs.)
    let case = Case::new(&[
        ("empty.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
        (
            "s.toml",
            &format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"empty.obj\"\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0.5, 0]\nradius = 1\n"),
        ),
    ]);
    let out = case.render("s.toml", &[]);
    case.assert_renders(&out);
    assert!(stderr(&out).contains("no triangles"));
}

#[test]
fn image_size_zero_or_absurd() {
    let case = Case::new(&[("s.toml", CAMERA)]);
    case.assert_fails(
        &case.render("s.toml", &["--width", "0"]),
        &["error: --width 0: image size 0x24", "at least 1"],
    );
    // The file's own size keeps its field's name and line.
    let case = Case::new(&[("s.toml", &format!("[render]\nwidth = 0\n{CAMERA}"))]);
    let out = retrace(&["render", "s.toml", "-o", "out.png"], case.dir.path());
    case.assert_fails(&out, &["s.toml:2: render.width", "at least 1"]);
    let out = case.render("s.toml", &["--width", "1000000", "--height", "1000000"]);
    case.assert_fails(&out, &["too large"]);
}

#[test]
fn field_of_view_out_of_range() {
    let case = Case::new(&[("s.toml", CAMERA)]);
    for fov in ["0", "-10", "180", "200"] {
        let out = case.render("s.toml", &["--fov", fov]);
        case.assert_fails(&out, &["--fov", &format!("field of view {fov} degrees")]);
    }
    // Wide is fine below 180 for perspective, and up to 360 for equal-angle.
    case.assert_renders(&case.render("s.toml", &["--fov", "179"]));
    std::fs::remove_file(case.path("out.png")).unwrap();
    let out = case.render(
        "s.toml",
        &["--fov", "360", "--camera", "equal-angle", "--height", "12"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn unwritable_output_says_why_once() {
    let case = Case::new(&[("s.toml", CAMERA)]);
    // A folder where the image should go: the final rename fails.
    std::fs::create_dir(case.path("out.png")).unwrap();
    let out = case.render("s.toml", &[]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("out.png: cannot write"), "{err}");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
}

#[test]
fn unsupported_output_format() {
    let case = Case::new(&[("s.toml", CAMERA)]);
    let out = retrace(&["render", "s.toml", "-o", "out.jpg"], case.dir.path());
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("unsupported image format"));
    assert!(!case.path("out.jpg").exists());
}

#[test]
fn grid_backend_answers_the_same_at_any_resolution() {
    let case = Case::new(&[]);
    let mut images = Vec::new();
    for resolution in ["1", "3x7x2", "40"] {
        let out = retrace(
            &[
                "render",
                "--backend",
                "grid",
                "--grid-resolution",
                resolution,
                "--width",
                "48",
                "--height",
                "36",
                "-o",
                "out.png",
            ],
            case.dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        images.push(image::open(case.path("out.png")).unwrap().to_rgb8());
    }
    assert!(images.windows(2).all(|w| w[0] == w[1]));
    let out = retrace(
        &["render", "--backend", "grid", "--grid-resolution", "0"],
        case.dir.path(),
    );
    assert_eq!(
        out.status.code(),
        Some(2),
        "clap rejects it as a usage error"
    );
    assert!(stderr(&out).contains("1 to 1024"));
    // With Embree it would do nothing: said, not ignored.
    let out = retrace(&["render", "--grid-resolution", "8"], case.dir.path());
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("add --backend grid"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn help_is_available_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["--help"],
        vec!["render", "--help"],
        vec!["bench", "--help"],
    ] {
        let out = retrace(&args, dir.path());
        assert!(out.status.success());
        assert!(String::from_utf8_lossy(&out.stdout).contains("Usage"));
    }
}

/// The bench from the repository (it reads the experiment scenes there),
/// tiny and short, into `out`.
fn bench(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["bench", "--width", "64", "--height", "48", "--out"];
    let out = out.to_str().expect("temporary paths are UTF-8");
    args.push(out);
    args.extend_from_slice(extra);
    retrace(&args, Path::new(env!("CARGO_MANIFEST_DIR")))
}

#[test]
fn bench_says_when_reuse_could_not_apply() {
    let dir = tempfile::tempdir().unwrap();
    // E1 through a perspective camera: its pan cannot be a shift.
    let out = bench(
        &dir.path().join("bench"),
        &["--only", "E1", "--frames", "0-1", "--camera", "perspective"],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: E1: rendered in full: the perspective camera moves"),
        "{err}"
    );
    // The paper's own E1 has nothing to say; its rows go to --json too.
    let json = dir.path().join("e1.json");
    let out = bench(
        &dir.path().join("bench"),
        &[
            "--only",
            "E1",
            "--frames",
            "0-1",
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert!(out.status.success());
    assert!(
        !stderr(&out).contains("rendered in full"),
        "{}",
        stderr(&out)
    );
    let rows: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(rows[0]["id"], "E1", "{rows}");
    assert_eq!(rows[0]["frames"], 2, "{rows}");
}

#[test]
fn bench_repeats_viewport_experiments_too() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("bench");
    let out = bench(
        &out_dir,
        &["--only", "E2", "--frames", "2-4", "--repeats", "2"],
    );
    assert!(out.status.success(), "stderr: {}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("median of 2 alternated runs"), "{stdout}");
    let frames = std::fs::read_to_string(out_dir.join("e2-in-frames.csv")).unwrap();
    assert_eq!(frames.lines().count(), 1 + 3, "{frames}");
}

#[test]
fn bench_measures_the_viewport_experiments_at_the_knobs_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let samples = |extra: &[&str], name: &str| {
        let out_dir = dir.path().join(name);
        let mut args = vec!["--only", "E2", "--frames", "0-3"];
        args.extend_from_slice(extra);
        let out = bench(&out_dir, &args);
        assert!(out.status.success(), "stderr: {}", stderr(&out));
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("bench.json")).unwrap())
                .unwrap();
        let traced: Vec<u64> = json
            .as_array()
            .unwrap()
            .iter()
            .map(|row| row["samples_traced"].as_u64().unwrap())
            .collect();
        (stdout, traced)
    };
    let (stdout, default) = samples(&[], "default");
    assert!(stdout.contains("E2 in (RSVP)"), "{stdout}");
    // A level bias of +1 doubles the density on each axis: far more
    // samples (the zoom starts at the coarsest level, so -1 could not halve
    // it).
    let (stdout, fine) = samples(&["--level-bias", "1"], "fine");
    assert!(stdout.contains("E2 in (RSVP, level bias +1)"), "{stdout}");
    for (coarse, fine) in default.iter().zip(&fine) {
        assert!(2 * coarse < *fine, "{coarse} against {fine}");
    }
}

/// Both sides against a converged reference, side by side, in every
/// output of the bench: the table, bench.json, bench.csv and report.md.
#[test]
fn bench_reports_both_sides_against_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("bench");
    let out = bench(&out_dir, &["--only", "E2", "--frames", "0-2", "--spp", "4"]);
    assert!(out.status.success(), "stderr: {}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let header = stdout
        .lines()
        .find(|l| l.starts_with("experiment"))
        .unwrap();
    for column in ["spp (ref)", "full vs ref dB", "accel vs ref dB"] {
        assert!(header.contains(column), "no {column}: {stdout}");
    }
    let row = stdout.lines().find(|l| l.starts_with("E2 in")).unwrap();
    assert!(row.contains("  4 (64)  "), "{row}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("bench.json")).unwrap())
            .unwrap();
    for row in json.as_array().unwrap() {
        assert_eq!(row["samples_per_pixel"], 4, "{row}");
        assert_eq!(row["reference_samples"], 64, "{row}");
        assert_eq!(row["reference_frames"], serde_json::json!([0, 2]), "{row}");
        for side in ["full_vs_reference", "accelerated_vs_reference"] {
            let worst = row[side]["worst_psnr_db"].as_f64().expect("finite");
            assert!(worst > 5.0 && worst < 100.0, "{side}: {row}");
            let mean_abs = row[side]["mean_abs"].as_f64().unwrap();
            assert!(mean_abs > 0.0, "{side}: {row}");
        }
        // The old comparison stays: against the same samples' full render.
        assert!(row["worst_psnr_db"].as_f64().is_some(), "{row}");
    }
    let csv = std::fs::read_to_string(out_dir.join("bench.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for column in [
        "full_vs_reference.worst_psnr_db",
        "accelerated_vs_reference.worst_psnr_db",
    ] {
        let at = header.iter().position(|c| *c == column).unwrap();
        let cell = csv.lines().nth(1).unwrap().split(',').nth(at).unwrap();
        assert!(cell.parse::<f64>().unwrap().is_finite(), "{column}: {cell}");
    }
    let report = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(
        report
            .contains("Against a 64-spp reference of frames 0, 2: the full render at 4 spp: PSNR"),
        "{report}"
    );
}

#[test]
fn bench_writes_the_table_profiles_plots_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("bench");
    let out = bench(&out_dir, &["--frames", "2-4"]);
    assert!(out.status.success(), "stderr: {}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let ids = ["E1", "E2 in", "E2 out", "E3", "E4"];
    for id in ids {
        assert!(
            stdout.contains(&format!("{id} (")),
            "{id} missing: {stdout}"
        );
    }
    assert!(stdout.contains("oracle") && stdout.contains("efficiency"));

    let csv = std::fs::read_to_string(out_dir.join("bench.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    for column in [
        "id",
        "paper_speedup",
        "full_ms_per_frame",
        "accelerated_ms_per_frame",
        "speedup",
        "oracle_speedup",
        "efficiency",
        "bookkeeping_share",
        "exactness",
    ] {
        assert!(header.contains(&column), "no {column} in {header:?}");
    }
    assert_eq!(lines.len(), 1 + ids.len(), "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("bench.json")).unwrap())
            .unwrap();
    let rows = json.as_array().expect("a list of rows");
    assert_eq!(rows.len(), ids.len());
    for (row, id) in rows.iter().zip(ids) {
        assert_eq!(row["id"], id);
        assert_eq!(row["frames"], 3);
        assert!(row["speedup"].as_f64().unwrap() > 0.0);
        // Every experiment has its oracle, and tracing less than it is
        // impossible: the accelerated side traced at least what it says.
        let oracle = row["oracle_samples"].as_u64().expect("oracle measured");
        assert!(oracle > 0 && oracle <= 3 * 64 * 48, "{id}: {oracle}");
        // Where the accelerated time went: every sequence traced something
        // (frame 2 has nothing to reuse) and copied or resampled its frames.
        let (tracing, copying) = (
            row["tracing_share"].as_f64().unwrap(),
            row["copying_share"].as_f64().unwrap(),
        );
        assert!(tracing > 0.0 && copying > 0.0, "{id}: {tracing} {copying}");
        assert!(tracing + copying <= 1.0 + 1e-9, "{id}: {tracing} {copying}");
    }
    // The camera experiments are exact; E4 checks its buffer bit for bit.
    for i in [0, 3, 4] {
        assert_eq!(rows[i]["exact"], true, "{}", rows[i]);
    }

    let report = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    for id in ids {
        let stem = id.to_lowercase().replace(' ', "-");
        let frames = std::fs::read_to_string(out_dir.join(format!("{stem}-frames.csv"))).unwrap();
        let frame_numbers: Vec<&str> = frames
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap())
            .collect();
        assert_eq!(frame_numbers, ["2", "3", "4"], "{stem}");
        assert!(frames.starts_with("frame,full_ms,accelerated_ms,"));
        assert!(frames
            .lines()
            .next()
            .unwrap()
            .contains(",accelerated.trace_ms,accelerated.copy_ms,"));
        for plot in [format!("{stem}-time.png"), format!("{stem}-rays.png")] {
            let image = image::open(out_dir.join(&plot)).unwrap();
            assert!(image.width() > 100 && image.height() > 100);
            assert!(report.contains(&format!("]({plot})")), "{plot} not linked");
        }
    }
    // Nothing half-written is left behind.
    for entry in std::fs::read_dir(&out_dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "left over: {name}");
    }
}

#[test]
fn bench_e3_and_e4_cut_regions_as_asked() {
    // Coarser regions dirty fewer, bigger regions: the per-frame dirty
    // counts of both OSTC experiments must follow --regions.
    let dirty_per_experiment = |regions: &str| -> Vec<u64> {
        ["E3", "E4"]
            .iter()
            .map(|id| {
                let dir = tempfile::tempdir().unwrap();
                let out_dir = dir.path().join("bench");
                let args = ["--only", id, "--frames", "85-88", "--regions", regions];
                let out = bench(&out_dir, &args);
                assert!(out.status.success(), "stderr: {}", stderr(&out));
                let stem = id.to_lowercase();
                let frames =
                    std::fs::read_to_string(out_dir.join(format!("{stem}-frames.csv"))).unwrap();
                let mut lines = frames.lines();
                let header: Vec<&str> = lines.next().unwrap().split(',').collect();
                let column = header
                    .iter()
                    .position(|c| *c == "accelerated.dirty_regions")
                    .unwrap();
                lines
                    .map(|l| l.split(',').nth(column).unwrap().parse::<u64>().unwrap())
                    .sum()
            })
            .collect()
    };
    let (coarse, fine) = (dirty_per_experiment("4"), dirty_per_experiment("16"));
    for (index, id) in ["E3", "E4"].iter().enumerate() {
        assert!(
            0 < coarse[index] && coarse[index] < fine[index],
            "{id}: {} dirty regions at 4x4, {} at 16x16",
            coarse[index],
            fine[index]
        );
    }
}

#[test]
fn bench_rejects_bad_frames_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("bench");
    let cases: [(&[&str], &str); 7] = [
        (&["--frames", "5-2"], "first frame comes after the last"),
        (&["--frames", "0-100"], "frames 0-99"),
        (
            &["--frames", "0..2"],
            "'0..2' is not a frame number (give A-B (inclusive) or A, e.g. 0-49)",
        ),
        (
            &["--only", "E2", "--oversample", "0"],
            "--oversample 0: must be within 0.01..8",
        ),
        (&["--only", "E9"], "unknown measurement 'E9'"),
        (
            &["--only", "E2", "--level-bias", "16"],
            "--level-bias 16: must be within -4..4",
        ),
        // A scene given is measured as it is: a still one has nothing to
        // measure.
        (
            &["--only", "E4", "scenes/paper.toml"],
            "E4 measures a scene's own timeline, and scenes/paper.toml has no [animation] \
             (scenes/paper-all.toml is E4's)",
        ),
    ];
    for (args, needle) in cases {
        let out = bench(&out_dir, args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: expected '{needle}' in {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            !out_dir.exists(),
            "{args:?}: output written before the check"
        );
    }
}

/// A scene given to an experiment is measured on its own timeline (the
/// bouncing ball here: a camera sequence, exact), under its own name; the
/// default is the experiment's shipped scene.
#[test]
fn bench_measures_a_scene_given_on_its_own_timeline() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("bench");
    let out = bench(
        &out_dir,
        &[
            "--only",
            "E4",
            "--frames",
            "0-2",
            "scenes/paper-bounce.toml",
        ],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let table = std::fs::read_to_string(out_dir.join("bench.csv")).unwrap();
    let row = table.lines().nth(1).expect("one row");
    assert!(
        row.starts_with("E4,") && row.contains(",paper-bounce,"),
        "{row}"
    );
    assert!(row.contains(",bit-exact"), "{row}");
    let out = bench(&out_dir, &["--only", "E4", "--frames", "0-2"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let table = std::fs::read_to_string(out_dir.join("bench.csv")).unwrap();
    let row = table.lines().nth(1).expect("one row");
    assert!(row.contains(",paper-all,"), "{row}");
    assert!(row.contains("buffer bit-exact"), "{row}");
}

#[test]
fn samples_per_pixel_come_from_the_scene_or_the_flag() {
    let sphere = "[[object]]\ntype = \"sphere\"\ncenter = [0, 0.5, 0]\nradius = 0.8\n\
                  [[light]]\nposition = [2, 4, 3]\n";
    let case = Case::new(&[
        ("one.toml", &format!("{CAMERA}{sphere}")),
        ("four.toml", &format!("{CAMERA}[render]\nspp = 4\n{sphere}")),
        ("zero.toml", &format!("{CAMERA}[render]\nspp = 0\n{sphere}")),
    ]);
    let image = |scene: &str, extra: &[&str]| {
        let out = case.render(scene, extra);
        case.assert_renders(&out)
    };
    let (point, file) = (image("one.toml", &[]), image("four.toml", &[]));
    // The sphere's edge is antialiased: some pixels between the two.
    assert_ne!(point, file);
    assert_eq!(image("one.toml", &["--spp", "4"]), file);
    assert_eq!(image("four.toml", &["--spp", "1"]), point);

    std::fs::remove_file(case.path("out.png")).unwrap();
    let out = case.render("zero.toml", &[]);
    case.assert_fails(&out, &["zero.toml:6", "render.spp", "within 1..256, got 0"]);
    let out = case.render("one.toml", &["--spp", "257"]);
    case.assert_fails(&out, &["--spp 257", "within 1..256"]);
    let err = stderr(&out);
    assert!(
        !err.contains("one.toml"),
        "the flag alone is at fault: {err}"
    );
}

#[test]
fn light_samples_come_from_the_scene_or_the_flag() {
    let lit = "[[object]]\ntype = \"sphere\"\ncenter = [0, 0.5, 0]\nradius = 0.8\n\
               [[object]]\ntype = \"plane\"\npoint = [0, -0.3, 0]\nnormal = [0, 1, 0]\n\
               [[light]]\nshape = \"sphere\"\nposition = [2, 4, 3]\nradius = 1.5\nintensity = 20\n";
    let case = Case::new(&[
        ("default.toml", &format!("{CAMERA}{lit}")),
        (
            "one.toml",
            &format!("{CAMERA}[render]\nlight_samples = 1\n{lit}"),
        ),
        (
            "zero.toml",
            &format!("{CAMERA}[render]\nlight_samples = 0\n{lit}"),
        ),
    ]);
    let image = |scene: &str, extra: &[&str]| {
        let out = case.render(scene, extra);
        case.assert_renders(&out)
    };
    let (four, one) = (image("default.toml", &[]), image("one.toml", &[]));
    // The sphere's soft shadow: one light sample leaves other noise there.
    assert_ne!(four, one);
    assert_eq!(image("default.toml", &["--light-samples", "1"]), one);
    assert_eq!(image("one.toml", &["--light-samples", "4"]), four);

    std::fs::remove_file(case.path("out.png")).unwrap();
    let out = case.render("zero.toml", &[]);
    case.assert_fails(
        &out,
        &[
            "zero.toml:6",
            "render.light_samples",
            "within 1..=256, got 0",
        ],
    );
    let out = case.render("one.toml", &["--light-samples", "257"]);
    case.assert_fails(&out, &["--light-samples 257", "within 1..=256"]);
}

#[test]
fn the_reference_is_256_samples_a_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["render", "--width", "16", "--height", "12", "-o", "r.png"];
    let out = retrace(&[&args[..], &["--reference"]].concat(), dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("256 samples a pixel"));
    let out = retrace(
        &[&args[..], &["--reference", "--spp", "4"]].concat(),
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(stderr(&out).contains("'--reference' cannot be used with '--spp"));
}
