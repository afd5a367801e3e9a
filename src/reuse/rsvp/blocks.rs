//! Pass 2's copy of the buffer: each level's samples at every one of its
//! positions (its own and those its coarser owners traced), assembled into
//! square blocks of sample codes ([`SampleCode`]: what the filters blend),
//! so a patch's samples are a few rows of one or two plain arrays instead
//! of strided runs from every owner.
//!
//! Derived data: a block is assembled from the tiles the first time a
//! frame reads it, and from then on follows every traced group. It holds
//! exactly what assembling it again would give (erasing only clears traced
//! bits, so it changes nothing here), which the tests check.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::Vec3;
use rayon::prelude::*;

use super::{
    filter::{encode, SampleCode},
    lattice::{column_runs, owned_positions, wrap},
    map::SampleBox,
    tiles::{tile_key, TileCache, TileHasher, TILE_COLS},
    Level, SampleBuffer, SampleLattice,
};
use crate::ray::PACKET_WIDTH;
use crate::render::{SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};

/// Positions per side of a block: a 16x16-pixel patch reads 17-40 samples
/// a side, so it copies from one block or from two to four; 128-wide
/// blocks would cost four times the assembly for each block first read.
const BLOCK_SHIFT: u32 = 6;
const BLOCK: i64 = 1 << BLOCK_SHIFT;
const BLOCK_SAMPLES: usize = (BLOCK * BLOCK) as usize;

/// The memory a block takes: its samples and its bookkeeping.
pub(super) const BLOCK_BYTES: u64 = (BLOCK_SAMPLES * std::mem::size_of::<SampleCode>()) as u64 + 64;

/// A block of a level: (level index, block key).
pub(super) type BlockId = (usize, (i64, i64));

/// One level's assembled blocks, row-major inside, made on first read.
#[derive(Default)]
pub(super) struct LevelBlocks {
    index: HashMap<(i64, i64), u32, BuildHasherDefault<TileHasher>>,
    /// By slot; a slot given up holds an empty box until it is reused.
    blocks: Vec<Box<[SampleCode]>>,
    /// The frame each slot was last read in.
    read_in: Vec<u64>,
    free: Vec<u32>,
}

/// The block holding position (col, row) of a level, and the sample's
/// index in it.
fn block_key(col: i64, row: i64) -> ((i64, i64), usize) {
    let key = (col >> BLOCK_SHIFT, row >> BLOCK_SHIFT);
    let sample = (row & (BLOCK - 1)) * BLOCK + (col & (BLOCK - 1));
    (key, sample as usize)
}

impl LevelBlocks {
    fn block(&self, key: (i64, i64)) -> Option<u32> {
        self.index.get(&key).copied()
    }

    fn samples(&self, block: u32) -> &[SampleCode] {
        &self.blocks[block as usize]
    }

    /// Keeps the assembled `samples` of block `key`, read in `frame`.
    fn add(&mut self, key: (i64, i64), samples: Box<[SampleCode]>, frame: u64) {
        let slot = match self.free.pop() {
            Some(slot) => {
                self.blocks[slot as usize] = samples;
                self.read_in[slot as usize] = frame;
                slot
            }
            None => {
                self.blocks.push(samples);
                self.read_in.push(frame);
                self.blocks.len() as u32 - 1
            }
        };
        self.index.insert(key, slot);
    }

    /// Blocks assembled.
    pub(super) fn count(&self) -> usize {
        self.index.len()
    }

    /// Frees every block.
    pub(super) fn clear(&mut self) {
        *self = LevelBlocks::default();
    }

    /// Gives every block last read before frame `since` to `spare`.
    fn give_up_unread(&mut self, since: u64, spare: &mut Vec<Box<[SampleCode]>>) {
        let (blocks, read_in, free) = (&mut self.blocks, &self.read_in, &mut self.free);
        self.index.retain(|_, &mut slot| {
            let keep = read_in[slot as usize] >= since;
            if !keep {
                spare.push(std::mem::take(&mut blocks[slot as usize]));
                free.push(slot);
            }
            keep
        });
    }
}

/// The samples (c0.., r0..) of a level as one row-major array `width`
/// wide, copied out of the blocks.
pub(super) struct SampleView<'a> {
    pub(super) col: i64,
    pub(super) row: i64,
    pub(super) width: usize,
    pub(super) samples: &'a [SampleCode],
}

