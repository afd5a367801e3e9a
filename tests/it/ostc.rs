//! OSTC: moving objects and lights re-trace only their regions, and every
//! frame still equals a full render of the same frame bit for bit, on every
//! backend.

use std::path::Path;

use proptest::prelude::*;
use retrace::accel::BackendKind;
use retrace::camera::Projection;
use retrace::frame_loop::{FrameStats, Options, Techniques, ViewOutput};
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

const PAPER: &str = include_str!("../../scenes/paper.toml");

/// The paper scene at `width` x `height` with `extra` (objects and a
/// timeline) appended.
fn paper_with(extra: &str, width: u32, height: u32) -> Scene {
    crate::common::paper_with_at(extra, width, height)
}

const BALL: &str = r#"
[material.bouncer]
diffuse = [0.95, 0.75, 0.1]
specular = [0.6, 0.6, 0.6]
shininess = 80.0

[[object]]
type = "sphere"
name = "ball"
center = [-2.6, 0.5, 3.0]
radius = 0.5
material = "bouncer"
"#;

use crate::common::{run_exact, run_exact_reusing};

fn traced(stats: &[FrameStats]) -> u64 {
    stats.iter().map(|s| s.work.samples_traced).sum()
}

on_every_backend! {
    a_bouncing_ball_retraces_only_its_regions_exactly(backend) {
        let scene = paper_with(
            &format!("{BALL}\n[animation]\nframes = 8\n[[animation.bounce]]\nobject = \"ball\"\nheight = 2.0\nperiod = 8\n"),
            96,
            64,
        );
        let stats = run_exact_reusing(&scene, backend, Techniques::AUTO);
        // The camera stands still: its own image, no pan lattice.
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"), "{:?}", stats.iter().map(|s| s.mode).collect::<Vec<_>>());
        assert!(stats[1..].iter().all(|s| s.ostc.dirty_regions > 0));
        assert!(stats[1..].iter().all(|s| s.ostc.voxels_walked > 0));
        // Frames 1-7 re-trace 1984 samples (the ball's regions, 224-312 a
        // frame) of 43008 shown; twice that (3968) must fail.
        let later = traced(&stats[1..]);
        assert!(later < 3000, "traced {later}");
    }

    a_moving_light_retraces_lit_regions_exactly(backend) {
        let scene = paper_with(
            "[animation]\nframes = 4\n[[animation.light]]\nlight = 0\nframe = 0\n[[animation.light]]\nlight = 0\nframe = 3\nposition = [-4.0, 10.0, 12.0]\nintensity = 0.5\n",
            64,
            48,
        );
        let stats = run_exact_reusing(&scene, backend, Techniques::AUTO);
        // No object moves: no voxel grid, nothing walked.
        assert!(stats.iter().all(|s| s.ostc.voxels_walked == 0));
        // The sky above the horizon keeps its samples.
        assert!(stats[1..].iter().all(|s| s.work.samples_traced < 64 * 48), "{:?}", stats.iter().map(|s| s.work.samples_traced).collect::<Vec<_>>());
        assert!(stats[1..].iter().all(|s| s.ostc.dirty_regions > 0));
    }

    a_recoloured_light_retraces_only_what_it_lit(backend) {
        // Light 1 below the ground plane: every shadow ray toward it is
        // blocked, so it lights nothing in view.
        let light = |change: &str| paper_with(
            &format!("[animation]\nframes = 3\n[[animation.light]]\nlight = 1\nframe = 0\nposition = [2.0, -5.0, 3.0]\n[[animation.light]]\nlight = 1\nframe = 2\n{change}\n"),
            64,
            48,
        );
        let recoloured = run_exact_reusing(&light("color = [1.0, 0.2, 0.2]"), backend, Techniques::AUTO);
        assert_eq!(traced(&recoloured[1..]), 0, "a light that lit nothing re-traced samples");
        let moved = run_exact_reusing(&light("position = [3.0, -4.0, 2.0]"), backend, Techniques::AUTO);
        // A moved light may now light anything it could face.
        assert!(moved[1..].iter().all(|s| s.ostc.dirty_regions > 0));
    }

    pan_and_motion_together_stay_exact(backend) {
        let scene = paper_with(
            &format!("{BALL}\n[animation]\nframes = 6\n[[animation.camera]]\nframe = 0\nyaw = -20.0\n[[animation.camera]]\nframe = 5\nyaw = 20.0\n[[animation.object]]\nobject = \"ball\"\nframe = 0\n[[animation.object]]\nobject = \"ball\"\nframe = 5\ntranslate = [3.0, 0.5, -1.0]\nrotate = [0.0, 90.0, 0.0]\n"),
            64,
            48,
        );
        let stats = run_exact_reusing(&scene, backend, Techniques::AUTO);
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan+ostc"));
        assert!(traced(&stats) < 6 * 64 * 48);
    }

    viewports_keep_an_exact_buffer_while_the_ball_moves(backend) {
        // E4 in small: pan, zoom and a bouncing ball, seen by a viewport.
        let extra = format!(
            "{BALL}\n[[viewport]]\nname = \"v\"\nwidth = 48\nheight = 32\nfov = 70.0\n[animation]\nframes = 6\n[[animation.camera]]\nframe = 0\nyaw = -10.0\n[[animation.camera]]\nframe = 5\nyaw = 10.0\n[[animation.viewport]]\nframe = 0\nzoom = 1.0\n[[animation.viewport]]\nframe = 5\nzoom = 1.6\n[[animation.bounce]]\nobject = \"ball\"\nheight = 2.0\nperiod = 6\n"
        );
        let scene = paper_with(&extra, 64, 48);
        let mut accel = retrace::accel::Accelerator::build(backend, &scene.objects).unwrap();
        let mut animator = retrace::frame_loop::Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..6));
        let mut traced = 0;
        for frame in 0..6 {
            let outputs = animator.render(frame);
            let stats = &outputs[0].stats;
            assert_eq!(stats.mode.as_str(), "rsvp+ostc", "frame {frame}: {}", crate::common::reason(stats));
            if frame > 0 {
                assert!(stats.ostc.dirty_regions > 0, "frame {frame}");
                traced += stats.work.samples_traced;
            }
            let (compared, differing) = animator.verify_store().unwrap();
            assert!(compared > 0);
            assert_eq!(differing, 0, "frame {frame}: buffer samples differ from a fresh trace");
            // What the viewport shows from the kept buffer (and its views,
            // updated as samples were erased and traced again) equals what a
            // fresh buffer shows of this frame alone.
            let mut accel = retrace::accel::Accelerator::build(backend, &scene.objects).unwrap();
            let mut fresh = retrace::frame_loop::Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..6));
            assert!(fresh.render(frame)[0].image == outputs[0].image, "frame {frame}: kept and fresh views differ");
        }
        // Kept samples: later frames trace far less than the first.
        let first = {
            let mut accel = retrace::accel::Accelerator::build(backend, &scene.objects).unwrap();
            let mut fresh = retrace::frame_loop::Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..6));
            fresh.render(0)[0].stats.work.samples_traced
        };
        assert!(traced < 5 * first, "traced {traced} after a first frame of {first}");
    }

    still_cameras_of_any_projection_use_ostc(backend) {
        for projection in [Projection::Perspective, Projection::Fisheye] {
            let mut scene = paper_with(
                &format!("{BALL}\n[animation]\nframes = 5\n[[animation.bounce]]\nobject = \"ball\"\nheight = 2.0\nperiod = 6\n"),
                64,
                48,
            );
            scene.camera.projection = projection;
            scene.camera.fov = 70f64.to_radians();
            let stats = run_exact_reusing(&scene, backend, Techniques::AUTO);
            assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"), "{projection}: {:?}", stats.iter().map(|s| (s.mode, s.reason)).collect::<Vec<_>>());
            assert!(traced(&stats[1..]) < 4 * 64 * 48 / 2, "{projection}: traced {}", traced(&stats[1..]));
        }
    }

    ostc_off_rerenders_moving_scenes_in_full(backend) {
        let scene = paper_with(
            &format!("{BALL}\n[animation]\nframes = 3\n[[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 4\n"),
            32,
            24,
        );
        let pan_only = Techniques {
            pan: true,
            ..Techniques::FULL
        };
        let stats = run_exact(&scene, backend, pan_only);
        assert!(stats[1..].iter().all(|s| s.work.samples_traced >= 32 * 24));
        assert!(crate::common::reason(&stats[1]).contains("ostc is off"), "{:?}", crate::common::reason(&stats[1]));
    }
}

