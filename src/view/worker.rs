//! The viewer's render thread: the frame loop ([`Animator`]) off the
//! input's thread, always rendering the latest view asked for.
//!
//! Promises: asking never blocks (the request replaces any not yet
//! started: input arriving faster than pictures is coalesced, never
//! queued); every picture is the frame loop's picture of one requested
//! state, tagged with that request's number; the thread sleeps while
//! nothing new is asked. Reuse is the frame loop's: an animator lives as
//! long as its kind of view (the camera's image or the viewport) and the
//! reuse mode last, so its kept samples carry from picture to picture.
//! A new animator (a new kind of view, reuse mode or window size) starts
//! its buffers from nothing: its first picture is preceded by a coarse
//! one (a sixteenth of the samples, traced afresh, marked not complete),
//! and the full picture then shows the latest request.
//!
//! A picture the frame loop traces from nothing (in full: reuse off; or
//! into a new buffer: the first of an animator, or after the eye moved) is
//! given up when a newer request comes ([`Animator::render_views_until`]:
//! within a packet of rays); the frame loop then drops the buffer it was
//! filling, so the next picture is traced afresh and exact, and nothing of
//! the stale one is published. So that input faster than pictures cannot
//! starve the window of pictures, a request gives up the picture under way
//! only while the oldest request not yet answered has waited less than
//! the last picture traced from nothing took (its patience): past that,
//! the picture under way is finished. The last input of a burst shorter
//! than a picture is then answered about one picture after it (without
//! giving up: up to two), and input faster than pictures for longer still
//! gets a picture at least every two or so. Giving up throws away the
//! work done, so the first inputs of a burst wait longer than they would
//! have. Pictures from kept buffers (pans, zooms, OSTC) are quick and run
//! to the end, keeping their buffers.
//!
//! With nothing new asked after a complete picture, the thread refines it
//! ([`super::refine`]): the same view traced afresh at more samples a
//! pixel, rung by rung of a ladder, each rung published as it finishes
//! (mode `refine`); a new request abandons the refinement within a band
//! of sample groups, and no refined picture is published once a newer
//! request is waiting. After the last rung (the picture is converged) the thread
//! sleeps until the next request.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::accel::{Accelerator, BackendKind};
use crate::camera::{Camera, RayTable, Viewport};
use crate::clock::{self, Stopwatch};
use crate::frame_loop::{Animator, FrameStats, KeptSamples, Options, Techniques};
use crate::reuse::rsvp::{RsvpKnobs, ViewportRays};
use crate::reuse::{FrameMode, ViewWork};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::Shader;
use crate::timeline::ViewportTrack;

use super::refine::{ladder, trace_in_bands};
use super::state::{ViewState, Viewer};

/// One finished picture and what it cost.
#[derive(Clone, Debug)]
pub struct Picture {
    /// The request it answers.
    pub generation: u64,
    pub state: ViewState,
    pub image: image::RgbImage,
    /// The picture painted black where it traced (the paper's figure 4);
    /// for a refined picture, which traces every pixel, the frame loop's
    /// picture of the same request: the overlay keeps showing what reuse
    /// traced.
    pub traced: image::RgbImage,
    /// What it cost, as the frame loop records it (a coarse picture: at
    /// its own size; a refinement: its own trace of every pixel).
    pub stats: FrameStats,
    pub stage: Stage,
    /// When it was finished.
    pub done: Instant,
    /// False for a coarse picture shown while the full one is traced.
    pub complete: bool,
    /// Samples a pixel (of the coarse picture's pixels for a coarse one).
    pub samples: u32,
    /// The last picture of its request: refined to the top of the ladder
    /// (or the frame loop's, with refinement off).
    pub converged: bool,
}

/// How a picture was made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The frame loop's picture of the view.
    FrameLoop,
    /// Traced afresh at a fraction of the size and magnified, while the
    /// frame loop's is traced.
    Coarse,
    /// Traced afresh at more samples a pixel ([`super::refine`]).
    Refined,
}

