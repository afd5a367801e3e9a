//! The timeline and the frame loop: the one place that decides what a frame
//! must trace.
//!
//! Every frame's state is computed from its frame number and the keyframes,
//! never accumulated from the previous frame, so frame 10,000 is as exact as
//! frame 1.

use std::time::Instant;

use glam::Affine3A;

use crate::accel::Accelerator;
use crate::camera::RayTable;
use crate::camera::ViewportPose;
use crate::camera::{Camera, Projection};
use crate::geometry::Light;
use crate::geometry::Placement;
use crate::metrics::ImageError;
use crate::render::{render_view, Frame};
use crate::reuse::ostc::{Footprint, Ostc, DEFAULT_VOXELS};
use crate::reuse::pan::{
    image_window, render_window, EqualAngleLattice, Lattice, PanBuffer, Window,
};
use crate::reuse::regions::{RegionGrid, RegionLayout, RegionSet};
use crate::reuse::rsvp::{render_direct, RsvpKnobs, SampleBuffer, SampleLattice};
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};
use crate::timeline::Animation;

/// How a pan by a fraction of a sample is shown.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FractionalPan {
    /// Move the view to the nearest whole sample (exact: equals a full
    /// render of the snapped view; the angle is off by at most half a
    /// sample).
    #[default]
    Snap,
    /// Resample the exact view bilinearly from the buffer (the true angle;
    /// slightly blurred, error measured against the camera's own rays).
    Resample,
}

impl std::str::FromStr for FractionalPan {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "snap" => Ok(FractionalPan::Snap),
            "resample" => Ok(FractionalPan::Resample),
            other => Err(format!(
                "unknown fractional pan '{other}' (expected snap or resample)"
            )),
        }
    }
}

/// Which reuse techniques a run may use (`--mode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Techniques {
    pub pan: bool,
    /// RSVP: viewports resample the lazily traced camera sample buffer.
    pub rsvp: bool,
    pub ostc: bool,
}

impl Techniques {
    pub const FULL: Techniques = Techniques {
        pan: false,
        rsvp: false,
        ostc: false,
    };
    /// Everything the timeline allows.
    pub const AUTO: Techniques = Techniques {
        pan: true,
        rsvp: true,
        ostc: true,
    };

    /// Parses `full`, `auto`, or a comma list of techniques (`pan`, `rsvp`,
    /// `ostc`).
    pub fn parse(text: &str) -> Result<Techniques, String> {
        let mut techniques = Techniques::FULL;
        for word in text.split(',').map(str::trim) {
            match word {
                "full" => {}
                "auto" => techniques = Techniques::AUTO,
                "pan" => techniques.pan = true,
                "ostc" => techniques.ostc = true,
                "rsvp" => techniques.rsvp = true,
                other => {
                    return Err(format!(
                        "unknown mode '{other}' (expected full, auto, or a comma list of: pan, rsvp, ostc)"
                    ))
                }
            }
        }
        Ok(techniques)
    }

    fn buffered(self) -> bool {
        self.pan || self.ostc
    }
}

/// What one frame did and cost.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    pub frame: u32,
    /// How the frame was made: `full`; from a camera buffer, `pan`, `ostc`,
    /// `pan+ostc` or `still` (a still camera's own image, nothing moving);
    /// from viewports, `rsvp` or `rsvp+ostc`.
    pub mode: &'static str,
    /// Why a frame that could have reused did not (empty otherwise).
    pub reason: String,
    pub pixels: u64,
    pub pixels_reused: u64,
    pub samples_traced: u64,
    pub primary_rays: u64,
    pub shadow_rays: u64,
    pub reflection_rays: u64,
    /// OSTC: regions found dirty (object or light changes) and erased.
    pub dirty_regions: u64,
    /// OSTC: traced samples nulled by the erasure.
    pub samples_nulled: u64,
    /// OSTC: voxel visits while recording this frame's rays.
    pub voxels_walked: u64,
    /// OSTC: time recording rays (summed over threads) and finding and
    /// erasing dirty regions.
    pub bookkeeping_ms: f64,
    pub trace_ms: f64,
    /// Everything else: copying samples out of the buffer, conversion to
    /// 8 bits, buffer set-up, scene updates.
    pub copy_ms: f64,
    pub total_ms: f64,
    /// Snapped minus requested yaw and pitch, degrees (pan lattice only).
    pub yaw_error_deg: f64,
    pub pitch_error_deg: f64,
    /// With verification: time of the full render of the same frame.
    pub full_ms: Option<f64>,
    /// full_ms / total_ms.
    pub speedup: Option<f64>,
    /// With verification: pixels differing from the full render.
    pub differing_pixels: Option<u64>,
    /// With verification: regions of the output image (the OSTC region
    /// size, tiled from its corner) whose pixels truly changed since the
    /// previous frame. What `dirty_regions` would be at best, though that
    /// counts regions of the buffer (its whole turn, off-screen ones too).
    pub changed_regions: Option<u64>,
    /// With verification: the frame's error against the camera's own,
    /// unsnapped rays (what snapping or resampling costs).
    pub error: Option<ImageError>,
    /// RSVP: the viewport this row is about (empty: the camera's image).
    pub viewport: String,
    /// RSVP: the finest and the coarsest pyramid level the viewport read
    /// (a level's number is its finer axis's,
    /// [`crate::reuse::rsvp::Level::finest`]).
    pub finest_level: Option<u32>,
    pub coarsest_level: Option<u32>,
}

