//! RSVP: the lazily traced sample buffer and its viewports, on every
//! backend; scene-file errors for bad viewports; the CLI's Figure 5.

use std::path::Path;

use glam::DVec3;
use retrace::accel::Accelerator;
use retrace::camera::{Camera, Projection};
use retrace::camera::{ViewTransform, ViewportPose};
use retrace::color::encode_srgb;
use retrace::frame_loop::{Animator, Options, Techniques};
use retrace::metrics::image_error;
use retrace::render::trace_groups;
use retrace::render::SampleGroup;
use retrace::reuse::rsvp::{Filter, Level, LevelRays, RsvpKnobs, SampleBuffer, SampleLattice};
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};
use retrace::shade::Shader;

fn paper_text() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml")).unwrap()
}

/// The paper scene (camera 64x48, so the buffer's level 0 is coarse) with
/// `extra` tables appended.
fn paper_with(extra: &str) -> Result<Scene, retrace::scene::SceneError> {
    let text = format!("{}\n{extra}", paper_text());
    let overrides = SceneOverrides {
        width: Some(64),
        height: Some(48),
        ..SceneOverrides::default()
    };
    parse_scene_str(&text, Path::new("scenes/paper.toml"), &overrides)
}

fn lattice_for(scene: &Scene) -> SampleLattice {
    SampleLattice::for_camera(&scene.camera)
}

/// A 64x48 viewport looking like the scene camera, with `transform`.
fn pose(scene: &Scene, projection: Projection, transform: ViewTransform) -> ViewportPose {
    ViewportPose::new(
        Camera {
            projection,
            width: 64,
            height: 48,
            ..scene.camera.clone()
        },
        transform,
    )
}

