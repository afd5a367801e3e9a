//! What one frame did and cost, as the statistics files and the lab read
//! it, and why a frame did not reuse what it could have.

use crate::metrics::ImageError;
use crate::output::{csv_text, CsvError, Floats};
use crate::reuse::{FrameMode, FullReason, Unfit, ViewWork};

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
    /// The lens's aperture or focus changed: every camera ray with it.
    LensChanged,
    /// The camera moves otherwise while this frame's shutter is open than
    /// while the kept samples' was (motion blur): every camera ray moves
    /// with it, as its own frame's camera does.
    CameraMoving,
}

impl std::fmt::Display for Restart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Restart::FirstFrame => write!(f, "first frame"),
            Restart::LensChanged => {
                write!(f, "the lens's aperture or focus changed: buffer restarted")
            }
            Restart::CameraMoving => {
                write!(
                    f,
                    "the camera moves otherwise in this frame's shutter than in the kept \
                     samples': traced in full"
                )
            }
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

/// What one view of one frame did and cost: one record, made as the
/// frame is rendered (the store's own [`ViewWork`], OSTC's share, the
/// frame loop's set-up) and, with verification, the check's
/// [`FrameCheck`]; every statistics file, the bench and the viewer read
/// it as it is. Its columns, in order, are those of [`FrameStats::COLUMNS`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    pub frame: u32,
    /// The view this row is about (empty: the camera's image).
    pub view: String,
    pub mode: FrameMode,
    /// Why a frame that could have reused did not.
    pub reason: Option<Reason>,
    pub pixels: u64,
    /// What the store (or the full render) did for the view.
    pub work: ViewWork,
    /// This view's share of OSTC's work on the frame.
    pub ostc: OstcWork,
    /// This view's share of the frame's set-up: posing the scene, making
    /// or keeping the store.
    pub setup_ms: f64,
    /// With verification: how the frame compared with a full render.
    pub check: Option<FrameCheck>,
}

/// OSTC's work on one frame. Counts are the frame's; times are one
/// view's share.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OstcWork {
    /// Regions found dirty (object or light changes) and erased.
    pub dirty_regions: u64,
    /// Traced samples nulled by the erasure.
    pub samples_nulled: u64,
    /// Voxel visits while recording this frame's rays.
    pub voxels_walked: u64,
    /// Recording rays (summed over threads, as a share of the elapsed
    /// time); part of the store's tracing time.
    pub record_ms: f64,
    /// Finding and erasing dirty regions.
    pub erase_ms: f64,
}

/// How a frame compared with an independently made full render of it
/// (`--verify`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameCheck {
    /// Time of the full render of the same frame.
    pub full_ms: f64,
    /// Pixels differing from the full render.
    pub differing_pixels: u64,
    /// Regions of the output image (the OSTC region size, tiled from its
    /// corner) whose pixels truly changed since the previous frame: what
    /// `dirty_regions` would be at best, though that counts regions of the
    /// buffer (its whole turn, off-screen ones too). None on a first
    /// frame.
    pub changed_regions: Option<u64>,
    /// The frame's error against the view's own, unsnapped rays (what
    /// snapping or resampling costs).
    pub error: Option<ImageError>,
}

impl FrameStats {
    /// The columns of a statistics file, in order (`error` stands for its
    /// fields, `error.max_abs` ...).
    pub const COLUMNS: [&'static str; 29] = [
        "frame",
        "mode",
        "reason",
        "pixels",
        "pixels_reused",
        "samples_traced",
        "primary_rays",
        "shadow_rays",
        "reflection_rays",
        "refraction_rays",
        "dirty_regions",
        "samples_nulled",
        "voxels_walked",
        // OSTC's recording and erasure.
        "bookkeeping_ms",
        // Tracing, without OSTC's recording.
        "trace_ms",
        // Everything else: copying samples out of the store, conversion to
        // 8 bits, set-up, scene updates.
        "copy_ms",
        "total_ms",
        // Snapped minus requested yaw and pitch, degrees (a snapped pan).
        "yaw_error_deg",
        "pitch_error_deg",
        // With verification: the full render's time, and it over total_ms.
        "full_ms",
        "speedup",
        "differing_pixels",
        "changed_regions",
        "error",
        "viewport",
        // RSVP: the finest and the coarsest pyramid level the view read (a
        // level's number is its finer axis's, rsvp::Level::finest).
        "finest_level",
        "coarsest_level",
        // RSVP: the bytes its buffer keeps after the frame, and the traced
        // samples it evicted to stay within its memory cap.
        "kept_bytes",
        "samples_evicted",
    ];