impl Picture {
    /// Samples traced for this picture over its pixels.
    pub fn traced_share(&self) -> f64 {
        self.stats.work.samples_traced as f64 / self.stats.pixels.max(1) as f64
    }

    /// The frame loop's word for how it was made (pan, rsvp, full, ...),
    /// or `coarse`, or `refine`.
    pub fn mode(&self) -> &'static str {
        match self.stage {
            Stage::FrameLoop => self.stats.mode.as_str(),
            Stage::Coarse => "coarse",
            Stage::Refined => REFINE_MODE,
        }
    }

    /// Traced from nothing: in full, into a new buffer, coarse or refined.
    pub fn traced_afresh(&self) -> bool {
        self.stage != Stage::FrameLoop || self.stats.traced_afresh()
    }

    /// What is shown: the picture, or with the overlay, the picture
    /// painted where it traced.
    pub fn shown(&self, overlay: bool) -> &image::RgbImage {
        if overlay {
            &self.traced
        } else {
            &self.image
        }
    }
}

/// A finished picture as the log keeps it: enough to time each request.
#[derive(Clone, Debug)]
pub struct Finished {
    pub generation: u64,
    pub done: Instant,
    pub stats: FrameStats,
    pub mode: &'static str,
    pub complete: bool,
    pub samples: u32,
    pub converged: bool,
    /// The newest request made when it was published.
    pub newest_asked: u64,
}

/// A picture given up because a newer request came: a refinement, or
/// the frame loop's picture traced from nothing.
#[derive(Clone, Copy, Debug)]
pub struct Abandoned {
    /// The request it answered.
    pub generation: u64,
    /// The samples a pixel of the rung it was tracing, or the scene's.
    pub samples: u32,
    /// The frame loop's picture (else a refinement).
    pub frame_loop: bool,
    pub at: Instant,
    /// Milliseconds from the newer request to giving up: the band (or
    /// packets) it waited for.
    pub waited_ms: f64,
}

#[derive(Default)]
struct Inbox {
    /// The latest request not yet started.
    request: Option<(u64, ViewState)>,
    /// The generation of the newest request made, and when.
    newest: u64,
    newest_at: Option<Instant>,
    /// Requests not yet answered by a complete picture of the frame loop,
    /// oldest first, and when each was made.
    unanswered: VecDeque<(u64, Instant)>,
    /// What the last picture traced from nothing took: while the oldest
    /// unanswered request has waited less, a newer one gives up the
    /// picture under way.
    patience: Duration,
    quit: bool,
}

/// The patience before any picture was traced from nothing.
const FIRST_PATIENCE: Duration = Duration::from_millis(200);

#[derive(Default)]
struct Outbox {
    /// The picture shown.
    latest: Option<Arc<Picture>>,
    /// The frame loop's latest complete picture (at the scene's samples).
    frame_loop: Option<Arc<Picture>>,
    /// Every picture finished, in order, when a log is kept (scripts).
    log: Vec<Finished>,
    abandoned: Vec<Abandoned>,
    keep_log: bool,
    /// Why the thread stopped, if it failed.
    failure: Option<String>,
    stopped: bool,
    /// Whether the waiting was given up (an interrupt): waits return at
    /// once.
    interrupted: bool,
}

