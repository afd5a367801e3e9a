//! The `retrace` command line: parses arguments, calls the library, reports.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use retrace::accel::{Accelerator, BackendKind};
use retrace::anim::{Animator, Techniques};
use retrace::camera::Projection;
use retrace::output::{save_image, PendingFile};
use retrace::render::render_frame;
use retrace::scene::{load_scene, paper_scene, Scene, SceneOverrides};

/// Prints a line to stdout; a closed stdout (`retrace ... | head -1`) is
/// not an error worth a panic: the work is done, only the report is cut.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

#[derive(Parser)]
#[command(
    name = "retrace",
    version,
    about = "A ray tracer for animation that re-traces only what changed"
)]
struct Cli {
    /// Worker threads (default: one per core).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one image of a scene file (.toml) or a bare model (.obj).
    Render(RenderArgs),
    /// Render an animation's frames, re-tracing only what changed.
    Animate(AnimateArgs),
    /// Measure rendering costs (release builds only make sense here).
    Bench(BenchArgs),
    /// Check Embree against the pure-Rust grid: ray by ray (camera rays and
    /// seeded random rays) and image by image. Exits with status 1 when
    /// agreement falls below the limits: hit/miss agreement 99.95%, same
    /// primitive on 99.9% of common hits, relative t difference 1e-3 on
    /// those, at most 0.5% of pixels differing by more than 1/255, mean
    /// colour difference 1e-3.
    Validate(ValidateArgs),
    /// Sweep each approximation knob (pan snap vs resample; RSVP filter,
    /// oversampling and level bias; OSTC region and voxel grids) and report
    /// its speedup against its error versus the exact reference (direct
    /// tracing of the output's own rays). Writes tradeoff.csv and
    /// tradeoff.png (error against speedup). All 100 frames take about 5
    /// CPU-minutes (roughly 3 minutes on a quiet 2-core machine, release
    /// build); `--frames 0-49` takes half that, with frame 0's full trace
    /// weighing more in each speedup.
    Tradeoff(TradeoffArgs),
}

#[derive(Args)]
struct TradeoffArgs {
    /// The base scene: the pan (E1) and zoom (E2) timelines are put on it;
    /// the OSTC knobs run on its own timeline if that moves objects or
    /// lights (skipped otherwise). Without it: the built-in paper scene,
    /// and the built-in bouncing ball (E3) for OSTC.
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Folder for tradeoff.csv and tradeoff.png.
    #[arg(long, default_value = "out/tradeoff")]
    out: PathBuf,
    /// Frames of each experiment: A-B (inclusive) or A; default: all 100.
    #[arg(long)]
    frames: Option<String>,
}

#[derive(Args)]
struct ValidateArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Random rays to compare besides the camera rays.
    #[arg(long, default_value_t = 100_000)]
    rays: usize,
    /// Seed of the random rays.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// How many disagreeing rays to list.
    #[arg(long, default_value_t = 10)]
    show: usize,
    /// Also write the report as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Cells per axis of the grid's world grid, N or XxYxZ.
    #[arg(long, value_parser = parse_resolution)]
    grid_resolution: Option<[u32; 3]>,
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene file (.toml) or OBJ model; the built-in paper scene if omitted.
    scene: Option<PathBuf>,
    /// Image width in pixels: the camera's (RSVP viewports keep their own
    /// sizes; `bench` gives its viewport experiments' viewport this size too).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (as for --width).
    #[arg(long)]
    height: Option<u32>,
    /// Camera projection.
    #[arg(long, value_parser = parse_projection)]
    camera: Option<Projection>,
    /// Horizontal field of view in degrees.
    #[arg(long, allow_negative_numbers = true)]
    fov: Option<f64>,
}

#[derive(Args)]
struct BackendArg {
    /// Intersection backend: embree, or grid (the pure-Rust reference).
    #[arg(long, default_value = "embree", value_parser = parse_backend)]
    backend: BackendKind,
    /// Grid backend: cells per axis of the world grid, N or XxYxZ (default:
    /// chosen from the primitive count).
    #[arg(long, value_parser = parse_resolution)]
    grid_resolution: Option<[u32; 3]>,
}

impl BackendArg {
    fn build(&self, scene: &Scene) -> Result<Accelerator> {
        Ok(Accelerator::build_with(
            self.backend,
            &scene.objects,
            self.grid_resolution,
        )?)
    }
}

fn parse_resolution(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split('x').collect();
    let numbers: Vec<u32> = parts
        .iter()
        .map(|p| p.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not N or XxYxZ"))?;
    let resolution = match numbers[..] {
        [n] => [n; 3],
        [x, y, z] => [x, y, z],
        _ => return Err(format!("'{s}' is not N or XxYxZ")),
    };
    if resolution.iter().any(|&n| n == 0 || n > 1024) {
        return Err(format!("'{s}': each axis needs 1 to 1024 cells"));
    }
    Ok(resolution)
}

fn parse_projection(s: &str) -> Result<Projection, String> {
    s.parse()
}

fn parse_backend(s: &str) -> Result<BackendKind, String> {
    s.parse()
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Output image (.png or .tga).
    #[arg(short, long, default_value = "out/render.png")]
    output: PathBuf,
}

#[derive(Args)]
struct AnimateArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Frames to render: A-B (inclusive) or A; default: the whole animation.
    #[arg(long)]
    frames: Option<String>,
    /// Frame files (.png or .tga); a run of # becomes the zero-padded frame
    /// number. A scene with RSVP viewports writes one file per viewport,
    /// its name added before the extension: out/frame_0007_zoomed.png.
    #[arg(short, long, default_value = "out/frame_####.png")]
    output: String,
    /// RSVP: also write the camera's sample buffer per frame (e.g.
    /// out/buffer_####.png), never-traced samples black (paper, figure 5a).
    #[arg(long)]
    buffer_image: Option<String>,
    #[command(flatten)]
    rsvp: RsvpKnobArgs,
    /// Also write the frames as an animated GIF here (with RSVP viewports:
    /// the first viewport's frames).
    #[arg(long)]
    gif: Option<PathBuf>,
    /// Per-frame statistics: .csv or .json.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write each frame with the samples it re-traced painted black
    /// (like the paper's figure 4), e.g. out/dirty_####.png.
    #[arg(long)]
    dirty_image: Option<String>,
    /// full (no reuse), auto (every technique the timeline allows), or a
    /// comma list of techniques: pan (camera pans shift the image), ostc
    /// (moving objects and lights re-trace only their regions), rsvp
    /// (viewports resample the camera's lazily traced sample buffer; with
    /// viewports, full traces each viewport's own rays).
    #[arg(long, default_value = "auto", value_parser = Techniques::parse)]
    mode: Techniques,
    #[command(flatten)]
    ostc: OstcArgs,
    /// How a pan by a fraction of a sample is shown: snap (to whole samples:
    /// exact, the angle off by at most half a sample) or resample (the true
    /// angle, bilinear from the buffer: slightly blurred).
    #[arg(long, default_value = "snap")]
    fractional_pan: retrace::anim::FractionalPan,
    /// Also render every frame in full: exact (snapped) frames must equal
    /// it bit for bit; resampled frames (and RSVP viewports) report their
    /// error against it.
    #[arg(long)]
    verify: bool,
    /// Leave frames whose file already exists (to resume a run).
    #[arg(long)]
    skip_existing: bool,
    /// For array jobs on a render farm: cut the frames into N contiguous
    /// chunks and render one, starting from a full frame. Which one:
    /// --chunk-index, else the scheduler's task index (SLURM_ARRAY_TASK_ID
    /// from SLURM_ARRAY_TASK_MIN, JOB_COMPLETION_INDEX of a Kubernetes
    /// indexed Job, AWS_BATCH_JOB_ARRAY_INDEX). The frames equal those of
    /// one run; --stats files get the chunk's number (stats.chunk03.csv).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    chunks: Option<u32>,
    /// With --chunks: this task's chunk, from 0.
    #[arg(long, requires = "chunks")]
    chunk_index: Option<u32>,
}

