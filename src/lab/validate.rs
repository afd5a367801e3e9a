//! `retrace validate`: Embree's answers checked against the pure-Rust grid.
//!
//! Two checks: (a) ray by ray, on every camera ray of the scene plus seeded
//! random rays through its bounds: do both backends agree on hit or miss, on
//! the object and primitive hit, and on where the ray meets it; (b) image by
//! image: the full frame from each backend, compared pixel by pixel.
//!
//! Rays that graze an edge shared by two triangles may legitimately name a
//! different triangle (or, for a silhouette edge, hit in one backend and miss
//! in the other): the thresholds allow a small share of those, and list the
//! disagreements so a user can reproduce them.
//!
//! Where both hit the same primitive, the two hit points `o + t d` must lie
//! within float rounding of each other across the surface: at most
//! `gamma(n) * M` apart along its normal, where `M` is the magnitude of the
//! coordinates the hit was computed from (ray origin, distance travelled,
//! the primitive's own coordinates), as in pbrt-v4's error bounds. A bound
//! relative to `t` alone fails rays that start almost on a surface (t near
//! 1e-5, where rounding of coordinates near 10 is a large share of t), and
//! one along the ray fails rays that graze a surface, where any error in
//! `t` is stretched by 1/cos of the angle; neither is a disagreement.
//!
//! On textured meshes the texture coordinates each backend's barycentrics
//! give must agree too ([`texcoord_bound`]): a texture lookup then reads
//! the same texels whichever backend found the hit.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::accel::{moving_sphere, placed_sphere, Intersector};
use crate::camera::RayTable;
use crate::geometry::{transform_normal, Aabb, Placement, Shape};
use crate::ray::{Hit, Ray};
use crate::render::render_frame;
use crate::rng::SplitMix64;
use crate::scene::Scene;

/// Pass/fail limits, documented in `retrace validate --help`.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Thresholds {
    /// Least share of rays on which both backends agree on hit or miss.
    pub min_hit_agreement: f64,
    /// Least share of rays hit by both on which the same primitive is hit.
    pub min_same_primitive: f64,
    /// `n` of the `gamma(n)` that bounds how far apart, across the surface,
    /// the two hit points on the same primitive may lie, relative to the
    /// magnitude of the coordinates involved ([`hit_point_bound`]).
    pub hit_point_gamma: u32,
    /// Largest share of pixels whose colours differ by more than 1/255.
    pub max_differing_pixels: f64,
    /// Largest mean absolute colour difference over the image.
    pub max_mean_difference: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            min_hit_agreement: 0.9995,
            min_same_primitive: 0.999,
            hit_point_gamma: HIT_POINT_GAMMA,
            max_differing_pixels: 0.005,
            max_mean_difference: 1e-3,
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Disagreement {
    pub source: &'static str,
    pub origin: [f32; 3],
    pub direction: [f32; 3],
    pub embree: Option<HitSummary>,
    pub grid: Option<HitSummary>,
}

#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct HitSummary {
    pub t: f32,
    pub object: u32,
    pub prim: u32,
}

impl From<Hit> for HitSummary {
    fn from(h: Hit) -> Self {
        HitSummary {
            t: h.t,
            object: h.object,
            prim: h.prim,
        }
    }
}

/// The default `n` of [`Thresholds::hit_point_gamma`]: each backend's hit
/// point lies within about gamma(16) M of the surface (the dozen or so f32
/// operations of a ray/triangle or ray/sphere test, with a margin), so the
/// two lie within gamma(32) M of each other. Measured over seeds 0-49 of
/// 100,000 random rays on every shipped scene, and on scenes moved 1e5-1e7
/// from the origin or scaled to 1e-4, the largest separation was 3.7
/// gamma(1) M. At the scale of the shipped scenes (M near 30) the bound is
/// 6e-5, so a relative error of 1e-3 in one backend's distance fails.
pub const HIT_POINT_GAMMA: u32 = 32;

/// `gamma(n) = n u / (1 - n u)`, u = 2^-24 the unit roundoff of f32: the
/// bound on the relative error of `n` successive f32 operations (Higham,
/// pbrt-v4's `gamma`).
pub fn gamma(n: u32) -> f64 {
    let nu = f64::from(n) * f64::from(f32::EPSILON) * 0.5;
    nu / (1.0 - nu)
}