impl FrameStats {
    /// Why this frame was rendered in full though reuse was asked for (a
    /// pan on a camera that is not equal-angle, say), if it was.
    pub fn refusal(&self) -> Option<&str> {
        (self.mode == "full" && !self.reason.is_empty()).then_some(self.reason.as_str())
    }

    fn count_rays(&mut self, rays: RayCounts) {
        self.primary_rays = rays.primary;
        self.shadow_rays = rays.shadow;
        self.reflection_rays = rays.reflection;
    }
}

/// Where the scene's moving parts were when a buffer's samples were traced.
#[derive(Clone, Debug, PartialEq)]
struct ScenePose {
    /// Where each animated object is (in the order of the tracks).
    places: Vec<Footprint>,
    lights: Vec<Light>,
}

impl ScenePose {
    fn of(scene: &Scene, animation: Option<&Animation>) -> ScenePose {
        let places = animation
            .into_iter()
            .flat_map(|a| &a.objects)
            .flat_map(|track| &track.objects)
            .map(|&object| footprint(&scene.objects[object]))
            .collect();
        ScenePose {
            places,
            lights: scene.lights.clone(),
        }
    }
}

/// Where an object is in the world, for OSTC.
fn footprint(object: &crate::geometry::Object) -> Footprint {
    match (&object.shape, object.placement) {
        (crate::geometry::Shape::Sphere(sphere), Placement::Instance(xf)) => Footprint::Ball {
            center: xf.transform_point3(sphere.center),
            // Motion is rigid: any axis gives the scale.
            radius: sphere.radius * xf.matrix3.x_axis.length(),
        },
        (crate::geometry::Shape::Sphere(sphere), Placement::World) => Footprint::Ball {
            center: sphere.center,
            radius: sphere.radius,
        },
        _ => Footprint::Box(object.world_bounds()),
    }
}

/// OSTC settings (`--regions`, `--ostc-voxels`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OstcSettings {
    pub regions: RegionGrid,
    pub voxels: u32,
}

impl Default for OstcSettings {
    fn default() -> Self {
        OstcSettings {
            regions: RegionGrid::default(),
            voxels: DEFAULT_VOXELS,
        }
    }
}

/// Where a buffered run keeps its samples.
enum Store {
    /// Equal-angle cameras: the world-fixed lattice (a pan is a shift).
    Lattice(PanBuffer),
    /// Any other camera, held still: its own image (for OSTC).
    Image(PanBuffer<RayTable>),
}

impl Store {
    fn regions(&self, size: (i64, i64)) -> crate::reuse::regions::RegionLayout {
        match self {
            Store::Lattice(pan) => pan.regions(size),
            Store::Image(image) => image.regions(size),
        }
    }

    fn erase(
        &mut self,
        layout: &crate::reuse::regions::RegionLayout,
        regions: &crate::reuse::regions::RegionSet,
    ) -> u64 {
        match self {
            Store::Lattice(pan) => pan.erase(layout, regions),
            Store::Image(image) => image.erase(layout, regions),
        }
    }

    /// Where `camera` looks in the store.
    fn window(&self, camera: &Camera) -> Window {
        match self {
            Store::Lattice(pan) => pan.lattice().window(camera),
            Store::Image(image) => image_window(image.lattice()),
        }
    }
}

/// The sample buffer and what goes with its samples.
struct Buffered {
    store: Store,
    /// Bookkeeping, when OSTC is on and something in the scene moves.
    ostc: Option<Ostc>,
    /// The scene as it was when the buffer's samples were traced.
    pose: ScenePose,
    /// The window the buffer last showed (a still camera shows the same).
    window: Window,
}

/// The most memory a pan buffer may take. A narrow equal-angle view keeps
/// a whole turn of its fine samples (E1's: 17 MB; 0.1 degrees over 640 px:
/// 17 GB): beyond this, frames are rendered in full, with the reason.
pub const PAN_BUFFER_LIMIT_BYTES: f64 = 2e9;

/// The most memory OSTC's region bits and grid may take (E3's: 1 MB). Fine
/// regions over a narrow view's whole-turn buffer, or a huge voxel grid,
/// would pass it: OSTC is then off, with the reason.
pub const OSTC_LIMIT_BYTES: f64 = 2e9;

