//! The frame loop: the one place that decides what a frame must trace.
//!
//! A frame's output is its views: the camera's own image (a trivial
//! viewport: the identity transform over the camera's own projection), or
//! the scene's RSVP viewports. For each frame the loop poses the scene,
//! decides whether its views may come from a sample store
//! ([`crate::reuse::SampleStore`]) and whether the kept store can serve
//! them or must start again (and why), erases from it what OSTC says the
//! scene's changes dirtied ([`changes`]), and renders the views through
//! it; a frame that may not reuse is rendered in full.
//!
//! Promises:
//! - Every frame's state comes from its frame number and the timeline,
//!   never from the previous frame, and whether frames live on the pan
//!   lattice is decided over the whole timeline: a chunk of frames equals
//!   the same frames of one long run.
//! - A camera frame from a store equals [`Animator::render_full`] of the
//!   same frame bit for bit (a snapped pan: of the snapped view); RSVP's
//!   buffer samples equal a fresh trace, its viewports are measured
//!   against their own rays.

mod abandon;
mod changes;
mod options;
mod stats;

pub use changes::{swept_bounds, OSTC_LIMIT_BYTES};
pub use options::{Options, OstcSettings, Technique, Techniques};
pub use stats::{FrameStats, FullReason, Reason, Restart};

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use glam::Affine3A;

use crate::accel::{Accelerator, Intersector};
use crate::camera::{Camera, Projection, ViewTransform, ViewportPose};
use crate::geometry::Placement;
use crate::pool::with_workers_awake;
use crate::render::{render_view_sampled, Frame};
use crate::reuse::lattice_buffer::{cells_traced, render_window};
use crate::reuse::ostc::Ostc;
use crate::reuse::pan::{EqualAngleLattice, FractionalPan, PanStore};
use crate::reuse::rsvp::{render_direct_sampled, RsvpStore, SampleLattice};
use crate::reuse::still::StillStore;
use crate::reuse::{FrameMode, SampleStore, Wanted};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};
use crate::timeline::Animation;
use abandon::Abandonable;
use changes::{build_ostc, invalidate, Invalidation, ScenePose};

/// The most memory a pan buffer may take. A narrow equal-angle view keeps
/// a whole turn of its fine samples (E1's: 17 MB; 0.1 degrees over 640 px:
/// 17 GB): beyond this, frames are rendered in full, with the reason.
pub const PAN_BUFFER_LIMIT_BYTES: f64 = 2e9;

/// One output picture of a frame: the camera's image (named "") or an RSVP
/// viewport.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    pub name: String,
    pub pose: ViewportPose,
}

/// One view's picture of a frame, and what it cost.
pub struct ViewOutput {
    pub name: String,
    /// Linear colour, when [`Options::linear`] asks for it.
    pub frame: Option<Frame>,
    pub image: image::RgbImage,
    pub stats: FrameStats,
    /// The picture with every pixel black whose samples the frame traced,
    /// when [`Options::traced_images`] asks for it (a full render: all
    /// black).
    pub traced_image: Option<image::RgbImage>,
}

/// What the timeline allows, found once for a run.
struct TimelineFacts {
    /// Whether the camera changes at all over the timeline.
    camera_moves: bool,
    /// The most a pan buffer of this timeline's views could take, in bytes.
    pan_buffer_bytes: f64,
    /// Per pan lattice (see [`lattice_key`]), the rows the run's views of
    /// it cover.
    row_spans: HashMap<LatticeKey, (i64, i64)>,
}

/// The samples kept from earlier frames and what goes with them.
struct Kept {
    store: Box<dyn SampleStore>,
    /// Bookkeeping, when OSTC is on and something in the scene moves.
    ostc: Option<Ostc>,
    /// The scene as it was when the store's samples were traced.
    pose: ScenePose,
}

/// An animator's kept samples and bookkeeping, taken out of it
/// ([`Animator::into_kept`]) for a later animator of the same scene and
/// options to go on from ([`Animator::resume`]): an interactive viewer
/// switching between kinds of view, one animator at a time.
pub struct KeptSamples(Kept);

