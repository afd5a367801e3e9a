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
            resolution[a] = (extent[a] * per_unit)
                .round()
                .clamp(1.0, MAX_RESOLUTION as f64) as u32;
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

    /// This grid set up for many walks.
    pub fn walker(&self) -> GridWalker {
        GridWalker::new(self)
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

/// A grid set up for many walks: the map to voxel units (three divisions)
/// and the validity check are done once, not once per segment. Walks from
/// here and from [`GridSpec::walk`] visit the same voxels, bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct GridWalker {
    grid: GridCoords,
    valid: bool,
    /// Linear-index step per axis (`1, nx, nx * ny`).
    strides: [usize; 3],
}

impl GridWalker {
    pub fn new(spec: &GridSpec) -> GridWalker {
        let [nx, ny, _] = spec.resolution.map(|n| n as usize);
        GridWalker {
            grid: GridCoords::new(spec),
            valid: spec.is_valid(),
            strides: [1, nx, nx * ny],
        }
    }

    /// The supercover walk of the segment `origin + t * dir`, `t` in
    /// `[t0, t1]`: see [`VoxelWalk`].
    pub fn walk(&self, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> VoxelWalk {
        let segment = Segment::new(&self.grid, self.valid, origin, dir, t0, t1);
        match segment.and_then(|s| Some((s, s.axis_loop(s.axes[0], s.span)?))) {
            Some((segment, outer)) => VoxelWalk {
                segment,
                loops: [outer, AxisLoop::default(), AxisLoop::default()],
                spans: [segment.span, (0.0, 0.0), (0.0, 0.0)],
                voxel: [0; 3],
                depth: 0,
                done: false,
            },
            None => VoxelWalk::EMPTY,
        }
    }

    /// The linear index ([`GridSpec::linear_index`]) of every voxel the walk
    /// of the segment visits, in no particular order: straight nested loops
    /// without the iterator's resumable state, for callers (OSTC's marking)
    /// that only need the set.
    pub fn for_each_index(
        &self,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        t1: f32,
        mut visit: impl FnMut(usize),
    ) {
        let Some(segment) = Segment::new(&self.grid, self.valid, origin, dir, t0, t1) else {
            return;
        };
        let Some(outer) = segment.axis_range(segment.axes[0], segment.span) else {
            return;
        };
        let strides = segment.axes.map(|axis| self.strides[axis]);
        segment.for_each_run(outer, |i, j, inner| {
            let base = i as usize * strides[0] + j as usize * strides[1];
            for k in inner.0..inner.1 + 1 {
                visit(base + k as usize * strides[2]);
            }
        });
    }
}

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
    segment: Segment,
    loops: [AxisLoop; 3],
    /// `spans[n]`: the part of the segment (a t-interval) inside the grid
    /// and inside the current slabs of the levels above `n`.
    spans: [(f64, f64); 3],
    voxel: [i64; 3],
    depth: usize,
    done: bool,
}

/// A segment in voxel units, clipped to the (slightly grown) grid: what
/// every level of a walk's nested loops reads.
#[derive(Clone, Copy, Debug)]
struct Segment {
    /// Origin and direction in voxel units.
    g0: [f64; 3],
    d: [f64; 3],
    /// `1 / d` (unused on axes where `d` is zero). A product instead of a
    /// quotient adds an ulp or so to each `t`, far inside `eps`.
    inv_d: [f64; 3],
    eps: f64,
    /// Voxels per axis.
    n: [i64; 3],
    /// The axis of each nesting level, outermost first: axes the segment
    /// moves along come before axes it does not, so voxels met at the same
    /// point come together and the walk stays in order.
    axes: [usize; 3],
    /// The t-interval of the segment inside the grown grid.
    span: (f64, f64),
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

    fn index_range(&self, axis: usize, lo: f64, hi: f64) -> Option<(i64, i64)> {
        index_range(self.n[axis], lo, hi)
    }
}