struct Shared {
    inbox: Mutex<Inbox>,
    /// Whether a request that may give up the picture under way (or the
    /// word to quit) waits in the inbox: what a picture traced from
    /// nothing looks at, without a lock.
    preempt: AtomicBool,
    asked: Condvar,
    outbox: Mutex<Outbox>,
    finished: Condvar,
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Called on the render thread whenever a picture is finished (a window
/// wakes its event loop with it).
pub type Notify = Box<dyn Fn() + Send + Sync>;

/// The render thread and the way to it.
pub struct RenderThread {
    shared: Arc<Shared>,
    handle: Option<JoinHandle<()>>,
}

impl RenderThread {
    /// Starts the thread on `scene` with `backend`: it builds the
    /// accelerator there (an error building it is returned here) and then
    /// waits for requests. `log`: keep every finished picture's timing.
    /// `refine_spp`: refine complete pictures in idle time up to this many
    /// samples a pixel (no more than the scene's: no refinement).
    /// `sample_memory`: the most bytes the samples kept for every kind of
    /// view together may take (None: no cap).
    pub fn spawn(
        scene: Scene,
        backend: BackendKind,
        grid_resolution: Option<[u32; 3]>,
        log: bool,
        refine_spp: u32,
        sample_memory: Option<u64>,
        notify: Notify,
    ) -> Result<RenderThread, String> {
        let shared = Arc::new(Shared {
            inbox: Mutex::new(Inbox {
                patience: FIRST_PATIENCE,
                ..Inbox::default()
            }),
            preempt: AtomicBool::new(false),
            asked: Condvar::new(),
            outbox: Mutex::new(Outbox {
                keep_log: log,
                ..Outbox::default()
            }),
            finished: Condvar::new(),
        });
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread_shared = Arc::clone(&shared);
        let handle = std::thread::Builder::new()
            .name("retrace-view-render".to_string())
            .spawn(move || {
                let shared = thread_shared;
                let failure = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    // On a worker of the pool, so that each parallel step of
                    // the frame loop starts at once (see main.rs).
                    rayon::scope(|_| {
                        let accel =
                            match Accelerator::build_with(backend, &scene.objects, grid_resolution)
                            {
                                Ok(accel) => accel,
                                Err(err) => {
                                    let _ = ready_tx.send(Err(err.to_string()));
                                    return;
                                }
                            };
                        let _ = ready_tx.send(Ok(()));
                        let rungs = ladder(scene.samples.count(), refine_spp);
                        serve(&shared, &scene, accel, &rungs, sample_memory, &notify);
                    })
                }))
                .err()
                .map(|panic| panic_text(panic.as_ref()));
                let mut outbox = lock(&shared.outbox);
                outbox.failure = failure;
                outbox.stopped = true;
                drop(outbox);
                shared.finished.notify_all();
                notify();
            })
            .map_err(|err| format!("cannot start the render thread: {err}"))?;
        let thread = RenderThread {
            shared,
            handle: Some(handle),
        };
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(thread),
            Ok(Err(err)) => Err(err),
            Err(_) => Err(thread
                .failure()
                .unwrap_or_else(|| "the render thread stopped before starting".to_string())),
        }
    }

    /// Asks for a picture of `state`, replacing any request not started yet.
    pub fn request(&self, generation: u64, state: ViewState) {
        let now = Instant::now();
        let mut inbox = lock(&self.shared.inbox);
        inbox.request = Some((generation, state));
        inbox.newest = inbox.newest.max(generation);
        inbox.newest_at = Some(now);
        inbox.unanswered.push_back((generation, now));
        let oldest = inbox.unanswered.front().map_or(now, |&(_, at)| at);
        if now.duration_since(oldest) < inbox.patience {
            self.shared.preempt.store(true, Ordering::Relaxed);
        }
        drop(inbox);
        self.shared.asked.notify_one();
    }

    /// The latest finished picture.
    pub fn latest(&self) -> Option<Arc<Picture>> {
        lock(&self.shared.outbox).latest.clone()
    }

    /// Why the thread stopped, if it failed.
    pub fn failure(&self) -> Option<String> {
        lock(&self.shared.outbox).failure.clone()
    }

    /// Waits for the frame loop's complete picture answering request
    /// `generation` or a later one (at the scene's samples a pixel, even
    /// if a refined one is already shown).
    pub fn wait_for(&self, generation: u64) -> Result<Arc<Picture>, String> {
        self.wait_until(|outbox| {
            outbox
                .frame_loop
                .as_ref()
                .filter(|p| p.generation >= generation)
        })
    }

    /// Waits for the converged picture answering request `generation` or
    /// a later one: refined to the top of the ladder, or the frame loop's
    /// with refinement off.
    pub fn wait_converged(&self, generation: u64) -> Result<Arc<Picture>, String> {
        self.wait_until(|outbox| {
            outbox
                .latest
                .as_ref()
                .filter(|p| p.generation >= generation && p.converged)
        })
    }

    fn wait_until(
        &self,
        found: impl Fn(&Outbox) -> Option<&Arc<Picture>>,
    ) -> Result<Arc<Picture>, String> {
        let mut outbox = lock(&self.shared.outbox);
        loop {
            if let Some(picture) = found(&outbox) {
                return Ok(Arc::clone(picture));
            }
            if outbox.interrupted {
                return Err("interrupted".to_string());
            }
            if outbox.stopped {
                return Err(outbox
                    .failure
                    .clone()
                    .unwrap_or_else(|| "the render thread stopped".to_string()));
            }
            outbox = self
                .shared
                .finished
                .wait(outbox)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// What gives up every wait, now and later, from any thread (an
    /// interrupt's handler): a script then stops where it is.
    pub fn interrupter(&self) -> Box<dyn FnOnce() + Send> {
        let shared = Arc::clone(&self.shared);
        Box::new(move || {
            lock(&shared.outbox).interrupted = true;
            shared.finished.notify_all();
        })
    }

    /// Whether the interrupter was called.
    pub fn interrupted(&self) -> bool {
        lock(&self.shared.outbox).interrupted
    }

    /// The pictures finished so far (with a log kept).
    pub fn log(&self) -> Vec<Finished> {
        lock(&self.shared.outbox).log.clone()
    }

    /// The refinements abandoned for newer requests so far (with a log
    /// kept).
    pub fn abandoned(&self) -> Vec<Abandoned> {
        lock(&self.shared.outbox).abandoned.clone()
    }
}

impl Drop for RenderThread {
    fn drop(&mut self) {
        lock(&self.shared.inbox).quit = true;
        self.shared.preempt.store(true, Ordering::Relaxed);
        self.shared.asked.notify_all();
        if let Some(handle) = self.handle.take() {
            let _ = handle.join();
        }
    }
}

fn panic_text(panic: &(dyn std::any::Any + Send)) -> String {
    let text = panic
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| panic.downcast_ref::<&str>().copied())
        .unwrap_or("unknown panic");
    format!("the render thread failed: {text}")
}

