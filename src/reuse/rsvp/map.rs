//! Pass 1 of a viewport frame: each patch's pyramid level and mapping
//! grid, its pixels' lattice coordinates, and the groups not yet traced
//! that its filter will read.

use std::f64::consts::FRAC_PI_2;

use glam::DVec2;
use rayon::prelude::*;

use super::{
    fast_atan2,
    filter::{for_each_read, for_each_read_run, PatchFilter},
    lattice::{column_runs, owned_positions},
    tiles::{tile_key, TILE_COLS, TILE_COL_SHIFT, TILE_ROW_SHIFT},
    viewport::PixelMap,
    Level, RsvpKnobs, SampleBuffer, MAX_LEVEL, PATCH,
};
use crate::camera::ViewportPose;
use crate::render::{SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};

/// Pixels between exactly mapped points of a patch's grid; the pixels
/// between are interpolated.
pub(super) const GRID_SPACING: u32 = 4;
const GRID_POINTS: usize = (PATCH / GRID_SPACING) as usize + 1;
const _: () = assert!(PATCH % GRID_SPACING == 0);

/// The most a grid may miss the exact mapping, in samples of the patch's
/// level, for the patch to be interpolated: it moves a bilinear weight by
/// at most 3%. (E2's widest view needs 1/64..1/32 at its edges; a finer
/// grid would cost more exact mappings than it saves.)
const GRID_TOLERANCE: f64 = 1.0 / 32.0;

/// Lattice coordinates, at the patch's level, of the pixels (x0 + 4i,
/// y0 + 4j) of a patch.
type MapGrid = [[DVec2; GRID_POINTS]; GRID_POINTS];

/// How pass 1 left a patch for pass 2.
pub(super) struct PatchMap {
    pub(super) level: Level,
    /// The filter as the patch's pixels apply it at that level.
    pub(super) filter: PatchFilter,
    /// None: the mapping bends too much here (near a pole, across the view's
    /// back seam, fisheye): every pixel is mapped exactly.
    pub(super) grid: Option<MapGrid>,
    /// A box holding every sample the pixels' filters read (rows not
    /// clamped), when pass 2 reads them through assembled blocks. None: no
    /// pixel has a ray, or the samples are so sparse (zoomed far out) that
    /// each pixel reads its own.
    pub(super) blocks: Option<SampleBox>,
}

/// The samples (c0..=c1, r0..=r1) of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SampleBox {
    pub(super) c0: i64,
    pub(super) r0: i64,
    pub(super) c1: i64,
    pub(super) r1: i64,
}

impl SampleBox {
    /// The samples `filter` reads for pixels whose lattice coordinates lie
    /// in `lo..=hi`: filter origins grow with the coordinates, so the box
    /// spans the origins of the corners, and the rest of the last corner's
    /// square of reads.
    pub(super) fn read_by(filter: &PatchFilter, lo: DVec2, hi: DVec2) -> SampleBox {
        let (sx, sy) = filter.sides();
        let (c0, r0) = filter.origin(lo.x, lo.y);
        let (c1, r1) = filter.origin(hi.x, hi.y);
        SampleBox {
            c0,
            r0,
            c1: c1 + sx - 1,
            r1: r1 + sy - 1,
        }
    }

    /// The samples in both boxes (rows unclamped, as boxes are).
    pub(super) fn intersection(&self, other: &SampleBox) -> SampleBox {
        SampleBox {
            c0: self.c0.max(other.c0),
            r0: self.r0.max(other.r0),
            c1: self.c1.min(other.c1),
            r1: self.r1.min(other.r1),
        }
    }

    pub(super) fn width(&self) -> usize {
        (self.c1 - self.c0 + 1) as usize
    }

    pub(super) fn height(&self) -> usize {
        (self.r1 - self.r0 + 1) as usize
    }

    fn area(&self) -> f64 {
        (self.c1 - self.c0 + 1) as f64 * (self.r1 - self.r0 + 1) as f64
    }
}

/// Pass 1's result for one viewport.
pub(super) struct Mapped {
    /// Per patch, row-major.
    pub(super) patches: Vec<PatchMap>,
    pub(super) patches_x: usize,
    /// Groups to trace: (owning level, group of its slots), sorted by
    /// level index, row and column, unique.
    pub(super) missing: Vec<(Level, SampleGroup)>,
}

