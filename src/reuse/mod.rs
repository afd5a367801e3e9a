//! The reuse algorithms: what a frame can take from earlier frames instead
//! of tracing. Reuse code never calls Embree: it decides which samples must
//! be traced and hands them to [`crate::render`].
//!
//! Every kind of kept samples is a [`SampleStore`]: the pan lattice's
//! whole turn ([`pan::PanStore`]), a still camera's own image
//! ([`still::StillStore`]) and RSVP's lazily traced pyramid
//! ([`rsvp::RsvpStore`]). The frame loop asks a store whether it can serve
//! a frame's views, erases from it what OSTC says changed, and renders the
//! views through it; a store traces only the samples it lacks.
//!
//! Every kind of store plans itself ([`StorePlan`]): from the scene's
//! timeline and the run's options it decides, before the first frame,
//! whether its stores can serve the run's frames, how large they will be
//! and, where they cannot, why ([`FullReason`]). [`plan_for`] is the
//! registry that picks the plan of a run; the frame loop asks it and
//! follows.
//!
//! Promises of every store: a sample it keeps is bit for bit what a fresh
//! trace of its group gives (groups are fixed 4x2 packets aligned to the
//! store's lattice, traced through [`crate::render`]); a sample erased is
//! traced again before any view shows it.

pub mod lattice_buffer;
mod options;
pub mod ostc;
pub mod pan;
pub mod regions;
pub mod rsvp;
pub mod still;

pub use options::{Options, OstcSettings, Technique, Techniques};

use crate::camera::{Camera, Projection, RayTable, ViewportPose};
use crate::render::{Frame, PrimaryRays};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};
use ostc::Ostc;
use regions::{RegionGrid, RegionLayout, RegionSet};

/// One output picture of a frame: the camera's image (named "") or an RSVP
/// viewport.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    pub name: String,
    pub pose: ViewportPose,
}

/// What a run asks of the stores: the scene as loaded and the options,
/// and whether the views come from a caller rather than the timeline.
#[derive(Clone, Copy)]
pub struct Run<'a> {
    pub scene: &'a Scene,
    pub options: &'a Options,
    /// Views no timeline knows in advance (an interactive viewer's): the
    /// camera may turn anywhere at any frame.
    pub interactive: bool,
}

impl Run<'_> {
    pub fn camera_at(&self, frame: u32) -> Camera {
        match &self.scene.animation {
            Some(animation) => animation.camera_at(&self.scene.camera, frame),
            None => self.scene.camera.clone(),
        }
    }

    /// Whether the scene's output is its RSVP viewports rather than the
    /// camera's image.
    pub fn has_viewports(&self) -> bool {
        !self.scene.viewports.is_empty()
    }

    /// Whether OSTC will keep a store's samples: asked for, and something
    /// other than the camera moves.
    pub fn ostc_keeps(&self) -> bool {
        self.options.techniques.ostc
            && self
                .scene
                .animation
                .as_ref()
                .is_some_and(|a| a.moves_scene())
    }

    /// Whether `camera`, shown at `frame`, stands still from the frame
    /// before to the frame after: a store that cannot follow the camera
    /// holds only then.
    pub fn camera_still_at(&self, frame: u32, camera: &Camera) -> bool {
        let moves = |other: u32| self.camera_at(other) != *camera;
        (frame == 0 || !moves(frame - 1)) && !moves(frame + 1)
    }

    /// Whether `camera`, the camera of `frame`, has its eye where it is in
    /// the frames on either side.
    pub fn eye_still_at(&self, frame: u32, camera: &Camera) -> bool {
        let moves = |other: u32| self.camera_at(other).position != camera.position;
        (frame == 0 || !moves(frame - 1)) && !moves(frame + 1)
    }
}

/// Whether a frame's views come from a store.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Serve {
    Store,
    /// Rendered in full, for the reason given (None: reuse was not asked
    /// for at all).
    Full(Option<FullReason>),
}

/// A kind of store's plan for a run, made once before its first frame
/// ([`plan_for`]).
pub trait StorePlan {
    /// Whether `views` of `frame` come from this plan's store, and if not,
    /// why.
    fn serves(&self, run: &Run, frame: u32, views: &[View]) -> Serve;

    /// A new, empty store for `views`.
    fn new_store(&self, run: &Run, views: &[View]) -> Box<dyn SampleStore>;

    /// `view` traced from scratch at `samples` a pixel through the rays a
    /// frame of this plan shows, so that a reused frame compares with it
    /// bit for bit (a snapped pan: the lattice's).
    fn render_full(
        &self,
        shader: &Shader,
        view: &View,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        self.render_own_rays(shader, view, samples)
    }