/// Voxels (of `n` along an axis) whose closed span [i, i+1] meets the
/// closed span [lo, hi], clamped to the grid; `None` if there are none.
fn index_range(n: i64, lo: f64, hi: f64) -> Option<(i64, i64)> {
    // Compared as floats (whole numbers, never NaN: `max` and `min` drop a
    // NaN), so `first` needs no clamp to fit: when they bound a range, it
    // is at most `last`.
    let first = (lo.ceil() - 1.0).max(0.0);
    let last = hi.floor().min((n - 1) as f64).max(-1.0);
    (first <= last && lo <= hi).then_some((first as i64, last as i64))
}

impl Segment {
    /// The segment `origin + t * dir`, `t` in `[t0, t1]`, clipped to the
    /// grid; `None` when it misses the grid (or `valid`, the grid's own
    /// check, is false).
    fn new(
        grid: &GridCoords,
        valid: bool,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        t1: f32,
    ) -> Option<Segment> {
        let valid = valid
            && origin.is_finite()
            && dir.is_finite()
            && t0 <= t1
            && !t0.is_nan()
            && !t1.is_nan();
        if !valid {
            return None;
        }
        let g0: [f64; 3] = std::array::from_fn(|a| grid.coord(a, f64::from(origin[a])));
        let d: [f64; 3] = std::array::from_fn(|a| f64::from(dir[a]) * grid.scale[a]);
        let (t0, t1) = (f64::from(t0), f64::from(t1));
        // The largest coordinate the walk computes with: the slack grows
        // with it. Every term is finite and non-negative, so the order of
        // the maxima does not matter.
        let mut magnitude = 0.0f64;
        for a in 0..3 {
            let mut reach = 0.0f64;
            if d[a] != 0.0 {
                for t in [t0, t1] {
                    let x = (t * d[a]).abs();
                    if x.is_finite() {
                        reach = reach.max(x);
                    }
                }
            }
            magnitude = magnitude.max(g0[a].abs() + reach + grid.n[a] as f64);
        }
        // Moving axes first, each group in axis order.
        let mut axes = [0usize; 3];
        let mut level = 0;
        for moving in [true, false] {
            for (a, &da) in d.iter().enumerate() {
                if (da != 0.0) == moving {
                    axes[level] = a;
                    level += 1;
                }
            }
        }
        let mut segment = Segment {
            g0,
            d,
            inv_d: d.map(|x| 1.0 / x),
            eps: WALK_SLACK_VOXELS + magnitude * 1e-12,
            n: grid.n,
            axes,
            span: (t0, t1),
        };
        // Clip to the (slightly grown) grid box, one slab per axis.
        for a in 0..3 {
            let hi = grid.n[a] as f64 + segment.eps;
            segment.span = segment.slab_interval(a, -segment.eps, hi, segment.span)?;
        }
        Some(segment)
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
            let ta = (lo - self.g0[axis]) * self.inv_d[axis];
            let tb = (hi - self.g0[axis]) * self.inv_d[axis];
            (span.0.max(ta.min(tb)), span.1.min(ta.max(tb)))
        };
        (a <= b).then_some((a, b))
    }

    /// The voxels of `axis` that the part `span` of the segment touches.
    fn axis_range(&self, axis: usize, span: (f64, f64)) -> Option<(i64, i64)> {
        let (p, q) = (self.at(axis, span.0), self.at(axis, span.1));
        index_range(self.n[axis], p.min(q) - self.eps, p.max(q) + self.eps)
    }

    /// [`Segment::axis_range`] as a loop in the direction of travel.
    fn axis_loop(&self, axis: usize, span: (f64, f64)) -> Option<AxisLoop> {
        let (first, last) = self.axis_range(axis, span)?;
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

    /// Calls `run(i, j, (first, last))` for every run of voxels along the
    /// innermost axis: outer index `i`, middle index `j`, inner indices
    /// `first..=last`. The same voxels as the iterator, computed the same
    /// way, but in ascending order per level instead of along the segment.
    /// `outer`: the outermost level's indices, first to last.
    fn for_each_run(&self, outer: (i64, i64), mut run: impl FnMut(i64, i64, (i64, i64))) {
        let [outer_axis, middle, inner] = self.axes;
        let (first, last) = outer;
        // Half-open ranges: an inclusive range's end check costs more.
        for i in first..last + 1 {
            let Some(outer_span) = self.voxel_span(outer_axis, i, self.span) else {
                continue;
            };
            let Some((first, last)) = self.axis_range(middle, outer_span) else {
                continue;
            };
            for j in first..last + 1 {
                let Some(middle_span) = self.voxel_span(middle, j, outer_span) else {
                    continue;
                };
                if let Some(run_k) = self.axis_range(inner, middle_span) {
                    run(i, j, run_k);
                }
            }
        }
    }
}