fn bits(v: glam::Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

on_every_backend! {
    null_samples_are_traced_once_and_kept(backend) {
        let scene = paper_with("").unwrap();
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let mut buffer = SampleBuffer::new(lattice_for(&scene));
        let knobs = RsvpKnobs::default();
        let zoomed = ViewTransform { zoom: 3.0, rotate: 0.5, ..ViewTransform::default() };
        let poses = [pose(&scene, Projection::Perspective, zoomed)];
        let first = buffer.render(&shader, &poses, &knobs, true, None);
        assert!(first[0].work.samples_traced > 0);
        assert_eq!(buffer.samples_traced(), first[0].work.samples_traced);
        // The same frame again traces nothing and gives the same picture.
        let again = buffer.render(&shader, &poses, &knobs, true, None);
        assert_eq!(again[0].work.samples_traced, 0);
        assert_eq!(again[0].work.rays.total(), 0);
        assert_eq!(again[0].frame, first[0].frame);
        // A second viewport over the same area shares the samples.
        let both = [poses[0].clone(), poses[0].clone()];
        let shared = buffer.render(&shader, &both, &knobs, true, None);
        assert_eq!(shared[0].work.samples_traced + shared[1].work.samples_traced, 0);
    }

    buffer_samples_equal_a_fresh_trace_of_their_group(backend) {
        let scene = paper_with("").unwrap();
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let lattice = lattice_for(&scene);
        let mut buffer = SampleBuffer::new(lattice.clone());
        // Wide and zoomed views: levels 0 to 3 or so.
        let poses = [
            pose(&scene, Projection::Perspective, ViewTransform::default()),
            pose(&scene, Projection::Perspective, ViewTransform { zoom: 6.0, ..ViewTransform::default() }),
        ];
        buffer.render(&shader, &poses, &RsvpKnobs::default(), false, None);
        let mut checked = 0;
        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1), (2, 1), (2, 2), (3, 3), (4, 4)] {
            let level = Level::new(x, y);
            // Samples around the view centre at this level.
            let centre = lattice.viewport_coords(&poses[0], glam::DVec2::new(32.0, 24.0)).unwrap();
            let (c0, r0) = ((centre.0 * f64::from(1u32 << x)) as i64, (centre.1 * f64::from(1u32 << y)) as i64);
            for (dc, dr) in [(0, 0), (1, 0), (0, 1), (1, 1), (3, 2), (-5, 4)] {
                let (col, row) = (c0 + dc, r0 + dr);
                let Some(stored) = buffer.sample(level, col, row) else { continue };
                let (owner, oc, or) = lattice.owner(level, col, row);
                let group = SampleGroup::containing(oc, or);
                let (colors, _) = trace_groups(&shader, &LevelRays { lattice: &lattice, level: owner }, &[group]);
                let lane = group.lane_samples().iter().position(|&s| s == (oc, or)).unwrap();
                assert_eq!(bits(stored), bits(colors[0][lane]), "level {level} ({col}, {row})");
                checked += 1;
            }
        }
        assert!(checked >= 10, "only {checked} samples were traced to check");
    }

    identity_equal_angle_viewport_reproduces_the_buffer(backend) {
        let scene = paper_with("").unwrap();
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let lattice = lattice_for(&scene);
        let step = lattice.step;
        // Same angle per pixel as level 0, pixel centres on samples.
        let camera = Camera {
            projection: Projection::EqualAngle,
            position: scene.camera.position,
            yaw: 40.5 * step,
            pitch: -9.5 * step,
            fov: 64.0 * step,
            width: 64,
            height: 48,
        };
        let pose = ViewportPose::new(camera, ViewTransform::default());
        for filter in [Filter::Bilinear, Filter::Nearest] {
            let mut buffer = SampleBuffer::new(lattice.clone());
            let knobs = RsvpKnobs { filter, ..RsvpKnobs::default() };
            let view = buffer.render(&shader, std::slice::from_ref(&pose), &knobs, true, None);
            assert_eq!(view[0].work.levels, Some((0, 0)));
            // Pass 2 blends sRGB codes: the image shows each sample's own
            // 8 bits, exactly.
            let image = &view[0].image;
            for y in 0..48u32 {
                for x in 0..64u32 {
                    let (col, row) = lattice.viewport_coords(&pose, glam::DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5)).unwrap();
                    let (col, row) = (col.round() as i64, row.round() as i64);
                    let sample = buffer.sample(Level::default(), col, row).expect("traced");
                    assert_eq!(image.get_pixel(x, y).0, sample.to_array().map(encode_srgb), "{filter} ({x}, {y})");
                }
            }
        }
    }

    zoom_extremes_render(backend) {
        let scene = paper_with("").unwrap();
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let mut buffer = SampleBuffer::new(lattice_for(&scene));
        for zoom in [1e-3, 1e3] {
            let p = pose(&scene, Projection::Perspective, ViewTransform { zoom, rotate: 0.3, ..ViewTransform::default() });
            let view = buffer.render(&shader, std::slice::from_ref(&p), &RsvpKnobs::default(), true, None);
            let frame = view[0].frame.as_ref().unwrap();
            assert!(frame.pixels.iter().all(|c| c.is_finite()), "zoom {zoom}");
            let (direct, _) = retrace::reuse::rsvp::render_direct(&shader, &p);
            let error = image_error(frame, &direct).unwrap();
            if zoom > 1.0 {
                // Far finer than level 0: the pyramid, not an upscale.
                assert!(view[0].work.levels.unwrap().0 >= 8, "{:?}", view[0].work.levels);
                // Measured 68.2 dB; samples read from a level they were not
                // traced into (black) measured 4.3 dB. At this zoom the view
                // is nearly flat: a one-pixel shift cannot show (88 dB).
                assert!(error.psnr_db > 50.0, "zoom {zoom}: {error:?}");
            } else {
                // Zoomed out a thousandfold: measured 42.8 dB; the direct
                // render moved one pixel scores 13.7 dB, and must fail.
                assert!(error.psnr_db > 30.0, "zoom {zoom}: {error:?}");
                let shifted = image_error(&crate::common::shifted_by_one(&direct), &direct).unwrap();
                assert!(shifted.psnr_db < 30.0, "a one-pixel shift passes: {shifted:?}");
            }
        }
    }

    zoom_sequence_stays_close_to_direct_renders(backend) {
        let scene = paper_with(
            "[animation]\nframes = 6\n\
             [[viewport]]\nname = \"z\"\nwidth = 64\nheight = 48\n\
             [[animation.viewport]]\nframe = 0\nzoom = 1.0\n\
             [[animation.viewport]]\nframe = 5\nzoom = 2.0\nrotate = 20.0\n",
        )
        .unwrap();
        let mut accel = Accelerator::build(backend, &scene.objects).unwrap();
        let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..6));
        let mut traced = Vec::new();
        for frame in 0..6 {
            let outputs = animator.render(frame);
            assert_eq!(outputs.len(), 1);
            assert_eq!(outputs[0].stats.mode.as_str(), "rsvp");
            traced.push(outputs[0].stats.work.samples_traced);
            let (direct, _) = animator.render_full(frame, 0, None);
            let error = image_error(outputs[0].frame.as_ref().unwrap(), &direct).unwrap();
            // Measured 18.7-20.1 dB (the far checkerboard aliases at 64x48);
            // the direct render moved one pixel scores 14.1-14.6 dB, and
            // must fail.
            assert!(error.psnr_db > 16.5, "frame {frame}: {error:?}");
            let shifted = image_error(&crate::common::shifted_by_one(&direct), &direct).unwrap();
            assert!(shifted.psnr_db < 16.5, "a one-pixel shift passes: {shifted:?}");
        }
        // Zooming in re-uses: frames 1-5 trace 5392 samples, half of frame
        // 0's 10656 (its levels for a 64x48 view); tracing them twice over
        // (10784) must fail, as must tracing one sample a pixel a frame
        // (15360).
        let later: u64 = traced[1..].iter().sum();
        assert!(later < traced[0], "{traced:?}");
        let buffer = animator.store_picture(5).unwrap();
        assert_eq!(buffer.dimensions(), (64, 48));
        // Full mode traces the viewport's own rays.
        let mut full = Animator::new(&scene, &mut accel, Options::new(Techniques::FULL, 0..6));
        let outputs = full.render(3);
        let (direct, _) = full.render_full(3, 0, None);
        assert_eq!(outputs[0].frame.as_ref().unwrap(), &direct);
    }
}

