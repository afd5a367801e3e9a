//! Where a camera sample stands among its neighbours, for stratifying
//! what it draws (its shutter time, lens position and first glossy
//! bounce): a sub-sample's cell of its pixel's n x n grid, dealt to the
//! cells of each purpose's sampled square ([`CellDeal`]), or an RSVP
//! buffer sample's place on the lattice, which fixes its draws' leading
//! digits ([`lattice_digits`]).

use std::sync::OnceLock;

use super::draws::ONE_BELOW;
use crate::ray::PACKET_WIDTH;
use crate::sampling::{hash, MAX_SAMPLES_PER_PIXEL};

/// The largest side of a pixel's grid of sub-samples.
pub(super) const MAX_SIDE: usize = 16;
const _: () = assert!(MAX_SIDE * MAX_SIDE == MAX_SAMPLES_PER_PIXEL as usize);

/// Where each lane's camera sample stands among its neighbours, for
/// stratifying its draws. Both kinds are anchored to the world, so a
/// sample stands in the same place whichever packet, frame or window
/// traces it:
/// - a sub-sample of a square count: the cell of its pixel's n x n grid
///   its stratum is, read off the stratum's place on the lattice of
///   strata (a pan moves that lattice by whole cells, n strata);
/// - a sample of the RSVP lattice: its place on the lattice's finest
///   level, where every level's samples sit (see [`lattice_digits`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelStrata {
    places: Places,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Places {
    Cells {
        side: u32,
        /// (column, row) in 0..side.
        cells: [(u32, u32); PACKET_WIDTH],
    },
    /// (column, row) on the finest level.
    Lattice([(u64, u64); PACKET_WIDTH]),
}

/// Where one lane's camera sample stands ([`PixelStrata`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Stratum {
    /// (n, its cell of its pixel's n x n grid).
    Cell(u32, (u32, u32)),
    /// (column, row) on the RSVP lattice's finest level.
    Lattice(u64, u64),
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
            places: Places::Cells {
                side,
                cells: strata
                    .map(|(col, row)| (col.rem_euclid(n) as u32, row.rem_euclid(n) as u32)),
            },
        }
    }

    /// Samples of the RSVP lattice at `places` (column, row) on its finest
    /// level (two's complement for a row above the pole: such lanes carry
    /// no ray).
    pub fn on_lattice(places: [(i64, i64); PACKET_WIDTH]) -> PixelStrata {
        PixelStrata {
            places: Places::Lattice(places.map(|(col, row)| (col as u64, row as u64))),
        }
    }

    /// Where lane `lane`'s sample stands.
    pub(super) fn lane(&self, lane: usize) -> Stratum {
        match self.places {
            Places::Cells { side, cells } => Stratum::Cell(side, cells[lane]),
            Places::Lattice(places) => Stratum::Lattice(places[lane].0, places[lane].1),
        }
    }
}

/// Finest-level places a tile of the lattice's draws spans on each axis,
/// as a power of two: a whole turn (2^32 places, a turn of up to 2^16
/// columns at level 0) in one tile, whose samples are stratified
/// together.
const TILE_BITS: u32 = 32;

/// Leading digits of a lattice sample's draw its place fixes: aligned
/// blocks of up to 2^8 neighbouring samples a side are stratified, far
/// more than a viewport pixel reads (up to 11 a side); below those digits
/// a draw is the path key's own.
const LATTICE_DIGITS: u32 = 16;

/// The [`LATTICE_DIGITS`] leading digits (as an integer) of the draw of
/// the purpose seeded `seed` for the sample at finest-level place
/// `(x, y)` of the RSVP lattice.
///
/// The lattice's levels nest (a level's samples are every other one of
/// the next finer level's on each axis), so a sample cannot be dealt a
/// stratum by its cell at one level without clashing at the others.
/// Instead the place, read in Morton order (its column's and row's
/// digits interleaved), is the first coordinate of the Sobol
/// (0, 2)-sequence (the van der Corput radical inverse read backwards: a
/// level's samples are the sequence's first points) and the draw is its
/// second. By Sobol's (0, m, 2)-net property every aligned 2^m x 2^m
/// block of any level's samples, a run of 4^m in Morton order, then
/// draws one in each 4^-m interval, and a pair of neighbours along a row
/// one in each half. A nested uniform scramble (Owen's, hashed as Laine
/// and Karras do) seeded by the purpose and the tile keeps that, and
/// decorrelates purposes and tiles.
pub(super) fn lattice_digits(seed: u64, (x, y): (u64, u64)) -> u32 {
    // The sequence is linear in the index's digits, and the index is the
    // Morton order read backwards: its draw is the XOR of a table entry
    // for each byte of the column and of the row.
    let [columns, rows] = &PLACE_DRAWS;
    let draw = columns
        .iter()
        .zip(rows)
        .enumerate()
        .fold(0, |draw, (byte, (column, row))| {
            let at = |v: u64| ((v >> (8 * byte)) & 0xff) as usize;
            draw ^ column[at(x)] ^ row[at(y)]
        });
    let scramble = hash(&[seed, x >> TILE_BITS, y >> TILE_BITS]) as u32;
    nested_scramble((draw >> 32) as u32, scramble) >> (32 - LATTICE_DIGITS)
}

