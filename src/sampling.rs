//! Where inside a pixel (a lattice cell) its sub-samples look: the
//! positions antialiasing averages over.
//!
//! Promises:
//! - A sub-sample's offset is a pure function of its cell's column (for
//!   x) or row (for y), its index and a fixed seed: never of the thread,
//!   the tile order or the frame. Cells keyed by world-anchored lattice
//!   positions (a pan's whole turn) get the same offsets in every frame, so
//!   a reused cell equals a fresh trace of it bit for bit.
//! - Stratified: with a square count (4, 9, 16, ...) the offsets of a cell
//!   are multi-jittered (Chiu, Shirley and Wang): one in each cell of an
//!   n x n grid, and one in each of the count's slices along x and along
//!   y, so a straight edge across the pixel is covered to within one
//!   sub-sample's share; otherwise each axis alone is stratified
//!   (n-rooks: one offset in each of the count's slices along x, and along
//!   y).
//! - Separable: x offsets depend on the column alone and y offsets on the
//!   row alone, so projections that tabulate their column and row terms
//!   keep doing so (count x (width + height) entries, not per pixel).
//! - A single sample is the cell's centre, as without antialiasing.

/// Sub-samples a pixel at most (a 16 x 16 stratified reference).
pub const MAX_SAMPLES_PER_PIXEL: u32 = 256;

/// The count a converged reference traces for each pixel.
pub const REFERENCE_SAMPLES_PER_PIXEL: u32 = 256;

/// The seed all offsets are drawn from.
const SEED: u64 = 0x7265_7472_6163_6521;

/// How many sub-samples a pixel gets, and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSamples {
    count: u32,
    /// The side of the grid for a square count; 0 otherwise.
    grid: u32,
}

impl Default for PixelSamples {
    fn default() -> Self {
        PixelSamples::ONE
    }
}

impl PixelSamples {
    /// One sample at the centre of each pixel.
    pub const ONE: PixelSamples = PixelSamples { count: 1, grid: 1 };

    /// `count` sub-samples a pixel, within 1..=[`MAX_SAMPLES_PER_PIXEL`].
    pub fn new(count: u32) -> Result<PixelSamples, String> {
        if !(1..=MAX_SAMPLES_PER_PIXEL).contains(&count) {
            return Err(format!(
                "samples per pixel must be within 1..{MAX_SAMPLES_PER_PIXEL}, got {count}"
            ));
        }
        let side = (f64::from(count).sqrt().round()) as u32;
        let grid = if side * side == count { side } else { 0 };
        Ok(PixelSamples { count, grid })
    }

    pub fn count(self) -> u32 {
        self.count
    }

    /// The side n of the n x n grid of a square count (1 for one sample);
    /// 0 for the other counts.
    pub fn grid_side(self) -> u32 {
        self.grid
    }

    /// The x offset within its cell, in [0, 1), of sub-sample `index` of
    /// the cells of column `col`.
    #[inline]
    pub fn x(self, col: i64, index: u32) -> f64 {
        self.offset(col, index, 0)
    }

    /// The y offset within its cell, in [0, 1), of sub-sample `index` of
    /// the cells of row `row`.
    #[inline]
    pub fn y(self, row: i64, index: u32) -> f64 {
        self.offset(row, index, 1)
    }

    fn offset(self, line: i64, index: u32, axis: u64) -> f64 {
        debug_assert!(index < self.count);
        if self.count == 1 {
            return 0.5;
        }
        let jitter = unit(hash(&[SEED, axis, line as u64, u64::from(index)]));
        let slice = if self.grid > 0 {
            // Sub-sample k sits in grid cell (k % n, k / n); along x its
            // fine slice within the cell's column is a permutation, drawn
            // from the line and the column, of the cell's row (and the
            // same along y with the axes swapped): n-rooks over all n^2.
            let n = self.grid;
            let (coarse, fine) = if axis == 0 {
                (index % n, index / n)
            } else {
                (index / n, index % n)
            };
            coarse * n + permuted(n, fine, &[axis, line as u64, u64::from(coarse)])
        } else {
            // n-rooks: a permutation of the slices per line and axis.
            permuted(self.count, index, &[axis, line as u64])
        };
        (f64::from(slice) + jitter) / f64::from(self.count)
    }
}

