//! RSVP's plan for a run: a scene whose output is its viewports keeps one
//! sample buffer around the eye, which follows the camera's pans and zooms
//! by itself.

use super::{render_direct_sampled, RsvpStore, SampleLattice};
use crate::render::Frame;
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
}
