//! Panimation's plan for a run: whether the camera's frames live on the pan
//! lattice, how many of its rows the run's views reach, and what a frame
//! on it is compared with.
//!
//! Promises: whether frames live on the lattice is decided over the whole
//! timeline, never the frames of one run, so a chunk of a render farm's
//! run equals the same frames of one long run; a full render of a frame
//! on the lattice is traced through the lattice's rays, so a snapped pan
//! equals it bit for bit.

use std::collections::HashMap;

use super::{EqualAngleLattice, FractionalPan, PanStore};
use crate::camera::{Camera, Projection, RayTable};
use crate::render::{Frame, PrimaryRays, Shifted};
use crate::reuse::lattice_buffer::{render_window, Window, STRATA_LIMIT_BYTES};
use crate::reuse::{FullReason, Idle, Run, SampleStore, Serve, StorePlan, View};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};

/// The most memory a pan buffer may take. A narrow equal-angle view keeps
/// a whole turn of its fine samples (E1's: 17 MB; 0.1 degrees over 640 px:
/// 17 GB): beyond this, frames are rendered in full, with the reason.
pub const PAN_BUFFER_LIMIT_BYTES: f64 = 2e9;

/// A run whose equal-angle camera turns, with a pan buffer that fits: its
/// frames live on the pan lattice (with pan off too, so that they equal
/// full renders, which are taken there).
pub struct PanPlan {
    facts: TimelineFacts,
    fractional: FractionalPan,
    /// Strata a cell along each axis a snapped view snaps to: the side of
    /// the run's square count where the buffer keeps its strata for every
    /// view of the timeline, else 1 (whole samples).
    snap_side: i64,
}

impl PanPlan {
    /// The plan for `run`, or why the camera's frames do not live on the
    /// lattice: a reason to render in full where pan was asked for and
    /// cannot act (None: nothing pan-specific stops a still camera's store).
    pub fn new(run: &Run) -> Result<PanPlan, Option<FullReason>> {
        let facts = TimelineFacts::for_run(run);
        let camera = &run.scene.camera;
        if facts.on_lattice(camera) {
            let fractional = run.options.fractional_pan;
            let side = i64::from(run.scene.samples.grid_side());
            let strata_fit = facts.strata_bytes(side) <= STRATA_LIMIT_BYTES;
            let on_strata = matches!(fractional, FractionalPan::Snap | FractionalPan::BlendStrata);
            let snap_side = if on_strata && side > 1 && strata_fit {
                side
            } else {
                1
            };
            return Ok(PanPlan {
                facts,
                fractional,
                snap_side,
            });
        }
        let techniques = run.options.techniques;
        let equal_angle = camera.projection == Projection::EqualAngle;
        if techniques.pan && equal_angle && facts.camera_moves {
            return Err(Some(FullReason::PanBufferTooLarge {
                bytes: facts.pan_buffer_bytes,
            }));
        }
        if techniques.pan && !equal_angle && !techniques.ostc {
            return Err(Some(FullReason::PanNeedsEqualAngle(camera.projection)));
        }
        Err(None)
    }

    /// Why pan cannot act on `run`, whether asked for or not.
    pub fn idle_reason(run: &Run) -> Option<Idle> {
        if run.has_viewports() {
            return Some(Idle::ViewportsPanThemselves);
        }
        let facts = TimelineFacts::of(run.scene, &run.options.frames);
        // Keys move the camera; its projection stays the scene's.
        let camera = &run.scene.camera;
        if !facts.camera_moves {
            Some(Idle::CameraStill)
        } else if camera.projection != Projection::EqualAngle {
            Some(Idle::NotEqualAngle(camera.projection))
        } else {
            (!facts.on_lattice(camera)).then_some(Idle::Full(FullReason::PanBufferTooLarge {
                bytes: facts.pan_buffer_bytes,
            }))
        }
    }
}

impl StorePlan for PanPlan {
    fn serves(&self, run: &Run, frame: u32, views: &[View]) -> Serve {
        let techniques = run.options.techniques;
        if !techniques.buffered() {
            return Serve::Full(None);
        }
        // Without panning the buffer holds only while the camera stands
        // still; a viewer's store says by itself whether it fits.
        if techniques.pan || run.interactive || run.camera_still_at(frame, &views[0].pose.camera) {
            Serve::Store
        } else {
            Serve::Full(Some(FullReason::CameraMovesPanOff))
        }
    }

