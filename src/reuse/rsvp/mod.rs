//! RSVP (Ray Sample Viewport): a lazily traced buffer of equal-angle samples
//! around a fixed eye, and viewports that resample it through their own
//! projection and 2D transform.
//!
//! Owns: the sample lattice pyramid ([`SampleLattice`]), the samples traced
//! so far ([`SampleBuffer`]), the resampling of viewports (described in
//! [`crate::camera::Viewport`]) and its knobs ([`RsvpKnobs`]).
//!
//! Promises:
//! - Level (x, y) of the pyramid puts column c at world azimuth
//!   `c * step_0 / 2^x` and row r at elevation `90deg - r * step_0 / 2^y`,
//!   with a whole number of columns per turn (a multiple of the group
//!   width): the azimuth wraps, the rows end at the poles. The axes refine
//!   independently, because a wide perspective view squeezes azimuth at
//!   its sides long before elevation. Levels below 0 (down to
//!   [`COARSEST_LEVEL`]) serve zoomed-out views, whose pixels are wider
//!   than level 0's samples. Halving a step is exact in floating point, so
//!   level (x+1, y)'s sample (2c, r) has bit for bit level (x, y)'s
//!   direction, and likewise for rows: the levels nest.
//! - Level 0 and the finer levels form one pyramid, the coarser ones
//!   another ([`SampleLattice::base`]): a view that is not zoomed out reads
//!   and traces exactly what it would without the coarser levels. Every
//!   sample belongs to the coarsest level of its pyramid that has it (on
//!   each axis), is stored only there, and is traced only there. A level
//!   finer than its pyramid's coarsest on an axis owns the odd positions on
//!   it; its samples are stored and traced by slot (the odd positions
//!   numbered densely), in aligned 4x2 groups of slots, so every lane of a
//!   packet is a sample the level owns. A sample's colour never depends on
//!   which level or viewport asked first, and a fresh trace of the same
//!   group reproduces it bit for bit (a sample of both pyramids is traced
//!   in each, the same).
//! - Pass 2 reads copies: each level's samples at all its positions,
//!   assembled from their owners into blocks that take every group traced
//!   after them, so they always equal the stores (`verify` checks that too).
//! - A sample is traced once and kept for every later frame, unless the
//!   buffer's memory cap ([`SampleBuffer::set_memory_cap`]) evicts its
//!   tile, the least recently read first: it is then traced again when a
//!   frame reads it, the same bit for bit. All null samples the viewports
//!   of a frame touch are traced in one batch per level through
//!   [`crate::render::trace_groups`].
//! - Resampling is an approximation: its error against the viewport's own
//!   rays is measured (`--verify`, `bench --only E2`), never assumed.

mod blocks;
mod filter;
mod gather;
mod lattice;
mod map;
mod plan;
mod tiles;
mod viewport;

pub use filter::{Filter, RsvpKnobs};
pub use lattice::{fast_atan2, Level, LevelRays, SampleLattice};
pub use plan::RsvpPlan;
pub use viewport::{render_direct, render_direct_sampled, ViewportRays};

use std::f64::consts::FRAC_PI_2;

use glam::Vec3;
use rayon::prelude::*;

use crate::camera::{Camera, ViewportPose};
use crate::clock::Stopwatch;
use crate::color::srgb_table;
use crate::render::{trace_each, trace_groups, Frame, PrimaryRays, SampleGroup, GROUP_WIDTH};
use crate::reuse::ostc::Ostc;
use crate::reuse::regions::{RegionGrid, RegionLayout, RegionSet};
use crate::reuse::{Dirty, Erasure, FrameMode, SampleStore, StoreFrame, Unfit, ViewWork, Wanted};
use crate::sampling::PixelSamples;
use crate::shade::{RayCounts, Shader};
use blocks::LevelBlocks;
use blocks::BLOCK_BYTES;
use filter::for_each_read;
use filter::SampleCode;
use lattice::wrap;
use map::nan_filled;
use tiles::{
    group_key, key_group, tile_key, traced_groups, LevelSamples, TracedGroups, TILE_BYTES,
    TILE_COLS, TILE_COL_SHIFT, TILE_ROW_SHIFT,
};
use viewport::PixelMap;

/// Finest pyramid level: 2^16 times the camera's angular resolution, enough
/// for a zoom of 1000 with room for oversampling and level bias.
pub const MAX_LEVEL: i32 = 16;

/// Coarsest pyramid level: 2^-8 times the camera's angular resolution, for
/// views zoomed out as far as the viewer goes (1/97) and their widest
/// pixels (where azimuth lets it: see [`SampleLattice::coarsest`]).
pub const COARSEST_LEVEL: i32 = -8;

