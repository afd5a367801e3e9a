//! Glass: Whitted refraction with exact Fresnel weighting, read from scene
//! files and MTL libraries; refracted rays counted and recorded by OSTC, so
//! a moving glass ball stays bit-exact; shadows through glass opaque;
//! total internal reflection in a prism.

use std::path::Path;

use glam::Vec3;
use retrace::accel::Intersector;
use retrace::accel::{Accelerator, BackendKind};
use retrace::render::{render_frame, Frame};
use retrace::scene::{load_scene, parse_scene_str, SceneOverrides};
use retrace::shade::Surface;

use crate::common::{retrace, retrace_ok};

fn small(width: u32, height: u32) -> SceneOverrides {
    SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    }
}

/// A glass (or, with `transparency = 0`, black opaque) ball over a
/// red-and-white floor, seen from above at a slant.
fn ball_scene(transparency: f32) -> String {
    format!(
        "[render]\nmax_depth = 6\nbackground = [0, 0, 1]\nambient = [0.1, 0.1, 0.1]\n\
         [camera]\nposition = [0, 2.2, 6]\nlook_at = [0, 1, 0]\nfov = 30\n\
         [[light]]\nposition = [0, 10, 0]\n\
         [material.floor]\ncheckers = 0\n\
         [material.glass]\ndiffuse = [0, 0, 0]\ntransparency = {transparency}\nior = 1.5\n\
         [[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"floor\"\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\nmaterial = \"glass\"\n"
    )
    .replace(
        "checkers = 0",
        "checker = { colors = [[1, 1, 1], [1, 0, 0]], scale = 0.25 }",
    )
}

#[test]
fn a_glass_ball_shows_the_floor_behind_it_and_counts_refraction_rays() {
    for backend in [BackendKind::Embree, BackendKind::Grid] {
        let render = |transparency: f32| {
            let scene = parse_scene_str(
                &ball_scene(transparency),
                Path::new("glass.toml"),
                &small(64, 48),
            )
            .unwrap();
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            render_frame(&scene, &accel)
        };
        let (opaque, opaque_rays) = render(0.0);
        let (glass, glass_rays) = render(1.0);
        assert_eq!(opaque_rays.refraction, 0);
        assert!(glass_rays.refraction > 0, "{glass_rays:?}");
        // The ball's centre: black (ambient times black) when opaque; the
        // floor seen through it when glass, red and white squares.
        let centre = |f: &retrace::render::Frame| f.pixels[(24 * 64 + 32) as usize];
        assert!(opaque.pixels.len() == glass.pixels.len());
        assert!(centre(&opaque).max_element() < 0.01, "{}", centre(&opaque));
        assert!(centre(&glass).x > 0.3, "{}", centre(&glass));
    }
}

#[test]
fn shadows_through_glass_are_opaque() {
    // Looking straight down at a green ball over a white floor, lit from
    // the left: the shadow falls beside the ball, on floor the camera sees
    // directly. Glass or not, it is the same shadow: ambient only.
    let scene = |transparency: f32| {
        format!(
            "[render]\nambient = [0.05, 0.05, 0.05]\nmax_depth = 6\n\
             [camera]\nposition = [0, 6, 0]\nlook_at = [0, 0, -0.0001]\nfov = 90\n\
             [[light]]\nposition = [-8, 8, 0]\n\
             [material.white]\ndiffuse = [1, 1, 1]\n\
             [material.ball]\ndiffuse = [0, 1, 0]\ntransparency = {transparency}\n\
             [[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"white\"\n\
             [[object]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 0.6\nmaterial = \"ball\"\n"
        )
    };
    for backend in [BackendKind::Embree, BackendKind::Grid] {
        let render = |transparency: f32| {
            let scene =
                parse_scene_str(&scene(transparency), Path::new("s.toml"), &small(64, 64)).unwrap();
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            render_frame(&scene, &accel).0
        };
        let (opaque, glass) = (render(0.0), render(1.0));
        let ambient = Vec3::splat(0.05);
        let shadowed: Vec<usize> = (0..opaque.pixels.len())
            .filter(|&i| (opaque.pixels[i] - ambient).abs().max_element() < 1e-6)
            .collect();
        assert!(shadowed.len() > 20, "{}", shadowed.len());
        for i in shadowed {
            assert_eq!(
                glass.pixels[i], opaque.pixels[i],
                "pixel {i}: lit through the glass"
            );
        }
        // The glass ball itself is not the green opaque one.
        assert_ne!(glass.pixels[32 * 64 + 32], opaque.pixels[32 * 64 + 32]);
    }
}

