//! Camera pose and projections, each with its exact inverse.
//!
//! World frame: y up; yaw 0 looks along -z, positive yaw turns right
//! (toward +x), positive pitch looks up. No roll: the horizon stays level,
//! which is what lets an equal-angle pan be an image shift.
//!
//! Image coordinates are continuous: pixel (x, y) covers [x, x+1) x [y, y+1)
//! and its centre is (x + 0.5, y + 0.5); y grows downward.
//!
//! The equal-angle projection is indexed in *world* azimuth and elevation:
//! column x looks at azimuth `yaw + (x + 0.5 - w/2) * step` and row y at
//! elevation `pitch + (h/2 - y - 0.5) * step`, the same `step` both ways.
//! Pitch slides the window over that map (it is not a rotation), so a pan in
//! either direction moves pixels without changing them.
//!
//! Direction math runs in f64: at a field of view of 0.01 degrees, neighbour
//! pixels differ by 3e-7 rad, near f32's resolution.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt;
use std::str::FromStr;

use glam::{DVec2, DVec3, Vec3};

use crate::ray::Ray;
use crate::sampling::PixelSamples;

mod lens;
mod motion;
mod viewport;

pub use lens::{concentric_disc, Lens};
pub use motion::CameraMotion;

pub use viewport::{TransformError, ViewTransform, Viewport, ViewportPose, MAX_ZOOM, MIN_ZOOM};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Projection {
    /// Pinhole: straight lines stay straight; field of view below 180 degrees.
    Perspective,
    /// Cylindrical equirectangular: every pixel spans the same angle in
    /// azimuth and in elevation (the paper's Panimation projection).
    EqualAngle,
    /// Equidistant fisheye: distance from the image centre is proportional
    /// to the angle from the view axis; up to 360 degrees.
    Fisheye,
}

impl fmt::Display for Projection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Projection::Perspective => "perspective",
            Projection::EqualAngle => "equal-angle",
            Projection::Fisheye => "fisheye",
        })
    }
}

impl FromStr for Projection {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "perspective" => Ok(Projection::Perspective),
            "equal-angle" => Ok(Projection::EqualAngle),
            "fisheye" => Ok(Projection::Fisheye),
            other => Err(format!(
                "unknown projection '{other}' (expected perspective, equal-angle or fisheye)"
            )),
        }
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    #[error("image size {width}x{height}: both sides must be at least 1")]
    EmptyImage { width: u32, height: u32 },
    #[error("image size {width}x{height} is too large (at most {max} pixels per side and {max_pixels} pixels in all)")]
    ImageTooLarge {
        width: u32,
        height: u32,
        max: u32,
        max_pixels: u64,
    },
    #[error("field of view {} degrees: must be a number above 0 and {limit}", tidy_degrees(*fov))]
    FieldOfView { fov: f64, limit: &'static str },
    #[error("field of view {} degrees over {width} pixels: a pixel spans under {:.2e} degrees, finer than the sample lattices count (at most 2^27 samples a turn)", tidy_degrees(*fov), 360.0 / MAX_SAMPLES_PER_TURN as f64)]
    TooFine { fov: f64, width: u32 },
    #[error("equal-angle view spans elevation {low:.3}..{high:.3} degrees: must stay within -90..90 (lower the pitch, the field of view or the height)")]
    ElevationOutOfRange { low: f64, high: f64 },
    #[error("{field} must be finite, got {value}")]
    NotFinite { field: &'static str, value: f64 },
    #[error(
        "{field} = {value:e} lies beyond the scene's extent (within ±{:e} of the origin)",
        crate::geometry::WORLD_LIMIT
    )]
    TooFar { field: &'static str, value: f64 },
}

/// Degrees that went through radians, without the round trip's last-digit
/// noise (500 rather than 500.00000000000006), and far from 1 in
/// scientific notation rather than hundreds of digits.
fn tidy_degrees(degrees: f64) -> String {
    let tidy = (degrees * 1e9).round() / 1e9;
    // Below a billionth of a degree the noise is all there is.
    readable_number(if tidy.is_finite() && (tidy != 0.0 || degrees == 0.0) {
        tidy
    } else {
        degrees
    })
}