/// Viewport pixels per side of a patch: a square whose pixels all read
/// one pyramid level.
pub const PATCH: u32 = 16;

/// Every sample traced so far, over all pyramid levels.
pub struct SampleBuffer {
    lattice: SampleLattice,
    /// By [`Level::index`].
    levels: Vec<LevelSamples>,
    /// What pass 2 reads: every level's samples assembled, by
    /// [`Level::index`].
    blocks: Vec<LevelBlocks>,
    /// Blocks given up, for new ones to reuse.
    spare_blocks: Vec<Box<[SampleCode]>>,
    /// Frames rendered: when each tile was last used and each block last
    /// read.
    frame: u64,
    samples_traced: u64,
    samples_evicted: u64,
    /// The most bytes the tiles and blocks may take (None: no cap).
    memory_cap: Option<u64>,
    /// The groups the last [`SampleBuffer::render`] traced, sorted as
    /// `missing` is: what [`SampleBuffer::fresh_image`] paints.
    fresh: Vec<(Level, SampleGroup)>,
}

impl SampleBuffer {
    pub fn new(lattice: SampleLattice) -> SampleBuffer {
        SampleBuffer {
            lattice,
            levels: (0..Level::COUNT).map(|_| LevelSamples::default()).collect(),
            blocks: (0..Level::COUNT).map(|_| LevelBlocks::default()).collect(),
            spare_blocks: Vec::new(),
            frame: 0,
            samples_traced: 0,
            samples_evicted: 0,
            memory_cap: None,
            fresh: Vec::new(),
        }
    }

    /// Caps the memory the buffer keeps at `bytes` (None: no cap). Past
    /// it, before a frame keeps new tiles, the tiles no view of the frame
    /// reads go, least recently used first, until the buffer holds three
    /// quarters of the cap (so that the next frames need not evict again
    /// at once); samples they held are traced again when read, the same
    /// bit for bit. What one frame reads always stays, cap or not.
    pub fn set_memory_cap(&mut self, bytes: Option<u64>) {
        self.memory_cap = bytes;
    }

    /// Bytes the buffer keeps: its tiles of samples and pass 2's blocks,
    /// with their bookkeeping.
    pub fn kept_bytes(&self) -> u64 {
        let tiles: usize = self.levels.iter().map(LevelSamples::tile_count).sum();
        let blocks =
            self.blocks.iter().map(LevelBlocks::count).sum::<usize>() + self.spare_blocks.len();
        tiles as u64 * TILE_BYTES + blocks as u64 * BLOCK_BYTES
    }

    /// Evicts the least recently used tiles until the buffer keeps at most
    /// `bytes` (or nothing); between frames, when no frame reads any.
    pub fn trim(&mut self, bytes: u64) {
        if self.kept_bytes() <= bytes {
            return;
        }
        // Every tile was last used by a frame before the next.
        self.frame += 1;
        self.samples_evicted += self.evict_to(bytes);
    }

    /// Makes the tiles the traced `groups` (sorted as `trace` sorts them)
    /// go into, first evicting tiles if they and the blocks the frame
    /// reads (`blocks`: how many, how many of them not assembled yet)
    /// would take the buffer past its cap. Returns the samples evicted.
    fn make_tiles(
        &mut self,
        groups: &[(Level, SampleGroup, usize)],
        (blocks_read, fresh_blocks): (usize, usize),
    ) -> u64 {
        // A tile is one row of groups: a row's groups, in column order,
        // share their tiles in turn.
        let mut new: Vec<(usize, (i64, i64))> = Vec::new();
        let mut last = None;
        for &(level, group, _) in groups {
            let (key, _, _) = tile_key(group.col, group.row);
            let at = (level.index(), key);
            if last != Some(at) && self.levels[at.0].tile(key).is_none() {
                new.push(at);
            }
            last = Some(at);
        }
        let new_bytes = new.len() as u64 * TILE_BYTES;
        // Assembling takes the fresh blocks from those given up when it
        // can: at most this many more.
        let more_blocks = fresh_blocks as u64 * BLOCK_BYTES;
        let evicted = match self.memory_cap {
            Some(cap) if self.kept_bytes() + new_bytes + more_blocks > cap => {
                // Evicting frees every block: the frame assembles all it
                // reads afresh.
                let frame_bytes = new_bytes + blocks_read as u64 * BLOCK_BYTES;
                self.evict_to((cap / 4 * 3).saturating_sub(frame_bytes))
            }
            _ => 0,
        };
        for (index, key) in new {
            self.levels[index].tile_or_insert(key, self.frame);
        }
        evicted
    }