/// Where `index` goes in a permutation of 0..`count` drawn from `key`
/// (Fisher-Yates with hashed draws).
fn permuted(count: u32, index: u32, key: &[u64]) -> u32 {
    let n = count as usize;
    let mut slots: [u16; MAX_SAMPLES_PER_PIXEL as usize] = std::array::from_fn(|i| i as u16);
    for i in (1..n).rev() {
        let mut words = [SEED ^ 0x5eed, i as u64, 0, 0, 0];
        words[2..2 + key.len()].copy_from_slice(key);
        let j = (hash(&words[..2 + key.len()]) % (i as u64 + 1)) as usize;
        slots.swap(i, j);
    }
    u32::from(slots[index as usize])
}

/// SplitMix64 over `words`: the same bits everywhere, for any input.
pub(crate) fn hash(words: &[u64]) -> u64 {
    words.iter().fold(0x9e37_79b9_7f4a_7c15u64, |state, &w| {
        let mut z = (state ^ w).wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    })
}

/// The top 53 bits of `bits` as a number in [0, 1).
pub(crate) fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sample_is_the_centre() {
        let one = PixelSamples::new(1).unwrap();
        assert_eq!(one, PixelSamples::ONE);
        for line in [-5, 0, 7, 1 << 40] {
            assert_eq!((one.x(line, 0), one.y(line, 0)), (0.5, 0.5));
        }
    }

    #[test]
    fn counts_outside_the_limits_are_refused() {
        assert!(PixelSamples::new(0).is_err());
        assert!(PixelSamples::new(MAX_SAMPLES_PER_PIXEL + 1).is_err());
        assert!(PixelSamples::new(MAX_SAMPLES_PER_PIXEL).is_ok());
    }

    #[test]
    fn square_counts_put_one_sample_in_each_cell_of_the_grid() {
        for count in [4, 9, 16, 256] {
            let samples = PixelSamples::new(count).unwrap();
            let n = f64::from(count).sqrt() as usize;
            for (col, row) in [(0i64, 0i64), (17, -3), (2303, 1151)] {
                let mut cells = vec![0; n * n];
                for index in 0..count {
                    let (x, y) = (samples.x(col, index), samples.y(row, index));
                    assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                    cells[(y * n as f64) as usize * n + (x * n as f64) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "{count} at ({col}, {row})");
            }
        }
    }

    #[test]
    fn every_count_puts_one_sample_in_each_slice_of_each_axis() {
        for count in [2, 3, 4, 5, 8, 9, 12, 16, 256] {
            let samples = PixelSamples::new(count).unwrap();
            for line in [0i64, 9, -40] {
                for axis in 0..2 {
                    let mut slices = vec![0; count as usize];
                    for index in 0..count {
                        let offset = if axis == 0 {
                            samples.x(line, index)
                        } else {
                            samples.y(line, index)
                        };
                        slices[(offset * f64::from(count)) as usize] += 1;
                    }
                    assert!(slices.iter().all(|&s| s == 1), "{count}, axis {axis}");
                }
            }
        }
    }

    #[test]
    fn offsets_depend_on_the_line_and_index_alone() {
        let samples = PixelSamples::new(4).unwrap();
        // The same from any thread, in any order.
        let here: Vec<f64> = (0..4).map(|i| samples.x(123, i)).collect();
        let there =
            std::thread::spawn(move || (0..4).rev().map(|i| samples.x(123, i)).collect::<Vec<_>>())
                .join()
                .unwrap();
        assert_eq!(here, there.into_iter().rev().collect::<Vec<_>>());
        // Jittered: lines differ.
        assert_ne!(samples.x(123, 0), samples.x(124, 0));
        assert_ne!(samples.x(123, 0), samples.y(123, 0));
    }
}
