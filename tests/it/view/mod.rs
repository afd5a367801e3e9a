//! `retrace view`: scripted input against `retrace render` of the view it
//! should show; the window itself under Xvfb, driven by xdotool, in
//! [`window`] and [`keys_and_exits`].

mod keys_and_exits;
mod window;

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::common::{retrace, retrace_ok};

/// The paper scene at 320x240 (its 100-degree field of view: 0.3125
/// degrees a pixel) with the pitch moved from -9 to -9.375 degrees, so
/// that the camera's own image sits exactly on the pan lattice (its top
/// row a whole, even lattice row; at -9 the lattice snaps it by 0.4 of a
/// row): then `retrace render` of a camera turned by a multiple of 4
/// pixels traces the same rays in the same groups as the viewer's pan.
fn paper_on_lattice(dir: &Path, name: &str, yaw: f64, pitch: f64) {
    let text = retrace::scene::BUILTIN_SCENES
        .iter()
        .find(|(file, _)| *file == "paper.toml")
        .unwrap()
        .1;
    assert!(text.contains("\nyaw = 0.0\n") && text.contains("\npitch = -9.0\n"));
    let text = text
        .replace("\nyaw = 0.0\n", &format!("\nyaw = {yaw}\n"))
        .replace("\npitch = -9.0\n", &format!("\npitch = {pitch}\n"));
    std::fs::write(dir.join(name), text).unwrap();
}

/// The pitch that puts the paper scene's image on the pan lattice.
const ON_LATTICE_PITCH: f64 = -9.375;

/// Writes `scene.toml`, the paper scene on the lattice, and `turned.toml`,
/// the same camera after a drag of 24 pixels left and 8 down: the view
/// turned 24 pixels right and 8 up (yaw 7.5, pitch -6.875, both on the
/// lattice's groups).
fn scene_and_turned(dir: &Path) {
    paper_on_lattice(dir, "scene.toml", 0.0, ON_LATTICE_PITCH);
    paper_on_lattice(
        dir,
        "turned.toml",
        24.0 * STEP,
        ON_LATTICE_PITCH + 8.0 * STEP,
    );
}

/// Script lines making the drag [`scene_and_turned`] turns by, in two moves.
const TURNING_DRAG: &str = "drag -10 3\ndrag -14 5\n";

const SMALL: [&str; 4] = ["--width", "320", "--height", "240"];
/// Degrees a pixel at 320 pixels over 100 degrees.
const STEP: f64 = 0.3125;

