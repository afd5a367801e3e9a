//! Area lights: soft shadows that match the penumbra geometry predicts,
//! and reuse (OSTC, pans) that stays exact under them.

use std::path::Path;

use glam::Vec3;
use retrace::accel::{Accelerator, BackendKind};
use retrace::frame_loop::{Options, Techniques};
use retrace::ray::{Ray, PACKET_WIDTH};
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};
use retrace::shade::{RayCounts, Shader};

use crate::common::run_exact_reusing_with;

/// A disc light of radius 1 at height 4 shining down, a disc of radius 1
/// at height 2 under it, and a white floor: from a floor point at
/// distance x from the axis the occluder covers a disc of radius 2
/// centred at -x on the light's plane, so the umbra is |x| <= 1 and the
/// floor is fully lit from |x| >= 3.
const PENUMBRA: (f32, f32, f32, f32) = (4.0, 1.0, 2.0, 1.0);

fn penumbra_scene(light_samples: u32) -> Scene {
    let (light_height, light_radius, occluder_height, occluder_radius) = PENUMBRA;
    let sides = 256;
    let vertices: Vec<String> = (0..sides)
        .map(|i| {
            // The polygon's vertices lie on the occluder's circle.
            let a = std::f32::consts::TAU * i as f32 / sides as f32;
            format!(
                "[{}, {occluder_height}, {}]",
                occluder_radius * a.cos(),
                -occluder_radius * a.sin()
            )
        })
        .collect();
    let text = format!(
        "[render]\nambient = [0, 0, 0]\nlight_samples = {light_samples}\n\
         [camera]\nposition = [0, 1, 20]\nfov = 40\n\
         [[light]]\nshape = \"disc\"\nposition = [0, {light_height}, 0]\nradius = {light_radius}\n\
         normal = [0, -1, 0]\nintensity = 12\n\
         [material.white]\ndiffuse = [1, 1, 1]\n\
         [[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"white\"\n\
         [[object]]\ntype = \"polygon\"\nvertices = [{}]\nmaterial = \"white\"\n",
        vertices.join(", ")
    );
    parse_scene_str(
        &text,
        Path::new("penumbra.toml"),
        &SceneOverrides::default(),
    )
    .unwrap()
}

/// What the floor at distance `x` from the axis shows, integrated over
/// the light's disc on a fine polar grid (independent of the renderer's
/// sampling): the light's power over its area times the integral of
/// visibility x cos at the light x cos at the floor / distance^2.
fn penumbra_expected(x: f32) -> f64 {
    let (light_height, light_radius, occluder_height, occluder_radius) = PENUMBRA;
    let (h, r, oh, or) = (
        f64::from(light_height),
        f64::from(light_radius),
        f64::from(occluder_height),
        f64::from(occluder_radius),
    );
    let (rings, spokes) = (600, 1200);
    let mut sum = 0.0;
    for i in 0..rings {
        let rho = r * (i as f64 + 0.5) / rings as f64;
        let ring_area = std::f64::consts::TAU * rho * (r / rings as f64) / spokes as f64;
        for j in 0..spokes {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / spokes as f64;
            let (lx, lz) = (rho * phi.cos(), rho * phi.sin());
            // Where the segment from the floor point to the light point
            // crosses the occluder's plane.
            let t = oh / h;
            let (cx, cz) = (f64::from(x) + (lx - f64::from(x)) * t, lz * t);
            if cx.hypot(cz) <= or {
                continue;
            }
            let d2 = (lx - f64::from(x)).powi(2) + lz * lz + h * h;
            let cos = h / d2.sqrt();
            sum += cos * cos / d2 * ring_area;
        }
    }
    12.0 * sum / (std::f64::consts::PI * r * r)
}

/// The mean of what `rays` rays landing within a hair of floor point
/// (x, 0, 0) show (each its own light samples), from a low eye that
/// passes under the occluder.
fn penumbra_rendered(shader: &Shader, x: f32, rays: usize) -> f64 {
    let mut sum = 0.0;
    let mut counts = RayCounts::default();
    for packet in 0..rays / PACKET_WIDTH {
        let packet: [Ray; PACKET_WIDTH] = std::array::from_fn(|lane| {
            let k = (packet * PACKET_WIDTH + lane) as f32;
            let target = Vec3::new(x + 1e-6 * k, 0.0, 1e-6 * (k % 7.0));
            let origin = target + Vec3::new(0.0, 0.2, 12.0);
            Ray::new(origin, (target - origin).normalize())
        });
        let colors = shader.shade(&packet, 0xff, 0, &mut counts, None);
        sum += colors.iter().map(|c| f64::from(c.x)).sum::<f64>();
    }
    sum / rays as f64
}

