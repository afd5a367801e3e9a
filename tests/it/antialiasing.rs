//! Antialiasing: several stratified sub-samples a pixel, world-anchored, so
//! reused frames stay exact.

use std::path::Path;

use retrace::frame_loop::{Options, Techniques};
use retrace::sampling::PixelSamples;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

/// `scenes/name` with its include spliced in, at `width` x `height`.
fn shipped(name: &str, width: u32, height: u32) -> Scene {
    crate::common::shipped_at(name, width, height)
}

/// The paper scene with `extra` tables, at 48x32.
fn paper_with(extra: &str) -> Scene {
    crate::common::paper_with_at(extra, 48, 32)
}

fn four() -> PixelSamples {
    PixelSamples::new(4).unwrap()
}

on_every_backend! {
    antialiased_pans_equal_full_renders_bit_for_bit(backend) {
        let mut scene = paper_with(
            "[animation]\nframes = 6\n[[animation.camera]]\nframe = 0\nyaw = 0.0\npitch = -9.0\n\
             [[animation.camera]]\nframe = 5\nyaw = 40.0\npitch = -6.0\n",
        );
        scene.samples = four();
        let options = Options::new(Techniques::AUTO, 0..6);
        let stats = crate::common::run_exact_reusing_with(&scene, backend, options);
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan"));
        // Samples count cells; the rays, their four sub-samples each.
        assert_eq!(stats[0].work.samples_traced * 4, stats[0].work.rays.primary);
    }

    antialiased_moving_objects_equal_full_renders_bit_for_bit(backend) {
        let mut scene = shipped("paper-bounce.toml", 48, 32);
        scene.samples = four();
        let options = Options::new(Techniques::AUTO, 0..5);
        let stats = crate::common::run_exact_reusing_with(&scene, backend, options);
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
    }

    // Strata of 3 x 3 straddle groups of cells, of 4 x 4 split a cell in
    // two groups; 2 and 8 sub-samples are not squares: no strata kept.
    moving_objects_equal_full_renders_with_strata_of_every_shape(backend) {
        for count in [2, 8, 9, 16] {
            let mut scene = shipped("paper-bounce.toml", 24, 16);
            scene.samples = PixelSamples::new(count).unwrap();
            let options = Options::new(Techniques::AUTO, 2..5);
            let stats = crate::common::run_exact_reusing_with(&scene, backend, options);
            assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"), "{count} a pixel");
        }
    }
}

/// With four sub-samples a pixel, OSTC erases and re-traces groups of
/// strata (two pixels each), not groups of whole pixels (eight, the finest
/// regions at one sample a pixel): a moving ball then re-traces fewer
/// pixels at four samples a pixel than at one, though each of its pixels
/// changes where any of four sub-samples does rather than one.
#[test]
fn antialiased_ostc_re_traces_groups_of_strata() {
    let traced = |count: u32| -> u64 {
        let mut scene = shipped("paper-bounce.toml", 160, 120);
        scene.samples = PixelSamples::new(count).unwrap();
        let options = Options::new(Techniques::AUTO, 0..6);
        let stats = crate::common::run_exact_reusing_with(
            &scene,
            retrace::accel::BackendKind::Embree,
            options,
        );
        stats[1..].iter().map(|s| s.work.samples_traced).sum()
    };
    let (one, four) = (traced(1), traced(4));
    assert!(
        four < one,
        "pixels re-traced at 4 samples a pixel: {four}, at 1: {one}"
    );
}

/// A converged reference: 256 stratified sub-samples a pixel.
fn reference() -> PixelSamples {
    PixelSamples::new(retrace::sampling::REFERENCE_SAMPLES_PER_PIXEL).unwrap()
}

/// A scene of `objects` seen by a 90-degree perspective camera at the
/// origin looking down -z, 64x48, lit by the ambient term alone (white):
/// a surface shows its diffuse colour, the sky the background.
fn flat_scene(background: [f32; 3], objects: &str) -> Scene {
    let text = format!(
        "[render]\nwidth = 64\nheight = 48\nambient = [1.0, 1.0, 1.0]\nbackground = {background:?}\n\
         [camera]\nprojection = \"perspective\"\nposition = [0, 0, 0]\nfov = 90\n{objects}"
    );
    parse_scene_str(&text, Path::new("flat.toml"), &SceneOverrides::default()).unwrap()
}

#[test]
fn a_flat_coloured_scene_s_reference_is_the_colour() {
    // Binary fractions: the mean of 256 equal colours is the colour itself.
    let scene = flat_scene([0.25, 0.5, 0.75], "");
    let accel =
        retrace::accel::Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects)
            .unwrap();
    let (frame, rays) =
        retrace::render::render_view_sampled(&scene, &scene.camera, reference(), &accel);
    assert_eq!(rays.primary, 64 * 48 * 256);
    assert!(
        frame
            .pixels
            .iter()
            .all(|p| *p == glam::Vec3::new(0.25, 0.5, 0.75)),
        "{:?}",
        frame
            .pixels
            .iter()
            .find(|p| **p != glam::Vec3::new(0.25, 0.5, 0.75))
    );
}

