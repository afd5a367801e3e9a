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

mod plan;

pub use plan::{PanPlan, PAN_BUFFER_LIMIT_BYTES};

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{DVec3, Vec3};

use crate::camera::ViewportPose;
use crate::camera::{Camera, Projection};
use crate::clock::Stopwatch;
use crate::color::srgb_table;
use crate::ray::Ray;
use crate::render::{PrimaryRays, SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};
use crate::reuse::lattice_buffer::{assembled, cells_traced, Lattice, LatticeBuffer, Window};
use crate::reuse::ostc::Ostc;
use crate::reuse::regions::{RegionGrid, RegionLayout};
use crate::reuse::{Dirty, FrameMode, SampleStore, StoreFrame, Unfit, ViewWork, Wanted};
use crate::sampling::PixelSamples;
use crate::shade::Shader;

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

    /// The samples (cells) of a pan buffer over `rows` rows of `camera`'s
    /// lattice, a band of rows spare (the buffer rounds its rows to whole
    /// groups).
    pub fn buffer_samples(camera: &Camera, rows: i64) -> f64 {
        let rows = rows + i64::from(GROUP_HEIGHT);
        Self::columns_per_turn_for(camera) as f64 * rows as f64
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
        self.window_on_strata(camera, 1)
    }

    /// The window a camera sees, its corner snapped to the nearest of
    /// `side` strata a cell along each axis (1: whole samples): at most
    /// half a stratum from the camera.
    pub fn window_on_strata(&self, camera: &Camera, side: i64) -> Window {
        self.window_at_strata(camera, side, false)
    }

    /// The window of the camera as keyed, on `side` strata a cell: its
    /// corner on the stratum before the camera's, each pixel's box moved
    /// on by the fraction of a stratum left over ([`Window::blend`]).
    pub fn window_blended(&self, camera: &Camera, side: i64) -> Window {
        self.window_at_strata(camera, side, true)
    }

    /// The camera's corner on `side` strata a cell: the nearest stratum,
    /// or with `blended` the one before and the fraction left over.
    fn window_at_strata(&self, camera: &Camera, side: i64, blended: bool) -> Window {
        let (exact_col, exact_row) = self.exact_corner(camera);
        let n = side as f64;
        let (at_col, at_row) = (exact_col * n, exact_row * n);
        let snap = if blended { f64::floor } else { f64::round };
        let (col, row) = (snap(at_col), snap(at_row));
        let (col_i, row_i) = (col as i64, row as i64);
        let (yaw_error, pitch_error, blend) = if blended {
            (0.0, 0.0, ((at_col - col) as f32, (at_row - row) as f32))
        } else {
            let yaw_error = (col / n - exact_col) * self.step;
            let pitch_error = -(row / n - exact_row) * self.step;
            (yaw_error, pitch_error, (0.0, 0.0))
        };
        Window {
            col: col_i.div_euclid(side),
            row: row_i.div_euclid(side),
            width: camera.width,
            height: camera.height,
            yaw_error,
            pitch_error,
            strata_offset: (col_i.rem_euclid(side), row_i.rem_euclid(side)),
            strata_side: side,
            blend,
        }
    }

    /// The window a frame of `camera` shows as `fractional` asks, at
    /// `side` strata a cell: snapped, or blended between strata (a
    /// resampled view reads [`LatticeBuffer::resample_window`] instead).
    pub fn shown_window(&self, camera: &Camera, fractional: FractionalPan, side: i64) -> Window {
        match fractional {
            FractionalPan::BlendStrata => self.window_blended(camera, side),
            _ => self.window_on_strata(camera, side),
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
        let (col, row) = self.lattice().exact_corner(camera);
        let rows = self.lattice().rows;
        let height = (i64::from(camera.height) + 1).min(rows);
        let c0 = col.floor();
        let r0 = row.floor().clamp(0.0, (rows - height) as f64);
        let window = Window::on_cells(c0 as i64, r0 as i64, camera.width + 1, height as u32);
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
    ) -> (StoreFrame, Vec<SampleGroup>) {
        let watch = Stopwatch::start();
        let (window, fx, fy) = self.resample_window(camera);
        let (_, rays, traced) = self.trace_missing(shader, &window, ostc);
        let trace_ms = watch.ms();
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
                let color = |col, row| self.color(col, row);
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
        let work = ViewWork {
            samples_traced: cells_traced(&rays, self.lattice().samples()),
            pixels_reused: total.saturating_sub(rays.primary),
            rays,
            trace_ms,
            assembly_ms: watch.ms() - trace_ms,
            ..ViewWork::default()
        };
        (StoreFrame { frame, image, work }, traced)
    }
}

