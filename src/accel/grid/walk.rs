//! A uniform voxel grid's geometry ([`GridSpec`]) and the supercover walk of
//! a segment through it ([`VoxelWalk`]).
//!
//! The walk knows nothing about primitives: the grid intersector uses
//! [`GridSpec`] for its cells, and the OSTC bookkeeping walks its own grid to
//! mark the voxels each traced ray crossed.

use glam::{DVec3, Vec3};

use crate::geometry::Aabb;

/// A box cut into `resolution[0] x resolution[1] x resolution[2]` equal
/// voxels. Voxel `[i, j, k]` is the closed box
/// `bounds.min + [i, j, k] * cell .. bounds.min + [i + 1, j + 1, k + 1] * cell`
/// with `cell = bounds.extent() / resolution` (in exact arithmetic).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    pub bounds: Aabb,
    pub resolution: [u32; 3],
}

impl GridSpec {
    /// # Panics
    /// If `bounds` is not finite with `min < max` on every axis, or a
    /// resolution is zero.
    pub fn new(bounds: Aabb, resolution: [u32; 3]) -> GridSpec {
        let spec = GridSpec { bounds, resolution };
        assert!(
            spec.is_valid(),
            "grid needs finite bounds with min < max and a resolution of at least 1 per axis: {spec:?}"
        );
        spec
    }

    /// A grid over `bounds` with about `cells` voxels of near-cubic shape.
    /// Axes much thinner than the widest one (flat boxes) get one voxel,
    /// and are padded so every axis has `min < max`.
    pub fn with_cell_budget(bounds: Aabb, cells: f64) -> GridSpec {
        let bounds = padded(bounds);
        let extent = bounds.extent().as_dvec3().to_array();
        let widest = extent.iter().cloned().fold(0.0, f64::max);
        let thick: Vec<usize> = (0..3).filter(|&a| extent[a] > widest * 1e-3).collect();
        let volume: f64 = thick.iter().map(|&a| extent[a]).product();
        let per_unit = (cells.max(1.0) / volume).powf(1.0 / thick.len().max(1) as f64);
        let mut resolution = [1u32; 3];
        for &a in &thick {
            resolution[a] = (extent[a] * per_unit).round().clamp(1.0, MAX_RESOLUTION as f64) as u32;
        }
        GridSpec::new(bounds, resolution)
    }

    pub fn is_valid(&self) -> bool {
        self.bounds.is_finite()
            && self.bounds.min.cmplt(self.bounds.max).all()
            && self.resolution.iter().all(|&n| n >= 1)
    }

    pub fn voxel_count(&self) -> usize {
        self.resolution.iter().map(|&n| n as usize).product()
    }

    pub fn cell_size(&self) -> Vec3 {
        self.bounds.extent() / Vec3::from(self.resolution.map(|n| n as f32))
    }

    /// Index of a voxel in x-fastest order (`i + nx * (j + ny * k)`).
    pub fn linear_index(&self, voxel: [u32; 3]) -> usize {
        let [nx, ny, _] = self.resolution.map(|n| n as usize);
        voxel[0] as usize + nx * (voxel[1] as usize + ny * voxel[2] as usize)
    }

    pub fn voxel_bounds(&self, voxel: [u32; 3]) -> Aabb {
        let cell = self.cell_size();
        let lo = Vec3::from(voxel.map(|i| i as f32));
        Aabb {
            min: self.bounds.min + lo * cell,
            max: self.bounds.min + (lo + 1.0) * cell,
        }
    }

    /// The inclusive voxel range `[first, last]` of every voxel whose closed
    /// box meets the closed box `b`, or `None` if `b` misses the grid.
    /// Rounded outward: a box touching a voxel face includes that voxel.
    pub fn voxel_range(&self, b: &Aabb) -> Option<[[u32; 3]; 2]> {
        if b.is_empty() || b.min.is_nan() || b.max.is_nan() {
            return None;
        }
        let g = GridCoords::new(self);
        let mut first = [0u32; 3];
        let mut last = [0u32; 3];
        for axis in 0..3 {
            let lo = g.coord(axis, f64::from(b.min[axis]));
            let hi = g.coord(axis, f64::from(b.max[axis]));
            let (a, z) = g.index_range(axis, lo, hi)?;
            first[axis] = a as u32;
            last[axis] = z as u32;
        }
        Some([first, last])
    }

