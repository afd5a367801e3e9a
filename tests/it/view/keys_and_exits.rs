//! The window's keys, wheel and focus, and every way it ends, under Xvfb
//! (no window manager) driven by xdotool.

use std::path::Path;

use super::window::{field, window_tools, Viewer, Xvfb};
use super::{differing, paper_on_lattice, png, stats_rows, ON_LATTICE_PITCH};

/// The paper scene on the pan lattice, in `dir`, and the flags that make
/// the window keep statistics there.
fn scene(dir: &Path) -> &'static str {
    paper_on_lattice(dir, "scene.toml", 0.0, ON_LATTICE_PITCH);
    "scene.toml"
}

const STATS: [&str; 4] = ["--refine-spp", "1", "--stats", "stats.csv"];

/// The statistics the window wrote: one row per picture, the first the
/// opening's.
fn assert_stats_written(dir: &Path, err: &str) {
    assert!(dir.join("stats.csv").exists(), "no statistics; {err}");
    let (stats, rows) = stats_rows(&dir.join("stats.csv"));
    assert!(!rows.is_empty(), "{stats}");
    assert_eq!(rows[0]["event"], "picture 1", "{stats}");
}

#[test]
fn a_destroyed_window_ends_the_program_with_its_statistics_written() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    let x = Xvfb::start();
    let mut viewer = Viewer::open_with(&x, path, scene(path), &STATS);
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    x.run("xdotool", &["windowclose", &x.window()]);
    let (code, err) = viewer.wait_exit();
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("view ended: the window was destroyed"),
        "{err}"
    );
    // The keys were listed when the window opened.
    assert!(err.contains("keys:") && err.contains("h ? F1"), "{err}");
    assert_stats_written(path, &err);
}

#[test]
fn an_interrupt_ends_the_window_with_its_statistics_written() {
    use nix::sys::signal::{kill, Signal};
    if !window_tools() {
        return;
    }
    let x = Xvfb::start();
    for signal in [Signal::SIGTERM, Signal::SIGINT, Signal::SIGHUP] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path();
        let mut viewer = Viewer::open_with(&x, path, scene(path), &STATS);
        viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
        let pid = nix::unistd::Pid::from_raw(viewer.pid() as i32);
        kill(pid, signal).unwrap();
        let (code, err) = viewer.wait_exit();
        assert_eq!(code, Some(130), "{signal}: {err}");
        assert!(err.contains("interrupted"), "{signal}: {err}");
        assert_stats_written(path, &err);
    }
}

#[test]
fn losing_the_x_server_is_an_error_with_the_statistics_written() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    let mut x = Xvfb::start();
    let mut viewer = Viewer::open_with(&x, path, scene(path), &STATS);
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    x.stop();
    let (code, err) = viewer.wait_exit();
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("error: lost the connection to the X server"),
        "{err}"
    );
    assert_stats_written(path, &err);
}

#[test]
fn one_wheel_click_is_one_notch() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, scene(path), "1");
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    let window = x.window();
    // After each click, `h` (taken after the click's press and release,
    // X keeping their order) says the view the window asks for.
    for (notches, help) in [("1", "on"), ("2", "off")] {
        x.wheel_in_at(&window, 60, 50);
        x.run("xdotool", &["key", "h"]);
        let line = viewer.wait_for("the help toggled", |l| {
            l.starts_with("shown picture") && field(l, "help") == help
        });
        assert_eq!(field(&line, "notches"), notches, "{line}");
    }
    // Far out, the wheel stops at the zoom limit, and the title says so.
    x.run("xdotool", &["click", "--repeat", "40", "--delay", "5", "5"]);
    x.run("xdotool", &["key", "h"]);
    let line = viewer.wait_for("the help toggled", |l| {
        l.starts_with("shown picture") && field(l, "help") == "on"
    });
    let notches: i32 = field(&line, "notches").parse().unwrap();
    assert!(notches < 0 && notches > -40, "{line}");
    let title = x.run("xdotool", &["getwindowname", &window]);
    assert!(title.contains("(the limit)"), "{title}");
    viewer.quit(&x);
}

