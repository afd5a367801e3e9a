//! Mesh lights: a model's glowing faces (MTL `Ke`, on an object with
//! `mesh_lights = true`) light the scene as its form factor predicts, are
//! left out unless asked for, and keep reuse bit-exact.

use std::path::Path;

use glam::Vec3;
use retrace::accel::Accelerator;
use retrace::frame_loop::{Options, Techniques};
use retrace::geometry::LightShape;
use retrace::ray::{Ray, PACKET_WIDTH};
use retrace::scene::{load_scene, SceneOverrides};
use retrace::shade::{RayCounts, Shader};

use crate::common::run_exact_reusing_with;

/// A 4 x 4 panel at height 1 centred over the origin, glowing `Ke 1 1 1`.
const PANEL_OBJ: &str = "mtllib p.mtl\n\
    v -2 1 -2\nv 2 1 -2\nv 2 1 2\nv -2 1 2\n\
    usemtl glow\nf 1 2 3 4\n";
const PANEL_MTL: &str = "newmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\n";

/// A white floor under the panel, nothing else lighting it; `mesh_lights`
/// is the object's line for it (empty: not asked for).
fn panel_scene(dir: &Path, mesh_lights: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("p.obj"), PANEL_OBJ).unwrap();
    std::fs::write(dir.join("p.mtl"), PANEL_MTL).unwrap();
    let text = format!(
        "[render]\nwidth = 16\nheight = 16\nambient = [0, 0, 0]\nlight_samples = 64\n\
         [camera]\nposition = [0, 0.5, 3]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [material.white]\ndiffuse = [1, 1, 1]\n\
         [[object]]\nname = \"floor\"\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n\
         material = \"white\"\n\
         [[object]]\nname = \"panel\"\ntype = \"mesh\"\nfile = \"p.obj\"\n{mesh_lights}\n"
    );
    let path = dir.join("s.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The form factor from a point to a parallel a x b rectangle at height
/// c above one of its corners (the textbook closed form).
fn corner_form_factor(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / std::f64::consts::TAU
}

/// The mean of what rays landing within a hair of floor point `at` show,
/// from a low eye that passes under the panel.
fn floor_shows(shader: &Shader, at: Vec3, rays: usize) -> f64 {
    let mut sum = 0.0;
    let mut counts = RayCounts::default();
    for packet in 0..rays / PACKET_WIDTH {
        let packet: [Ray; PACKET_WIDTH] = std::array::from_fn(|lane| {
            let k = (packet * PACKET_WIDTH + lane) as f32;
            let target = at + Vec3::new(1e-6 * k, 0.0, 1e-6 * (k % 7.0));
            let origin = target + Vec3::new(0.0, 0.1, 3.0);
            Ray::new(origin, (target - origin).normalize())
        });
        let colors = shader.shade(&packet, 0xff, 0, &mut counts, None);
        sum += colors.iter().map(|c| f64::from(c.x)).sum::<f64>();
    }
    sum / rays as f64
}

on_every_backend! {
    a_glowing_panel_lights_a_white_floor_as_its_form_factor_predicts(backend) {
        let dir = tempfile::tempdir().unwrap();
        let scene = load_scene(&panel_scene(dir.path(), "mesh_lights = true"), &SceneOverrides::default()).unwrap();
        // A triangle light for each of the panel's two faces.
        assert_eq!(scene.lights.len(), 2);
        assert!(scene.lights.iter().all(|l| matches!(l.shape, LightShape::Triangle { .. })));
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        // Under the centre: four corners' worth of a 2 x 2 rectangle at
        // height 1. A white floor under a glow of 1 shows the form factor.
        let centre = 4.0 * corner_form_factor(2.0, 2.0, 1.0);
        // Under the middle of an edge: two 2 x 4 rectangles.
        let edge = 2.0 * corner_form_factor(4.0, 2.0, 1.0);
        for (at, expected) in [(Vec3::ZERO, centre), (Vec3::new(2.0, 0.0, 0.0), edge)] {
            let got = floor_shows(&shader, at, 512);
            assert!(
                (got / expected - 1.0).abs() < 0.01,
                "at {at}: rendered {got:.4}, the form factor gives {expected:.4}"
            );
        }
        // Seen from below, the panel shows its glow (plus what its grey
        // surface makes of the ambient-free scene: nothing).
        let mut counts = RayCounts::default();
        let up = [Ray::new(Vec3::new(0.3, 0.2, 0.1), Vec3::Y); PACKET_WIDTH];
        let seen = shader.shade(&up, 0xff, 0, &mut counts, None);
        assert!(seen.iter().all(|&c| c == Vec3::ONE), "{seen:?}");
    }

    a_ball_bouncing_in_the_cornell_box_retraces_exactly_at_four_samples(backend) {
        let overrides = SceneOverrides {
            width: Some(64),
            height: Some(64),
            spp: Some(4),
            ..SceneOverrides::default()
        };
        let scene = load_scene(Path::new("scenes/cornell.toml"), &overrides).unwrap();
        assert!(scene.lights.iter().all(|l| matches!(l.shape, LightShape::Triangle { .. })));
        let stats = run_exact_reusing_with(&scene, backend, Options::new(Techniques::AUTO, 0..4));
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
        let later: u64 = stats[1..].iter().map(|s| s.work.samples_traced).sum();
        assert!(later > 0 && later < 3 * 4 * 64 * 64 / 2, "traced {later}");
    }
}

#[test]
fn a_models_glow_is_left_out_with_a_warning_unless_the_object_asks_for_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_scene(&panel_scene(dir.path(), ""), &SceneOverrides::default()).unwrap();
    assert!(scene.lights.is_empty());
    assert!(scene.materials.iter().all(|m| m.emission == Vec3::ZERO));
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'glow' gives off light (Ke)") && w.contains("mesh_lights = true")),
        "{:?}",
        scene.warnings
    );
    // A bare model never glows: there is no object to ask.
    let bare = load_scene(&dir.path().join("p.obj"), &SceneOverrides::default()).unwrap();
    assert!(bare.materials.iter().all(|m| m.emission == Vec3::ZERO));
    assert!(bare
        .warnings
        .iter()
        .any(|w| w.contains("gives off light (Ke)")));
}

