//! `retrace render`: one image of a scene.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use retrace::aov::{exr_picture, Aovs};
use retrace::camera::RayTable;
use retrace::output::{frame_format_for, save_exr, save_image, FrameFormat};
use retrace::render::{render_frame, PrimaryRays};
use retrace::reuse::rsvp::ViewportRays;
use retrace::sampling::PixelSamples;
use retrace::shade::Shader;

use super::{
    check_parent, check_writable, ensure_parent, folder_of, load, scene_name, AovArgs, BackendArg,
    SceneArgs,
};

#[derive(Args)]
pub(crate) struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    backend: BackendArg,
    /// Output image (.png, .tga, or .exr: linear half floats, with
    /// --aov's layers).
    #[arg(short, long, default_value = "out/render.png")]
    output: PathBuf,
    #[command(flatten)]
    aov: AovArgs,
    /// Render the scene's RSVP viewport of this name (at frame 0, through
    /// its own rays) instead of the camera's image.
    #[arg(long)]
    viewport: Option<String>,
    /// The converged reference accuracy is measured against: 256
    /// stratified samples a pixel (the same as --spp 256).
    #[arg(long, conflicts_with = "spp")]
    reference: bool,
}

pub(crate) fn render(mut args: RenderArgs) -> Result<()> {
    // Check the output name, and that its folder takes files, before any
    // work: a typo or a read-only folder should not cost a render.
    let format = frame_format_for(&args.output)?;
    let aov_set = args.aov.set(&args.output.display().to_string(), format)?;
    check_parent(&args.output)?;
    check_writable(&folder_of(&args.output))?;
    if args.reference {
        args.scene.spp = Some(retrace::sampling::REFERENCE_SAMPLES_PER_PIXEL);
    }
    let scene = load(&args.scene)?;
    let names: Vec<&str> = scene
        .viewports
        .iter()
        .map(|t| t.viewport.name.as_str())
        .collect();
    let viewport = match &args.viewport {
        None => {
            if !names.is_empty() {
                eprintln!(
                    "note: the scene's viewports ({}) are not rendered: this is the camera's \
                     image; --viewport NAME renders one",
                    names.join(", ")
                );
            }
            None
        }
        Some(name) => {
            let Some(track) = scene.viewports.iter().find(|t| &t.viewport.name == name) else {
                anyhow::bail!(
                    "--viewport {name}: the scene has no viewport of that name ({})",
                    if names.is_empty() {
                        "it has none".to_string()
                    } else {
                        format!("it has {}", names.join(", "))
                    }
                );
            };
            let camera = match &scene.animation {
                Some(animation) => animation.camera_at(&scene.camera, 0),
                None => scene.camera.clone(),
            };
            Some(track.pose_at(&camera, 0))
        }
    };
    let (width, height) = viewport
        .as_ref()
        .map_or((scene.camera.width, scene.camera.height), |pose| {
            (pose.camera.width, pose.camera.height)
        });
    let memory = retrace::frame_loop::MemoryEstimate::picture(width, height);
    super::check_memory(&memory)?;
    let accel = args.backend.build(&scene)?;
    let start = Instant::now();
    let (frame, rays) = match &viewport {
        None => render_frame(&scene, &accel),
        Some(pose) => {
            retrace::reuse::rsvp::render_direct(&retrace::shade::Shader::new(&scene, &accel), pose)
        }
    };
    // A still render traces every pixel: its `traced` mask is all 1.
    let aovs = (!aov_set.is_empty()).then(|| {
        let shader = Shader::new(&scene, &accel);
        let centre_rays: Box<dyn PrimaryRays> = match &viewport {
            None => Box::new(RayTable::new(&scene.camera)),
            Some(pose) => Box::new(ViewportRays {
                pose,
                samples: PixelSamples::ONE,
            }),
        };
        let pixels = frame.width as usize * frame.height as usize;
        Aovs::trace(
            &shader,
            &*centre_rays,
            (frame.width, frame.height),
            aov_set,
            || vec![true; pixels],
        )
    });
    let elapsed = start.elapsed();
    ensure_parent(&args.output)?;
    match format {
        FrameFormat::Picture(_) => save_image(&args.output, &frame.to_rgb8())?,
        FrameFormat::Exr => save_exr(&args.output, &exr_picture(&frame, aovs.as_ref()))?,
    }
    let seconds = elapsed.as_secs_f64();
    let spp = scene.samples.count();
    say!(
        "{}: {}x{} {}{} via {} in {:.1} ms -> {}",
        scene_name(&args.scene),
        frame.width,
        frame.height,
        viewport
            .as_ref()
            .map_or(scene.camera.projection, |pose| pose.camera.projection),
        if spp > 1 {
            format!(", {spp} samples a pixel")
        } else {
            String::new()
        },
        accel.kind(),
        seconds * 1e3,
        args.output.display()
    );
    let refraction = match rays.refraction {
        0 => String::new(),
        n => format!(", {n} refraction"),
    };
    say!(
        "rays: {} primary, {} shadow, {} reflection{refraction} ({:.1} Mrays/s)",
        rays.primary,
        rays.shadow,
        rays.reflection,
        rays.total() as f64 / seconds / 1e6
    );
    Ok(())
}
