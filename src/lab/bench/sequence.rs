//! An experiment's sequence, rendered in full and with reuse in one run:
//! the paper's E1-E4 and the tradeoff sweeps all go through
//! [`bench_sequence`], for the camera's image and for RSVP viewports alike.
//!
//! Timed passes write nothing and keep no linear colour; what the output is
//! worth (bit-exactness, the error against each view's own rays, the error
//! of both sides against a converged reference, the buffer's self-check,
//! the oracle) is measured on a separate, untimed pass.

use std::time::Instant;

use crate::accel::Accelerator;
use crate::clock;
use crate::frame_loop::{Animator, FrameStats, Options, Techniques};
use crate::metrics::{ImageError, REFERENCE_EVERY};
use crate::pool::with_workers_awake;
use crate::reuse::lattice_buffer::lattice_region_size;
use crate::reuse::rsvp::RsvpKnobs;
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};
use crate::verify::{Checks, References, Verifier};

use super::oracle::{rays_per_pixel, traced_as_groups, Oracle, OracleRays};
use super::{median, set_frame_medians};

/// One frame of an experiment, both sides: where the time and the rays go.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameProfile {
    pub frame: u32,
    /// The full render (every viewport, for RSVP), 8-bit conversion included.
    pub full_ms: f64,
    pub accelerated_ms: f64,
    pub full_rays: RayCounts,
    /// The accelerated side's statistics, the frame's views as one
    /// ([`FrameStats::frame_total`]) of the last timed round.
    pub accelerated: FrameStats,
    /// Samples the oracle says this frame could not avoid tracing.
    pub oracle_samples: Option<u64>,
    /// The same with every region that holds one traced whole.
    pub oracle_region_samples: Option<u64>,
    /// Approximate views: the worst view's PSNR against its own rays.
    pub psnr_db: Option<f64>,
    /// Frames the reference was rendered for: the worst view's PSNR of the
    /// full render, and of the accelerated output, against it.
    pub full_reference_psnr_db: Option<f64>,
    pub accelerated_reference_psnr_db: Option<f64>,
    /// Exact views: the accelerated frame equals the full one bit for bit.
    pub exact: Option<bool>,
}

impl FrameProfile {
    /// One empty profile per frame of `frames`.
    fn empty(frames: std::ops::Range<u32>) -> Vec<FrameProfile> {
        frames
            .map(|frame| FrameProfile {
                frame,
                ..FrameProfile::default()
            })
            .collect()
    }
}

/// The error of one side's frames against what they are measured by,
/// over the frames and views measured.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ErrorSummary {
    pub worst_psnr_db: f64,
    /// Identical frames count as 100 dB.
    pub mean_psnr_db: f64,
    pub max_abs: f32,
    pub mean_abs: f64,
    pub differing_share: f64,
    /// Every frame equal to what it is measured by, bit for bit.
    pub identical: bool,
}

/// Both sides of a sequence against a converged reference of the same
/// views: what antialiasing at the run's samples costs (the full render)
/// beside what reuse adds to it (the accelerated output).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ReferenceErrors {
    /// The reference's samples a pixel.
    pub samples: u32,
    /// The frames measured (every [`REFERENCE_EVERY`]th and the last).
    pub frames: Vec<u32>,
    /// The full render at the run's samples against the reference.
    pub full: ErrorSummary,
    /// The accelerated output against the reference of the view it shows:
    /// for a snapped pan, the camera moved onto the lattice, of which each
    /// frame is an exact render.
    pub accelerated: ErrorSummary,
    /// Snapped pans only: the accelerated output against the keyed
    /// camera's reference, what the registration of up to half a sample
    /// costs on top.
    pub accelerated_vs_keyed: Option<ErrorSummary>,
}

