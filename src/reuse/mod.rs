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
//! Promises of every store: a sample it keeps is bit for bit what a fresh
//! trace of its group gives (groups are fixed 4x2 packets aligned to the
//! store's lattice, traced through [`crate::render`]); a sample erased is
//! traced again before any view shows it.

pub mod lattice_buffer;
pub mod ostc;
pub mod pan;
pub mod regions;
pub mod rsvp;
pub mod still;

use crate::camera::{Camera, ViewportPose};
use crate::render::Frame;
use crate::shade::{RayCounts, Shader};
use ostc::Ostc;
use regions::{RegionLayout, RegionSet};

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
    /// The eye moved or the field of view changed: another lattice.
    LatticeChanged,
    /// A view reaches rows the pan buffer does not hold.
    RowsLeft,
    /// The camera moved while pan is off.
    MovedPanOff,
    /// A still camera (of this projection) moved.
    CameraMoved(crate::camera::Projection),
    /// RSVP: the eye moved.
    EyeMoved,
}

impl std::fmt::Display for Unfit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Unfit::LatticeChanged => write!(f, "eye or field of view changed: buffer restarted"),
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
    pub levels: Option<(u32, u32)>,
}

/// Samples kept from earlier frames, and the views made from them.
pub trait SampleStore {
    /// What the store is called in a restart's reason ("buffer").
    fn name(&self) -> &'static str;

    /// How a frame made by this store is described, with or without OSTC.
    fn mode(&self, ostc: bool) -> FrameMode;

    /// Why the store cannot serve `views`, if it cannot.
    fn unfit(&self, views: &[ViewportPose]) -> Option<Unfit>;

    /// Samples of the store's lattice along each axis of a camera pixel
    /// (a still camera keeping strata: the side of their grid), so regions
    /// can be sized in the lattice's own samples.
    fn lattice_side(&self) -> u32 {
        1
    }

    /// OSTC regions of `size` samples laid over everything the store can
    /// keep.
    fn regions(&self, size: (i64, i64)) -> RegionLayout;

    fn erasure(&self) -> Erasure {
        Erasure::Regions
    }

    /// Nulls the samples in `regions` (of `layout`, from
    /// [`SampleStore::regions`]); returns how many of them were traced.
    fn erase(&mut self, layout: &RegionLayout, regions: &RegionSet) -> u64;

    /// Nulls the sample groups recorded under `keys` (see
    /// [`Ostc::dirty_groups_for`]); returns how many samples were traced.
    /// Only stores that erase by [`Erasure::Groups`] are asked.
    fn erase_groups(&mut self, keys: &[u128]) -> u64 {
        debug_assert!(keys.is_empty(), "{} erases whole regions", self.name());
        0
    }

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
}
