//! Rendering behaviour, run on every backend: determinism, exact partial
//! re-traces, shadows, reflections, and scenes far from the origin or tiny.

use std::path::Path;

use glam::Vec3;
use retrace::accel::{Accelerator, BackendKind};
use retrace::geometry::{Shape, TriangleMesh};
use retrace::render::{render_frame, trace_groups, Frame, SampleGroup};
use retrace::scene::{paper_scene, parse_scene_str, Scene, SceneOverrides};
use retrace::shade::Shader;

fn small(width: u32, height: u32) -> SceneOverrides {
    SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    }
}

fn scene(text: &str, width: u32, height: u32) -> Scene {
    parse_scene_str(text, Path::new("test.toml"), &small(width, height)).unwrap()
}

fn render(scene: &Scene, backend: BackendKind) -> Frame {
    let accel = Accelerator::build(backend, &scene.objects).unwrap();
    render_frame(scene, &accel).0
}

fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// A sphere floating over a plane under the camera, lit from the left: its
/// shadow falls to the right, beside it.
const SHADOW_SCENE: &str = r#"
[render]
background = [0.0, 0.0, 1.0]
ambient = [0.05, 0.05, 0.05]
[camera]
position = [0.0, 6.0, 0.0]
look_at = [0.0, 0.0, -0.0001]
fov = 90.0
[[light]]
position = [-8.0, 8.0, 0.0]
[[object]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
[[object]]
type = "sphere"
center = [0.0, 1.0, 0.0]
radius = 0.6
"#;

/// A mirror quad facing the camera, with a red ball behind the camera.
const MIRROR_SCENE: &str = r#"
[render]
background = [0.0, 0.0, 0.0]
ambient = [0.2, 0.2, 0.2]
[camera]
position = [0.0, 0.0, 5.0]
yaw = 0.0
fov = 40.0
[[light]]
position = [0.0, 3.0, 3.0]
[material.mirror]
diffuse = [0.0, 0.0, 0.0]
reflectivity = 1.0
[material.red]
diffuse = [1.0, 0.0, 0.0]
[[object]]
type = "quad"
vertices = [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]]
material = "mirror"
[[object]]
type = "sphere"
center = [0.0, 0.0, 9.0]
radius = 1.5
material = "red"
"#;

/// Moves and scales every position in a scene (camera, lights, shapes,
/// checker squares), which leaves the picture unchanged in exact arithmetic.
fn transformed(mut scene: Scene, scale: f32, offset: Vec3) -> Scene {
    let map = |p: Vec3| p * scale + offset;
    scene.camera.position = scene.camera.position * f64::from(scale) + offset.as_dvec3();
    for light in &mut scene.lights {
        light.position = map(light.position);
    }
    for material in &mut scene.materials {
        if let Some(checker) = &mut material.checker {
            checker.scale *= scale;
        }
    }
    for object in &mut scene.objects {
        match &mut object.shape {
            Shape::Mesh(TriangleMesh { positions, .. }) => {
                positions.iter_mut().for_each(|p| *p = map(*p))
            }
            Shape::Sphere(s) => {
                s.center = map(s.center);
                s.radius *= scale;
            }
            Shape::Plane(p) => p.point = map(p.point),
        }
    }
    scene
}

/// Share of pixels of `b` that differ by more than `tolerance` (in some
/// channel) from every pixel of `a` in their 3x3 neighbourhood: edges that
/// moved by less than a pixel do not count, speckle and holes do.
fn share_differing_beyond_edges(a: &Frame, b: &Frame, tolerance: f32) -> f64 {
    let (w, h) = (a.width as i64, a.height as i64);
    let mut differing = 0;
    for y in 0..h {
        for x in 0..w {
            let value = b.get(x as u32, y as u32);
            let matched = (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    (0..w).contains(&nx)
                        && (0..h).contains(&ny)
                        && (a.get(nx as u32, ny as u32) - value).abs().max_element() <= tolerance
                })
            });
            differing += usize::from(!matched);
        }
    }
    differing as f64 / (w * h) as f64
}

fn mean_difference(a: &Frame, b: &Frame) -> f32 {
    let sum: f32 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .sum();
    sum / a.pixels.len() as f32
}

