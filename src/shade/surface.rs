//! Where a ray met a surface, as shading works with it: the hit point
//! rebuilt from the primitive, the normals, the texture coordinates and
//! the material's colour there; each object's shape in world space.

use glam::{Affine3A, Mat3A, Vec3};

use crate::accel::moving_sphere;
use crate::geometry::normals::terminator_point;
use crate::geometry::{
    normal_matrix, plane_axes, transform_normal, Motion, MovingSphere, Object, Placement, Shape,
    TriangleMesh,
};
use crate::ray::{offset_origin, Hit, Ray};
use crate::scene::{Material, Scene};
use crate::texture::{cone_level_of_detail, Texture};

/// Where a ray met a surface, refined for shading and for spawning rays.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// On the surface, reconstructed from the primitive (not `o + t d`,
    /// whose error grows with the distance travelled).
    pub point: Vec3,
    /// Unit geometric normal, facing the incoming ray.
    pub geometric_normal: Vec3,
    /// Unit shading normal (interpolated for smooth meshes), same side.
    pub shading_normal: Vec3,
    /// Where rays leaving the surface start: `point` moved off the surface
    /// to the side the incoming ray came from. Every ray shading spawns
    /// leaves from that side (lights behind the surface are skipped, and
    /// reflections are kept above it).
    pub spawn_point: Vec3,
    /// Where shadow rays start: `spawn_point`, except on smooth-shaded
    /// triangles, where it is lifted toward the curved surface their
    /// vertex normals describe (`geometry::normals::terminator_point`).
    pub shadow_point: Vec3,
    pub material: usize,
    /// Whether the ray arrived on the side the shape's own normal points to
    /// (outside a sphere, the front of a triangle as wound): into glass.
    pub front_face: bool,
    /// In-plane coordinates for plane checkers; None elsewhere.
    pub plane_uv: Option<(f32, f32)>,
}

impl Surface {
    /// The surface `ray` met at `hit`. Shading itself goes through a
    /// [`Shader`], which prepares every object's world-space data once.
    pub fn from_hit(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
        let object = &scene.objects[hit.object as usize];
        let shape = match ShapeMotion::new(object) {
            Some(motion) => motion.at(ray.time),
            None => WorldShape::new(object),
        };
        shape.surface(ray, hit, object.material)
    }
}

/// How an object moving while the shutter is open changes shape in the
/// world: its shape for a ray is made at the ray's time, placed as every
/// backend places it then (a sphere's centre and radius interpolated, a
/// mesh through the interpolated transform).
pub(super) enum ShapeMotion<'a> {
    Sphere(MovingSphere),
    Placed {
        object: &'a Object,
        motion: &'a Motion,
    },
}

impl<'a> ShapeMotion<'a> {
    /// `None` unless `object` moves while the shutter is open.
    pub(super) fn new(object: &'a Object) -> Option<ShapeMotion<'a>> {
        let Placement::Moving(motion) = &object.placement else {
            return None;
        };
        Some(match &object.shape {
            // A motion that would not keep the sphere round never reaches
            // shading (the accelerator refuses it).
            Shape::Sphere(sphere) => {
                ShapeMotion::Sphere(moving_sphere(sphere, motion).unwrap_or(MovingSphere {
                    steps: [*sphere; crate::geometry::MOTION_STEPS],
                }))
            }
            _ => ShapeMotion::Placed { object, motion },
        })
    }

    /// The shape where a ray cast at shutter time `time` meets it.
    pub(super) fn at(&self, time: f32) -> WorldShape<'a> {
        match self {
            ShapeMotion::Sphere(moving) => {
                let sphere = moving.at(time);
                WorldShape::sphere(sphere.center, sphere.radius)
            }
            ShapeMotion::Placed { object, motion } => {
                WorldShape::placed(object, Some(motion.at(time)))
            }
        }
    }
}