impl VoxelWalk {
    /// A walk that visits nothing.
    const EMPTY: VoxelWalk = VoxelWalk {
        segment: Segment {
            g0: [0.0; 3],
            d: [0.0; 3],
            inv_d: [0.0; 3],
            eps: 0.0,
            n: [0; 3],
            axes: [0, 1, 2],
            span: (0.0, 0.0),
        },
        loops: [AxisLoop {
            next: 0,
            last: 0,
            step: 0,
        }; 3],
        spans: [(0.0, 0.0); 3],
        voxel: [0; 3],
        depth: 0,
        done: true,
    };

    pub fn new(spec: &GridSpec, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> VoxelWalk {
        GridWalker::new(spec).walk(origin, dir, t0, t1)
    }

    /// Visits the same voxels as iterating, but in no particular order:
    /// straight nested loops without the iterator's resumable state.
    pub fn for_each_voxel(self, mut visit: impl FnMut([u32; 3])) {
        if self.done {
            return;
        }
        let [outer, middle, inner] = self.segment.axes;
        let rest = self.loops[0];
        let range = if rest.step < 0 {
            (rest.last, rest.next)
        } else {
            (rest.next, rest.last)
        };
        self.segment.for_each_run(range, |i, j, (first, last)| {
            let mut voxel = [0u32; 3];
            voxel[outer] = i as u32;
            voxel[middle] = j as u32;
            for k in first..=last {
                voxel[inner] = k as u32;
                visit(voxel);
            }
        });
    }
}

impl Iterator for VoxelWalk {
    type Item = [u32; 3];

    fn next(&mut self) -> Option<[u32; 3]> {
        while !self.done {
            let depth = self.depth;
            let Some(i) = self.loops[depth].take() else {
                if depth == 0 {
                    self.done = true;
                } else {
                    self.depth -= 1;
                }
                continue;
            };
            let axis = self.segment.axes[depth];
            if depth == 2 {
                self.voxel[axis] = i;
                return Some(self.voxel.map(|c| c as u32));
            }
            // The part of the segment in this slab, and the voxels it
            // touches on the next axis in.
            let Some(span) = self.segment.voxel_span(axis, i, self.spans[depth]) else {
                continue;
            };
            if let Some(inner) = self.segment.axis_loop(self.segment.axes[depth + 1], span) {
                self.voxel[axis] = i;
                self.spans[depth + 1] = span;
                self.loops[depth + 1] = inner;
                self.depth += 1;
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::HashSet;

    fn unit_grid(n: [u32; 3]) -> GridSpec {
        // Voxels of size 1 from the origin: voxel planes are exact integers.
        GridSpec::new(
            Aabb {
                min: Vec3::ZERO,
                max: Vec3::from(n.map(|x| x as f32)),
            },
            n,
        )
    }

    fn collect(spec: &GridSpec, o: Vec3, d: Vec3, t0: f32, t1: f32) -> Vec<[u32; 3]> {
        spec.walk(o, d, t0, t1).collect()
    }

    fn set(v: &[[u32; 3]]) -> HashSet<[u32; 3]> {
        v.iter().copied().collect()
    }

    /// Voxels whose closed box, grown by `grow` voxels, meets the segment:
    /// brute force over every voxel, in f64 voxel units.
    fn touched(
        spec: &GridSpec,
        o: Vec3,
        d: Vec3,
        t0: f32,
        t1: f32,
        grow: f64,
    ) -> HashSet<[u32; 3]> {
        let g = GridCoords::new(spec);
        let g0: [f64; 3] = std::array::from_fn(|a| g.coord(a, f64::from(o[a])));
        let gd: [f64; 3] = std::array::from_fn(|a| f64::from(d[a]) * g.scale[a]);
        let mut out = HashSet::new();
        let [nx, ny, nz] = spec.resolution;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = [i, j, k];
                    let (mut lo, mut hi) = (f64::from(t0), f64::from(t1));
                    let mut hit = true;
                    for a in 0..3 {
                        let (s, e) = (v[a] as f64 - grow, v[a] as f64 + 1.0 + grow);
                        if gd[a] == 0.0 {
                            hit &= g0[a] >= s && g0[a] <= e;
                        } else {
                            let ta = (s - g0[a]) / gd[a];
                            let tb = (e - g0[a]) / gd[a];
                            lo = lo.max(ta.min(tb));
                            hi = hi.min(ta.max(tb));
                        }
                    }
                    if hit && lo <= hi {
                        out.insert(v);
                    }
                }
            }
        }
        out
    }

