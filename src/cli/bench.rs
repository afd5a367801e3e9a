//! `retrace bench`: the paper's experiments and the single measurements,
//! full against accelerated in one run.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;

use retrace::frame_loop::{Options, Techniques};
use retrace::lab::bench::{bench_sequence, Measure, SequenceBench};
use retrace::sampling::PixelSamples;
use retrace::scene::Scene;

mod chunking;

use super::{
    check_writable, idle_flag, load, parse_frame_range, scene_name, write_json, BackendArg,
    OstcArgs, RsvpKnobArgs, SceneArgs,
};

#[derive(Args)]
pub(crate) struct BenchArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// What to measure: `all` (the paper's table: E1, E2 in and out, E3,
    /// E4), one experiment of it (`E1`, `E2`, `E3`, `E4`), `scaling` (the
    /// experiments on a larger scene and at 1280x960), `frame` (a full
    /// frame against bare Embree on the same ray packets), `backends` (the
    /// grid against Embree on the same ray packets), `E4nomotion` (pan 3.6
    /// deg/frame and zoom together), `E1blur`, `E3blur`, `E4blur` or `blur`
    /// (E1, E3 and E4 with the shutter open half a frame: motion blur),
    /// `E1lens` or `lens` (E1 through a lens: depth of field) or `knobs` (RSVP filter, oversampling
    /// and level bias: cost and error), `chunking` (E1, E3 and E4, or the
    /// scene given, cut into farm chunks: CPU and wall time against the
    /// number of chunks).
    #[arg(long, default_value = "all")]
    only: String,
    /// With `--only chunking`: the numbers of chunks measured (one long
    /// run is always among them).
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16")]
    chunk_counts: Vec<u32>,
    /// Frames of every experiment, `A-B` or `A` (default: all 100).
    #[arg(long, allow_hyphen_values = true, value_parser = super::frame_range_text)]
    frames: Option<String>,
    /// Also run the scaling rows (a scene of about a million triangles,
    /// and 1280x960) after the paper's table.
    #[arg(long)]
    scaling: bool,
    /// Folder for the table (bench.csv, bench.json), per-frame CSVs, plots
    /// and report.md (default: out/bench, and out/chunking for `--only
    /// chunking`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Timed repetitions, the median reported (default: 15 for `frame`
    /// and `backends`, one run of each sequence for the experiments; with
    /// more, an experiment alternates full and accelerated runs).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1000))]
    repeats: Option<u64>,
    /// Also write the result as JSON here (for the experiments, the rows of
    /// the folder's bench.json).
    #[arg(long)]
    json: Option<PathBuf>,
    #[command(flatten)]
    ostc: OstcArgs,
    /// The RSVP knobs of the viewport experiments (E2, E4, E4nomotion);
    /// `knobs` sweeps its own.
    #[command(flatten)]
    rsvp: RsvpKnobArgs,
    /// How the pans (E1) show a pan by a fraction of a sample, as `animate
    /// --fractional-pan`: snap, snap-samples, blend-strata or resample
    /// [default: snap]
    #[arg(long)]
    fractional_pan: Option<retrace::reuse::pan::FractionalPan>,
}

impl BenchArgs {
    /// The folder written.
    fn out(&self) -> PathBuf {
        self.out.clone().unwrap_or_else(|| {
            PathBuf::from(if self.only.eq_ignore_ascii_case("chunking") {
                "out/chunking"
            } else {
                "out/bench"
            })
        })
    }

    /// Repetitions of a single-frame measurement.
    fn frame_repeats(&self) -> usize {
        self.repeats.unwrap_or(15) as usize
    }
}

