//! A buffer of every sample traced so far on a lattice: a frame traces
//! only the groups of its window not traced before, then copies the window
//! out. The pan lattice ([`super::pan`]) and a still camera's own image
//! ([`super::still`]) are kept in it.
//!
//! Promises: the buffer traces exactly the groups (and, keeping strata,
//! the packets) a full render of the window traces, so a frame made from
//! it equals a full render bit for bit.

use glam::Vec3;
use rayon::prelude::*;

use crate::clock::Stopwatch;
use crate::color::srgb_table;
use crate::ray::{LaneMask, PACKET_WIDTH};
use crate::render::{
    box_filter, stratum_cell, trace_group, trace_groups, Frame, PrimaryRays, SampleGroup, Strata,
    GROUP_HEIGHT, GROUP_WIDTH,
};
use crate::reuse::ostc::Ostc;
use crate::reuse::regions::{RegionGrid, RegionLayout, RegionSet};
use crate::reuse::{StoreFrame, ViewWork};
use crate::sampling::PixelSamples;
use crate::shade::{RayCounts, RayObserver, Shader};

mod strata_window;

use strata_window::ResolvedStrata;

/// Where a camera's view sits on the lattice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Lattice column of the image's left edge (any integer; wraps).
    pub col: i64,
    /// Lattice row of the image's top edge.
    pub row: i64,
    pub width: u32,
    pub height: u32,
    /// Snapped minus requested yaw and pitch, radians (at most half a step).
    pub yaw_error: f64,
    pub pitch_error: f64,
    /// Strata of the lattice's cells past (col, row) where the image's
    /// corner sits, (0, 0) on whole cells: pixel (x, y) is then the box
    /// over the side x side strata from there, two or four cells' worth
    /// ([`strata_window`]).
    pub strata_offset: (i64, i64),
    /// Strata a cell along each axis the offset and blend count in (1: the
    /// cells themselves).
    pub strata_side: i64,
    /// How far past that stratum, in strata (0 to 1), the box is moved on
    /// along each axis, its edge strata weighed by how much of them it
    /// covers: (0, 0) for a view snapped to strata.
    pub blend: (f32, f32),
}

impl Window {
    /// A window on whole cells, as shown without strata.
    pub fn on_cells(col: i64, row: i64, width: u32, height: u32) -> Window {
        Window {
            col,
            row,
            width,
            height,
            yaw_error: 0.0,
            pitch_error: 0.0,
            strata_offset: (0, 0),
            strata_side: 1,
            blend: (0.0, 0.0),
        }
    }
}

/// A sample lattice a [`LatticeBuffer`] can hold: rays by integer position,
/// repeating every `period()` columns, `rows()` rows from row 0.
pub trait Lattice: PrimaryRays {
    /// Columns after which the lattice repeats (a multiple of the group
    /// width).
    fn period(&self) -> i64;
    fn rows(&self) -> i64;
    fn wrap(&self, col: i64) -> i64 {
        wrap_into(col, self.period())
    }
}

/// `x.rem_euclid(turn)`, without the division when `x` lies in the first
/// turn already, as nearly every column a frame copies does.
fn wrap_into(x: i64, turn: i64) -> i64 {
    if (0..turn).contains(&x) {
        x
    } else {
        x.rem_euclid(turn)
    }
}

/// The groups a window covers: on each of its group rows, `count` groups
/// from `first_col` on (wrapped into one turn; never more than a turn).
struct GroupSpan {
    first_row: i64,
    last_row: i64,
    first_col: i64,
    count: i64,
}

impl GroupSpan {
    fn of<L: Lattice>(lattice: &L, window: &Window) -> Option<GroupSpan> {
        if window.width == 0 || window.height == 0 {
            return None;
        }
        let first = SampleGroup::containing(window.col, window.row);
        let last = SampleGroup::containing(
            window.col + i64::from(window.width) - 1,
            window.row + i64::from(window.height) - 1,
        );
        let gw = i64::from(GROUP_WIDTH);
        Some(GroupSpan {
            first_row: first.row,
            last_row: last.row,
            first_col: lattice.wrap(first.col),
            // A window wider than a turn would meet some groups twice.
            count: ((last.col - first.col) / gw + 1).min(lattice.period() / gw),
        })
    }

