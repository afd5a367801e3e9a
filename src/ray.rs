//! Rays, hits, 8-wide packets, and the scale-aware origin offset for
//! secondary rays.
//!
//! Every backend takes and returns these types, so shading and the reuse
//! algorithms never see a backend's own structures.

use glam::Vec3;

/// Lanes in a ray packet. Eight is native width on the AVX2 machines this
/// project targets (Embree's 16-wide packets would be emulated there).
pub const PACKET_WIDTH: usize = 8;

/// Which lanes of a packet carry a ray (bit `i` = lane `i`).
pub type LaneMask = u8;

/// All eight lanes active.
pub const ALL_LANES: LaneMask = 0xff;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    /// Not necessarily normalized: `t` is measured in units of `dir`.
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
    /// When the ray is cast, as a fraction of the shutter's opening (0 at
    /// its opening, 1 at its closing): what it meets is where moving
    /// objects are then. Every ray of a camera sample's path shares its
    /// camera ray's time; 0 in a scene without a shutter.
    pub time: f32,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
            time: 0.0,
        }
    }

    pub fn segment(origin: Vec3, dir: Vec3, tmax: f32) -> Self {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax,
            time: 0.0,
        }
    }

    /// The ray cast at shutter time `time`.
    pub fn at_time(self, time: f32) -> Ray {
        Ray { time, ..self }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// A placeholder for inactive packet lanes: finite, so no backend trips
    /// over NaNs in lanes it is told to ignore.
    pub const INACTIVE: Ray = Ray {
        origin: Vec3::ZERO,
        dir: Vec3::Z,
        tmin: 0.0,
        tmax: 0.0,
        time: 0.0,
    };
}

/// The closest hit along a ray, in the terms every backend shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Index of the scene object (`Scene::objects`).
    pub object: u32,
    /// Primitive within the object (triangle index; 0 for spheres and planes).
    pub prim: u32,
    /// Barycentric coordinates for triangles: p = (1-u-v) v0 + u v1 + v v2.
    pub u: f32,
    pub v: f32,
}

pub type HitPacket = [Option<Hit>; PACKET_WIDTH];
pub type RayPacket = [Ray; PACKET_WIDTH];

/// Iterates over the lanes set in `mask`, lowest first.
pub fn lanes(mask: LaneMask) -> impl Iterator<Item = usize> {
    let mut rest = mask;
    std::iter::from_fn(move || {
        if rest == 0 {
            return None;
        }
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        Some(lane)
    })
}

/// Relative error bound used for reconstructed hit points: a few ULPs of the
/// largest coordinate involved (the reconstruction does a handful of f32
/// operations, each within half an ULP), with a safety margin.
const HIT_POINT_RELATIVE_ERROR: f32 = 16.0 * f32::EPSILON;

/// Moves a surface point off its surface along `normal` (which must point to
/// the side the new rays leave from), far enough that a ray from there cannot
/// hit the same surface again yet close enough that no nearby geometry is
/// skipped.
///
/// The distance scales with the magnitude of the point (the error of an f32
/// position is relative to its size), in the spirit of Waechter & Binder,
/// Ray Tracing Gems ch. 6 and pbrt's `OffsetRayOrigin`: no fixed epsilon, so
/// scenes at 1e7 from the origin and scenes 1e-4 across both work. `scale`
/// is the magnitude the point was computed from (at least |p|; larger when
/// the point came from larger coordinates, such as a far-away sphere centre).
/// The distance is at least 16 ULPs of that magnitude, so the rounding of the
/// final add (half an ULP) cannot bring the point back onto the surface.
pub fn offset_origin(p: Vec3, normal: Vec3, scale: f32) -> Vec3 {
    p + normal * offset_distance(p.abs().max_element().max(scale))
}

/// How far [`offset_origin`] moves a point whose magnitude (with its
/// `scale`) is `magnitude`.
#[inline]
pub fn offset_distance(magnitude: f32) -> f32 {
    // Never below the smallest normal float: keeps the offset meaningful for
    // a point exactly at the origin.
    (magnitude * HIT_POINT_RELATIVE_ERROR).max(f32::MIN_POSITIVE * 64.0)
}

pub fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let bits = x.to_bits();
    f32::from_bits(if x > 0.0 { bits + 1 } else { bits - 1 })
}

pub fn next_down(x: f32) -> f32 {
    -next_up(-x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_along_the_normal() {
        let p = Vec3::new(1.0, 0.0, 2.0);
        assert!(offset_origin(p, Vec3::Y, 0.0).y > 0.0);
        assert!(offset_origin(p, -Vec3::Y, 0.0).y < 0.0);
        // Every component of a tilted normal moves the point off the plane.
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let q = offset_origin(Vec3::new(3.0, -3.0, 0.0), n, 0.0);
        assert!(q.dot(n) > 0.0);
    }

    #[test]
    fn offset_scales_with_magnitude() {
        for magnitude in [1e-4f32, 1.0, 1e5, 1e7] {
            let p = Vec3::new(magnitude, 0.0, magnitude);
            let q = offset_origin(p, Vec3::Y, 0.0);
            assert!(q.y > 0.0, "offset lost at {magnitude}");
            // Far below the size of any feature at that scale.
            assert!(
                q.y < magnitude * 1e-4,
                "offset {} too big at {magnitude}",
                q.y
            );
        }
    }

    #[test]
    fn lanes_lists_set_bits_in_order() {
        assert_eq!(lanes(0b1010_0101).collect::<Vec<_>>(), vec![0, 2, 5, 7]);
        assert_eq!(lanes(0).count(), 0);
        assert_eq!(lanes(ALL_LANES).count(), PACKET_WIDTH);
    }

    #[test]
    fn next_float_steps() {
        assert!(next_up(1.0) > 1.0);
        assert!(next_down(1.0) < 1.0);
        assert!(next_up(-0.0) > 0.0);
        assert!(next_down(0.0) < 0.0);
        assert_eq!(next_up(next_down(3.5)), 3.5);
    }
}
