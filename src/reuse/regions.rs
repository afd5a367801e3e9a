//! Screen regions: the rectangles of samples that OSTC dirties and erases
//! as a whole, laid out in the coordinates of the buffer that keeps the
//! samples (a pan lattice's whole turn, a still camera's image, a level of
//! RSVP's pyramid), so a pan moves the view and not the regions.
//!
//! Promises: a region is a whole number of sample groups
//! ([`crate::render::SampleGroup`]), so erasing regions never splits a
//! packet, and a re-trace of a region equals a full render's groups.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::render::{SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};

/// How the screen is cut into regions: `n` x `n` regions over the camera's
/// image, each a whole number of sample groups.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RegionGrid(pub u32);

impl RegionGrid {
    /// The paper's 16x16 grid (40x30 samples at 640x480).
    pub const PAPER: RegionGrid = RegionGrid(16);

    /// The grid for RSVP's sample pyramid unless asked otherwise: 4x4
    /// samples at 640x480. Its regions are erased level by level, and a
    /// viewport traces only the nulls it reads, so finer regions save
    /// little tracing and cost bookkeeping (docs/RESULTS.md, "OSTC: one
    /// group a region").
    pub const PYRAMID: RegionGrid = RegionGrid(160);

    /// The grid whose regions are one sample group each on a `width` x
    /// `height` screen: the finest there is, and the camera image's
    /// default. The regions a moving object dirties hold its reflections
    /// and shadows too, whose samples cost more than the average, and a
    /// region is dirtied only by recorded ray segments that meet the
    /// object, so every finer grid re-traces less for little more
    /// bookkeeping.
    pub fn one_group(width: u32, height: u32) -> RegionGrid {
        RegionGrid(
            width
                .div_ceil(GROUP_WIDTH)
                .max(height.div_ceil(GROUP_HEIGHT))
                .max(1),
        )
    }

    /// Region width and height in samples for a `width` x `height` image,
    /// rounded to whole sample groups (at least one).
    pub fn region_size(self, width: u32, height: u32) -> (i64, i64) {
        let n = f64::from(self.0.max(1));
        let round_to = |length: u32, step: u32| {
            let step = f64::from(step);
            ((f64::from(length) / n / step).round().max(1.0) * step) as i64
        };
        (round_to(width, GROUP_WIDTH), round_to(height, GROUP_HEIGHT))
    }
}

/// Regions tiling a buffer of `columns` x `rows` samples whose first row
/// is `first_row` (columns wrap: they are a whole turn).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RegionLayout {
    pub width: i64,
    pub height: i64,
    pub columns: i64,
    pub first_row: i64,
    pub rows: i64,
    pub across: i64,
    pub down: i64,
}

impl RegionLayout {
    pub fn new(size: (i64, i64), columns: i64, first_row: i64, rows: i64) -> RegionLayout {
        let (width, height) = size;
        debug_assert!(width % i64::from(GROUP_WIDTH) == 0 && height % i64::from(GROUP_HEIGHT) == 0);
        RegionLayout {
            width,
            height,
            columns,
            first_row,
            rows,
            across: (columns + width - 1) / width,
            down: (rows + height - 1) / height,
        }
    }

    pub fn count(&self) -> usize {
        (self.across * self.down) as usize
    }

    /// The region of sample (col, row); `col` already wrapped into the turn.
    pub fn region_of(&self, col: i64, row: i64) -> usize {
        ((row - self.first_row) / self.height * self.across + col / self.width) as usize
    }

    /// The sample groups of `region`.
    pub fn groups(&self, region: usize) -> Vec<SampleGroup> {
        let (rx, ry) = (region as i64 % self.across, region as i64 / self.across);
        let col0 = rx * self.width;
        let row0 = self.first_row + ry * self.height;
        SampleGroup::covering(
            col0..(col0 + self.width).min(self.columns),
            row0..(row0 + self.height).min(self.first_row + self.rows),
        )
    }
}

/// A set of regions, one bit each.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RegionSet {
    words: Vec<u64>,
}

