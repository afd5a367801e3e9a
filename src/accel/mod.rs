//! Ray/scene intersection behind one trait, with two backends: Embree (fast,
//! through FFI) and a pure-Rust uniform grid (readable, the reference).
//!
//! Backends see bounded shapes only. Infinite planes are tested here, once,
//! for every backend ([`Accelerator`]), so both give the same answer for them.
//!
//! A sphere placed by a transform (an animated ball) is traced by both
//! backends as a plain world-space sphere, [`placed_sphere`]: the centre
//! moved, the radius scaled, exactly as shading places it. A move rewrites
//! that sphere; only meshes are traced through their transform.

// The crate's one FFI module; everything else is safe Rust.
#[allow(unsafe_code)]
pub mod embree;
pub mod grid;

use std::fmt;
use std::str::FromStr;

use glam::Affine3A;

use crate::geometry::{
    plane_distance, transform_normal, Motion, MovingSphere, Object, Placement, Plane, Shape,
    Sphere, MOTION_STEPS,
};
use crate::ray::{lanes, Hit, HitPacket, LaneMask, Ray, RayPacket, PACKET_WIDTH};

/// Closest-hit and any-hit queries, one ray or an 8-wide packet at a time.
///
/// Only the single-ray calls are required; packet calls default to a loop.
/// Lanes outside `mask` are neither traced nor written.
pub trait Intersector: Sync {
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True if anything lies on the ray strictly between `tmin` and `tmax`.
    fn occluded(&self, ray: &Ray) -> bool;

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        for lane in lanes(mask) {
            hits[lane] = self.intersect(&rays[lane]);
        }
    }

    /// Sets bit `i` of the result for each occluded lane `i` in `mask`.
    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        lanes(mask)
            .filter(|&lane| self.occluded(&rays[lane]))
            .fold(0, |acc, lane| acc | (1 << lane))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendKind {
    #[default]
    Embree,
    Grid,
}

impl fmt::Display for BackendKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BackendKind::Embree => "embree",
            BackendKind::Grid => "grid",
        })
    }
}

impl FromStr for BackendKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "embree" => Ok(BackendKind::Embree),
            "grid" => Ok(BackendKind::Grid),
            other => Err(format!(
                "unknown backend '{other}' (expected embree or grid)"
            )),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    #[error(transparent)]
    Embree(#[from] embree::EmbreeError),
    #[error("backend '{0}' is not available in this build")]
    Unavailable(BackendKind),
    #[error(
        "object {object}: a sphere can only be moved, rotated and scaled uniformly \
         (its transform would make it an ellipsoid, or is not finite)"
    )]
    SphereNotRound { object: u32 },
}

/// How far a sphere's transform may be from a similarity (relative, on the
/// columns' lengths and angles) and still count as one: a rotation built
/// from a quaternion in f32 is off by a few ULPs.
const SIMILARITY_TOLERANCE: f32 = 1e-4;

/// Where `sphere` is once placed by `transform`: its centre moved, its
/// radius scaled by the length of the transform's first column, the same
/// two operations shading and OSTC use, so every part of the renderer sees
/// the same sphere. `None` unless the transform keeps spheres round (a
/// rotation or reflection times a uniform, non-zero scale) and everything
/// is finite.
pub fn placed_sphere(sphere: &Sphere, transform: &Affine3A) -> Option<Sphere> {
    let m = transform.matrix3;
    let [x, y, z] = [m.x_axis, m.y_axis, m.z_axis];
    let scale = x.length();
    let tolerance = SIMILARITY_TOLERANCE * scale;
    let square_tolerance = SIMILARITY_TOLERANCE * scale * scale;
    let similar = scale > 0.0
        && (y.length() - scale).abs() <= tolerance
        && (z.length() - scale).abs() <= tolerance
        && x.dot(y).abs() <= square_tolerance
        && y.dot(z).abs() <= square_tolerance
        && z.dot(x).abs() <= square_tolerance;
    let placed = Sphere {
        center: transform.transform_point3(sphere.center),
        radius: sphere.radius * scale,
    };
    (similar && placed.center.is_finite() && placed.radius.is_finite()).then_some(placed)
}

