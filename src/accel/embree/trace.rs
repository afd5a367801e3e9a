//! Tracing committed scenes: rays and 8-wide packets converted to Embree's
//! layout, the rtcIntersect/rtcOccluded calls, and hits converted back.
//!
//! Promises:
//! - Only committed scenes are traced, through `&` (Embree allows any
//!   number of concurrent traces on a committed scene).
//! - Lanes outside the caller's mask are neither traced nor written.
//! - A hit names its object: the instance id for a hit inside an instance,
//!   else the geometry id (every scene attaches geometries by object id).
//! - A stack of scenes reports exactly the nearest hit of one scene holding
//!   everything: each scene is traced with the ray as the one before left it.
//! - A panic in the error callback during a trace call is raised right after
//!   that call returns (`callback_panic.rs`); Embree's error slot is not read
//!   per ray.

use super::CommittedScene;
use super::{callback_panic, sys};
use crate::ray::{lanes, Hit, HitPacket, LaneMask, Ray, RayPacket, PACKET_WIDTH};

/// Embree's id for "no geometry" / "no instance".
const INVALID_ID: u32 = u32::MAX;

#[cfg(embree_version = "3")]
// Which optional fields exist depends on how Embree was configured
// (instStackSize, minWidthDistanceFactor), hence the catch-all update.
#[allow(clippy::needless_update)]
fn intersect_context() -> sys::RTCIntersectContext {
    // Re-creation of the header's inline rtcInitIntersectContext.
    sys::RTCIntersectContext {
        flags: sys::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
        filter: None,
        instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
        ..Default::default()
    }
}

#[repr(C, align(32))]
struct ValidMask8([i32; PACKET_WIDTH]);

impl ValidMask8 {
    fn new(mask: LaneMask) -> Self {
        ValidMask8(std::array::from_fn(|lane| {
            if mask & (1 << lane) != 0 {
                -1
            } else {
                0
            }
        }))
    }
}

fn embree_ray(ray: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tmin,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        time: ray.time,
        tfar: ray.tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

fn hit_object(geom_id: u32, inst_id: u32) -> u32 {
    if inst_id != INVALID_ID {
        inst_id
    } else {
        geom_id
    }
}

impl CommittedScene {
    pub fn intersect1(&self, ray: &Ray) -> Option<Hit> {
        intersect1(&[self], ray)
    }

    pub fn occluded1(&self, ray: &Ray) -> bool {
        occluded1(&[self], ray)
    }

    pub fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        intersect8(&[self], rays, mask, hits)
    }

    pub fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        occluded8(&[self], rays, mask)
    }
}

// Tracing a stack of scenes: each call keeps the ray's shortened `tfar` and
// hit from the previous scene, so Embree reports the nearest hit over all of
// them. Every scene of a stack names its geometries by object id, so a hit
// says its object whichever scene it came from.

/// The lanes of `mask` worth tracing through the `index`th scene of a
/// stack: all of them for the first; for the later (small, moving) ones
/// only the lanes whose ray, as shortened so far, may cross the scene's
/// bounds. The later scenes hold only the moving objects, which most
/// rays pass far from: without this every packet would pay a full call
/// into each of them.
fn lanes_to_trace(
    scene: &CommittedScene,
    index: usize,
    ray: &sys::RTCRay8,
    mask: LaneMask,
) -> LaneMask {
    match index {
        0 => mask,
        _ if scene.bounds.is_empty() => 0,
        _ => scene.bounds.crossing_lanes_soa(
            &[ray.org_x, ray.org_y, ray.org_z],
            &[ray.dir_x, ray.dir_y, ray.dir_z],
            &ray.tnear,
            &ray.tfar,
            mask,
        ),
    }
}

