//! RSVP (Ray Sample Viewport): a lazily traced buffer of equal-angle samples
//! around a fixed eye, and viewports that resample it through their own
//! projection and 2D transform.
//!
//! Owns: the sample lattice pyramid ([`SampleLattice`]), the samples traced
//! so far ([`SampleBuffer`]), viewports and their 2D transforms
//! ([`Viewport`], [`ViewTransform`], [`ViewportPose`]) and the resampling
//! knobs ([`RsvpKnobs`]).
//!
//! Promises:
//! - Level (x, y) of the pyramid puts column c at world azimuth
//!   `c * step_0 / 2^x` and row r at elevation `90deg - r * step_0 / 2^y`,
//!   with a whole number of columns per turn (a multiple of the group
//!   width): the azimuth wraps, the rows end at the poles. The axes refine
//!   independently, because a wide perspective view squeezes azimuth at
//!   its sides long before elevation. Halving a step is exact in floating
//!   point, so level (x+1, y)'s sample (2c, r) has bit for bit level
//!   (x, y)'s direction, and likewise for rows: the levels nest.
//! - Every sample belongs to the coarsest level that has it (on each axis),
//!   is stored only there, and is traced only there. A level finer than 0
//!   on an axis owns the odd positions on it; its samples are stored and
//!   traced by slot (the odd positions numbered densely), in aligned 4x2
//!   groups of slots, so every lane of a packet is a sample the level owns.
//!   A sample's colour never depends on which level or viewport asked
//!   first, and a fresh trace of the same group reproduces it bit for bit.
//! - A sample is traced at most once and kept for every later frame; all
//!   null samples the viewports of a frame touch are traced in one batch per
//!   level through [`crate::render::trace_groups`].
//! - Resampling is an approximation: its error against the viewport's own
//!   rays is measured (`--verify`, `bench --only E2`), never assumed.

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};
use std::hash::{BuildHasherDefault, Hasher};
use std::time::Instant;

use glam::{DMat2, DVec2, DVec3, Vec3};
use rayon::prelude::*;

use crate::camera::{Camera, Projection};
use crate::ray::{LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::render::{
    srgb_table, trace_groups, trace_groups_observed, Frame, PrimaryRays, SampleGroup, GROUP_HEIGHT,
    GROUP_WIDTH,
};
use crate::reuse::ostc::{Ostc, RegionLayout, RegionSet};
use crate::shade::{RayCounts, Shader};

/// Finest pyramid level: 2^16 times the camera's angular resolution, enough
/// for a zoom of 1000 with room for oversampling and level bias.
pub const MAX_LEVEL: u32 = 16;

/// Accepted zoom factors.
pub const MIN_ZOOM: f64 = 1e-3;
pub const MAX_ZOOM: f64 = 1e3;

/// Viewport pixels per side of a region that shares one pyramid level.
pub const REGION: u32 = 16;

/// Samples per side of a storage tile (a multiple of both group sides).
/// A tile is one row of groups, 256 samples wide: a viewport row reads
/// long contiguous runs, which the hardware prefetcher follows (square
/// tiles made the sample loads miss the cache every few pixels).
const TILE_COLS: i64 = 256;
const TILE_COL_SHIFT: u32 = 8;
const TILE_ROWS: i64 = GROUP_HEIGHT as i64;
const TILE_ROW_SHIFT: u32 = 1;
const TILE_SAMPLES: usize = (TILE_COLS * TILE_ROWS) as usize;
const _: () = assert!(TILE_COLS / GROUP_WIDTH as i64 == 64);
const _: () = assert!(1 << TILE_COL_SHIFT == TILE_COLS && 1 << TILE_ROW_SHIFT == TILE_ROWS);

/// (-1)^n / (2n + 1): atan's Taylor series in t^2 after the leading t.
const ATAN_TAYLOR: [f64; 15] = {
    let mut c = [0.0; 15];
    let mut n = 0;
    while n < 15 {
        let v = 1.0 / (2 * n + 1) as f64;
        c[n] = if n % 2 == 0 { v } else { -v };
        n += 1;
    }
    c
};

/// atan2 without a libm call: range reduction to |t| <= tan(pi/8), then the
/// Taylor series to t^29. The error stays below 1e-12 rad (tested), a
/// millionth of a sample even at the finest level of a 640-pixel camera.
///
/// Branch-free (every step a select), so loops over pixels vectorise.
#[inline(always)]
pub fn fast_atan2(y: f64, x: f64) -> f64 {
    const TAN_PI_8: f64 = 0.414_213_562_373_095_03;
    let (ax, ay) = (x.abs(), y.abs());
    let swapped = ay > ax;
    let num = if swapped { ax } else { ay };
    let den = if swapped { ay } else { ax };
    // 0/0 (the zero vector) gives 0 rather than NaN.
    let t = num / den.max(f64::MIN_POSITIVE);
    let reduce = t > TAN_PI_8;
    let reduced = (t - 1.0) / (t + 1.0);
    let t = if reduce { reduced } else { t };
    let base = if reduce { FRAC_PI_4 } else { 0.0 };
    let t2 = t * t;
    let mut p = ATAN_TAYLOR[ATAN_TAYLOR.len() - 1];
    for &c in ATAN_TAYLOR.iter().rev().skip(1) {
        p = c + t2 * p;
    }
    let a = base + t * p;
    let a = if swapped { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// A pyramid level: the azimuth step halved `x` times and the elevation
/// step halved `y` times. Levels refine each axis on its own: the edges of a
/// wide perspective view squeeze azimuth far more than elevation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Level {
    pub x: u32,
    pub y: u32,
}

impl Level {
    /// Every level pair, for per-level tables.
    pub const COUNT: usize = ((MAX_LEVEL + 1) * (MAX_LEVEL + 1)) as usize;

    pub const fn new(x: u32, y: u32) -> Level {
        Level { x, y }
    }

    /// The same refinement on both axes.
    pub const fn square(k: u32) -> Level {
        Level { x: k, y: k }
    }

    pub fn index(self) -> usize {
        (self.x * (MAX_LEVEL + 1) + self.y) as usize
    }

    pub fn from_index(index: usize) -> Level {
        let n = MAX_LEVEL as usize + 1;
        Level::new((index / n) as u32, (index % n) as u32)
    }

    /// The finer of the two axes' levels.
    pub fn finest(self) -> u32 {
        self.x.max(self.y)
    }
}

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.x == self.y {
            write!(f, "{}", self.x)
        } else {
            write!(f, "{}x{}", self.x, self.y)
        }
    }
}

/// The corner-sampled equal-angle lattice pyramid around one eye.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleLattice {
    pub position: DVec3,
    /// Columns in a whole turn at level 0 (a multiple of the group width).
    pub columns_per_turn: i64,
    /// Angle per sample at level 0, radians.
    pub step: f64,
    /// Per elevation level: the last row (a division saved on every sample
    /// read).
    last_rows: [i64; MAX_LEVEL as usize + 1],
}

impl SampleLattice {
    /// Level 0 at the camera's angle per pixel, nudged so a whole turn
    /// holds whole groups (640 px over 100 degrees: 2304 columns).
    pub fn for_camera(camera: &Camera) -> SampleLattice {
        let group = f64::from(GROUP_WIDTH);
        let columns_per_turn =
            ((TAU / camera.angle_step() / group).round().max(1.0) * group) as i64;
        SampleLattice::new(camera.position, columns_per_turn)
    }

    /// `columns_per_turn` (a multiple of the group width) columns at level 0.
    pub fn new(position: DVec3, columns_per_turn: i64) -> SampleLattice {
        let step = TAU / columns_per_turn as f64;
        SampleLattice {
            position,
            columns_per_turn,
            step,
            last_rows: std::array::from_fn(|level| {
                (PI / (step / f64::from(1u32 << level))).floor() as i64
            }),
        }
    }

    /// Angle per sample after `halvings` (exact: a power-of-two scaling).
    pub fn step(&self, halvings: u32) -> f64 {
        self.step / f64::from(1u32 << halvings)
    }

    /// Columns in a turn at azimuth level `x`.
    pub fn columns(&self, x: u32) -> i64 {
        self.columns_per_turn << x
    }

    /// Last row at elevation level `y` (the south pole when the turn divides
    /// evenly).
    pub fn last_row(&self, y: u32) -> i64 {
        self.last_rows[y as usize]
    }

    /// `col` brought into the turn at azimuth level `x`.
    pub fn wrap_column(&self, x: u32, col: i64) -> i64 {
        wrap(col, self.columns(x))
    }

    /// Unit direction of sample (col, row) of `level`; None beyond the poles.
    pub fn direction(&self, level: Level, col: i64, row: i64) -> Option<DVec3> {
        if !(0..=self.last_row(level.y)).contains(&row) {
            return None;
        }
        let az = self.wrap_column(level.x, col) as f64 * self.step(level.x);
        let el = FRAC_PI_2 - row as f64 * self.step(level.y);
        Some(crate::camera::direction_from_angles(az, el))
    }

    /// The coarsest level holding sample (col, row) of `level`, and the
    /// sample's slot there: its column and row among the samples that level
    /// owns (see [`SampleLattice::slot_position`]).
    pub fn owner(&self, level: Level, col: i64, row: i64) -> (Level, i64, i64) {
        let col = self.wrap_column(level.x, col);
        let sx = col.trailing_zeros().min(level.x);
        let sy = row.trailing_zeros().min(level.y);
        let owner = Level::new(level.x - sx, level.y - sy);
        let (col, row) = (col >> sx, row >> sy);
        (
            owner,
            col >> u32::from(owner.x > 0),
            row >> u32::from(owner.y > 0),
        )
    }

    /// The (col, row) on `level` of its own slot (col, row): a level finer
    /// than 0 on an axis owns the odd positions there (the even ones are
    /// the coarser level's), so its slots are dense and a 4x2 group of them
    /// is eight samples the level owns.
    pub fn slot_position(&self, level: Level, col: i64, row: i64) -> (i64, i64) {
        let expand = |k: u32, v: i64| if k > 0 { 2 * v + 1 } else { v };
        (expand(level.x, col), expand(level.y, row))
    }

    /// Slot columns in a turn at `level`.
    pub fn slot_columns(&self, level: Level) -> i64 {
        if level.x > 0 {
            self.columns(level.x - 1)
        } else {
            self.columns_per_turn
        }
    }

    /// Last slot row of `level`.
    pub fn last_slot_row(&self, level: Level) -> i64 {
        let last = self.last_row(level.y);
        if level.y > 0 {
            (last - 1) >> 1
        } else {
            last
        }
    }

    /// Continuous lattice coordinates of world (az, el) at level 0.
    fn coords(&self, az: f64, el: f64) -> (f64, f64) {
        (az / self.step, (FRAC_PI_2 - el) / self.step)
    }
}

/// `v` modulo `n`, cheaply when it is at most a turn away.
#[inline(always)]
fn wrap(v: i64, n: i64) -> i64 {
    if (0..n).contains(&v) {
        v
    } else if (n..2 * n).contains(&v) {
        v - n
    } else if (-n..0).contains(&v) {
        v + n
    } else {
        v.rem_euclid(n)
    }
}