    fn rows(&self) -> impl Iterator<Item = i64> {
        (self.first_row..=self.last_row).step_by(GROUP_HEIGHT as usize)
    }

    /// The span's group columns, as indices of groups in a row of a turn
    /// of `per_row`: one range, or two where it wraps.
    fn column_ranges(&self, per_row: usize) -> [std::ops::Range<usize>; 2] {
        let first = (self.first_col / i64::from(GROUP_WIDTH)) as usize;
        let end = first + self.count as usize;
        if end <= per_row {
            [first..end, 0..0]
        } else {
            [first..per_row, 0..end - per_row]
        }
    }
}

/// The groups covering a window, with their columns wrapped into one turn,
/// each once, row by row.
pub fn window_groups<L: Lattice>(lattice: &L, window: &Window) -> Vec<SampleGroup> {
    let Some(span) = GroupSpan::of(lattice, window) else {
        return Vec::new();
    };
    let gw = i64::from(GROUP_WIDTH);
    let ranges = span.column_ranges((lattice.period() / gw) as usize);
    span.rows()
        .flat_map(|row| {
            ranges
                .clone()
                .into_iter()
                .flatten()
                .map(move |index| SampleGroup {
                    col: index as i64 * gw,
                    row,
                })
        })
        .collect()
}

/// Renders the window fresh (nothing kept): the reference a shifted frame
/// must equal.
pub fn render_window<L: Lattice>(
    shader: &Shader,
    lattice: &L,
    window: &Window,
) -> (Frame, RayCounts) {
    if !window.on_whole_cells() {
        return strata_window::render(shader, lattice, window);
    }
    let groups = window_groups(lattice, window);
    let (colors, counts) = trace_groups(shader, lattice, &groups);
    let mut frame = Frame::new(window.width, window.height);
    for (group, colors) in groups.iter().zip(&colors) {
        for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
            for (x, y) in window_positions(lattice, window, col, row) {
                frame.pixels[y * window.width as usize + x] = colors[lane];
            }
        }
    }
    (frame, counts)
}

/// Image positions of lattice sample (col, row) in the window (none, one,
/// or several when the window spans more than a turn).
fn window_positions<L: Lattice>(
    lattice: &L,
    window: &Window,
    col: i64,
    row: i64,
) -> impl Iterator<Item = (usize, usize)> {
    let y = row - window.row;
    let turn = lattice.period();
    let first = wrap_into(col - window.col, turn);
    let (width, height) = (i64::from(window.width), i64::from(window.height));
    let row_inside = (0..height).contains(&y);
    (0..)
        .map(move |k| first + k * turn)
        .take_while(move |&x| x < width)
        .filter(move |_| row_inside)
        .map(move |x| (x as usize, y as usize))
}

/// A frame's output from its assembled pixels: the linear frame when its
/// pixels were kept, and the 8-bit image.
pub(super) fn assembled(
    width: u32,
    height: u32,
    pixels: Option<Vec<Vec3>>,
    bytes: Vec<u8>,
) -> (Option<Frame>, image::RgbImage) {
    let frame = pixels.map(|pixels| Frame {
        width,
        height,
        pixels,
    });
    let image = image::RgbImage::from_raw(width, height, bytes).expect("three bytes per pixel");
    (frame, image)
}

/// Cells traced, from the primary rays of their sub-samples: every cell
/// that has a ray has one for each sub-sample (a fisheye pixel on its
/// circle's edge may miss some: counted down).
pub fn cells_traced(rays: &RayCounts, samples: PixelSamples) -> u64 {
    rays.primary / u64::from(samples.count())
}

