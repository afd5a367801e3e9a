//! Animation and Panimation: accelerated frames equal full renders bit for
//! bit, on every backend, and the CLI's animate command.

use std::path::Path;

use retrace::accel::Accelerator;
use retrace::frame_loop::{Animator, Options, Techniques, ViewOutput};
use retrace::scene::{paper_scene, parse_scene_str, Scene, SceneOverrides};

use crate::common::retrace;

/// The paper scene, small, with the given camera keyframes appended.
fn paper_with_keys(keys: &str, frames: u32) -> Scene {
    paper_with_keys_at(keys, frames, None)
}

/// [`paper_with_keys`] at `spp` samples a pixel (None: the scene's).
pub fn paper_with_keys_at(keys: &str, frames: u32, spp: Option<u32>) -> Scene {
    let paper =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml")).unwrap();
    let text = format!("{paper}\n[animation]\nframes = {frames}\n{keys}");
    let overrides = SceneOverrides {
        width: Some(64),
        height: Some(48),
        spp,
        ..SceneOverrides::default()
    };
    parse_scene_str(&text, Path::new("scenes/paper.toml"), &overrides).unwrap()
}

pub fn key(frame: u32, fields: &str) -> String {
    format!("[[animation.camera]]\nframe = {frame}\n{fields}\n")
}

/// Renders every frame with `techniques`, checks each against a full render
/// bit for bit, and returns the samples traced and each frame's mode.
fn run_exact(
    scene: &Scene,
    backend: retrace::accel::BackendKind,
    techniques: Techniques,
) -> (u64, Vec<String>) {
    let stats = crate::common::run_exact_reusing(scene, backend, techniques);
    (
        stats.iter().map(|s| s.work.samples_traced).sum(),
        stats.iter().map(|s| s.mode.to_string()).collect(),
    )
}

on_every_backend! {
    whole_pixel_pans_are_bit_exact_and_trace_only_new_samples(backend) {
        // 100 degrees over 64 px: 230.4 columns a turn, rounded to 232.
        // Yaw right by 20 degrees a frame (snapped), then pitch.
        let scene = paper_with_keys(
            &(key(0, "yaw = 0.0\npitch = -9.0") + &key(6, "yaw = 120.0\npitch = -9.0") + &key(9, "yaw = 120.0\npitch = 6.0")),
            10,
        );
        let (traced, modes) = run_exact(&scene, backend, Techniques::AUTO);
        assert!(modes.iter().all(|m| m == "pan"), "{modes:?}");
        let full_samples = 10 * 64 * 48;
        assert!(traced < full_samples / 2, "traced {traced} of {full_samples}");
    }

    a_pan_that_comes_back_traces_nothing(backend) {
        let scene = paper_with_keys(&(key(0, "yaw = 0.0") + &key(4, "yaw = 40.0") + &key(8, "yaw = 0.0")), 9);
        let mut accel = Accelerator::build(backend, &scene.objects).unwrap();
        let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..9));
        let traced: Vec<u64> = (0..9).map(|f| animator.render(f).remove(0).stats.work.samples_traced).collect();
        assert!(traced[1..=4].iter().all(|&t| t > 0), "{traced:?}");
        assert!(traced[5..].iter().all(|&t| t == 0), "coming back traced again: {traced:?}");
    }

    full_turns_wrap_exactly(backend) {
        let scene = paper_with_keys(&(key(0, "yaw = 0.0") + &key(8, "yaw = 720.0")), 9);
        let (traced, _) = run_exact(&scene, backend, Techniques::AUTO);
        // One turn of columns (232) over the rows seen, whatever the turns.
        assert!(traced <= 232 * 48, "traced {traced}");
    }

    ostc_without_pan_equals_full_renders_where_the_camera_stands_still(backend) {
        // With pan off, the still frames of a timeline whose camera moves
        // elsewhere are the lattice's frames, as full renders take them.
        let scene = pan_then_still();
        let ostc = Techniques { pan: false, rsvp: false, ostc: true };
        let stats = crate::common::run_exact(&scene, backend, ostc);
        let modes: Vec<&str> = stats.iter().map(|s| s.mode.as_str()).collect();
        assert!(modes[6..].iter().all(|&m| m == "ostc"), "{modes:?}");
        assert!(stats[6..].iter().all(|s| s.work.pixels_reused > 0), "{modes:?}");
    }
}