/// The kinds of view an animator serves: the camera's image, the
/// viewer's viewport, or one of the scene's viewports (by index).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ViewKind {
    Camera,
    Viewport,
    Scene(usize),
}

/// Which animator serves a state: its kept samples are for one kind of
/// view and one reuse mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct AnimatorKind {
    view: ViewKind,
    reuse: bool,
}

impl AnimatorKind {
    fn of(state: &ViewState) -> AnimatorKind {
        let view = match state.scene_viewport {
            Some(index) => ViewKind::Scene(index),
            None if Viewer::is_camera_view(state) => ViewKind::Camera,
            None => ViewKind::Viewport,
        };
        AnimatorKind {
            view,
            reuse: state.reuse,
        }
    }
}

/// A coarse picture is this many times smaller each way than the full
/// one: a sixteenth of its samples, traced afresh in a few ms.
pub const COARSE_FACTOR: u32 = 4;

/// The scenes the frame loop serves at one window size: the camera's
/// image and the viewer's viewport, full and coarse, and each of the
/// scene's viewports.
struct Scenes {
    size: (u32, u32),
    camera: Scene,
    viewport: Scene,
    coarse_camera: Scene,
    coarse_viewport: Scene,
    /// The scene as loaded with only its viewport k: the frame loop then
    /// renders and poses it as `retrace animate` does (its sample buffer
    /// on the scene camera's lattice, whatever the window's size).
    scene_viewports: Vec<Scene>,
}