/// Traces one group of cells afresh, its rays recorded into `ostc` when
/// given. With strata kept (`strata`), only its groups of strata not kept
/// are traced, and every cell of the group is resolved from its strata as
/// [`trace_group`] resolves a traced cell, so the bits are the same.
fn trace_cells<L: Lattice>(
    shader: &Shader,
    lattice: &L,
    group: SampleGroup,
    ostc: Option<&Ostc>,
    strata: Option<&BandStrata>,
) -> TracedCells {
    let mut rays = RayCounts::default();
    let Some(kept) = strata else {
        let mut marker = ostc.map(|o| o.marker(group));
        let observer = marker.as_mut().map(|m| m as &mut dyn RayObserver);
        let colors = trace_group(shader, lattice, group, &mut rays, observer);
        return TracedCells {
            colors,
            rays,
            strata: Vec::new(),
            fresh: LaneMask::MAX,
        };
    };
    let source = Strata::new(lattice);
    let side = kept.side;
    let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
    let mut fresh_strata = Vec::new();
    let mut fresh: LaneMask = 0;
    for packet_row in 0..side {
        for packet_col in 0..side {
            let stratum_group = SampleGroup {
                col: group.col * side + packet_col * gw,
                row: group.row * side + packet_row * gh,
            };
            if kept.traced[kept.group_index(stratum_group)] {
                continue;
            }
            let mut marker = ostc.map(|o| o.marker(stratum_group));
            let observer = marker.as_mut().map(|m| m as &mut dyn RayObserver);
            let colors = trace_group(shader, &source, stratum_group, &mut rays, observer);
            for (col, row) in stratum_group.lane_samples() {
                let (cell, _) = stratum_cell(col, row, side);
                let lane = (cell.1 - group.row) * gw + (cell.0 - group.col);
                fresh |= 1 << lane;
            }
            fresh_strata.push((stratum_group, colors));
        }
    }
    let stratum = |col: i64, row: i64| -> Vec3 {
        let traced = SampleGroup::containing(col, row);
        match fresh_strata.iter().find(|(g, _)| *g == traced) {
            Some((g, colors)) => colors[((row - g.row) * gw + (col - g.col)) as usize],
            None => Vec3::from(kept.colors[kept.stratum_index(col, row)]),
        }
    };
    let count = side * side;
    let scale = 1.0 / count as f32;
    let lanes = group.lane_samples();
    let colors = std::array::from_fn(|lane| {
        let (col, row) = lanes[lane];
        let strata =
            (0..count).map(|index| stratum(col * side + index % side, row * side + index / side));
        box_filter(strata, scale)
    });
    TracedCells {
        colors,
        rays,
        strata: fresh_strata,
        fresh,
    }
}

/// Every sample traced so far on one lattice, in a band of rows.
pub struct LatticeBuffer<L: Lattice> {
    lattice: L,
    /// First stored row (even) and number of stored rows (even).
    first_row: i64,
    row_count: i64,
    /// Linear colours, as plain arrays: a zeroed array vector is allocated
    /// zeroed by the system (pages mapped when first written, by the
    /// tracing threads), where zeroing a turn of `Vec3`s would fill tens of
    /// megabytes on one thread before the first frame.
    colors: Vec<[f32; 3]>,
    /// The same samples as 8-bit sRGB, converted once when traced, so a
    /// frame's output image is a byte copy.
    bytes: Vec<[u8; 3]>,
    /// One flag per 4x2 group: traced yet (with strata kept: every
    /// stratum of the group)?
    traced: Vec<bool>,
    /// With a square count above one, the cells' strata, which the cells
    /// are resolved from (None for other counts, and where they would not
    /// fit in [`STRATA_LIMIT_BYTES`]).
    strata: Option<KeptStrata>,
    /// Windows snapped between cells, as resolved from the strata so far
    /// (made when the first is shown).
    resolved: Option<ResolvedStrata>,
}

/// The most memory a buffer's strata may take: past it a buffer keeps
/// whole cells, which is as exact and re-traces by groups of cells.
pub const STRATA_LIMIT_BYTES: f64 = 256.0 * 1024.0 * 1024.0;

/// A buffer's strata ([`Strata`]): as traced, so OSTC can erase and
/// re-trace a group of strata (two cells at 4 samples a cell) where
/// without them it re-traces a group of cells.
struct KeptStrata {
    side: i64,
    /// Linear colours, row-major over the strata of the buffer's rows.
    colors: Vec<[f32; 3]>,
    /// One flag per group of strata: traced yet?
    traced: Vec<bool>,
}

/// The flag index of `group` in a buffer whose rows start at `first_row`
/// and run `turn` samples wide, group row by group row.
fn group_index(group: SampleGroup, first_row: i64, turn: i64) -> usize {
    let per_row = turn / i64::from(GROUP_WIDTH);
    let group_row = (group.row - first_row) / i64::from(GROUP_HEIGHT);
    (group_row * per_row + group.col / i64::from(GROUP_WIDTH)) as usize
}

