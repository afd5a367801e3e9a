//! Where traced samples live: per level, tiles of slots allocated on first
//! touch, with a traced bit per group and the frame that last used them
//! (the least recently used go first when the buffer is over its memory
//! cap), and a small cache of recent tiles.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

use super::Level;
use crate::ray::PACKET_WIDTH;
use crate::render::{SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};
use crate::shade::RayCounts;

/// Samples per side of a storage tile (a multiple of both group sides).
/// A tile is one row of groups, 64 samples wide: pass 2 reads assembled
/// blocks 64 wide, each row of which one tile gives; and where a view's
/// pixels read samples far apart (zoomed far out, or slivers of pixels
/// tilted to the lattice) each group takes a tile of its own, whose
/// memory is mostly unused: 256-wide tiles kept three times the memory at
/// the viewer's zoom-out limit, and were no faster.
pub(super) const TILE_COLS: i64 = 64;
pub(super) const TILE_COL_SHIFT: u32 = 6;
const TILE_ROWS: i64 = GROUP_HEIGHT as i64;
pub(super) const TILE_ROW_SHIFT: u32 = 1;
pub(super) const TILE_SAMPLES: usize = (TILE_COLS * TILE_ROWS) as usize;
const _: () = assert!(TILE_COLS / GROUP_WIDTH as i64 <= 64);
const _: () = assert!(1 << TILE_COL_SHIFT == TILE_COLS && 1 << TILE_ROW_SHIFT == TILE_ROWS);

/// The memory a tile takes: its samples, and an estimate of its share of
/// the bookkeeping (its key in the map, its traced mask, when it was last
/// used).
pub(super) const TILE_BYTES: u64 = (TILE_SAMPLES * std::mem::size_of::<Vec3>()) as u64 + 64;

/// One level's traced samples, by slot, in tiles allocated on first touch
/// and given back when evicted (a tile's slot is then reused).
#[derive(Default)]
pub(super) struct LevelSamples {
    pub(super) tiles: HashMap<(i64, i64), u32, BuildHasherDefault<TileHasher>>,
    /// By tile, its samples; empty while the slot is free. A tile of its
    /// own each: an evicted tile's memory goes back to the allocator for
    /// the next, whatever its level.
    samples: Vec<Box<[[f32; 3]]>>,
    /// Per tile, one bit per 4x2 group: traced yet?
    pub(super) traced: Vec<u64>,
    /// Per tile, the last frame that read or traced it (pass 1 marks the
    /// tiles its patches read from every thread).
    used: Vec<AtomicU64>,
    /// Per tile, its key (what eviction removes from `tiles`).
    keys: Vec<(i64, i64)>,
    /// Slots of evicted tiles.
    free: Vec<u32>,
}

/// Multiplicative hashing of tile keys (small integers; no adversary).
#[derive(Default)]
pub(super) struct TileHasher(u64);