    /// The supercover walk of the segment `origin + t * dir`, `t` in
    /// `[t0, t1]`: see [`VoxelWalk`].
    pub fn walk(&self, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> VoxelWalk {
        VoxelWalk::new(self, origin, dir, t0, t1)
    }
}

/// The most voxels per axis [`GridSpec::with_cell_budget`] chooses.
pub const MAX_RESOLUTION: u32 = 1024;

/// Grows a box by a little on every side, relative to its size and its
/// distance from the origin, so flat boxes get a thickness and points on
/// the boundary are safely inside.
pub(crate) fn padded(b: Aabb) -> Aabb {
    let magnitude = b.min.abs().max(b.max.abs()).max_element();
    let pad = (b.extent().max_element() * 1e-5)
        .max(magnitude * 1e-6)
        .max(1e-30);
    Aabb {
        min: b.min - Vec3::splat(pad),
        max: b.max + Vec3::splat(pad),
    }
}

/// Calls `visit` for every voxel of the supercover walk of the segment
/// `origin + t * dir`, `t` in `[t0, t1]`, in order along the segment. See
/// [`VoxelWalk`] for the contract.
pub fn walk_segment(
    spec: &GridSpec,
    origin: Vec3,
    dir: Vec3,
    t0: f32,
    t1: f32,
    mut visit: impl FnMut([u32; 3]),
) {
    for voxel in VoxelWalk::new(spec, origin, dir, t0, t1) {
        visit(voxel);
    }
}

/// Relative slack of the walk, in voxels: voxels within this distance of the
/// segment count as touched (so rounding can only add voxels, never lose one).
pub const WALK_SLACK_VOXELS: f64 = 1e-6;

/// The supercover walk of a segment through a [`GridSpec`]: an iterator over
/// voxel coordinates `[i, j, k]`.
///
/// Contract, for the segment `S = { origin + t * dir : t0 <= t <= t1 }` (in
/// exact arithmetic on the given f32 values; `t1` may be infinite, e.g. "to
/// the grid exit" for a ray that misses everything):
/// - **Complete (supercover):** every voxel whose closed box meets `S` is
///   yielded, including all the voxels around an edge or a corner the
///   segment passes exactly through, and the voxels on both sides of a
///   voxel face the segment runs inside or starts on.
/// - **Tight:** every yielded voxel lies within [`WALK_SLACK_VOXELS`] of a
///   voxel size (per axis, plus 1e-12 relative to the coordinates, in voxel
///   units) of `S`; the slack only ever adds voxels.
/// - **Once, in order:** each voxel at most once, ordered by where `S`
///   enters it (voxels that `S` enters at the same point come in some order).
/// - **Robust:** direction components of 0.0 or -0.0 (axis-parallel
///   segments, or a zero direction: a point), origins on voxel planes or
///   outside the grid, segments that miss the grid (nothing is yielded) and
///   `t0 > t1` or NaN (nothing) are all fine.
///
/// Internally the walk runs in f64 in voxel units, nesting the three axes:
/// for each x-slab the segment crosses, the part of the segment inside it;
/// for each y-slab that part crosses, the smaller part; then the z range of
/// that. Closed intervals throughout, so touching counts.
#[derive(Clone, Debug)]
pub struct VoxelWalk {
    grid: GridCoords,
    /// Origin and direction in voxel units.
    g0: [f64; 3],
    d: [f64; 3],
    eps: f64,
    x: AxisLoop,
    y: AxisLoop,
    z: AxisLoop,
    /// The t-interval of the segment inside the grid, and of the part of it
    /// inside the current x-slab.
    clip: (f64, f64),
    tx: (f64, f64),
    /// The current x and y voxel index.
    i: i64,
    j: i64,
    level: Level,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Level {
    X,
    Y,
    Z,
    Done,
}

/// One axis of the nested loop: indices from `next` to `last` by `step`.
#[derive(Clone, Copy, Debug, Default)]
struct AxisLoop {
    next: i64,
    last: i64,
    step: i64,
}

impl AxisLoop {
    fn take(&mut self) -> Option<i64> {
        if self.step == 0 || (self.next - self.last) * self.step > 0 {
            return None;
        }
        let i = self.next;
        self.next += self.step;
        Some(i)
    }
}

/// The affine map from world coordinates to voxel units (voxel i spans [i, i+1]).
#[derive(Clone, Copy, Debug)]
struct GridCoords {
    min: DVec3,
    scale: DVec3,
    n: [i64; 3],
}

impl GridCoords {
    fn new(spec: &GridSpec) -> GridCoords {
        let n = spec.resolution.map(i64::from);
        let min = spec.bounds.min.as_dvec3();
        let extent = spec.bounds.max.as_dvec3() - min;
        GridCoords {
            min,
            scale: DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) / extent,
            n,
        }
    }

    fn coord(&self, axis: usize, x: f64) -> f64 {
        (x - self.min[axis]) * self.scale[axis]
    }