#[test]
fn full_renders_are_the_same_reference_whatever_the_mode() {
    // The benches render the full side with reuse off: its frames must be
    // the very frames a pan is checked against.
    let scene = paper_with_keys(&(key(0, "yaw = 0.0") + &key(3, "yaw = 30.0")), 4);
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let mut auto = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..4));
    let panned: Vec<_> = (0..4)
        .map(|f| auto.render(f).remove(0).frame.unwrap())
        .collect();
    drop(auto);
    let mut full = Animator::new(&scene, &mut accel, Options::new(Techniques::FULL, 0..4));
    for (frame, panned) in panned.iter().enumerate() {
        let (reference, _) = full.render_full(frame as u32, 0, None);
        assert_eq!(
            retrace::metrics::count_differences(panned, &reference).unwrap(),
            0,
            "frame {frame}"
        );
    }
}

#[test]
fn non_equal_angle_cameras_fall_back_with_a_reason() {
    let mut scene = paper_with_keys(&(key(0, "yaw = 0.0") + &key(2, "yaw = 10.0")), 3);
    scene.camera.projection = retrace::camera::Projection::Perspective;
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..3));
    let stats = animator.render(1).remove(0).stats;
    assert_eq!(stats.mode.as_str(), "full");
    assert!(
        crate::common::reason(&stats).contains("equal-angle"),
        "{:?}",
        crate::common::reason(&stats)
    );
}