#[test]
fn an_edge_between_two_colours_converges_to_its_analytic_coverage() {
    // A white wall at z = -10 left of x = x0, black sky beyond: the camera
    // maps x to column 32 + 3.2 x (90 degrees over 64 px), so an edge at
    // column 20 + f covers f of pixel 20. Several fractions, the rows all
    // alike (the edge is vertical).
    for coverage in [0.1f32, 0.3, 0.5, 0.77, 0.93] {
        let x0 = (20.0 + f64::from(coverage) - 32.0) / 3.2;
        let wall = format!(
            "[material.white]\ndiffuse = [1.0, 1.0, 1.0]\n\
             [[object]]\ntype = \"quad\"\nname = \"wall\"\nmaterial = \"white\"\n\
             vertices = [[-100.0, -100.0, -10.0], [{x0}, -100.0, -10.0], [{x0}, 100.0, -10.0], [-100.0, 100.0, -10.0]]\n"
        );
        let scene = flat_scene([0.0, 0.0, 0.0], &wall);
        for backend in [
            retrace::accel::BackendKind::Embree,
            retrace::accel::BackendKind::Grid,
        ] {
            let accel = retrace::accel::Accelerator::build(backend, &scene.objects).unwrap();
            let (frame, _) =
                retrace::render::render_view_sampled(&scene, &scene.camera, reference(), &accel);
            for y in 0..48 {
                let value = |x: u32| frame.get(x, y).x;
                assert_eq!(value(19), 1.0, "left of the edge");
                assert_eq!(value(21), 0.0, "right of the edge");
                let error = (value(20) - coverage).abs();
                assert!(
                    error <= 1.0 / 255.0,
                    "{backend:?}: coverage {coverage}, row {y}: {} ({error})",
                    value(20)
                );
            }
        }
    }
}

/// An RSVP viewport's pixel on an edge between white and black shows the
/// share of the pixel the white side covers, in linear colour as a
/// direct render averages its samples: the pixel box weighs each buffer
/// sample's cell by how much of it the pixel covers, so on a lattice `d`
/// samples a pixel side the coverage is off by at most about half a cell,
/// 1 / (2 d). Blending the samples' sRGB codes instead would be off by up
/// to 0.29 (half covered showing 0.21).
#[test]
fn an_rsvp_viewport_of_an_edge_shows_its_coverage_in_linear_colour() {
    for coverage in [0.3f32, 0.5, 0.77] {
        // A wall at z = -10 left of x = x0, black sky beyond, seen by a
        // 90-degree viewport 64 px wide looking down -z: the viewport maps
        // x to column 32 + 3.2 x, so the edge covers `coverage` of column
        // 20.
        let x0 = (20.0 + f64::from(coverage) - 32.0) / 3.2;
        let text = format!(
            "[render]\nwidth = 64\nheight = 48\nambient = [1.0, 1.0, 1.0]\nbackground = [0.0, 0.0, 0.0]\n\
             [camera]\nprojection = \"equal-angle\"\nposition = [0, 0, 0]\nfov = 90\n\
             [material.white]\ndiffuse = [1.0, 1.0, 1.0]\n\
             [[object]]\ntype = \"quad\"\nname = \"wall\"\nmaterial = \"white\"\n\
             vertices = [[-100.0, -100.0, -10.0], [{x0}, -100.0, -10.0], [{x0}, 100.0, -10.0], [-100.0, 100.0, -10.0]]\n\
             [[viewport]]\nname = \"edge\"\nwidth = 64\nheight = 48\nfov = 90.0\n"
        );
        let mut scene =
            parse_scene_str(&text, Path::new("edge.toml"), &SceneOverrides::default()).unwrap();
        scene.samples = four();
        let mut accel =
            retrace::accel::Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects)
                .unwrap();
        // 5-10 buffer samples a pixel side: the coverage within 0.1.
        let oversample = 2.5;
        let knobs = retrace::reuse::rsvp::RsvpKnobs {
            oversample,
            ..retrace::reuse::rsvp::RsvpKnobs::default_for(scene.samples)
        };
        assert_eq!(knobs.filter, retrace::reuse::rsvp::Filter::PixelBox);
        let options = Options {
            rsvp: knobs,
            ..Options::new(Techniques::AUTO, 0..1)
        };
        let mut rsvp = retrace::frame_loop::Animator::new(&scene, &mut accel, options);
        let output = rsvp.render(0).remove(0);
        assert_eq!(output.stats.mode.as_str(), "rsvp");
        let frame = output.frame.unwrap();
        let bound = 1.0 / (2.0 * 2.0 * oversample as f32);
        for y in 4..44 {
            let value = |x: u32| frame.get(x, y).x;
            assert!(value(18) > 0.99 && value(22) < 0.01, "row {y}: the sides");
            let error = (value(20) - coverage).abs();
            assert!(
                error <= bound,
                "coverage {coverage}, row {y}: {} (off by {error}, more than {bound})",
                value(20)
            );
        }
    }
}

/// RSVP antialiases by reading its buffer at sub-pixel shifts of the
/// viewport's pixels: at four samples a pixel its frames are no worse,
/// against a converged reference, than direct renders at four samples a
/// pixel (the margin: 0.25 dB), and the buffer's samples stay
/// exactly what a fresh trace gives.
#[test]
fn antialiased_viewports_are_no_worse_than_direct_renders_at_the_same_samples() {
    let mut scene = shipped("paper-zoom-in.toml", 160, 120);
    scene.viewports[0].viewport.width = 160;
    scene.viewports[0].viewport.height = 120;
    for frame in [0, 60, 99] {
        let (mode, rsvp_db, direct_db) =
            crate::common::viewport_and_direct_psnr(&scene, frame, 4, 64);
        assert_eq!(mode, "rsvp");
        assert!(
            rsvp_db >= direct_db - 0.25,
            "frame {frame}: RSVP {rsvp_db:.2} dB, direct {direct_db:.2} dB"
        );
    }
}