impl SampleBuffer {
    /// The level a patch needs: on each axis, the densest its pixels lie
    /// along that lattice axis, brought to at least `oversample` samples per
    /// pixel.
    fn patch_level(
        &self,
        pose: &ViewportPose,
        map: &PixelMap,
        knobs: &RsvpKnobs,
        x0: u32,
        y0: u32,
    ) -> (Level, PatchFilter) {
        let cam = &pose.camera;
        let x1 = (x0 + PATCH).min(cam.width) - 1;
        let y1 = (y0 + PATCH).min(cam.height) - 1;
        let points = [
            (x0, y0),
            (x1, y0),
            (x0, y1),
            (x1, y1),
            ((x0 + x1) / 2, (y0 + y1) / 2),
        ];
        let mut density = SampleDensity::default();
        for (x, y) in points {
            // In level-0 samples.
            let at = |x: u32, y: u32| {
                map.angles(pose, x, y)
                    .map(|(az, el)| DVec2::new(az, -el) / self.lattice.step)
            };
            let (Some(p), Some(r), Some(b)) = (at(x, y), at(x + 1, y), at(x, y + 1)) else {
                continue;
            };
            let (mut dx, dy) = (r - p, b - p);
            // Relative azimuths jump by a turn straight behind the view.
            let turn = self.lattice.columns_per_turn as f64;
            if dx.x.abs() > 0.5 * turn {
                dx.x -= turn.copysign(dx.x);
            }
            density.add(dx, dy);
        }
        density.choose(knobs, self.lattice.coarsest())
    }

    /// The patch's level and mapping grid, or None when interpolating it
    /// could miss the exact mapping by more than [`GRID_TOLERANCE`] at that
    /// level or a point has no ray. Mapping a pixel exactly costs two atan2;
    /// a grid costs 25 mappings for 256 pixels, and its cells give the level
    /// too (the finest footprint over 16 cells), where
    /// [`SampleBuffer::patch_level`] would map 15 more points.
    fn patch_grid(
        &self,
        pose: &ViewportPose,
        map: &PixelMap,
        knobs: &RsvpKnobs,
        x0: u32,
        y0: u32,
    ) -> Option<(Level, PatchFilter, MapGrid)> {
        // Level 0 first: scaling to the patch's level is by a power of
        // two, exact, so the grid is the one mapped at that level bit for
        // bit.
        const CELLS: usize = GRID_POINTS - 1;
        const MAPPED: usize = GRID_POINTS * GRID_POINTS;
        let (mut xs, mut ys) = ([0f64; MAPPED], [0f64; MAPPED]);
        for j in 0..GRID_POINTS {
            for i in 0..GRID_POINTS {
                let k = j * GRID_POINTS + i;
                xs[k] = f64::from(x0 + i as u32 * GRID_SPACING);
                ys[k] = f64::from(y0 + j as u32 * GRID_SPACING);
            }
        }
        let mut mapped = [DVec2::ZERO; MAPPED];
        if !map.lattice_many(&self.lattice, pose.camera.yaw, (&xs, &ys), &mut mapped) {
            return None;
        }
        if !mapped.iter().all(|p| p.is_finite()) {
            return None;
        }
        let mut grid = [[DVec2::ZERO; GRID_POINTS]; GRID_POINTS];
        for (line, points) in grid.iter_mut().zip(mapped.chunks_exact(GRID_POINTS)) {
            line.copy_from_slice(points);
        }
        // Bilinear interpolation of a quadratic misses by at most
        // (|f_xx| + |f_yy|) h^2 / 8, and a second difference over the grid
        // is f_xx h^2 (or f_yy h^2): the grid's own points estimate the
        // miss, per axis, so a saddle (near a pole, where the two cancel)
        // shows too. (Mapping each cell's edge midpoints gives the same
        // estimate for 32 more mappings per patch; the test below holds
        // every pixel to the tolerance.) A seam makes the differences huge.
        let second = |a: DVec2, b: DVec2, c: DVec2| (a - b * 2.0 + c).abs();
        // Second differences along x at the inner columns, along y at the
        // inner rows; a cell takes the largest at its nearest inner points.
        let mut along_x = [[DVec2::ZERO; GRID_POINTS]; GRID_POINTS];
        let mut along_y = [[DVec2::ZERO; GRID_POINTS]; GRID_POINTS];
        for j in 0..GRID_POINTS {
            for i in 1..CELLS {
                along_x[j][i] = second(grid[j][i - 1], grid[j][i], grid[j][i + 1]);
                along_y[i][j] = second(grid[i - 1][j], grid[i][j], grid[i + 1][j]);
            }
        }
        let inner = |k: usize| (k.clamp(1, CELLS - 1), (k + 1).clamp(1, CELLS - 1));
        let spacing = f64::from(GRID_SPACING);
        let (mut worst, mut density) = (DVec2::ZERO, SampleDensity::default());
        for j in 0..CELLS {
            for i in 0..CELLS {
                let (i0, i1) = inner(i);
                let (j0, j1) = inner(j);
                let fxx = along_x[j][i0]
                    .max(along_x[j][i1])
                    .max(along_x[j + 1][i0])
                    .max(along_x[j + 1][i1]);
                let fyy = along_y[j0][i]
                    .max(along_y[j1][i])
                    .max(along_y[j0][i + 1])
                    .max(along_y[j1][i + 1]);
                worst = worst.max((fxx + fyy) / 8.0);
                // The cell's pixel footprint, as patch_level measures it.
                let dx = (grid[j][i + 1] - grid[j][i]) / spacing;
                let dy = (grid[j + 1][i] - grid[j][i]) / spacing;
                density.add(dx, dy);
            }
        }
        let (level, filter) = density.choose(knobs, self.lattice.coarsest());
        let scale = level_scale(level);
        if (worst * scale).max_element() > GRID_TOLERANCE {
            return None;
        }
        for point in grid.iter_mut().flatten() {
            *point *= scale;
        }
        Some((level, filter, grid))
    }