    /// `view` traced through its own, unsnapped rays at `samples` a pixel:
    /// the exact picture any approximation is measured against.
    fn render_own_rays(
        &self,
        shader: &Shader,
        view: &View,
        samples: PixelSamples,
    ) -> (Frame, RayCounts) {
        crate::render::render_camera(shader, &view.pose.camera, samples)
    }

    /// Whether this plan's frames equal [`StorePlan::render_full`] bit for
    /// bit.
    fn exact(&self) -> bool;

    /// About the most bytes the store of `views` will hold over `run`,
    /// known before it is made.
    fn store_bytes(&self, run: &Run, views: &[View]) -> f64;

    /// One ray through the centre of each pixel of the picture a frame of
    /// this plan shows of `view` (cell (x, y) for pixel (x, y)), whatever
    /// the samples a pixel: what the arbitrary output variables are cast
    /// through ([`crate::aov`]).
    fn centre_rays<'v>(&self, view: &'v View) -> Box<dyn PrimaryRays + 'v> {
        Box::new(RayTable::new(&view.pose.camera))
    }
}

/// The bytes of strata a camera store keeps for OSTC (which re-traces
/// groups of them) over `pixels` pixels: none when OSTC keeps nothing.
pub(crate) fn strata_bytes(run: &Run, pixels: f64) -> f64 {
    if !run.ostc_keeps() || run.scene.samples.count() == 1 {
        return 0.0;
    }
    let bytes =
        pixels * f64::from(run.scene.samples.count()) * std::mem::size_of::<[f32; 3]>() as f64;
    bytes.min(lattice_buffer::STRATA_LIMIT_BYTES)
}

/// The plan of `run`: RSVP's buffer for viewports; for the camera's image
/// the pan lattice where the timeline turns an equal-angle camera and its
/// buffer fits, the still camera's own image otherwise. Adding a kind of
/// store adds its case here.
pub fn plan_for(run: &Run) -> Box<dyn StorePlan + Send + Sync> {
    if run.has_viewports() {
        return Box::new(rsvp::RsvpPlan);
    }
    match pan::PanPlan::new(run) {
        Ok(pan) => Box::new(pan),
        Err(refusal) => Box::new(still::StillPlan::new(refusal)),
    }
}

/// Why `technique` cannot act on `run`, whether asked for or not; None
/// when it can. Known before the run, so flags are checked before any
/// work.
pub fn idle_reason(run: &Run, technique: Technique) -> Option<Idle> {
    match technique {
        Technique::Pan => pan::PanPlan::idle_reason(run),
        Technique::Rsvp => (!run.has_viewports()).then_some(Idle::NoViewports),
        Technique::Ostc => ostc::idle_reason(run),
    }
}

/// Why a technique cannot act on a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Idle {
    /// RSVP: nothing to resample.
    NoViewports,
    /// Pan: the output is viewports, which RSVP's buffer pans by itself.
    ViewportsPanThemselves,
    /// Pan: the camera does not move.
    CameraStill,
    /// Pan: the camera is of another projection.
    NotEqualAngle(Projection),
    /// Pan: the buffer would pass its limit.
    Full(FullReason),
    /// OSTC: no object or light moves.
    NothingMoves,
    /// OSTC: viewports traced through their own rays keep nothing.
    ViewportsWithoutRsvp,
}

impl std::fmt::Display for Idle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Idle::NoViewports => write!(
                f,
                "the scene has no [[viewport]] for RSVP to resample (the camera's image \
                 reuses through pan and ostc)"
            ),
            Idle::ViewportsPanThemselves => write!(
                f,
                "the scene's output is its [[viewport]]s, and RSVP's buffer follows the \
                 camera's pans by itself (use rsvp)"
            ),
            Idle::CameraStill => write!(f, "the camera does not move"),
            Idle::NotEqualAngle(projection) => write!(
                f,
                "only an equal-angle camera pans, and this one is {projection}"
            ),
            Idle::Full(reason) => reason.fmt(f),
            Idle::NothingMoves => write!(f, "no object or light moves"),
            Idle::ViewportsWithoutRsvp => write!(
                f,
                "without rsvp the viewports are traced through their own rays, every frame \
                 (use rsvp,ostc)"
            ),
        }
    }
}

/// Why a frame was rendered in full though reuse was asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FullReason {
    /// A whole turn of the pan lattice's samples would take this many
    /// bytes, past [`pan::PAN_BUFFER_LIMIT_BYTES`].
    PanBufferTooLarge { bytes: f64 },
    /// Only an equal-angle camera pans.
    PanNeedsEqualAngle(Projection),
    /// The equal-angle camera moves and pan is off.
    CameraMovesPanOff,
    /// A camera of another projection moves.
    CameraMovesNotEqualAngle(Projection),
    /// The camera's eye (its position) moves: every store keeps its
    /// samples only while the eye stands still.
    EyeMoves,
}