    /// The pan lattice sized for every window of this run that shares it.
    fn new_store(&self, run: &Run, views: &[View]) -> Box<dyn SampleStore> {
        let camera = &views[0].pose.camera;
        let window = EqualAngleLattice::for_camera(camera).window(camera);
        let (mut low, mut high) = (window.row, window.row + i64::from(window.height));
        if let Some(&(top, bottom)) = self.facts.row_spans.get(&lattice_key(camera)) {
            (low, high) = (low.min(top), high.max(bottom));
        }
        // A resampled view reads up to one row more on either side.
        Box::new(PanStore::new(
            camera,
            low - 1..high + 1,
            self.fractional,
            self.snap_side,
            run.options.techniques.pan,
            run.scene.samples,
            // Strata serve OSTC alone (it re-traces groups of them).
            run.ostc_keeps(),
        ))
    }

    fn render_full(
        &self,
        shader: &Shader,
        view: &View,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        let camera = &view.pose.camera;
        let shown = self.shown_window(camera);
        let lattice = EqualAngleLattice::for_camera_sampled(camera, samples);
        let side = i64::from(samples.grid_side().max(1));
        if side == self.snap_side {
            return render_window(shader, &lattice, &shown);
        }
        // At other samples a pixel (a converged reference's), a snapped
        // corner in their strata, where they are as fine; else the shown
        // camera's own rays.
        let (x, y) = shown.strata_offset;
        if shown.blend == (0.0, 0.0)
            && (shown.strata_offset == (0, 0) || side % self.snap_side == 0)
        {
            let scale = side / self.snap_side;
            let window = Window {
                strata_offset: (x * scale, y * scale),
                strata_side: if shown.strata_offset == (0, 0) {
                    1
                } else {
                    side
                },
                ..shown
            };
            return render_window(shader, &lattice, &window);
        }
        crate::render::render_camera(shader, &shown_camera(camera, &shown), samples)
    }

    fn exact(&self) -> bool {
        self.fractional.exact()
    }

    fn store_bytes(&self, run: &Run, views: &[View]) -> f64 {
        let camera = &views[0].pose.camera;
        let pixels = f64::from(camera.width) * f64::from(camera.height);
        // The buffer covers every row the timeline's views reach.
        self.facts
            .pan_buffer_bytes
            .max(EqualAngleLattice::buffer_bytes(
                camera,
                i64::from(camera.height),
            ))
            + if self.snap_side > 1 {
                // The strata, and the pixels resolved between cells from
                // them (a linear colour, its bytes and a flag a cell).
                let resolved = std::mem::size_of::<[f32; 3]>() + 3 + 1;
                self.facts.strata_bytes(self.snap_side)
                    + self.facts.pan_buffer_samples * resolved as f64
            } else {
                crate::reuse::strata_bytes(run, pixels)
            }
    }

    /// A snapped pan shows the lattice's window; a resampled one, the
    /// camera's own view.
    fn centre_rays<'v>(&self, view: &'v View) -> Box<dyn PrimaryRays + 'v> {
        let camera = &view.pose.camera;
        if !self.exact() {
            return Box::new(RayTable::new(camera));
        }
        let window = self.shown_window(camera);
        if !window.on_whole_cells() {
            return Box::new(RayTable::new(&shown_camera(camera, &window)));
        }
        Box::new(Shifted {
            source: EqualAngleLattice::for_camera(camera),
            col: window.col,
            row: window.row,
            width: window.width,
            height: window.height,
        })
    }
}

impl PanPlan {
    /// Where a snapped frame of `camera` sits on its lattice.
    fn shown_window(&self, camera: &Camera) -> Window {
        let lattice = EqualAngleLattice::for_camera(camera);
        lattice.shown_window(camera, self.fractional, self.snap_side)
    }
}

/// `camera` turned onto the view `window` shows.
fn shown_camera(camera: &Camera, window: &Window) -> Camera {
    Camera {
        yaw: camera.yaw + window.yaw_error,
        pitch: camera.pitch + window.pitch_error,
        ..camera.clone()
    }
}

/// What the timeline allows the pan lattice, found once for a run.
struct TimelineFacts {
    /// Whether the camera changes at all over the timeline.
    camera_moves: bool,
    /// The most a pan buffer of this timeline's views could take, in bytes.
    pan_buffer_bytes: f64,
    /// The most samples (cells) such a buffer could hold.
    pan_buffer_samples: f64,
    /// Per pan lattice (see [`lattice_key`]), the rows the run's views of
    /// it cover.
    row_spans: HashMap<LatticeKey, (i64, i64)>,
}

