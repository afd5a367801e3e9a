//! RSVP's plan for a run: a scene whose output is its viewports keeps one
//! sample buffer around the eye, which follows the camera's pans and zooms
//! by itself.

use super::{render_direct_sampled, RsvpStore, SampleLattice, ViewportRays};
use crate::render::{Frame, PrimaryRays};
use crate::reuse::{Run, SampleStore, Serve, StorePlan, View};
use crate::sampling::PixelSamples;
use crate::shade::{RayCounts, Shader};

/// Viewports, resampled from RSVP's buffer when rsvp is asked for.
pub struct RsvpPlan;

impl StorePlan for RsvpPlan {
    fn serves(&self, run: &Run, _frame: u32, _views: &[View]) -> Serve {
        if run.options.techniques.rsvp {
            Serve::Store
        } else {
            Serve::Full(None)
        }
    }

    /// A buffer around the eye of `views`, with the angle per sample of
    /// the scene's own camera whichever camera keys pose.
    fn new_store(&self, run: &Run, views: &[View]) -> Box<dyn SampleStore> {
        let columns = SampleLattice::for_camera(&run.scene.camera).columns_per_turn;
        let lattice = SampleLattice::new(views[0].pose.camera.position, columns);
        let mut store = RsvpStore::new(lattice, run.options.rsvp, run.scene.samples);
        store.set_memory_cap(run.options.sample_memory);
        Box::new(store)
    }

    /// A viewport traced directly, through its own rays: resampled
    /// viewports are measured against it, never equal to it.
    fn render_own_rays(
        &self,
        shader: &Shader,
        view: &View,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        render_direct_sampled(shader, &view.pose, samples)
    }

    fn exact(&self) -> bool {
        false
    }

    /// The samples the viewports read, at the density the knobs choose,
    /// rounded up to a power-of-two level (up to four times the samples:
    /// a zoom's frames read the levels on both sides of their density),
    /// over the levels a zoom passes through.
    fn store_bytes(&self, run: &Run, views: &[View]) -> f64 {
        let pixels: f64 = views
            .iter()
            .map(|view| f64::from(view.pose.camera.width) * f64::from(view.pose.camera.height))
            .sum();
        let knobs = &run.options.rsvp;
        let per_pixel =
            knobs.density_scale(run.scene.samples).powi(2) * knobs.samples_per_pixel() * 4.0;
        pixels * per_pixel * RSVP_BYTES_PER_SAMPLE
    }

    /// A viewport's own rays, as its direct render traces them.
    fn centre_rays<'v>(&self, view: &'v View) -> Box<dyn PrimaryRays + 'v> {
        Box::new(ViewportRays {
            pose: &view.pose,
            samples: PixelSamples::ONE,
        })
    }
}

/// A kept sample's colour, and the coarser levels a zoom leaves behind
/// (a third more).
const RSVP_BYTES_PER_SAMPLE: f64 = 12.0 * 4.0 / 3.0;
