//! The shapes a scene is made of, as every backend receives them.
//!
//! Spheres and planes stay analytic (no tessellation). Triangle meshes keep
//! only non-degenerate triangles: the loader drops zero-area ones and counts
//! them, so backends never see a triangle without a normal.

use glam::{Affine3A, Mat3A, Vec2, Vec3};

use crate::ray::{LaneMask, Ray, RayPacket, PACKET_WIDTH};

pub mod cutout;
pub mod motion;
pub mod normals;

pub use cutout::{Coverage, CoverageRef, Cutout};
pub use motion::{motion_segment, Motion, MovingSphere, MOTION_STEPS};

/// How far from the origin a scene may reach, on each axis. Beyond, f32
/// positions lie more than 6e4 apart, and Embree refuses (aborts on) rays
/// whose origin or direction passes 1.8e18: within this every ray, a
/// shadow ray's unnormalised span included, stays far inside.
pub const WORLD_LIMIT: f32 = 1e12;

/// Whether `p` lies within [`WORLD_LIMIT`] of the origin on every axis.
pub fn within_world(p: Vec3) -> bool {
    p.abs().max_element() <= WORLD_LIMIT
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grow(p))
    }

    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The box around this box after an affine transform.
    pub fn transformed(&self, transform: &Affine3A) -> Aabb {
        if self.is_empty() {
            return *self;
        }
        Aabb::from_points((0..8).map(|corner| {
            let pick = |bit: u32, lo: f32, hi: f32| if corner & bit == 0 { lo } else { hi };
            transform.transform_point3(Vec3::new(
                pick(1, self.min.x, self.max.x),
                pick(2, self.min.y, self.max.y),
                pick(4, self.min.z, self.max.z),
            ))
        }))
    }

    /// The lanes of `mask` whose segment (`tmin` to `ends`) may cross this
    /// box: a slab test in f32 that rejects a lane only when the gap between
    /// entry and exit is far beyond the few ulps of rounding each `t`
    /// carries.
    pub fn crossing_lanes(
        &self,
        rays: &RayPacket,
        mask: LaneMask,
        ends: &[f32; PACKET_WIDTH],
    ) -> LaneMask {
        let lanes = |coordinate: &dyn Fn(&Ray) -> f32| -> [f32; PACKET_WIDTH] {
            std::array::from_fn(|lane| coordinate(&rays[lane]))
        };
        let origin = [
            lanes(&|r| r.origin.x),
            lanes(&|r| r.origin.y),
            lanes(&|r| r.origin.z),
        ];
        let dir = [
            lanes(&|r| r.dir.x),
            lanes(&|r| r.dir.y),
            lanes(&|r| r.dir.z),
        ];
        let tmin = lanes(&|r| r.tmin);
        self.crossing_lanes_soa(&origin, &dir, &tmin, ends, mask)
    }

    /// [`Aabb::crossing_lanes`] on a packet already laid out lane-parallel
    /// (axis-major). Culling runs it on every packet, so it is written as
    /// plain selects on whole lanes (`f32::min`'s NaN rules and per-lane
    /// branches block vectorizing).
    pub fn crossing_lanes_soa(
        &self,
        origin: &[[f32; PACKET_WIDTH]; 3],
        dir: &[[f32; PACKET_WIDTH]; 3],
        tmin: &[f32; PACKET_WIDTH],
        ends: &[f32; PACKET_WIDTH],
        mask: LaneMask,
    ) -> LaneMask {
        let mut enter = *tmin;
        let mut exit = *ends;
        // A lane whose slab distances come out NaN (a ray parallel to a slab
        // and starting exactly on it) is kept: the exact test decides.
        let mut undecided = [false; PACKET_WIDTH];
        for axis in 0..3 {
            let (lo, hi) = (self.min[axis], self.max[axis]);
            let (origin, dir) = (&origin[axis], &dir[axis]);
            for lane in 0..PACKET_WIDTH {
                // A zero direction component gives infinite distances of the
                // right signs: no limit from inside the slab, a miss from
                // outside it.
                let inv = 1.0 / dir[lane];
                let a = (lo - origin[lane]) * inv;
                let z = (hi - origin[lane]) * inv;
                undecided[lane] |= a.is_nan() | z.is_nan();
                let (near, far) = if a < z { (a, z) } else { (z, a) };
                enter[lane] = if near > enter[lane] {
                    near
                } else {
                    enter[lane]
                };
                exit[lane] = if far < exit[lane] { far } else { exit[lane] };
            }
        }
        let mut crossing: LaneMask = 0;
        for lane in 0..PACKET_WIDTH {
            let margin = (enter[lane].abs() + exit[lane].abs()) * 1e-5 + f32::MIN_POSITIVE;
            // NaN is unordered, so a NaN entry or exit keeps the lane too.
            let misses = enter[lane] > exit[lane] + margin && !undecided[lane];
            crossing |= LaneMask::from(!misses) << lane;
        }
        crossing & mask
    }
}