#[test]
fn built_in_paper_scene_is_still_single_frame() {
    assert!(paper_scene(&SceneOverrides::default())
        .unwrap()
        .animation
        .is_none());
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A small animated scene in a temp dir that includes the real paper scene.
pub fn pan_case(extra: &str) -> tempfile::TempDir {
    paper_case(
        "pan.toml",
        &format!(
            "[animation]\nframes = 6\n\n{}{}{extra}",
            key(0, "yaw = 0.0"),
            key(5, "yaw = 50.0")
        ),
    )
}

/// A folder holding the paper scene and `name`, which includes it and
/// adds `tables`.
fn paper_case(name: &str, tables: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml");
    std::fs::copy(paper, dir.path().join("paper.toml")).unwrap();
    let text = format!("include = \"paper.toml\"\n\n{tables}");
    std::fs::write(dir.path().join(name), text).unwrap();
    dir
}

#[test]
fn animate_writes_frames_gif_and_stats_and_verifies() {
    let dir = pan_case("");
    let out = retrace(
        &[
            "animate",
            "pan.toml",
            "--width",
            "48",
            "--height",
            "32",
            "-o",
            "out/f_###.png",
            "--gif",
            "out/a.gif",
            "--stats",
            "out/s.csv",
            "--verify",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    for frame in 0..6 {
        let image = image::open(dir.path().join(format!("out/f_{frame:03}.png"))).unwrap();
        assert_eq!((image.width(), image.height()), (48, 32));
    }
    let gif = std::fs::read(dir.path().join("out/a.gif")).unwrap();
    assert!(gif.starts_with(b"GIF89a"));
    let csv = std::fs::read_to_string(dir.path().join("out/s.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7);
    assert!(csv.lines().nth(2).unwrap().contains(",pan,"));
    assert!(String::from_utf8_lossy(&out.stdout).contains("bit for bit"));

    // The same frames again, with more arguments.
    let again = |extra: &[&str]| {
        let size = ["animate", "pan.toml", "--width", "48", "--height", "32"];
        retrace(
            &[&size[..], &["-o", "out/f_###.png"], extra].concat(),
            dir.path(),
        )
    };
    // --skip-existing leaves finished frames alone; JSON stats work too.
    let out = again(&[
        "--skip-existing",
        "--frames",
        "4-5",
        "--stats",
        "out/s.json",
        "--verify",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/s.json")).unwrap())
            .unwrap();
    assert_eq!(json.as_array().unwrap().len(), 0, "both frames existed");
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("0 frames (2 more skipped"),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("verify: no frame rendered, nothing to check"),
        "{said}"
    );
    assert!(
        !said.contains("-0.0") && !said.contains("bit for bit"),
        "{said}"
    );

    // Resuming with a GIF: the frames already there go into it too, so it
    // equals the first run's.
    std::fs::remove_file(dir.path().join("out/f_003.png")).unwrap();
    let out = again(&["--skip-existing", "--gif", "out/b.gif"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let resumed = std::fs::read(dir.path().join("out/b.gif")).unwrap();
    let frames = |bytes: &[u8]| {
        use image::AnimationDecoder;
        let decoder = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(bytes)).unwrap();
        decoder
            .into_frames()
            .map(|f| f.unwrap().into_buffer())
            .collect::<Vec<_>>()
    };
    assert_eq!(frames(&resumed).len(), 6);
    assert!(frames(&resumed) == frames(&gif), "the resumed GIF differs");
}

#[test]
fn animate_rejects_bad_input_cleanly() {
    let dir = pan_case("");
    let cases: [(&[&str], &str); 9] = [
        (
            &["animate", "pan.toml", "-o", "out/frame.png"],
            "no # for the frame number",
        ),
        (
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--frames",
                "3-9",
            ],
            "frames 0-5",
        ),
        (
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--frames",
                "4-2",
            ],
            "comes after",
        ),
        (
            &["animate", "pan.toml", "-o", "/proc/forbidden/f_#.png"],
            "output folder",
        ),
        (
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--gif",
                "out/a.png",
            ],
            "--gif out/a.png: use a .gif file",
        ),
        (
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--stats",
                "out/s.txt",
            ],
            "--stats out/s.txt: use a .csv or .json file",
        ),
        (
            &["animate", "pan.toml", "-o", "out/p##/f.png"],
            "the # must be in the file name",
        ),
        (
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--dirty-image",
                "out/f_#.png",
            ],
            "-o and --dirty-image both write 'out/f_#.png'",
        ),
        (
            // A folder that is a file: refused before any frame, not after
            // the last.
            &[
                "animate",
                "pan.toml",
                "-o",
                "out/f_#.png",
                "--stats",
                "pan.toml/s.csv",
            ],
            "cannot make the folder pan.toml: a file of that name is in the way",
        ),
    ];
    for (args, needle) in cases {
        let out = retrace(args, dir.path());
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
        assert!(!stderr(&out).contains("panicked"));
        assert!(
            !dir.path().join("out").exists()
                || std::fs::read_dir(dir.path().join("out")).unwrap().count() == 0
        );
    }
    // Keyframes out of order: the file and line of the offending frame.
    let dir = pan_case(&key(3, "yaw = 10.0"));
    let out = retrace(&["animate", "pan.toml", "-o", "out/f_#.png"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.contains("pan.toml:13")
            && err.contains("animation.camera[2].frame")
            && err.contains("increasing"),
        "{err}"
    );
}

/// Asked for by name, a pan that cannot act is refused with the reason,
/// before any frame; under `auto` the frames render in full, with a
/// warning that says why.
#[test]
fn pan_on_a_perspective_camera_is_refused_by_name_and_explained_under_auto() {
    let dir = pan_case("");
    let run = |mode: &str| {
        retrace(
            &[
                "animate",
                "pan.toml",
                "--camera",
                "perspective",
                "--width",
                "32",
                "--height",
                "24",
                "-o",
                "out/f_#.png",
                "--mode",
                mode,
            ],
            dir.path(),
        )
    };
    let out = run("pan");
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "--mode pan has nothing to act on in this run: only an equal-angle camera pans, \
             and this one is perspective"
        ),
        "{}",
        stderr(&out)
    );
    assert!(!dir.path().join("out/f_0.png").exists());
    let out = run("auto");
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "warning: rendered in full: the perspective camera moves: only equal-angle views pan"
        ),
        "{}",
        stderr(&out)
    );
}

