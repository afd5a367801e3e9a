//! Ray/scene intersection behind one trait, with two backends: Embree (fast,
//! through FFI) and a pure-Rust uniform grid (readable, the reference).
//!
//! Backends see bounded shapes only. Infinite planes are tested here, once,
//! for every backend ([`Accelerator`]), so both give the same answer for them.

pub mod embree;
pub mod grid;

use std::fmt;
use std::str::FromStr;

use crate::geometry::{intersect_plane, transform_normal, Object, Placement, Plane, Shape};
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
    planes: Vec<(u32, Plane)>,
    kind: BackendKind,
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
                (Shape::Plane(plane), Placement::Instance(xf)) => Some((
                    id as u32,
                    Plane {
                        point: xf.transform_point3(plane.point),
                        normal: transform_normal(xf, plane.normal),
                    },
                )),
                _ => None,
            })
            .collect();
        Ok(Accelerator {
            bounded,
            planes,
            kind,
        })
    }

    pub fn kind(&self) -> BackendKind {
        self.kind
    }

    /// Moves object `object`, which must have been built as an instance
    /// (not a plane), to `transform`; only the top level is rebuilt.
    pub fn set_object_transform(
        &mut self,
        object: u32,
        transform: &glam::Affine3A,
    ) -> Result<(), AccelError> {
        match &mut self.bounded {
            Backend::Embree(embree) => Ok(embree
                .scene_mut()
                .set_instance_transform(object, transform)?),
            Backend::Grid(grid) => {
                // False means the grid holds nothing of the object (an empty
                // mesh): nothing to move. Motion transforms are rigid, so
                // always invertible.
                grid.set_instance_transform(object, transform);
                Ok(())
            }
        }
    }

    fn nearest_plane(&self, ray: &Ray, tmax: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for &(object, ref plane) in &self.planes {
            let limit = best.map_or(tmax, |h| h.t);
            if let Some(t) = intersect_plane(plane, ray.origin, ray.dir, ray.tmin, limit) {
                best = Some(Hit {
                    t,
                    object,
                    prim: 0,
                    u: 0.0,
                    v: 0.0,
                });
            }
        }
        best
    }

    /// For each plane, its hit distance in every lane (infinity where it
    /// misses), computed lane-parallel so the compiler can vectorize it.
    /// Same arithmetic as [`intersect_plane`], so single rays and packets
    /// agree bit for bit.
    fn plane_distances(
        plane: &Plane,
        rays: &RayPacket,
        tmax: &[f32; PACKET_WIDTH],
    ) -> [f32; PACKET_WIDTH] {
        std::array::from_fn(|lane| {
            let ray = &rays[lane];
            let denom = plane.normal.dot(ray.dir);
            let t = plane.normal.dot(plane.point - ray.origin) / denom;
            let valid = denom != 0.0 && denom.is_finite() && t > ray.tmin && t < tmax[lane];
            if valid {
                t
            } else {
                f32::INFINITY
            }
        })
    }
}

impl Intersector for Accelerator {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let hit = self.bounded.intersector().intersect(ray);
        let limit = hit.map_or(ray.tmax, |h| h.t);
        self.nearest_plane(ray, limit).or(hit)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let blocked_by_plane = self.planes.iter().any(|(_, plane)| {
            intersect_plane(plane, ray.origin, ray.dir, ray.tmin, ray.tmax).is_some()
        });
        blocked_by_plane || self.bounded.intersector().occluded(ray)
    }

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        self.bounded.intersector().intersect8(rays, mask, hits);
        for &(object, ref plane) in &self.planes {
            let limits: [f32; PACKET_WIDTH] =
                std::array::from_fn(|lane| hits[lane].map_or(rays[lane].tmax, |h| h.t));
            let distances = Self::plane_distances(plane, rays, &limits);
            for lane in lanes(mask) {
                if distances[lane] < f32::INFINITY {
                    hits[lane] = Some(Hit {
                        t: distances[lane],
                        object,
                        prim: 0,
                        u: 0.0,
                        v: 0.0,
                    });
                }
            }
        }
    }

    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        let tmax: [f32; PACKET_WIDTH] = std::array::from_fn(|lane| rays[lane].tmax);
        let mut by_planes: LaneMask = 0;
        for (_, plane) in &self.planes {
            let distances = Self::plane_distances(plane, rays, &tmax);
            for (lane, t) in distances.iter().enumerate() {
                by_planes |= u8::from(*t < f32::INFINITY) << lane;
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
