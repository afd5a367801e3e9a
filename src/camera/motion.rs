//! Where the camera is while the shutter is open (motion blur of a
//! moving camera).
//!
//! A camera ray made for the frame's instant is cast, at its shutter
//! time, through the same image point of the camera as it stands then:
//! the ray's direction is projected through the instant's camera and
//! taken back out through the moving one, and its origin moves as the
//! eye does. The camera is given at a few evenly spaced instants of the
//! shutter and interpolated straight between them, value by value, as
//! moving objects are ([`crate::geometry::Motion`]). An equal-angle
//! camera turning at a steady rate needs none of that: each ray's angles
//! shift by the turn since the frame's instant, the same in every frame
//! of the turn, which is what lets a pan keep its samples.

use glam::{DVec3, Vec3};

use super::{angles_from_direction, direction_from_angles, Camera};
use crate::geometry::{motion_segment, MOTION_STEPS};
use crate::ray::Ray;

/// The camera over a frame's shutter, when it moves then.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraMotion {
    /// An equal-angle camera turning and moving at a steady rate, its
    /// field of view unchanged: at a given shutter time every ray's
    /// azimuth, elevation and origin shift by the same amounts in every
    /// frame of the move, so a sample kept from one of its frames is cast
    /// as a fresh trace of the next frame casts it. Rates per frame; the
    /// shutter's `open` and `close` in frames about the frame's instant.
    Steady {
        yaw: f64,
        pitch: f64,
        position: DVec3,
        open: f64,
        close: f64,
    },
    /// Any other motion, as the camera's poses.
    Posed(Box<PosedMotion>),
}

/// A camera's poses over a frame's shutter.
#[derive(Clone, Debug, PartialEq)]
pub struct PosedMotion {
    /// The camera the frame's rays are made for: the keyed camera at the
    /// frame's instant.
    instant: Camera,
    /// The camera at [`MOTION_STEPS`] evenly spaced shutter times.
    poses: [Camera; MOTION_STEPS],
}

impl CameraMotion {
    /// The motion of the cameras `poses` (at the shutter's evenly spaced
    /// times) about `instant`; None when they all stand as `instant` does.
    pub fn posed(instant: Camera, poses: [Camera; MOTION_STEPS]) -> Option<CameraMotion> {
        let still = poses.iter().all(|pose| *pose == instant);
        (!still).then(|| CameraMotion::Posed(Box::new(PosedMotion { instant, poses })))
    }

    /// `ray`, made for the frame instant's camera, as the camera casts it
    /// at the ray's time: through the same image point, from where the
    /// eye is then. A ray the instant's camera cannot show (behind a
    /// perspective camera) is left as it is.
    pub fn moved(&self, ray: &Ray) -> Ray {
        match self {
            CameraMotion::Steady {
                yaw,
                pitch,
                position,
                open,
                close,
            } => {
                let frames = open + (close - open) * f64::from(ray.time);
                let (az, el) = angles_from_direction(ray.dir.as_dvec3());
                let dir = direction_from_angles(az + yaw * frames, el + pitch * frames);
                Ray {
                    origin: ray.origin + (*position * frames).as_vec3(),
                    dir: dir.as_vec3(),
                    ..*ray
                }
            }
            CameraMotion::Posed(motion) => motion.moved(ray),
        }
    }
}

impl PosedMotion {
    /// The camera at shutter time `time` (0 at the opening, 1 at the
    /// closing).
    fn camera_at(&self, time: f32) -> Camera {
        let (i, f) = motion_segment(time);
        let (a, b) = (&self.poses[i], &self.poses[i + 1]);
        let f = f64::from(f);
        let lerp = |x: f64, y: f64| (1.0 - f) * x + f * y;
        Camera {
            yaw: lerp(a.yaw, b.yaw),
            pitch: lerp(a.pitch, b.pitch),
            fov: lerp(a.fov, b.fov),
            position: DVec3::new(
                lerp(a.position.x, b.position.x),
                lerp(a.position.y, b.position.y),
                lerp(a.position.z, b.position.z),
            ),
            ..a.clone()
        }
    }

