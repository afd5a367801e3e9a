//! Pans at more than one sample a pixel snap to the strata of the
//! lattice's cells: every frame stays a bit-exact render of a camera at
//! most half a stratum from the keyed one, and a slow pan moves every
//! frame instead of in whole-pixel jumps.

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::{Animator, FrameStats, Options, Techniques};
use retrace::reuse::pan::FractionalPan;
use retrace::scene::Scene;

use crate::animate::{key, paper_with_keys_at};

/// The paper lattice's angle a sample at 64 px over 100 degrees: 232
/// columns a turn.
const STEP_DEG: f64 = 360.0 / 232.0;

/// The small paper scene at `spp`, panned `pixels_a_frame` across and
/// `pixels_down` down a frame over `frames` frames, with a bouncing ball
/// when `ball` is set.
fn slow_pan(spp: u32, frames: u32, pixels_a_frame: f64, pixels_down: f64, ball: bool) -> Scene {
    let last = frames - 1;
    let yaw = f64::from(last) * pixels_a_frame * STEP_DEG;
    let pitch = -f64::from(last) * pixels_down * STEP_DEG;
    let mut text =
        key(0, "yaw = 0.0\npitch = 0.0") + &key(last, &format!("yaw = {yaw}\npitch = {pitch}"));
    if ball {
        text += "[[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 4\n\n\
                 [[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [-0.6, 0.5, 3.0]\n\
                 radius = 0.5\nmaterial = \"red\"\n";
    }
    paper_with_keys_at(&text, frames, Some(spp))
}

/// The largest snap of `stats`' frames, in samples of the lattice.
fn largest_snap(stats: &[FrameStats]) -> f64 {
    stats
        .iter()
        .map(|s| {
            let (yaw, pitch) = s.snap_error_deg();
            yaw.abs().max(pitch.abs()) / STEP_DEG
        })
        .fold(0.0, f64::max)
}

fn snapping(fractional: FractionalPan, frames: u32) -> Options {
    Options {
        fractional_pan: fractional,
        ..Options::new(Techniques::AUTO, 0..frames)
    }
}

#[test]
fn slow_pans_at_4_spp_snap_to_strata_and_stay_bit_exact() {
    // A quarter pixel a frame: half a stratum of a 2 x 2 pixel's.
    let scene = slow_pan(4, 9, 0.25, 0.0, false);
    let stats = crate::common::run_exact_reusing_with(
        &scene,
        BackendKind::Embree,
        snapping(FractionalPan::Snap, 9),
    );
    let snap = largest_snap(&stats);
    assert!(snap > 0.0 && snap <= 0.25 + 1e-9, "{snap} samples off");
    // The shown view moves with the keyed one: each frame's motion is the
    // keyed quarter pixel, give or take half a stratum.
    for pair in stats.windows(2) {
        let shown = |s: &FrameStats| s.snap_error_deg().0 / STEP_DEG;
        let motion = 0.25 + shown(&pair[1]) - shown(&pair[0]);
        assert!(
            (motion - 0.25).abs() <= 0.25 + 1e-9,
            "frame {}: {motion}",
            pair[1].frame
        );
    }
}

#[test]
fn snap_samples_snaps_slow_pans_at_4_spp_to_whole_samples() {
    let scene = slow_pan(4, 9, 0.25, 0.0, false);
    let stats = crate::common::run_exact_reusing_with(
        &scene,
        BackendKind::Embree,
        snapping(FractionalPan::SnapSamples, 9),
    );
    let snap = largest_snap(&stats);
    assert!(snap > 0.25 && snap <= 0.5 + 1e-9, "{snap} samples off");
    // Frames 0 and 2, half a pixel apart, show one whole-sample view: the
    // pan judders; snapped to strata, they differ.
    let mut accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
    for (fractional, judders) in [
        (FractionalPan::SnapSamples, true),
        (FractionalPan::Snap, false),
    ] {
        let mut animator = Animator::new(&scene, &mut accel, snapping(fractional, 3));
        let first = animator.render(0).remove(0).frame.unwrap();
        let third = animator.render(2).remove(0).frame.unwrap();
        let same = retrace::metrics::count_differences(&first, &third).unwrap() == 0;
        assert_eq!(same, judders, "{fractional:?}");
    }
}

on_every_backend! {
    pans_between_strata_by_whole_and_part_pixels_stay_bit_exact(backend) {
        // 16 samples a pixel (strata a quarter pixel), panned 1.3 pixels
        // across and 0.3 down a frame, a ball bouncing: OSTC erases
        // regions of strata as the view moves between them.
        let scene = slow_pan(16, 6, 1.3, 0.3, true);
        let stats = crate::common::run_exact_reusing_with(&scene, backend, snapping(FractionalPan::Snap, 6));
        assert!(stats[1..].iter().all(|s| s.mode.to_string() == "pan+ostc"), "{:?}",
            stats.iter().map(|s| s.mode.to_string()).collect::<Vec<_>>());
        assert!(stats[1..].iter().any(|s| s.ostc.samples_nulled > 0));
        let snap = largest_snap(&stats);
        assert!(snap > 0.0 && snap <= 0.125 + 1e-9, "{snap} samples off");
    }
}

