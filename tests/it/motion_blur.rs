//! Motion blur: objects move while the shutter is open, each camera
//! sample cast at its own time, and reuse stays exact through it.

use std::path::Path;

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::{Options, Techniques};
use retrace::sampling::PixelSamples;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

/// Pixels a unit of the image plane spans: a 128-pixel-wide image of a
/// 90-degree perspective camera.
const PIXELS_A_UNIT: f64 = 64.0;

/// A white `shape` (a table's lines) at distance 10 straight ahead of a
/// 90-degree perspective camera at the origin, 128x96, on black, lit by
/// the ambient term alone, moving right at `speed` units a frame through
/// `shutter` (an `[animation]` line, or none).
fn moving(shape: &str, speed: f64, shutter: &str) -> Scene {
    let text = format!(
        "[render]\nwidth = 128\nheight = 96\nambient = [1.0, 1.0, 1.0]\nbackground = [0.0, 0.0, 0.0]\n\
         [camera]\nprojection = \"perspective\"\nposition = [0, 0, 0]\nfov = 90\n\
         [material.white]\ndiffuse = [1.0, 1.0, 1.0]\n\
         [[object]]\nname = \"mover\"\nmaterial = \"white\"\n{shape}\n\
         [animation]\nframes = 2\n{shutter}\n\
         [[animation.object]]\nobject = \"mover\"\nframe = 0\ntranslate = [0, 0, 0]\n\
         [[animation.object]]\nobject = \"mover\"\nframe = 1\ntranslate = [{speed}, 0, 0]\n"
    );
    parse_scene_str(&text, Path::new("moving.toml"), &SceneOverrides::default()).unwrap()
}

const BALL: &str = "type = \"sphere\"\ncenter = [0.0, 0.0, -10.0]\nradius = 0.3";
const SQUARE: &str = "type = \"quad\"\nvertices = [[-0.3, -0.3, -10.0], [0.3, -0.3, -10.0], \
                      [0.3, 0.3, -10.0], [-0.3, 0.3, -10.0]]";

/// The width at half its height, in pixels, of the profile of frame 0
/// along its middle rows (48 and 47 averaged): where the profile crosses
/// half its peak, interpolated between pixel centres.
fn middle_width(scene: &Scene, backend: BackendKind) -> f64 {
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    let samples = PixelSamples::new(retrace::sampling::REFERENCE_SAMPLES_PER_PIXEL).unwrap();
    let (frame, _) = retrace::render::render_view_sampled(scene, &scene.camera, samples, &accel);
    let profile: Vec<f64> = (0..128)
        .map(|x| f64::from(frame.get(x, 47).x + frame.get(x, 48).x) / 2.0)
        .collect();
    // The plateau's level: the mean of the values near the largest,
    // which alone would sit on the noise of the shutter's sampling.
    let largest = profile.iter().copied().fold(0.0, f64::max);
    assert!(largest > 0.05, "the mover shows: largest {largest}");
    let top: Vec<f64> = profile
        .iter()
        .copied()
        .filter(|&v| v >= 0.9 * largest)
        .collect();
    let peak = top.iter().sum::<f64>() / top.len() as f64;
    let half = peak / 2.0;
    let first = profile.iter().position(|&v| v >= half).unwrap();
    let last = profile.iter().rposition(|&v| v >= half).unwrap();
    // Pixel x's value is its centre's, x + 0.5.
    let rise = first as f64 - (profile[first] - half) / (profile[first] - profile[first - 1]);
    let fall = last as f64 + (profile[last] - half) / (profile[last] - profile[last + 1]);
    fall - rise
}

on_every_backend! {
    // Moving 2 units a frame at distance 10 (12.8 pixels a frame), a
    // ball or a square 0.6 across (3.84 pixels) open for half a frame
    // sweeps 6.4 pixels: the profile of a shape swept further than its
    // width is a trapezoid whose width at half height is the sweep. With
    // the shutter closed to an instant it is the shape's own width.
    a_shape_moving_through_an_open_shutter_streaks_as_far_as_it_moves(backend) {
        for (name, shape) in [("ball", BALL), ("square", SQUARE)] {
            let sweep = 2.0 / 10.0 * PIXELS_A_UNIT * 0.5;
            let streak = middle_width(&moving(shape, 2.0, "shutter = [0.0, 0.5]"), backend);
            assert!(
                (streak - sweep).abs() <= 1.0,
                "{backend:?}, {name}: a streak {streak:.2} px long, the sweep {sweep:.2}"
            );
            let width = 0.6 / 10.0 * PIXELS_A_UNIT;
            let sharp = middle_width(&moving(shape, 2.0, ""), backend);
            assert!(
                (sharp - width).abs() <= 1.0,
                "{backend:?}, {name}: without a shutter {sharp:.2} px across, the shape {width:.2}"
            );
        }
    }

    // Over the hop's peak (frame 12.5) and its touchdown (25): shutters
    // on either side of the peak sweep the same heights in reverse, so
    // only the motion itself, not where it reaches, tells them apart.
    the_bouncing_ball_with_a_shutter_equals_full_renders_bit_for_bit(backend) {
        let mut scene = crate::common::shipped_at("paper-bounce-blur.toml", 48, 32);
        scene.samples = PixelSamples::new(4).unwrap();
        for frames in [11..15, 23..27] {
            let stats = crate::common::run_exact_reusing_with(
                &scene,
                backend,
                Options::new(Techniques::AUTO, frames),
            );
            assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
        }
    }
}

/// The shutter blurs the shipped bouncing ball (so the exactness test
/// above is not of a still frame's), and a scene without one renders as
/// it did.
#[test]
fn the_shutter_blurs_the_bouncing_ball() {
    let render = |name: &str| {
        let scene = crate::common::shipped_at(name, 64, 48);
        let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        let samples = PixelSamples::new(4).unwrap();
        retrace::render::render_view_sampled(&scene, &scene.camera, samples, &accel).0
    };
    assert!(render("paper-bounce-blur.toml") != render("paper-bounce.toml"));
}

#[test]
fn bad_shutters_name_the_field() {
    let error = |shutter: &str| {
        let text = format!(
            "[camera]\nposition = [0, 0, 0]\nfov = 90\n\
             [[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [0, 0, -5]\nradius = 1\n\
             [animation]\nframes = 2\nshutter = {shutter}\n"
        );
        parse_scene_str(&text, Path::new("bad.toml"), &SceneOverrides::default())
            .err()
            .unwrap_or_else(|| panic!("shutter = {shutter} was accepted"))
            .to_string()
    };
    for (shutter, says) in [
        ("[0.5, 0.5]", "opens before it closes"),
        ("[0.5, -0.5]", "opens before it closes"),
        ("[-0.75, 0.75]", "at most a frame"),
        ("[0.5, 1.25]", "within a frame"),
        ("[0.0, nan]", "must be finite"),
        ("0.5", "animation.shutter"),
    ] {
        let message = error(shutter);
        assert!(
            message.contains("bad.toml") && message.contains("animation.shutter"),
            "{shutter}: {message}"
        );
        assert!(message.contains(says), "{shutter}: {message}");
    }
}
