//! Shared by the integration tests: run a test body on every backend,
//! check accelerated frames against full renders, run the binary.

use std::path::Path;
use std::process::{Command, Output};

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::{Animator, FrameStats, Options, Techniques};
use retrace::scene::{load_scene, parse_scene_str, Scene, SceneOverrides};
use retrace::verify::{Checks, Verifier};

/// Renders every frame of `scene`'s timeline with `techniques`, checks each
/// against a full render of the same frame bit for bit (linear colour and
/// 8-bit output), and returns the frames' stats.
pub fn run_exact(scene: &Scene, backend: BackendKind, techniques: Techniques) -> Vec<FrameStats> {
    let frames = scene.animation.as_ref().unwrap().frames;
    run_exact_with(scene, backend, Options::new(techniques, 0..frames))
}

/// [`run_exact`] with every option given (its frames are rendered).
pub fn run_exact_with(scene: &Scene, backend: BackendKind, options: Options) -> Vec<FrameStats> {
    let mut accel = Accelerator::build(backend, &scene.objects).unwrap();
    let frames = options.frames.clone();
    let mut animator = Animator::new(scene, &mut accel, options);
    let mut all = Vec::new();
    assert!(animator.is_exact(), "only exact runs compare bit for bit");
    let mut verifier = Verifier::new(scene.samples);
    // Against the full render, and against the frame built afresh: a scene
    // posed by the timeline and an accelerator of its own, sharing nothing
    // the loop posed.
    let checks = Checks {
        full: true,
        afresh: true,
        ..Checks::default()
    };
    for frame in frames {
        let output = animator.render(frame).remove(0);
        let check = verifier
            .check_view(&mut animator, frame, 0, &output, checks)
            .unwrap();
        assert_eq!(
            check.differing,
            Some((0, 0)),
            "frame {frame} ({}): pixels differing from its full renders (linear, 8-bit)",
            output.stats.mode
        );
        all.push(output.stats);
    }
    all
}

/// [`run_exact`] where reuse must apply: every frame after the first came
/// from the sample store (not a full render, nor a restart that reused
/// nothing). Without this a test of exactness passes vacuously when reuse
/// silently stops: a full render equals itself.
pub fn run_exact_reusing(
    scene: &Scene,
    backend: BackendKind,
    techniques: Techniques,
) -> Vec<FrameStats> {
    let frames = scene.animation.as_ref().unwrap().frames;
    run_exact_reusing_with(scene, backend, Options::new(techniques, 0..frames))
}

/// [`run_exact_reusing`] with every option given.
pub fn run_exact_reusing_with(
    scene: &Scene,
    backend: BackendKind,
    options: Options,
) -> Vec<FrameStats> {
    let stats = run_exact_with(scene, backend, options);
    for s in &stats[1..] {
        assert!(
            s.mode != retrace::reuse::FrameMode::Full
                && s.reason.is_none()
                && s.work.pixels_reused > 0,
            "frame {} did not reuse: {} ({}), {} pixels reused",
            s.frame,
            s.mode,
            reason(s),
            s.work.pixels_reused
        );
    }
    stats
}