    /// Voxels whose closed span [i, i+1] meets the closed span [lo, hi],
    /// clamped to the grid; `None` if there are none.
    fn index_range(&self, axis: usize, lo: f64, hi: f64) -> Option<(i64, i64)> {
        let first = ((lo.ceil() - 1.0).max(0.0)).min(i64::MAX as f64) as i64;
        let last = (hi.floor().min((self.n[axis] - 1) as f64)).max(-1.0) as i64;
        (first <= last && lo <= hi).then_some((first, last))
    }
}

impl VoxelWalk {
    pub fn new(spec: &GridSpec, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> VoxelWalk {
        let grid = GridCoords::new(spec);
        let g0: [f64; 3] = std::array::from_fn(|a| grid.coord(a, f64::from(origin[a])));
        let d: [f64; 3] = std::array::from_fn(|a| f64::from(dir[a]) * grid.scale[a]);
        let mut walk = VoxelWalk {
            grid,
            g0,
            d,
            eps: 0.0,
            x: AxisLoop::default(),
            y: AxisLoop::default(),
            z: AxisLoop::default(),
            clip: (0.0, 0.0),
            tx: (0.0, 0.0),
            i: 0,
            j: 0,
            level: Level::Done,
        };
        let valid = spec.is_valid()
            && origin.is_finite()
            && dir.is_finite()
            && t0 <= t1
            && !t0.is_nan()
            && !t1.is_nan();
        if !valid {
            return walk;
        }
        let (t0, t1) = (f64::from(t0), f64::from(t1));
        let magnitude = (0..3)
            .map(|a| {
                let reach = [t0, t1]
                    .iter()
                    .map(|t| if d[a] == 0.0 { 0.0 } else { (t * d[a]).abs() })
                    .filter(|x| x.is_finite())
                    .fold(0.0, f64::max);
                g0[a].abs() + reach + grid.n[a] as f64
            })
            .fold(0.0, f64::max);
        walk.eps = WALK_SLACK_VOXELS + magnitude * 1e-12;
        // Clip to the (slightly grown) grid box, one slab per axis.
        let mut span = (t0, t1);
        for a in 0..3 {
            match walk.slab_interval(a, -walk.eps, grid.n[a] as f64 + walk.eps, span) {
                Some(s) => span = s,
                None => return walk,
            }
        }
        walk.clip = span;
        if let Some(x) = walk.axis_loop(0, span) {
            walk.x = x;
            walk.level = Level::X;
        }
        walk
    }

    /// The coordinate on `axis` at parameter `t` (exact for a zero direction
    /// component even when `t` is infinite).
    fn at(&self, axis: usize, t: f64) -> f64 {
        if self.d[axis] == 0.0 {
            self.g0[axis]
        } else {
            self.g0[axis] + t * self.d[axis]
        }
    }

    /// The part of `span` where the coordinate on `axis` lies in `[lo, hi]`.
    fn slab_interval(&self, axis: usize, lo: f64, hi: f64, span: (f64, f64)) -> Option<(f64, f64)> {
        let d = self.d[axis];
        let (a, b) = if d == 0.0 {
            if self.g0[axis] < lo || self.g0[axis] > hi {
                return None;
            }
            span
        } else {
            let ta = (lo - self.g0[axis]) / d;
            let tb = (hi - self.g0[axis]) / d;
            (span.0.max(ta.min(tb)), span.1.min(ta.max(tb)))
        };
        (a <= b).then_some((a, b))
    }

    /// The loop over the voxels of `axis` that the part `span` of the
    /// segment touches, in the direction of travel.
    fn axis_loop(&self, axis: usize, span: (f64, f64)) -> Option<AxisLoop> {
        let (p, q) = (self.at(axis, span.0), self.at(axis, span.1));
        let (first, last) =
            self.grid
                .index_range(axis, p.min(q) - self.eps, p.max(q) + self.eps)?;
        Some(if self.d[axis] < 0.0 {
            AxisLoop {
                next: last,
                last: first,
                step: -1,
            }
        } else {
            AxisLoop {
                next: first,
                last,
                step: 1,
            }
        })
    }

    fn voxel_span(&self, axis: usize, i: i64, span: (f64, f64)) -> Option<(f64, f64)> {
        self.slab_interval(axis, i as f64 - self.eps, (i + 1) as f64 + self.eps, span)
    }
}

impl Iterator for VoxelWalk {
    type Item = [u32; 3];

    fn next(&mut self) -> Option<[u32; 3]> {
        loop {
            match self.level {
                Level::Done => return None,
                Level::Z => match self.z.take() {
                    Some(k) => return Some([self.i as u32, self.j as u32, k as u32]),
                    None => self.level = Level::Y,
                },
                Level::Y => match self.y.take() {
                    Some(j) => {
                        if let Some(txy) = self.voxel_span(1, j, self.tx) {
                            if let Some(z) = self.axis_loop(2, txy) {
                                self.j = j;
                                self.z = z;
                                self.level = Level::Z;
                            }
                        }
                    }
                    None => self.level = Level::X,
                },
                Level::X => match self.x.take() {
                    Some(i) => {
                        if let Some(tx) = self.voxel_span(0, i, self.clip) {
                            if let Some(y) = self.axis_loop(1, tx) {
                                self.i = i;
                                self.tx = tx;
                                self.y = y;
                                self.level = Level::Y;
                            }
                        }
                    }
                    None => self.level = Level::Done,
                },
            }
        }
    }
}

