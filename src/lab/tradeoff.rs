//! `retrace tradeoff`: what each approximation knob buys in speed and costs
//! in accuracy (DESIGN section 5).
//!
//! Every setting is timed against full renders of the same frames in the
//! same run, and its frames are compared with the exact reference: direct
//! tracing of the output image's own rays (the camera's unsnapped view, or
//! the viewport's own rays). Knobs, one changed at a time from the default:
//! - pan: snap to whole lattice samples vs bilinear resampling at the true
//!   yaw (E1's pan);
//! - RSVP filter, buffer oversampling and pyramid level bias (E2's zoom in);
//! - OSTC region grid and voxel grid resolution (E3's bouncing ball): exact,
//!   so only their speed varies;
//! - light samples (scenes with area lights): shadow rays a pixel sample
//!   casts to each area light, against their noise. Each setting's full
//!   and accelerated sides render at that setting, and all are scored
//!   against one converged reference.
//!
//! Accelerated sides are timed with 8-bit output only; errors come from a
//! second, untimed pass that keeps linear colour.

use std::ops::Range;
use std::path::Path;

use crate::accel::{AccelError, Accelerator, BackendKind};
use crate::frame_loop::{Options, OstcSettings, Techniques};
use crate::geometry::Light;
use crate::lab::bench::ErrorSummary;
use crate::lab::bench::{bench_sequence, Measure, SequenceBench};
use crate::lab::plot::{LabelledPoint, PlotError, ScatterGroup};
use crate::output::{csv_text, CsvError, Floats};
use crate::reuse::ostc::DEFAULT_VOXELS;
use crate::reuse::pan::FractionalPan;
use crate::reuse::regions::RegionGrid;
use crate::reuse::rsvp::{Filter, RsvpKnobs};
use crate::scene::{builtin_scene, Scene, SceneError, SceneOverrides};
use crate::verify::References;

/// One knob at one setting, against the exact reference.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TradeoffRow {
    pub knob: &'static str,
    pub setting: String,
    pub frames: u32,
    /// Full renders of the sequence's frames, per frame.
    pub full_ms_per_frame: f64,
    /// The accelerated sequence (frame 0 included), per frame.
    pub accelerated_ms_per_frame: f64,
    pub speedup: f64,
    /// Over every frame, on colours clamped to [0, 1].
    pub max_abs_error: f32,
    /// Mean over frames of each frame's mean absolute error.
    pub mean_abs_error: f64,
    /// The worst frame's PSNR (infinite when every frame is exact).
    pub worst_psnr_db: f64,
    /// Mean over frames of the share of pixels whose 8-bit value differs.
    pub differing_share: f64,
    /// Every frame equal to its reference bit for bit; None where the
    /// check does not apply (RSVP resamples, so it is measured only).
    pub bit_exact: Option<bool>,
    /// Mean PSNR against a converged reference of the full render at the
    /// run's samples a pixel, and of the accelerated output (see
    /// [`crate::lab::bench::ReferenceErrors`]).
    pub full_reference_psnr_db: f64,
    pub accelerated_reference_psnr_db: f64,
}

/// The animations the knobs are swept on; a knob group with no scene is
/// skipped.
pub struct TradeoffScenes {
    /// A camera that pans (E1: a whole turn, 3.6 degrees per frame), for
    /// snapping against resampling.
    pub pan: Option<Scene>,
    /// RSVP viewports (E2: one zooming in from 100 to 50 degrees), for the
    /// RSVP knobs.
    pub zoom: Option<Scene>,
    /// Objects or lights that move (E3: a bouncing ball), for the OSTC
    /// knobs.
    pub objects: Option<Scene>,
    /// Area lights (none among the paper's experiments), for the light
    /// samples.
    pub area_lit: Option<Scene>,
}

impl TradeoffScenes {
    /// The paper's experiments built into the binary: E1's pan
    /// (`scenes/paper-pan.toml`), E2's zoom in and E3's bouncing ball.
    pub fn builtin(overrides: &SceneOverrides) -> Result<TradeoffScenes, SceneError> {
        Ok(TradeoffScenes {
            pan: Some(builtin_scene("paper-pan.toml", overrides)?),
            zoom: Some(builtin_scene("paper-zoom-in.toml", overrides)?),
            objects: Some(builtin_scene("paper-bounce.toml", overrides)?),
            area_lit: None,
        })
    }

