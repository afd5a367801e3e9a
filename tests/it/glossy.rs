//! Glossy reflection at several samples a pixel: the first bounces of a
//! pixel's sub-samples, and of any window of as many neighbouring strata,
//! share the lobe out one to each cell of its n x n grid; and reuse under
//! a glossy floor (pans whole and snapped to strata, OSTC) stays exact.

use std::collections::HashMap;
use std::f32::consts::TAU;
use std::path::Path;

use glam::Vec3;
use retrace::accel::{Accelerator, BackendKind};
use retrace::camera::RayTable;
use retrace::frame_loop::{Options, Techniques};
use retrace::geometry::plane_axes;
use retrace::ray::{LaneMask, RayPacket, PACKET_WIDTH};
use retrace::render::{trace_group, PrimaryRays, SampleGroup, Strata};
use retrace::reuse::pan::FractionalPan;
use retrace::scene::{parse_scene_str, Scene, SceneOverrides};
use retrace::shade::{RayCounts, RayKind, RayObserver, Shader};

use crate::common::run_exact_reusing_with;

/// The floor's roughness: a Phong lobe of exponent 2 / 0.25 - 2 = 6.
const ROUGHNESS: f32 = 0.5;

/// A glossy floor seen from nearly straight above through a narrow lens,
/// `size` pixels square at `spp`: every camera ray meets the floor, and
/// the mirror directions lie so near its normal that the lobe never
/// reaches below it (no draw is folded back up).
fn floor_from_above(size: u32, spp: u32) -> Scene {
    let text = format!(
        "[render]\nmax_depth = 1\nambient = [0.1, 0.1, 0.1]\n\
         [camera]\nprojection = \"perspective\"\nposition = [0, 6, 0]\nyaw = 0\npitch = -88\nfov = 12\n\
         [[light]]\nposition = [2, 9, 1]\n\
         [material.floor]\ndiffuse = [0.5, 0.5, 0.5]\nreflectivity = 0.5\nroughness = {ROUGHNESS}\n\
         [[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"floor\"\n"
    );
    let overrides = SceneOverrides {
        width: Some(size),
        height: Some(size),
        spp: Some(spp),
        ..SceneOverrides::default()
    };
    parse_scene_str(&text, Path::new("floor.toml"), &overrides).unwrap()
}

/// Each camera ray's direction (by its bits) with the direction of the
/// reflection its hit sent on, as traced.
#[derive(Default)]
struct Bounces {
    last_primary: Option<(RayPacket, LaneMask)>,
    pairs: Vec<(Vec3, Vec3)>,
}

impl RayObserver for Bounces {
    fn traced(&mut self, kind: RayKind, rays: &RayPacket, mask: LaneMask, _: &[f32; PACKET_WIDTH]) {
        match kind {
            RayKind::Primary => self.last_primary = Some((*rays, mask)),
            RayKind::Reflection => {
                let (primary, primary_mask) = self.last_primary.take().expect("a camera packet");
                for lane in (0..PACKET_WIDTH).filter(|lane| mask & (1 << lane) != 0) {
                    assert!(primary_mask & (1 << lane) != 0);
                    self.pairs.push((primary[lane].dir, rays[lane].dir));
                }
            }
            _ => {}
        }
    }
}

/// Where in the lobe's parameter square [0, 1)^2 `reflected` lies about
/// the floor's mirror direction of camera ray `dir`: the inverse of the
/// Phong lobe's map (u = cos^(e + 1), v = the turn about the mirror).
fn lobe_position(dir: Vec3, reflected: Vec3) -> (f32, f32) {
    let d = dir.normalize();
    let mirror = d - Vec3::Y * (2.0 * d.dot(Vec3::Y));
    let (t1, t2) = plane_axes(mirror);
    let exponent = 2.0 / (ROUGHNESS * ROUGHNESS) - 2.0;
    let u = reflected.dot(mirror).clamp(0.0, 1.0).powf(exponent + 1.0);
    let v = (reflected.dot(t2).atan2(reflected.dot(t1)) / TAU).rem_euclid(1.0);
    (u, v)
}

/// Each stratum's (column, row on the lattice of strata) first bounce, as
/// a position in the lobe's parameter square, from tracing `groups` of
/// `source`, whose rays are `table`'s sub-samples.
fn bounces_by_stratum(
    shader: &Shader,
    table: &RayTable,
    source: &dyn PrimaryRays,
    groups: &[SampleGroup],
) -> HashMap<(i64, i64), (f32, f32)> {
    let side = i64::from(table.samples().grid_side());
    let (width, height) = table.size();
    let mut stratum_of = HashMap::new();
    for row in 0..i64::from(height) {
        for col in 0..i64::from(width) {
            for k in 0..table.samples().count() {
                let dir = table.sample(col, row, k).unwrap().dir;
                let stratum = (
                    col * side + i64::from(k) % side,
                    row * side + i64::from(k) / side,
                );
                assert!(stratum_of
                    .insert(dir.to_array().map(f32::to_bits), stratum)
                    .is_none());
            }
        }
    }
    let mut bounces = Bounces::default();
    for &group in groups {
        trace_group(
            shader,
            source,
            group,
            &mut RayCounts::default(),
            Some(&mut bounces),
        );
    }
    bounces
        .pairs
        .iter()
        .map(|&(dir, reflected)| {
            (
                stratum_of[&dir.to_array().map(f32::to_bits)],
                lobe_position(dir, reflected),
            )
        })
        .collect()
}