impl TimelineFacts {
    fn for_run(run: &Run) -> TimelineFacts {
        let mut facts = TimelineFacts::of(run.scene, &run.options.frames);
        if run.interactive {
            facts.free_camera(run.scene);
        }
        facts
    }

    /// The facts for a camera that may turn anywhere at any frame: it
    /// moves, and the views of each pan lattice may reach every row.
    fn free_camera(&mut self, scene: &Scene) {
        self.camera_moves = true;
        let mut cameras = vec![scene.camera.clone()];
        if let Some(animation) = &scene.animation {
            cameras.extend((0..animation.frames).map(|f| animation.camera_at(&scene.camera, f)));
        }
        for camera in cameras {
            if camera.projection != Projection::EqualAngle {
                continue;
            }
            let rows = EqualAngleLattice::rows_for(&camera);
            self.row_spans.insert(lattice_key(&camera), (0, rows));
            // Resampling reads a row more on either side.
            self.pan_buffer_bytes = self
                .pan_buffer_bytes
                .max(EqualAngleLattice::buffer_bytes(&camera, rows + 2));
            self.pan_buffer_samples = self
                .pan_buffer_samples
                .max(EqualAngleLattice::buffer_samples(&camera, rows + 2));
        }
    }

    /// Whether a full render of `camera` is taken on the pan lattice, so
    /// that a pan (by any run of this timeline) compares with it bit for
    /// bit: equal-angle cameras of a timeline that moves the camera.
    fn on_lattice(&self, camera: &Camera) -> bool {
        camera.projection == Projection::EqualAngle
            && self.camera_moves
            && self.pan_buffer_bytes <= PAN_BUFFER_LIMIT_BYTES
    }

    /// The most bytes the strata of a pan buffer of this timeline's views
    /// could take at `side` x `side` strata a cell, as
    /// [`crate::reuse::lattice_buffer::LatticeBuffer::new`] counts them (a
    /// band of rows spare).
    fn strata_bytes(&self, side: i64) -> f64 {
        let strata = (side * side) as f64;
        (self.pan_buffer_samples * strata) * std::mem::size_of::<[f32; 3]>() as f64
    }

    fn of(scene: &Scene, run: &std::ops::Range<u32>) -> TimelineFacts {
        let mut facts = TimelineFacts {
            camera_moves: false,
            pan_buffer_bytes: 0.0,
            pan_buffer_samples: 0.0,
            row_spans: HashMap::new(),
        };
        let camera_at = |frame| match &scene.animation {
            Some(animation) => animation.camera_at(&scene.camera, frame),
            None => scene.camera.clone(),
        };
        // Over the whole timeline, not just this run: whether frames live on
        // the lattice must not depend on which frames a run renders, or a
        // chunk of a render farm's run would differ from one long run.
        let timeline = scene.animation.as_ref().map_or(0..0, |a| 0..a.frames);
        let first = camera_at(0);
        // The rows every equal-angle view reaches, top and bottom.
        let (mut top, mut bottom) = (i64::MAX, i64::MIN);
        for frame in timeline.chain(run.clone()) {
            let camera = camera_at(frame);
            facts.camera_moves |= camera != first;
            if camera.projection != Projection::EqualAngle {
                continue;
            }
            let seen = EqualAngleLattice::rows_seen(&camera);
            (top, bottom) = (top.min(seen.start), bottom.max(seen.end));
            // Resampling reads a row more on either side.
            let span = bottom.saturating_sub(top).saturating_add(2);
            facts.pan_buffer_bytes = facts
                .pan_buffer_bytes
                .max(EqualAngleLattice::buffer_bytes(&camera, span));
            facts.pan_buffer_samples = facts
                .pan_buffer_samples
                .max(EqualAngleLattice::buffer_samples(&camera, span));
            // Each lattice's rows, found once here rather than at every
            // restart (an eye that moves every frame restarts every frame).
            if run.contains(&frame) {
                let span = facts
                    .row_spans
                    .entry(lattice_key(&camera))
                    .or_insert((seen.start, seen.end));
                *span = (span.0.min(seen.start), span.1.max(seen.end));
            }
        }
        facts
    }
}

/// Which pan lattice an equal-angle camera's views live on: its eye (to
/// the bit) and its columns per turn, as [`EqualAngleLattice::fits`] tells.
type LatticeKey = ([u64; 3], i64);

fn lattice_key(camera: &Camera) -> LatticeKey {
    (
        // + 0.0: -0.0 and 0.0 are one eye, as `fits` compares them.
        camera.position.to_array().map(|c| (c + 0.0).to_bits()),
        EqualAngleLattice::columns_per_turn_for(camera),
    )
}