#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex shading normals (same length as `positions`), or empty for
    /// flat shading.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates (same length as `positions`), or
    /// empty for a mesh without them. Finite (the loader refuses others);
    /// any value, since textures wrap.
    pub texcoords: Vec<Vec2>,
    /// Where the mesh lets rays through (its material's cut-out map); both
    /// backends skip hits there. `None` for a solid mesh.
    pub cutout: Option<Cutout>,
}

impl TriangleMesh {
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.positions.iter().copied())
    }

    pub fn vertices(&self, prim: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[prim as usize];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The texture coordinates at barycentrics (`u`, `v`) of triangle
    /// `prim`, in the backends' convention (p = (1-u-v) v0 + u v1 + v v2);
    /// `None` for a mesh without texture coordinates.
    #[inline]
    pub fn texcoord(&self, prim: u32, u: f32, v: f32) -> Option<Vec2> {
        if self.texcoords.is_empty() {
            return None;
        }
        let [a, b, c] = self.triangles[prim as usize].map(|i| self.texcoords[i as usize]);
        Some(a * (1.0 - u - v) + b * u + c * v)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// An infinite plane: every point p with `normal . p == offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    /// Unit length.
    pub normal: Vec3,
}

#[derive(Clone, Debug)]
pub enum Shape {
    Mesh(TriangleMesh),
    Sphere(Sphere),
    Plane(Plane),
}

impl Shape {
    /// Object-space bounds; infinite for planes.
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Mesh(mesh) => mesh.bounds(),
            Shape::Sphere(s) => Aabb {
                min: s.center - Vec3::splat(s.radius),
                max: s.center + Vec3::splat(s.radius),
            },
            Shape::Plane(_) => Aabb {
                min: Vec3::splat(f32::NEG_INFINITY),
                max: Vec3::splat(f32::INFINITY),
            },
        }
    }
}

/// How an object is placed in the world.
// A motion's poses make the enum large; a scene holds one per object, and
// staying `Copy` keeps posing a frame free of allocation.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Placement {
    /// The shape is already in world space (static objects: their transform
    /// was applied once at load time).
    World,
    /// The shape is in object space and reaches the world through this
    /// transform; backends build it once and only update the transform when
    /// the object moves.
    Instance(Affine3A),
    /// The shape is in object space and moves while the shutter is open
    /// (motion blur): each ray meets it where its time puts it.
    Moving(Motion),
}

#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub shape: Shape,
    pub material: usize,
    pub placement: Placement,
}

impl Placement {
    /// The object-to-world transform of a ray cast at shutter time `time`;
    /// `None` for a shape already in world space.
    pub fn transform_at(&self, time: f32) -> Option<Affine3A> {
        match self {
            Placement::World => None,
            Placement::Instance(xf) => Some(*xf),
            Placement::Moving(motion) => Some(motion.at(time)),
        }
    }
}

impl Object {
    pub fn world_bounds(&self) -> Aabb {
        match &self.placement {
            Placement::World => self.shape.bounds(),
            Placement::Instance(xf) => self.shape.bounds().transformed(xf),
            Placement::Moving(motion) => motion.swept(self.shape.bounds()),
        }
    }
}

/// A light: a point, or a shape whose surface glows evenly (an area
/// light, which casts soft shadows).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// A point light's position; an area light's centre; a triangle
    /// light's first corner.
    pub position: Vec3,
    /// Colour times intensity.
    pub power: Vec3,
    pub shape: LightShape,
    /// Where the light is and how bright while the shutter is open, when
    /// it changes then (motion blur); `position` and `power` are its
    /// opening's.
    pub motion: Option<LightMotion>,
}