    /// Checks the whole contract for one segment.
    fn check(spec: &GridSpec, o: Vec3, d: Vec3, t0: f32, t1: f32) -> Result<(), String> {
        let walked = collect(spec, o, d, t0, t1);
        let got = set(&walked);
        if got.len() != walked.len() {
            return Err(format!("a voxel repeats: {walked:?}"));
        }
        let mut visited = Vec::new();
        spec.walk(o, d, t0, t1).for_each_voxel(|v| visited.push(v));
        visited.sort_unstable();
        let mut iterated = walked.clone();
        iterated.sort_unstable();
        if visited != iterated {
            return Err(format!(
                "for_each_voxel visits {visited:?}, the iterator {iterated:?}"
            ));
        }
        let mut indexed = Vec::new();
        spec.walker()
            .for_each_index(o, d, t0, t1, |index| indexed.push(index));
        indexed.sort_unstable();
        let mut linear: Vec<usize> = walked.iter().map(|&v| spec.linear_index(v)).collect();
        linear.sort_unstable();
        if indexed != linear {
            return Err(format!(
                "for_each_index visits {indexed:?}, the iterator {linear:?}"
            ));
        }
        let must = touched(spec, o, d, t0, t1, 0.0);
        if let Some(v) = must.difference(&got).next() {
            return Err(format!("missed touched voxel {v:?}; walked {walked:?}"));
        }
        let may = touched(spec, o, d, t0, t1, 1e-5);
        if let Some(v) = got.difference(&may).next() {
            return Err(format!("walked untouched voxel {v:?}; walked {walked:?}"));
        }
        // In order along the segment: entry parameters never decrease (up to
        // the slack, for voxels entered at one point).
        let g = GridCoords::new(spec);
        let entry = |v: &[u32; 3]| {
            let mut lo = f64::from(t0);
            for a in 0..3 {
                let d = f64::from(d[a]) * g.scale[a];
                if d != 0.0 {
                    let g0 = g.coord(a, f64::from(o[a]));
                    let ta = (v[a] as f64 - 1e-5 - g0) / d;
                    let tb = (v[a] as f64 + 1.0 + 1e-5 - g0) / d;
                    lo = lo.max(ta.min(tb));
                }
            }
            lo
        };
        // The slack as a parameter range: 1e-5 voxel along the slowest axis.
        let slack_t = (0..3)
            .map(|a| f64::from(d[a]) * g.scale[a])
            .filter(|&x| x != 0.0)
            .map(|x| 1e-5 / x.abs())
            .fold(0.0, f64::max);
        for w in walked.windows(2) {
            let (a, b) = (entry(&w[0]), entry(&w[1]));
            if b < a - 2.0 * slack_t {
                return Err(format!("out of order: {w:?} entered at {a} then {b}"));
            }
        }
        Ok(())
    }