    /// Frees pass 2's blocks (copies of the tiles, assembled again as
    /// frames read them), then evicts the least recently used tiles this
    /// frame does not read until the tiles take at most `target` bytes, or
    /// none is left to evict. Returns the samples evicted.
    fn evict_to(&mut self, target: u64) -> u64 {
        for blocks in &mut self.blocks {
            blocks.clear();
        }
        self.spare_blocks = Vec::new();
        let tiles: usize = self.levels.iter().map(LevelSamples::tile_count).sum();
        let excess = (tiles as u64 * TILE_BYTES).saturating_sub(target);
        if excess == 0 {
            return 0;
        }
        let now = self.frame;
        let mut unused: Vec<(u64, usize, u32)> = self
            .levels
            .iter()
            .enumerate()
            .flat_map(|(index, store)| {
                store
                    .unused_since(now)
                    .map(move |(used, tile)| (used, index, tile))
            })
            .collect();
        let count = (excess.div_ceil(TILE_BYTES) as usize).min(unused.len());
        if count < unused.len() {
            unused.select_nth_unstable(count);
        }
        let mut evicted = 0;
        for &(_, index, tile) in &unused[..count] {
            let store = &mut self.levels[index];
            evicted += u64::from(store.traced[tile as usize].count_ones()) * GROUP_SAMPLES;
            store.evict(tile);
        }
        evicted
    }

    /// Regions of `size` level-0 samples tiling the whole buffer (a whole
    /// turn, pole to pole). A finer level's group lies in the region of
    /// its position on level 0: a group of slots spans 8 columns and 4 rows
    /// at a level finer than 0 on that axis, aligned, which is 4 or fewer
    /// level-0 columns and 2 or fewer rows; regions a multiple of 4 wide and
    /// 2 tall (40 x 30 samples) so never cut a group. A coarser level's
    /// group may span regions: it is recorded into, and erased with, the
    /// region of its first sample.
    pub fn regions(&self, size: (i64, i64)) -> RegionLayout {
        RegionLayout::new(
            size,
            self.lattice.columns(0),
            0,
            self.lattice.last_row(0) + 1,
        )
    }

    /// The region (of `layout`) of a group of `level`'s slots.
    fn region_of(
        lattice: &SampleLattice,
        layout: &RegionLayout,
        level: Level,
        group: SampleGroup,
    ) -> usize {
        let (col, row) = lattice.slot_position(level, group.col, group.row);
        let to_level_0 = |v: i64, k: i32| if k >= 0 { v >> k } else { v << -k };
        let col = to_level_0(lattice.wrap_column(level.x, col), level.x);
        let row = to_level_0(row, level.y).clamp(0, lattice.last_row(0));
        layout.region_of(col, row)
    }