on_every_backend! {
    a_disc_light_over_a_disc_casts_the_umbra_and_penumbra_geometry_predicts(backend) {
        let scene = penumbra_scene(64);
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        // Deep in the umbra every shadow ray is blocked: black exactly.
        for x in [0.0, 0.5, -0.9] {
            assert_eq!(penumbra_rendered(&shader, x, 64), 0.0, "umbra at x = {x}");
        }
        // Fully lit, and across the penumbra, within an 8-bit level of the
        // integral (1024 rays of 64 light samples each).
        for x in [1.1, 1.5, 2.0, 2.5, 2.9, -1.8, 3.1, 4.0] {
            let (got, expected) = (penumbra_rendered(&shader, x, 1024), penumbra_expected(x));
            assert!(
                (got - expected).abs() < 1.0 / 255.0,
                "x = {x}: rendered {got:.5}, geometry gives {expected:.5}"
            );
        }
        // The penumbra is a ramp, not a step (past x = 2.4 the light's
        // falloff with distance outweighs the light uncovered).
        let ramp: Vec<f64> = [1.05, 1.2, 1.6, 2.0, 2.4].iter().map(|&x| penumbra_rendered(&shader, x, 64)).collect();
        assert!(ramp[0] > 0.0 && ramp.windows(2).all(|w| w[0] < w[1]), "{ramp:?}");
    }

    a_ball_bouncing_under_area_lights_retraces_exactly_at_four_samples(backend) {
        let text = include_str!("../../scenes/soft-light.toml");
        let overrides = SceneOverrides {
            width: Some(96),
            height: Some(72),
            spp: Some(4),
            ..SceneOverrides::default()
        };
        let scene = parse_scene_str(text, Path::new("scenes/soft-light.toml"), &overrides).unwrap();
        let stats = run_exact_reusing_with(&scene, backend, Options::new(Techniques::AUTO, 0..5));
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
        // The ball's regions, its soft shadow among them, and no more.
        let later: u64 = stats[1..].iter().map(|s| s.work.samples_traced).sum();
        assert!(later > 0 && later < 4 * 96 * 72 / 2, "traced {later}");
    }

    a_pan_under_area_lights_is_exact(backend) {
        let text = format!(
            "{}\n[[light]]\nshape = \"rectangle\"\nposition = [0, 9, 4]\nsize = [3, 2]\nnormal = [0, -1, 0]\nintensity = 40\n\
             [[light]]\nshape = \"sphere\"\nposition = [4, 3, 6]\nradius = 0.5\nintensity = 9\n\
             [animation]\nframes = 4\n[[animation.camera]]\nframe = 0\nyaw = -6\n[[animation.camera]]\nframe = 3\nyaw = 6\n",
            include_str!("../../scenes/paper.toml")
        );
        let overrides = SceneOverrides {
            width: Some(64),
            height: Some(48),
            spp: Some(4),
            ..SceneOverrides::default()
        };
        let scene = parse_scene_str(&text, Path::new("scenes/paper.toml"), &overrides).unwrap();
        let stats = run_exact_reusing_with(&scene, backend, Options::new(Techniques::AUTO, 0..4));
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan"), "{:?}", stats.iter().map(|s| s.mode).collect::<Vec<_>>());
    }
}

#[test]
fn a_scene_without_area_lights_casts_one_shadow_ray_a_light() {
    let text = include_str!("../../scenes/paper.toml");
    let overrides = SceneOverrides {
        width: Some(32),
        height: Some(24),
        ..SceneOverrides::default()
    };
    let scene = parse_scene_str(text, Path::new("scenes/paper.toml"), &overrides).unwrap();
    let accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
    let (_, counts) = retrace::render::render_frame(&scene, &accel);
    // Two point lights: at most two shadow rays a primary hit (plus the
    // reflections' own), whatever `light_samples` says.
    let mut more = scene.clone();
    more.light_samples = 64;
    let (_, same) = retrace::render::render_frame(&more, &accel);
    assert_eq!(counts.shadow, same.shadow);
    assert!(counts.shadow <= 2 * (counts.primary + counts.reflection));
}
