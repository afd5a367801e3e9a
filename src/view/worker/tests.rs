use super::*;
use crate::scene::{paper_scene, SceneOverrides};
use glam::DVec2;

fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    crate::metrics::psnr_8bit(a, b).expect("same size")
}

/// `image` averaged over blocks of `COARSE_FACTOR` pixels each way.
fn shrink(image: &image::RgbImage) -> image::RgbImage {
    let f = COARSE_FACTOR;
    image::RgbImage::from_fn(image.width() / f, image.height() / f, |x, y| {
        let mut sum = [0u32; 3];
        for dy in 0..f {
            for dx in 0..f {
                let p = image.get_pixel(x * f + dx, y * f + dy);
                for c in 0..3 {
                    sum[c] += u32::from(p[c]);
                }
            }
        }
        image::Rgb(sum.map(|v| (v / (f * f)) as u8))
    })
}

#[test]
fn a_coarse_picture_shows_the_same_field_as_the_full_one() {
    let overrides = SceneOverrides {
        width: Some(160),
        height: Some(120),
        ..SceneOverrides::default()
    };
    let scene = paper_scene(&overrides).unwrap();
    let viewer = Viewer::new(&scene);
    let mut accel = Accelerator::build_with(BackendKind::default(), &scene.objects, None).unwrap();
    let mut zoomed = ViewState::default();
    viewer.apply(
        &mut zoomed,
        super::super::Input::Wheel {
            notches: 3,
            at: DVec2::new(40.0, 30.0),
        },
    );
    for state in [ViewState::default(), zoomed] {
        let scenes = Scenes::new(&scene, &viewer, viewer.size_of(&state));
        let kind = AnimatorKind::of(&state);
        let options = |scene: &Scene| Options {
            linear: false,
            rsvp: RsvpKnobs::default_for(scene.samples),
            traced_images: true,
            ..Options::new(Techniques::FULL, 0..1)
        };
        let coarse_scene = scenes.of(kind, true);
        let mut coarse = Animator::interactive(coarse_scene, &mut accel, options(coarse_scene));
        let rough = render_coarse(&mut coarse, &viewer, 1, state.clone());
        drop(coarse);
        let full_scene = scenes.of(kind, false);
        let mut full = Animator::interactive(full_scene, &mut accel, options(full_scene));
        let exact = render(&mut full, &viewer, 1, state.clone(), None).unwrap();
        assert!(!rough.complete && exact.complete);
        assert_eq!(rough.image.dimensions(), exact.image.dimensions());
        // A sixteenth of the samples (snapped to whole sample groups).
        assert!(
            (40 * 30..2 * 40 * 30).contains(&rough.stats.work.samples_traced),
            "{}",
            rough.stats.work.samples_traced
        );
        // One coarse pixel a block: near the block's average (point
        // samples of a checkerboard at 40x30 alias: 17-21 dB here).
        let blocks = image::RgbImage::from_fn(40, 30, |x, y| {
            *rough.image.get_pixel(x * COARSE_FACTOR, y * COARSE_FACTOR)
        });
        let score = psnr(&blocks, &shrink(&exact.image));
        assert!(score > 15.0, "{state:?}: {score:.1} dB");
    }
}