#[test]
fn ostc_too_big_for_memory_is_refused_and_frames_stay_exact() {
    use retrace::accel::Accelerator;
    use retrace::frame_loop::{Animator, OstcSettings};
    use retrace::metrics::count_differences;
    let scene = paper_with(
        &format!("{BALL}\n[animation]\nframes = 3\n[[animation.bounce]]\nobject = \"ball\"\nheight = 2.0\nperiod = 4\n"),
        160,
        120,
    );
    let mut accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
    // 40x60 regions of one group each: 38 words a voxel; 16M voxels, 10 GB.
    let options = Options {
        ostc: OstcSettings {
            regions: Some(retrace::reuse::regions::RegionGrid(256)),
            voxels: 16_777_216,
        },
        ..Options::new(Techniques::AUTO, 0..3)
    };
    let mut animator = Animator::new(&scene, &mut accel, options);
    for frame in 0..3 {
        let ViewOutput {
            frame: image,
            stats,
            ..
        } = animator.render(frame).remove(0);
        let (reference, _) = animator.render_full(frame, 0, None);
        assert_eq!(
            count_differences(&image.unwrap(), &reference).unwrap(),
            0,
            "frame {frame}"
        );
        if frame > 0 {
            assert!(
                crate::common::reason(&stats).contains("OSTC was refused"),
                "{:?}",
                stats.reason
            );
        }
    }
    let why = animator.ostc_refusal().expect("refused").to_string();
    assert!(
        why.contains("GB") && why.contains("16777216 voxels"),
        "{why}"
    );
}

