//! The oracle for viewport sequences (RSVP): the least tracing any reuse
//! of a sample buffer around the eye could get away with.
//!
//! Each viewport pixel needs one buffer sample close to its centre, on a
//! pyramid level whose spacing is no wider than the pixel's footprint (one
//! sample per pixel, the least that keeps the output's detail): any of the
//! 2x2 samples around its centre on that level (L) or the next finer one
//! serves, if it was traced before and still has its true colour;
//! otherwise the pixel's nearest sample on level L must be traced. A frame
//! must so trace the samples never traced before (exposed by a pan, or by
//! a zoom into a finer level) and those whose colour truly changed since
//! they were last traced (found by tracing the candidates again on this
//! untimed pass, when the scene moves). Samples are identified by their
//! owning level, so a sample shared by two levels counts once. A pixel is
//! not served by a sample first traced for another pixel of the same frame
//! (this overcounts a little where footprints overlap).
//!
//! It does not depend on what RSVP chose (its filter reads four samples,
//! its level is chosen per patch, it traces whole groups of eight): the
//! gap between the two is what the efficiency column shows.

use std::collections::HashMap;

use glam::DVec2;
use rayon::prelude::*;

use crate::accel::Accelerator;
use crate::camera::ViewportPose;
use crate::render::{trace_groups, SampleGroup};
use crate::reuse::rsvp::{Level, LevelRays, SampleLattice, MAX_LEVEL};
use crate::scene::Scene;
use crate::shade::Shader;

/// A buffer sample: (owning level, its slot's column and row).
type SampleId = (Level, i64, i64);

/// The level of `lattice` at which a pixel whose neighbours lie `dx` and
/// `dy` away (in level-0 samples) gets at least one sample per pixel.
fn level_for_footprint(dx: DVec2, dy: DVec2) -> i32 {
    let longest = dx.length().max(dy.length());
    if longest <= 0.0 {
        return 0;
    }
    // The parallelogram's least width, in level-0 samples.
    let width = (dx.x * dy.y - dx.y * dy.x).abs() / longest;
    if !width.is_finite() || width <= 0.0 {
        return 0;
    }
    // A hair of tolerance: exactly one sample per pixel needs no finer level.
    ((1.0 / width).log2() - 1e-6)
        .ceil()
        .clamp(0.0, f64::from(MAX_LEVEL)) as i32
}

/// A pixel's candidate samples (2x2 around its centre on its level and
/// the next finer one) and the one it traces when none serves.
struct PixelSamples {
    candidates: [SampleId; 8],
    nearest: SampleId,
}

/// Calls `each` with the samples of every pixel of `pose`, in parallel.
fn for_each_pixel<T: Send>(
    pose: &ViewportPose,
    lattice: &SampleLattice,
    each: impl Fn(PixelSamples) -> Option<T> + Sync,
) -> Vec<T> {
    let (width, height) = (pose.camera.width, pose.camera.height);
    let turn = lattice.columns_per_turn as f64;
    (0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let each = &each;
            (0..width).filter_map(move |x| {
                let at = |dx: f64, dy: f64| {
                    lattice
                        .viewport_coords(
                            pose,
                            DVec2::new(f64::from(x) + 0.5 + dx, f64::from(y) + 0.5 + dy),
                        )
                        .map(|(c, r)| DVec2::new(c, r))
                };
                let centre = at(0.0, 0.0)?;
                let mut right = at(1.0, 0.0).unwrap_or(centre) - centre;
                let down = at(0.0, 1.0).unwrap_or(centre) - centre;
                // Azimuths jump by a turn across the seam.
                if right.x.abs() > 0.5 * turn {
                    right.x -= turn.copysign(right.x);
                }
                let level = level_for_footprint(right, down);
                let sample = |level: i32, col: f64, row: f64| {
                    let row = (row as i64).clamp(0, lattice.last_row(level));
                    lattice.owner(Level::square(level), col as i64, row)
                };
                let mut candidates = [(Level::default(), 0, 0); 8];
                for (k, slot) in candidates.iter_mut().enumerate() {
                    let level = (level + (k / 4) as i32).min(MAX_LEVEL);
                    let at = centre * f64::from(1u32 << level);
                    *slot = sample(
                        level,
                        at.x.floor() + (k % 2) as f64,
                        at.y.floor() + (k / 2 % 2) as f64,
                    );
                }
                let at = centre * f64::from(1u32 << level);
                let nearest = sample(level, at.x.round(), at.y.round());
                each(PixelSamples {
                    candidates,
                    nearest,
                })
            })
        })
        .collect()
}