#[test]
fn a_bouncing_glass_ball_is_bit_exact_with_ostc() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/glass-bounce.toml");
    for backend in ["embree", "grid"] {
        let out = retrace_ok(
            &[
                "animate",
                scene.to_str().unwrap(),
                "--width",
                "96",
                "--height",
                "72",
                "--frames",
                "0-7",
                "--mode",
                "ostc",
                "--backend",
                backend,
                "-o",
                "out/f_###.png",
                "--stats",
                "out/s.csv",
                "--verify",
            ],
            dir.path(),
        );
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains("bit for bit"), "{backend}: {said}");
        let csv = std::fs::read_to_string(dir.path().join("out/s.csv")).unwrap();
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let column = header.iter().position(|c| *c == "refraction_rays").unwrap();
        let refracted: u64 = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(column).unwrap().parse::<u64>().unwrap())
            .sum();
        assert!(refracted > 0, "{backend}: {csv}");
        // OSTC re-traced less than the whole frame after frame 0.
        let traced = header.iter().position(|c| *c == "samples_traced").unwrap();
        let later: Vec<u64> = csv
            .lines()
            .skip(2)
            .map(|l| l.split(',').nth(traced).unwrap().parse().unwrap())
            .collect();
        assert!(later.iter().all(|&n| n < 96 * 72), "{backend}: {later:?}");
    }
}

#[test]
fn bad_glass_values_are_refused_with_file_line_and_field() {
    let base = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n[material.g]\n";
    for (fields, field, needle) in [
        (
            "transparency = 1\nior = 0\n",
            "material.g.ior",
            "above 0, got 0",
        ),
        (
            "transparency = 1\nior = -1.5\n",
            "material.g.ior",
            "above 0, got -1.5",
        ),
        (
            "transparency = 1.5\n",
            "material.g.transparency",
            "within 0..1",
        ),
        (
            "transparency = 1\ntransmission_filter = [1, -1, 1]\n",
            "material.g.transmission_filter",
            "negative",
        ),
    ] {
        let err = parse_scene_str(
            &format!("{base}{fields}"),
            Path::new("g.toml"),
            &SceneOverrides::default(),
        )
        .unwrap_err();
        assert!(matches!(err.line, Some(6..=8)), "{err}");
        assert_eq!(err.field.as_deref(), Some(field), "{err}");
        assert!(err.message.contains(needle), "{err}");
    }
}