#[test]
fn resampled_pans_match_snapped_ones_on_whole_samples_and_measure_their_error() {
    use retrace::metrics::image_error;
    // 90 degrees over 64 px: exactly 256 columns a turn; yaw steps of 4.21875
    // degrees are three whole samples, so resampling weighs one sample only.
    let mut scene = paper_with_keys(
        &(key(0, "yaw = 0.0\npitch = 0.0\nfov = 90.0") + &key(4, "yaw = 16.875\npitch = 0.0")),
        5,
    );
    scene.camera.fov = 90f64.to_radians();
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    // One accelerator each: an animator holds its accelerator for its life.
    let mut accel2 =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let mut snapped = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..5));
    let mut resampled = Animator::new(&scene, &mut accel2, resampling(0..5));
    assert!(!resampled.is_exact());
    for frame in 0..5 {
        let a = snapped.render(frame).remove(0).frame.unwrap();
        let b = resampled.render(frame).remove(0).frame.unwrap();
        let error = image_error(&b, &a).unwrap();
        assert!(error.max_abs < 1e-4, "frame {frame}: {error:?}");
    }
    // Off whole samples the resampled frame is an approximation of the true
    // view: close, not exact, and measured.
    let mut scene = paper_with_keys(&(key(0, "yaw = 0.0") + &key(3, "yaw = 10.0")), 4);
    scene.camera.fov = 100f64.to_radians();
    drop(snapped);
    let mut resampled = Animator::new(&scene, &mut accel, resampling(0..4));
    let ViewOutput { frame, stats, .. } = resampled.render(2).remove(0);
    assert_eq!(stats.mode.as_str(), "pan");
    let (truth, _) = resampled.render_own_rays(2, 0, None);
    let error = image_error(&frame.unwrap(), &truth).unwrap();
    // Measured over frames 0-3: 17.9-18.3 dB, mean error 0.048-0.058 (the
    // far checkerboard aliases at 64x48); the true view moved one pixel
    // scores 14.4-14.6 dB and 0.066-0.069, and must fail.
    let close = |e: &retrace::metrics::ImageError| e.psnr_db > 16.5 && e.mean_abs < 0.062;
    assert!(close(&error) && error.psnr_db.is_finite(), "{error:?}");
    let misregistered = image_error(&crate::common::shifted_by_one(&truth), &truth).unwrap();
    assert!(
        !close(&misregistered),
        "a one-pixel shift passes: {misregistered:?}"
    );
}