pub(crate) fn bench(args: BenchArgs) -> Result<()> {
    if cfg!(debug_assertions) {
        eprintln!(
            "warning: this is a debug build; timings mean little (use `cargo run --release`)"
        );
    }
    // Before any work, like the frames.
    args.rsvp.knobs(PixelSamples::ONE)?;
    let bar = indicatif::ProgressBar::new(args.frame_repeats() as u64).with_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {pos}/{len} {elapsed}")
            .expect("static template"),
    );
    let paper = [
        Experiment::E1,
        Experiment::E2In,
        Experiment::E2Out,
        Experiment::E3,
        Experiment::E4,
    ];
    let mut suite = match args.only.to_ascii_lowercase().as_str() {
        "all" => paper.to_vec(),
        "e1" => vec![Experiment::E1],
        "e2" => vec![Experiment::E2In, Experiment::E2Out],
        "e3" => vec![Experiment::E3],
        "e4" => vec![Experiment::E4],
        "e4nomotion" => vec![Experiment::E4NoMotion],
        "e3blur" => vec![Experiment::E3Blur],
        "e4blur" => vec![Experiment::E4Blur],
        "e1blur" => vec![Experiment::E1Blur],
        "blur" => vec![Experiment::E1Blur, Experiment::E3Blur, Experiment::E4Blur],
        "e1lens" | "lens" => vec![Experiment::E1Lens],
        "scaling" => Vec::new(),
        "chunking" => return chunking::bench_chunking_cli(&args, bar),
        "frame" | "backends" | "knobs" => {
            // These measure a single frame, or sweep the RSVP knobs
            // themselves: no knob given applies.
            let flag = (args.ostc.given().or(args.rsvp.given()))
                .or(args.fractional_pan.map(|_| "--fractional-pan"));
            if let Some(flag) = flag {
                return Err(idle_flag(
                    flag,
                    &format!(
                        "--only {} sets no reuse knob from the command line",
                        args.only
                    ),
                ));
            }
            match args.only.to_ascii_lowercase().as_str() {
                "frame" => return bench_frame(&args, &load(&args.scene)?, bar),
                "backends" => return bench_backends(&args, &load(&args.scene)?, bar),
                _ => return bench_knobs(&args, bar),
            }
        }
        _ => {
            anyhow::bail!(
                "unknown measurement '{}' for --only (available: all, E1, E2, E3, E4, scaling, frame, backends, E4nomotion, E1blur, E3blur, E4blur, blur, E1lens, lens, knobs, chunking)",
                args.only
            )
        }
    };
    let scaling = args.scaling || args.only.eq_ignore_ascii_case("scaling");
    let mut planned = Vec::new();
    for experiment in suite.drain(..) {
        planned.push(plan_experiment(&args, experiment, None)?);
    }
    if scaling {
        for (experiment, variant) in SCALING_ROWS {
            planned.push(plan_experiment(&args, experiment, Some(variant))?);
        }
    }
    // Knobs of a technique none of the experiments runs are refused.
    let any = |test: fn(&Scene) -> bool| planned.iter().any(|p| test(&p.scene));
    if let Some(flag) = args.rsvp.given() {
        if !any(|scene| !scene.viewports.is_empty()) {
            return Err(idle_flag(
                flag,
                "none of the experiments measured has a viewport for RSVP to resample",
            ));
        }
    }
    if args.fractional_pan.is_some() {
        use retrace::camera::Projection::EqualAngle;
        let pans = |scene: &Scene| {
            let turns = scene.animation.as_ref().is_some_and(|a| {
                let first = a.camera_at(&scene.camera, 0);
                (1..a.frames).any(|f| a.camera_at(&scene.camera, f) != first)
            });
            turns && scene.viewports.is_empty() && scene.camera.projection == EqualAngle
        };
        if !any(pans) {
            return Err(idle_flag(
                "--fractional-pan",
                "none of the experiments measured pans an equal-angle camera",
            ));
        }
    }
    if let Some(flag) = args.ostc.given() {
        if !any(|scene| scene.animation.as_ref().is_some_and(|a| a.moves_scene())) {
            return Err(idle_flag(
                flag,
                "none of the experiments measured moves an object or a light",
            ));
        }
    }
    bench_suite(&args, planned, bar)
}

/// The experiments of the paper's table, E4 without its ball, E1, E3
/// and E4 with motion blur, and E1 through a lens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Experiment {
    E1,
    E2In,
    E2Out,
    E3,
    E4,
    E4NoMotion,
    E3Blur,
    E4Blur,
    E1Lens,
    E1Blur,
}

