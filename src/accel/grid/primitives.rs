//! Ray/primitive tests of the grid backend: a watertight ray/triangle test
//! and a numerically stable ray/sphere test.
//!
//! Promises:
//! - [`WatertightRay::intersect_triangle`] never lets a ray through the shared
//!   edge or vertex of two triangles of a closed mesh (Woop, Benthin & Wald,
//!   "Watertight Ray/Triangle Intersection", JCGT 2013), and reports
//!   barycentrics in Embree's convention: p = (1-u-v) v0 + u v1 + v v2.
//! - [`intersect_sphere`] keeps full precision for spheres tiny or huge next
//!   to their distance from the ray origin (Haines et al., Ray Tracing Gems
//!   ch. 7: the discriminant from the squared distance between the centre
//!   and the line, and the q = b + sign(b) sqrt(disc) form of the roots).
//! - Both accept only `tmin < t < tmax` and are two-sided (no culling). An
//!   origin inside a sphere hits its far side.

use glam::{DVec3, Vec3};

use crate::geometry::Sphere;

/// A ray prepared for watertight triangle tests: the axis permutation and
/// shear that map the ray onto the +z axis, computed once per ray.
///
/// The permute-and-shear is stored as three rows (`x = row_x . p` and so on,
/// each row holding a 1 or `1/d[kz]`, a `-d[k]/d[kz]` and a 0), which gives
/// bit for bit the paper's `p[kx] - Sx * p[kz]` without indexing by
/// run-time axis: the extra product is an exact zero.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: Vec3,
    row_x: Vec3,
    row_y: Vec3,
    row_z: Vec3,
}

/// A ray/triangle hit: distance along the ray (in units of its direction)
/// and Embree-style barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

