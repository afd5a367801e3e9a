//! Where a moving object is while the shutter is open (motion blur).
//!
//! An object that moves during a frame's exposure is given as a few poses
//! at evenly spaced instants of the shutter, from its opening (shutter
//! time 0) to its closing (1). Between two poses its transform is
//! interpolated entry by entry, and a sphere's centre and radius as
//! numbers, the way Embree interpolates an instance's transforms and a
//! sphere's vertices between time steps: the grid, shading and OSTC place
//! the object as Embree does at every shutter time.

use glam::{Affine3A, Vec3};

use super::{Aabb, Sphere};

/// Poses a moving object is given over the shutter. Keyed motion is
/// linear between keys, so two poses would do within a key segment; more
/// follow a bounce's parabola and a segment boundary inside the shutter
/// (a half-frame shutter at frame rate 30 and a one-second hop: the chord
/// of each quarter departs from the arc by under 0.01% of its height).
pub const MOTION_STEPS: usize = 5;

/// An object's transforms at [`MOTION_STEPS`] evenly spaced shutter times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub poses: [Affine3A; MOTION_STEPS],
}

/// The pose before `time` (0 at the shutter's opening, 1 at its closing)
/// and the fraction of the way to the next, as Embree finds them: times
/// outside the shutter hold the first or last segment's ends.
#[inline]
pub fn motion_segment(time: f32) -> (usize, f32) {
    let segments = (MOTION_STEPS - 1) as f32;
    let scaled = time * segments;
    let index = scaled.floor().clamp(0.0, segments - 1.0);
    (index as usize, scaled - index)
}

#[inline]
fn lerp(a: f32, b: f32, f: f32) -> f32 {
    (1.0 - f) * a + f * b
}

impl Motion {
    /// The transform at shutter time `time`.
    pub fn at(&self, time: f32) -> Affine3A {
        let (i, f) = motion_segment(time);
        let (a, b) = (&self.poses[i], &self.poses[i + 1]);
        let cols = |x: [f32; 12], y: [f32; 12]| std::array::from_fn(|k| lerp(x[k], y[k], f));
        Affine3A::from_cols_array(&cols(a.to_cols_array(), b.to_cols_array()))
    }

    /// Whether every pose is the same: the object stands still while the
    /// shutter is open.
    pub fn is_still(&self) -> bool {
        self.poses.iter().all(|pose| *pose == self.poses[0])
    }

    /// Everything `local` (in object space) covers over the shutter. A
    /// point's place is interpolated linearly between its places at two
    /// poses, so it stays inside the union of the box at each pose.
    pub fn swept(&self, local: Aabb) -> Aabb {
        self.poses.iter().fold(Aabb::EMPTY, |swept, pose| {
            swept.union(local.transformed(pose))
        })
    }
}

/// A sphere at each pose of a motion, as every backend traces it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovingSphere {
    pub steps: [Sphere; MOTION_STEPS],
}

impl MovingSphere {
    /// The sphere at shutter time `time`: centre and radius interpolated.
    #[inline]
    pub fn at(&self, time: f32) -> Sphere {
        let (i, f) = motion_segment(time);
        let (a, b) = (&self.steps[i], &self.steps[i + 1]);
        Sphere {
            center: Vec3::new(
                lerp(a.center.x, b.center.x, f),
                lerp(a.center.y, b.center.y, f),
                lerp(a.center.z, b.center.z, f),
            ),
            radius: lerp(a.radius, b.radius, f),
        }
    }

    /// Everything the sphere covers over the shutter.
    pub fn swept(&self) -> Aabb {
        self.steps.iter().fold(Aabb::EMPTY, |swept, s| {
            swept.union(Aabb {
                min: s.center - Vec3::splat(s.radius),
                max: s.center + Vec3::splat(s.radius),
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sliding() -> Motion {
        Motion {
            poses: std::array::from_fn(|k| {
                Affine3A::from_translation(Vec3::new(k as f32, 0.0, 0.0))
            }),
        }
    }

    #[test]
    fn a_motion_passes_through_its_poses_and_between_them_linearly() {
        let motion = sliding();
        let last = (MOTION_STEPS - 1) as f32;
        for k in 0..MOTION_STEPS {
            let at = motion.at(k as f32 / last);
            assert_eq!(at, motion.poses[k], "pose {k}");
        }
        let halfway = motion.at(0.5 / last);
        assert!((halfway.translation.x - 0.5).abs() < 1e-6);
        // Outside the shutter the ends hold.
        assert_eq!(motion.at(-0.5).translation.x, -0.5 * last);
        assert!(!motion.is_still());
    }

    #[test]
    fn the_swept_box_holds_every_place_between_poses() {
        let motion = Motion {
            poses: std::array::from_fn(|k| {
                Affine3A::from_rotation_y(k as f32 * 0.4)
                    * Affine3A::from_translation(Vec3::new(2.0, k as f32, 0.0))
            }),
        };
        let local = Aabb {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        };
        let swept = motion.swept(local);
        for step in 0..=200 {
            let at = motion.at(step as f32 / 200.0);
            let b = local.transformed(&at);
            assert!(swept.min.cmple(b.min + 1e-5).all() && swept.max.cmpge(b.max - 1e-5).all());
        }
    }

    #[test]
    fn a_moving_sphere_interpolates_centre_and_radius() {
        let sphere = MovingSphere {
            steps: std::array::from_fn(|k| Sphere {
                center: Vec3::new(0.0, k as f32, 0.0),
                radius: 1.0 + k as f32,
            }),
        };
        let quarter = sphere.at(0.125);
        assert!((quarter.center.y - 0.5).abs() < 1e-6 && (quarter.radius - 1.5).abs() < 1e-6);
        let swept = sphere.swept();
        assert_eq!(swept.max.y, (MOTION_STEPS - 1) as f32 * 2.0 + 1.0);
    }
}
