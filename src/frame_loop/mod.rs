//! The frame loop: the one place that decides what a frame must trace.
//!
//! A frame's output is its views: the camera's own image (a trivial
//! viewport: the identity transform over the camera's own projection), or
//! the scene's RSVP viewports. Before the first frame the loop asks the
//! stores for the run's plan ([`crate::reuse::plan_for`]); for each frame
//! it poses the scene, asks the plan whether the views come from a store
//! ([`crate::reuse::SampleStore`]) and whether the kept store can serve
//! them or must start again (and why), erases from it what OSTC says the
//! scene's changes dirtied ([`changes`]), and renders the views through
//! it; a frame the plan does not serve is rendered in full. The loop knows
//! no store's internals: adding a store touches its own files and the
//! registry in [`crate::reuse`].
//!
//! Promises:
//! - Every frame's state comes from its frame number and the timeline,
//!   never from the previous frame, and the plan is made over the whole
//!   timeline: a chunk of frames equals the same frames of one long run.
//! - A camera frame from a store equals [`Animator::render_full`] of the
//!   same frame bit for bit (a snapped pan: of the snapped view); RSVP's
//!   buffer samples equal a fresh trace, its viewports are measured
//!   against their own rays.

mod abandon;
mod changes;
mod memory;
mod stats;

pub use crate::reuse::{FullReason, Options, OstcSettings, Technique, Techniques, View};
pub use changes::{swept_bounds, OstcRefusal, OSTC_LIMIT_BYTES};
pub use memory::{available_bytes, bytes_text, peak_resident_bytes, MemoryEstimate};
pub use stats::{
    stats_csv, stats_json, stats_rows, FrameCheck, FrameStats, OstcWork, Reason, Restart, StatsRows,
};

use std::sync::atomic::AtomicBool;

use crate::accel::{Accelerator, Intersector};
use crate::aov::{AovSet, Aovs};
use crate::camera::{Camera, ViewTransform, ViewportPose};
use crate::clock::Stopwatch;
use crate::geometry::Placement;
use crate::pool::with_workers_awake;
use crate::render::Frame;
use crate::reuse::lattice_buffer::cells_traced;
use crate::reuse::ostc::Ostc;
use crate::reuse::{plan_for, FrameMode, Run, SampleStore, Serve, StorePlan, ViewWork, Wanted};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};
use crate::timeline::Animation;
use abandon::Abandonable;
use changes::{build_ostc, invalidate, Invalidation, ScenePose};

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
    /// The arbitrary output variables [`Options::aovs`] asks for (None:
    /// none asked for).
    pub aovs: Option<Aovs>,
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

impl KeptSamples {
    /// The bytes of kept samples a memory cap bounds
    /// ([`Options::sample_memory`]).
    pub fn kept_bytes(&self) -> u64 {
        self.0.store.kept_bytes()
    }

    /// Drops kept samples, least recently used first, until those a memory
    /// cap bounds take at most `bytes`.
    pub fn trim(&mut self, bytes: u64) {
        self.0.store.trim(bytes);
    }
}

/// Renders the frames of one animation, reusing what it may.
pub struct Animator<'a> {
    /// The scene as loaded.
    base: &'a Scene,
    /// The scene posed at `posed_frame`: animated objects and lights moved.
    scene: Scene,
    posed_frame: Option<u32>,
    accel: &'a mut Accelerator,
    options: Options,
    /// Whether the views come from the caller ([`Animator::render_views`]),
    /// not from the timeline alone.
    interactive: bool,
    /// What kind of store serves the run's frames, and when.
    plan: Box<dyn StorePlan>,
    kept: Option<Kept>,
    /// Why OSTC, asked for, could not be kept.
    ostc_refusal: Option<OstcRefusal>,
}