/// The last blocks a patch's rows came from, by the parity of their key
/// (a patch's box spans a few neighbouring blocks).
struct BlockCache([((i64, i64), u32); 4]);

impl BlockCache {
    fn new() -> BlockCache {
        BlockCache([((i64::MIN, i64::MIN), u32::MAX); 4])
    }

    fn block(&mut self, blocks: &LevelBlocks, key: (i64, i64)) -> u32 {
        let slot = &mut self.0[((key.0 & 1) * 2 + (key.1 & 1)) as usize];
        if slot.0 != key {
            *slot = (key, blocks.block(key).unwrap_or(u32::MAX));
        }
        slot.1
    }
}

impl SampleBuffer {
    /// The blocks the boxes of `reads` cover (rows clamped to the
    /// lattice, columns wrapped), as (level index, key), sorted, each
    /// once; and how many of them are not assembled yet.
    pub(super) fn blocks_read(
        &self,
        reads: impl Iterator<Item = (Level, SampleBox)>,
    ) -> (Vec<BlockId>, usize) {
        let mut read: Vec<BlockId> = Vec::new();
        for (level, bounds) in reads {
            let columns = self.lattice.columns(level.x);
            let last_row = self.lattice.last_row(level.y);
            let (r0, r1) = (bounds.r0.clamp(0, last_row), bounds.r1.clamp(0, last_row));
            for block_row in (r0 >> BLOCK_SHIFT)..=(r1 >> BLOCK_SHIFT) {
                for_each_run(bounds.c0, bounds.c1, columns, |col, _| {
                    read.push((level.index(), (col >> BLOCK_SHIFT, block_row)));
                });
            }
        }
        read.sort_unstable();
        read.dedup();
        let fresh = read
            .iter()
            .filter(|&&(index, key)| self.blocks[index].block(key).is_none())
            .count();
        (read, fresh)
    }

    /// Assembles every block of `read` (from [`SampleBuffer::blocks_read`])
    /// that is not assembled yet. Blocks no frame read since the one
    /// before give their memory to the new ones: a fresh block's pages
    /// would each fault in on first touch, and the faults would make
    /// assembling cost more than copying.
    pub(super) fn assemble_blocks(&mut self, read: &[BlockId]) {
        let frame = self.frame;
        let mut wanted: Vec<BlockId> = Vec::new();
        for &(index, key) in read {
            let blocks = &mut self.blocks[index];
            match blocks.block(key) {
                Some(slot) => blocks.read_in[slot as usize] = frame,
                None => wanted.push((index, key)),
            }
        }
        if wanted.is_empty() {
            return;
        }
        for blocks in &mut self.blocks {
            blocks.give_up_unread(frame - 1, &mut self.spare_blocks);
        }
        // New blocks are assembled before they join their levels, so the
        // tiles can be read while they are written.
        let mut fresh: Vec<Box<[SampleCode]>> = wanted
            .iter()
            .map(|_| {
                self.spare_blocks
                    .pop()
                    .unwrap_or_else(|| vec![0; BLOCK_SAMPLES].into_boxed_slice())
            })
            .collect();
        let this = &*self;
        fresh
            .par_iter_mut()
            .zip(&wanted)
            .for_each(|(out, &(index, key))| {
                this.assemble_block(Level::from_index(index), key, out)
            });
        for (samples, (index, key)) in fresh.into_iter().zip(wanted) {
            self.blocks[index].add(key, samples, frame);
        }
    }

    /// Block `key` of `level` from the tiles: each row owner by owner.
    /// Rows past the pole and columns past the turn are black (no read
    /// reaches them: reads clamp rows and wrap columns).
    fn assemble_block(&self, level: Level, key: (i64, i64), out: &mut [SampleCode]) {
        let mut cache = TileCache::new();
        let srgb = crate::color::srgb_table();
        let mut linear = [Vec3::ZERO; BLOCK as usize];
        let c0 = key.0 << BLOCK_SHIFT;
        let width = (self.lattice.columns(level.x) - c0).min(BLOCK) as usize;
        let last_row = self.lattice.last_row(level.y);
        for (j, line) in out.chunks_exact_mut(BLOCK as usize).enumerate() {
            let row = (key.1 << BLOCK_SHIFT) + j as i64;
            let (mine, past_turn) = line.split_at_mut(width);
            // A reused block's old samples stay nowhere a read can reach.
            past_turn.fill(0);
            if row > last_row {
                mine.fill(0);
            } else {
                let linear = &mut linear[..width];
                self.copy_row(&mut cache, level, c0, row, linear);
                for (o, c) in mine.iter_mut().zip(linear.iter()) {
                    *o = encode(srgb, *c);
                }
            }
        }
    }