    /// Lattice coordinates (at `level`) of a patch's pixels into `out`,
    /// row-major, `cols` wide, which comes filled with NaN (left where a
    /// pixel has no ray): interpolated from `grid`, else exact.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn patch_coords(
        &self,
        pose: &ViewportPose,
        map: &PixelMap,
        level: Level,
        grid: Option<&MapGrid>,
        (x0, y0): (u32, u32),
        cols: usize,
        out: &mut [DVec2],
    ) {
        if let Some(grid) = grid {
            let s = GRID_SPACING as usize;
            let inv = 1.0 / GRID_SPACING as f64;
            for (j, line_out) in out.chunks_exact_mut(cols).enumerate() {
                let (gj, ty) = (j / s, (j % s) as f64 * inv);
                let line: [DVec2; GRID_POINTS] =
                    std::array::from_fn(|i| grid[gj][i] + (grid[gj + 1][i] - grid[gj][i]) * ty);
                for (cell, span) in line_out.chunks_mut(s).enumerate() {
                    let (a, d) = (line[cell], (line[cell + 1] - line[cell]) * inv);
                    for (i, c) in span.iter_mut().enumerate() {
                        *c = a + d * i as f64;
                    }
                }
            }
            return;
        }
        let inv_step = level_scale(level) / self.lattice.step;
        let yaw = pose.camera.yaw;
        for (j, span) in out.chunks_exact_mut(cols).enumerate() {
            let y = y0 + j as u32;
            if let PixelMap::Perspective { o, u, v } = map {
                // Straight-line code over a row so the two atan2 vectorise.
                let start = *o + *v * f64::from(y) + *u * f64::from(x0);
                for (i, c) in span.iter_mut().enumerate() {
                    let d = start + *u * i as f64;
                    let az = fast_atan2(d.x, -d.z);
                    let el = fast_atan2(d.y, (d.x * d.x + d.z * d.z).sqrt());
                    *c = DVec2::new(yaw + az, FRAC_PI_2 - el) * inv_step;
                }
            } else {
                for (i, c) in span.iter_mut().enumerate() {
                    if let Some((az, el)) = map.angles(pose, x0 + i as u32, y) {
                        *c = DVec2::new(yaw + az, FRAC_PI_2 - el) * inv_step;
                    }
                }
            }
        }
    }

    /// Pass 1: each patch's level and mapping grid, and the groups not
    /// yet traced that the filter will read.
    pub(super) fn map(&self, pose: &ViewportPose, knobs: &RsvpKnobs) -> Mapped {
        let cam = &pose.camera;
        let (w, h) = (cam.width, cam.height);
        let patches_x = w.div_ceil(PATCH) as usize;
        let patches_y = h.div_ceil(PATCH) as usize;
        let map = PixelMap::new(pose);
        // Patch by patch, collected in place: concatenating bands of
        // patches would copy every patch's grid again, on one thread.
        let mut patches = Vec::with_capacity(patches_x * patches_y);
        let mut requests: Vec<Vec<u128>> = Vec::new();
        (0..patches_x * patches_y)
            .into_par_iter()
            .map_init(Vec::new, |coords, index| {
                let x0 = (index % patches_x) as u32 * PATCH;
                let y0 = (index / patches_x) as u32 * PATCH;
                let rows = (h - y0).min(PATCH) as usize;
                let mut missing = Vec::new();
                let cols = (w - x0).min(PATCH) as usize;
                let (level, filter, grid) = match self.patch_grid(pose, &map, knobs, x0, y0) {
                    Some((level, filter, grid)) => (level, filter, Some(grid)),
                    None => {
                        let (level, filter) = self.patch_level(pose, &map, knobs, x0, y0);
                        (level, filter, None)
                    }
                };
                // Interpolated points lie within their cell's corners, so
                // the grid's box holds every pixel's.
                let mut mapped = false;
                let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
                let mut count = 0u32;
                match &grid {
                    Some(grid) => {
                        for p in grid.iter().flatten() {
                            lo = lo.min(*p);
                            hi = hi.max(*p);
                        }
                        count = (cols * rows) as u32;
                    }
                    None => {
                        self.patch_coords(
                            pose,
                            &map,
                            level,
                            None,
                            (x0, y0),
                            cols,
                            nan_filled(coords, cols * rows),
                        );
                        mapped = true;
                        for c in coords.iter().filter(|c| !c.x.is_nan()) {
                            lo = lo.min(*c);
                            hi = hi.max(*c);
                            count += 1;
                        }
                    }
                }
                let reads = (count > 0).then(|| SampleBox::read_by(&filter, lo, hi));
                if let Some(reads) = reads {
                    self.collect_missing(level, &filter, knobs, reads, count, &mut missing, |f| {
                        if !mapped {
                            self.patch_coords(
                                pose,
                                &map,
                                level,
                                grid.as_ref(),
                                (x0, y0),
                                cols,
                                nan_filled(coords, cols * rows),
                            );
                        }
                        for c in coords.iter().filter(|c| !c.x.is_nan()) {
                            f((c.x, c.y));
                        }
                    });
                }
                // A box with 16 times more samples a pixel than the level
                // was chosen for would copy far more than its pixels read.
                let blocks = reads.filter(|b| {
                    b.area() <= 16.0 * knobs.samples_per_pixel() * (cols * rows) as f64
                        && b.c1 - b.c0 < self.lattice.columns(level.x)
                });
                (
                    PatchMap {
                        level,
                        filter,
                        grid,
                        blocks,
                    },
                    missing,
                )
            })
            .unzip_into_vecs(&mut patches, &mut requests);
        // A first frame asks for many groups, many of them twice (by
        // neighbouring patches): they are sorted and deduplicated as
        // integer keys, which is cheaper than sorting tuples or computing
        // a key in each comparison, on both threads. A steady frame asks
        // for few, which sort faster on one thread than handed to both.
        let mut keys = requests.concat();
        if keys.len() > 1 << 14 {
            keys.par_sort_unstable();
        } else {
            keys.sort_unstable();
        }
        keys.dedup();
        let missing = keys.into_iter().map(from_trace_order).collect();
        Mapped {
            patches,
            patches_x,
            missing,
        }
    }

    /// Whether every group of `owner`'s slots on the group row of slot row
    /// `row` covering slot columns `c_from..=c_to` was traced: whole tiles'
    /// masks at once.
    fn run_traced(&self, owner: Level, row: i64, c_from: i64, c_to: i64) -> bool {
        let samples = &self.levels[owner.index()];
        let columns = self.lattice.slot_columns(owner);
        tile_spans(columns, row, c_from, c_to, |key, wanted| {
            let traced = samples.tile(key).map_or(0, |t| {
                samples.mark_used(t, self.frame);
                samples.traced[t as usize]
            });
            traced & wanted == wanted
        })
    }

    /// Whether every sample of `level` in columns `c0..=c1` and rows
    /// `r0..=r1` (rows within the lattice) was traced, at every level that
    /// owns some of them.
    fn box_traced(&self, level: Level, (c0, c1): (i64, i64), (r0, r1): (i64, i64)) -> bool {
        let gh = i64::from(GROUP_HEIGHT);
        let base = self.lattice.base(level);
        (base.x..=level.x).all(|ox| {
            (base.y..=level.y).all(|oy| {
                let owner = Level::new(ox, oy);
                let (sx, sy) = (level.x - ox, level.y - oy);
                // The owner's positions in the box, then its slots there: a
                // level finer than its pyramid's coarsest on an axis owns
                // the odd positions.
                let slots = |finer: bool, lo: i64, hi: i64| {
                    if finer {
                        (lo >> 1, (hi - 1) >> 1)
                    } else {
                        (lo, hi)
                    }
                };
                let (sc0, sc1) = slots(ox > base.x, c0 >> sx, c1 >> sx);
                let (sr0, sr1) = slots(oy > base.y, r0 >> sy, r1 >> sy);
                if sc0 > sc1 || sr0 > sr1 {
                    return true;
                }
                let first = SampleGroup::containing(sc0, sr0).row;
                (0..)
                    .map(|k| first + k * gh)
                    .take_while(|&row| row <= sr1)
                    .all(|row| self.run_traced(owner, row, sc0, sc1))
            })
        })
    }

    /// Adds the untraced groups a patch's filter reads. A patch whose
    /// samples are dense (at most eight times as many a pixel as its level
    /// was chosen for: [`RsvpKnobs::samples_per_pixel`]) first checks every group of its
    /// box at every owning level, a quick yes in the usual case that all
    /// were traced; otherwise it marks the samples its pixels read in a
    /// bitmap of the box and asks for the groups under each row's runs of
    /// marks. A sparse patch (zoomed far out, or near a pole) asks for
    /// each pixel's own groups.
    #[allow(clippy::too_many_arguments)]
    // Inlined into the per-patch closure of `map`, its one caller: a call
    // per patch, out of line, costs instructions for nothing.
    #[inline]
    fn collect_missing(
        &self,
        level: Level,
        filter: &PatchFilter,
        knobs: &RsvpKnobs,
        reads: SampleBox,
        pixels: u32,
        missing: &mut Vec<u128>,
        for_each_pixel: impl FnOnce(&mut dyn FnMut((f64, f64))),
    ) {
        let SampleBox { c0, r0, c1, r1 } = reads;
        let last_row = self.lattice.last_row(level.y);
        let (r0, r1) = (r0.clamp(0, last_row), r1.clamp(0, last_row));
        let area = ((c1 - c0 + 1) as f64) * ((r1 - r0 + 1) as f64);
        let dense = area <= 8.0 * knobs.samples_per_pixel() * f64::from(pixels)
            && c1 - c0 < self.lattice.columns(level.x);
        if dense && self.box_traced(level, (c0, c1), (r0, r1)) {
            return;
        }
        let mut requests = GroupRequests::new(self, missing);
        if dense {
            let marks =
                SampleMarks::of_pixels(filter, (c0, c1), (r0, r1), last_row, for_each_pixel);
            marks.for_each_run(|row, from, to| {
                self.request_run(&mut requests, level, row, from, to);
            });
        } else {
            for_each_pixel(&mut |pixel| {
                for_each_read(filter, pixel, last_row, |col, row| {
                    let (owner, c, r) = self.lattice.owner(level, col, row);
                    requests.add(owner, SampleGroup::containing(c, r));
                });
            });
        }
    }

    /// Asks for the groups holding samples `from..=to` of row `row` of
    /// `level`, at every level that owns some of them.
    fn request_run(
        &self,
        requests: &mut GroupRequests,
        level: Level,
        row: i64,
        from: i64,
        to: i64,
    ) {
        let base = self.lattice.base(level);
        let sy = row.trailing_zeros().min((level.y - base.y) as u32);
        let oy = level.y - sy as i32;
        let slot_row = (row >> sy) >> u32::from(oy > base.y);
        for ox in base.x..=level.x {
            let sx = level.x - ox;
            let (period, offset) = owned_positions((level.x - base.x) as u32, (ox - base.x) as u32);
            let first = from + ((offset - from) & (period - 1));
            let last = to - ((to - offset) & (period - 1));
            if first > last {
                continue;
            }
            let slot = |col: i64| (col >> sx) >> u32::from(ox > base.x);
            requests.add_span(Level::new(ox, oy), slot_row, slot(first), slot(last));
        }
    }
}