fn args<'a>(head: &[&'a str], tail: &[&'a str]) -> Vec<&'a str> {
    head.iter()
        .chain(SMALL.iter())
        .chain(tail)
        .copied()
        .collect()
}

/// A viewer's `--stats` CSV: its text, and its rows after the header,
/// each cell by its column's name (no cell here holds a comma).
fn stats_rows(csv: &Path) -> (String, Vec<HashMap<String, String>>) {
    let text = std::fs::read_to_string(csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let rows = text
        .lines()
        .skip(1)
        .map(|l| {
            let cells = l.split(',').map(str::to_owned);
            header.iter().map(|c| c.to_string()).zip(cells).collect()
        })
        .collect();
    (text, rows)
}

/// The paper scene at `width` x `height`.
fn paper_at(width: u32, height: u32) -> retrace::scene::Scene {
    let overrides = retrace::scene::SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..Default::default()
    };
    retrace::scene::paper_scene(&overrides).unwrap()
}

/// Runs the script `text` in this process through a render thread of
/// `scene` (its log kept, refining to `refine_spp`): the thread, the
/// viewer, one row per command and the pictures saved, by path.
fn run_in_process(
    scene: retrace::scene::Scene,
    text: &str,
    refine_spp: u32,
) -> (
    retrace::view::RenderThread,
    retrace::view::Viewer,
    Vec<retrace::view::script::EventStats>,
    Vec<(PathBuf, image::RgbImage)>,
) {
    use retrace::view::script::{parse_script, run_script};
    let view = retrace::view::Viewer::new(&scene);
    let lines = parse_script(text, Path::new("script.txt"), view.size()).unwrap();
    let thread = retrace::view::RenderThread::spawn(
        scene,
        retrace::accel::BackendKind::default(),
        None,
        true,
        refine_spp,
        None,
        Box::new(|| {}),
    )
    .unwrap();
    let mut saved = Vec::new();
    let rows = run_script(
        &thread,
        &view,
        &lines,
        &mut || unreachable!("no key s"),
        &mut |path, image| {
            saved.push((path.to_path_buf(), image.clone()));
            Ok(())
        },
    )
    .unwrap();
    (thread, view, rows, saved)
}

fn png(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

/// Pixels whose bytes differ between two written pictures, as the
/// library's verifier counts them.
fn differing(a: &image::RgbImage, b: &image::RgbImage) -> u64 {
    retrace::verify::written_differences(a, b).expect("same size")
}

fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    retrace::metrics::psnr_8bit(a, b).expect("same size")
}

#[test]
fn a_scripted_drag_equals_a_render_of_the_turned_camera() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    scene_and_turned(path);
    std::fs::write(
        path.join("drag.txt"),
        format!("save open.png\n{TURNING_DRAG}save dragged.png\n"),
    )
    .unwrap();
    let out = retrace_ok(
        &args(
            &["view", "scene.toml"],
            &["--script", "drag.txt", "--stats", "stats.csv"],
        ),
        path,
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("saved dragged.png"));
    retrace_ok(
        &args(&["render", "scene.toml"], &["-o", "open_render.png"]),
        path,
    );
    retrace_ok(
        &args(&["render", "turned.toml"], &["-o", "turned_render.png"]),
        path,
    );
    assert!(
        differing(
            &png(&path.join("open.png")),
            &png(&path.join("open_render.png"))
        ) == 0
    );
    let dragged = png(&path.join("dragged.png"));
    assert!(
        differing(&dragged, &png(&path.join("turned_render.png"))) == 0,
        "the dragged view differs from a render of the turned camera"
    );
    assert!(differing(&dragged, &png(&path.join("open.png"))) > 0);
    // One row per command that asked for a picture: the opening, both
    // drags; the drags were panned, tracing only what came into view.
    let (stats, rows) = stats_rows(&path.join("stats.csv"));
    assert_eq!(rows.len(), 3, "{stats}");
    assert_eq!(rows[0]["event"], "open");
    // The opening starts the buffer from nothing: a coarse picture came
    // first, sooner than the complete one; a pan is complete at once.
    let ms = |row: &HashMap<String, String>, column: &str| row[column].parse::<f64>().unwrap();
    assert!(
        ms(&rows[0], "ms_to_first_picture") < ms(&rows[0], "ms_to_picture"),
        "{stats}"
    );
    for row in &rows[1..] {
        assert_eq!(
            ms(row, "ms_to_first_picture"),
            ms(row, "ms_to_picture"),
            "{stats}"
        );
    }
    for row in &rows[1..] {
        // The frame loop's own record of the picture.
        assert_eq!(row["mode"], "pan", "{stats}");
        assert_eq!(row["picture.mode"], "pan", "{stats}");
        let traced: u64 = row["picture.samples_traced"].parse().unwrap();
        assert!(traced > 0 && traced < 320 * 240 / 4, "{stats}");
        let reused: u64 = row["picture.pixels_reused"].parse().unwrap();
        assert!(reused > 320 * 240 / 2, "{stats}");
    }
}