impl Experiment {
    /// Its row heading: id, what changes, the technique, the paper's
    /// speedup.
    fn heading(self) -> (&'static str, &'static str, &'static str, &'static str) {
        match self {
            Experiment::E1 => (
                "E1",
                "pan 3.6 deg/frame, a whole turn",
                "Panimation",
                "~10x",
            ),
            Experiment::E2In => ("E2 in", "zoom in 100 -> 50 deg", "RSVP", "~10x"),
            Experiment::E2Out => ("E2 out", "zoom out 50 -> 100 deg", "RSVP", "~10x"),
            Experiment::E3 => ("E3", "a small ball bounces, camera still", "OSTC", "~2x"),
            Experiment::E4 => (
                "E4",
                "pan + zoom in + bouncing ball, viewport",
                "RSVP+OSTC",
                "~2x",
            ),
            Experiment::E4NoMotion => ("E4 no motion", "pan + zoom in, viewport", "RSVP", "-"),
            Experiment::E3Blur => ("E3 blur", "E3, shutter open half a frame", "OSTC", "-"),
            Experiment::E4Blur => ("E4 blur", "E4, shutter open half a frame", "RSVP+OSTC", "-"),
            Experiment::E1Lens => ("E1 lens", "E1 through a lens", "Panimation", "-"),
            Experiment::E1Blur => (
                "E1 blur",
                "E1, shutter open half a frame",
                "Panimation",
                "-",
            ),
        }
    }

    /// The shipped scene file that is the experiment on the paper scene
    /// (built into the binary).
    fn scene_file(self) -> &'static str {
        match self {
            Experiment::E1 => "paper-pan.toml",
            Experiment::E2In => "paper-zoom-in.toml",
            Experiment::E2Out => "paper-zoom-out.toml",
            Experiment::E3 => "paper-bounce.toml",
            Experiment::E4 => "paper-all.toml",
            Experiment::E4NoMotion => "paper-pan-zoom.toml",
            Experiment::E3Blur => "paper-bounce-blur.toml",
            Experiment::E4Blur => "paper-all-blur.toml",
            Experiment::E1Lens => "paper-pan-lens.toml",
            Experiment::E1Blur => "paper-pan-blur.toml",
        }
    }

    /// The same on the bunnies (`scenes/`, on disk), where there is one.
    fn bunnies_file(self) -> Option<&'static str> {
        match self {
            Experiment::E1 => Some("bunnies-pan.toml"),
            Experiment::E2In => Some("bunnies-zoom-in.toml"),
            Experiment::E3 => Some("bunnies.toml"),
            Experiment::E4 => Some("bunnies-all.toml"),
            Experiment::E2Out
            | Experiment::E4NoMotion
            | Experiment::E3Blur
            | Experiment::E4Blur
            | Experiment::E1Lens
            | Experiment::E1Blur => None,
        }
    }
}

/// Where a scaling row runs instead of the paper scene at its own size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalingVariant {
    /// scenes/bunnies.toml: the bouncing-ball scene among 256 bunnies.
    Bunnies,
    /// The paper's scenes at 1280x960.
    Large,
}

/// The rows `--scaling` adds: the experiments on a million triangles,
/// and the paper's table at four times the pixels (E2 out behaves as E2 in
/// does, so once is enough).
const SCALING_ROWS: [(Experiment, ScalingVariant); 8] = [
    (Experiment::E1, ScalingVariant::Bunnies),
    (Experiment::E2In, ScalingVariant::Bunnies),
    (Experiment::E3, ScalingVariant::Bunnies),
    (Experiment::E4, ScalingVariant::Bunnies),
    (Experiment::E1, ScalingVariant::Large),
    (Experiment::E2In, ScalingVariant::Large),
    (Experiment::E3, ScalingVariant::Large),
    (Experiment::E4, ScalingVariant::Large),
];

/// An experiment ready to run: its scene, frames and row heading.
struct PlannedExperiment {
    info: retrace::lab::report::ExperimentInfo,
    scene: Scene,
    frames: std::ops::Range<u32>,
}

impl PlannedExperiment {
    /// Progress steps: both sides of the sequence, each of `rounds` times,
    /// the untimed check, and for viewports the oracle pass.
    fn steps(&self, rounds: u64) -> u64 {
        let frames = u64::from(self.frames.end - self.frames.start);
        let oracle_pass = u64::from(!self.scene.viewports.is_empty());
        (2 * rounds + 1 + oracle_pass) * frames
    }
}