impl<'a> Animator<'a> {
    pub fn new(scene: &'a Scene, accel: &'a mut Accelerator, options: Options) -> Animator<'a> {
        Animator::with_views_from(scene, accel, options, false)
    }

    /// An animator for views no timeline knows in advance (an interactive
    /// viewer's, given to [`Animator::render_views`]): the scene's objects
    /// and lights still follow the timeline, but the camera may turn
    /// anywhere at any frame (an equal-angle camera's frames live on the
    /// pan lattice from the first, and its pan buffer holds every row of
    /// the lattice, pole to pole).
    pub fn interactive(
        scene: &'a Scene,
        accel: &'a mut Accelerator,
        options: Options,
    ) -> Animator<'a> {
        Animator::with_views_from(scene, accel, options, true)
    }

    fn with_views_from(
        scene: &'a Scene,
        accel: &'a mut Accelerator,
        options: Options,
        interactive: bool,
    ) -> Animator<'a> {
        let plan = plan_for(&Run {
            scene,
            options: &options,
            interactive,
        });
        Animator {
            base: scene,
            scene: scene.clone(),
            posed_frame: None,
            accel,
            options,
            interactive,
            plan,
            kept: None,
            ostc_refusal: None,
        }
    }

    fn run(&self) -> Run<'_> {
        Run {
            scene: self.base,
            options: &self.options,
            interactive: self.interactive,
        }
    }

    pub fn options(&self) -> &Options {
        &self.options
    }

    /// What this animator keeps for its next frame (None when it keeps
    /// nothing: reuse off, or nothing rendered yet).
    pub fn into_kept(self) -> Option<KeptSamples> {
        self.kept.map(KeptSamples)
    }

    /// Caps the bytes its kept samples may take from the next frame on
    /// ([`Options::sample_memory`]).
    pub fn set_sample_memory(&mut self, bytes: Option<u64>) {
        self.options.sample_memory = bytes;
        if let Some(kept) = &mut self.kept {
            kept.store.set_memory_cap(bytes);
        }
    }

    /// The bytes of its kept samples a memory cap bounds (0 with nothing
    /// kept).
    pub fn kept_bytes(&self) -> u64 {
        self.kept.as_ref().map_or(0, |kept| kept.store.kept_bytes())
    }

    /// Goes on from `kept`, which an animator of this scene with these
    /// options kept. Its samples stay exact: the next frame checks them
    /// against the views and the scene's pose as it checks its own (a
    /// store unfit for the views starts afresh; objects that moved since
    /// re-trace through OSTC), and the first pose places every animated
    /// object in the accelerator.
    pub fn resume(&mut self, kept: KeptSamples) {
        let mut kept = kept.0;
        kept.store.set_memory_cap(self.options.sample_memory);
        self.kept = Some(kept);
    }

    pub fn animation(&self) -> Option<&'a Animation> {
        self.base.animation.as_ref()
    }

    /// Whether the frame's views are RSVP viewports rather than the
    /// camera's image.
    pub fn has_viewports(&self) -> bool {
        self.run().has_viewports()
    }

    pub fn camera_at(&self, frame: u32) -> Camera {
        self.run().camera_at(frame)
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
            self.scene.lens = animation.lens_at(self.base.lens, frame);
            // An interactive run's camera goes where its caller takes it,
            // not where the keys say.
            self.scene.camera_motion = match self.interactive {
                true => None,
                false => animation.camera_motion(&self.base.camera, frame),
            };
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
            let placements: Vec<(u32, Placement)> = moved
                .into_iter()
                .map(|object| (object as u32, self.scene.objects[object].placement))
                .collect();
            self.accel
                .place_objects(&placements)
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

    /// View `index` of `frame` traced from scratch, at `samples` a pixel
    /// (None: the scene's), through the rays an exact frame shows: a
    /// snapped pan's lattice view, not the keyed camera's. A reused frame
    /// that is exact ([`Animator::is_exact`]) equals it bit for bit.
    pub fn render_full(
        &mut self,
        frame: u32,
        index: usize,
        samples: Option<PixelSamples>,
    ) -> (Frame, RayCounts) {
        self.pose(frame);
        let view = self.views(frame).swap_remove(index);
        let shader = Shader::new(&self.scene, &*self.accel);
        let samples = samples.unwrap_or(self.scene.samples);
        self.plan.render_full(&shader, &view, samples)
    }

    /// As [`Animator::render_full`] at the scene's samples, from a scene
    /// and an accelerator built afresh for `frame` (the timeline's state
    /// at `frame` put on the scene as loaded): a reference that shares
    /// nothing the frame loop posed, so a posing bug cannot hide in both.
    pub fn render_full_afresh(
        &self,
        frame: u32,
        index: usize,
    ) -> Result<(Frame, RayCounts), crate::accel::AccelError> {
        let (image, rays, _) = self.render_full_afresh_with_aovs(frame, index, AovSet::NONE)?;
        Ok((image, rays))
    }

    /// As [`Animator::render_full_afresh`], with the arbitrary output
    /// variables `set` as [`Animator::render_aovs`] gives them (None when
    /// `set` is empty), from the same scene and accelerator built afresh.
    pub fn render_full_afresh_with_aovs(
        &self,
        frame: u32,
        index: usize,
        set: AovSet,
    ) -> Result<(Frame, RayCounts, Option<Aovs>), crate::accel::AccelError> {
        let mut scene = self.base.clone();
        if let Some(animation) = self.animation() {
            animation.pose(&mut scene.objects, &mut scene.lights, frame);
            scene.lens = animation.lens_at(self.base.lens, frame);
            scene.camera_motion = animation.camera_motion(&self.base.camera, frame);
        }
        let accel = Accelerator::build(self.accel.kind(), &scene.objects)?;
        let view = self.views(frame).swap_remove(index);
        let shader = Shader::new(&scene, &accel);
        let (image, rays) = self.plan.render_full(&shader, &view, scene.samples);
        let aovs = (!set.is_empty()).then(|| full_aovs(&shader, self.plan.as_ref(), &view, set));
        Ok((image, rays, aovs))
    }

    /// View `index` of `frame`'s arbitrary output variables `set` as its
    /// full render ([`Animator::render_full`]) writes them: `traced` is 1
    /// everywhere. A reused frame's equal them but for `traced`.
    pub fn render_aovs(&mut self, frame: u32, index: usize, set: AovSet) -> Aovs {
        self.pose(frame);
        let view = self.views(frame).swap_remove(index);
        let shader = Shader::new(&self.scene, &*self.accel);
        full_aovs(&shader, self.plan.as_ref(), &view, set)
    }

    /// View `index` of `frame` through its own, unsnapped rays at
    /// `samples` a pixel (None: the scene's): the exact picture any
    /// approximation is measured against, or at many samples the
    /// converged reference.
    pub fn render_own_rays(
        &mut self,
        frame: u32,
        index: usize,
        samples: Option<PixelSamples>,
    ) -> (Frame, RayCounts) {
        self.pose(frame);
        let view = self.views(frame).swap_remove(index);
        let shader = Shader::new(&self.scene, &*self.accel);
        let samples = samples.unwrap_or(self.scene.samples);
        self.plan.render_own_rays(&shader, &view, samples)
    }

    /// Whether the frames are exact, comparable bit for bit with
    /// [`Animator::render_full`]: the camera's image, pans snapped.
    pub fn is_exact(&self) -> bool {
        self.plan.exact()
    }

    /// What view `index` of `frame` is measured against: its full render
    /// where the frames are exact, its own rays otherwise.
    pub fn render_reference(&mut self, frame: u32, index: usize) -> (Frame, RayCounts) {
        if self.is_exact() {
            self.render_full(frame, index, None)
        } else {
            self.render_own_rays(frame, index, None)
        }
    }

    /// Why OSTC was asked for but not kept, if it was not: stores then
    /// restart whenever something moves.
    pub fn ostc_refusal(&self) -> Option<OstcRefusal> {
        self.ostc_refusal
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

    /// OSTC bookkeeping for `store`, when it is on and the timeline moves
    /// something; a refusal is kept for [`Animator::ostc_refusal`] (the
    /// store then restarts whenever something moves, which is exact).
    fn new_ostc(&mut self, store: &dyn SampleStore) -> Option<Ostc> {
        let animation = self.animation()?;
        if !self.options.techniques.ostc {
            return None;
        }
        // Regions are cut from the scene camera's screen, whatever views it.
        let camera = &self.base.camera;
        let layout = store.ostc_regions(self.options.ostc.regions, (camera.width, camera.height));
        let built = build_ostc(self.base, animation, &self.options.ostc, layout);
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
        // Every camera ray passes the lens: a new one changes them all.
        if kept.pose.lens != pose.lens {
            return Some(Restart::LensChanged);
        }
        // A kept sample's ray moved as the camera did in its own frame's
        // shutter: only a steady turn moves it the same in this one's.
        if kept.pose.camera_motion != pose.camera_motion {
            return Some(Restart::CameraMoving);
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
        self.render_views(frame, views, None)
            .expect("nothing to stop it")
    }

    /// As [`Animator::render`], showing `views` (of the kind
    /// [`Animator::views`] gives: the camera's image, or one per viewport)
    /// rather than the timeline's where the animator is
    /// [`Animator::interactive`]. A frame traced from nothing (in full, or
    /// into a new store) gives up as soon as `stop` is set, and is None:
    /// the store it was filling is dropped with it (the next frame starts
    /// one afresh), so nothing half-traced is ever kept or shown. A frame
    /// from a kept store runs to the end (it is quick, and its store is
    /// worth keeping).
    pub fn render_views(
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
        let watch = Stopwatch::start();
        self.pose(frame);
        if let Serve::Full(reason) = self.plan.serves(&self.run(), frame, &views) {
            self.kept = None;
            return self.render_in_full(frame, views, reason, stop);
        }
        let pose = ScenePose::of(&self.scene, self.animation());
        let poses: Vec<ViewportPose> = views.iter().map(|v| v.pose.clone()).collect();
        let restart = self.restart(&poses, &pose);
        let mut changed = Invalidation::default();
        if restart.is_some() {
            let store = self.plan.new_store(&self.run(), &views);
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
        let setup_ms = watch.ms() - changed.ms;
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
        // Frame-wide figures are shared out over the views; recording ran
        // on every worker thread, so its share of the elapsed time counts.
        let count = frames.len().max(1) as f64;
        let ostc = OstcWork {
            dirty_regions: changed.regions,
            samples_nulled: changed.samples_nulled,
            voxels_walked: walked,
            record_ms: record_ms / rayon::current_num_threads() as f64 / count,
            erase_ms: changed.ms / count,
        };
        let mode = kept.store.mode(kept.ostc.is_some());
        let mut outputs = Vec::with_capacity(views.len());
        for (view, mut made) in views.into_iter().zip(frames) {
            let aovs = (!self.options.aovs.is_empty()).then(|| {
                let watch = Stopwatch::start();
                let shader = Shader::new(&self.scene, &*self.accel);
                let rays = self.plan.centre_rays(&view);
                let store = kept.store.as_ref();
                let index = outputs.len();
                let aovs = Aovs::trace(&shader, &*rays, size(&view), self.options.aovs, || {
                    traced_mask(store, index, &view.pose)
                });
                made.work.assembly_ms += watch.ms();
                aovs
            });
            let stats = FrameStats {
                frame,
                view: view.name.clone(),
                mode,
                reason: restart.map(Reason::Restart),
                pixels: pixels(&view.pose),
                work: made.work,
                ostc,
                setup_ms: setup_ms / count,
                check: None,
            };
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
                aovs,
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
            let watch = Stopwatch::start();
            let gate = stop.map(|stop| Abandonable::new(&*self.accel, stop));
            let intersector: &dyn Intersector = match &gate {
                Some(gate) => gate,
                None => &*self.accel,
            };
            let shader = Shader::new(&self.scene, intersector);
            let (image, rays) = self.plan.render_full(&shader, &view, self.scene.samples);
            if gate.as_ref().is_some_and(Abandonable::tripped) {
                return None;
            }
            let trace_ms = watch.ms();
            let rgb = image.to_rgb8();
            let aovs = (!self.options.aovs.is_empty()).then(|| {
                let shader = Shader::new(&self.scene, &*self.accel);
                full_aovs(&shader, self.plan.as_ref(), &view, self.options.aovs)
            });
            let stats = FrameStats {
                frame,
                view: view.name.clone(),
                mode: FrameMode::Full,
                reason: reason.map(Reason::Full),
                pixels: pixels(&view.pose),
                work: ViewWork {
                    samples_traced: cells_traced(&rays, self.scene.samples),
                    rays,
                    trace_ms,
                    assembly_ms: watch.ms() - trace_ms,
                    ..ViewWork::default()
                },
                ..FrameStats::default()
            };
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
                aovs,
            });
        }
        Some(outputs)
    }
}

/// The AOVs `set` of `view` as a full render of `plan` writes them: every
/// pixel traced.
fn full_aovs(shader: &Shader, plan: &dyn StorePlan, view: &View, set: AovSet) -> Aovs {
    let rays = plan.centre_rays(view);
    let (width, height) = size(view);
    Aovs::trace(shader, &*rays, (width, height), set, || {
        vec![true; width as usize * height as usize]
    })
}

/// Which pixels of view `index` (`pose`) the store's last render traced:
/// those its traced picture ([`SampleStore::paint_traced`]) paints black
/// on a white one.
fn traced_mask(store: &dyn SampleStore, index: usize, pose: &ViewportPose) -> Vec<bool> {
    let (width, height) = (pose.camera.width, pose.camera.height);
    let white = image::RgbImage::from_pixel(width, height, image::Rgb([255; 3]));
    store
        .paint_traced(index, pose, &white)
        .pixels()
        .map(|p| p.0 == [0; 3])
        .collect()
}

/// A view's width and height in pixels.
fn size(view: &View) -> (u32, u32) {
    (view.pose.camera.width, view.pose.camera.height)
}

/// A view's pixel count.
fn pixels(pose: &ViewportPose) -> u64 {
    u64::from(pose.camera.width) * u64::from(pose.camera.height)
}
