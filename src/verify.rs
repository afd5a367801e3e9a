//! The one verifier: an accelerated frame against a full render of the
//! same frame, against the view's own rays, and against a converged
//! reference.
//!
//! `animate --verify`, the bench's check pass and the tests all check
//! through [`Verifier::check_view`], so "exact" and "error" mean one thing
//! everywhere.
//!
//! Promises:
//! - An exact frame ([`Animator::is_exact`]) is compared with a full render
//!   of the same frame both in linear colour and in the values written:
//!   8-bit bytes or, for an OpenEXR frame, its half floats and its
//!   arbitrary output variables but `traced` (the reuse mask, which a full
//!   render has all 1); where objects or lights move, also with a full
//!   render from a scene and accelerator built afresh, which shares
//!   nothing the frame loop posed.
//! - A snapped pan's output is measured against the reference of the view
//!   it shows and, besides, against the keyed camera's; any other output
//!   against the keyed view's.

use std::collections::HashMap;
use std::time::Instant;

use crate::accel::AccelError;
use crate::aov::{exr_picture, Aovs, TRACED_CHANNEL};
use crate::clock;
use crate::frame_loop::{Animator, FrameCheck, ViewOutput};
use crate::metrics::{
    count_byte_differences, count_differences, image_error, output_differences, reference_samples,
    ImageError, SizeMismatch,
};
use crate::render::Frame;
use crate::sampling::PixelSamples;

/// Why a check could not be made (not a failed check: that is a
/// [`ViewCheck`]'s finding).
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    #[error(transparent)]
    Size(#[from] SizeMismatch),
    #[error("building the afresh reference's accelerator: {0}")]
    Accel(#[from] AccelError),
    #[error(transparent)]
    Exr(#[from] crate::output::ExrMismatch),
}

/// A picture as written against one made independently of it (a
/// `retrace render` of the same view, a picture written earlier): the
/// pixels whose bytes differ. Used where only the written files are at
/// hand, as the viewer's pictures are.
pub fn written_differences(
    picture: &image::RgbImage,
    truth: &image::RgbImage,
) -> Result<u64, VerifyError> {
    Ok(count_byte_differences(picture, truth)?)
}

/// The pixels where `frame`'s OpenEXR picture differs from `truth`'s in
/// any channel but `traced`.
fn exr_differences(
    (frame, aovs): (&Frame, Option<&Aovs>),
    (truth, truth_aovs): (&Frame, Option<&Aovs>),
) -> Result<u64, VerifyError> {
    let written = exr_picture(frame, aovs);
    let expected = exr_picture(truth, truth_aovs);
    Ok(written.differing_pixels(&expected, &[TRACED_CHANNEL])?)
}

/// What to check of a view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Checks {
    /// Compare with a full render of the frame (an exact frame: bit for
    /// bit), timed.
    pub full: bool,
    /// Where objects or lights move, compare an exact frame also with a
    /// full render from a scene and accelerator built afresh.
    pub afresh: bool,
    /// Measure the error against the view's own, unsnapped rays.
    pub own_rays: bool,
    /// Measure the output and the full render at the run's samples
    /// against a converged reference.
    pub reference: bool,
    /// The frame is written as OpenEXR: what is written is its half
    /// floats and its AOVs, compared with the full render's in place of
    /// 8-bit bytes.
    pub exr: bool,
}

/// One view of one frame, checked.
#[derive(Clone, Debug, Default)]
pub struct ViewCheck {
    /// With [`Checks::full`]: what the frame was compared with (a full
    /// render where frames are exact, the view's own rays otherwise) and
    /// how long it took (its AOVs' too, where the frame has some).
    pub full: Option<(Frame, f64)>,
    /// With [`Checks::full`]: pixels differing from it, in linear colour
    /// (the larger count of the two full renders where the scene moves)
    /// and in what is written (the 8-bit image, or with [`Checks::exr`]
    /// the OpenEXR picture, the larger count where the scene moves).
    pub differing: Option<(u64, u64)>,
    /// With [`Checks::own_rays`]: the error against the view's own rays,
    /// and whether every pixel equals them.
    pub own_rays: Option<(ImageError, bool)>,
    pub reference: Option<ReferenceErrors>,
}

impl ViewCheck {
    /// Whether the frame is exact and equals its full render bit for bit
    /// (None: not compared).
    pub fn equal_to_full(&self) -> Option<bool> {
        self.differing.map(|d| d == (0, 0))
    }

    /// The check as the frame's statistics record it, with the regions
    /// that truly changed since the previous frame where they were
    /// counted; None without [`Checks::full`].
    pub fn frame_check(&self, changed_regions: Option<u64>) -> Option<FrameCheck> {
        let (_, full_ms) = self.full.as_ref()?;
        Some(FrameCheck {
            full_ms: *full_ms,
            differing_pixels: self.differing.map_or(0, |d| d.0),
            changed_regions,
            error: self.own_rays.map(|(error, _)| error),
        })
    }
}

/// One view of one frame against the converged reference.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceErrors {
    /// The full render of the keyed view at the run's samples.
    pub full: ImageError,
    /// The output, against the reference of the view it shows.
    pub output: ImageError,
    /// A snapped pan's output against the keyed camera's reference.
    pub snapped_vs_keyed: Option<ImageError>,
}

