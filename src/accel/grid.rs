//! The pure-Rust backend: a uniform grid traversed by 3D-DDA (Amanatides &
//! Woo), with watertight triangles and stable spheres. Slower than Embree,
//! but small enough to read, and the reference Embree is checked against.
//!
//! Layout: one grid over the world bounds of every bounded object. A cell
//! lists the primitives that overlap it (CSR: `cell_start` offsets into one
//! flat `cell_items` array), built in parallel from sorted (cell, primitive)
//! pairs. Spheres and the triangles of small world-placed meshes are
//! primitives of the world grid, and so is a sphere placed by a transform,
//! as the world-space sphere [`super::placed_sphere`] gives (a move rewrites
//! it and re-bins). Any other instanced object, or a world mesh of
//! [`NESTED_MESH_TRIANGLES`] triangles or more, is one primitive there,
//! covering the cells its world box overlaps, and carries its own grid fitted
//! to it (so a detailed mesh in a big, sparse scene keeps a fine grid: the
//! "teapot in a stadium"). A ray reaching an instance is mapped into object
//! space by the inverse transform (direction not normalized, so `t` keeps
//! its meaning) and traced there.
//!
//! Promises:
//! - Closest hits are exact per primitive (the nearest `t` of any primitive
//!   the ray meets in `(tmin, tmax)`), not "first cell with a hit": traversal
//!   stops only once the best `t` lies inside the cells already visited.
//!   Primitives are put in every cell their shape overlaps once grown by
//!   1e-4 of a cell plus a few ULPs of the coordinates, which covers the
//!   rounding of the DDA's plane crossings (for ray origins up to ~1e3 cells
//!   from the grid; farther, an f32 position is coarser than that anyway).
//!   A small per-ray mailbox keeps a primitive spanning several cells from
//!   being tested again in each.
//! - A triangle met where its mesh's cut-out lets rays through is no hit,
//!   for closest hits and occlusion alike ([`crate::geometry::Cutout`]).
//! - Nesting is one level deep: the world grid, then an object's own grid.
//!   A moved instance only re-bins the world grid.
//! - Planes are ignored ([`super::Accelerator`] handles them for every
//!   backend); empty meshes, degenerate triangles and an empty scene are
//!   fine; primitives with non-finite coordinates are left out.
//! - No allocation per ray; `Sync + Send`.
//!
//! The grid's cells and the supercover walk through them live in
//! [`crate::voxel`], which the OSTC bookkeeping walks its own grid with.

mod primitives;
#[cfg(test)]
mod tests;

use glam::{Affine3A, Vec3};
use rayon::prelude::*;

pub use primitives::{intersect_sphere, TriangleHit, WatertightRay};

use super::{moving_sphere, placed_sphere, Intersector};
use crate::geometry::{Aabb, Cutout, Motion, MovingSphere, Object, Placement, Shape, Sphere};
use crate::ray::{Hit, Ray};
use crate::voxel::{padded, GridSpec};

/// Cells per primitive when the resolution is chosen automatically (the
/// lambda of Cleary & Wyvill / Wald et al.: 2..4 is the usual sweet spot).
pub const CELLS_PER_PRIMITIVE: f64 = 4.0;

/// Up to this many primitives an object's level is tested brute force,
/// without a grid (a single sphere, a small polygon).
const BRUTE_FORCE_MAX: usize = 4;

/// World meshes with at least this many triangles get a grid of their own.
pub const NESTED_MESH_TRIANGLES: usize = 64;

/// How much a primitive grows, in cell sizes, before it is binned: covers
/// the rounding of the DDA's plane crossings.
const BIN_SLACK_CELLS: f32 = 1e-4;

/// The grid backend. Build once per scene; when instanced objects move,
/// [`GridIntersector::set_instance_transform`] re-bins only the world grid
/// (the objects' own grids stay as they are).
pub struct GridIntersector {
    world: Level,
    resolution: Option<[u32; 3]>,
    placed_spheres: Vec<PlacedSphere>,
}

/// A sphere placed by a transform: its own description, and where its
/// world-space copy sits in the world level's spheres (or, moving while
/// the shutter is open, its moving spheres).
struct PlacedSphere {
    object: u32,
    local: Sphere,
    slot: usize,
    moving: bool,
}