#[test]
fn still_scenes_build_no_ostc_bookkeeping() {
    let scene = paper_with(
        "[animation]\nframes = 3\n[[animation.camera]]\nframe = 0\nyaw = 0.0\n[[animation.camera]]\nframe = 2\nyaw = 10.0\n",
        32,
        24,
    );
    let stats = run_exact_reusing(&scene, BackendKind::Embree, Techniques::AUTO);
    assert!(stats
        .iter()
        .all(|s| s.mode.as_str() == "pan" && s.ostc.voxels_walked == 0));
}

#[test]
fn bad_animation_input_names_file_line_and_field() {
    let parse = |extra: &str| {
        parse_scene_str(
            &format!("{PAPER}\n{BALL}\n[animation]\nframes = 4\n{extra}"),
            Path::new("scenes/paper.toml"),
            &SceneOverrides::default(),
        )
        .unwrap_err()
    };
    let err = parse("[[animation.bounce]]\nobject = \"balll\"\nheight = 1.0\nperiod = 4\n");
    assert_eq!(err.field.as_deref(), Some("animation.bounce[0].object"));
    assert!(err.message.contains("no object named 'balll'"), "{err}");
    assert!(err.line.is_some());
    let err = parse("[[animation.object]]\nobject = \"ground\"\nframe = 0\n");
    assert!(err.message.contains("infinite plane"), "{err}");
    let err = parse("[[animation.light]]\nlight = 7\nframe = 0\n");
    assert_eq!(err.field.as_deref(), Some("animation.light[0].light"));
    let err = parse(
        "[[animation.object]]\nobject = \"ball\"\nframe = 3\n[[animation.object]]\nobject = \"ball\"\nframe = 1\n",
    );
    assert_eq!(err.field.as_deref(), Some("animation.object[1].frame"));
    let err = parse("[[animation.bounce]]\nobject = \"ball\"\nheight = 1.0\nperiod = 0\n");
    assert_eq!(err.field.as_deref(), Some("animation.bounce[0].period"));
    let err =
        parse("[[animation.object]]\nobject = \"ball\"\nframe = 0\ntranslate = [0, nan, 0]\n");
    assert_eq!(err.field.as_deref(), Some("animation.object[0].translate"));
}

