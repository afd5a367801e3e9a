//! Panimation: with an equal-angle camera a pan is an image shift.
//!
//! Samples live on a world-fixed lattice around the eye: column `c` looks at
//! azimuth `(c + 0.5) * step` and row `r` at elevation `90deg - (r + 0.5) *
//! step`, with a whole number of columns per turn (a multiple of the packet
//! group width), so columns wrap and a pan that comes back, or a full turn,
//! traces nothing twice. A camera's view is a window on that lattice, its
//! corner snapped to whole samples (the snap error is reported, at most half
//! a sample each way).
//!
//! [`LatticeBuffer`] keeps every sample traced so far; a frame traces only the
//! groups of its window not traced before, then copies the window out.
//! [`PanStore`] is that buffer over the pan lattice as the frame loop uses
//! it (a still camera's own image uses the same buffer: see
//! [`super::still`]).
//! Full renders and the buffer compute each ray from the integer lattice
//! position and trace the same aligned groups, so a shifted frame equals a
//! full render bit for bit.

use std::f64::consts::{FRAC_PI_2, TAU};
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::camera::ViewportPose;
use crate::camera::{Camera, Projection};
use crate::color::srgb_table;
use crate::ray::{LaneMask, Ray, PACKET_WIDTH};
use crate::render::{
    box_filter, stratum_cell, trace_group, trace_groups, Frame, PrimaryRays, SampleGroup, Strata,
    GROUP_HEIGHT, GROUP_WIDTH,
};
use crate::reuse::ostc::Ostc;
use crate::reuse::regions::{RegionLayout, RegionSet};
use crate::reuse::{FrameMode, SampleStore, StoreFrame, Unfit, Wanted};
use crate::sampling::PixelSamples;
use crate::shade::{RayCounts, RayObserver, Shader};

/// The world-fixed equal-angle sample lattice around one eye position.
#[derive(Clone, Debug)]
pub struct EqualAngleLattice {
    pub position: DVec3,
    /// Columns in a whole turn (a multiple of the group width).
    pub columns_per_turn: i64,
    /// Rows from pole to pole.
    pub rows: i64,
    /// Angle per sample, radians: a whole turn over `columns_per_turn`.
    pub step: f64,
    /// (sin, cos) of each column's azimuth.
    columns: Vec<(f64, f64)>,
    /// (sin, cos) of each row's elevation.
    row_angles: Vec<(f64, f64)>,
    /// Antialiased: the sub-samples of each cell, at offsets keyed by the
    /// cell's lattice column and row (world-anchored: the same in every
    /// frame), and their angles' (sin, cos), cell-major; empty with one
    /// sample a cell.
    samples: PixelSamples,
    sample_columns: Vec<(f64, f64)>,
    sample_row_angles: Vec<(f64, f64)>,
}

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
}

impl EqualAngleLattice {
    /// The lattice for an equal-angle camera: the camera's angle per pixel,
    /// nudged so a whole turn holds a whole number of groups of columns
    /// (640 px over 100 degrees: exactly 2304 columns).
    pub fn for_camera(camera: &Camera) -> EqualAngleLattice {
        EqualAngleLattice::for_camera_sampled(camera, PixelSamples::ONE)
    }

    /// As [`EqualAngleLattice::for_camera`], each cell traced through
    /// `samples` sub-samples.
    pub fn for_camera_sampled(camera: &Camera, samples: PixelSamples) -> EqualAngleLattice {
        let columns_per_turn = Self::columns_per_turn_for(camera);
        let step = Self::step_for(camera);
        let rows = Self::rows_at(step);
        EqualAngleLattice {
            position: camera.position,
            columns_per_turn,
            rows,
            step,
            columns: (0..columns_per_turn)
                .map(|c| ((c as f64 + 0.5) * step).sin_cos())
                .collect(),
            row_angles: (0..rows)
                .map(|r| (FRAC_PI_2 - (r as f64 + 0.5) * step).sin_cos())
                .collect(),
            samples,
            sample_columns: Self::sample_angles(samples, columns_per_turn, |c, k| {
                ((c as f64 + samples.x(c, k)) * step).sin_cos()
            }),
            sample_row_angles: Self::sample_angles(samples, rows, |r, k| {
                (FRAC_PI_2 - (r as f64 + samples.y(r, k)) * step).sin_cos()
            }),
        }
    }