#[test]
fn first_glossy_bounces_fall_one_in_each_lobe_cell_over_any_window_of_strata() {
    for spp in [4, 9, 16] {
        let size = 8;
        let scene = floor_from_above(size, spp);
        let accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let shader = Shader::new(&scene, &accel);
        let table = RayTable::with_samples(&scene.camera, scene.samples);
        let side = i64::from(table.samples().grid_side());
        // Traced as a full render traces them: by groups of pixels.
        let pixel_groups = SampleGroup::covering(0..i64::from(size), 0..i64::from(size));
        let bounces = bounces_by_stratum(&shader, &table, &table, &pixel_groups);
        let strata = i64::from(size) * side;
        assert_eq!(
            bounces.len() as i64,
            strata * strata,
            "{spp}: every ray reflects"
        );
        // Every window of side x side strata, on a pixel or between pixels.
        for top in 0..=strata - side {
            for left in 0..=strata - side {
                let mut cells = vec![0; (side * side) as usize];
                for row in top..top + side {
                    for col in left..left + side {
                        let (u, v) = bounces[&(col, row)];
                        let cell = |x: f32| (x * side as f32) as i64;
                        cells[(cell(v) * side + cell(u)) as usize] += 1;
                    }
                }
                assert!(
                    cells.iter().all(|&n| n == 1),
                    "{spp} spp, window at stratum ({left}, {top}): lobe cells {cells:?}"
                );
            }
        }
        // A store keeping strata traces them as groups of strata, four
        // wide and two tall whatever the pixel: the same bounces, bit for
        // bit.
        let strata_source = Strata::new(&table);
        let strata_groups = SampleGroup::covering(0..strata, 0..strata);
        let again = bounces_by_stratum(&shader, &table, &strata_source, &strata_groups);
        assert!(
            again == bounces,
            "{spp} spp: traced by strata, bounced elsewhere"
        );
    }
}

/// The soft-light room (its floor glossy) small, at `spp`, seen by an
/// equal-angle camera panned `yaw_a_frame` degrees a frame over `frames`
/// frames while the ball bounces.
fn panned_soft_light(spp: u32, frames: u32, yaw_a_frame: f64) -> Scene {
    let text = include_str!("../../scenes/soft-light.toml");
    let perspective = "projection = \"perspective\"\nposition = [0.0, 2.2, 9.0]\nlook_at = [0.0, 1.3, 0.0]\nfov = 60.0\n";
    assert!(text.contains(perspective));
    let text = text
        .replace(
            perspective,
            "projection = \"equal-angle\"\nposition = [0.0, 2.2, 9.0]\nyaw = 0.0\npitch = -12.0\nfov = 70.0\n",
        )
        .replace("frames = 50\n", &format!("frames = {frames}\n"));
    let last = frames - 1;
    let text = format!(
        "{text}\n[[animation.camera]]\nframe = 0\nyaw = 0.0\npitch = -12.0\n\
         [[animation.camera]]\nframe = {last}\nyaw = {}\npitch = -12.0\n",
        f64::from(last) * yaw_a_frame
    );
    let overrides = SceneOverrides {
        width: Some(64),
        height: Some(48),
        spp: Some(spp),
        ..SceneOverrides::default()
    };
    parse_scene_str(&text, Path::new("scenes/soft-light.toml"), &overrides).unwrap()
}

on_every_backend! {
    a_pan_over_a_glossy_floor_is_exact_at_four_samples(backend) {
        // 70 degrees over 64 px: a little over a degree a sample, so 4
        // degrees a frame is several whole pixels.
        let scene = panned_soft_light(4, 4, 4.0);
        let stats = run_exact_reusing_with(&scene, backend, Options::new(Techniques::AUTO, 0..4));
        assert!(stats[1..].iter().all(|s| s.mode.as_str() != "full"));
    }

    a_slow_pan_over_a_glossy_floor_snaps_to_strata_and_stays_exact(backend) {
        // A quarter of a sample a frame: views whose corners sit between
        // cells, resolved from strata traced in groups of their own.
        let step = 70.0 / 64.0;
        let scene = panned_soft_light(4, 5, step / 4.0);
        let options = Options {
            fractional_pan: FractionalPan::Snap,
            ..Options::new(Techniques::AUTO, 0..5)
        };
        let stats = run_exact_reusing_with(&scene, backend, options);
        assert!(stats.iter().any(|s| s.snap_error_deg() != (0.0, 0.0)));
    }
}