impl Hasher for TileHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(5) ^ u64::from(b)).wrapping_mul(0x517c_c1b7_2722_0a95);
        }
    }
    fn write_i64(&mut self, v: i64) {
        self.0 = (self.0.rotate_left(29) ^ v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

pub(super) fn tile_key(col: i64, row: i64) -> ((i64, i64), usize, u32) {
    let key = (col >> TILE_COL_SHIFT, row >> TILE_ROW_SHIFT);
    let (c, r) = (col & (TILE_COLS - 1), row & (TILE_ROWS - 1));
    let sample = (r * TILE_COLS + c) as usize;
    let group = c / i64::from(GROUP_WIDTH);
    (key, sample, group as u32)
}

/// Bits of a [`group_key`] for each of a group's slot column and row:
/// room for any turn's slots at the finest level; the level's index takes
/// the rest of OSTC's key.
const KEY_COORD_BITS: u32 = 43;
const _: () =
    assert!(Level::COUNT <= 1 << (crate::reuse::ostc::GROUP_KEY_BITS - 2 * KEY_COORD_BITS));

/// The name OSTC records a traced group's rays under, so that a moving
/// object erases just the groups whose rays meet it: a level-0 region
/// holds 4^k times its samples on level k.
pub(super) fn group_key(level: Level, group: SampleGroup) -> u128 {
    let fits = 0..1i64 << KEY_COORD_BITS;
    debug_assert!(
        fits.contains(&group.col) && fits.contains(&group.row),
        "{group:?}"
    );
    (level.index() as u128) << (2 * KEY_COORD_BITS)
        | (group.col as u128) << KEY_COORD_BITS
        | group.row as u128
}

/// The level and group a [`group_key`] names.
pub(super) fn key_group(key: u128) -> (Level, SampleGroup) {
    let coord = |shift: u32| ((key >> shift) & ((1 << KEY_COORD_BITS) - 1)) as i64;
    let level = Level::from_index((key >> (2 * KEY_COORD_BITS)) as usize);
    let group = SampleGroup {
        col: coord(KEY_COORD_BITS),
        row: coord(0),
    };
    (level, group)
}

/// Every traced group of a level's samples: (group, tile, bit in its mask).
pub(super) fn traced_groups(
    samples: &LevelSamples,
) -> impl Iterator<Item = (SampleGroup, usize, u32)> + '_ {
    samples
        .tiles
        .iter()
        .flat_map(move |(&(tile_col, tile_row), &tile)| {
            let mut rest = samples.traced[tile as usize];
            std::iter::from_fn(move || {
                if rest == 0 {
                    return None;
                }
                let bit = rest.trailing_zeros();
                rest &= rest - 1;
                let group = SampleGroup {
                    col: (tile_col << TILE_COL_SHIFT) + i64::from(bit) * i64::from(GROUP_WIDTH),
                    row: tile_row << TILE_ROW_SHIFT,
                };
                Some((group, tile as usize, bit))
            })
        })
}

impl LevelSamples {
    pub(super) fn tile(&self, key: (i64, i64)) -> Option<u32> {
        self.tiles.get(&key).copied()
    }

    /// The tile of `key`, made (all black, untraced) if there is none.
    pub(super) fn tile_or_insert(&mut self, key: (i64, i64), frame: u64) -> u32 {
        if let Some(tile) = self.tile(key) {
            return tile;
        }
        // Zeros of a primitive type: allocated zeroed, not filled.
        let samples = vec![[0f32; 3]; TILE_SAMPLES].into_boxed_slice();
        let tile = match self.free.pop() {
            Some(tile) => {
                let t = tile as usize;
                self.samples[t] = samples;
                self.traced[t] = 0;
                *self.used[t].get_mut() = frame;
                self.keys[t] = key;
                tile
            }
            None => {
                self.samples.push(samples);
                self.traced.push(0);
                self.used.push(AtomicU64::new(frame));
                self.keys.push(key);
                self.samples.len() as u32 - 1
            }
        };
        self.tiles.insert(key, tile);
        tile
    }

    /// Tiles holding samples.
    pub(super) fn tile_count(&self) -> usize {
        self.tiles.len()
    }

    /// Marks tile `tile` as read by `frame`.
    #[inline]
    pub(super) fn mark_used(&self, tile: u32, frame: u64) {
        self.used[tile as usize].store(frame, Ordering::Relaxed);
    }

    /// Every tile not used since before frame `since`: (last used, tile).
    pub(super) fn unused_since(&self, since: u64) -> impl Iterator<Item = (u64, u32)> + '_ {
        self.tiles.values().filter_map(move |&tile| {
            let used = self.used[tile as usize].load(Ordering::Relaxed);
            (used < since).then_some((used, tile))
        })
    }

    /// Gives tile `tile` back: its samples are gone (null, traced again
    /// when read) and its memory freed.
    pub(super) fn evict(&mut self, tile: u32) {
        let t = tile as usize;
        self.tiles.remove(&self.keys[t]);
        self.samples[t] = Box::default();
        self.traced[t] = 0;
        self.free.push(tile);
    }

    /// The samples of tile `tile`, by [`tile_key`]'s sample index.
    pub(super) fn tile_colors(&self, tile: u32) -> &[Vec3] {
        bytemuck::cast_slice(&self.samples[tile as usize])
    }

    fn tile_colors_mut(&mut self, tile: u32) -> &mut [Vec3] {
        bytemuck::cast_slice_mut(&mut self.samples[tile as usize])
    }

    /// Keeps freshly traced groups of this level, sorted by row and
    /// column. Returns, per requester, the samples it gained (none past
    /// `last_row`, beyond the pole) and the rays they took.
    /// Every tile of this level's groups in `groups` (sorted by row and
    /// column) must exist ([`LevelSamples::tile_or_insert`]).
    pub(super) fn keep(
        &mut self,
        traced: TracedGroups,
        last_row: i64,
        requesters: usize,
    ) -> Vec<(u64, RayCounts)> {
        let mut kept = vec![(0u64, RayCounts::default()); requesters];
        // Consecutive groups mostly share a tile.
        let mut recent = None;
        for ((&(_, group, who), colors), rays) in
            traced.groups.iter().zip(traced.colors).zip(traced.rays)
        {
            let (key, _, bit) = tile_key(group.col, group.row);
            let tile = match recent {
                Some((k, tile)) if k == key => tile,
                _ => self.tile(key).expect("tiles made before keeping") as usize,
            };
            recent = Some((key, tile));
            self.traced[tile] |= 1u64 << bit;
            let mut owned = 0u64;
            let tile_colors = self.tile_colors_mut(tile as u32);
            for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                let (_, sample, _) = tile_key(col, row);
                tile_colors[sample] = colors[lane];
                owned += u64::from((0..=last_row).contains(&row));
            }
            kept[who].0 += owned;
            kept[who].1 += *rays;
        }
        kept
    }

    pub(super) fn group_traced(&self, group: SampleGroup) -> bool {
        let (key, _, bit) = tile_key(group.col, group.row);
        self.tile(key)
            .is_some_and(|t| self.traced[t as usize] >> bit & 1 == 1)
    }
}

