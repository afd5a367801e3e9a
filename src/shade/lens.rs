//! Where on the lens each camera ray passes (depth of field).
//!
//! Promise: a camera ray's lens position is a pure function of its
//! pinhole ray (through [`super::draws`]: a hash of the ray's bits, so of
//! the world-anchored sample), a fixed seed and where the sample stands
//! among its neighbours ([`PixelStrata`]), so a reused sample passes the
//! lens where a fresh trace of it does. Stratified:
//! - the sub-samples of a square count n x n draw one in each cell of an
//!   n x n grid over the lens's square (their pixel cells dealt a fixed
//!   shuffle of the grid's cells, its own);
//! - the RSVP lattice's samples draw one in each cell of a 2^m x 2^m grid
//!   across every aligned 2^m x 2^m block of any level
//!   ([`super::strata::lattice_digits`]);
//!
//! each jittered inside its cell by the key.

use super::draws::{key_draw, ray_keys};
use super::strata::{CellDeal, PixelStrata};
use crate::camera::Lens;
use crate::ray::{LaneMask, RayPacket};

/// The seed lens positions are drawn from.
const SEED: u64 = 0x6c65_6e73_2070_6f73;

/// The deal of the lens square's cells to a pixel's sub-samples.
static LENS_CELLS: CellDeal = CellDeal::new(0x6c65_6e73_2063_656c);

/// The lens rays of the pinhole camera rays `rays` (lanes outside `mask`
/// as they were).
pub(super) fn lens_rays(
    lens: &Lens,
    rays: &RayPacket,
    mask: LaneMask,
    strata: Option<&PixelStrata>,
) -> RayPacket {
    let keys = ray_keys(rays, 0);
    std::array::from_fn(|lane| {
        if mask & (1 << lane) == 0 {
            return rays[lane];
        }
        let (u, v) = (
            key_draw(keys[lane], SEED, &[0]),
            key_draw(keys[lane], SEED, &[1]),
        );
        let at = LENS_CELLS.place((u, v), strata.map(|s| s.lane(lane)));
        lens.ray(&rays[lane], at)
    })
}
