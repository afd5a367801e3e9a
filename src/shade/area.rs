//! Where the shadow rays to a light go, and what each brings: a point
//! light's one ray, or an area light's samples over its surface.
//!
//! Promises:
//! - A sample's position on the light is a pure function of the path's
//!   key (see [`super::draws`]), the light's number, the sample's index
//!   and a fixed seed: never of the thread, the tile or the frame. A
//!   reused pixel sample draws as a fresh trace of it, so its light
//!   samples, and its colour, are the same bit for bit.
//! - Stratified: the `count` samples a point takes of a light fall one in
//!   each cell of an n x n grid over the light's parameter square when
//!   `count` is square, else one in each of `count` slices of its first
//!   axis.
//! - Unbiased for the light's glow: the weights make the mean over a
//!   light's samples converge to the light as an evenly glowing surface
//!   whose far field is an inverse-square point light of the same power
//!   (from straight in front, for the flat rectangle, disc and triangle;
//!   the triangle glows to both sides).

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, TAU};

use glam::Vec3;

use super::draws::{key_draw, ONE_BELOW};
use crate::geometry::{plane_axes, Falloff, Light, LightShape};

/// The seed light samples are drawn from.
const SEED: u64 = 0x6c69_6768_7473_2121;

/// How far along the segment to an area light's sample a shadow ray
/// looks for blockers: short of the light by a ten-thousandth, so a
/// surface the light lies flush with (a lamp on a ceiling) does not
/// shadow it.
pub(super) const AREA_SHADOW_REACH: f32 = 0.9999;

/// The point a shadow ray from `point` aims at for sample `(u, v)` (in
/// [0, 1)^2) of `light`, and the weight the light's power takes there
/// (before dividing by the samples taken); None where the sample cannot
/// light the point (behind a one-sided light, within a sphere light, in
/// a flat light's plane).
pub(super) fn sample_toward(light: &Light, point: Vec3, (u, v): (f32, f32)) -> Option<(Vec3, f32)> {
    let centre = light.position;
    match light.shape {
        LightShape::Point { falloff } => {
            let weight = match falloff {
                Falloff::None => 1.0,
                Falloff::InverseSquare => 1.0 / (centre - point).length_squared(),
            };
            weight.is_finite().then_some((centre, weight))
        }
        LightShape::Sphere { radius } => sphere_sample(centre, radius, point, (u, v)),
        LightShape::Rectangle {
            half_width,
            half_height,
            normal,
        } => {
            let target = centre + half_width * (2.0 * u - 1.0) + half_height * (2.0 * v - 1.0);
            planar_weight(target, normal, point)
        }
        LightShape::Disc { radius, normal } => {
            let (a, b) = plane_axes(normal);
            let (x, y) = concentric_disc(u, v);
            planar_weight(centre + (a * x + b * y) * radius, normal, point)
        }
        LightShape::Triangle { edges, normal } => {
            // Uniform over the triangle; the square root keeps strata
            // compact, so stratified samples stay stratified.
            let s = u.sqrt();
            let target = centre + edges[0] * (s * (1.0 - v)) + edges[1] * (s * v);
            let facing = if normal.dot(point - target) < 0.0 {
                -normal
            } else {
                normal
            };
            planar_weight(target, facing, point)
        }
    }
}

/// A one-sided flat light's sample at `target`: cosine at the light over
/// the distance squared.
fn planar_weight(target: Vec3, normal: Vec3, point: Vec3) -> Option<(Vec3, f32)> {
    let to_light = target - point;
    let distance_squared = to_light.length_squared();
    let cos_at_light = -normal.dot(to_light) / distance_squared.sqrt();
    (cos_at_light > 0.0 && distance_squared > 0.0)
        .then(|| (target, cos_at_light / distance_squared))
}