/// A light's positions and powers at [`MOTION_STEPS`] evenly spaced
/// shutter times, interpolated straight between them as a moving
/// object's poses are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightMotion {
    pub positions: [Vec3; MOTION_STEPS],
    pub powers: [Vec3; MOTION_STEPS],
}

impl Light {
    /// A point light whose light does not fall off with distance.
    pub fn point(position: Vec3, power: Vec3) -> Light {
        Light {
            position,
            power,
            shape: LightShape::Point {
                falloff: Falloff::None,
            },
            motion: None,
        }
    }

    /// The light as it stands at shutter time `time` (0 at the opening,
    /// 1 at the closing).
    #[inline]
    pub fn at_time(&self, time: f32) -> Light {
        let Some(motion) = &self.motion else {
            return *self;
        };
        let (i, f) = motion_segment(time);
        let lerp = |a: Vec3, b: Vec3| (1.0 - f) * a + f * b;
        Light {
            position: lerp(motion.positions[i], motion.positions[i + 1]),
            power: lerp(motion.powers[i], motion.powers[i + 1]),
            motion: None,
            ..*self
        }
    }

    /// Whether the light stands anywhere else than `other` at any time of
    /// the shutter (a change of power alone does not move it).
    pub fn moved_from(&self, other: &Light) -> bool {
        self.position != other.position
            || self.motion.map(|m| m.positions) != other.motion.map(|m| m.positions)
    }

    /// Whether the light has an extent (soft shadows, sampled).
    pub fn is_area(&self) -> bool {
        !matches!(self.shape, LightShape::Point { .. })
    }

    /// Whether lighting from it draws anything per shaded point: an area
    /// light's position on it, a falling-off light's weight. Only a plain
    /// point light (the paper's) needs neither.
    pub fn draws_samples(&self) -> bool {
        self.shape
            != (LightShape::Point {
                falloff: Falloff::None,
            })
    }
}

/// How a point light's brightness changes with distance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Falloff {
    /// The same at any distance (the paper's lights).
    #[default]
    None,
    /// As one over the distance squared, reaching `power` at distance 1.
    InverseSquare,
}

/// What a light glows from. Area lights fall off physically: a point far
/// from one gets what an inverse-square point light of the same power
/// would give it (from straight in front, for the flat ones).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightShape {
    Point {
        falloff: Falloff,
    },
    /// A ball of `radius` around the position, glowing to every side.
    Sphere {
        radius: f32,
    },
    /// A rectangle centred on the position, spanned by two perpendicular
    /// half-edges, shining to the side of its unit `normal` only.
    Rectangle {
        half_width: Vec3,
        half_height: Vec3,
        normal: Vec3,
    },
    /// A disc of `radius` centred on the position, shining to the side of
    /// its unit `normal` only.
    Disc {
        radius: f32,
        normal: Vec3,
    },
    /// A triangle with corners at the position and the position plus
    /// each edge, glowing to both sides: an emissive face of a model
    /// (exporters do not agree on which way a face turns, and renderers
    /// that import them light both sides). `normal` is its unit normal.
    Triangle {
        edges: [Vec3; 2],
        normal: Vec3,
    },
}

/// A surface normal carried through an affine transform (by the inverse
/// transpose, so it stays perpendicular under non-uniform scaling); unit
/// length, or zero for a zero normal.
pub fn transform_normal(transform: &Affine3A, n: Vec3) -> Vec3 {
    normal_matrix(transform).mul_vec3(n).normalize_or_zero()
}

/// The matrix [`transform_normal`] multiplies by: worth keeping where many
/// normals go through one transform.
pub fn normal_matrix(transform: &Affine3A) -> Mat3A {
    transform.matrix3.inverse().transpose()
}

/// Two unit vectors spanning the plane with unit normal `n` (a right-handed
/// frame u, v, n), used for finite planes and plane checkers.
pub fn plane_axes(n: Vec3) -> (Vec3, Vec3) {
    let helper = if n.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
    let u = helper.cross(n).normalize();
    let v = n.cross(u);
    (u, v)
}