impl GridIntersector {
    /// Builds the world grid over `objects` (planes skipped). `resolution`
    /// overrides the world grid's cells per axis; `None` chooses about
    /// [`CELLS_PER_PRIMITIVE`] cells per primitive, near-cubic.
    pub fn build(objects: &[Object], resolution: Option<[u32; 3]>) -> GridIntersector {
        let mut prims = Prims::default();
        let mut placed_spheres = Vec::new();
        for (id, object) in objects.iter().enumerate() {
            let id = id as u32;
            match (&object.placement, &object.shape) {
                (Placement::World, Shape::Mesh(mesh))
                    if mesh.triangles.len() >= NESTED_MESH_TRIANGLES =>
                {
                    prims.nested.extend(Nested::new(id, &object.shape, None));
                }
                (Placement::World, shape) => prims.add_shape(id, shape),
                (Placement::Instance(xf), Shape::Sphere(sphere)) => {
                    // A transform that would not keep the sphere round is
                    // left out, like a non-invertible one.
                    if let Some(placed) = placed_sphere(sphere, xf) {
                        placed_spheres.push(PlacedSphere {
                            object: id,
                            local: *sphere,
                            slot: prims.spheres.len(),
                            moving: false,
                        });
                        prims.spheres.push((placed, id));
                    }
                }
                (Placement::Moving(motion), Shape::Sphere(sphere)) => {
                    if let Some(moving) = moving_sphere(sphere, motion) {
                        placed_spheres.push(PlacedSphere {
                            object: id,
                            local: *sphere,
                            slot: prims.moving_spheres.len(),
                            moving: true,
                        });
                        prims.moving_spheres.push((moving, id));
                    }
                }
                (Placement::Instance(xf), shape) => {
                    prims.nested.extend(Nested::new(id, shape, Some(xf)));
                }
                (Placement::Moving(motion), shape) => {
                    prims.nested.extend(Nested::moving(id, shape, motion));
                }
            }
        }
        GridIntersector {
            world: Level::build(prims, resolution),
            resolution,
            placed_spheres,
        }
    }

    /// Moves object `object` (its index in the objects the grid was built
    /// from), built with a transform, to `transform`, and re-bins the world
    /// grid. Returns false, changing nothing, if `object` was not built with
    /// a transform (or had nothing to hit), or `transform` cannot be inverted
    /// (or, for a sphere, would not keep it round).
    pub fn set_instance_transform(&mut self, object: u32, transform: &Affine3A) -> bool {
        self.move_objects(&[(object, *transform)])
    }

    /// Several moves as [`GridIntersector::set_instance_transform`], with one
    /// re-bin. Returns false if any move was refused; the others are made.
    pub fn move_objects(&mut self, moves: &[(u32, Affine3A)]) -> bool {
        let placements: Vec<(u32, Placement)> = moves
            .iter()
            .map(|&(object, xf)| (object, Placement::Instance(xf)))
            .collect();
        self.place_objects(&placements)
    }

    /// Places several objects, each built with the same kind of placement
    /// (a transform, or a motion over the shutter), with one re-bin.
    /// Returns false if any placement was refused; the others are made.
    pub fn place_objects(&mut self, placements: &[(u32, Placement)]) -> bool {
        let mut all_made = true;
        let mut any_made = false;
        for (object, placement) in placements {
            let made = self.place(*object, placement);
            all_made &= made;
            any_made |= made;
        }
        if any_made {
            self.world.rebin(self.resolution);
        }
        all_made
    }