#[test]
fn chunks_of_an_array_job_render_the_frames_of_one_run() {
    // Pan, a bouncing ball and a viewport at once, small.
    let dir = tempfile::tempdir().unwrap();
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml");
    std::fs::copy(paper, dir.path().join("paper.toml")).unwrap();
    let text = format!(
        "include = \"paper.toml\"\n\n[render]\nwidth = 64\nheight = 48\n\n\
         [[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [-2.6, 0.5, 3.0]\nradius = 0.5\n\n\
         [[viewport]]\nname = \"view\"\nwidth = 40\nheight = 30\n\n\
         [animation]\nframes = 7\n\n{}{}\
         [[animation.viewport]]\nframe = 0\nzoom = 1.0\n\n\
         [[animation.viewport]]\nframe = 6\nzoom = 1.5\n\n\
         [[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 4\n",
        key(0, "yaw = 0.0"),
        key(6, "yaw = 20.0")
    );
    std::fs::write(dir.path().join("all.toml"), text).unwrap();
    let run = |out: &str, extra: &[&str], env: &[(&str, &str)]| {
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_retrace"));
        command
            .args(["animate", "all.toml", "-o", out])
            .args(extra)
            .current_dir(dir.path());
        for var in [
            "SLURM_ARRAY_TASK_ID",
            "SLURM_ARRAY_TASK_MIN",
            "JOB_COMPLETION_INDEX",
        ] {
            command.env_remove(var);
        }
        command.envs(env.iter().copied());
        let out = command.output().unwrap();
        assert!(out.status.success(), "{extra:?} {env:?}: {}", stderr(&out));
        stderr(&out)
    };
    // At one and at four samples a pixel; the long run at four on one
    // thread, the chunks on every core: sub-sample positions depend on
    // neither the thread nor the chunk.
    for (spp, one_threads) in [("1", None), ("4", Some("1"))] {
        let (one, chunked) = (format!("one{spp}"), format!("chunked{spp}"));
        let (one_out, out) = (format!("{one}/f_#.png"), format!("{chunked}/f_#.png"));
        let stats = format!("{chunked}/s.csv");
        let mut long = vec!["--spp", spp];
        if let Some(threads) = one_threads {
            long.extend(["--threads", threads]);
        }
        run(&one_out, &long, &[]);
        let chunk = |extra: &[&'static str]| -> Vec<String> {
            ["--spp", spp, "--chunks", "3", "--stats", &stats]
                .iter()
                .map(|s| s.to_string())
                .chain(extra.iter().map(|s| s.to_string()))
                .collect()
        };
        let args = chunk(&[]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        // Three tasks, each told its index a different way.
        let said = run(
            &out,
            &args,
            &[("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_ARRAY_TASK_MIN", "1")],
        );
        assert!(
            said.contains("chunk 0 of 3") && said.contains("frames 0-1"),
            "{said}"
        );
        let said = run(&out, &args, &[("JOB_COMPLETION_INDEX", "1")]);
        assert!(said.contains("frames 2-3"), "{said}");
        let last = chunk(&["--chunk-index", "2"]);
        let last: Vec<&str> = last.iter().map(String::as_str).collect();
        run(&out, &last, &[]);
        for frame in 0..7 {
            let name = format!("f_{frame}_view.png");
            let one = std::fs::read(dir.path().join(&one).join(&name)).unwrap();
            let chunked = std::fs::read(dir.path().join(&chunked).join(&name)).unwrap();
            assert!(one == chunked, "spp {spp}: {name} differs");
        }
        // Each task's statistics, its own frames' rows; the first frame of
        // each chunk traced from scratch.
        for (index, rows) in [(0, 2), (1, 2), (2, 3)] {
            let csv =
                std::fs::read_to_string(dir.path().join(format!("{chunked}/s.chunk{index}.csv")))
                    .unwrap();
            assert_eq!(csv.lines().count(), 1 + rows, "chunk {index}");
            assert!(csv.lines().nth(1).unwrap().contains("first frame"), "{csv}");
        }
    }
}

#[test]
fn views_reaching_a_pole_keep_panning_in_both_pan_modes() {
    // 90 degrees over 64 px: exactly 256 columns a turn and 128 rows from
    // pole to pole. A 48-row view pitched -56.25 degrees ends on the last
    // row; pitched +56.25 it starts on the first.
    for pitch in ["-56.25", "56.25"] {
        let keys = key(0, &format!("yaw = 0.0\npitch = {pitch}\nfov = 90.0"))
            + &key(3, &format!("yaw = 12.0\npitch = {pitch}\nfov = 90.0"));
        let mut scene = paper_with_keys(&keys, 4);
        scene.camera.fov = 90f64.to_radians();
        let stats = crate::common::run_exact(
            &scene,
            retrace::accel::BackendKind::Embree,
            Techniques::AUTO,
        );
        for s in &stats[1..] {
            assert!(
                s.mode.as_str() == "pan" && s.work.pixels_reused > 0 && s.reason.is_none(),
                "pitch {pitch}, frame {}: {} {:?}, {} reused",
                s.frame,
                s.mode,
                s.reason,
                s.work.pixels_reused
            );
        }
        let mut accel =
            Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
        let mut resampled = Animator::new(&scene, &mut accel, resampling(0..4));
        for frame in 0..4 {
            let ViewOutput {
                frame: image,
                stats,
                ..
            } = resampled.render(frame).remove(0);
            let (truth, _) = resampled.render_own_rays(frame, 0, None);
            let error = retrace::metrics::image_error(&image.unwrap(), &truth).unwrap();
            // Looking down (-56.25): at least 23.2 dB, mean error at most
            // 0.0151; the true view moved one pixel scores 16.8-17.0 dB and
            // 0.032, and must fail. Looking up, the view is all sky: a
            // shift cannot show, the frames must simply match.
            let close = |e: &retrace::metrics::ImageError| e.psnr_db > 20.0 && e.mean_abs < 0.024;
            assert!(close(&error), "pitch {pitch}, frame {frame}: {error:?}");
            let misregistered =
                retrace::metrics::image_error(&crate::common::shifted_by_one(&truth), &truth)
                    .unwrap();
            if pitch.starts_with('-') {
                assert!(
                    !close(&misregistered),
                    "a one-pixel shift passes: {misregistered:?}"
                );
            }
            assert!(
                frame == 0 || stats.work.pixels_reused > 0,
                "pitch {pitch}, frame {frame}"
            );
        }
    }
}

/// A camera that pans over frames 0-4 and then stands still, with a
/// bouncing ball throughout.
fn pan_then_still() -> Scene {
    let keys = key(0, "yaw = 0.0") + &key(4, "yaw = 10.0") + &key(9, "yaw = 10.0");
    let ball = "[[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 4\n\n\
                [[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [-2.6, 0.5, 3.0]\n\
                radius = 0.5\nmaterial = \"red\"\n";
    paper_with_keys(&(keys + ball), 10)
}

/// Renders frames `late..frames` of `scene` in a run of their own and
/// checks each equals the same frame of one run over all `frames`.
pub fn assert_later_frames_equal_one_long_run(scene: &Scene, frames: u32, late: u32) {
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let mut long = Animator::new(scene, &mut accel, Options::new(Techniques::AUTO, 0..frames));
    let long_frames: Vec<_> = (0..frames)
        .map(|f| long.render(f).remove(0).frame.unwrap())
        .collect();
    drop(long);
    let options = Options::new(Techniques::AUTO, late..frames);
    let mut late_run = Animator::new(scene, &mut accel, options);
    for frame in late..frames {
        let image = late_run.render(frame).remove(0).frame.unwrap();
        assert_eq!(
            retrace::metrics::count_differences(&image, &long_frames[frame as usize]).unwrap(),
            0,
            "frame {frame}"
        );
    }
}

#[test]
fn a_run_of_later_frames_equals_one_long_run() {
    // Frames 5-9 stand still: alone they must still be the frames a run
    // over the whole timeline makes (on the pan lattice).
    let scene = pan_then_still();
    assert_later_frames_equal_one_long_run(&scene, 10, 5);
}

#[test]
fn a_pan_too_narrow_for_a_whole_turn_buffer_renders_in_full() {
    // 0.001 degrees over 64 px: 23M columns a turn, 17 GB of pan buffer.
    let keys = key(0, "yaw = 0.0\nfov = 0.001") + &key(2, "yaw = 0.002\nfov = 0.001");
    let mut scene = paper_with_keys(&keys, 3);
    scene.camera.fov = 0.001f64.to_radians();
    let stats = crate::common::run_exact(
        &scene,
        retrace::accel::BackendKind::Embree,
        Techniques::AUTO,
    );
    for s in &stats {
        assert_eq!(s.mode.as_str(), "full", "frame {}", s.frame);
        assert!(
            crate::common::reason(s).contains("pan buffer"),
            "{:?}",
            crate::common::reason(s)
        );
    }
    // Not snapped to a lattice: the camera's own rays.
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..3));
    let image = animator.render(1).remove(0).frame.unwrap();
    let (truth, _) = animator.render_own_rays(1, 0, None);
    assert_eq!(
        retrace::metrics::count_differences(&image, &truth).unwrap(),
        0
    );
}