#[test]
fn bad_glass_values_in_a_material_library_are_warnings_naming_the_line() {
    // MTL files come from other programs: as for its other mistakes, the
    // material falls back to the default and the model still renders.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
    )
    .unwrap();
    for (line, needle) in [
        (
            "Ni 0",
            "m.mtl:3: Ni: an index of refraction must be above 0, got 0",
        ),
        (
            "Ni -1.2",
            "m.mtl:3: Ni: an index of refraction must be above 0, got -1.2",
        ),
        ("d 1.5", "m.mtl:3: d: 1.5 is outside 0..1"),
        ("d -0.5", "m.mtl:3: d: -0.5 is outside 0..1"),
    ] {
        std::fs::write(
            dir.path().join("m.mtl"),
            format!("newmtl a\nKd 0.5 0.5 0.5\n{line}\nillum 7\n"),
        )
        .unwrap();
        let out = retrace(
            &[
                "render", "m.obj", "--width", "16", "--height", "12", "-o", "m.png",
            ],
            dir.path(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{line}: {err}");
        assert!(err.contains(needle), "{line}: {err}");
        assert!(
            err.contains("material 'a' uses the default material"),
            "{err}"
        );
    }
    // A good glass entry loads as glass.
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl a\nKd 0 0 0\nd 0.2\nNi 1.33\nTf 0.5 1 1\nillum 7\n",
    )
    .unwrap();
    let mesh = retrace::scene::load_obj_mesh(&dir.path().join("m.obj")).unwrap();
    let glass = mesh.parts[0].material.as_ref().unwrap().glass.unwrap();
    assert!((glass.transparency - 0.8).abs() < 1e-6);
    assert_eq!(glass.ior, 1.33);
    assert_eq!(glass.filter, Vec3::new(0.5, 1.0, 1.0));
}

/// `scenes/glass-prism.toml`: looking into the prism's front face, every
/// ray meets the hypotenuse inside beyond the critical angle and is
/// reflected whole down through the bottom face to the red and white
/// floor beneath. Were the hypotenuse to let light through (TIR broken, or
/// the prism's index 1), the face would show the blue wall and sky behind.
#[test]
fn the_prism_reflects_totally_at_its_hypotenuse() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/glass-prism.toml");
    let (width, height) = (160, 120);
    let scene = load_scene(&path, &small(width, height)).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let prism = scene
        .objects
        .iter()
        .position(|o| o.name == "prism")
        .unwrap();
    let glass = scene.materials[scene.objects[prism].material]
        .glass
        .expect("the MTL's glass");
    assert_eq!((glass.ior, glass.transparency), (1.5, 1.0));
    let mut unbent = scene.clone();
    let material = unbent.objects[prism].material;
    unbent.materials[material].glass.as_mut().unwrap().ior = 1.0;
    // Blue well above red: the wall (0.1, 0.2, 0.8) or the sky, not the
    // floor's white or red squares.
    let bluish = |frame: &Frame, i: usize| frame.pixels[i].z > frame.pixels[i].x + 0.2;
    for backend in [BackendKind::Embree, BackendKind::Grid] {
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        // Pixels whose centre and 8 neighbours' centres meet the front
        // face (its normal +z) first, in its upper three quarters: a ray
        // entering lower, bent down, meets the bottom face first (and
        // reflects totally there), then leaves through the hypotenuse.
        let on_front_face = |x: u32, y: u32| {
            let ray = scene.camera.primary_ray(x, y).unwrap();
            accel.intersect(&ray).is_some_and(|hit| {
                let surface = Surface::from_hit(&scene, &ray, &hit);
                hit.object as usize == prism
                    && surface.geometric_normal.z > 0.99
                    && surface.point.y > 0.85
            })
        };
        let face: Vec<usize> = (1..height - 1)
            .flat_map(|y| (1..width - 1).map(move |x| (x, y)))
            .filter(|&(x, y)| (0..9).all(|k| on_front_face(x + k % 3 - 1, y + k / 3 - 1)))
            .map(|(x, y)| (y * width + x) as usize)
            .collect();
        assert!(face.len() > 800, "{backend:?}: {} pixels", face.len());
        let (frame, rays) = render_frame(&scene, &accel);
        let (seen_through, _) = render_frame(&unbent, &accel);
        let count = |f: &Frame| face.iter().filter(|&&i| bluish(f, i)).count();
        assert_eq!(
            count(&frame),
            0,
            "{backend:?}: light through the hypotenuse"
        );
        assert!(
            count(&seen_through) > face.len() / 2,
            "{backend:?}: at index 1 only {} of {} pixels show the wall",
            count(&seen_through),
            face.len()
        );
        assert!(rays.refraction > 0, "{rays:?}");
    }
}