impl WatertightRay {
    /// `None` for a zero or non-finite direction, which hits nothing.
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3) -> Option<WatertightRay> {
        if !dir.is_finite() || !origin.is_finite() || dir == Vec3::ZERO {
            return None;
        }
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the sheared triangle independent of the sign
        // of the major axis, so det has a consistent meaning.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let (mut row_x, mut row_y, mut row_z) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        row_x[kx] = 1.0;
        let inv_z = 1.0 / dir[kz];
        row_x[kz] = -(dir[kx] * inv_z);
        row_y[ky] = 1.0;
        row_y[kz] = -(dir[ky] * inv_z);
        row_z[kz] = inv_z;
        Some(WatertightRay {
            origin,
            row_x,
            row_y,
            row_z,
        })
    }

    /// The hit with `v0 v1 v2`, if any, strictly inside (`tmin`, `tmax`).
    /// Degenerate triangles (zero area as seen along the ray) never hit.
    #[inline]
    pub fn intersect_triangle(&self, v: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<TriangleHit> {
        let a = v[0] - self.origin;
        let b = v[1] - self.origin;
        let c = v[2] - self.origin;
        // Shear and scale the vertices into ray space (ray along +z).
        let (ax, ay) = (self.row_x.dot(a), self.row_y.dot(a));
        let (bx, by) = (self.row_x.dot(b), self.row_y.dot(b));
        let (cx, cy) = (self.row_x.dot(c), self.row_y.dot(c));
        // Scaled barycentrics: edge functions of the edges opposite v0, v1, v2.
        let mut u = cx * by - cy * bx;
        let mut v_ = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        // A zero edge function may be a rounding artefact on a shared edge:
        // recompute it exactly (products of f32s are exact in f64), so both
        // triangles of the edge agree on its sign.
        if u == 0.0 || v_ == 0.0 || w == 0.0 {
            let f = |x: f32, y: f32, z: f32, t: f32| {
                (f64::from(x) * f64::from(y) - f64::from(z) * f64::from(t)) as f32
            };
            u = f(cx, by, cy, bx);
            v_ = f(ax, cy, ay, cx);
            w = f(bx, ay, by, ax);
        }
        if (u < 0.0 || v_ < 0.0 || w < 0.0) && (u > 0.0 || v_ > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v_ + w;
        if det == 0.0 {
            return None;
        }
        let az = self.row_z.dot(a);
        let bz = self.row_z.dot(b);
        let cz = self.row_z.dot(c);
        let t_scaled = u * az + v_ * bz + w * cz;
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        if !(t > tmin && t < tmax) {
            return None;
        }
        Some(TriangleHit {
            t,
            u: v_ * inv_det,
            v: w * inv_det,
        })
    }
}

/// The nearest `t` strictly inside (`tmin`, `tmax`) where the ray
/// `origin + t * dir` meets the sphere's surface. `dir` need not be
/// normalized. Computed in f64 from the exact f32 inputs, with the stable
/// formulation (no b^2 - 4ac), so a 1e-4 sphere seen from 1e3 away and a 1e4
/// sphere around the origin both keep their hits.
pub fn intersect_sphere(
    sphere: &Sphere,
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<f32> {
    let d = dir.as_dvec3();
    let f: DVec3 = origin.as_dvec3() - sphere.center.as_dvec3();
    let a = d.length_squared();
    if a == 0.0 || !a.is_finite() {
        return None;
    }
    let r = f64::from(sphere.radius);
    let r2 = r * r;
    // Roots of a t^2 - 2 beta t + c = 0.
    let beta = -f.dot(d);
    // The centre's offset from the line, not |f|^2 - beta^2/a: no
    // cancellation when the sphere is small next to its distance.
    let l = f + d * (beta / a);
    let disc = r2 - l.length_squared();
    if disc < 0.0 || !disc.is_finite() {
        return None;
    }
    let c = f.length_squared() - r2;
    let q = beta + (a * disc).sqrt().copysign(beta);
    let (t0, t1) = if q == 0.0 {
        // Tangent at the origin itself (beta == 0 and disc == 0).
        (0.0, 0.0)
    } else {
        let (x, y) = (c / q, q / a);
        (x.min(y), x.max(y))
    };
    [t0, t1]
        .into_iter()
        .map(|t| t as f32)
        .find(|&t| t > tmin && t < tmax)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(o: Vec3, d: Vec3, tri: [Vec3; 3]) -> Option<TriangleHit> {
        WatertightRay::new(o, d)
            .unwrap()
            .intersect_triangle(&tri, 0.0, f32::INFINITY)
    }

    #[test]
    fn triangle_barycentrics_follow_embree_convention() {
        let tri = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        for dir in [
            -Vec3::Z,
            Vec3::new(0.1, -0.2, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ] {
            let p = Vec3::new(0.25, 0.5, 0.0);
            let o = p - dir * 2.0;
            let h = hit(o, dir, tri).unwrap();
            assert!((h.t - 2.0).abs() < 1e-6, "{h:?}");
            let q = (1.0 - h.u - h.v) * tri[0] + h.u * tri[1] + h.v * tri[2];
            assert!((q - p).length() < 1e-6, "{q} vs {p}");
            assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn triangle_respects_open_t_range_and_misses() {
        let tri = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let r = WatertightRay::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z).unwrap();
        assert!(r.intersect_triangle(&tri, 0.0, 2.0).is_none());
        assert!(r.intersect_triangle(&tri, 2.0, 3.0).is_none());
        assert!(r.intersect_triangle(&tri, 1.9, 2.1).is_some());
        // Behind the origin.
        let r = WatertightRay::new(Vec3::new(0.0, 0.0, -2.0), -Vec3::Z).unwrap();
        assert!(r.intersect_triangle(&tri, 0.0, f32::INFINITY).is_none());
        // Beside it.
        assert!(hit(Vec3::new(0.0, 1.5, 2.0), -Vec3::Z, tri).is_none());
        // Degenerate triangles never hit.
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!(hit(Vec3::new(1.0, 0.0, 1.0), -Vec3::Z, line).is_none());
        let point = [Vec3::ZERO; 3];
        assert!(hit(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z, point).is_none());
        // Parallel to the plane of the triangle.
        assert!(hit(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, tri).is_none());
        assert!(WatertightRay::new(Vec3::ZERO, Vec3::ZERO).is_none());
    }

    #[test]
    fn shared_edges_and_vertices_of_a_quad_fan_are_watertight() {
        // A fan of 8 triangles around the centre of a square, every edge
        // shared; rays aimed exactly at the edges and the centre vertex.
        let c = Vec3::new(0.3, -0.2, 0.0);
        let ring: Vec<Vec3> = (0..8)
            .map(|i| {
                let a = i as f32 * std::f32::consts::FRAC_PI_4;
                c + Vec3::new(a.cos(), a.sin(), 0.0) * 1.7
            })
            .collect();
        let tris: Vec<[Vec3; 3]> = (0..8).map(|i| [c, ring[i], ring[(i + 1) % 8]]).collect();
        let mut targets = vec![c];
        for p in &ring {
            for s in [0.1f32, 0.37, 0.5, 0.9] {
                targets.push(c + (*p - c) * s);
            }
        }
        for (i, target) in targets.iter().enumerate() {
            for origin in [
                Vec3::new(0.0, 0.0, 3.0),
                Vec3::new(1.1, 2.3, -0.7),
                Vec3::new(-4.0, 0.5, 0.25),
            ] {
                let dir = *target - origin;
                let ray = WatertightRay::new(origin, dir).unwrap();
                let hits = tris
                    .iter()
                    .filter(|t| ray.intersect_triangle(t, 0.0, f32::INFINITY).is_some())
                    .count();
                assert!(hits >= 1, "target {i} from {origin} slipped through");
            }
        }
    }

    #[test]
    fn sphere_hits_near_side_and_far_side_from_inside() {
        let s = Sphere {
            center: Vec3::new(0.0, 0.0, -5.0),
            radius: 1.0,
        };
        let t = intersect_sphere(&s, Vec3::ZERO, -Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-6);
        // Unnormalized direction: t in units of dir.
        let t = intersect_sphere(&s, Vec3::ZERO, -Vec3::Z * 2.0, 0.0, f32::INFINITY).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        let t = intersect_sphere(&s, s.center, Vec3::X, 0.0, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert_eq!(
            intersect_sphere(&s, Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY),
            None
        );
        assert_eq!(intersect_sphere(&s, Vec3::ZERO, -Vec3::Z, 0.0, 4.0), None);
        assert_eq!(
            intersect_sphere(&s, Vec3::Y * 1.01, -Vec3::Z, 0.0, 10.0),
            None
        );
        // tmin past the near side: the far side.
        let t = intersect_sphere(&s, Vec3::ZERO, -Vec3::Z, 4.5, 10.0).unwrap();
        assert!((t - 6.0).abs() < 1e-6);
    }

    #[test]
    fn tiny_sphere_far_away_is_hit_stably() {
        // Radius 1e-4 at distance 1e3: b^2 - ac would cancel to noise.
        let s = Sphere {
            center: Vec3::new(600.0, 0.0, -800.0),
            radius: 1e-4,
        };
        let origin = Vec3::ZERO;
        let mut hits = 0;
        for i in -4..=4 {
            for j in -4..=4 {
                // Aim at offsets up to 0.8 r from the centre (in world units).
                let off = Vec3::new(i as f32, j as f32, 0.0) * 0.2e-4;
                let dir = s.center + off - origin;
                let t = intersect_sphere(&s, origin, dir, 0.0, f32::INFINITY);
                let t = t.unwrap_or_else(|| panic!("missed at offset {off}"));
                // The near side is within r of the aim point (t ~ 1).
                assert!((t - 1.0).abs() < 2e-7, "t = {t}");
                hits += 1;
            }
        }
        assert_eq!(hits, 81);
        // Aimed at 3 r beside the centre: a miss.
        let dir = s.center + Vec3::new(0.0, 3e-4, 0.0);
        assert_eq!(intersect_sphere(&s, origin, dir, 0.0, f32::INFINITY), None);
        // A normalized direction gives t in world units: 1e3 - r.
        let t = intersect_sphere(&s, origin, s.center.normalize(), 0.0, f32::INFINITY).unwrap();
        assert!((t - (1000.0 - 1e-4)).abs() < 1e-4, "t = {t}");
    }

    #[test]
    fn huge_sphere_near_origin_is_hit_stably() {
        let s = Sphere {
            center: Vec3::new(1.0, -2.0, 0.5),
            radius: 1e4,
        };
        // From inside: the far side, about r away.
        for dir in [Vec3::X, -Vec3::Y, Vec3::new(0.3, 0.4, -0.5).normalize()] {
            let t = intersect_sphere(&s, Vec3::ZERO, dir, 0.0, f32::INFINITY).unwrap();
            let p = dir * t - s.center;
            assert!((p.length() - 1e4).abs() < 2e-3, "{}", p.length());
        }
        // From outside, 5e3 beyond the surface.
        let o = Vec3::new(0.0, 0.0, 1.5e4);
        let t = intersect_sphere(&s, o, -Vec3::Z, 0.0, f32::INFINITY).unwrap();
        let expected = 1.5e4 - (0.5 + (1e8f64 - 5.0).sqrt()) as f32;
        assert!((t - expected).abs() < 2e-3, "{t} vs {expected}");
        // A ray grazing just outside misses, just inside hits.
        let o = Vec3::new(1.0, -2.0 + 1.0001e4, 2e4);
        assert_eq!(intersect_sphere(&s, o, -Vec3::Z, 0.0, f32::INFINITY), None);
        let o = Vec3::new(1.0, -2.0 + 0.9999e4, 2e4);
        assert!(intersect_sphere(&s, o, -Vec3::Z, 0.0, f32::INFINITY).is_some());
    }
}