#[test]
fn a_scripted_zoom_magnifies_about_the_cursor() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    // Four notches in (1.1^4 = 1.4641) about (80, 60), then back out.
    std::fs::write(
        path.join("zoom.txt"),
        "save open.png\nwheel 4 80 60\nsave zoomed.png\nwheel -4 80 60\nsave back.png\n",
    )
    .unwrap();
    retrace_ok(
        &args(&["view", "scene.toml"], &["--script", "zoom.txt"]),
        path,
    );
    // The same view through its own rays: a viewport magnified 1.4641
    // whose point (80, 60) shows what the camera's did; and, to show the
    // comparison can tell, the same zoom about the centre.
    let zoom = 1.1f64.powi(4);
    let (cx, cy) = (160.0, 120.0);
    let translate = |px: f64, py: f64| {
        (
            (1.0 - 1.0 / zoom) * (px - cx),
            (1.0 - 1.0 / zoom) * (py - cy),
        )
    };
    for (name, (tx, ty)) in [("cursor", translate(80.0, 60.0)), ("centre", (0.0, 0.0))] {
        let scene = format!(
            "include = \"scene.toml\"\n[[viewport]]\nname = \"{name}\"\nwidth = 320\nheight = 240\n\
             projection = \"equal-angle\"\nfov = 100.0\nzoom = {zoom}\ntranslate = [{tx}, {ty}]\n"
        );
        std::fs::write(path.join(format!("{name}.toml")), scene).unwrap();
        retrace_ok(
            &[
                "render",
                &format!("{name}.toml"),
                "--viewport",
                name,
                "-o",
                &format!("{name}.png"),
            ],
            path,
        );
    }
    let zoomed = png(&path.join("zoomed.png"));
    let about_cursor = psnr(&zoomed, &png(&path.join("cursor.png")));
    let about_centre = psnr(&zoomed, &png(&path.join("centre.png")));
    let unzoomed = psnr(&zoomed, &png(&path.join("open.png")));
    // RSVP resamples: close to the view's own rays, far from the others.
    assert!(about_cursor > 25.0, "{about_cursor:.1} dB");
    assert!(
        about_centre < about_cursor - 8.0 && unzoomed < about_cursor - 8.0,
        "cursor {about_cursor:.1} dB, centre {about_centre:.1}, unzoomed {unzoomed:.1}"
    );
    // Zoomed back out, the view is the camera's own image again, exact.
    assert!(differing(&png(&path.join("back.png")), &png(&path.join("open.png"))) == 0);
}

#[test]
fn zooming_in_again_goes_on_from_the_samples_kept_before() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    // In, out to the camera's image, and in again to the same viewport.
    std::fs::write(
        path.join("zoom.txt"),
        "save open.png\nwheel 2 80 60\nsave in.png\nwheel -2 80 60\nsave out.png\n\
         wheel 2 80 60\nsave in_again.png\nwheel -2 80 60\nsave out_again.png\n",
    )
    .unwrap();
    retrace_ok(
        &args(
            &["view", "scene.toml"],
            &["--script", "zoom.txt", "--stats", "stats.csv"],
        ),
        path,
    );
    let (stats, rows) = stats_rows(&path.join("stats.csv"));
    let traced =
        |row: &HashMap<String, String>| row["picture.samples_traced"].parse::<u64>().unwrap();
    assert_eq!(rows.len(), 5, "{stats}");
    // The first zoom in and out start their buffers (the viewport's, then
    // the camera's kept one goes on); the second pair traces nothing.
    assert!(traced(&rows[1]) > 320 * 240 / 2, "{stats}");
    assert_eq!((traced(&rows[3]), traced(&rows[4])), (0, 0), "{stats}");
    // And the pictures are what they were: exact where the first were.
    assert!(differing(&png(&path.join("in_again.png")), &png(&path.join("in.png"))) == 0);
    assert!(differing(&png(&path.join("out.png")), &png(&path.join("open.png"))) == 0);
    assert!(
        differing(
            &png(&path.join("out_again.png")),
            &png(&path.join("open.png"))
        ) == 0
    );
}

