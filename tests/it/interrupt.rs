//! Ctrl-C, or a scheduler's SIGTERM, in the middle of `retrace animate`:
//! only whole files stay, and what the run says it kept, the statistics it
//! saves and the frame files on disk are the same frames, whenever the
//! signal comes; the command it prints to resume renders exactly the
//! missing frames, and the statistics then cover every frame.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;
use proptest::prelude::*;

/// Starts `retrace animate` on the shipped `scene` with `args`, in `dir`.
fn spawn_animate(dir: &Path, scene: &str, args: &[&str]) -> std::process::Child {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(scene);
    Command::new(env!("CARGO_BIN_EXE_retrace"))
        .arg("animate")
        .arg(scene)
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Sends `signal` to `child` (which may have ended already) and waits.
fn stop(child: std::process::Child, signal: Signal) -> Output {
    // No `kill` program needed: minimal systems lack one.
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    let _ = nix::sys::signal::kill(pid, signal);
    child.wait_with_output().unwrap()
}

/// The names of the files in `folder`, none if it is missing.
fn names(folder: &Path) -> Vec<String> {
    std::fs::read_dir(folder)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// The frames whose files `out/f_####.png` are in `dir`, in order.
fn frame_files(dir: &Path) -> Vec<u32> {
    let mut frames: Vec<u32> = names(&dir.join("out"))
        .iter()
        .filter_map(|n| n.strip_prefix("f_")?.strip_suffix(".png")?.parse().ok())
        .collect();
    frames.sort_unstable();
    frames
}

/// The frame of each row of the statistics file at `path` (CSV or JSON),
/// in the file's order; None if there is no file.
fn stats_frames(path: &Path) -> Option<Vec<u32>> {
    let text = std::fs::read_to_string(path).ok()?;
    let frames = if path.extension().is_some_and(|e| e == "json") {
        let rows: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
        rows.iter()
            .map(|row| row["frame"].as_u64().unwrap() as u32)
            .collect()
    } else {
        retrace::output::csv_records(&text)[1..]
            .iter()
            .map(|record| record.split(',').next().unwrap().parse().unwrap())
            .collect()
    };
    Some(frames)
}

/// The number of frames an interrupted run says it kept.
fn kept(said: &str) -> Option<u32> {
    let line = said.lines().find(|l| l.contains("of this run kept"))?;
    Some(line.split(' ').next().unwrap().parse().unwrap())
}

/// The command an interrupted run says resumes it.
fn resume_command(said: &str) -> Option<String> {
    let mut lines = said.lines().skip_while(|l| !l.contains("resume with:"));
    Some(lines.nth(1)?.trim().to_string())
}

#[test]
fn an_interrupted_run_leaves_finished_files_only() {
    // As Ctrl-C does.
    stop_leaves_finished_files_only(Signal::SIGINT);
}

#[test]
fn a_terminated_run_leaves_finished_files_only() {
    // As a batch scheduler's cancel (Slurm's scancel, Kubernetes) does.
    stop_leaves_finished_files_only(Signal::SIGTERM);
}

fn stop_leaves_finished_files_only(signal: Signal) {
    let dir = tempfile::tempdir().unwrap();
    let mut child = spawn_animate(
        dir.path(),
        "paper-bounce.toml",
        &[
            "--width",
            "320",
            "--height",
            "240",
            "-o",
            "out/f_####.png",
            "--gif",
            "out/a.gif",
            "--stats",
            "stats/s.csv",
        ],
    );
    let out = dir.path().join("out");
    // Interrupt once a few frames are out and the GIF is being written.
    let start = Instant::now();
    while frame_files(dir.path()).len() < 3 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the interrupt"
        );
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no frames written"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        names(&out).iter().any(|n| n.ends_with(".tmp")),
        "{:?}",
        names(&out)
    );
    let result = stop(child, signal);
    let err = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    let left = names(&out);
    assert!(!left.iter().any(|n| n.ends_with(".tmp")), "{left:?}");
    assert!(!left.contains(&"a.gif".to_string()), "{left:?}");
    // Every frame that is there is whole, and counted, with its
    // statistics.
    for name in &left {
        image::open(out.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    assert!(err.contains("finished frames of this run kept"), "{err}");
    let frames = frame_files(dir.path());
    assert_eq!(kept(&err), Some(frames.len() as u32), "{err}");
    assert_eq!(
        stats_frames(&dir.path().join("stats/s.csv")),
        Some(frames),
        "{err}"
    );
    let resume = resume_command(&err).unwrap_or_else(|| panic!("no resume command: {err}"));
    assert!(resume.ends_with("--skip-existing"), "{resume}");
    // The command it gives finishes the run (its first frames, for speed).
    let resumed = Command::new("sh")
        .arg("-c")
        .arg(format!("{resume} --frames 0-5"))
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    assert_eq!(frame_files(dir.path()), (0..6).collect::<Vec<_>>());
}

/// The frames of the interrupted runs below: at 320x240 about 0.8 s on
/// one core of a debug build, half of it writing the frames and the GIF.
const FRAMES: u32 = 20;

/// Interrupts `retrace animate` with a GIF and statistics (`stats`: csv or
/// json) after `delay`, then resumes it as it says, checking that the
/// frames it says it kept, the rows it saved and the files on disk are
/// the same frames, and that the resumed run completes all three.
fn interrupt_and_resume(delay: Duration, stats: &str) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stats_file = format!("out/s.{stats}");
    let last = (FRAMES - 1).to_string();
    let args = [
        "--width",
        "320",
        "--height",
        "240",
        "--frames",
        &format!("0-{last}"),
        "-o",
        "out/f_####.png",
        "--gif",
        "out/a.gif",
        "--stats",
        &stats_file,
    ];
    let child = spawn_animate(d, "paper-bounce.toml", &args);
    std::thread::sleep(delay);
    let result = stop(child, Signal::SIGINT);
    let said = String::from_utf8_lossy(&result.stderr).into_owned();
    let on_disk = frame_files(d);
    let rows = stats_frames(&d.join(&stats_file));
    assert!(
        !names(&d.join("out")).iter().any(|n| n.ends_with(".tmp")),
        "{said}"
    );
    let all: Vec<u32> = (0..FRAMES).collect();
    let resume = match result.status.code() {
        // Done before the signal.
        Some(0) => {
            assert_eq!((on_disk, rows), (all.clone(), Some(all.clone())));
            return;
        }
        Some(130) => match kept(&said) {
            Some(count) => {
                let counted: Vec<u32> = (0..count).collect();
                assert_eq!(on_disk, counted, "frame files against what it said: {said}");
                let rows = rows.unwrap_or_default();
                assert_eq!(rows, counted, "statistics against what it said: {said}");
                resume_command(&said).unwrap_or_else(|| panic!("no resume command: {said}"))
            }
            // Stopped while loading, before it could count anything.
            None => {
                assert_eq!((on_disk.len(), rows), (0, None), "{said}");
                return;
            }
        },
        // Killed before its handler was in place: nothing written yet.
        None => {
            assert_eq!((on_disk.len(), rows), (0, None), "{said}");
            return;
        }
        Some(code) => panic!("exit status {code}: {said}"),
    };
    let resumed = Command::new("sh")
        .arg("-c")
        .arg(&resume)
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{resume}: {err}");
    assert_eq!(frame_files(d), all, "{err}");
    assert_eq!(stats_frames(&d.join(&stats_file)), Some(all), "{err}");
    assert!(d.join("out/a.gif").is_file());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(crate::common::cases(6)))]

    #[test]
    fn what_an_interrupt_counts_saves_and_leaves_agree(
        delay_ms in 0u64..1000,
        json in any::<bool>(),
    ) {
        interrupt_and_resume(Duration::from_millis(delay_ms), if json { "json" } else { "csv" });
    }
}