    /// Re-traces every traced group, as it was traced, and compares the kept
    /// samples with the fresh ones bit for bit: (samples compared, samples
    /// that differ, counting also any copy in pass 2's assembled blocks that
    /// no longer equals its sample). What `--verify` checks when objects
    /// move and OSTC keeps the buffer.
    pub fn verify(&self, shader: &Shader) -> (u64, u64) {
        let (mut compared, mut differing) = (0u64, 0u64);
        for (index, store) in self.levels.iter().enumerate() {
            let level = Level::from_index(index);
            let (groups, tiles): (Vec<SampleGroup>, Vec<usize>) = traced_groups(store)
                .map(|(group, tile, _)| (group, tile))
                .unzip();
            if groups.is_empty() {
                continue;
            }
            let source = LevelRays {
                lattice: &self.lattice,
                level,
            };
            let (fresh, _) = trace_groups(shader, &source, &groups);
            let last = self.lattice.last_slot_row(level);
            for ((group, tile), colors) in groups.iter().zip(&tiles).zip(&fresh) {
                for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                    if row > last {
                        continue;
                    }
                    let (_, sample, _) = tile_key(col, row);
                    let kept = store.tile_colors(*tile as u32)[sample];
                    compared += 1;
                    differing += u64::from(!same_bits(kept, colors[lane]));
                }
            }
        }
        (compared, differing + self.stale_block_samples())
    }

    /// Nulls the groups named by `keys` (the keys their rays were recorded
    /// under, as [`Ostc::dirty_groups_for`] gives them); returns how many
    /// of them were traced. They are traced again when a viewport next
    /// reads them.
    pub fn erase_groups(&mut self, keys: &[u128]) -> u64 {
        let mut erased = 0;
        for &key in keys {
            let (level, group) = key_group(key);
            let store = &mut self.levels[level.index()];
            let (tile, _, bit) = tile_key(group.col, group.row);
            if let Some(tile) = store.tile(tile) {
                let mask = &mut store.traced[tile as usize];
                erased += *mask >> bit & 1;
                *mask &= !(1u64 << bit);
            }
        }
        erased
    }

    /// Nulls, at every level, the samples lying in `regions` (of `layout`,
    /// from [`SampleBuffer::regions`]); returns how many groups were
    /// erased. They are traced again when a viewport next reads them.
    pub fn erase(&mut self, layout: &RegionLayout, regions: &RegionSet) -> u64 {
        let layout = *layout;
        let mut erased = 0;
        let gw = i64::from(GROUP_WIDTH);
        for (index, store) in self.levels.iter_mut().enumerate() {
            let level = Level::from_index(index);
            for (&(tile_col, tile_row), &tile) in &store.tiles {
                let mask = &mut store.traced[tile as usize];
                if *mask == 0 {
                    continue;
                }
                // A tile is one row of groups, so its groups' regions run
                // along one region row, in column order unless the tile
                // wraps the turn (a small camera's turn may be shorter than
                // a tile): one range test skips most clean tiles.
                let (col, row) = (tile_col << TILE_COL_SHIFT, tile_row << TILE_ROW_SHIFT);
                let region = |col| {
                    let group = SampleGroup { col, row };
                    Self::region_of(&self.lattice, &layout, level, group)
                };
                let last_col = col + TILE_COLS - gw;
                let wraps = self.lattice.slot_position(level, last_col, row).0
                    >= self.lattice.columns(level.x);
                if !wraps && !regions.any_in(region(col)..=region(last_col)) {
                    continue;
                }
                let mut rest = *mask;
                while rest != 0 {
                    let bit = rest.trailing_zeros();
                    rest &= rest - 1;
                    if regions.contains(region(col + i64::from(bit) * gw)) {
                        *mask &= !(1u64 << bit);
                        erased += 1;
                    }
                }
            }
        }
        erased
    }

    pub fn lattice(&self) -> &SampleLattice {
        &self.lattice
    }

    /// Samples traced since the buffer was made.
    pub fn samples_traced(&self) -> u64 {
        self.samples_traced
    }

    /// Traced samples evicted (to keep within the memory cap) since the
    /// buffer was made.
    pub fn samples_evicted(&self) -> u64 {
        self.samples_evicted
    }

    /// The colour of sample (col, row) of `level`, if traced.
    pub fn sample(&self, level: Level, col: i64, row: i64) -> Option<Vec3> {
        let (owner, col, row) = self.lattice.owner(level, col, row);
        let store = &self.levels[owner.index()];
        let (key, sample, bit) = tile_key(col, row);
        let tile = store.tile(key)? as usize;
        (store.traced[tile] >> bit & 1 == 1).then(|| store.tile_colors(tile as u32)[sample])
    }

    /// Whether `group` of `level`'s slots was traced.
    pub fn group_traced(&self, level: Level, group: SampleGroup) -> bool {
        self.levels[level.index()].group_traced(group)
    }

    /// Traces the missing groups of every level in one parallel batch and
    /// keeps them, their rays recorded into `ostc` (built over
    /// [`SampleBuffer::regions`]) when given; `blocks` (read, not yet
    /// assembled) are the blocks the frame will then read. Returns the
    /// samples and rays traced for each request list, and the samples
    /// evicted to make room.
    fn trace(
        &mut self,
        shader: &Shader,
        requests: &[Vec<(Level, SampleGroup)>],
        ostc: Option<&Ostc>,
        blocks: (usize, usize),
    ) -> (Vec<(u64, RayCounts, f64)>, u64) {
        let mut all: Vec<(Level, SampleGroup, usize)> = Vec::new();
        for (who, list) in requests.iter().enumerate() {
            all.extend(list.iter().map(|&(l, g)| (l, g, who)));
        }
        // The first requester pays. One list comes sorted and unique from
        // `map` already.
        if requests.len() > 1 {
            all.sort_by_key(|&(l, g, who)| (l, g.row, g.col, who));
            all.dedup_by_key(|&mut (l, g, _)| (l, g));
        }
        debug_assert!(all
            .windows(2)
            .all(|w| (w[0].0, w[0].1.row, w[0].1.col) < (w[1].0, w[1].1.row, w[1].1.col)));
        let mut out = vec![(0u64, RayCounts::default(), 0.0f64); requests.len()];
        self.fresh.clear();
        self.fresh
            .extend(all.iter().map(|&(level, group, _)| (level, group)));
        if all.is_empty() {
            let evicted = self.make_tiles(&all, blocks);
            self.samples_evicted += evicted;
            return (out, evicted);
        }
        // One batch rather than one per level: a frame that refines a few
        // levels would otherwise wait for each level's last group in turn.
        let watch = Stopwatch::start();
        let lattice = &self.lattice;
        let sources: Vec<LevelRays> = (0..Level::COUNT)
            .map(|index| LevelRays {
                lattice,
                level: Level::from_index(index),
            })
            .collect();
        let (colors, rays) = trace_each(shader, &all, |&(level, group, _)| {
            let region = |o: &Ostc| Self::region_of(lattice, o.layout(), level, group);
            let marker = ostc.map(|o| o.marker_in(region(o), group_key(level, group)));
            (&sources[level.index()] as &dyn PrimaryRays, group, marker)
        });
        // On this thread, before the levels keep their groups on theirs:
        // the memory evicted tiles give back is then the next tiles'.
        let evicted = self.make_tiles(&all, blocks);
        self.samples_evicted += evicted;
        // Each level's store keeps its own groups, on its own thread: a
        // first frame grows the stores by many fresh pages, each a fault,
        // and the levels take theirs in parallel. The blocks follow the
        // same groups meanwhile: a steady frame's groups fall in one or two
        // levels, so either alone would leave a thread idle.
        let (levels, blocks, lattice) = (&mut self.levels, &mut self.blocks, &self.lattice);
        let (kept, ()): (Vec<Vec<(u64, RayCounts)>>, ()) = rayon::join(
            || {
                levels
                    .par_iter_mut()
                    .enumerate()
                    .filter_map(|(index, store)| {
                        let first = all.partition_point(|g| g.0.index() < index);
                        let end = all.partition_point(|g| g.0.index() <= index);
                        (first < end).then(|| {
                            let traced = TracedGroups {
                                groups: &all[first..end],
                                colors: &colors[first..end],
                                rays: &rays[first..end],
                            };
                            let last = lattice.last_slot_row(Level::from_index(index));
                            store.keep(traced, last, requests.len())
                        })
                    })
                    .collect()
            },
            || blocks::follow_traced(blocks, lattice, &all, &colors),
        );
        // Keeping the samples (above) counts as tracing them.
        let per_group = watch.ms() / all.len() as f64;
        for level in kept {
            for (who, (owned, rays)) in level.into_iter().enumerate() {
                self.samples_traced += owned;
                out[who].0 += owned;
                out[who].1 += rays;
            }
        }
        for &(_, _, who) in &all {
            out[who].2 += per_group;
        }
        (out, evicted)
    }

    /// Renders every viewport of a frame: maps their pixels, traces the
    /// null samples they touch in one batch (recording their rays into
    /// `ostc` when given), and resamples.
    pub fn render(
        &mut self,
        shader: &Shader,
        poses: &[ViewportPose],
        knobs: &RsvpKnobs,
        linear: bool,
        ostc: Option<&Ostc>,
    ) -> Vec<StoreFrame> {
        self.frame += 1;
        let mut mapped = Vec::with_capacity(poses.len());
        let mut map_ms = Vec::with_capacity(poses.len());
        for pose in poses {
            let watch = Stopwatch::start();
            mapped.push(self.map(pose, knobs));
            map_ms.push(watch.ms());
        }
        let requests: Vec<Vec<(Level, SampleGroup)>> = mapped
            .iter_mut()
            .map(|m| std::mem::take(&mut m.missing))
            .collect();
        // Pass 2 reads assembled blocks; assembling new ones is its cost,
        // shared between the viewports.
        let watch = Stopwatch::start();
        let (blocks, fresh_blocks) = self.blocks_read(mapped.iter().flat_map(|m| {
            m.patches
                .iter()
                .filter_map(|p| p.blocks.map(|b| (p.level, b)))
        }));
        let mut assembly_ms = watch.ms();
        let (traced, evicted) = self.trace(shader, &requests, ostc, (blocks.len(), fresh_blocks));
        let watch = Stopwatch::start();
        self.assemble_blocks(&blocks);
        assembly_ms = (assembly_ms + watch.ms()) / poses.len().max(1) as f64;
        let kept_bytes = self.kept_bytes();
        poses
            .iter()
            .zip(&mapped)
            .zip(traced.into_iter().zip(map_ms))
            .enumerate()
            .map(
                |(index, ((pose, mapped), ((samples, rays, trace_ms), map_ms)))| {
                    let watch = Stopwatch::start();
                    let (frame, image) = self.gather(pose, mapped, linear);
                    let gather_ms = watch.ms() + assembly_ms;
                    let levels = mapped
                        .patches
                        .iter()
                        .fold((i32::MAX, i32::MIN), |(lo, hi), p| {
                            (lo.min(p.level.finest()), hi.max(p.level.finest()))
                        });
                    StoreFrame {
                        frame,
                        image,
                        work: ViewWork {
                            samples_traced: samples,
                            pixels_reused: pixels(pose).saturating_sub(samples),
                            rays,
                            trace_ms,
                            assembly_ms: map_ms + gather_ms,
                            snap_error: None,
                            levels: Some(levels),
                            kept_bytes: Some(kept_bytes),
                            // The frame's, on its first view's row.
                            samples_evicted: if index == 0 { evicted } else { 0 },
                        },
                    }
                },
            )
            .collect()
    }

    /// `image` (the viewport `pose` as the last [`SampleBuffer::render`]
    /// showed it) with every pixel black whose filter read a sample traced
    /// in that render: what the frame re-traced (the paper's figure 4).
    /// Maps the viewport again, so it costs about a frame's resampling.
    pub fn fresh_image(
        &self,
        pose: &ViewportPose,
        knobs: &RsvpKnobs,
        image: &image::RgbImage,
    ) -> image::RgbImage {
        let mut out = image.clone();
        if self.fresh.is_empty() {
            return out;
        }
        let mapped = self.map(pose, knobs);
        let map = PixelMap::new(pose);
        let (w, h) = (pose.camera.width, pose.camera.height);
        // Patch by patch on every thread. Neighbouring pixels read the
        // same groups, so each read first asks the group the last read
        // found: most pixels then search the fresh list not at all.
        let painted: Vec<Vec<(u32, u32)>> = (0..mapped.patches.len())
            .into_par_iter()
            .map_init(Vec::new, |coords, index| {
                let patch = &mapped.patches[index];
                let (x0, y0) = (
                    (index % mapped.patches_x) as u32 * PATCH,
                    (index / mapped.patches_x) as u32 * PATCH,
                );
                let (cols, rows) = ((w - x0).min(PATCH), (h - y0).min(PATCH));
                let level = patch.level;
                let size = (cols as usize, rows as usize);
                let grid = patch.grid.as_ref();
                let slots = nan_filled(coords, size.0 * size.1);
                self.patch_coords(pose, &map, level, grid, (x0, y0), size.0, slots);
                let last_row = self.lattice.last_row(level.y);
                let mut last: Option<((Level, i64, i64), bool)> = None;
                let mut is_fresh = |key: (Level, i64, i64)| match last {
                    Some((k, fresh)) if k == key => fresh,
                    _ => {
                        let fresh = self
                            .fresh
                            .binary_search_by_key(&key, |&(l, g)| (l, g.row, g.col))
                            .is_ok();
                        last = Some((key, fresh));
                        fresh
                    }
                };
                let mut marks = Vec::new();
                for (k, c) in coords.iter().enumerate() {
                    if c.x.is_nan() {
                        continue;
                    }
                    let mut fresh = false;
                    for_each_read(&patch.filter, (c.x, c.y), last_row, |col, row| {
                        if fresh {
                            return;
                        }
                        let (owner, col, row) = self.lattice.owner(level, col, row);
                        let group = SampleGroup::containing(col, row);
                        let col = wrap(group.col, self.lattice.slot_columns(owner));
                        fresh = is_fresh((owner, group.row, col));
                    });
                    if fresh {
                        marks.push((x0 + (k % size.0) as u32, y0 + (k / size.0) as u32));
                    }
                }
                marks
            })
            .collect();
        for (x, y) in painted.into_iter().flatten() {
            out.put_pixel(x, y, image::Rgb([0, 0, 0]));
        }
        out
    }

    /// The buffer at level 0 as an equal-angle camera of width x height
    /// samples sees it, centred on the camera's view (corner snapped to a
    /// sample): traced samples in colour, never-traced ones black (the
    /// paper's figure 5a). Where level 0 is null but a finer level traced
    /// inside the sample's cell, that sample shows, so what a zoomed
    /// viewport traced appears solid; failing that, a coarser level's
    /// sample whose cell holds it (what a zoomed-out viewport traced).
    pub fn buffer_image(&self, camera: &Camera, width: u32, height: u32) -> image::RgbImage {
        let col0 = (camera.yaw / self.lattice.step - 0.5 * f64::from(width)).round() as i64;
        let row0 = ((FRAC_PI_2 - camera.pitch) / self.lattice.step - 0.5 * f64::from(height))
            .round() as i64;
        let srgb = srgb_table();
        // Level 0 and the finer ones first, fewer halvings in all first;
        // then the coarser, the least coarse first.
        let mut levels: Vec<Level> = (0..Level::COUNT)
            .filter(|&i| !self.levels[i].traced.is_empty())
            .map(Level::from_index)
            .collect();
        levels.sort_by_key(|l| (l.x < 0 || l.y < 0, l.x.abs() + l.y.abs(), *l));
        // On a finer axis, the cell's first position the level owns (an
        // odd one); on a coarser axis, the position whose cell holds it.
        let cell = |k: i32, v: i64| match k {
            0 => v,
            k if k > 0 => (v << k) + 1,
            k => v >> -k,
        };
        image::RgbImage::from_fn(width, height, |x, y| {
            let (c, r) = (col0 + i64::from(x), row0 + i64::from(y));
            let colour = levels
                .iter()
                .find_map(|&level| self.sample(level, cell(level.x, c), cell(level.y, r)));
            image::Rgb(colour.map_or([0; 3], |c| c.to_array().map(|v| srgb.encode(v))))
        })
    }
}

