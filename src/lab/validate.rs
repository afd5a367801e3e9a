//! `retrace validate`: Embree's answers checked against the pure-Rust grid.
//!
//! Two checks: (a) ray by ray, on every camera ray of the scene plus seeded
//! random rays through its bounds: do both backends agree on hit or miss, on
//! the object and primitive hit, and on the distance; (b) image by image:
//! the full frame from each backend, compared pixel by pixel.
//!
//! Rays that graze an edge shared by two triangles may legitimately name a
//! different triangle (or, for a silhouette edge, hit in one backend and miss
//! in the other): the thresholds allow a small share of those, and list the
//! disagreements so a user can reproduce them.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{Accelerator, Intersector};
use crate::camera::RayTable;
use crate::geometry::Aabb;
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
    /// Largest relative difference in t on rays hitting the same primitive.
    pub max_relative_t: f64,
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
            max_relative_t: 1e-3,
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

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RayAgreement {
    pub rays: usize,
    pub both_hit: usize,
    pub both_miss: usize,
    pub hit_miss_disagree: usize,
    pub same_primitive: usize,
    pub max_relative_t: f64,
    pub mean_relative_t: f64,
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

fn compare_rays(
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
    let mut relative_sum = 0.0;
    for (ray, (a, b)) in rays.iter().zip(&results) {
        let mut disagree = false;
        match (a, b) {
            (None, None) => agreement.both_miss += 1,
            (Some(a), Some(b)) => {
                agreement.both_hit += 1;
                if (a.object, a.prim) == (b.object, b.prim) {
                    agreement.same_primitive += 1;
                    let relative = f64::from(
                        (a.t - b.t).abs() / a.t.abs().max(b.t.abs()).max(f32::MIN_POSITIVE),
                    );
                    relative_sum += relative;
                    agreement.max_relative_t = agreement.max_relative_t.max(relative);
                    disagree = relative > thresholds.max_relative_t;
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
    agreement.mean_relative_t = relative_sum / agreement.same_primitive.max(1) as f64;
    agreement
}

/// Runs both checks. `embree` and `grid` must be built from `scene`.
pub fn validate(
    scene: &Scene,
    embree: &Accelerator,
    grid: &Accelerator,
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

    let mut failures = Vec::new();
    for (name, agreement) in [("camera", &camera_agreement), ("random", &random_agreement)] {
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
        if agreement.max_relative_t > thresholds.max_relative_t {
            failures.push(format!(
                "{name} rays: relative t difference up to {:.2e}, above {:.0e}",
                agreement.max_relative_t, thresholds.max_relative_t
            ));
        }
    }
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