/// One group row of a buffer's stores, and the groups to trace in it.
struct Band<'a> {
    groups: &'a [SampleGroup],
    first_row: i64,
    turn: usize,
    colors: &'a mut [[f32; 3]],
    bytes: &'a mut [[u8; 3]],
    /// The row's group flags.
    traced: &'a mut [bool],
    strata: Option<BandStrata<'a>>,
}

/// The strata of a band's rows.
struct BandStrata<'a> {
    side: i64,
    /// The band's first row of strata.
    first_row: i64,
    /// Strata in a row of the turn.
    turn: usize,
    colors: &'a mut [[f32; 3]],
    traced: &'a mut [bool],
}

impl BandStrata<'_> {
    fn group_index(&self, group: SampleGroup) -> usize {
        group_index(group, self.first_row, self.turn as i64)
    }

    fn stratum_index(&self, col: i64, row: i64) -> usize {
        (row - self.first_row) as usize * self.turn + col as usize
    }
}

/// What tracing one group of cells gave.
struct TracedCells {
    colors: [Vec3; PACKET_WIDTH],
    rays: RayCounts,
    /// With strata kept: the groups of strata traced, and their colours.
    strata: Vec<(SampleGroup, [Vec3; PACKET_WIDTH])>,
    /// The lanes (cells) whose samples were traced afresh.
    fresh: LaneMask,
}

/// OSTC's region size over a lattice's buffer, in its samples: `grid`
/// (None: one sample group a region, the camera image's default) cut from
/// a screen of `camera` pixels at `side` lattice samples a pixel along
/// each axis. The one rule for the camera image's regions; the bench's
/// region oracle uses it too.
pub fn lattice_region_size(grid: Option<RegionGrid>, camera: (u32, u32), side: u32) -> (i64, i64) {
    let (width, height) = (camera.0 * side, camera.1 * side);
    grid.unwrap_or_else(|| RegionGrid::one_group(width, height))
        .region_size(width, height)
}

impl<L: Lattice> LatticeBuffer<L> {
    /// A buffer for windows within rows `rows` of the lattice, keeping a
    /// square count's strata too when `keep_strata` is set (for OSTC, which
    /// then re-traces groups of strata: a pan alone has no use for them).
    pub fn new(lattice: L, rows: std::ops::Range<i64>, keep_strata: bool) -> LatticeBuffer<L> {
        let gh = i64::from(GROUP_HEIGHT);
        let first_row = rows.start.max(0).div_euclid(gh) * gh;
        let end = rows.end.min(lattice.rows());
        let row_count = ((end - first_row + gh - 1).div_euclid(gh) * gh).max(0);
        let samples = (lattice.period() * row_count) as usize;
        let groups = samples / (GROUP_WIDTH * GROUP_HEIGHT) as usize;
        let side = i64::from(lattice.samples().grid_side());
        let strata_count = samples * (side * side) as usize;
        let strata = (keep_strata
            && side > 1
            && (strata_count * std::mem::size_of::<[f32; 3]>()) as f64 <= STRATA_LIMIT_BYTES)
            .then(|| KeptStrata {
                side,
                colors: vec![[0.0; 3]; strata_count],
                traced: vec![false; groups * (side * side) as usize],
            });
        LatticeBuffer {
            lattice,
            first_row,
            row_count,
            colors: vec![[0.0; 3]; samples],
            bytes: vec![[0; 3]; samples],
            traced: vec![false; groups],
            strata,
            resolved: None,
        }
    }

    /// Samples of the buffer's own lattice along each side of a cell: the
    /// side of the strata's grid when it keeps strata, else 1. OSTC's
    /// regions are laid over the kept samples ([`LatticeBuffer::regions`]).
    /// OSTC's regions over the buffer (see [`lattice_region_size`]).
    pub fn ostc_regions(&self, grid: Option<RegionGrid>, camera: (u32, u32)) -> RegionLayout {
        self.regions(lattice_region_size(grid, camera, self.lattice_side()))
    }

    pub fn lattice_side(&self) -> u32 {
        self.strata.as_ref().map_or(1, |strata| strata.side as u32)
    }

    pub fn lattice(&self) -> &L {
        &self.lattice
    }

    pub fn covers(&self, window: &Window) -> bool {
        let window = window.cells();
        window.row >= self.first_row
            && window.row + i64::from(window.height) <= self.first_row + self.row_count
    }