    #[test]
    fn axis_parallel_rays_visit_their_row() {
        let spec = unit_grid([4, 3, 2]);
        let row = collect(
            &spec,
            Vec3::new(-1.0, 1.5, 0.5),
            Vec3::X,
            0.0,
            f32::INFINITY,
        );
        assert_eq!(row, vec![[0, 1, 0], [1, 1, 0], [2, 1, 0], [3, 1, 0]]);
        let back = collect(
            &spec,
            Vec3::new(9.0, 1.5, 0.5),
            -Vec3::X,
            0.0,
            f32::INFINITY,
        );
        assert_eq!(back, vec![[3, 1, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0]]);
        // Stops at t1: from x = 0.5 to x = 2.0, which touches voxel 2's face.
        let part = collect(&spec, Vec3::new(0.5, 1.5, 0.5), Vec3::X, 0.0, 1.5);
        assert_eq!(part, vec![[0, 1, 0], [1, 1, 0], [2, 1, 0]]);
    }

    #[test]
    fn ray_on_voxel_planes_visits_both_sides() {
        let spec = unit_grid([4, 3, 2]);
        // On the plane y = 1 (between rows 0 and 1), z inside voxel 0.
        let on = set(&collect(
            &spec,
            Vec3::new(-1.0, 1.0, 0.5),
            Vec3::X,
            0.0,
            100.0,
        ));
        let expected: HashSet<_> = (0..4).flat_map(|i| [[i, 0, 0], [i, 1, 0]]).collect();
        assert_eq!(on, expected);
        // On the edge y = 1, z = 1: four rows.
        let edge = set(&collect(
            &spec,
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::X,
            0.0,
            100.0,
        ));
        assert_eq!(edge.len(), 16);
        // -0.0 components behave as +0.0.
        let neg = set(&collect(
            &spec,
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::new(1.0, -0.0, -0.0),
            0.0,
            100.0,
        ));
        assert_eq!(neg, edge);
        // On the grid's outer face y = 0 and outside it.
        let face = set(&collect(
            &spec,
            Vec3::new(-1.0, 0.0, 0.5),
            Vec3::X,
            0.0,
            100.0,
        ));
        assert_eq!(face, (0..4).map(|i| [i, 0, 0]).collect());
        assert!(collect(&spec, Vec3::new(-1.0, -0.001, 0.5), Vec3::X, 0.0, 100.0).is_empty());
    }

    #[test]
    fn origin_on_a_voxel_plane_starts_on_both_sides() {
        let spec = unit_grid([4, 4, 4]);
        // Starting exactly on x = 2, moving +y.
        let w = collect(&spec, Vec3::new(2.0, 0.5, 0.5), Vec3::Y, 0.0, 1.0);
        assert_eq!(set(&w), set(&[[1, 0, 0], [2, 0, 0], [1, 1, 0], [2, 1, 0]]));
        // Starting exactly on x = 2, moving +x: voxel 1 is touched at t = 0.
        let w = collect(&spec, Vec3::new(2.0, 0.5, 0.5), Vec3::X, 0.0, 0.5);
        assert_eq!(w, vec![[1, 0, 0], [2, 0, 0]]);
        let w = collect(&spec, Vec3::new(2.0, 0.5, 0.5), -Vec3::X, 0.0, 0.5);
        assert_eq!(w, vec![[2, 0, 0], [1, 0, 0]]);
    }