impl Scenes {
    fn new(scene: &Scene, viewer: &Viewer, size: (u32, u32)) -> Scenes {
        let coarse_size = (
            size.0.div_ceil(COARSE_FACTOR),
            size.1.div_ceil(COARSE_FACTOR),
        );
        // The window's picture, and the coarse one: the same field in
        // fewer, bigger pixels.
        let full = Viewer::resized(&scene.camera, size);
        let coarse = Camera {
            width: coarse_size.0,
            height: coarse_size.1,
            ..full.clone()
        };
        let at = |camera: Camera| {
            // The scene's own viewports are not the viewer's.
            let mut camera_scene = scene.clone();
            camera_scene.viewports.clear();
            let viewport = Viewport {
                width: camera.width,
                height: camera.height,
                ..viewer.viewport(size)
            };
            camera_scene.camera = camera;
            let mut viewport_scene = camera_scene.clone();
            viewport_scene.viewports.push(ViewportTrack {
                viewport,
                keys: Vec::new(),
            });
            (camera_scene, viewport_scene)
        };
        let (camera, viewport) = at(full);
        let (coarse_camera, coarse_viewport) = at(coarse);
        let scene_viewports = scene
            .viewports
            .iter()
            .map(|track| Scene {
                viewports: vec![track.clone()],
                ..scene.clone()
            })
            .collect();
        Scenes {
            size,
            camera,
            viewport,
            coarse_camera,
            coarse_viewport,
            scene_viewports,
        }
    }

    /// The scene an animator of `kind` renders. A scene viewport's coarse
    /// picture is its own viewport at fewer pixels, traced directly: the
    /// same scene.
    fn of(&self, kind: AnimatorKind, coarse: bool) -> &Scene {
        match (kind.view, coarse) {
            (ViewKind::Camera, false) => &self.camera,
            (ViewKind::Viewport, false) => &self.viewport,
            (ViewKind::Camera, true) => &self.coarse_camera,
            (ViewKind::Viewport, true) => &self.coarse_viewport,
            (ViewKind::Scene(index), _) => &self.scene_viewports[index],
        }
    }
}

/// The next request, waiting for one; None when told to quit.
fn next_request(shared: &Shared) -> Option<(u64, ViewState)> {
    let mut inbox = lock(&shared.inbox);
    loop {
        if inbox.quit {
            return None;
        }
        if let Some(request) = inbox.request.take() {
            shared.preempt.store(false, Ordering::Relaxed);
            return Some(request);
        }
        inbox = shared
            .asked
            .wait(inbox)
            .unwrap_or_else(PoisonError::into_inner);
    }
}

/// A request that came in meanwhile, without waiting.
fn newer_request(shared: &Shared) -> Option<(u64, ViewState)> {
    let mut inbox = lock(&shared.inbox);
    let request = inbox.request.take();
    if request.is_some() {
        shared.preempt.store(false, Ordering::Relaxed);
    }
    request
}

/// Whether a request (or the word to quit) is waiting.
fn asked_meanwhile(shared: &Shared) -> bool {
    let inbox = lock(&shared.inbox);
    inbox.request.is_some() || inbox.quit
}

fn publish(shared: &Shared, notify: &Notify, picture: Picture) {
    let mut inbox = lock(&shared.inbox);
    publish_locked(shared, notify, &mut inbox, picture);
}

/// Publishes a refined picture unless a request (or the word to quit) is
/// waiting: then it answers an old state, and is dropped. Returns whether
/// it was published.
fn publish_refined(shared: &Shared, notify: &Notify, picture: Picture) -> bool {
    // The inbox stays locked while publishing, so no request can come
    // between the look and the publishing.
    let mut inbox = lock(&shared.inbox);
    if inbox.request.is_some() || inbox.quit {
        return false;
    }
    publish_locked(shared, notify, &mut inbox, picture);
    true
}

