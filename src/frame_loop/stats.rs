//! What one frame did and cost, as the statistics files and the lab read
//! it, and why a frame did not reuse what it could have.

use crate::metrics::ImageError;
use crate::reuse::{FrameMode, FullReason, Unfit};
use crate::shade::RayCounts;

/// Why a frame's sample store started again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Restart {
    FirstFrame,
    /// The store cannot serve the frame's views.
    Unfit(Unfit),
    /// Objects or lights moved and no OSTC keeps the store: `ostc_refused`
    /// says whether it was asked for and refused.
    SceneMoved {
        store: &'static str,
        ostc_refused: bool,
    },
}

impl std::fmt::Display for Restart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Restart::FirstFrame => write!(f, "first frame"),
            Restart::Unfit(unfit) => write!(f, "{unfit}"),
            Restart::SceneMoved {
                store,
                ostc_refused,
            } => {
                let off = if *ostc_refused {
                    "OSTC was refused (see the run's warning)"
                } else {
                    "ostc is off"
                };
                write!(f, "objects or lights moved and {off}: {store} restarted")
            }
        }
    }
}

/// Why a frame did not simply reuse everything it kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reason {
    Full(FullReason),
    Restart(Restart),
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reason::Full(reason) => reason.fmt(f),
            Reason::Restart(restart) => restart.fmt(f),
        }
    }
}

/// A reason as its words; none as an empty string.
fn reason_text<S: serde::Serializer>(
    reason: &Option<Reason>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    match reason {
        Some(reason) => serializer.collect_str(reason),
        None => serializer.serialize_str(""),
    }
}

/// What one view of one frame did and cost.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    pub frame: u32,
    pub mode: FrameMode,
    /// Why a frame that could have reused did not (empty otherwise).
    #[serde(serialize_with = "reason_text")]
    pub reason: Option<Reason>,
    pub pixels: u64,
    pub pixels_reused: u64,
    pub samples_traced: u64,
    pub primary_rays: u64,
    pub shadow_rays: u64,
    pub reflection_rays: u64,
    pub refraction_rays: u64,
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
    /// With verification: the frame's error against the view's own,
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
    pub fn refusal(&self) -> Option<FullReason> {
        match (self.mode, self.reason) {
            (FrameMode::Full, Some(Reason::Full(reason))) => Some(reason),
            _ => None,
        }
    }

    /// Whether the frame shows a view other than its keyed camera's: a
    /// pan snapped onto the lattice or resampled at the true angle.
    pub fn off_keyed_view(&self) -> bool {
        self.yaw_error_deg != 0.0 || self.pitch_error_deg != 0.0
    }

    pub(super) fn count_rays(&mut self, rays: RayCounts) {
        self.primary_rays = rays.primary;
        self.shadow_rays = rays.shadow;
        self.reflection_rays = rays.reflection;
        self.refraction_rays = rays.refraction;
    }

    /// The rays counted, as one value.
    pub fn rays(&self) -> RayCounts {
        RayCounts {
            primary: self.primary_rays,
            shadow: self.shadow_rays,
            reflection: self.reflection_rays,
            refraction: self.refraction_rays,
        }
    }
}