/// Renders the frames of one animation, reusing what it may.
pub struct Animator<'a> {
    /// The scene as loaded.
    base: &'a Scene,
    /// The scene posed at `posed_frame`: animated objects and lights moved.
    scene: Scene,
    posed_frame: Option<u32>,
    accel: &'a mut Accelerator,
    techniques: Techniques,
    buffer: Option<Buffered>,
    /// Frames of the run, to size the pan buffer's rows.
    frame_range: std::ops::Range<u32>,
    /// Whether reused frames are also assembled in linear colour.
    linear_output: bool,
    fractional: FractionalPan,
    ostc_settings: OstcSettings,
    /// Whether to keep, per frame, the image with re-traced samples black.
    keep_traced_image: bool,
    traced_image: Option<image::RgbImage>,
    /// Whether the camera changes at all over the timeline.
    camera_moves: bool,
    /// The most a pan buffer of this timeline's views could take, in bytes.
    pan_buffer_bytes: f64,
    /// Why OSTC, asked for, could not be kept.
    ostc_refusal: Option<String>,
    /// Per pan lattice (see [`lattice_key`]), the rows the run's views of
    /// it cover.
    row_spans: std::collections::HashMap<LatticeKey, (i64, i64)>,
    samples: Option<SampleBuffer>,
    /// The scene as it was when the sample buffer's samples were traced.
    samples_pose: Option<ScenePose>,
    knobs: RsvpKnobs,
}

/// One viewport's image of a frame, and what it cost.
pub struct ViewportOutput {
    pub name: String,
    /// Linear colour, unless turned off.
    pub frame: Option<Frame>,
    pub image: image::RgbImage,
    pub stats: FrameStats,
}

