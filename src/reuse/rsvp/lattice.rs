//! The equal-angle sample lattice pyramid: levels, sample directions,
//! which level owns a sample, and the rays of a level's own samples.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};
use std::sync::OnceLock;

use glam::{DVec2, DVec3};

use crate::camera::Camera;
use crate::camera::ViewportPose;
use crate::ray::{LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::render::{PrimaryRays, SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};
use crate::shade::PixelStrata;

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
use super::{COARSEST_LEVEL, MAX_LEVEL};

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
/// step halved `y` times (doubled, where negative: coarser than the
/// camera's, for zoomed-out views). Levels refine each axis on its own: the
/// edges of a wide perspective view squeeze azimuth far more than
/// elevation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Level {
    pub x: i32,
    pub y: i32,
}

/// Levels on each axis, [`COARSEST_LEVEL`] to [`MAX_LEVEL`].
const LEVELS_PER_AXIS: usize = (MAX_LEVEL - COARSEST_LEVEL + 1) as usize;

impl Level {
    /// Every level pair, for per-level tables.
    pub const COUNT: usize = LEVELS_PER_AXIS * LEVELS_PER_AXIS;

    pub const fn new(x: i32, y: i32) -> Level {
        Level { x, y }
    }

    /// The same refinement on both axes.
    pub const fn square(k: i32) -> Level {
        Level { x: k, y: k }
    }

    /// Dense and in the order of the levels (by `x`, then `y`).
    pub fn index(self) -> usize {
        axis_index(self.x) * LEVELS_PER_AXIS + axis_index(self.y)
    }

    pub fn from_index(index: usize) -> Level {
        let axis = |i: usize| i as i32 + COARSEST_LEVEL;
        Level::new(axis(index / LEVELS_PER_AXIS), axis(index % LEVELS_PER_AXIS))
    }

    /// The finer of the two axes' levels.
    pub fn finest(self) -> i32 {
        self.x.max(self.y)
    }
}

/// Where level `k` of one axis sits in that axis's tables.
fn axis_index(k: i32) -> usize {
    debug_assert!((COARSEST_LEVEL..=MAX_LEVEL).contains(&k), "level {k}");
    (k - COARSEST_LEVEL) as usize
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

/// The corner-sampled equal-angle lattice pyramid around one eye: level 0
/// and the finer ones nest, and so do the coarser ones, each pyramid
/// apart (see [`SampleLattice::base`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SampleLattice {
    pub position: DVec3,
    /// Columns in a whole turn at level 0 (a multiple of the group width).
    pub columns_per_turn: i64,
    /// Angle per sample at level 0, radians.
    pub step: f64,
    /// The coarsest level on each axis: as many as [`COARSEST_LEVEL`]
    /// allows in elevation, and in azimuth as many as keep a whole number
    /// of groups in a turn.
    coarsest: Level,
    /// Per elevation level: the last row (a division saved on every sample
    /// read).
    last_rows: [i64; LEVELS_PER_AXIS],
    /// Sines and cosines of the coarse levels' angles, made on first use.
    angles: AngleTables,
}

/// Per level, the sine and cosine of every column's azimuth and every
/// row's elevation, exactly as `f64::sin_cos` gives them: what the libm
/// calls of [`LevelRays::primary_group`] would compute again for every
/// group. Only levels with at most [`TABLED_ANGLES`] columns are
/// tabled; finer ones, read by extreme zooms only, call libm.
#[derive(Clone, Default)]
struct AngleTables {
    azimuths: LevelAngles,
    elevations: LevelAngles,
}

/// Per level, its angles' sines and cosines, by column or row.
#[derive(Clone, Default)]
struct LevelAngles([OnceLock<Box<[SinCos]>>; LEVELS_PER_AXIS]);

/// `(sin, cos)` of one angle.
type SinCos = (f64, f64);

/// The most angles a level's table holds (1 MiB of pairs).
const TABLED_ANGLES: i64 = 1 << 16;

