//! Viewports: their size, projection and 2D transform, keyframes, the
//! pose at a frame, direct renders of their own rays, and the fast map
//! from a pixel to world angles.

use std::f64::consts::FRAC_PI_2;

use glam::{DMat2, DVec2, DVec3};

use super::{fast_atan2, SampleLattice, MAX_ZOOM, MIN_ZOOM};
use crate::camera::{Camera, Projection};
use crate::ray::Ray;
use crate::render::{render_image, Frame, PrimaryRays};
use crate::shade::{RayCounts, Shader};

/// A viewport: its own image size, projection and field of view, looking
/// from the scene camera's eye, turned by its own yaw and pitch on top of
/// the camera's.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewport {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub projection: Projection,
    /// Horizontal field of view at zoom 1, radians.
    pub fov: f64,
    /// Radians, added to the camera's.
    pub yaw: f64,
    pub pitch: f64,
    /// The transform when no keyframe says otherwise.
    pub transform: ViewTransform,
}

/// A viewport's 2D affine transform in its image plane: the picture is
/// magnified by `zoom`, turned counter-clockwise by `rotate`, sheared by
/// `shear`, and its centre shows the point `translate` (pixels of the
/// unzoomed image, x right, y down).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ViewTransform {
    pub zoom: f64,
    /// Radians.
    pub rotate: f64,
    /// [x by y, y by x].
    pub shear: [f64; 2],
    pub translate: [f64; 2],
}

impl Default for ViewTransform {
    fn default() -> Self {
        ViewTransform {
            zoom: 1.0,
            rotate: 0.0,
            shear: [0.0, 0.0],
            translate: [0.0, 0.0],
        }
    }
}

/// Why a transform cannot be used; the field it is about.
#[derive(Clone, Debug, PartialEq)]
pub struct TransformError {
    pub field: &'static str,
    pub message: String,
}

impl ViewTransform {
    /// Unzoomed image to viewport image (about the image centre).
    pub fn matrix(&self) -> DMat2 {
        let (s, c) = self.rotate.sin_cos();
        // Counter-clockwise as seen, with y growing downward.
        let rotation = DMat2::from_cols(DVec2::new(c, -s), DVec2::new(s, c));
        let shear = DMat2::from_cols(
            DVec2::new(1.0, self.shear[1]),
            DVec2::new(self.shear[0], 1.0),
        );
        rotation * shear * self.zoom
    }

    pub fn validate(&self) -> Result<(), TransformError> {
        let err = |field, message: String| Err(TransformError { field, message });
        if !(self.zoom.is_finite() && (MIN_ZOOM..=MAX_ZOOM).contains(&self.zoom)) {
            return err(
                "zoom",
                format!(
                    "must be within {MIN_ZOOM}..{MAX_ZOOM} (1/1000..1000), got {}",
                    self.zoom
                ),
            );
        }
        if !self.rotate.is_finite() {
            return err("rotate", format!("must be finite, got {}", self.rotate));
        }
        if !self.shear.iter().all(|v| v.is_finite()) {
            return err("shear", format!("must be finite, got {:?}", self.shear));
        }
        if !self.translate.iter().all(|v| v.is_finite()) {
            return err(
                "translate",
                format!("must be finite, got {:?}", self.translate),
            );
        }
        // The shear's determinant: near zero the image collapses to a line.
        let det = 1.0 - self.shear[0] * self.shear[1];
        if det.abs() < 1e-3 {
            return err(
                "shear",
                format!(
                    "{:?} makes the transform singular (1 - sx*sy = {det:.2e}; keep it away from 0)",
                    self.shear
                ),
            );
        }
        Ok(())
    }

    /// Interpolated at `t` in [0, 1]: zoom geometrically (a steady zoom
    /// rate), the rest linearly.
    pub fn lerp(&self, other: &ViewTransform, t: f64) -> ViewTransform {
        let lerp = |a: f64, b: f64| a + (b - a) * t;
        ViewTransform {
            zoom: (lerp(self.zoom.ln(), other.zoom.ln())).exp(),
            rotate: lerp(self.rotate, other.rotate),
            shear: [
                lerp(self.shear[0], other.shear[0]),
                lerp(self.shear[1], other.shear[1]),
            ],
            translate: [
                lerp(self.translate[0], other.translate[0]),
                lerp(self.translate[1], other.translate[1]),
            ],
        }
    }
}