#[derive(Args)]
struct RsvpKnobArgs {
    /// RSVP reconstruction filter: nearest, bilinear or box.
    #[arg(long, default_value = "bilinear")]
    filter: retrace::reuse::rsvp::Filter,
    /// RSVP: buffer samples per viewport pixel (per side) the pyramid level
    /// is chosen for, at least.
    #[arg(long, default_value_t = 1.0)]
    oversample: f64,
    /// RSVP: pyramid levels added to the chosen one (negative: coarser).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    level_bias: i32,
}

impl RsvpKnobArgs {
    fn knobs(&self) -> Result<retrace::reuse::rsvp::RsvpKnobs> {
        if !(self.oversample.is_finite() && (0.01..=64.0).contains(&self.oversample)) {
            anyhow::bail!("--oversample {}: must be within 0.01..64", self.oversample);
        }
        Ok(retrace::reuse::rsvp::RsvpKnobs {
            filter: self.filter,
            oversample: self.oversample,
            level_bias: self.level_bias,
        })
    }
}

#[derive(Args)]
struct OstcArgs {
    /// OSTC: the screen is cut into N x N regions (the paper's 16: 40x30
    /// pixels at 640x480; the default 160: 4x4); finer regions re-trace
    /// less but take more memory for their bits.
    #[arg(long, default_value_t = retrace::reuse::ostc::RegionGrid::default().0, value_parser = clap::value_parser!(u32).range(1..=256))]
    regions: u32,
    /// OSTC: about this many voxels in the grid over the moving objects'
    /// swept volume.
    #[arg(long, default_value_t = retrace::reuse::ostc::DEFAULT_VOXELS, value_parser = clap::value_parser!(u32).range(1..=16_777_216))]
    ostc_voxels: u32,
}

impl OstcArgs {
    fn settings(&self) -> retrace::anim::OstcSettings {
        retrace::anim::OstcSettings {
            regions: retrace::reuse::ostc::RegionGrid(self.regions),
            voxels: self.ostc_voxels,
        }
    }
}

#[derive(Args)]
struct BenchArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// What to measure: `all` (the paper's table: E1, E2 in and out, E3,
    /// E4), one experiment of it (`E1`, `E2`, `E3`, `E4`), `scaling` (the
    /// experiments on a larger scene and at 1280x960), `frame` (a full
    /// frame against bare Embree on the same ray packets), `backends` (the
    /// grid against Embree on the same ray packets), `E4nomotion` (pan 3.6
    /// deg/frame and zoom together) or `knobs` (RSVP filter, oversampling
    /// and level bias: cost and error).
    #[arg(long, default_value = "all")]
    only: String,
    /// Frames of every experiment, `A-B` or `A` (default: all 100).
    #[arg(long)]
    frames: Option<String>,
    /// Also run the scaling rows (a scene of about a million triangles,
    /// and 1280x960) after the paper's table.
    #[arg(long)]
    scaling: bool,
    /// Folder for the table (bench.csv, bench.json), per-frame CSVs, plots
    /// and report.md.
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// Timed repetitions, the median reported (default: 15 for `frame`
    /// and `backends`, one run of each sequence for the experiments; with
    /// more, an experiment alternates full and accelerated runs).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1000))]
    repeats: Option<u64>,
    /// Also write the result as JSON here (`frame`, `backends`, `E4nomotion`, `knobs`).
    #[arg(long)]
    json: Option<PathBuf>,
    #[command(flatten)]
    ostc: OstcArgs,
    /// The RSVP knobs of the viewport experiments (E2, E4, E4nomotion);
    /// `knobs` sweeps its own.
    #[command(flatten)]
    rsvp: RsvpKnobArgs,
}

impl BenchArgs {
    /// Repetitions of a single-frame measurement.
    fn frame_repeats(&self) -> usize {
        self.repeats.unwrap_or(15) as usize
    }
}

fn load(args: &SceneArgs) -> Result<Scene> {
    let overrides = SceneOverrides {
        width: args.width,
        height: args.height,
        projection: args.camera,
        fov: args.fov,
    };
    let scene = match &args.scene {
        Some(path) => load_scene(path, &overrides)?,
        None => paper_scene(&overrides)?,
    };
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(scene)
}

fn scene_name(args: &SceneArgs) -> String {
    args.scene
        .as_deref()
        .map_or("built-in paper scene".to_string(), |p| {
            p.display().to_string()
        })
}

fn ensure_parent(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
    }
    Ok(())
}

fn render(args: RenderArgs) -> Result<()> {
    // Check the output name before any work: a typo should not cost a render.
    retrace::output::format_for(&args.output)?;
    let scene = load(&args.scene)?;
    let accel = args.backend.build(&scene)?;
    let start = Instant::now();
    let (frame, rays) = render_frame(&scene, &accel);
    let elapsed = start.elapsed();
    ensure_parent(&args.output)?;
    save_image(&args.output, &frame.to_rgb8())?;
    let seconds = elapsed.as_secs_f64();
    say!(
        "{}: {}x{} {} via {} in {:.1} ms -> {}",
        scene_name(&args.scene),
        frame.width,
        frame.height,
        scene.camera.projection,
        accel.kind(),
        seconds * 1e3,
        args.output.display()
    );
    say!(
        "rays: {} primary, {} shadow, {} reflection ({:.1} Mrays/s)",
        rays.primary,
        rays.shadow,
        rays.reflection,
        rays.total() as f64 / seconds / 1e6
    );
    Ok(())
}