/// Which view of a frame a reference is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum ViewShown {
    /// The camera (or viewport) as keyed.
    Keyed,
    /// The view an exact frame shows: a pan's camera snapped onto the
    /// lattice.
    Snapped,
}

/// Converged references of a scene's views, by frame, view and whether
/// the view is the one a snapped pan shows: runs of the same scene,
/// samples and frames at other knobs (the tradeoff's settings) share
/// them, as a reference costs as much as 64 frames.
#[derive(Default)]
pub struct References(HashMap<(u32, usize, ViewShown), Frame>);

/// Checks views of a run's frames, keeping the converged references it
/// renders.
pub struct Verifier {
    reference_samples: PixelSamples,
    references: References,
}

impl Verifier {
    /// A verifier for a run at `samples` a pixel; its references are at
    /// [`reference_samples`] of those.
    pub fn new(samples: PixelSamples) -> Verifier {
        Verifier::with_references(samples, References::default())
    }

    /// As [`Verifier::new`], going on from `references` of the same scene,
    /// samples and frames.
    pub fn with_references(samples: PixelSamples, references: References) -> Verifier {
        Verifier {
            reference_samples: reference_samples(samples),
            references,
        }
    }

    /// The references rendered so far, for a later verifier of the same
    /// scene, samples and frames.
    pub fn into_references(self) -> References {
        self.references
    }

    pub fn reference_samples(&self) -> PixelSamples {
        self.reference_samples
    }

    /// Checks `output`, view `index` of `frame` as `animator` rendered it
    /// (with linear colour), as `checks` asks.
    pub fn check_view(
        &mut self,
        animator: &mut Animator,
        frame: u32,
        index: usize,
        output: &ViewOutput,
        checks: Checks,
    ) -> Result<ViewCheck, VerifyError> {
        let image = output
            .frame
            .as_ref()
            .expect("checking needs the frame in linear colour (Options::linear)");
        let exact = animator.is_exact();
        let mut check = ViewCheck::default();
        if checks.full {
            let start = Instant::now();
            let (full, _) = animator.render_reference(frame, index);
            let aovs = output.aovs.as_ref();
            let full_aovs = aovs.map(|a| animator.render_aovs(frame, index, a.set));
            let full_ms = clock::ms(start.elapsed());
            let (mut linear, mut written) = if checks.exr {
                let written = exr_differences((image, aovs), (&full, full_aovs.as_ref()))?;
                (count_differences(image, &full)?, written)
            } else {
                output_differences(image, &output.image, &full)?
            };
            let moves = animator.animation().is_some_and(|a| a.moves_scene());
            if checks.afresh && exact && moves {
                let set = aovs
                    .filter(|_| checks.exr)
                    .map(|a| a.set)
                    .unwrap_or_default();
                let (afresh, _, afresh_aovs) =
                    animator.render_full_afresh_with_aovs(frame, index, set)?;
                linear = linear.max(count_differences(image, &afresh)?);
                if checks.exr {
                    let differing =
                        exr_differences((image, aovs), (&afresh, afresh_aovs.as_ref()))?;
                    written = written.max(differing);
                }
            }
            check.differing = Some((linear, written));
            check.full = Some((full, full_ms));
        }
        let own_rays = match &check.full {
            // Where frames are not exact, the full render is of their own
            // rays.
            Some((full, _)) if !exact => Some(full.clone()),
            _ if checks.own_rays || checks.reference => {
                Some(animator.render_own_rays(frame, index, None).0)
            }
            _ => None,
        };
        if let (true, Some(truth)) = (checks.own_rays, &own_rays) {
            let identical = count_differences(image, truth)? == 0;
            check.own_rays = Some((image_error(image, truth)?, identical));
        }
        if let (true, Some(truth)) = (checks.reference, &own_rays) {
            let snapped = exact && output.stats.off_keyed_view();
            check.reference =
                Some(self.against_reference(animator, frame, index, image, truth, snapped)?);
        }
        Ok(check)
    }