    /// Samples (col.., row) of `level` whichever level owns them (black
    /// where nothing was traced). The row belongs to one elevation level;
    /// along it, each coarser azimuth level owns every 2^k-th sample, so
    /// each owner's slots go straight into `out` at their stride.
    fn copy_row(&self, cache: &mut TileCache, level: Level, col: i64, row: i64, out: &mut [Vec3]) {
        let base = self.lattice.base(level);
        let sy = row.trailing_zeros().min((level.y - base.y) as u32);
        let oy = level.y - sy as i32;
        let slot_row = (row >> sy) >> u32::from(oy > base.y);
        let n = out.len() as i64;
        for ox in base.x..=level.x {
            let sx = level.x - ox;
            let (period, offset) = owned_positions((level.x - base.x) as u32, (ox - base.x) as u32);
            let first = col + ((offset - col) & (period - 1));
            if first - col >= n {
                continue;
            }
            let slot = (first >> sx) >> u32::from(ox > base.x);
            let owner = Level::new(ox, oy);
            let out = &mut out[(first - col) as usize..];
            self.copy_run(cache, owner, slot, slot_row, out, period as usize);
        }
    }

    /// The slots (col.., row) of `level` as its tiles hold them, into every
    /// `stride`th entry of `out` (black where no tile is), in runs. A
    /// block's rows come in pairs per tile row and span a tile or two:
    /// `cache` saves most of the hash map lookups.
    fn copy_run(
        &self,
        cache: &mut TileCache,
        level: Level,
        col: i64,
        row: i64,
        out: &mut [Vec3],
        stride: usize,
    ) {
        let samples = &self.levels[level.index()];
        let columns = self.lattice.slot_columns(level);
        let count = out.len().div_ceil(stride);
        let mut i = 0;
        while i < count {
            let wc = wrap(col + i as i64, columns);
            let (key, sample, _) = tile_key(wc, row);
            let run = (count - i)
                .min((TILE_COLS - (wc & (TILE_COLS - 1))) as usize)
                .min((columns - wc) as usize);
            let tile = cache.tile(samples, level, key);
            let source =
                (tile != u32::MAX).then(|| &samples.tile_colors(tile)[sample..sample + run]);
            match (source, stride) {
                (None, 1) => out[i..i + run].fill(Vec3::ZERO),
                (Some(source), 1) => out[i..i + run].copy_from_slice(source),
                (None, _) => scatter(&mut out[i * stride..], &BLACK[..run], stride),
                (Some(source), _) => scatter(&mut out[i * stride..], source, stride),
            }
            i += run;
        }
    }

    /// Samples of the assembled blocks that differ (bit for bit) from
    /// assembling the blocks again from the tiles: none, unless a traced
    /// group was not followed.
    pub(super) fn stale_block_samples(&self) -> u64 {
        let mut fresh: Vec<SampleCode> = vec![0; BLOCK_SAMPLES];
        let mut stale = 0;
        for (index, blocks) in self.blocks.iter().enumerate() {
            for (&key, &slot) in &blocks.index {
                self.assemble_block(Level::from_index(index), key, &mut fresh);
                let kept = blocks.samples(slot);
                stale += kept.iter().zip(&fresh).filter(|(&a, &b)| a != b).count() as u64;
            }
        }
        stale
    }

    /// The samples of `level` in `bounds` (rows clamped to the lattice,
    /// columns wrapped around the turn), every block of which
    /// [`SampleBuffer::assemble_blocks`] assembled, copied into
    /// `view_samples`.
    /// Copied even when they lie in one block: the copy's loads overlap
    /// where the filter's, in place, wait one by one, and the filter then
    /// reads one array of a fixed width.
    pub(super) fn view<'a>(
        &'a self,
        level: Level,
        bounds: &SampleBox,
        view_samples: &'a mut Vec<SampleCode>,
    ) -> SampleView<'a> {
        let blocks = &self.blocks[level.index()];
        let columns = self.lattice.columns(level.x);
        let last_row = self.lattice.last_row(level.y);
        let (width, height) = (bounds.width(), bounds.height());
        view_samples.resize(width * height, 0);
        let mut cache = BlockCache::new();
        let mut at = 0;
        // Column runs outside, rows inside: every row of a run copies the
        // same length, so the copy's branches predict and the rows' loads
        // overlap instead of each waiting on the last.
        for_each_run(bounds.c0, bounds.c1, columns, |col, run| {
            for (j, line) in view_samples.chunks_exact_mut(width).enumerate() {
                let row = (bounds.r0 + j as i64).clamp(0, last_row);
                let (key, sample) = block_key(col, row);
                let out = &mut line[at..at + run];
                match cache.block(blocks, key) {
                    u32::MAX => {
                        debug_assert!(false, "block {key:?} of {level:?} was not assembled");
                        out.fill(0);
                    }
                    block => copy_samples(out, &blocks.samples(block)[sample..sample + run]),
                }
            }
            at += run;
        });
        SampleView {
            col: bounds.c0,
            row: bounds.r0,
            width,
            samples: view_samples,
        }
    }
}

