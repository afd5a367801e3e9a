//! The farm without a scheduler: chunk runs assembled into one report,
//! chunking measured, and the chunk size `farm submit` recommends (the
//! real Slurm runs are `make test-farm`).

use crate::common::{retrace, retrace_ok};

fn stderr(output: &std::process::Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// "keep at least N frames a chunk" in a submit's messages.
fn recommended(messages: &str) -> u32 {
    let rest = messages
        .split("keep at least ")
        .nth(1)
        .unwrap_or_else(|| panic!("no recommendation in: {messages}"));
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn submit_recommends_longer_chunks_for_viewports_whose_buffer_restarts_too() {
    let dir = tempfile::tempdir().unwrap();
    let submit = |scene: &str, chunks: &str| {
        let output = retrace_ok(
            &[
                "farm",
                "submit",
                scene,
                "--chunks",
                chunks,
                "--dry-run",
                "-o",
                &dir.path().join("f_###.png").display().to_string(),
            ],
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
        );
        stderr(&output)
    };
    let ball = submit("scenes/paper-bounce.toml", "4");
    let viewports = submit("scenes/paper-all.toml", "4");
    assert!(
        recommended(&viewports) > recommended(&ball),
        "{ball}\n{viewports}"
    );
    // More chunks of the same frames lose more.
    let lost = |messages: &str| -> f64 {
        let before = messages.split("% of the").next().unwrap();
        before.rsplit(' ').next().unwrap().parse().unwrap()
    };
    assert!(lost(&submit("scenes/paper-bounce.toml", "16")) > lost(&ball));
}

#[test]
fn an_assembled_report_says_what_the_runs_restarts_cost() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = dir.path().join("f_###.png").display().to_string();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let common = [
        "scenes/paper-bounce.toml",
        "--width",
        "64",
        "--height",
        "48",
        "--frames",
        "0-7",
        "--chunks",
        "2",
        "-o",
        &pattern,
    ];
    for index in ["0", "1"] {
        let mut args = vec!["animate"];
        args.extend(common);
        args.extend(["--chunk-index", index, "--stats"]);
        let stats = dir.path().join("stats.json").display().to_string();
        args.push(&stats);
        retrace_ok(&args, root);
    }
    let out = dir.path().display().to_string();
    let mut args = vec!["farm", "assemble", "--out", &out];
    args.extend(
        common
            .iter()
            .filter(|a| !["--width", "--height", "64", "48"].contains(a)),
    );
    retrace_ok(&args, root);
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    let line = report
        .lines()
        .find(|l| l.starts_with("Restarts:"))
        .unwrap_or_else(|| panic!("no restart line in:\n{report}"));
    assert!(line.contains("the 1 restarts"), "{line}");
    assert!(dir.path().join("animation.gif").is_file());
    // The MP4 is made where ffmpeg is installed: every frame in it.
    let probe = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args(["-show_entries", "stream=nb_read_frames", "-of", "csv=p=0"])
        .arg(dir.path().join("animation.mp4"))
        .output();
    match probe {
        Ok(probe) => {
            assert!(probe.status.success(), "{}", stderr(&probe));
            assert_eq!(String::from_utf8_lossy(&probe.stdout).trim(), "8");
        }
        Err(_) => eprintln!("no ffprobe: the MP4 is not checked"),
    }
}

#[test]
fn chunking_is_measured_against_one_long_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("chunking");
    let output = retrace_ok(
        &[
            "bench",
            "--only",
            "chunking",
            "scenes/paper-bounce.toml",
            "--width",
            "64",
            "--height",
            "48",
            "--frames",
            "0-5",
            "--chunk-counts",
            "3",
            "--out",
            &out.display().to_string(),
        ],
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
    );
    let printed = String::from_utf8_lossy(&output.stdout);
    // The long run is measured although not asked for.
    assert!(printed.contains("| paper-bounce | 1 | 6 |"), "{printed}");
    assert!(printed.contains("| paper-bounce | 3 | 2 |"), "{printed}");
    let csv = std::fs::read_to_string(out.join("chunking.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    for file in ["report.md", "chunking-cpu.png", "chunking-wall.png"] {
        assert!(out.join(file).is_file(), "{file}");
    }
    let refused = retrace(
        &["bench", "--only", "chunking", "--chunk-counts", "0"],
        dir.path(),
    );
    assert!(!refused.status.success());
    assert!(
        stderr(&refused).contains("--chunk-counts"),
        "{}",
        stderr(&refused)
    );
}