#[test]
fn mesh_lights_are_refused_where_they_cannot_work_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let error = |mesh_lights: &str| {
        let path = panel_scene(dir.path(), mesh_lights);
        load_scene(&path, &SceneOverrides::default())
            .unwrap_err()
            .to_string()
    };
    let replaced = error("mesh_lights = true\nmaterial = \"white\"");
    assert!(
        replaced.contains("s.toml:")
            && replaced.contains("object[1].mesh_lights")
            && replaced.contains("`material` replaces"),
        "{replaced}"
    );
    let moving = error(
        "mesh_lights = true\n[animation]\nframes = 3\n[[animation.object]]\nobject = \"panel\"\n\
         frame = 2\ntranslate = [0, 0.1, 0]",
    );
    assert!(
        moving.contains("animation.object[0].object") && moving.contains("cannot move yet"),
        "{moving}"
    );
    // A finely cut glowing model: more lights than any pixel should pay for.
    let mut fine = String::from("mtllib p.mtl\nusemtl glow\n");
    for i in 0..40 {
        let x = i as f32 * 0.1;
        fine += &format!(
            "v {x} 1 0\nv {} 1 0\nv {} 1 1\nv {x} 1 1\n",
            x + 0.1,
            x + 0.1
        );
        let v = 4 * i + 1;
        fine += &format!("f {v} {} {} {}\n", v + 1, v + 2, v + 3);
    }
    std::fs::write(dir.path().join("fine.obj"), fine).unwrap();
    let text = std::fs::read_to_string(panel_scene(dir.path(), "mesh_lights = true"))
        .unwrap()
        .replace("p.obj", "fine.obj");
    std::fs::write(dir.path().join("s.toml"), text).unwrap();
    let many = load_scene(&dir.path().join("s.toml"), &SceneOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(
        many.contains("80 glowing triangles") && many.contains("at most 64"),
        "{many}"
    );
}