/// Renders the frames of one animation, reusing what it may.
pub struct Animator<'a> {
    /// The scene as loaded.
    base: &'a Scene,
    /// The scene posed at `posed_frame`: animated objects and lights moved.
    scene: Scene,
    posed_frame: Option<u32>,
    accel: &'a mut Accelerator,
    options: Options,
    facts: TimelineFacts,
    kept: Option<Kept>,
    /// Why OSTC, asked for, could not be kept.
    ostc_refusal: Option<String>,
    /// Whether the views come from the caller ([`Animator::render_views`]),
    /// not from the timeline alone.
    interactive: bool,
}

impl<'a> Animator<'a> {
    pub fn new(scene: &'a Scene, accel: &'a mut Accelerator, options: Options) -> Animator<'a> {
        let facts = TimelineFacts::of(scene, &options.frames);
        Animator {
            base: scene,
            scene: scene.clone(),
            posed_frame: None,
            accel,
            options,
            facts,
            kept: None,
            ostc_refusal: None,
            interactive: false,
        }
    }

    /// An animator for views no timeline knows in advance (an interactive
    /// viewer's, given to [`Animator::render_views`]): the scene's objects
    /// and lights still follow the timeline, but the camera may turn
    /// anywhere at any frame, so an equal-angle camera's frames live on the
    /// pan lattice from the first, and its pan buffer holds every row of
    /// the lattice, pole to pole.
    pub fn interactive(
        scene: &'a Scene,
        accel: &'a mut Accelerator,
        options: Options,
    ) -> Animator<'a> {
        let mut animator = Animator::new(scene, accel, options);
        animator.facts.free_camera(scene);
        animator.interactive = true;
        animator
    }

    pub fn options(&self) -> &Options {
        &self.options
    }

    /// What this animator keeps for its next frame (None when it keeps
    /// nothing: reuse off, or nothing rendered yet).
    pub fn into_kept(self) -> Option<KeptSamples> {
        self.kept.map(KeptSamples)
    }

    /// Goes on from `kept`, which an animator of this scene with these
    /// options kept. Its samples stay exact: the next frame checks them
    /// against the views and the scene's pose as it checks its own (a
    /// store unfit for the views starts afresh; objects that moved since
    /// re-trace through OSTC), and the first pose places every animated
    /// object in the accelerator.
    pub fn resume(&mut self, kept: KeptSamples) {
        self.kept = Some(kept.0);
    }

    pub fn animation(&self) -> Option<&'a Animation> {
        self.base.animation.as_ref()
    }

    /// Whether the frame's views are RSVP viewports rather than the
    /// camera's image.
    pub fn has_viewports(&self) -> bool {
        !self.base.viewports.is_empty()
    }

    pub fn camera_at(&self, frame: u32) -> Camera {
        match self.animation() {
            Some(animation) => animation.camera_at(&self.base.camera, frame),
            None => self.base.camera.clone(),
        }
    }

    /// The views of `frame`: every viewport, or the camera's own image.
    pub fn views(&self, frame: u32) -> Vec<View> {
        let camera = self.camera_at(frame);
        if !self.has_viewports() {
            return vec![View {
                name: String::new(),
                pose: ViewportPose::new(camera, ViewTransform::default()),
            }];
        }
        self.base
            .viewports
            .iter()
            .map(|track| View {
                name: track.viewport.name.clone(),
                pose: track.pose_at(&camera, frame),
            })
            .collect()
    }

    /// Moves the scene's animated objects and lights to `frame`.
    fn pose(&mut self, frame: u32) {
        if self.posed_frame == Some(frame) {
            return;
        }
        if let Some(animation) = self.animation() {
            let moved = animation.pose(&mut self.scene.objects, &mut self.scene.lights, frame);
            // The accelerator may be shared with another animator that left
            // it elsewhere: the first pose sets every animated object.
            let moved = match self.posed_frame {
                Some(_) => moved,
                None => animation
                    .objects
                    .iter()
                    .flat_map(|track| track.objects.iter().copied())
                    .collect(),
            };
            let moves: Vec<(u32, Affine3A)> = moved
                .into_iter()
                .map(|object| match self.scene.objects[object].placement {
                    Placement::Instance(transform) => (object as u32, transform),
                    Placement::World => unreachable!("animated objects are instances"),
                })
                .collect();
            self.accel
                .move_objects(&moves)
                .unwrap_or_else(|err| panic!("moving objects: {err}"));
        }
        self.posed_frame = Some(frame);
    }

    /// The scene posed at `frame` and the accelerator holding it.
    pub fn posed_scene(&mut self, frame: u32) -> (&Scene, &Accelerator) {
        self.pose(frame);
        (&self.scene, self.accel)
    }

    /// The scene posed at `frame`, ready to trace, and the camera there:
    /// for untimed passes that need the shading itself (the bench's ray
    /// costs).
    pub fn posed_shader(&mut self, frame: u32) -> (Shader<'_>, Camera) {
        self.pose(frame);
        let camera = self.camera_at(frame);
        (Shader::new(&self.scene, self.accel), camera)
    }

    /// Whether a full render of `camera` is taken on the pan lattice, so
    /// that a pan (by any animator of this timeline) compares with it bit
    /// for bit: equal-angle cameras of a timeline that moves the camera.
    fn on_lattice(&self, camera: &Camera) -> bool {
        self.facts.on_lattice(camera)
    }

    /// View `index` of `frame` rendered from scratch, as the reference for
    /// reuse: a viewport through its own rays; the camera's image on the
    /// pan lattice when the timeline pans it (so a snapped pan compares
    /// exactly), through the camera's own rays otherwise.
    pub fn render_full(&mut self, frame: u32, index: usize) -> (Frame, RayCounts) {
        self.render_full_sampled(frame, index, self.scene.samples)
    }

    /// As [`Animator::render_full`] at `samples` a pixel rather than the
    /// scene's: a converged reference of the view an exact frame shows (a
    /// snapped pan's view, not the keyed camera's).
    pub fn render_full_sampled(
        &mut self,
        frame: u32,
        index: usize,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        self.pose(frame);
        let view = self.views(frame).swap_remove(index);
        self.render_view_in_full(&self.scene, &*self.accel, &view, samples)
    }

    /// As [`Animator::render_full`], from a scene and an accelerator built
    /// afresh for `frame` (the timeline's state at `frame` put on the scene
    /// as loaded): a reference that shares nothing the frame loop posed,
    /// so a posing bug cannot hide in both.
    pub fn render_full_afresh(
        &self,
        frame: u32,
        index: usize,
    ) -> Result<(Frame, RayCounts), crate::accel::AccelError> {
        let mut scene = self.base.clone();
        if let Some(animation) = self.animation() {
            animation.pose(&mut scene.objects, &mut scene.lights, frame);
        }
        let accel = Accelerator::build(self.accel.kind(), &scene.objects)?;
        let view = self.views(frame).swap_remove(index);
        Ok(self.render_view_in_full(&scene, &accel, &view, self.scene.samples))
    }

    /// `view` of `scene` (posed) traced in full through `accel` at
    /// `samples` a pixel.
    fn render_view_in_full(
        &self,
        scene: &Scene,
        accel: &dyn Intersector,
        view: &View,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        let shader = Shader::new(scene, accel);
        if self.has_viewports() {
            return render_direct_sampled(&shader, &view.pose, samples);
        }
        let camera = &view.pose.camera;
        if self.on_lattice(camera) {
            let lattice = EqualAngleLattice::for_camera_sampled(camera, samples);
            let window = lattice.window(camera);
            return render_window(&shader, &lattice, &window);
        }
        render_view_sampled(scene, camera, samples, accel)
    }

    /// View `index` of `frame` through its own, unsnapped rays: the exact
    /// picture any approximation is measured against.
    pub fn render_true_view(&mut self, frame: u32, index: usize) -> (Frame, RayCounts) {
        self.render_view_sampled(frame, index, self.scene.samples)
    }

    /// As [`Animator::render_true_view`] at `samples` a pixel rather than
    /// the scene's: a converged reference of the view, for measuring how
    /// far the scene's own samples (full or reused) are from it.
    pub fn render_view_sampled(
        &mut self,
        frame: u32,
        index: usize,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        self.pose(frame);
        let view = self.views(frame).swap_remove(index);
        if self.has_viewports() {
            let shader = Shader::new(&self.scene, self.accel);
            return render_direct_sampled(&shader, &view.pose, samples);
        }
        render_view_sampled(&self.scene, &view.pose.camera, samples, self.accel)
    }

    /// Whether the frames are exact, comparable bit for bit with
    /// [`Animator::render_full`]: the camera's image, pans snapped.
    pub fn is_exact(&self) -> bool {
        !self.has_viewports() && self.options.fractional_pan == FractionalPan::Snap
    }

    /// What view `index` of `frame` is measured against: its full render
    /// where the frames are exact, its own rays otherwise.
    pub fn render_reference(&mut self, frame: u32, index: usize) -> (Frame, RayCounts) {
        if self.is_exact() {
            self.render_full(frame, index)
        } else {
            self.render_true_view(frame, index)
        }
    }

    /// Why OSTC was asked for but not kept, if it was not: stores then
    /// restart whenever something moves.
    pub fn ostc_refusal(&self) -> Option<&str> {
        self.ostc_refusal.as_deref()
    }

    /// The kept samples as a picture around the view of `frame`'s camera,
    /// never-traced ones black (RSVP's buffer; None for other stores).
    pub fn store_picture(&self, frame: u32) -> Option<image::RgbImage> {
        self.kept.as_ref()?.store.picture(&self.camera_at(frame))
    }

    /// Re-traces every sample the store keeps (the scene posed at the last
    /// frame rendered) and compares bit for bit: (samples compared,
    /// samples that differ); None where the store does not check itself.
    pub fn verify_store(&self) -> Option<(u64, u64)> {
        let kept = self.kept.as_ref()?;
        kept.store.verify(&Shader::new(&self.scene, self.accel))
    }

    /// Why `frame` (of `views`) may not come from a store, if it may not:
    /// None inside when reuse was not asked for at all.
    fn full_reason(&self, frame: u32, views: &[View]) -> Option<Option<FullReason>> {
        let techniques = self.options.techniques;
        if self.has_viewports() {
            return (!techniques.rsvp).then_some(None);
        }
        let camera = &views[0].pose.camera;
        if !techniques.buffered() {
            return Some(None);
        }
        let equal_angle = camera.projection == Projection::EqualAngle;
        if techniques.pan && equal_angle && self.facts.camera_moves && !self.on_lattice(camera) {
            return Some(Some(FullReason::PanBufferTooLarge {
                bytes: self.facts.pan_buffer_bytes,
            }));
        }
        if techniques.pan && self.on_lattice(camera) {
            return None;
        }
        if !techniques.ostc && !equal_angle {
            return Some(Some(FullReason::PanNeedsEqualAngle(camera.projection)));
        }
        // The store says whether it fits camera views no timeline foresees.
        if self.interactive {
            return None;
        }
        // Without panning a store holds only while the camera stands still.
        let moves = |other: u32| self.camera_at(other) != *camera;
        let still = (frame == 0 || !moves(frame - 1)) && !moves(frame + 1);
        let reason = if equal_angle {
            FullReason::CameraMovesPanOff
        } else {
            FullReason::CameraMovesNotEqualAngle(camera.projection)
        };
        (!still).then_some(Some(reason))
    }

    /// A new store for `views`: RSVP's buffer for viewports; for the
    /// camera's image the pan lattice, sized for every window of this run
    /// that shares it, where its frames live there (with pan off too, so
    /// they equal full renders), and its own image otherwise.
    fn new_store(&self, views: &[View]) -> Box<dyn SampleStore> {
        let camera = &views[0].pose.camera;
        if self.has_viewports() {
            let columns = SampleLattice::for_camera(&self.base.camera).columns_per_turn;
            let lattice = SampleLattice::new(camera.position, columns);
            return Box::new(RsvpStore::new(
                lattice,
                self.options.rsvp,
                self.scene.samples,
            ));
        }
        // Strata serve OSTC alone (it re-traces groups of them).
        let keep_strata =
            self.options.techniques.ostc && self.animation().is_some_and(|a| a.moves_scene());
        if !self.on_lattice(camera) {
            return Box::new(StillStore::new(camera, self.scene.samples, keep_strata));
        }
        let window = EqualAngleLattice::for_camera(camera).window(camera);
        let (mut low, mut high) = (window.row, window.row + i64::from(window.height));
        if let Some(&(top, bottom)) = self.facts.row_spans.get(&lattice_key(camera)) {
            (low, high) = (low.min(top), high.max(bottom));
        }
        // A resampled view reads up to one row more on either side.
        Box::new(PanStore::new(
            camera,
            low - 1..high + 1,
            self.options.fractional_pan,
            self.options.techniques.pan,
            self.scene.samples,
            keep_strata,
        ))
    }

    /// OSTC bookkeeping for `store`, when it is on and the timeline moves
    /// something; a refusal is kept for [`Animator::ostc_refusal`] (the
    /// store then restarts whenever something moves, which is exact).
    fn new_ostc(&mut self, store: &dyn SampleStore) -> Option<Ostc> {
        let animation = self.animation()?;
        if !self.options.techniques.ostc {
            return None;
        }
        // Regions are cut from the scene camera's screen, whatever views it,
        // in the samples of the store's lattice.
        let camera = &self.base.camera;
        let side = store.lattice_side();
        let size = self.options.ostc.region_size(
            camera.width * side,
            camera.height * side,
            self.has_viewports(),
        );
        let built = build_ostc(
            self.base,
            animation,
            &self.options.ostc,
            store.regions(size),
        );
        built.unwrap_or_else(|why| {
            self.ostc_refusal = Some(why);
            None
        })
    }

    /// Why the kept store cannot carry over to `views` with the scene
    /// posed as `pose`, if it cannot.
    fn restart(&self, views: &[ViewportPose], pose: &ScenePose) -> Option<Restart> {
        let Some(kept) = &self.kept else {
            return Some(Restart::FirstFrame);
        };
        if let Some(unfit) = kept.store.unfit(views) {
            return Some(Restart::Unfit(unfit));
        }
        (kept.pose != *pose && kept.ostc.is_none()).then(|| Restart::SceneMoved {
            store: kept.store.name(),
            ostc_refused: self.ostc_refusal.is_some(),
        })
    }

    /// Renders `frame`: every view, with whatever reuse applies, in 8-bit
    /// sRGB (frame assembly is part of the cost) and, when asked, linear
    /// colour, with what each took.
    pub fn render(&mut self, frame: u32) -> Vec<ViewOutput> {
        let views = self.views(frame);
        self.render_views(frame, views)
    }

    /// As [`Animator::render`], showing `views` (of the kind
    /// [`Animator::views`] gives: the camera's image, or one per viewport)
    /// rather than the timeline's: for an [`Animator::interactive`] one.
    pub fn render_views(&mut self, frame: u32, views: Vec<View>) -> Vec<ViewOutput> {
        self.render_views_until(frame, views, None)
            .expect("nothing to stop it")
    }

    /// As [`Animator::render_views`]; a frame traced from nothing (in
    /// full, or into a new store) gives up as soon as `stop` is set, and
    /// is None: the store it was filling is dropped with it (the next
    /// frame starts one afresh), so nothing half-traced is ever kept or
    /// shown. A frame from a kept store runs to the end (it is quick, and
    /// its store is worth keeping).
    pub fn render_views_until(
        &mut self,
        frame: u32,
        views: Vec<View>,
        stop: Option<&AtomicBool>,
    ) -> Option<Vec<ViewOutput>> {
        with_workers_awake(|| self.render_awake(frame, views, stop))
    }

    fn render_awake(
        &mut self,
        frame: u32,
        views: Vec<View>,
        stop: Option<&AtomicBool>,
    ) -> Option<Vec<ViewOutput>> {
        debug_assert!(
            self.interactive || views == self.views(frame),
            "views other than the timeline's need an interactive animator"
        );
        let start = Instant::now();
        self.pose(frame);
        if let Some(reason) = self.full_reason(frame, &views) {
            self.kept = None;
            return self.render_in_full(frame, views, reason, stop);
        }
        let pose = ScenePose::of(&self.scene, self.animation());
        let poses: Vec<ViewportPose> = views.iter().map(|v| v.pose.clone()).collect();
        let restart = self.restart(&poses, &pose);
        let mut changed = Invalidation::default();
        if restart.is_some() {
            let store = self.new_store(&views);
            let ostc = self.new_ostc(store.as_ref());
            self.kept = Some(Kept { store, ostc, pose });
        } else {
            let kept = self.kept.as_mut().expect("kept unless restarted");
            if kept.pose != pose {
                let ostc = kept
                    .ostc
                    .as_mut()
                    .expect("restarted on changes without ostc");
                changed = invalidate(kept.store.as_mut(), ostc, &kept.pose, &pose);
                kept.pose = pose;
            }
        }
        let setup_ms = start.elapsed().as_secs_f64() * 1e3 - changed.ms;
        let kept = self.kept.as_mut().expect("store just ensured");
        let gate = stop
            .filter(|_| restart.is_some())
            .map(|stop| Abandonable::new(&*self.accel, stop));
        let intersector: &dyn Intersector = match &gate {
            Some(gate) => gate,
            None => &*self.accel,
        };
        let shader = Shader::new(&self.scene, intersector);
        let wanted = Wanted {
            linear: self.options.linear,
        };
        let frames = kept
            .store
            .render(&shader, &poses, kept.ostc.as_ref(), wanted);
        if gate.as_ref().is_some_and(Abandonable::tripped) {
            self.kept = None;
            return None;
        }
        let (walked, record_ms) = kept.ostc.as_ref().map_or((0, 0.0), Ostc::take_counters);
        // Recording ran on every worker thread: its share of the elapsed
        // time. Frame-wide figures are shared out over the views.
        let record_share = record_ms / rayon::current_num_threads() as f64;
        let count = frames.len().max(1) as f64;
        let mode = kept.store.mode(kept.ostc.is_some());
        let mut outputs = Vec::with_capacity(views.len());
        for (view, made) in views.into_iter().zip(frames) {
            let total = (setup_ms + changed.ms) / count + made.trace_ms + made.assembly_ms;
            let bookkeeping = (changed.ms + record_share) / count;
            let trace = (made.trace_ms - record_share / count).max(0.0);
            let (yaw_error, pitch_error) = made.snap_error.unwrap_or((0.0, 0.0));
            let mut stats = FrameStats {
                frame,
                mode,
                reason: restart.map(Reason::Restart),
                pixels: pixels(&view.pose),
                pixels_reused: made.pixels_reused,
                samples_traced: made.samples_traced,
                dirty_regions: changed.regions,
                samples_nulled: changed.samples_nulled,
                voxels_walked: walked,
                bookkeeping_ms: bookkeeping,
                trace_ms: trace,
                copy_ms: (total - trace - bookkeeping).max(0.0),
                total_ms: total,
                yaw_error_deg: yaw_error.to_degrees(),
                pitch_error_deg: pitch_error.to_degrees(),
                viewport: view.name.clone(),
                finest_level: made.levels.map(|l| l.1),
                coarsest_level: made.levels.map(|l| l.0),
                ..FrameStats::default()
            };
            stats.count_rays(made.rays);
            let traced_image = self.options.traced_images.then(|| {
                kept.store
                    .paint_traced(outputs.len(), &view.pose, &made.image)
            });
            outputs.push(ViewOutput {
                name: view.name,
                frame: made.frame,
                image: made.image,
                stats,
                traced_image,
            });
        }
        Some(outputs)
    }

    /// Renders every view of `frame` from scratch (see
    /// [`Animator::render_full`]), for the `reason` given; None if `stop`
    /// was set before it finished.
    fn render_in_full(
        &mut self,
        frame: u32,
        views: Vec<View>,
        reason: Option<FullReason>,
        stop: Option<&AtomicBool>,
    ) -> Option<Vec<ViewOutput>> {
        let mut outputs = Vec::with_capacity(views.len());
        self.pose(frame);
        for view in views {
            let start = Instant::now();
            let gate = stop.map(|stop| Abandonable::new(&*self.accel, stop));
            let intersector: &dyn Intersector = match &gate {
                Some(gate) => gate,
                None => &*self.accel,
            };
            let (image, rays) =
                self.render_view_in_full(&self.scene, intersector, &view, self.scene.samples);
            if gate.as_ref().is_some_and(Abandonable::tripped) {
                return None;
            }
            let trace_ms = start.elapsed().as_secs_f64() * 1e3;
            let rgb = image.to_rgb8();
            let total_ms = start.elapsed().as_secs_f64() * 1e3;
            let mut stats = FrameStats {
                frame,
                mode: FrameMode::Full,
                reason: reason.map(Reason::Full),
                pixels: pixels(&view.pose),
                samples_traced: cells_traced(&rays, self.scene.samples),
                trace_ms,
                copy_ms: total_ms - trace_ms,
                total_ms,
                viewport: view.name.clone(),
                ..FrameStats::default()
            };
            stats.count_rays(rays);
            let traced_image = self
                .options
                .traced_images
                .then(|| image::RgbImage::new(rgb.width(), rgb.height()));
            outputs.push(ViewOutput {
                name: view.name,
                frame: self.options.linear.then_some(image),
                image: rgb,
                stats,
                traced_image,
            });
        }
        Some(outputs)
    }
}

