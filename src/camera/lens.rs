//! A thin lens: depth of field.
//!
//! Promises:
//! - A lens ray is a pure function of its pinhole ray (the ray from the
//!   eye a pixel's or a lattice sample's position gives), the lens and a
//!   position on the lens, (u, v) in [0, 1)^2: a reused sample's lens
//!   ray is a fresh trace's.
//! - Anchored to the world, not to the camera's turn: the lens disc lies
//!   square to the pinhole ray's own direction, its axes fixed by that
//!   direction alone ([`plane_axes`]), and the surface in focus is the
//!   sphere of radius `focus_distance` about the eye. A pan, which turns
//!   the camera under the same lattice of directions, meets the same lens
//!   rays, and so stays exact.
//! - Every lens ray of a pinhole ray crosses it at the focus distance,
//!   so a point there is sharp, and a point at distance `d` along the
//!   ray images as a disc of angular radius `aperture * |1/d - 1/focus|`
//!   (the thin lens's circle of confusion, in angle).
//! - Lens positions are spread evenly over the disc: (u, v) maps to it by
//!   Shirley and Chiu's concentric map, which keeps strata of the square
//!   strata of the disc.

use crate::geometry::plane_axes;
use crate::ray::Ray;

/// A thin lens at the eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    /// The lens's radius, in scene units (not an f-number: a scene's
    /// units are its own, so a radius says what the blur will be).
    pub aperture: f64,
    /// The distance from the eye that is in focus, along each ray.
    pub focus_distance: f64,
}

impl Lens {
    /// The ray through lens position `(u, v)` ([0, 1)^2) of the pinhole
    /// ray `pinhole`: from that point of the lens disc to where the
    /// pinhole ray meets the focus sphere.
    pub fn ray(&self, pinhole: &Ray, (u, v): (f32, f32)) -> Ray {
        let dir = pinhole.dir.normalize();
        let (across, up) = plane_axes(dir);
        let (x, y) = concentric_disc(u, v);
        let offset = (across * x + up * y) * self.aperture as f32;
        let focus = dir * self.focus_distance as f32;
        Ray {
            origin: pinhole.origin + offset,
            dir: (focus - offset).normalize(),
            ..*pinhole
        }
    }
}

/// Shirley and Chiu's concentric map of the unit square onto the unit
/// disc: squares about the centre go to rings, so strata stay compact.
pub fn concentric_disc(u: f32, v: f32) -> (f32, f32) {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let quarter = std::f32::consts::FRAC_PI_4;
    let (r, angle) = if a.abs() > b.abs() {
        (a, quarter * (b / a))
    } else {
        (b, 2.0 * quarter - quarter * (a / b))
    };
    let (sin, cos) = angle.sin_cos();
    (r * cos, r * sin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn lens() -> Lens {
        Lens {
            aperture: 0.3,
            focus_distance: 4.0,
        }
    }

    #[test]
    fn every_lens_ray_crosses_its_pinhole_ray_at_the_focus_distance() {
        let eye = Vec3::new(1.0, 2.0, 3.0);
        for (i, dir) in [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.3, -0.2, -1.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-2.0, 0.1, 0.5),
        ]
        .into_iter()
        .enumerate()
        {
            let pinhole = Ray::new(eye, dir * (i as f32 + 1.0));
            let focus = eye + dir.normalize() * 4.0;
            for (u, v) in [(0.1, 0.9), (0.5, 0.5), (0.99, 0.02), (0.7, 0.3)] {
                let ray = lens().ray(&pinhole, (u, v));
                assert!((ray.dir.length() - 1.0).abs() < 1e-6);
                let t = (focus - ray.origin).length();
                let missed = (ray.origin + ray.dir * t - focus).length();
                assert!(missed < 1e-5, "{dir} at ({u}, {v}): {missed}");
                // On the lens disc: square to the ray, within the aperture.
                let offset = ray.origin - eye;
                assert!(offset.dot(dir.normalize()).abs() < 1e-6);
                assert!(offset.length() <= 0.3 + 1e-6);
            }
        }
    }

    #[test]
    fn the_concentric_map_fills_the_disc_evenly() {
        // 64 x 64 strata of the square: each lands in the disc, and the
        // share within half the radius is a quarter, as area says.
        let n = 64;
        let mut inner = 0;
        for j in 0..n {
            for i in 0..n {
                let (u, v) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (x, y) = concentric_disc(u, v);
                let r = (x * x + y * y).sqrt();
                assert!(r <= 1.0 + 1e-6);
                inner += usize::from(r < 0.5);
            }
        }
        assert_eq!(inner, n * n / 4);
    }
}
