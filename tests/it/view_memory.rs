//! `retrace view --sample-memory`: a long scripted zoom about many points
//! keeps the samples it keeps within the cap, and the process within the
//! cap and what it needs besides.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// The cap asked for, in MB.
const CAP_MB: u64 = 8;

/// What the viewer of the paper scene at 160x120 takes besides the samples
/// it keeps, with room to spare: the program, the scene, Embree, the
/// threads and pictures took 24 MB measured. (The same zoom without a cap
/// keeps 38 MB of samples and peaks at 64 MB.)
const BESIDES_MB: u64 = 40;

/// Twelve cycles of 30 steps in and 35 out (two notches each, every
/// picture waited for) about points spread over a 160x120 picture, then
/// a pause that keeps the process alive while its peak is read.
fn long_zoom() -> String {
    let mut script = String::new();
    for cycle in 0..12u32 {
        let (x, y) = (7 + cycle * 37 % 150, 5 + cycle * 29 % 110);
        script += &format!("wheel 2 {x} {y}\nwait\n").repeat(30);
        script += &format!("wheel -2 {x} {y}\nwait\n").repeat(35);
    }
    script + "sleep 300\n"
}

/// The peak resident memory of process `pid` so far, in kB (None once it
/// has gone).
fn peak_kb(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
    line.trim().strip_suffix("kB")?.trim().parse().ok()
}

#[test]
fn a_long_zoom_keeps_its_samples_within_the_cap() {
    let dir = tempfile::tempdir().unwrap();
    let path: &Path = dir.path();
    std::fs::write(path.join("zoom.txt"), long_zoom()).unwrap();
    let cap = CAP_MB.to_string();
    let mut child = Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args([
            "view",
            "--width",
            "160",
            "--height",
            "120",
            "--refine-spp",
            "1",
        ])
        .args([
            "--sample-memory",
            &cap,
            "--script",
            "zoom.txt",
            "--stats",
            "stats.csv",
        ])
        .current_dir(path)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The high-water mark only grows: its last reading is the peak, the
    // script's closing pause long after its last picture.
    let mut peak = 0;
    while child.try_wait().unwrap().is_none() {
        peak = peak_kb(child.id()).unwrap_or(peak).max(peak);
        std::thread::sleep(Duration::from_millis(20));
    }
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let text = std::fs::read_to_string(path.join("stats.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (kept, evicted) = (
        column("picture.kept_bytes"),
        column("picture.samples_evicted"),
    );
    let cell =
        |line: &str, at: usize| -> u64 { line.split(',').nth(at).unwrap().parse().unwrap_or(0) };
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert!(rows.len() > 500, "{} rows", rows.len());
    let cap_bytes = CAP_MB << 20;
    let most = rows.iter().map(|row| cell(row, kept)).max().unwrap();
    assert!(
        most <= cap_bytes,
        "{most} bytes kept, over the cap of {cap_bytes}"
    );
    // The cap was reached, and kept to by evicting.
    assert!(
        most > cap_bytes / 2,
        "only {most} bytes kept: the cap was never near"
    );
    assert!(rows.iter().map(|row| cell(row, evicted)).sum::<u64>() > 0);
    assert!(peak > 0, "no peak read");
    assert!(
        peak <= (CAP_MB + BESIDES_MB) << 10,
        "peak resident memory {peak} kB, over {CAP_MB} + {BESIDES_MB} MB"
    );
}