/// `value` as a message shows it: far from 1 in scientific notation
/// (`1e300`, `1e-300`), not hundreds of digits.
pub fn readable_number(value: f64) -> String {
    if value != 0.0 && !(1e-6..1e9).contains(&value.abs()) {
        format!("{value:e}")
    } else {
        value.to_string()
    }
}

/// Most samples a whole turn may hold at a camera's angle per pixel: the
/// pan and RSVP lattices count a turn's columns, and the RSVP pyramid's
/// finest level 2^16 times as many, in 43-bit keys. (0.01 degrees over
/// 640 px is 2.3e7; a narrower pixel, 2.7e-6 degrees, is refused.)
pub const MAX_SAMPLES_PER_TURN: i64 = 1 << 27;

/// Largest accepted image side: 32k pixels, and 256 Mpixel in all, checked
/// before any buffer is allocated.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
pub const MAX_IMAGE_PIXELS: u64 = 1 << 28;

#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub projection: Projection,
    pub position: DVec3,
    /// Radians.
    pub yaw: f64,
    /// Radians.
    pub pitch: f64,
    /// Horizontal field of view, radians.
    pub fov: f64,
    pub width: u32,
    pub height: u32,
}

/// The unit vector at world azimuth `az` and elevation `el`.
pub fn direction_from_angles(az: f64, el: f64) -> DVec3 {
    let (sin_az, cos_az) = az.sin_cos();
    let (sin_el, cos_el) = el.sin_cos();
    DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az)
}

/// World azimuth and elevation of a direction (any length): the paper's
/// atan correction, az = atan2(x, -z), el = atan2(y, hypot(x, z)).
pub fn angles_from_direction(d: DVec3) -> (f64, f64) {
    (d.x.atan2(-d.z), d.y.atan2(d.x.hypot(d.z)))
}

/// Yaw and pitch (radians) that look from `from` toward `to`.
pub fn yaw_pitch_toward(from: DVec3, to: DVec3) -> (f64, f64) {
    angles_from_direction(to - from)
}