/// The untraced groups a patch asks for, appended to the frame's list:
/// none already traced, and mostly each once (a group is asked for again
/// only once its tile left the cache); the frame's sort drops the rest,
/// and those its neighbours asked for too. (Sorting each patch's list
/// first would add work that the frame's sort does anyway.)
struct GroupRequests<'a> {
    buffer: &'a SampleBuffer,
    /// As [`trace_order`] keys.
    missing: &'a mut Vec<u128>,
    /// Consecutive groups mostly share a tile: its traced mask is kept. A
    /// pixel reads two rows, which may lie in neighbouring tile rows: one
    /// slot per owning level and tile row parity, distinct for owners
    /// within 4 levels on each axis (those a patch reads most).
    cached: [(usize, (i64, i64), u64); 32],
}

impl<'a> GroupRequests<'a> {
    fn new(buffer: &'a SampleBuffer, missing: &'a mut Vec<u128>) -> Self {
        GroupRequests {
            buffer,
            missing,
            cached: [(usize::MAX, (i64::MIN, i64::MIN), 0u64); 32],
        }
    }

    /// Asks for `group` of `owner`'s slots (its column in any turn).
    fn add(&mut self, owner: Level, group: SampleGroup) {
        self.add_span(owner, group.row, group.col, group.col);
    }