    #[test]
    fn diagonals_through_corners_visit_every_touching_voxel() {
        // 2D: through the corner (1, 1) of a 2x2 layer.
        let spec = unit_grid([2, 2, 1]);
        let w = collect(
            &spec,
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(1.0, 1.0, 0.0),
            0.0,
            2.0,
        );
        assert_eq!(w.len(), 4);
        assert_eq!(w[0], [0, 0, 0]);
        assert_eq!(w[3], [1, 1, 0]);
        // 3D: through the centre corner of a 2x2x2 grid.
        let spec = unit_grid([2, 2, 2]);
        let w = collect(&spec, Vec3::splat(0.25), Vec3::ONE, 0.0, 2.0);
        assert_eq!(set(&w).len(), 8);
        assert_eq!((w[0], w[7]), ([0, 0, 0], [1, 1, 1]));
        // Backwards along the other diagonal, from outside.
        let w = collect(
            &spec,
            Vec3::new(3.0, -1.0, 3.0),
            Vec3::new(-1.0, 1.0, -1.0),
            0.0,
            10.0,
        );
        assert_eq!(set(&w).len(), 8);
        assert_eq!((w[0], w[7]), ([1, 0, 1], [0, 1, 0]));
        check(
            &spec,
            Vec3::new(3.0, -1.0, 3.0),
            Vec3::new(-1.0, 1.0, -1.0),
            0.0,
            10.0,
        )
        .unwrap();
    }

    #[test]
    fn misses_and_empty_segments_yield_nothing() {
        let spec = unit_grid([3, 3, 3]);
        let far = Vec3::new(-5.0, 1.5, 1.5);
        assert!(collect(&spec, far, -Vec3::X, 0.0, f32::INFINITY).is_empty());
        assert!(collect(&spec, far, Vec3::Y, 0.0, f32::INFINITY).is_empty());
        assert!(collect(&spec, far, Vec3::X, 0.0, 4.0).is_empty());
        assert!(collect(&spec, far, Vec3::X, 2.0, 1.0).is_empty());
        assert!(collect(&spec, far, Vec3::X, f32::NAN, 10.0).is_empty());
        assert!(collect(&spec, Vec3::NAN, Vec3::X, 0.0, 10.0).is_empty());
        // Just reaching the face x = 0 touches the first column.
        assert_eq!(collect(&spec, far, Vec3::X, 0.0, 5.0), vec![[0, 1, 1]]);
        // A point (zero direction) yields the voxels around it, with t1 = inf.
        assert_eq!(
            collect(&spec, Vec3::splat(1.5), Vec3::ZERO, 0.0, f32::INFINITY),
            vec![[1, 1, 1]]
        );
        assert_eq!(
            collect(&spec, Vec3::splat(1.0), Vec3::ZERO, 0.0, 0.0).len(),
            8
        );
        // An invalid spec yields nothing instead of panicking.
        let flat = GridSpec {
            bounds: Aabb {
                min: Vec3::ZERO,
                max: Vec3::new(1.0, 0.0, 1.0),
            },
            resolution: [2, 2, 2],
        };
        assert!(collect(&flat, Vec3::splat(-1.0), Vec3::ONE, 0.0, 10.0).is_empty());
    }

    #[test]
    fn walk_segment_matches_the_iterator_and_far_origins_work() {
        let spec = GridSpec::new(
            Aabb {
                min: Vec3::new(-1.0e5, 2.0, -3.0),
                max: Vec3::new(-0.99e5, 2.5, 1.0),
            },
            [7, 5, 3],
        );
        let o = Vec3::new(-1.2e5, 2.1, 0.3);
        let d = Vec3::new(1.0, 1e-6, -2e-5);
        let mut v = Vec::new();
        walk_segment(&spec, o, d, 0.0, f32::INFINITY, |x| v.push(x));
        assert_eq!(v, collect(&spec, o, d, 0.0, f32::INFINITY));
        assert!(!v.is_empty());
        check(&spec, o, d, 0.0, f32::INFINITY).unwrap();
    }

