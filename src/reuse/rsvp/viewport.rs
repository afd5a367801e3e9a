//! Viewports at work: direct renders of their own rays, and the fast map
//! from a pixel to world angles.

use std::f64::consts::FRAC_PI_2;

use glam::{DVec2, DVec3};

use super::{fast_atan2, SampleLattice};
use crate::camera::{Projection, ViewportPose};
use crate::ray::Ray;
use crate::render::{render_image, Frame, PrimaryRays};
use crate::sampling::PixelSamples;
use crate::shade::{RayCounts, Shader};

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
    /// Sub-samples a pixel, at offsets keyed by the viewport's pixel.
    pub samples: PixelSamples,
}

impl ViewportRays<'_> {
    /// The ray through point `(x, y)` of the viewport image, in pixels.
    fn ray_at(&self, col: i64, row: i64, x: f64, y: f64) -> Option<Ray> {
        let cam = &self.pose.camera;
        if !(0..i64::from(cam.width)).contains(&col) || !(0..i64::from(cam.height)).contains(&row) {
            return None;
        }
        self.pose
            .direction(DVec2::new(x, y))
            .map(|d| Ray::new(cam.position.as_vec3(), d.as_vec3()))
    }
}

impl PrimaryRays for ViewportRays<'_> {
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        self.ray_at(col, row, col as f64 + 0.5, row as f64 + 0.5)
    }

    fn samples(&self) -> PixelSamples {
        self.samples
    }

    fn sample(&self, col: i64, row: i64, index: u32) -> Option<Ray> {
        let x = col as f64 + self.samples.x(col, index);
        let y = row as f64 + self.samples.y(row, index);
        self.ray_at(col, row, x, y)
    }
}

/// Traces every pixel of the viewport through its own rays, at the
/// scene's samples a pixel.
pub fn render_direct(shader: &Shader, pose: &ViewportPose) -> (Frame, RayCounts) {
    render_direct_sampled(shader, pose, shader.scene().samples)
}

/// As [`render_direct`], `samples` a pixel.
pub fn render_direct_sampled(
    shader: &Shader,
    pose: &ViewportPose,
    samples: PixelSamples,
) -> (Frame, RayCounts) {
    let (w, h) = (pose.camera.width, pose.camera.height);
    render_image(shader, &ViewportRays { pose, samples }, w, h)
}

/// Maps viewport pixels to world angles cheaply: perspective and
/// equal-angle directions are affine in the pixel position, so a row is a
/// running sum; only fisheye calls the camera per pixel.
pub(super) enum PixelMap {
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
    pub(super) fn new(pose: &ViewportPose) -> PixelMap {
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
    pub(super) fn angles(&self, pose: &ViewportPose, x: u32, y: u32) -> Option<(f64, f64)> {
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
    pub(super) fn lattice_many<const N: usize>(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, ViewTransform};
    use crate::reuse::rsvp::fixtures::*;

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
                let exact = lattice
                    .viewport_coords(&pose, DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
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
}
