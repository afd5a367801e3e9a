//! What the command line says where a new user would otherwise be left
//! guessing: a run of one frame, flags that cannot act, viewports not
//! rendered, progress in a log, counts in words.

use std::path::Path;

use crate::common::retrace;

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn animating_a_still_scene_says_it_is_one_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "animate",
            &scene("paper.toml"),
            "--width",
            "32",
            "--height",
            "24",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("has no [animation]: it is one frame (`retrace render`"),
        "{}",
        stderr(&out)
    );
    // One frame, in the singular.
    assert!(stdout(&out).contains(": 1 frame in "), "{}", stdout(&out));
}

/// Every flag that cannot act on the run is refused, with the reason,
/// before any frame is written; each of these used to run silently.
#[test]
fn flags_that_cannot_act_are_refused_with_the_reason() {
    let cases: &[(&str, &[&str], &str)] = &[
        (
            "paper-pan.toml",
            &["--mode", "full,pan"],
            "'full' stands alone",
        ),
        (
            "paper-pan.toml",
            &["--mode", "rsvp"],
            "--mode rsvp has nothing to act on in this run: the scene has no [[viewport]]",
        ),
        (
            "paper-pan.toml",
            &["--mode", "full", "--fractional-pan", "resample"],
            "--fractional-pan has nothing to act on in this run: --mode leaves pan off",
        ),
        (
            "paper-zoom-in.toml",
            &["--mode", "full", "--filter", "box"],
            "--filter has nothing to act on in this run: --mode leaves rsvp off",
        ),
        (
            "paper-zoom-in.toml",
            &["--mode", "full", "--buffer-image", "out/b_####.png"],
            "--buffer-image has nothing to act on in this run: --mode leaves rsvp off",
        ),
        (
            "paper-pan.toml",
            &["--regions", "16"],
            "--regions has nothing to act on in this run: no object or light moves",
        ),
        (
            "paper-all.toml",
            &["--mode", "pan"],
            "--mode pan has nothing to act on in this run: the scene's output is its [[viewport]]s",
        ),
        (
            "paper-all.toml",
            &["--mode", "ostc"],
            "--mode ostc has nothing to act on in this run: without rsvp the viewports",
        ),
        (
            "paper-bounce.toml",
            &["--mode", "pan"],
            "--mode pan has nothing to act on in this run: the camera does not move",
        ),
    ];
    for (file, flags, needle) in cases {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec!["animate", &scene(file)]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>();
        args.extend(["--frames", "0-1", "-o", "out/f_####.png"].map(String::from));
        args.extend(flags.iter().map(|f| f.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = retrace(&args, dir.path());
        // 1, or clap's 2 for a value it parses itself.
        assert!(
            matches!(out.status.code(), Some(1 | 2)),
            "{args:?}: {}",
            stderr(&out)
        );
        assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
        assert!(!dir.path().join("out").exists(), "{args:?}: wrote files");
    }
    // The same flags where they act run as before.
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "animate",
            &scene("paper-bounce.toml"),
            "--frames",
            "0-1",
            "--width",
            "32",
            "--height",
            "24",
            "--mode",
            "ostc",
            "--regions",
            "16",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn render_says_the_viewports_it_leaves_and_renders_one_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &["render", &scene("paper-viewports.toml"), "-o", "cam.png"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "note: the scene's viewports (zoomed, rotated) are not rendered: this is the \
             camera's image; --viewport NAME renders one"
        ),
        "{}",
        stderr(&out)
    );
    assert_eq!(
        image::image_dimensions(dir.path().join("cam.png")).unwrap(),
        (640, 480)
    );
    let out = retrace(
        &[
            "render",
            &scene("paper-viewports.toml"),
            "--viewport",
            "rotated",
            "-o",
            "rotated.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        image::image_dimensions(dir.path().join("rotated.png")).unwrap(),
        (320, 200)
    );
    let out = retrace(
        &[
            "render",
            &scene("paper-viewports.toml"),
            "--viewport",
            "nope",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains(
            "--viewport nope: the scene has no viewport of that name (it has zoomed, rotated)"
        ),
        "{}",
        stderr(&out)
    );
}

/// With stderr a log rather than a terminal (as in these tests, or a
/// render farm's task), progress comes as plain lines, not a bar's
/// control codes; and the closing line counts in words.
#[test]
fn a_log_gets_plain_progress_lines_and_the_summary_counts_in_words() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "animate",
            &scene("paper-viewports.toml"),
            "-o",
            "out/f_####.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("frame 0: 1 of 1 done, "), "{err}");
    assert!(!err.contains('\u{1b}') && !err.contains('\r'), "{err:?}");
    let text = stdout(&out);
    assert!(
        text.contains("1 frame x 2 viewports (zoomed, rotated)"),
        "{text}"
    );
    // Samples a pixel, and why RSVP's can pass one.
    let per_pixel = text
        .split("samples for 128000 pixels: ")
        .nth(1)
        .and_then(|rest| rest.split_once(" a pixel (RSVP traces whole pyramid levels"))
        .unwrap_or_else(|| panic!("{text}"))
        .0;
    assert!(per_pixel.parse::<f64>().unwrap() > 1.0, "{text}");
}

/// `--dirty-image` paints what a frame traced: with reuse off, every pixel,
/// for viewports as for the camera's image (viewports wrote nothing).
#[test]
fn traced_images_of_full_renders_are_black_for_viewports_too() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "animate",
            &scene("paper-viewports.toml"),
            "--mode",
            "full",
            "-o",
            "out/f_####.png",
            "--dirty-image",
            "out/d_####.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    for name in ["zoomed", "rotated"] {
        let traced = image::open(dir.path().join(format!("out/d_0000_{name}.png")))
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .to_rgb8();
        assert_eq!(traced.dimensions(), (320, 200));
        assert!(traced.pixels().all(|p| p.0 == [0, 0, 0]), "{name}");
    }
}