/// The rays of one level's own samples, by slot: every lane of a group is a
/// sample the level owns, and a group's packet is the same whoever asks
/// for it.
pub struct LevelRays<'a> {
    pub lattice: &'a SampleLattice,
    pub level: Level,
}

impl PrimaryRays for LevelRays<'_> {
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let (col, row) = self.lattice.slot_position(self.level, col, row);
        self.lattice
            .direction(self.level, col, row)
            .map(|d| Ray::new(self.lattice.position.as_vec3(), d.as_vec3()))
    }

    /// As `primary` lane by lane, bit for bit, but with one sine and cosine
    /// per column and per row of the group rather than two per lane: the
    /// libm calls were a tenth of a steady frame.
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        let (lattice, level) = (self.lattice, self.level);
        let (step_x, step_y) = (lattice.step(level.x), lattice.step(level.y));
        let origin = lattice.position.as_vec3();
        let az: [(f64, f64); GROUP_WIDTH as usize] = std::array::from_fn(|i| {
            let (col, _) = lattice.slot_position(level, group.col + i as i64, 0);
            (lattice.wrap_column(level.x, col) as f64 * step_x).sin_cos()
        });
        let rows: [i64; GROUP_HEIGHT as usize] =
            std::array::from_fn(|j| lattice.slot_position(level, 0, group.row + j as i64).1);
        let el: [(f64, f64); GROUP_HEIGHT as usize] =
            std::array::from_fn(|j| (FRAC_PI_2 - rows[j] as f64 * step_y).sin_cos());
        let last_row = lattice.last_row(level.y);
        let mut packet = [Ray::INACTIVE; PACKET_WIDTH];
        let mut mask: LaneMask = 0;
        for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
            let (i, j) = ((col - group.col) as usize, (row - group.row) as usize);
            if !(0..=last_row).contains(&rows[j]) {
                continue;
            }
            let ((sin_az, cos_az), (sin_el, cos_el)) = (az[i], el[j]);
            let d = DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az);
            packet[lane] = Ray::new(origin, d.as_vec3());
            mask |= 1 << lane;
        }
        (packet, mask)
    }
}

/// How a viewport pixel's colour is made from buffer samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Filter {
    /// The nearest sample.
    Nearest,
    /// The four samples around the pixel centre, weighted by distance.
    #[default]
    Bilinear,
    /// The mean of the 2x2 samples around the pixel centre one level finer
    /// than the pixel's footprint needs: a box over the pixel, four samples.
    Box,
}

impl std::str::FromStr for Filter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "nearest" => Ok(Filter::Nearest),
            "bilinear" => Ok(Filter::Bilinear),
            "box" => Ok(Filter::Box),
            other => Err(format!(
                "unknown filter '{other}' (expected nearest, bilinear or box)"
            )),
        }
    }
}

impl std::fmt::Display for Filter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Filter::Nearest => "nearest",
            Filter::Bilinear => "bilinear",
            Filter::Box => "box",
        })
    }
}

/// The resampling knobs; each one's cost and error is measured by `retrace
/// bench --only knobs`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RsvpKnobs {
    pub filter: Filter,
    /// Buffer samples per viewport pixel (per side) the level choice aims
    /// for at least.
    pub oversample: f64,
    /// Levels added to the chosen one (negative: coarser, cheaper).
    pub level_bias: i32,
}

impl Default for RsvpKnobs {
    fn default() -> Self {
        RsvpKnobs {
            filter: Filter::Bilinear,
            oversample: 1.0,
            level_bias: 0,
        }
    }
}

/// A viewport: its own image size, projection and field of view, looking
/// from the scene camera's eye, turned by its own yaw and pitch on top of
/// the camera's.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewport {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub projection: Projection,
    /// Horizontal field of view at zoom 1, radians.
    pub fov: f64,
    /// Radians, added to the camera's.
    pub yaw: f64,
    pub pitch: f64,
    /// The transform when no keyframe says otherwise.
    pub transform: ViewTransform,
}

/// A viewport's 2D affine transform in its image plane: the picture is
/// magnified by `zoom`, turned counter-clockwise by `rotate`, sheared by
/// `shear`, and its centre shows the point `translate` (pixels of the
/// unzoomed image, x right, y down).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ViewTransform {
    pub zoom: f64,
    /// Radians.
    pub rotate: f64,
    /// [x by y, y by x].
    pub shear: [f64; 2],
    pub translate: [f64; 2],
}

impl Default for ViewTransform {
    fn default() -> Self {
        ViewTransform {
            zoom: 1.0,
            rotate: 0.0,
            shear: [0.0, 0.0],
            translate: [0.0, 0.0],
        }
    }
}

/// Why a transform cannot be used; the field it is about.
#[derive(Clone, Debug, PartialEq)]
pub struct TransformError {
    pub field: &'static str,
    pub message: String,
}

impl ViewTransform {
    /// Unzoomed image to viewport image (about the image centre).
    pub fn matrix(&self) -> DMat2 {
        let (s, c) = self.rotate.sin_cos();
        // Counter-clockwise as seen, with y growing downward.
        let rotation = DMat2::from_cols(DVec2::new(c, -s), DVec2::new(s, c));
        let shear = DMat2::from_cols(
            DVec2::new(1.0, self.shear[1]),
            DVec2::new(self.shear[0], 1.0),
        );
        rotation * shear * self.zoom
    }

    pub fn validate(&self) -> Result<(), TransformError> {
        let err = |field, message: String| Err(TransformError { field, message });
        if !(self.zoom.is_finite() && (MIN_ZOOM..=MAX_ZOOM).contains(&self.zoom)) {
            return err(
                "zoom",
                format!(
                    "must be within {MIN_ZOOM}..{MAX_ZOOM} (1/1000..1000), got {}",
                    self.zoom
                ),
            );
        }
        if !self.rotate.is_finite() {
            return err("rotate", format!("must be finite, got {}", self.rotate));
        }
        if !self.shear.iter().all(|v| v.is_finite()) {
            return err("shear", format!("must be finite, got {:?}", self.shear));
        }
        if !self.translate.iter().all(|v| v.is_finite()) {
            return err(
                "translate",
                format!("must be finite, got {:?}", self.translate),
            );
        }
        // The shear's determinant: near zero the image collapses to a line.
        let det = 1.0 - self.shear[0] * self.shear[1];
        if det.abs() < 1e-3 {
            return err(
                "shear",
                format!(
                    "{:?} makes the transform singular (1 - sx*sy = {det:.2e}; keep it away from 0)",
                    self.shear
                ),
            );
        }
        Ok(())
    }

    /// Interpolated at `t` in [0, 1]: zoom geometrically (a steady zoom
    /// rate), the rest linearly.
    pub fn lerp(&self, other: &ViewTransform, t: f64) -> ViewTransform {
        let lerp = |a: f64, b: f64| a + (b - a) * t;
        ViewTransform {
            zoom: (lerp(self.zoom.ln(), other.zoom.ln())).exp(),
            rotate: lerp(self.rotate, other.rotate),
            shear: [
                lerp(self.shear[0], other.shear[0]),
                lerp(self.shear[1], other.shear[1]),
            ],
            translate: [
                lerp(self.translate[0], other.translate[0]),
                lerp(self.translate[1], other.translate[1]),
            ],
        }
    }
}

impl Viewport {
    /// Checks size, field of view, elevation and transform against the
    /// scene camera `base`; the error names the field.
    pub fn validate(&self, base: &Camera) -> Result<(), TransformError> {
        let err = |field, message: String| Err(TransformError { field, message });
        if self.width == 0 || self.height == 0 {
            return err(
                "width/height",
                format!(
                    "size {}x{}: both sides must be at least 1",
                    self.width, self.height
                ),
            );
        }
        for (field, value) in [("yaw", self.yaw), ("pitch", self.pitch)] {
            if !value.is_finite() {
                return err(field, format!("must be finite, got {value}"));
            }
        }
        let camera = self.camera(base);
        if camera.pitch.abs() > FRAC_PI_2 {
            return err(
                "pitch",
                format!(
                    "looks at elevation {:.3} degrees (camera pitch plus the viewport's): beyond +-90",
                    camera.pitch.to_degrees()
                ),
            );
        }
        camera.validate().map_err(|e| TransformError {
            field: match e {
                crate::camera::CameraError::EmptyImage { .. }
                | crate::camera::CameraError::ImageTooLarge { .. } => "width/height",
                crate::camera::CameraError::ElevationOutOfRange { .. } => "pitch",
                crate::camera::CameraError::FieldOfView { .. } => "fov",
                crate::camera::CameraError::NotFinite { .. } => "pitch",
            },
            message: e.to_string(),
        })?;
        self.transform.validate()
    }

    /// The viewport's untransformed camera when the scene camera is `base`.
    pub fn camera(&self, base: &Camera) -> Camera {
        Camera {
            projection: self.projection,
            position: base.position,
            yaw: base.yaw + self.yaw,
            pitch: base.pitch + self.pitch,
            fov: self.fov,
            width: self.width,
            height: self.height,
        }
    }

    pub fn pose(&self, base: &Camera, transform: ViewTransform) -> ViewportPose {
        ViewportPose::new(self.camera(base), transform)
    }
}

/// A viewport transform keyframe, fully resolved (unset values carried
/// over from the previous key of the same viewport).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewportKey {
    pub frame: u32,
    pub transform: ViewTransform,
    /// How the segment from this key to the next is eased.
    pub ease: crate::anim::Ease,
}

/// A viewport and its keyframes (in increasing frame order).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewportTrack {
    pub viewport: Viewport,
    pub keys: Vec<ViewportKey>,
}

impl ViewportTrack {
    /// The transform at `frame`, from the frame number alone: the nearest
    /// key outside the keyed range, interpolated between keys.
    pub fn transform_at(&self, frame: u32) -> ViewTransform {
        let keys = &self.keys;
        let Some(first) = keys.first() else {
            return self.viewport.transform;
        };
        let next = keys.partition_point(|k| k.frame <= frame);
        if next == 0 {
            return first.transform;
        }
        let a = &keys[next - 1];
        let Some(b) = keys.get(next) else {
            return a.transform;
        };
        let t = a
            .ease
            .apply(f64::from(frame - a.frame) / f64::from(b.frame - a.frame));
        a.transform.lerp(&b.transform, t)
    }

    /// The viewport at `frame` when the scene camera is `base`.
    pub fn pose_at(&self, base: &Camera, frame: u32) -> ViewportPose {
        self.viewport.pose(base, self.transform_at(frame))
    }
}

/// A viewport at one frame: its camera and 2D transform.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewportPose {
    pub camera: Camera,
    pub transform: ViewTransform,
    /// Viewport image offset from the centre -> unzoomed image offset.
    inverse: DMat2,
}

impl ViewportPose {
    pub fn new(camera: Camera, transform: ViewTransform) -> ViewportPose {
        ViewportPose {
            inverse: transform.matrix().inverse(),
            camera,
            transform,
        }
    }

    fn centre(&self) -> DVec2 {
        DVec2::new(f64::from(self.camera.width), f64::from(self.camera.height)) * 0.5
    }