/// Loads and checks an experiment's scene and frames before anything runs,
/// so bad input costs no measuring time. The experiment is its shipped
/// scene file (see [`Experiment::scene_file`]), or the scene given, whose
/// own timeline is then measured.
fn plan_experiment(
    args: &BenchArgs,
    experiment: Experiment,
    variant: Option<ScalingVariant>,
) -> Result<PlannedExperiment> {
    let mut scene_args = args.scene.clone();
    if variant == Some(ScalingVariant::Large) {
        scene_args.width = Some(1280);
        scene_args.height = Some(960);
    }
    let resized = scene_args.width.is_some() || scene_args.height.is_some();
    let (id, what, technique, paper) = experiment.heading();
    let file = experiment.scene_file();
    let overrides = scene_args.overrides();
    let (mut scene, scene_label) = match (&scene_args.scene, variant) {
        (Some(path), None | Some(ScalingVariant::Large)) => {
            let scene = load(&scene_args)?;
            if scene.animation.is_none() {
                anyhow::bail!(
                    "{id} measures a scene's own timeline, and {} has no [animation] \
                     (scenes/{file} is {id}'s)",
                    path.display()
                );
            }
            let label = path
                .file_stem()
                .map_or("scene".to_string(), |s| s.to_string_lossy().into_owned());
            (scene, label)
        }
        (_, Some(ScalingVariant::Bunnies)) => {
            let Some(file) = experiment.bunnies_file() else {
                anyhow::bail!("{id} has no scene on the bunnies");
            };
            let path = Path::new("scenes").join(file);
            if !path.exists() {
                anyhow::bail!(
                    "{id} on the bunnies needs {} (run from the repository)",
                    path.display()
                );
            }
            let scene = load(&SceneArgs {
                scene: Some(path),
                ..scene_args.clone()
            })?;
            (scene, "bunnies".to_string())
        }
        _ => {
            let scene = retrace::scene::builtin_scene(file, &overrides)?;
            (scene, file.trim_end_matches(".toml").to_string())
        }
    };
    if resized {
        // The viewport takes the size asked for, as the camera does.
        for track in &mut scene.viewports {
            track.viewport.width = scene.camera.width;
            track.viewport.height = scene.camera.height;
        }
    }
    let count = scene.animation.as_ref().map_or(1, |a| a.frames);
    let frames = parse_frame_range(args.frames.as_deref(), count)
        .map_err(|err| anyhow::anyhow!("{id}: {err}"))?;
    let (width, height) = scene
        .viewports
        .first()
        .map_or((scene.camera.width, scene.camera.height), |track| {
            (track.viewport.width, track.viewport.height)
        });
    let mut id = id.to_string();
    if variant.is_some() {
        id = format!("{id} {scene_label} {width}x{height}");
    }
    Ok(PlannedExperiment {
        info: retrace::lab::report::ExperimentInfo {
            id,
            what: what.to_string(),
            technique: technique.to_string(),
            paper_speedup: paper.to_string(),
            scene: scene_label,
            triangles: retrace::lab::report::triangles(&scene),
            width,
            height,
        },
        frames: *frames.start()..*frames.end() + 1,
        scene,
    })
}