impl ErrorSummary {
    pub fn of(errors: &[ImageError], identical: bool) -> ErrorSummary {
        let count = errors.len().max(1) as f64;
        ErrorSummary {
            worst_psnr_db: errors
                .iter()
                .map(|e| e.psnr_db)
                .fold(f64::INFINITY, f64::min),
            mean_psnr_db: errors.iter().map(|e| e.psnr_db.min(100.0)).sum::<f64>() / count,
            max_abs: errors.iter().map(|e| e.max_abs).fold(0.0, f32::max),
            mean_abs: errors.iter().map(|e| e.mean_abs).sum::<f64>() / count,
            differing_share: errors.iter().map(|e| e.differing_share).sum::<f64>() / count,
            identical,
        }
    }
}

/// The oracle of a camera sequence (see [`Oracle`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OracleSpeedups {
    /// The rays of full renders of every frame over the rays of the
    /// samples no reuse could avoid tracing: the lattice samples the
    /// windows expose, each once, and the samples whose colour changed.
    pub samples: f64,
    /// The same, with every region that holds such a sample traced whole
    /// (the best OSTC can do at its region size).
    pub regions: f64,
    /// The region oracle timed rather than counted: full renders over
    /// frame 0 in full plus, for each later frame, the time of tracing
    /// just the groups of its regions that had to be traced. Rays differ
    /// in cost (those near a moving object hit more and reflect more),
    /// which counting rays cannot see.
    pub timed_regions: f64,
    /// The ray totals behind the counted speedups.
    pub rays: OracleRays,
}

/// What to measure besides the times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Measure {
    /// The error of every view against its own rays.
    pub error: bool,
    /// The camera image's oracle (camera sequences only).
    pub oracle: bool,
    /// Both sides against a converged reference (see
    /// [`crate::metrics::BENCH_REFERENCE_SAMPLES`]), on every
    /// [`REFERENCE_EVERY`]th frame and the last.
    pub reference: bool,
}

/// One sequence, rendered in full and with reuse in one run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SequenceBench {
    pub frames: u32,
    pub views: usize,
    pub pixels_per_frame: u64,
    /// Median over rounds of the whole full sequence: every view of every
    /// frame through its own rays, converted to 8 bits, not written.
    pub full_ms: f64,
    /// The full side against plain renders of the same views outside the
    /// frame loop (the `--only frame` way), on every tenth frame: near 1
    /// when the full side is the fastest plain render, as it must be.
    pub full_vs_plain: f64,
    /// The same for the accelerated sequence (frame 0, buffers and copies
    /// included).
    pub accelerated_ms: f64,
    /// `full_ms` over `accelerated_ms`.
    pub speedup: f64,
    /// Each round's full sequence over the accelerated one that followed
    /// it: how far the machine's own noise moves the speedup. `speedup`,
    /// the medians' ratio, always lies within them.
    pub round_speedups: Vec<f64>,
    pub samples_traced: u64,
    /// OSTC's recording and merging over the whole sequence (last round).
    pub bookkeeping_ms: f64,
    pub knobs: RsvpKnobs,
    /// Exact output (the camera's image, snapped): every accelerated frame
    /// equal, bit for bit, to its full render. None for approximate output.
    pub exact: Option<bool>,
    /// The scene's samples a pixel, which both sides trace.
    pub samples_per_pixel: u32,
    /// With [`Measure::error`]: against each view's own rays.
    pub error: Option<ErrorSummary>,
    /// With [`Measure::reference`].
    pub reference: Option<ReferenceErrors>,
    /// A store that checks itself (RSVP's buffer, when the scene moves):
    /// its kept samples re-traced at checkpoints (compared, differing).
    pub buffer_check: Option<(u64, u64)>,
    /// With [`Measure::oracle`], for the camera's image.
    pub oracle: Option<OracleSpeedups>,
    /// Snapped pans: the largest angle in yaw or pitch between a frame's
    /// view and its keyed camera, in degrees and in samples (at most half).
    pub largest_snap_deg: f64,
    pub largest_snap_samples: f64,
    pub rounds: usize,
    pub threads: usize,
    /// Why accelerated frames were rendered in full, where reuse could not
    /// apply (a pan on a camera that is not equal-angle, say), each once.
    pub full_reasons: Vec<String>,
    /// Per frame: times are medians over the rounds.
    pub profile: Vec<FrameProfile>,
}

