//! Still geometry split off into its own Embree scene (traced first, the
//! moving scene after it) finds exactly the hits of one scene holding
//! everything, before and after moves, for single rays and packets.

use std::path::Path;

use glam::Vec3;
use retrace::accel::embree::{EmbreeIntersector, StillSplit};
use retrace::accel::Intersector;
use retrace::geometry::{Object, Placement};
use retrace::ray::{HitPacket, Ray, RayPacket, ALL_LANES, PACKET_WIDTH};
use retrace::rng::SplitMix64;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};
use retrace::timeline::Animation;

const PAPER: &str = include_str!("../../scenes/paper.toml");

/// The paper scene with a still bunny, a bouncing ball and a bunny that
/// slides and turns: spheres moved in place and a mesh moved as an instance.
const MOVERS: &str = r#"
[material.porcelain]
diffuse = [0.85, 0.82, 0.76]

[[object]]
name = "still-bunny"
type = "mesh"
file = "bunny.obj"
material = "porcelain"
translate = [2.0, 0.0, 6.0]

[[object]]
name = "moving-bunny"
type = "mesh"
file = "bunny.obj"
material = "porcelain"
translate = [-1.0, 0.0, 5.0]

[[object]]
type = "sphere"
name = "ball"
center = [-2.6, 0.5, 3.0]
radius = 0.5
material = "porcelain"

[animation]
frames = 12

[[animation.bounce]]
object = "ball"
height = 2.0
period = 10

[[animation.object]]
object = "moving-bunny"
frame = 0

[[animation.object]]
object = "moving-bunny"
frame = 11
translate = [2.5, 0.3, -1.5]
rotate = [0.0, 120.0, 0.0]
"#;

fn scene() -> Scene {
    let text = format!("{PAPER}\n{MOVERS}");
    parse_scene_str(
        &text,
        Path::new("scenes/paper.toml"),
        &SceneOverrides::default(),
    )
    .unwrap()
}

/// Rays from the camera's side of the scene into the movers' space, and
/// from points all over it in random directions (shadow- and
/// reflection-like rays, many starting near or inside the movers' bounds).
fn random_packets(rng: &mut SplitMix64, count: usize) -> Vec<RayPacket> {
    let mut point = |scale: f32| {
        Vec3::new(
            rng.range(-scale, scale),
            rng.range(0.0, scale),
            rng.range(-scale, scale) + 4.0,
        )
    };
    (0..count)
        .map(|_| {
            std::array::from_fn(|_| {
                let origin = point(6.0);
                let target = point(3.0);
                Ray::new(origin, (target - origin).normalize())
            })
        })
        .collect()
}

fn moves_at(animation: &Animation, objects: &[Object], frame: u32) -> Vec<(u32, glam::Affine3A)> {
    animation
        .objects
        .iter()
        .flat_map(|track| {
            let transform = track.transform_at(frame);
            track.objects.iter().map(move |&id| (id, transform))
        })
        .filter(|&(id, _)| matches!(objects[id].placement, Placement::Instance(_)))
        .map(|(id, transform)| (id as u32, transform))
        .collect()
}

fn assert_same_hits(split: &EmbreeIntersector, whole: &EmbreeIntersector, packets: &[RayPacket]) {
    for (p, rays) in packets.iter().enumerate() {
        let mut a: HitPacket = [None; PACKET_WIDTH];
        let mut b: HitPacket = [None; PACKET_WIDTH];
        split.intersect8(rays, ALL_LANES, &mut a);
        whole.intersect8(rays, ALL_LANES, &mut b);
        assert_eq!(a, b, "packet {p}: nearest hits differ");
        assert_eq!(
            split.occluded8(rays, ALL_LANES),
            whole.occluded8(rays, ALL_LANES),
            "packet {p}: occlusion differs"
        );
        // Odd lanes only: masked-off lanes stay untouched.
        let mut c: HitPacket = [None; PACKET_WIDTH];
        split.intersect8(rays, 0b1010_1010, &mut c);
        for lane in 0..PACKET_WIDTH {
            let expected = if lane % 2 == 1 { b[lane] } else { None };
            assert_eq!(c[lane], expected, "packet {p} lane {lane}: masked trace");
        }
        for (lane, ray) in rays.iter().enumerate() {
            // Embree's single-ray and packet kernels may round differently,
            // so single rays are compared with single rays.
            assert_eq!(
                split.intersect(ray),
                whole.intersect(ray),
                "packet {p} lane {lane}"
            );
            assert_eq!(
                split.occluded(ray),
                whole.occluded(ray),
                "packet {p} lane {lane}"
            );
        }
    }
}

#[test]
fn split_still_geometry_finds_the_same_hits_as_one_scene() {
    let scene = scene();
    let animation = scene.animation.clone().unwrap();
    let mut split = EmbreeIntersector::build_with(&scene.objects, StillSplit::Always).unwrap();
    let mut whole = EmbreeIntersector::build_with(&scene.objects, StillSplit::Never).unwrap();
    assert!(split.still_split() && !whole.still_split());
    let packets = random_packets(&mut SplitMix64(7), 3000);
    let mut hits_on_movers = 0;
    for frame in [0, 3, 7, 11] {
        let moves = moves_at(&animation, &scene.objects, frame);
        assert_eq!(moves.len(), 2, "the ball and the moving bunny");
        split.move_objects(&moves).unwrap();
        whole.move_objects(&moves).unwrap();
        assert_same_hits(&split, &whole, &packets);
        let movers: Vec<u32> = moves.iter().map(|(id, _)| *id).collect();
        hits_on_movers += packets
            .iter()
            .flat_map(|rays| rays.iter())
            .filter(|ray| {
                whole
                    .intersect(ray)
                    .is_some_and(|hit| movers.contains(&hit.object))
            })
            .count();
    }
    // The comparison must have covered hits on the moving scene too.
    assert!(
        hits_on_movers > 100,
        "only {hits_on_movers} hits on the movers"
    );
}

#[test]
fn only_big_still_geometry_beside_movers_is_split() {
    let scene = scene();
    let auto = EmbreeIntersector::build(&scene.objects).unwrap();
    assert!(!auto.still_split(), "two bunnies are below the threshold");
    let mut still = scene.clone();
    for object in &mut still.objects {
        object.placement = Placement::World;
    }
    let nothing_moves = EmbreeIntersector::build_with(&still.objects, StillSplit::Always).unwrap();
    assert!(!nothing_moves.still_split(), "nothing moves: one scene");
}
