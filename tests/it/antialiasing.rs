//! Antialiasing: several stratified sub-samples a pixel, world-anchored, so
//! reused frames stay exact.

use std::path::Path;

use retrace::frame_loop::{Options, Techniques};
use retrace::sampling::PixelSamples;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

/// `scenes/name` with its include spliced in, at `width` x `height`.
fn shipped(name: &str, width: u32, height: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let overrides = SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    };
    retrace::scene::load_scene(&path, &overrides).unwrap()
}

/// The paper scene with `extra` tables, at 48x32.
fn paper_with(extra: &str) -> Scene {
    let paper =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paper.toml")).unwrap();
    let overrides = SceneOverrides {
        width: Some(48),
        height: Some(32),
        ..SceneOverrides::default()
    };
    parse_scene_str(
        &format!("{paper}\n{extra}"),
        Path::new("scenes/paper.toml"),
        &overrides,
    )
    .unwrap()
}

fn four() -> PixelSamples {
    PixelSamples::new(4).unwrap()
}

on_every_backend! {
    antialiased_pans_equal_full_renders_bit_for_bit(backend) {
        let scene = paper_with(
            "[animation]\nframes = 6\n[[animation.camera]]\nframe = 0\nyaw = 0.0\npitch = -9.0\n\
             [[animation.camera]]\nframe = 5\nyaw = 40.0\npitch = -6.0\n",
        );
        let options = Options { samples: four(), ..Options::new(Techniques::AUTO, 0..6) };
        let stats = crate::common::run_exact_reusing_with(&scene, backend, options);
        assert!(stats.iter().all(|s| s.mode.as_str() == "pan"));
        // Samples count cells; the rays, their four sub-samples each.
        assert_eq!(stats[0].samples_traced * 4, stats[0].primary_rays);
    }

    antialiased_moving_objects_equal_full_renders_bit_for_bit(backend) {
        let scene = shipped("paper-bounce.toml", 48, 32);
        let options = Options { samples: four(), ..Options::new(Techniques::AUTO, 0..5) };
        let stats = crate::common::run_exact_reusing_with(&scene, backend, options);
        assert!(stats.iter().all(|s| s.mode.as_str() == "ostc"));
    }
}
