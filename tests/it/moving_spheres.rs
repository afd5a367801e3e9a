//! Animated spheres stay plain spheres in both backends: a move puts the
//! sphere where the transform says (and nowhere else), both backends agree
//! on it, and a sphere moved away and back renders bit for bit as if it had
//! never moved.

use std::path::Path;

use glam::{Affine3A, Quat, Vec3};
use retrace::accel::{placed_sphere, AccelError, Accelerator, BackendKind, Intersector};
use retrace::geometry::{Object, Placement, Shape, Sphere};
use retrace::metrics::count_differences;
use retrace::ray::{Hit, Ray, RayPacket, ALL_LANES, PACKET_WIDTH};
use retrace::render::render_frame;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};

const PAPER: &str = include_str!("../../scenes/paper.toml");

const BOUNCING_BALL: &str = r#"
[material.bouncer]
diffuse = [0.95, 0.75, 0.1]
specular = [0.6, 0.6, 0.6]
shininess = 80.0
reflectivity = 0.05

[[object]]
type = "sphere"
name = "ball"
center = [-2.6, 0.5, 3.0]
radius = 0.5
material = "bouncer"

[animation]
frames = 20

[[animation.bounce]]
object = "ball"
height = 2.0
period = 10
"#;

fn bouncing_ball_scene() -> Scene {
    let overrides = SceneOverrides {
        width: Some(128),
        height: Some(96),
        ..SceneOverrides::default()
    };
    let text = format!("{PAPER}\n{BOUNCING_BALL}");
    parse_scene_str(&text, Path::new("scenes/paper.toml"), &overrides).unwrap()
}

fn ball_index(scene: &Scene) -> usize {
    scene.objects.iter().position(|o| o.name == "ball").unwrap()
}

on_every_backend! {
    a_ball_moved_away_and_back_renders_as_if_it_never_moved(backend) {
        let animated = bouncing_ball_scene();
        let ball = ball_index(&animated);
        // The same scene with the ball a static object of the world.
        let mut still = animated.clone();
        still.animation = None;
        still.objects[ball].placement = Placement::World;
        let still_accel = Accelerator::build(backend, &still.objects).unwrap();
        let (reference, _) = render_frame(&still, &still_accel);

        let track = animated.animation.as_ref().unwrap().objects[0].clone();
        let mut scene = animated.clone();
        let mut accel = Accelerator::build(backend, &scene.objects).unwrap();
        // Up the bounce, then back down where it started (frame 10, one
        // whole period); the lift at frame 10 is exactly zero.
        for frame in [3, 7, 10] {
            let transform = track.transform_at(frame);
            scene.objects[ball].placement = Placement::Instance(transform);
            accel.move_objects(&[(ball as u32, transform)]).unwrap();
            let (image, _) = render_frame(&scene, &accel);
            let differences = count_differences(&image, &reference).unwrap();
            if frame == 10 {
                assert_eq!(differences, 0, "the ball is back, yet the frame differs");
            } else {
                assert!(differences > 50, "frame {frame}: the ball did not move ({differences} pixels differ)");
            }
        }
    }
}

/// A big ground sphere and, above it, a ball placed by a transform.
fn ball_on_ground() -> (Vec<Object>, Sphere) {
    let ball = Sphere {
        center: Vec3::new(1.0, 0.5, 2.0),
        radius: 0.5,
    };
    let object = |shape, placement| Object {
        name: String::new(),
        shape,
        material: 0,
        placement,
    };
    let objects = vec![
        object(
            Shape::Sphere(Sphere {
                center: Vec3::new(0.0, -100.0, 0.0),
                radius: 100.0,
            }),
            Placement::World,
        ),
        object(Shape::Sphere(ball), Placement::Instance(Affine3A::IDENTITY)),
    ];
    (objects, ball)
}

/// Rays from `eye` at points of the disc of radius `0.8 * radius` around
/// `target`, facing the eye: each would hit a sphere of that radius there.
fn rays_at(eye: Vec3, target: Vec3, radius: f32) -> RayPacket {
    let forward = (target - eye).normalize();
    let side = forward.cross(Vec3::Y).normalize();
    let up = side.cross(forward);
    std::array::from_fn(|lane| {
        let angle = lane as f32 * std::f32::consts::TAU / PACKET_WIDTH as f32;
        let offset =
            (side * angle.cos() + up * angle.sin()) * (0.8 * radius) * (lane % 3) as f32 / 2.0;
        Ray::new(eye, target + offset - eye)
    })
}

fn assert_near(a: &Hit, b: &Hit, what: &str) {
    assert_eq!(
        (a.object, a.prim),
        (b.object, b.prim),
        "{what}: {a:?} vs {b:?}"
    );
    assert!(
        (a.t - b.t).abs() <= 1e-5 * a.t.abs(),
        "{what}: {a:?} vs {b:?}"
    );
}