fn scene_error(extra: &str) -> String {
    match paper_with(extra) {
        Ok(_) => panic!("accepted: {extra}"),
        Err(err) => err.to_string(),
    }
}

fn assert_names(message: &str, line: usize, field: &str) {
    assert!(
        message.starts_with(&format!("scenes/paper.toml:{line}: {field}")),
        "{message}"
    );
}

/// Line of the first appended table in [`paper_with`]'s text.
fn first_extra_line() -> usize {
    paper_text().lines().count() + 2
}

#[test]
fn bad_viewports_name_file_line_and_field() {
    let line = first_extra_line();
    let view = |fields: &str| format!("[[viewport]]\nname = \"v\"\n{fields}\n");
    // Each error names the line of its value, `line` + 2 onwards.
    let e = scene_error(&view("width = 0\nheight = 10"));
    assert_names(&e, line + 2, "viewport[0].width");
    let e = scene_error(&view("width = 10\nheight = -4"));
    assert_names(&e, line + 3, "viewport[0].height");
    let e = scene_error(&view("width = 10\nheight = 10\nzoom = 0.0"));
    assert_names(&e, line + 4, "viewport[0].zoom");
    assert!(e.contains("1/1000..1000"), "{e}");
    let e = scene_error(&view("width = 10\nheight = 10\nzoom = 1500.0"));
    assert_names(&e, line + 4, "viewport[0].zoom");
    let e = scene_error(&view("width = 10\nheight = 10\nshear = [2.0, 0.5]"));
    assert_names(&e, line + 4, "viewport[0].shear");
    assert!(e.contains("singular"), "{e}");
    // The paper camera looks 9 degrees down: 85 more is beyond -90.
    let e = scene_error(&view("width = 10\nheight = 10\npitch = -85.0"));
    assert_names(&e, line + 4, "viewport[0].pitch");
    let e = scene_error(&view(
        "width = 10\nheight = 10\nprojection = \"perspective\"\nfov = 180.0",
    ));
    assert_names(&e, line + 5, "viewport[0].fov");
    // Keyframes: their value's line, the viewport named.
    let keys = format!(
        "{}[animation]\nframes = 10\n[[animation.viewport]]\nframe = 0\nviewport = \"v\"\nzoom = 0.0001\n",
        view("width = 10\nheight = 10")
    );
    let e = scene_error(&keys);
    assert_names(&e, line + 9, "animation.viewport[0] (viewport 'v').zoom");
    let e = scene_error(&keys.replace("viewport = \"v\"", "viewport = \"w\""));
    assert_names(&e, line + 8, "animation.viewport[0].viewport");
    assert!(e.contains("defined: v"), "{e}");
    let e = scene_error(&keys.replace("zoom = 0.0001", "shear = [1.0, 1.0]"));
    assert_names(&e, line + 9, "animation.viewport[0] (viewport 'v').shear");
    // An equal-angle viewport moved, turned or zoomed out past a pole: its
    // transform, statically or keyed (RSVP clamped to the pole row while
    // its own rays went over it).
    let ea = "width = 64\nheight = 48\nprojection = \"equal-angle\"";
    for transform in [
        "translate = [0.0, 60.0]",
        "zoom = 0.25",
        "fov = 170.0\nrotate = 90.0",
    ] {
        let e = scene_error(&view(&format!("{ea}\n{transform}")));
        assert_names(&e, line, "viewport[0].zoom/rotate/translate");
        assert!(e.contains("within -90..90"), "{e}");
    }
    let keyed = format!(
        "{}[animation]\nframes = 10\n[[animation.viewport]]\nframe = 5\nzoom = 0.25\n",
        view(ea)
    );
    let e = scene_error(&keyed);
    assert_names(
        &e,
        line + 7,
        "animation.viewport[0] (viewport 'v').zoom/rotate/translate",
    );
    paper_with(&view(&format!("{ea}\nzoom = 2.0\nrotate = 30.0"))).unwrap();
    // Zoom 1/1000 and 1000 are accepted.
    paper_with(&view("width = 10\nheight = 10\nzoom = 0.001")).unwrap();
    paper_with(&view("width = 10\nheight = 10\nzoom = 1000.0")).unwrap();
}

