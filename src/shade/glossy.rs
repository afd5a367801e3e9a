//! Glossy reflection: where a rough mirror's reflection rays go.
//!
//! Promises:
//! - A glossy direction is a pure function of the path's key (see
//!   [`super::draws`]), the mirror direction, the surface's roughness and
//!   a fixed seed: a reused sample reflects as a fresh trace of it.
//! - It lies in a Phong lobe about the mirror direction whose exponent is
//!   `2 / roughness^2 - 2` (Walter et al.'s match of a Beckmann surface of
//!   that roughness; a cosine lobe at 1), so its mean over many samples
//!   converges to the lobe's blur of what the mirror sees.
//! - It leaves on the side of the surface the incoming ray came from: a
//!   direction the lobe tips below the surface is mirrored back above it.

use std::f32::consts::TAU;

use glam::Vec3;

use super::draws::key_draw;
use crate::geometry::plane_axes;

/// The seed glossy directions are drawn from.
const SEED: u64 = 0x676c_6f73_7379_2121;

/// The Phong exponent of the lobe of a surface of `roughness` in (0, 1].
fn lobe_exponent(roughness: f32) -> f32 {
    (2.0 / (roughness * roughness) - 2.0).max(0.0)
}

/// The direction the reflection ray of the path keyed `path` leaves in, on a surface of
/// `roughness` (above 0) whose perfect mirror would send it along unit
/// `mirror`; `facing` is the unit geometric normal on the incoming side.
pub(super) fn glossy_direction(mirror: Vec3, facing: Vec3, path: u64, roughness: f32) -> Vec3 {
    let (u, v) = (key_draw(path, SEED, &[0]), key_draw(path, SEED, &[1]));
    let cos_theta = u.powf(1.0 / (lobe_exponent(roughness) + 1.0));
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = (TAU * v).sin_cos();
    let (t1, t2) = plane_axes(mirror);
    let mut d = t1 * (sin_theta * cos_phi) + t2 * (sin_theta * sin_phi) + mirror * cos_theta;
    let below = d.dot(facing);
    if below <= 0.0 {
        d -= facing * (2.0 * below);
    }
    d.normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Glossy directions from `n` points near the origin.
    fn directions(mirror: Vec3, facing: Vec3, roughness: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| glossy_direction(mirror, facing, i as u64, roughness))
            .collect()
    }

    #[test]
    fn the_lobe_narrows_as_the_surface_smooths_and_centres_on_the_mirror() {
        let mirror = Vec3::new(0.6, 0.8, 0.0);
        let mean_cos = |roughness| {
            let d = directions(mirror, Vec3::Y, roughness, 4000);
            d.iter().map(|d| d.dot(mirror)).sum::<f32>() / d.len() as f32
        };
        let (smooth, medium, rough) = (mean_cos(0.05), mean_cos(0.3), mean_cos(0.8));
        assert!(
            smooth > 0.998 && smooth > medium && medium > rough,
            "{smooth} {medium} {rough}"
        );
        // Phong lobe: E[cos] = (e + 1) / (e + 2).
        let e = lobe_exponent(0.3);
        assert!((medium - (e + 1.0) / (e + 2.0)).abs() < 2e-3, "{medium}");
        // Centred: the mean direction is the mirror's.
        let d = directions(mirror, Vec3::Y, 0.3, 4000);
        let mean = d.iter().copied().sum::<Vec3>().normalize();
        assert!(mean.dot(mirror) > 0.9999, "{mean}");
    }

    #[test]
    fn directions_stay_above_the_surface_and_depend_on_the_path_alone() {
        // A grazing mirror direction: the lobe reaches below the surface.
        let mirror = Vec3::new(0.999, 0.0447, 0.0).normalize();
        for (i, d) in directions(mirror, Vec3::Y, 1.0, 500)
            .into_iter()
            .enumerate()
        {
            assert!(d.y >= 0.0 && (d.length() - 1.0).abs() < 1e-5, "{i}: {d}");
        }
        let a = glossy_direction(mirror, Vec3::Y, 99, 0.4);
        assert_eq!(a, glossy_direction(mirror, Vec3::Y, 99, 0.4));
        assert_ne!(a, glossy_direction(mirror, Vec3::Y, 100, 0.4));
    }
}