/// An object's shape as shading sees it: in world space, with everything
/// that does not depend on the hit (instance transforms and their inverse
/// transpose, sphere centres and radii, plane axes) worked out once.
///
/// The arithmetic per hit is the same, operation for operation, as working
/// from the object's own description each time, so a surface comes out bit
/// for bit the same either way.
pub(super) enum WorldShape<'a> {
    Mesh {
        mesh: &'a TriangleMesh,
        transform: Option<Affine3A>,
        /// Inverse transpose of the transform's linear part (for normals).
        normal_matrix: Mat3A,
    },
    Sphere {
        center: Vec3,
        radius: f32,
        /// Magnitude the hit point is computed from (for `offset_origin`).
        scale: f32,
    },
    Plane {
        origin: Vec3,
        normal: Vec3,
        u_axis: Vec3,
        v_axis: Vec3,
        /// `origin.abs().max_element()`.
        origin_scale: f32,
    },
}

impl<'a> WorldShape<'a> {
    /// The shape of `object`; one moving while the shutter is open as it
    /// is when the shutter opens (shading asks [`ShapeMotion`] instead).
    pub(super) fn new(object: &'a Object) -> WorldShape<'a> {
        WorldShape::placed(object, object.placement.transform_at(0.0))
    }

    fn sphere(center: Vec3, radius: f32) -> WorldShape<'a> {
        WorldShape::Sphere {
            center,
            radius,
            scale: center.abs().max_element() + radius,
        }
    }

    /// `object`'s shape placed by `transform` (`None`: already in world
    /// space).
    fn placed(object: &'a Object, transform: Option<Affine3A>) -> WorldShape<'a> {
        let to_world = |p: Vec3| transform.map_or(p, |xf| xf.transform_point3(p));
        match &object.shape {
            Shape::Mesh(mesh) => WorldShape::Mesh {
                mesh,
                transform,
                normal_matrix: transform.map_or(Mat3A::IDENTITY, |xf| normal_matrix(&xf)),
            },
            Shape::Sphere(sphere) => {
                let center = to_world(sphere.center);
                let radius = match transform {
                    Some(xf) => sphere.radius * xf.matrix3.x_axis.length(),
                    None => sphere.radius,
                };
                WorldShape::sphere(center, radius)
            }
            Shape::Plane(plane) => {
                let (origin, normal) = match transform {
                    Some(xf) => (
                        xf.transform_point3(plane.point),
                        transform_normal(&xf, plane.normal),
                    ),
                    None => (plane.point, plane.normal),
                };
                let (u_axis, v_axis) = plane_axes(normal);
                WorldShape::Plane {
                    origin,
                    normal,
                    u_axis,
                    v_axis,
                    origin_scale: origin.abs().max_element(),
                }
            }
        }
    }

    #[inline]
    pub(super) fn surface(&self, ray: &Ray, hit: &Hit, material: usize) -> Surface {
        // Smooth triangles: the vertices and their unit normals, turned to
        // the side the shading normal faces before `facing` applies.
        let mut curved: Option<([Vec3; 3], [Vec3; 3])> = None;
        let (point, normal, shading, scale, plane_uv) = match self {
            WorldShape::Mesh {
                mesh,
                transform,
                normal_matrix,
            } => {
                let [a, b, c] = mesh
                    .vertices(hit.prim)
                    .map(|p| transform.map_or(p, |xf| xf.transform_point3(p)));
                let (u, v) = (hit.u, hit.v);
                let point = a * (1.0 - u - v) + b * u + c * v;
                let normal = (b - a).cross(c - a).normalize();
                let shading = if mesh.normals.is_empty() {
                    normal
                } else {
                    let [i, j, k] = mesh.triangles[hit.prim as usize];
                    let n = mesh.normals[i as usize] * (1.0 - u - v)
                        + mesh.normals[j as usize] * u
                        + mesh.normals[k as usize] * v;
                    let n = match transform {
                        Some(_) => normal_matrix.mul_vec3(n).normalize_or_zero(),
                        None => n,
                    };
                    let n = n.normalize_or_zero();
                    let side = if n.dot(normal) < 0.0 { -1.0 } else { 1.0 };
                    if n != Vec3::ZERO {
                        let vertex_normals = [i, j, k].map(|index| {
                            let n = mesh.normals[index as usize];
                            let n = match transform {
                                Some(_) => normal_matrix.mul_vec3(n),
                                None => n,
                            };
                            n.normalize_or_zero() * side
                        });
                        curved = Some(([a, b, c], vertex_normals));
                    }
                    if n == Vec3::ZERO {
                        normal
                    } else {
                        n * side
                    }
                };
                let scale = a.abs().max(b.abs()).max(c.abs()).max_element();
                (point, normal, shading, scale, None)
            }
            &WorldShape::Sphere {
                center,
                radius,
                scale,
            } => {
                let outward = (ray.at(hit.t) - center).normalize();
                let point = center + outward * radius;
                (point, outward, outward, scale, None)
            }
            &WorldShape::Plane {
                origin,
                normal,
                u_axis,
                v_axis,
                origin_scale,
            } => {
                let rough = ray.at(hit.t);
                let point = rough - normal * normal.dot(rough - origin);
                let scale = origin_scale.max(ray.origin.abs().max_element());
                let uv = plane_uv(point, origin, u_axis, v_axis);
                (point, normal, normal, scale, Some(uv))
            }
        };
        let facing = if normal.dot(ray.dir) > 0.0 { -1.0 } else { 1.0 };
        let geometric_normal = normal * facing;
        let spawn_point = offset_origin(point, geometric_normal, scale);
        let shadow_point = match curved {
            None => spawn_point,
            Some((vertices, normals)) => {
                let (u, v) = (hit.u, hit.v);
                let lifted = terminator_point(
                    point,
                    vertices,
                    normals.map(|n| n * facing),
                    [1.0 - u - v, u, v],
                );
                if lifted == point {
                    spawn_point
                } else {
                    offset_origin(lifted, geometric_normal, scale)
                }
            }
        };
        Surface {
            point,
            geometric_normal,
            shading_normal: shading * facing,
            spawn_point,
            shadow_point,
            material,
            front_face: facing > 0.0,
            plane_uv,
        }
    }
}

impl WorldShape<'_> {
    /// `point`'s in-plane coordinates on a plane; None on other shapes.
    #[inline]
    pub(super) fn plane_uv(&self, point: Vec3) -> Option<(f32, f32)> {
        match *self {
            WorldShape::Plane {
                origin,
                u_axis,
                v_axis,
                ..
            } => Some(plane_uv(point, origin, u_axis, v_axis)),
            _ => None,
        }
    }

