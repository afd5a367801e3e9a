//! `animate --verify`: each frame checked through the library's verifier
//! ([`retrace::verify`]) as it is rendered, and the run's verdict.

use anyhow::Result;

use retrace::frame_loop::{Animator, FrameStats, ViewOutput};
use retrace::metrics::{changed_regions, ImageError, REFERENCE_EVERY};
use retrace::render::Frame;
use retrace::sampling::PixelSamples;
use retrace::verify::{Checks, ReferenceErrors, Verifier};

/// What `--verify` found over a run.
pub(super) struct RunCheck {
    verifier: Verifier,
    run_samples: PixelSamples,
    /// The first and last frame of the run.
    frames: (u32, u32),
    /// OSTC's region size, for the regions that truly changed.
    region_size: (i64, i64),
    /// The camera image's last full render, for the regions that changed.
    previous_full: Option<Frame>,
    /// Exact frames that differ from their full renders: (frame, (pixels
    /// in linear colour, in the image written)).
    failed_frames: Vec<(u32, (u64, u64))>,
    /// Approximate output against the converged reference: (frame, view,
    /// errors), on every [`REFERENCE_EVERY`]th frame of the run and the
    /// last.
    references: Vec<(u32, String, ReferenceErrors)>,
    /// The store's samples re-traced: (frames, samples compared, samples
    /// differing).
    store: (u32, u64, u64),
    /// The frames are written as OpenEXR: their half floats and AOVs are
    /// what is compared as written.
    pub(super) exr: bool,
}

impl RunCheck {
    pub(super) fn new(
        samples: PixelSamples,
        frames: (u32, u32),
        region_size: (i64, i64),
    ) -> RunCheck {
        RunCheck {
            verifier: Verifier::new(samples),
            run_samples: samples,
            frames,
            region_size,
            previous_full: None,
            failed_frames: Vec::new(),
            references: Vec::new(),
            store: (0, 0, 0),
            exr: false,
        }
    }

    /// Checks view `index` of `frame` and records, in `output`'s stats,
    /// the full render's time, the pixels that differ from it, the error
    /// against the view's own rays and the regions that truly changed.
    pub(super) fn check_view(
        &mut self,
        animator: &mut Animator,
        frame: u32,
        index: usize,
        output: &mut ViewOutput,
    ) -> Result<()> {
        let sampled = frame == self.frames.1 || (frame - self.frames.0) % REFERENCE_EVERY == 0;
        // Exact output off its camera's own rays is a snapped or blended
        // pan: approximate against the camera's view, so measured too.
        let approximate = !animator.is_exact() || output.stats.off_keyed_view() || blends(animator);
        let checks = Checks {
            full: true,
            afresh: true,
            own_rays: true,
            reference: sampled && approximate,
            exr: self.exr,
        };
        let check = self
            .verifier
            .check_view(animator, frame, index, output, checks)?;
        let differing = check.differing.expect("asked for");
        // The regions a perfect OSTC would re-trace, from the full renders'
        // changes (of the camera's image).
        let camera_image = !animator.has_viewports();
        let changed = match (&self.previous_full, &check.full) {
            (Some(previous), Some((full, _))) if camera_image => {
                Some(changed_regions(previous, full, self.region_size)?)
            }
            _ => None,
        };
        output.stats.check = check.frame_check(changed);
        if camera_image {
            self.previous_full = check.full.map(|(full, _)| full);
        }
        if animator.is_exact() && differing != (0, 0) {
            self.failed_frames.push((frame, differing));
        }
        if let Some(errors) = check.reference {
            self.references.push((frame, output.name.clone(), errors));
        }
        Ok(())
    }

    /// Re-traces every sample the store keeps: they must be exactly what a
    /// fresh trace gives, however objects moved.
    pub(super) fn check_store(&mut self, animator: &Animator) {
        if let Some((compared, differing)) = animator.verify_store() {
            self.store.0 += 1;
            self.store.1 += compared;
            self.store.2 += differing;
        }
    }

    /// The store's verdict: fails the run if a kept sample differs from a
    /// fresh trace.
    pub(super) fn say_store(&self) -> Result<()> {
        let (frames, compared, differing) = self.store;
        if frames == 0 {
            return Ok(());
        }
        say!(
            "verify: buffer samples re-traced at {frames} frame(s): {compared} compared, \
             {differing} differ"
        );
        if differing > 0 {
            anyhow::bail!(
                "verification failed: {differing} buffer samples differ from a fresh trace"
            );
        }
        Ok(())
    }