#[test]
fn figure_5_writes_the_buffer_and_both_viewports() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper-viewports.toml");
    let out = crate::common::retrace_ok(
        &[
            "animate",
            scene,
            "-o",
            "out/f_####.png",
            "--buffer-image",
            "buffers/buffer_####.png",
            "--stats",
            "out/stats.csv",
            "--verify",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("verify zoomed"), "{stdout}");
    let size = |name: &str| image::image_dimensions(dir.path().join("out").join(name)).unwrap();
    assert_eq!(size("f_0000_zoomed.png"), (320, 200));
    assert_eq!(size("f_0000_rotated.png"), (320, 200));
    // Its own folder, made for it.
    let size_in =
        |name: &str| image::image_dimensions(dir.path().join("buffers").join(name)).unwrap();
    assert_eq!(size_in("buffer_0000.png"), (640, 480));
    // The buffer shows black where no viewport looked.
    let buffer = image::open(dir.path().join("buffers/buffer_0000.png"))
        .unwrap()
        .to_rgb8();
    let black = buffer.pixels().filter(|p| p.0 == [0, 0, 0]).count();
    assert!(black > 640 * 480 / 10, "{black} black pixels");
    assert!(black < 640 * 480 * 9 / 10, "{black} black pixels");
    let stats = std::fs::read_to_string(dir.path().join("out/stats.csv")).unwrap();
    assert_eq!(stats.lines().count(), 3, "{stats}");
    assert!(stats.lines().nth(1).unwrap().contains("zoomed"), "{stats}");
}

#[test]
fn eye_moves_restart_the_buffer() {
    let scene = paper_with(
        "[animation]\nframes = 2\n\
         [[animation.camera]]\nframe = 0\n\
         [[animation.camera]]\nframe = 1\nposition = [0.0, 3.2, 13.0]\n\
         [[viewport]]\nwidth = 16\nheight = 8\n",
    )
    .unwrap();
    let mut accel = Accelerator::build(retrace::accel::BackendKind::Grid, &scene.objects).unwrap();
    let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..2));
    animator.render(0);
    let outputs = animator.render(1);
    assert!(crate::common::reason(&outputs[0].stats).contains("eye moved"));
    let (direct, _) = animator.render_full(1, 0, None);
    assert!(
        image_error(outputs[0].frame.as_ref().unwrap(), &direct)
            .unwrap()
            .psnr_db
            > 15.0
    );
    let _ = DVec3::ZERO;
}