    /// A row with every optional value present: optional nested values are
    /// null in some rows, and a CSV's header names the columns of this one.
    pub fn every_column() -> FrameStats {
        FrameStats {
            check: Some(FrameCheck {
                error: Some(ImageError::default()),
                ..FrameCheck::default()
            }),
            ..FrameStats::default()
        }
    }

    /// The frame's time, all of it.
    pub fn total_ms(&self) -> f64 {
        self.setup_ms + self.ostc.erase_ms + self.work.trace_ms + self.work.assembly_ms
    }

    /// OSTC's recording and erasure.
    pub fn bookkeeping_ms(&self) -> f64 {
        self.ostc.record_ms + self.ostc.erase_ms
    }

    /// Tracing, without OSTC's recording.
    pub fn trace_ms(&self) -> f64 {
        (self.work.trace_ms - self.ostc.record_ms).max(0.0)
    }

    /// Everything but tracing and bookkeeping.
    pub fn copy_ms(&self) -> f64 {
        (self.total_ms() - self.trace_ms() - self.bookkeeping_ms()).max(0.0)
    }

    /// With verification: the full render's time over this frame's.
    pub fn speedup(&self) -> Option<f64> {
        self.check.map(|check| check.full_ms / self.total_ms())
    }

    /// With verification: the error against the view's own rays.
    pub fn error(&self) -> Option<ImageError> {
        self.check.and_then(|check| check.error)
    }

    /// Snapped minus requested yaw and pitch, degrees (zero unless a
    /// snapped pan).
    pub fn snap_error_deg(&self) -> (f64, f64) {
        let (yaw, pitch) = self.work.snap_error.unwrap_or((0.0, 0.0));
        (yaw.to_degrees(), pitch.to_degrees())
    }

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
        self.snap_error_deg() != (0.0, 0.0)
    }

    /// Whether the picture was traced afresh: rendered in full, or its
    /// store started again.
    pub fn traced_afresh(&self) -> bool {
        self.mode == FrameMode::Full || matches!(self.reason, Some(Reason::Restart(_)))
    }
}

impl FrameStats {
    /// A frame's views as one row for the whole frame: counts and times
    /// add up, OSTC's frame-wide counts are counted once, the mode and
    /// reason are the first view's.
    pub fn frame_total(views: &[FrameStats]) -> FrameStats {
        let Some(first) = views.first() else {
            return FrameStats::default();
        };
        let ostc = OstcWork {
            record_ms: views.iter().map(|v| v.ostc.record_ms).sum(),
            erase_ms: views.iter().map(|v| v.ostc.erase_ms).sum(),
            ..first.ostc
        };
        FrameStats {
            frame: first.frame,
            view: String::new(),
            mode: first.mode,
            reason: first.reason,
            pixels: views.iter().map(|v| v.pixels).sum(),
            work: ViewWork::combined(views.iter().map(|v| v.work)),
            ostc,
            setup_ms: views.iter().map(|v| v.setup_ms).sum(),
            check: None,
        }
    }
}