    /// Places one object without re-binning.
    fn place(&mut self, object: u32, placement: &Placement) -> bool {
        if let Some(placed) = self.placed_spheres.iter().find(|p| p.object == object) {
            let prims = &mut self.world.prims;
            return match (placement, placed.moving) {
                (Placement::Instance(xf), false) => placed_sphere(&placed.local, xf)
                    .map(|sphere| prims.spheres[placed.slot].0 = sphere)
                    .is_some(),
                (Placement::Moving(motion), true) => moving_sphere(&placed.local, motion)
                    .map(|moving| prims.moving_spheres[placed.slot].0 = moving)
                    .is_some(),
                _ => false,
            };
        }
        let Some(nested) = self
            .world
            .prims
            .nested
            .iter_mut()
            .find(|n| n.object == object && !matches!(n.place, NestedPlace::World))
        else {
            return false;
        };
        match (placement, &mut nested.place) {
            (Placement::Instance(xf), NestedPlace::Instance(world_to_object)) => {
                let Some(inverse) = invert(xf) else {
                    return false;
                };
                *world_to_object = inverse;
                nested.bounds = nested.local_bounds.transformed(xf);
            }
            (Placement::Moving(motion), NestedPlace::Moving(moving)) => {
                if motion.poses.iter().any(|pose| invert(pose).is_none()) {
                    return false;
                }
                *moving = *motion;
                nested.bounds = motion.swept(nested.local_bounds);
            }
            _ => return false,
        }
        true
    }

    /// The world grid, or `None` when the scene is tested brute force (a
    /// few primitives or none).
    pub fn spec(&self) -> Option<&GridSpec> {
        self.world.cells.as_ref().map(|c| &c.spec)
    }

    /// Total (cell, primitive) references in the world grid.
    pub fn references(&self) -> usize {
        self.world.cells.as_ref().map_or(0, |c| c.cell_items.len())
    }
}

impl Intersector for GridIntersector {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.world.closest(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.world.any(ray)
    }
}

/// The primitives of one level, by kind. Index `p` into a level runs over
/// triangles, then spheres, then nested objects.
#[derive(Default)]
struct Prims {
    triangles: Vec<[Vec3; 3]>,
    /// (object, primitive index in the object) per triangle.
    triangle_ids: Vec<[u32; 2]>,
    spheres: Vec<(Sphere, u32)>,
    /// Spheres that move while the shutter is open.
    moving_spheres: Vec<(MovingSphere, u32)>,
    nested: Vec<Nested>,
    /// The cut-outs of the meshes among the triangles, by object: few, so
    /// looked up by a scan, and only once a triangle is hit.
    cutouts: Vec<(u32, Cutout)>,
}

impl Prims {
    fn add_shape(&mut self, object: u32, shape: &Shape) {
        match shape {
            Shape::Mesh(mesh) => {
                if let Some(cutout) = &mesh.cutout {
                    self.cutouts.push((object, cutout.clone()));
                }
                for (prim, tri) in mesh.triangles.iter().enumerate() {
                    let v = tri.map(|i| mesh.positions[i as usize]);
                    if v.iter().all(|p| p.is_finite()) {
                        self.triangles.push(v);
                        self.triangle_ids.push([object, prim as u32]);
                    }
                }
            }
            Shape::Sphere(s) => {
                if s.center.is_finite() && s.radius.is_finite() {
                    self.spheres.push((*s, object));
                }
            }
            Shape::Plane(_) => {}
        }
    }

    fn len(&self) -> usize {
        self.triangles.len() + self.spheres.len() + self.moving_spheres.len() + self.nested.len()
    }

    /// Where each kind's indices start: spheres, moving spheres, nested.
    #[inline]
    fn starts(&self) -> (usize, usize, usize) {
        let spheres = self.triangles.len();
        let moving = spheres + self.spheres.len();
        (spheres, moving, moving + self.moving_spheres.len())
    }

    /// Whether triangle primitive `p`'s mesh is clear where `hit` met it.
    #[inline]
    fn lets_through(&self, p: usize, hit: &TriangleHit) -> bool {
        if self.cutouts.is_empty() {
            return false;
        }
        let [object, prim] = self.triangle_ids[p];
        self.cutouts
            .iter()
            .find(|(id, _)| *id == object)
            .is_some_and(|(_, cutout)| cutout.lets_through(prim, hit.u, hit.v))
    }

    fn bounds(&self, p: usize) -> Aabb {
        let (spheres, moving, nested) = self.starts();
        if p < spheres {
            Aabb::from_points(self.triangles[p])
        } else if p < moving {
            Shape::Sphere(self.spheres[p - spheres].0).bounds()
        } else if p < nested {
            self.moving_spheres[p - moving].0.swept()
        } else {
            self.nested[p - nested].bounds
        }
    }