impl LevelAngles {
    /// `angle(i).sin_cos()`, from level `level`'s table of `count` angles
    /// when it is small enough to keep.
    fn sin_cos(&self, level: i32, count: i64, i: i64, angle: impl Fn(i64) -> f64) -> (f64, f64) {
        if count > TABLED_ANGLES || !(0..count).contains(&i) {
            return angle(i).sin_cos();
        }
        let table = self.0[axis_index(level)]
            .get_or_init(|| (0..count).map(|k| angle(k).sin_cos()).collect());
        table[i as usize]
    }
}

/// The tables follow from the lattice's other fields: they never make two
/// lattices differ.
impl PartialEq for AngleTables {
    fn eq(&self, _: &AngleTables) -> bool {
        true
    }
}

impl std::fmt::Debug for AngleTables {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("AngleTables")
    }
}

/// How far (relative) level 0's step may be moved from the camera's angle
/// per pixel so that coarser levels hold whole groups: a fifth of a percent,
/// no change a resampled view can show.
const COARSENING_NUDGE: f64 = 1.0 / 512.0;

impl SampleLattice {
    /// Level-0 coordinates of point `p` of viewport `pose`, by the exact
    /// functions (for level choice and tests).
    pub fn viewport_coords(&self, pose: &ViewportPose, p: DVec2) -> Option<(f64, f64)> {
        let d = pose.direction(p)?;
        let (s, c) = pose.camera.yaw.sin_cos();
        let (x, z) = (d.x * c + d.z * s, d.z * c - d.x * s);
        let (rel_az, el) = (x.atan2(-z), d.y.atan2(x.hypot(z)));
        Some(self.coords(pose.camera.yaw + rel_az, el))
    }

    /// Level 0 at the camera's angle per pixel, nudged so a whole turn
    /// holds whole groups (640 px over 100 degrees: 2304 columns), and
    /// where a nudge of at most [`COARSENING_NUDGE`] makes it so, whole
    /// groups of the coarser levels too: a camera whose turn does not
    /// halve into whole groups (16384 px over 100 degrees: 58982.4
    /// columns) would leave zoomed-out views only level 0's columns,
    /// many times finer than their pixels.
    pub fn for_camera(camera: &Camera) -> SampleLattice {
        let exact = TAU / camera.angle_step();
        let whole_groups = |halvings: i32| {
            let unit = f64::from(GROUP_WIDTH << halvings);
            (exact / unit).round().max(1.0) * unit
        };
        let columns_per_turn = (1..=-COARSEST_LEVEL)
            .rev()
            .map(whole_groups)
            .find(|&columns| (columns - exact).abs() <= exact * COARSENING_NUDGE)
            .unwrap_or_else(|| whole_groups(0));
        SampleLattice::new(camera.position, columns_per_turn as i64)
    }

    /// `columns_per_turn` (a multiple of the group width) columns at level 0.
    pub fn new(position: DVec3, columns_per_turn: i64) -> SampleLattice {
        let step = TAU / columns_per_turn as f64;
        let group = i64::from(GROUP_WIDTH);
        let coarser_x = (0..-COARSEST_LEVEL)
            .take_while(|&k| columns_per_turn % (group << (k + 1)) == 0)
            .count() as i32;
        let mut lattice = SampleLattice {
            position,
            columns_per_turn,
            step,
            coarsest: Level::new(-coarser_x, COARSEST_LEVEL),
            last_rows: [0; LEVELS_PER_AXIS],
            angles: AngleTables::default(),
        };
        lattice.last_rows = std::array::from_fn(|i| {
            let y = i as i32 + COARSEST_LEVEL;
            (PI / lattice.step(y)).floor() as i64
        });
        lattice
    }

    /// The coarsest level on each axis.
    pub fn coarsest(&self) -> Level {
        self.coarsest
    }

    /// The coarsest level of `level`'s pyramid on each axis: 0 for level 0
    /// and the finer ones, [`SampleLattice::coarsest`] for the coarser. A
    /// pyramid's coarsest level owns all its samples, each finer one the
    /// odd positions: the camera's level and the finer ones never read a
    /// coarser level's store (a frame that is not zoomed out checks and
    /// traces exactly what it would without them), and a sample of both
    /// pyramids is traced in each.
    pub fn base(&self, level: Level) -> Level {
        let axis = |k: i32, coarsest: i32| if k >= 0 { 0 } else { coarsest };
        Level::new(
            axis(level.x, self.coarsest.x),
            axis(level.y, self.coarsest.y),
        )
    }