/// `sphere` at each pose of `motion`, as [`placed_sphere`] places it; `None`
/// if a pose would not keep it round.
pub fn moving_sphere(sphere: &Sphere, motion: &Motion) -> Option<MovingSphere> {
    let mut steps = [*sphere; MOTION_STEPS];
    for (step, pose) in steps.iter_mut().zip(&motion.poses) {
        *step = placed_sphere(sphere, pose)?;
    }
    Some(MovingSphere { steps })
}

/// The backend behind an [`Accelerator`], kept concrete so instanced
/// objects can be moved.
enum Backend {
    Embree(embree::EmbreeIntersector),
    Grid(grid::GridIntersector),
}

impl Backend {
    fn intersector(&self) -> &dyn Intersector {
        match self {
            Backend::Embree(embree) => embree,
            Backend::Grid(grid) => grid,
        }
    }
}

/// A backend plus the scene's infinite planes: what the renderer traces.
pub struct Accelerator {
    bounded: Backend,
    planes: Vec<PlaneTest>,
    kind: BackendKind,
    /// Objects that are spheres placed by a transform: a move must keep
    /// them round.
    placed_spheres: Vec<(u32, Sphere)>,
}

impl Accelerator {
    pub fn build(kind: BackendKind, objects: &[Object]) -> Result<Accelerator, AccelError> {
        Self::build_with(kind, objects, None)
    }

    /// As [`Accelerator::build`], with the grid backend's world resolution
    /// set instead of chosen from the primitive count (ignored by Embree).
    pub fn build_with(
        kind: BackendKind,
        objects: &[Object],
        grid_resolution: Option<[u32; 3]>,
    ) -> Result<Accelerator, AccelError> {
        let mut placed_spheres = Vec::new();
        for (id, object) in objects.iter().enumerate() {
            if let Shape::Sphere(sphere) = &object.shape {
                let round = match &object.placement {
                    Placement::World => continue,
                    Placement::Instance(xf) => placed_sphere(sphere, xf).is_some(),
                    Placement::Moving(motion) => moving_sphere(sphere, motion).is_some(),
                };
                if !round {
                    return Err(AccelError::SphereNotRound { object: id as u32 });
                }
                placed_spheres.push((id as u32, *sphere));
            }
        }
        let bounded = match kind {
            BackendKind::Embree => Backend::Embree(embree::EmbreeIntersector::build(objects)?),
            BackendKind::Grid => {
                Backend::Grid(grid::GridIntersector::build(objects, grid_resolution))
            }
        };
        let planes = objects
            .iter()
            .enumerate()
            .filter_map(|(id, object)| match (&object.shape, &object.placement) {
                (Shape::Plane(plane), Placement::World) => Some((id as u32, *plane)),
                // The scene file keeps planes from moving while the shutter
                // is open; a plane given a motion anyway stands at its first
                // pose.
                (Shape::Plane(plane), Placement::Instance(xf))
                | (Shape::Plane(plane), Placement::Moving(Motion { poses: [xf, ..] })) => Some((
                    id as u32,
                    Plane {
                        point: xf.transform_point3(plane.point),
                        normal: transform_normal(xf, plane.normal),
                    },
                )),
                _ => None,
            })
            .map(|(object, plane)| PlaneTest {
                object,
                plane,
                axis: plane.axis(),
            })
            .collect();
        Ok(Accelerator {
            bounded,
            planes,
            kind,
            placed_spheres,
        })
    }

    pub fn kind(&self) -> BackendKind {
        self.kind
    }

    /// Moves object `object`, which must have been built with a transform
    /// (not a plane), to `transform`. Instanced meshes are not rebuilt; see
    /// [`embree`] for what a move costs there.
    pub fn set_object_transform(
        &mut self,
        object: u32,
        transform: &Affine3A,
    ) -> Result<(), AccelError> {
        self.move_objects(&[(object, *transform)])
    }

