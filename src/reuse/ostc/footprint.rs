//! Where a moving object is, for OSTC: its footprint (a ball for a
//! sphere, its box otherwise) and the tests of a recorded ray segment
//! against it.
//!
//! Promises: conservative. A footprint may touch a voxel or meet a segment
//! it does not truly reach (bounds rounded outward, slack past the hit),
//! never the reverse; `Reach` never rules out a segment a footprint meets.

use glam::{DVec3, Vec3};

use crate::geometry::{Aabb, MOTION_STEPS};
use crate::ray::Ray;

use super::{padded_outward, WALK_END_SLACK};

/// Where an object is, as tightly as cheaply known: a ball for spheres
/// (whose bounding box has 48% of its volume outside the sphere), the
/// bounding box otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Footprint {
    Box(Aabb),
    Ball {
        center: Vec3,
        radius: f32,
    },
    /// A sphere moving while the shutter is open: everything within
    /// `radius` (its largest) of the path through its centres at the
    /// motion's poses, which it follows straight between them.
    Path {
        centers: [Vec3; MOTION_STEPS],
        radius: f32,
    },
}

impl Footprint {
    pub fn bounds(&self) -> Aabb {
        match *self {
            Footprint::Box(b) => b,
            Footprint::Ball { center, radius } => Aabb {
                min: center - Vec3::splat(radius),
                max: center + Vec3::splat(radius),
            },
            Footprint::Path { centers, radius } => Aabb {
                min: centers.into_iter().reduce(Vec3::min).unwrap() - Vec3::splat(radius),
                max: centers.into_iter().reduce(Vec3::max).unwrap() + Vec3::splat(radius),
            },
        }
    }

    /// False only if the footprint surely misses `voxel` (with room for
    /// rounding: voxel boxes are computed in f32 too).
    pub(super) fn may_touch(&self, voxel: &Aabb) -> bool {
        match *self {
            Footprint::Box(_) | Footprint::Path { .. } => true,
            Footprint::Ball { center, radius } => {
                let closest = center.clamp(voxel.min, voxel.max);
                let slack = (radius + voxel.extent().max_element()) * 1e-3
                    + center.abs().max_element() * 1e-5;
                (closest - center).length() <= radius + slack
            }
        }
    }
}

impl Footprint {
    /// False only if the segment `ray` (`tmin` to `tmax`, which may be
    /// infinite) surely misses the footprint. In f64, with a slack far
    /// above the rounding of the posed object (its centre and bounds come
    /// out of an f32 transform, Embree intersects in f32) and of the walk's
    /// end (which already lies a little past the hit).
    pub(super) fn meets_segment(&self, ray: &Ray) -> bool {
        let (t0, t1) = (f64::from(ray.tmin), f64::from(ray.tmax));
        // An empty or NaN segment was never walked; keep it anyway.
        if !(t0 <= t1 && t0.is_finite()) {
            return true;
        }
        let origin = ray.origin.as_dvec3();
        let dir = ray.dir.as_dvec3();
        match *self {
            Footprint::Ball { center, radius } => {
                let center = center.as_dvec3();
                let radius = f64::from(radius);
                let dd = dir.length_squared();
                // The segment's point nearest the centre.
                let t = if dd > 0.0 {
                    ((center - origin).dot(dir) / dd).clamp(t0, t1)
                } else {
                    t0
                };
                let nearest = origin + dir * t;
                let slack = radius * 1e-3
                    + (center.abs().max_element() + nearest.abs().max_element()) * 1e-5;
                let distance = (center - nearest).length();
                // A NaN (an overflow) is kept.
                distance <= radius + slack || distance.is_nan()
            }
            Footprint::Path { centers, radius } => {
                let radius = f64::from(radius);
                // Past where the line leaves the path's bounds the segment
                // only moves away: an endless one is cut there.
                let bounds = self.bounds();
                let reach = (bounds.center().as_dvec3() - origin).length()
                    + bounds.extent().as_dvec3().length()
                    + 1.0;
                let t1 = t1.min(t0 + 2.0 * reach / dir.length());
                let (p, q) = (origin + dir * t0, origin + dir * t1);
                centers.windows(2).any(|ends| {
                    let (a, b) = (ends[0].as_dvec3(), ends[1].as_dvec3());
                    let (on_ray, on_path) = closest_points(p, q, a, b);
                    let slack = radius * 1e-3
                        + (a.abs().max(b.abs()).max_element() + on_ray.abs().max_element()) * 1e-5;
                    let distance = (on_ray - on_path).length();
                    // A NaN (an overflow) is kept.
                    distance <= radius + slack || distance.is_nan()
                })
            }
            Footprint::Box(bounds) => {
                let bounds = padded_outward(bounds);
                let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
                let (mut enter, mut exit) = (t0, t1);
                for axis in 0..3 {
                    if dir[axis] == 0.0 {
                        if origin[axis] < lo[axis] || origin[axis] > hi[axis] {
                            return false;
                        }
                        continue;
                    }
                    let a = (lo[axis] - origin[axis]) / dir[axis];
                    let z = (hi[axis] - origin[axis]) / dir[axis];
                    enter = enter.max(a.min(z));
                    exit = exit.min(a.max(z));
                }
                // The box is padded far beyond f64's error in `t`; a NaN
                // (an overflow) is kept.
                enter <= exit || enter.is_nan() || exit.is_nan()
            }
        }
    }
}

