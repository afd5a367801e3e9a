//! Tests of the Embree wrappers: tracing single rays and packets, moving
//! spheres and instances, Embree's errors arriving as `Result`s and a
//! panic in its error callback arriving as a panic of the caller.

use glam::{Affine3A, Vec3};

use super::*;
use crate::ray::{Ray, RayPacket, PACKET_WIDTH};

fn unit_triangle_scene(device: &Device) -> CommittedScene {
    let mut builder = SceneBuilder::new(device).unwrap();
    builder
        .attach_triangles(
            3,
            &[
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            &[[0, 1, 2]],
            None,
        )
        .unwrap();
    builder
        .attach_sphere(5, Vec3::new(0.0, 0.0, -5.0), 1.0)
        .unwrap();
    builder.commit().unwrap()
}

#[test]
fn device_reports_version_and_packet_support() {
    let device = Device::new().unwrap();
    assert!(device.version() >= 30000, "version {}", device.version());
    let _ = device.native_packet8();
}

#[test]
fn single_ray_hits_triangle_then_sphere() {
    let device = Device::new().unwrap();
    let scene = unit_triangle_scene(&device);
    let hit = scene
        .intersect1(&Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z))
        .unwrap();
    assert_eq!((hit.object, hit.prim), (3, 0));
    assert!((hit.t - 2.0).abs() < 1e-6);
    let hit = scene.intersect1(&Ray::new(Vec3::new(0.0, 1.5, 2.0), -Vec3::Z));
    assert!(hit.is_none());
    let behind = Ray::new(Vec3::new(0.0, 0.0, -1.0), -Vec3::Z);
    let hit = scene.intersect1(&behind).unwrap();
    assert_eq!(hit.object, 5);
    assert!((hit.t - 3.0).abs() < 1e-5);
    assert!(scene.occluded1(&behind));
    assert!(!scene.occluded1(&Ray::segment(behind.origin, behind.dir, 2.5)));
}

#[test]
fn packets_agree_with_single_rays_and_respect_the_mask() {
    let device = Device::new().unwrap();
    let scene = unit_triangle_scene(&device);
    let rays: RayPacket =
        std::array::from_fn(|i| Ray::new(Vec3::new(-1.2 + 0.35 * i as f32, 0.1, 2.0), -Vec3::Z));
    let mask = 0b1011_0111;
    let mut hits = [None; PACKET_WIDTH];
    scene.intersect8(&rays, mask, &mut hits);
    let occluded = scene.occluded8(&rays, mask);
    for lane in 0..PACKET_WIDTH {
        if mask & (1 << lane) == 0 {
            assert_eq!(hits[lane], None);
            assert_eq!(occluded & (1 << lane), 0);
        } else {
            assert_eq!(
                hits[lane].map(|h| h.object),
                scene.intersect1(&rays[lane]).map(|h| h.object)
            );
            assert_eq!(occluded & (1 << lane) != 0, scene.occluded1(&rays[lane]));
        }
    }
    assert!(hits.iter().any(Option::is_some) && hits.iter().any(Option::is_none));
}

#[test]
fn instances_move_without_rebuilding_and_report_their_id() {
    let device = Device::new().unwrap();
    let mut child = SceneBuilder::new(&device).unwrap();
    child.attach_sphere(0, Vec3::ZERO, 1.0).unwrap();
    let mut top = SceneBuilder::new(&device).unwrap();
    top.attach_instance(
        7,
        child.commit().unwrap(),
        &Affine3A::from_translation(Vec3::new(0.0, 0.0, -10.0)),
    )
    .unwrap();
    let mut scene = top.commit().unwrap();
    let ray = Ray::new(Vec3::ZERO, -Vec3::Z);
    let hit = scene.intersect1(&ray).unwrap();
    assert_eq!(hit.object, 7);
    assert!((hit.t - 9.0).abs() < 1e-5);
    scene
        .set_instance_transform(7, &Affine3A::from_translation(Vec3::new(0.0, 0.0, -4.0)))
        .unwrap();
    assert!((scene.intersect1(&ray).unwrap().t - 3.0).abs() < 1e-5);
    scene
        .set_instance_transform(7, &Affine3A::from_translation(Vec3::new(5.0, 0.0, -4.0)))
        .unwrap();
    assert!(scene.intersect1(&ray).is_none());
}

