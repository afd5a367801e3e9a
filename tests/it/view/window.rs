//! The window under Xvfb, driven by xdotool: what it shows against
//! `retrace render`, and its errors.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::{
    args, differing, paper_on_lattice, png, psnr, scene_and_turned, ON_LATTICE_PITCH, STEP,
};
use crate::common::retrace_ok;

#[test]
fn without_a_display_the_window_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args(["view"])
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot open a window: DISPLAY is not set"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// Whether the window tests can run: Xvfb, xdotool and ImageMagick's
/// `import`. Missing, they are skipped with the reason, except under
/// CI, where they must run.
pub(super) fn window_tools() -> bool {
    let missing: Vec<&str> = ["Xvfb", "xdotool", "import"]
        .into_iter()
        .filter(|tool| {
            Command::new("sh")
                .args(["-c", &format!("command -v {tool}")])
                .output()
                .map_or(true, |o| !o.status.success())
        })
        .collect();
    if missing.is_empty() {
        return true;
    }
    let why = format!(
        "window tests need {} (make test installs xvfb xdotool imagemagick)",
        missing.join(", ")
    );
    crate::common::skip_unless_ci(&why);
    false
}

/// An X server of its own, stopped when dropped.
pub(super) struct Xvfb {
    child: Child,
    pub(super) display: String,
}

impl Xvfb {
    pub(super) fn start() -> Xvfb {
        // -displayfd: Xvfb picks a free display and says which once it is
        // ready, so tests run side by side.
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1024x768x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start Xvfb");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let number: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb said '{line}', not a display"));
        Xvfb {
            child,
            display: format!(":{number}"),
        }
    }

    /// Stops the X server now, as a crash or a logout would.
    pub(super) fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// The viewer's window, once it is there.
    pub(super) fn window(&self) -> String {
        let found = self.run("xdotool", &["search", "--sync", "--name", "^retrace view"]);
        found.lines().next().unwrap().to_string()
    }

    /// A drag with the left button in `window` through `points` (its
    /// coordinates), pressed at the first and released at the last.
    pub(super) fn drag(&self, window: &str, points: &[(i32, i32)]) {
        let mut args: Vec<String> = Vec::new();
        for (i, (x, y)) in points.iter().enumerate() {
            args.extend(["mousemove", "--window", window, "--sync"].map(String::from));
            args.extend([x.to_string(), y.to_string()]);
            if i == 0 {
                args.extend(["mousedown", "1"].map(String::from));
            }
        }
        args.extend(["mouseup", "1"].map(String::from));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        self.run("xdotool", &args);
    }

    /// One click of the wheel in (button 4) at (`x`, `y`) of `window`.
    pub(super) fn wheel_in_at(&self, window: &str, x: i32, y: i32) {
        let (x, y) = (x.to_string(), y.to_string());
        self.run(
            "xdotool",
            &[
                "mousemove",
                "--window",
                window,
                "--sync",
                &x,
                &y,
                "click",
                "4",
            ],
        );
    }

    pub(super) fn run(&self, program: &str, args: &[&str]) -> String {
        let out = Command::new("timeout")
            .arg("20")
            .arg(program)
            .args(args)
            .env("DISPLAY", &self.display)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{program} {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    pub(super) fn screenshot(&self, window: &str, (width, height): (u32, u32)) -> image::RgbImage {
        let out = Command::new("import")
            .args(["-window", window, "-depth", "8", "rgb:-"])
            .env("DISPLAY", &self.display)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        image::RgbImage::from_raw(width, height, out.stdout).expect("a screenshot of the window")
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `retrace view` in a window, its picture lines read as they come.
pub(super) struct Viewer {
    child: Child,
    lines: mpsc::Receiver<String>,
    pub(super) seen: Vec<String>,
}

impl Viewer {
    /// The window on `scene`, refining idle pictures up to `refine_spp`
    /// samples a pixel ("1": the frame loop's pictures only).
    pub(super) fn open(x: &Xvfb, dir: &Path, scene: &str, refine_spp: &str) -> Viewer {
        Viewer::open_with(x, dir, scene, &["--refine-spp", refine_spp])
    }

    /// The window on `scene` at 320x240 with flags `more`.
    pub(super) fn open_with(x: &Xvfb, dir: &Path, scene: &str, more: &[&str]) -> Viewer {
        let flags: Vec<&str> = ["--print-pictures", "--save-dir", "saved"]
            .iter()
            .chain(more)
            .copied()
            .collect();
        let mut child = Command::new(env!("CARGO_BIN_EXE_retrace"))
            .args(args(&["view", scene], &flags))
            .current_dir(dir)
            .env("DISPLAY", &x.display)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = child.stdout.take().unwrap();
        let (send, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                if send.send(line.unwrap()).is_err() {
                    break;
                }
            }
        });
        Viewer {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Waits (at most 30 s) for a line the program prints that `wanted`
    /// accepts.
    pub(super) fn wait_for(&mut self, what: &str, wanted: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if wanted(&line) {
                        return line;
                    }
                }
                Err(_) => panic!("no {what}; the viewer said:\n{}", self.seen.join("\n")),
            }
        }
    }

    /// Waits (at most 30 s) for the program to end; its exit code and
    /// stderr.
    pub(super) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Presses `q` in the window and waits for the program to end well.
    pub(super) fn quit(self, x: &Xvfb) {
        x.run("xdotool", &["key", "q"]);
        let (code, err) = self.wait_exit();
        assert_eq!(code, Some(0), "{err}");
    }

    pub(super) fn wait_exit(mut self) -> (Option<i32>, String) {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let mut err = String::new();
                self.child
                    .stderr
                    .take()
                    .unwrap()
                    .read_to_string(&mut err)
                    .unwrap();
                return (status.code(), err);
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                panic!("the viewer did not end; it said:\n{}", self.seen.join("\n"));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A field of a picture line: `... yaw 7.500000 ...` -> "7.500000".
pub(super) fn field<'a>(line: &'a str, name: &str) -> &'a str {
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words
        .windows(2)
        .position(|w| w[0] == name)
        .unwrap_or_else(|| panic!("no {name} in '{line}'"));
    words[at + 1]
}