/// `source` into `out` (as long) in whole vectors, inline: a call to
/// `memcpy` per row, whose branches depend on the length, costs more.
#[inline(always)]
fn copy_samples(out: &mut [SampleCode], source: &[SampleCode]) {
    let mut out = out.chunks_exact_mut(8);
    let mut source = source.chunks_exact(8);
    for (o, s) in (&mut out).zip(&mut source) {
        let s: &[SampleCode; 8] = s.try_into().expect("chunks of 8");
        o.copy_from_slice(s);
    }
    for (o, s) in out.into_remainder().iter_mut().zip(source.remainder()) {
        *o = *s;
    }
}

/// Writes freshly traced groups (sorted by level, as `trace` keeps them)
/// into every assembled block of `blocks` (by level index) holding their
/// positions: at their own level and at every finer one. A free function
/// so that it can run beside the tiles keeping the same groups.
pub(super) fn follow_traced(
    blocks: &mut [LevelBlocks],
    lattice: &SampleLattice,
    groups: &[(Level, SampleGroup, usize)],
    colors: &[[Vec3; PACKET_WIDTH]],
) {
    if blocks.iter().all(|blocks| blocks.index.is_empty()) {
        return;
    }
    // Encoded once, not once per level holding them.
    let srgb = crate::color::srgb_table();
    let codes: Vec<[SampleCode; PACKET_WIDTH]> = colors
        .par_iter()
        .map(|colors| colors.map(|c| encode(srgb, c)))
        .collect();
    blocks
        .par_iter_mut()
        .enumerate()
        .filter(|(_, blocks)| !blocks.index.is_empty())
        .for_each(|(index, blocks)| {
            let level = Level::from_index(index);
            let base = lattice.base(level);
            let mut recent = ((i64::MIN, i64::MIN), None);
            for (&(owner, group, _), codes) in groups.iter().zip(&codes) {
                // Only the owners of its pyramid hold a level's samples.
                if !(base.x..=level.x).contains(&owner.x) || !(base.y..=level.y).contains(&owner.y)
                {
                    continue;
                }
                let (sx, sy) = (level.x - owner.x, level.y - owner.y);
                let last = lattice.last_slot_row(owner);
                // Mostly the whole group lies in one block: its lanes then
                // go in at fixed steps, with no lookup each.
                let (c0, r0) = lattice.slot_position(owner, group.col, group.row);
                let (col, row) = (c0 << sx, r0 << sy);
                let step = |finer: bool, s: i32| (1usize + usize::from(finer)) << s;
                let (step_x, step_y) = (step(owner.x > base.x, sx), step(owner.y > base.y, sy));
                let (key, first) = block_key(col, row);
                let width = (GROUP_WIDTH - 1) as usize;
                let (corner, _) = block_key(col + (width * step_x) as i64, row + step_y as i64);
                if corner == key && group.row + i64::from(GROUP_HEIGHT) - 1 <= last {
                    if recent.0 != key {
                        recent = (key, blocks.block(key));
                    }
                    if let Some(block) = recent.1 {
                        let out = &mut blocks.blocks[block as usize];
                        for (lane, &code) in codes.iter().enumerate() {
                            let (i, j) = (lane % GROUP_WIDTH as usize, lane / GROUP_WIDTH as usize);
                            out[first + j * step_y * BLOCK as usize + i * step_x] = code;
                        }
                    }
                    continue;
                }
                for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                    if row > last {
                        continue;
                    }
                    let (col, row) = lattice.slot_position(owner, col, row);
                    let (key, sample) = block_key(col << sx, row << sy);
                    if recent.0 != key {
                        recent = (key, blocks.block(key));
                    }
                    if let Some(block) = recent.1 {
                        blocks.blocks[block as usize][sample] = codes[lane];
                    }
                }
            }
        });
}