/// Runs each test body once per backend, as `embree::name` and `grid::name`,
/// with `$backend` bound to the backend's `BackendKind`.
macro_rules! on_every_backend {
    ($($name:ident($backend:ident) $body:block)*) => {
        mod embree {
            use super::*;
            $(#[test] fn $name() { let $backend = retrace::accel::BackendKind::Embree; $body })*
        }
        mod grid {
            use super::*;
            $(#[test] fn $name() { let $backend = retrace::accel::BackendKind::Grid; $body })*
        }
    };
}

/// Runs the `retrace` binary with `args` in `dir`.
pub fn retrace(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_retrace"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run retrace")
}

/// [`retrace`], failing the test (with the program's stderr) unless it
/// succeeded.
pub fn retrace_ok(args: &[&str], dir: &Path) -> Output {
    let out = retrace(args, dir);
    assert!(
        out.status.success(),
        "retrace {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Why a frame did not reuse what it kept, in words ("" for no reason).
pub fn reason(stats: &FrameStats) -> String {
    stats.reason.map(|r| r.to_string()).unwrap_or_default()
}

/// `frame` moved one pixel right (its first column repeated): what a
/// misregistered picture looks like, for checking that an error bound
/// rejects it.
pub fn shifted_by_one(frame: &retrace::render::Frame) -> retrace::render::Frame {
    let mut out = frame.clone();
    let width = frame.width as usize;
    for (row, out_row) in frame.pixels.chunks(width).zip(out.pixels.chunks_mut(width)) {
        out_row[1..].copy_from_slice(&row[..width - 1]);
    }
    out
}

/// Property-test cases: `cases`, or sixteen times as many under
/// `make test-deep` (`RETRACE_DEEP` set).
pub fn cases(cases: u32) -> u32 {
    if std::env::var_os("RETRACE_DEEP").is_some() {
        cases * 16
    } else {
        cases
    }
}

/// Skips a test whose tools are missing, saying why; under CI (`CI` set to
/// anything but "false"), where `make test` and `make test-embree4` install
/// every tool, a missing one fails the test instead.
pub fn skip_unless_ci(why: &str) {
    if std::env::var("CI").is_ok_and(|v| v != "false") {
        panic!("{why}");
    }
    eprintln!("skipped: {why}");
}

/// The paper scene (`scenes/paper.toml`) at `width` x `height` with
/// `extra` tables appended.
pub fn paper_with_at(extra: &str, width: u32, height: u32) -> Scene {
    let paper = include_str!("../../scenes/paper.toml");
    parse_scene_str(
        &format!("{paper}\n{extra}"),
        Path::new("scenes/paper.toml"),
        &sized(width, height),
    )
    .unwrap()
}

/// The shipped scene `scenes/name`, its includes spliced in, at `width` x
/// `height`.
pub fn shipped_at(name: &str, width: u32, height: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    load_scene(&path, &sized(width, height)).unwrap()
}

/// The command line's `--width` and `--height`.
fn sized(width: u32, height: u32) -> SceneOverrides {
    SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    }
}

/// Frame `frame` of `scene` (whose output is its viewport) at `samples` a
/// pixel, scored against a full render at `reference` a pixel: the RSVP
/// frame's mode and PSNR, and the direct render's PSNR. The RSVP buffer is
/// checked bit-exact on the way (its samples re-traced afresh).
pub fn viewport_and_direct_psnr(
    scene: &Scene,
    frame: u32,
    samples: u32,
    reference: u32,
) -> (String, f64, f64) {
    use retrace::frame_loop::{Animator, Options, Techniques};
    let mut accel =
        retrace::accel::Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects)
            .unwrap();
    let at_samples = |samples: u32| Scene {
        samples: retrace::sampling::PixelSamples::new(samples).unwrap(),
        ..scene.clone()
    };
    let (reference, sampled) = (at_samples(reference), at_samples(samples));
    let at = |scene: &Scene, techniques: Techniques| Options {
        rsvp: retrace::reuse::rsvp::RsvpKnobs::default_for(scene.samples),
        ..Options::new(techniques, frame..frame + 1)
    };
    let (truth, _) = Animator::new(&reference, &mut accel, at(&reference, Techniques::FULL))
        .render_full(frame, 0, None);
    let (direct, _) = Animator::new(&sampled, &mut accel, at(&sampled, Techniques::FULL))
        .render_full(frame, 0, None);
    let mut rsvp = Animator::new(&sampled, &mut accel, at(&sampled, Techniques::AUTO));
    let output = rsvp.render(frame).remove(0);
    let (compared, differing) = rsvp.verify_store().unwrap();
    assert!(compared > 0 && differing == 0, "{differing} of {compared}");
    let error = |image: &retrace::render::Frame| {
        retrace::metrics::image_error(image, &truth)
            .unwrap()
            .psnr_db
    };
    (
        output.stats.mode.to_string(),
        error(output.frame.as_ref().unwrap()),
        error(&direct),
    )
}