#[test]
fn a_bad_script_names_its_line_and_renders_nothing() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.txt"), "drag 1 2\nwheel in\n").unwrap();
    let out = retrace(&["view", "--script", "bad.txt"], dir.path());
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.txt:2: wheel: N 'in'"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_converged_picture_equals_a_render_at_the_top_samples_a_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    scene_and_turned(path);
    std::fs::write(
        path.join("refine.txt"),
        format!("{TURNING_DRAG}save first.png\nwait-converged\nsave converged.png\n"),
    )
    .unwrap();
    let out = retrace_ok(
        &args(
            &["view", "scene.toml"],
            &["--script", "refine.txt", "--stats", "stats.csv"],
        ),
        path,
    );
    retrace_ok(
        &args(
            &["render", "turned.toml"],
            &["--spp", "16", "-o", "turned16.png"],
        ),
        path,
    );
    retrace_ok(
        &args(&["render", "turned.toml"], &["-o", "turned1.png"]),
        path,
    );
    let converged = png(&path.join("converged.png"));
    assert!(
        differing(&converged, &png(&path.join("turned16.png"))) == 0,
        "the converged view differs from a 16-spp render of the turned camera"
    );
    // The frame loop's picture first, at the scene's one sample a pixel.
    let first = png(&path.join("first.png"));
    assert!(differing(&first, &png(&path.join("turned1.png"))) == 0);
    assert!(differing(&converged, &first) > 0);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("refinement: "), "{said}");
    // The last drag's row: converged after its complete picture.
    let (stats, rows) = stats_rows(&path.join("stats.csv"));
    let last = rows.last().unwrap();
    let ms = |column: &str| last[column].parse::<f64>().unwrap();
    assert!(ms("ms_to_converged") > ms("ms_to_picture"), "{stats}");
}

#[test]
fn a_converged_zoomed_view_equals_the_direct_render_of_its_viewport() {
    use retrace::accel::{Accelerator, BackendKind};
    use retrace::reuse::rsvp::render_direct_sampled;
    use retrace::sampling::PixelSamples;
    use retrace::shade::Shader;
    use retrace::view::Viewer as View;

    let scene = paper_at(160, 120);
    let text = "wheel 3 40 30\nwait-converged\nsave zoomed\n";
    let (thread, view, _, saved) = run_in_process(scene.clone(), text, 16);
    let shown = thread.latest().unwrap();
    assert_eq!((shown.mode(), shown.samples), ("refine", 16));
    assert!(!View::is_camera_view(&shown.state));
    // The frame loop's truth for the viewport: its own rays, at 16 spp.
    let accel = Accelerator::build_with(BackendKind::default(), &scene.objects, None).unwrap();
    let shader = Shader::new(&scene, &accel);
    let pose = view.view(&shown.state).pose;
    let (direct, _) = render_direct_sampled(&shader, &pose, PixelSamples::new(16).unwrap());
    assert!(saved == [(PathBuf::from("zoomed"), direct.to_rgb8())]);
}