    /// Does primitive `p` (grown by `slack`) overlap the closed box `b`?
    /// Exact for triangles (separating axes) and spheres; nested objects use
    /// their box, which the caller already checked.
    fn overlaps(&self, p: usize, b: &Aabb, slack: Vec3) -> bool {
        let (spheres, moving, _) = self.starts();
        if p < spheres {
            triangle_overlaps_box(&self.triangles[p], b, slack)
        } else if p < moving {
            let s = &self.spheres[p - spheres].0;
            let nearest = s.center.clamp(b.min, b.max);
            let r = s.radius + slack.max_element();
            (nearest - s.center).length_squared() <= r * r
        } else {
            true
        }
    }
}

/// A grid (or a brute-force list) over one set of primitives.
struct Level {
    prims: Prims,
    cells: Option<Cells>,
}

struct Cells {
    spec: GridSpec,
    res: [i32; 3],
    min: Vec3,
    cell_size: Vec3,
    inv_cell_size: Vec3,
    /// `cell_items[cell_start[c]..cell_start[c + 1]]` are cell `c`'s
    /// primitives, in increasing order.
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
}

impl Cells {
    #[inline]
    fn items(&self, cell: usize) -> &[u32] {
        let a = self.cell_start[cell] as usize;
        let b = self.cell_start[cell + 1] as usize;
        &self.cell_items[a..b]
    }
}

/// An object with a level of its own: an instance (in object space, behind
/// a transform) or a large world mesh (no transform).
struct Nested {
    object: u32,
    place: NestedPlace,
    /// Bounds in object space, and in the world (for an instance, the
    /// object box transformed).
    local_bounds: Aabb,
    bounds: Aabb,
    level: Level,
}

/// The inverse of an affine transform, if it has one with finite entries.
fn invert(xf: &Affine3A) -> Option<Affine3A> {
    let det = xf.matrix3.determinant();
    if det == 0.0 || !det.is_finite() || !xf.translation.is_finite() {
        return None;
    }
    let inverse = xf.inverse();
    (inverse.matrix3.is_finite() && inverse.translation.is_finite()).then_some(inverse)
}

/// How a nested object reaches the world.
// One per nested object, read by every ray that reaches it: kept inline.
#[allow(clippy::large_enum_variant)]
enum NestedPlace {
    World,
    /// The inverse of its transform.
    Instance(Affine3A),
    /// Its motion over the shutter: a ray is mapped by the inverse of the
    /// transform at the ray's time, as Embree maps it.
    Moving(Motion),
}

impl Nested {
    /// `None` for shapes with nothing to hit (planes, empty meshes) or a
    /// transform that cannot be inverted.
    fn new(object: u32, shape: &Shape, xf: Option<&Affine3A>) -> Option<Nested> {
        let place = match xf {
            None => NestedPlace::World,
            Some(xf) => NestedPlace::Instance(invert(xf)?),
        };
        let mut nested = Nested::unplaced(object, shape, place)?;
        if let Some(xf) = xf {
            nested.bounds = nested.local_bounds.transformed(xf);
        }
        Some(nested)
    }

    /// A nested object moving over the shutter; `None` as for
    /// [`Nested::new`], or if a pose cannot be inverted.
    fn moving(object: u32, shape: &Shape, motion: &Motion) -> Option<Nested> {
        if motion.poses.iter().any(|pose| invert(pose).is_none()) {
            return None;
        }
        let mut nested = Nested::unplaced(object, shape, NestedPlace::Moving(*motion))?;
        nested.bounds = motion.swept(nested.local_bounds);
        Some(nested)
    }

    /// The object's own grid, its bounds those in object space.
    fn unplaced(object: u32, shape: &Shape, place: NestedPlace) -> Option<Nested> {
        let mut prims = Prims::default();
        prims.add_shape(object, shape);
        if prims.len() == 0 {
            return None;
        }
        let local_bounds = (0..prims.len()).fold(Aabb::EMPTY, |b, p| b.union(prims.bounds(p)));
        Some(Nested {
            object,
            place,
            local_bounds,
            bounds: local_bounds,
            level: Level::build(prims, None),
        })
    }