#[test]
fn gif_frames_last_as_long_as_the_frame_rate_says() {
    let dir = tempfile::tempdir().unwrap();
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml");
    std::fs::copy(paper, dir.path().join("paper.toml")).unwrap();
    for (fps, ms) in [("0.5", 2000), ("25", 40), ("12.5", 80)] {
        let text = format!("include = \"paper.toml\"\n\n[animation]\nframes = 2\nfps = {fps}\n");
        std::fs::write(dir.path().join("slow.toml"), text).unwrap();
        let out = retrace(
            &[
                "animate",
                "slow.toml",
                "--width",
                "16",
                "--height",
                "12",
                "-o",
                "f_#.png",
                "--gif",
                "a.gif",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        use image::AnimationDecoder;
        let bytes = std::fs::read(dir.path().join("a.gif")).unwrap();
        let decoder = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(bytes)).unwrap();
        for frame in decoder.into_frames() {
            let (numer, denom) = frame.unwrap().delay().numer_denom_ms();
            assert_eq!(
                f64::from(numer) / f64::from(denom),
                f64::from(ms),
                "{fps} fps"
            );
        }
    }
}

/// Every technique over `frames`, fractional pans resampled.
fn resampling(frames: std::ops::Range<u32>) -> Options {
    Options {
        fractional_pan: retrace::reuse::pan::FractionalPan::Resample,
        ..Options::new(Techniques::AUTO, frames)
    }
}

/// Where snapping moves nothing (yaw in whole samples, the rows on the
/// lattice), a panned frame is the camera's own view: equal, bit for bit,
/// to its own rays and not only to the lattice's full render.
#[test]
fn pans_by_whole_samples_equal_the_cameras_own_rays() {
    // 90 degrees over 64 px: 256 columns a turn, 4.21875 degrees three
    // whole samples; -7.03125 degrees of pitch is five rows.
    for pitch in ["0.0", "-7.03125"] {
        let keys = key(0, &format!("yaw = 0.0\npitch = {pitch}\nfov = 90.0"))
            + &key(4, &format!("yaw = 16.875\npitch = {pitch}"));
        let mut scene = paper_with_keys(&keys, 5);
        scene.camera.fov = 90f64.to_radians();
        let mut accel =
            Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
        let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..5));
        for frame in 0..5 {
            let output = animator.render(frame).remove(0);
            assert_eq!(
                output.stats.snap_error_deg(),
                (0.0, 0.0),
                "frame {frame} snapped"
            );
            let (own, _) = animator.render_own_rays(frame, 0, None);
            assert_eq!(
                retrace::metrics::count_differences(output.frame.as_ref().unwrap(), &own).unwrap(),
                0,
                "pitch {pitch}, frame {frame} ({}) differs from the camera's own rays",
                output.stats.mode
            );
        }
    }
}