fn publish_locked(shared: &Shared, notify: &Notify, inbox: &mut Inbox, picture: Picture) {
    if picture.complete && picture.stage != Stage::Refined {
        while inbox
            .unanswered
            .front()
            .is_some_and(|&(generation, _)| generation <= picture.generation)
        {
            inbox.unanswered.pop_front();
        }
        if picture.traced_afresh() {
            inbox.patience = clock::duration(picture.stats.total_ms());
        }
    }
    let mut outbox = lock(&shared.outbox);
    if outbox.keep_log {
        outbox.log.push(Finished {
            generation: picture.generation,
            done: picture.done,
            stats: picture.stats.clone(),
            mode: picture.mode(),
            complete: picture.complete,
            samples: picture.samples,
            converged: picture.converged,
            newest_asked: inbox.newest,
        });
    }
    let picture = Arc::new(picture);
    if picture.complete && picture.stage != Stage::Refined {
        outbox.frame_loop = Some(Arc::clone(&picture));
    }
    outbox.latest = Some(picture);
    drop(outbox);
    shared.finished.notify_all();
    notify();
}

fn abandon(shared: &Shared, generation: u64, samples: u32, frame_loop: bool) {
    let at = Instant::now();
    let asked = lock(&shared.inbox).newest_at.unwrap_or(at);
    let mut outbox = lock(&shared.outbox);
    if outbox.keep_log {
        outbox.abandoned.push(Abandoned {
            generation,
            samples,
            frame_loop,
            at,
            waited_ms: clock::ms(at.saturating_duration_since(asked)),
        });
    }
}

/// The mode of a refined picture.
pub const REFINE_MODE: &str = "refine";

/// The render loop: waits for a request, renders the latest, repeats
/// until told to quit. Each window size has its own scenes and animators.
fn serve(
    shared: &Shared,
    scene: &Scene,
    mut accel: Accelerator,
    rungs: &[u32],
    sample_memory: Option<u64>,
    notify: &Notify,
) {
    let viewer = Viewer::new(scene);
    let mut pending = next_request(shared);
    while let Some(request) = pending {
        let scenes = Scenes::new(scene, &viewer, viewer.size_of(&request.1));
        let serving = Serving {
            shared,
            viewer: &viewer,
            scenes: &scenes,
            rungs,
            sample_memory,
            notify,
        };
        pending = serve_size(&serving, &mut accel, request);
    }
}

/// What the render loop serves one window size with.
struct Serving<'a> {
    shared: &'a Shared,
    viewer: &'a Viewer,
    scenes: &'a Scenes,
    /// The refinement ladder's samples a pixel (empty: no refinement).
    rungs: &'a [u32],
    /// The most bytes the kept samples of every kind of view together may
    /// take (None: no cap).
    sample_memory: Option<u64>,
    notify: &'a Notify,
}