    /// The knob groups `scene`'s own timeline exercises: the pan knobs
    /// when its equal-angle camera moves (and it has no viewports), the
    /// RSVP knobs when it has viewports, the OSTC knobs when objects or
    /// lights move; and the light samples when it has area lights.
    pub fn of(scene: Scene) -> TradeoffScenes {
        let animation = scene.animation.as_ref();
        let pans = scene.viewports.is_empty()
            && scene.camera.projection == crate::camera::Projection::EqualAngle
            && animation.is_some_and(|a| !a.camera_keys.is_empty());
        let moves = animation.is_some_and(|a| a.moves_scene());
        let zooms = !scene.viewports.is_empty();
        let area_lit = scene.lights.iter().any(Light::is_area);
        TradeoffScenes {
            pan: pans.then(|| scene.clone()),
            zoom: zooms.then(|| scene.clone()),
            objects: moves.then(|| scene.clone()),
            area_lit: area_lit.then_some(scene),
        }
    }

    /// The knob groups with no scene to run on, by name.
    pub fn skipped(&self) -> Vec<&'static str> {
        [
            ("pan", &self.pan),
            ("RSVP", &self.zoom),
            ("OSTC", &self.objects),
            ("light samples", &self.area_lit),
        ]
        .into_iter()
        .filter(|(_, scene)| scene.is_none())
        .map(|(name, _)| name)
        .collect()
    }

    fn scenes(&self) -> impl Iterator<Item = &Scene> {
        [&self.pan, &self.zoom, &self.objects, &self.area_lit]
            .into_iter()
            .flatten()
    }

    /// Frames every swept animation has: the valid frame numbers are
    /// `0..frame_count()`.
    pub fn frame_count(&self) -> u32 {
        self.scenes()
            .map(|scene| scene.animation.as_ref().map_or(1, |a| a.frames))
            .min()
            .unwrap_or(1)
    }

    /// How many times [`sweep`] calls its progress callback for `frames` frames.
    pub fn progress_steps(&self, frames: u32) -> u64 {
        // Each setting's sequence: full, accelerated and checked, a step
        // per frame each.
        let settings = |scene: &Option<Scene>, count: usize| scene.as_ref().map_or(0, |_| count);
        let count = settings(&self.pan, PAN_SETTINGS.len())
            + settings(&self.zoom, rsvp_knob_settings().len())
            + settings(&self.objects, unique_ostc_settings().len())
            + self
                .area_lit
                .as_ref()
                .map_or(0, |scene| light_sample_settings(scene.light_samples).len());
        3 * u64::from(frames) * count as u64
    }
}

const PAN_SETTINGS: [FractionalPan; 2] = [FractionalPan::Snap, FractionalPan::Resample];

/// The light samples swept on a scene whose own count is `own`: its own
/// first (the most converged of the usual ones, it renders the shared
/// reference), then one, four and sixteen, each once.
fn light_sample_settings(own: u32) -> Vec<u32> {
    let mut settings = vec![own];
    for n in [1, 4, 16] {
        if !settings.contains(&n) {
            settings.push(n);
        }
    }
    settings
}

/// The RSVP settings swept: the default first, then one knob changed at a
/// time (filter, oversampling, level bias).
pub fn rsvp_knob_settings() -> Vec<RsvpKnobs> {
    let default = RsvpKnobs::default();
    let mut settings = vec![default];
    for filter in [Filter::Nearest, Filter::Box] {
        settings.push(RsvpKnobs { filter, ..default });
    }
    // The default (0.71) is below 1: some pixels get fewer than one sample
    // each. Cheaper still, and dearer, measured alike.
    for oversample in [0.5, 1.0, 1.5, 2.0] {
        settings.push(RsvpKnobs {
            oversample,
            ..default
        });
    }
    for level_bias in [-1, 1] {
        settings.push(RsvpKnobs {
            level_bias,
            ..default
        });
    }
    settings
}

