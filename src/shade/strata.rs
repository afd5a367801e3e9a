//! Where a camera sample stands among its neighbours, for stratifying
//! what it draws (its shutter time, lens position and first glossy
//! bounce): the cell of its pixel's n x n grid of sub-samples, and the
//! deal of those cells to the cells of each purpose's sampled square.

use std::sync::OnceLock;

use super::draws::ONE_BELOW;
use crate::ray::PACKET_WIDTH;
use crate::sampling::{hash, MAX_SAMPLES_PER_PIXEL};

/// The largest side of a pixel's grid of sub-samples.
pub(super) const MAX_SIDE: usize = 16;
const _: () = assert!(MAX_SIDE * MAX_SIDE == MAX_SAMPLES_PER_PIXEL as usize);

/// Where each lane's camera sample lies in its pixel: the cell of the
/// pixel's n x n grid of sub-samples its stratum is, read off the
/// stratum's place on the lattice of strata. That lattice is anchored to
/// the world (a pan moves it by whole cells, n strata), so a sample keeps
/// its cell whichever packet, frame or window traces it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelStrata {
    side: u32,
    /// (column, row) in 0..side.
    cells: [(u32, u32); PACKET_WIDTH],
}

impl PixelStrata {
    /// The lanes' cells for strata at lattice positions `strata`
    /// (column, row) on a lattice `side` strata a cell along each axis
    /// (2 to 16).
    pub fn new(side: u32, strata: [(i64, i64); PACKET_WIDTH]) -> PixelStrata {
        assert!(
            (2..=MAX_SIDE as u32).contains(&side),
            "strata of 2 x 2 to 16 x 16 a cell, not {side}"
        );
        let n = i64::from(side);
        PixelStrata {
            side,
            cells: strata.map(|(col, row)| (col.rem_euclid(n) as u32, row.rem_euclid(n) as u32)),
        }
    }

    /// The side n and lane `lane`'s cell, as [`lobe_position`] takes them.
    pub(super) fn lane(&self, lane: usize) -> (u32, (u32, u32)) {
        (self.side, self.cells[lane])
    }
}

/// A fixed shuffle of a pixel's n x n cells for each side n, drawn from a
/// seed: which cell of a sampled square (a lobe's, a lens's) a sub-sample
/// in cell `cell` of its pixel draws in. A bijection, so any n x n window
/// of strata, which holds each pixel cell once, draws in each cell of the
/// square once. Each purpose has its own seed, so its cells share nothing
/// with another's or with where the sub-samples sit.
pub(super) struct CellDeal {
    seed: u64,
    shuffles: [OnceLock<Box<[u16]>>; MAX_SIDE + 1],
}

impl CellDeal {
    pub(super) const fn new(seed: u64) -> CellDeal {
        CellDeal {
            seed,
            shuffles: [const { OnceLock::new() }; MAX_SIDE + 1],
        }
    }

    /// The cell of the square's `side` x `side` grid a sub-sample in
    /// pixel cell `cell` draws in.
    pub(super) fn cell(&self, side: u32, (col, row): (u32, u32)) -> (u32, u32) {
        let shuffle = self.shuffles[side as usize].get_or_init(|| self.shuffled(side * side));
        let cell = u32::from(shuffle[(row * side + col) as usize]);
        (cell % side, cell / side)
    }

    /// A shuffle of 0..`count` drawn from the seed (Fisher-Yates with
    /// hashed draws).
    fn shuffled(&self, count: u32) -> Box<[u16]> {
        let mut cells: Vec<u16> = (0..count as u16).collect();
        for i in (1..count as usize).rev() {
            let j = hash(&[self.seed, u64::from(count), i as u64]) % (i as u64 + 1);
            cells.swap(i, j as usize);
        }
        cells.into_boxed_slice()
    }

    /// `(u, v)` (in [0, 1)^2) placed in the cell a sub-sample with
    /// `stratum` (n, its cell of its pixel's n x n grid) is dealt; as it
    /// is without.
    pub(super) fn place(
        &self,
        (u, v): (f32, f32),
        stratum: Option<(u32, (u32, u32))>,
    ) -> (f32, f32) {
        let Some((side, cell)) = stratum else {
            return (u, v);
        };
        let (a, b) = self.cell(side, cell);
        let n = side as f32;
        // f32 rounding can carry a cell's last draw onto its end.
        (
            ((a as f32 + u) / n).min(ONE_BELOW),
            ((b as f32 + v) / n).min(ONE_BELOW),
        )
    }
}

impl CellDeal {
    /// `u` (in [0, 1)) placed in the interval a sub-sample with `stratum`
    /// is dealt, of [0, 1) cut into n^2 (dealt cell (a, b) of the n x n
    /// grid is interval `b n + a`); as it is without.
    pub(super) fn place_on_line(&self, u: f32, stratum: Option<(u32, (u32, u32))>) -> f32 {
        let Some((side, cell)) = stratum else {
            return u;
        };
        let (a, b) = self.cell(side, cell);
        let intervals = side * side;
        ((b * side + a) as f32 + u) / intervals as f32
    }
}
