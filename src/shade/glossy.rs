//! Glossy reflection: where a rough mirror's reflection rays go.
//!
//! Promises:
//! - A glossy direction is a pure function of the path's key (see
//!   [`super::draws`]), the mirror direction, the surface's roughness, a
//!   fixed seed and, on a camera sample's first bounce, the sample's cell
//!   of its pixel's n x n grid of sub-samples ([`super::PixelStrata`]): a reused
//!   sample reflects as a fresh trace of it.
//! - Stratified across a pixel's sub-samples: the first bounces of the
//!   sub-samples of a square count n x n draw one in each cell of an
//!   n x n grid over the lobe's parameter square, and so do those of any
//!   n x n window of neighbouring strata (a view whose corner sits between
//!   cells). The lobe cell a sub-sample's cell is dealt is a fixed shuffle
//!   of the n^2 cells (the same in every pixel, or a window straddling
//!   pixels could deal a lobe cell twice), not the cell itself, which
//!   would tie where across the pixel a ray starts to which side of the
//!   lobe it leaves by, axis for axis. Within its lobe cell a bounce is
//!   placed by the path's key. The first bounces of the RSVP lattice's
//!   samples are stratified across every aligned block of neighbours of
//!   any level instead ([`super::strata::lattice_digits`]). Deeper
//!   bounces, refractions' children, counts that are not squares and a
//!   single sample draw from the key alone.
//! - It lies in a Phong lobe about the mirror direction whose exponent is
//!   `2 / roughness^2 - 2` (Walter et al.'s match of a Beckmann surface of
//!   that roughness; a cosine lobe at 1), so its mean over many samples
//!   converges to the lobe's blur of what the mirror sees.
//! - It leaves on the side of the surface the incoming ray came from: a
//!   direction the lobe tips below the surface is mirrored back above it.

use std::f32::consts::TAU;

use glam::Vec3;

use super::draws::key_draw;
use super::strata::{CellDeal, Stratum};
use crate::geometry::plane_axes;

/// The seed glossy directions are drawn from.
const SEED: u64 = 0x676c_6f73_7379_2121;

/// The seed of the shuffle that deals a pixel's sub-sample cells their
/// lobe cells: its own, so the shuffle shares nothing with the draws
/// inside the cells or with where the sub-samples sit.
const CELL_SEED: u64 = 0x6c6f_6265_2063_656c;

/// The deal of the lobe's cells.
static LOBE_CELLS: CellDeal = CellDeal::new(CELL_SEED);

/// Where in the lobe's parameter square, [0, 1)^2, the path keyed `path`
/// reflects: with `stratum`, a camera sample's first bounce (where the
/// sample stands among its neighbours), within the lobe cell that place
/// is dealt; without, anywhere.
pub(super) fn lobe_position(path: u64, stratum: Option<Stratum>) -> (f32, f32) {
    let (u, v) = (key_draw(path, SEED, &[0]), key_draw(path, SEED, &[1]));
    LOBE_CELLS.place((u, v), stratum)
}

/// The Phong exponent of the lobe of a surface of `roughness` in (0, 1].
fn lobe_exponent(roughness: f32) -> f32 {
    (2.0 / (roughness * roughness) - 2.0).max(0.0)
}

/// The direction a reflection ray leaves in from point `(u, v)` of the
/// lobe's parameter square ([`lobe_position`]), on a surface of
/// `roughness` (above 0) whose perfect mirror would send it along unit
/// `mirror`; `facing` is the unit geometric normal on the incoming side.
pub(super) fn glossy_direction(
    mirror: Vec3,
    facing: Vec3,
    roughness: f32,
    (u, v): (f32, f32),
) -> Vec3 {
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
    use crate::ray::PACKET_WIDTH;
    use crate::shade::strata::{PixelStrata, MAX_SIDE};

    /// Glossy directions from `n` points near the origin.
    fn directions(mirror: Vec3, facing: Vec3, roughness: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| glossy_direction(mirror, facing, roughness, lobe_position(i as u64, None)))
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
        let at = |path| glossy_direction(mirror, Vec3::Y, 0.4, lobe_position(path, None));
        assert_eq!(at(99), at(99));
        assert_ne!(at(99), at(100));
    }

    /// The lobe cells the first bounces of the `side` x `side` strata from
    /// lattice position `corner` draw in, counted.
    fn lobe_cells(side: u32, corner: (i64, i64)) -> Vec<u32> {
        let n = i64::from(side);
        let window: Vec<(i64, i64)> = (0..n * n)
            .map(|k| (corner.0 + k % n, corner.1 + k / n))
            .collect();
        let mut cells = vec![0; (side * side) as usize];
        for lanes in window.chunks(PACKET_WIDTH) {
            let strata = std::array::from_fn(|lane| lanes.get(lane).copied().unwrap_or((0, 0)));
            let strata = PixelStrata::new(side, strata);
            for (lane, &(col, row)) in lanes.iter().enumerate() {
                let path = crate::sampling::hash(&[col as u64, row as u64]);
                let (u, v) = lobe_position(path, Some(strata.lane(lane)));
                assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
                let cell = |x: f32| (x * side as f32) as u32;
                cells[(cell(v) * side + cell(u)) as usize] += 1;
            }
        }
        cells
    }

    #[test]
    fn any_window_of_strata_draws_one_first_bounce_in_each_lobe_cell() {
        for side in [2, 3, 4, 5, 16] {
            let n = i64::from(side);
            // On a pixel, between pixels, and far from the origin on either
            // side of it (a pan's lattice runs both ways).
            for corner in [(0, 0), (-7 * n, 3 * n), (1 << 40, -(1 << 33))] {
                for (dx, dy) in [(0, 0), (1, 0), (0, n - 1), (n - 1, 1), (n / 2, n / 2)] {
                    let at = (corner.0 + dx, corner.1 + dy);
                    assert_eq!(
                        lobe_cells(side, at),
                        vec![1; (side * side) as usize],
                        "{side} at {at:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn sub_samples_are_dealt_shuffled_lobe_cells_and_jitter_in_them_by_the_key() {
        for side in 2..=MAX_SIDE as u32 {
            let cells: Vec<(u32, u32)> = (0..side * side)
                .map(|k| LOBE_CELLS.cell(side, (k % side, k / side)))
                .collect();
            let own = cells
                .iter()
                .enumerate()
                .filter(|&(k, &(a, b))| (a, b) == (k as u32 % side, k as u32 / side))
                .count();
            // A shuffle keeps about one cell in place (as many as it keeps
            // on average), not all.
            assert!(own <= 3, "{side}: {own} cells kept");
        }
        // Within its cell a draw is the key's, as unstratified.
        let path = 0x5eed_cafe;
        let (u, v) = lobe_position(path, None);
        let (a, b) = LOBE_CELLS.cell(4, (1, 2));
        let (su, sv) = lobe_position(path, Some(Stratum::Cell(4, (1, 2))));
        assert_eq!((su, sv), ((a as f32 + u) / 4.0, (b as f32 + v) / 4.0));
    }
}
