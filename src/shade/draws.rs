//! Numbers drawn from a shaded point: what light and glossy samples are
//! placed by.
//!
//! Promise: a draw is a pure function of the point's bits, the purpose's
//! seed and the words given (a light's number, a sample's index, an
//! axis), never of the thread, the tile or the frame. A reused pixel
//! sample meets the same point as a fresh trace of it, so it draws the
//! same numbers.

use glam::Vec3;

use crate::sampling::{hash, unit};

/// A number in [0, 1) drawn from `point`, `seed` and `words` (at most
/// four).
pub(super) fn point_draw(point: Vec3, seed: u64, words: &[u64]) -> f32 {
    let mut key = [
        seed,
        u64::from(point.x.to_bits()),
        u64::from(point.y.to_bits()),
        u64::from(point.z.to_bits()),
        0,
        0,
        0,
        0,
    ];
    key[4..4 + words.len()].copy_from_slice(words);
    // f32 rounding can carry a draw just below 1 onto 1.
    (unit(hash(&key[..4 + words.len()])) as f32).min(ONE_BELOW)
}

/// The largest f32 below 1.
pub(super) const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;