/// Why `technique` cannot act on a run of `scene` with `options`,
/// whether asked for or not; None when it can. (Known before the run:
/// flags are checked before any work.)
pub fn idle_reason(scene: &Scene, options: &Options, technique: Technique) -> Option<String> {
    idle_reason_in(
        scene,
        options,
        &TimelineFacts::of(scene, &options.frames),
        technique,
    )
}

fn idle_reason_in(
    scene: &Scene,
    options: &Options,
    facts: &TimelineFacts,
    technique: Technique,
) -> Option<String> {
    let animation = scene.animation.as_ref();
    let has_viewports = !scene.viewports.is_empty();
    match technique {
        Technique::Rsvp => (!has_viewports).then(|| {
            "the scene has no [[viewport]] for RSVP to resample (the camera's image \
             reuses through pan and ostc)"
                .to_string()
        }),
        Technique::Pan if has_viewports => Some(
            "the scene's output is its [[viewport]]s, and RSVP's buffer follows the \
             camera's pans by itself (use rsvp)"
                .to_string(),
        ),
        Technique::Pan if !facts.camera_moves => Some("the camera does not move".to_string()),
        // Keys move the camera; its projection stays the scene's.
        Technique::Pan if scene.camera.projection != Projection::EqualAngle => Some(format!(
            "only an equal-angle camera pans, and this one is {}",
            scene.camera.projection
        )),
        Technique::Pan => (!facts.on_lattice(&scene.camera)).then(|| {
            FullReason::PanBufferTooLarge {
                bytes: facts.pan_buffer_bytes,
            }
            .to_string()
        }),
        Technique::Ostc if !animation.is_some_and(|a| a.moves_scene()) => {
            Some("no object or light moves".to_string())
        }
        Technique::Ostc if has_viewports && !options.techniques.rsvp => Some(
            "without rsvp the viewports are traced through their own rays, every frame \
             (use rsvp,ostc)"
                .to_string(),
        ),
        Technique::Ostc => None,
    }
}

/// A view's pixel count.
fn pixels(pose: &ViewportPose) -> u64 {
    u64::from(pose.camera.width) * u64::from(pose.camera.height)
}

impl TimelineFacts {
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
        }
    }

    /// Whether a full render of `camera` is taken on the pan lattice (see
    /// [`Animator::render_full`]).
    fn on_lattice(&self, camera: &Camera) -> bool {
        camera.projection == Projection::EqualAngle
            && self.camera_moves
            && self.pan_buffer_bytes <= PAN_BUFFER_LIMIT_BYTES
    }

    fn of(scene: &Scene, run: &std::ops::Range<u32>) -> TimelineFacts {
        let mut facts = TimelineFacts {
            camera_moves: false,
            pan_buffer_bytes: 0.0,
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
