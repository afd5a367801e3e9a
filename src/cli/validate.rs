//! `retrace validate`: Embree against the pure-Rust grid.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use retrace::accel::{Accelerator, BackendKind};

use super::{load, parse_resolution, scene_name, write_json, SceneArgs};

#[derive(Args)]
pub(crate) struct ValidateArgs {
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

pub(crate) fn validate(args: ValidateArgs) -> Result<()> {
    let scene = load(&args.scene)?;
    let embree = Accelerator::build(BackendKind::Embree, &scene.objects)?;
    let grid = Accelerator::build_with(BackendKind::Grid, &scene.objects, args.grid_resolution)?;
    let report =
        retrace::lab::validate::validate(&scene, &embree, &grid, args.rays, args.seed, args.show);
    say!("{}: Embree vs grid", scene_name(&args.scene));
    say!(
        "{:<12} {:>9} {:>15} {:>14} {:>14} {:>14}",
        "rays",
        "count",
        "hit/miss agree",
        "same primitive",
        "max sep/bound",
        "mean sep/bound"
    );
    for (name, a) in [
        ("camera", &report.camera_rays),
        ("random", &report.random_rays),
    ] {
        say!(
            "{:<12} {:>9} {:>14.4}% {:>13.4}% {:>14.3} {:>14.2e}",
            name,
            a.rays,
            a.hit_agreement() * 100.0,
            a.same_primitive_share() * 100.0,
            a.max_hit_point_ratio,
            a.mean_hit_point_ratio
        );
    }
    for (name, a) in [
        ("camera", &report.camera_rays),
        ("random", &report.random_rays),
    ] {
        if a.textured > 0 {
            say!(
                "{name} rays on textured triangles: {}; texture coordinates' max sep/bound {:.3}",
                a.textured,
                a.max_texcoord_ratio
            );
        }
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
            let show = |h: &Option<retrace::lab::validate::HitSummary>| {
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