    /// Angle per sample after `halvings` (negative: doublings); exact, a
    /// power-of-two scaling.
    pub fn step(&self, halvings: i32) -> f64 {
        if halvings >= 0 {
            self.step / f64::from(1u32 << halvings)
        } else {
            self.step * f64::from(1u32 << -halvings)
        }
    }

    /// Columns in a turn at azimuth level `x` (at least the coarsest).
    pub fn columns(&self, x: i32) -> i64 {
        if x >= 0 {
            self.columns_per_turn << x
        } else {
            self.columns_per_turn >> -x
        }
    }

    /// Last row at elevation level `y` (the south pole when the turn divides
    /// evenly).
    pub fn last_row(&self, y: i32) -> i64 {
        self.last_rows[axis_index(y)]
    }

    /// `col` brought into the turn at azimuth level `x`.
    pub fn wrap_column(&self, x: i32, col: i64) -> i64 {
        wrap(col, self.columns(x))
    }

    /// Sine and cosine of the azimuth of column `col` (in the turn) at
    /// azimuth level `x`.
    fn azimuth_sin_cos(&self, x: i32, col: i64) -> (f64, f64) {
        let step = self.step(x);
        self.angles
            .azimuths
            .sin_cos(x, self.columns(x), col, |c| c as f64 * step)
    }

