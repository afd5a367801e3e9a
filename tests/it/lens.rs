//! Depth of field: a thin lens at the eye whose rays are anchored to the
//! world, so reuse stays exact through it.

use std::path::Path;

use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::{Options, Techniques};
use retrace::sampling::PixelSamples;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

/// A white ball of radius `radius` at distance 10 straight ahead of a
/// 90-degree perspective camera at the origin, 128x96, on black, lit by
/// the ambient term alone (so it shows white), through `lens`.
fn ball_through(lens: &str, radius: f64) -> Scene {
    let text = format!(
        "[render]\nwidth = 128\nheight = 96\nambient = [1.0, 1.0, 1.0]\nbackground = [0.0, 0.0, 0.0]\n\
         [camera]\nprojection = \"perspective\"\nposition = [0, 0, 0]\nfov = 90\n{lens}\n\
         [material.white]\ndiffuse = [1.0, 1.0, 1.0]\n\
         [[object]]\ntype = \"sphere\"\nname = \"ball\"\nmaterial = \"white\"\n\
         center = [0.0, 0.0, -10.0]\nradius = {radius}\n"
    );
    parse_scene_str(&text, Path::new("ball.toml"), &SceneOverrides::default()).unwrap()
}

/// The diameter, in pixels, of the disc the ball images as: the pixels
/// brighter than half its middle's level, as a disc's area.
fn disc_diameter(scene: &Scene, backend: BackendKind) -> f64 {
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    let samples = PixelSamples::new(retrace::sampling::REFERENCE_SAMPLES_PER_PIXEL).unwrap();
    let (frame, _) = retrace::render::render_view_sampled(scene, &scene.camera, samples, &accel);
    let middle: Vec<f32> = [(63, 47), (64, 47), (63, 48), (64, 48)]
        .iter()
        .map(|&(x, y)| frame.get(x, y).x)
        .collect();
    let level = middle.iter().sum::<f32>() / 4.0;
    assert!(level > 0.05, "the disc's middle is lit: {middle:?}");
    let bright = frame.pixels.iter().filter(|p| p.x > 0.5 * level).count();
    2.0 * (bright as f64 / std::f64::consts::PI).sqrt()
}

on_every_backend! {
    // Focused at 2.5 with a lens of radius 0.25, a point at 10 blurs into
    // a disc of angular radius 0.25 x (1/2.5 - 1/10) = 0.075: 9.6 pixels
    // across at 64 pixels a unit of the image plane. In focus at 10, the
    // ball shows its own size (0.03 in angle: 3.8 pixels).
    an_out_of_focus_ball_images_as_the_thin_lens_circle_of_confusion(backend) {
        let f_px = 64.0;
        let radius = 0.3;
        let blurred = disc_diameter(
            &ball_through("aperture = 0.25\nfocus_distance = 2.5", radius),
            backend,
        );
        let confusion = 2.0 * f_px * (0.25f64 * (1.0 / 2.5 - 1.0 / 10.0)).tan();
        assert!(
            (blurred - confusion).abs() <= 1.0,
            "{backend:?}: a disc {blurred:.2} px across, the circle of confusion {confusion:.2}"
        );
        let sharp = disc_diameter(
            &ball_through("aperture = 0.25\nfocus_distance = 10", radius),
            backend,
        );
        let ball = 2.0 * f_px * (radius / 10.0f64).asin().tan();
        assert!(
            (sharp - ball).abs() <= 1.0,
            "{backend:?}: in focus {sharp:.2} px across, the ball {ball:.2}"
        );
    }

    pans_through_a_lens_equal_full_renders_bit_for_bit(backend) {
        let mut scene = paper_with(
            "[animation]\nframes = 5\n[[animation.camera]]\nframe = 0\nyaw = 0.0\npitch = -9.0\n\
             [[animation.camera]]\nframe = 4\nyaw = 30.0\npitch = -6.0\n",
        );
        scene.samples = PixelSamples::new(4).unwrap();
        let stats = crate::common::run_exact_reusing_with(
            &scene,
            backend,
            Options::new(Techniques::AUTO, 0..5),
        );
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan"));
    }

    a_moving_ball_through_a_lens_equals_full_renders_bit_for_bit(backend) {
        let mut scene = shipped_with_lens("paper-bounce.toml");
        scene.samples = PixelSamples::new(4).unwrap();
        let stats = crate::common::run_exact_reusing_with(
            &scene,
            backend,
            Options::new(Techniques::AUTO, 0..5),
        );
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
    }
}

/// The lens the paper-scene tests look through: focused on the mirror,
/// blurring the checkerboard's far end.
const PAPER_LENS: retrace::camera::Lens = retrace::camera::Lens {
    aperture: 0.15,
    focus_distance: 6.0,
};

/// The paper scene at 48x32 with `extra` tables, through [`PAPER_LENS`].
fn paper_with(extra: &str) -> Scene {
    Scene {
        lens: Some(PAPER_LENS),
        ..crate::common::paper_with_at(extra, 48, 32)
    }
}

/// A shipped scene at 48x32, through [`PAPER_LENS`].
fn shipped_with_lens(name: &str) -> Scene {
    Scene {
        lens: Some(PAPER_LENS),
        ..crate::common::shipped_at(name, 48, 32)
    }
}

/// A lens changes the picture (so the exactness tests above are not of a
/// pinhole's), and an aperture of 0 is the pinhole, bit for bit.
#[test]
fn a_lens_blurs_and_an_aperture_of_zero_is_a_pinhole() {
    let render = |lens: &str| {
        let scene = ball_through(lens, 0.3);
        let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        retrace::render::render_view_sampled(
            &scene,
            &scene.camera,
            PixelSamples::new(4).unwrap(),
            &accel,
        )
        .0
    };
    let pinhole = render("");
    assert!(render("aperture = 0\nfocus_distance = 3") == pinhole);
    assert!(render("aperture = 0.1\nfocus_distance = 3") != pinhole);
}