/// Per axis (column, row), per byte of the place within its tile and per
/// value of that byte: the XOR of the Sobol second dimension's direction
/// numbers of the index digits the byte's set digits become (the column's
/// digit d is the Morton order's digit 2d, the row's 2d + 1, and the
/// Morton order's digit m the index's digit 63 - m).
static PLACE_DRAWS: [[[u64; 256]; 4]; 2] = {
    let mut tables = [[[0; 256]; 4]; 2];
    let mut axis = 0;
    while axis < 2 {
        let mut byte = 0;
        while byte < 4 {
            let mut value = 0;
            while value < 256 {
                let mut draw = 0;
                let mut bit = 0;
                while bit < 8 {
                    if value >> bit & 1 != 0 {
                        let morton = 2 * (8 * byte + bit) + axis;
                        draw ^= SOBOL_SECOND[63 - morton];
                    }
                    bit += 1;
                }
                tables[axis][byte][value] = draw;
                value += 1;
            }
            byte += 1;
        }
        axis += 1;
    }
    tables
};

/// The even-placed and odd-placed digits of the [`LATTICE_DIGITS`]-digit
/// `digits`, each as an integer of half as many: a draw's point in a
/// square, whose cells of any 2^m x 2^m grid take the draws of 4^m
/// intervals, one each.
fn split_digits(digits: u32) -> (u32, u32) {
    let gather =
        |v: u32| (0..LATTICE_DIGITS / 2).fold(0, |acc, bit| acc | ((v >> (2 * bit)) & 1) << bit);
    (gather(digits >> 1), gather(digits))
}

/// The direction numbers of the Sobol sequence's second dimension
/// (generator x + 1: each is the last XOR itself shifted right once).
const SOBOL_SECOND: [u64; 64] = {
    let mut directions = [0; 64];
    let mut direction = 1u64 << 63;
    let mut i = 0;
    while i < 64 {
        directions[i] = direction;
        direction ^= direction >> 1;
        i += 1;
    }
    directions
};

/// Owen's nested uniform scramble of the 32-bit fraction `v`: each digit
/// flipped or not by a hash of the digits above it and `seed`. A
/// bijection on every prefix of digits, so stratification by leading
/// digits survives it.
fn nested_scramble(v: u32, seed: u32) -> u32 {
    // Laine and Karras's hash on the reversed digits: every step changes a
    // bit by the bits below it only.
    let mut x = v.reverse_bits().wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x.reverse_bits()
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

    /// `(u, v)` (in [0, 1)^2) placed in the cell a sample standing at
    /// `stratum` is dealt: a sub-sample's pixel cell's dealt cell of the
    /// n x n grid, a lattice sample's cell of the 256 x 256 grid its
    /// [`lattice_digits`] name; as it is without.
    pub(super) fn place(&self, (u, v): (f32, f32), stratum: Option<Stratum>) -> (f32, f32) {
        let ((a, b), side) = match stratum {
            None => return (u, v),
            Some(Stratum::Cell(side, cell)) => (self.cell(side, cell), side),
            Some(Stratum::Lattice(x, y)) => (
                split_digits(lattice_digits(self.seed, (x, y))),
                1 << (LATTICE_DIGITS / 2),
            ),
        };
        let n = side as f32;
        // f32 rounding can carry a cell's last draw onto its end.
        (
            ((a as f32 + u) / n).min(ONE_BELOW),
            ((b as f32 + v) / n).min(ONE_BELOW),
        )
    }
}