    /// Asks for the groups of `owner`'s slot row `row` holding slot
    /// columns `from..=to` (in any turn): a tile's worth at a time, as
    /// masks.
    fn add_span(&mut self, owner: Level, row: i64, from: i64, to: i64) {
        let columns = self.buffer.lattice.slot_columns(owner);
        tile_spans(columns, row, from, to, |key, wanted| {
            let asked = self.asked(owner, key);
            // A group asked for counts as traced in the cached mask, so
            // later asks skip it.
            let mut fresh = wanted & !*asked;
            *asked |= wanted;
            while fresh != 0 {
                let bit = i64::from(fresh.trailing_zeros());
                fresh &= fresh - 1;
                let group = SampleGroup {
                    col: (key.0 << TILE_COL_SHIFT) + bit * i64::from(GROUP_WIDTH),
                    row: key.1 << TILE_ROW_SHIFT,
                };
                self.missing.push(trace_order(owner, group));
            }
            true
        });
    }

    /// The cached mask of tile `key` of `owner`: its groups traced or
    /// asked for.
    fn asked(&mut self, owner: Level, key: (i64, i64)) -> &mut u64 {
        let index = owner.index();
        let slot_index = (((owner.x & 3) * 4 + (owner.y & 3)) * 2) as usize + (key.1 & 1) as usize;
        let slot = &mut self.cached[slot_index];
        if (slot.0, slot.1) != (index, key) {
            let samples = &self.buffer.levels[index];
            let traced = samples.tile(key).map_or(0, |t| {
                samples.mark_used(t, self.buffer.frame);
                samples.traced[t as usize]
            });
            *slot = (index, key, traced);
        }
        &mut slot.2
    }
}