/// Each RSVP setting of [`rsvp_knob_settings`] on `scene`'s viewports:
/// direct renders against RSVP, with the error against the direct renders.
/// `progress` is called three times per frame and setting.
pub fn sweep_rsvp_knobs(
    scene: &Scene,
    accel: &mut Accelerator,
    frames: Range<u32>,
    mut progress: impl FnMut(),
) -> Vec<SequenceBench> {
    let mut references = References::default();
    rsvp_knob_settings()
        .into_iter()
        .map(|rsvp| {
            let options = Options {
                rsvp,
                ..Options::new(Techniques::AUTO, frames.clone())
            };
            bench_sequence(
                scene,
                accel,
                &options,
                1,
                ERRORS_NOT_ORACLE,
                &mut references,
                &mut progress,
            )
        })
        .collect()
}

/// The tradeoff measures each setting's error, against the views' own
/// rays and against a converged reference, never the oracle.
const ERRORS_NOT_ORACLE: Measure = Measure {
    error: true,
    oracle: false,
    reference: true,
};

/// OSTC settings: the region grids, then the voxel grids (each with the
/// other knob at its default).
fn ostc_settings() -> Vec<(&'static str, String, OstcSettings)> {
    let default = OstcSettings::default();
    let mut settings = Vec::new();
    for n in [8, 16, 32, 64, RegionGrid::PYRAMID.0] {
        settings.push((
            "OSTC region grid",
            format!("{n}x{n}"),
            OstcSettings {
                regions: Some(RegionGrid(n)),
                ..default
            },
        ));
    }
    settings.push((
        "OSTC region grid",
        "one group a region".to_string(),
        default,
    ));
    let mut voxel_counts = vec![64, DEFAULT_VOXELS, 4096, 32_768];
    voxel_counts.sort_unstable();
    voxel_counts.dedup();
    for voxels in voxel_counts {
        settings.push((
            "OSTC voxel grid",
            format!("{voxels} voxel{}", if voxels == 1 { "" } else { "s" }),
            OstcSettings { voxels, ..default },
        ));
    }
    settings
}

/// The distinct settings of [`ostc_settings`] (the default appears in both
/// groups but runs once).
fn unique_ostc_settings() -> Vec<OstcSettings> {
    let mut unique: Vec<OstcSettings> = Vec::new();
    for (_, _, setting) in ostc_settings() {
        if !unique.contains(&setting) {
            unique.push(setting);
        }
    }
    unique
}

/// Sweeps every knob on `scenes` over `frames` (which must lie within
/// [`TradeoffScenes::frame_count`]); `progress` gets what is running.
pub fn sweep(
    scenes: &TradeoffScenes,
    backend: BackendKind,
    grid_resolution: Option<[u32; 3]>,
    frames: Range<u32>,
    mut progress: impl FnMut(&str),
) -> Result<Vec<TradeoffRow>, AccelError> {
    let count = frames.end - frames.start;
    let mut rows = Vec::new();

    if let Some(scene) = &scenes.pan {
        let mut accel = Accelerator::build_with(backend, &scene.objects, grid_resolution)?;
        let pan_settings: Vec<_> = PAN_SETTINGS
            .iter()
            .map(|&fractional| CameraSetting {
                fractional,
                ostc: OstcSettings::default(),
            })
            .collect();
        let pan = measure_camera_settings(
            scene,
            &mut accel,
            frames.clone(),
            &pan_settings,
            &mut References::default(),
            |what| progress(&format!("pan: {what}")),
        );
        for (fractional, measured) in PAN_SETTINGS.iter().zip(pan) {
            let setting = match fractional {
                FractionalPan::Snap => "snap to lattice",
                FractionalPan::SnapSamples => "snap to whole samples",
                FractionalPan::BlendStrata => "blend strata",
                FractionalPan::Resample => "resample true yaw",
            };
            rows.push(measured.row("pan", setting.to_string(), count));
        }
    }

    if let Some(scene) = &scenes.zoom {
        let mut accel = Accelerator::build_with(backend, &scene.objects, grid_resolution)?;
        let rsvp = sweep_rsvp_knobs(scene, &mut accel, frames.clone(), || progress("RSVP knobs"));
        let measured: Vec<(RsvpKnobs, Measured)> = rsvp
            .iter()
            .map(|result| (result.knobs, Measured::of(result, false)))
            .collect();
        // Each knob's rows: the settings that differ from the default in that
        // knob alone, the default among them (the point each knob moves from).
        for knob in [
            RsvpKnob::Filter,
            RsvpKnob::Oversampling,
            RsvpKnob::LevelBias,
        ] {
            for (settings, result) in &measured {
                if knob.alone_varied(settings) {
                    rows.push(result.row(knob.name(), knob.setting(settings), count));
                }
            }
        }
    }

    if let Some(scene) = &scenes.objects {
        let mut accel = Accelerator::build_with(backend, &scene.objects, grid_resolution)?;
        let unique = unique_ostc_settings();
        let settings: Vec<_> = unique
            .iter()
            .map(|&ostc| CameraSetting {
                fractional: FractionalPan::Snap,
                ostc,
            })
            .collect();
        let measured = measure_camera_settings(
            scene,
            &mut accel,
            frames.clone(),
            &settings,
            &mut References::default(),
            |what| progress(&format!("OSTC: {what}")),
        );
        for (knob, setting, ostc) in ostc_settings() {
            let index = unique.iter().position(|u| *u == ostc).expect("listed");
            rows.push(measured[index].row(knob, setting, count));
        }
    }

    if let Some(scene) = &scenes.area_lit {
        let mut accel = Accelerator::build_with(backend, &scene.objects, grid_resolution)?;
        // One reference for every count: the first setting's, the scene's own.
        let mut references = References::default();
        let default = [CameraSetting {
            fractional: FractionalPan::Snap,
            ostc: OstcSettings::default(),
        }];
        for light_samples in light_sample_settings(scene.light_samples) {
            let at = Scene {
                light_samples,
                ..scene.clone()
            };
            let measured = measure_camera_settings(
                &at,
                &mut accel,
                frames.clone(),
                &default,
                &mut references,
                |what| progress(&format!("light samples {light_samples}: {what}")),
            );
            let setting = if light_samples == scene.light_samples {
                format!("{light_samples} (the scene's)")
            } else {
                light_samples.to_string()
            };
            rows.push(measured[0].row("light samples", setting, count));
        }
    }
    Ok(rows)
}