/// FNV-1a over a colour's bits, never 0.
fn colour_hash(colour: glam::Vec3) -> u64 {
    colour
        .to_array()
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, c| {
            (h ^ u64::from(c.to_bits())).wrapping_mul(0x0100_0000_01b3)
        })
        | 1
}

/// Traces `samples` (sorted, unique) in the scene `shader` sees: one hash
/// per sample, in order.
fn trace_samples(shader: &Shader, lattice: &SampleLattice, samples: &[SampleId]) -> Vec<u64> {
    let mut hashes = vec![0u64; samples.len()];
    let mut levels: Vec<Level> = samples.iter().map(|s| s.0).collect();
    levels.sort_unstable();
    levels.dedup();
    for level in levels {
        let indices: Vec<usize> = (0..samples.len())
            .filter(|&i| samples[i].0 == level)
            .collect();
        if indices.is_empty() {
            continue;
        }
        let mut groups: Vec<SampleGroup> = indices
            .iter()
            .map(|&i| SampleGroup::containing(samples[i].1, samples[i].2))
            .collect();
        groups.sort_unstable_by_key(|g| (g.row, g.col));
        groups.dedup();
        let (colours, _) = trace_groups(shader, &LevelRays { lattice, level }, &groups);
        let mut traced = HashMap::with_capacity(groups.len() * 8);
        for (group, colours) in groups.iter().zip(&colours) {
            for (lane, sample) in group.lane_samples().into_iter().enumerate() {
                traced.insert(sample, colours[lane]);
            }
        }
        for i in indices {
            let (_, col, row) = samples[i];
            hashes[i] = colour_hash(traced[&(col, row)]);
        }
    }
    hashes
}