    /// `angle(line, index)` for every sub-sample of every line of `lines`
    /// (line-major); none with one sample a cell.
    fn sample_angles(
        samples: PixelSamples,
        lines: i64,
        angle: impl Fn(i64, u32) -> (f64, f64),
    ) -> Vec<(f64, f64)> {
        if samples.count() == 1 {
            return Vec::new();
        }
        (0..lines)
            .flat_map(|line| (0..samples.count()).map(move |k| (line, k)))
            .map(|(line, k)| angle(line, k))
            .collect()
    }

    /// The direction of sub-sample `index` of cell (col, row); None past a
    /// pole. Inlined into the packet loops (a call per ray costs more than
    /// the table lookups).
    #[inline(always)]
    fn sample_direction(&self, col: i64, row: i64, index: u32) -> Option<DVec3> {
        if self.samples.count() == 1 {
            return self.direction(col, row);
        }
        if !(0..self.rows).contains(&row) {
            return None;
        }
        let count = self.samples.count() as usize;
        let (sin_az, cos_az) =
            self.sample_columns[self.wrap_column(col) as usize * count + index as usize];
        let (sin_el, cos_el) = self.sample_row_angles[row as usize * count + index as usize];
        Some(DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az))
    }

    /// Rows from pole to pole at `step` radians a row, rounded up to whole
    /// groups.
    fn rows_at(step: f64) -> i64 {
        ((FRAC_PI_2 * 2.0 / step / f64::from(GROUP_HEIGHT)).ceil() * f64::from(GROUP_HEIGHT)) as i64
    }

    /// The rows of `camera`'s lattice, from pole to pole, known without
    /// making the lattice.
    pub fn rows_for(camera: &Camera) -> i64 {
        Self::rows_at(TAU / Self::columns_per_turn_for(camera) as f64)
    }

    /// The rows `camera`'s snapped window covers on its lattice, known
    /// without making the lattice.
    pub fn rows_seen(camera: &Camera) -> std::ops::Range<i64> {
        let step = TAU / Self::columns_per_turn_for(camera) as f64;
        let top = ((FRAC_PI_2 - camera.pitch) / step - 0.5 * f64::from(camera.height)).round();
        let top = top.clamp(-1e15, 1e15) as i64;
        top..top + i64::from(camera.height)
    }

    /// The bytes a pan buffer over `rows` rows of `camera`'s lattice takes,
    /// with the lattice's tables: what [`LatticeBuffer::new`] would allocate
    /// (strata aside, which [`STRATA_LIMIT_BYTES`] bounds), known before
    /// allocating it.
    pub fn buffer_bytes(camera: &Camera, rows: i64) -> f64 {
        let columns = Self::columns_per_turn_for(camera) as f64;
        let per_sample =
            (std::mem::size_of::<Vec3>() + 3) as f64 + 1.0 / f64::from(GROUP_WIDTH * GROUP_HEIGHT);
        // A sine and cosine per column, and per row from pole to pole.
        let tables = 16.0 * 1.5 * columns;
        columns * rows as f64 * per_sample + tables
    }

    /// The angle between neighbouring samples of `camera`'s lattice,
    /// radians: the unit a snapped view's offset is measured in.
    pub fn step_for(camera: &Camera) -> f64 {
        TAU / Self::columns_per_turn_for(camera) as f64
    }

    /// Columns per turn for a camera's angle per pixel, rounded to whole
    /// groups.
    pub fn columns_per_turn_for(camera: &Camera) -> i64 {
        let group = f64::from(GROUP_WIDTH);
        ((TAU / camera.angle_step() / group).round().max(1.0) * group) as i64
    }

    /// Whether `camera` views this lattice: same eye, equal-angle, same
    /// angle per pixel after snapping to a whole turn.
    pub fn fits(&self, camera: &Camera) -> bool {
        camera.projection == Projection::EqualAngle
            && camera.position == self.position
            && Self::columns_per_turn_for(camera) == self.columns_per_turn
    }

    pub fn wrap_column(&self, col: i64) -> i64 {
        col.rem_euclid(self.columns_per_turn)
    }

    /// The lattice position of a camera's image corner, unsnapped: pixel
    /// (x, y) of the camera looks exactly where lattice coordinates
    /// (col + x, row + y) do, sample (c, r) sitting at (c, r).
    pub fn exact_corner(&self, camera: &Camera) -> (f64, f64) {
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        (
            camera.yaw / self.step - 0.5 * w,
            (FRAC_PI_2 - camera.pitch) / self.step - 0.5 * h,
        )
    }

    /// The window a camera sees, its corner snapped to the nearest sample.
    pub fn window(&self, camera: &Camera) -> Window {
        let (exact_col, exact_row) = self.exact_corner(camera);
        let col = exact_col.round();
        let row = exact_row.round();
        Window {
            col: col as i64,
            row: row as i64,
            width: camera.width,
            height: camera.height,
            yaw_error: (col - exact_col) * self.step,
            pitch_error: -(row - exact_row) * self.step,
        }
    }

    /// Unit direction of lattice sample (col, row); None beyond the poles.
    pub fn direction(&self, col: i64, row: i64) -> Option<DVec3> {
        if !(0..self.rows).contains(&row) {
            return None;
        }
        let (sin_az, cos_az) = self.columns[self.wrap_column(col) as usize];
        let (sin_el, cos_el) = self.row_angles[row as usize];
        Some(DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az))
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

