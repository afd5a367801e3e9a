//! The command line's limits (issue 51, items 11, 12 and 17): too many
//! threads refused at once, `render`'s output folder checked before the
//! render, usage errors (status 2) told from the others (status 1) as the
//! guide says, and help that lists what a flag takes and speaks of its own
//! command.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::retrace;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `retrace args` in `dir`, failing the test if it has not finished
/// within `limit` (the run is killed first: an unchecked run may go on
/// for minutes).
fn retrace_within(args: &[&str], dir: &Path, limit: Duration) -> Output {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run retrace");
    while child.try_wait().expect("wait for retrace").is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().expect("reap retrace");
            panic!(
                "retrace {} still running after {limit:?}: {}",
                args.join(" "),
                stderr(&out)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("read retrace's output")
}

/// An error, not a usage error: status 1, each of `needles` said, no
/// panic.
fn assert_error(out: &Output, needles: &[&str]) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for needle in needles {
        assert!(err.contains(needle), "expected '{needle}' in: {err}");
    }
}

#[test]
fn too_many_threads_are_refused_at_once_naming_the_flag_and_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    for threads in ["100000", "20000", "1000000000000"] {
        let out = retrace_within(
            &["--threads", threads, "render", "-o", "out.png"],
            dir.path(),
            Duration::from_secs(5),
        );
        assert_error(
            &out,
            &[&format!("--threads {threads}"), "at most", "worker threads"],
        );
        // After the subcommand too: the flag is global.
        let out = retrace_within(
            &["render", "--threads", threads, "-o", "out.png"],
            dir.path(),
            Duration::from_secs(5),
        );
        assert_error(&out, &[&format!("--threads {threads}")]);
        assert!(!dir.path().join("out.png").exists(), "rendered anyway");
    }
    // The floor of the limit runs on any machine, and 0 is taken as 1.
    for threads in ["256", "0"] {
        let out = retrace_within(
            &[
                "--threads",
                threads,
                "render",
                "--width",
                "16",
                "--height",
                "12",
                "-o",
                "out.png",
            ],
            dir.path(),
            Duration::from_secs(60),
        );
        assert!(
            out.status.success(),
            "--threads {threads}: {}",
            stderr(&out)
        );
    }
    // A count that is not one is a usage error, without clap's hint to
    // write `-- -1` (which would not work either).
    let out = retrace(&["render", "--threads", "-1"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("'-1' is not a number of threads"),
        "{}",
        stderr(&out)
    );
    assert!(!stderr(&out).contains("-- -1"), "{}", stderr(&out));
    let help = stdout(&retrace(&["render", "--help"], dir.path()));
    assert!(help.contains("0 is taken as 1"), "{help}");
}

#[test]
fn threads_the_system_will_not_start_are_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    // 400 MB of address space, and a stack of 512 MiB a thread: the first
    // worker cannot start, so none runs short of memory after it started
    // (glibc aborts a thread that cannot register its destructors). The
    // pool is set up before anything else.
    let out = Command::new("sh")
        .args(["-c", "ulimit -v 400000 && exec \"$0\" \"$@\""])
        .arg(env!("CARGO_BIN_EXE_retrace"))
        .args(["--threads", "256", "render", "-o", "out.png"])
        .env("RUST_MIN_STACK", (512u64 << 20).to_string())
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_error(
        &out,
        &["--threads 256", "would not start that many worker threads"],
    );
}

/// Output paths no one may write, as root too (the tests run as root,
/// whom permissions do not stop): a folder that cannot be made, one that
/// takes no files, and a read-only folder when permissions do bind.
fn unwritable_outputs(dir: &Path) -> Vec<(String, String)> {
    let mut outputs = vec![
        (
            "/proc/forbidden/x.png".to_string(),
            "/proc/forbidden".to_string(),
        ),
        ("/proc/x.png".to_string(), "/proc".to_string()),
    ];
    use std::os::unix::fs::PermissionsExt as _;
    let read_only = dir.join("read-only");
    std::fs::create_dir(&read_only).unwrap();
    std::fs::set_permissions(&read_only, std::fs::Permissions::from_mode(0o555)).unwrap();
    if std::fs::write(read_only.join("probe"), b"").is_err() {
        let folder = read_only.to_string_lossy().into_owned();
        outputs.push((format!("{folder}/x.png"), folder.clone()));
        outputs.push((format!("{folder}/sub/x.png"), format!("{folder}/sub")));
    }
    outputs
}