/// Which samples of a box of one level a patch's pixels read: a bit per
/// sample, row-major.
struct SampleMarks {
    c0: i64,
    r0: i64,
    width: usize,
    height: usize,
    bits: Vec<u64>,
}

impl SampleMarks {
    /// Marks the samples each pixel's filter reads; the box
    /// (`c0..=c1`, `r0..=r1`, rows clamped like the reads) holds them all.
    fn of_pixels(
        filter: &PatchFilter,
        (c0, c1): (i64, i64),
        (r0, r1): (i64, i64),
        last_row: i64,
        for_each_pixel: impl FnOnce(&mut dyn FnMut((f64, f64))),
    ) -> SampleMarks {
        let (width, height) = ((c1 - c0 + 1) as usize, (r1 - r0 + 1) as usize);
        // A word past the end, which a run in the last word may spill into.
        let mut bits = vec![0u64; (width * height).div_ceil(64) + 1];
        for_each_pixel(&mut |pixel| {
            for_each_read_run(filter, pixel, last_row, |col, row, run| {
                debug_assert!(
                    c0 <= col && col + run - 1 <= c1 && run <= 64,
                    "{col} + {run} outside {c0}..={c1}"
                );
                // A run a word at a time: the pixel box's rows are up to
                // eleven samples long.
                let bit = (row - r0) as usize * width + (col - c0) as usize;
                let (word, offset) = (bit >> 6, (bit & 63) as u32);
                let mask = u64::MAX >> (64 - run as u32);
                bits[word] |= mask << offset;
                if offset + run as u32 > 64 {
                    bits[word + 1] |= mask >> (64 - offset);
                }
            });
        });
        SampleMarks {
            c0,
            r0,
            width,
            height,
            bits,
        }
    }