impl Lattice for EqualAngleLattice {
    fn period(&self) -> i64 {
        self.columns_per_turn
    }
    fn rows(&self) -> i64 {
        self.rows
    }
}

impl PrimaryRays for EqualAngleLattice {
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        self.direction(col, row)
            .map(|d| Ray::new(self.position.as_vec3(), d.as_vec3()))
    }

    fn samples(&self) -> PixelSamples {
        self.samples
    }

    #[inline(always)]
    fn sample(&self, col: i64, row: i64, index: u32) -> Option<Ray> {
        self.sample_direction(col, row, index)
            .map(|d| Ray::new(self.position.as_vec3(), d.as_vec3()))
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
fn assembled(
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
pub struct LatticeBuffer<L: Lattice = EqualAngleLattice> {
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
        let per_row = self.turn / GROUP_WIDTH as usize;
        let row = ((group.row - self.first_row) / i64::from(GROUP_HEIGHT)) as usize;
        row * per_row + (group.col / i64::from(GROUP_WIDTH)) as usize
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

/// What one frame of a pan cost.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PanFrameStats {
    pub samples_traced: u64,
    pub pixels_reused: u64,
    pub rays: RayCounts,
    /// Of the frame's time, tracing (recording into OSTC included).
    pub trace_ms: f64,
    /// The groups traced for the frame (wrapped lattice coordinates).
    #[serde(skip)]
    pub traced: Vec<SampleGroup>,
}

impl PanFrameStats {
    /// The frame as a store gives it (`elapsed_ms` in all), and the groups
    /// it traced.
    pub fn store_frame(
        self,
        frame: Option<Frame>,
        image: image::RgbImage,
        elapsed_ms: f64,
        snap_error: Option<(f64, f64)>,
    ) -> (StoreFrame, Vec<SampleGroup>) {
        let made = StoreFrame {
            frame,
            image,
            samples_traced: self.samples_traced,
            pixels_reused: self.pixels_reused,
            rays: self.rays,
            trace_ms: self.trace_ms,
            assembly_ms: (elapsed_ms - self.trace_ms).max(0.0),
            snap_error,
            levels: None,
        };
        (made, self.traced)
    }
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
        }
    }

    /// Samples of the buffer's own lattice along each side of a cell: the
    /// side of the strata's grid when it keeps strata, else 1. OSTC's
    /// regions are laid over the kept samples ([`LatticeBuffer::regions`]).
    pub fn lattice_side(&self) -> u32 {
        self.strata.as_ref().map_or(1, |strata| strata.side as u32)
    }

    pub fn lattice(&self) -> &L {
        &self.lattice
    }

    pub fn covers(&self, window: &Window) -> bool {
        window.row >= self.first_row
            && window.row + i64::from(window.height) <= self.first_row + self.row_count
    }

    fn group_index(&self, group: SampleGroup) -> usize {
        let per_row = self.lattice.period() / i64::from(GROUP_WIDTH);
        let group_row = (group.row - self.first_row) / i64::from(GROUP_HEIGHT);
        (group_row * per_row + group.col / i64::from(GROUP_WIDTH)) as usize
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
        let per_row = self.lattice.period() * side / i64::from(GROUP_WIDTH);
        let mut nulled = 0;
        let mut cell_groups = Vec::new();
        for region in regions.iter() {
            for group in layout.groups(region) {
                let row = (group.row - self.first_row * side) / i64::from(GROUP_HEIGHT);
                let index = (row * per_row + group.col / i64::from(GROUP_WIDTH)) as usize;
                nulled +=
                    u64::from(std::mem::replace(&mut strata.traced[index], false)) * group_samples;
                cell_groups.push(SampleGroup::containing(group.col / side, group.row / side));
            }
        }
        for group in cell_groups {
            let index = self.group_index(group);
            self.traced[index] = false;
        }
        nulled / (side * side) as u64
    }

    /// Traces the window's groups not traced before (their rays recorded
    /// into `ostc` when given); returns how many of the window's pixels got
    /// fresh samples, and the rays.
    fn trace_missing(
        &mut self,
        shader: &Shader,
        window: &Window,
        ostc: Option<&Ostc>,
    ) -> (u64, RayCounts, Vec<SampleGroup>) {
        assert!(self.covers(window), "window rows outside the pan buffer");
        let missing = self.untraced_groups(window);
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
    ) -> (Option<Frame>, image::RgbImage, PanFrameStats) {
        let start = Instant::now();
        let (fresh_pixels, rays, traced) = self.trace_missing(shader, window, ostc);
        let trace_ms = start.elapsed().as_secs_f64() * 1e3;
        let (width, height) = (window.width as usize, window.height as usize);
        let mut pixels = Vec::with_capacity(if linear { width * height } else { 0 });
        let mut bytes: Vec<u8> = Vec::with_capacity(width * height * 3);
        let turn = self.lattice.period() as usize;
        for y in 0..height {
            let row_start = (window.row + y as i64 - self.first_row) as usize * turn;
            // Copy whole runs up to each wrap of the turn.
            let mut x = 0usize;
            while x < width {
                let col = self.lattice.wrap(window.col + x as i64) as usize;
                let run = (turn - col).min(width - x);
                let samples = row_start + col..row_start + col + run;
                if linear {
                    pixels.extend(self.colors[samples.clone()].iter().map(|&c| Vec3::from(c)));
                }
                bytes.extend_from_slice(self.bytes[samples].as_flattened());
                x += run;
            }
        }
        let (frame, image) =
            assembled(window.width, window.height, linear.then_some(pixels), bytes);
        let pixels = u64::from(window.width) * u64::from(window.height);
        (
            frame,
            image,
            PanFrameStats {
                samples_traced: cells_traced(&rays, self.lattice.samples()),
                pixels_reused: pixels - fresh_pixels.min(pixels),
                rays,
                trace_ms,
                traced,
            },
        )
    }
}