/// `retrace animate pan.toml --verify` of [`pan_case`] `dir` at `width` x
/// `height` and 4 samples a pixel, which must succeed: what it printed.
fn verify_pan_at_4_spp(dir: &tempfile::TempDir, width: &str, height: &str) -> String {
    let out = retrace(
        &[
            "animate",
            "pan.toml",
            "--width",
            width,
            "--height",
            height,
            "--spp",
            "4",
            "-o",
            "out/f_###.png",
            "--verify",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The worst PSNR on the `--verify` line of `heading` that names `side`.
pub fn verified_worst_psnr(said: &str, heading: &str, side: &str) -> f64 {
    let line = said
        .lines()
        .find(|l| l.starts_with(heading) && l.contains(side))
        .unwrap_or_else(|| panic!("no {side} line: {said}"));
    line.split("PSNR worst ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .unwrap()
        .parse()
        .unwrap()
}

/// A snapped pan is an exact render of the camera moved onto the lattice:
/// `--verify` scores it against that view's reference, as close to it as
/// the keyed camera's full render is to its own, and against the keyed
/// camera's reference on a line of its own.
#[test]
fn verify_scores_a_snapped_pan_against_the_view_it_shows() {
    let said = verify_pan_at_4_spp(&pan_case(""), "64", "48");
    assert!(
        said.contains("of the view snapped onto the lattice, at most 0."),
        "{said}"
    );
    let heading = "verify (against a 64-spp reference, frames 0, 5): ";
    let full = verified_worst_psnr(&said, heading, "full render at 4 spp:");
    let shown = verified_worst_psnr(&said, heading, "output (its snapped view):");
    let keyed = verified_worst_psnr(&said, heading, "output (keyed camera):");
    assert!(shown >= full - 0.25, "{said}");
    assert!(keyed < shown - 1.0, "{said}");
}

/// Resampled output under --verify: the full render and the output, each
/// against the same converged reference, one line each; exact output that
/// is its camera's own rays has nothing to add.
#[test]
fn verify_measures_resampled_output_and_full_render_against_a_reference() {
    let dir = pan_case("[[viewport]]\nname = \"v\"\nwidth = 16\nheight = 12\n");
    let said = verify_pan_at_4_spp(&dir, "32", "24");
    let heading = "verify v (against a 64-spp reference, frames 0, 5): ";
    for side in ["full render at 4 spp:", "accelerated output:"] {
        let worst = verified_worst_psnr(&said, heading, side);
        assert!(worst.is_finite() && worst > 5.0, "{said}");
    }

    // A still camera's own image: exact and its own rays.
    let still = retrace(
        &[
            "animate",
            "paper.toml",
            "--width",
            "32",
            "--height",
            "24",
            "--frames",
            "0",
            "-o",
            "out/g_###.png",
            "--verify",
        ],
        dir.path(),
    );
    assert!(still.status.success(), "{}", stderr(&still));
    let said = String::from_utf8_lossy(&still.stdout);
    assert!(!said.contains("reference"), "{said}");
}

/// A killed run (SIGKILL: no chance to clean up) leaves its temporary
/// files; the next run writing into the same folder removes them and says
/// so.
#[test]
fn a_killed_runs_temporary_files_are_removed_by_the_next_run() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper-bounce.toml");
    let run = |frames: &str| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_retrace"));
        command
            .arg("animate")
            .args([scene.to_str().unwrap(), "--width", "160", "--height", "120"])
            .args([
                "--frames",
                frames,
                "-o",
                "out/f_####.png",
                "--gif",
                "out/a.gif",
            ])
            .current_dir(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        command
    };
    let temporaries = || -> Vec<String> {
        std::fs::read_dir(dir.path().join("out"))
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.ends_with(".tmp"))
                    .collect()
            })
            .unwrap_or_default()
    };
    // The GIF is written under a temporary name from the first frame on.
    let mut child = run("0-99").spawn().unwrap();
    let start = Instant::now();
    while temporaries().is_empty() {
        assert!(child.try_wait().unwrap().is_none(), "finished too soon");
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no temporary file"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let left = temporaries();
    assert!(!left.is_empty(), "SIGKILL leaves its temporary files");
    let again = run("0-1").output().unwrap();
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success(), "{err}");
    assert_eq!(temporaries(), Vec::<String>::new());
    assert!(
        err.contains("note: removed ") && err.contains(&left[0]),
        "{err}"
    );
}