fn bench(args: BenchArgs) -> Result<()> {
    if cfg!(debug_assertions) {
        eprintln!(
            "warning: this is a debug build; timings mean little (use `cargo run --release`)"
        );
    }
    // Before any work, like the frames.
    args.rsvp.knobs()?;
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
        "scaling" => Vec::new(),
        "frame" => return bench_frame(&args, &load(&args.scene)?, bar),
        "backends" => return bench_backends(&args, &load(&args.scene)?, bar),
        "e4nomotion" => {
            return bench_e2(
                &args,
                load(&args.scene)?,
                bar,
                retrace::bench::E4_PAN_DEG_PER_FRAME,
            )
        }
        "knobs" => return bench_knobs(&args, load(&args.scene)?, bar),
        _ => {
            anyhow::bail!(
                "unknown measurement '{}' for --only (available: all, E1, E2, E3, E4, scaling, frame, backends, E4nomotion, knobs)",
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
    bench_suite(&args, planned, bar)
}

/// The experiments of the paper's table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Experiment {
    E1,
    E2In,
    E2Out,
    E3,
    E4,
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
    experiment: Experiment,
    info: retrace::report::ExperimentInfo,
    scene: Scene,
    frames: std::ops::Range<u32>,
}

impl PlannedExperiment {
    /// Progress steps: both sides of a camera sequence, each of `rounds`
    /// times; for viewports also the error pass and the oracle pass.
    fn steps(&self, rounds: u64) -> u64 {
        let frames = u64::from(self.frames.end - self.frames.start);
        match self.experiment {
            Experiment::E1 | Experiment::E3 => 2 * rounds * frames,
            _ => (2 * rounds + 2) * frames,
        }
    }
}

/// Loads and checks an experiment's scene and frames before anything runs,
/// so bad input costs no measuring time.
fn plan_experiment(
    args: &BenchArgs,
    experiment: Experiment,
    variant: Option<ScalingVariant>,
) -> Result<PlannedExperiment> {
    use retrace::bench::{e1_scene, e2_scene, e4_scene, ZoomDirection};
    let mut scene_args = args.scene.clone();
    let mut label = None;
    match variant {
        Some(ScalingVariant::Bunnies) => {
            scene_args.scene = Some(PathBuf::from("scenes/bunnies.toml"));
            label = Some("bunnies".to_string());
        }
        Some(ScalingVariant::Large) => {
            scene_args.width = Some(1280);
            scene_args.height = Some(960);
        }
        None => {}
    }
    let resized = scene_args.width.is_some() || scene_args.height.is_some();
    let own = |file: &str| -> Result<Scene> {
        if scene_args.scene.is_some() {
            return load(&scene_args);
        }
        let path = Path::new(file);
        if !path.exists() {
            anyhow::bail!("{experiment:?} needs {file} (run from the repository) or a scene file");
        }
        load(&SceneArgs {
            scene: Some(path.to_path_buf()),
            ..scene_args.clone()
        })
    };
    let (id, what, technique, paper, mut scene) = match experiment {
        Experiment::E1 => (
            "E1",
            "pan 3.6 deg/frame, a whole turn",
            "Panimation",
            "~10x",
            e1_scene(load(&scene_args)?),
        ),
        Experiment::E2In | Experiment::E2Out => {
            let (id, what, direction) = if experiment == Experiment::E2In {
                ("E2 in", "zoom in 100 -> 50 deg", ZoomDirection::In)
            } else {
                ("E2 out", "zoom out 50 -> 100 deg", ZoomDirection::Out)
            };
            (
                id,
                what,
                "RSVP",
                "~10x",
                e2_scene(load(&scene_args)?, direction, 0.0),
            )
        }
        Experiment::E3 => {
            let scene = own("scenes/paper-bounce.toml")?;
            if !matches!(&scene.animation, Some(a) if a.moves_scene()) {
                anyhow::bail!("E3 needs a scene whose timeline moves objects or lights");
            }
            (
                "E3",
                "a small ball bounces, camera still",
                "OSTC",
                "~2x",
                scene,
            )
        }
        Experiment::E4 => {
            let scene = own("scenes/paper-all.toml")?;
            let moves = matches!(&scene.animation, Some(a) if a.moves_scene());
            // A scene without viewports gets E4's pan and zoom on top of
            // its own motion; one with viewports runs as it is.
            let scene = match (scene.viewports.is_empty(), moves) {
                (false, _) => scene,
                (true, true) => e4_scene(scene),
                (true, false) => anyhow::bail!(
                    "E4 needs a scene with a [[viewport]], or one whose timeline moves objects or lights"
                ),
            };
            (
                "E4",
                "pan + zoom in + bouncing ball, viewport",
                "RSVP+OSTC",
                "~2x",
                scene,
            )
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
    let scene_label = label.unwrap_or_else(|| match &scene_args.scene {
        Some(path) => path
            .file_stem()
            .map_or("scene".to_string(), |s| s.to_string_lossy().into_owned()),
        None if experiment == Experiment::E3 => "paper-bounce".to_string(),
        None if experiment == Experiment::E4 => "paper-all".to_string(),
        None => "paper".to_string(),
    });
    let mut id = id.to_string();
    if variant.is_some() {
        id = format!("{id} {scene_label} {width}x{height}");
    }
    Ok(PlannedExperiment {
        experiment,
        info: retrace::report::ExperimentInfo {
            id,
            what: what.to_string(),
            technique: technique.to_string(),
            paper_speedup: paper.to_string(),
            scene: scene_label,
            triangles: retrace::report::triangles(&scene),
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
    check_writable(&args.out)?;
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
            n => format!("median of {n} alternated runs of each sequence"),
        },
        if cfg!(debug_assertions) {
            " (DEBUG BUILD)"
        } else {
            ""
        }
    );
    say!("{}", retrace::report::table(&rows));
    let run = retrace::report::RunInfo {
        command: std::env::args()
            .map(|a| if a.contains(' ') { format!("'{a}'") } else { a })
            .collect::<Vec<_>>()
            .join(" "),
        backend: args.backend.backend.to_string(),
        threads: rayon::current_num_threads(),
        load: load_at_start.zip(load_average()),
        release: !cfg!(debug_assertions),
    };
    let written = retrace::report::write_bench(&args.out, &run, &results, draw_chart)?;
    say!(
        "wrote {} files to {} (open {})",
        written.len(),
        args.out.display(),
        args.out.join("report.md").display()
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
fn draw_chart(path: &Path, chart: &retrace::report::ChartSpec) -> Result<()> {
    let series: Vec<retrace::plot::Series> = chart
        .lines
        .iter()
        .map(|(label, points)| retrace::plot::Series {
            label: label.clone(),
            points: points.clone(),
        })
        .collect();
    retrace::plot::line_chart(path, &chart.title, "frame", &chart.y_label, &series)?;
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
) -> Result<retrace::report::ExperimentResult> {
    use retrace::report::ExperimentResult;
    let PlannedExperiment {
        experiment,
        mut info,
        scene,
        frames,
    } = plan;
    let knobs = args.rsvp.knobs()?;
    if let (true, Some(changes)) = (info.uses_rsvp(), knobs.changes()) {
        info.technique = format!("{}, {changes}", info.technique);
    }
    let mut accel = args.backend.build(&scene)?;
    let tick = || bar.inc(1);
    Ok(match experiment {
        Experiment::E1 | Experiment::E3 => {
            let result = retrace::bench::bench_sequence(
                &scene,
                &mut accel,
                Techniques::AUTO,
                args.ostc.settings(),
                frames,
                args.repeats.unwrap_or(1) as usize,
                tick,
            );
            for reason in &result.full_reasons {
                bar.suspend(|| eprintln!("warning: {}: rendered in full: {reason}", info.id));
            }
            ExperimentResult::from_sequence(info, result, experiment == Experiment::E3)
        }
        Experiment::E2In | Experiment::E2Out | Experiment::E4 => {
            let result = retrace::bench::bench_viewport_sequence(
                &scene,
                &mut accel,
                frames.clone(),
                args.repeats.unwrap_or(1) as usize,
                knobs,
                true,
                (experiment == Experiment::E4).then(|| args.ostc.settings()),
                tick,
            );
            let oracle = retrace::bench::viewport_oracle(&scene, &mut accel, frames, tick);
            ExperimentResult::from_viewports(info, result, Some(oracle))
        }
    })
}

fn print_packets(args: &BenchArgs, run: &retrace::bench::PacketRun) {
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
    let result = retrace::bench::bench_frame(scene, &accel, args.frame_repeats(), || bar.inc(1))?;
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

fn print_viewport_bench(label: &str, r: &retrace::bench::ViewportSequenceBench) {
    say!(
        "{label}: full {:8.1} ms ({:6.2} ms/frame)  RSVP {:7.1} ms ({:5.2} ms/frame)  speedup {:6.2}x  \
         PSNR worst {:5.2} dB mean {:5.2} dB  max abs {:.3}  mean abs {:.5}  differ {:5.2}%  traced {}",
        r.full_ms,
        r.full_ms / f64::from(r.frames),
        r.rsvp_ms,
        r.rsvp_ms / f64::from(r.frames),
        r.speedup,
        r.worst_psnr_db,
        r.mean_psnr_db,
        r.max_abs,
        r.mean_abs,
        r.differing_share * 100.0,
        r.samples_traced,
    );
}

/// E2 (zoom 100 <-> 50 degrees over 100 frames, both directions), or with
/// a pan E4 without the moving ball.
fn bench_e2(
    args: &BenchArgs,
    scene: Scene,
    bar: indicatif::ProgressBar,
    pan_deg_per_frame: f64,
) -> Result<()> {
    use retrace::bench::{bench_viewport_sequence, e2_scene, ZoomDirection};
    let mut accel = args.backend.build(&scene)?;
    bar.set_length(2 * 300);
    let mut results = Vec::new();
    for (label, direction) in [
        ("zoom in ", ZoomDirection::In),
        ("zoom out", ZoomDirection::Out),
    ] {
        bar.set_message(label);
        let scene = e2_scene(scene.clone(), direction, pan_deg_per_frame);
        let result = bench_viewport_sequence(
            &scene,
            &mut accel,
            0..100,
            1,
            args.rsvp.knobs()?,
            true,
            None,
            || bar.inc(1),
        );
        results.push((label, result));
    }
    bar.finish_and_clear();
    say!(
        "{} (perspective viewport 640x480, 100 <-> 50 deg over 100 frames{}), {} threads, one run, release",
        if pan_deg_per_frame == 0.0 { "E2" } else { "E4 without motion" },
        if pan_deg_per_frame == 0.0 {
            String::new()
        } else {
            format!(", camera yaw {pan_deg_per_frame} deg/frame")
        },
        rayon::current_num_threads()
    );
    for (label, result) in &results {
        print_viewport_bench(label, result);
    }
    if let Some(path) = &args.json {
        let list: Vec<_> = results.iter().map(|(_, r)| r).collect();
        write_json(path, &list)?;
    }
    Ok(())
}

/// RSVP knobs on E2's zoom in: each filter, oversampling and level bias,
/// with its time and its error against direct renders.
fn bench_knobs(args: &BenchArgs, scene: Scene, bar: indicatif::ProgressBar) -> Result<()> {
    use retrace::bench::{e2_scene, ZoomDirection};
    let mut accel = args.backend.build(&scene)?;
    let scene = e2_scene(scene, ZoomDirection::In, 0.0);
    let settings = retrace::tradeoff::rsvp_knob_settings();
    bar.set_length((settings.len() * 300) as u64);
    let results = retrace::tradeoff::sweep_rsvp_knobs(&scene, &mut accel, 0..100, || bar.inc(1));
    bar.finish_and_clear();
    say!(
        "RSVP knobs on E2 zoom in (100 frames, 640x480), {} threads",
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
    let result = retrace::bench::bench_backends(scene, args.frame_repeats(), || bar.inc(1))?;
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

/// `A-B` or `A`, within `0..count`.
fn parse_frame_range(text: Option<&str>, count: u32) -> Result<std::ops::RangeInclusive<u32>> {
    let Some(text) = text else {
        return Ok(0..=count - 1);
    };
    let parse = |s: &str| -> Result<u32> {
        s.trim()
            .parse()
            .with_context(|| format!("--frames {text}: '{s}' is not a frame number"))
    };
    let (first, last) = match text.split_once('-') {
        Some((a, b)) => (parse(a)?, parse(b)?),
        None => {
            let frame = parse(text)?;
            (frame, frame)
        }
    };
    if first > last {
        anyhow::bail!("--frames {text}: the first frame comes after the last");
    }
    if last >= count {
        anyhow::bail!("--frames {text}: the animation has frames 0-{}", count - 1);
    }
    Ok(first..=last)
}

/// The file name of each frame under `pattern` (a run of # becomes the
/// zero-padded frame number), checked for a known image format.
fn frame_namer(pattern: &str) -> Result<impl Fn(u32) -> PathBuf> {
    let (prefix, digits, suffix) = frame_pattern(pattern)?;
    let name = move |frame: u32| PathBuf::from(format!("{prefix}{frame:0digits$}{suffix}"));
    retrace::output::format_for(&name(0))?;
    Ok(name)
}

/// Splits a frame pattern around its run of `#`.
fn frame_pattern(pattern: &str) -> Result<(String, usize, String)> {
    let start = pattern.find('#').with_context(|| {
        format!(
            "output pattern '{pattern}' has no # for the frame number (e.g. out/frame_####.png)"
        )
    })?;
    let width = pattern[start..].chars().take_while(|&c| c == '#').count();
    let (prefix, suffix) = (&pattern[..start], &pattern[start + width..]);
    if suffix.contains('#') {
        anyhow::bail!("output pattern '{pattern}' has more than one run of #");
    }
    Ok((prefix.to_string(), width, suffix.to_string()))
}

/// Fails early, before any rendering, if `dir` cannot take new files.
fn check_writable(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create output folder {}", dir.display()))?;
    let probe = dir.join(format!(".retrace-probe-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .with_context(|| format!("cannot write into output folder {}", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

struct GifWriter {
    /// None once finished. Declared first: dropped (closing the file)
    /// before `file` removes an unfinished one.
    encoder: Option<image::codecs::gif::GifEncoder<std::io::BufWriter<std::fs::File>>>,
    file: PendingFile,
    path: PathBuf,
    delay: image::Delay,
}

impl GifWriter {
    fn create(path: &Path, fps: f64) -> Result<GifWriter> {
        ensure_parent(path)?;
        let file = PendingFile::beside(path);
        let out = std::fs::File::create(file.temp())
            .with_context(|| format!("cannot write {}", path.display()))?;
        // Speed 20 of 30: quantization good enough for previews, several times faster than the default.
        let mut encoder =
            image::codecs::gif::GifEncoder::new_with_speed(std::io::BufWriter::new(out), 20);
        encoder.set_repeat(image::codecs::gif::Repeat::Infinite)?;
        Ok(GifWriter {
            encoder: Some(encoder),
            file,
            path: path.to_path_buf(),
            delay: image::Delay::from_numer_denom_ms(1000, fps.round().max(1.0) as u32),
        })
    }

    fn add(&mut self, image: &image::RgbImage) -> Result<()> {
        let rgba = image::DynamicImage::ImageRgb8(image.clone()).to_rgba8();
        self.encoder
            .as_mut()
            .expect("frames are added before finish")
            .encode_frame(image::Frame::from_parts(rgba, 0, 0, self.delay))
            .with_context(|| format!("cannot encode {}", self.path.display()))
    }

    /// A frame written by an earlier run (`--skip-existing`), read back so
    /// that the GIF still shows every frame.
    fn add_file(&mut self, path: &Path) -> Result<()> {
        let image = image::open(path)
            .with_context(|| format!("cannot read {} back for the GIF", path.display()))?;
        self.add(&image.to_rgb8())
    }

    fn finish(mut self) -> Result<()> {
        // Dropping the encoder writes the trailer and flushes the file.
        drop(self.encoder.take());
        Ok(self.file.commit()?)
    }
}

/// Closes what an animation run writes besides its frames.
fn finish_outputs(
    gif: Option<GifWriter>,
    stats_path: Option<&Path>,
    stats: &[retrace::anim::FrameStats],
) -> Result<()> {
    if let Some(gif) = gif {
        gif.finish()?;
    }
    if let Some(path) = stats_path {
        write_stats(path, stats)?;
    }
    Ok(())
}

fn write_stats(path: &Path, stats: &[retrace::anim::FrameStats]) -> Result<()> {
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let text = if is_json {
        serde_json::to_string_pretty(stats)?
    } else {
        stats_csv(stats)?
    };
    ensure_parent(path)?;
    retrace::output::save_text(path, &text)?;
    Ok(())
}

/// The stats as CSV, one column per field (nested fields as `error.psnr_db`),
/// in the order `FrameStats` declares them, so CSV and JSON never drift apart.
fn stats_csv(stats: &[retrace::anim::FrameStats]) -> Result<String> {
    fn flatten(prefix: &str, value: &serde_json::Value, out: &mut Vec<(String, String)>) {
        match value {
            serde_json::Value::Object(map) => {
                for (key, inner) in map {
                    let name = if prefix.is_empty() {
                        key.clone()
                    } else {
                        format!("{prefix}.{key}")
                    };
                    flatten(&name, inner, out);
                }
            }
            serde_json::Value::Null => out.push((prefix.to_string(), String::new())),
            serde_json::Value::String(text) => {
                let cell = if text.contains([',', '"', '\n']) {
                    format!("\"{}\"", text.replace('"', "\"\""))
                } else {
                    text.clone()
                };
                out.push((prefix.to_string(), cell))
            }
            serde_json::Value::Number(n) => out.push((
                prefix.to_string(),
                match n.as_f64() {
                    Some(x) if n.is_f64() => format!("{x:.6}"),
                    _ => n.to_string(),
                },
            )),
            other => out.push((prefix.to_string(), other.to_string())),
        }
    }
    // Optional nested values are null in some rows: the columns of a row
    // with every value present name them all.
    let template = retrace::anim::FrameStats {
        error: Some(retrace::anim::ImageError::default()),
        ..Default::default()
    };
    let mut header = Vec::new();
    flatten("", &serde_json::to_value(&template)?, &mut header);
    let mut csv = header
        .iter()
        .map(|(name, _)| name.as_str())
        .collect::<Vec<_>>()
        .join(",");
    csv.push('\n');
    for s in stats {
        let mut row = Vec::new();
        flatten("", &serde_json::to_value(s)?, &mut row);
        let cells: std::collections::HashMap<_, _> = row.into_iter().collect();
        let line: Vec<&str> = header
            .iter()
            .map(|(name, _)| cells.get(name).map_or("", String::as_str))
            .collect();
        csv.push_str(&line.join(","));
        csv.push('\n');
    }
    Ok(csv)
}

/// The frames this task renders and where its statistics go: all of
/// `range`, or with `--chunks` this task's chunk of it (None: the chunk is
/// empty, nothing to do).
fn chunk_of(
    args: &AnimateArgs,
    range: std::ops::RangeInclusive<u32>,
) -> Result<Option<(std::ops::RangeInclusive<u32>, Option<PathBuf>)>> {
    use retrace::chunk::{chunk_frames, chunk_path, index_from_env, IndexSource};
    let Some(count) = args.chunks else {
        return Ok(Some((range, args.stats.clone())));
    };
    let (index, source) = match args.chunk_index {
        Some(index) => (index, IndexSource::Flag),
        None => index_from_env(|name| std::env::var(name).ok())
            .map_err(|err| anyhow::anyhow!("--chunks {count}: {err}"))?
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "--chunks {count}: which chunk is this task's? Give --chunk-index, or run it as \
                     a Slurm array task, a Kubernetes indexed Job or an AWS Batch array job"
                )
            })?,
    };
    if index >= count {
        anyhow::bail!(
            "--chunks {count}: chunk {index} (from {source}) is not one of 0-{}",
            count - 1
        );
    }
    if count > 1 && args.gif.is_some() {
        anyhow::bail!(
            "--gif with --chunks {count}: each task has only its chunk's frames; make the GIF \
             from all the frame files once the tasks are done"
        );
    }
    let stats = args
        .stats
        .as_deref()
        .map(|path| chunk_path(path, count, index));
    let what = format!(
        "chunk {index} of {count} (from {source}) of frames {}-{}",
        range.start(),
        range.end()
    );
    match chunk_frames(&range, count, index) {
        Some(frames) => {
            eprintln!("{what}: frames {}-{}", frames.start(), frames.end());
            Ok(Some((frames, stats)))
        }
        None => {
            eprintln!("{what}: no frames (more chunks than frames)");
            Ok(None)
        }
    }
}

fn animate(args: AnimateArgs) -> Result<()> {
    let frame_path = frame_namer(&args.output)?;
    let dirty_path = args.dirty_image.as_deref().map(frame_namer).transpose()?;
    let extension = |path: &Path| path.extension().map(|e| e.to_string_lossy().to_lowercase());
    if let Some(path) = &args.stats {
        if !matches!(extension(path).as_deref(), Some("csv" | "json")) {
            anyhow::bail!("--stats {}: use a .csv or .json file", path.display());
        }
    }
    if let Some(path) = &args.gif {
        if extension(path).as_deref() != Some("gif") {
            anyhow::bail!("--gif {}: use a .gif file", path.display());
        }
    }
    let scene = load(&args.scene)?;
    let (count, fps) = scene
        .animation
        .as_ref()
        .map_or((1, 25.0), |a| (a.frames, a.fps));
    let range = parse_frame_range(args.frames.as_deref(), count)?;
    let Some((range, stats_path)) = chunk_of(&args, range)? else {
        return Ok(());
    };
    let out_dir = frame_path(*range.start())
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map_or(PathBuf::from("."), Path::to_path_buf);
    check_writable(&out_dir)?;
    if let Some(dirty_path) = &dirty_path {
        if let Some(dir) = dirty_path(*range.start()).parent() {
            check_writable(&if dir.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                dir.to_path_buf()
            })?;
        }
    }
    let mut gif = match &args.gif {
        Some(path) => Some(GifWriter::create(path, fps)?),
        None => None,
    };
    let mut accel = args.backend.build(&scene)?;
    let mut animator = Animator::new(
        &scene,
        &mut accel,
        args.mode,
        *range.start()..*range.end() + 1,
    );
    animator.set_linear_output(args.verify);
    animator.set_fractional_pan(args.fractional_pan);
    animator.set_ostc(args.ostc.settings());
    animator.set_traced_image(dirty_path.is_some());
    if animator.has_viewports() {
        animator.set_rsvp_knobs(args.rsvp.knobs()?);
        return animate_viewports(&args, &scene, animator, range, gif, stats_path.as_deref());
    }
    if args.buffer_image.is_some() {
        anyhow::bail!("--buffer-image needs a scene with [[viewport]] tables (RSVP)");
    }

    let bar = indicatif::ProgressBar::new(u64::from(range.end() - range.start() + 1)).with_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} frames {msg} [{elapsed} < {eta}]",
        )
        .expect("static template"),
    );
    let mut all_stats = Vec::new();
    let mut failed_frames = Vec::new();
    let mut previous_reference: Option<retrace::render::Frame> = None;
    let region_size = args
        .ostc
        .settings()
        .regions
        .region_size(scene.camera.width, scene.camera.height);
    let mut write_ms = 0.0;
    let mut skipped = 0;
    for frame in range.clone() {
        let path = frame_path(frame);
        if args.skip_existing && path.exists() {
            if let Some(gif) = &mut gif {
                gif.add_file(&path)?;
            }
            skipped += 1;
            bar.inc(1);
            continue;
        }
        let (image, rgb, mut stats) = animator.render(frame);
        if args.verify {
            let start = Instant::now();
            let (reference, _) = animator.render_reference(frame);
            let full_ms = start.elapsed().as_secs_f64() * 1e3;
            let image = image.expect("verification keeps linear colour");
            let differing = retrace::anim::count_differences(&image, &reference);
            stats.full_ms = Some(full_ms);
            stats.speedup = Some(full_ms / stats.total_ms);
            stats.differing_pixels = Some(differing);
            if let Some(previous) = &previous_reference {
                stats.changed_regions = Some(retrace::anim::changed_regions(
                    previous,
                    &reference,
                    region_size,
                ));
            }
            if animator.is_exact() {
                if differing > 0 {
                    failed_frames.push((frame, differing));
                }
                // What snapping costs against the true (unsnapped) view.
                let (true_view, _) = animator.render_true_view(frame);
                stats.error = Some(retrace::anim::image_error(&image, &true_view));
            } else {
                stats.error = Some(retrace::anim::image_error(&image, &reference));
            }
            previous_reference = Some(reference);
        }
        let write_start = Instant::now();
        save_image(&path, &rgb)?;
        if let (Some(dirty_path), Some(dirty)) = (&dirty_path, animator.take_traced_image()) {
            save_image(&dirty_path(frame), &dirty)?;
        }
        if let Some(gif) = &mut gif {
            gif.add(&rgb)?;
        }
        write_ms += write_start.elapsed().as_secs_f64() * 1e3;
        bar.set_message(format!("{} {:.0} ms", stats.mode, stats.total_ms));
        all_stats.push(stats);
        bar.inc(1);
    }
    bar.finish_and_clear();
    finish_outputs(gif, stats_path.as_deref(), &all_stats)?;
    // Reuse that was asked for but could not apply is worth a word.
    let mut refusals: Vec<&str> = all_stats
        .iter()
        .filter(|s| s.mode == "full" && !s.reason.is_empty())
        .map(|s| s.reason.as_str())
        .collect();
    refusals.dedup();
    for reason in refusals {
        eprintln!("warning: rendered in full: {reason}");
    }
    let what = format!("{} frames{}", all_stats.len(), skipped_note(skipped));
    say!(
        "{}: {what} {}",
        scene_name(&args.scene),
        run_summary(&all_stats, write_ms)
    );
    if args.verify {
        say!("verify: full renders {}", verify_timing(&all_stats));
        if !failed_frames.is_empty() {
            let list: Vec<String> = failed_frames
                .iter()
                .map(|(f, d)| format!("frame {f}: {d} pixels"))
                .collect();
            anyhow::bail!(
                "verification failed, frames differ from full renders: {}",
                list.join(", ")
            );
        }
        // Only a pan moves frames off the camera's own rays (snapped to
        // the lattice, or resampled); without one the two checks agree.
        let off_own_rays = all_stats
            .iter()
            .any(|s| s.yaw_error_deg != 0.0 || s.pitch_error_deg != 0.0);
        if animator.is_exact() {
            say!(
                "verify: every frame equals its full render bit for bit{}",
                if off_own_rays {
                    " (a pan: of the snapped view)"
                } else {
                    ""
                }
            );
        }
        if off_own_rays || !animator.is_exact() {
            say!(
                "verify ({}, against the camera's own unsnapped rays): {}",
                if animator.is_exact() {
                    "snapped"
                } else {
                    "resampled"
                },
                error_summary(all_stats.iter())
            );
        }
    }
    Ok(())
}

/// `pattern`'s file for `frame` and viewport `name`: the name goes before
/// the extension (out/frame_####.png -> out/frame_0007_zoomed.png).
fn viewport_path(pattern: &(String, usize, String), frame: u32, name: &str) -> PathBuf {
    let (prefix, digits, suffix) = pattern;
    let (stem, ext) = match suffix.rfind('.') {
        Some(dot) if !suffix[dot..].contains('/') => suffix.split_at(dot),
        _ => (suffix.as_str(), ""),
    };
    PathBuf::from(format!("{prefix}{frame:0digits$}{stem}_{name}{ext}"))
}

/// The frame loop for a scene whose output is its RSVP viewports: one file
/// per viewport per frame, the buffer image on request, per-viewport stats
/// and, with --verify, each viewport's error against its own rays.
fn animate_viewports(
    args: &AnimateArgs,
    scene: &Scene,
    mut animator: Animator,
    range: std::ops::RangeInclusive<u32>,
    mut gif: Option<GifWriter>,
    stats_path: Option<&Path>,
) -> Result<()> {
    let pattern = frame_pattern(&args.output)?;
    let buffer_pattern = args
        .buffer_image
        .as_deref()
        .map(frame_pattern)
        .transpose()?;
    if let Some((prefix, digits, suffix)) = &buffer_pattern {
        retrace::output::format_for(Path::new(&format!("{prefix}{:0digits$}{suffix}", 0)))?;
    }
    let dirty_pattern = args.dirty_image.as_deref().map(frame_pattern).transpose()?;
    if let Some(pattern) = &dirty_pattern {
        retrace::output::format_for(&viewport_path(pattern, 0, "view"))?;
    }
    let names: Vec<String> = scene
        .viewports
        .iter()
        .map(|t| t.viewport.name.clone())
        .collect();
    let bar = indicatif::ProgressBar::new(u64::from(range.end() - range.start() + 1)).with_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} frames {msg} [{elapsed} < {eta}]",
        )
        .expect("static template"),
    );
    let mut all_stats = Vec::new();
    let mut write_ms = 0.0;
    // (frames checked, samples compared, samples differing)
    let mut buffer_check = (0u32, 0u64, 0u64);
    let mut skipped = 0;
    for frame in range.clone() {
        if args.skip_existing
            && names
                .iter()
                .all(|n| viewport_path(&pattern, frame, n).exists())
        {
            if let Some(gif) = &mut gif {
                gif.add_file(&viewport_path(&pattern, frame, &names[0]))?;
            }
            skipped += 1;
            bar.inc(1);
            continue;
        }
        let outputs = animator.render_viewports(frame);
        let mut frame_ms = 0.0;
        for (index, mut output) in outputs.into_iter().enumerate() {
            if args.verify {
                let start = Instant::now();
                let (reference, _) = animator.render_viewport_direct(frame, index);
                let full_ms = start.elapsed().as_secs_f64() * 1e3;
                let image = output
                    .frame
                    .as_ref()
                    .expect("verification keeps linear colour");
                output.stats.full_ms = Some(full_ms);
                output.stats.speedup = Some(full_ms / output.stats.total_ms);
                output.stats.differing_pixels =
                    Some(retrace::anim::count_differences(image, &reference));
                output.stats.error = Some(retrace::anim::image_error(image, &reference));
            }
            let write_start = Instant::now();
            save_image(&viewport_path(&pattern, frame, &output.name), &output.image)?;
            if let Some(dirty) = &dirty_pattern {
                if let Some(image) = animator.viewport_fresh_image(frame, index, &output.image) {
                    save_image(&viewport_path(dirty, frame, &output.name), &image)?;
                }
            }
            if index == 0 {
                if let Some(gif) = &mut gif {
                    gif.add(&output.image)?;
                }
            }
            write_ms += write_start.elapsed().as_secs_f64() * 1e3;
            frame_ms += output.stats.total_ms;
            all_stats.push(output.stats);
        }
        if let Some((prefix, digits, suffix)) = &buffer_pattern {
            if let Some(image) = animator.buffer_image(frame) {
                let write_start = Instant::now();
                save_image(
                    Path::new(&format!("{prefix}{frame:0digits$}{suffix}")),
                    &image,
                )?;
                write_ms += write_start.elapsed().as_secs_f64() * 1e3;
            }
        }
        // The buffer's samples must be exactly what a fresh trace gives,
        // however objects moved: re-trace them all (every 10th frame and
        // the last, as it costs a full trace of the buffer).
        let checkpoint = (frame - range.start()) % 10 == 9 || frame == *range.end();
        if args.verify && checkpoint {
            if let Some((compared, differing)) = animator.verify_sample_buffer() {
                buffer_check.0 += 1;
                buffer_check.1 += compared;
                buffer_check.2 += differing;
            }
        }
        bar.set_message(format!("{frame_ms:.0} ms"));
        bar.inc(1);
    }
    bar.finish_and_clear();
    finish_outputs(gif, stats_path, &all_stats)?;
    if buffer_check.0 > 0 {
        say!(
            "verify: buffer samples re-traced at {} frame(s): {} compared, {} differ",
            buffer_check.0,
            buffer_check.1,
            buffer_check.2
        );
        if buffer_check.2 > 0 {
            anyhow::bail!(
                "verification failed: {} buffer samples differ from a fresh trace",
                buffer_check.2
            );
        }
    }
    let what = format!(
        "{} frames x {} viewports ({}){}",
        range.end() - range.start() + 1 - skipped,
        names.len(),
        names.join(", "),
        skipped_note(skipped)
    );
    say!(
        "{}: {what} {}",
        scene_name(&args.scene),
        run_summary(&all_stats, write_ms)
    );
    if args.verify {
        say!("verify: direct renders {}", verify_timing(&all_stats));
        for name in &names {
            let rows = all_stats.iter().filter(|s| &s.viewport == name);
            say!(
                "verify {name} (against its own rays): {}",
                error_summary(rows)
            );
        }
    }
    Ok(())
}

/// Says how many frames `--skip-existing` left as they were, if any.
fn skipped_note(skipped: u32) -> String {
    if skipped == 0 {
        String::new()
    } else {
        format!(" ({skipped} more skipped: their files exist)")
    }
}

/// Time spent, and samples traced against pixels shown, over a run.
fn run_summary(stats: &[retrace::anim::FrameStats], write_ms: f64) -> String {
    // A float sum starts at -0.0: no frame rendered would say "-0.0 ms".
    let total: f64 = stats.iter().map(|s| s.total_ms).sum::<f64>() + 0.0;
    let traced: u64 = stats.iter().map(|s| s.samples_traced).sum();
    let pixels: u64 = stats.iter().map(|s| s.pixels).sum();
    format!(
        "in {total:.1} ms rendering ({write_ms:.1} ms writing); traced {traced} samples for {pixels} pixels ({:.1}%)",
        100.0 * traced as f64 / pixels.max(1) as f64
    )
}

/// The reference renders' time and the speedup against them.
fn verify_timing(stats: &[retrace::anim::FrameStats]) -> String {
    let total: f64 = stats.iter().map(|s| s.total_ms).sum();
    let full: f64 = stats.iter().filter_map(|s| s.full_ms).sum();
    format!("{full:.1} ms, speedup {:.2}x", full / total.max(1e-9))
}

/// Worst and mean PSNR, largest and mean absolute error and share of
/// differing pixels over the rows that measured an error.
fn error_summary<'a>(rows: impl Iterator<Item = &'a retrace::anim::FrameStats>) -> String {
    let errors: Vec<_> = rows.filter_map(|s| s.error).collect();
    let count = errors.len().max(1) as f64;
    let worst_psnr = errors
        .iter()
        .map(|e| e.psnr_db)
        .fold(f64::INFINITY, f64::min);
    // Identical frames have infinite PSNR: cap them so the mean stays finite.
    let mean_psnr = errors.iter().map(|e| e.psnr_db.min(100.0)).sum::<f64>() / count;
    let max_abs = errors.iter().map(|e| e.max_abs).fold(0.0f32, f32::max);
    let mean = errors.iter().map(|e| e.mean_abs).sum::<f64>() / count;
    let share = errors.iter().map(|e| e.differing_share).sum::<f64>() / count;
    format!(
        "PSNR worst {worst_psnr:.2} dB, mean {mean_psnr:.2} dB; max abs error {max_abs:.4}, \
         mean abs error {mean:.5}, {:.2}% of pixels differ in 8 bits",
        share * 100.0
    )
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    ensure_parent(path)?;
    let text = serde_json::to_string_pretty(value)?;
    retrace::output::write_atomically(path, |temp| {
        std::fs::write(temp, &text).map_err(|source| retrace::output::OutputError::Write {
            path: path.to_path_buf(),
            source,
        })
    })?;
    Ok(())
}

fn validate(args: ValidateArgs) -> Result<()> {
    let scene = load(&args.scene)?;
    let embree = Accelerator::build(BackendKind::Embree, &scene.objects)?;
    let grid = Accelerator::build_with(BackendKind::Grid, &scene.objects, args.grid_resolution)?;
    let report =
        retrace::validate::validate(&scene, &embree, &grid, args.rays, args.seed, args.show);
    say!("{}: Embree vs grid", scene_name(&args.scene));
    say!(
        "{:<12} {:>9} {:>15} {:>14} {:>12} {:>12}",
        "rays",
        "count",
        "hit/miss agree",
        "same primitive",
        "max rel. t",
        "mean rel. t"
    );
    for (name, a) in [
        ("camera", &report.camera_rays),
        ("random", &report.random_rays),
    ] {
        say!(
            "{:<12} {:>9} {:>14.4}% {:>13.4}% {:>12.2e} {:>12.2e}",
            name,
            a.rays,
            a.hit_agreement() * 100.0,
            a.same_primitive_share() * 100.0,
            a.max_relative_t,
            a.mean_relative_t
        );
    }
    let image = &report.image;
    say!(
        "image        {:>9} pixels: {:.4}% differ by more than 1/255, max difference {:.4}, mean {:.2e}",
        image.pixels,
        image.differing_pixels * 100.0,
        image.max_difference,
        image.mean_difference
    );
    if !report.disagreements.is_empty() {
        say!("disagreeing rays (first {}):", report.disagreements.len());
        for d in &report.disagreements {
            let show = |h: &Option<retrace::validate::HitSummary>| {
                h.map_or("miss".to_string(), |h| {
                    format!("object {} prim {} t {}", h.object, h.prim, h.t)
                })
            };
            say!(
                "  {} origin {:?} dir {:?}: embree {}, grid {}",
                d.source,
                d.origin,
                d.direction,
                show(&d.embree),
                show(&d.grid)
            );
        }
    }
    if let Some(path) = &args.json {
        write_json(path, &report)?;
    }
    if report.passed() {
        say!("PASS");
        Ok(())
    } else {
        anyhow::bail!("validation failed: {}", report.failures.join("; "))
    }
}

fn tradeoff(args: TradeoffArgs) -> Result<()> {
    use retrace::tradeoff::{bouncing_ball_scene, TradeoffScenes};
    if cfg!(debug_assertions) {
        eprintln!(
            "warning: this is a debug build; timings mean little (use `cargo run --release`)"
        );
    }
    let base = load(&args.scene)?;
    let objects = match &args.scene.scene {
        None => Some(bouncing_ball_scene(&SceneOverrides {
            width: args.scene.width,
            height: args.scene.height,
            projection: args.scene.camera,
            fov: args.scene.fov,
        })?),
        Some(_) if base.animation.as_ref().is_some_and(|a| a.moves_scene()) => Some(base.clone()),
        Some(path) => {
            eprintln!(
                "note: OSTC knobs skipped: the timeline of {} moves no object or light",
                path.display()
            );
            None
        }
    };
    let scenes = TradeoffScenes::new(base, objects);
    let frames = parse_frame_range(args.frames.as_deref(), scenes.frame_count())?;
    check_writable(&args.out)?;
    let frames = *frames.start()..*frames.end() + 1;
    let bar = indicatif::ProgressBar::new(scenes.progress_steps(frames.len() as u32)).with_style(
        indicatif::ProgressStyle::with_template("{msg:28} {bar:30} {pos}/{len} {elapsed}")
            .expect("static template"),
    );
    let rows = retrace::tradeoff::sweep(
        &scenes,
        args.backend.backend,
        args.backend.grid_resolution,
        frames.clone(),
        |what| {
            bar.set_message(what.to_string());
            bar.inc(1);
        },
    )?;
    bar.finish_and_clear();
    say!(
        "{}: frames {}-{}, {} backend, {} threads, one run each; errors against direct renders of each output's own rays",
        scene_name(&args.scene),
        frames.start,
        frames.end - 1,
        args.backend.backend,
        rayon::current_num_threads()
    );
    say!("{}", retrace::tradeoff::table(&rows).trim_end());
    let csv = args.out.join("tradeoff.csv");
    retrace::output::save_text(&csv, &retrace::tradeoff::csv(&rows))?;
    let png = args.out.join("tradeoff.png");
    retrace::tradeoff::plot(&png, &rows)?;
    say!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}

/// `err` and its causes, each said once: an error that prints its source
/// itself (`path: cannot write: No such file`) would otherwise repeat it.
fn error_text(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text = format!("{text}: {cause}");
        }
    }
    text
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Ctrl-C stops at once, leaving finished files and no unfinished ones
    // (frames, GIFs, reports are written under temporary names).
    let interrupted = ctrlc::set_handler(|| {
        eprintln!("\ninterrupted");
        retrace::output::remove_unfinished_and_exit(130)
    });
    if let Err(err) = interrupted {
        eprintln!("warning: Ctrl-C will not clean up unfinished files: {err}");
    }
    if let Some(threads) = cli.threads {
        if let Err(err) = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build_global()
        {
            eprintln!("error: cannot set up {threads} worker threads: {err}");
            return ExitCode::FAILURE;
        }
    }
    // The command runs on a worker thread of the pool, so each parallel
    // step starts at once on this thread while the other workers wake.
    // Called from outside the pool, every step first waited for a sleeping
    // worker, ~0.2 ms here (2 vCPUs); an RSVP frame has five steps of
    // 0.2-2 ms each, so it paid that wait five times a frame.
    let result = rayon::scope(|_| match cli.command {
        Command::Render(args) => render(args),
        Command::Animate(args) => animate(args),
        Command::Bench(args) => bench(args),
        Command::Validate(args) => validate(args),
        Command::Tradeoff(args) => tradeoff(args),
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", error_text(&err));
            ExitCode::FAILURE
        }
    }
}
