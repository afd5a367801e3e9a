//! The timeline and the frame loop: the one place that decides what a frame
//! must trace.
//!
//! Every frame's state is computed from its frame number and the keyframes,
//! never accumulated from the previous frame, so frame 10,000 is as exact as
//! frame 1.

use std::time::Instant;

use glam::DVec3;

use crate::accel::Accelerator;
use crate::camera::{Camera, Projection};
use crate::render::{render_view, Frame};
use crate::reuse::pan::{render_window, EqualAngleLattice, PanBuffer};
use crate::reuse::samples::{render_direct, RsvpKnobs, SampleBuffer, SampleLattice, ViewportPose};
use crate::scene::Scene;
use crate::shade::{RayCounts, Shader};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ease {
    /// Constant speed.
    #[default]
    Linear,
    /// Smoothstep: starts and ends at rest.
    EaseInOut,
}

impl Ease {
    pub fn apply(self, t: f64) -> f64 {
        match self {
            Ease::Linear => t,
            Ease::EaseInOut => t * t * (3.0 - 2.0 * t),
        }
    }
}

/// A camera keyframe, fully resolved (unset values carried over).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKey {
    pub frame: u32,
    /// Radians.
    pub yaw: f64,
    pub pitch: f64,
    pub fov: f64,
    pub position: DVec3,
    /// How the segment from this key to the next is eased.
    pub ease: Ease,
}

impl CameraKey {
    /// `base` posed as this key says.
    pub fn apply(&self, base: &Camera) -> Camera {
        Camera {
            yaw: self.yaw,
            pitch: self.pitch,
            fov: self.fov,
            position: self.position,
            ..base.clone()
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    pub frames: u32,
    pub fps: f64,
    /// In increasing frame order.
    pub camera_keys: Vec<CameraKey>,
}

impl Animation {
    /// The camera at `frame`: before the first key and after the last, the
    /// nearest key; between two keys, interpolated (with the first key's ease).
    pub fn camera_at(&self, base: &Camera, frame: u32) -> Camera {
        let keys = &self.camera_keys;
        let Some(first) = keys.first() else {
            return base.clone();
        };
        let next = keys.partition_point(|k| k.frame <= frame);
        if next == 0 {
            return first.apply(base);
        }
        let a = &keys[next - 1];
        let Some(b) = keys.get(next) else {
            return a.apply(base);
        };
        let t = a
            .ease
            .apply(f64::from(frame - a.frame) / f64::from(b.frame - a.frame));
        let lerp = |x: f64, y: f64| x + (y - x) * t;
        Camera {
            yaw: lerp(a.yaw, b.yaw),
            pitch: lerp(a.pitch, b.pitch),
            fov: lerp(a.fov, b.fov),
            position: a.position + (b.position - a.position) * t,
            ..base.clone()
        }
    }
}

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
}

impl Techniques {
    pub const FULL: Techniques = Techniques {
        pan: false,
        rsvp: false,
    };
    /// Everything the timeline allows.
    pub const AUTO: Techniques = Techniques {
        pan: true,
        rsvp: true,
    };

    /// Parses `full`, `auto`, or a comma list of techniques (`pan`, `rsvp`).
    pub fn parse(text: &str) -> Result<Techniques, String> {
        let mut techniques = Techniques::FULL;
        for word in text.split(',').map(str::trim) {
            match word {
                "full" => {}
                "auto" => techniques = Techniques::AUTO,
                "pan" => techniques.pan = true,
                "rsvp" => techniques.rsvp = true,
                "ostc" => {
                    return Err(format!(
                        "mode '{word}' is not implemented yet (available: full, auto, pan, rsvp)"
                    ))
                }
                other => {
                    return Err(format!(
                        "unknown mode '{other}' (expected full, auto, or a comma list of: pan, rsvp)"
                    ))
                }
            }
        }
        Ok(techniques)
    }
}

/// What one frame did and cost.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    pub frame: u32,
    /// `full` or `pan`.
    pub mode: &'static str,
    /// Why a frame that could have reused did not (empty otherwise).
    pub reason: String,
    pub pixels: u64,
    pub pixels_reused: u64,
    pub samples_traced: u64,
    pub primary_rays: u64,
    pub shadow_rays: u64,
    pub reflection_rays: u64,
    pub trace_ms: f64,
    /// Everything else: copying samples out of the buffer, conversion to
    /// 8 bits, buffer set-up.
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
    /// With verification: the frame's error against the camera's own,
    /// unsnapped rays (what snapping or resampling costs).
    pub error: Option<ImageError>,
    /// RSVP: the viewport this row is about (empty: the camera's image).
    pub viewport: String,
    /// RSVP: finest and coarsest pyramid level the viewport read.
    pub levels: Option<(u32, u32)>,
}