/// How far apart across the surface (along its normal) the hit points of
/// `a` and `b`, both on the same primitive, lie; and the bound that rounding
/// keeps them within, `gamma(n) * M`. `M` sums the largest coordinates of
/// the ray origin, of the distance travelled (`t * dir`) and of the
/// primitive (a triangle's vertices, a sphere's centre plus radius, a
/// plane's point), since every backend works from differences of those.
pub fn hit_point_bound(scene: &Scene, ray: &Ray, a: &Hit, b: &Hit, n: u32) -> (f64, f64) {
    let origin = ray.origin.as_dvec3();
    let dir = ray.dir.as_dvec3();
    let (ta, tb) = (f64::from(a.t), f64::from(b.t));
    let object = &scene.objects[a.object as usize];
    let transform = object.placement.transform_at(ray.time);
    let place = |p: Vec3| transform.map_or(p, |xf| xf.transform_point3(p));
    let (normal, primitive) = match &object.shape {
        Shape::Mesh(mesh) => {
            let [p, q, r] = mesh.vertices(a.prim).map(|v| place(v).as_dvec3());
            let scale = p.abs().max(q.abs()).max(r.abs()).max_element();
            ((q - p).cross(r - p).normalize_or_zero(), scale)
        }
        Shape::Sphere(sphere) => {
            let sphere = match (&object.placement, transform) {
                (Placement::Moving(motion), _) => {
                    moving_sphere(sphere, motion).map_or(*sphere, |moving| moving.at(ray.time))
                }
                (_, Some(xf)) => placed_sphere(sphere, &xf).unwrap_or(*sphere),
                (_, None) => *sphere,
            };
            let center = sphere.center.as_dvec3();
            let hit = origin + dir * ta;
            let scale = center.abs().max_element() + f64::from(sphere.radius);
            ((hit - center).normalize_or_zero(), scale)
        }
        Shape::Plane(plane) => {
            let (point, normal) = match transform {
                Some(xf) => (
                    xf.transform_point3(plane.point),
                    transform_normal(&xf, plane.normal),
                ),
                None => (plane.point, plane.normal),
            };
            (
                normal.as_dvec3().normalize_or_zero(),
                point.as_dvec3().abs().max_element(),
            )
        }
    };
    // A degenerate normal leaves the whole separation to be checked.
    let across = if normal == DVec3::ZERO {
        dir.length()
    } else {
        dir.dot(normal).abs()
    };
    let separation = (ta - tb).abs() * across;
    let magnitude =
        origin.abs().max_element() + ta.abs().max(tb.abs()) * dir.abs().max_element() + primitive;
    (separation, gamma(n) * magnitude)
}

