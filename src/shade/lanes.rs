//! Packets of hits and colours stored by coordinate (eight lanes of each
//! of x, y and z), so the arithmetic shading does on every lane at once
//! vectorizes: the layout, lane masks as flags, and what lighting and
//! reflection need of each lane's hit.

use glam::Vec3;

use super::GlassLanes;
use super::{Surface, WorldShape};
use crate::ray::{lanes, offset_distance, LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::scene::glass::refract;
use crate::scene::Glass;

pub(super) type Lanes = [f32; PACKET_WIDTH];

/// The mask of lanes where `test` holds.
#[inline]
pub(super) fn lanes_where(test: impl Fn(usize) -> bool) -> LaneMask {
    (0..PACKET_WIDTH).fold(0, |acc, lane| acc | (u8::from(test(lane)) << lane))
}

/// Lane by lane, whether `mask` holds it. A bit test inside a lane loop
/// keeps LLVM from vectorizing the loop; a flag per lane does not.
#[inline]
pub(super) fn lane_flags(mask: LaneMask) -> [bool; PACKET_WIDTH] {
    LANE_FLAGS[usize::from(mask)]
}

/// [`lane_flags`] of every mask, worked out at compile time: one load,
/// where LLVM spreads a mask's bits over lanes with a dozen shuffles.
const LANE_FLAGS: [[bool; PACKET_WIDTH]; 1 << PACKET_WIDTH] = {
    let mut table = [[false; PACKET_WIDTH]; 1 << PACKET_WIDTH];
    let mut mask = 0;
    while mask < table.len() {
        let mut lane = 0;
        while lane < PACKET_WIDTH {
            table[mask][lane] = mask & (1 << lane) != 0;
            lane += 1;
        }
        mask += 1;
    }
    table
};

/// Eight vectors stored by coordinate, so arithmetic on all lanes at once
/// vectorizes. Each operation is glam's, lane by lane, with the same
/// operations in the same order (a dot product is `x*x' + y*y' + z*z'`, a
/// normalization multiplies by `1 / sqrt(dot)`), so results are bit for bit
/// those of [`Vec3`].
#[derive(Clone, Copy, Default)]
pub(super) struct Vec3Lanes {
    pub(super) x: Lanes,
    pub(super) y: Lanes,
    pub(super) z: Lanes,
}

impl Vec3Lanes {
    #[inline]
    pub(super) fn splat(v: Vec3) -> Vec3Lanes {
        Vec3Lanes {
            x: [v.x; PACKET_WIDTH],
            y: [v.y; PACKET_WIDTH],
            z: [v.z; PACKET_WIDTH],
        }
    }

    #[inline]
    pub(super) fn get(&self, lane: usize) -> Vec3 {
        Vec3::new(self.x[lane], self.y[lane], self.z[lane])
    }

    #[inline]
    pub(super) fn set(&mut self, lane: usize, v: Vec3) {
        self.x[lane] = v.x;
        self.y[lane] = v.y;
        self.z[lane] = v.z;
    }

    #[inline]
    pub(super) fn vectors(&self) -> [Vec3; PACKET_WIDTH] {
        std::array::from_fn(|lane| self.get(lane))
    }

    #[inline]
    fn zip(&self, other: &Vec3Lanes, f: impl Fn(f32, f32) -> f32) -> Vec3Lanes {
        Vec3Lanes {
            x: std::array::from_fn(|i| f(self.x[i], other.x[i])),
            y: std::array::from_fn(|i| f(self.y[i], other.y[i])),
            z: std::array::from_fn(|i| f(self.z[i], other.z[i])),
        }
    }

    #[inline]
    pub(super) fn sub(&self, other: &Vec3Lanes) -> Vec3Lanes {
        self.zip(other, |a, b| a - b)
    }

    #[inline]
    pub(super) fn add(&self, other: &Vec3Lanes) -> Vec3Lanes {
        self.zip(other, |a, b| a + b)
    }

    #[inline]
    pub(super) fn mul(&self, other: &Vec3Lanes) -> Vec3Lanes {
        self.zip(other, |a, b| a * b)
    }

    /// `self` in the `pick` lanes, `other` elsewhere.
    #[inline]
    pub(super) fn select(&self, pick: &[bool; PACKET_WIDTH], other: &Vec3Lanes) -> Vec3Lanes {
        let choose = |a: &Lanes, b: &Lanes| -> Lanes {
            std::array::from_fn(|i| if pick[i] { a[i] } else { b[i] })
        };
        Vec3Lanes {
            x: choose(&self.x, &other.x),
            y: choose(&self.y, &other.y),
            z: choose(&self.z, &other.z),
        }
    }

    #[inline]
    pub(super) fn neg(&self) -> Vec3Lanes {
        Vec3Lanes {
            x: self.x.map(|c| -c),
            y: self.y.map(|c| -c),
            z: self.z.map(|c| -c),
        }
    }

    /// Each lane's largest coordinate magnitude, as glam's
    /// `v.abs().max_element()`.
    #[inline]
    pub(super) fn max_magnitude(&self) -> Lanes {
        std::array::from_fn(|i| self.x[i].abs().max(self.y[i].abs().max(self.z[i].abs())))
    }

    /// Each lane times its own scalar.
    #[inline]
    pub(super) fn scale(&self, s: &Lanes) -> Vec3Lanes {
        Vec3Lanes {
            x: std::array::from_fn(|i| self.x[i] * s[i]),
            y: std::array::from_fn(|i| self.y[i] * s[i]),
            z: std::array::from_fn(|i| self.z[i] * s[i]),
        }
    }

    #[inline]
    pub(super) fn dot(&self, other: &Vec3Lanes) -> Lanes {
        std::array::from_fn(|i| {
            (self.x[i] * other.x[i]) + (self.y[i] * other.y[i]) + (self.z[i] * other.z[i])
        })
    }

    #[inline]
    pub(super) fn normalize(&self) -> Vec3Lanes {
        let recip = self.dot(self).map(|d| 1.0 / d.sqrt());
        self.scale(&recip)
    }
}

/// `d` mirrored about `n`, lane by lane: `d - n * (2 (d.n))`.
#[inline(always)]
pub(super) fn reflect_lanes(d: &Vec3Lanes, n: &Vec3Lanes) -> Vec3Lanes {
    let twice = d.dot(n).map(|c| 2.0 * c);
    d.sub(&n.scale(&twice))
}

/// What lighting and reflection need of each lane's hit, by coordinate.
#[derive(Default)]
pub(super) struct HitLanes {
    pub(super) point: Vec3Lanes,
    pub(super) geometric_normal: Vec3Lanes,
    pub(super) shading_normal: Vec3Lanes,
    pub(super) spawn_point: Vec3Lanes,
    pub(super) shadow_point: Vec3Lanes,
    pub(super) albedo: Vec3Lanes,
    /// The incoming ray's direction; unit once
    /// [`HitLanes::normalize_directions`] has run.
    pub(super) direction: Vec3Lanes,
    pub(super) material: [u32; PACKET_WIDTH],
    /// The material's highlight cutoff and reflectivity.
    pub(super) cutoff: Lanes,
    pub(super) reflectivity: Lanes,
    /// Scenes with glass only: each lane's glass, if its material is
    /// transparent, and whether the ray arrived on the front face.
    pub(super) glass: [Option<Glass>; PACKET_WIDTH],
    pub(super) front_face: [bool; PACKET_WIDTH],
    /// Scenes with area lights or glossy surfaces only: each lane's path
    /// key, which their samples are drawn from (`super::draws`).
    pub(super) path: [u64; PACKET_WIDTH],
    /// The incoming ray's shutter time, which every ray leaving the hit
    /// keeps.
    pub(super) time: Lanes,
}

impl HitLanes {
    /// Toward a light at `light` (a point per lane): the facing term `n_s . (light - point)`
    /// (the light is in front where it is positive; by the shading normal,
    /// which is the geometric one except on smooth triangles, where a
    /// light below a facet's plane still lights the curved surface it
    /// stands for, and the shadow ray from the lifted shadow point decides),
    /// the direction the
    /// light falls from (from the points themselves: the spawn points sit
    /// off the surface by an amount that grows with the distance from the
    /// origin, 19 units at 1e7, enough to bend the cosines), and the shadow
    /// rays' directions, from the shadow points to the light (so the
    /// segment ends at t = 1).
    ///
    /// The lighting math is kept out of line (here, [`HitLanes::cosines`]
    /// and [`add_light`]): inlined into `shade_lanes`, these lanes are left
    /// to LLVM's SLP vectorizer, which shapes them anew whenever the code
    /// around them changes, at times into split halves and shuffles.
    #[inline(never)]
    pub(super) fn toward(&self, light: &Vec3Lanes) -> (Lanes, Vec3Lanes, Vec3Lanes) {
        let from_point = light.sub(&self.point);
        let facing = self.shading_normal.dot(&from_point);
        (facing, from_point, light.sub(&self.shadow_point))
    }

    /// Where mirror reflections leave: the incoming direction mirrored
    /// about the shading normal, or about the geometric normal where an
    /// interpolated normal would bend the reflection into the surface.
    #[inline(never)]
    pub(super) fn mirror_directions(&self) -> Vec3Lanes {
        let d = &self.direction;
        let by_shading = reflect_lanes(d, &self.shading_normal);
        let by_geometry = reflect_lanes(d, &self.geometric_normal);
        let bent = by_shading.dot(&self.geometric_normal).map(|c| c <= 0.0);
        by_geometry.select(&bent, &by_shading)
    }

    /// The glass lanes among `hit_mask`: Fresnel reflectance and the
    /// refracted rays, bent by Snell's law about the shading normal (about
    /// the geometric one where the shading normal would send the ray back
    /// out on the side it came from), leaving from the far side of the
    /// surface. Going in through the front face, the index ratio is
    /// 1 / ior; coming out, ior.
    pub(super) fn glass_lanes(&self, hit_mask: LaneMask) -> GlassLanes {
        let mut out = GlassLanes::default();
        for lane in lanes(hit_mask) {
            let Some(glass) = self.glass[lane] else {
                continue;
            };
            let d = self.direction.get(lane);
            let geometric = self.geometric_normal.get(lane);
            let eta = if self.front_face[lane] {
                1.0 / glass.ior
            } else {
                glass.ior
            };
            let (mut reflectance, mut bent) = refract(d, self.shading_normal.get(lane), eta);
            if bent.is_some_and(|t| t.dot(geometric) >= 0.0) {
                (reflectance, bent) = refract(d, geometric, eta);
            }
            out.lanes |= 1 << lane;
            if reflectance > 0.0 {
                out.reflecting |= 1 << lane;
            }
            if let Some(t) = bent {
                out.refracting |= 1 << lane;
                // The spawn point mirrored through the surface: as far
                // below it as rays leaving the near side start above it.
                let point = self.point.get(lane);
                let through = point + (point - self.spawn_point.get(lane));
                out.rays[lane] = Ray::new(through, t).at_time(self.time[lane]);
            }
            out.eta[lane] = eta;
            out.transparency[lane] = glass.transparency;
            out.reflectance[lane] = reflectance;
            out.filter[lane] = if self.front_face[lane] {
                glass.filter
            } else {
                Vec3::ONE
            };
        }
        out
    }

    /// Makes every lane's direction unit length, all lanes at once rather
    /// than one per hit. Lanes without a hit hold their ray's direction,
    /// which nothing reads.
    #[inline(never)]
    pub(super) fn normalize_directions(&mut self) {
        self.direction = self.direction.normalize();
    }

    /// Lambert's `n . l`, clamped at zero, and Phong's `r . v` for light
    /// arriving along `to_light`.
    #[inline(never)]
    pub(super) fn cosines(&self, to_light: &Vec3Lanes) -> (Lanes, Lanes) {
        let n = &self.shading_normal;
        let l = to_light.normalize();
        let n_dot_l = n.dot(&l).map(|c| c.max(0.0));
        let view = self.direction.neg();
        let r_dot_v = reflect_lanes(&l.neg(), n).dot(&view);
        (n_dot_l, r_dot_v)
    }

    #[inline]
    pub(super) fn set(&mut self, lane: usize, surface: &Surface, albedo: Vec3) {
        self.point.set(lane, surface.point);
        self.geometric_normal.set(lane, surface.geometric_normal);
        self.shading_normal.set(lane, surface.shading_normal);
        self.spawn_point.set(lane, surface.spawn_point);
        self.shadow_point.set(lane, surface.shadow_point);
        self.albedo.set(lane, albedo);
        self.front_face[lane] = surface.front_face;
    }
}

/// A packet's rays by coordinate: origins and directions.
pub(super) struct RayColumns {
    pub(super) origin: Vec3Lanes,
    pub(super) direction: Vec3Lanes,
}

impl RayColumns {
    #[inline]
    pub(super) fn new(rays: &RayPacket) -> RayColumns {
        let column = |f: &dyn Fn(&Ray) -> f32| -> Lanes { std::array::from_fn(|i| f(&rays[i])) };
        RayColumns {
            origin: Vec3Lanes {
                x: column(&|r| r.origin.x),
                y: column(&|r| r.origin.y),
                z: column(&|r| r.origin.z),
            },
            direction: Vec3Lanes {
                x: column(&|r| r.dir.x),
                y: column(&|r| r.dir.y),
                z: column(&|r| r.dir.z),
            },
        }
    }
}

/// The hits of a packet on spheres and planes, the shapes whose surface is
/// a formula, reconstructed on all lanes at once. Each lane is given its
/// shape's numbers one by one ([`AnalyticHits::add`]);
/// [`AnalyticHits::reconstruct`] then does what [`WorldShape::surface`]
/// does for one hit, with the same operations in the same order, so the
/// surfaces come out bit for bit the same.
#[derive(Default)]
pub(super) struct AnalyticHits {
    /// Lanes on a plane; the others are on a sphere.
    on_plane: [bool; PACKET_WIDTH],
    /// A sphere's centre, a plane's origin.
    anchor: Vec3Lanes,
    plane_normal: Vec3Lanes,
    radius: Lanes,
    /// A sphere's scale, a plane's origin scale (for `offset_origin`).
    scale: Lanes,
    t: Lanes,
}

impl AnalyticHits {
    /// Gives `lane` its hit at distance `t` on `shape`, if `shape` is a
    /// sphere or a plane; false (and nothing given) on a mesh.
    #[inline]
    pub(super) fn add(&mut self, lane: usize, shape: &WorldShape, t: f32) -> bool {
        match *shape {
            WorldShape::Sphere {
                center,
                radius,
                scale,
            } => {
                self.on_plane[lane] = false;
                self.anchor.set(lane, center);
                self.radius[lane] = radius;
                self.scale[lane] = scale;
            }
            WorldShape::Plane {
                origin,
                normal,
                origin_scale,
                ..
            } => {
                self.on_plane[lane] = true;
                self.anchor.set(lane, origin);
                self.plane_normal.set(lane, normal);
                self.scale[lane] = origin_scale;
            }
            WorldShape::Mesh { .. } => return false,
        }
        self.t[lane] = t;
        true
    }

    /// The surfaces of the `keep` lanes, written into `hits`: point,
    /// normals (geometric and shading are one on these shapes), spawn and
    /// shadow points, and which face the ray arrived on.
    #[inline(never)]
    pub(super) fn reconstruct(
        &self,
        rays: &RayColumns,
        keep: &[bool; PACKET_WIDTH],
        hits: &mut HitLanes,
    ) {
        let (origin, direction) = (&rays.origin, &rays.direction);
        let rough = origin.add(&direction.scale(&self.t));
        // Spheres: the point put back on the sphere along its normal.
        let outward = rough.sub(&self.anchor).normalize();
        let on_sphere = self.anchor.add(&outward.scale(&self.radius));
        // Planes: the point projected back onto the plane; the offset
        // scales with the ray's origin too, which the point came from.
        let normal = &self.plane_normal;
        let height = normal.dot(&rough.sub(&self.anchor));
        let on_plane = rough.sub(&normal.scale(&height));
        let origin_scale = origin.max_magnitude();
        let plane_scale: Lanes = std::array::from_fn(|i| self.scale[i].max(origin_scale[i]));

        let point = on_plane.select(&self.on_plane, &on_sphere);
        let normal = normal.select(&self.on_plane, &outward);
        let scale: Lanes = std::array::from_fn(|i| {
            if self.on_plane[i] {
                plane_scale[i]
            } else {
                self.scale[i]
            }
        });
        let facing = normal
            .dot(direction)
            .map(|cos| if cos > 0.0 { -1.0 } else { 1.0 });
        let facing_normal = normal.scale(&facing);
        let magnitude = point.max_magnitude();
        let distance: Lanes = std::array::from_fn(|i| offset_distance(magnitude[i].max(scale[i])));
        let spawn = point.add(&facing_normal.scale(&distance));

        hits.point = point.select(keep, &hits.point);
        hits.geometric_normal = facing_normal.select(keep, &hits.geometric_normal);
        hits.shading_normal = facing_normal.select(keep, &hits.shading_normal);
        hits.spawn_point = spawn.select(keep, &hits.spawn_point);
        hits.shadow_point = spawn.select(keep, &hits.shadow_point);
        for lane in 0..PACKET_WIDTH {
            if keep[lane] {
                hits.front_face[lane] = facing[lane] > 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Quat};

    use super::*;
    use crate::geometry::{Object, Placement, Plane, Shape, Sphere};
    use crate::ray::Hit;
    use crate::rng::SplitMix64;

    /// A sphere or a plane somewhere within `reach` of the origin, in world
    /// space or placed by a transform, and a point on it.
    fn shape_and_point(rng: &mut SplitMix64, reach: f32) -> (Object, Vec3) {
        let anchor = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let anchor = anchor * reach;
        let placement = if rng.unit() < 0.3 {
            let turn = Quat::from_axis_angle(rng.direction(), rng.range(0.0, 3.0));
            Placement::Instance(Affine3A::from_rotation_translation(turn, anchor * 0.5))
        } else {
            Placement::World
        };
        let (shape, point) = if rng.unit() < 0.5 {
            let radius = rng.range(0.01, 2.0) * reach.max(1.0) * 0.1;
            let sphere = Sphere {
                center: anchor,
                radius,
            };
            (Shape::Sphere(sphere), anchor + rng.direction() * radius)
        } else {
            // Along an axis half the time: the ground planes of scenes.
            let normal = if rng.unit() < 0.5 {
                Vec3::Y
            } else {
                rng.direction()
            };
            let along = rng.direction().reject_from(normal) * reach;
            (
                Shape::Plane(Plane {
                    point: anchor,
                    normal,
                }),
                anchor + along,
            )
        };
        let point = placement
            .transform_at(0.0)
            .map_or(point, |xf| xf.transform_point3(point));
        let object = Object {
            name: String::new(),
            shape,
            material: 0,
            placement,
        };
        (object, point)
    }

    /// Packets of hits on spheres and planes, near the origin and far from
    /// it, met from either side: reconstructed lane-parallel they are the
    /// surfaces the one-hit path gives, bit for bit.
    #[test]
    fn analytic_hits_are_the_surfaces_of_single_hits() {
        let mut rng = SplitMix64(0x5eed);
        for round in 0..3000 {
            let reach = [1.0, 40.0, 1e4, 3e6][round % 4];
            let lanes_of: Vec<(Object, Vec3)> = (0..PACKET_WIDTH)
                .map(|_| shape_and_point(&mut rng, reach))
                .collect();
            let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
            let mut hits = [Hit {
                t: 0.0,
                object: 0,
                prim: 0,
                u: 0.0,
                v: 0.0,
            }; PACKET_WIDTH];
            for (lane, (_, point)) in lanes_of.iter().enumerate() {
                let origin = *point + rng.direction() * reach * rng.range(0.1, 3.0);
                let stretch = rng.range(0.2, 5.0);
                rays[lane] = Ray::new(origin, (*point - origin) * stretch);
                hits[lane].t = 1.0 / stretch;
            }
            let shapes: Vec<WorldShape> = lanes_of
                .iter()
                .map(|(object, _)| WorldShape::new(object))
                .collect();
            let mut analytic = AnalyticHits::default();
            for lane in 0..PACKET_WIDTH {
                assert!(analytic.add(lane, &shapes[lane], hits[lane].t));
            }
            let mut lanes_hit = HitLanes::default();
            let keep = [true; PACKET_WIDTH];
            analytic.reconstruct(&RayColumns::new(&rays), &keep, &mut lanes_hit);
            for lane in 0..PACKET_WIDTH {
                let surface = shapes[lane].surface(&rays[lane], &hits[lane], 0);
                let one = [
                    surface.point,
                    surface.geometric_normal,
                    surface.shading_normal,
                    surface.spawn_point,
                    surface.shadow_point,
                ];
                let packet = [
                    &lanes_hit.point,
                    &lanes_hit.geometric_normal,
                    &lanes_hit.shading_normal,
                    &lanes_hit.spawn_point,
                    &lanes_hit.shadow_point,
                ]
                .map(|field| field.get(lane));
                let names = [
                    "point",
                    "geometric normal",
                    "shading normal",
                    "spawn point",
                    "shadow point",
                ];
                for ((what, one), packet) in names.iter().zip(one).zip(packet) {
                    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                    assert_eq!(
                        bits(one),
                        bits(packet),
                        "{what}, round {round}, lane {lane}"
                    );
                }
                assert_eq!(surface.front_face, lanes_hit.front_face[lane]);
            }
        }
    }
}