    /// The first bit from `from` (up to `end`) that is `set`, else `end`.
    fn next(&self, from: usize, end: usize, set: bool) -> usize {
        let mut i = from;
        while i < end {
            let word = self.bits[i >> 6];
            let word = if set { word } else { !word } >> (i & 63);
            if word != 0 {
                return (i + word.trailing_zeros() as usize).min(end);
            }
            i = (i | 63) + 1;
        }
        end
    }

    /// Calls `each(row, first, last)` for every run of marked samples of
    /// each row of the box (lattice row and columns).
    fn for_each_run(&self, mut each: impl FnMut(i64, i64, i64)) {
        for j in 0..self.height {
            let (start, end) = (j * self.width, (j + 1) * self.width);
            let col = |bit: usize| self.c0 + (bit - start) as i64;
            let mut at = start;
            loop {
                let first = self.next(at, end, true);
                if first == end {
                    break;
                }
                let after = self.next(first, end, false);
                each(self.r0 + j as i64, col(first), col(after - 1));
                at = after;
            }
        }
    }
}

/// Slot columns `from..=to` (in any turn of `columns`) of slot row `row`
/// as tiles: `each(key, mask of the groups)`, while it returns true;
/// whether it always did.
fn tile_spans(
    columns: i64,
    row: i64,
    from: i64,
    to: i64,
    mut each: impl FnMut((i64, i64), u64) -> bool,
) -> bool {
    let gw = i64::from(GROUP_WIDTH);
    column_runs(from, to, columns, TILE_COLS, |col, run| {
        let (key, _, first) = tile_key(col, row);
        let last = ((col + run - 1) & (TILE_COLS - 1)) / gw;
        each(key, (u64::MAX >> (63 - last as u32)) & (u64::MAX << first))
    })
}

/// Bits of a row or column in a [`trace_order`] key; the level's index
/// takes the bits above both.
const ORDER_COORD_BITS: u32 = 59;
const _: () = assert!(Level::COUNT <= 1 << (128 - 2 * ORDER_COORD_BITS));

/// The order groups are traced in, (level, row, column), as one integer:
/// requested groups lie in the turn and within the poles, so neither row
/// nor column is negative.
fn trace_order(level: Level, group: SampleGroup) -> u128 {
    let fits = 0..1i64 << ORDER_COORD_BITS;
    debug_assert!(fits.contains(&group.row) && fits.contains(&group.col));
    (level.index() as u128) << (2 * ORDER_COORD_BITS)
        | (group.row as u128) << ORDER_COORD_BITS
        | group.col as u128
}