/// Whether two colours are the same bit for bit (what "exact" means for a
/// kept sample and its copies).
fn same_bits(a: Vec3, b: Vec3) -> bool {
    a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)
}

/// RSVP's sample buffer as the frame loop keeps it: every viewport of a
/// frame resampled from it with the run's knobs.
///
/// Antialiased (`samples` above one), a viewport is resampled at that many
/// sub-pixel shifts of its pixels (the same for every pixel, stratified)
/// and the shifted pictures averaged: the buffer read at sub-pixel
/// positions, its samples untouched. The pyramid level each read needs is
/// chosen for the shifted pixels' spacing (the oversampling knob times the
/// square root of the count). The pixel box reads four shifts' worth in
/// one pass: a quarter of the count's shifts, at least one.
pub struct RsvpStore {
    buffer: SampleBuffer,
    knobs: RsvpKnobs,
    /// The sub-pixel shifts each viewport is resampled at.
    shifts: PixelSamples,
}

impl RsvpStore {
    pub fn new(lattice: SampleLattice, knobs: RsvpKnobs, samples: PixelSamples) -> RsvpStore {
        let shifts = knobs.shifts(samples);
        let oversample = knobs.oversample * knobs.density_scale(samples);
        RsvpStore {
            buffer: SampleBuffer::new(lattice),
            knobs: RsvpKnobs {
                oversample,
                ..knobs
            },
            shifts,
        }
    }