/// A random small animation: a few spheres, quads and cut-out plants
/// near the paper scene's centre, some moving (keys or bounces), maybe an
/// area light (and glossy spheres) or a model lit by its glowing panel
/// (mesh lights, `scenes/cornell/`), maybe moving lights, maybe a panning
/// camera, maybe a brick wall with a height map
/// (`scenes/textured/wall.obj`), still or moving.
fn random_animation() -> impl Strategy<Value = String> {
    let object = (0u8..3, -4.0f32..4.0, 0.2f32..2.0, -4.0f32..6.0, 0.2f32..1.2)
        .prop_map(|(shape, x, y, z, size)| (shape, x, y, z, size));
    let motion = (
        0u8..3,
        -3.0f32..3.0,
        -1.0f32..2.0,
        -3.0f32..3.0,
        0.0f32..180.0,
        2u32..6,
    );
    (
        prop::collection::vec((object, motion), 1..4),
        prop::bool::ANY,
        -30.0f64..30.0,
        -12.0f64..0.0,
        0u8..4,
        0u8..3,
    )
        .prop_map(|(objects, light_moves, yaw, pitch, area_light, wall)| {
            // Maybe an area light (light 2): soft shadows, four shadow rays
            // a sample.
            let mut text = match area_light {
                0 => String::new(),
                1 => "[[light]]\nshape = \"rectangle\"\nposition = [1.0, 7.0, 4.0]\nsize = [3.0, 2.0]\nnormal = [0.0, -1.0, 0.2]\nintensity = 30.0\n".to_string(),
                2 => "[[light]]\nshape = \"sphere\"\nposition = [-3.0, 5.0, 6.0]\nradius = 0.8\nintensity = 20.0\n".to_string(),
                // A small open box lit inside by its two glowing triangles.
                _ => "[[object]]\ntype = \"mesh\"\nname = \"lit box\"\nfile = \"cornell/cornell.obj\"\nmesh_lights = true\nscale = 0.5\ntranslate = [-2.0, 0.0, 2.5]\nrotate = [0.0, 160.0, 0.0]\n".to_string(),
            };
            // With the rectangle light the spheres are glossy mirrors.
            text += "[material.brushed]\ndiffuse = [0.2, 0.2, 0.25]\nreflectivity = 0.6\nroughness = 0.3\n";
            let sphere_material = if area_light == 1 { "brushed" } else { "red" };
            let mut timeline = String::from("[animation]\nframes = 5\n");
            for (i, ((shape, x, y, z, size), (kind, dx, dy, dz, turn, period))) in
                objects.into_iter().enumerate()
            {
                let name = format!("thing{i}");
                if shape == 0 {
                    text += &format!(
                        "[[object]]\ntype = \"sphere\"\nname = \"{name}\"\ncenter = [{x}, {y}, {z}]\nradius = {size}\nmaterial = \"{sphere_material}\"\n"
                    );
                } else if shape == 1 {
                    // Leaves on cards cut out by their texture's alpha. At
                    // twice the size two plants could cover every region of
                    // a 4x4 grid at 32x24 in every frame: nothing to reuse.
                    text += &format!(
                        "[[object]]\ntype = \"mesh\"\nname = \"{name}\"\nfile = \"plant/plant.obj\"\ntranslate = [{x}, {y}, {z}]\nscale = {size}\n"
                    );
                } else {
                    text += &format!(
                        "[[object]]\ntype = \"quad\"\nname = \"{name}\"\nvertices = [[{x}, {y}, {z}], [{}, {y}, {z}], [{}, {}, {z}], [{x}, {}, {z}]]\nmaterial = \"mirror\"\n",
                        x + size,
                        x + size,
                        y + size,
                        y + size
                    );
                }
                match kind {
                    0 => {}
                    1 => {
                        timeline += &format!(
                            "[[animation.object]]\nobject = \"{name}\"\nframe = 0\n[[animation.object]]\nobject = \"{name}\"\nframe = 4\ntranslate = [{dx}, {dy}, {dz}]\nrotate = [0.0, {turn}, 0.0]\n"
                        );
                    }
                    _ => {
                        timeline += &format!(
                            "[[animation.bounce]]\nobject = \"{name}\"\nheight = {}\nperiod = {period}\n",
                            dy.abs() + 0.5
                        );
                    }
                }
            }
            // Maybe a bump-mapped wall (its relief read through the cone
            // of each ray), still (1) or sliding across (2).
            if wall > 0 {
                text += "[[object]]\ntype = \"mesh\"\nname = \"wall\"\nfile = \"textured/wall.obj\"\nscale = 0.4\ntranslate = [-1.0, 0.0, 1.0]\nrotate = [0.0, 20.0, 0.0]\n";
            }
            if wall > 1 {
                timeline += "[[animation.object]]\nobject = \"wall\"\nframe = 0\n[[animation.object]]\nobject = \"wall\"\nframe = 4\ntranslate = [1.5, 0.0, 0.5]\n";
            }
            if light_moves {
                timeline += "[[animation.light]]\nlight = 1\nframe = 1\n[[animation.light]]\nlight = 1\nframe = 3\nposition = [4.0, 9.0, 6.0]\n";
                if area_light == 1 || area_light == 2 {
                    timeline += "[[animation.light]]\nlight = 2\nframe = 2\n[[animation.light]]\nlight = 2\nframe = 4\nposition = [0.0, 6.0, 5.0]\n";
                }
            }
            timeline += &format!(
                "[[animation.camera]]\nframe = 0\nyaw = {yaw}\npitch = {pitch}\n[[animation.camera]]\nframe = 4\nyaw = {}\npitch = {pitch}\n",
                yaw + 12.0
            );
            format!("{text}\n{timeline}")
        })
}