#[test]
fn render_refuses_an_unwritable_output_folder_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    for (output, folder) in unwritable_outputs(dir.path()) {
        // About 25 CPU-seconds of rendering: refused long before.
        let out = retrace_within(
            &[
                "render", "--spp", "256", "--width", "1280", "--height", "960", "-o", &output,
            ],
            dir.path(),
            Duration::from_secs(5),
        );
        assert_error(&out, &[&folder]);
        assert!(
            stderr(&out).contains("output folder"),
            "{output}: {}",
            stderr(&out)
        );
        // Before the scene is even read: a broken scene is not what is
        // reported.
        std::fs::write(dir.path().join("broken.toml"), "[camera\n").unwrap();
        let out = retrace(&["render", "broken.toml", "-o", &output], dir.path());
        assert_error(&out, &[&folder, "output folder"]);
    }
    // A folder that is not there yet is still made, and written.
    let out = retrace(
        &[
            "render",
            "--width",
            "16",
            "--height",
            "12",
            "-o",
            "new/sub/x.png",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(dir.path().join("new/sub/x.png").exists());
    let probes: Vec<_> = std::fs::read_dir(dir.path().join("new/sub"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|name| name.to_string_lossy().starts_with(".retrace-probe"))
        .collect();
    assert!(probes.is_empty(), "probe files left: {probes:?}");
}

#[test]
fn negative_and_malformed_frame_ranges_get_our_error_not_a_dash_dash_hint() {
    let dir = tempfile::tempdir().unwrap();
    let runs: [&[&str]; 4] = [
        &["animate", "--frames", "-3", "-o", "out/f_#.png"],
        &["animate", "-o", "out/f_#.png", "--frames=-3"],
        &["animate", "--frames", "2--1", "-o", "out/f_#.png"],
        &["tradeoff", "--frames", "-3", "--out", "o"],
    ];
    for args in runs {
        let out = retrace(args, dir.path());
        assert_error(&out, &["--frames", "numbered from 0"]);
        assert!(!stderr(&out).contains("-- -"), "{args:?}: {}", stderr(&out));
        assert!(!dir.path().join("o").exists(), "{args:?}: output written");
    }
    // A flag where the range should be is a usage error, named.
    let out = retrace(&["animate", "--frames", "--gif", "a.gif"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("'--gif' is a flag, not a frame range"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn camera_help_and_errors_list_the_projections() {
    let dir = tempfile::tempdir().unwrap();
    let values = "[possible values: perspective, equal-angle, fisheye]";
    for command in ["render", "animate", "view", "validate", "bench", "tradeoff"] {
        let help = stdout(&retrace(&[command, "--help"], dir.path()));
        let camera = help
            .split("--camera <CAMERA>")
            .nth(1)
            .unwrap_or_else(|| panic!("{command} --help has no --camera: {help}"));
        let camera = camera.split("\n      --").next().unwrap();
        assert!(camera.contains(values), "{command}: {camera}");
    }
    let out = retrace(&["render", "--camera", "pinhole"], dir.path());
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains(values), "{}", stderr(&out));
}

#[test]
fn width_help_speaks_of_its_own_command() {
    let dir = tempfile::tempdir().unwrap();
    let width_help = |command: &str| {
        let help = stdout(&retrace(&[command, "--help"], dir.path()));
        let width = help
            .split("--width <WIDTH>")
            .nth(1)
            .unwrap_or_else(|| panic!("{command} --help has no --width: {help}"));
        width.split("\n      --").next().unwrap().to_string()
    };
    for command in ["render", "animate", "view", "validate", "tradeoff"] {
        let help = width_help(command);
        assert!(!help.contains("bench"), "{command} --width: {help}");
        assert!(help.contains("viewports keep their own sizes"), "{help}");
    }
    let help = width_help("bench");
    assert!(!help.contains("`bench`"), "bench --width: {help}");
    assert!(help.contains("each RSVP viewport's too"), "{help}");
}

#[test]
fn usage_errors_exit_2_other_errors_1_as_the_guide_says() {
    let dir = tempfile::tempdir().unwrap();
    let usage: [&[&str]; 4] = [
        &["render", "--no-such-flag"],
        &["no-such-command"],
        &["render", "--width", "wide"],
        &["render", "--camera", "pinhole"],
    ];
    for args in usage {
        let out = retrace(args, dir.path());
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("--help"),
            "{args:?}: {}",
            stderr(&out)
        );
    }
    let errors: [&[&str]; 3] = [
        &["render", "-o", "out.jpg"],
        &["--threads", "100000", "render"],
        &["render", "--width", "0"],
    ];
    for args in errors {
        let out = retrace_within(args, dir.path(), Duration::from_secs(5));
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).starts_with("error: "), "{}", stderr(&out));
    }
    let guide =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/GUIDE.md"))
            .unwrap();
    let errors = guide
        .split("## Errors, exit status and signals")
        .nth(1)
        .expect("the guide's errors section")
        .split("\n## ")
        .next()
        .unwrap();
    for rule in ["Status 2", "usage error", "Status 1"] {
        assert!(errors.contains(rule), "the guide does not say '{rule}'");
    }
}
