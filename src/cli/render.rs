//! `retrace render`: one image of a scene.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use retrace::output::save_image;
use retrace::render::render_frame;

use super::{check_parent, ensure_parent, load, scene_name, BackendArg, SceneArgs};

#[derive(Args)]
pub(crate) struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Output image (.png or .tga).
    #[arg(short, long, default_value = "out/render.png")]
    output: PathBuf,
}

pub(crate) fn render(args: RenderArgs) -> Result<()> {
    // Check the output name before any work: a typo should not cost a render.
    retrace::output::format_for(&args.output)?;
    check_parent(&args.output)?;
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