impl Camera {
    pub fn validate(&self) -> Result<(), CameraError> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Err(CameraError::EmptyImage {
                width: w,
                height: h,
            });
        }
        if w > MAX_IMAGE_SIDE
            || h > MAX_IMAGE_SIDE
            || u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS
        {
            return Err(CameraError::ImageTooLarge {
                width: w,
                height: h,
                max: MAX_IMAGE_SIDE,
                max_pixels: MAX_IMAGE_PIXELS,
            });
        }
        for (field, value) in [
            ("camera.yaw", self.yaw),
            ("camera.pitch", self.pitch),
            ("camera.position.x", self.position.x),
            ("camera.position.y", self.position.y),
            ("camera.position.z", self.position.z),
        ] {
            if !value.is_finite() {
                return Err(CameraError::NotFinite { field, value });
            }
        }
        for (field, value) in [
            ("camera.position.x", self.position.x),
            ("camera.position.y", self.position.y),
            ("camera.position.z", self.position.z),
        ] {
            if (value as f32).abs() > crate::geometry::WORLD_LIMIT {
                return Err(CameraError::TooFar { field, value });
            }
        }
        let fov_deg = self.fov.to_degrees();
        let (ok, limit) = match self.projection {
            Projection::Perspective => {
                (self.fov > 0.0 && self.fov < PI, "below 180 for perspective")
            }
            Projection::EqualAngle => (
                self.fov > 0.0 && self.fov <= TAU,
                "at most 360 for equal-angle",
            ),
            Projection::Fisheye => (self.fov > 0.0 && self.fov <= TAU, "at most 360 for fisheye"),
        };
        if !ok || !self.fov.is_finite() {
            return Err(CameraError::FieldOfView {
                fov: fov_deg,
                limit,
            });
        }
        if TAU / self.angle_step() > MAX_SAMPLES_PER_TURN as f64 {
            return Err(CameraError::TooFine {
                fov: fov_deg,
                width: w,
            });
        }
        if self.projection == Projection::EqualAngle {
            let half = 0.5 * f64::from(h) * self.angle_step();
            let (low, high) = (self.pitch - half, self.pitch + half);
            // A hair of tolerance: exactly 90 degrees from f64 sums is fine.
            if low < -FRAC_PI_2 - 1e-12 || high > FRAC_PI_2 + 1e-12 {
                return Err(CameraError::ElevationOutOfRange {
                    low: low.to_degrees(),
                    high: high.to_degrees(),
                });
            }
        }
        Ok(())
    }

    /// Angle per pixel of the equal-angle projection (radians).
    pub fn angle_step(&self) -> f64 {
        self.fov / f64::from(self.width)
    }

    /// Right, up and forward unit vectors of the camera.
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        let forward = direction_from_angles(self.yaw, self.pitch);
        let right = DVec3::new(self.yaw.cos(), 0.0, self.yaw.sin());
        let up = right.cross(forward);
        (right, up, forward)
    }

    fn half_size(&self) -> DVec2 {
        DVec2::new(f64::from(self.width), f64::from(self.height)) * 0.5
    }

    /// Unit world direction through image point `p`, or None where the
    /// projection has no ray (fisheye corners beyond 180 degrees off-axis).
    pub fn direction(&self, p: DVec2) -> Option<DVec3> {
        let centre = self.half_size();
        match self.projection {
            Projection::EqualAngle => {
                let step = self.angle_step();
                let az = self.yaw + (p.x - centre.x) * step;
                let el = self.pitch + (centre.y - p.y) * step;
                Some(direction_from_angles(az, el))
            }
            Projection::Perspective => {
                let scale = (0.5 * self.fov).tan() / centre.x;
                let (right, up, forward) = self.basis();
                let local = DVec3::new((p.x - centre.x) * scale, (centre.y - p.y) * scale, 1.0);
                Some((right * local.x + up * local.y + forward).normalize())
            }
            Projection::Fisheye => {
                let offset = DVec2::new(p.x - centre.x, centre.y - p.y);
                let r = offset.length();
                let theta = r * (0.5 * self.fov) / centre.x;
                if theta > PI {
                    return None;
                }
                let (right, up, forward) = self.basis();
                let (sin_t, cos_t) = theta.sin_cos();
                let radial = if r > 0.0 { offset / r } else { DVec2::ZERO };
                Some(right * (sin_t * radial.x) + up * (sin_t * radial.y) + forward * cos_t)
            }
        }
    }

    /// The image point a world direction lands on (the inverse of
    /// [`Camera::direction`]); None if the projection cannot show the
    /// direction at all (behind a perspective camera). The point may lie
    /// outside the image rectangle.
    pub fn project(&self, d: DVec3) -> Option<DVec2> {
        let centre = self.half_size();
        match self.projection {
            Projection::EqualAngle => {
                let step = self.angle_step();
                let (az, el) = angles_from_direction(d);
                // Azimuth relative to the view centre, wrapped into (-pi, pi].
                let rel = (az - self.yaw + PI).rem_euclid(TAU) - PI;
                Some(DVec2::new(
                    centre.x + rel / step,
                    centre.y - (el - self.pitch) / step,
                ))
            }
            Projection::Perspective => {
                let (right, up, forward) = self.basis();
                let z = d.dot(forward);
                if z <= 0.0 {
                    return None;
                }
                let scale = (0.5 * self.fov).tan() / centre.x;
                Some(DVec2::new(
                    centre.x + d.dot(right) / z / scale,
                    centre.y - d.dot(up) / z / scale,
                ))
            }
            Projection::Fisheye => {
                let (right, up, forward) = self.basis();
                let local = DVec3::new(d.dot(right), d.dot(up), d.dot(forward));
                let sideways = local.x.hypot(local.y);
                let theta = sideways.atan2(local.z);
                let r = theta * centre.x / (0.5 * self.fov);
                let radial = if sideways > 0.0 {
                    DVec2::new(local.x, local.y) / sideways
                } else {
                    DVec2::ZERO
                };
                Some(DVec2::new(centre.x + r * radial.x, centre.y - r * radial.y))
            }
        }
    }

    /// The primary ray through the centre of pixel (x, y).
    pub fn primary_ray(&self, x: u32, y: u32) -> Option<Ray> {
        let p = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
        self.direction(p)
            .map(|d| Ray::new(self.position.as_vec3(), d.as_vec3()))
    }

    pub fn origin(&self) -> Vec3 {
        self.position.as_vec3()
    }
}