/// A random animation seen by a random camera: an equal-angle one that
/// pans (the pan lattice), or a still camera of any projection (its own
/// image).
fn random_shot() -> impl Strategy<Value = (String, Option<Projection>)> {
    (
        random_animation(),
        prop_oneof![
            Just(None),
            Just(Some(Projection::EqualAngle)),
            Just(Some(Projection::Perspective)),
            Just(Some(Projection::Fisheye)),
        ],
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(crate::common::cases(24)))]

    /// Random motion, random camera, at sizes and region grids where a
    /// region spans one sample group or many (up to 6x8 of them), one
    /// sample a pixel or four (antialiased): every frame reuses and equals
    /// its full render and a render built afresh.
    #[test]
    fn random_animations_are_exact_on_both_backends(
        (extra, still) in random_shot(),
        (width, height) in prop_oneof![Just((32, 24)), Just((64, 48)), Just((96, 64))],
        regions in prop_oneof![Just(4u32), Just(8), Just(16), Just(160)],
        samples in prop_oneof![Just(1u32), Just(4)],
    ) {
        let mut scene = paper_with(&extra, width, height);
        scene.samples = retrace::sampling::PixelSamples::new(samples).unwrap();
        if let Some(projection) = still {
            scene.camera.projection = projection;
            scene.camera.fov = 80f64.to_radians();
            scene.animation.as_mut().unwrap().camera_keys.clear();
        }
        let options = Options {
            ostc: retrace::frame_loop::OstcSettings {
                regions: Some(retrace::reuse::regions::RegionGrid(regions)),
                ..Default::default()
            },
            ..Options::new(Techniques::AUTO, 0..5)
        };
        for backend in [BackendKind::Embree, BackendKind::Grid] {
            let stats = crate::common::run_exact_with(&scene, backend, options.clone());
            // Every frame comes from the store. A big mesh's move may dirty
            // every region of a coarse grid for a frame (a plant a few
            // units tall at 32x24 in 4x4 regions), so the run as a whole,
            // not each frame, must reuse.
            let from_store = stats[1..]
                .iter()
                .all(|s| s.mode != retrace::reuse::FrameMode::Full && s.reason.is_none());
            prop_assert!(from_store, "a frame not from the store: {:?}", stats);
            let reused: u64 = stats[1..].iter().map(|s| s.work.pixels_reused).sum();
            prop_assert!(reused > 0, "nothing reused: {:?}", stats);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(crate::common::cases(8)))]

    /// Random motion under a panning camera, seen through a viewport that
    /// zooms into finer pyramid levels (where a moving object erases only
    /// the groups whose rays meet it): every kept buffer sample equals a
    /// fresh trace at every frame, on both backends.
    #[test]
    fn random_animations_through_a_zooming_viewport_keep_an_exact_buffer(
        extra in random_animation(),
        zoom in 1.0f64..3.0,
        rotate in -40.0f64..40.0,
        samples in prop_oneof![Just(1u32), Just(4)],
    ) {
        let view = format!(
            "[[viewport]]\nname = \"v\"\nwidth = 40\nheight = 30\nfov = 90.0\n\
             [[animation.viewport]]\nframe = 0\nzoom = 1.0\n\
             [[animation.viewport]]\nframe = 4\nzoom = {zoom}\nrotate = {rotate}\n"
        );
        let mut scene = paper_with(&format!("{extra}\n{view}"), 48, 32);
        let samples = retrace::sampling::PixelSamples::new(samples).unwrap();
        scene.samples = samples;
        for backend in [BackendKind::Embree, BackendKind::Grid] {
            let mut accel = retrace::accel::Accelerator::build(backend, &scene.objects).unwrap();
            // Antialiased, the viewport reads the buffer at four sub-pixel
            // shifts; the buffer's samples stay what a fresh trace gives.
            let options = Options {
                rsvp: retrace::reuse::rsvp::RsvpKnobs::default_for(samples),
                ..Options::new(Techniques::AUTO, 0..5)
            };
            let mut animator = retrace::frame_loop::Animator::new(&scene, &mut accel, options);
            for frame in 0..5 {
                let stats = animator.render(frame).remove(0).stats;
                // The buffer is kept (no restart; OSTC where something
                // but the camera moves): the check is not vacuous.
                prop_assert!(stats.mode.as_str().starts_with("rsvp"), "{}", stats.mode);
                prop_assert!(frame == 0 || stats.reason.is_none(), "frame {}: {:?}", frame, stats.reason);
                let (compared, differing) = animator.verify_store().unwrap();
                prop_assert!(compared > 0);
                prop_assert_eq!(differing, 0, "{:?} frame {}", backend, frame);
            }
        }
    }
}

