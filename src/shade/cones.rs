//! Ray cones (Akenine-Möller et al., Ray Tracing Gems ch. 20, and the
//! curvature estimate of their JCGT 2021 paper): how wide a ray's
//! footprint is where it meets a texture, after the mirrors and glass
//! it met on its way.

use glam::Vec3;

use super::{Lanes, Surface, WorldShape};
use crate::camera::Projection;
use crate::ray::Hit;
use crate::scene::Scene;

impl WorldShape<'_> {
    /// The signed radius of curvature a cone meets at `hit` on `surface`,
    /// as the incoming ray sees it: positive where the surface bulges
    /// toward the ray (outside a sphere), negative where it is hollow
    /// (inside one), infinite where it is flat (planes, flat-shaded
    /// triangles). Only mirrors and glass ask: it bends the cones they
    /// pass on ([`reflected_spread`], [`refracted_spread`]).
    ///
    /// A smooth-shaded triangle's curvature is that of the surface its
    /// vertex normals describe (Akenine-Möller et al., "Improved Shader and
    /// Texture Level of Detail Using Ray Cones", JCGT 10(1), 2021): per
    /// edge, `k = (n_i - n_j).(p_i - p_j) / |p_i - p_j|^2`, and per
    /// triangle the mean of its three edges. The mean rather than the
    /// largest: on a tessellated sphere whose normals are the sphere's,
    /// every edge gives exactly `1 / radius`, so the mean is the sphere's
    /// own; where the surface curves one way only (a cylinder), the mean
    /// sits between the flat and the curved direction, the one width an
    /// isotropic cone can take, where the largest would blur the flat
    /// direction as much as the curved one. Worked out in world space
    /// from the triangle's placed vertices and normals, so an instance's
    /// scale and turn are taken as they are, with nothing kept per
    /// triangle and nothing computed for scenes without textures.
    #[inline(never)]
    pub(super) fn curvature_radius(&self, hit: &Hit, surface: &Surface) -> f32 {
        match self {
            WorldShape::Sphere { radius, .. } => {
                if surface.front_face {
                    *radius
                } else {
                    -*radius
                }
            }
            WorldShape::Plane { .. } => f32::INFINITY,
            WorldShape::Mesh {
                mesh,
                transform,
                normal_matrix,
            } => {
                if mesh.normals.is_empty() {
                    return f32::INFINITY;
                }
                let points = mesh
                    .vertices(hit.prim)
                    .map(|p| transform.map_or(p, |xf| xf.transform_point3(p)));
                let normals = mesh.triangles[hit.prim as usize].map(|index| {
                    let n = mesh.normals[index as usize];
                    match transform {
                        Some(_) => normal_matrix.mul_vec3(n).normalize_or_zero(),
                        None => n.normalize_or_zero(),
                    }
                });
                if normals.contains(&Vec3::ZERO) {
                    return f32::INFINITY;
                }
                // The vertex normals turned to the side the shading normal
                // faces (toward the incoming ray), so a bulge toward the
                // ray comes out positive from either side.
                let (u, v) = (hit.u, hit.v);
                let blend = normals[0] * (1.0 - u - v) + normals[1] * u + normals[2] * v;
                let side = if blend.dot(surface.shading_normal) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                let edge = |i: usize, j: usize| {
                    let dp = points[i] - points[j];
                    let length_sq = dp.length_squared();
                    if length_sq > 0.0 {
                        (normals[i] - normals[j]).dot(dp) / length_sq
                    } else {
                        0.0
                    }
                };
                let curvature = side * (edge(0, 1) + edge(1, 2) + edge(2, 0)) / 3.0;
                1.0 / curvature
            }
        }
    }
}

/// The spread of a cone `width` wide leaving a mirror whose radius of
/// curvature is `radius` ([`WorldShape::curvature_radius`]): the normals
/// turn by `width / radius` across the footprint, the reflection by twice
/// that (a concave mirror's negative radius narrows the cone; flat ones,
/// of infinite radius, pass it on as it came).
#[inline]
pub(super) fn reflected_spread(spread: f32, width: f32, radius: f32) -> f32 {
    spread + 2.0 * width / radius
}