/// How a pan by a fraction of a sample is shown.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FractionalPan {
    /// Move the view to the nearest stratum of the lattice's cells (with
    /// a square count of samples a pixel above one, where the buffer can
    /// keep its strata), else to the nearest whole sample. Exact: equals a
    /// full render of the snapped view; the angle is off by at most half a
    /// stratum.
    #[default]
    Snap,
    /// Move the view to the nearest whole sample whatever the samples a
    /// pixel (exact; off by up to half a pixel, in whole-pixel steps).
    SnapSamples,
    /// Show the camera as keyed: each pixel the box over the strata (or
    /// samples, at one a pixel) it covers, the strata it covers in part
    /// weighed by how much. Exact (equals a full render of the same
    /// blend), a little softer than a snapped view, and moves with the
    /// keys.
    BlendStrata,
    /// Resample the exact view bilinearly from the buffer (the true angle;
    /// slightly blurred, error measured against the camera's own rays).
    Resample,
}

impl FractionalPan {
    /// Whether frames are views of a camera snapped onto the lattice.
    pub fn snaps(self) -> bool {
        matches!(self, FractionalPan::Snap | FractionalPan::SnapSamples)
    }

    /// Whether frames equal full renders of the same view bit for bit.
    pub fn exact(self) -> bool {
        self != FractionalPan::Resample
    }
}

impl FractionalPan {
    /// The name `--fractional-pan` takes.
    pub fn name(self) -> &'static str {
        match self {
            FractionalPan::Snap => "snap",
            FractionalPan::SnapSamples => "snap-samples",
            FractionalPan::BlendStrata => "blend-strata",
            FractionalPan::Resample => "resample",
        }
    }
}

impl std::str::FromStr for FractionalPan {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "snap" => Ok(FractionalPan::Snap),
            "snap-samples" => Ok(FractionalPan::SnapSamples),
            "blend-strata" => Ok(FractionalPan::BlendStrata),
            "resample" => Ok(FractionalPan::Resample),
            other => Err(format!(
                "unknown fractional pan '{other}' \
                 (expected snap, snap-samples, blend-strata or resample)"
            )),
        }
    }
}

/// An equal-angle camera's samples on its pan lattice, as the frame loop
/// keeps them: one view (the camera's image), shown snapped to whole
/// samples or resampled.
pub struct PanStore {
    buffer: LatticeBuffer<EqualAngleLattice>,
    fractional: FractionalPan,
    /// Strata a cell along each axis a snapped view snaps to (1: whole
    /// samples).
    snap_side: i64,
    /// Whether the view may move (pan is on); without, the buffer serves
    /// a still view for OSTC.
    pans: bool,
    /// The window last shown.
    window: Window,
    /// The groups the last render traced.
    traced: Vec<SampleGroup>,
}