#[test]
fn a_run_of_later_frames_of_a_slow_pan_at_4_spp_equals_one_long_run() {
    let scene = slow_pan(4, 8, 0.3, 0.1, false);
    crate::animate::assert_later_frames_equal_one_long_run(&scene, 8, 5);
}

/// `--fractional-pan blend-strata`: the keyed camera itself, each pixel's
/// box moved between strata; exact against its full render, at one sample
/// a pixel too, and never off the keys.
#[test]
fn blended_pans_stay_bit_exact_and_show_the_keyed_camera() {
    for spp in [1, 16] {
        let scene = slow_pan(spp, 6, 0.3, 0.1, true);
        let stats = crate::common::run_exact_reusing_with(
            &scene,
            BackendKind::Embree,
            snapping(FractionalPan::BlendStrata, 6),
        );
        assert_eq!(largest_snap(&stats), 0.0, "{spp} spp");
    }
    // Snapped and blended frames differ where the keys fall between strata.
    let scene = slow_pan(4, 3, 0.3, 0.1, false);
    let mut accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
    let [snapped, blended] = [FractionalPan::Snap, FractionalPan::BlendStrata].map(|fractional| {
        let mut animator = Animator::new(&scene, &mut accel, snapping(fractional, 3));
        animator.render(0);
        animator.render(1).remove(0).frame.unwrap()
    });
    let differing = retrace::metrics::count_differences(&snapped, &blended).unwrap();
    assert!(differing > 0);
}

/// `--verify` of a blended pan: exact against its full render, and, as it
/// is not the camera's own rays, scored against the converged reference
/// beside the full render.
#[test]
fn verify_scores_a_blended_pan_against_the_reference() {
    let dir = crate::animate::pan_case("");
    let args = [
        "animate", "pan.toml", "--width", "64", "--height", "48", "--spp", "4",
    ];
    let more = [
        "--fractional-pan",
        "blend-strata",
        "-o",
        "out/f_###.png",
        "--verify",
    ];
    let out = crate::common::retrace_ok(&[&args[..], &more[..]].concat(), dir.path());
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("verify: every frame equals its full render bit for bit\n"),
        "{said}"
    );
    assert!(
        said.contains("verify (blended, against the camera's own unsnapped rays)"),
        "{said}"
    );
    let heading = "verify (against a 64-spp reference, frames 0, 5): ";
    let full = crate::animate::verified_worst_psnr(&said, heading, "full render at 4 spp:");
    let output = crate::animate::verified_worst_psnr(&said, heading, "accelerated output:");
    assert!(output >= full - 0.5, "{said}");
}

/// The bench takes `--fractional-pan` for its pans, and refuses it where
/// nothing measured pans.
#[test]
fn bench_refuses_a_fractional_pan_where_nothing_pans() {
    let dir = tempfile::tempdir().unwrap();
    for only in ["E2", "frame"] {
        let args = ["bench", "--only", only, "--fractional-pan", "blend-strata"];
        let out = crate::common::retrace(&args, dir.path());
        let said = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{said}");
        assert!(
            said.contains("--fractional-pan has nothing to act on"),
            "{said}"
        );
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// A pan that comes to rest between cells while a ball bounces: the
/// resting frames copy what was resolved at their offset before, and
/// the entries whose strata OSTC erased are resolved again.
#[test]
fn a_pan_at_rest_between_cells_keeps_resolving_what_the_ball_changes() {
    let yaw = 3.0 * 1.3 * STEP_DEG;
    let keys = key(0, "yaw = 0.0\npitch = 0.0")
        + &key(3, &format!("yaw = {yaw}\npitch = -0.5"))
        + &key(9, &format!("yaw = {yaw}\npitch = -0.5"));
    let ball = "[[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 4\n\n\
                [[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [-0.6, 0.5, 3.0]\n\
                radius = 0.5\nmaterial = \"red\"\n";
    let scene = paper_with_keys_at(&(keys + ball), 10, Some(4));
    let stats = crate::common::run_exact_reusing_with(
        &scene,
        BackendKind::Embree,
        snapping(FractionalPan::Snap, 10),
    );
    let rest = &stats[4..];
    assert!(rest
        .iter()
        .all(|s| s.snap_error_deg() == rest[0].snap_error_deg()));
    assert_ne!(rest[0].snap_error_deg(), (0.0, 0.0));
    assert!(rest.iter().any(|s| s.ostc.samples_nulled > 0));
}