/// Renders requests of one window size; returns the first request of
/// another size (None: quit).
fn serve_size(
    serving: &Serving,
    accel: &mut Accelerator,
    first: (u64, ViewState),
) -> Option<(u64, ViewState)> {
    let Serving {
        shared,
        viewer,
        scenes,
        rungs,
        sample_memory,
        notify,
    } = *serving;
    let options = |kind: AnimatorKind, scene: &Scene| Options {
        techniques: if kind.reuse {
            Techniques::AUTO
        } else {
            Techniques::FULL
        },
        frames: 0..viewer.frames(),
        linear: false,
        rsvp: RsvpKnobs::default_for(scene.samples),
        traced_images: true,
        sample_memory,
        ..Options::new(Techniques::FULL, 0..1)
    };
    let mut current: Option<(AnimatorKind, Animator)> = None;
    // What the animators of the other kinds of view kept, so switching
    // back (zooming out to zoom 1 and in again) goes on from their samples.
    let mut stashed: Vec<(AnimatorKind, KeptSamples)> = Vec::new();
    let mut request = Some(first);
    loop {
        let (mut generation, mut state) = request.take().or_else(|| next_request(shared))?;
        if viewer.size_of(&state) != scenes.size {
            return Some((generation, state));
        }
        let mut kind = AnimatorKind::of(&state);
        if current.as_ref().map(|(k, _)| *k) != Some(kind) {
            // The old animator lets go of the accelerator first.
            if let Some((old_kind, old)) = current.take() {
                if let Some(kept) = old.into_kept() {
                    stashed.retain(|(k, _)| *k != old_kind);
                    stashed.push((old_kind, kept));
                }
                // Under a cap, what the other kinds of view kept takes at
                // most half of it (the latest left keeps the most), and
                // the view shown the rest.
                if let Some(cap) = sample_memory {
                    let mut left = cap / 2;
                    for (_, kept) in stashed.iter_mut().rev() {
                        kept.trim(left);
                        left = left.saturating_sub(kept.kept_bytes());
                    }
                }
            }
            if let Some(at) = stashed.iter().position(|(k, _)| *k == kind) {
                let (_, kept) = stashed.swap_remove(at);
                let scene = scenes.of(kind, false);
                let mut animator = Animator::interactive(scene, accel, options(kind, scene));
                animator.resume(kept);
                current = Some((kind, animator));
            }
        }
        if current.as_ref().map(|(k, _)| *k) != Some(kind) {
            // A new animator starts its buffers from nothing (a full
            // trace, or several for a viewport's levels): show a coarse
            // picture, traced afresh, first.
            let coarse_scene = scenes.of(kind, true);
            let coarse_options = Options {
                techniques: Techniques::FULL,
                ..options(kind, coarse_scene)
            };
            let mut coarse = Animator::interactive(coarse_scene, accel, coarse_options);
            let picture = render_coarse(&mut coarse, viewer, generation, state.clone());
            drop(coarse);
            publish(shared, notify, picture);
            // Input that came meanwhile is what the full picture shows.
            if let Some(newer) = newer_request(shared) {
                if viewer.size_of(&newer.1) != scenes.size {
                    return Some(newer);
                }
                (generation, state) = newer;
                kind = AnimatorKind::of(&state);
            }
            let scene = scenes.of(kind, false);
            current = Some((
                kind,
                Animator::interactive(scene, accel, options(kind, scene)),
            ));
        }
        let (_, animator) = current.as_mut().expect("an animator for the state");
        let stashed_bytes: u64 = stashed.iter().map(|(_, k)| k.kept_bytes()).sum();
        animator.set_sample_memory(sample_memory.map(|cap| cap.saturating_sub(stashed_bytes)));
        let Some(mut picture) = render(
            animator,
            viewer,
            generation,
            state.clone(),
            Some(&shared.preempt),
        ) else {
            // A newer request is waiting: it is served next, afresh.
            abandon(shared, generation, viewer.samples(), true);
            continue;
        };
        picture.converged = rungs.is_empty();
        publish(shared, notify, picture);
        refine(serving, animator, generation, &state);
    }
}