#[test]
fn keys_need_no_focusing_and_the_help_and_reset_work() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, scene(path), "1");
    let first = viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    // Its coarse picture came just before: the title says how fast
    // pictures came.
    let rate: f64 = first
        .split(" | ")
        .find_map(|part| part.strip_suffix(" fps"))
        .unwrap_or_else(|| panic!("no fps in '{first}'"))
        .parse()
        .unwrap();
    assert!(rate > 1.0, "{first}");
    let window = x.window();
    let size = (320, 240);
    let opening = x.screenshot(&window, size);
    // No `xdotool windowfocus`, no pointer over the window: with no window
    // manager the window took the focus itself.
    x.run("xdotool", &["key", "h"]);
    viewer.wait_for("the help", |l| {
        l.starts_with("shown picture 1:") && field(l, "help") == "on"
    });
    let help = x.screenshot(&window, size);
    if let Ok(folder) = std::env::var("RETRACE_SCREENSHOTS") {
        help.save(Path::new(&folder).join("help.png")).unwrap();
    }
    // Drawn over the top-left corner; the rest of the picture as it was.
    let changed = differing(&help, &opening);
    assert!(changed > 320 * 240 / 8, "{changed} pixels changed");
    assert_eq!(help.get_pixel(319, 239), opening.get_pixel(319, 239));
    x.run("xdotool", &["key", "question"]);
    viewer.wait_for("the help gone", |l| {
        l.starts_with("shown picture 1:") && field(l, "help") == "off"
    });
    assert!(differing(&x.screenshot(&window, size), &opening) == 0);
    // A pan, then `r`: the opening view again, exactly.
    x.run("xdotool", &["key", "Left"]);
    viewer.wait_for("the pan", |l| {
        l.starts_with("picture 2:") && field(l, "yaw") == "-10.000000"
    });
    x.run("xdotool", &["key", "r"]);
    viewer.wait_for("the reset view", |l| {
        l.starts_with("picture 3:") && field(l, "yaw") == "0.000000"
    });
    assert!(differing(&x.screenshot(&window, size), &opening) == 0);
    x.run("xdotool", &["key", "Escape"]);
    let (code, err) = viewer.wait_exit();
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("view ended: q or Escape pressed"), "{err}");
}

#[test]
fn the_overlay_after_refinement_shows_what_the_last_reuse_picture_traced() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    // What the pan traced, as a script saves it.
    std::fs::write(
        path.join("mask.txt"),
        "wait\nkey Left\nkey t\nsave mask.png\n",
    )
    .unwrap();
    crate::common::retrace_ok(
        &super::args(
            &["view", scene(path)],
            &["--script", "mask.txt", "--refine-spp", "1"],
        ),
        path,
    );
    let mask = png(&path.join("mask.png"));
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, "scene.toml", "16");
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    x.run("xdotool", &["key", "Left"]);
    viewer.wait_for("the pan refined", |l| {
        l.starts_with("picture 2:") && field(l, "mode") == "refine" && field(l, "spp") == "16"
    });
    let window = x.window();
    x.run("xdotool", &["key", "t"]);
    viewer.wait_for("the overlay", |l| {
        l.starts_with("shown picture 2:") && field(l, "overlay") == "on"
    });
    let shown = x.screenshot(&window, (320, 240));
    if let Ok(folder) = std::env::var("RETRACE_SCREENSHOTS") {
        shown.save(Path::new(&folder).join("overlay.png")).unwrap();
    }
    assert!(
        differing(&shown, &mask) == 0,
        "the overlay differs from what the pan traced"
    );
    let title = x.run("xdotool", &["getwindowname", &window]);
    assert!(title.contains("t: black where reuse traced"), "{title}");
    viewer.quit(&x);
}

#[test]
fn f_makes_the_window_fullscreen_and_back() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    let x = Xvfb::start();
    // A perspective camera: it can show the whole screen's size.
    let mut viewer = Viewer::open_with(
        &x,
        path,
        scene(path),
        &[
            "--refine-spp",
            "1",
            "--camera",
            "perspective",
            "--fov",
            "60",
        ],
    );
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    x.run("xdotool", &["key", "f"]);
    viewer.wait_for("a fullscreen picture", |l| {
        l.contains("picture") && l.contains(" size 1024x768 ")
    });
    x.run("xdotool", &["key", "F11"]);
    viewer.wait_for("the windowed picture again", |l| {
        l.starts_with("picture") && field(l, "size") == "320x240" && !l.starts_with("picture 1:")
    });
    viewer.quit(&x);
}