/// A sample of the cone a sphere light fills as seen from `point`, on the
/// sphere's near side: uniform in solid angle, weighted by the cone's
/// solid angle over the sphere's cross-section (pi r^2).
fn sphere_sample(
    centre: Vec3,
    radius: f32,
    point: Vec3,
    (u, v): (f32, f32),
) -> Option<(Vec3, f32)> {
    let axis = centre - point;
    let distance_squared = axis.length_squared();
    let radius_squared = radius * radius;
    if distance_squared <= radius_squared {
        return None;
    }
    let distance = distance_squared.sqrt();
    let axis = axis / distance;
    // 1 - cos of the cone's half-angle, without the cancellation of
    // 1 - sqrt(1 - s^2) for a small, far light.
    let sin_squared_max = radius_squared / distance_squared;
    let one_minus_cos_max = sin_squared_max / (1.0 + (1.0 - sin_squared_max).sqrt());
    let a = u * one_minus_cos_max;
    let cos_theta = 1.0 - a;
    let sin_theta = (a * (2.0 - a)).max(0.0).sqrt();
    let (sin_phi, cos_phi) = (TAU * v).sin_cos();
    let (t1, t2) = plane_axes(axis);
    let direction = t1 * (sin_theta * cos_phi) + t2 * (sin_theta * sin_phi) + axis * cos_theta;
    let across = radius_squared - distance_squared * sin_theta * sin_theta;
    let reach = distance * cos_theta - across.max(0.0).sqrt();
    let weight = 2.0 * one_minus_cos_max / radius_squared;
    Some((point + direction * reach, weight))
}

/// Shirley and Chiu's concentric map of the unit square onto the unit
/// disc: strata stay compact, so stratified samples stay stratified.
fn concentric_disc(u: f32, v: f32) -> (f32, f32) {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
    };
    let (sin, cos) = phi.sin_cos();
    (r * cos, r * sin)
}