    fn group_index(&self, group: SampleGroup) -> usize {
        group_index(group, self.first_row, self.lattice.period())
    }

    /// The window's groups not traced yet, in the order of
    /// [`window_groups`]: a row whose flags are all set is passed
    /// over in one sweep. In a steady frame nearly every row is, and
    /// testing its groups one by one would be a visible share of the
    /// frame.
    fn untraced_groups(&self, window: &Window) -> Vec<SampleGroup> {
        let Some(span) = GroupSpan::of(&self.lattice, window) else {
            return Vec::new();
        };
        let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
        let per_row = (self.lattice.period() / gw) as usize;
        let ranges = span.column_ranges(per_row);
        let mut missing = Vec::new();
        for row in span.rows() {
            let base = ((row - self.first_row) / gh) as usize * per_row;
            let flags = &self.traced[base..base + per_row];
            for range in ranges.iter().cloned() {
                if flags[range.clone()].iter().all(|&traced| traced) {
                    continue;
                }
                let untraced = range.filter(|&index| !flags[index]);
                missing.extend(untraced.map(|index| SampleGroup {
                    col: index as i64 * gw,
                    row,
                }));
            }
        }
        missing
    }

    /// The kept colour of sample (col, row), which must lie within the
    /// buffer's rows.
    pub(super) fn color(&self, col: i64, row: i64) -> Vec3 {
        Vec3::from(self.colors[self.sample_index(col, row)])
    }

    fn sample_index(&self, col: i64, row: i64) -> usize {
        ((row - self.first_row) * self.lattice.period() + self.lattice.wrap(col)) as usize
    }

    /// Regions of `size` samples tiling the whole buffer (a whole turn by
    /// the buffer's rows), for OSTC: samples of its own lattice, strata
    /// when it keeps them.
    pub fn regions(&self, size: (i64, i64)) -> RegionLayout {
        let side = i64::from(self.lattice_side());
        RegionLayout::new(
            size,
            self.lattice.period() * side,
            self.first_row * side,
            self.row_count * side,
        )
    }

    /// Nulls every sample of `regions` (of `layout`, from
    /// [`LatticeBuffer::regions`]); returns how many cells' worth of
    /// samples had been traced (a stratum counting as its share of a cell).
    pub fn erase(&mut self, layout: &RegionLayout, regions: &RegionSet) -> u64 {
        let group_samples = u64::from(GROUP_WIDTH * GROUP_HEIGHT);
        let Some(strata) = self.strata.as_mut() else {
            let mut nulled = 0;
            for region in regions.iter() {
                for group in layout.groups(region) {
                    let index = self.group_index(group);
                    nulled += u64::from(std::mem::replace(&mut self.traced[index], false))
                        * group_samples;
                }
            }
            return nulled;
        };
        let side = strata.side;
        let (first_row, turn) = (self.first_row * side, self.lattice.period() * side);
        let mut nulled = 0;
        let mut cell_groups = Vec::new();
        for region in regions.iter() {
            for group in layout.groups(region) {
                let index = group_index(group, first_row, turn);
                nulled +=
                    u64::from(std::mem::replace(&mut strata.traced[index], false)) * group_samples;
                cell_groups.push(SampleGroup::containing(group.col / side, group.row / side));
            }
        }
        for group in cell_groups {
            let index = self.group_index(group);
            self.traced[index] = false;
            if let Some(resolved) = self.resolved.as_mut() {
                resolved.forget(group, self.first_row, self.lattice.period());
            }
        }
        nulled / (side * side) as u64
    }