    fn moved(&self, ray: &Ray) -> Ray {
        let Some(point) = self.instant.project(ray.dir.as_dvec3()) else {
            return *ray;
        };
        let camera = self.camera_at(ray.time);
        let Some(dir) = camera.direction(point) else {
            return *ray;
        };
        let shift: Vec3 = (camera.position - self.instant.position).as_vec3();
        Ray {
            origin: ray.origin + shift,
            dir: dir.as_vec3(),
            ..*ray
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;

    fn camera(projection: Projection, yaw: f64, position: DVec3) -> Camera {
        Camera {
            projection,
            position,
            yaw,
            pitch: 0.1,
            fov: 1.2,
            width: 64,
            height: 48,
        }
    }

    /// A camera turning by `turn` and moving by `step` over the shutter.
    fn turning(projection: Projection, turn: f64, step: DVec3) -> CameraMotion {
        let poses = std::array::from_fn(|k| {
            let s = k as f64 / (MOTION_STEPS - 1) as f64;
            camera(projection, 0.3 + turn * s, step * s)
        });
        CameraMotion::posed(camera(projection, 0.3, DVec3::ZERO), poses).unwrap()
    }

    #[test]
    fn a_ray_is_cast_through_its_image_point_by_the_camera_of_its_time() {
        for projection in [
            Projection::EqualAngle,
            Projection::Perspective,
            Projection::Fisheye,
        ] {
            let motion = turning(projection, 0.2, DVec3::new(1.0, 0.0, -2.0));
            let instant = camera(projection, 0.3, DVec3::ZERO);
            let point = glam::DVec2::new(20.5, 30.5);
            let ray = Ray::new(
                instant.origin(),
                instant.direction(point).unwrap().as_vec3(),
            );
            for time in [0.0f32, 0.3, 0.5, 0.99] {
                let moved = motion.moved(&ray.at_time(time));
                let then = camera(
                    projection,
                    0.3 + 0.2 * f64::from(time),
                    DVec3::new(1.0, 0.0, -2.0) * f64::from(time),
                );
                let expected = then.direction(point).unwrap().as_vec3();
                assert!(
                    (moved.dir - expected).length() < 1e-5,
                    "{projection:?} at {time}: {} against {expected}",
                    moved.dir
                );
                assert!((moved.origin - then.origin()).length() < 1e-5);
                assert_eq!(moved.time, time);
            }
        }
    }

    #[test]
    fn a_camera_standing_still_through_the_shutter_has_no_motion() {
        let still = camera(Projection::EqualAngle, 0.3, DVec3::ZERO);
        let poses = std::array::from_fn(|_| still.clone());
        assert_eq!(CameraMotion::posed(still, poses), None);
    }

    #[test]
    fn a_steady_turn_shifts_rays_as_the_posed_camera_casts_them() {
        let (yaw, pitch, step) = (0.2, -0.05, DVec3::new(1.0, 0.5, -2.0));
        let (open, close) = (-0.25, 0.25);
        let steady = CameraMotion::Steady {
            yaw,
            pitch,
            position: step,
            open,
            close,
        };
        let at = |frames: f64| Camera {
            yaw: 0.3 + yaw * frames,
            pitch: 0.1 + pitch * frames,
            position: step * frames,
            ..camera(Projection::EqualAngle, 0.0, DVec3::ZERO)
        };
        let poses = std::array::from_fn(|k| {
            at(open + (close - open) * k as f64 / (MOTION_STEPS - 1) as f64)
        });
        let posed = CameraMotion::posed(at(0.0), poses).unwrap();
        let instant = at(0.0);
        for point in [glam::DVec2::new(3.5, 40.5), glam::DVec2::new(60.5, 2.5)] {
            let ray = Ray::new(
                instant.origin(),
                instant.direction(point).unwrap().as_vec3(),
            );
            for time in [0.0f32, 0.4, 0.9] {
                let (a, b) = (
                    steady.moved(&ray.at_time(time)),
                    posed.moved(&ray.at_time(time)),
                );
                assert!(
                    (a.dir - b.dir).length() < 1e-5,
                    "{} against {}",
                    a.dir,
                    b.dir
                );
                assert!((a.origin - b.origin).length() < 1e-5);
            }
        }
    }
}