impl<'a> Animator<'a> {
    pub fn new(
        scene: &'a Scene,
        accel: &'a mut Accelerator,
        techniques: Techniques,
        frames: std::ops::Range<u32>,
    ) -> Animator<'a> {
        let mut animator = Animator {
            base: scene,
            scene: scene.clone(),
            posed_frame: None,
            accel,
            techniques,
            buffer: None,
            frame_range: frames,
            linear_output: true,
            fractional: FractionalPan::Snap,
            ostc_settings: OstcSettings::default(),
            keep_traced_image: false,
            traced_image: None,
            samples: None,
            samples_pose: None,
            knobs: RsvpKnobs::default(),
            camera_moves: false,
            pan_buffer_bytes: 0.0,
            ostc_refusal: None,
            row_spans: std::collections::HashMap::new(),
        };
        // Over the whole timeline, not just this run: whether frames live on
        // the lattice must not depend on which frames a run renders, or a
        // chunk of a render farm's run would differ from one long run.
        let timeline = scene.animation.as_ref().map_or(0..0, |a| 0..a.frames);
        let first = animator.camera_at(0);
        // The rows every equal-angle view reaches, top and bottom.
        let (mut top, mut bottom, mut bytes) = (i64::MAX, i64::MIN, 0f64);
        for frame in timeline.chain(animator.frame_range.clone()) {
            let camera = animator.camera_at(frame);
            animator.camera_moves |= camera != first;
            if camera.projection != Projection::EqualAngle {
                continue;
            }
            let seen = EqualAngleLattice::rows_seen(&camera);
            (top, bottom) = (top.min(seen.start), bottom.max(seen.end));
            // Resampling reads a row more on either side.
            let span = bottom.saturating_sub(top).saturating_add(2);
            bytes = bytes.max(EqualAngleLattice::buffer_bytes(&camera, span));
            // Each lattice's rows, found once here rather than at every
            // restart (an eye that moves every frame restarts every frame).
            if animator.frame_range.contains(&frame) {
                let span = animator
                    .row_spans
                    .entry(lattice_key(&camera))
                    .or_insert((seen.start, seen.end));
                *span = (span.0.min(seen.start), span.1.max(seen.end));
            }
        }
        animator.pan_buffer_bytes = bytes;
        animator
    }

    pub fn set_rsvp_knobs(&mut self, knobs: RsvpKnobs) {
        self.knobs = knobs;
    }

    /// Whether the scene's output is its viewports (RSVP) rather than the
    /// camera's image.
    pub fn has_viewports(&self) -> bool {
        !self.scene.viewports.is_empty()
    }

    /// Every viewport at `frame`.
    pub fn viewport_poses(&self, frame: u32) -> Vec<ViewportPose> {
        let camera = self.camera_at(frame);
        self.scene
            .viewports
            .iter()
            .map(|track| track.pose_at(&camera, frame))
            .collect()
    }

    /// Viewport `index` at `frame`, traced through its own rays: the
    /// reference RSVP frames are measured against.
    pub fn render_viewport_direct(&mut self, frame: u32, index: usize) -> (Frame, RayCounts) {
        self.pose(frame);
        let pose = self.scene.viewports[index].pose_at(&self.camera_at(frame), frame);
        render_direct(&Shader::new(&self.scene, self.accel), &pose)
    }

    /// The camera's sample buffer around the view at `frame`: traced samples
    /// in colour, never-traced ones black (None before RSVP ran).
    pub fn buffer_image(&self, frame: u32) -> Option<image::RgbImage> {
        let camera = self.camera_at(frame);
        let buffer = self.samples.as_ref()?;
        Some(buffer.buffer_image(&camera, self.scene.camera.width, self.scene.camera.height))
    }

    /// With RSVP, viewport `index`'s image of the last frame rendered with
    /// every pixel black that read a sample traced for that frame; None
    /// without a sample buffer.
    pub fn viewport_fresh_image(
        &self,
        frame: u32,
        index: usize,
        image: &image::RgbImage,
    ) -> Option<image::RgbImage> {
        let buffer = self.samples.as_ref()?;
        let pose = self.viewport_poses(frame).into_iter().nth(index)?;
        Some(buffer.fresh_image(&pose, &self.knobs, image))
    }

    /// With RSVP, re-traces every sample the buffer keeps (the scene posed
    /// at the last frame rendered) and compares bit for bit: (samples
    /// compared, samples that differ); None without a sample buffer.
    pub fn verify_sample_buffer(&self) -> Option<(u64, u64)> {
        let buffer = self.samples.as_ref()?;
        let shader = Shader::new(&self.scene, self.accel);
        Some(buffer.verify(&shader))
    }

    /// Renders every viewport of `frame`: with RSVP from the sample buffer
    /// (tracing, in one batch, the null samples they touch), otherwise
    /// each through its own rays.
    pub fn render_viewports(&mut self, frame: u32) -> Vec<ViewportOutput> {
        let start = Instant::now();
        let camera = self.camera_at(frame);
        let poses = self.viewport_poses(frame);
        self.pose(frame);
        let scene_pose = ScenePose::of(&self.scene, self.animation());
        let moved = self
            .samples_pose
            .as_ref()
            .is_some_and(|traced| *traced != scene_pose);
        let shader = Shader::new(&self.scene, self.accel);
        let names = self.scene.viewports.iter().map(|t| t.viewport.name.clone());
        let pixels =
            |pose: &ViewportPose| u64::from(pose.camera.width) * u64::from(pose.camera.height);
        if !self.techniques.rsvp {
            self.samples = None;
            return poses
                .iter()
                .zip(names)
                .map(|(pose, name)| {
                    let start = Instant::now();
                    let (image, rays) = render_direct(&shader, pose);
                    let rgb = image.to_rgb8();
                    let ms = start.elapsed().as_secs_f64() * 1e3;
                    let mut stats = FrameStats {
                        frame,
                        mode: "full",
                        pixels: pixels(pose),
                        samples_traced: rays.primary,
                        trace_ms: ms,
                        total_ms: ms,
                        viewport: name.clone(),
                        ..FrameStats::default()
                    };
                    stats.count_rays(rays);
                    ViewportOutput {
                        name,
                        frame: Some(image),
                        image: rgb,
                        stats,
                    }
                })
                .collect();
        }
        let mut reason = String::new();
        let lattice = SampleLattice::for_camera(&self.scene.camera);
        let restart = match &self.samples {
            None => Some("first frame".to_string()),
            Some(buffer) if moved && buffer.ostc().is_none() => {
                Some(self.moved_without_ostc("sample buffer"))
            }
            Some(buffer) if buffer.lattice().position != camera.position => {
                Some("eye moved: sample buffer restarted".to_string())
            }
            Some(buffer) if buffer.lattice().columns_per_turn != lattice.columns_per_turn => {
                Some("buffer resolution changed: restarted".to_string())
            }
            Some(_) => None,
        };
        let (mut dirty_count, mut erased, mut book_ms) = (0u64, 0u64, 0.0);
        if let Some(why) = restart {
            let mut buffer = SampleBuffer::new(SampleLattice::new(
                camera.position,
                lattice.columns_per_turn,
            ));
            let ostc = self.new_ostc(|size| buffer.regions(size));
            buffer.set_ostc(kept_ostc(&mut self.ostc_refusal, ostc));
            self.samples = Some(buffer);
            reason = why;
        } else if moved {
            // OSTC: erase what the motion can change; viewports trace it
            // again when they read it.
            let book_start = Instant::now();
            let buffer = self.samples.as_mut().expect("kept buffer");
            let old = self
                .samples_pose
                .as_ref()
                .expect("a kept buffer has a pose");
            let ostc = buffer.ostc().expect("restarted unless ostc is on");
            // A moved light dirties whole regions; a moved object only the
            // groups whose rays meet it (finer levels hold many groups to
            // a region).
            let lit = dirty_by_lights(ostc, old, &scene_pose);
            let (regions, groups) = dirty_groups(ostc, old, &scene_pose);
            let mut touched = regions.clone();
            touched.union_with(&lit);
            dirty_count = touched.len() as u64;
            erased = (buffer.erase(&lit) + buffer.erase_groups(&groups))
                * u64::from(crate::render::GROUP_WIDTH * crate::render::GROUP_HEIGHT);
            let ostc = buffer.ostc_mut().expect("just used");
            ostc.forget(&lit);
            ostc.forget_groups(&regions, &groups);
            book_ms = book_start.elapsed().as_secs_f64() * 1e3;
        }
        self.samples_pose = Some(scene_pose);
        let buffer = self.samples.as_mut().expect("sample buffer just ensured");
        let setup_ms = start.elapsed().as_secs_f64() * 1e3 - book_ms;
        let views = buffer.render(&shader, &poses, &self.knobs, self.linear_output);
        let count = views.len().max(1) as f64;
        let (walked, record_ms) = buffer.ostc().map_or((0, 0.0), Ostc::take_counters);
        // Recording ran on every worker thread: its share of the elapsed time.
        let record_share = record_ms / rayon::current_num_threads() as f64;
        let mode = if buffer.ostc().is_some() {
            "rsvp+ostc"
        } else {
            "rsvp"
        };
        views
            .into_iter()
            .zip(poses.iter().zip(names))
            .map(|(view, (pose, name))| {
                let total =
                    (setup_ms + book_ms) / count + view.map_ms + view.trace_ms + view.gather_ms;
                let mut stats = FrameStats {
                    frame,
                    mode,
                    // Frame-wide OSTC figures, shared out over the viewports.
                    dirty_regions: dirty_count,
                    samples_nulled: erased,
                    voxels_walked: walked,
                    bookkeeping_ms: (book_ms + record_share) / count,
                    reason: reason.clone(),
                    pixels: pixels(pose),
                    pixels_reused: pixels(pose).saturating_sub(view.samples_traced),
                    samples_traced: view.samples_traced,
                    trace_ms: (view.trace_ms - record_share / count).max(0.0),
                    copy_ms: total - view.trace_ms - book_ms / count,
                    total_ms: total,
                    viewport: name.clone(),
                    finest_level: Some(view.levels.1),
                    coarsest_level: Some(view.levels.0),
                    ..FrameStats::default()
                };
                stats.count_rays(view.rays);
                ViewportOutput {
                    name,
                    frame: view.frame,
                    image: view.image,
                    stats,
                }
            })
            .collect()
    }

    /// Keep, for each frame, its image with every re-traced sample black
    /// (see [`Animator::take_traced_image`]).
    pub fn set_traced_image(&mut self, keep: bool) {
        self.keep_traced_image = keep;
    }

    /// The last frame's image with the samples it traced painted black (a
    /// full render is all black), when asked for.
    pub fn take_traced_image(&mut self) -> Option<image::RgbImage> {
        self.traced_image.take()
    }

    pub fn set_fractional_pan(&mut self, fractional: FractionalPan) {
        self.fractional = fractional;
    }

    pub fn set_ostc(&mut self, settings: OstcSettings) {
        self.ostc_settings = settings;
    }

    /// Whether frames are exact (snapped) renders, comparable bit for bit
    /// with [`Animator::render_reference`].
    pub fn is_exact(&self) -> bool {
        self.fractional == FractionalPan::Snap
    }

    fn animation(&self) -> Option<&'a Animation> {
        self.base.animation.as_ref()
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

    /// What an accelerated frame is measured against: the full render of
    /// the snapped view (snap), or of the camera's own rays (resample).
    pub fn render_reference(&mut self, frame: u32) -> (Frame, RayCounts) {
        match self.fractional {
            FractionalPan::Snap => self.render_full(frame),
            FractionalPan::Resample => self.render_true_view(frame),
        }
    }

    /// Whether [`Animator::render`] returns frames in linear colour too;
    /// without them (only 8-bit output, no bit-exact checks) reused frames
    /// skip copying 12 bytes per pixel.
    pub fn set_linear_output(&mut self, linear: bool) {
        self.linear_output = linear;
    }

    pub fn camera_at(&self, frame: u32) -> Camera {
        match self.animation() {
            Some(animation) => animation.camera_at(&self.base.camera, frame),
            None => self.base.camera.clone(),
        }
    }

    /// Renders `frame` from scratch, as the reference for reuse: on the pan
    /// lattice for equal-angle cameras (so a snapped pan compares exactly),
    /// through the camera's own rays otherwise.
    pub fn render_full(&mut self, frame: u32) -> (Frame, RayCounts) {
        self.pose(frame);
        let camera = self.camera_at(frame);
        let shader = Shader::new(&self.scene, self.accel);
        if self.on_lattice(&camera) {
            let lattice = EqualAngleLattice::for_camera(&camera);
            let window = lattice.window(&camera);
            return render_window(&shader, &lattice, &window);
        }
        render_view(&self.scene, &camera, self.accel)
    }

    /// The scene posed at `frame`, ready to trace, and the camera there:
    /// for untimed passes that need the shading itself (the bench's ray
    /// costs).
    pub fn posed_shader(&mut self, frame: u32) -> (Shader<'_>, Camera) {
        self.pose(frame);
        let camera = self.camera_at(frame);
        (Shader::new(&self.scene, self.accel), camera)
    }

    /// The camera's own rays at `frame`, unsnapped: the exact picture any
    /// pan approximation is measured against.
    pub fn render_true_view(&mut self, frame: u32) -> (Frame, RayCounts) {
        self.pose(frame);
        render_view(&self.scene, &self.camera_at(frame), self.accel)
    }

    /// Whether frames of `camera` live on the pan lattice: an equal-angle
    /// camera that pans during the run. A camera that stands still keeps
    /// its own image instead: its exact view, with no snapping to the
    /// lattice.
    fn pans(&self, camera: &Camera) -> bool {
        self.techniques.pan && self.on_lattice(camera)
    }

    /// Whether a full render of `camera` is taken on the pan lattice, so
    /// that a pan (by any animator of this timeline) compares with it bit
    /// for bit: equal-angle cameras of a timeline that moves the camera.
    fn on_lattice(&self, camera: &Camera) -> bool {
        camera.projection == Projection::EqualAngle
            && self.camera_moves
            && self.pan_buffer_bytes <= PAN_BUFFER_LIMIT_BYTES
    }

    /// Why `camera` cannot use a sample buffer, if it cannot.
    fn buffer_refusal(&self, camera: &Camera, frame: u32) -> Option<String> {
        if !self.techniques.buffered() {
            return Some(String::new());
        }
        let equal_angle = camera.projection == Projection::EqualAngle;
        if self.techniques.pan && equal_angle && self.camera_moves && !self.on_lattice(camera) {
            return Some(format!(
                "a pan buffer at this field of view (a whole turn of samples) would take \
                 {:.1} GB; the limit is {:.0} GB",
                self.pan_buffer_bytes / 1e9,
                PAN_BUFFER_LIMIT_BYTES / 1e9
            ));
        }
        if self.pans(camera) {
            return None;
        }
        if !self.techniques.ostc && camera.projection != Projection::EqualAngle {
            return Some(format!(
                "pan needs an equal-angle camera, not {}",
                camera.projection
            ));
        }
        // Without panning a buffer holds only while the camera stands still.
        let moves = |other: u32| self.camera_at(other) != *camera;
        let still = (frame == 0 || !moves(frame - 1)) && !moves(frame + 1);
        (!still).then(|| match camera.projection {
            Projection::EqualAngle => "the camera moves and pan is off".to_string(),
            projection => format!("the {projection} camera moves: only equal-angle views pan"),
        })
    }

    /// A sample buffer for `camera`: the pan lattice, sized for every
    /// window of this run that shares it, for the cameras whose frames live
    /// there (with pan off too, so they equal full renders); the camera's
    /// own image otherwise.
    fn new_store(&self, camera: &Camera) -> Store {
        if !self.on_lattice(camera) {
            let table = RayTable::new(camera);
            let rows = table.rows();
            return Store::Image(PanBuffer::new(table, 0..rows));
        }
        let lattice = EqualAngleLattice::for_camera(camera);
        let window = lattice.window(camera);
        let (mut low, mut high) = (window.row, window.row + i64::from(window.height));
        if let Some(&(top, bottom)) = self.row_spans.get(&lattice_key(camera)) {
            (low, high) = (low.min(top), high.max(bottom));
        }
        // A resampled view reads up to one row more on either side.
        Store::Lattice(PanBuffer::new(lattice, low - 1..high + 1))
    }

    /// OSTC bookkeeping for `store`, when it is on and the timeline moves
    /// something (no grid when no object moves, no light bookkeeping when
    /// no light moves).
    ///
    /// Without it (off, or refused with a reason, which [`kept_ostc`] keeps
    /// for [`Animator::ostc_refusal`]) a buffer restarts whenever something
    /// moves, which is always exact.
    fn new_ostc(
        &self,
        regions: impl FnOnce((i64, i64)) -> RegionLayout,
    ) -> Result<Option<Ostc>, String> {
        let Some(animation) = self.animation() else {
            return Ok(None);
        };
        if !self.techniques.ostc || !animation.moves_scene() {
            return Ok(None);
        }
        let swept = (!animation.objects.is_empty()).then(|| swept_bounds(self.base, animation));
        if swept.is_some_and(|b| !(b.max - b.min).is_finite()) {
            return Err(
                "the moving objects' swept bounds are not finite (no grid fits them)".into(),
            );
        }
        // Regions are cut from the scene camera's screen, whatever views it.
        let camera = &self.base.camera;
        let size = self
            .ostc_settings
            .regions
            .region_size(camera.width, camera.height);
        let mut animated_lights = vec![false; self.base.lights.len()];
        for track in &animation.lights {
            animated_lights[track.light] = true;
        }
        let layout = regions(size);
        let voxels = self.ostc_settings.voxels;
        let bytes = Ostc::bytes_for(layout.count(), voxels, swept.is_some());
        if bytes > OSTC_LIMIT_BYTES {
            return Err(format!(
                "its bookkeeping ({} regions of {}x{} samples, {voxels} voxels) would take \
                 {:.1} GB; the limit is {:.0} GB",
                layout.count(),
                size.0,
                size.1,
                bytes / 1e9,
                OSTC_LIMIT_BYTES / 1e9
            ));
        }
        Ok(Some(Ostc::new(layout, swept, voxels, &animated_lights)))
    }

    /// Why OSTC was asked for but not kept, if it was not: buffers then
    /// restart whenever something moves.
    pub fn ostc_refusal(&self) -> Option<&str> {
        self.ostc_refusal.as_deref()
    }

    /// Why a buffer restarts when something moved.
    fn moved_without_ostc(&self, what: &str) -> String {
        let off = match self.ostc_refusal {
            Some(_) => "OSTC was refused (see the run's warning)",
            None => "ostc is off",
        };
        format!("objects or lights moved and {off}: {what} restarted")
    }

    /// Renders one frame with whatever reuse applies: the frame in linear
    /// colour (unless turned off), the same as 8-bit sRGB (frame assembly is
    /// part of the cost), and what it took.
    pub fn render(&mut self, frame: u32) -> (Option<Frame>, image::RgbImage, FrameStats) {
        let start = Instant::now();
        self.pose(frame);
        let camera = self.camera_at(frame);
        let mut stats = FrameStats {
            frame,
            pixels: u64::from(camera.width) * u64::from(camera.height),
            ..FrameStats::default()
        };
        let (image, rgb) = match self.buffer_refusal(&camera, frame) {
            Some(reason) => {
                self.buffer = None;
                stats.mode = "full";
                stats.reason = reason;
                let trace_start = Instant::now();
                let (image, rays) = self.render_full(frame);
                stats.trace_ms = trace_start.elapsed().as_secs_f64() * 1e3;
                stats.samples_traced = rays.primary;
                stats.count_rays(rays);
                let rgb = image.to_rgb8();
                if self.keep_traced_image {
                    self.traced_image = Some(image::RgbImage::new(rgb.width(), rgb.height()));
                }
                (Some(image), rgb)
            }
            None => self.render_buffered(&camera, &mut stats),
        };
        stats.total_ms = start.elapsed().as_secs_f64() * 1e3;
        stats.copy_ms = (stats.total_ms - stats.trace_ms - stats.bookkeeping_ms).max(0.0);
        (image, rgb, stats)
    }

    /// Why the buffer cannot carry over to a view of `camera` with the scene
    /// posed as `pose`, if it cannot.
    fn restart_reason(&self, camera: &Camera, pose: &ScenePose) -> Option<String> {
        let Some(buffered) = &self.buffer else {
            return Some("first frame".to_string());
        };
        match &buffered.store {
            Store::Lattice(pan) => {
                if !pan.lattice().fits(camera) {
                    return Some("eye or field of view changed: buffer restarted".to_string());
                }
                let read = match self.fractional {
                    FractionalPan::Snap => pan.lattice().window(camera),
                    FractionalPan::Resample => pan.resample_window(camera).0,
                };
                if !pan.covers(&read) {
                    return Some("view left the pan buffer's rows: restarted".to_string());
                }
                let window = pan.lattice().window(camera);
                let moved_view =
                    (window.col, window.row) != (buffered.window.col, buffered.window.row);
                if moved_view && !self.techniques.pan {
                    return Some("the camera moved and pan is off: buffer restarted".to_string());
                }
            }
            Store::Image(image) => {
                if image.lattice().camera() != camera {
                    return Some(format!(
                        "the {} camera moved (only equal-angle views pan): buffer restarted",
                        image.lattice().camera().projection
                    ));
                }
            }
        }
        if buffered.pose != *pose && buffered.ostc.is_none() {
            return Some(self.moved_without_ostc("buffer"));
        }
        None
    }

    /// Erases, in the buffer, what changed since its samples were traced.
    fn erase_dirty(buffered: &mut Buffered, pose: ScenePose, stats: &mut FrameStats) {
        let ostc = buffered
            .ostc
            .as_mut()
            .expect("buffers restart on changes unless ostc is on");
        let book_start = Instant::now();
        let dirty = dirty_regions(ostc, &buffered.pose, &pose);
        stats.dirty_regions = dirty.len() as u64;
        stats.samples_nulled = buffered.store.erase(ostc.layout(), &dirty);
        ostc.forget(&dirty);
        buffered.pose = pose;
        stats.bookkeeping_ms += book_start.elapsed().as_secs_f64() * 1e3;
    }

    fn render_buffered(
        &mut self,
        camera: &Camera,
        stats: &mut FrameStats,
    ) -> (Option<Frame>, image::RgbImage) {
        let pose = ScenePose::of(&self.scene, self.animation());
        if let Some(reason) = self.restart_reason(camera, &pose) {
            let store = self.new_store(camera);
            let ostc = self.new_ostc(|size| store.regions(size));
            let ostc = kept_ostc(&mut self.ostc_refusal, ostc);
            let window = store.window(camera);
            self.buffer = Some(Buffered {
                store,
                ostc,
                pose: pose.clone(),
                window,
            });
            stats.reason = reason;
        }
        let buffered = self.buffer.as_mut().expect("buffer just ensured");
        if buffered.pose != pose {
            Self::erase_dirty(buffered, pose, stats);
        }
        let window = buffered.store.window(camera);
        buffered.window = window;
        let shader = Shader::new(&self.scene, self.accel);
        let ostc = buffered.ostc.as_ref();
        let linear = self.linear_output;
        let trace_start = Instant::now();
        let (image, rgb, pan) = match (&mut buffered.store, self.fractional) {
            (Store::Lattice(pan), FractionalPan::Snap) => pan.frame(&shader, &window, linear, ostc),
            (Store::Lattice(pan), FractionalPan::Resample) => {
                pan.frame_resampled(&shader, camera, linear, ostc)
            }
            // A still camera's own pixels need no resampling.
            (Store::Image(image), _) => image.frame(&shader, &window, linear, ostc),
        };
        let elapsed = trace_start.elapsed().as_secs_f64() * 1e3;
        if let Some(ostc) = ostc {
            let (walked, record_ms) = ostc.take_counters();
            stats.voxels_walked = walked;
            // Recording runs on every worker thread: its share of the
            // elapsed time is its summed time over the threads.
            let share = record_ms / rayon::current_num_threads() as f64;
            stats.bookkeeping_ms += share;
            stats.trace_ms = (elapsed - share).max(0.0);
        } else {
            stats.trace_ms = elapsed;
        }
        let panning = self.techniques.pan && matches!(buffered.store, Store::Lattice(_));
        stats.mode = match (panning, ostc.is_some()) {
            (true, true) => "pan+ostc",
            (false, true) => "ostc",
            (true, false) => "pan",
            (false, false) => "still",
        };
        stats.pixels_reused = pan.pixels_reused;
        stats.samples_traced = pan.samples_traced;
        if self.keep_traced_image {
            let mut traced = rgb.clone();
            match (&buffered.store, self.fractional) {
                (Store::Lattice(lattice), FractionalPan::Resample) => lattice.paint_groups(
                    &lattice.resample_window(camera).0,
                    &pan.traced,
                    &mut traced,
                ),
                (Store::Lattice(lattice), FractionalPan::Snap) => {
                    lattice.paint_groups(&window, &pan.traced, &mut traced)
                }
                (Store::Image(image), _) => image.paint_groups(&window, &pan.traced, &mut traced),
            }
            self.traced_image = Some(traced);
        }
        if self.fractional == FractionalPan::Snap {
            stats.yaw_error_deg = window.yaw_error.to_degrees();
            stats.pitch_error_deg = window.pitch_error.to_degrees();
        }
        stats.count_rays(pan.rays);
        (image, rgb)
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

/// The OSTC bookkeeping [`Animator::new_ostc`] made, if it made one; the
/// reason it refused to, if it did, is kept in `refusal`.
fn kept_ostc(refusal: &mut Option<String>, made: Result<Option<Ostc>, String>) -> Option<Ostc> {
    made.unwrap_or_else(|why| {
        *refusal = Some(why);
        None
    })
}

/// The regions whose samples the change from `old` to `new` can alter.
fn dirty_regions(ostc: &Ostc, old: &ScenePose, new: &ScenePose) -> RegionSet {
    let mut dirty = dirty_by_lights(ostc, old, new);
    for (was, is) in old.places.iter().zip(&new.places) {
        if was != is {
            dirty.union_with(&ostc.dirty_for(&[*was, *is]));
        }
    }
    dirty
}

/// The regions whose samples the lights' change from `old` to `new` can
/// alter.
fn dirty_by_lights(ostc: &Ostc, old: &ScenePose, new: &ScenePose) -> RegionSet {
    let mut dirty = RegionSet::empty(ostc.layout().count());
    for (index, (was, is)) in old.lights.iter().zip(&new.lights).enumerate() {
        if was != is {
            let moved = was.position != is.position;
            dirty.union_with(&ostc.dirty_for_light(index, moved));
        }
    }
    dirty
}

/// The groups (sorted keys) whose samples the objects' moves from `old`
/// to `new` can alter, and the regions they lie in.
fn dirty_groups(ostc: &Ostc, old: &ScenePose, new: &ScenePose) -> (RegionSet, Vec<u128>) {
    let mut regions = RegionSet::empty(ostc.layout().count());
    let mut groups = Vec::new();
    for (was, is) in old.places.iter().zip(&new.places) {
        if was != is {
            let (r, g) = ostc.dirty_groups_for(&[*was, *is]);
            regions.union_with(&r);
            groups.extend(g);
        }
    }
    groups.sort_unstable();
    groups.dedup();
    (regions, groups)
}

/// Everything the animated objects of `scene` cover over the whole
/// animation (not just the frames of a run: a superset is always safe).
pub fn swept_bounds(scene: &Scene, animation: &Animation) -> crate::geometry::Aabb {
    let mut swept = crate::geometry::Aabb::EMPTY;
    for track in &animation.objects {
        let rest = track
            .objects
            .iter()
            .map(|&object| scene.objects[object].shape.bounds())
            .fold(crate::geometry::Aabb::EMPTY, |a, b| a.union(b));
        if rest.is_empty() {
            continue;
        }
        for frame in 0..animation.frames {
            swept = swept.union(rest.transformed(&track.transform_at(frame)));
        }
    }
    swept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse() {
        assert_eq!(Techniques::parse("full"), Ok(Techniques::FULL));
        assert_eq!(Techniques::parse("auto"), Ok(Techniques::AUTO));
        assert_eq!(
            Techniques::parse("pan"),
            Ok(Techniques {
                pan: true,
                rsvp: false,
                ostc: false
            })
        );
        assert_eq!(
            Techniques::parse("rsvp,pan"),
            Ok(Techniques {
                pan: true,
                rsvp: true,
                ostc: false
            })
        );
        assert_eq!(Techniques::parse("pan,ostc,rsvp"), Ok(Techniques::AUTO));
        assert!(Techniques::parse("zoom").is_err());
    }
}