/// A projection's column (or row) terms: (sin, cos) of an angle for the
/// equal-angle projection, (offset, 0) for the perspective one.
type Terms = Vec<(f64, f64)>;

/// Per-frame tables of the separable part of the projections: azimuth and
/// elevation terms depend only on the column or only on the row, so the
/// trigonometry runs w + h times instead of w * h. Directions come out bit
/// for bit as [`Camera::direction`] gives them.
pub struct RayTable {
    camera: Camera,
    columns: Vec<(f64, f64)>,
    rows: Vec<(f64, f64)>,
    /// Antialiased: how many sub-samples a pixel, and the same tables for
    /// each pixel's sub-samples (pixel-major), empty with one sample.
    samples: PixelSamples,
    sample_columns: Vec<(f64, f64)>,
    sample_rows: Vec<(f64, f64)>,
    /// The camera's basis, which costs trigonometry: once per frame, not per ray.
    basis: (DVec3, DVec3, DVec3),
    origin: Vec3,
}

impl RayTable {
    /// The camera's rays through its pixel centres.
    pub fn new(camera: &Camera) -> RayTable {
        RayTable::with_samples(camera, PixelSamples::ONE)
    }

    /// The camera's rays, `samples` a pixel (at offsets keyed by the
    /// pixel's column and row: the camera stands still for them to be
    /// reused).
    pub fn with_samples(camera: &Camera, samples: PixelSamples) -> RayTable {
        let centre_offset = |_: i64, _: u32| 0.5;
        let (columns, rows) = Self::tables(camera, PixelSamples::ONE, centre_offset, centre_offset);
        let (sample_columns, sample_rows) = if samples.count() > 1 {
            Self::tables(
                camera,
                samples,
                |x, k| samples.x(x, k),
                |y, k| samples.y(y, k),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        RayTable {
            camera: camera.clone(),
            columns,
            rows,
            samples,
            sample_columns,
            sample_rows,
            basis: camera.basis(),
            origin: camera.origin(),
        }
    }

    /// The column and row terms of `camera`'s separable projections, one
    /// for each of `samples` sub-samples of each pixel (pixel-major), at
    /// offsets `x_offset(column, index)` and `y_offset(row, index)`.
    fn tables(
        camera: &Camera,
        samples: PixelSamples,
        x_offset: impl Fn(i64, u32) -> f64,
        y_offset: impl Fn(i64, u32) -> f64,
    ) -> (Terms, Terms) {
        let centre = camera.half_size();
        let count = samples.count();
        let xs = (0..camera.width).flat_map(|x| (0..count).map(move |k| (x, k)));
        let ys = (0..camera.height).flat_map(|y| (0..count).map(move |k| (y, k)));
        let px = |(x, k): (u32, u32)| f64::from(x) + x_offset(i64::from(x), k);
        let py = |(y, k): (u32, u32)| f64::from(y) + y_offset(i64::from(y), k);
        match camera.projection {
            Projection::EqualAngle => {
                let step = camera.angle_step();
                (
                    xs.map(|p| (camera.yaw + (px(p) - centre.x) * step).sin_cos())
                        .collect(),
                    ys.map(|p| (camera.pitch + (centre.y - py(p)) * step).sin_cos())
                        .collect(),
                )
            }
            Projection::Perspective => {
                let scale = (0.5 * camera.fov).tan() / centre.x;
                (
                    xs.map(|p| ((px(p) - centre.x) * scale, 0.0)).collect(),
                    ys.map(|p| ((centre.y - py(p)) * scale, 0.0)).collect(),
                )
            }
            Projection::Fisheye => (Vec::new(), Vec::new()),
        }
    }

    /// How many sub-samples a pixel this table's rays take.
    pub fn samples(&self) -> PixelSamples {
        self.samples
    }

    /// The ray of sub-sample `index` of pixel (x, y), which must lie inside
    /// the image (with one sample a pixel: its centre).
    #[inline(always)]
    pub fn sample_ray(&self, x: u32, y: u32, index: u32) -> Option<Ray> {
        let count = self.samples.count();
        if count == 1 {
            return self.primary_ray(x, y);
        }
        let cam = &self.camera;
        let (column, row) = ((x * count + index) as usize, (y * count + index) as usize);
        let d = match cam.projection {
            Projection::EqualAngle => {
                let (sin_az, cos_az) = self.sample_columns[column];
                let (sin_el, cos_el) = self.sample_rows[row];
                DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az)
            }
            Projection::Perspective => {
                let (right, up, forward) = self.basis;
                let lx = self.sample_columns[column].0;
                let ly = self.sample_rows[row].0;
                (right * lx + up * ly + forward).normalize()
            }
            Projection::Fisheye => {
                let p = DVec2::new(
                    f64::from(x) + self.samples.x(i64::from(x), index),
                    f64::from(y) + self.samples.y(i64::from(y), index),
                );
                return Some(Ray::new(self.origin, cam.direction(p)?.as_vec3()));
            }
        };
        Some(Ray::new(self.origin, d.as_vec3()))
    }

    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn size(&self) -> (u32, u32) {
        (self.camera.width, self.camera.height)
    }

    /// The primary ray through the centre of pixel (x, y), which must lie
    /// inside the image.
    /// Inlined always, and no path returns a whole ray from a call: a ray
    /// returned through memory is written in pieces and read back whole, a
    /// store-forwarding stall per ray that costs more than computing it.
    #[inline(always)]
    pub fn primary_ray(&self, x: u32, y: u32) -> Option<Ray> {
        let cam = &self.camera;
        let d = match cam.projection {
            Projection::EqualAngle => {
                let (sin_az, cos_az) = self.columns[x as usize];
                let (sin_el, cos_el) = self.rows[y as usize];
                DVec3::new(cos_el * sin_az, sin_el, -cos_el * cos_az)
            }
            Projection::Perspective => {
                let (right, up, forward) = self.basis;
                let lx = self.columns[x as usize].0;
                let ly = self.rows[y as usize].0;
                (right * lx + up * ly + forward).normalize()
            }
            Projection::Fisheye => {
                return Some(Ray::new(self.origin, self.fisheye_direction(x, y)?))
            }
        };
        Some(Ray::new(self.origin, d.as_vec3()))
    }

    /// As [`Camera::primary_ray`] gives it; kept out of line, away from the
    /// tabled projections.
    #[inline(never)]
    fn fisheye_direction(&self, x: u32, y: u32) -> Option<Vec3> {
        let p = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
        self.camera.direction(p).map(|d| d.as_vec3())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(projection: Projection, fov_deg: f64, width: u32, height: u32) -> Camera {
        Camera {
            projection,
            position: DVec3::new(1.0, 2.0, 3.0),
            yaw: 0.3,
            pitch: -0.1,
            fov: fov_deg.to_radians(),
            width,
            height,
        }
    }

    /// Every pixel centre, and points on the image border, survive
    /// direction -> project to well below a thousandth of a pixel.
    fn assert_round_trip(cam: &Camera) {
        cam.validate().unwrap();
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        let mut points: Vec<DVec2> = (0..cam.height)
            .flat_map(|y| {
                (0..cam.width).map(move |x| DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5))
            })
            .collect();
        for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
            points.extend([
                DVec2::new(t * w, 0.0),
                DVec2::new(t * w, h),
                DVec2::new(0.0, t * h),
                DVec2::new(w, t * h),
            ]);
        }
        let mut checked = 0;
        for p in points {
            let Some(d) = cam.direction(p) else {
                assert_eq!(
                    cam.projection,
                    Projection::Fisheye,
                    "only fisheye corners lack rays"
                );
                continue;
            };
            assert!((d.length() - 1.0).abs() < 1e-12);
            if cam.projection == Projection::Fisheye && d.dot(cam.basis().2) < -1.0 + 1e-12 {
                // The 360-degree fisheye's rim is one direction (straight
                // back): no single point to return to.
                continue;
            }
            let q = cam
                .project(d)
                .unwrap_or_else(|| panic!("{:?}: no projection for {p}", cam.projection));
            let mut err = (q - p).abs();
            if cam.projection == Projection::EqualAngle && cam.fov >= TAU - 1e-12 {
                // A full turn: the left and right borders are the same azimuth.
                err.x = err.x.min((err.x - w).abs());
            }
            assert!(err.max_element() < 1e-6, "{:?} {p} -> {q}", cam.projection);
            checked += 1;
        }
        assert!(checked > 0);
    }