on_every_backend! {
    paper_scene_renders_deterministically(backend) {
        let scene = paper_scene(&small(96, 72)).unwrap();
        let a = render(&scene, backend);
        let b = render(&scene, backend);
        assert!(a.pixels.iter().zip(&b.pixels).all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)));
        // Sky at the top, something brighter and darker below.
        let distinct: std::collections::HashSet<_> = a.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect();
        assert!(distinct.len() > 500, "{} colours", distinct.len());
    }

    partial_traces_equal_the_full_frame_bit_for_bit(backend) {
        let scene = paper_scene(&small(64, 48)).unwrap();
        let accel = Accelerator::build(backend, &scene.objects).unwrap();
        let (full, full_rays) = render_frame(&scene, &accel);
        let shader = Shader::new(&scene, &accel);
        let table = retrace::camera::RayTable::new(&scene.camera);
        // A scattered subset of groups, traced on their own.
        let groups: Vec<SampleGroup> = (0..40).map(|i| SampleGroup::containing((i * 37) % 64, (i * 11) % 48)).collect();
        let (colors, rays) = trace_groups(&shader, &table, &groups);
        assert!(rays.primary > 0 && rays.primary < full_rays.primary);
        for (group, colors) in groups.iter().zip(&colors) {
            for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                let expected = full.get(col as u32, row as u32);
                assert_eq!(colors[lane].to_array().map(f32::to_bits), expected.to_array().map(f32::to_bits), "({col}, {row})");
            }
        }
    }

    shadows_fall_under_objects(backend) {
        let scene = scene(SHADOW_SCENE, 64, 64);
        let frame = render(&scene, backend);
        let camera = &scene.camera;
        // In the shadow, and the mirror-image spot on the lit side.
        let pixel_of = |p: Vec3| camera.project((p - camera.position.as_vec3()).as_dvec3()).unwrap();
        let shadowed = pixel_of(Vec3::new(1.4, 0.0, 0.0));
        let lit = pixel_of(Vec3::new(-1.4, 0.0, 0.0));
        let dark = frame.get(shadowed.x as u32, shadowed.y as u32);
        let bright = frame.get(lit.x as u32, lit.y as u32);
        assert!(luminance(dark) * 3.0 < luminance(bright), "shadow {dark} vs lit {bright}");
        let rays = {
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            render_frame(&scene, &accel).1
        };
        assert_eq!(rays.primary, 64 * 64);
        assert!(rays.shadow > 0 && rays.shadow <= rays.primary);
    }

    mirrors_reflect_what_is_behind_the_camera(backend) {
        let scene = scene(MIRROR_SCENE, 33, 33);
        let frame = render(&scene, backend);
        let centre = frame.get(16, 16);
        assert!(centre.x > 0.3 && centre.y < 0.05 && centre.z < 0.05, "centre {centre}");
        let rays = {
            let accel = Accelerator::build(backend, &scene.objects).unwrap();
            render_frame(&scene, &accel).1
        };
        assert!(rays.reflection > 0);
    }

    far_and_tiny_scenes_render_like_the_original(backend) {
        let mut base = paper_scene(&SceneOverrides {
            projection: Some(retrace::camera::Projection::Perspective),
            ..small(80, 60)
        })
        .unwrap();
        // The far checkerboard aliases: any sub-ULP shift flips pixels there.
        // A plain ground shows acne (self-shadowing speckle) and lost hits
        // just as well, without the noise.
        for material in &mut base.materials {
            material.checker = None;
        }
        let reference = render(&base, backend);
        for (scale, offset) in [(1.0, Vec3::splat(1e5)), (1e3, Vec3::splat(1e7)), (1e-4, Vec3::ZERO), (1e-4, Vec3::splat(1e-3))] {
            let moved = render(&transformed(base.clone(), scale, offset), backend);
            // Shading directions lose a few digits 1e5 from the origin, and
            // edges (silhouettes, shadow borders) may move by a fraction of
            // a pixel. Acne (self-shadowing speckle) or lost hits would make
            // large differences away from edges.
            let gross = share_differing_beyond_edges(&reference, &moved, 0.1);
            let mean = mean_difference(&reference, &moved);
            eprintln!("scale {scale}, offset {offset}: {:.3}% differ by > 0.1, mean {mean:.5}", gross * 100.0);
            assert!(gross < 0.005, "scale {scale}, offset {offset}: {:.2}% of pixels differ by > 0.1", gross * 100.0);
            assert!(mean < 0.01, "scale {scale}, offset {offset}: mean difference {mean}");
        }
    }
}
