//! Numbers drawn for a ray's path: what light and glossy samples are
//! placed by.
//!
//! Promise: a draw is a pure function of the path's key, the purpose's
//! seed and the words given (a light's number, a sample's index, an
//! axis), never of the thread, the tile, the frame or the backend. A
//! path's key is a hash of its camera ray's bits (a pure function of the
//! world-anchored sample) and of the bounces taken since ([`child_key`]),
//! so a reused sample draws what a fresh trace of it draws, and Embree
//! and the grid, whose hit points differ in their last bits, draw alike.

use crate::ray::{Ray, RayPacket, PACKET_WIDTH};
use crate::sampling::{hash, unit};

/// The keys of a packet of camera rays (or of rays entering shading at
/// `depth`): a hash of each ray's origin and direction bits.
pub(super) fn ray_keys(rays: &RayPacket, depth: u32) -> [u64; PACKET_WIDTH] {
    std::array::from_fn(|lane| {
        let Ray { origin, dir, .. } = rays[lane];
        hash(&[
            u64::from(origin.x.to_bits()) << 32 | u64::from(origin.y.to_bits()),
            u64::from(origin.z.to_bits()) << 32 | u64::from(dir.x.to_bits()),
            u64::from(dir.y.to_bits()) << 32 | u64::from(dir.z.to_bits()),
            u64::from(depth),
        ])
    })
}

/// The key of the path a bounce of kind `bounce` (1 reflection, 2
/// refraction) continues from a path keyed `key`.
pub(super) fn child_key(key: u64, bounce: u64) -> u64 {
    hash(&[key, bounce])
}

/// A number in [0, 1) drawn from `key`, `seed` and `words` (at most
/// four).
pub(super) fn key_draw(key: u64, seed: u64, words: &[u64]) -> f32 {
    let mut all = [seed, key, 0, 0, 0, 0];
    all[2..2 + words.len()].copy_from_slice(words);
    // f32 rounding can carry a draw just below 1 onto 1.
    (unit(hash(&all[..2 + words.len()])) as f32).min(ONE_BELOW)
}

/// The largest f32 below 1.
pub(super) const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;