#[test]
fn a_moved_sphere_is_hit_where_it_is_now_not_where_it_was_on_both_backends() {
    let (objects, ball) = ball_on_ground();
    let eye = Vec3::new(0.0, 1.5, -6.0);
    let mut backends = [BackendKind::Embree, BackendKind::Grid]
        .map(|kind| Accelerator::build(kind, &objects).unwrap());
    // Turned a quarter about a pivot off its centre, then lifted: for a
    // sphere that only moves its centre.
    let pivot = Vec3::new(0.0, 0.5, 0.0);
    let transform = Affine3A::from_translation(pivot + Vec3::new(0.0, 1.25, 0.0))
        * Affine3A::from_quat(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2))
        * Affine3A::from_translation(-pivot);
    let moved = placed_sphere(&ball, &transform).unwrap();
    assert!(
        (moved.center - Vec3::new(2.0, 1.75, -1.0)).length() < 1e-5,
        "{moved:?}"
    );
    assert!((moved.radius - ball.radius).abs() < 1e-6);
    for accel in &mut backends {
        accel.move_objects(&[(1, transform)]).unwrap();
    }

    let now = rays_at(eye, moved.center, ball.radius);
    let before = rays_at(eye, ball.center, ball.radius);
    let mut hits = [[None; PACKET_WIDTH]; 2];
    for (accel, hits) in backends.iter().zip(&mut hits) {
        accel.intersect8(&now, ALL_LANES, hits);
        for (ray, hit) in now.iter().zip(hits.iter()) {
            let hit = hit.expect("a ray at the moved ball hits");
            assert_eq!((hit.object, hit.prim), (1, 0), "{:?}", accel.kind());
            let distance = (ray.at(hit.t) - moved.center).length();
            assert!((distance - moved.radius).abs() < 1e-4, "{distance}");
            assert_near(&hit, &accel.intersect(ray).unwrap(), "packet vs single ray");
            // Nothing between the eye and the near side of the ball, the
            // ball itself up to its centre.
            let near = Ray::segment(ray.origin, ray.dir, hit.t * 0.999);
            assert!(!accel.occluded(&near));
            assert!(accel.occluded(&Ray::segment(ray.origin, ray.dir, hit.t * 1.001)));
        }
        assert_eq!(accel.occluded8(&now, ALL_LANES), ALL_LANES);
        // Where the ball was, rays pass (and go on to hit the ground).
        for ray in &before {
            let hit = accel.intersect(ray);
            assert!(
                hit.is_none_or(|h| h.object == 0),
                "{:?}: {hit:?}",
                accel.kind()
            );
            let to_old_centre = Ray::segment(ray.origin, ray.dir, 1.0);
            assert!(!accel.occluded(&to_old_centre), "{:?}", accel.kind());
        }
    }
    for (embree, grid) in hits[0].iter().zip(&hits[1]) {
        assert_near(&embree.unwrap(), &grid.unwrap(), "embree vs grid");
    }
}

#[test]
fn a_sphere_cannot_be_stretched_into_an_ellipsoid() {
    let (mut objects, ball) = ball_on_ground();
    let eye = Vec3::new(0.0, 1.5, -6.0);
    let stretch = Affine3A::from_scale(Vec3::new(1.0, 2.0, 1.0));
    for kind in [BackendKind::Embree, BackendKind::Grid] {
        let mut accel = Accelerator::build(kind, &objects).unwrap();
        let err = accel.move_objects(&[(1, stretch)]).unwrap_err();
        assert!(
            matches!(err, AccelError::SphereNotRound { object: 1 }),
            "{err}"
        );
        assert!(err.to_string().contains("object 1"), "{err}");
        // Nothing moved: the ball is still hit where it was.
        let ray = Ray::new(eye, ball.center - eye);
        assert_eq!(accel.intersect(&ray).map(|h| h.object), Some(1));
        // A uniform scale keeps it a sphere.
        let grown = Affine3A::from_scale(Vec3::splat(2.0));
        accel.move_objects(&[(1, grown)]).unwrap();
        let hit = accel
            .intersect(&Ray::new(eye, 2.0 * ball.center - eye))
            .unwrap();
        assert_eq!(hit.object, 1);
    }
    objects[1].placement = Placement::Instance(stretch);
    for kind in [BackendKind::Embree, BackendKind::Grid] {
        let err = Accelerator::build(kind, &objects).err().unwrap();
        assert!(
            matches!(err, AccelError::SphereNotRound { object: 1 }),
            "{err}"
        );
    }
}