impl PanStore {
    /// A store for views of `camera`'s lattice within `rows`, snapping to
    /// `snap_side` strata a cell ([`PanPlan`] decides, as the buffer must
    /// keep strata for it).
    pub fn new(
        camera: &Camera,
        rows: std::ops::Range<i64>,
        fractional: FractionalPan,
        snap_side: i64,
        pans: bool,
        samples: PixelSamples,
        keep_strata: bool,
    ) -> PanStore {
        let lattice = EqualAngleLattice::for_camera_sampled(camera, samples);
        let window = lattice.shown_window(camera, fractional, snap_side);
        let buffer = LatticeBuffer::new(lattice, rows, keep_strata || snap_side > 1);
        assert!(
            snap_side == 1 || i64::from(buffer.lattice_side()) == snap_side,
            "the plan snaps to strata only where the buffer keeps them"
        );
        PanStore {
            buffer,
            fractional,
            snap_side,
            pans,
            window,
            traced: Vec::new(),
        }
    }

    /// The window of the buffer a view of `camera` reads.
    fn read_window(&self, camera: &Camera) -> Window {
        match self.fractional {
            FractionalPan::Resample => self.buffer.resample_window(camera).0,
            fractional => {
                let lattice = self.buffer.lattice();
                lattice.shown_window(camera, fractional, self.snap_side)
            }
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
        if camera.position != lattice.position {
            return Some(Unfit::EyeMoved);
        }
        if !lattice.fits(camera) {
            return Some(Unfit::LatticeChanged);
        }
        if !self.buffer.covers(&self.read_window(camera)) {
            return Some(Unfit::RowsLeft);
        }
        let window = lattice.shown_window(camera, self.fractional, self.snap_side);
        let corner = |w: &Window| (w.col, w.row, w.strata_offset, w.blend);
        let moved = corner(&window) != corner(&self.window);
        (moved && !self.pans).then_some(Unfit::MovedPanOff)
    }

    fn ostc_regions(&self, grid: Option<RegionGrid>, camera: (u32, u32)) -> RegionLayout {
        self.buffer.ostc_regions(grid, camera)
    }

    fn erase(&mut self, dirty: &Dirty) -> u64 {
        debug_assert!(dirty.groups.is_empty(), "the buffer erases whole regions");
        self.buffer.erase(dirty.layout, dirty.regions)
    }

    fn render(
        &mut self,
        shader: &Shader,
        views: &[ViewportPose],
        ostc: Option<&Ostc>,
        wanted: Wanted,
    ) -> Vec<StoreFrame> {
        let camera = &views[0].camera;
        self.window = (self.buffer.lattice()).shown_window(camera, self.fractional, self.snap_side);
        let (mut made, traced) = match self.fractional {
            FractionalPan::Snap | FractionalPan::SnapSamples | FractionalPan::BlendStrata => {
                self.buffer.frame(shader, &self.window, wanted.linear, ostc)
            }
            FractionalPan::Resample => {
                self.buffer
                    .frame_resampled(shader, camera, wanted.linear, ostc)
            }
        };
        made.work.snap_error =
            (self.fractional.snaps()).then_some((self.window.yaw_error, self.window.pitch_error));
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

    #[test]
    fn snapping_to_strata_is_within_half_a_stratum() {
        let lattice = EqualAngleLattice::for_camera(&camera(0.0, 0.0));
        for side in [1i64, 2, 4] {
            for frame in [1u32, 7, 99, 10_000] {
                let cam = camera(f64::from(frame) * 0.37, f64::from(frame % 13) - 9.0);
                let window = lattice.window_on_strata(&cam, side);
                let half = lattice.step * 0.5 / side as f64 + 1e-12;
                assert!(window.yaw_error.abs() <= half && window.pitch_error.abs() <= half);
                let (x, y) = window.strata_offset;
                assert!((0..side).contains(&x) && (0..side).contains(&y));
                // The corner shown is the keyed one moved by the error.
                let (col, row) = lattice.exact_corner(&cam);
                let shown = |cell: i64, offset: i64| (cell * side + offset) as f64 / side as f64;
                let yaw_moved = (shown(window.col, x) - col) * lattice.step;
                let pitch_moved = -(shown(window.row, y) - row) * lattice.step;
                assert!((yaw_moved - window.yaw_error).abs() < 1e-12);
                assert!((pitch_moved - window.pitch_error).abs() < 1e-12);
            }
        }
    }
}