    /// The point of the unzoomed camera image that viewport point `p` shows.
    pub fn base_point(&self, p: DVec2) -> DVec2 {
        let centre = self.centre();
        centre + self.inverse * (p - centre) + DVec2::from_array(self.transform.translate)
    }

    /// The direction viewport point `p` looks along: its own ray.
    pub fn direction(&self, p: DVec2) -> Option<DVec3> {
        self.camera.direction(self.base_point(p))
    }

    /// Level-0 lattice coordinates of viewport point `p`, by the exact
    /// functions (for level choice and tests).
    pub fn lattice_coords(&self, lattice: &SampleLattice, p: DVec2) -> Option<(f64, f64)> {
        let d = self.direction(p)?;
        let (s, c) = self.camera.yaw.sin_cos();
        let (x, z) = (d.x * c + d.z * s, d.z * c - d.x * s);
        let (rel_az, el) = (x.atan2(-z), d.y.atan2(x.hypot(z)));
        Some(lattice.coords(self.camera.yaw + rel_az, el))
    }
}

/// Azimuth relative to `yaw` (in (-pi, pi], continuous across the view so
/// a viewport never straddles the lattice's seam) and elevation.
fn relative_angles(d: DVec3, yaw: f64) -> (f64, f64) {
    let (s, c) = yaw.sin_cos();
    let x = d.x * c + d.z * s;
    let z = d.z * c - d.x * s;
    (fast_atan2(x, -z), fast_atan2(d.y, (x * x + z * z).sqrt()))
}

/// The viewport's own rays, for direct renders (the reference RSVP is
/// measured against).
pub struct ViewportRays<'a> {
    pub pose: &'a ViewportPose,
}

impl PrimaryRays for ViewportRays<'_> {
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let cam = &self.pose.camera;
        if !(0..i64::from(cam.width)).contains(&col) || !(0..i64::from(cam.height)).contains(&row) {
            return None;
        }
        let p = DVec2::new(col as f64 + 0.5, row as f64 + 0.5);
        self.pose
            .direction(p)
            .map(|d| Ray::new(cam.position.as_vec3(), d.as_vec3()))
    }
}

/// Traces every pixel of the viewport through its own rays.
pub fn render_direct(shader: &Shader, pose: &ViewportPose) -> (Frame, RayCounts) {
    let (w, h) = (pose.camera.width, pose.camera.height);
    let groups = crate::render::image_groups(w, h);
    let (colors, counts) = trace_groups(shader, &ViewportRays { pose }, &groups);
    let mut frame = Frame::new(w, h);
    for (group, colors) in groups.iter().zip(&colors) {
        for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
            if col < i64::from(w) && row < i64::from(h) {
                frame.pixels[row as usize * w as usize + col as usize] = colors[lane];
            }
        }
    }
    (frame, counts)
}

/// Maps viewport pixels to world angles cheaply: perspective and
/// equal-angle directions are affine in the pixel position, so a row is a
/// running sum; only fisheye calls the camera per pixel.
enum PixelMap {
    /// Unnormalised direction (relative to the view's yaw) = o + x u + y v.
    Perspective {
        o: DVec3,
        u: DVec3,
        v: DVec3,
    },
    /// (relative azimuth, elevation) = o + x u + y v.
    EqualAngle {
        o: DVec2,
        u: DVec2,
        v: DVec2,
    },
    Fisheye,
}

impl PixelMap {
    fn new(pose: &ViewportPose) -> PixelMap {
        let cam = &pose.camera;
        // Pixel centre (x + 0.5, y + 0.5) -> base point: affine in (x, y).
        let b0 = pose.base_point(DVec2::new(0.5, 0.5));
        let bx = pose.base_point(DVec2::new(1.5, 0.5)) - b0;
        let by = pose.base_point(DVec2::new(0.5, 1.5)) - b0;
        let centre = pose.centre();
        match cam.projection {
            Projection::Perspective => {
                let scale = (0.5 * cam.fov).tan() / centre.x;
                let (right, up, forward) = cam.basis();
                let (s, c) = cam.yaw.sin_cos();
                let unyaw = |d: DVec3| DVec3::new(d.x * c + d.z * s, d.y, d.z * c - d.x * s);
                let (right, up, forward) = (unyaw(right), unyaw(up), unyaw(forward));
                let linear = |b: DVec2| right * (b.x * scale) - up * (b.y * scale);
                PixelMap::Perspective {
                    o: linear(b0 - centre) + forward,
                    u: linear(bx),
                    v: linear(by),
                }
            }
            Projection::EqualAngle => {
                let step = cam.angle_step();
                let angles = |b: DVec2| DVec2::new(b.x * step, -b.y * step);
                PixelMap::EqualAngle {
                    o: angles(b0 - centre) + DVec2::new(0.0, cam.pitch),
                    u: angles(bx),
                    v: angles(by),
                }
            }
            Projection::Fisheye => PixelMap::Fisheye,
        }
    }

    /// (azimuth relative to the view's yaw, elevation) of pixel (x, y).
    #[inline]
    fn angles(&self, pose: &ViewportPose, x: u32, y: u32) -> Option<(f64, f64)> {
        let (xf, yf) = (f64::from(x), f64::from(y));
        match self {
            PixelMap::Perspective { o, u, v } => {
                let d = *o + *u * xf + *v * yf;
                Some((
                    fast_atan2(d.x, -d.z),
                    fast_atan2(d.y, (d.x * d.x + d.z * d.z).sqrt()),
                ))
            }
            PixelMap::EqualAngle { o, u, v } => {
                let a = *o + *u * xf + *v * yf;
                Some((a.x, a.y))
            }
            PixelMap::Fisheye => {
                let d = pose.direction(DVec2::new(xf + 0.5, yf + 0.5))?;
                Some(relative_angles(d, pose.camera.yaw))
            }
        }
    }

    /// Level-0 lattice coordinates of many pixels, bit for bit as
    /// [`PixelMap::angles`] and [`SampleLattice::coords`] give them, in one
    /// straight loop that vectorises; false for fisheye (which has no
    /// affine map).
    fn lattice_many<const N: usize>(
        &self,
        lattice: &SampleLattice,
        yaw: f64,
        (xs, ys): (&[f64; N], &[f64; N]),
        out: &mut [DVec2; N],
    ) -> bool {
        let inv_step = 1.0 / lattice.step;
        match self {
            PixelMap::Perspective { o, u, v } => {
                for ((c, &x), &y) in out.iter_mut().zip(xs).zip(ys) {
                    let d = *o + *u * x + *v * y;
                    let az = fast_atan2(d.x, -d.z);
                    let el = fast_atan2(d.y, (d.x * d.x + d.z * d.z).sqrt());
                    *c = DVec2::new((yaw + az) * inv_step, (FRAC_PI_2 - el) * inv_step);
                }
                true
            }
            PixelMap::EqualAngle { o, u, v } => {
                for ((c, &x), &y) in out.iter_mut().zip(xs).zip(ys) {
                    let a = *o + *u * x + *v * y;
                    *c = DVec2::new((yaw + a.x) * inv_step, (FRAC_PI_2 - a.y) * inv_step);
                }
                true
            }
            PixelMap::Fisheye => false,
        }
    }
}

/// One level's traced samples, by slot, in tiles allocated on first touch.
#[derive(Default)]
struct LevelSamples {
    tiles: HashMap<(i64, i64), u32, BuildHasherDefault<TileHasher>>,
    colors: Vec<Vec3>,
    /// Per tile, one bit per 4x2 group: traced yet?
    traced: Vec<u64>,
}

/// Multiplicative hashing of tile keys (small integers; no adversary).
#[derive(Default)]
struct TileHasher(u64);

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

fn tile_key(col: i64, row: i64) -> ((i64, i64), usize, u32) {
    let key = (col >> TILE_COL_SHIFT, row >> TILE_ROW_SHIFT);
    let (c, r) = (col & (TILE_COLS - 1), row & (TILE_ROWS - 1));
    let sample = (r * TILE_COLS + c) as usize;
    let group = c / i64::from(GROUP_WIDTH);
    (key, sample, group as u32)
}