/// A run's worth of black, for the samples of a tile never allocated.
static BLACK: [Vec3; TILE_COLS as usize] = [Vec3::ZERO; TILE_COLS as usize];

/// Writes `source` into every `stride`th entry of `out` from its first
/// (`out` reaches the last). The usual strides (2, 4, 8: a coarser owner's
/// samples among a finer level's) get loops of fixed step, which take
/// fewer instructions than chunks of a variable length.
#[inline]
fn scatter(out: &mut [Vec3], source: &[Vec3], stride: usize) {
    match stride {
        2 => scatter_by::<2>(out, source),
        4 => scatter_by::<4>(out, source),
        8 => scatter_by::<8>(out, source),
        _ => {
            for (chunk, &sample) in out.chunks_mut(stride).zip(source) {
                chunk[0] = sample;
            }
        }
    }
}

#[inline(always)]
fn scatter_by<const STRIDE: usize>(out: &mut [Vec3], source: &[Vec3]) {
    for (slot, &sample) in out.iter_mut().step_by(STRIDE).zip(source) {
        *slot = sample;
    }
}

/// Columns `c0..=c1` (in any turn of `columns`) as runs (first column in
/// the turn, length) that stay within one block and one turn.
fn for_each_run(c0: i64, c1: i64, columns: i64, mut each: impl FnMut(i64, usize)) {
    column_runs(c0, c1, columns, BLOCK, |col, run| {
        each(col, run as usize);
        true
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accelerator, BackendKind};
    use crate::camera::{Camera, Projection};
    use crate::camera::{ViewTransform, ViewportPose};
    use crate::reuse::rsvp::{RsvpKnobs, SampleLattice};
    use crate::scene::{paper_scene, SceneOverrides};
    use crate::shade::Shader;

    /// A zoom that refines levels frame by frame (blocks assembled early
    /// take groups traced later), a rotated view and a turn past the seam
    /// (columns wrapping): afterwards every block still equals a fresh
    /// assembly, and the later frames did write into older blocks.
    #[test]
    fn blocks_follow_every_traced_group() {
        let overrides = SceneOverrides {
            width: Some(64),
            height: Some(48),
            ..SceneOverrides::default()
        };
        let scene = paper_scene(&overrides).unwrap();
        let accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let mut buffer = SampleBuffer::new(SampleLattice::for_camera(&scene.camera));
        let knobs = RsvpKnobs::default();
        let pose = |yaw: f64, zoom: f64, rotate: f64| {
            let camera = Camera {
                projection: Projection::Perspective,
                yaw: yaw.to_radians(),
                width: 64,
                height: 48,
                ..scene.camera.clone()
            };
            let transform = ViewTransform {
                zoom,
                rotate,
                ..ViewTransform::default()
            };
            ViewportPose::new(camera, transform)
        };
        let mut followed = 0;
        for frame in 0..8 {
            let t = f64::from(frame);
            let poses = [
                pose(0.0, 1.0 + 0.4 * t, 0.0),
                pose(175.0 + 2.0 * t, 1.5, 0.3),
            ];
            let before = buffer.blocks.iter().map(|b| b.index.len()).sum::<usize>();
            buffer.render(&shader, &poses, &knobs, false, None);
            if frame > 0 && before > 0 {
                followed += buffer.fresh.len();
            }
            assert_eq!(buffer.stale_block_samples(), 0, "frame {frame}");
        }
        assert!(followed > 0, "no later frame traced anything");
        let levels = buffer.blocks.iter().filter(|b| !b.index.is_empty()).count();
        assert!(levels >= 3, "blocks at only {levels} levels");
    }

    #[test]
    fn runs_stay_in_one_block_and_one_turn() {
        let columns = 200;
        let mut runs = Vec::new();
        for_each_run(-3, 130, columns, |col, run| runs.push((col, run)));
        assert_eq!(runs, vec![(197, 3), (0, 64), (64, 64), (128, 3)]);
        let mut runs = Vec::new();
        for_each_run(190, 205, columns, |col, run| runs.push((col, run)));
        assert_eq!(runs, vec![(190, 2), (192, 8), (0, 6)]);
    }
}