    /// The colour `map` (diffuse or specular) gives at `hit` on a mesh with texture
    /// coordinates (`None` elsewhere), filtered over the footprint of a ray
    /// cone `width` wide at the hit (Ray Tracing Gems ch. 20): the triangle's
    /// texel-to-world area ratio and the ray's slant to it set the mip level.
    #[inline(never)]
    pub(super) fn texel(&self, map: &Texture, ray: &Ray, hit: &Hit, width: f32) -> Option<Vec3> {
        let WorldShape::Mesh {
            mesh, transform, ..
        } = self
        else {
            return None;
        };
        let uv = mesh.texcoord(hit.prim, hit.u, hit.v)?;
        let [a, b, c] = mesh
            .vertices(hit.prim)
            .map(|p| transform.map_or(p, |xf| xf.transform_point3(p)));
        let [ta, tb, tc] = mesh.triangles[hit.prim as usize].map(|i| mesh.texcoords[i as usize]);
        let (w, h) = map.size();
        let cross = (b - a).cross(c - a);
        let world_area = cross.length();
        let texel_area = (tb - ta).perp_dot(tc - ta).abs() * w as f32 * h as f32;
        let cos = ray.dir.dot(cross) / (ray.dir.length() * world_area);
        let lod = cone_level_of_detail(width, cos, texel_area, world_area);
        Some(map.sample(uv, lod).truncate())
    }
}

/// In-plane coordinates of `point` on a plane through `origin`.
#[inline]
fn plane_uv(point: Vec3, origin: Vec3, u_axis: Vec3, v_axis: Vec3) -> (f32, f32) {
    let local = point - origin;
    (local.dot(u_axis), local.dot(v_axis))
}

/// The material's colour at `point` (with its in-plane coordinates on a
/// plane): its diffuse colour, or its checker's.
#[inline]
pub(super) fn albedo(material: &Material, point: Vec3, plane_uv: Option<(f32, f32)>) -> Vec3 {
    let Some(checker) = &material.checker else {
        return material.diffuse;
    };
    let parity = match plane_uv {
        Some((u, v)) => (u / checker.scale).floor() as i64 + (v / checker.scale).floor() as i64,
        None => {
            let p = point / checker.scale;
            p.x.floor() as i64 + p.y.floor() as i64 + p.z.floor() as i64
        }
    };
    checker.colors[(parity & 1) as usize]
}