    #[test]
    fn cell_budget_and_ranges() {
        let b = Aabb {
            min: Vec3::new(0.0, 0.0, 0.0),
            max: Vec3::new(8.0, 4.0, 0.0),
        };
        let spec = GridSpec::with_cell_budget(b, 32.0);
        assert_eq!(spec.resolution, [8, 4, 1]);
        assert!(spec.bounds.min.cmple(b.min).all() && spec.bounds.max.cmpge(b.max).all());
        let spec = unit_grid([4, 4, 4]);
        let r = spec.voxel_range(&Aabb {
            min: Vec3::new(1.0, 0.5, -3.0),
            max: Vec3::new(2.5, 0.7, 0.0),
        });
        assert_eq!(r, Some([[0, 0, 0], [2, 0, 0]]));
        assert_eq!(spec.voxel_range(&Aabb::EMPTY), None);
        assert_eq!(spec.linear_index([1, 2, 3]), 1 + 4 * (2 + 4 * 3));
        assert_eq!(spec.voxel_bounds([1, 2, 3]).min, Vec3::new(1.0, 2.0, 3.0));
    }

    /// A coordinate on a voxel plane (exactly, on dyadic grids) or anywhere.
    fn coord(n: u32) -> impl Strategy<Value = f32> {
        let n = n as f32;
        prop_oneof![
            (-1i32..=(n as i32 + 1)).prop_map(|k| k as f32),
            (-1.0f32..n + 1.0),
            Just(-0.0f32),
        ]
    }

    fn point(n: [u32; 3]) -> impl Strategy<Value = Vec3> {
        (coord(n[0]), coord(n[1]), coord(n[2])).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn dyadic_case() -> impl Strategy<Value = (GridSpec, Vec3, Vec3, f32, f32)> {
        (1u32..6, 1u32..6, 1u32..6).prop_flat_map(|(nx, ny, nz)| {
            let n = [nx, ny, nz];
            (
                Just(n),
                point(n),
                point(n),
                prop_oneof![Just(1.0f32), Just(f32::INFINITY), 0.1f32..3.0],
            )
                .prop_map(|(n, a, b, t1)| (unit_grid(n), a, b - a, 0.0, t1))
        })
    }

    fn general_case() -> impl Strategy<Value = (GridSpec, Vec3, Vec3, f32, f32)> {
        let unit = |lo: f32, hi: f32| (lo..hi, lo..hi, lo..hi).prop_map(Vec3::from);
        // Far from the origin (integers, then a fraction: proptest's float
        // sampler trips over wide f32 ranges).
        let far = (
            -100_000i32..100_000,
            -100_000i32..100_000,
            -100_000i32..100_000,
        )
            .prop_map(|(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) + 0.375);
        (
            prop_oneof![
                (unit(-10.0, 10.0), unit(0.01, 5.0)),
                (unit(-10.0, 10.0), unit(1e-3, 1e-2)),
                (far, unit(1.0, 100.0)),
            ],
            (1u32..9, 1u32..9, 1u32..9),
            unit(-0.3, 1.3),
            unit(-0.3, 1.3),
            0u8..32,
            (-0.3f32..0.3, 0.0f32..3.0),
        )
            .prop_map(|((min, ext), n, a, b, zero, (t0, len))| {
                let spec = GridSpec::new(
                    Aabb {
                        min,
                        max: min + ext,
                    },
                    [n.0, n.1, n.2],
                );
                // From one point around the grid to another.
                let o = min + ext * a;
                let mut d = ext * (b - a);
                // Zero some direction components when bit 4 is set (bits
                // 0..2: axes), as -0.0 when bit 3 is set.
                let zero_value = if zero & 8 != 0 { -0.0 } else { 0.0 };
                for a in 0..3 {
                    if zero & 16 != 0 && zero & (1 << a) != 0 && zero & 7 != 7 {
                        d[a] = zero_value;
                    }
                }
                (spec, o, d, t0, t0 + len)
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        #[test]
        fn supercover_on_dyadic_grids((spec, o, d, t0, t1) in dyadic_case()) {
            check(&spec, o, d, t0, t1).map_err(TestCaseError::fail)?;
        }

        #[test]
        fn supercover_on_general_grids((spec, o, d, t0, t1) in general_case()) {
            check(&spec, o, d, t0, t1).map_err(TestCaseError::fail)?;
        }
    }
}