impl std::fmt::Display for FullReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FullReason::PanBufferTooLarge { bytes } => write!(
                f,
                "a pan buffer at this field of view (a whole turn of samples) would take \
                 {:.1} GB; the limit is {:.0} GB",
                bytes / 1e9,
                pan::PAN_BUFFER_LIMIT_BYTES / 1e9
            ),
            FullReason::PanNeedsEqualAngle(projection) => {
                write!(f, "pan needs an equal-angle camera, not {projection}")
            }
            FullReason::CameraMovesPanOff => write!(f, "the camera moves and pan is off"),
            FullReason::CameraMovesNotEqualAngle(projection) => write!(
                f,
                "the {projection} camera moves: only equal-angle views pan"
            ),
            FullReason::EyeMoves => write!(
                f,
                "the camera's eye moves: samples are kept only while the eye stands still \
                 (pans, zooms and moving objects)"
            ),
        }
    }
}

/// What OSTC found a change can alter, as a store erases it.
pub struct Dirty<'a> {
    /// The layout of [`SampleStore::ostc_regions`].
    pub layout: &'a RegionLayout,
    /// Whole regions to null.
    pub regions: &'a RegionSet,
    /// Sample groups to null, by the keys they were recorded under (see
    /// [`Ostc::dirty_groups_for`]); empty unless the store erases by
    /// [`Erasure::Groups`].
    pub groups: &'a [u128],
}

/// How finely OSTC nulls a store's samples when an object moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Erasure {
    /// Whole regions.
    Regions,
    /// Just the sample groups whose recorded rays meet the moved object
    /// (a region of RSVP's finer levels holds many groups).
    Groups,
}

/// Why a store cannot serve a frame's views and must start again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unfit {
    /// The field of view changed: another lattice.
    LatticeChanged,
    /// A view reaches rows the pan buffer does not hold.
    RowsLeft,
    /// The camera moved while pan is off.
    MovedPanOff,
    /// A still camera (of this projection) moved.
    CameraMoved(crate::camera::Projection),
    /// The eye moved: samples are another eye's.
    EyeMoved,
}

impl std::fmt::Display for Unfit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Unfit::LatticeChanged => write!(f, "field of view changed: buffer restarted"),
            Unfit::RowsLeft => write!(f, "view left the pan buffer's rows: restarted"),
            Unfit::MovedPanOff => write!(f, "the camera moved and pan is off: buffer restarted"),
            Unfit::CameraMoved(projection) => write!(
                f,
                "the {projection} camera moved (only equal-angle views pan): buffer restarted"
            ),
            Unfit::EyeMoved => write!(f, "eye moved: sample buffer restarted"),
        }
    }
}

/// How a frame was made: in full, or from a store (see
/// [`SampleStore::mode`]). Shown as `full`, `pan`, `ostc`, `pan+ostc`,
/// `still`, `rsvp` and `rsvp+ostc` (the statistics files' `mode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrameMode {
    /// Every sample traced afresh.
    #[default]
    Full,
    Pan,
    /// A still view's buffer kept with OSTC.
    Ostc,
    PanOstc,
    /// A still camera's own image, nothing moving.
    Still,
    Rsvp,
    RsvpOstc,
}

impl FrameMode {
    pub fn as_str(self) -> &'static str {
        match self {
            FrameMode::Full => "full",
            FrameMode::Pan => "pan",
            FrameMode::Ostc => "ostc",
            FrameMode::PanOstc => "pan+ostc",
            FrameMode::Still => "still",
            FrameMode::Rsvp => "rsvp",
            FrameMode::RsvpOstc => "rsvp+ostc",
        }
    }
}

impl std::fmt::Display for FrameMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl serde::Serialize for FrameMode {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.as_str())
    }
}

/// What a view's picture is wanted as.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Wanted {
    /// The picture in linear colour too (for bit-exact checks), not only
    /// as 8-bit sRGB.
    pub linear: bool,
}

/// One view's picture from a store, and what it took.
pub struct StoreFrame {
    /// Linear colour, when wanted.
    pub frame: Option<Frame>,
    pub image: image::RgbImage,
    pub work: ViewWork,
}