/// Per frame of `frames`, how many samples the viewports of `scene` could
/// not avoid tracing (see the module notes). Poses `accel`'s animated
/// objects as it goes; `progress` is called once per frame.
pub fn viewport_oracle(
    scene: &Scene,
    accel: &mut Accelerator,
    frames: std::ops::Range<u32>,
    mut progress: impl FnMut(),
) -> Vec<u64> {
    let base_lattice = SampleLattice::for_camera(&scene.camera);
    let animation = scene.animation.as_ref();
    // A lens the keys change changes samples as a move does.
    let lens_moves = animation.is_some_and(|a| {
        let first = a.lens_at(scene.lens, 0);
        (1..a.frames).any(|f| a.lens_at(scene.lens, f) != first)
    });
    let moves = animation.is_some_and(|a| a.moves_scene()) || lens_moves;
    let mut posed = scene.clone();
    // Per sample traced so far, a hash of the colour it was traced with.
    let mut kept: HashMap<SampleId, u64> = HashMap::new();
    let mut lattice: Option<SampleLattice> = None;
    let mut first_pose = true;
    let mut counts = Vec::new();
    for frame in frames {
        let camera = match animation {
            Some(a) => a.camera_at(&scene.camera, frame),
            None => scene.camera.clone(),
        };
        // A moved eye sees other samples: nothing carries over.
        if !matches!(&lattice, Some(l) if l.position == camera.position) {
            lattice = Some(SampleLattice::new(
                camera.position,
                base_lattice.columns_per_turn,
            ));
            kept.clear();
        }
        let lattice = lattice.as_ref().expect("just set");
        let poses: Vec<ViewportPose> = scene
            .viewports
            .iter()
            .map(|track| track.pose_at(&camera, frame))
            .collect();
        if moves {
            let animation = animation.expect("moves implies an animation");
            let mut moved = animation.pose(&mut posed.objects, &mut posed.lights, frame);
            posed.lens = animation.lens_at(scene.lens, frame);
            posed.camera_motion = animation.camera_motion(&scene.camera, frame);
            if first_pose {
                // The accelerator may have been left posed anywhere.
                moved = animation
                    .objects
                    .iter()
                    .flat_map(|track| track.objects.iter().copied())
                    .collect();
                first_pose = false;
            }
            let placements: Vec<_> = moved
                .into_iter()
                .map(|object| (object as u32, posed.objects[object].placement))
                .collect();
            accel
                .place_objects(&placements)
                .unwrap_or_else(|err| panic!("moving objects: {err}"));
        }
        let shader = Shader::new(&posed, &*accel);
        // Which kept samples still hold their true colour: in a still
        // scene all; otherwise the candidates are traced again to see.
        let still_true: Option<HashMap<SampleId, bool>> = moves.then(|| {
            let mut candidates: Vec<SampleId> = poses
                .iter()
                .flat_map(|pose| {
                    for_each_pixel(pose, lattice, |p| {
                        Some(p.candidates.into_iter().filter(|c| kept.contains_key(c)))
                    })
                    .into_iter()
                    .flatten()
                })
                .collect();
            candidates.par_sort_unstable();
            candidates.dedup();
            let hashes = trace_samples(&shader, lattice, &candidates);
            candidates
                .into_iter()
                .zip(hashes)
                .map(|(c, hash)| (c, kept[&c] == hash))
                .collect()
        });
        let serves = |c: &SampleId| match &still_true {
            Some(map) => map.get(c).copied().unwrap_or(false),
            None => kept.contains_key(c),
        };
        let mut needed: Vec<SampleId> = poses
            .iter()
            .flat_map(|pose| {
                for_each_pixel(pose, lattice, |p| {
                    (!p.candidates.iter().any(serves)).then_some(p.nearest)
                })
            })
            .collect();
        needed.par_sort_unstable();
        needed.dedup();
        let hashes = if moves {
            trace_samples(&shader, lattice, &needed)
        } else {
            // A still scene: a sample, once traced, never changes.
            vec![1; needed.len()]
        };
        counts.push(needed.len() as u64);
        kept.extend(needed.into_iter().zip(hashes));
        progress();
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BackendKind;
    use crate::scene::{builtin_scene, load_scene, SceneOverrides};

    const SMALL: SceneOverrides = SceneOverrides {
        width: Some(32),
        height: Some(24),
        projection: None,
        fov: None,
        spp: None,
        light_samples: None,
        texture_memory_mb: None,
        texture_filter: None,
        up: None,
    };

    fn oracle(scene: &Scene, frames: std::ops::Range<u32>) -> Vec<u64> {
        let mut accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        viewport_oracle(scene, &mut accel, frames, || {})
    }

    /// E2's zoom in (`scenes/paper-zoom-in.toml`), its viewport as small
    /// as the camera.
    fn zoom_in() -> Scene {
        let mut scene = builtin_scene("paper-zoom-in.toml", &SMALL).unwrap();
        scene.viewports[0].viewport.width = 32;
        scene.viewports[0].viewport.height = 24;
        scene
    }

    /// E2's viewport held at the zoom of its first key.
    fn still(mut scene: Scene) -> Scene {
        let track = &mut scene.viewports[0];
        let first = track.keys[0];
        for key in &mut track.keys {
            key.transform = first.transform;
        }
        scene
    }

    #[test]
    fn a_still_view_of_a_still_scene_traces_only_its_first_frame() {
        let scene = still(zoom_in());
        let counts = oracle(&scene, 0..4);
        // At most one sample per pixel, and not fewer than half: a pixel's
        // footprint spans at most about two samples here.
        assert!((32 * 24 / 2..=32 * 24).contains(&counts[0]), "{counts:?}");
        assert_eq!(counts[1..], [0, 0, 0]);
    }

    #[test]
    fn zooming_in_needs_finer_samples() {
        let scene = zoom_in();
        let counts = oracle(&scene, 0..100);
        let later: u64 = counts[1..].iter().sum();
        // A 2.5x zoom needs more than a frame's pixels again at the finer
        // level, yet far less than tracing every frame.
        assert!(later > counts[0] && later < 20 * counts[0], "{counts:?}");
    }

    #[test]
    fn a_moving_ball_retraces_only_what_it_changes() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper-all.toml");
        let mut scene = still(load_scene(&path, &SMALL).unwrap());
        scene.viewports[0].viewport.width = 32;
        scene.viewports[0].viewport.height = 24;
        // The camera stands still too: only the ball changes samples.
        scene.animation.as_mut().unwrap().camera_keys.truncate(1);
        let counts = oracle(&scene, 0..8);
        let pixels = 32 * 24;
        assert!(counts[1..].iter().any(|&n| n > 0), "{counts:?}");
        assert!(counts[1..].iter().all(|&n| n < pixels / 4), "{counts:?}");
    }

    #[test]
    fn a_footprint_of_one_sample_or_more_stays_on_level_zero() {
        let unit = |s: f64| (DVec2::new(s, 0.0), DVec2::new(0.0, s));
        assert_eq!(level_for_footprint(unit(1.0).0, unit(1.0).1), 0);
        assert_eq!(level_for_footprint(unit(3.0).0, unit(3.0).1), 0);
        assert_eq!(level_for_footprint(unit(0.5).0, unit(0.5).1), 1);
        assert_eq!(level_for_footprint(unit(0.3).0, unit(0.3).1), 2);
        // A sheared footprint is as fine as its narrowest width.
        assert_eq!(
            level_for_footprint(DVec2::new(1.0, 0.0), DVec2::new(0.9, 0.4)),
            2
        );
    }
}