/// How often (in frames) a store that checks itself is re-traced whole: a
/// stale sample shows up at the next checkpoint unless erased again before
/// it, and every checkpoint costs a retrace of all kept samples.
const BUFFER_CHECK_EVERY: u32 = 20;

/// Renders `options.frames` of `scene` in full and with `options`,
/// alternating `rounds` times, and compares the medians of the sequence
/// totals; then, untimed, measures what `measure` asks for.
/// `progress` is called once per frame of every pass.
pub fn bench_sequence(
    scene: &Scene,
    accel: &mut Accelerator,
    options: &Options,
    rounds: usize,
    measure: Measure,
    references: &mut References,
    mut progress: impl FnMut(),
) -> SequenceBench {
    let frames = options.frames.clone();
    let full_options = Options::new(Techniques::FULL, frames.clone());
    let views = Animator::new(scene, accel, full_options.clone())
        .views(frames.start)
        .len();
    let rounds = rounds.max(1);
    let mut profile = FrameProfile::empty(frames.clone());
    // Untimed: the first render of a process pays for page faults and
    // rayon's threads, which neither side should.
    std::hint::black_box(
        Animator::new(scene, accel, full_options.clone()).render_full(frames.start, 0, None),
    );
    let (mut full_times, mut fast_times) = (Vec::new(), Vec::new());
    // Per frame and round, for per-frame medians.
    let mut full_frame_ms = vec![Vec::new(); profile.len()];
    let mut fast_frame_ms = vec![Vec::new(); profile.len()];
    let mut counts = AcceleratedCounts::default();
    for _ in 0..rounds {
        let mut full = Animator::new(scene, accel, full_options.clone());
        full_times.push(full_round(
            &mut full,
            views,
            &mut profile,
            &mut full_frame_ms,
            &mut progress,
        ));
        drop(full);
        let mut fast = Animator::new(
            scene,
            accel,
            Options {
                linear: false,
                ..options.clone()
            },
        );
        fast_times.push(accelerated_round(
            &mut fast,
            &mut profile,
            &mut fast_frame_ms,
            &mut counts,
            &mut progress,
        ));
    }
    set_frame_medians(&mut profile, full_frame_ms, fast_frame_ms);
    let checked = check_sequence(
        scene,
        accel,
        options,
        measure,
        references,
        &mut profile,
        &mut progress,
    );
    let round_speedups = full_times
        .iter()
        .zip(&fast_times)
        .map(|(full, fast)| full / fast.max(1e-9))
        .collect();
    let timed_regions = |oracle_ms: f64| full_times[0] / oracle_ms.max(1e-9);
    let oracle = checked.oracle.map(|(oracle, traced_ms)| OracleSpeedups {
        // Weighted by the rays each sample costs (see `Oracle::rays`).
        samples: oracle.rays.all as f64 / oracle.rays.samples.max(1) as f64,
        regions: oracle.rays.all as f64 / oracle.rays.regions.max(1) as f64,
        timed_regions: timed_regions(traced_ms),
        rays: oracle.rays,
    });
    let (full_ms, accelerated_ms) = (median(full_times), median(fast_times));
    let full_sampled: f64 = checked
        .plain_ms
        .iter()
        .map(|&(frame, _)| profile[(frame - frames.start) as usize].full_ms)
        .sum();
    let plain_sampled: f64 = checked.plain_ms.iter().map(|&(_, ms)| ms).sum();
    SequenceBench {
        frames: frames.end - frames.start,
        views,
        pixels_per_frame: counts.pixels_per_frame,
        full_ms,
        full_vs_plain: full_sampled / plain_sampled.max(1e-9),
        accelerated_ms,
        speedup: full_ms / accelerated_ms,
        round_speedups,
        samples_traced: counts.samples_traced,
        bookkeeping_ms: counts.bookkeeping_ms,
        knobs: options.rsvp,
        exact: checked.exact,
        samples_per_pixel: scene.samples.count(),
        error: checked.error,
        reference: checked.reference,
        buffer_check: checked.buffer_check,
        oracle,
        largest_snap_deg: counts.largest_snap_deg,
        largest_snap_samples: counts.largest_snap_deg.to_radians()
            / crate::reuse::pan::EqualAngleLattice::step_for(&scene.camera),
        rounds,
        threads: rayon::current_num_threads(),
        full_reasons: counts.full_reasons,
        profile,
    }
}