#[derive(Clone, Copy)]
enum RsvpKnob {
    Filter,
    Oversampling,
    LevelBias,
}

impl RsvpKnob {
    fn name(self) -> &'static str {
        match self {
            RsvpKnob::Filter => "RSVP filter",
            RsvpKnob::Oversampling => "RSVP oversampling",
            RsvpKnob::LevelBias => "RSVP level bias",
        }
    }

    fn setting(self, knobs: &RsvpKnobs) -> String {
        match self {
            RsvpKnob::Filter => knobs.filter.to_string(),
            RsvpKnob::Oversampling => format!("{}x", knobs.oversample),
            RsvpKnob::LevelBias => format!("{:+}", knobs.level_bias),
        }
    }

    /// Whether `knobs` differ from the default in this knob at most.
    fn alone_varied(self, knobs: &RsvpKnobs) -> bool {
        let default = RsvpKnobs::default();
        let same_filter = knobs.filter == default.filter;
        let same_oversample = knobs.oversample == default.oversample;
        let same_bias = knobs.level_bias == default.level_bias;
        match self {
            RsvpKnob::Filter => same_oversample && same_bias,
            RsvpKnob::Oversampling => same_filter && same_bias,
            RsvpKnob::LevelBias => same_filter && same_oversample,
        }
    }
}

#[derive(Clone, Copy)]
struct CameraSetting {
    fractional: FractionalPan,
    ostc: OstcSettings,
}

/// Whole-sequence times (ms) and the error of one setting.
#[derive(Clone, Copy, Debug)]
struct Measured {
    full_ms: f64,
    accelerated_ms: f64,
    error: ErrorSummary,
    /// Every frame equal to its own rays bit for bit; None where the
    /// check does not apply (RSVP resamples, so it is measured only).
    bit_exact: Option<bool>,
    /// Mean PSNR against the converged reference: (full, accelerated).
    reference_psnr_db: (f64, f64),
}

impl Measured {
    /// A sequence's times and error; `exact_check` says whether bit
    /// equality with the views' own rays is reported.
    fn of(bench: &SequenceBench, exact_check: bool) -> Measured {
        let error = bench.error.expect("the tradeoff measures every error");
        let reference = bench
            .reference
            .as_ref()
            .expect("the tradeoff measures against the reference");
        Measured {
            full_ms: bench.full_ms,
            accelerated_ms: bench.accelerated_ms,
            error,
            bit_exact: exact_check.then_some(error.identical),
            reference_psnr_db: (
                reference.full.mean_psnr_db,
                reference.accelerated.mean_psnr_db,
            ),
        }
    }