#[test]
fn the_finest_pyramid_levels_resample_as_well_as_the_others() {
    // Zoom 1000 with the level pushed to the finest (16 on both axes):
    // levels past the 256th were traced into a coarser level's store and
    // read back null (black).
    let scene = paper_with(
        "[animation]\nframes = 1\n[[viewport]]\nwidth = 16\nheight = 12\nzoom = 1000.0\n",
    )
    .unwrap();
    let mut accel =
        Accelerator::build(retrace::accel::BackendKind::Embree, &scene.objects).unwrap();
    let options = Options {
        rsvp: retrace::reuse::rsvp::RsvpKnobs {
            level_bias: 8,
            ..Default::default()
        },
        ..Options::new(Techniques::AUTO, 0..1)
    };
    let mut animator = Animator::new(&scene, &mut accel, options);
    let outputs = animator.render(0);
    assert_eq!(
        outputs[0].stats.work.levels.map(|(_, finest)| finest),
        Some(16)
    );
    let (direct, _) = animator.render_full(0, 0, None);
    let error = image_error(outputs[0].frame.as_ref().unwrap(), &direct).unwrap();
    assert!(error.psnr_db > 30.0, "{error:?}");
}

/// `--verify` re-traces RSVP's whole buffer after every frame (a stale
/// sample between checkpoints would otherwise go unseen), and says so.
#[test]
fn verify_checks_the_buffer_after_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper-all.toml");
    let out = crate::common::retrace_ok(
        &[
            "animate",
            scene,
            "--frames",
            "0-3",
            "--width",
            "64",
            "--height",
            "48",
            "-o",
            "out/f_####.png",
            "--verify",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("verify: buffer samples re-traced at 4 frame(s)"),
        "{stdout}"
    );
}

/// A buffer capped far below what a zooming session reads evicts the tiles
/// no frame reads, traces them again when a view comes back to them, and
/// shows every frame exactly as an uncapped buffer does: samples are pure
/// functions of their direction. It keeps within its cap, and its samples
/// stay a fresh trace's, bit for bit.
#[test]
fn a_capped_buffer_shows_what_an_uncapped_one_does() {
    let scene = paper_with("").unwrap();
    let accel = Accelerator::build(retrace::accel::BackendKind::default(), &scene.objects).unwrap();
    let shader = Shader::new(&scene, &accel);
    let knobs = RsvpKnobs::default();
    let mut uncapped = SampleBuffer::new(lattice_for(&scene));
    let mut capped = SampleBuffer::new(lattice_for(&scene));
    let cap = 3 << 20;
    capped.set_memory_cap(Some(cap));
    // Zooming in about three points in turn from zoomed out (levels
    // coarser than 0 too), then about the first again: its tiles were
    // evicted meanwhile.
    let points = [[-20.0, -12.0], [18.0, 10.0], [25.0, -15.0], [-20.0, -12.0]];
    let mut frames = 0;
    for translate in points {
        for notches in -10..30 {
            let zoom = 1.25f64.powi(notches);
            let transform = ViewTransform {
                zoom,
                rotate: 0.2,
                translate: [
                    translate[0] * (1.0 - 1.0 / zoom),
                    translate[1] * (1.0 - 1.0 / zoom),
                ],
                ..ViewTransform::default()
            };
            let poses = [pose(&scene, Projection::Perspective, transform)];
            let want = uncapped.render(&shader, &poses, &knobs, true, None);
            let got = capped.render(&shader, &poses, &knobs, true, None);
            assert_eq!(
                got[0].image.as_raw(),
                want[0].image.as_raw(),
                "{translate:?} zoom {zoom}"
            );
            let linear = |frame: &Option<retrace::render::Frame>| {
                frame
                    .as_ref()
                    .unwrap()
                    .pixels
                    .iter()
                    .map(|&c| bits(c))
                    .collect::<Vec<_>>()
            };
            assert_eq!(linear(&got[0].frame), linear(&want[0].frame));
            assert!(
                capped.kept_bytes() <= cap,
                "{} bytes kept",
                capped.kept_bytes()
            );
            assert_eq!(got[0].work.kept_bytes, Some(capped.kept_bytes()));
            frames += 1;
        }
    }
    assert!(
        uncapped.kept_bytes() > 3 * cap,
        "the uncapped buffer kept only {}",
        uncapped.kept_bytes()
    );
    assert!(capped.samples_evicted() > 0);
    // The way back to the first point traced again what it had evicted.
    assert!(capped.samples_traced() > uncapped.samples_traced());
    let (compared, differing) = capped.verify(&shader);
    assert!(
        compared > 0 && differing == 0,
        "{differing} of {compared} differ ({frames} frames)"
    );
}