    /// `ray` in the object's space, `None` when no transform is needed;
    /// at a time whose transform cannot be inverted, a ray that meets
    /// nothing.
    #[inline]
    fn to_object(&self, ray: &Ray) -> Option<Ray> {
        let inverse = match &self.place {
            NestedPlace::World => return None,
            NestedPlace::Instance(m) => *m,
            NestedPlace::Moving(motion) => {
                invert(&motion.at(ray.time)).unwrap_or(Affine3A::from_scale(Vec3::ZERO))
            }
        };
        Some(Ray {
            origin: inverse.transform_point3(ray.origin),
            dir: inverse.transform_vector3(ray.dir),
            ..*ray
        })
    }

    #[inline]
    fn closest(&self, ray: &Ray, prepared: &Prepared, tmax: f32) -> Option<Hit> {
        match self.to_object(ray) {
            None => self.level.closest_prepared(&Ray { tmax, ..*ray }, prepared),
            Some(local) => self.level.closest(&Ray { tmax, ..local }),
        }
    }

    #[inline]
    fn any(&self, ray: &Ray, prepared: &Prepared) -> bool {
        match self.to_object(ray) {
            None => self.level.any_prepared(ray, prepared),
            Some(local) => self.level.any(&local),
        }
    }
}

impl Level {
    fn build(prims: Prims, resolution: Option<[u32; 3]>) -> Level {
        let mut level = Level { prims, cells: None };
        level.rebin(resolution);
        level
    }

    /// (Re)builds the cells from the primitives' current bounds.
    fn rebin(&mut self, resolution: Option<[u32; 3]>) {
        let prims = &self.prims;
        let count = prims.len();
        let bounds: Vec<Aabb> = (0..count)
            .into_par_iter()
            .map(|p| prims.bounds(p))
            .collect();
        let world = bounds
            .iter()
            .filter(|b| b.is_finite())
            .fold(Aabb::EMPTY, |acc, b| acc.union(*b));
        if world.is_empty() || (resolution.is_none() && count <= BRUTE_FORCE_MAX) {
            self.cells = None;
            return;
        }
        let spec = match resolution {
            Some(r) => GridSpec::new(padded(world), r.map(|n| n.max(1))),
            None => GridSpec::with_cell_budget(world, CELLS_PER_PRIMITIVE * count as f64),
        };
        self.cells = Some(bin(prims, &bounds, spec));
    }

    /// Closest hit in `(ray.tmin, ray.tmax)`.
    fn closest(&self, ray: &Ray) -> Option<Hit> {
        self.closest_prepared(ray, &Prepared::new(ray)?)
    }

    #[inline(always)]
    fn closest_prepared(&self, ray: &Ray, prepared: &Prepared) -> Option<Hit> {
        let mut best = Closest {
            tmax: ray.tmax,
            hit: None,
        };
        match &self.cells {
            None => {
                for p in 0..self.prims.len() as u32 {
                    self.test_closest(p, ray, prepared, &mut best);
                }
            }
            Some(cells) => {
                let mut dda = Dda::new(cells, ray, prepared.inv_dir)?;
                let mut mailbox = Mailbox::default();
                loop {
                    for &p in cells.items(dda.index) {
                        if !mailbox.seen(p) {
                            self.test_closest(p, ray, prepared, &mut best);
                        }
                    }
                    // Every hit closer than the current cell's exit lies in a
                    // cell already visited.
                    if best.tmax <= dda.t_exit() || !dda.step(best.tmax) {
                        break;
                    }
                }
            }
        }
        best.hit
    }

    #[inline]
    fn test_closest(&self, p: u32, ray: &Ray, prepared: &Prepared, best: &mut Closest) {
        let p = p as usize;
        let (spheres, moving, nested) = self.prims.starts();
        if p < spheres {
            if let Some(h) = prepared
                .wt
                .intersect_triangle(&self.prims.triangles[p], ray.tmin, best.tmax)
                .filter(|h| !self.prims.lets_through(p, h))
            {
                let [object, prim] = self.prims.triangle_ids[p];
                best.tmax = h.t;
                best.hit = Some(Hit {
                    t: h.t,
                    object,
                    prim,
                    u: h.u,
                    v: h.v,
                });
            }
        } else if p < nested {
            let (sphere, object) = if p < moving {
                let (sphere, object) = &self.prims.spheres[p - spheres];
                (*sphere, *object)
            } else {
                let (sphere, object) = &self.prims.moving_spheres[p - moving];
                (sphere.at(ray.time), *object)
            };
            if let Some(t) = intersect_sphere(&sphere, ray.origin, ray.dir, ray.tmin, best.tmax) {
                best.tmax = t;
                best.hit = Some(Hit {
                    t,
                    object,
                    prim: 0,
                    u: 0.0,
                    v: 0.0,
                });
            }
        } else if let Some(h) = self.prims.nested[p - nested].closest(ray, prepared, best.tmax) {
            best.tmax = h.t;
            best.hit = Some(h);
        }
    }