#[test]
fn the_window_pans_exactly_zooms_about_the_cursor_and_quits_on_q() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    scene_and_turned(path);
    retrace_ok(&args(&["render", "scene.toml"], &["-o", "open.png"]), path);
    retrace_ok(
        &args(&["render", "turned.toml"], &["-o", "turned.png"]),
        path,
    );
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, "scene.toml", "1");
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    let window = x.run("xdotool", &["search", "--sync", "--name", "^retrace view"]);
    let window = window.lines().next().unwrap().to_string();
    let size = (320, 240);
    let before = x.screenshot(&window, size);
    assert!(
        differing(&before, &png(&path.join("open.png"))) == 0,
        "the opened window"
    );

    // A drag of 24 pixels left and 8 down, in two moves.
    x.drag(&window, &[(200, 100), (190, 104), (176, 108)]);
    let yaw = format!("{:.6}", 24.0 * STEP);
    viewer.wait_for("the dragged picture", |l| {
        l.starts_with("picture") && field(l, "yaw") == yaw && field(l, "pitch") == "2.500000"
    });
    let after = x.screenshot(&window, size);
    assert!(
        differing(&after, &png(&path.join("turned.png"))) == 0,
        "the dragged window differs from a render of the turned camera"
    );
    // Moved by the drag, pixel for pixel: what was at (x + 24, y - 8) is
    // now at (x, y).
    for y in 8..240 {
        for x in 0..320 - 24 {
            assert_eq!(
                after.get_pixel(x, y),
                before.get_pixel(x + 24, y - 8),
                "({x}, {y})"
            );
        }
    }

    // The wheel in, at (60, 50): one click, one notch.
    x.wheel_in_at(&window, 60, 50);
    let last = viewer.wait_for("a zoomed picture", |l| {
        l.starts_with("picture") && field(l, "notches") == "1"
    });
    assert_eq!(field(&last, "mode"), "rsvp", "{last}");
    let zoomed = x.screenshot(&window, size);
    assert!(
        psnr(&zoomed, &after) < 30.0,
        "the wheel barely changed the picture"
    );
    // The window's picture is the frame loop's for the same input, as a
    // script gives it without X.
    let script = "drag -10 4\ndrag -14 4\nwheel 1 60 50\nsave scripted.png\n";
    std::fs::write(path.join("same.txt"), script).unwrap();
    retrace_ok(
        &args(
            &["view", "scene.toml"],
            &["--script", "same.txt", "--refine-spp", "1"],
        ),
        path,
    );
    assert!(
        differing(&zoomed, &png(&path.join("scripted.png"))) == 0,
        "the zoomed window differs from the scripted zoom"
    );

    // `s` saves, `q` quits with 0.
    x.run("xdotool", &["key", "s"]);
    viewer.wait_for("the save", |l| l.starts_with("saved "));
    x.run("xdotool", &["key", "q"]);
    let (code, err) = viewer.wait_exit();
    assert_eq!(code, Some(0), "{err}");
    assert!(differing(&png(&path.join("saved/view_0001.png")), &zoomed) == 0);
}