impl Viewport {
    /// Checks size, field of view, elevation and transform against the
    /// scene camera `base`; the error names the field.
    pub fn validate(&self, base: &Camera) -> Result<(), TransformError> {
        let err = |field, message: String| Err(TransformError { field, message });
        if self.width == 0 || self.height == 0 {
            return err(
                "width/height",
                format!(
                    "size {}x{}: both sides must be at least 1",
                    self.width, self.height
                ),
            );
        }
        for (field, value) in [("yaw", self.yaw), ("pitch", self.pitch)] {
            if !value.is_finite() {
                return err(field, format!("must be finite, got {value}"));
            }
        }
        let camera = self.camera(base);
        if camera.pitch.abs() > FRAC_PI_2 {
            return err(
                "pitch",
                format!(
                    "looks at elevation {:.3} degrees (camera pitch plus the viewport's): beyond +-90",
                    camera.pitch.to_degrees()
                ),
            );
        }
        camera.validate().map_err(|e| TransformError {
            field: match e {
                crate::camera::CameraError::EmptyImage { .. }
                | crate::camera::CameraError::ImageTooLarge { .. } => "width/height",
                crate::camera::CameraError::ElevationOutOfRange { .. } => "pitch",
                crate::camera::CameraError::FieldOfView { .. }
                | crate::camera::CameraError::TooFine { .. } => "fov",
                crate::camera::CameraError::NotFinite { .. } => "pitch",
                // The viewport's eye is the camera's, checked with it.
                crate::camera::CameraError::TooFar { .. } => "camera.position",
            },
            message: e.to_string(),
        })?;
        self.validate_transform(base, &self.transform)
    }

    /// Checks `transform` for this viewport under the scene camera `base`:
    /// its own checks, and an equal-angle view's elevation, which the
    /// transform moves (shifted, rotated or zoomed out past a pole, its
    /// pixels would look where the sample buffer has no rows).
    pub fn validate_transform(
        &self,
        base: &Camera,
        transform: &ViewTransform,
    ) -> Result<(), TransformError> {
        transform.validate()?;
        let camera = self.camera(base);
        if camera.projection != Projection::EqualAngle {
            return Ok(());
        }
        let pose = ViewportPose::new(camera, *transform);
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        // Elevation is linear in the unzoomed image's rows: the corners
        // bound it.
        let elevations = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)].map(|(x, y)| {
            let base_point = pose.base_point(DVec2::new(x, y));
            pose.camera.pitch - (base_point.y - 0.5 * h) * pose.camera.angle_step()
        });
        let low = elevations.iter().copied().fold(f64::INFINITY, f64::min);
        let high = elevations.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if low < -FRAC_PI_2 - 1e-9 || high > FRAC_PI_2 + 1e-9 {
            return Err(TransformError {
                field: "zoom/rotate/translate",
                message: format!(
                    "the equal-angle viewport then spans elevation {:.3}..{:.3} degrees: \
                     it must stay within -90..90",
                    low.to_degrees(),
                    high.to_degrees()
                ),
            });
        }
        Ok(())
    }

    /// The viewport's untransformed camera when the scene camera is `base`.
    pub fn camera(&self, base: &Camera) -> Camera {
        Camera {
            projection: self.projection,
            position: base.position,
            yaw: base.yaw + self.yaw,
            pitch: base.pitch + self.pitch,
            fov: self.fov,
            width: self.width,
            height: self.height,
        }
    }

    pub fn pose(&self, base: &Camera, transform: ViewTransform) -> ViewportPose {
        ViewportPose::new(self.camera(base), transform)
    }
}

/// A viewport transform keyframe, fully resolved (unset values carried
/// over from the previous key of the same viewport).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewportKey {
    pub frame: u32,
    pub transform: ViewTransform,
    /// How the segment from this key to the next is eased.
    pub ease: crate::anim::Ease,
}

/// A viewport and its keyframes (in increasing frame order).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewportTrack {
    pub viewport: Viewport,
    pub keys: Vec<ViewportKey>,
}

impl ViewportTrack {
    /// The transform at `frame`, from the frame number alone: the nearest
    /// key outside the keyed range, interpolated between keys.
    pub fn transform_at(&self, frame: u32) -> ViewTransform {
        let keys = &self.keys;
        let Some(first) = keys.first() else {
            return self.viewport.transform;
        };
        let next = keys.partition_point(|k| k.frame <= frame);
        if next == 0 {
            return first.transform;
        }
        let a = &keys[next - 1];
        let Some(b) = keys.get(next) else {
            return a.transform;
        };
        let t = a
            .ease
            .apply(f64::from(frame - a.frame) / f64::from(b.frame - a.frame));
        a.transform.lerp(&b.transform, t)
    }