    /// Anything in `(ray.tmin, ray.tmax)`?
    fn any(&self, ray: &Ray) -> bool {
        Prepared::new(ray).is_some_and(|prepared| self.any_prepared(ray, &prepared))
    }

    #[inline(always)]
    fn any_prepared(&self, ray: &Ray, prepared: &Prepared) -> bool {
        match &self.cells {
            None => (0..self.prims.len() as u32).any(|p| self.test_any(p, ray, prepared)),
            Some(cells) => {
                let Some(mut dda) = Dda::new(cells, ray, prepared.inv_dir) else {
                    return false;
                };
                let mut mailbox = Mailbox::default();
                loop {
                    for &p in cells.items(dda.index) {
                        if !mailbox.seen(p) && self.test_any(p, ray, prepared) {
                            return true;
                        }
                    }
                    if !dda.step(ray.tmax) {
                        return false;
                    }
                }
            }
        }
    }

    #[inline]
    fn test_any(&self, p: u32, ray: &Ray, prepared: &Prepared) -> bool {
        let p = p as usize;
        let (spheres, moving, nested) = self.prims.starts();
        if p < spheres {
            prepared
                .wt
                .intersect_triangle(&self.prims.triangles[p], ray.tmin, ray.tmax)
                .is_some_and(|h| !self.prims.lets_through(p, &h))
        } else if p < moving {
            let (sphere, _) = &self.prims.spheres[p - spheres];
            intersect_sphere(sphere, ray.origin, ray.dir, ray.tmin, ray.tmax).is_some()
        } else if p < nested {
            let sphere = self.prims.moving_spheres[p - moving].0.at(ray.time);
            intersect_sphere(&sphere, ray.origin, ray.dir, ray.tmin, ray.tmax).is_some()
        } else {
            self.prims.nested[p - nested].any(ray, prepared)
        }
    }
}

/// What every level's traversal needs from a ray, computed once per ray
/// (and shared with nested levels that have no transform).
struct Prepared {
    wt: WatertightRay,
    inv_dir: Vec3,
}

impl Prepared {
    /// `None` for rays that hit nothing: non-finite, or a zero direction.
    #[inline(always)]
    fn new(ray: &Ray) -> Option<Prepared> {
        Some(Prepared {
            wt: WatertightRay::new(ray.origin, ray.dir)?,
            inv_dir: ray.dir.recip(),
        })
    }
}

struct Closest {
    tmax: f32,
    hit: Option<Hit>,
}

/// The last few primitives tested by a ray: a primitive spanning several
/// consecutive cells is tested once (a miss stays a miss as `tmax` only
/// shrinks; a hit is already the best or beaten).
struct Mailbox {
    /// `u32::MAX` marks an empty slot (no level has that many primitives).
    ids: [u32; 8],
    next: usize,
}

impl Default for Mailbox {
    fn default() -> Mailbox {
        Mailbox {
            ids: [u32::MAX; 8],
            next: 0,
        }
    }
}

impl Mailbox {
    #[inline]
    fn seen(&mut self, p: u32) -> bool {
        if self.ids.contains(&p) {
            return true;
        }
        self.ids[self.next % self.ids.len()] = p;
        self.next = self.next.wrapping_add(1);
        false
    }
}