impl FrameStats {
    fn count_rays(&mut self, rays: RayCounts) {
        self.primary_rays = rays.primary;
        self.shadow_rays = rays.shadow;
        self.reflection_rays = rays.reflection;
    }
}

/// Renders the frames of one animation, reusing what it may.
pub struct Animator<'a> {
    scene: &'a Scene,
    accel: &'a Accelerator,
    techniques: Techniques,
    pan: Option<PanBuffer>,
    /// Frames of the run, to size the pan buffer's rows.
    frame_range: std::ops::Range<u32>,
    /// Whether reused frames are also assembled in linear colour.
    linear_output: bool,
    fractional: FractionalPan,
    samples: Option<SampleBuffer>,
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
        accel: &'a Accelerator,
        techniques: Techniques,
        frames: std::ops::Range<u32>,
    ) -> Animator<'a> {
        Animator {
            scene,
            accel,
            techniques,
            pan: None,
            frame_range: frames,
            linear_output: true,
            fractional: FractionalPan::Snap,
            samples: None,
            knobs: RsvpKnobs::default(),
        }
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
    pub fn render_viewport_direct(&self, frame: u32, index: usize) -> (Frame, RayCounts) {
        let pose = self.scene.viewports[index].pose_at(&self.camera_at(frame), frame);
        render_direct(&Shader::new(self.scene, self.accel), &pose)
    }

    /// The camera's sample buffer around the view at `frame`: traced samples
    /// in colour, never-traced ones black (None before RSVP ran).
    pub fn buffer_image(&self, frame: u32) -> Option<image::RgbImage> {
        let camera = self.camera_at(frame);
        let buffer = self.samples.as_ref()?;
        Some(buffer.buffer_image(&camera, self.scene.camera.width, self.scene.camera.height))
    }

    /// Renders every viewport of `frame`: with RSVP from the sample buffer
    /// (tracing, in one batch, the null samples they touch), otherwise
    /// each through its own rays.
    pub fn render_viewports(&mut self, frame: u32) -> Vec<ViewportOutput> {
        let start = Instant::now();
        let camera = self.camera_at(frame);
        let poses = self.viewport_poses(frame);
        let shader = Shader::new(self.scene, self.accel);
        let names = self.scene.viewports.iter().map(|t| t.viewport.name.clone());
        let pixels = |pose: &ViewportPose| u64::from(pose.camera.width) * u64::from(pose.camera.height);
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
            None => Some("first frame"),
            Some(buffer) if buffer.lattice().position != camera.position => {
                Some("eye moved: sample buffer restarted")
            }
            Some(buffer) if buffer.lattice().columns_per_turn != lattice.columns_per_turn => {
                Some("buffer resolution changed: restarted")
            }
            Some(_) => None,
        };
        if let Some(why) = restart {
            self.samples = Some(SampleBuffer::new(SampleLattice::new(
                camera.position,
                lattice.columns_per_turn,
            )));
            reason = why.to_string();
        }
        let buffer = self.samples.as_mut().expect("sample buffer just ensured");
        let setup_ms = start.elapsed().as_secs_f64() * 1e3;
        let views = buffer.render(&shader, &poses, &self.knobs, self.linear_output);
        let count = views.len().max(1) as f64;
        views
            .into_iter()
            .zip(poses.iter().zip(names))
            .map(|(view, (pose, name))| {
                let total = setup_ms / count + view.map_ms + view.trace_ms + view.gather_ms;
                let mut stats = FrameStats {
                    frame,
                    mode: "rsvp",
                    reason: reason.clone(),
                    pixels: pixels(pose),
                    pixels_reused: pixels(pose).saturating_sub(view.samples_traced),
                    samples_traced: view.samples_traced,
                    trace_ms: view.trace_ms,
                    copy_ms: total - view.trace_ms,
                    total_ms: total,
                    viewport: name.clone(),
                    levels: Some(view.levels),
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

    pub fn set_fractional_pan(&mut self, fractional: FractionalPan) {
        self.fractional = fractional;
    }

    /// Whether frames are exact (snapped) renders, comparable bit for bit
    /// with [`Animator::render_reference`].
    pub fn is_exact(&self) -> bool {
        self.fractional == FractionalPan::Snap
    }

    /// What an accelerated frame is measured against: the full render of
    /// the snapped view (snap), or of the camera's own rays (resample).
    pub fn render_reference(&self, frame: u32) -> (Frame, RayCounts) {
        match self.fractional {
            FractionalPan::Snap => self.render_full(frame),
            FractionalPan::Resample => self.render_camera(&self.camera_at(frame)),
        }
    }

    /// Whether [`Animator::render`] returns frames in linear colour too;
    /// without them (only 8-bit output, no bit-exact checks) reused frames
    /// skip copying 12 bytes per pixel.
    pub fn set_linear_output(&mut self, linear: bool) {
        self.linear_output = linear;
    }

    pub fn camera_at(&self, frame: u32) -> Camera {
        match &self.scene.animation {
            Some(animation) => animation.camera_at(&self.scene.camera, frame),
            None => self.scene.camera.clone(),
        }
    }

    /// Renders `frame` from scratch, as the reference for reuse: on the pan
    /// lattice for equal-angle cameras (so a snapped pan compares exactly),
    /// through the camera's own rays otherwise.
    pub fn render_full(&self, frame: u32) -> (Frame, RayCounts) {
        let camera = self.camera_at(frame);
        let shader = Shader::new(self.scene, self.accel);
        if camera.projection == Projection::EqualAngle {
            let lattice = EqualAngleLattice::for_camera(&camera);
            let window = lattice.window(&camera);
            return render_window(&shader, &lattice, &window);
        }
        self.render_camera(&camera)
    }

    /// The camera's own rays at `frame`, unsnapped: the exact picture any
    /// pan approximation is measured against.
    pub fn render_true_view(&self, frame: u32) -> (Frame, RayCounts) {
        self.render_camera(&self.camera_at(frame))
    }

    /// The camera's own rays, traced in full.
    fn render_camera(&self, camera: &Camera) -> (Frame, RayCounts) {
        render_view(self.scene, camera, self.accel)
    }

    /// Why `camera` cannot be panned to, if it cannot.
    fn pan_refusal(&self, camera: &Camera) -> Option<String> {
        if !self.techniques.pan {
            return Some(String::new());
        }
        if camera.projection != Projection::EqualAngle {
            return Some(format!(
                "pan needs an equal-angle camera, not {}",
                camera.projection
            ));
        }
        None
    }

    /// A pan buffer sized for every window of this run that shares the
    /// lattice of `camera`.
    fn new_pan_buffer(&self, camera: &Camera) -> PanBuffer {
        let lattice = EqualAngleLattice::for_camera(camera);
        let (mut low, mut high) = (i64::MAX, i64::MIN);
        for frame in self.frame_range.clone() {
            let other = self.camera_at(frame);
            if lattice.fits(&other) {
                let window = lattice.window(&other);
                low = low.min(window.row);
                high = high.max(window.row + i64::from(window.height));
            }
        }
        let window = lattice.window(camera);
        low = low.min(window.row);
        high = high.max(window.row + i64::from(window.height));
        // A resampled view reads up to one row more on either side.
        PanBuffer::new(lattice, low - 1..high + 1)
    }

    /// Renders one frame with whatever reuse applies: the frame in linear
    /// colour (unless turned off), the same as 8-bit sRGB (frame assembly is
    /// part of the cost), and what it took.
    pub fn render(&mut self, frame: u32) -> (Option<Frame>, image::RgbImage, FrameStats) {
        let start = Instant::now();
        let camera = self.camera_at(frame);
        let mut stats = FrameStats {
            frame,
            pixels: u64::from(camera.width) * u64::from(camera.height),
            ..FrameStats::default()
        };
        let (image, rgb) = match self.pan_refusal(&camera) {
            Some(reason) => {
                self.pan = None;
                stats.mode = "full";
                stats.reason = reason;
                let trace_start = Instant::now();
                let (image, rays) = self.render_full(frame);
                stats.trace_ms = trace_start.elapsed().as_secs_f64() * 1e3;
                stats.samples_traced = rays.primary;
                stats.count_rays(rays);
                let rgb = image.to_rgb8();
                (Some(image), rgb)
            }
            None => {
                let restart = match &self.pan {
                    None => Some("first frame".to_string()),
                    Some(buffer) if !buffer.lattice().fits(&camera) => {
                        Some("eye or field of view changed: pan buffer restarted".to_string())
                    }
                    Some(buffer) if !buffer.covers(&buffer.resample_window(&camera).0) => {
                        Some("view left the pan buffer's rows: restarted".to_string())
                    }
                    Some(_) => None,
                };
                if let Some(reason) = restart {
                    self.pan = Some(self.new_pan_buffer(&camera));
                    stats.reason = reason;
                }
                let buffer = self.pan.as_mut().expect("pan buffer just ensured");
                let window = buffer.lattice().window(&camera);
                let shader = Shader::new(self.scene, self.accel);
                let trace_start = Instant::now();
                let (image, rgb, pan) = match self.fractional {
                    FractionalPan::Snap => buffer.frame(&shader, &window, self.linear_output),
                    FractionalPan::Resample => {
                        buffer.frame_resampled(&shader, &camera, self.linear_output)
                    }
                };
                let elapsed = trace_start.elapsed().as_secs_f64() * 1e3;
                stats.mode = "pan";
                stats.trace_ms = elapsed;
                stats.pixels_reused = pan.pixels_reused;
                stats.samples_traced = pan.samples_traced;
                if self.fractional == FractionalPan::Snap {
                    stats.yaw_error_deg = window.yaw_error.to_degrees();
                    stats.pitch_error_deg = window.pitch_error.to_degrees();
                }
                stats.count_rays(pan.rays);
                (image, rgb)
            }
        };
        stats.total_ms = start.elapsed().as_secs_f64() * 1e3;
        stats.copy_ms = (stats.total_ms - stats.trace_ms).max(0.0);
        (image, rgb, stats)
    }
}

/// How far an approximate frame is from its reference, on colours clamped
/// to [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImageError {
    pub max_abs: f32,
    pub mean_abs: f64,
    /// Peak signal-to-noise ratio in dB (infinite for identical frames).
    pub psnr_db: f64,
    /// Share of pixels whose 8-bit sRGB value differs.
    pub differing_share: f64,
}

pub fn image_error(frame: &Frame, reference: &Frame) -> ImageError {
    let srgb = crate::render::srgb_table();
    let (mut max_abs, mut sum_abs, mut sum_sq, mut differing) = (0.0f32, 0.0f64, 0.0f64, 0u64);
    for (a, b) in frame.pixels.iter().zip(&reference.pixels) {
        let (a, b) = (
            a.clamp(glam::Vec3::ZERO, glam::Vec3::ONE),
            b.clamp(glam::Vec3::ZERO, glam::Vec3::ONE),
        );
        let d = (a - b).abs();
        max_abs = max_abs.max(d.max_element());
        sum_abs += f64::from(d.element_sum()) / 3.0;
        sum_sq += f64::from(d.dot(d)) / 3.0;
        differing +=
            u64::from(a.to_array().map(|c| srgb.encode(c)) != b.to_array().map(|c| srgb.encode(c)));
    }
    let n = frame.pixels.len().max(1) as f64;
    let mse = sum_sq / n;
    ImageError {
        max_abs,
        mean_abs: sum_abs / n,
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        },
        differing_share: differing as f64 / n,
    }
}