    /// The run's verdict: exact frames equal their full renders (or the
    /// run fails); approximate ones say their error, and both sides'
    /// against the reference.
    pub(super) fn say(
        &self,
        animator: &Animator,
        names: &[String],
        stats: &[FrameStats],
    ) -> Result<()> {
        say_verified(animator, names, stats, &self.failed_frames)?;
        self.say_references(names);
        Ok(())
    }

    /// Two lines a view, full render above output, with the same figures.
    fn say_references(&self, names: &[String]) {
        if self.references.is_empty() {
            return;
        }
        let mut frames: Vec<String> = self.references.iter().map(|r| r.0.to_string()).collect();
        frames.dedup();
        let reference = self.verifier.reference_samples().count();
        for name in names {
            let rows = || self.references.iter().filter(|r| &r.1 == name).map(|r| r.2);
            let label = if name.is_empty() {
                String::new()
            } else {
                format!(" {name}")
            };
            let heading = format!(
                "verify{label} (against a {reference}-spp reference, frames {})",
                frames.join(", ")
            );
            let full = format!("full render at {} spp:", self.run_samples.count());
            say!(
                "{heading}: {full:26} {}",
                error_summary(rows().map(|e| e.full))
            );
            let snapped = rows().any(|e| e.snapped_vs_keyed.is_some());
            say!(
                "{heading}: {:26} {}",
                if snapped {
                    "output (its snapped view):"
                } else {
                    "accelerated output:"
                },
                error_summary(rows().map(|e| e.output))
            );
            if snapped {
                say!(
                    "{heading}: {:26} {}",
                    "output (keyed camera):",
                    error_summary(rows().filter_map(|e| e.snapped_vs_keyed))
                );
            }
        }
    }
}

/// The run's verdict with `--verify`: exact frames equal their full
/// renders (or the run fails); approximate ones say their error.
fn say_verified(
    animator: &Animator,
    names: &[String],
    stats: &[retrace::frame_loop::FrameStats],
    failed_frames: &[(u32, (u64, u64))],
) -> Result<()> {
    if animator.has_viewports() {
        for name in names {
            let rows = stats.iter().filter(|s| &s.view == name);
            say!(
                "verify {name} (against its own rays): {}",
                error_summary(rows.filter_map(FrameStats::error))
            );
        }
        return Ok(());
    }
    if !failed_frames.is_empty() {
        let list: Vec<String> = failed_frames
            .iter()
            .map(|(f, (linear, written))| {
                format!("frame {f}: {linear} pixels ({written} in the image written)")
            })
            .collect();
        anyhow::bail!(
            "verification failed, frames differ from full renders: {}",
            list.join(", ")
        );
    }
    // Only a pan moves frames off the camera's own rays (snapped to the
    // lattice, or resampled); without one the two checks agree.
    let snapped = stats
        .iter()
        .any(retrace::frame_loop::FrameStats::off_keyed_view);
    if animator.is_exact() {
        let largest_snap_deg = stats
            .iter()
            .map(|s| {
                let (yaw, pitch) = s.snap_error_deg();
                yaw.abs().max(pitch.abs())
            })
            .fold(0.0, f64::max);
        let step_deg =
            retrace::reuse::pan::EqualAngleLattice::step_for(&animator.camera_at(0)).to_degrees();
        say!(
            "verify: every frame equals its full render bit for bit{}",
            if snapped {
                format!(
                    " (a pan: of the view snapped onto the lattice, at most {:.2} samples = {:.3} degrees off the keyed camera)",
                    largest_snap_deg / step_deg,
                    largest_snap_deg
                )
            } else {
                String::new()
            }
        );
    }
    if snapped || blends(animator) || !animator.is_exact() {
        say!(
            "verify ({}, against the camera's own unsnapped rays): {}",
            if !animator.is_exact() {
                "resampled"
            } else if blends(animator) {
                "blended"
            } else {
                "snapped"
            },
            error_summary(stats.iter().filter_map(FrameStats::error))
        );
    }
    Ok(())
}

/// Whether the run's pans blend between strata: exact frames, of the
/// keyed camera but not through its own rays.
fn blends(animator: &Animator) -> bool {
    animator.options().fractional_pan == retrace::reuse::pan::FractionalPan::BlendStrata
}

/// Worst and mean PSNR, largest and mean absolute error and share of
/// differing pixels over `errors`.
fn error_summary(errors: impl Iterator<Item = ImageError>) -> String {
    let errors: Vec<ImageError> = errors.collect();
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
         mean abs error {mean:.5}, {:.2}% of pixels differ by more than one 8-bit step",
        share * 100.0
    )
}