/// Resampling needs the lattice's angles: equal-angle buffers only.
impl LatticeBuffer<EqualAngleLattice> {
    /// The window a resampled view of `camera` reads: its unsnapped corner
    /// rounded down, one sample wider and taller (bilinear neighbours).
    ///
    /// A view that reaches a pole has its edge on the lattice's first or
    /// last row, where rounding can put the exact corner a hair (up to
    /// about a tenth of a sample) beyond it: the window then starts on the
    /// edge row itself, and a view as tall as the lattice (or, rounded,
    /// a row taller) reads its last row as its own neighbour.
    pub fn resample_window(&self, camera: &Camera) -> (Window, f64, f64) {
        let (col, row) = self.lattice.exact_corner(camera);
        let rows = self.lattice.rows;
        let height = (i64::from(camera.height) + 1).min(rows);
        let c0 = col.floor();
        let r0 = row.floor().clamp(0.0, (rows - height) as f64);
        let window = Window {
            col: c0 as i64,
            row: r0 as i64,
            width: camera.width + 1,
            height: height as u32,
            yaw_error: 0.0,
            pitch_error: 0.0,
        };
        (window, col - c0, (row - r0).clamp(0.0, 1.0))
    }

    /// The unsnapped view of `camera`, resampled bilinearly from the buffer
    /// (tracing what it lacks first). Approximate: the error against the
    /// camera's own rays is measured by `--verify`, never assumed.
    pub fn frame_resampled(
        &mut self,
        shader: &Shader,
        camera: &Camera,
        linear: bool,
        ostc: Option<&Ostc>,
    ) -> (Option<Frame>, image::RgbImage, PanFrameStats) {
        let (window, fx, fy) = self.resample_window(camera);
        let start = Instant::now();
        let (_, rays, traced) = self.trace_missing(shader, &window, ostc);
        let trace_ms = start.elapsed().as_secs_f64() * 1e3;
        let (fx, fy) = (fx as f32, fy as f32);
        let weights = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        let (width, height) = (camera.width as usize, camera.height as usize);
        let srgb = srgb_table();
        let mut pixels = Vec::with_capacity(if linear { width * height } else { 0 });
        let mut bytes: Vec<u8> = Vec::with_capacity(width * height * 3);
        let last_row = window.row + i64::from(window.height) - 1;
        for y in 0..height as i64 {
            let row = (window.row + y).min(last_row);
            let below = (row + 1).min(last_row);
            for x in 0..width as i64 {
                let col = window.col + x;
                let color = |col, row| Vec3::from(self.colors[self.sample_index(col, row)]);
                let c = color(col, row) * weights[0]
                    + color(col + 1, row) * weights[1]
                    + color(col, below) * weights[2]
                    + color(col + 1, below) * weights[3];
                bytes.extend(c.to_array().map(|v| srgb.encode(v)));
                if linear {
                    pixels.push(c);
                }
            }
        }
        let (frame, image) =
            assembled(camera.width, camera.height, linear.then_some(pixels), bytes);
        let total = (width * height) as u64;
        (
            frame,
            image,
            PanFrameStats {
                samples_traced: cells_traced(&rays, self.lattice.samples()),
                pixels_reused: total.saturating_sub(rays.primary),
                rays,
                trace_ms,
                traced,
            },
        )
    }
}