    fn row(&self, knob: &'static str, setting: String, frames: u32) -> TradeoffRow {
        let per_frame = f64::from(frames.max(1));
        TradeoffRow {
            knob,
            setting,
            frames,
            full_ms_per_frame: self.full_ms / per_frame,
            accelerated_ms_per_frame: self.accelerated_ms / per_frame,
            speedup: self.full_ms / self.accelerated_ms,
            max_abs_error: self.error.max_abs,
            mean_abs_error: self.error.mean_abs,
            worst_psnr_db: self.error.worst_psnr_db,
            differing_share: self.error.differing_share,
            bit_exact: self.bit_exact,
            full_reference_psnr_db: self.reference_psnr_db.0,
            accelerated_reference_psnr_db: self.reference_psnr_db.1,
        }
    }
}

/// The camera's image of `scene` over `frames` at each of `settings`
/// (every technique the timeline allows), against its own rays.
fn measure_camera_settings(
    scene: &Scene,
    accel: &mut Accelerator,
    frames: Range<u32>,
    settings: &[CameraSetting],
    references: &mut References,
    mut progress: impl FnMut(&str),
) -> Vec<Measured> {
    settings
        .iter()
        .map(|setting| {
            let options = Options {
                fractional_pan: setting.fractional,
                ostc: setting.ostc,
                ..Options::new(Techniques::AUTO, frames.clone())
            };
            let bench = bench_sequence(
                scene,
                accel,
                &options,
                1,
                ERRORS_NOT_ORACLE,
                references,
                || progress("sequence"),
            );
            Measured::of(&bench, true)
        })
        .collect()
}

fn psnr_text(db: f64) -> String {
    if db.is_infinite() {
        "inf".to_string()
    } else {
        format!("{db:.2}")
    }
}

/// The rows as CSV, one line per knob setting, with a header, at full
/// precision (an infinite PSNR, every frame exact, as `inf`).
pub fn csv(rows: &[TradeoffRow]) -> Result<String, CsvError> {
    match rows.first() {
        Some(first) => csv_text(rows, first, Floats::Shortest),
        None => Ok(String::new()),
    }
}

/// The rows as a table for a terminal.
pub fn table(rows: &[TradeoffRow]) -> String {
    let mut text = format!(
        "{:<18} {:<18} {:>9} {:>9} {:>8} {:>9} {:>10} {:>9} {:>8} {:>5} {:>11} {:>11}\n",
        "knob",
        "setting",
        "full ms",
        "accel ms",
        "speedup",
        "max abs",
        "mean abs",
        "PSNR dB",
        "differ",
        "exact",
        "full vs ref",
        "accel vs ref"
    );
    for r in rows {
        text.push_str(&format!(
            "{:<18} {:<18} {:>9.2} {:>9.2} {:>7.2}x {:>9.4} {:>10.6} {:>9} {:>7.2}% {:>5} {:>8} dB {:>8} dB\n",
            r.knob,
            r.setting,
            r.full_ms_per_frame,
            r.accelerated_ms_per_frame,
            r.speedup,
            r.max_abs_error,
            r.mean_abs_error,
            psnr_text(r.worst_psnr_db),
            r.differing_share * 100.0,
            r.bit_exact.map_or("-", |b| if b { "yes" } else { "NO" }),
            psnr_text(r.full_reference_psnr_db),
            psnr_text(r.accelerated_reference_psnr_db),
        ));
    }
    text
}