pub(super) fn intersect1(scenes: &[&CommittedScene], ray: &Ray) -> Option<Hit> {
    let mut rayhit = sys::RTCRayHit {
        ray: embree_ray(ray),
        hit: sys::RTCHit {
            geomID: INVALID_ID,
            primID: INVALID_ID,
            instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        },
    };
    for scene in scenes {
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; context and rayhit are valid for the call.
        unsafe {
            let mut context = intersect_context();
            sys::rtcIntersect1(scene.raw, &mut context, &mut rayhit);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: the scene is committed; null arguments select the defaults.
        unsafe {
            sys::rtcIntersect1(scene.raw, &mut rayhit, std::ptr::null_mut());
        }
        callback_panic::resume();
    }
    (rayhit.hit.geomID != INVALID_ID).then(|| Hit {
        t: rayhit.ray.tfar,
        object: hit_object(rayhit.hit.geomID, rayhit.hit.instID[0]),
        prim: rayhit.hit.primID,
        u: rayhit.hit.u,
        v: rayhit.hit.v,
    })
}

pub(super) fn occluded1(scenes: &[&CommittedScene], ray: &Ray) -> bool {
    let mut r = embree_ray(ray);
    for scene in scenes {
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; context and ray are valid for the call.
        unsafe {
            let mut context = intersect_context();
            sys::rtcOccluded1(scene.raw, &mut context, &mut r);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: the scene is committed; null arguments select the defaults.
        unsafe {
            sys::rtcOccluded1(scene.raw, &mut r, std::ptr::null_mut());
        }
        callback_panic::resume();
        if r.tfar == f32::NEG_INFINITY {
            return true;
        }
    }
    false
}

fn ray8(rays: &RayPacket) -> sys::RTCRay8 {
    sys::RTCRay8 {
        org_x: rays.map(|r| r.origin.x),
        org_y: rays.map(|r| r.origin.y),
        org_z: rays.map(|r| r.origin.z),
        tnear: rays.map(|r| r.tmin),
        dir_x: rays.map(|r| r.dir.x),
        dir_y: rays.map(|r| r.dir.y),
        dir_z: rays.map(|r| r.dir.z),
        time: rays.map(|r| r.time),
        tfar: rays.map(|r| r.tmax),
        mask: [u32::MAX; PACKET_WIDTH],
        id: [0; PACKET_WIDTH],
        flags: [0; PACKET_WIDTH],
    }
}

pub(super) fn intersect8(
    scenes: &[&CommittedScene],
    rays: &RayPacket,
    mask: LaneMask,
    hits: &mut HitPacket,
) {
    let mut rayhit = sys::RTCRayHit8 {
        ray: ray8(rays),
        hit: sys::RTCHit8 {
            geomID: [INVALID_ID; PACKET_WIDTH],
            primID: [INVALID_ID; PACKET_WIDTH],
            instID: [[INVALID_ID; PACKET_WIDTH]; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        },
    };
    for (index, scene) in scenes.iter().enumerate() {
        let open = lanes_to_trace(scene, index, &rayhit.ray, mask);
        if open == 0 {
            continue;
        }
        let valid = ValidMask8::new(open);
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; `valid` and `rayhit` are 32-byte
        // aligned as rtcIntersect8 requires (repr(align(32)) on both).
        unsafe {
            let mut context = intersect_context();
            sys::rtcIntersect8(valid.0.as_ptr(), scene.raw, &mut context, &mut rayhit);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: as above; null arguments select the defaults.
        unsafe {
            sys::rtcIntersect8(
                valid.0.as_ptr(),
                scene.raw,
                &mut rayhit,
                std::ptr::null_mut(),
            );
        }
        callback_panic::resume();
    }
    for lane in lanes(mask) {
        let geom = rayhit.hit.geomID[lane];
        hits[lane] = (geom != INVALID_ID).then(|| Hit {
            t: rayhit.ray.tfar[lane],
            object: hit_object(geom, rayhit.hit.instID[0][lane]),
            prim: rayhit.hit.primID[lane],
            u: rayhit.hit.u[lane],
            v: rayhit.hit.v[lane],
        });
    }
}

pub(super) fn occluded8(scenes: &[&CommittedScene], rays: &RayPacket, mask: LaneMask) -> LaneMask {
    let mut ray = ray8(rays);
    let mut occluded: LaneMask = 0;
    for (index, scene) in scenes.iter().enumerate() {
        let open = lanes_to_trace(scene, index, &ray, mask & !occluded);
        if open == 0 {
            continue;
        }
        let valid = ValidMask8::new(open);
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; `valid` and `ray` are 32-byte aligned.
        unsafe {
            let mut context = intersect_context();
            sys::rtcOccluded8(valid.0.as_ptr(), scene.raw, &mut context, &mut ray);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: as above; null arguments select the defaults.
        unsafe {
            sys::rtcOccluded8(valid.0.as_ptr(), scene.raw, &mut ray, std::ptr::null_mut());
        }
        callback_panic::resume();
        occluded |= lanes(open)
            .filter(|&lane| ray.tfar[lane] == f32::NEG_INFINITY)
            .fold(0, |acc, lane| acc | (1 << lane));
    }
    occluded
}