/// One timed round of full renders of `full`'s frames (its options'),
/// each view through its own rays with the workers kept awake through the
/// frame, as the frame loop keeps them for the accelerated side. Returns
/// the round's milliseconds; each frame's go to `frame_ms`.
fn full_round(
    full: &mut Animator,
    views: usize,
    profile: &mut [FrameProfile],
    frame_ms: &mut [Vec<f64>],
    progress: &mut impl FnMut(),
) -> f64 {
    let frames = full.options().frames.clone();
    let mut elapsed = 0.0;
    for (row, frame) in profile.iter_mut().zip(frames.clone()) {
        let start = Instant::now();
        let mut frame_rays = RayCounts::default();
        with_workers_awake(|| {
            for index in 0..views {
                // Each view's own rays, rendered in place: the fastest
                // plain render of the frame (a snapped pan's lattice
                // render copies its samples into place besides).
                let (image, rays) = full.render_own_rays(frame, index, None);
                std::hint::black_box(image.to_rgb8());
                frame_rays += rays;
            }
        });
        let ms = clock::ms(start.elapsed());
        frame_ms[(frame - frames.start) as usize].push(ms);
        elapsed += ms;
        row.full_rays = frame_rays;
        progress();
    }
    elapsed
}

/// What the accelerated rounds count: the same every round, the last
/// one's kept.
#[derive(Default)]
struct AcceleratedCounts {
    samples_traced: u64,
    bookkeeping_ms: f64,
    pixels_per_frame: u64,
    largest_snap_deg: f64,
    /// Why frames were rendered in full though reuse was asked for.
    full_reasons: Vec<String>,
}

/// One timed round of `fast`'s frames, with reuse. Returns the round's
/// milliseconds; each frame's go to `frame_ms`, its counts to `profile`
/// and the sequence's to `counts`.
fn accelerated_round(
    fast: &mut Animator,
    profile: &mut [FrameProfile],
    frame_ms: &mut [Vec<f64>],
    counts: &mut AcceleratedCounts,
    progress: &mut impl FnMut(),
) -> f64 {
    let frames = fast.options().frames.clone();
    let mut elapsed = 0.0;
    (counts.samples_traced, counts.bookkeeping_ms) = (0, 0.0);
    for (row, frame) in profile.iter_mut().zip(frames.clone()) {
        let start = Instant::now();
        let outputs = fast.render(frame);
        let ms = clock::ms(start.elapsed());
        frame_ms[(frame - frames.start) as usize].push(ms);
        elapsed += ms;
        let views: Vec<FrameStats> = outputs.iter().map(|o| o.stats.clone()).collect();
        row.accelerated = FrameStats::frame_total(&views);
        counts.pixels_per_frame = row.accelerated.pixels;
        for stats in &views {
            let (yaw, pitch) = stats.snap_error_deg();
            counts.largest_snap_deg = counts.largest_snap_deg.max(yaw.abs()).max(pitch.abs());
            if let Some(reason) = stats.refusal().map(|r| r.to_string()) {
                if !counts.full_reasons.contains(&reason) {
                    counts.full_reasons.push(reason);
                }
            }
        }
        counts.samples_traced += row.accelerated.work.samples_traced;
        counts.bookkeeping_ms += row.accelerated.bookkeeping_ms();
        std::hint::black_box(outputs);
        progress();
    }
    elapsed
}

/// What the untimed pass found.
struct Checked {
    /// Medians of plain renders of every tenth frame's views, by frame.
    plain_ms: Vec<(u32, f64)>,
    exact: Option<bool>,
    error: Option<ErrorSummary>,
    reference: Option<ReferenceErrors>,
    buffer_check: Option<(u64, u64)>,
    /// The oracle and the time its region groups took to trace.
    oracle: Option<(Oracle, f64)>,
}