/// How a pan by a fraction of a sample is shown.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FractionalPan {
    /// Move the view to the nearest whole sample (exact: equals a full
    /// render of the snapped view; the angle is off by at most half a
    /// sample).
    #[default]
    Snap,
    /// Resample the exact view bilinearly from the buffer (the true angle;
    /// slightly blurred, error measured against the camera's own rays).
    Resample,
}

impl std::str::FromStr for FractionalPan {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "snap" => Ok(FractionalPan::Snap),
            "resample" => Ok(FractionalPan::Resample),
            other => Err(format!(
                "unknown fractional pan '{other}' (expected snap or resample)"
            )),
        }
    }
}

/// An equal-angle camera's samples on its pan lattice, as the frame loop
/// keeps them: one view (the camera's image), shown snapped to whole
/// samples or resampled.
pub struct PanStore {
    buffer: LatticeBuffer,
    fractional: FractionalPan,
    /// Whether the view may move (pan is on); without, the buffer serves
    /// a still view for OSTC.
    pans: bool,
    /// The window last shown.
    window: Window,
    /// The groups the last render traced.
    traced: Vec<SampleGroup>,
}

impl PanStore {
    /// A store for views of `camera`'s lattice within `rows`.
    pub fn new(
        camera: &Camera,
        rows: std::ops::Range<i64>,
        fractional: FractionalPan,
        pans: bool,
        samples: PixelSamples,
        keep_strata: bool,
    ) -> PanStore {
        let lattice = EqualAngleLattice::for_camera_sampled(camera, samples);
        let window = lattice.window(camera);
        PanStore {
            buffer: LatticeBuffer::new(lattice, rows, keep_strata),
            fractional,
            pans,
            window,
            traced: Vec::new(),
        }
    }

    /// The window of the buffer a view of `camera` reads.
    fn read_window(&self, camera: &Camera) -> Window {
        match self.fractional {
            FractionalPan::Snap => self.buffer.lattice().window(camera),
            FractionalPan::Resample => self.buffer.resample_window(camera).0,
        }
    }
}