#[test]
fn input_during_refinement_abandons_it_and_no_stale_picture_follows() {
    // Each drag is sent as soon as the frame loop's picture of the last
    // is shown: while its refinement runs.
    let text = format!("{}wait-converged\n", "wait\ndrag -4 0\n".repeat(6));
    let (thread, _, rows, _) = run_in_process(paper_at(320, 240), &text, 16);
    assert_eq!(rows.len(), 7);
    let log = thread.log();
    let abandoned = thread.abandoned();
    let described = || {
        log.iter()
            .map(|f| {
                format!(
                    "{} {} {} spp (newest asked {})",
                    f.generation, f.mode, f.samples, f.newest_asked
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    // A refined picture only ever shows the newest request: none was
    // published once a newer one had come.
    for f in log.iter().filter(|f| f.mode == "refine") {
        assert_eq!(f.generation, f.newest_asked, "{}", described());
    }
    // Refinements were given up for the drags (each drag while one ran;
    // a loaded machine may let some finish a rung first, not all six).
    assert!(!abandoned.is_empty(), "{}", described());
    for a in &abandoned {
        assert!(a.generation < 7 && a.samples > 1, "{a:?}");
        assert!(!log
            .iter()
            .any(|f| f.generation == a.generation && f.mode == "refine" && f.done > a.at));
    }
    // The last drag's view, refined rung by rung to 16 spp.
    let last: Vec<(&str, u32, bool)> = log
        .iter()
        .filter(|f| f.generation == 7)
        .map(|f| (f.mode, f.samples, f.converged))
        .collect();
    assert_eq!(
        last,
        [
            ("pan", 1, false),
            ("refine", 4, false),
            ("refine", 16, true)
        ],
        "{}",
        described()
    );
}

#[test]
fn input_during_a_full_render_abandons_it_and_the_next_picture_is_exact() {
    use retrace::scene::{load_scene, SceneOverrides};

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    // Four turning drags, then two more with reuse on again.
    paper_on_lattice(
        path,
        "off.toml",
        96.0 * STEP,
        ON_LATTICE_PITCH + 32.0 * STEP,
    );
    paper_on_lattice(path, "on.toml", 72.0 * STEP, ON_LATTICE_PITCH + 24.0 * STEP);
    let overrides = SceneOverrides {
        width: Some(320),
        height: Some(240),
        ..SceneOverrides::default()
    };
    let scene = load_scene(&path.join("scene.toml"), &overrides).unwrap();
    // Reuse off: every picture is traced in full. The second drag of each
    // pair comes while the first's picture is traced (a few ms into it);
    // with reuse on again, a drag comes while the new buffer is filled.
    let text = format!(
        "key m\nwait\n{}save off\nkey m\nsleep 2\ndrag 10 -3\nsleep 2\ndrag 14 -5\nwait\nsave on\n",
        "drag -10 3\nsleep 2\ndrag -14 5\nwait\n".repeat(4)
    );
    // No refinement: every picture is the frame loop's.
    let (thread, _, rows, saved) = run_in_process(scene, &text, 1);
    assert_eq!(rows.len(), 13);
    let log = thread.log();
    let abandoned = thread.abandoned();
    let described = || {
        let pictures = log.iter().map(|f| {
            format!(
                "{} {} (newest asked {})",
                f.generation, f.mode, f.newest_asked
            )
        });
        let given_up = abandoned
            .iter()
            .map(|a| format!("{} abandoned", a.generation));
        pictures.chain(given_up).collect::<Vec<_>>().join("\n")
    };
    // Full pictures were given up for the second drag of a pair (a loaded
    // machine may start one late, after both drags, not all four), and
    // no complete picture of a request given up was shown (a coarse one
    // may have come before).
    let full: Vec<_> = abandoned.iter().filter(|a| a.frame_loop).collect();
    assert!(!full.is_empty(), "{}", described());
    for a in &full {
        assert!(
            !log.iter()
                .any(|f| f.generation == a.generation && f.complete),
            "{}",
            described()
        );
    }
    // Each pair's second drag has its own full picture.
    for pair in 0..4 {
        let second = 4 + 2 * pair;
        assert!(
            log.iter()
                .any(|f| f.generation == second && f.mode == "full" && f.complete),
            "{}",
            described()
        );
    }
    retrace_ok(
        &args(&["render", "off.toml"], &["-o", "off_render.png"]),
        path,
    );
    retrace_ok(
        &args(&["render", "on.toml"], &["-o", "on_render.png"]),
        path,
    );
    let names: Vec<String> = saved.iter().map(|(p, _)| p.display().to_string()).collect();
    assert_eq!(names, ["off", "on"]);
    assert!(differing(&saved[0].1, &png(&path.join("off_render.png"))) == 0);
    assert!(differing(&saved[1].1, &png(&path.join("on_render.png"))) == 0);
}

/// The paper scene with a bouncing ball, a panning camera and two
/// viewports, one of them zooming, turning and shifting along the
/// timeline (E4 in small).
const SCENE_VIEWPORTS: &str = r#"include = "paper.toml"

[material.bouncer]
diffuse = [0.95, 0.75, 0.1]

[[object]]
type = "sphere"
name = "ball"
center = [-2.6, 0.5, 3.0]
radius = 0.5
material = "bouncer"

[[viewport]]
name = "wide"
width = 96
height = 64

[[viewport]]
name = "zoom"
width = 120
height = 80
fov = 90.0
rotate = 10.0

[animation]
frames = 4

[[animation.camera]]
frame = 0
yaw = 0.0

[[animation.camera]]
frame = 4
yaw = 14.4

[[animation.viewport]]
viewport = "zoom"
frame = 0
zoom = 1.0

[[animation.viewport]]
viewport = "zoom"
frame = 3
zoom = 2.0
rotate = 25.0
translate = [12.0, -6.0]

[[animation.bounce]]
object = "ball"
height = 2.0
period = 4
"#;

#[test]
fn a_scene_viewport_shows_what_animate_writes_and_refines_to_its_direct_render() {
    use retrace::accel::{Accelerator, BackendKind};
    use retrace::frame_loop::{Animator, Options, Techniques};
    use retrace::sampling::PixelSamples;
    use retrace::scene::{load_scene, SceneOverrides};

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "paper.toml", 0.0, -9.0);
    std::fs::write(path.join("vp.toml"), SCENE_VIEWPORTS).unwrap();
    retrace_ok(
        &args(&["animate", "vp.toml"], &["-o", "anim/frame_####.png"]),
        path,
    );
    // Opens on the first viewport; `v` the second, played to frame 3 and
    // refined there; `v` the camera's image; `v` the first again.
    std::fs::write(
        path.join("vp.txt"),
        "save wide_0.png\nkey v\nsave zoom_0.png\nplay 1\nsave zoom_1.png\nplay 2\n\
         save zoom_3.png\nwait-converged\nsave zoom_3_converged.png\nkey v\nsave camera_3.png\n\
         key v\nsave wide_3.png\n",
    )
    .unwrap();
    let out = retrace_ok(
        &args(
            &["view", "vp.toml"],
            &["--script", "vp.txt", "--stats", "stats.csv"],
        ),
        path,
    );
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("opens on the scene's viewport wide"),
        "{said}"
    );
    // Bit for bit what animate wrote: the same frame loop, the same samples.
    for (shown, written) in [
        ("wide_0", "frame_0000_wide"),
        ("zoom_0", "frame_0000_zoom"),
        ("zoom_1", "frame_0001_zoom"),
        ("zoom_3", "frame_0003_zoom"),
        ("wide_3", "frame_0003_wide"),
    ] {
        let shown_image = png(&path.join(format!("{shown}.png")));
        let written_image = png(&path.join(format!("anim/{written}.png")));
        assert!(
            differing(&shown_image, &written_image) == 0,
            "{shown} differs from animate's {written}"
        );
    }
    // The zoom moved along the timeline, and the camera is another view.
    assert!(
        differing(
            &png(&path.join("zoom_0.png")),
            &png(&path.join("zoom_3.png"))
        ) > 0
    );
    assert_eq!(png(&path.join("camera_3.png")).dimensions(), (320, 240));
    // Played frames of a viewport come from its sample buffer (RSVP).
    let stats = std::fs::read_to_string(path.join("stats.csv")).unwrap();
    let play: Vec<&str> = stats.lines().filter(|l| l.contains("play frame")).collect();
    assert_eq!(play.len(), 3, "{stats}");
    assert!(play.iter().all(|l| l.contains(",rsvp")), "{stats}");
    // Refined: the direct render of the viewport at frame 3, 16 spp, as
    // the frame loop of `retrace animate` poses it.
    let overrides = SceneOverrides {
        width: Some(320),
        height: Some(240),
        ..SceneOverrides::default()
    };
    let scene = load_scene(&path.join("vp.toml"), &overrides).unwrap();
    let mut accel = Accelerator::build_with(BackendKind::default(), &scene.objects, None).unwrap();
    let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::FULL, 0..4));
    let (direct, _) = animator.render_own_rays(3, 1, Some(PixelSamples::new(16).unwrap()));
    let converged = png(&path.join("zoom_3_converged.png"));
    assert!(differing(&converged, &direct.to_rgb8()) == 0);
    assert!(differing(&converged, &png(&path.join("zoom_3.png"))) > 0);
}