/// A temporary directory holding the paper scene, the bouncing ball and
/// `extra` files (name, contents).
fn bounce_dir(extra: &[(&str, &str)]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    for name in ["paper.toml", "paper-bounce.toml"] {
        std::fs::copy(format!("{scenes}/{name}"), dir.path().join(name)).unwrap();
    }
    for (name, contents) in extra {
        std::fs::write(dir.path().join(name), contents).unwrap();
    }
    dir
}

/// Black pixels of image `name` under `dir`/out.
fn black_pixels(dir: &Path, name: &str) -> usize {
    let image = image::open(dir.join("out").join(name)).unwrap().to_rgb8();
    image.pixels().filter(|p| p.0 == [0, 0, 0]).count()
}

/// Animates frames 0-3 of `scene` in `dir` at 64x48 with dirty images
/// (plus `extra` arguments) and checks them: frame 0 traces every pixel's
/// samples, frame 2 only the ball's regions, and the frame itself has no
/// black. `suffix` is the viewport's file suffix ("" for the camera).
fn check_dirty_frames(dir: &Path, scene: &str, suffix: &str, extra: &[&str]) {
    let mut args = vec![
        "animate",
        scene,
        "--frames",
        "0-3",
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        "out/f_##.png",
        "--dirty-image",
        "out/d_##.png",
    ];
    args.extend_from_slice(extra);
    crate::common::retrace_ok(&args, dir);
    let black = |name: &str| black_pixels(dir, &format!("{name}{suffix}.png"));
    assert_eq!(black("d_00"), 64 * 48);
    let later = black("d_02");
    assert!(later > 0 && later < 64 * 48 / 2, "{later} black pixels");
    assert_eq!(black("f_02"), 0);
}

#[test]
fn animate_writes_dirty_images_and_ostc_stats() {
    let dir = bounce_dir(&[]);
    let stats = ["--stats", "out/s.csv", "--verify"];
    check_dirty_frames(dir.path(), "paper-bounce.toml", "", &stats);
    let csv = std::fs::read_to_string(dir.path().join("out/s.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for column in [
        "dirty_regions",
        "voxels_walked",
        "bookkeeping_ms",
        "changed_regions",
    ] {
        assert!(header.contains(&column), "{column} missing from {header:?}");
    }
    let mode = header.iter().position(|&c| c == "mode").unwrap();
    let row: Vec<&str> = csv.lines().nth(3).unwrap().split(',').collect();
    assert_eq!(row[mode], "ostc");
}

#[test]
fn dirty_images_of_viewports_show_what_each_frame_traced() {
    let view = "include = \"paper-bounce.toml\"\n\n[[viewport]]\nname = \"view\"\nwidth = 64\nheight = 48\nfov = 100.0\n";
    let dir = bounce_dir(&[("view.toml", view)]);
    check_dirty_frames(dir.path(), "view.toml", "_view", &[]);
}