#[test]
fn a_missing_xkbcommon_x11_is_a_clear_error() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // An empty file where the loader looks first: the library cannot load.
    let fake = dir.path().join("lib");
    std::fs::create_dir(&fake).unwrap();
    std::fs::write(fake.join("libxkbcommon-x11.so.0"), b"").unwrap();
    std::fs::write(fake.join("libxkbcommon-x11.so"), b"").unwrap();
    let x = Xvfb::start();
    let out = Command::new("timeout")
        .arg("20")
        .arg(env!("CARGO_BIN_EXE_retrace"))
        .arg("view")
        .current_dir(dir.path())
        .env("DISPLAY", &x.display)
        .env("LD_LIBRARY_PATH", &fake)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot open a window") && err.contains("libxkbcommon-x11"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_resized_window_shows_more_at_the_same_angle_per_pixel() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    // Twice as wide keeps 0.3125 degrees a pixel: 200 degrees across
    // (doubling is exact in floating point, so the fields of view agree
    // to the bit).
    retrace_ok(
        &[
            "render",
            "scene.toml",
            "--width",
            "640",
            "--height",
            "360",
            "--fov",
            "200",
            "-o",
            "wide.png",
        ],
        path,
    );
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, "scene.toml", "1");
    viewer.wait_for("first picture", |l| l.starts_with("picture 1:"));
    let window = x.run("xdotool", &["search", "--sync", "--name", "^retrace view"]);
    let window = window.lines().next().unwrap().to_string();
    x.run("xdotool", &["windowsize", "--sync", &window, "640", "360"]);
    viewer.wait_for("the resized picture", |l| {
        l.starts_with("picture") && field(l, "size") == "640x360"
    });
    let wide = x.screenshot(&window, (640, 360));
    assert!(
        differing(&wide, &png(&path.join("wide.png"))) == 0,
        "the resized window differs from a render at its size"
    );
    // A drag after the resize is still a pan of the wider camera.
    x.drag(&window, &[(300, 100), (276, 100)]);
    let yaw = format!("{:.6}", 24.0 * STEP);
    let line = viewer.wait_for("the dragged picture", |l| {
        l.starts_with("picture") && field(l, "yaw") == yaw
    });
    assert_eq!(field(&line, "mode"), "pan", "{line}");
    assert_eq!(field(&line, "size"), "640x360", "{line}");
    viewer.quit(&x);
}

#[test]
fn the_window_refines_an_idle_picture_and_shows_its_samples_a_pixel() {
    if !window_tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    retrace_ok(
        &args(
            &["render", "scene.toml"],
            &["--spp", "16", "-o", "open16.png"],
        ),
        path,
    );
    let x = Xvfb::start();
    let mut viewer = Viewer::open(&x, path, "scene.toml", "16");
    let line = viewer.wait_for("the converged picture", |l| {
        l.starts_with("picture 1:") && field(l, "mode") == "refine" && field(l, "spp") == "16"
    });
    // The title says how many samples a pixel the shown picture has.
    assert!(line.contains("| 16 spp |"), "{line}");
    let rungs: Vec<&str> = viewer
        .seen
        .iter()
        .filter(|l| l.starts_with("picture 1:"))
        .map(|l| field(l, "spp"))
        .collect();
    assert_eq!(rungs.first(), Some(&"1"), "{:?}", viewer.seen);
    let window = x.run("xdotool", &["search", "--sync", "--name", "^retrace view"]);
    let window = window.lines().next().unwrap().to_string();
    assert!(
        differing(
            &x.screenshot(&window, (320, 240)),
            &png(&path.join("open16.png"))
        ) == 0,
        "the converged window differs from a 16-spp render"
    );
    viewer.quit(&x);
}