/// Mean absolute error against speedup, one colour per knob, each point
/// labelled with its setting.
pub fn plot(path: &Path, rows: &[TradeoffRow]) -> Result<(), PlotError> {
    let mut groups: Vec<ScatterGroup> = Vec::new();
    for row in rows {
        let (x, y) = (row.speedup, row.mean_abs_error);
        // A default setting belongs to several knobs but is one
        // measurement: one dot, named after each knob's setting.
        let same = groups
            .iter_mut()
            .flat_map(|g| g.points.iter_mut())
            .find(|p| p.x == x && p.y == y);
        if let Some(point) = same {
            point.label = format!("{} = {}", point.label, row.setting);
            continue;
        }
        let point = LabelledPoint {
            x,
            y,
            label: row.setting.clone(),
        };
        match groups.iter_mut().find(|g| g.label == row.knob) {
            Some(group) => group.points.push(point),
            None => groups.push(ScatterGroup {
                label: row.knob.to_string(),
                points: vec![point],
            }),
        }
    }
    crate::lab::plot::scatter_chart(
        path,
        "Error against speedup, per knob setting",
        "speedup over full renders",
        "mean abs error (linear colour, 0-1)",
        &groups,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(knob: &'static str, setting: &str, bit_exact: Option<bool>) -> TradeoffRow {
        TradeoffRow {
            knob,
            setting: setting.into(),
            frames: 3,
            full_ms_per_frame: 30.0,
            accelerated_ms_per_frame: 3.0,
            speedup: 10.0,
            max_abs_error: 0.5,
            mean_abs_error: 0.01,
            worst_psnr_db: 31.5,
            differing_share: 0.2,
            bit_exact,
            full_reference_psnr_db: 28.5,
            accelerated_reference_psnr_db: 30.25,
        }
    }

    #[test]
    fn csv_has_one_line_per_row_and_a_column_per_field() {
        let rows = [
            row("pan", "snap to lattice", Some(false)),
            TradeoffRow {
                worst_psnr_db: f64::INFINITY,
                ..row("OSTC region grid", "8x8", Some(true))
            },
            row("RSVP filter", "box", None),
        ];
        let text = csv(&rows).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        let columns = lines[0].split(',').count();
        assert!(lines.iter().all(|l| l.split(',').count() == columns));
        assert!(lines[2].contains(",inf,"), "{}", lines[2]);
        assert!(lines[2].ends_with(",true,28.5,30.25"), "{}", lines[2]);
        assert!(
            lines[3].ends_with(",,28.5,30.25"),
            "no exactness claim for RSVP: {}",
            lines[3]
        );
        assert!(lines[0].ends_with(",full_reference_psnr_db,accelerated_reference_psnr_db"));
    }

    #[test]
    fn every_ostc_setting_is_in_its_group_and_runs_once() {
        let settings = ostc_settings();
        assert_eq!(settings.len(), 10);
        // The default is both a region grid and a voxel grid setting.
        assert_eq!(unique_ostc_settings().len(), 9);
        let rsvp = rsvp_knob_settings();
        assert_eq!(rsvp[0], RsvpKnobs::default());
        assert!(rsvp.iter().any(|k| k.filter == Filter::Nearest));
        assert!(rsvp.iter().any(|k| k.filter == Filter::Box));
        assert!(rsvp.iter().any(|k| k.level_bias == -1));
    }

    #[test]
    fn the_built_in_experiments_give_each_knob_group_its_scene() {
        let overrides = SceneOverrides::default();
        let scenes = TradeoffScenes::builtin(&overrides).unwrap();
        assert_eq!(scenes.skipped(), ["light samples"]);
        let of = |name| TradeoffScenes::of(builtin_scene(name, &overrides).unwrap());
        // Each experiment is classified as the knobs it exercises.
        let pan = of("paper-pan.toml");
        assert_eq!(pan.skipped(), ["RSVP", "OSTC", "light samples"]);
        let zoom = of("paper-zoom-in.toml");
        assert_eq!(zoom.skipped(), ["pan", "OSTC", "light samples"]);
        let bounce = of("paper-bounce.toml");
        assert_eq!(bounce.skipped(), ["pan", "RSVP", "light samples"]);
        // E4's camera pans under a viewport: RSVP and OSTC, not the pan's
        // snap (its output is the viewport).
        assert_eq!(of("paper-all.toml").skipped(), ["pan", "light samples"]);
        assert_eq!(
            of("paper.toml").skipped(),
            ["pan", "RSVP", "OSTC", "light samples"]
        );
        assert_eq!(light_sample_settings(4), [4, 1, 16]);
        assert_eq!(light_sample_settings(9), [9, 1, 4, 16]);
        assert_eq!(scenes.frame_count(), 100);
        assert_eq!(bounce.progress_steps(10), 3 * 10 * 9);
    }
}