#[test]
fn bad_lenses_name_the_field() {
    let error = |lens: &str| {
        let text = format!("[camera]\nposition = [0, 1, 5]\nfov = 60\n{lens}\n");
        parse_scene_str(&text, Path::new("lens.toml"), &SceneOverrides::default())
            .unwrap_err()
            .to_string()
    };
    for (lens, field, words) in [
        (
            "aperture = -0.1\nfocus_distance = 2",
            "camera.aperture",
            "at least 0",
        ),
        (
            "aperture = 0.1\nfocus_distance = 0",
            "camera.focus_distance",
            "above 0",
        ),
        ("aperture = 0.1", "camera.focus_distance", "look_at"),
    ] {
        let message = error(lens);
        assert!(
            message.contains("lens.toml") && message.contains(field) && message.contains(words),
            "{lens:?}: {message}"
        );
    }
    // Focused where it looks when no distance is given.
    let text = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -4]\nfov = 60\naperture = 0.1\n";
    let scene = parse_scene_str(text, Path::new("lens.toml"), &SceneOverrides::default()).unwrap();
    assert_eq!(scene.lens.map(|l| l.focus_distance), Some(4.0));
}

/// RSVP serves a viewport through a lens: its buffer's samples are lens
/// rays of the lattice's directions, each still what a fresh trace of it
/// gives (the check `--verify` makes after every frame), while a ball
/// bounces through the blur (paper-all: pan, zoom and OSTC at once).
#[test]
fn a_zoom_through_a_lens_keeps_its_buffer_exact() {
    let dir = tempfile::tempdir().unwrap();
    let all = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper-all.toml");
    let camera = "[camera]\nprojection = \"equal-angle\"\nposition = [0.0, 3.2, 14.0]\n\
                  pitch = -9.0\nfov = 100.0\naperture = 0.15\nfocus_distance = 12.0\n";
    let scene = dir.path().join("all-lens.toml");
    std::fs::write(&scene, format!("include = {all:?}\n{camera}")).unwrap();
    let out = crate::common::retrace_ok(
        &[
            "animate",
            scene.to_str().unwrap(),
            "--frames",
            "0-3",
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "4",
            "-o",
            "out/f_####.png",
            "--verify",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let checked = stdout
        .lines()
        .find(|l| l.starts_with("verify: buffer samples re-traced at 4 frame(s)"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(checked.ends_with(" 0 differ"), "{checked}");
}

/// A focus pull keyed on the camera while a ball bounces: each frame is
/// rendered through the lens its keys give (bit for bit a full render of
/// it), frames whose lens is unchanged keep what OSTC leaves of the frame
/// before, and a frame whose lens changed starts again, saying why (OSTC,
/// which follows moving objects, would keep samples of the old lens).
#[test]
fn a_keyed_focus_pull_restarts_where_the_lens_changes_and_reuses_elsewhere() {
    let mut scene = crate::common::paper_with_at(
        "[[object]]\ntype = \"sphere\"\nname = \"ball\"\ncenter = [-2.6, 0.5, 3.0]\nradius = 0.5\n\
         [animation]\nframes = 6\n\
         [[animation.bounce]]\nobject = \"ball\"\nheight = 2.0\nperiod = 25\n\
         [[animation.camera]]\nframe = 0\naperture = 0.15\nfocus_distance = 4.0\n\
         [[animation.camera]]\nframe = 2\n\
         [[animation.camera]]\nframe = 4\nfocus_distance = 9.0\n",
        48,
        32,
    );
    scene.samples = PixelSamples::new(4).unwrap();
    let animation = scene.animation.clone().unwrap();
    let focus = |frame| animation.lens_at(scene.lens, frame).unwrap().focus_distance;
    assert_eq!(
        [focus(0), focus(2), focus(3), focus(5)],
        [4.0, 4.0, 6.5, 9.0]
    );
    let stats = crate::common::run_exact_with(
        &scene,
        BackendKind::Embree,
        Options::new(Techniques::AUTO, 0..6),
    );
    let reasons: Vec<String> = stats.iter().map(crate::common::reason).collect();
    for frame in [3, 4] {
        assert!(
            reasons[frame].contains("lens"),
            "frame {frame}: {:?}",
            reasons[frame]
        );
    }
    for frame in [1, 2, 5] {
        assert!(
            stats[frame].mode.as_str() != "full" && stats[frame].reason.is_none(),
            "frame {frame} reuses: {} {:?}",
            stats[frame].mode,
            reasons[frame]
        );
    }
}

#[test]
fn bad_lens_keys_name_the_key() {
    let error = |keys: &str| {
        let text = format!(
            "[camera]\nposition = [0, 1, 5]\nfov = 60\n[animation]\nframes = 3\n\
             [[animation.camera]]\nframe = 0\n[[animation.camera]]\nframe = 2\n{keys}\n"
        );
        parse_scene_str(&text, Path::new("keys.toml"), &SceneOverrides::default())
            .unwrap_err()
            .to_string()
    };
    for (keys, field, words) in [
        (
            "aperture = -1",
            "animation.camera[1].aperture",
            "at least 0",
        ),
        (
            "aperture = 0.1\nfocus_distance = -2",
            "animation.camera[1].focus_distance",
            "above 0",
        ),
        (
            "aperture = 0.1",
            "animation.camera[1].focus_distance",
            "needs a distance to focus at",
        ),
    ] {
        let message = error(keys);
        assert!(
            message.contains("keys.toml") && message.contains(field) && message.contains(words),
            "{keys:?}: {message}"
        );
    }
}