/// A batch's groups of one level, as traced: (level, group, requester),
/// each group's colours and its rays.
pub(super) struct TracedGroups<'a> {
    pub(super) groups: &'a [(Level, SampleGroup, usize)],
    pub(super) colors: &'a [[Vec3; PACKET_WIDTH]],
    pub(super) rays: &'a [RayCounts],
}

/// Remembers the last tiles read: neighbouring pixels read the same few
/// tiles, so most reads skip the hash map. Direct-mapped by level and tile
/// row parity (rows r and r + 1 may lie in neighbouring tile rows).
pub(super) struct TileCache {
    pub(super) keys: [(usize, (i64, i64)); TILE_CACHE_SLOTS],
    pub(super) tiles: [u32; TILE_CACHE_SLOTS],
}

const TILE_CACHE_SLOTS: usize = 64;
const _: () = assert!(TILE_CACHE_SLOTS == 4 * 8 * 2);

impl TileCache {
    pub(super) fn new() -> TileCache {
        TileCache {
            keys: [(usize::MAX, (i64::MIN, i64::MIN)); TILE_CACHE_SLOTS],
            tiles: [u32::MAX; TILE_CACHE_SLOTS],
        }
    }

    /// The tile of `key` in `samples` (level `level`), or u32::MAX if none.
    #[inline(always)]
    pub(super) fn tile(&mut self, samples: &LevelSamples, level: Level, key: (i64, i64)) -> u32 {
        let index = level.index();
        // Distinct for levels within 4 of each other in azimuth and 8 in
        // elevation: the owners one patch reads.
        let slot = (((level.x & 3) * 8 + (level.y & 7)) * 2) as usize + (key.1 & 1) as usize;
        if self.keys[slot] != (index, key) {
            self.keys[slot] = (index, key);
            self.tiles[slot] = samples.tile(key).unwrap_or(u32::MAX);
        }
        self.tiles[slot]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reuse::rsvp::MAX_LEVEL;

    #[test]
    fn group_keys_name_each_level_s_groups_apart() {
        let levels = [
            Level::new(0, 0),
            Level::new(2, 1),
            Level::new(MAX_LEVEL, MAX_LEVEL),
        ];
        let groups = [
            (0, 0),
            (8, 4),
            ((1 << KEY_COORD_BITS) - 8, 6),
            (73720, 36862),
        ];
        let mut keys = Vec::new();
        for level in levels {
            for (col, row) in groups {
                let group = SampleGroup { col, row };
                let key = group_key(level, group);
                assert_eq!(key_group(key), (level, group));
                keys.push(key);
            }
        }
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), levels.len() * groups.len());
    }
}