impl SampleStore for PanStore {
    fn name(&self) -> &'static str {
        "buffer"
    }

    fn mode(&self, ostc: bool) -> FrameMode {
        match (self.pans, ostc) {
            (true, true) => FrameMode::PanOstc,
            (false, true) => FrameMode::Ostc,
            (true, false) => FrameMode::Pan,
            (false, false) => FrameMode::Still,
        }
    }

    fn unfit(&self, views: &[ViewportPose]) -> Option<Unfit> {
        let camera = &views.first()?.camera;
        let lattice = self.buffer.lattice();
        if !lattice.fits(camera) {
            return Some(Unfit::LatticeChanged);
        }
        if !self.buffer.covers(&self.read_window(camera)) {
            return Some(Unfit::RowsLeft);
        }
        let window = lattice.window(camera);
        let moved = (window.col, window.row) != (self.window.col, self.window.row);
        (moved && !self.pans).then_some(Unfit::MovedPanOff)
    }

    fn lattice_side(&self) -> u32 {
        self.buffer.lattice_side()
    }

    fn regions(&self, size: (i64, i64)) -> RegionLayout {
        self.buffer.regions(size)
    }

    fn erase(&mut self, layout: &RegionLayout, regions: &RegionSet) -> u64 {
        self.buffer.erase(layout, regions)
    }

    fn render(
        &mut self,
        shader: &Shader,
        views: &[ViewportPose],
        ostc: Option<&Ostc>,
        wanted: Wanted,
    ) -> Vec<StoreFrame> {
        let camera = &views[0].camera;
        let start = Instant::now();
        self.window = self.buffer.lattice().window(camera);
        let (frame, image, pan) = match self.fractional {
            FractionalPan::Snap => self.buffer.frame(shader, &self.window, wanted.linear, ostc),
            FractionalPan::Resample => {
                self.buffer
                    .frame_resampled(shader, camera, wanted.linear, ostc)
            }
        };
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        let snap_error = (self.fractional == FractionalPan::Snap)
            .then_some((self.window.yaw_error, self.window.pitch_error));
        let (made, traced) = pan.store_frame(frame, image, elapsed, snap_error);
        self.traced = traced;
        vec![made]
    }

    fn paint_traced(
        &self,
        _index: usize,
        view: &ViewportPose,
        image: &image::RgbImage,
    ) -> image::RgbImage {
        let mut painted = image.clone();
        let window = self.read_window(&view.camera);
        self.buffer
            .paint_groups(&window, &self.traced, &mut painted);
        painted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(yaw_deg: f64, pitch_deg: f64) -> Camera {
        Camera {
            projection: Projection::EqualAngle,
            position: DVec3::new(0.0, 1.0, 0.0),
            yaw: yaw_deg.to_radians(),
            pitch: pitch_deg.to_radians(),
            fov: 100f64.to_radians(),
            width: 640,
            height: 480,
        }
    }

    #[test]
    fn paper_camera_gets_2304_columns_per_turn() {
        let lattice = EqualAngleLattice::for_camera(&camera(0.0, 0.0));
        assert_eq!(lattice.columns_per_turn, 2304);
        assert_eq!(lattice.rows, 1152);
    }

    #[test]
    fn window_matches_the_camera_where_no_snap_is_needed() {
        // Yaw 0, pitch 0 puts the window corner on whole samples: the lattice
        // directions are the camera's own pixel directions.
        let cam = camera(0.0, 0.0);
        let lattice = EqualAngleLattice::for_camera(&cam);
        let window = lattice.window(&cam);
        assert_eq!(window.yaw_error.abs() + window.pitch_error.abs(), 0.0);
        for (x, y) in [(0u32, 0u32), (639, 479), (320, 240), (17, 401)] {
            let d = lattice
                .direction(window.col + i64::from(x), window.row + i64::from(y))
                .unwrap();
            let e = cam
                .direction(glam::DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
                .unwrap();
            assert!((d - e).length() < 1e-12, "({x}, {y})");
        }
    }

    #[test]
    fn snapping_is_within_half_a_sample_and_never_drifts() {
        let lattice = EqualAngleLattice::for_camera(&camera(0.0, 0.0));
        for frame in [1u32, 7, 99, 10_000, 123_457] {
            let yaw = f64::from(frame) * 3.6;
            let window = lattice.window(&camera(yaw, -9.0));
            assert!(window.yaw_error.abs() <= lattice.step * 0.5 + 1e-12);
            assert!(window.pitch_error.abs() <= lattice.step * 0.5 + 1e-12);
            // 3.6 degrees is 23.04 columns: frame f sits at round(23.04 f) - 320.
            assert_eq!(window.col, (f64::from(frame) * 23.04).round() as i64 - 320);
        }
        // Directions repeat exactly after a whole turn.
        assert_eq!(lattice.direction(5, 100), lattice.direction(5 + 2304, 100));
        assert_eq!(lattice.direction(-1, 100), lattice.direction(2303, 100));
        assert_eq!(lattice.direction(0, -1), None);
        assert_eq!(lattice.direction(0, 1152), None);
    }
}
