//! The `retrace` command line: parses arguments, calls the library, reports.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use retrace::accel::{Accelerator, BackendKind};
use retrace::camera::Projection;
use retrace::output::save_image;
use retrace::render::render_frame;
use retrace::scene::{load_scene, paper_scene, Scene, SceneOverrides};
use retrace::shade::RayCounts;

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
    /// Measure rendering costs (release builds only make sense here).
    Bench(BenchArgs),
    /// Check Embree against the pure-Rust grid: ray by ray (camera rays and
    /// seeded random rays) and image by image. Exits with status 1 when
    /// agreement falls below the limits: hit/miss agreement 99.95%, same
    /// primitive on 99.9% of common hits, relative t difference 1e-3 on
    /// those, at most 0.5% of pixels differing by more than 1/255, mean
    /// colour difference 1e-3.
    Validate(ValidateArgs),
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
}

#[derive(Args)]
struct SceneArgs {
    /// Scene file (.toml) or OBJ model; the built-in paper scene if omitted.
    scene: Option<PathBuf>,
    /// Image width in pixels.
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels.
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
struct BenchArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Which measurement: `frame` (a full frame against bare Embree on the
    /// same ray packets) or `backends` (the grid against Embree on the same
    /// ray packets).
    #[arg(long, default_value = "frame")]
    only: String,
    /// Timed repetitions (the median is reported).
    #[arg(long, default_value_t = 15)]
    repeats: usize,
    /// Also write the result as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
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
    let accel = Accelerator::build(args.backend.backend, &scene.objects)?;
    let start = Instant::now();
    let (frame, rays) = render_frame(&scene, &accel);
    let elapsed = start.elapsed();
    ensure_parent(&args.output)?;
    save_image(&args.output, &frame.to_rgb8())?;
    let seconds = elapsed.as_secs_f64();
    println!(
        "{}: {}x{} {} via {} in {:.1} ms -> {}",
        scene_name(&args.scene),
        frame.width,
        frame.height,
        scene.camera.projection,
        accel.kind(),
        seconds * 1e3,
        args.output.display()
    );
    println!(
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
    let scene = load(&args.scene)?;
    let bar = indicatif::ProgressBar::new(args.repeats.max(1) as u64).with_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {pos}/{len}")
            .expect("static template"),
    );
    match args.only.as_str() {
        "frame" => bench_frame(&args, &scene, bar),
        "backends" => bench_backends(&args, &scene, bar),
        other => {
            anyhow::bail!("unknown measurement '{other}' for --only (available: frame, backends)")
        }
    }
}

fn print_packets(
    args: &BenchArgs,
    width: u32,
    height: u32,
    packets: usize,
    rays: RayCounts,
    repeats: usize,
) {
    println!(
        "{}: {width}x{height}, {packets} packets ({} primary, {} shadow, {} reflection rays), {} threads, median of {repeats}",
        scene_name(&args.scene),
        rays.primary,
        rays.shadow,
        rays.reflection,
        rayon::current_num_threads(),
    );
}

fn bench_frame(args: &BenchArgs, scene: &Scene, bar: indicatif::ProgressBar) -> Result<()> {
    let accel = Accelerator::build(args.backend.backend, &scene.objects)?;
    bar.set_message("frame vs bare Embree");
    let result = retrace::bench::bench_frame(scene, &accel, args.repeats, || bar.inc(1))?;
    bar.finish_and_clear();
    print_packets(
        args,
        result.width,
        result.height,
        result.packets,
        result.rays,
        result.repeats,
    );
    println!(
        "full frame ({}):      {:8.2} ms",
        accel.kind(),
        result.full_ms
    );
    println!("bare Embree, same packets: {:8.2} ms", result.embree_ms);
    println!("ratio:                     {:8.3}x", result.ratio);
    if let Some(path) = &args.json {
        write_json(path, &result)?;
    }
    Ok(())
}

fn bench_backends(args: &BenchArgs, scene: &Scene, bar: indicatif::ProgressBar) -> Result<()> {
    bar.set_message("grid vs Embree");
    let result = retrace::bench::bench_backends(scene, args.repeats, || bar.inc(1))?;
    bar.finish_and_clear();
    print_packets(
        args,
        result.width,
        result.height,
        result.packets,
        result.rays,
        result.repeats,
    );
    println!("Embree, recorded packets: {:8.2} ms", result.embree_ms);
    println!("grid, same packets:       {:8.2} ms", result.grid_ms);
    println!("ratio grid / Embree:      {:8.3}x", result.ratio);
    if let Some(path) = &args.json {
        write_json(path, &result)?;
    }
    Ok(())
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
    let grid = Accelerator::build(BackendKind::Grid, &scene.objects)?;
    let report =
        retrace::validate::validate(&scene, &embree, &grid, args.rays, args.seed, args.show);
    println!("{}: Embree vs grid", scene_name(&args.scene));
    println!(
        "{:<12} {:>9} {:>15} {:>14} {:>12} {:>12}",
        "rays", "count", "hit/miss agree", "same primitive", "max rel. t", "mean rel. t"
    );
    for (name, a) in [
        ("camera", &report.camera_rays),
        ("random", &report.random_rays),
    ] {
        println!(
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
    println!(
        "image        {:>9} pixels: {:.4}% differ by more than 1/255, max difference {:.4}, mean {:.2e}",
        image.pixels,
        image.differing_pixels * 100.0,
        image.max_difference,
        image.mean_difference
    );
    if !report.disagreements.is_empty() {
        println!("disagreeing rays (first {}):", report.disagreements.len());
        for d in &report.disagreements {
            let show = |h: &Option<retrace::validate::HitSummary>| {
                h.map_or("miss".to_string(), |h| {
                    format!("object {} prim {} t {}", h.object, h.prim, h.t)
                })
            };
            println!(
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
        println!("PASS");
        Ok(())
    } else {
        anyhow::bail!("validation failed: {}", report.failures.join("; "))
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(threads) = cli.threads {
        if let Err(err) = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build_global()
        {
            eprintln!("error: cannot set up {threads} worker threads: {err}");
            return ExitCode::FAILURE;
        }
    }
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Bench(args) => bench(args),
        Command::Validate(args) => validate(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprint!("error: {err}");
            for cause in err.chain().skip(1) {
                eprint!(": {cause}");
            }
            eprintln!();
            ExitCode::FAILURE
        }
    }
}