/// Refines the picture of `state` up the ladder while nothing new is
/// asked: each rung traced afresh in bands, published when done; a
/// request waiting abandons it.
fn refine(serving: &Serving, animator: &mut Animator, generation: u64, state: &ViewState) {
    let Serving {
        shared,
        viewer,
        rungs,
        notify,
        ..
    } = *serving;
    if rungs.is_empty() {
        return;
    }
    let view = viewer.view(state);
    let camera_view = Viewer::is_camera_view(state);
    let (width, height) = (view.pose.camera.width, view.pose.camera.height);
    let (scene, accel) = animator.posed_scene(state.frame);
    let shader = Shader::new(scene, accel);
    let stop = || asked_meanwhile(shared);
    let reuse_traced = lock(&shared.outbox)
        .frame_loop
        .as_ref()
        .filter(|p| p.generation == generation)
        .map(|p| p.traced.clone());
    for (rung, &spp) in rungs.iter().enumerate() {
        let watch = Stopwatch::start();
        let samples = PixelSamples::new(spp).expect("the ladder's counts are checked");
        // The camera's image as a render of the camera traces it; a
        // viewport through its own rays, the frame loop's reference.
        let traced = if camera_view {
            let table = RayTable::with_samples(&view.pose.camera, samples);
            trace_in_bands(&shader, &table, width, height, &stop)
        } else {
            let rays = ViewportRays {
                pose: &view.pose,
                samples,
            };
            trace_in_bands(&shader, &rays, width, height, &stop)
        };
        let Some((frame, rays)) = traced else {
            return abandon(shared, generation, spp, false);
        };
        let trace_ms = watch.ms();
        let image = frame.to_rgb8();
        let pixels = u64::from(width) * u64::from(height);
        let stats = FrameStats {
            frame: state.frame,
            view: view.name.clone(),
            mode: FrameMode::Full,
            pixels,
            work: ViewWork {
                // Every pixel, each through `spp` rays.
                samples_traced: pixels,
                rays,
                trace_ms,
                assembly_ms: watch.ms() - trace_ms,
                ..ViewWork::default()
            },
            ..FrameStats::default()
        };
        let picture = Picture {
            generation,
            state: state.clone(),
            image,
            traced: reuse_traced
                .clone()
                .unwrap_or_else(|| image::RgbImage::new(width, height)),
            stats,
            stage: Stage::Refined,
            done: Instant::now(),
            complete: true,
            samples: spp,
            converged: rung + 1 == rungs.len(),
        };
        if !publish_refined(shared, notify, picture) {
            return abandon(shared, generation, spp, false);
        }
    }
}

/// The frame loop's picture of `state`; None if `stop` (a newer request
/// waiting) made it give up (a picture traced from nothing).
fn render(
    animator: &mut Animator,
    viewer: &Viewer,
    generation: u64,
    state: ViewState,
    stop: Option<&AtomicBool>,
) -> Option<Picture> {
    let view = viewer.view(&state);
    let output = animator
        .render_views(state.frame, vec![view], stop)?
        .pop()
        .expect("one view, one picture");
    Some(Picture {
        generation,
        stats: output.stats,
        stage: Stage::FrameLoop,
        done: Instant::now(),
        traced: output.traced_image.expect("traced images asked for"),
        image: output.image,
        complete: true,
        samples: viewer.samples(),
        converged: false,
        state,
    })
}

/// A picture of `state` traced at the coarse size and magnified to the
/// full one (each coarse pixel a block).
fn render_coarse(
    animator: &mut Animator,
    viewer: &Viewer,
    generation: u64,
    state: ViewState,
) -> Picture {
    let view = viewer.coarse_view(&state, COARSE_FACTOR);
    let output = animator
        .render_views(state.frame, vec![view], None)
        .expect("nothing to stop it")
        .pop()
        .expect("one view, one picture");
    let (width, height) = viewer.picture_size(&state);
    let magnify = |image: &image::RgbImage| {
        image::RgbImage::from_fn(width, height, |x, y| {
            *image.get_pixel(x / COARSE_FACTOR, y / COARSE_FACTOR)
        })
    };
    Picture {
        generation,
        done: Instant::now(),
        stage: Stage::Coarse,
        traced: magnify(
            output
                .traced_image
                .as_ref()
                .expect("traced images asked for"),
        ),
        image: magnify(&output.image),
        stats: output.stats,
        complete: false,
        samples: viewer.samples(),
        converged: false,
        state,
    }
}

#[cfg(test)]
mod tests;