impl serde::Serialize for FrameStats {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let rays = self.work.rays;
        let (yaw_error, pitch_error) = self.snap_error_deg();
        let check = self.check.as_ref();
        let levels = self.work.levels;
        let mut row = serializer.serialize_struct("FrameStats", Self::COLUMNS.len())?;
        let [frame, mode, reason, pixels, pixels_reused, samples_traced, primary_rays, shadow_rays, reflection_rays, refraction_rays, dirty_regions, samples_nulled, voxels_walked, bookkeeping_ms, trace_ms, copy_ms, total_ms, yaw_error_deg, pitch_error_deg, full_ms, speedup, differing_pixels, changed_regions, error, viewport, finest_level, coarsest_level, kept_bytes, samples_evicted] =
            Self::COLUMNS;
        row.serialize_field(frame, &self.frame)?;
        row.serialize_field(mode, &self.mode)?;
        // A reason as its words; none as an empty string.
        let reason_words = self.reason.map(|r| r.to_string()).unwrap_or_default();
        row.serialize_field(reason, &reason_words)?;
        row.serialize_field(pixels, &self.pixels)?;
        row.serialize_field(pixels_reused, &self.work.pixels_reused)?;
        row.serialize_field(samples_traced, &self.work.samples_traced)?;
        row.serialize_field(primary_rays, &rays.primary)?;
        row.serialize_field(shadow_rays, &rays.shadow)?;
        row.serialize_field(reflection_rays, &rays.reflection)?;
        row.serialize_field(refraction_rays, &rays.refraction)?;
        row.serialize_field(dirty_regions, &self.ostc.dirty_regions)?;
        row.serialize_field(samples_nulled, &self.ostc.samples_nulled)?;
        row.serialize_field(voxels_walked, &self.ostc.voxels_walked)?;
        row.serialize_field(bookkeeping_ms, &self.bookkeeping_ms())?;
        row.serialize_field(trace_ms, &self.trace_ms())?;
        row.serialize_field(copy_ms, &self.copy_ms())?;
        row.serialize_field(total_ms, &self.total_ms())?;
        row.serialize_field(yaw_error_deg, &yaw_error)?;
        row.serialize_field(pitch_error_deg, &pitch_error)?;
        row.serialize_field(full_ms, &check.map(|c| c.full_ms))?;
        row.serialize_field(speedup, &self.speedup())?;
        row.serialize_field(differing_pixels, &check.map(|c| c.differing_pixels))?;
        row.serialize_field(changed_regions, &check.and_then(|c| c.changed_regions))?;
        row.serialize_field(error, &check.and_then(|c| c.error))?;
        row.serialize_field(viewport, &self.view)?;
        row.serialize_field(finest_level, &levels.map(|l| l.1))?;
        row.serialize_field(coarsest_level, &levels.map(|l| l.0))?;
        row.serialize_field(kept_bytes, &self.work.kept_bytes)?;
        row.serialize_field(samples_evicted, &self.work.samples_evicted)?;
        row.end()
    }
}

/// Rows of per-frame statistics as JSON values: a run's own
/// ([`FrameStats`] serialized) or read back from its chunks' JSON files.
pub type StatsRows = [serde_json::Value];

/// Per-frame statistics as the JSON file holds them.
pub fn stats_json(rows: &StatsRows) -> String {
    serde_json::to_string_pretty(rows).expect("JSON values serialize")
}

/// Per-frame statistics as CSV: one column per field (the check's error
/// as `error.psnr_db`, ...), in [`FrameStats::COLUMNS`]' order, floats to
/// six places. Written from the JSON values, so a farm's assembled file
/// reads as one run's; a value JSON cannot hold (an infinite PSNR: the
/// frame equals its own rays) is empty, as JSON's null.
pub fn stats_csv(rows: &StatsRows) -> Result<String, CsvError> {
    let columns_of =
        serde_json::to_value(FrameStats::every_column()).expect("statistics serialize");
    csv_text(rows, &columns_of, Floats::Fixed(6))
}

/// `stats` as the rows [`stats_csv`] and [`stats_json`] write.
pub fn stats_rows(stats: &[FrameStats]) -> Vec<serde_json::Value> {
    stats
        .iter()
        .map(|s| serde_json::to_value(s).expect("statistics serialize"))
        .collect()
}