impl Plane {
    /// The coordinate axis (0, 1 or 2) the normal lies along when it is
    /// exactly one of +-x, +-y, +-z, as ground planes and walls are.
    pub fn axis(&self) -> Option<usize> {
        let n = self.normal.abs();
        [Vec3::X, Vec3::Y, Vec3::Z].iter().position(|&a| n == a)
    }
}

/// Ray/plane intersection shared by all backends (Embree has no infinite
/// primitive, and a huge quad would lose precision far from the eye).
pub fn intersect_plane(
    plane: &Plane,
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<f32> {
    let t = plane_distance(plane, plane.axis(), origin, dir);
    (t > tmin && t < tmax).then_some(t)
}

/// Distance along `dir` from `origin` to `plane`, NaN when the ray runs
/// parallel to it (or `n.d` is not finite). `axis` must be
/// [`Plane::axis`]; the packet tests in [`crate::accel`] repeat this
/// arithmetic operation for operation.
///
/// Along a coordinate axis, `n.(p - o) / n.d` with `n = +-e_k` is exactly
/// `(p_k - o_k) / d_k` for finite rays (the zero terms add nothing and the
/// signs cancel; at most the sign of a zero distance differs, which no
/// range test can tell apart): one subtraction and one division instead of
/// two dot products.
#[inline]
pub fn plane_distance(plane: &Plane, axis: Option<usize>, origin: Vec3, dir: Vec3) -> f32 {
    let (along, denom) = match axis {
        Some(k) => (plane.point[k] - origin[k], dir[k]),
        None => (
            plane.normal.dot(plane.point - origin),
            plane.normal.dot(dir),
        ),
    };
    if denom == 0.0 || !denom.is_finite() {
        return f32::NAN;
    }
    along / denom
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transformed_box_contains_transformed_corners() {
        let b = Aabb {
            min: Vec3::new(-1.0, 0.0, 2.0),
            max: Vec3::new(1.0, 3.0, 4.0),
        };
        let xf =
            Affine3A::from_rotation_y(0.7) * Affine3A::from_translation(Vec3::new(5.0, 1.0, -2.0));
        let t = b.transformed(&xf);
        for p in [b.min, b.max, Vec3::new(b.min.x, b.max.y, b.min.z)] {
            let q = xf.transform_point3(p);
            assert!(q.cmpge(t.min - 1e-5).all() && q.cmple(t.max + 1e-5).all());
        }
    }

    #[test]
    fn plane_hit_and_parallel_miss() {
        let plane = Plane {
            point: Vec3::ZERO,
            normal: Vec3::Y,
        };
        let t = intersect_plane(
            &plane,
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, -1.0, 1.0),
            0.0,
            f32::INFINITY,
        );
        assert_eq!(t, Some(2.0));
        assert_eq!(
            intersect_plane(&plane, Vec3::Y, Vec3::X, 0.0, f32::INFINITY),
            None
        );
        assert_eq!(
            intersect_plane(&plane, Vec3::Y, Vec3::Y, 0.0, f32::INFINITY),
            None
        );
    }

    #[test]
    fn a_light_moves_through_its_poses_and_a_new_motion_is_a_move() {
        let still = Light::point(Vec3::ZERO, Vec3::ONE);
        let motion = LightMotion {
            positions: std::array::from_fn(|step| Vec3::X * step as f32),
            powers: std::array::from_fn(|step| Vec3::ONE * (1.0 + step as f32)),
        };
        let moving = Light {
            motion: Some(motion),
            ..still
        };
        assert_eq!(still.at_time(0.7), still);
        let halfway = moving.at_time(0.5);
        assert_eq!(
            (halfway.position, halfway.power),
            (Vec3::X * 2.0, Vec3::ONE * 3.0)
        );
        assert_eq!(halfway.motion, None);
        assert_eq!(moving.at_time(1.0).position, Vec3::X * 4.0);
        // Standing where it stood at the opening, it moves later on.
        assert!(moving.moved_from(&still) && still.moved_from(&moving));
        let brighter = Light {
            motion: Some(LightMotion {
                powers: [Vec3::ONE; MOTION_STEPS],
                ..motion
            }),
            ..moving
        };
        assert!(!brighter.moved_from(&moving));
    }
}