/// CPU time the process `pid` has used, in clock ticks (user + system).
fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    // The fields after the command's name (in parentheses, which may hold
    // spaces): utime and stime are the 14th and 15th of the line.
    let after = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap()
}

#[test]
fn once_converged_the_viewer_uses_no_cpu() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("idle.txt"),
        "wait-converged\nsave converged.png\nsleep 1500\n",
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args(args(&["view"], &["--script", "idle.txt"]))
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let saved = lines.next().unwrap().unwrap();
    assert!(saved.starts_with("saved "), "{saved}");
    // Let the pool's threads finish spinning down, then watch for 500 ms.
    std::thread::sleep(Duration::from_millis(100));
    let before = cpu_ticks(child.id());
    std::thread::sleep(Duration::from_millis(500));
    let after = cpu_ticks(child.id());
    assert!(child.wait().unwrap().success());
    // Ticks are 10 ms on Linux: at most 2 over the 500 ms (rounding).
    assert!(
        after - before <= 2,
        "{} ticks of CPU in 500 ms after converging",
        after - before
    );
}

#[test]
fn a_scripted_wheel_past_the_zoom_limit_stops_at_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    // Twenty notches out at once, and one at a time: the view stops at
    // the same limit either way (each notch past it is refused).
    std::fs::write(
        path.join("zoom.txt"),
        "save open.png\nwheel -20\nsave at_once.png\n",
    )
    .unwrap();
    std::fs::write(
        path.join("notches.txt"),
        format!("{}save one_by_one.png\n", "wheel -1\n".repeat(20)),
    )
    .unwrap();
    for script in ["zoom.txt", "notches.txt"] {
        retrace_ok(
            &args(
                &["view", "scene.toml"],
                &["--script", script, "--refine-spp", "1"],
            ),
            path,
        );
    }
    let at_once = png(&path.join("at_once.png"));
    assert!(differing(&at_once, &png(&path.join("open.png"))) > 0);
    assert!(differing(&at_once, &png(&path.join("one_by_one.png"))) == 0);
}