#[test]
fn spheres_move_in_place_and_one_edit_commits_every_move() {
    let device = Device::new().unwrap();
    let mut scene = unit_triangle_scene(&device);
    let ray = Ray::new(Vec3::new(4.0, 0.0, 2.0), -Vec3::Z);
    assert!(scene.intersect1(&ray).is_none());
    let mut edit = scene.edit();
    edit.move_sphere(5, Vec3::new(4.0, 0.0, -1.0), 0.5).unwrap();
    // Not a sphere, and not a geometry at all: refused before Embree.
    assert_eq!(
        edit.move_sphere(3, Vec3::ZERO, 1.0).unwrap_err().code,
        "invalid argument"
    );
    assert!(edit.move_sphere(42, Vec3::ZERO, 1.0).is_err());
    edit.commit().unwrap();
    let hit = scene.intersect1(&ray).unwrap();
    assert_eq!((hit.object, hit.prim), (5, 0));
    assert!((hit.t - 2.5).abs() < 1e-5, "{hit:?}");
    // Gone from where it was.
    let old = Ray::new(Vec3::new(0.0, 0.0, -1.0), -Vec3::Z);
    assert!(scene.intersect1(&old).is_none() && !scene.occluded1(&old));
    // An edit dropped early (as by `?`) still commits what it moved.
    {
        let mut edit = scene.edit();
        edit.move_sphere(5, Vec3::new(4.0, 0.0, -3.0), 0.5).unwrap();
    }
    assert!((scene.intersect1(&ray).unwrap().t - 4.5).abs() < 1e-5);
}

/// The bindings come from the Embree 4 headers, so the library must be
/// the same 4.x minor release: struct layouts change between them (4.3
/// added `instPrimID` to hits), and a mismatch corrupts rays silently.
#[cfg(embree_version = "4")]
#[test]
fn embree4_library_matches_its_headers() {
    let device = Device::new().unwrap();
    assert_eq!(
        device.version() / 100,
        i64::from(sys::RTC_VERSION / 100),
        "library {} vs headers {}",
        device.version(),
        sys::RTC_VERSION
    );
}

#[test]
fn embree_errors_become_results() {
    let device = Device::new().unwrap();
    let builder = SceneBuilder::new(&device).unwrap();
    // A geometry type Embree does not know: reported through the callback.
    let err = builder
        .new_geometry(sys::RTCGeometryType(9999))
        .unwrap_err();
    assert!(err.message.contains("geometry type"), "{err}");
    // The slot was cleared: later calls succeed again.
    assert!(device.take_error().is_ok());
    let mut scene = unit_triangle_scene(&device);
    let err = scene
        .set_instance_transform(42, &Affine3A::IDENTITY)
        .unwrap_err();
    assert_eq!(err.code, "invalid argument");
}

/// The real path: Embree calls the error callback, which panics; the panic
/// does not unwind through Embree (that would abort the process) but comes
/// out of the wrapper that called Embree, once Embree has returned, with
/// Embree's own message in it.
#[test]
fn a_panic_in_the_error_callback_reaches_the_caller() {
    let device = Device::new().unwrap();
    let builder = SceneBuilder::new(&device).unwrap();
    device.panic_on_next_error();
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        builder.new_geometry(sys::RTCGeometryType(9999))
    }));
    let payload = caught.expect_err("the callback's panic reaches the caller");
    let message = payload
        .downcast_ref::<String>()
        .expect("a formatted panic message");
    assert!(
        message.starts_with("panic in the error callback on:") && message.contains("geometry type"),
        "{message}"
    );
    // Raised once; the device works on, and its errors are Results again.
    assert!(device.take_error().is_ok());
    let err = builder
        .new_geometry(sys::RTCGeometryType(9999))
        .unwrap_err();
    assert!(err.message.contains("geometry type"), "{err}");
    assert!(unit_triangle_scene(&device)
        .intersect1(&Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z))
        .is_some());
}