/// `a.min(b)` for values known not to be NaN, without the NaN handling.
#[inline]
fn fast_min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Amanatides & Woo's 3D-DDA over a level's cells, started where the ray
/// enters the grid box.
///
/// Robust to zero and -0.0 direction components (those axes never step and
/// never bound the ray), origins on cell planes (the start cell is clamped
/// into the grid), and rays starting outside the grid or limited by
/// `tmin`/`tmax`. Plane crossings are not accumulated step by step: the
/// crossing of plane `k` is `k * t_per_plane + t_plane0` (one rounding of
/// each term), so no error builds up along long walks.
struct Dda {
    cell: [i32; 3],
    /// Index (as f32, exact) of the plane the ray crosses next on each axis,
    /// and how it moves per step (+1, -1, or 0 for axes the ray runs
    /// parallel to).
    plane: [f32; 3],
    plane_step: [f32; 3],
    t_per_plane: [f32; 3],
    t_plane0: [f32; 3],
    /// `t` where the ray crosses the next plane on each axis (infinite for
    /// axes it runs parallel to).
    t_next: [f32; 3],
    /// The ray leaves the grid box (or passes `tmax`) at `t_far`.
    t_far: f32,
    /// Linear index of `cell`, and how it moves per step on each axis.
    index: usize,
    index_step: [isize; 3],
    cell_step: [i32; 3],
    res: [u32; 3],
}