#[test]
fn the_overlay_of_a_refined_picture_shows_what_reuse_traced() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "scene.toml", 0.0, ON_LATTICE_PITCH);
    std::fs::write(
        path.join("mask.txt"),
        "wait\nkey Left\nkey t\nsave pan.png\nwait-converged\nsave converged.png\n",
    )
    .unwrap();
    retrace_ok(
        &args(&["view", "scene.toml"], &["--script", "mask.txt"]),
        path,
    );
    // The pan traced a strip 32 pixels wide: black there, the picture
    // elsewhere; refined to 16 spp, the overlay shows the same.
    let pan = png(&path.join("pan.png"));
    let black = pan.pixels().filter(|p| p.0 == [0, 0, 0]).count();
    assert!(
        (32 * 240..320 * 240 / 2).contains(&black),
        "{black} black pixels"
    );
    assert!(differing(&png(&path.join("converged.png")), &pan) == 0);
}

#[test]
fn a_scene_with_one_viewport_opens_saying_v_shows_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path();
    paper_on_lattice(path, "paper.toml", 0.0, -9.0);
    std::fs::write(
        path.join("one.toml"),
        "include = \"paper.toml\"\n[[viewport]]\nname = \"only\"\nwidth = 96\nheight = 64\n",
    )
    .unwrap();
    std::fs::write(path.join("wait.txt"), "wait\n").unwrap();
    let out = retrace_ok(
        &args(
            &["view", "one.toml"],
            &["--script", "wait.txt", "--refine-spp", "1"],
        ),
        path,
    );
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("opens on the scene's viewport only"),
        "{said}"
    );
    assert!(said.contains("`v` shows the camera's image"), "{said}");
    assert!(!said.contains("the next"), "{said}");
}

#[test]
fn an_interrupted_script_writes_the_statistics_of_the_commands_run() {
    use nix::sys::signal::{kill, Signal};
    let dir = tempfile::tempdir().unwrap();
    // A long script: the interrupt comes while it sleeps between drags.
    let drags = "drag 4 0\nwait\nsleep 200\n".repeat(50);
    std::fs::write(
        dir.path().join("long.txt"),
        format!("save open.png\n{drags}"),
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args(args(
            &["view"],
            &["--script", "long.txt", "--stats", "stats.csv"],
        ))
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let saved = lines.next().unwrap().unwrap();
    assert!(saved.starts_with("saved "), "{saved}");
    std::thread::sleep(Duration::from_millis(500));
    kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        Signal::SIGINT,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    // The opening and the drags run before the interrupt, not all fifty.
    let (stats, rows) = stats_rows(&dir.path().join("stats.csv"));
    assert!(rows.len() >= 2 && rows.len() < 51, "{stats}");
    assert_eq!(rows[0]["event"], "open", "{stats}");
    assert!(
        rows.iter().all(|r| !r["ms_to_picture"].is_empty()),
        "{stats}"
    );
}