    /// Traces the window's groups not traced before (their rays recorded
    /// into `ostc` when given); returns how many of the window's pixels got
    /// fresh samples, and the rays.
    pub(super) fn trace_missing(
        &mut self,
        shader: &Shader,
        window: &Window,
        ostc: Option<&Ostc>,
    ) -> (u64, RayCounts, Vec<SampleGroup>) {
        assert!(self.covers(window), "window rows outside the pan buffer");
        let missing = self.untraced_groups(window);
        if let Some(resolved) = self.resolved.as_mut() {
            for &group in &missing {
                resolved.forget(group, self.first_row, self.lattice.period());
            }
        }
        let srgb = srgb_table();
        // Each group row's groups are traced and kept in its own band of
        // the stores, bands in parallel and the groups of a band too (a
        // pitch pan's new rows are one or two bands). Tracing them all
        // into a list first and keeping it on one thread would fault in
        // megabytes of fresh pages on a first frame, one at a time.
        let (lattice, bands) = self.bands_of(&missing);
        let (rays, fresh_pixels, strata_traced) = bands
            .into_par_iter()
            .map(|band| {
                let traced: Vec<TracedCells> = band
                    .groups
                    .par_iter()
                    .with_min_len(16)
                    .map(|&group| trace_cells(shader, lattice, group, ostc, band.strata.as_ref()))
                    .collect();
                let (mut rays, mut fresh) = (RayCounts::default(), 0u64);
                let mut strata_traced = Vec::new();
                let mut band = band;
                for (group, traced) in band.groups.iter().zip(traced) {
                    rays += traced.rays;
                    band.traced[(group.col / i64::from(GROUP_WIDTH)) as usize] = true;
                    for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                        let sample = (row - band.first_row) as usize * band.turn + col as usize;
                        let color = traced.colors[lane].to_array();
                        band.colors[sample] = color;
                        band.bytes[sample] = color.map(|c| srgb.encode(c));
                        if traced.fresh & (1 << lane) != 0 {
                            fresh += window_positions(lattice, window, col, row).count() as u64;
                        }
                    }
                    if let Some(strata) = band.strata.as_mut() {
                        for (stratum_group, colors) in &traced.strata {
                            let index = strata.group_index(*stratum_group);
                            strata.traced[index] = true;
                            for (lane, (col, row)) in
                                stratum_group.lane_samples().into_iter().enumerate()
                            {
                                let at = strata.stratum_index(col, row);
                                strata.colors[at] = colors[lane].to_array();
                            }
                            strata_traced.push(*stratum_group);
                        }
                    }
                }
                (rays, fresh, strata_traced)
            })
            .reduce(
                || (RayCounts::default(), 0, Vec::new()),
                |(a, m, mut x), (b, n, y)| {
                    x.extend(y);
                    (a + b, m + n, x)
                },
            );
        // With strata kept, what a frame traced is groups of strata.
        let traced = if self.strata.is_some() {
            strata_traced
        } else {
            missing
        };
        (fresh_pixels, rays, traced)
    }

    /// `groups` (sorted by row, columns within one turn) cut by group row,
    /// each run with its band of the stores; and the lattice, still to be
    /// read meanwhile.
    fn bands_of<'a>(&'a mut self, groups: &'a [SampleGroup]) -> (&'a L, Vec<Band<'a>>) {
        let turn = self.lattice.period() as usize;
        let gh = i64::from(GROUP_HEIGHT);
        let band_samples = turn * GROUP_HEIGHT as usize;
        let per_row = turn / GROUP_WIDTH as usize;
        let mut colors = self.colors.chunks_mut(band_samples).enumerate();
        let mut bytes = self.bytes.chunks_mut(band_samples);
        let mut flags = self.traced.chunks_mut(per_row);
        let first_row = self.first_row;
        // A band's strata: its rows times the side, its groups' strata
        // groups likewise.
        let mut strata = self.strata.as_mut().map(|strata| {
            let side = strata.side as usize;
            let turn = turn * side;
            let colors = strata
                .colors
                .chunks_mut(turn * GROUP_HEIGHT as usize * side);
            let traced = strata.traced.chunks_mut(per_row * side * side);
            (strata.side, turn, colors.zip(traced))
        });
        let mut bands = Vec::new();
        for run in groups.chunk_by(|a, b| a.row == b.row) {
            let index = ((run[0].row - self.first_row) / gh) as usize;
            // Bands come in order: skip to this run's.
            let (colors, bytes, traced, band_strata) = loop {
                let (at, colors) = colors.next().expect("group rows inside the buffer");
                let (bytes, traced) = (bytes.next(), flags.next());
                let band_strata = strata.as_mut().map(|(side, turn, chunks)| {
                    let (colors, traced) = chunks.next().expect("as many");
                    BandStrata {
                        side: *side,
                        first_row: (first_row + at as i64 * gh) * *side,
                        turn: *turn,
                        colors,
                        traced,
                    }
                });
                if at == index {
                    break (
                        colors,
                        bytes.expect("as many"),
                        traced.expect("as many"),
                        band_strata,
                    );
                }
            };
            bands.push(Band {
                groups: run,
                first_row: run[0].row,
                turn,
                colors,
                bytes,
                traced,
                strata: band_strata,
            });
        }
        (&self.lattice, bands)
    }

    /// Paints black, in `image` (a view of `window`), every cell with a
    /// sample in `groups` (of the buffer's own lattice: strata when it
    /// keeps them): what a frame re-traced, like the paper's figure 4.
    pub fn paint_groups(
        &self,
        window: &Window,
        groups: &[SampleGroup],
        image: &mut image::RgbImage,
    ) {
        let side = i64::from(self.lattice_side());
        for group in groups {
            for (col, row) in group.lane_samples() {
                let (col, row) = (col.div_euclid(side), row.div_euclid(side));
                for (x, y) in window_positions(&self.lattice, window, col, row) {
                    if x < image.width() as usize && y < image.height() as usize {
                        image.put_pixel(x as u32, y as u32, image::Rgb([0, 0, 0]));
                    }
                }
            }
        }
    }

    /// Traces the window's groups not traced before, then copies the window
    /// out as 8-bit sRGB and, when `linear` is set, in linear colour too
    /// (for bit-exact checks). The window must lie within the buffer's rows.
    pub fn frame(
        &mut self,
        shader: &Shader,
        window: &Window,
        linear: bool,
        ostc: Option<&Ostc>,
    ) -> (StoreFrame, Vec<SampleGroup>) {
        let watch = Stopwatch::start();
        let (fresh_pixels, rays, traced) = self.trace_missing(shader, &window.cells(), ostc);
        let trace_ms = watch.ms();
        let (pixels, bytes) = if window.on_whole_cells() {
            self.copy_cells(window, linear)
        } else if let Some(strata) = (self.strata.as_ref())
            .filter(|strata| window.blend == (0.0, 0.0) && strata.side == window.strata_side)
        {
            // Snapped between cells: what was resolved at this offset
            // before is copied.
            let entries = self.colors.len();
            let rows = (self.first_row, self.lattice.period());
            (self
                .resolved
                .get_or_insert_with(|| ResolvedStrata::new(entries)))
            .window(window, &strata.colors, rows, linear)
        } else {
            self.resolve_strata(window, linear)
        };
        let (frame, image) = assembled(window.width, window.height, pixels, bytes);
        let pixels = u64::from(window.width) * u64::from(window.height);
        let work = ViewWork {
            samples_traced: cells_traced(&rays, self.lattice.samples()),
            pixels_reused: pixels - fresh_pixels.min(pixels),
            rays,
            trace_ms,
            assembly_ms: watch.ms() - trace_ms,
            ..ViewWork::default()
        };
        (StoreFrame { frame, image, work }, traced)
    }

    /// A window on whole cells: its kept colours copied out, as 8-bit sRGB
    /// and, when `linear` is set, in linear colour.
    fn copy_cells(&self, window: &Window, linear: bool) -> (Option<Vec<Vec3>>, Vec<u8>) {
        let rows = (self.first_row, self.lattice.period());
        strata_window::copy_rows(window, &self.colors, &self.bytes, rows, linear)
    }

    /// A window on strata, resolved from the kept strata (the cells
    /// themselves at one stratum a cell), as [`LatticeBuffer::copy_cells`]
    /// gives it.
    fn resolve_strata(&self, window: &Window, linear: bool) -> (Option<Vec<Vec3>>, Vec<u8>) {
        let side = window.strata_side;
        let colors = match &self.strata {
            _ if side == 1 => &self.colors,
            Some(strata) if strata.side == side => &strata.colors,
            _ => panic!("a window on strata the buffer does not keep"),
        };
        let turn = self.lattice.period() * side;
        let (first_col, first_row) = window.first_stratum();
        let (span_cols, _) = window.strata_span();
        let columns: Vec<usize> = (0..span_cols)
            .map(|k| wrap_into(first_col + k, turn) as usize)
            .collect();
        let top = (first_row - self.first_row * side) as usize;
        let turn = turn as usize;
        let row = |j: usize| &colors[(top + j) * turn..(top + j + 1) * turn];
        strata_window::resolve(window, side as usize, &columns, row, linear)
    }
}