/// The untimed pass: the accelerated frames again with linear colour,
/// against full renders (exactness), each view's own rays (error), a
/// converged reference (both sides), the store's own check, and the oracle.
fn check_sequence(
    scene: &Scene,
    accel: &mut Accelerator,
    options: &Options,
    measure: Measure,
    references: &mut References,
    profile: &mut [FrameProfile],
    progress: &mut impl FnMut(),
) -> Checked {
    let frames = options.frames.clone();
    let mut check = Animator::new(
        scene,
        accel,
        Options {
            linear: true,
            ..options.clone()
        },
    );
    let exact = check.is_exact();
    let moves = scene.animation.as_ref().is_some_and(|a| a.moves_scene());
    // OSTC's regions are of a store's strata when the count is a square
    // above one (`LatticeBuffer`); the oracle's, of the pixels they cover.
    let side = if moves && options.techniques.ostc {
        scene.samples.grid_side().max(1)
    } else {
        1
    };
    let (strata_wide, strata_high) = lattice_region_size(
        options.ostc.regions,
        (scene.camera.width, scene.camera.height),
        side,
    );
    let side_i = i64::from(side);
    let region_size = ((strata_wide / side_i).max(1), (strata_high / side_i).max(1));
    let mut oracle = (measure.oracle && !check.has_viewports()).then(|| Oracle::new(region_size));
    let mut oracle_ms = 0.0;
    let mut buffer_check: Option<(u64, u64)> = None;
    let mut errors = Vec::new();
    let (mut all_exact, mut identical) = (true, true);
    let mut plain_ms = Vec::new();
    let mut verifier = Verifier::with_references(scene.samples, std::mem::take(references));
    let reference_count = verifier.reference_samples();
    let (mut reference_frames, mut full_vs_reference, mut fast_vs_reference) =
        (Vec::new(), Vec::new(), Vec::new());
    let mut snapped_vs_keyed = Vec::new();
    for (row, frame) in profile.iter_mut().zip(frames.clone()) {
        if (frame - frames.start) % 10 == 0 {
            plain_ms.push((frame, plain_render_ms(&mut check, frame)));
        }
        let outputs = check.render(frame);
        let mut worst = f64::INFINITY;
        let last = frame + 1 == frames.end;
        let referenced =
            measure.reference && (last || (frame - frames.start) % REFERENCE_EVERY == 0);
        let (mut full_worst, mut fast_worst) = (f64::INFINITY, f64::INFINITY);
        for (index, output) in outputs.iter().enumerate() {
            let checks = Checks {
                full: exact,
                // The bench's check pass shares the posed scene; the tests
                // and `animate --verify` build it afresh too.
                afresh: false,
                own_rays: measure.error,
                reference: referenced,
                exr: false,
            };
            // A view and its own rays are one size: a bug otherwise.
            let view = verifier
                .check_view(&mut check, frame, index, output, checks)
                .expect("a view's frames");
            if let Some(same) = view.equal_to_full() {
                row.exact = Some(same);
                all_exact &= same;
            }
            if let (Some(oracle), Some((full, _))) = (&mut oracle, &view.full) {
                let (shader, camera) = check.posed_shader(frame);
                let pixel_rays = rays_per_pixel(&shader, &camera, scene.samples);
                let (samples, region_samples) = oracle.add(&camera, full, &pixel_rays);
                row.oracle_samples = Some(samples);
                row.oracle_region_samples = Some(region_samples);
                let table = crate::camera::RayTable::with_samples(&camera, scene.samples);
                let groups = oracle.region_groups(camera.width, side);
                let start = Instant::now();
                traced_as_groups(&table, side_i, |source| {
                    std::hint::black_box(crate::render::trace_groups(&shader, source, &groups))
                });
                oracle_ms += clock::ms(start.elapsed());
            }
            if let Some((error, same)) = view.own_rays {
                identical &= same;
                worst = worst.min(error.psnr_db);
                errors.push(error);
            }
            if let Some(reference) = view.reference {
                full_worst = full_worst.min(reference.full.psnr_db);
                fast_worst = fast_worst.min(reference.output.psnr_db);
                full_vs_reference.push(reference.full);
                fast_vs_reference.push(reference.output);
                snapped_vs_keyed.extend(reference.snapped_vs_keyed);
            }
        }
        if measure.error && !exact {
            row.psnr_db = Some(worst);
        }
        if referenced {
            reference_frames.push(frame);
            row.full_reference_psnr_db = Some(full_worst);
            row.accelerated_reference_psnr_db = Some(fast_worst);
        }
        let checkpoint = last || (frame - frames.start + 1) % BUFFER_CHECK_EVERY == 0;
        if moves && checkpoint {
            if let Some((compared, differing)) = check.verify_store() {
                let (c, d) = buffer_check.unwrap_or((0, 0));
                buffer_check = Some((c + compared, d + differing));
            }
        }
        progress();
    }
    *references = verifier.into_references();
    Checked {
        plain_ms,
        exact: exact.then_some(all_exact),
        error: measure.error.then(|| ErrorSummary::of(&errors, identical)),
        reference: measure.reference.then(|| {
            let summary = |errors: &[ImageError]| {
                ErrorSummary::of(errors, errors.iter().all(|e| e.psnr_db.is_infinite()))
            };
            ReferenceErrors {
                samples: reference_count.count(),
                frames: reference_frames,
                full: summary(&full_vs_reference),
                accelerated: summary(&fast_vs_reference),
                accelerated_vs_keyed: (!snapped_vs_keyed.is_empty())
                    .then(|| summary(&snapped_vs_keyed)),
            }
        }),
        buffer_check,
        oracle: oracle.map(|o| (o, oracle_ms)),
    }
}