    /// `image` and `full` (the view's own rays at the run's samples)
    /// against the converged reference.
    fn against_reference(
        &mut self,
        animator: &mut Animator,
        frame: u32,
        index: usize,
        image: &Frame,
        full: &Frame,
        snapped: bool,
    ) -> Result<ReferenceErrors, VerifyError> {
        let samples = Some(self.reference_samples);
        let keyed = self
            .references
            .0
            .entry((frame, index, ViewShown::Keyed))
            .or_insert_with(|| animator.render_own_rays(frame, index, samples).0);
        let full = image_error(full, keyed)?;
        if !snapped {
            return Ok(ReferenceErrors {
                full,
                output: image_error(image, keyed)?,
                snapped_vs_keyed: None,
            });
        }
        // A snapped pan's frame is an exact render of the camera moved onto
        // the lattice: measured against that view's reference, and against
        // the keyed camera's besides.
        let snapped_vs_keyed = Some(image_error(image, keyed)?);
        let shown = self
            .references
            .0
            .entry((frame, index, ViewShown::Snapped))
            .or_insert_with(|| animator.render_full(frame, index, samples).0);
        Ok(ReferenceErrors {
            full,
            output: image_error(image, shown)?,
            snapped_vs_keyed,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accelerator, BackendKind};
    use crate::frame_loop::{Options, Techniques};
    use crate::scene::{paper_scene, SceneOverrides};
    use glam::Vec3;

    /// The paper scene at 64x48, and its accelerator.
    fn small_paper_scene() -> (crate::scene::Scene, Accelerator) {
        let scene = paper_scene(&SceneOverrides {
            width: Some(64),
            height: Some(48),
            ..SceneOverrides::default()
        })
        .unwrap();
        let accel = Accelerator::build(BackendKind::Embree, &scene.objects).unwrap();
        (scene, accel)
    }

    #[test]
    fn a_changed_pixel_is_found_in_linear_colour_and_in_the_bytes_written() {
        let (scene, mut accel) = small_paper_scene();
        let mut animator = Animator::new(&scene, &mut accel, Options::new(Techniques::AUTO, 0..1));
        let mut output = animator.render(0).remove(0);
        let checks = Checks {
            full: true,
            afresh: true,
            own_rays: true,
            reference: false,
            exr: false,
        };
        let mut verifier = Verifier::new(scene.samples);
        let check = verifier
            .check_view(&mut animator, 0, 0, &output, checks)
            .unwrap();
        assert_eq!(check.differing, Some((0, 0)));
        assert_eq!(check.equal_to_full(), Some(true));
        assert!(check.own_rays.is_some_and(|(_, identical)| identical));

        // A change too small for 8 bits shows in linear colour only.
        let kept = output.frame.as_ref().unwrap().pixels[5];
        output.frame.as_mut().unwrap().pixels[5] = kept + Vec3::splat(1e-6);
        let check = verifier
            .check_view(&mut animator, 0, 0, &output, checks)
            .unwrap();
        assert_eq!(check.differing, Some((1, 0)));
        assert_eq!(check.equal_to_full(), Some(false));
        // And one byte written, with the linear colour right.
        output.frame.as_mut().unwrap().pixels[5] = kept;
        output.image.get_pixel_mut(7, 3).0[1] ^= 0x10;
        let check = verifier
            .check_view(&mut animator, 0, 0, &output, checks)
            .unwrap();
        assert_eq!(check.differing, Some((0, 1)));
    }

    #[test]
    fn an_exr_frame_is_compared_in_its_half_floats_and_aovs_but_traced() {
        let (scene, mut accel) = small_paper_scene();
        let options = Options {
            aovs: crate::aov::AovSet::parse("depth,normal,albedo,object,traced").unwrap(),
            ..Options::new(Techniques::AUTO, 0..1)
        };
        let mut animator = Animator::new(&scene, &mut accel, options);
        let mut output = animator.render(0).remove(0);
        let checks = Checks {
            full: true,
            exr: true,
            ..Checks::default()
        };
        let mut verifier = Verifier::new(scene.samples);
        let mut check = |output: &ViewOutput| {
            verifier
                .check_view(&mut animator, 0, 0, output, checks)
                .unwrap()
                .differing
        };
        assert_eq!(check(&output), Some((0, 0)));
        // The 8-bit picture is not what an EXR frame writes.
        output.image.get_pixel_mut(7, 3).0[1] ^= 0x10;
        assert_eq!(check(&output), Some((0, 0)));
        // Nor is a change within half precision.
        let kept = output.frame.as_ref().unwrap().pixels[5];
        output.frame.as_mut().unwrap().pixels[5] = kept * (1.0 + 1e-6);
        assert_eq!(check(&output), Some((1, 0)));
        output.frame.as_mut().unwrap().pixels[5] = kept * 1.01;
        assert_eq!(check(&output), Some((1, 1)));
        output.frame.as_mut().unwrap().pixels[5] = kept;
        // Every AOV but the reuse mask is compared.
        let aovs = output.aovs.as_mut().unwrap();
        aovs.traced[9] = !aovs.traced[9];
        assert_eq!(check(&output), Some((0, 0)));
        let hit = output.aovs.as_mut().unwrap().first_hits[40 * 64 + 10]
            .as_mut()
            .expect("the ground at the bottom of the picture");
        hit.distance *= 1.01;
        assert_eq!(check(&output), Some((0, 1)));
    }
}