    /// Sine and cosine of the elevation of row `row` at elevation level `y`.
    fn elevation_sin_cos(&self, y: i32, row: i64) -> (f64, f64) {
        let step = self.step(y);
        self.angles
            .elevations
            .sin_cos(y, self.last_row(y) + 1, row, |r| {
                FRAC_PI_2 - r as f64 * step
            })
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

    /// The coarsest level of its pyramid holding sample (col, row) of
    /// `level`, and the sample's slot there: its column and row among the
    /// samples that level owns (see [`SampleLattice::slot_position`]).
    pub fn owner(&self, level: Level, col: i64, row: i64) -> (Level, i64, i64) {
        let base = self.base(level);
        let col = self.wrap_column(level.x, col);
        let sx = col.trailing_zeros().min((level.x - base.x) as u32);
        let sy = row.trailing_zeros().min((level.y - base.y) as u32);
        let owner = Level::new(level.x - sx as i32, level.y - sy as i32);
        let (col, row) = (col >> sx, row >> sy);
        (
            owner,
            col >> u32::from(owner.x > base.x),
            row >> u32::from(owner.y > base.y),
        )
    }

    /// The (col, row) on `level` of its own slot (col, row): a level finer
    /// than its pyramid's coarsest on an axis owns the odd positions there
    /// (the even ones are the coarser level's), so its slots are dense and
    /// a 4x2 group of them is eight samples the level owns.
    pub fn slot_position(&self, level: Level, col: i64, row: i64) -> (i64, i64) {
        let base = self.base(level);
        let expand = |k: i32, base: i32, v: i64| if k > base { 2 * v + 1 } else { v };
        (expand(level.x, base.x, col), expand(level.y, base.y, row))
    }

    /// Slot columns in a turn at `level`.
    pub fn slot_columns(&self, level: Level) -> i64 {
        if level.x > self.base(level).x {
            self.columns(level.x - 1)
        } else {
            self.columns(level.x)
        }
    }

    /// Last slot row of `level`.
    pub fn last_slot_row(&self, level: Level) -> i64 {
        let last = self.last_row(level.y);
        if level.y > self.base(level).y {
            (last - 1) >> 1
        } else {
            last
        }
    }

    /// Continuous lattice coordinates of world (az, el) at level 0.
    pub(super) fn coords(&self, az: f64, el: f64) -> (f64, f64) {
        (az / self.step, (FRAC_PI_2 - el) / self.step)
    }
}

/// Along one axis of a level refined `k` times, the positions that level
/// `owner` (0..=k) of that axis owns are those congruent to `offset` modulo
/// `period`: level 0 every 2^k-th, a finer level the odd multiples of
/// 2^(k - owner) (as [`SampleLattice::owner`] decides by trailing zeros).
/// The period is a power of two: `x & (period - 1)` is `x.rem_euclid(period)`
/// without a division (two of them per run of marked samples cost pass 1
/// more than the rest of asking for the run's groups).
#[inline]
pub(super) fn owned_positions(k: u32, owner: u32) -> (i64, i64) {
    let shift = k - owner;
    if owner == 0 {
        (1 << k, 0)
    } else {
        (1 << (shift + 1), 1 << shift)
    }
}

/// Columns `from..=to` (in any turn of `columns`) as runs that stay within
/// one turn and one aligned `chunk` (a power of two: a tile, a block):
/// `each(first column in the turn, length)`, while it returns true;
/// whether it always did.
#[inline(always)]
pub(super) fn column_runs(
    from: i64,
    to: i64,
    columns: i64,
    chunk: i64,
    mut each: impl FnMut(i64, i64) -> bool,
) -> bool {
    let mut col = from;
    while col <= to {
        let wc = wrap(col, columns);
        let run = (to - col + 1)
            .min(chunk - (wc & (chunk - 1)))
            .min(columns - wc);
        if !each(wc, run) {
            return false;
        }
        col += run;
    }
    true
}

/// `v` modulo `n`, cheaply when it is at most a turn away.
#[inline(always)]
pub(super) fn wrap(v: i64, n: i64) -> i64 {
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
    /// per column and per row of the group rather than two per lane (libm
    /// calls per lane would be a large share of a steady frame), read from
    /// the lattice's tables where the level has them.
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        let (lattice, level) = (self.lattice, self.level);
        let origin = lattice.position.as_vec3();
        let az: [(f64, f64); GROUP_WIDTH as usize] = std::array::from_fn(|i| {
            let (col, _) = lattice.slot_position(level, group.col + i as i64, 0);
            lattice.azimuth_sin_cos(level.x, lattice.wrap_column(level.x, col))
        });
        let rows: [i64; GROUP_HEIGHT as usize] =
            std::array::from_fn(|j| lattice.slot_position(level, 0, group.row + j as i64).1);
        let el: [(f64, f64); GROUP_HEIGHT as usize] =
            std::array::from_fn(|j| lattice.elevation_sin_cos(level.y, rows[j]));
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

    /// Each sample stands at its place on the finest level, where every
    /// level's samples sit: a sample draws alike at every level and in
    /// both pyramids, and neighbouring samples of any level draw
    /// stratified (see `shade::PixelStrata`).
    fn draw_strata(&self, group: SampleGroup) -> Option<PixelStrata> {
        let (lattice, level) = (self.lattice, self.level);
        Some(PixelStrata::on_lattice(group.lane_samples().map(
            |(col, row)| {
                let (col, row) = lattice.slot_position(level, col, row);
                (
                    lattice.wrap_column(level.x, col) << (MAX_LEVEL - level.x),
                    row << (MAX_LEVEL - level.y),
                )
            },
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;
    use crate::reuse::rsvp::fixtures::*;

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
    fn a_camera_whose_turn_does_not_halve_still_gets_coarser_levels() {
        for width in [640, 320, 1920, 16384] {
            let camera = Camera {
                width,
                ..camera(Projection::EqualAngle)
            };
            let lattice = SampleLattice::for_camera(&camera);
            let nudge = lattice.step(0) / camera.angle_step() - 1.0;
            assert!(nudge.abs() <= COARSENING_NUDGE, "{width}: nudged {nudge}");
            // A view 25 times wider than a pixel of 16384 over 100 degrees
            // finds a level at least 16 times coarser.
            assert!(
                lattice.coarsest().x <= -4,
                "{width}: {:?}",
                lattice.coarsest()
            );
        }
        // 640 over 100 degrees stays exactly as before: 2304 columns.
        assert_eq!(lattice().columns_per_turn, 2304);
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
    fn coarser_levels_nest_with_level_0_and_own_their_samples_apart() {
        let lattice = lattice();
        // 2304 = 4 * 9 * 2^6: six halvings keep whole groups in a turn.
        assert_eq!(lattice.coarsest(), Level::new(-6, COARSEST_LEVEL));
        assert_eq!(lattice.columns(-6), 36);
        for (col, row) in [(0, 0), (5, 7), (35, 4), (-1, 3), (17, 4)] {
            for (x, y) in [(-1, -1), (-6, -8), (-3, -1), (-2, -5)] {
                let level = Level::new(x, y);
                let coarse = lattice.direction(level, col, row);
                let (c0, r0) = (col << -x, row << -y);
                let fine = lattice.direction(Level::default(), c0, r0);
                assert_eq!(
                    coarse.map(|d| d.to_array().map(f64::to_bits)),
                    fine.map(|d| d.to_array().map(f64::to_bits)),
                    "({col}, {row}) at level {level}"
                );
                // Level 0's own sample: never a coarser level's store.
                assert_eq!(lattice.owner(Level::default(), c0, r0).0, Level::default());
                // A coarser level's, within its pyramid.
                let (owner, c, r) = lattice.owner(level, col, row);
                assert!(owner.x < 0 && owner.x <= x && owner.y < 0 && owner.y <= y);
                let (sc, sr) = lattice.slot_position(owner, c, r);
                assert_eq!(
                    (sc << (x - owner.x), sr << (y - owner.y)),
                    (lattice.wrap_column(x, col), row),
                    "{level}"
                );
            }
        }
        // Column 8 of azimuth level -3 is column 1 of level -6, the
        // coarsest, which owns all its positions; row 4 of level -2 is
        // row 1 of level -4, its slot 0.
        assert_eq!(
            lattice.owner(Level::new(-3, -2), 8, 4),
            (Level::new(-6, -4), 1, 0)
        );
        // A level finer on one axis and coarser on the other.
        assert_eq!(
            lattice.owner(Level::new(2, -2), 6, 4),
            (Level::new(1, -4), 1, 0)
        );
        for index in 0..Level::COUNT {
            let level = Level::from_index(index);
            assert_eq!(level.index(), index);
        }
        assert_eq!(Level::from_index(0), Level::square(COARSEST_LEVEL));
    }

    #[test]
    fn slots_are_the_samples_a_level_owns() {
        let lattice = lattice();
        let levels = [
            (0, 0),
            (1, 0),
            (0, 1),
            (2, 3),
            (7, 7),
            (-6, -8),
            (-1, -1),
            (2, -3),
        ];
        for (x, y) in levels {
            let level = Level::new(x, y);
            let base = lattice.base(level);
            // Within the turn of the coarsest levels' 36 slot columns too.
            let last_col = lattice.slot_columns(level) - 1;
            for (col, row) in [(0, 0), (1, 2), (5, 9), (last_col, 3)] {
                let (c, r) = lattice.slot_position(level, col, row);
                assert_eq!(lattice.owner(level, c, r), (level, col, row), "{level}");
            }
            // A group of slots is eight rays, the same lane by lane as one
            // by one: inside the turn, wrapping round it, and at the south
            // pole (tabled angles on the coarse levels, libm on 7x7).
            let source = LevelRays {
                lattice: &lattice,
                level,
            };
            // Slot rows straddling the last row (slot v is row 2v + 1 on a
            // level finer than its pyramid's coarsest).
            let pole = if y == base.y {
                lattice.last_row(y)
            } else {
                lattice.last_row(y) / 2 - 1
            };
            // Level -8 has five rows.
            for group in [
                SampleGroup {
                    col: 8,
                    row: 6.min(pole - 2),
                },
                SampleGroup { col: -4, row: 2 },
                SampleGroup { col: 16, row: pole },
            ] {
                let (packet, mask) = source.primary_group(group);
                assert_eq!(mask == 0xff, group.row != pole, "{level} {group:?}");
                for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                    let ray = source.primary(col, row);
                    assert_eq!(mask >> lane & 1 == 1, ray.is_some(), "{level} {group:?}");
                    if let Some(ray) = ray {
                        assert_eq!(
                            ray.dir.to_array().map(f32::to_bits),
                            packet[lane].dir.to_array().map(f32::to_bits)
                        );
                    }
                }
            }
        }
    }
}