/// Numbers past what the renderer holds are quoted as the user wrote them,
/// with the real limit: not as the infinity, zero or hundreds of digits
/// they parse to.
#[test]
fn numbers_out_of_range_are_quoted_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let paper = std::fs::read_to_string(scene("paper.toml")).unwrap();
    let digits = format!("1{}.0", "0".repeat(300));
    let file_cases = [
        (
            "intensity = 0.75",
            "intensity = 1e300",
            "light[0].intensity",
            "1e300 is too large",
        ),
        (
            "intensity = 0.75",
            "intensity = 1e-300",
            "light[0].intensity",
            "1e-300 is too near 0",
        ),
        (
            "fov = 100.0",
            &format!("fov = {digits}"),
            "camera.fov",
            "is too large",
        ),
        (
            "width = 640",
            "width = 1e30",
            "render.width",
            "expected a whole number, got 1e30",
        ),
    ];
    for (from, to, field, needle) in file_cases {
        let path = dir.path().join("numbers.toml");
        std::fs::write(&path, paper.replacen(from, to, 1)).unwrap();
        let out = retrace(&["render", "numbers.toml", "-o", "n.png"], dir.path());
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{to}: {err}");
        assert!(err.contains(&format!(": {field}: ")), "{to}: {err}");
        assert!(err.contains(needle), "{to}: expected '{needle}' in {err}");
        assert!(err.len() < 300, "{to}: the number printed whole: {err}");
        assert!(!dir.path().join("n.png").exists());
    }
    let flag_cases = [
        ("1e300", "--fov 1e300: field of view 1e300 degrees"),
        (
            "1e400",
            "invalid value '1e400' for '--fov <FOV>': a finite number is needed",
        ),
    ];
    for (fov, needle) in flag_cases {
        let out = retrace(
            &["render", &scene("paper.toml"), "--fov", fov, "-o", "n.png"],
            dir.path(),
        );
        let err = stderr(&out);
        assert!(!out.status.success(), "{fov}: {err}");
        assert!(err.contains(needle), "{fov}: expected '{needle}' in {err}");
    }
}

/// A run too large for the machine is refused before any work, with the
/// figure and what lowers it; a run that fits says what it held at its
/// peak beside the estimate, and the two agree within a small factor.
#[test]
fn memory_is_estimated_before_the_run_and_measured_after() {
    let dir = tempfile::tempdir().unwrap();
    let out = retrace(
        &[
            "animate",
            &scene("paper-bounce.toml"),
            "--width",
            "16384",
            "--height",
            "16384",
            "--spp",
            "256",
            "-o",
            "huge_####.png",
        ],
        dir.path(),
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("this run would need about "), "{err}");
    assert!(
        err.contains("lower --width and --height, or --spp"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    for name in ["paper-bounce.toml", "paper-pan.toml", "paper-zoom-in.toml"] {
        let out = retrace(
            &[
                "animate",
                &scene(name),
                "--width",
                "640",
                "--height",
                "480",
                "--spp",
                "4",
                "--frames",
                "0-1",
                "-o",
                "f_####.png",
            ],
            dir.path(),
        );
        let text = stdout(&out);
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let megabytes = |after: &str| -> f64 {
            let at = text
                .find(after)
                .unwrap_or_else(|| panic!("{name}: no '{after}' in {text}"));
            let mut words = text[at + after.len()..].split(' ');
            let number: f64 = words.next().unwrap().parse().unwrap();
            match words.next() {
                Some("GB") => number * 1e3,
                _ => number,
            }
        };
        let (peak, estimate) = (megabytes("memory: "), megabytes("(estimated "));
        assert!(
            (0.4..=2.5).contains(&(estimate / peak)),
            "{name}: estimated {estimate} MB, peak {peak} MB"
        );
    }
}