    /// Moves several objects at once (each as [`Accelerator::set_object_transform`]),
    /// paying for one re-commit or re-bin. Nothing moves if a sphere's new
    /// transform would not keep it round.
    pub fn move_objects(&mut self, moves: &[(u32, Affine3A)]) -> Result<(), AccelError> {
        let placements: Vec<(u32, Placement)> = moves
            .iter()
            .map(|&(object, xf)| (object, Placement::Instance(xf)))
            .collect();
        self.place_objects(&placements)
    }

    /// Places several objects at once, each built with the same kind of
    /// placement (a transform, or a motion over the shutter), paying for
    /// one re-commit or re-bin. Nothing moves if a sphere's new placement
    /// would not keep it round.
    pub fn place_objects(&mut self, placements: &[(u32, Placement)]) -> Result<(), AccelError> {
        for (object, placement) in placements {
            let sphere = self.placed_spheres.iter().find(|(id, _)| id == object);
            if let Some((_, sphere)) = sphere {
                let round = match placement {
                    Placement::World => true,
                    Placement::Instance(xf) => placed_sphere(sphere, xf).is_some(),
                    Placement::Moving(motion) => moving_sphere(sphere, motion).is_some(),
                };
                if !round {
                    return Err(AccelError::SphereNotRound { object: *object });
                }
            }
        }
        match &mut self.bounded {
            Backend::Embree(embree) => Ok(embree.place_objects(placements)?),
            Backend::Grid(grid) => {
                // False means the grid holds nothing of some object (an
                // empty mesh): nothing to move. Motion transforms are rigid,
                // so always invertible.
                grid.place_objects(placements);
                Ok(())
            }
        }
    }

    fn nearest_plane(&self, ray: &Ray, tmax: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for plane in &self.planes {
            let limit = best.map_or(tmax, |h| h.t);
            if let Some(t) = plane.intersect(ray, limit) {
                best = Some(Hit {
                    t,
                    object: plane.object,
                    prim: 0,
                    u: 0.0,
                    v: 0.0,
                });
            }
        }
        best
    }
}

/// An infinite plane of the scene, ready for ray tests.
struct PlaneTest {
    object: u32,
    plane: Plane,
    /// [`Plane::axis`], found once.
    axis: Option<usize>,
}

impl PlaneTest {
    fn intersect(&self, ray: &Ray, tmax: f32) -> Option<f32> {
        let t = plane_distance(&self.plane, self.axis, ray.origin, ray.dir);
        (t > ray.tmin && t < tmax).then_some(t)
    }

    /// The plane's hit distance in every lane (infinity where it misses),
    /// with the arithmetic of [`plane_distance`] operation for operation,
    /// so single rays and packets agree bit for bit. Planes along an axis
    /// read one coordinate per lane; others work lane-parallel on the
    /// packet's columns, gathered on first need into `columns`.
    #[inline]
    fn distances(
        &self,
        rays: &RayPacket,
        columns: &mut Option<PacketColumns>,
        tmax: &[f32; PACKET_WIDTH],
    ) -> [f32; PACKET_WIDTH] {
        let point = self.plane.point;
        match self.axis {
            Some(0) => axis_distances::<0>(point.x, rays, tmax),
            Some(1) => axis_distances::<1>(point.y, rays, tmax),
            Some(_) => axis_distances::<2>(point.z, rays, tmax),
            None => {
                let columns = columns.get_or_insert_with(|| PacketColumns::new(rays));
                let n = self.plane.normal;
                std::array::from_fn(|lane| {
                    let denom = n.x * columns.dir[0][lane]
                        + n.y * columns.dir[1][lane]
                        + n.z * columns.dir[2][lane];
                    let t = (n.x * (point.x - columns.origin[0][lane])
                        + n.y * (point.y - columns.origin[1][lane])
                        + n.z * (point.z - columns.origin[2][lane]))
                        / denom;
                    in_range(denom, t, columns.tmin[lane], tmax[lane])
                })
            }
        }
    }
}

