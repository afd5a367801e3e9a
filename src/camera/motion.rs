//! Where the camera is while the shutter is open (motion blur of a
//! moving camera).
//!
//! A camera ray made for the frame's instant is cast, at its shutter
//! time, through the same image point of the camera as it stands then:
//! the ray's direction is projected through the instant's camera and
//! taken back out through the moving one, and its origin moves as the
//! eye does. The camera is given at a few evenly spaced instants of the
//! shutter and interpolated straight between them, value by value, as
//! moving objects are ([`crate::geometry::Motion`]).

use glam::{DVec3, Vec3};

use super::Camera;
use crate::geometry::{motion_segment, MOTION_STEPS};
use crate::ray::Ray;

/// The camera over a frame's shutter, when it moves then.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraMotion {
    /// The camera the frame's rays are made for: the keyed camera at the
    /// frame's instant.
    instant: Camera,
    /// The camera at [`MOTION_STEPS`] evenly spaced shutter times.
    poses: [Camera; MOTION_STEPS],
}

impl CameraMotion {
    /// The motion of the cameras `poses` (at the shutter's evenly spaced
    /// times) about `instant`; None when they all stand as `instant` does.
    pub fn new(instant: Camera, poses: [Camera; MOTION_STEPS]) -> Option<CameraMotion> {
        let still = poses.iter().all(|pose| *pose == instant);
        (!still).then_some(CameraMotion { instant, poses })
    }

    /// The camera at shutter time `time` (0 at the opening, 1 at the
    /// closing).
    pub fn camera_at(&self, time: f32) -> Camera {
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

    /// `ray`, made for the instant's camera, as the camera casts it at
    /// the ray's time: through the same image point, from where the eye
    /// is then. A ray the instant's camera cannot show (behind a
    /// perspective camera) is left as it is.
    pub fn moved(&self, ray: &Ray) -> Ray {
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
        CameraMotion::new(camera(projection, 0.3, DVec3::ZERO), poses).unwrap()
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
        assert_eq!(CameraMotion::new(still, poses), None);
    }
}
