//! `retrace tradeoff`: each approximation knob's speedup against its error.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::{check_writable, load, parse_frame_range, scene_name, BackendArg, SceneArgs};

#[derive(Args)]
pub(crate) struct TradeoffArgs {
    /// The scene whose timeline the knobs are swept on: the pan knobs if
    /// its equal-angle camera moves, the RSVP knobs if it has viewports,
    /// the OSTC knobs if objects or lights move. Without it: the paper's
    /// experiments built into the binary (E1's pan, E2's zoom in, E3's
    /// bouncing ball), at the size and camera the flags give.
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Folder for tradeoff.csv and tradeoff.png.
    #[arg(long, default_value = "out/tradeoff")]
    out: PathBuf,
    /// Frames of each experiment: A-B (inclusive) or A; default: all 100.
    #[arg(long, allow_hyphen_values = true, value_parser = super::frame_range_text)]
    frames: Option<String>,
}

pub(crate) fn tradeoff(args: TradeoffArgs) -> Result<()> {
    use retrace::lab::tradeoff::TradeoffScenes;
    if cfg!(debug_assertions) {
        eprintln!(
            "warning: this is a debug build; timings mean little (use `cargo run --release`)"
        );
    }
    let scenes = match &args.scene.scene {
        None => TradeoffScenes::builtin(&args.scene.overrides())?,
        Some(path) => {
            let scenes = TradeoffScenes::of(load(&args.scene)?);
            let skipped = scenes.skipped();
            if skipped.len() == 4 {
                anyhow::bail!(
                    "{}: it exercises no knob (no pan of an equal-angle camera, no viewport, \
                     nothing else moving, no area light)",
                    path.display()
                );
            }
            if !skipped.is_empty() {
                eprintln!(
                    "note: {} knobs skipped: {} does not exercise them",
                    skipped.join(", "),
                    path.display()
                );
            }
            scenes
        }
    };
    let frames = parse_frame_range(args.frames.as_deref(), scenes.frame_count())?;
    check_writable(&args.out)?;
    let frames = *frames.start()..*frames.end() + 1;
    let bar = indicatif::ProgressBar::new(scenes.progress_steps(frames.len() as u32)).with_style(
        indicatif::ProgressStyle::with_template("{msg:28} {bar:30} {pos}/{len} {elapsed}")
            .expect("static template"),
    );
    let rows = retrace::lab::tradeoff::sweep(
        &scenes,
        args.backend.backend,
        args.backend.grid_resolution()?,
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
    say!("{}", retrace::lab::tradeoff::table(&rows).trim_end());
    let csv = args.out.join("tradeoff.csv");
    retrace::output::save_text(&csv, &retrace::lab::tradeoff::csv(&rows)?)?;
    let png = args.out.join("tradeoff.png");
    retrace::lab::tradeoff::plot(&png, &rows)?;
    say!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}