/// Where in the light's parameter square sample `index` of `count` of
/// the path keyed `path` lies, for light number `light` (see the
/// module's promises).
pub(super) fn stratum_position(path: u64, light: usize, index: u32, count: u32) -> (f32, f32) {
    let draw = |axis: u64| key_draw(path, SEED, &[light as u64, u64::from(index), axis]);
    let side = (count as f32).sqrt().round() as u32;
    let (u, v) = if side * side == count {
        (
            ((index % side) as f32 + draw(0)) / side as f32,
            ((index / side) as f32 + draw(1)) / side as f32,
        )
    } else {
        ((index as f32 + draw(0)) / count as f32, draw(1))
    };
    // f32 rounding can carry a stratum's last draw onto its end.
    (u.min(ONE_BELOW), v.min(ONE_BELOW))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(shape: LightShape) -> Light {
        Light {
            position: Vec3::new(0.0, 4.0, 0.0),
            power: Vec3::ONE,
            shape,
            motion: None,
        }
    }

    /// The mean weight over `n` x `n` stratified samples from `point`.
    fn mean_weight(light: &Light, point: Vec3, n: u32) -> f32 {
        let count = n * n;
        (0..count)
            .map(|k| {
                let uv = stratum_position(point.x.to_bits().into(), 0, k, count);
                sample_toward(light, point, uv).map_or(0.0, |(_, w)| w)
            })
            .sum::<f32>()
            / count as f32
    }

    #[test]
    fn far_away_every_shape_lights_as_an_inverse_square_point_light() {
        let below = Vec3::new(0.0, -996.0, 0.0);
        let point = area(LightShape::Point {
            falloff: Falloff::InverseSquare,
        });
        let expected = sample_toward(&point, below, (0.5, 0.5)).unwrap().1;
        assert!((expected * 1e6 - 1.0).abs() < 1e-4, "{expected}");
        let down = Vec3::NEG_Y;
        for shape in [
            LightShape::Sphere { radius: 0.5 },
            LightShape::Disc {
                radius: 0.5,
                normal: down,
            },
            LightShape::Rectangle {
                half_width: Vec3::X * 0.3,
                half_height: Vec3::Z * 0.2,
                normal: down,
            },
            LightShape::Triangle {
                edges: [Vec3::X * 0.4, Vec3::Z * 0.3],
                normal: Vec3::Y,
            },
        ] {
            let got = mean_weight(&area(shape), below, 4);
            assert!(
                (got / expected - 1.0).abs() < 1e-3,
                "{shape:?}: {got} for {expected}"
            );
        }
    }

    #[test]
    fn samples_lie_on_the_light() {
        let light = area(LightShape::Sphere { radius: 1.5 });
        let from = Vec3::new(2.0, -1.0, 3.0);
        for k in 0..64 {
            let (target, weight) =
                sample_toward(&light, from, stratum_position(7, 2, k, 64)).unwrap();
            let off = ((target - light.position).length() - 1.5).abs();
            assert!(
                off < 1e-5 && weight > 0.0,
                "sample {k}: {off} off the sphere"
            );
            // On the near side: nothing of the sphere between.
            assert!((target - from).length() <= (light.position - from).length());
        }
        let disc = area(LightShape::Disc {
            radius: 2.0,
            normal: Vec3::NEG_Y,
        });
        for k in 0..64 {
            let (target, _) = sample_toward(&disc, Vec3::ZERO, stratum_position(7, 0, k, 64))
                .expect("the disc faces the origin");
            assert_eq!(target.y, 4.0);
            assert!(target.x.hypot(target.z) <= 2.0 + 1e-5, "{target}");
        }
    }

    #[test]
    fn a_triangle_light_spreads_its_samples_evenly_and_lights_both_sides() {
        let edges = [Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.5, 0.0, 1.5)];
        let light = area(LightShape::Triangle {
            edges,
            normal: edges[1].cross(edges[0]).normalize(),
        });
        let n = 32;
        let mut mean = Vec3::ZERO;
        for k in 0..n * n {
            let (target, _) =
                sample_toward(&light, Vec3::ZERO, stratum_position(3, 0, k, n * n)).unwrap();
            // Within the triangle: barycentric coordinates in [0, 1].
            let d = target - light.position;
            let (a, b) = (edges[0], edges[1]);
            let det = a.x * b.z - a.z * b.x;
            let s = (d.x * b.z - d.z * b.x) / det;
            let t = (a.x * d.z - a.z * d.x) / det;
            assert!(d.y.abs() < 1e-5 && s >= -1e-5 && t >= -1e-5 && s + t <= 1.0 + 1e-5);
            mean += target;
        }
        // Uniform over the area: the samples' mean is the centroid.
        let centroid = light.position + (edges[0] + edges[1]) / 3.0;
        let off = (mean / (n * n) as f32 - centroid).length();
        assert!(off < 5e-3, "{off}");
        // The same light from above as from below.
        let below = mean_weight(&light, Vec3::new(0.8, 1.0, 0.5), 4);
        let above = mean_weight(&light, Vec3::new(0.8, 7.0, 0.5), 4);
        assert!(
            below > 0.0 && (below / above - 1.0).abs() < 1e-3,
            "{below} {above}"
        );
        // Nothing to a point in its plane.
        assert_eq!(
            sample_toward(&light, Vec3::new(-3.0, 4.0, 0.0), (0.3, 0.6)),
            None
        );
    }

    #[test]
    fn one_sided_lights_do_not_light_what_lies_behind_them() {
        let above = Vec3::new(0.3, 6.0, 0.0);
        for shape in [
            LightShape::Disc {
                radius: 1.0,
                normal: Vec3::NEG_Y,
            },
            LightShape::Rectangle {
                half_width: Vec3::X,
                half_height: Vec3::Z,
                normal: Vec3::NEG_Y,
            },
        ] {
            assert_eq!(sample_toward(&area(shape), above, (0.3, 0.6)), None);
        }
        let inside = area(LightShape::Sphere { radius: 1.0 });
        assert_eq!(
            sample_toward(&inside, Vec3::new(0.0, 4.5, 0.0), (0.3, 0.6)),
            None
        );
    }

    #[test]
    fn strata_hold_one_sample_each_and_depend_on_the_path_alone() {
        let point = 0x1234_5678_9abc_u64;
        let mut cells = [0u32; 16];
        for k in 0..16 {
            let (u, v) = stratum_position(point, 1, k, 16);
            assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            cells[(u * 4.0) as usize + 4 * (v * 4.0) as usize] += 1;
            assert_eq!((u, v), stratum_position(point, 1, k, 16));
        }
        assert_eq!(cells, [1; 16]);
        let mut slices = [0u32; 5];
        for k in 0..5 {
            slices[(stratum_position(point, 1, k, 5).0 * 5.0) as usize] += 1;
        }
        assert_eq!(slices, [1; 5]);
        // Another point, or another light, draws elsewhere.
        let other_point = stratum_position(point + 1, 1, 0, 16);
        let other_light = stratum_position(point, 0, 0, 16);
        assert_ne!(other_point, stratum_position(point, 1, 0, 16));
        assert_ne!(other_light, stratum_position(point, 1, 0, 16));
    }
}
