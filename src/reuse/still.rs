//! A still camera's own image as a sample store: any projection, held
//! still, keeps its samples so OSTC can re-trace only what moving objects
//! and lights change.
//!
//! Promises: the samples are the camera's own pixels (or their strata),
//! traced in exactly the packets a full render of the camera uses, so a
//! frame equals a full render bit for bit.

use crate::camera::{Projection, RayTable, ViewportPose};
use crate::render::{SampleGroup, GROUP_HEIGHT, GROUP_WIDTH};
use crate::reuse::lattice_buffer::{Lattice, LatticeBuffer, Window};
use crate::reuse::ostc::Ostc;
use crate::reuse::regions::{RegionGrid, RegionLayout};
use crate::reuse::{
    Dirty, FrameMode, FullReason, Run, SampleStore, Serve, StoreFrame, StorePlan, Unfit, View,
    Wanted,
};
use crate::sampling::PixelSamples;
use crate::shade::Shader;

/// A fixed camera's own pixels as a lattice (its image, padded to whole
/// groups, repeating past its width), traced in exactly the groups a full
/// render uses.
impl Lattice for RayTable {
    fn period(&self) -> i64 {
        let gw = i64::from(GROUP_WIDTH);
        (i64::from(self.size().0) + gw - 1) / gw * gw
    }
    fn rows(&self) -> i64 {
        let gh = i64::from(GROUP_HEIGHT);
        (i64::from(self.size().1) + gh - 1) / gh * gh
    }
}

/// The window of a fixed camera's lattice: its whole image.
fn image_window(table: &RayTable) -> Window {
    let (width, height) = table.size();
    Window::on_cells(0, 0, width, height)
}

/// A run whose camera's frames do not live on the pan lattice: a still
/// camera's own image serves the frames where the camera stands still.
pub struct StillPlan {
    /// Why pan, asked for, cannot act: every frame is then rendered in
    /// full.
    pan_refusal: Option<FullReason>,
}

impl StillPlan {
    pub fn new(pan_refusal: Option<FullReason>) -> StillPlan {
        StillPlan { pan_refusal }
    }
}

impl StorePlan for StillPlan {
    fn serves(&self, run: &Run, frame: u32, views: &[View]) -> Serve {
        if !run.options.techniques.buffered() {
            return Serve::Full(None);
        }
        if let Some(reason) = self.pan_refusal {
            return Serve::Full(Some(reason));
        }
        let camera = &views[0].pose.camera;
        // A viewer's store says by itself whether it fits the camera.
        if run.interactive || run.camera_still_at(frame, camera) {
            return Serve::Store;
        }
        if !run.eye_still_at(frame, camera) {
            return Serve::Full(Some(FullReason::EyeMoves));
        }
        Serve::Full(Some(match camera.projection {
            Projection::EqualAngle => FullReason::CameraMovesPanOff,
            projection => FullReason::CameraMovesNotEqualAngle(projection),
        }))
    }

    fn new_store(&self, run: &Run, views: &[View]) -> Box<dyn SampleStore> {
        Box::new(StillStore::new(
            &views[0].pose.camera,
            run.scene.samples,
            // Strata serve OSTC alone (it re-traces groups of them).
            run.ostc_keeps(),
        ))
    }

    fn exact(&self) -> bool {
        true
    }

    fn store_bytes(&self, run: &Run, views: &[View]) -> f64 {
        let camera = &views[0].pose.camera;
        let pixels = f64::from(camera.width) * f64::from(camera.height);
        // A colour and a traced flag a sample, and an OSTC marker a group.
        pixels * (std::mem::size_of::<glam::Vec3>() + 4) as f64
            + crate::reuse::strata_bytes(run, pixels)
    }
}

/// A still camera's samples.
pub struct StillStore {
    buffer: LatticeBuffer<RayTable>,
    /// The groups the last render traced.
    traced: Vec<SampleGroup>,
}

impl StillStore {
    /// The samples of `camera`'s image, keeping a square count's strata
    /// when `keep_strata` is set (see [`LatticeBuffer::new`]).
    pub fn new(
        camera: &crate::camera::Camera,
        samples: PixelSamples,
        keep_strata: bool,
    ) -> StillStore {
        let table = RayTable::with_samples(camera, samples);
        let rows = table.rows();
        StillStore {
            buffer: LatticeBuffer::new(table, 0..rows, keep_strata),
            traced: Vec::new(),
        }
    }
}

impl SampleStore for StillStore {
    fn name(&self) -> &'static str {
        "buffer"
    }

    fn mode(&self, ostc: bool) -> FrameMode {
        if ostc {
            FrameMode::Ostc
        } else {
            FrameMode::Still
        }
    }

    fn unfit(&self, views: &[ViewportPose]) -> Option<Unfit> {
        let camera = &views.first()?.camera;
        let own = self.buffer.lattice().camera();
        if own.position != camera.position {
            return Some(Unfit::EyeMoved);
        }
        (own != camera).then_some(Unfit::CameraMoved(own.projection))
    }

    fn ostc_regions(&self, grid: Option<RegionGrid>, camera: (u32, u32)) -> RegionLayout {
        self.buffer.ostc_regions(grid, camera)
    }

    fn erase(&mut self, dirty: &Dirty) -> u64 {
        debug_assert!(dirty.groups.is_empty(), "the buffer erases whole regions");
        self.buffer.erase(dirty.layout, dirty.regions)
    }

    fn render(
        &mut self,
        shader: &Shader,
        _views: &[ViewportPose],
        ostc: Option<&Ostc>,
        wanted: Wanted,
    ) -> Vec<StoreFrame> {
        let window = image_window(self.buffer.lattice());
        let (made, traced) = self.buffer.frame(shader, &window, wanted.linear, ostc);
        self.traced = traced;
        vec![made]
    }

    fn paint_traced(
        &self,
        _index: usize,
        _view: &ViewportPose,
        image: &image::RgbImage,
    ) -> image::RgbImage {
        let mut painted = image.clone();
        let window = image_window(self.buffer.lattice());
        self.buffer
            .paint_groups(&window, &self.traced, &mut painted);
        painted
    }
}