    #[test]
    fn round_trips_across_the_whole_image() {
        for projection in [
            Projection::Perspective,
            Projection::EqualAngle,
            Projection::Fisheye,
        ] {
            for fov in [0.01, 30.0, 100.0, 170.0] {
                assert_round_trip(&camera(projection, fov, 64, 48));
            }
        }
        assert_round_trip(&camera(Projection::Perspective, 179.0, 64, 48));
        assert_round_trip(&camera(Projection::Fisheye, 360.0, 64, 64));
        let mut full_turn = camera(Projection::EqualAngle, 360.0, 72, 30);
        full_turn.pitch = 0.0;
        assert_round_trip(&full_turn);
    }

    #[test]
    fn centre_pixel_looks_forward_and_right_is_right() {
        for projection in [
            Projection::Perspective,
            Projection::EqualAngle,
            Projection::Fisheye,
        ] {
            let cam = camera(projection, 90.0, 64, 64);
            let (right, up, forward) = cam.basis();
            let d = cam.direction(DVec2::new(32.0, 32.0)).unwrap();
            assert!((d - forward).length() < 1e-12);
            let d = cam.direction(DVec2::new(60.0, 32.0)).unwrap();
            assert!(d.dot(right) > 0.5, "{projection:?}");
            let d = cam.direction(DVec2::new(32.0, 4.0)).unwrap();
            assert!(d.dot(up) > 0.5, "{projection:?}");
        }
        let cam = Camera {
            yaw: 0.0,
            pitch: 0.0,
            ..camera(Projection::Perspective, 90.0, 8, 8)
        };
        let (right, up, forward) = cam.basis();
        assert!((forward - DVec3::NEG_Z).length() < 1e-12);
        assert!((right - DVec3::X).length() < 1e-12);
        assert!((up - DVec3::Y).length() < 1e-12);
    }

