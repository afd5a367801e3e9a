//! `retrace tradeoff`: each approximation knob's speedup against its error.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use retrace::scene::SceneOverrides;

use super::{check_writable, load, parse_frame_range, scene_name, BackendArg, SceneArgs};

#[derive(Args)]
pub(crate) struct TradeoffArgs {
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

pub(crate) fn tradeoff(args: TradeoffArgs) -> Result<()> {
    use retrace::lab::tradeoff::{bouncing_ball_scene, TradeoffScenes};
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
    retrace::output::save_text(&csv, &retrace::lab::tradeoff::csv(&rows))?;
    let png = args.out.join("tradeoff.png");
    retrace::lab::tradeoff::plot(&png, &rows)?;
    say!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}
