//! Cut-outs (MTL `map_d`, a scene's `cutout_texture`): clear texels let
//! camera, shadow and reflection rays through on both backends, packets
//! and single rays alike, and reuse stays bit-exact past a cut-out plant.

use std::path::Path;

use glam::Vec3;
use retrace::accel::{Accelerator, Intersector};
use retrace::frame_loop::{Options, Techniques};
use retrace::ray::{Ray, PACKET_WIDTH};
use retrace::scene::{load_scene, parse_scene_str, SceneOverrides};

use crate::common::run_exact_reusing_with;

/// A 2 x 2 quad facing +z at z = 0, its texture once over it.
const QUAD: &str = "mtllib q.mtl\n\
    v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
    usemtl m\nf 1/1 2/2 3/3 4/4\n";

/// The quad (object 0) before a wall at z = -1 (object 1); the quad's
/// cut-out comes from its MTL, or from the scene's material when
/// `scene_cutout` names an image.
fn quad_scene(dir: &Path, scene_cutout: Option<&str>) -> String {
    let material = match scene_cutout {
        Some(file) => format!("[material.leaf]\ncutout_texture = \"{file}\"\n"),
        None => String::new(),
    };
    let uses = if scene_cutout.is_some() {
        "material = \"leaf\"\n"
    } else {
        ""
    };
    let text = format!(
        "[render]\nwidth = 32\nheight = 32\n\
         [camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [[light]]\nposition = [0, 0, 3]\n{material}\
         [[object]]\nname = \"quad\"\ntype = \"mesh\"\nfile = \"q.obj\"\n{uses}\
         [[object]]\nname = \"wall\"\ntype = \"plane\"\npoint = [0, 0, -1]\nnormal = [0, 0, 1]\n"
    );
    std::fs::write(dir.join("q.obj"), QUAD).unwrap();
    std::fs::write(dir.join("s.toml"), &text).unwrap();
    text
}

/// Left half clear, right half opaque: by alpha (colour everywhere) or, as
/// a black-and-white mask, by grey level.
fn half_clear(path: &Path, by_alpha: bool) {
    image::RgbaImage::from_fn(8, 8, |x, _| match (by_alpha, x < 4) {
        (true, clear) => image::Rgba([200, 50, 50, if clear { 0 } else { 255 }]),
        (false, true) => image::Rgba([0, 0, 0, 255]),
        (false, false) => image::Rgba([255, 255, 255, 255]),
    })
    .save(path)
    .unwrap();
}

on_every_backend! {
    clear_texels_let_rays_through_and_opaque_ones_stop_them(backend) {
        for (by_alpha, in_scene) in [(true, false), (false, false), (true, true)] {
            let dir = tempfile::tempdir().unwrap();
            half_clear(&dir.path().join("mask.png"), by_alpha);
            let mtl = if in_scene { "newmtl m\nKd 1 1 1\n" } else { "newmtl m\nKd 1 1 1\nmap_d mask.png\n" };
            std::fs::write(dir.path().join("q.mtl"), mtl).unwrap();
            quad_scene(dir.path(), in_scene.then_some("mask.png"));
            let scene = load_scene(&dir.path().join("s.toml"), &SceneOverrides::default()).unwrap();
            assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            let case = format!("alpha {by_alpha}, in the scene file {in_scene}");
            let toward = |x: f32| Ray::new(Vec3::new(x, 0.3, 3.0), Vec3::NEG_Z);
            // Through the clear half: the wall, 4 away; the opaque half: the quad.
            let clear = accel.intersect(&toward(-0.5)).expect(&case);
            assert_eq!((clear.object, clear.t), (1, 4.0), "{case}");
            let opaque = accel.intersect(&toward(0.5)).expect(&case);
            assert_eq!((opaque.object, opaque.t), (0, 3.0), "{case}");
            // Shadow rays from the wall back to the light.
            let shadow = |x: f32| Ray::segment(Vec3::new(x, 0.3, -0.99), Vec3::Z, 3.5);
            assert!(!accel.occluded(&shadow(-0.5)), "{case}");
            assert!(accel.occluded(&shadow(0.5)), "{case}");
            // Packets: lanes across the quad, left half clear.
            let xs: [f32; PACKET_WIDTH] = std::array::from_fn(|lane| -0.875 + 0.25 * lane as f32);
            let rays = xs.map(toward);
            let mut hits = [None; PACKET_WIDTH];
            accel.intersect8(&rays, 0xff, &mut hits);
            let objects = hits.map(|h| h.map(|h| h.object));
            assert_eq!(objects, [1, 1, 1, 1, 0, 0, 0, 0].map(Some), "{case}");
            let blocked = accel.occluded8(&xs.map(shadow), 0xff);
            assert_eq!(blocked, 0xf0, "{case}");
        }
    }

    a_pan_past_a_cut_out_plant_is_exact(backend) {
        let text = format!(
            "{}\n[[object]]\nname = \"plant\"\ntype = \"mesh\"\nfile = \"plant/plant.obj\"\n\
             translate = [0, 0, 8]\nscale = 3\n\
             [animation]\nframes = 4\n[[animation.camera]]\nframe = 0\nyaw = -6\n\
             [[animation.camera]]\nframe = 3\nyaw = 6\n",
            include_str!("../../scenes/paper.toml")
        );
        let overrides = SceneOverrides {
            width: Some(64),
            height: Some(48),
            spp: Some(4),
            ..SceneOverrides::default()
        };
        let scene = parse_scene_str(&text, Path::new("scenes/paper.toml"), &overrides).unwrap();
        assert!(scene.materials.iter().any(|m| m.cutout.is_some()));
        let stats = run_exact_reusing_with(&scene, backend, Options::new(Techniques::AUTO, 0..4));
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan"));
    }
}

#[test]
fn a_cutout_on_a_shape_without_texture_coordinates_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    half_clear(&dir.path().join("mask.png"), true);
    let text = "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 40\n\
                [[light]]\nposition = [0, 0, 3]\n\
                [material.leaf]\ncutout_texture = \"mask.png\"\n\
                [[object]]\nname = \"ball\"\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"leaf\"\n";
    std::fs::write(dir.path().join("s.toml"), text).unwrap();
    let scene = load_scene(&dir.path().join("s.toml"), &SceneOverrides::default()).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'ball' has no texture coordinates")),
        "{:?}",
        scene.warnings
    );
}