/// A dolly moves the eye, which no store keeps samples across: a
/// perspective camera's frames are rendered in full and an equal-angle
/// camera's pan buffer starts again, each saying the eye moved (not that
/// only equal-angle views pan, which would not help).
#[test]
fn a_moving_eye_is_named_as_the_reason_for_full_frames() {
    let dir = paper_case(
        "dolly.toml",
        &format!(
            "[animation]\nframes = 4\n\n{}{}",
            key(0, "position = [0.0, 3.2, 14.0]"),
            key(3, "position = [0.0, 3.2, 10.0]")
        ),
    );
    for camera in ["perspective", "equal-angle"] {
        let stats = format!("{camera}.csv");
        let out = retrace(
            &[
                "animate",
                "dolly.toml",
                "--camera",
                camera,
                "--width",
                "32",
                "--height",
                "24",
                "-o",
                "out/f_#.png",
                "--stats",
                &stats,
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        let reasons: Vec<String> = std::fs::read_to_string(dir.path().join(&stats))
            .unwrap()
            .lines()
            .skip(2)
            .map(|line| line.split(',').nth(2).unwrap_or("").to_string())
            .collect();
        assert_eq!(reasons.len(), 3, "{camera}: {reasons:?}");
        assert!(
            reasons.iter().all(|r| r.contains("eye move")),
            "{camera}: {reasons:?}"
        );
        assert!(
            !stderr(&out).contains("only equal-angle views pan"),
            "{camera}"
        );
    }
}