/// The median time of three plain renders of `frame`'s views (8-bit
/// output included), made directly rather than through the frame loop.
fn plain_render_ms(animator: &mut Animator, frame: u32) -> f64 {
    let views = animator.views(frame);
    let (scene, accel) = animator.posed_scene(frame);
    let times = (0..3)
        .map(|_| {
            let start = Instant::now();
            for view in &views {
                let (image, _) = if scene.viewports.is_empty() {
                    crate::render::render_view(scene, &view.pose.camera, accel)
                } else {
                    crate::reuse::rsvp::render_direct(&Shader::new(scene, accel), &view.pose)
                };
                std::hint::black_box(image.to_rgb8());
            }
            clock::ms(start.elapsed())
        })
        .collect();
    median(times)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BackendKind;
    use crate::metrics::BENCH_REFERENCE_SAMPLES;
    use crate::scene::{builtin_scene, SceneOverrides};

    const REFERENCE_ONLY: Measure = Measure {
        error: false,
        oracle: false,
        reference: true,
    };

    /// One of the shipped experiments at 32x24 (viewports too) and 4 spp.
    fn small(file: &str) -> Scene {
        sized(file, 32, 24)
    }

    /// One of the shipped experiments at `width` x `height` (viewports
    /// too) and 4 spp.
    fn sized(file: &str, width: u32, height: u32) -> Scene {
        let overrides = SceneOverrides {
            width: Some(width),
            height: Some(height),
            spp: Some(4),
            ..SceneOverrides::default()
        };
        let mut scene = builtin_scene(file, &overrides).unwrap();
        for track in &mut scene.viewports {
            (track.viewport.width, track.viewport.height) = (width, height);
        }
        scene
    }

    fn reference_errors(scene: &Scene, frames: std::ops::Range<u32>) -> SequenceBench {
        let mut accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let options = Options::new(Techniques::AUTO, frames);
        let mut references = References::default();
        bench_sequence(
            scene,
            &mut accel,
            &options,
            1,
            REFERENCE_ONLY,
            &mut references,
            || {},
        )
    }

    /// The bouncing ball before a still camera: OSTC's frames are exact, so
    /// against the reference they are exactly as far as the full render.
    #[test]
    fn an_exact_output_is_as_far_from_the_reference_as_its_full_render() {
        let bench = reference_errors(&small("paper-bounce.toml"), 40..62);
        assert_eq!(bench.exact, Some(true));
        let reference = bench.reference.expect("asked for");
        assert_eq!(reference.samples, BENCH_REFERENCE_SAMPLES);
        assert_eq!(reference.frames, [40, 60, 61]);
        assert_eq!(reference.accelerated, reference.full);
        // 4 samples a pixel are not 64: a finite error, and not a small one.
        assert!(reference.full.worst_psnr_db.is_finite());
        assert!(reference.full.max_abs > 0.0 && reference.full.differing_share > 0.0);
        let measured: Vec<u32> = bench
            .profile
            .iter()
            .filter(|p| p.full_reference_psnr_db.is_some())
            .map(|p| p.frame)
            .collect();
        assert_eq!(measured, reference.frames);
    }

    /// A snapped pan's frames are exact renders of the camera moved onto
    /// the lattice: against that view's reference they are about as close
    /// as the keyed camera's full render is to its own (a pixel between
    /// cells takes its strata from two cells' patterns, a little less even
    /// than one cell's: within half a decibel on three small frames);
    /// against the keyed camera's reference the shift of up to half a
    /// stratum shows.
    #[test]
    fn a_snapped_pan_is_measured_against_the_view_it_shows() {
        let bench = reference_errors(&sized("paper-pan.toml", 128, 96), 0..3);
        assert_eq!(bench.exact, Some(true));
        let snap = bench.largest_snap_samples;
        assert!(snap > 0.0 && snap <= 0.5 + 1e-9, "{snap}");
        let reference = bench.reference.expect("asked for");
        let keyed = reference.accelerated_vs_keyed.expect("the pan snaps");
        let (full, shown) = (reference.full, reference.accelerated);
        assert!(
            shown.worst_psnr_db >= full.worst_psnr_db - 0.5,
            "{shown:?} against {full:?}"
        );
        assert!(
            keyed.mean_psnr_db < shown.mean_psnr_db - 1.0,
            "{keyed:?} against {shown:?}"
        );
    }

    /// A resampled viewport is measured against the same reference as the
    /// full render, and is not the full render.
    #[test]
    fn a_resampled_output_has_its_own_error_against_the_reference() {
        let bench = reference_errors(&small("paper-zoom-in.toml"), 0..3);
        assert_eq!(bench.exact, None);
        let reference = bench.reference.expect("asked for");
        assert_eq!(reference.frames, [0, 2]);
        for side in [reference.full, reference.accelerated] {
            assert!(side.worst_psnr_db.is_finite() && side.worst_psnr_db > 5.0);
            assert!(side.mean_psnr_db >= side.worst_psnr_db);
        }
        assert_ne!(reference.accelerated, reference.full);
    }

    /// Each round's speedup is kept, and the medians' ratio lies among
    /// them.
    #[test]
    fn every_round_keeps_its_own_speedup() {
        let scene = small("paper-bounce.toml");
        let mut accel = Accelerator::build(BackendKind::Grid, &scene.objects).unwrap();
        let options = Options::new(Techniques::AUTO, 0..4);
        let times_only = Measure {
            reference: false,
            ..REFERENCE_ONLY
        };
        let mut references = References::default();
        let bench = bench_sequence(
            &scene,
            &mut accel,
            &options,
            3,
            times_only,
            &mut references,
            || {},
        );
        assert_eq!(bench.round_speedups.len(), 3);
        let mut sorted = bench.round_speedups.clone();
        sorted.sort_by(f64::total_cmp);
        let (lowest, highest) = (sorted[0], sorted[2]);
        assert!(
            lowest > 0.0 && highest.is_finite(),
            "{:?}",
            bench.round_speedups
        );
        assert!(
            (lowest..=highest).contains(&bench.speedup),
            "{} outside {:?}",
            bench.speedup,
            bench.round_speedups
        );
    }
}