impl CellDeal {
    /// `u` (in [0, 1)) placed in the interval a sample standing at
    /// `stratum` is dealt: of [0, 1) cut into n^2 for a sub-sample (dealt
    /// cell (a, b) of the n x n grid is interval `b n + a`), into 65536 for
    /// a lattice sample ([`lattice_digits`]); as it is without.
    pub(super) fn place_on_line(&self, u: f32, stratum: Option<Stratum>) -> f32 {
        let interval = match stratum {
            None => return u,
            Some(Stratum::Cell(side, cell)) => {
                let (a, b) = self.cell(side, cell);
                (b * side + a, side * side)
            }
            Some(Stratum::Lattice(x, y)) => {
                (lattice_digits(self.seed, (x, y)), 1 << LATTICE_DIGITS)
            }
        };
        (interval.0 as f32 + u) / interval.1 as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Finest-level places of the aligned `side` x `side` block of level
    /// samples `spacing` places apart whose first sample is (col, row) of
    /// that level.
    fn block(spacing: u64, (col, row): (u64, u64), side: u64) -> Vec<(u64, u64)> {
        (0..side * side)
            .map(|k| ((col + k % side) * spacing, (row + k / side) * spacing))
            .collect()
    }

    #[test]
    fn every_aligned_block_of_every_level_draws_one_in_each_stratum() {
        let deal = CellDeal::new(0x7465_7374);
        // Level 0 (2^16 places apart), finer and coarser ones; blocks near
        // the origin and in far tiles.
        for spacing in [1u64 << 24, 1 << 16, 1 << 13, 1 << 2, 1] {
            for side in [2u64, 4, 8] {
                for corner in [(0, 0), (side * 3, side * 5), (side * 2301, side * 77)] {
                    let places = block(spacing, corner, side);
                    let intervals = side * side;
                    let mut on_line = vec![0; intervals as usize];
                    let mut in_square = vec![0; intervals as usize];
                    for &(x, y) in &places {
                        let t = deal.place_on_line(0.5, Some(Stratum::Lattice(x, y)));
                        on_line[(f64::from(t) * intervals as f64) as usize] += 1;
                        let (u, v) = deal.place((0.5, 0.5), Some(Stratum::Lattice(x, y)));
                        let cell = |w: f32| (f64::from(w) * side as f64) as u64;
                        in_square[(cell(v) * side + cell(u)) as usize] += 1;
                    }
                    let what = format!("spacing {spacing}, {side} a side at {corner:?}");
                    assert!(on_line.iter().all(|&n| n == 1), "times, {what}");
                    assert!(in_square.iter().all(|&n| n == 1), "squares, {what}");
                }
            }
        }
    }

    /// The draw of the Sobol sequence's second dimension at the index of
    /// place (x, y), digit by digit.
    fn direct_draw(x: u64, y: u64) -> u64 {
        let spread = |v: u64| (0..32).fold(0u64, |acc, d| acc | ((v >> d) & 1) << (2 * d));
        let mut index = (spread(x) | spread(y) << 1).reverse_bits();
        let (mut draw, mut direction) = (0, 1u64 << 63);
        while index != 0 {
            if index & 1 != 0 {
                draw ^= direction;
            }
            index >>= 1;
            direction ^= direction >> 1;
        }
        draw
    }

    #[test]
    fn the_tables_draw_as_the_sequence_does() {
        for (x, y) in [
            (0u64, 0u64),
            (1, 0),
            (0, 1),
            (5 << 16, 9 << 16),
            (0x8765_4321, 0xfedc_ba98),
        ] {
            let scramble = hash(&[7, 0, 0]) as u32;
            let direct = nested_scramble((direct_draw(x, y) >> 32) as u32, scramble);
            assert_eq!(
                lattice_digits(7, (x, y)),
                direct >> (32 - LATTICE_DIGITS),
                "({x}, {y})"
            );
        }
    }

    #[test]
    fn neighbours_along_a_row_draw_in_different_halves() {
        let deal = CellDeal::new(0x7465_7374);
        for row in 0..64u64 {
            let at = |col: u64| {
                deal.place_on_line(0.5, Some(Stratum::Lattice(col << 16, row << 16))) < 0.5
            };
            for pair in 0..32u64 {
                assert_ne!(at(2 * pair), at(2 * pair + 1), "row {row}, pair {pair}");
            }
        }
    }

    #[test]
    fn purposes_and_tiles_draw_apart_and_the_key_jitters_within_a_stratum() {
        let (time, lens) = (CellDeal::new(1), CellDeal::new(2));
        let places: Vec<(u64, u64)> = block(1 << 16, (0, 0), 16);
        let digits = |seed, dx: u64| {
            places
                .iter()
                .map(|&(x, y)| lattice_digits(seed, (x + dx, y)))
                .collect::<Vec<_>>()
        };
        assert_ne!(digits(1, 0), digits(2, 0));
        assert_ne!(digits(1, 0), digits(1, 1 << TILE_BITS));
        let at = Some(Stratum::Lattice(5 << 16, 9 << 16));
        let (low, high) = (time.place_on_line(0.0, at), time.place_on_line(0.999, at));
        assert!(high > low && high - low < 1.01 / 65536.0, "{low} {high}");
        assert_ne!(time.place_on_line(0.5, at), lens.place_on_line(0.5, at));
    }
}