/// The level and group a [`trace_order`] key stands for.
fn from_trace_order(key: u128) -> (Level, SampleGroup) {
    const COORD: u128 = (1 << ORDER_COORD_BITS) - 1;
    let group = SampleGroup {
        col: (key & COORD) as i64,
        row: (key >> ORDER_COORD_BITS & COORD) as i64,
    };
    (
        Level::from_index((key >> (2 * ORDER_COORD_BITS)) as usize),
        group,
    )
}

/// `v` as `len` NaN coordinates, reusing its allocation.
pub(super) fn nan_filled(v: &mut Vec<DVec2>, len: usize) -> &mut [DVec2] {
    v.clear();
    v.resize(len, DVec2::NAN);
    v
}

/// How densely a patch's pixels lie along each lattice axis: the most
/// pixels per level-0 sample step, over the pixels measured.
#[derive(Clone, Copy, Debug, Default)]
struct SampleDensity {
    pub(super) x: f64,
    pub(super) y: f64,
}

impl SampleDensity {
    /// A pixel whose right and lower neighbours lie `dx` and `dy` away (in
    /// level-0 samples). One sample step along a lattice axis moves the
    /// image by a column of the inverse Jacobian [dx dy]^-1; its length is
    /// the pixels per step. (For an unrotated view: 1/|dx| and 1/|dy|; for
    /// a rotated or uniformly zoomed one the same on both axes, as the
    /// parallelogram's least width gives it.)
    fn add(&mut self, dx: DVec2, dy: DVec2) {
        let det = (dx.x * dy.y - dx.y * dy.x).abs();
        if !(det.is_finite() && det > 0.0) {
            return;
        }
        // sqrt rather than hypot (a libm call per cell): no overflow here.
        self.x = self.x.max((dy.y * dy.y + dx.y * dx.y).sqrt() / det);
        self.y = self.y.max((dy.x * dy.x + dx.x * dx.x).sqrt() / det);
    }

    /// The level giving at least `oversample` samples per pixel on each
    /// axis, with the knobs' bias, no coarser than `coarsest`.
    ///
    /// A level coarser than 0 only where the pixels are wider than level
    /// 0's samples (the view zoomed out), and never coarser than one
    /// sample a pixel there: the knobs choose among the finer levels as
    /// they did before there were coarser ones, and a zoomed-out view
    /// traces about a sample a pixel rather than groups of level 0's
    /// scattered far apart.
    fn level(&self, knobs: &RsvpKnobs, coarsest: Level) -> Level {
        let axis = |pixels_per_step: f64, coarsest: i32| {
            if !(pixels_per_step.is_finite() && pixels_per_step > 0.0) {
                return 0;
            }
            // A hair of tolerance: exactly one sample per pixel, up to
            // rounding, needs no finer level.
            let at_least = |per_pixel: f64| (per_pixel.log2() - 1e-6).ceil() as i64;
            let wanted = at_least(knobs.oversample * pixels_per_step)
                + i64::from(knobs.level_bias)
                + i64::from(knobs.filter.finer_levels());
            let floor = at_least(pixels_per_step).clamp(i64::from(coarsest), 0);
            wanted.clamp(floor, i64::from(MAX_LEVEL)) as i32
        };
        Level::new(axis(self.x, coarsest.x), axis(self.y, coarsest.y))
    }

    /// The level (see [`SampleDensity::level`]) and the filter as its
    /// pixels apply it there: the pixel box as wide as the densest pixel's
    /// footprint, in that level's samples.
    fn choose(&self, knobs: &RsvpKnobs, coarsest: Level) -> (Level, PatchFilter) {
        let level = self.level(knobs, coarsest);
        let footprint = level_scale(level) / DVec2::new(self.x, self.y);
        (level, PatchFilter::new(knobs.filter, footprint))
    }
}

/// Level-0 lattice coordinates times this are `level`'s (exact: powers of
/// two).
fn level_scale(level: Level) -> DVec2 {
    DVec2::new(power_of_two(level.x), power_of_two(level.y))
}

/// 2^k, exactly.
fn power_of_two(k: i32) -> f64 {
    if k >= 0 {
        f64::from(1u32 << k)
    } else {
        1.0 / f64::from(1u32 << -k)
    }
}

#[cfg(test)]
mod tests;