impl RegionSet {
    pub fn empty(regions: usize) -> RegionSet {
        RegionSet {
            words: vec![0; regions.div_ceil(64)],
        }
    }

    pub fn insert(&mut self, region: usize) {
        self.words[region / 64] |= 1 << (region % 64);
    }

    pub fn contains(&self, region: usize) -> bool {
        self.words[region / 64] & (1 << (region % 64)) != 0
    }

    /// Whether any region of `range` is in the set.
    pub fn any_in(&self, range: std::ops::RangeInclusive<usize>) -> bool {
        let (first, last) = (*range.start(), *range.end());
        if first > last {
            return false;
        }
        let (w0, w1) = (first / 64, last / 64);
        (w0..=w1).any(|w| {
            let lo = if w == w0 { first % 64 } else { 0 };
            let hi = if w == w1 { last % 64 } else { 63 };
            // Bits lo..=hi of the word.
            let span = (u64::MAX >> (63 - (hi - lo))) << lo;
            self.words[w] & span != 0
        })
    }

    pub fn len(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.words.iter().enumerate().flat_map(|(i, &word)| {
            let mut rest = word;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let bit = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    i * 64 + bit
                })
            })
        })
    }

    /// Adds every region whose bit is set in `words` (read relaxed: the
    /// writers are done).
    pub(crate) fn union_atomic(&mut self, words: &[AtomicU64]) {
        debug_assert_eq!(words.len(), self.words.len());
        for (mine, theirs) in self.words.iter_mut().zip(words) {
            *mine |= theirs.load(Ordering::Relaxed);
        }
    }

    /// The set as words of 64 regions each (region `r` is bit `r % 64` of
    /// word `r / 64`), for bitwise work over many sets.
    pub(crate) fn words(&self) -> &[u64] {
        &self.words
    }

    pub(crate) fn words_mut(&mut self) -> &mut [u64] {
        &mut self.words
    }

    pub fn union_with(&mut self, other: &RegionSet) {
        for (mine, theirs) in self.words.iter_mut().zip(&other.words) {
            *mine |= theirs;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> RegionLayout {
        RegionLayout::new(RegionGrid(16).region_size(640, 480), 2304, 10, 482)
    }

    #[test]
    fn one_group_regions_are_one_group_at_any_size() {
        let group = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
        for (width, height) in [(640, 480), (1280, 960), (64, 48), (30, 7), (7, 300), (1, 1)] {
            let grid = RegionGrid::one_group(width, height);
            assert_eq!(grid.region_size(width, height), group, "{width}x{height}");
        }
    }

    #[test]
    fn paper_regions_are_40_by_30_and_tile_the_buffer() {
        assert_eq!(RegionGrid(16).region_size(640, 480), (40, 30));
        assert_eq!(RegionGrid(32).region_size(640, 480), (20, 16));
        let layout = layout();
        assert_eq!(layout.across, 58);
        assert_eq!(layout.down, 17);
        let mut seen = std::collections::HashSet::new();
        for region in 0..layout.count() {
            for group in layout.groups(region) {
                assert_eq!(layout.region_of(group.col, group.row), region);
                assert!(seen.insert(group), "{group:?} in two regions");
            }
        }
        // Every group of the buffer belongs to a region.
        assert_eq!(seen.len(), (2304 / 4) * (482 / 2));
    }

    #[test]
    fn region_sets() {
        let mut set = RegionSet::empty(130);
        for r in [0, 63, 64, 129] {
            set.insert(r);
        }
        assert_eq!(set.iter().collect::<Vec<_>>(), vec![0, 63, 64, 129]);
        assert_eq!(set.len(), 4);
        assert!(set.contains(64) && !set.contains(65));
        // Every range of 0..130 against the members, across word edges.
        for first in 0..130 {
            for last in first..130 {
                let expected = [0, 63, 64, 129].iter().any(|r| (first..=last).contains(r));
                assert_eq!(set.any_in(first..=last), expected, "{first}..={last}");
            }
        }
        assert!(!set.any_in(std::ops::RangeInclusive::new(5, 4)));
    }
}