impl Dda {
    #[inline(always)]
    fn new(cells: &Cells, ray: &Ray, inv_dir: Vec3) -> Option<Dda> {
        let (o, d) = (ray.origin, ray.dir);
        let (lo, hi) = (cells.spec.bounds.min, cells.spec.bounds.max);
        let (mut t0, mut t1) = (ray.tmin, ray.tmax);
        for a in 0..3 {
            if d[a] == 0.0 {
                // Parallel to this slab: inside it or never in the box.
                if !(o[a] >= lo[a] && o[a] <= hi[a]) {
                    return None;
                }
                continue;
            }
            let ta = (lo[a] - o[a]) * inv_dir[a];
            let tb = (hi[a] - o[a]) * inv_dir[a];
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        // Widen by a few ULPs (the slab distances are rounded; Ize, "Robust
        // BVH Ray Traversal"): a ray grazing the box is walked, not dropped.
        let t0 = t0 - t0.abs() * 4.0 * f32::EPSILON;
        let t1 = t1 + t1.abs() * 4.0 * f32::EPSILON;
        if t0.is_nan() || t1.is_nan() || t0 > t1 {
            return None;
        }
        let t_start = t0.max(ray.tmin);
        let strides = [
            1,
            cells.res[0] as isize,
            cells.res[0] as isize * cells.res[1] as isize,
        ];
        let mut dda = Dda {
            cell: [0; 3],
            plane: [0.0; 3],
            plane_step: [0.0; 3],
            t_per_plane: [0.0; 3],
            t_plane0: [0.0; 3],
            t_next: [f32::INFINITY; 3],
            t_far: t1.min(ray.tmax),
            index: 0,
            index_step: [0; 3],
            cell_step: [0; 3],
            res: cells.res.map(|n| n as u32),
        };
        let mut index = 0;
        for a in 0..3 {
            let p = if d[a] == 0.0 {
                o[a]
            } else {
                o[a] + d[a] * t_start
            };
            let c = ((p - cells.min[a]) * cells.inv_cell_size[a]).floor();
            // Clamp in float first: far-off starts must not overflow i32.
            let c = c.clamp(0.0, (cells.res[a] - 1) as f32) as i32;
            dda.cell[a] = c;
            index += c as isize * strides[a];
            if d[a] == 0.0 {
                continue;
            }
            let step = if d[a] > 0.0 { 1 } else { -1 };
            dda.cell_step[a] = step;
            dda.index_step[a] = strides[a] * step as isize;
            dda.plane_step[a] = step as f32;
            dda.plane[a] = (c + i32::from(step > 0)) as f32;
            dda.t_per_plane[a] = cells.cell_size[a] * inv_dir[a];
            dda.t_plane0[a] = (cells.min[a] - o[a]) * inv_dir[a];
            dda.t_next[a] = dda.plane[a] * dda.t_per_plane[a] + dda.t_plane0[a];
        }
        dda.index = index as usize;
        Some(dda)
    }

    /// Where the ray leaves the current cell.
    #[inline]
    fn t_exit(&self) -> f32 {
        fast_min(fast_min(self.t_next[0], self.t_next[1]), self.t_next[2])
    }

    /// Moves to the next cell; false once the ray has left the grid or the
    /// next cell starts beyond `tmax`.
    #[inline(always)]
    fn step(&mut self, tmax: f32) -> bool {
        let [x, y, z] = self.t_next;
        // One code path per axis, so every index is a constant and the
        // state can live in registers.
        if x <= y && x <= z {
            self.advance::<0>(tmax)
        } else if y <= z {
            self.advance::<1>(tmax)
        } else {
            self.advance::<2>(tmax)
        }
    }

    #[inline(always)]
    fn advance<const A: usize>(&mut self, tmax: f32) -> bool {
        if self.t_next[A] > fast_min(self.t_far, tmax) {
            return false;
        }
        let c = self.cell[A] + self.cell_step[A];
        // Also catches c == -1 (as a huge u32).
        if c as u32 >= self.res[A] {
            return false;
        }
        self.cell[A] = c;
        self.index = self.index.wrapping_add_signed(self.index_step[A]);
        self.plane[A] += self.plane_step[A];
        self.t_next[A] = self.plane[A] * self.t_per_plane[A] + self.t_plane0[A];
        true
    }
}

/// Sorts every primitive into the cells it overlaps (grown by
/// [`BIN_SLACK_CELLS`]): (cell, primitive) pairs in parallel, one sort, then
/// offsets.
fn bin(prims: &Prims, bounds: &[Aabb], spec: GridSpec) -> Cells {
    let cell_size = spec.cell_size();
    let magnitude = spec.bounds.min.abs().max(spec.bounds.max.abs());
    let slack = cell_size * BIN_SLACK_CELLS + magnitude * (4.0 * f32::EPSILON);
    let mut pairs: Vec<u64> = (0..bounds.len())
        .into_par_iter()
        .flat_map_iter(|p| {
            let b = &bounds[p];
            let grown = Aabb {
                min: b.min - slack,
                max: b.max + slack,
            };
            let range = if b.is_finite() {
                spec.voxel_range(&grown)
            } else {
                None
            };
            let mut cells = Vec::new();
            if let Some([first, last]) = range {
                let single = first == last;
                for k in first[2]..=last[2] {
                    for j in first[1]..=last[1] {
                        for i in first[0]..=last[0] {
                            let voxel = [i, j, k];
                            if single || prims.overlaps(p, &spec.voxel_bounds(voxel), slack) {
                                cells.push(((spec.linear_index(voxel) as u64) << 32) | p as u64);
                            }
                        }
                    }
                }
            }
            cells
        })
        .collect();
    pairs.par_sort_unstable();
    let count = spec.voxel_count();
    let mut cell_start = vec![0u32; count + 1];
    for &pair in &pairs {
        cell_start[(pair >> 32) as usize + 1] += 1;
    }
    for c in 0..count {
        cell_start[c + 1] += cell_start[c];
    }
    let cell_items = pairs.iter().map(|&pair| pair as u32).collect();
    Cells {
        spec,
        res: spec.resolution.map(|n| n as i32),
        min: spec.bounds.min,
        cell_size,
        inv_cell_size: cell_size.recip(),
        cell_start,
        cell_items,
    }
}

/// Separating-axis test of a triangle against a closed box grown by `slack`
/// (Akenine-Möller, "Fast 3D Triangle-Box Overlap Testing"). Conservative:
/// the slack covers the rounding of the test itself.
fn triangle_overlaps_box(tri: &[Vec3; 3], b: &Aabb, slack: Vec3) -> bool {
    let center = b.center();
    let half = b.extent() * 0.5 + slack;
    let v = tri.map(|p| p - center);
    // Box normals.
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    if lo.cmpgt(half).any() || hi.cmplt(-half).any() {
        return false;
    }
    let separated = |axis: Vec3| {
        let p = [axis.dot(v[0]), axis.dot(v[1]), axis.dot(v[2])];
        let r = half.dot(axis.abs());
        let (pmin, pmax) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        // Relative slack for the dot products' rounding.
        let tol = (pmin.abs().max(pmax.abs()) + r) * (8.0 * f32::EPSILON);
        pmin > r + tol || pmax < -r - tol
    };
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    if separated(edges[0].cross(edges[1])) {
        return false;
    }
    for e in edges {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            if separated(axis.cross(e)) {
                return false;
            }
        }
    }
    true
}