/// Pixels whose colours differ in any bit.
pub fn count_differences(a: &Frame, b: &Frame) -> u64 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits))
        .count() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> Camera {
        Camera {
            projection: Projection::EqualAngle,
            position: DVec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            fov: 1.0,
            width: 8,
            height: 8,
        }
    }

    fn key(frame: u32, yaw_deg: f64, ease: Ease) -> CameraKey {
        CameraKey {
            frame,
            yaw: yaw_deg.to_radians(),
            pitch: 0.0,
            fov: 1.0,
            position: DVec3::ZERO,
            ease,
        }
    }

    #[test]
    fn interpolates_from_the_frame_number() {
        let animation = Animation {
            frames: 100,
            fps: 25.0,
            camera_keys: vec![
                key(10, 0.0, Ease::Linear),
                key(110, 360.0, Ease::EaseInOut),
                key(210, 0.0, Ease::Linear),
            ],
        };
        let yaw = |f| animation.camera_at(&base(), f).yaw.to_degrees();
        assert_eq!(yaw(0), 0.0);
        assert!((yaw(60) - 180.0).abs() < 1e-9);
        assert!((yaw(11) - 3.6).abs() < 1e-9);
        // Eased segment: slow at both ends, halfway in the middle.
        assert!((yaw(160) - 180.0).abs() < 1e-9);
        assert!(360.0 - yaw(111) < 3.6 * 0.1);
        assert_eq!(yaw(10_000), 0.0);
    }

    #[test]
    fn modes_parse() {
        assert_eq!(Techniques::parse("full"), Ok(Techniques::FULL));
        assert_eq!(Techniques::parse("auto"), Ok(Techniques::AUTO));
        assert_eq!(
            Techniques::parse("pan"),
            Ok(Techniques {
                pan: true,
                rsvp: false
            })
        );
        assert_eq!(
            Techniques::parse("rsvp,pan"),
            Ok(Techniques {
                pan: true,
                rsvp: true
            })
        );
        assert!(Techniques::parse("zoom").is_err());
        assert!(Techniques::parse("ostc")
            .unwrap_err()
            .contains("not implemented"));
    }
}
