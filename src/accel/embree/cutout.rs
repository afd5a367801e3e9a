//! Cut-out meshes in Embree: an intersection and an occlusion filter on
//! their triangle geometry, which rejects every hit where the mesh's
//! [`Cutout`] lets rays through, so Embree goes on to the next one.
//!
//! Promises:
//! - The filters ask [`Cutout::lets_through`] exactly what the grid asks:
//!   the triangle and the barycentrics of the candidate hit.
//! - The cut-out a filter reads is owned by the scene the geometry is
//!   attached to and outlives it (see `SceneBuilder::attach_triangles`).
//! - No panic reaches C: the body runs in [`callback_panic::catch`]; a
//!   panic there keeps the hit and is raised once the trace returns.

use std::ffi::c_void;

use super::{callback_panic, sys};
use crate::geometry::Cutout;

/// Sets `cutout` as `geometry`'s user data and both filters on it.
///
/// # Safety
/// `geometry` must be a live triangle geometry, and `cutout` must stay at
/// its address, unchanged, until the geometry is destroyed.
pub(super) unsafe fn set_filters(geometry: sys::RTCGeometry, cutout: &Cutout) {
    // SAFETY: the caller promises a live geometry and a cut-out that
    // outlives it; Embree stores the pointer and passes it back unread.
    unsafe {
        sys::rtcSetGeometryUserData(geometry, cutout as *const Cutout as *mut c_void);
        sys::rtcSetGeometryIntersectFilterFunction(geometry, Some(reject_clear_hits));
        sys::rtcSetGeometryOccludedFilterFunction(geometry, Some(reject_clear_hits));
    }
}

/// Embree's filter callback: clears `valid` for every candidate hit the
/// geometry's cut-out lets through.
unsafe extern "C" fn reject_clear_hits(args: *const sys::RTCFilterFunctionNArguments) {
    callback_panic::catch(|| {
        // SAFETY: Embree passes valid arguments for the duration of the
        // call: `geometryUserPtr` is the `Cutout` `set_filters` stored;
        // `valid` holds `N` ints and `hit` an RTCHitN of `N` lanes, laid
        // out by field (Ng_x, Ng_y, Ng_z, u, v, primID, ...: the header's
        // RTCHitN_u/_v/_primID accessors), all of 4-byte elements.
        unsafe {
            let args = &*args;
            let cutout = &*(args.geometryUserPtr as *const Cutout);
            let n = args.N as usize;
            let valid = std::slice::from_raw_parts_mut(args.valid, n);
            let floats = args.hit as *const f32;
            let ids = args.hit as *const u32;
            for (lane, valid) in valid.iter_mut().enumerate() {
                if *valid == 0 {
                    continue;
                }
                let u = *floats.add(3 * n + lane);
                let v = *floats.add(4 * n + lane);
                let prim = *ids.add(5 * n + lane);
                if cutout.lets_through(prim, u, v) {
                    *valid = 0;
                }
            }
        }
    });
}