/// Every traced group of a level's store: (group, tile, bit in its mask).
fn traced_groups(store: &LevelSamples) -> impl Iterator<Item = (SampleGroup, usize, u32)> + '_ {
    store
        .tiles
        .iter()
        .flat_map(move |(&(tile_col, tile_row), &tile)| {
            let mut rest = store.traced[tile as usize];
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
    fn tile(&self, key: (i64, i64)) -> Option<u32> {
        self.tiles.get(&key).copied()
    }

    fn tile_or_insert(&mut self, key: (i64, i64)) -> u32 {
        let next = self.traced.len() as u32;
        let index = *self.tiles.entry(key).or_insert(next);
        if index == next {
            self.traced.push(0);
            self.colors
                .resize(self.colors.len() + TILE_SAMPLES, Vec3::ZERO);
        }
        index
    }

    fn group_traced(&self, group: SampleGroup) -> bool {
        let (key, _, bit) = tile_key(group.col, group.row);
        self.tile(key)
            .is_some_and(|t| self.traced[t as usize] >> bit & 1 == 1)
    }
}

/// Remembers the last tiles read: neighbouring pixels read the same few
/// tiles, so most reads skip the hash map. Direct-mapped by level and tile
/// row parity (rows r and r + 1 may lie in neighbouring tile rows).
struct TileCache {
    keys: [(usize, (i64, i64)); TILE_CACHE_SLOTS],
    tiles: [u32; TILE_CACHE_SLOTS],
}

const TILE_CACHE_SLOTS: usize = 64;
const _: () = assert!(TILE_CACHE_SLOTS == 4 * 8 * 2);

impl TileCache {
    fn new() -> TileCache {
        TileCache {
            keys: [(usize::MAX, (i64::MIN, i64::MIN)); TILE_CACHE_SLOTS],
            tiles: [u32::MAX; TILE_CACHE_SLOTS],
        }
    }

    /// The tile of `key` in `store` (level `level`), or u32::MAX if none.
    #[inline(always)]
    fn tile(&mut self, store: &LevelSamples, level: Level, key: (i64, i64)) -> u32 {
        let index = level.index();
        // Distinct for levels within 4 of each other in azimuth and 8 in
        // elevation: the owners one region reads.
        let slot = (((level.x & 3) * 8 + (level.y & 7)) * 2) as usize + (key.1 & 1) as usize;
        if self.keys[slot] != (index, key) {
            self.keys[slot] = (index, key);
            self.tiles[slot] = store.tile(key).unwrap_or(u32::MAX);
        }
        self.tiles[slot]
    }
}

/// What one viewport's frame cost and gave.
pub struct ViewportFrame {
    /// Linear colour, when asked for.
    pub frame: Option<Frame>,
    pub image: image::RgbImage,
    /// Samples this viewport asked for first and that were traced for it.
    pub samples_traced: u64,
    pub rays: RayCounts,
    /// Mapping pixels and finding null samples.
    pub map_ms: f64,
    /// This viewport's share of the frame's trace batch.
    pub trace_ms: f64,
    /// Filtering and conversion to 8 bits.
    pub gather_ms: f64,
    /// The lowest and highest [`Level::finest`] of the levels the
    /// viewport's regions read.
    pub levels: (u32, u32),
}

/// Pixels between exactly mapped points of a region's grid; the pixels
/// between are interpolated.
const GRID_SPACING: u32 = 4;
const GRID_POINTS: usize = (REGION / GRID_SPACING) as usize + 1;
const _: () = assert!(REGION % GRID_SPACING == 0);

/// The most a grid may miss the exact mapping, in samples of the region's
/// level, for the region to be interpolated: it moves a bilinear weight by
/// at most 3%. (E2's widest view needs 1/64..1/32 at its edges; a finer
/// grid would cost more exact mappings than it saves.)
const GRID_TOLERANCE: f64 = 1.0 / 32.0;

/// Lattice coordinates, at the region's level, of the pixels (x0 + 4i,
/// y0 + 4j) of a region.
type MapGrid = [[DVec2; GRID_POINTS]; GRID_POINTS];

/// How pass 1 left a region for pass 2.
struct RegionMap {
    level: Level,
    /// None: the mapping bends too much here (near a pole, across the view's
    /// back seam, fisheye): every pixel is mapped exactly.
    grid: Option<MapGrid>,
}

/// One band of regions from pass 1, and the groups they miss.
type BandMap = (Vec<RegionMap>, Vec<(Level, SampleGroup)>);

/// Pass 1's result for one viewport.
struct Mapped {
    /// Per region, row-major.
    regions: Vec<RegionMap>,
    regions_x: usize,
    /// Groups to trace: (owning level, group of its slots), sorted by
    /// level index, row and column, unique.
    missing: Vec<(Level, SampleGroup)>,
}

/// Every sample traced so far, over all pyramid levels.
pub struct SampleBuffer {
    lattice: SampleLattice,
    /// By [`Level::index`].
    levels: Vec<LevelSamples>,
    samples_traced: u64,
    /// The groups the last [`SampleBuffer::render`] traced, sorted as
    /// `missing` is: what [`SampleBuffer::fresh_image`] paints.
    fresh: Vec<(Level, SampleGroup)>,
    /// OSTC bookkeeping of the samples, when objects or lights move: every
    /// batch's rays are recorded into it (see [`SampleBuffer::erase`]).
    ostc: Option<Ostc>,
}

impl SampleBuffer {
    pub fn new(lattice: SampleLattice) -> SampleBuffer {
        SampleBuffer {
            lattice,
            levels: (0..Level::COUNT).map(|_| LevelSamples::default()).collect(),
            samples_traced: 0,
            fresh: Vec::new(),
            ostc: None,
        }
    }

    /// Regions of `size` level-0 samples tiling the whole buffer (a whole
    /// turn, pole to pole). A finer level's group lies in the region of
    /// its position on level 0: a group of slots spans 8 columns and 4 rows
    /// at a level finer than 0 on that axis, aligned, which is 4 or fewer
    /// level-0 columns and 2 or fewer rows; regions a multiple of 4 wide and
    /// 2 tall (40 x 30 samples) so never cut a group.
    pub fn regions(&self, size: (i64, i64)) -> RegionLayout {
        RegionLayout::new(
            size,
            self.lattice.columns(0),
            0,
            self.lattice.last_row(0) + 1,
        )
    }

    /// Records every ray traced from now on into `ostc` (built over
    /// [`SampleBuffer::regions`]).
    pub fn set_ostc(&mut self, ostc: Option<Ostc>) {
        self.ostc = ostc;
    }

    pub fn ostc(&self) -> Option<&Ostc> {
        self.ostc.as_ref()
    }

    pub fn ostc_mut(&mut self) -> Option<&mut Ostc> {
        self.ostc.as_mut()
    }

    /// The region (of `layout`) of a group of `level`'s slots.
    fn region_of(
        lattice: &SampleLattice,
        layout: &RegionLayout,
        level: Level,
        group: SampleGroup,
    ) -> usize {
        let (col, row) = lattice.slot_position(level, group.col, group.row);
        let col = lattice.wrap_column(level.x, col) >> level.x;
        let row = (row >> level.y).clamp(0, lattice.last_row(0));
        layout.region_of(col, row)
    }

    /// Re-traces every traced group, as it was traced, and compares the kept
    /// samples with the fresh ones bit for bit: (samples compared, samples
    /// that differ). What `--verify` checks when objects move and OSTC keeps
    /// the buffer.
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
                    let kept = store.colors[tile * TILE_SAMPLES + sample];
                    compared += 1;
                    let same = kept.to_array().map(f32::to_bits)
                        == colors[lane].to_array().map(f32::to_bits);
                    differing += u64::from(!same);
                }
            }
        }
        (compared, differing)
    }

    /// Nulls, at every level, the samples lying in `regions` (of the OSTC
    /// layout); returns how many groups were erased. They are traced again
    /// when a viewport next reads them.
    pub fn erase(&mut self, regions: &RegionSet) -> u64 {
        let Some(ostc) = &self.ostc else {
            return 0;
        };
        let layout = *ostc.layout();
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

    /// The colour of sample (col, row) of `level`, if traced.
    pub fn sample(&self, level: Level, col: i64, row: i64) -> Option<Vec3> {
        let (owner, col, row) = self.lattice.owner(level, col, row);
        let store = &self.levels[owner.index()];
        let (key, sample, bit) = tile_key(col, row);
        let tile = store.tile(key)? as usize;
        (store.traced[tile] >> bit & 1 == 1).then(|| store.colors[tile * TILE_SAMPLES + sample])
    }

    /// Whether `group` of `level`'s slots was traced.
    pub fn group_traced(&self, level: Level, group: SampleGroup) -> bool {
        self.levels[level.index()].group_traced(group)
    }

    /// A traced (or null: black) sample, with the tile cache.
    #[inline(always)]
    fn read(&self, cache: &mut TileCache, level: Level, col: i64, row: i64) -> Vec3 {
        let row = row.clamp(0, self.lattice.last_row(level.y));
        let (owner, col, row) = self.lattice.owner(level, col, row);
        let (key, sample, _) = tile_key(col, row);
        let store = &self.levels[owner.index()];
        match cache.tile(store, owner, key) {
            u32::MAX => Vec3::ZERO,
            tile => store.colors[tile as usize * TILE_SAMPLES + sample],
        }
    }

    /// The level a region needs: on each axis, the densest its pixels lie
    /// along that lattice axis, brought to at least `oversample` samples per
    /// pixel.
    fn region_level(
        &self,
        pose: &ViewportPose,
        map: &PixelMap,
        knobs: &RsvpKnobs,
        x0: u32,
        y0: u32,
    ) -> Level {
        let cam = &pose.camera;
        let x1 = (x0 + REGION).min(cam.width) - 1;
        let y1 = (y0 + REGION).min(cam.height) - 1;
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
        density.level(knobs)
    }

    /// The region's level and mapping grid, or None when interpolating it
    /// could miss the exact mapping by more than [`GRID_TOLERANCE`] at that
    /// level (checked in every cell) or a point has no ray. Mapping a pixel
    /// exactly costs two atan2; a grid costs 57 mappings for 256 pixels, and
    /// its cells give the level too (the finest footprint over 16 cells),
    /// where [`SampleBuffer::region_level`] would map 15 more points.
    fn region_grid(
        &self,
        pose: &ViewportPose,
        map: &PixelMap,
        knobs: &RsvpKnobs,
        x0: u32,
        y0: u32,
    ) -> Option<(Level, MapGrid)> {
        // Level 0 first: scaling to the region's level is by a power of
        // two, exact, so the grid is the one mapped at that level bit for
        // bit. All 57 points in one batch: the grid's, then each cell's top
        // and left edge midpoints.
        const CELLS: usize = GRID_POINTS - 1;
        const MAPPED: usize = GRID_POINTS * GRID_POINTS + 2 * CELLS * CELLS;
        let (mut xs, mut ys) = ([0f64; MAPPED], [0f64; MAPPED]);
        let half = GRID_SPACING / 2;
        for j in 0..GRID_POINTS {
            for i in 0..GRID_POINTS {
                let (x, y) = (x0 + i as u32 * GRID_SPACING, y0 + j as u32 * GRID_SPACING);
                let k = j * GRID_POINTS + i;
                (xs[k], ys[k]) = (f64::from(x), f64::from(y));
                if i < CELLS && j < CELLS {
                    let k = GRID_POINTS * GRID_POINTS + 2 * (j * CELLS + i);
                    (xs[k], ys[k]) = (f64::from(x + half), f64::from(y));
                    (xs[k + 1], ys[k + 1]) = (f64::from(x), f64::from(y + half));
                }
            }
        }
        let mut mapped = [DVec2::ZERO; MAPPED];
        if !map.lattice_many(&self.lattice, pose.camera.yaw, (&xs, &ys), &mut mapped) {
            return None;
        }
        let mut grid = [[DVec2::ZERO; GRID_POINTS]; GRID_POINTS];
        for (line, points) in grid.iter_mut().zip(mapped.chunks_exact(GRID_POINTS)) {
            line.copy_from_slice(points);
        }
        // Bilinear interpolation of a quadratic misses by at most
        // (|f_xx| + |f_yy|) h^2 / 8, and the misses at a cell's edge
        // midpoints are f_xx h^2 / 8 and f_yy h^2 / 8: their sum bounds the
        // miss in the cell. (The centre alone can hide a saddle, as near a
        // pole, where the two cancel.)
        let spacing = f64::from(GRID_SPACING);
        let (mut worst, mut density) = (DVec2::ZERO, SampleDensity::default());
        for j in 0..CELLS {
            for i in 0..CELLS {
                let k = GRID_POINTS * GRID_POINTS + 2 * (j * CELLS + i);
                let across = mapped[k] - (grid[j][i] + grid[j][i + 1]) * 0.5;
                let down = mapped[k + 1] - (grid[j][i] + grid[j + 1][i]) * 0.5;
                let miss = across.abs() + down.abs();
                if miss.is_nan() {
                    return None;
                }
                worst = worst.max(miss);
                // The cell's pixel footprint, as region_level measures it.
                let dx = (grid[j][i + 1] - grid[j][i]) / spacing;
                let dy = (grid[j + 1][i] - grid[j][i]) / spacing;
                density.add(dx, dy);
            }
        }
        let level = density.level(knobs);
        let scale = level_scale(level);
        if (worst * scale).max_element() > GRID_TOLERANCE {
            return None;
        }
        for point in grid.iter_mut().flatten() {
            *point *= scale;
        }
        Some((level, grid))
    }

    /// Lattice coordinates (at `level`) of a region's pixels into `out`,
    /// row-major, `cols` wide, which comes filled with NaN (left where a
    /// pixel has no ray): interpolated from `grid`, else exact.
    #[allow(clippy::too_many_arguments)]
    fn region_coords(
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

    /// Pass 1: each region's level and mapping grid, and the groups not
    /// yet traced that the filter will read.
    fn map(&self, pose: &ViewportPose, knobs: &RsvpKnobs) -> Mapped {
        let cam = &pose.camera;
        let (w, h) = (cam.width, cam.height);
        let regions_x = w.div_ceil(REGION) as usize;
        let regions_y = h.div_ceil(REGION) as usize;
        let map = PixelMap::new(pose);
        let results: Vec<BandMap> = (0..regions_y)
            .into_par_iter()
            .map(|band| {
                let y0 = band as u32 * REGION;
                let rows = (h - y0).min(REGION) as usize;
                let mut regions = Vec::with_capacity(regions_x);
                let mut missing = Vec::new();
                let mut coords = Vec::new();
                for rx in 0..regions_x {
                    let x0 = rx as u32 * REGION;
                    let cols = (w - x0).min(REGION) as usize;
                    let (level, grid) = match self.region_grid(pose, &map, knobs, x0, y0) {
                        Some((level, grid)) => (level, Some(grid)),
                        None => (self.region_level(pose, &map, knobs, x0, y0), None),
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
                            self.region_coords(
                                pose,
                                &map,
                                level,
                                None,
                                (x0, y0),
                                cols,
                                nan_filled(&mut coords, cols * rows),
                            );
                            mapped = true;
                            for c in coords.iter().filter(|c| !c.x.is_nan()) {
                                lo = lo.min(*c);
                                hi = hi.max(*c);
                                count += 1;
                            }
                        }
                    }
                    if count > 0 {
                        self.collect_missing(
                            level,
                            knobs.filter,
                            lo,
                            hi,
                            count,
                            &mut missing,
                            |f| {
                                if !mapped {
                                    self.region_coords(
                                        pose,
                                        &map,
                                        level,
                                        grid.as_ref(),
                                        (x0, y0),
                                        cols,
                                        nan_filled(&mut coords, cols * rows),
                                    );
                                }
                                for c in coords.iter().filter(|c| !c.x.is_nan()) {
                                    f((c.x, c.y));
                                }
                            },
                        );
                    }
                    regions.push(RegionMap { level, grid });
                }
                (regions, missing)
            })
            .collect();
        let mut regions = Vec::with_capacity(regions_x * regions_y);
        let mut missing = Vec::new();
        for (r, m) in results {
            regions.extend(r);
            missing.extend(m);
        }
        missing.sort_unstable_by_key(|&(level, g)| (level, g.row, g.col));
        missing.dedup();
        Mapped {
            regions,
            regions_x,
            missing,
        }
    }

    /// Whether every group of `owner`'s slots on the group row of slot row
    /// `row` covering slot columns `c_from..=c_to` was traced: whole tiles'
    /// masks at once.
    fn run_traced(&self, owner: Level, row: i64, c_from: i64, c_to: i64) -> bool {
        let store = &self.levels[owner.index()];
        let columns = self.lattice.slot_columns(owner);
        let gw = i64::from(GROUP_WIDTH);
        let mut col = c_from;
        while col <= c_to {
            let wc = wrap(col, columns);
            let run = (c_to - col + 1)
                .min(TILE_COLS - (wc & (TILE_COLS - 1)))
                .min(columns - wc);
            let (key, _, first) = tile_key(wc, row);
            let last = ((wc + run - 1) & (TILE_COLS - 1)) / gw;
            let wanted = (u64::MAX >> (63 - last as u32)) & (u64::MAX << first);
            let traced = store.tile(key).map_or(0, |t| store.traced[t as usize]);
            if traced & wanted != wanted {
                return false;
            }
            col += run;
        }
        true
    }

    /// Whether every sample of `level` in columns `c0..=c1` and rows
    /// `r0..=r1` (rows within the lattice) was traced, at every level that
    /// owns some of them.
    fn box_traced(&self, level: Level, (c0, c1): (i64, i64), (r0, r1): (i64, i64)) -> bool {
        let gh = i64::from(GROUP_HEIGHT);
        (0..=level.x).all(|ox| {
            (0..=level.y).all(|oy| {
                let owner = Level::new(ox, oy);
                let (sx, sy) = (level.x - ox, level.y - oy);
                // The owner's positions in the box, then its slots there: a
                // level finer than 0 on an axis owns the odd positions.
                let slots = |k: u32, lo: i64, hi: i64| {
                    if k > 0 {
                        (lo >> 1, (hi - 1) >> 1)
                    } else {
                        (lo, hi)
                    }
                };
                let (sc0, sc1) = slots(ox, c0 >> sx, c1 >> sx);
                let (sr0, sr1) = slots(oy, r0 >> sy, r1 >> sy);
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

    /// Adds the untraced groups a region's filter reads. A region whose
    /// samples are dense (a few per pixel) first checks every group of its
    /// bounding box at every owning level, a quick yes in the usual case
    /// that all were traced; otherwise, or for a sparse region (zoomed far
    /// out, or near a pole), each pixel's own samples are checked.
    #[allow(clippy::too_many_arguments)]
    fn collect_missing(
        &self,
        level: Level,
        filter: Filter,
        lo: DVec2,
        hi: DVec2,
        pixels: u32,
        missing: &mut Vec<(Level, SampleGroup)>,
        for_each_pixel: impl FnOnce(&mut dyn FnMut((f64, f64))),
    ) {
        let (c0, r0) = (lo.x.floor() as i64, lo.y.floor() as i64);
        let (c1, r1) = (hi.x.floor() as i64 + 1, hi.y.floor() as i64 + 1);
        let last_row = self.lattice.last_row(level.y);
        let (r0, r1) = (r0.clamp(0, last_row), r1.clamp(0, last_row));
        let area = ((c1 - c0 + 1) as f64) * ((r1 - r0 + 1) as f64);
        let dense = area <= 8.0 * f64::from(pixels) && c1 - c0 < self.lattice.columns(level.x);
        if dense && self.box_traced(level, (c0, c1), (r0, r1)) {
            return;
        }
        // Consecutive groups mostly share a tile: keep its traced mask. A
        // pixel reads two rows, which may lie in neighbouring tile rows: one
        // slot per owning level and tile row parity, distinct for owners
        // within 4 levels on each axis (those a region reads most).
        const SLOTS: usize = 32;
        let mut cached = [(usize::MAX, (i64::MIN, i64::MIN), 0u64); SLOTS];
        let slot_of = |level: Level, key: (i64, i64)| {
            (((level.x & 3) * 4 + (level.y & 3)) * 2) as usize + (key.1 & 1) as usize
        };
        let mut add =
            |missing: &mut Vec<(Level, SampleGroup)>, owner: Level, group: SampleGroup| {
                let group = SampleGroup {
                    col: wrap(group.col, self.lattice.slot_columns(owner)),
                    row: group.row,
                };
                let (key, _, bit) = tile_key(group.col, group.row);
                let index = owner.index();
                let slot = &mut cached[slot_of(owner, key)];
                if (slot.0, slot.1) != (index, key) {
                    let store = &self.levels[index];
                    *slot = (
                        index,
                        key,
                        store.tile(key).map_or(0, |t| store.traced[t as usize]),
                    );
                }
                // A group asked for counts as traced in the cached mask: the
                // pixels after it that read it skip it (a pixel reads four
                // samples, alternating between owners, so the list's last entry
                // alone caught few repeats).
                if slot.2 >> bit & 1 == 0 {
                    slot.2 |= 1 << bit;
                    missing.push((owner, group));
                }
            };
        // The bounding box holds more than the filter reads (at the region's
        // corners, in whole groups): ask for exactly the pixels' own groups.
        let before = missing.len();
        for_each_pixel(&mut |(x, y)| {
            let (cx, ry) = filter_origin(filter, x, y);
            let extra = i64::from(filter != Filter::Nearest);
            for dr in 0..=extra {
                for dc in 0..=extra {
                    let row = (ry + dr).clamp(0, last_row);
                    let (owner, c, r) = self.lattice.owner(level, cx + dc, row);
                    add(missing, owner, SampleGroup::containing(c, r));
                }
            }
        });
        // Neighbouring pixels share groups: a small sort here keeps the
        // frame's list short.
        let region = &mut missing[before..];
        region.sort_unstable_by_key(|&(level, g)| (level, g.row, g.col));
        let mut kept = before;
        for i in before..missing.len() {
            if kept == before || missing[kept - 1] != missing[i] {
                missing[kept] = missing[i];
                kept += 1;
            }
        }
        missing.truncate(kept);
    }

    /// Traces the missing groups, one batch per level, and keeps them.
    /// Returns the samples and rays traced for each request list.
    fn trace(
        &mut self,
        shader: &Shader,
        requests: &[Vec<(Level, SampleGroup)>],
    ) -> Vec<(u64, RayCounts, f64)> {
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
        for batch in all.chunk_by(|a, b| a.0 == b.0) {
            let level = batch[0].0;
            let batch: Vec<(SampleGroup, usize)> =
                batch.iter().map(|&(_, g, who)| (g, who)).collect();
            let groups: Vec<SampleGroup> = batch.iter().map(|&(g, _)| g).collect();
            let start = Instant::now();
            let source = LevelRays {
                lattice: &self.lattice,
                level,
            };
            let ostc = self.ostc.as_ref();
            let lattice = &self.lattice;
            let (colors, rays) = trace_groups_observed(shader, &source, &groups, |group| {
                ostc.map(|o| o.marker_in(Self::region_of(lattice, o.layout(), level, group)))
            });
            let ms = start.elapsed().as_secs_f64() * 1e3;
            let per_group = ms / groups.len() as f64;
            let lattice = self.lattice.clone();
            let store = &mut self.levels[level.index()];
            let last = lattice.last_slot_row(level);
            let mut owned_total = 0u64;
            for ((group, who), colors) in batch.iter().zip(&colors) {
                let (key, _, bit) = tile_key(group.col, group.row);
                let tile = store.tile_or_insert(key) as usize;
                store.traced[tile] |= 1u64 << bit;
                let mut owned = 0u64;
                for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                    let (_, sample, _) = tile_key(col, row);
                    store.colors[tile * TILE_SAMPLES + sample] = colors[lane];
                    // Beyond the poles there is no sample (and no ray).
                    owned += u64::from((0..=last).contains(&row));
                }
                owned_total += owned;
                out[*who].0 += owned;
                out[*who].2 += per_group;
            }
            // Rays by share of samples (groups differ only by masked lanes).
            let mut given = RayCounts::default();
            let batch_len = batch.len();
            let mut counts = vec![0usize; requests.len()];
            for &(_, who) in &batch {
                counts[who] += 1;
            }
            for (who, &n) in counts.iter().enumerate() {
                if n == 0 {
                    continue;
                }
                let share = |v: u64| v * n as u64 / batch_len as u64;
                let part = RayCounts {
                    primary: share(rays.primary),
                    shadow: share(rays.shadow),
                    reflection: share(rays.reflection),
                };
                given += part;
                out[who].1 += part;
            }
            if let Some(first) = counts.iter().position(|&n| n > 0) {
                out[first].1.primary += rays.primary - given.primary;
                out[first].1.shadow += rays.shadow - given.shadow;
                out[first].1.reflection += rays.reflection - given.reflection;
            }
            self.samples_traced += owned_total;
        }
        out
    }

    /// Pass 2: each pixel's colour from its samples. The samples under a
    /// run of neighbouring regions of one level are first copied into one
    /// dense window, so the filter reads plain arrays. A window per run
    /// rather than per region copies each row as one long run per owner
    /// instead of many runs of a few cache lines (about 18% off E2's
    /// gather). Filling windows is still about half of the gather: the
    /// loads of the owners' samples stall.
    fn gather(
        &self,
        pose: &ViewportPose,
        mapped: &Mapped,
        filter: Filter,
        linear: bool,
    ) -> (Option<Frame>, image::RgbImage) {
        let (w, h) = (pose.camera.width as usize, pose.camera.height as usize);
        let map = PixelMap::new(pose);
        let band = w * REGION as usize;
        let mut bytes = vec![0u8; w * h * 3];
        let mut pixels = if linear {
            vec![Vec3::ZERO; w * h]
        } else {
            Vec::new()
        };
        let mut pixel_bands: Vec<&mut [Vec3]> = if linear {
            pixels.chunks_mut(band).collect()
        } else {
            Vec::new()
        };
        pixel_bands.resize_with(h.div_ceil(REGION as usize), || &mut []);
        bytes
            .par_chunks_mut(band * 3)
            .zip(pixel_bands.into_par_iter())
            .enumerate()
            .for_each(|(band_index, (out, linear_out))| {
                let mut cache = TileCache::new();
                let mut window = Window::default();
                let mut colors = [Vec3::ZERO; (REGION * REGION) as usize];
                let srgb = srgb_table();
                let y0 = band_index * REGION as usize;
                let rows = (h - y0).min(REGION as usize);
                let regions = &mapped.regions[band_index * mapped.regions_x..][..mapped.regions_x];
                // Every region's coordinates first (region after region,
                // each row-major), for the boxes that decide the runs.
                let mut coords = vec![DVec2::NAN; w * rows];
                let spans: Vec<RegionSpan> = regions
                    .iter()
                    .enumerate()
                    .map(|(rx, region)| {
                        let x0 = rx * REGION as usize;
                        let cols = (w - x0).min(REGION as usize);
                        let coords = &mut coords[x0 * rows..(x0 + cols) * rows];
                        self.region_coords(
                            pose,
                            &map,
                            region.level,
                            region.grid.as_ref(),
                            (x0 as u32, y0 as u32),
                            cols,
                            coords,
                        );
                        RegionSpan::new(filter, region.level, cols, rows, coords)
                    })
                    .collect();
                let mut rx = 0;
                while rx < spans.len() {
                    let first = &spans[rx];
                    let mut end = rx + 1;
                    if let Some(mut joined) = first.window.filter(|_| !first.direct) {
                        let mut area = joined.area();
                        while let Some(next) = spans.get(end).filter(|n| n.level == first.level) {
                            let Some(b) = next.window.filter(|_| !next.direct) else {
                                break;
                            };
                            let union = joined.union(&b);
                            // A rotated view's band runs diagonally: its
                            // box would copy far more than its regions read.
                            if union.area() * 4 > (area + b.area()) * 5 {
                                break;
                            }
                            (joined, area) = (union, area + b.area());
                            end += 1;
                        }
                        self.fill_window(&mut cache, first.level, &joined, &mut window);
                    }
                    for (rx, span) in spans.iter().enumerate().take(end).skip(rx) {
                        let x0 = rx * REGION as usize;
                        let cols = span.cols;
                        let region_coords = &coords[x0 * rows..(x0 + cols) * rows];
                        let colors = &mut colors[..cols * rows];
                        match span.window {
                            None => colors.fill(Vec3::ZERO),
                            Some(_) if span.direct => {
                                for (slot, c) in colors.iter_mut().zip(region_coords) {
                                    *slot = if c.x.is_nan() {
                                        Vec3::ZERO
                                    } else {
                                        self.filter(&mut cache, span.level, filter, c.x, c.y)
                                    };
                                }
                            }
                            Some(_) => gather_region(&window, filter, region_coords, colors),
                        }
                        // Whole region rows at once: no per-pixel index checks.
                        for (j, line) in colors.chunks_exact(cols).enumerate() {
                            let p = j * w + x0;
                            for (byte, c) in
                                out[p * 3..(p + cols) * 3].chunks_exact_mut(3).zip(line)
                            {
                                byte[0] = srgb.encode(c.x);
                                byte[1] = srgb.encode(c.y);
                                byte[2] = srgb.encode(c.z);
                            }
                            if let Some(slots) = linear_out.get_mut(p..p + cols) {
                                slots.copy_from_slice(line);
                            }
                        }
                    }
                    rx = end;
                }
            });
        let image =
            image::RgbImage::from_raw(w as u32, h as u32, bytes).expect("three bytes per pixel");
        let frame = linear.then_some(Frame {
            width: w as u32,
            height: h as u32,
            pixels,
        });
        (frame, image)
    }

    /// Copies the samples of `level` in `bounds` (rows clamped to the
    /// lattice) into `window`.
    fn fill_window(
        &self,
        cache: &mut TileCache,
        level: Level,
        bounds: &SampleBox,
        window: &mut Window,
    ) {
        let (wd, ht) = (bounds.width(), bounds.height());
        window.col = bounds.c0;
        window.row = bounds.r0;
        window.width = wd;
        // No clearing: copy_row writes every entry of a row (the owners'
        // positions tile it), and a band's windows are up to ~1 MB.
        window.samples.resize(wd * ht, Vec3::ZERO);
        let last_row = self.lattice.last_row(level.y);
        for (j, line) in window.samples.chunks_mut(wd).enumerate() {
            let row = (bounds.r0 + j as i64).clamp(0, last_row);
            self.copy_row(cache, level, bounds.c0, row, line);
        }
    }

    /// Samples (col.., row) of `level` whichever level owns them (black
    /// where nothing was traced). The row belongs to one elevation level;
    /// along it, each coarser azimuth level owns every 2^k-th sample, so
    /// each owner's slots go straight into `out` at their stride.
    fn copy_row(&self, cache: &mut TileCache, level: Level, col: i64, row: i64, out: &mut [Vec3]) {
        let sy = row.trailing_zeros().min(level.y);
        let oy = level.y - sy;
        let slot_row = (row >> sy) >> u32::from(oy > 0);
        let n = out.len() as i64;
        for ox in 0..=level.x {
            // Owned by ox: multiples of 2^level.x for ox = 0, else the odd
            // multiples of 2^sx.
            let sx = level.x - ox;
            let (period, offset) = if ox == 0 {
                (1i64 << level.x, 0)
            } else {
                (1i64 << (sx + 1), 1i64 << sx)
            };
            let first = col + (offset - col).rem_euclid(period);
            if first - col >= n {
                continue;
            }
            let slot = (first >> sx) >> u32::from(ox > 0);
            let owner = Level::new(ox, oy);
            let out = &mut out[(first - col) as usize..];
            self.copy_run(cache, owner, slot, slot_row, out, period as usize);
        }
    }

    /// The slots (col.., row) of `level` as its tiles hold them, into every
    /// `stride`th entry of `out` (black where no tile is), in runs. A
    /// window's rows come in pairs per tile row and span a tile or two:
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
        let store = &self.levels[level.index()];
        let columns = self.lattice.slot_columns(level);
        let count = out.len().div_ceil(stride);
        let mut i = 0;
        while i < count {
            let wc = wrap(col + i as i64, columns);
            let (key, sample, _) = tile_key(wc, row);
            let run = (count - i)
                .min((TILE_COLS - (wc & (TILE_COLS - 1))) as usize)
                .min((columns - wc) as usize);
            let tile = cache.tile(store, level, key);
            let source = (tile != u32::MAX).then(|| {
                let start = tile as usize * TILE_SAMPLES + sample;
                &store.colors[start..start + run]
            });
            match (source, stride) {
                (None, 1) => out[i..i + run].fill(Vec3::ZERO),
                (Some(source), 1) => out[i..i + run].copy_from_slice(source),
                // Chunks rather than step_by, whose remaining-length
                // arithmetic (a division by 12-byte elements) cost more
                // than the copy.
                (None, _) => {
                    for chunk in out[i * stride..].chunks_mut(stride).take(run) {
                        chunk[0] = Vec3::ZERO;
                    }
                }
                (Some(source), _) => {
                    for (chunk, &sample) in out[i * stride..].chunks_mut(stride).zip(source) {
                        chunk[0] = sample;
                    }
                }
            }
            i += run;
        }
    }

    #[inline(always)]
    fn filter(&self, cache: &mut TileCache, level: Level, filter: Filter, x: f64, y: f64) -> Vec3 {
        let ((c, fx), (r, fy)) = (filter_split(filter, x), filter_split(filter, y));
        let (c, r) = (c as i64, r as i64);
        match filter {
            Filter::Nearest => self.read(cache, level, c, r),
            Filter::Box => {
                (self.read(cache, level, c, r)
                    + self.read(cache, level, c + 1, r)
                    + self.read(cache, level, c, r + 1)
                    + self.read(cache, level, c + 1, r + 1))
                    * 0.25
            }
            Filter::Bilinear => bilinear(
                [
                    self.read(cache, level, c, r),
                    self.read(cache, level, c + 1, r),
                    self.read(cache, level, c, r + 1),
                    self.read(cache, level, c + 1, r + 1),
                ],
                fx as f32,
                fy as f32,
            ),
        }
    }

    /// Renders every viewport of a frame: maps their pixels, traces the
    /// null samples they touch in one batch, and resamples.
    pub fn render(
        &mut self,
        shader: &Shader,
        poses: &[ViewportPose],
        knobs: &RsvpKnobs,
        linear: bool,
    ) -> Vec<ViewportFrame> {
        let mut mapped = Vec::with_capacity(poses.len());
        let mut map_ms = Vec::with_capacity(poses.len());
        for pose in poses {
            let start = Instant::now();
            mapped.push(self.map(pose, knobs));
            map_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let requests: Vec<Vec<(Level, SampleGroup)>> = mapped
            .iter_mut()
            .map(|m| std::mem::take(&mut m.missing))
            .collect();
        let traced = self.trace(shader, &requests);
        poses
            .iter()
            .zip(&mapped)
            .zip(traced.into_iter().zip(map_ms))
            .map(|((pose, mapped), ((samples, rays, trace_ms), map_ms))| {
                let start = Instant::now();
                let (frame, image) = self.gather(pose, mapped, knobs.filter, linear);
                let gather_ms = start.elapsed().as_secs_f64() * 1e3;
                let levels = mapped.regions.iter().fold((u32::MAX, 0), |(lo, hi), r| {
                    (lo.min(r.level.finest()), hi.max(r.level.finest()))
                });
                ViewportFrame {
                    frame,
                    image,
                    samples_traced: samples,
                    rays,
                    map_ms,
                    trace_ms,
                    gather_ms,
                    levels,
                }
            })
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
        let extra = i64::from(knobs.filter != Filter::Nearest);
        let mut coords = Vec::new();
        for (index, region) in mapped.regions.iter().enumerate() {
            let (x0, y0) = (
                (index % mapped.regions_x) as u32 * REGION,
                (index / mapped.regions_x) as u32 * REGION,
            );
            let (cols, rows) = ((w - x0).min(REGION), (h - y0).min(REGION));
            let level = region.level;
            let size = (cols as usize, rows as usize);
            let grid = region.grid.as_ref();
            let slots = nan_filled(&mut coords, size.0 * size.1);
            self.region_coords(pose, &map, level, grid, (x0, y0), size.0, slots);
            let last_row = self.lattice.last_row(level.y);
            for (k, c) in coords.iter().enumerate() {
                if c.x.is_nan() {
                    continue;
                }
                let (cx, ry) = filter_origin(knobs.filter, c.x, c.y);
                let fresh = (0..=extra).any(|dr| {
                    (0..=extra).any(|dc| {
                        let row = (ry + dr).clamp(0, last_row);
                        let (owner, col, row) = self.lattice.owner(level, cx + dc, row);
                        let group = SampleGroup::containing(col, row);
                        let group = SampleGroup {
                            col: wrap(group.col, self.lattice.slot_columns(owner)),
                            row: group.row,
                        };
                        self.fresh
                            .binary_search_by_key(&(owner, group.row, group.col), |&(l, g)| {
                                (l, g.row, g.col)
                            })
                            .is_ok()
                    })
                });
                if fresh {
                    let (x, y) = (x0 + (k % size.0) as u32, y0 + (k / size.0) as u32);
                    out.put_pixel(x, y, image::Rgb([0, 0, 0]));
                }
            }
        }
        out
    }

    /// The buffer at level 0 as seen by an equal-angle window around the
    /// camera's view (width x height samples, corner snapped): traced
    /// samples in colour, never-traced ones black (the paper's figure 5a).
    /// Where level 0 is null but a finer level traced inside the sample's
    /// cell, that sample shows, so zoomed regions appear solid.
    pub fn buffer_image(&self, camera: &Camera, width: u32, height: u32) -> image::RgbImage {
        let col0 = (camera.yaw / self.lattice.step - 0.5 * f64::from(width)).round() as i64;
        let row0 = ((FRAC_PI_2 - camera.pitch) / self.lattice.step - 0.5 * f64::from(height))
            .round() as i64;
        let srgb = srgb_table();
        // Coarser levels first: fewer halvings in all come first.
        let mut levels: Vec<Level> = (0..Level::COUNT)
            .filter(|&i| !self.levels[i].traced.is_empty())
            .map(Level::from_index)
            .collect();
        levels.sort_by_key(|l| (l.x + l.y, *l));
        image::RgbImage::from_fn(width, height, |x, y| {
            let (c, r) = (col0 + i64::from(x), row0 + i64::from(y));
            let colour = levels.iter().find_map(|&level| {
                // The first sample of the cell this level owns.
                let (col, row) = self.lattice.slot_position(
                    level,
                    c << level.x.saturating_sub(1),
                    r << level.y.saturating_sub(1),
                );
                self.sample(level, col, row)
            });
            image::Rgb(colour.map_or([0; 3], |c| c.to_array().map(|v| srgb.encode(v))))
        })
    }
}

/// `v` as `len` NaN coordinates, reusing its allocation.
fn nan_filled(v: &mut Vec<DVec2>, len: usize) -> &mut [DVec2] {
    v.clear();
    v.resize(len, DVec2::NAN);
    v
}

/// Samples of one level copied into a dense row-major array, `width`
/// wide, its first entry the sample (col, row).
#[derive(Default)]
struct Window {
    col: i64,
    row: i64,
    width: usize,
    samples: Vec<Vec3>,
}

/// The samples (c0..=c1, r0..=r1) of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SampleBox {
    c0: i64,
    r0: i64,
    c1: i64,
    r1: i64,
}

impl SampleBox {
    fn width(&self) -> usize {
        (self.c1 - self.c0 + 1) as usize
    }

    fn height(&self) -> usize {
        (self.r1 - self.r0 + 1) as usize
    }

    fn area(&self) -> usize {
        self.width() * self.height()
    }

    fn union(&self, other: &SampleBox) -> SampleBox {
        SampleBox {
            c0: self.c0.min(other.c0),
            r0: self.r0.min(other.r0),
            c1: self.c1.max(other.c1),
            r1: self.r1.max(other.r1),
        }
    }
}

/// What pass 2 needs to know of a region before reading its samples.
struct RegionSpan {
    level: Level,
    cols: usize,
    /// The samples its filter reads; None: no pixel has a ray.
    window: Option<SampleBox>,
    /// Zoomed far out: a window would copy far more samples than the
    /// region's pixels read, so each pixel reads its own.
    direct: bool,
}

impl RegionSpan {
    fn new(filter: Filter, level: Level, cols: usize, rows: usize, coords: &[DVec2]) -> Self {
        // Filter origins grow with the coordinates: the window spans the
        // origins of the coordinates' box (min and max skip NaN).
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for c in coords {
            lo = lo.min(*c);
            hi = hi.max(*c);
        }
        let window = (lo.x <= hi.x).then(|| {
            let (c0, r0) = filter_origin(filter, lo.x, lo.y);
            let (c1, r1) = filter_origin(filter, hi.x, hi.y);
            SampleBox {
                c0,
                r0,
                c1: c1 + 1,
                r1: r1 + 1,
            }
        });
        let direct = window.is_some_and(|b| b.area() > 16 * cols * rows);
        RegionSpan {
            level,
            cols,
            window,
            direct,
        }
    }
}

/// Filters one region's pixels (`coords`: their lattice coordinates at the
/// window's level, NaN for no ray) from `window`, which holds every sample
/// they read, into `out` (`coords`' length).
fn gather_region(window: &Window, filter: Filter, coords: &[DVec2], out: &mut [Vec3]) {
    let wd = window.width;
    let samples = &window.samples;
    // Window index and weights of every pixel first, in straight-line f64
    // code (exact: whole numbers and multiples of 2^-16) that vectorises;
    // NaN pixels get index 0 and are blacked out last.
    const N: usize = (REGION * REGION) as usize;
    let (mut index, mut wx, mut wy) = ([0u32; N], [0f32; N], [0f32; N]);
    let (c0f, r0f, wdf) = (window.col as f64, window.row as f64, wd as f64);
    let mut has_nan = false;
    for (((c, k), fx), fy) in coords.iter().zip(&mut index).zip(&mut wx).zip(&mut wy) {
        has_nan |= c.x.is_nan();
        let (ox, x) = filter_split(filter, c.x);
        let (oy, y) = filter_split(filter, c.y);
        *k = ((oy - r0f) * wdf + (ox - c0f)) as u32;
        *fx = x as f32;
        *fy = y as f32;
    }
    let n = coords.len();
    let (index, wx, wy) = (&index[..n], &wx[..n], &wy[..n]);
    // One loop per filter, without branches inside.
    match filter {
        Filter::Nearest => {
            for (slot, &k) in out.iter_mut().zip(index) {
                *slot = samples[k as usize];
            }
        }
        Filter::Box => {
            for (slot, &k) in out.iter_mut().zip(index) {
                let k = k as usize;
                let (top, bottom) = (&samples[k..k + 2], &samples[k + wd..k + wd + 2]);
                *slot = (top[0] + top[1] + bottom[0] + bottom[1]) * 0.25;
            }
        }
        Filter::Bilinear => {
            for (((slot, &k), &fx), &fy) in out.iter_mut().zip(index).zip(wx).zip(wy) {
                let k = k as usize;
                let (top, bottom) = (&samples[k..k + 2], &samples[k + wd..k + wd + 2]);
                *slot = bilinear([top[0], top[1], bottom[0], bottom[1]], fx, fy);
            }
        }
    }
    if has_nan {
        for (slot, c) in out.iter_mut().zip(coords) {
            if c.x.is_nan() {
                *slot = Vec3::ZERO;
            }
        }
    }
}

/// Weighted by distance. A zero weight adds an exact +0 (samples are
/// finite and not negative), so a pixel exactly on a sample shows it bit for
/// bit; no branches, so the loop over a region's pixels stays straight.
#[inline(always)]
fn bilinear(s: [Vec3; 4], fx: f32, fy: f32) -> Vec3 {
    let (gx, gy) = (1.0 - fx, 1.0 - fy);
    s[0] * (gx * gy) + s[1] * (fx * gy) + s[2] * (gx * fy) + s[3] * (fx * fy)
}

/// How densely a region's pixels lie along each lattice axis: the most
/// pixels per level-0 sample step, over the pixels measured.
#[derive(Clone, Copy, Debug, Default)]
struct SampleDensity {
    x: f64,
    y: f64,
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
    /// axis, with the knobs' bias.
    fn level(&self, knobs: &RsvpKnobs) -> Level {
        let axis = |pixels_per_step: f64| {
            if !(pixels_per_step.is_finite() && pixels_per_step > 0.0) {
                return 0;
            }
            // A hair of tolerance: exactly one sample per pixel, up to
            // rounding, needs no finer level.
            let wanted = ((knobs.oversample * pixels_per_step).log2() - 1e-6).ceil() as i64
                + i64::from(knobs.level_bias)
                + i64::from(knobs.filter == Filter::Box);
            wanted.clamp(0, i64::from(MAX_LEVEL)) as u32
        };
        Level::new(axis(self.x), axis(self.y))
    }
}

/// Level-0 lattice coordinates times this are `level`'s (exact: powers of
/// two).
fn level_scale(level: Level) -> DVec2 {
    DVec2::new(f64::from(1u32 << level.x), f64::from(1u32 << level.y))
}

/// Sub-sample steps per sample on the filter's grid.
const FRACTION_ONE: f64 = 65536.0;

/// A lattice coordinate on the filter's grid (rounded to 2^-16 of a
/// sample): the sample the filter starts from (the one below for bilinear
/// and box, the nearest for nearest) and the fraction past it. Every step
/// is exact in f64, so pass 1 (which samples to trace) and pass 2 (which to
/// read) always agree; a pixel within 2^-17 of a sample shows that sample
/// bit for bit.
#[inline(always)]
fn filter_split(filter: Filter, x: f64) -> (f64, f64) {
    let q = (x * FRACTION_ONE + 0.5).floor();
    let q = match filter {
        Filter::Nearest => q + 0.5 * FRACTION_ONE,
        Filter::Bilinear | Filter::Box => q,
    };
    let origin = (q * (1.0 / FRACTION_ONE)).floor();
    (origin, (q - origin * FRACTION_ONE) * (1.0 / FRACTION_ONE))
}

/// The sample a filter starts from (top-left for bilinear and box).
#[inline]
fn filter_origin(filter: Filter, x: f64, y: f64) -> (i64, i64) {
    (
        filter_split(filter, x).0 as i64,
        filter_split(filter, y).0 as i64,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper camera's size and field of view, level, one unit up.
    fn camera(projection: Projection) -> Camera {
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

    fn lattice() -> SampleLattice {
        SampleLattice::for_camera(&camera(Projection::EqualAngle))
    }

    #[test]
    fn fast_atan2_is_far_below_a_sample() {
        let mut rng = crate::rng::SplitMix64(7);
        let mut worst = 0.0f64;
        for _ in 0..200_000 {
            let y = f64::from(rng.range(-10.0, 10.0)) * f64::from(rng.unit()).powi(3);
            let x = f64::from(rng.range(-10.0, 10.0));
            worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
        }
        for (y, x) in [
            (0.0, 1.0),
            (1.0, 0.0),
            (0.0, -1.0),
            (-1.0, 0.0),
            (1.0, 1.0),
            (1e-300, 1.0),
            (1.0, 1e-300),
        ] {
            worst = worst.max((fast_atan2(y, x) - f64::atan2(y, x)).abs());
        }
        assert!(worst < 1e-12, "worst error {worst:e}");
        // A millionth of a sample at the finest level.
        assert!(worst < lattice().step(MAX_LEVEL) * 1e-6);
    }

    #[test]
    fn levels_nest_bit_for_bit() {
        let lattice = lattice();
        assert_eq!(lattice.columns_per_turn, 2304);
        let levels = [(1, 1), (1, 0), (0, 3), (5, 2), (MAX_LEVEL, MAX_LEVEL)];
        for (col, row) in [(0, 0), (5, 7), (2303, 1152), (-1, 100), (1234, 600)] {
            let coarse = lattice.direction(Level::default(), col, row);
            for (x, y) in levels {
                let level = Level::new(x, y);
                let fine = lattice.direction(level, col << x, row << y);
                assert_eq!(
                    coarse.map(|d| d.to_array().map(f64::to_bits)),
                    fine.map(|d| d.to_array().map(f64::to_bits)),
                    "({col}, {row}) at level {level}"
                );
                assert_eq!(
                    lattice.owner(level, col << x, row << y),
                    (Level::default(), lattice.wrap_column(0, col), row)
                );
            }
        }
        // Column 6 of azimuth level 2 is column 3 of level 1 (its slot 1);
        // row 4 of elevation level 2 is row 1 of level 0.
        assert_eq!(
            lattice.owner(Level::square(2), 6, 4),
            (Level::new(1, 0), 1, 1)
        );
        assert_eq!(
            lattice.owner(Level::square(2), 6, 5),
            (Level::new(1, 2), 1, 2)
        );
        assert_eq!(lattice.last_row(0), 1152);
        assert_eq!(lattice.direction(Level::default(), 0, 1153), None);
    }

    #[test]
    fn slots_are_the_samples_a_level_owns() {
        let lattice = lattice();
        for (x, y) in [(0, 0), (1, 0), (0, 1), (2, 3), (7, 7)] {
            let level = Level::new(x, y);
            for (col, row) in [(0, 0), (1, 2), (5, 9), (1151, 7)] {
                let (c, r) = lattice.slot_position(level, col, row);
                assert_eq!(lattice.owner(level, c, r), (level, col, row), "{level}");
            }
            // A group of slots is eight rays, the same lane by lane as one
            // by one.
            let source = LevelRays {
                lattice: &lattice,
                level,
            };
            let group = SampleGroup { col: 8, row: 6 };
            let (packet, mask) = source.primary_group(group);
            assert_eq!(mask, 0xff, "{level}");
            for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                let ray = source.primary(col, row).unwrap();
                assert_eq!(
                    ray.dir.to_array().map(f32::to_bits),
                    packet[lane].dir.to_array().map(f32::to_bits)
                );
            }
        }
    }

    #[test]
    fn transforms_invert_and_reject_bad_input() {
        let t = ViewTransform {
            zoom: 3.0,
            rotate: 0.4,
            shear: [0.2, -0.1],
            translate: [5.0, -2.0],
        };
        t.validate().unwrap();
        let m = t.matrix();
        assert!((m * m.inverse() - DMat2::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|v| v.abs() < 1e-12));
        let bad = |t: ViewTransform| t.validate().unwrap_err().field;
        assert_eq!(bad(ViewTransform { zoom: 0.0, ..t }), "zoom");
        assert_eq!(bad(ViewTransform { zoom: 1001.0, ..t }), "zoom");
        assert_eq!(bad(ViewTransform { zoom: 0.000_9, ..t }), "zoom");
        assert_eq!(
            bad(ViewTransform {
                shear: [2.0, 0.5],
                ..t
            }),
            "shear"
        );
        assert_eq!(
            bad(ViewTransform {
                rotate: f64::NAN,
                ..t
            }),
            "rotate"
        );
        ViewTransform { zoom: 1e-3, ..t }.validate().unwrap();
        ViewTransform { zoom: 1e3, ..t }.validate().unwrap();
        // Zoom interpolates at a steady rate.
        let a = ViewTransform { zoom: 1.0, ..t };
        let b = ViewTransform { zoom: 4.0, ..t };
        assert!((a.lerp(&b, 0.5).zoom - 2.0).abs() < 1e-12);
    }

    #[test]
    fn fast_mapping_matches_the_exact_one() {
        let lattice = lattice();
        let base = Camera {
            projection: Projection::Perspective,
            position: DVec3::ZERO,
            yaw: 3.0,
            pitch: -0.2,
            fov: 100f64.to_radians(),
            width: 64,
            height: 48,
        };
        for projection in [
            Projection::Perspective,
            Projection::EqualAngle,
            Projection::Fisheye,
        ] {
            let pose = ViewportPose::new(
                Camera {
                    projection,
                    ..base.clone()
                },
                ViewTransform {
                    zoom: 1.7,
                    rotate: 0.3,
                    shear: [0.1, 0.0],
                    translate: [3.0, 1.0],
                },
            );
            let map = PixelMap::new(&pose);
            for (x, y) in [(0u32, 0u32), (63, 47), (31, 20), (5, 40)] {
                let (az, el) = map.angles(&pose, x, y).unwrap();
                let fast = lattice.coords(pose.camera.yaw + az, el);
                let exact = pose
                    .lattice_coords(&lattice, DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
                    .unwrap();
                assert!(
                    (fast.0 - exact.0).abs() < 1e-6 && (fast.1 - exact.1).abs() < 1e-6,
                    "{projection} ({x}, {y}): {fast:?} vs {exact:?}"
                );
                // And the exact one round-trips through the camera.
                let d = pose
                    .direction(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
                    .unwrap();
                let back = pose.camera.project(d).unwrap();
                let want = pose.base_point(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5));
                assert!((back - want).length() < 1e-6);
            }
        }
    }

    #[test]
    fn interpolated_regions_stay_within_their_tolerance() {
        let buffer = SampleBuffer::new(lattice());
        let knobs = RsvpKnobs::default();
        let base = Camera {
            pitch: -9f64.to_radians(),
            ..camera(Projection::Perspective)
        };
        let transform = |zoom, rotate, shear| ViewTransform {
            zoom,
            rotate,
            shear,
            translate: [7.0, -3.0],
        };
        let cases = [
            // E2's ends, then rotation and shear, a view straight down
            // (the pole), a view wider than a turn (the back seam) and an
            // equal-angle viewport.
            (base.clone(), transform(1.0, 0.0, [0.0, 0.0])),
            (base.clone(), transform(2.5557, 0.0, [0.0, 0.0])),
            (base.clone(), transform(1.7, 0.5, [0.2, -0.1])),
            (
                Camera {
                    pitch: -89f64.to_radians(),
                    ..base.clone()
                },
                transform(1.0, 0.0, [0.0, 0.0]),
            ),
            (base.clone(), transform(0.01, 0.0, [0.0, 0.0])),
            (
                Camera {
                    projection: Projection::EqualAngle,
                    ..base.clone()
                },
                transform(3.0, 0.2, [0.0, 0.0]),
            ),
        ];
        let mut interpolated = [0usize; 6];
        // Regions whose grid level equals region_level's.
        let mut levels = [0usize; 6];
        for (case, (camera, transform)) in cases.into_iter().enumerate() {
            let pose = ViewportPose::new(camera, transform);
            let map = PixelMap::new(&pose);
            let (mut exact, mut fast) = (Vec::new(), Vec::new());
            for y0 in (0..pose.camera.height).step_by(REGION as usize) {
                for x0 in (0..pose.camera.width).step_by(REGION as usize) {
                    let Some((level, grid)) = buffer.region_grid(&pose, &map, &knobs, x0, y0)
                    else {
                        continue;
                    };
                    let chosen = buffer.region_level(&pose, &map, &knobs, x0, y0);
                    levels[case] += usize::from(level == chosen);
                    interpolated[case] += 1;
                    let size = (
                        (pose.camera.width - x0).min(REGION) as usize,
                        (pose.camera.height - y0).min(REGION) as usize,
                    );
                    let at = (x0, y0);
                    let n = size.0 * size.1;
                    let exact_out = nan_filled(&mut exact, n);
                    buffer.region_coords(&pose, &map, level, None, at, size.0, exact_out);
                    let fast_out = nan_filled(&mut fast, n);
                    buffer.region_coords(&pose, &map, level, Some(&grid), at, size.0, fast_out);
                    for (e, f) in exact.iter().zip(&fast) {
                        let miss = (*e - *f).abs().max_element();
                        assert!(
                            miss <= 1.25 * GRID_TOLERANCE,
                            "case {case}, region ({x0}, {y0}) at level {level}: {e} vs {f}"
                        );
                    }
                }
            }
        }
        // 40 x 30 regions: the smooth views interpolate nearly everywhere.
        assert_eq!(interpolated[0], 1200, "{interpolated:?}");
        assert_eq!(interpolated[1], 1200, "{interpolated:?}");
        // Near the pole some regions bend too much; zoomed far out (a region
        // spans many degrees) nearly none fit: only a few where azimuth
        // saturates at +-90 degrees and elevation keeps a coarse level.
        assert!((1..1200).contains(&interpolated[3]), "{interpolated:?}");
        assert!(interpolated[4] <= 12, "{interpolated:?}");
        assert_eq!(interpolated[5], 1200, "{interpolated:?}");
        // The grid's cells measure the footprint a few pixels from where
        // region_level does: a level may differ only where the footprint
        // sits on a threshold.
        for (case, (&same, &all)) in levels.iter().zip(&interpolated).enumerate() {
            assert!(
                same * 100 >= all * 97,
                "case {case}: {levels:?} of {interpolated:?}"
            );
        }
    }

    #[test]
    fn a_wide_perspective_viewport_needs_finer_levels_at_its_edges() {
        let lattice = lattice();
        let buffer = SampleBuffer::new(lattice);
        let pose = ViewportPose::new(camera(Projection::Perspective), ViewTransform::default());
        let knobs = RsvpKnobs::default();
        let map = PixelMap::new(&pose);
        let level = |x0| buffer.region_level(&pose, &map, &knobs, x0, 232);
        assert_eq!(level(312), Level::new(0, 0));
        // Perspective squeezes azimuth first: a third of the way out only
        // columns need the finer level, at the edge rows too.
        assert_eq!(level(112), Level::new(1, 0));
        assert_eq!(level(0), Level::new(1, 1));
        let zoomed = ViewportPose::new(
            pose.camera.clone(),
            ViewTransform {
                zoom: 1000.0,
                ..ViewTransform::default()
            },
        );
        let level = buffer.region_level(&zoomed, &PixelMap::new(&zoomed), &knobs, 312, 232);
        assert!((10..=11).contains(&level.x), "{level}");
        assert!((10..=11).contains(&level.y), "{level}");
    }
}