    /// The viewport at `frame` when the scene camera is `base`.
    pub fn pose_at(&self, base: &Camera, frame: u32) -> ViewportPose {
        self.viewport.pose(base, self.transform_at(frame))
    }
}

/// A viewport at one frame: its camera and 2D transform.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewportPose {
    pub camera: Camera,
    pub transform: ViewTransform,
    /// Viewport image offset from the centre -> unzoomed image offset.
    inverse: DMat2,
}

impl ViewportPose {
    pub fn new(camera: Camera, transform: ViewTransform) -> ViewportPose {
        ViewportPose {
            inverse: transform.matrix().inverse(),
            camera,
            transform,
        }
    }

    fn centre(&self) -> DVec2 {
        DVec2::new(f64::from(self.camera.width), f64::from(self.camera.height)) * 0.5
    }

    /// The point of the unzoomed camera image that viewport point `p` shows.
    pub fn base_point(&self, p: DVec2) -> DVec2 {
        let centre = self.centre();
        centre + self.inverse * (p - centre) + DVec2::from_array(self.transform.translate)
    }

    /// The direction viewport point `p` looks along: its own ray.
    pub fn direction(&self, p: DVec2) -> Option<DVec3> {
        self.camera.direction(self.base_point(p))
    }

    /// Level-0 lattice coordinates of viewport point `p`, by the exact
    /// functions (for level choice and tests).
    pub fn lattice_coords(&self, lattice: &SampleLattice, p: DVec2) -> Option<(f64, f64)> {
        let d = self.direction(p)?;
        let (s, c) = self.camera.yaw.sin_cos();
        let (x, z) = (d.x * c + d.z * s, d.z * c - d.x * s);
        let (rel_az, el) = (x.atan2(-z), d.y.atan2(x.hypot(z)));
        Some(lattice.coords(self.camera.yaw + rel_az, el))
    }
}

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
}

impl PrimaryRays for ViewportRays<'_> {
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let cam = &self.pose.camera;
        if !(0..i64::from(cam.width)).contains(&col) || !(0..i64::from(cam.height)).contains(&row) {
            return None;
        }
        let p = DVec2::new(col as f64 + 0.5, row as f64 + 0.5);
        self.pose
            .direction(p)
            .map(|d| Ray::new(cam.position.as_vec3(), d.as_vec3()))
    }
}

/// Traces every pixel of the viewport through its own rays.
pub fn render_direct(shader: &Shader, pose: &ViewportPose) -> (Frame, RayCounts) {
    let (w, h) = (pose.camera.width, pose.camera.height);
    render_image(shader, &ViewportRays { pose }, w, h)
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
    use crate::reuse::rsvp::fixtures::*;

    #[test]
    fn transforms_invert_and_reject_bad_input() {
        let t = ViewTransform {
            zoom: 3.0,
            rotate: 0.4,
            shear: [0.2, -0.1],
            translate: [5.0, -2.0],
        };
        t.validate().unwrap();
        let m = t.matrix();
        assert!((m * m.inverse() - DMat2::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|v| v.abs() < 1e-12));
        let bad = |t: ViewTransform| t.validate().unwrap_err().field;
        assert_eq!(bad(ViewTransform { zoom: 0.0, ..t }), "zoom");
        assert_eq!(bad(ViewTransform { zoom: 1001.0, ..t }), "zoom");
        assert_eq!(bad(ViewTransform { zoom: 0.000_9, ..t }), "zoom");
        assert_eq!(
            bad(ViewTransform {
                shear: [2.0, 0.5],
                ..t
            }),
            "shear"
        );
        assert_eq!(
            bad(ViewTransform {
                rotate: f64::NAN,
                ..t
            }),
            "rotate"
        );
        ViewTransform { zoom: 1e-3, ..t }.validate().unwrap();
        ViewTransform { zoom: 1e3, ..t }.validate().unwrap();
        // Zoom interpolates at a steady rate.
        let a = ViewTransform { zoom: 1.0, ..t };
        let b = ViewTransform { zoom: 4.0, ..t };
        assert!((a.lerp(&b, 0.5).zoom - 2.0).abs() < 1e-12);
    }

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
                let exact = pose
                    .lattice_coords(&lattice, DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
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
