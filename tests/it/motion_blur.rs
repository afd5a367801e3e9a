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

    // The camera turning 0.2 radians a frame (12.8 pixels at the middle
    // of the image, to within a third of a percent) open for half a frame
    // streaks the ball standing still ahead of it as far as the ball
    // moving 2 units a frame above: 6.4 pixels.
    a_camera_turning_through_an_open_shutter_streaks_what_it_sees(backend) {
        let turning = |shutter: &str| {
            let text = format!(
                "[render]\nwidth = 128\nheight = 96\nambient = [1.0, 1.0, 1.0]\nbackground = [0.0, 0.0, 0.0]\n\
                 [camera]\nprojection = \"perspective\"\nposition = [0, 0, 0]\nfov = 90\n\
                 [material.white]\ndiffuse = [1.0, 1.0, 1.0]\n\
                 [[object]]\nname = \"ball\"\nmaterial = \"white\"\n{BALL}\n\
                 [animation]\nframes = 2\n{shutter}\n\
                 [[animation.camera]]\nframe = 0\nyaw = 0\n\
                 [[animation.camera]]\nframe = 1\nyaw = {}\n",
                0.2f64.to_degrees()
            );
            let mut scene =
                parse_scene_str(&text, Path::new("turning.toml"), &SceneOverrides::default()).unwrap();
            let animation = scene.animation.clone().unwrap();
            scene.camera_motion = animation.camera_motion(&scene.camera, 0);
            scene
        };
        let sweep = 0.2 * PIXELS_A_UNIT * 0.5;
        let streak = middle_width(&turning("shutter = [0.0, 0.5]"), backend);
        assert!(
            (streak - sweep).abs() <= 1.0,
            "{backend:?}: a streak {streak:.2} px long, the sweep {sweep:.2}"
        );
        let still = turning("");
        assert!(still.camera_motion.is_none());
        let sharp = middle_width(&still, backend);
        let width = 0.6 / 10.0 * PIXELS_A_UNIT;
        assert!((sharp - width).abs() <= 1.0, "{backend:?}: without a shutter {sharp:.2} px");
    }

    // A steady pan with the shutter open keeps its samples: at a given
    // shutter time a turn at one rate shifts every ray alike in every
    // frame. Frames whose shutter reaches past a key (where the rate
    // changes) restart, with the reason; all equal their full renders.
    a_steady_pan_with_the_shutter_open_keeps_its_samples_exactly(backend) {
        let mut scene = crate::common::paper_with_at(
            "[animation]\nframes = 10\nshutter = [-0.25, 0.25]\n\
             [[animation.camera]]\nframe = 0\nyaw = 0\n\
             [[animation.camera]]\nframe = 8\nyaw = 20\n",
            64,
            48,
        );
        scene.samples = PixelSamples::new(4).unwrap();
        let stats = crate::common::run_exact(&scene, backend, Techniques::AUTO);
        let reasons: Vec<String> = stats.iter().map(crate::common::reason).collect();
        let moves_otherwise = |frame: usize| reasons[frame].contains("the camera moves otherwise");
        // Frame 0's shutter opens before the first key, frame 8's closes
        // after the last; frame 9 holds still.
        for frame in [1, 8, 9] {
            assert!(moves_otherwise(frame), "frame {frame}: {reasons:?}");
        }
        for s in &stats[2..8] {
            assert!(s.reason.is_none() && s.work.pixels_reused > 0, "{reasons:?}");
            assert_eq!(s.mode.as_str(), "pan");
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
    // Open for the whole frame, a light moving at constant speed lights
    // the scene as the mean of where it stands over the frame: shading
    // and shadows sweep with it. The light of the frame's instant alone
    // is far from that mean.
    a_light_moving_through_an_open_shutter_lights_as_the_mean_of_its_instants(backend) {
        let render = |scene: &Scene| {
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            retrace::render::render_view_sampled(scene, &scene.camera, scene.samples, &accel).0
        };
        let posed = |shutter: &str| {
            let mut scene = sweeping_light(shutter);
            let animation = scene.animation.clone().unwrap();
            animation.pose(&mut scene.objects, &mut scene.lights, 0);
            scene
        };
        let blurred = render(&posed("shutter = [0.0, 1.0]"));
        assert!(posed("shutter = [0.0, 1.0]").lights[0].motion.is_some());
        let instant = render(&posed(""));
        let instants = 16;
        let mut mean = retrace::render::Frame::new(instant.width, instant.height);
        let still = sweeping_light("");
        let track = &still.animation.as_ref().unwrap().lights[0];
        for k in 0..instants {
            let mut scene = still.clone();
            let time = (f64::from(k) + 0.5) / f64::from(instants);
            scene.lights[0] = track.light_at_time(time, scene.lights[0].shape);
            let image = render(&scene);
            for (sum, p) in mean.pixels.iter_mut().zip(&image.pixels) {
                *sum += *p / instants as f32;
            }
        }
        let blur_error = mean_difference(&blurred, &mean);
        let instant_error = mean_difference(&instant, &mean);
        assert!(
            blur_error < 0.2 * instant_error,
            "{backend:?}: blurred {blur_error:.5} from the mean of the instants, \
             the frame's instant {instant_error:.5}"
        );
    }

    // A light still for two frames, then sweeping, and another changing
    // colour while the shutter is open: frames reused through OSTC equal
    // their full renders bit for bit.
    moving_lights_with_a_shutter_keep_reuse_exact(backend) {
        let mut scene = crate::common::paper_with_at(
            "[animation]\nframes = 6\nshutter = [-0.25, 0.25]\n\
             [[animation.light]]\nlight = 0\nframe = 0\n\
             [[animation.light]]\nlight = 0\nframe = 2\n\
             [[animation.light]]\nlight = 0\nframe = 5\nposition = [-4.0, 10.0, 12.0]\n\
             [[animation.light]]\nlight = 1\nframe = 3\n\
             [[animation.light]]\nlight = 1\nframe = 5\ncolor = [1.0, 0.3, 0.2]\n",
            64,
            48,
        );
        scene.samples = PixelSamples::new(4).unwrap();
        let stats = crate::common::run_exact_reusing(&scene, backend, Techniques::AUTO);
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
    }
}

/// The paper scene at 64x48 with its first light swept from x = -9 to 9
/// between frames 0 and 1 and `shutter` (an `[animation]` line, or none).
fn sweeping_light(shutter: &str) -> Scene {
    let mut scene = crate::common::paper_with_at(
        &format!(
            "[animation]\nframes = 2\n{shutter}\n\
             [[animation.light]]\nlight = 0\nframe = 0\nposition = [-9.0, 14.0, 10.0]\n\
             [[animation.light]]\nlight = 0\nframe = 1\nposition = [9.0, 14.0, 10.0]\n"
        ),
        64,
        48,
    );
    scene.samples = PixelSamples::new(16).unwrap();
    scene
}

/// The mean absolute difference, over every channel of every pixel, of
/// two images.
fn mean_difference(a: &retrace::render::Frame, b: &retrace::render::Frame) -> f64 {
    let (w, h) = (a.width, a.height);
    let mut sum = 0.0;
    for y in 0..h {
        for x in 0..w {
            let d = a.get(x, y) - b.get(x, y);
            sum += f64::from(d.x.abs() + d.y.abs() + d.z.abs());
        }
    }
    sum / f64::from(3 * w * h)
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

/// A zoomed viewport of a camera turning through the shutter averages
/// buffer samples each cast at its own time. Those times are stratified
/// across neighbouring samples of every pyramid level, as a direct
/// render's are across a pixel's sub-samples, so against a converged
/// reference the viewport is no worse than the direct render at the same
/// samples (the margin of 0.25 dB); drawn at random it is worse.
#[test]
fn blurred_viewports_are_no_worse_than_direct_renders_at_the_same_samples() {
    let mut scene = crate::common::shipped_at("paper-all-blur.toml", 320, 240);
    scene.viewports[0].viewport.width = 320;
    scene.viewports[0].viewport.height = 240;
    // Zoomed about twofold, the world streaking a few pixels.
    let (mode, rsvp_db, direct_db) = crate::common::viewport_and_direct_psnr(&scene, 80, 4, 64);
    assert!(mode.starts_with("rsvp"));
    assert!(
        rsvp_db >= direct_db - 0.25,
        "RSVP {rsvp_db:.2} dB, direct {direct_db:.2} dB"
    );
}