/// The spread of a cone `width` wide refracted at a surface of radius of
/// curvature `radius` with index ratio `eta` (the index it leaves over
/// the index it enters): the paraxial refraction of a cone's edge ray at
/// a single curved interface, the thin-lens approximation
/// (`n2 theta2 = n1 theta1 - (n2 - n1) h / R`, halved for the cone's half
/// width and angle): its angle scaled by `eta`, and bent in by
/// `(1 - eta) width / radius`. A convex face going into glass focuses the
/// cone, so a glass ball turns it over and the floor seen through it is
/// minified, read at a coarser level, as it should be.
#[inline]
pub(super) fn refracted_spread(spread: f32, width: f32, radius: f32, eta: f32) -> f32 {
    eta * spread + (eta - 1.0) * width / radius
}

/// Ray cones (Akenine-Möller et al., Ray Tracing Gems ch. 20) lane by
/// lane: the cone's width where each ray starts and the angle it spreads
/// at. A pure function of the ray's path from the eye: the camera's pixel
/// angle, the distances travelled, and the curvature and index ratio of
/// the mirrors and glass met.
#[derive(Clone, Copy, Default)]
pub(super) struct RayCones {
    pub(super) width: Lanes,
    pub(super) spread: Lanes,
}

/// The angle one sample covers: the camera's pixel angle (at the image's
/// centre, for a perspective camera) over the square root of the samples
/// a pixel, as those samples share the pixel.
pub(super) fn sample_spread(scene: &Scene) -> f32 {
    let camera = &scene.camera;
    let pixel = match camera.projection {
        Projection::Perspective => 2.0 * (0.5 * camera.fov).tan() / f64::from(camera.width),
        _ => camera.fov / f64::from(camera.width),
    };
    (pixel / f64::from(scene.samples.count()).sqrt()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    use glam::Affine3A;

    use crate::geometry::{Object, Placement, Shape, TriangleMesh};
    use crate::ray::Ray;

    /// A sphere of `radius` about the origin, `rings` x `segments`, its
    /// vertex normals the sphere's own (or none: flat-shaded).
    fn tessellated_sphere(radius: f32, smooth: bool) -> TriangleMesh {
        let (rings, segments) = (12u32, 24u32);
        let mut positions = Vec::new();
        for ring in 0..=rings {
            let theta = std::f32::consts::PI * ring as f32 / rings as f32;
            for segment in 0..segments {
                let phi = std::f32::consts::TAU * segment as f32 / segments as f32;
                positions.push(Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    -theta.sin() * phi.sin(),
                ));
            }
        }
        let mut triangles = Vec::new();
        for ring in 1..rings - 1 {
            for segment in 0..segments {
                let a = ring * segments + segment;
                let b = ring * segments + (segment + 1) % segments;
                triangles.push([a, a + segments, b]);
                triangles.push([b, a + segments, b + segments]);
            }
        }
        TriangleMesh {
            normals: if smooth {
                positions.clone()
            } else {
                Vec::new()
            },
            positions: positions.iter().map(|p| *p * radius).collect(),
            triangles,
            texcoords: Vec::new(),
            cutout: None,
        }
    }

    fn object(shape: Shape, placement: Placement) -> Object {
        Object {
            name: "mirror".into(),
            shape,
            material: 0,
            placement,
        }
    }

    /// The radius of curvature a ray sees on triangle `prim` at
    /// barycentrics (0.3, 0.3), coming from `from` (in the mesh's own
    /// space; placed like the object).
    fn radius_seen(object: &Object, prim: u32, from: Vec3) -> f32 {
        let shape = WorldShape::new(object);
        let Shape::Mesh(mesh) = &object.shape else {
            unreachable!()
        };
        let [a, b, c] = mesh.vertices(prim);
        let at = a * 0.4 + b * 0.3 + c * 0.3;
        let transform = object.placement.transform_at(0.0);
        let to_world = |p: Vec3| transform.map_or(p, |xf| xf.transform_point3(p));
        let ray = Ray::new(to_world(from), to_world(at) - to_world(from));
        let hit = Hit {
            t: 1.0,
            object: 0,
            prim,
            u: 0.3,
            v: 0.3,
        };
        let surface = shape.surface(&ray, &hit, 0);
        shape.curvature_radius(&hit, &surface)
    }

    #[test]
    fn a_smooth_tessellated_sphere_curves_cones_as_the_sphere_does() {
        let mesh = tessellated_sphere(1.5, true);
        let count = mesh.triangles.len() as u32;
        let placed = [
            (Placement::World, 1.5),
            (
                Placement::Instance(Affine3A::from_scale_rotation_translation(
                    Vec3::splat(2.0),
                    glam::Quat::from_rotation_y(0.7),
                    Vec3::new(3.0, -1.0, 2.0),
                )),
                3.0,
            ),
        ];
        for (placement, radius) in placed {
            let sphere = object(Shape::Mesh(mesh.clone()), placement);
            for prim in [0, count / 3, count / 2, count - 1] {
                let [a, b, c] = mesh.vertices(prim);
                let out = (a + b + c).normalize();
                // From outside it bulges toward the ray, from inside it is
                // hollow.
                let outside = radius_seen(&sphere, prim, out * 10.0);
                let inside = radius_seen(&sphere, prim, Vec3::ZERO);
                assert!(
                    (outside - radius).abs() < 1e-3 * radius,
                    "{prim}: {outside}"
                );
                assert!((inside + radius).abs() < 1e-3 * radius, "{prim}: {inside}");
                // So a mirror widens a cone as a sphere of that radius does.
                let widened = reflected_spread(0.001, 0.01, outside);
                assert!((widened - (0.001 + 0.02 / radius)).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn flat_shaded_triangles_pass_cones_on_unchanged() {
        let flat = object(
            Shape::Mesh(tessellated_sphere(1.0, false)),
            Placement::World,
        );
        // A smooth-shaded plane: every vertex normal the same.
        let plane = object(
            Shape::Mesh(TriangleMesh {
                positions: vec![
                    Vec3::new(-1.0, 0.0, -1.0),
                    Vec3::new(-1.0, 0.0, 1.0),
                    Vec3::new(1.0, 0.0, 1.0),
                ],
                triangles: vec![[0, 1, 2]],
                normals: vec![Vec3::Y; 3],
                texcoords: Vec::new(),
                cutout: None,
            }),
            Placement::World,
        );
        for (shape, from) in [(&flat, Vec3::new(0.0, 0.0, 10.0)), (&plane, Vec3::Y * 3.0)] {
            let radius = radius_seen(shape, 0, from);
            assert!(radius.is_infinite(), "{radius}");
            let (spread, width) = (0.0013, 0.047);
            assert_eq!(reflected_spread(spread, width, radius), spread);
            assert_eq!(refracted_spread(spread, width, radius, 1.0), spread);
        }
    }

    #[test]
    fn glass_focuses_a_parallel_cone_where_a_thin_lens_would() {
        // Paraxially, light entering a glass sphere of index n parallel
        // meets at n R / (n - 1) behind its front face.
        let (radius, ior, width) = (2.0, 1.5, 0.01);
        let spread = refracted_spread(0.0, width, radius, 1.0 / ior);
        let focus = -width / spread;
        assert!((focus - ior * radius / (ior - 1.0)).abs() < 1e-4, "{focus}");
        // A flat face only scales the spread by the index ratio, and going
        // back out undoes it.
        let inside = refracted_spread(0.003, width, f32::INFINITY, 1.0 / ior);
        assert!((inside - 0.002).abs() < 1e-9);
        assert!((refracted_spread(inside, width, f32::INFINITY, ior) - 0.003).abs() < 1e-9);
    }
}