    /// `view` at each sub-pixel shift of the antialiasing (itself, with one
    /// shift): its 2D transform's translation moved by the shift, carried
    /// back through the transform into unzoomed pixels.
    fn shifted(&self, view: &ViewportPose) -> Vec<ViewportPose> {
        if self.shifts.count() == 1 {
            return vec![view.clone()];
        }
        let inverse = view.transform.matrix().inverse();
        (0..self.shifts.count())
            .map(|k| {
                let shift = glam::DVec2::new(self.shifts.x(0, k) - 0.5, self.shifts.y(0, k) - 0.5);
                let moved = inverse * shift;
                let mut transform = view.transform;
                transform.translate = [
                    transform.translate[0] + moved.x,
                    transform.translate[1] + moved.y,
                ];
                ViewportPose::new(view.camera.clone(), transform)
            })
            .collect()
    }
}

impl SampleStore for RsvpStore {
    fn name(&self) -> &'static str {
        "sample buffer"
    }

    fn mode(&self, ostc: bool) -> FrameMode {
        if ostc {
            FrameMode::RsvpOstc
        } else {
            FrameMode::Rsvp
        }
    }

    fn unfit(&self, views: &[ViewportPose]) -> Option<Unfit> {
        let eye = views.first()?.camera.position;
        (self.buffer.lattice().position != eye).then_some(Unfit::EyeMoved)
    }

    fn ostc_regions(&self, grid: Option<RegionGrid>, (width, height): (u32, u32)) -> RegionLayout {
        let grid = grid.unwrap_or(RegionGrid::PYRAMID);
        self.buffer.regions(grid.region_size(width, height))
    }

    fn erasure(&self) -> Erasure {
        Erasure::Groups
    }

    fn erase(&mut self, dirty: &Dirty) -> u64 {
        let regions = self.buffer.erase(dirty.layout, dirty.regions);
        (regions + self.buffer.erase_groups(dirty.groups)) * GROUP_SAMPLES
    }

    fn render(
        &mut self,
        shader: &Shader,
        views: &[ViewportPose],
        ostc: Option<&Ostc>,
        wanted: Wanted,
    ) -> Vec<StoreFrame> {
        let count = self.shifts.count() as usize;
        if count == 1 {
            return self
                .buffer
                .render(shader, views, &self.knobs, wanted.linear, ostc);
        }
        // Every view's shifts in one batch: samples any of them needs are
        // traced once.
        let shifted: Vec<ViewportPose> = views.iter().flat_map(|v| self.shifted(v)).collect();
        let frames = self
            .buffer
            .render(shader, &shifted, &self.knobs, true, ostc);
        let mut frames = frames.into_iter();
        views
            .iter()
            .map(|pose| {
                let watch = Stopwatch::start();
                let shifts: Vec<StoreFrame> = frames.by_ref().take(count).collect();
                let mut mean = Frame::new(pose.camera.width, pose.camera.height);
                let scale = 1.0 / count as f32;
                let linear: Vec<&Frame> = shifts
                    .iter()
                    .map(|s| s.frame.as_ref().expect("asked for linear colour"))
                    .collect();
                mean.pixels.par_iter_mut().enumerate().for_each(|(i, sum)| {
                    for frame in &linear {
                        *sum += frame.pixels[i];
                    }
                    *sum *= scale;
                });
                let image = mean.to_rgb8();
                let mut work = ViewWork::combined(shifts.iter().map(|s| s.work));
                work.assembly_ms += watch.ms();
                work.pixels_reused = pixels(pose).saturating_sub(work.samples_traced);
                StoreFrame {
                    frame: wanted.linear.then_some(mean),
                    image,
                    work,
                }
            })
            .collect()
    }

    fn paint_traced(
        &self,
        _index: usize,
        view: &ViewportPose,
        image: &image::RgbImage,
    ) -> image::RgbImage {
        // Black where any shift read a sample this frame traced.
        let mut painted = image.clone();
        for shifted in self.shifted(view) {
            let one = self.buffer.fresh_image(&shifted, &self.knobs, image);
            for (out, mark) in painted.pixels_mut().zip(one.pixels()) {
                if mark.0 == [0, 0, 0] {
                    *out = *mark;
                }
            }
        }
        painted
    }

    fn picture(&self, camera: &Camera) -> Option<image::RgbImage> {
        Some(
            self.buffer
                .buffer_image(camera, camera.width, camera.height),
        )
    }

    fn verify(&self, shader: &Shader) -> Option<(u64, u64)> {
        Some(self.buffer.verify(shader))
    }

    fn set_memory_cap(&mut self, bytes: Option<u64>) {
        self.buffer.set_memory_cap(bytes);
    }

    fn kept_bytes(&self) -> u64 {
        self.buffer.kept_bytes()
    }

    fn trim(&mut self, bytes: u64) {
        self.buffer.trim(bytes);
    }
}