/// Runs the planned experiments, prints the table and writes the bench
/// folder; fails (after writing) when an exact experiment was not.
fn bench_suite(
    args: &BenchArgs,
    planned: Vec<PlannedExperiment>,
    bar: indicatif::ProgressBar,
) -> Result<()> {
    let load_at_start = load_average();
    check_writable(&args.out())?;
    let rounds = args.repeats.unwrap_or(1);
    bar.set_length(planned.iter().map(|plan| plan.steps(rounds)).sum());
    bar.set_position(0);
    let mut results = Vec::new();
    for plan in planned {
        bar.set_message(format!("{} ({})", plan.info.id, plan.info.technique));
        results.push(run_experiment(args, plan, &bar)?);
    }
    bar.finish_and_clear();
    let rows: Vec<_> = results.iter().map(|r| r.row.clone()).collect();
    say!(
        "retrace bench: {} backend, {} threads, {}{}",
        args.backend.backend,
        rayon::current_num_threads(),
        match rounds {
            1 => "one run of each sequence".to_string(),
            n => format!(
                "median of {n} alternated runs of each sequence \
                 (speedups: the lowest and highest round in brackets)"
            ),
        },
        if cfg!(debug_assertions) {
            " (DEBUG BUILD)"
        } else {
            ""
        }
    );
    say!("{}", retrace::lab::report::table(&rows));
    let run = retrace::lab::report::RunInfo {
        command: std::env::args()
            .map(|a| if a.contains(' ') { format!("'{a}'") } else { a })
            .collect::<Vec<_>>()
            .join(" "),
        backend: args.backend.backend.to_string(),
        threads: rayon::current_num_threads(),
        load: load_at_start.zip(load_average()),
        release: !cfg!(debug_assertions),
    };
    let written = retrace::lab::report::write_bench(&args.out(), &run, &results, draw_chart)?;
    if let Some(path) = &args.json {
        let rows: serde_json::Value =
            serde_json::from_str(&retrace::lab::report::rows_json(&rows))?;
        write_json(path, &rows)?;
    }
    say!(
        "wrote {} files to {} (open {})",
        written.len(),
        args.out().display(),
        args.out().join("report.md").display()
    );
    let inexact: Vec<&str> = rows
        .iter()
        .filter(|r| r.exact == Some(false))
        .map(|r| r.info.id.as_str())
        .collect();
    if !inexact.is_empty() {
        anyhow::bail!(
            "{}: accelerated output differs from full renders",
            inexact.join(", ")
        );
    }
    Ok(())
}

/// Draws one of the bench's charts as a PNG.
fn draw_chart(path: &Path, chart: &retrace::lab::report::ChartSpec) -> Result<()> {
    let series: Vec<retrace::lab::plot::Series> = chart
        .lines
        .iter()
        .map(|(label, points)| retrace::lab::plot::Series {
            label: label.clone(),
            points: points.clone(),
        })
        .collect();
    retrace::lab::plot::line_chart(path, &chart.title, "frame", &chart.y_label, &series)?;
    Ok(())
}

/// The one-minute load average, where the system tells it.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn run_experiment(
    args: &BenchArgs,
    plan: PlannedExperiment,
    bar: &indicatif::ProgressBar,
) -> Result<retrace::lab::report::ExperimentResult> {
    use retrace::lab::report::ExperimentResult;
    let PlannedExperiment {
        mut info,
        scene,
        frames,
    } = plan;
    let knobs = args.rsvp.knobs(scene.samples)?;
    if let (true, Some(changes)) = (info.uses_rsvp(), knobs.changes(scene.samples)) {
        info.technique = format!("{}, {changes}", info.technique);
    }
    if let Some(fractional) = args.fractional_pan {
        info.technique = format!("{}, {}", info.technique, fractional.name());
    }
    let mut accel = args.backend.build(&scene)?;
    let options = Options {
        ostc: args.ostc.settings(),
        rsvp: knobs,
        fractional_pan: args.fractional_pan.unwrap_or_default(),
        ..Options::new(Techniques::AUTO, frames.clone())
    };
    let measure = Measure {
        error: !scene.viewports.is_empty(),
        oracle: true,
        reference: true,
    };
    let rounds = args.repeats.unwrap_or(1) as usize;
    let mut references = retrace::verify::References::default();
    let result = bench_sequence(
        &scene,
        &mut accel,
        &options,
        rounds,
        measure,
        &mut references,
        || bar.inc(1),
    );
    for reason in &result.full_reasons {
        bar.suspend(|| eprintln!("warning: {}: rendered in full: {reason}", info.id));
    }
    // A full side slower than a plain render of the same views would make
    // every speedup read high.
    if result.full_vs_plain > FULL_VS_PLAIN_NOISE {
        bar.suspend(|| {
            eprintln!(
                "warning: {}: the full side took {:.2}x a plain render of the same views",
                info.id, result.full_vs_plain
            )
        });
    }
    let viewport_oracle = (!scene.viewports.is_empty())
        .then(|| retrace::lab::bench::viewport_oracle(&scene, &mut accel, frames, || bar.inc(1)));
    Ok(ExperimentResult::from_bench(info, result, viewport_oracle))
}

/// How far the full side may be from a plain render of the same views
/// before a warning: the run-to-run noise of a sequence on a shared 2-core
/// machine.
const FULL_VS_PLAIN_NOISE: f64 = 1.1;

