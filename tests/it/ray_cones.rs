//! Texture filtering through curved mirrors and glass: the ray cone a
//! texture lookup sees bends at the curvature of what it met on the way,
//! smooth-shaded meshes as much as the analytic spheres they stand for.
//!
//! The floor is striped black and white one texel wide, so every mip level
//! above the first is a flat grey: a cone that comes out too narrow reads
//! the stripes where the pixel covers many of them (moiré), one too wide
//! greys out stripes the pixel resolves. Each check renders one sample a
//! pixel and scores it against the converged image inside the ball's
//! outline: 64 samples a pixel reading the full-size texture (bilinear),
//! so the yardstick owes nothing to ray cones.

use std::path::Path;

use retrace::accel::{Accelerator, BackendKind};
use retrace::scene::{parse_scene_str, SceneOverrides};
use retrace::texture::TextureFilter;

/// The ball: an analytic sphere, or `scenes/textured/sphere.obj` (the
/// same unit sphere as a smooth-shaded mesh of 2,208 triangles).
#[derive(Clone, Copy, PartialEq)]
enum Ball {
    Sphere,
    Mesh,
}

/// A 96 x 96 view of a unit ball standing over a striped floor, lit by
/// the ambient term alone. `material` is the ball's material's fields.
fn scene_text(ball: Ball, material: &str) -> String {
    let ball = match ball {
        Ball::Sphere => "type = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1",
        Ball::Mesh => "type = \"mesh\"\nfile = \"sphere.obj\"\ntranslate = [0, 1, 0]",
    };
    format!(
        "[render]\nwidth = 96\nheight = 96\nmax_depth = 6\nambient = [1, 1, 1]\n\
         background = [0.3, 0.3, 0.3]\n\
         [camera]\nposition = [0, 1.3, 3.5]\nlook_at = [0, 0.8, 0]\nfov = 40\n\
         [[light]]\nposition = [0, 5, 5]\nintensity = 0\n\
         [material.stripes]\ntexture = \"stripes.png\"\n\
         [material.ball]\n{material}\n\
         [[object]]\ntype = \"mesh\"\nfile = \"floor.obj\"\nmaterial = \"stripes\"\n\
         [[object]]\n{ball}\nmaterial = \"ball\"\n"
    )
}

const MIRROR: &str = "diffuse = [0, 0, 0]\nreflectivity = 1";
const GLASS: &str = "diffuse = [0, 0, 0]\ntransparency = 1\nior = 1.5";

/// A folder with the floor (20 x 20, the texture 31 times each way: a
/// texel is 8 cm), its 8 x 8 texture of one-texel stripes, and the mesh
/// ball.
fn folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x % 2 == 0 { 0 } else { 255 }]))
        .save(dir.path().join("stripes.png"))
        .unwrap();
    std::fs::write(
        dir.path().join("floor.obj"),
        "v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10\n\
         vt 0 31\nvt 31 31\nvt 31 0\nvt 0 0\nf 4/4 3/3 2/2 1/1\n",
    )
    .unwrap();
    let sphere = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured/sphere.obj");
    std::fs::copy(sphere, dir.path().join("sphere.obj")).unwrap();
    dir
}

/// The image of `text`, as 8-bit grey: at one sample a pixel, filtered
/// by ray cones, or `converged`.
fn render(dir: &Path, text: &str, converged: bool, backend: BackendKind) -> Vec<f64> {
    let overrides = SceneOverrides {
        spp: Some(if converged { 64 } else { 1 }),
        texture_filter: Some(if converged {
            TextureFilter::Bilinear
        } else {
            TextureFilter::Trilinear
        }),
        ..SceneOverrides::default()
    };
    let scene = parse_scene_str(text, &dir.join("s.toml"), &overrides).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    let (frame, _) = retrace::render::render_frame(&scene, &accel);
    frame
        .to_rgb8()
        .pixels()
        .map(|p| p.0.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0)
        .collect()
}

/// Which pixels see the ball, and which the floor directly.
fn outlines(dir: &Path, backend: BackendKind) -> (Vec<bool>, Vec<bool>) {
    let text = scene_text(Ball::Sphere, "diffuse = [1, 0, 0]")
        .replace("texture = \"stripes.png\"", "diffuse = [0, 1, 0]")
        .replace("background = [0.3, 0.3, 0.3]", "background = [0, 0, 0]");
    let scene = parse_scene_str(&text, &dir.join("s.toml"), &SceneOverrides::default()).unwrap();
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    let image = retrace::render::render_frame(&scene, &accel).0.to_rgb8();
    let ball = image.pixels().map(|p| p.0[0] > 100).collect();
    let floor = image.pixels().map(|p| p.0[1] > 100).collect();
    (ball, floor)
}

