//! Viewports described: a view's size, projection and field of view from
//! the scene camera's eye, its 2D transform in its image plane, and the
//! view at one frame ([`ViewportPose`]). Runtime (resampling, direct
//! renders) lives with RSVP.

use std::f64::consts::FRAC_PI_2;

use glam::{DMat2, DVec2, DVec3};

use super::{Camera, CameraError, Projection};

/// Accepted zoom factors.
pub const MIN_ZOOM: f64 = 1e-3;
pub const MAX_ZOOM: f64 = 1e3;

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
                CameraError::EmptyImage { .. } | CameraError::ImageTooLarge { .. } => {
                    "width/height"
                }
                CameraError::ElevationOutOfRange { .. } => "pitch",
                CameraError::FieldOfView { .. } | CameraError::TooFine { .. } => "fov",
                CameraError::NotFinite { .. } => "pitch",
                // The viewport's eye is the camera's, checked with it.
                CameraError::TooFar { .. } => "camera.position",
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

    /// The centre of the viewport image, in pixels.
    pub fn centre(&self) -> DVec2 {
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
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