/// The closest points of the segments `p`-`q` and `a`-`b` (Ericson,
/// *Real-Time Collision Detection*, 5.1.9), in f64.
fn closest_points(p: DVec3, q: DVec3, a: DVec3, b: DVec3) -> (DVec3, DVec3) {
    let (d1, d2, r) = (q - p, b - a, p - a);
    let (len1, len2, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let (s, t) = if len1 == 0.0 && len2 == 0.0 {
        (0.0, 0.0)
    } else if len1 == 0.0 {
        (0.0, (f / len2).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(r);
        if len2 == 0.0 {
            ((-c / len1).clamp(0.0, 1.0), 0.0)
        } else {
            let cross = d1.dot(d2);
            let denom = len1 * len2 - cross * cross;
            let s = if denom > 0.0 {
                ((cross * f - c * len2) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t = (cross * s + f) / len2;
            if t < 0.0 {
                ((-c / len1).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((cross - c) / len1).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    (p + d1 * s, a + d2 * t)
}

impl Footprint {
    /// True only if the object, whose exact shape this footprint is, surely
    /// blocks the shadow ray `ray` (recorded: its `tmax` carries
    /// [`WALK_END_SLACK`]): the segment passes through a ball well inside
    /// it, its whole chord of the ball grown by the slack of
    /// [`Footprint::meets_segment`] strictly between the segment's ends,
    /// with the same slack again as room. Never for boxes (a bound, not
    /// the shape).
    pub(super) fn surely_blocks(&self, ray: &Ray) -> bool {
        let Footprint::Ball { center, radius } = *self else {
            return false;
        };
        let t0 = f64::from(ray.tmin);
        // The recorded end lies past the light by the walk's slack: undo
        // it, and a little more.
        let t1 = f64::from(ray.tmax) * (1.0 - 3.0 * f64::from(WALK_END_SLACK));
        let origin = ray.origin.as_dvec3();
        let dir = ray.dir.as_dvec3();
        let dd = dir.length_squared();
        if !(t0.is_finite() && t1.is_finite() && t0 < t1 && dd > 0.0 && dd.is_finite()) {
            return false;
        }
        let center = center.as_dvec3();
        let radius = f64::from(radius);
        let closest = (center - origin).dot(dir) / dd;
        let nearest = origin + dir * closest;
        let slack =
            radius * 1e-3 + (center.abs().max_element() + nearest.abs().max_element()) * 1e-5;
        let distance = (center - nearest).length();
        // Well inside: a ray grazing the ball might be missed by rounding
        // (and a NaN settles nothing).
        if distance.is_nan() || distance >= radius - 2.0 * slack {
            return false;
        }
        let grown = radius + slack;
        let half_chord = (grown * grown - distance * distance).sqrt() / dd.sqrt();
        let room = slack / dd.sqrt();
        closest - half_chord > t0 + room && closest + half_chord < t1 - room
    }
}

/// A ball around every footprint of a move, for a quick first test of the
/// recorded segments: a segment whose whole line passes outside it meets
/// none of them. No division and no root: on E4 most segments of the
/// candidate regions pass a ball's length or more from the moving ball.
pub(super) struct Reach {
    center: DVec3,
    radius_squared: f64,
}

impl Reach {
    /// Around the footprints' padded bounds, grown far beyond the slack
    /// [`Footprint::meets_segment`] allows (a hundredth of the size and
    /// 1e-4 of the distance from the origin, against its 1e-3 and 1e-5).
    pub(super) fn around(volumes: &[Footprint]) -> Reach {
        let bounds = volumes
            .iter()
            .map(|volume| padded_outward(volume.bounds()))
            .reduce(Aabb::union)
            .unwrap_or(Aabb {
                min: Vec3::ZERO,
                max: Vec3::ZERO,
            });
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        let center = (min + max) * 0.5;
        let half_diagonal = (max - min).length() * 0.5;
        let radius = half_diagonal * 1.01 + (center.abs().max_element() + half_diagonal) * 1e-4;
        Reach {
            center,
            // No footprint (or a NaN in one): nothing is ruled out.
            radius_squared: if radius.is_finite() && !volumes.is_empty() {
                radius * radius
            } else {
                f64::INFINITY
            },
        }
    }

    /// False only if the line of `ray` surely passes outside the ball (a
    /// segment the exact test would keep whatever it is, empty or NaN,
    /// is kept).
    pub(super) fn may_meet(&self, ray: &Ray) -> bool {
        if !(ray.tmin <= ray.tmax && ray.tmin.is_finite()) {
            return true;
        }
        let to_center = self.center - ray.origin.as_dvec3();
        let dir = ray.dir.as_dvec3();
        let (dd, along) = (dir.length_squared(), to_center.dot(dir));
        // |to_center|^2 - along^2 / dd is the squared distance from the line;
        // times dd, so no division (dd = 0 keeps the segment, as do NaNs).
        let outside = to_center.length_squared() * dd - along * along > self.radius_squared * dd;
        !outside
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prop_oneof;
    use proptest::strategy::Just;

    /// A path meets every segment that meets the sphere at some time
    /// between its poses, and no segment far from all of them.
    #[test]
    fn a_path_meets_what_the_moving_sphere_meets_at_any_time() {
        use crate::geometry::{MovingSphere, Sphere};
        let mut rng = crate::rng::SplitMix64(7);
        let (mut met, mut missed) = (0, 0);
        for _ in 0..2_000 {
            let start = rng.direction() * rng.range(0.0, 5.0);
            let steps: [Sphere; MOTION_STEPS] = std::array::from_fn(|k| Sphere {
                center: start + Vec3::new(k as f32 * 0.4, (k * k) as f32 * 0.1, 0.0),
                radius: 0.5 + 0.05 * k as f32,
            });
            let moving = MovingSphere { steps };
            let path = Footprint::Path {
                centers: steps.map(|s| s.center),
                radius: steps.iter().map(|s| s.radius).fold(0.0, f32::max),
            };
            let origin = rng.direction() * 20.0;
            let aim = start + rng.direction() * rng.range(0.0, 4.0);
            let tmax = if rng.unit() < 0.5 {
                f32::INFINITY
            } else {
                rng.range(0.5, 1.5)
            };
            let ray = Ray {
                origin,
                dir: aim - origin,
                tmin: 0.0,
                tmax,
                time: 0.0,
            };
            let sphere_met = (0..=400).any(|i| {
                let s = moving.at(i as f32 / 400.0);
                Footprint::Ball {
                    center: s.center,
                    radius: s.radius,
                }
                .meets_segment(&ray)
            });
            let path_met = path.meets_segment(&ray);
            assert!(
                !sphere_met || path_met,
                "{ray:?} meets the sphere, not the path"
            );
            met += usize::from(path_met);
            missed += usize::from(!path_met);
        }
        assert!(met > 200 && missed > 200, "{met} met, {missed} missed");
    }

    proptest::proptest! {
        /// The quick ball around a move's footprints never rules out a
        /// segment the exact test keeps: balls and boxes, far from the
        /// origin and near, segments grazing them or from afar.
        #[test]
        fn reach_rules_out_only_segments_that_miss_every_footprint(
            center in proptest::array::uniform3(-50.0f32..50.0),
            offset in proptest::array::uniform3(-1.0f32..1.0),
            radius in 0.01f32..3.0,
            boxed in proptest::bool::ANY,
            origin in proptest::array::uniform3(-200.0f32..200.0),
            aim in proptest::array::uniform3(-4.0f32..4.0),
            t1 in prop_oneof![0.0f32..2.0, Just(f32::INFINITY)],
        ) {
            let center = Vec3::from(center);
            let places = [center, center + Vec3::from(offset) * radius * 2.0];
            let volumes: Vec<Footprint> = places
                .iter()
                .map(|&c| if boxed {
                    Footprint::Box(Aabb { min: c - Vec3::splat(radius), max: c + Vec3::splat(radius) })
                } else {
                    Footprint::Ball { center: c, radius }
                })
                .collect();
            let origin = Vec3::from(origin);
            // Aimed near the first place, so many segments graze it.
            let ray = Ray { origin, dir: center + Vec3::from(aim) * radius - origin, tmin: 0.0, tmax: t1, time: 0.0 };
            let meets = volumes.iter().any(|v| v.meets_segment(&ray));
            proptest::prop_assert!(!meets || Reach::around(&volumes).may_meet(&ray));
        }
    }
}