/// Mean absolute difference of `a` from `b` over the `inside` pixels.
fn error(a: &[f64], b: &[f64], inside: &[bool]) -> f64 {
    let picked: Vec<f64> = (0..a.len())
        .filter(|&i| inside[i])
        .map(|i| (a[i] - b[i]).abs())
        .collect();
    assert!(picked.len() > 500, "{} pixels", picked.len());
    picked.iter().sum::<f64>() / picked.len() as f64
}

/// Mean absolute difference between neighbours across the stripes over
/// the `inside` pixels: high where stripes or moiré show, low where they
/// are filtered to grey.
fn stripe_contrast(image: &[f64], inside: &[bool]) -> f64 {
    let width = 96;
    let picked: Vec<f64> = (0..image.len())
        .filter(|&i| inside[i] && (i + 1) % width != 0)
        .map(|i| (image[i + 1] - image[i]).abs())
        .collect();
    picked.iter().sum::<f64>() / picked.len() as f64
}

on_every_backend! {
    the_floor_in_a_smooth_mesh_mirror_is_filtered_as_in_the_sphere_it_stands_for(backend) {
        let dir = folder();
        let (ball, _) = outlines(dir.path(), backend);
        let mut scores = Vec::new();
        for shape in [Ball::Sphere, Ball::Mesh] {
            let text = scene_text(shape, MIRROR);
            let one = render(dir.path(), &text, false, backend);
            let converged = render(dir.path(), &text, true, backend);
            scores.push((stripe_contrast(&one, &ball), error(&one, &converged, &ball)));
        }
        let [(sphere_contrast, sphere_error), (mesh_contrast, mesh_error)] = scores[..] else {
            unreachable!()
        };
        eprintln!("mirror: contrast and error, sphere {:?}, mesh {:?}", scores[0], scores[1]);
        // Taken as flat, the mesh mirror reads the stripes' finest level
        // where each pixel covers several: a moiré of about twice the
        // contrast, and well off the converged image.
        assert!(
            mesh_contrast < 1.25 * sphere_contrast,
            "contrast: mesh {mesh_contrast:.2}, sphere {sphere_contrast:.2}"
        );
        assert!(
            mesh_error < 1.25 * sphere_error,
            "error: mesh {mesh_error:.2}, sphere {sphere_error:.2}"
        );
    }

    the_floor_through_a_glass_ball_is_filtered_as_well_as_the_floor_seen_directly(backend) {
        let dir = folder();
        let (ball, floor) = outlines(dir.path(), backend);
        for shape in [Ball::Sphere, Ball::Mesh] {
            let text = scene_text(shape, GLASS);
            let one = render(dir.path(), &text, false, backend);
            let converged = render(dir.path(), &text, true, backend);
            // The floor seen directly is the yardstick: its cones are the
            // camera's own, with nothing bent on the way.
            let direct = error(&one, &converged, &floor);
            let through = error(&one, &converged, &ball);
            let name = if shape == Ball::Sphere { "sphere" } else { "mesh" };
            eprintln!("glass {name}: through {through:.2}, directly {direct:.2}");
            assert!(
                through < direct,
                "{name}: through the glass {through:.2}, the floor directly {direct:.2}"
            );
        }
    }
}

/// The chrome mesh ball and the glass ball of `scenes/textured-curved.toml`
/// moving (so the mesh is an instance, its curvature worked out through
/// its transform), seen from a still camera: OSTC's frames equal full
/// renders bit for bit.
#[test]
fn moving_curved_mirrors_and_glass_over_textures_reuse_bit_exactly() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured-curved.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let timeline = "[animation]\nframes = 3\n\
        [[animation.object]]\nobject = \"chrome ball\"\nframe = 0\ntranslate = [0, 0, 0]\n\
        [[animation.object]]\nobject = \"chrome ball\"\nframe = 3\ntranslate = [0.4, 0.2, 0]\n\
        [[animation.object]]\nobject = \"glass ball\"\nframe = 0\ntranslate = [0, 0, 0]\n\
        [[animation.object]]\nobject = \"glass ball\"\nframe = 3\ntranslate = [-0.3, 0, 0.2]\n";
    let overrides = SceneOverrides {
        width: Some(96),
        height: Some(64),
        ..SceneOverrides::default()
    };
    let scene = parse_scene_str(&format!("{text}\n{timeline}"), &path, &overrides).unwrap();
    crate::common::run_exact_reusing(
        &scene,
        BackendKind::Embree,
        retrace::frame_loop::Techniques::parse("ostc").unwrap(),
    );
}