    #[test]
    fn equal_angle_pixels_span_equal_angles() {
        let cam = camera(Projection::EqualAngle, 100.0, 640, 480);
        let step = cam.angle_step();
        for (a, b) in [((0.5, 240.5), (1.5, 240.5)), ((320.5, 0.5), (320.5, 1.5))] {
            let (az0, el0) = angles_from_direction(cam.direction(DVec2::from(a)).unwrap());
            let (az1, el1) = angles_from_direction(cam.direction(DVec2::from(b)).unwrap());
            let moved = (az1 - az0).abs().max((el1 - el0).abs());
            assert!((moved - step).abs() < 1e-12);
        }
    }

    #[test]
    fn ray_table_matches_direct_rays_bit_for_bit() {
        for projection in [
            Projection::Perspective,
            Projection::EqualAngle,
            Projection::Fisheye,
        ] {
            let cam = camera(projection, 100.0, 40, 30);
            let table = RayTable::new(&cam);
            for y in 0..cam.height {
                for x in 0..cam.width {
                    assert_eq!(
                        table.primary_ray(x, y),
                        cam.primary_ray(x, y),
                        "{projection:?} ({x}, {y})"
                    );
                }
            }
        }
    }

    #[test]
    fn rejects_bad_settings() {
        let bad_fovs = [
            (Projection::Perspective, 180.0),
            (Projection::Perspective, 0.0),
            (Projection::Perspective, -5.0),
            (Projection::EqualAngle, 361.0),
            (Projection::Fisheye, f64::NAN),
        ];
        for (projection, fov) in bad_fovs {
            let err = camera(projection, fov, 64, 48).validate().unwrap_err();
            assert!(matches!(err, CameraError::FieldOfView { .. }), "{err}");
        }
        let err = camera(Projection::Perspective, 60.0, 0, 48)
            .validate()
            .unwrap_err();
        assert!(matches!(err, CameraError::EmptyImage { .. }));
        let err = camera(Projection::Perspective, 60.0, 100_000, 100_000)
            .validate()
            .unwrap_err();
        assert!(matches!(err, CameraError::ImageTooLarge { .. }));
        // 250 degrees wide at 4:3 is 187.5 degrees tall: beyond the poles.
        let err = camera(Projection::EqualAngle, 250.0, 64, 48)
            .validate()
            .unwrap_err();
        assert!(
            matches!(err, CameraError::ElevationOutOfRange { .. }),
            "{err}"
        );
    }
}
