//! Giving up a frame traced from nothing when newer input makes it stale
//! (an interactive viewer's): the tracing stops within a packet, and the
//! frame loop throws the frame and its half-filled store away.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::accel::Intersector;
use crate::ray::{lanes, Hit, HitPacket, LaneMask, Ray, RayPacket};

/// `inner`, until `stop` is set: from then on every ray misses, cheaply,
/// and [`Abandonable::tripped`] says so. A picture or store traced through
/// it after a trip is wrong and must be thrown away whole; if it never
/// tripped, every answer was `inner`'s and the picture is exact.
pub(super) struct Abandonable<'a> {
    inner: &'a dyn Intersector,
    stop: &'a AtomicBool,
    tripped: AtomicBool,
}

impl<'a> Abandonable<'a> {
    pub(super) fn new(inner: &'a dyn Intersector, stop: &'a AtomicBool) -> Abandonable<'a> {
        Abandonable {
            inner,
            stop,
            tripped: AtomicBool::new(false),
        }
    }

    /// Whether any ray was answered wrongly because `stop` was set.
    pub(super) fn tripped(&self) -> bool {
        self.tripped.load(Ordering::Relaxed)
    }

    fn given_up(&self) -> bool {
        let stop = self.stop.load(Ordering::Relaxed);
        if stop {
            self.tripped.store(true, Ordering::Relaxed);
        }
        stop
    }
}

impl Intersector for Abandonable<'_> {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if self.given_up() {
            return None;
        }
        self.inner.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        !self.given_up() && self.inner.occluded(ray)
    }

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        if self.given_up() {
            for lane in lanes(mask) {
                hits[lane] = None;
            }
            return;
        }
        self.inner.intersect8(rays, mask, hits);
    }

    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        if self.given_up() {
            return 0;
        }
        self.inner.occluded8(rays, mask)
    }
}