/// What a store did for one view of a frame, measured by the store as it
/// did it; the frame loop carries it unchanged into
/// [`crate::frame_loop::FrameStats`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewWork {
    /// Samples traced for this view (the first view to need a sample
    /// pays for it).
    pub samples_traced: u64,
    /// Pixels shown from samples traced before this frame.
    pub pixels_reused: u64,
    pub rays: RayCounts,
    /// Tracing, OSTC's recording included.
    pub trace_ms: f64,
    /// Everything else the store did for the view: mapping, copying,
    /// resampling, conversion to 8 bits.
    pub assembly_ms: f64,
    /// A snapped pan: snapped minus requested yaw and pitch, radians.
    pub snap_error: Option<(f64, f64)>,
    /// RSVP: the coarsest and finest pyramid level the view read (by
    /// [`rsvp::Level::finest`]).
    pub levels: Option<(i32, i32)>,
    /// RSVP: the bytes its buffer keeps after the frame (see
    /// [`rsvp::SampleBuffer::kept_bytes`]).
    pub kept_bytes: Option<u64>,
    /// Traced samples the store evicted to stay within its memory cap.
    pub samples_evicted: u64,
}

impl ViewWork {
    /// The work of views whose pictures were combined into one (RSVP's
    /// shifted viewports averaged into a pixel's samples): counts and
    /// times add up, the levels span them all.
    pub fn combined(parts: impl IntoIterator<Item = ViewWork>) -> ViewWork {
        parts
            .into_iter()
            .fold(ViewWork::default(), |sum, part| ViewWork {
                samples_traced: sum.samples_traced + part.samples_traced,
                pixels_reused: sum.pixels_reused + part.pixels_reused,
                rays: sum.rays + part.rays,
                trace_ms: sum.trace_ms + part.trace_ms,
                assembly_ms: sum.assembly_ms + part.assembly_ms,
                snap_error: sum.snap_error.or(part.snap_error),
                levels: match (sum.levels, part.levels) {
                    (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
                    (a, b) => a.or(b),
                },
                kept_bytes: sum.kept_bytes.max(part.kept_bytes),
                samples_evicted: sum.samples_evicted + part.samples_evicted,
            })
    }
}

/// Samples kept from earlier frames, and the views made from them.
pub trait SampleStore {
    /// What the store is called in a restart's reason ("buffer").
    fn name(&self) -> &'static str;

    /// How a frame made by this store is described, with or without OSTC.
    fn mode(&self, ostc: bool) -> FrameMode;

    /// Why the store cannot serve `views`, if it cannot.
    fn unfit(&self, views: &[ViewportPose]) -> Option<Unfit>;

    /// OSTC's regions laid over everything the store can keep: `grid` (the
    /// one asked for; None: the store's own default) cut from the scene
    /// camera's screen of `camera` pixels, sized in the store's own
    /// samples.
    fn ostc_regions(&self, grid: Option<RegionGrid>, camera: (u32, u32)) -> RegionLayout;

    /// How finely the store is erased when an object moves.
    fn erasure(&self) -> Erasure {
        Erasure::Regions
    }

    /// Nulls what `dirty` names; returns how many of the nulled samples
    /// had been traced.
    fn erase(&mut self, dirty: &Dirty) -> u64;

    /// Renders `views`, tracing (and recording into `ostc`) the samples
    /// they need that the store lacks.
    fn render(
        &mut self,
        shader: &Shader,
        views: &[ViewportPose],
        ostc: Option<&Ostc>,
        wanted: Wanted,
    ) -> Vec<StoreFrame>;

    /// `image`, view `index` (`view`) as the last render showed it, with
    /// every pixel black that shows a sample this render traced (the
    /// paper's figure 4).
    fn paint_traced(
        &self,
        index: usize,
        view: &ViewportPose,
        image: &image::RgbImage,
    ) -> image::RgbImage;

    /// The kept samples as an equal-angle picture around `camera`'s view,
    /// never-traced ones black (the paper's figure 5a), where the store
    /// has one.
    fn picture(&self, _camera: &Camera) -> Option<image::RgbImage> {
        None
    }

    /// Re-traces every kept sample and compares bit for bit: (samples
    /// compared, samples that differ); None where the store does not
    /// check itself this way.
    fn verify(&self, _shader: &Shader) -> Option<(u64, u64)> {
        None
    }

    /// Caps the bytes the store's kept samples may take (None: no cap), for
    /// stores that can keep within one ([`Options::sample_memory`]).
    fn set_memory_cap(&mut self, _bytes: Option<u64>) {}

    /// The bytes of kept samples the cap bounds (0 for stores without
    /// one).
    fn kept_bytes(&self) -> u64 {
        0
    }

    /// Drops kept samples, least recently used first, until those the cap
    /// bounds take at most `bytes` (stores without a cap keep theirs).
    fn trim(&mut self, _bytes: u64) {}
}