fn print_packets(args: &BenchArgs, run: &retrace::lab::bench::PacketRun) {
    say!(
        "{}: {}x{}, {} packets ({} primary, {} shadow, {} reflection rays), {} threads, median of {}",
        scene_name(&args.scene),
        run.width,
        run.height,
        run.packets,
        run.rays.primary,
        run.rays.shadow,
        run.rays.reflection,
        run.threads,
        run.repeats,
    );
}

fn bench_frame(args: &BenchArgs, scene: &Scene, bar: indicatif::ProgressBar) -> Result<()> {
    let accel = args.backend.build(scene)?;
    bar.set_message("frame vs bare Embree");
    let result =
        retrace::lab::bench::bench_frame(scene, &accel, args.frame_repeats(), || bar.inc(1))?;
    bar.finish_and_clear();
    print_packets(args, &result.run);
    say!(
        "full frame ({}):      {:8.2} ms",
        accel.kind(),
        result.full_ms
    );
    say!("bare Embree, same packets: {:8.2} ms", result.embree_ms);
    say!("ratio:                     {:8.3}x", result.ratio);
    if let Some(path) = &args.json {
        write_json(path, &result)?;
    }
    Ok(())
}

fn print_viewport_bench(label: &str, r: &SequenceBench) {
    let e = r.error.expect("viewport sequences measure their error");
    say!(
        "{label}: full {:8.1} ms ({:6.2} ms/frame)  RSVP {:7.1} ms ({:5.2} ms/frame)  speedup {:6.2}x  \
         PSNR worst {:5.2} dB mean {:5.2} dB  max abs {:.3}  mean abs {:.5}  differ {:5.2}%  traced {}",
        r.full_ms,
        r.full_ms / f64::from(r.frames),
        r.accelerated_ms,
        r.accelerated_ms / f64::from(r.frames),
        r.speedup,
        e.worst_psnr_db,
        e.mean_psnr_db,
        e.max_abs,
        e.mean_abs,
        e.differing_share * 100.0,
        r.samples_traced,
    );
}

/// RSVP knobs on E2's zoom in (or the scene given, if it has viewports):
/// each filter, oversampling and level bias, with its time and its error
/// against direct renders.
fn bench_knobs(args: &BenchArgs, bar: indicatif::ProgressBar) -> Result<()> {
    let scene = match &args.scene.scene {
        Some(path) => {
            let scene = load(&args.scene)?;
            if scene.viewports.is_empty() {
                anyhow::bail!(
                    "--only knobs: {} has no [[viewport]] for RSVP to resample",
                    path.display()
                );
            }
            scene
        }
        None => retrace::scene::builtin_scene("paper-zoom-in.toml", &args.scene.overrides())?,
    };
    let mut accel = args.backend.build(&scene)?;
    let frames = 0..scene.animation.as_ref().map_or(1, |a| a.frames);
    let settings = retrace::lab::tradeoff::rsvp_knob_settings();
    bar.set_length((settings.len() * 3 * frames.len()) as u64);
    let results =
        retrace::lab::tradeoff::sweep_rsvp_knobs(&scene, &mut accel, frames.clone(), || bar.inc(1));
    bar.finish_and_clear();
    say!(
        "RSVP knobs on {} ({} frames), {} threads",
        scene_name(&args.scene),
        frames.len(),
        rayon::current_num_threads()
    );
    for r in &results {
        let label = format!(
            "{:8} oversample {:4.2} bias {:+}",
            r.knobs.filter.to_string(),
            r.knobs.oversample,
            r.knobs.level_bias
        );
        print_viewport_bench(&label, r);
    }
    if let Some(path) = &args.json {
        write_json(path, &results)?;
    }
    Ok(())
}

fn bench_backends(args: &BenchArgs, scene: &Scene, bar: indicatif::ProgressBar) -> Result<()> {
    bar.set_message("grid vs Embree");
    let result = retrace::lab::bench::bench_backends(scene, args.frame_repeats(), || bar.inc(1))?;
    bar.finish_and_clear();
    print_packets(args, &result.run);
    say!("Embree, recorded packets: {:8.2} ms", result.embree_ms);
    say!("grid, same packets:       {:8.2} ms", result.grid_ms);
    say!("ratio grid / Embree:      {:8.3}x", result.ratio);
    if let Some(path) = &args.json {
        write_json(path, &result)?;
    }
    Ok(())
}