/// A view's pixel count.
fn pixels(pose: &ViewportPose) -> u64 {
    u64::from(pose.camera.width) * u64::from(pose.camera.height)
}

/// Samples in a group.
const GROUP_SAMPLES: u64 = (GROUP_WIDTH * crate::render::GROUP_HEIGHT) as u64;

/// What the unit tests of the submodules share.
#[cfg(test)]
mod fixtures {
    use glam::DVec3;

    use super::*;
    use crate::camera::{Projection, ViewTransform};

    /// The paper camera's size and field of view, level, one unit up.
    pub(super) fn camera(projection: Projection) -> Camera {
        Camera {
            projection,
            position: DVec3::new(0.0, 1.0, 0.0),
            yaw: 0.0,
            pitch: 0.0,
            fov: 100f64.to_radians(),
            width: 640,
            height: 480,
        }
    }

    pub(super) fn lattice() -> SampleLattice {
        SampleLattice::for_camera(&camera(Projection::EqualAngle))
    }

    /// The paper's perspective camera, pitched 9 degrees down.
    pub(super) fn tilted_camera() -> Camera {
        Camera {
            pitch: -9f64.to_radians(),
            ..camera(Projection::Perspective)
        }
    }

    /// A viewport transform moved off centre.
    pub(super) fn off_centre(zoom: f64, rotate: f64, shear: [f64; 2]) -> ViewTransform {
        ViewTransform {
            zoom,
            rotate,
            shear,
            translate: [7.0, -3.0],
        }
    }
}