/// `t` if the denominator it came from is usable and `t` lies in the
/// ray's range, infinity otherwise.
///
/// [`plane_distance`] also rejects a zero denominator; here the range test
/// does that: `t` is then an infinity or NaN, and neither lies strictly
/// inside any range. Spelled `abs != inf` rather than `is_finite() && != 0`,
/// which LLVM turns into a float-class test done lane by lane in integer
/// registers, the finiteness test stays a vector compare.
#[inline]
fn in_range(denom: f32, t: f32, tmin: f32, tmax: f32) -> f32 {
    // `&`, not `&&`: one select instead of four unpredictable branches.
    if (denom.abs() != f32::INFINITY) & (t > tmin) & (t < tmax) {
        t
    } else {
        f32::INFINITY
    }
}

/// Distances to the plane `coordinate K == point` in every lane.
#[inline]
fn axis_distances<const K: usize>(
    point: f32,
    rays: &RayPacket,
    tmax: &[f32; PACKET_WIDTH],
) -> [f32; PACKET_WIDTH] {
    std::array::from_fn(|lane| {
        let ray = &rays[lane];
        let denom = ray.dir[K];
        let t = (point - ray.origin[K]) / denom;
        in_range(denom, t, ray.tmin, tmax[lane])
    })
}

/// A packet's origins, directions and `tmin` by coordinate (one array of
/// eight lanes each), the layout lane-parallel arithmetic wants.
struct PacketColumns {
    origin: [[f32; PACKET_WIDTH]; 3],
    dir: [[f32; PACKET_WIDTH]; 3],
    tmin: [f32; PACKET_WIDTH],
}

impl PacketColumns {
    #[inline]
    fn new(rays: &RayPacket) -> PacketColumns {
        PacketColumns {
            origin: [
                rays.map(|r| r.origin.x),
                rays.map(|r| r.origin.y),
                rays.map(|r| r.origin.z),
            ],
            dir: [
                rays.map(|r| r.dir.x),
                rays.map(|r| r.dir.y),
                rays.map(|r| r.dir.z),
            ],
            tmin: rays.map(|r| r.tmin),
        }
    }
}

/// Lanes whose distance is finite, as a mask.
#[inline]
fn finite_lanes(distances: &[f32; PACKET_WIDTH]) -> LaneMask {
    distances.iter().enumerate().fold(0, |acc, (lane, t)| {
        acc | (u8::from(*t < f32::INFINITY) << lane)
    })
}

impl Intersector for Accelerator {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let hit = self.bounded.intersector().intersect(ray);
        let limit = hit.map_or(ray.tmax, |h| h.t);
        self.nearest_plane(ray, limit).or(hit)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let blocked_by_plane = self
            .planes
            .iter()
            .any(|plane| plane.intersect(ray, ray.tmax).is_some());
        blocked_by_plane || self.bounded.intersector().occluded(ray)
    }

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        self.bounded.intersector().intersect8(rays, mask, hits);
        if self.planes.is_empty() {
            return;
        }
        let mut columns = None;
        let mut limits: [f32; PACKET_WIDTH] =
            std::array::from_fn(|lane| hits[lane].map_or(rays[lane].tmax, |h| h.t));
        for plane in &self.planes {
            let distances = plane.distances(rays, &mut columns, &limits);
            for lane in lanes(mask & finite_lanes(&distances)) {
                limits[lane] = distances[lane];
                hits[lane] = Some(Hit {
                    t: distances[lane],
                    object: plane.object,
                    prim: 0,
                    u: 0.0,
                    v: 0.0,
                });
            }
        }
    }

    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        let mut by_planes: LaneMask = 0;
        if !self.planes.is_empty() {
            let mut columns = None;
            let tmax: [f32; PACKET_WIDTH] = rays.map(|r| r.tmax);
            for plane in &self.planes {
                by_planes |= finite_lanes(&plane.distances(rays, &mut columns, &tmax));
            }
        }
        let by_planes = by_planes & mask;
        let rest = mask & !by_planes;
        if rest == 0 {
            return by_planes;
        }
        by_planes | self.bounded.intersector().occluded8(rays, rest)
    }
}

const _: () = assert!(PACKET_WIDTH == 8, "packet calls below assume 8 lanes");