/// How far apart the texture coordinates of `a` and `b` (both on the same
/// triangle of a mesh with texture coordinates; `None` otherwise) lie, and
/// the bound rounding keeps them within. The two crossing points of the
/// triangle's plane lie within `gamma(n) M / |cos|` of each other along the
/// plane (M as in [`hit_point_bound`], the cosine between ray and normal),
/// so each barycentric differs by at most that over the triangle's least
/// altitude, and the coordinates by the sum of both differences times the
/// longest texture-space edge from the first vertex.
pub fn texcoord_bound(scene: &Scene, ray: &Ray, a: &Hit, b: &Hit, n: u32) -> Option<(f64, f64)> {
    let object = &scene.objects[a.object as usize];
    let Shape::Mesh(mesh) = &object.shape else {
        return None;
    };
    let (uv_a, uv_b) = (
        mesh.texcoord(a.prim, a.u, a.v)?,
        mesh.texcoord(b.prim, b.u, b.v)?,
    );
    let transform = object.placement.transform_at(ray.time);
    let place = |p: Vec3| transform.map_or(p, |xf| xf.transform_point3(p));
    let [p, q, r] = mesh.vertices(a.prim).map(|v| place(v).as_dvec3());
    let cross = (q - p).cross(r - p);
    let longest = (q - p).length().max((r - q).length()).max((p - r).length());
    let least_altitude = cross.length() / longest;
    let dir = ray.dir.as_dvec3();
    let cos = dir.normalize_or_zero().dot(cross.normalize_or_zero()).abs();
    let [ta, tb, tc] = mesh.triangles[a.prim as usize].map(|i| mesh.texcoords[i as usize]);
    let uv_edge = f64::from((tb - ta).length().max((tc - ta).length()));
    let magnitude = ray.origin.as_dvec3().abs().max_element()
        + f64::from(a.t.abs().max(b.t.abs())) * dir.abs().max_element()
        + p.abs().max(q.abs()).max(r.abs()).max_element();
    let along_plane = gamma(n) * magnitude / cos;
    let bound = 2.0 * along_plane / least_altitude * uv_edge;
    Some((f64::from((uv_a - uv_b).length()), bound))
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RayAgreement {
    pub rays: usize,
    pub both_hit: usize,
    pub both_miss: usize,
    pub hit_miss_disagree: usize,
    pub same_primitive: usize,
    /// On rays hitting the same primitive: the largest ratio of the hit
    /// points' separation across the surface to its bound (above 1 fails).
    pub max_hit_point_ratio: f64,
    pub mean_hit_point_ratio: f64,
    /// The separation and the bound of the ray with the largest ratio.
    pub worst_separation: f64,
    pub worst_bound: f64,
    /// Of those, the rays on a mesh with texture coordinates.
    pub textured: usize,
    /// On them: the largest ratio of the texture coordinates' separation to
    /// its bound ([`texcoord_bound`]; above 1 fails), with that separation
    /// and bound.
    pub max_texcoord_ratio: f64,
    pub worst_texcoord_separation: f64,
    pub worst_texcoord_bound: f64,
}

impl RayAgreement {
    pub fn hit_agreement(&self) -> f64 {
        1.0 - self.hit_miss_disagree as f64 / self.rays.max(1) as f64
    }

    /// Of the rays both backends hit, the share that hit the same
    /// primitive: all of them (vacuously) when none hit in both.
    pub fn same_primitive_share(&self) -> f64 {
        if self.both_hit == 0 {
            return 1.0;
        }
        self.same_primitive as f64 / self.both_hit as f64
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ImageAgreement {
    pub pixels: usize,
    pub differing_pixels: f64,
    pub max_difference: f32,
    pub mean_difference: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ValidationReport {
    pub camera_rays: RayAgreement,
    pub random_rays: RayAgreement,
    pub image: ImageAgreement,
    pub thresholds: Thresholds,
    pub failures: Vec<String>,
    pub disagreements: Vec<Disagreement>,
}

impl ValidationReport {
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// Random rays from points in the bounded part of the scene toward other
/// points in it, so most rays go somewhere interesting.
pub fn random_rays(scene: &Scene, count: usize, seed: u64) -> Vec<Ray> {
    let bounds = scene
        .objects
        .iter()
        .map(|o| o.world_bounds())
        .filter(Aabb::is_finite)
        .fold(Aabb::EMPTY, Aabb::union);
    let bounds = if bounds.is_empty() {
        Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        }
    } else {
        bounds
    };
    let mut rng = SplitMix64(seed);
    let point = |rng: &mut SplitMix64| {
        let pad = bounds.extent() * 0.1;
        let lo = bounds.min - pad;
        let size = bounds.extent() + pad * 2.0;
        lo + size * Vec3::new(rng.unit(), rng.unit(), rng.unit())
    };
    (0..count)
        .map(|_| {
            let from = point(&mut rng);
            let to = point(&mut rng);
            let dir = (to - from).normalize_or(Vec3::Y);
            Ray::new(from, dir)
        })
        .collect()
}

/// Traces `rays` through both backends and tallies their agreement; lists
/// up to `max_listed` disagreeing rays in `disagreements`.
#[allow(clippy::too_many_arguments)]
fn compare_rays(
    scene: &Scene,
    source: &'static str,
    rays: &[Ray],
    embree: &dyn Intersector,
    grid: &dyn Intersector,
    thresholds: &Thresholds,
    disagreements: &mut Vec<Disagreement>,
    max_listed: usize,
) -> RayAgreement {
    let results: Vec<(Option<Hit>, Option<Hit>)> = rays
        .par_iter()
        .map(|ray| (embree.intersect(ray), grid.intersect(ray)))
        .collect();
    let mut agreement = RayAgreement {
        rays: rays.len(),
        ..RayAgreement::default()
    };
    let mut ratio_sum = 0.0;
    for (ray, (a, b)) in rays.iter().zip(&results) {
        let mut disagree = false;
        match (a, b) {
            (None, None) => agreement.both_miss += 1,
            (Some(a), Some(b)) => {
                agreement.both_hit += 1;
                if (a.object, a.prim) == (b.object, b.prim) {
                    agreement.same_primitive += 1;
                    let (separation, bound) =
                        hit_point_bound(scene, ray, a, b, thresholds.hit_point_gamma);
                    // A NaN separation (or bound) is no agreement: infinitely
                    // far over.
                    let ratio = match separation / bound {
                        _ if separation == 0.0 => 0.0,
                        ratio if ratio.is_nan() => f64::INFINITY,
                        ratio => ratio,
                    };
                    ratio_sum += ratio;
                    if ratio > agreement.max_hit_point_ratio {
                        agreement.max_hit_point_ratio = ratio;
                        agreement.worst_separation = separation;
                        agreement.worst_bound = bound;
                    }
                    disagree = ratio > 1.0;
                    if let Some((separation, bound)) =
                        texcoord_bound(scene, ray, a, b, thresholds.hit_point_gamma)
                    {
                        agreement.textured += 1;
                        let ratio = match separation / bound {
                            _ if separation == 0.0 => 0.0,
                            ratio if ratio.is_nan() => f64::INFINITY,
                            ratio => ratio,
                        };
                        if ratio > agreement.max_texcoord_ratio {
                            agreement.max_texcoord_ratio = ratio;
                            agreement.worst_texcoord_separation = separation;
                            agreement.worst_texcoord_bound = bound;
                        }
                        disagree |= ratio > 1.0;
                    }
                } else {
                    disagree = true;
                }
            }
            _ => {
                agreement.hit_miss_disagree += 1;
                disagree = true;
            }
        }
        if disagree && disagreements.len() < max_listed {
            disagreements.push(Disagreement {
                source,
                origin: ray.origin.to_array(),
                direction: ray.dir.to_array(),
                embree: a.map(HitSummary::from),
                grid: b.map(HitSummary::from),
            });
        }
    }
    agreement.mean_hit_point_ratio = ratio_sum / agreement.same_primitive.max(1) as f64;
    agreement
}

/// What in `agreement` (of the rays named `name`) falls outside `thresholds`.
fn ray_failures(name: &str, agreement: &RayAgreement, thresholds: &Thresholds) -> Vec<String> {
    let mut failures = Vec::new();
    if agreement.hit_agreement() < thresholds.min_hit_agreement {
        failures.push(format!(
            "{name} rays: hit/miss agreement {:.4}% is below {:.4}%",
            agreement.hit_agreement() * 100.0,
            thresholds.min_hit_agreement * 100.0
        ));
    }
    if agreement.same_primitive_share() < thresholds.min_same_primitive {
        failures.push(format!(
            "{name} rays: same primitive on {:.4}% of common hits, below {:.4}%",
            agreement.same_primitive_share() * 100.0,
            thresholds.min_same_primitive * 100.0
        ));
    }
    if agreement.max_hit_point_ratio > 1.0 {
        failures.push(format!(
            "{name} rays: hit points on the same primitive up to {:.2e} apart across \
             the surface, {:.1} times the rounding bound gamma({}) x magnitude = {:.2e}",
            agreement.worst_separation,
            agreement.max_hit_point_ratio,
            thresholds.hit_point_gamma,
            agreement.worst_bound
        ));
    }
    if agreement.max_texcoord_ratio > 1.0 {
        failures.push(format!(
            "{name} rays: texture coordinates on the same triangle up to {:.2e} apart, \
             {:.1} times their rounding bound {:.2e}",
            agreement.worst_texcoord_separation,
            agreement.max_texcoord_ratio,
            agreement.worst_texcoord_bound
        ));
    }
    failures
}

/// Runs both checks. `embree` and `grid` must be built from `scene`.
pub fn validate(
    scene: &Scene,
    embree: &dyn Intersector,
    grid: &dyn Intersector,
    random_count: usize,
    seed: u64,
    max_listed: usize,
) -> ValidationReport {
    let thresholds = Thresholds::default();
    let camera = &scene.camera;
    let table = RayTable::new(camera);
    let camera_rays: Vec<Ray> = (0..camera.height)
        .flat_map(|y| (0..camera.width).map(move |x| (x, y)))
        .filter_map(|(x, y)| table.primary_ray(x, y))
        .collect();
    let mut disagreements = Vec::new();
    let camera_agreement = compare_rays(
        scene,
        "camera",
        &camera_rays,
        embree,
        grid,
        &thresholds,
        &mut disagreements,
        max_listed,
    );
    let random = random_rays(scene, random_count, seed);
    let random_agreement = compare_rays(
        scene,
        "random",
        &random,
        embree,
        grid,
        &thresholds,
        &mut disagreements,
        max_listed,
    );

    let (a, _) = render_frame(scene, embree);
    let (b, _) = render_frame(scene, grid);
    let differences: Vec<f32> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .collect();
    let image = ImageAgreement {
        pixels: differences.len(),
        differing_pixels: differences.iter().filter(|&&d| d > 1.0 / 255.0).count() as f64
            / differences.len().max(1) as f64,
        max_difference: differences.iter().copied().fold(0.0, f32::max),
        mean_difference: differences.iter().map(|&d| f64::from(d)).sum::<f64>()
            / differences.len().max(1) as f64,
    };

    let mut failures = ray_failures("camera", &camera_agreement, &thresholds);
    failures.extend(ray_failures("random", &random_agreement, &thresholds));
    if image.differing_pixels > thresholds.max_differing_pixels {
        failures.push(format!(
            "image: {:.3}% of pixels differ, above {:.3}%",
            image.differing_pixels * 100.0,
            thresholds.max_differing_pixels * 100.0
        ));
    }
    if image.mean_difference > thresholds.max_mean_difference {
        failures.push(format!(
            "image: mean difference {:.2e}, above {:.0e}",
            image.mean_difference, thresholds.max_mean_difference
        ));
    }
    ValidationReport {
        camera_rays: camera_agreement,
        random_rays: random_agreement,
        image,
        thresholds,
        failures,
        disagreements,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accelerator, BackendKind};
    use crate::geometry::{Object, Sphere, TriangleMesh};
    use crate::scene::{paper_scene, SceneOverrides};

    /// A backend whose distances are all off by a relative `skew`.
    struct Skewed<'a> {
        inner: &'a dyn Intersector,
        skew: f32,
    }

    impl Intersector for Skewed<'_> {
        fn intersect(&self, ray: &Ray) -> Option<Hit> {
            self.inner.intersect(ray).map(|hit| Hit {
                t: hit.t * (1.0 + self.skew),
                ..hit
            })
        }

        fn occluded(&self, ray: &Ray) -> bool {
            self.inner.occluded(ray)
        }
    }

    #[test]
    fn a_relative_error_of_1e_3_in_one_backends_distance_fails() {
        let scene = paper_scene(&SceneOverrides {
            width: Some(64),
            height: Some(48),
            ..SceneOverrides::default()
        })
        .unwrap();
        let embree = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        let grid = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let report = validate(&scene, &embree, &grid, 20_000, 1, 5);
        assert!(report.passed(), "{:?}", report.failures);
        let skewed = Skewed {
            inner: &embree,
            skew: 1e-3,
        };
        let report = validate(&scene, &skewed, &grid, 20_000, 1, 5);
        for name in ["camera", "random"] {
            let needle = format!("{name} rays: hit points on the same primitive");
            assert!(
                report.failures.iter().any(|f| f.starts_with(&needle)),
                "{name}: {:?}",
                report.failures
            );
        }
        // Far past the bound, not just over it.
        assert!(report.camera_rays.max_hit_point_ratio > 100.0, "{report:?}");
    }

    /// A latitude-longitude sphere of `rings` x `segments` quads with
    /// texture coordinates, as a textured model would have them.
    fn textured_sphere(rings: u32, segments: u32, center: Vec3, radius: f32) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        for ring in 0..=rings {
            for segment in 0..=segments {
                let (s, t) = (segment as f32 / segments as f32, ring as f32 / rings as f32);
                let (theta, phi) = (t * std::f32::consts::PI, s * std::f32::consts::TAU);
                let dir = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                mesh.positions.push(center + dir * radius);
                mesh.texcoords.push(glam::Vec2::new(s * 3.0, t * 2.0));
            }
        }
        let at = |ring: u32, segment: u32| ring * (segments + 1) + segment;
        for ring in 0..rings {
            for segment in 0..segments {
                let [a, b, c, d] = [
                    at(ring, segment),
                    at(ring, segment + 1),
                    at(ring + 1, segment + 1),
                    at(ring + 1, segment),
                ];
                mesh.triangles.extend([[a, b, c], [a, c, d]]);
            }
        }
        mesh.triangles.retain(|&t| {
            let [p, q, r] = t.map(|i| mesh.positions[i as usize]);
            (q - p).cross(r - p).length_squared() > 0.0
        });
        mesh
    }

    /// A backend whose barycentrics are all off by `skew`.
    struct SkewedBarycentrics<'a> {
        inner: &'a dyn Intersector,
        skew: f32,
    }

    impl Intersector for SkewedBarycentrics<'_> {
        fn intersect(&self, ray: &Ray) -> Option<Hit> {
            self.inner.intersect(ray).map(|hit| Hit {
                u: hit.u + self.skew,
                ..hit
            })
        }

        fn occluded(&self, ray: &Ray) -> bool {
            self.inner.occluded(ray)
        }
    }

    #[test]
    fn both_backends_give_the_same_texture_coordinates() {
        let mut scene = paper_scene(&SceneOverrides {
            width: Some(96),
            height: Some(64),
            ..SceneOverrides::default()
        })
        .unwrap();
        let ball = textured_sphere(24, 48, Vec3::new(0.0, 3.0, -6.0), 3.0);
        scene.objects.push(Object {
            name: "textured ball".into(),
            shape: Shape::Mesh(ball.clone()),
            material: 0,
            placement: Placement::World,
        });
        scene.objects.push(Object {
            name: "placed textured ball".into(),
            shape: Shape::Mesh(ball),
            material: 0,
            placement: Placement::Instance(glam::Affine3A::from_rotation_translation(
                glam::Quat::from_rotation_y(0.4),
                Vec3::new(6.0, 0.5, 0.0),
            )),
        });
        let embree = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        let grid = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let report = validate(&scene, &embree, &grid, 20_000, 2, 5);
        assert!(report.passed(), "{:?}", report.failures);
        assert!(report.camera_rays.textured > 100, "{report:?}");
        assert!(report.random_rays.textured > 200, "{report:?}");
        // A barycentric off by 1e-3 (a texel in a 1024-texel texture) fails.
        let skewed = SkewedBarycentrics {
            inner: &embree,
            skew: 1e-3,
        };
        let report = validate(&scene, &skewed, &grid, 20_000, 2, 5);
        assert!(
            report
                .failures
                .iter()
                .any(|f| f.starts_with("camera rays: texture coordinates")),
            "{:?}",
            report.failures
        );
    }

    #[test]
    fn rounding_near_a_surface_or_along_a_grazing_ray_is_within_the_bound() {
        let sphere = Sphere {
            center: Vec3::new(-7.5, 2.5, -3.0),
            radius: 2.5,
        };
        let scene = Scene {
            objects: vec![Object {
                name: "ball".into(),
                shape: Shape::Sphere(sphere),
                material: 0,
                placement: Placement::World,
            }],
            ..paper_scene(&SceneOverrides::default()).unwrap()
        };
        let hit = |t: f32| Hit {
            t,
            object: 0,
            prim: 0,
            u: 0.0,
            v: 0.0,
        };
        let ratio = |ray: &Ray, ta: f32, tb: f32| {
            let (separation, bound) = hit_point_bound(&scene, ray, &hit(ta), &hit(tb), 32);
            separation / bound
        };
        // `validate scenes/bunny.toml --seed 3` failed on this ray: it
        // starts 2.5e-5 from the ball, and the backends' distances differ by
        // 1.4e-7, a relative 5.7e-3 of t but a few f32 roundings of the
        // coordinates.
        let ray = Ray::new(
            Vec3::new(-5.400894, 3.8369727, -2.7630606),
            Vec3::new(0.6904004, 0.6532912, 0.31073785),
        );
        assert!(ratio(&ray, 0.000024557114, 0.000024697187) < 0.5);
        // Tangent to the ball from 10 away: a t error of 1e-4 moves the hit
        // point along the surface, not off it.
        let tangent = Ray::new(
            Vec3::new(-7.5 + 2.5 * 0.9999, 2.5, 7.0),
            Vec3::new(0.0, 0.0, -1.0),
        );
        let t = 10.0 - (2.5f32 * 2.5 - (2.5 * 0.9999f32).powi(2)).sqrt();
        assert!(ratio(&tangent, t, t + 1e-4) < 1.0);
        // Head on from 10 away, the same 1e-3 relative error is far off.
        let head_on = Ray::new(Vec3::new(-7.5, 2.5, 9.5), Vec3::new(0.0, 0.0, -1.0));
        assert!(ratio(&head_on, 10.0, 10.01) > 100.0);
    }
}
