//! What a viewer shows and how input changes it: the view the user has
//! turned, zoomed and played to, and the views of the frame loop that
//! show it.
//!
//! Promises: a view is computed from the state alone (the timeline's
//! camera at the state's frame, then the user's turn and zoom), never
//! accumulated from the previous picture; the same input gives the same
//! state in a window and in a script. With the transform at identity the
//! view is the camera's own image, so a drag of an equal-angle camera is a
//! Panimation pan, exact; zoomed or rotated it is an RSVP viewport.
//!
//! A scene's own `[[viewport]]`s can be shown instead (`v` cycles through
//! them and back to the camera's image; a scene that has them opens on the
//! first, as `retrace animate` outputs it): viewport k at frame f is the
//! timeline's pose of it, as `retrace animate` renders it. The user's
//! drag, wheel and turn on it compose with its (keyed) transform, in the
//! viewport's own pixels; `v` starts the next view unadjusted, and the
//! user's own view of the camera is kept while scene viewports are shown.

use std::f64::consts::FRAC_PI_2;

use glam::{DMat2, DVec2};

use crate::camera::{Camera, Projection, ViewTransform, Viewport, ViewportPose};
use crate::frame_loop::View;
use crate::scene::Scene;
use crate::timeline::{Animation, ViewportTrack};

/// One wheel notch magnifies by this much.
pub const ZOOM_STEP: f64 = 1.1;
/// Wheel notches allowed each way: 1.1^48 is about 97x in, 1/97 out (the
/// equal-angle view then meets the poles well before).
pub const MAX_NOTCHES: i32 = 48;
/// An arrow key pans by this many window pixels.
pub const ARROW_STEP: f64 = 32.0;
/// `[` and `]` turn the view by this much, radians.
pub const ROTATE_STEP: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// A perspective view zoomed out stops at this field of view across,
/// radians (or at the camera's own, if wider): past it the picture is a
/// few pixels of the scene stretched over many.
pub const MAX_PERSPECTIVE_FOV: f64 = 120.0 * std::f64::consts::PI / 180.0;

/// The name of the viewer's RSVP viewport (statistics name their view).
pub const VIEWPORT_NAME: &str = "view";

/// Everything a picture of the viewer depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    /// The timeline's frame.
    pub frame: u32,
    /// Added to the timeline camera's yaw and pitch, radians (equal-angle
    /// cameras: a drag turns the camera, a pan).
    pub yaw: f64,
    pub pitch: f64,
    /// Magnification [`ZOOM_STEP`]^`notches`.
    pub notches: i32,
    /// Radians, counter-clockwise as seen.
    pub rotate: f64,
    /// The viewport's translation, in pixels of the unzoomed image (other
    /// projections' pans; equal-angle ones turn the camera instead).
    pub translate: DVec2,
    /// Reuse on (every technique the frame loop can use) or off (every
    /// picture traced afresh).
    pub reuse: bool,
    /// The window's size in pixels (None: the scene camera's).
    pub size: Option<(u32, u32)>,
    /// The scene's viewport shown (its index among the scene's
    /// `[[viewport]]`s), or None: the user's own view of the camera (the
    /// fields above).
    pub scene_viewport: Option<usize>,
    /// The user's zoom, turn and shift on top of the scene viewport shown
    /// (identity: the viewport as `retrace animate` renders it).
    pub on_viewport: Adjust,
}

/// A zoom, turn and shift in a picture's own pixels, about its centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Adjust {
    /// Magnification [`ZOOM_STEP`]^`notches`.
    pub notches: i32,
    /// Radians, counter-clockwise as seen.
    pub rotate: f64,
    /// What the centre shows, in pixels of the unadjusted picture.
    pub translate: DVec2,
}

impl Adjust {
    fn transform(&self) -> ViewTransform {
        ViewTransform {
            zoom: ZOOM_STEP.powi(self.notches),
            rotate: self.rotate,
            shear: [0.0, 0.0],
            translate: self.translate.to_array(),
        }
    }

    /// `base` seen through this adjustment: the picture `base` makes,
    /// zoomed, turned and shifted. Rotations and uniform zooms commute, so
    /// the product is again a zoom, a turn and `base`'s shear; the shift
    /// is carried back through `base` into its unzoomed pixels.
    pub fn compose(&self, base: &ViewTransform) -> ViewTransform {
        if *self == Adjust::default() {
            return *base;
        }
        let own = self.transform();
        let shift = base.matrix().inverse() * self.translate;
        ViewTransform {
            zoom: own.zoom * base.zoom,
            rotate: own.rotate + base.rotate,
            shear: base.shear,
            translate: [base.translate[0] + shift.x, base.translate[1] + shift.y],
        }
    }

    /// Dragged by `delta` pixels: the point under the cursor stays there.
    fn drag(&mut self, delta: DVec2) {
        self.translate -= self.transform().matrix().inverse() * delta;
    }

    /// Zoomed to `notches` about `at` in a picture of `size` pixels: the
    /// point under it stays there.
    fn zoom_about(&mut self, notches: i32, at: DVec2, size: (u32, u32)) {
        let before = self.transform().matrix().inverse();
        self.notches = notches;
        let after = self.transform().matrix().inverse();
        let centre = DVec2::new(f64::from(size.0), f64::from(size.1)) * 0.5;
        self.translate += (before - after) * (at - centre);
    }
}

impl Default for ViewState {
    fn default() -> Self {
        ViewState {
            frame: 0,
            yaw: 0.0,
            pitch: 0.0,
            notches: 0,
            rotate: 0.0,
            translate: DVec2::ZERO,
            reuse: true,
            size: None,
            scene_viewport: None,
            on_viewport: Adjust::default(),
        }
    }
}

/// A key the viewer acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    Left,
    Right,
    Up,
    Down,
    /// Play or pause the timeline.
    Space,
    /// One frame back.
    Comma,
    /// One frame on.
    Period,
    /// Reuse off or on.
    M,
    /// The traced-samples overlay off or on.
    T,
    /// Save the picture.
    S,
    /// Show the scene's next viewport (after the last: the camera's image).
    V,
    /// Turn the view counter-clockwise (`[`) or clockwise (`]`).
    RotateLeft,
    RotateRight,
    /// Back to the view the window opened on (at the frame shown).
    Reset,
    /// The help over the picture, on or off (a window's only).
    Help,
    /// Fullscreen on or off (a window's only).
    Fullscreen,
    Quit,
}

impl Key {
    /// The key a script or a window names: a character, or Left, Right,
    /// Up, Down, Space, Home, F1, F11, Escape.
    pub fn parse(name: &str) -> Option<Key> {
        Some(match name {
            "Left" | "left" => Key::Left,
            "Right" | "right" => Key::Right,
            "Up" | "up" => Key::Up,
            "Down" | "down" => Key::Down,
            "space" | "Space" | " " => Key::Space,
            "," | "comma" => Key::Comma,
            "." | "period" => Key::Period,
            "m" => Key::M,
            "t" => Key::T,
            "s" => Key::S,
            "v" => Key::V,
            "[" => Key::RotateLeft,
            "]" => Key::RotateRight,
            "r" | "Home" | "home" => Key::Reset,
            "h" | "?" | "F1" => Key::Help,
            "f" | "F11" => Key::Fullscreen,
            "q" | "Escape" | "escape" => Key::Quit,
            _ => return None,
        })
    }
}

/// Input as the viewer receives it, in window pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Input {
    /// The picture dragged by (dx, dy): x right, y down.
    Drag(DVec2),
    /// Wheel notches (positive: zoom in) about a window point.
    Wheel {
        notches: i32,
        at: DVec2,
    },
    Key(Key),
    /// The window resized to (width, height) pixels.
    Resize(u32, u32),
}

/// What an input asks of the viewer beyond a new state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effect {
    /// The state changed: a new picture is wanted.
    Changed,
    /// Nothing to do (a zoom or turn past what the view allows, a frame
    /// step without a timeline).
    Nothing,
    TogglePlay,
    /// Show the picture, or the picture painted black where it traced
    /// (the paper's figure 4): the same picture, nothing to render.
    ToggleOverlay,
    ToggleHelp,
    ToggleFullscreen,
    Save,
    Quit,
}

/// The scene's camera and timeline as the viewer needs them.
#[derive(Clone, Debug)]
pub struct Viewer {
    camera: Camera,
    animation: Option<Animation>,
    samples: u32,
    viewports: Vec<ViewportTrack>,
}

impl Viewer {
    pub fn new(scene: &Scene) -> Viewer {
        Viewer {
            camera: scene.camera.clone(),
            animation: scene.animation.clone(),
            samples: scene.samples.count(),
            viewports: scene.viewports.clone(),
        }
    }

    /// The state a viewer opens on: the scene's first viewport where it
    /// has any (what `retrace animate` outputs), else the camera's image.
    pub fn opening(&self) -> ViewState {
        ViewState {
            scene_viewport: (!self.viewports.is_empty()).then_some(0),
            ..ViewState::default()
        }
    }

    /// The scene's viewports.
    pub fn scene_viewports(&self) -> &[ViewportTrack] {
        &self.viewports
    }

    /// What `state` shows, in words: `camera`, or the scene viewport's
    /// name and place (`viewport zoom 1/2`), `adjusted` when the user's
    /// input is on it.
    pub fn shown_name(&self, state: &ViewState) -> String {
        match state.scene_viewport {
            None => "camera".to_string(),
            Some(k) => format!(
                "viewport {} {}/{}{}",
                self.viewports[k].viewport.name,
                k + 1,
                self.viewports.len(),
                if state.on_viewport == Adjust::default() {
                    ""
                } else {
                    " adjusted"
                }
            ),
        }
    }

    /// The picture's size in pixels: the scene viewport's own, or the
    /// window's.
    pub fn picture_size(&self, state: &ViewState) -> (u32, u32) {
        match state.scene_viewport {
            Some(k) => {
                let viewport = &self.viewports[k].viewport;
                (viewport.width, viewport.height)
            }
            None => self.size_of(state),
        }
    }

    /// The scene's samples a pixel: the frame loop's pictures'.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Frames in the timeline (1 without one).
    pub fn frames(&self) -> u32 {
        self.animation.as_ref().map_or(1, |a| a.frames.max(1))
    }

    /// The timeline's frames a second.
    pub fn fps(&self) -> f64 {
        self.animation.as_ref().map_or(25.0, |a| a.fps)
    }

    /// The picture's size in pixels as the scene gives it.
    pub fn size(&self) -> (u32, u32) {
        (self.camera.width, self.camera.height)
    }

    /// The picture's size in pixels for `state`.
    pub fn size_of(&self, state: &ViewState) -> (u32, u32) {
        state.size.unwrap_or_else(|| self.size())
    }

    /// `camera` showing `size` pixels at the angle or focal length per
    /// pixel it had: a bigger window shows more of the scene at the same
    /// scale rather than the same view magnified. An equal-angle camera
    /// keeps its pan lattice, so pans stay exact at any size and a window
    /// twice as wide is the scene's image with twice the field of view.
    pub fn resized(camera: &Camera, (width, height): (u32, u32)) -> Camera {
        let scale = f64::from(width) / f64::from(camera.width);
        let fov = match camera.projection {
            Projection::Perspective => 2.0 * ((0.5 * camera.fov).tan() * scale).atan(),
            Projection::EqualAngle | Projection::Fisheye => {
                (camera.fov * scale).min(std::f64::consts::TAU)
            }
        };
        Camera {
            width,
            height,
            fov,
            ..camera.clone()
        }
    }

    /// Whether a drag turns the camera (equal-angle: a pan) rather than
    /// translating the viewport.
    fn turns(&self) -> bool {
        self.camera.projection == Projection::EqualAngle
    }

    fn transform(state: &ViewState) -> ViewTransform {
        ViewTransform {
            zoom: ZOOM_STEP.powi(state.notches),
            rotate: state.rotate,
            shear: [0.0, 0.0],
            translate: state.translate.to_array(),
        }
    }

    /// Whether `state` shows the camera's own image (no zoom, turn or
    /// translation): else an RSVP viewport (the viewer's or the scene's).
    pub fn is_camera_view(state: &ViewState) -> bool {
        state.scene_viewport.is_none()
            && state.notches == 0
            && state.rotate == 0.0
            && state.translate == DVec2::ZERO
    }

    /// The timeline's camera at `frame`, as the frame loop poses the
    /// scene's viewports from it (not turned by the user, not resized).
    fn timeline_camera(&self, frame: u32) -> Camera {
        match &self.animation {
            Some(animation) => animation.camera_at(&self.camera, frame),
            None => self.camera.clone(),
        }
    }

    /// Scene viewport `index` at the state's frame, as the frame loop
    /// poses it, with the user's adjustment composed on top.
    fn scene_view(&self, state: &ViewState, index: usize) -> View {
        let track = &self.viewports[index];
        let pose = track.pose_at(&self.timeline_camera(state.frame), state.frame);
        let pose = match state.on_viewport == Adjust::default() {
            true => pose,
            false => {
                let transform = state.on_viewport.compose(&pose.transform);
                ViewportPose::new(pose.camera, transform)
            }
        };
        View {
            name: track.viewport.name.clone(),
            pose,
        }
    }

    /// The viewport the viewer shows when zoomed or turned, `size` pixels.
    pub fn viewport(&self, size: (u32, u32)) -> Viewport {
        let camera = Self::resized(&self.camera, size);
        Viewport {
            name: VIEWPORT_NAME.to_string(),
            width: camera.width,
            height: camera.height,
            projection: camera.projection,
            fov: camera.fov,
            yaw: 0.0,
            pitch: 0.0,
            transform: ViewTransform::default(),
        }
    }

    /// The timeline's camera at the state's frame, turned by the user.
    pub fn camera(&self, state: &ViewState) -> Camera {
        let mut camera = self.timeline_camera(state.frame);
        if self.turns() {
            camera.yaw += state.yaw;
            camera.pitch += state.pitch;
        }
        match state.size {
            Some(size) if size != (camera.width, camera.height) => Self::resized(&camera, size),
            _ => camera,
        }
    }

    /// The one view of `state`: the camera's image, the viewer's
    /// viewport, or the scene's viewport.
    pub fn view(&self, state: &ViewState) -> View {
        if let Some(index) = state.scene_viewport {
            return self.scene_view(state, index);
        }
        let camera = self.camera(state);
        if Self::is_camera_view(state) {
            return View {
                name: String::new(),
                pose: ViewportPose::new(camera, ViewTransform::default()),
            };
        }
        View {
            name: VIEWPORT_NAME.to_string(),
            pose: ViewportPose::new(camera, Self::transform(state)),
        }
    }

    /// The view of `state` in `factor` times fewer pixels each way (sides
    /// rounded up) over the same field: a coarse picture of what
    /// [`Viewer::view`] shows.
    pub fn coarse_view(&self, state: &ViewState, factor: u32) -> View {
        let view = self.view(state);
        let mut camera = view.pose.camera;
        let width = camera.width.div_ceil(factor);
        let scale = f64::from(width) / f64::from(camera.width);
        camera.width = width;
        camera.height = camera.height.div_ceil(factor);
        let mut transform = view.pose.transform;
        transform.translate = transform.translate.map(|t| t * scale);
        View {
            name: view.name,
            pose: ViewportPose::new(camera, transform),
        }
    }

    /// Whether `state` can be shown: its camera valid (an equal-angle
    /// view within the poles), its transform too, and a perspective view
    /// no wider than [`MAX_PERSPECTIVE_FOV`] (or than unzoomed).
    pub fn check(&self, state: &ViewState) -> Result<(), String> {
        if let Some(index) = state.scene_viewport {
            let camera = self.timeline_camera(state.frame);
            let pose = self.scene_view(state, index).pose;
            self.viewports[index]
                .viewport
                .validate_transform(&camera, &pose.transform)
                .map_err(|e| format!("{}: {}", e.field, e.message))?;
            let keyed = self.scene_view(
                &ViewState {
                    on_viewport: Adjust::default(),
                    ..state.clone()
                },
                index,
            );
            return check_field(&pose.camera, pose.transform.zoom, keyed.pose.transform.zoom);
        }
        let camera = self.camera(state);
        camera.validate().map_err(|e| e.to_string())?;
        let base = Camera {
            yaw: camera.yaw,
            pitch: camera.pitch,
            ..Self::resized(&self.camera, self.size_of(state))
        };
        self.viewport(self.size_of(state))
            .validate_transform(&base, &Self::transform(state))
            .map_err(|e| format!("{}: {}", e.field, e.message))?;
        check_field(&base, ZOOM_STEP.powi(state.notches), 1.0)
    }

    /// `state` changed by `input`: a new state where the input changes
    /// what is shown, and what else it asks for. A change the view cannot
    /// take (past a pole, past the zoom limits) leaves the state as it was.
    pub fn apply(&self, state: &mut ViewState, input: Input) -> Effect {
        let mut next = state.clone();
        match input {
            Input::Drag(delta) => self.drag(&mut next, delta),
            Input::Wheel { notches, at } => next = self.wheel(state, notches, at),
            Input::Resize(width, height) => {
                next.size = Some((width, height)).filter(|&size| size != self.size());
            }
            Input::Key(key) => match key {
                Key::Left => self.drag(&mut next, DVec2::new(ARROW_STEP, 0.0)),
                Key::Right => self.drag(&mut next, DVec2::new(-ARROW_STEP, 0.0)),
                Key::Up => self.drag(&mut next, DVec2::new(0.0, ARROW_STEP)),
                Key::Down => self.drag(&mut next, DVec2::new(0.0, -ARROW_STEP)),
                Key::Comma | Key::Period => {
                    let frames = self.frames();
                    let step = if key == Key::Period { 1 } else { frames - 1 };
                    next.frame = (state.frame + step) % frames;
                }
                Key::M => next.reuse = !state.reuse,
                Key::T => return Effect::ToggleOverlay,
                Key::V => {
                    let count = self.viewports.len();
                    next.scene_viewport = match state.scene_viewport {
                        None => (count > 0).then_some(0),
                        Some(k) => (k + 1 < count).then_some(k + 1),
                    };
                    next.on_viewport = Adjust::default();
                }
                Key::RotateLeft | Key::RotateRight => {
                    let sign = if key == Key::RotateLeft { 1.0 } else { -1.0 };
                    // Whole steps from zero, so turning back is exactly 0.
                    let turn = |rotate: f64| ((rotate / ROTATE_STEP).round() + sign) * ROTATE_STEP;
                    if state.scene_viewport.is_some() {
                        next.on_viewport.rotate = turn(state.on_viewport.rotate);
                    } else {
                        next.rotate = turn(state.rotate);
                        self.settle(&mut next);
                    }
                }
                Key::Reset => {
                    next = ViewState {
                        frame: state.frame,
                        reuse: state.reuse,
                        size: state.size,
                        scene_viewport: state.scene_viewport,
                        ..ViewState::default()
                    };
                }
                Key::Space => return Effect::TogglePlay,
                Key::Help => return Effect::ToggleHelp,
                Key::Fullscreen => return Effect::ToggleFullscreen,
                Key::S => return Effect::Save,
                Key::Quit => return Effect::Quit,
            },
        }
        if next == *state || self.check(&next).is_err() {
            return Effect::Nothing;
        }
        *state = next;
        Effect::Changed
    }

    /// `state` zoomed by `notches` about `at`, a notch at a time, up to
    /// the first notch the view refuses: a wheel turned past a limit
    /// stops at it rather than being refused whole, and N notches at once
    /// are N single ones.
    fn wheel(&self, state: &ViewState, notches: i32, at: DVec2) -> ViewState {
        let mut zoomed = state.clone();
        for _ in 0..notches.unsigned_abs() {
            let target = self.notches_of(&zoomed) + notches.signum();
            if target.abs() > MAX_NOTCHES {
                break;
            }
            let next = self.zoomed(&zoomed, target, at);
            if self.check(&next).is_err() {
                break;
            }
            zoomed = next;
        }
        zoomed
    }

    /// The wheel notches the view shown is zoomed by: the scene
    /// viewport's adjustment, or the user's own view's.
    pub fn notches_of(&self, state: &ViewState) -> i32 {
        match state.scene_viewport {
            Some(_) => state.on_viewport.notches,
            None => state.notches,
        }
    }

    /// `state` zoomed to `notches` about `at`.
    fn zoomed(&self, state: &ViewState, notches: i32, at: DVec2) -> ViewState {
        let mut next = state.clone();
        if state.scene_viewport.is_some() {
            let size = self.picture_size(state);
            next.on_viewport.zoom_about(notches, at, size);
        } else {
            self.zoom_about(&mut next, notches, at);
        }
        next
    }

    /// The next frame of a playing timeline.
    pub fn advance(&self, state: &mut ViewState) -> Effect {
        self.apply(state, Input::Key(Key::Period))
    }

    /// Drags the picture by `delta` window pixels: the point under the
    /// cursor stays under it.
    fn drag(&self, state: &mut ViewState, delta: DVec2) {
        if state.scene_viewport.is_some() {
            return state.on_viewport.drag(delta);
        }
        let base = Self::transform(state).matrix().inverse() * delta;
        if self.turns() {
            let step = self.camera.angle_step();
            state.yaw -= base.x * step;
            state.pitch = self.clamp_pitch(state, state.pitch + base.y * step);
        } else {
            state.translate -= base;
        }
    }

    /// Zooms to `notches` about window point `at`: the point under it
    /// stays under it.
    fn zoom_about(&self, state: &mut ViewState, notches: i32, at: DVec2) {
        let inverse = |s: &ViewState| -> DMat2 { Self::transform(s).matrix().inverse() };
        let before = inverse(state);
        state.notches = notches;
        let after = inverse(state);
        let (width, height) = self.size_of(state);
        let centre = DVec2::new(f64::from(width), f64::from(height)) * 0.5;
        state.translate += (before - after) * (at - centre);
        self.settle(state);
    }

    /// An equal-angle camera's translation becomes a turn of the camera (a
    /// shift of its image is exactly a turn), so that a view back at zoom 1
    /// is the camera's own image again, and pans stay Panimation's.
    fn settle(&self, state: &mut ViewState) {
        if !self.turns() {
            return;
        }
        let step = self.camera.angle_step();
        state.yaw += state.translate.x * step;
        state.pitch = self.clamp_pitch(state, state.pitch - state.translate.y * step);
        state.translate = DVec2::ZERO;
    }

    /// `pitch` (the user's, added to the timeline's) kept so that the view
    /// stays within the poles, where it can.
    fn clamp_pitch(&self, state: &ViewState, pitch: f64) -> f64 {
        let camera = self.camera(&ViewState {
            pitch: 0.0,
            ..state.clone()
        });
        let pose = ViewportPose::new(camera.clone(), Self::transform(state));
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        // The view's rows reach this far from its centre row, in pixels of
        // the camera's image: its corners bound it.
        let reach = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .map(|(x, y)| (pose.base_point(DVec2::new(x, y)).y - 0.5 * h).abs())
            .into_iter()
            .fold(0.0, f64::max);
        let limit = FRAC_PI_2 - reach * camera.angle_step();
        if limit < 0.0 {
            return pitch;
        }
        (camera.pitch + pitch).clamp(-limit, limit) - camera.pitch
    }
}

/// A perspective `camera`'s picture magnified by `zoom` is no wider
/// than [`MAX_PERSPECTIVE_FOV`], or than at zoom `allowed` (the view the
/// scene itself asks for may be wider).
fn check_field(camera: &Camera, zoom: f64, allowed: f64) -> Result<(), String> {
    if camera.projection != Projection::Perspective {
        return Ok(());
    }
    let field = |zoom: f64| 2.0 * ((0.5 * camera.fov).tan() / zoom).atan();
    if field(zoom) > MAX_PERSPECTIVE_FOV.max(field(allowed)) + 1e-12 {
        return Err(format!(
            "zoom: the perspective view would span {:.1} degrees across, more than {:.0}",
            field(zoom).to_degrees(),
            MAX_PERSPECTIVE_FOV.to_degrees()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{paper_scene, SceneOverrides};

    fn paper() -> Viewer {
        Viewer::new(&paper_scene(&SceneOverrides::default()).unwrap())
    }

    #[test]
    fn a_drag_turns_an_equal_angle_camera_by_its_pixels() {
        let viewer = paper();
        let mut state = ViewState::default();
        let step = viewer.camera.angle_step();
        assert_eq!(
            viewer.apply(&mut state, Input::Drag(DVec2::new(-24.0, 8.0))),
            Effect::Changed
        );
        assert!((state.yaw - 24.0 * step).abs() < 1e-15);
        assert!((state.pitch - 8.0 * step).abs() < 1e-15);
        assert!(Viewer::is_camera_view(&state));
        // Dragged far up, the view stops at the pole.
        for _ in 0..100 {
            viewer.apply(&mut state, Input::Drag(DVec2::new(0.0, 100.0)));
        }
        let camera = viewer.camera(&state);
        camera.validate().unwrap();
        let top = camera.pitch + 0.5 * f64::from(camera.height) * step;
        assert!((top - FRAC_PI_2).abs() < 1e-9, "{}", top.to_degrees());
    }

    #[test]
    fn a_zoom_keeps_the_point_under_the_cursor_and_comes_back_exactly() {
        let viewer = paper();
        let mut state = ViewState::default();
        let at = DVec2::new(100.0, 90.0);
        let looks = |state: &ViewState| viewer.view(state).pose.direction(at).unwrap();
        let before = looks(&state);
        for _ in 0..3 {
            viewer.apply(&mut state, Input::Wheel { notches: 1, at });
        }
        assert!(!Viewer::is_camera_view(&state));
        assert_eq!(state.translate, DVec2::ZERO, "equal-angle: a turn");
        assert!((looks(&state) - before).length() < 1e-9);
        viewer.apply(&mut state, Input::Wheel { notches: -3, at });
        assert!(Viewer::is_camera_view(&state));
        assert!((looks(&state) - before).length() < 1e-9);
    }

    /// A viewer of the paper scene through a perspective camera of 60
    /// degrees.
    fn perspective_viewer() -> Viewer {
        let overrides = SceneOverrides {
            projection: Some(Projection::Perspective),
            fov: Some(60.0),
            ..SceneOverrides::default()
        };
        Viewer::new(&paper_scene(&overrides).unwrap())
    }

    #[test]
    fn a_perspective_view_pans_by_translating_its_viewport() {
        let viewer = perspective_viewer();
        let mut state = ViewState::default();
        viewer.apply(&mut state, Input::Drag(DVec2::new(10.0, -4.0)));
        assert_eq!(state.translate, DVec2::new(-10.0, 4.0));
        assert_eq!((state.yaw, state.pitch), (0.0, 0.0));
        assert_eq!(viewer.view(&state).name, VIEWPORT_NAME);
        // Zoomed in twice as far, the same drag moves half as far.
        let at = DVec2::new(320.0, 240.0);
        let mut zoomed = ViewState::default();
        viewer.apply(&mut zoomed, Input::Wheel { notches: 7, at });
        let zoom = ZOOM_STEP.powi(7);
        viewer.apply(&mut zoomed, Input::Drag(DVec2::new(10.0, 0.0)));
        assert!((zoomed.translate.x + 10.0 / zoom).abs() < 1e-12);
    }

    #[test]
    fn input_on_a_scene_viewport_composes_with_its_keyed_transform() {
        let text = "include = \"paper.toml\"\n[animation]\nframes = 3\n\
                    [[viewport]]\nname = \"a\"\nwidth = 120\nheight = 80\nrotate = 10.0\n\
                    shear = [0.2, 0.0]\n[[viewport]]\nname = \"b\"\nwidth = 60\nheight = 40\n\
                    [[animation.viewport]]\nframe = 2\nzoom = 2.0\ntranslate = [5.0, -3.0]\n";
        let scene = crate::scene::parse_scene_str(
            text,
            std::path::Path::new("scenes/v.toml"),
            &SceneOverrides::default(),
        )
        .unwrap();
        let viewer = Viewer::new(&scene);
        let mut state = viewer.opening();
        assert_eq!(state.scene_viewport, Some(0));
        assert_eq!(viewer.picture_size(&state), (120, 80));
        viewer.apply(&mut state, Input::Key(Key::Period));
        viewer.apply(&mut state, Input::Key(Key::Period));
        // Unadjusted: the timeline's pose, as the frame loop makes it.
        let camera = viewer.timeline_camera(2);
        let keyed = scene.viewports[0].pose_at(&camera, 2);
        assert_eq!(viewer.view(&state).pose, keyed);
        // A wheel keeps the point under the cursor, a drag moves it with
        // the cursor, a turn is about the centre; the keyed shear stays.
        let looks = |state: &ViewState, p: DVec2| viewer.view(state).pose.direction(p).unwrap();
        let at = DVec2::new(30.0, 20.0);
        let before = looks(&state, at);
        viewer.apply(&mut state, Input::Wheel { notches: 3, at });
        assert!((looks(&state, at) - before).length() < 1e-9);
        let delta = DVec2::new(7.0, -4.0);
        viewer.apply(&mut state, Input::Key(Key::RotateRight));
        let before = looks(&state, at);
        viewer.apply(&mut state, Input::Drag(delta));
        assert!((looks(&state, at + delta) - before).length() < 1e-9);
        let centre = DVec2::new(60.0, 40.0);
        let before = looks(&state, centre);
        viewer.apply(&mut state, Input::Key(Key::RotateLeft));
        assert!((looks(&state, centre) - before).length() < 1e-9);
        assert_eq!(viewer.view(&state).pose.transform.shear, [0.2, 0.0]);
        assert!(viewer.shown_name(&state).ends_with("a 1/2 adjusted"));
        // The user's own view of the camera is untouched; `v` goes on
        // unadjusted, then to the camera's image, then round again.
        assert!(state.notches == 0 && state.translate == DVec2::ZERO);
        viewer.apply(&mut state, Input::Key(Key::V));
        assert_eq!(state.scene_viewport, Some(1));
        assert_eq!(
            viewer.view(&state).pose,
            scene.viewports[1].pose_at(&camera, 2)
        );
        viewer.apply(&mut state, Input::Key(Key::V));
        assert!(Viewer::is_camera_view(&state));
        assert_eq!(viewer.shown_name(&state), "camera");
        viewer.apply(&mut state, Input::Key(Key::V));
        assert_eq!(state.scene_viewport, Some(0));
        // A scene without viewports: `v` does nothing.
        let paper = paper();
        let mut plain = paper.opening();
        assert_eq!(paper.apply(&mut plain, Input::Key(Key::V)), Effect::Nothing);
    }

    #[test]
    fn a_wheel_past_the_zoom_limit_stops_at_it() {
        let viewer = paper();
        let at = DVec2::new(100.0, 60.0);
        // Notch by notch out, until the view refuses one.
        let mut stepped = ViewState::default();
        let mut steps = 0;
        while viewer.apply(&mut stepped, Input::Wheel { notches: -1, at }) == Effect::Changed {
            steps += 1;
        }
        assert!(steps > 0 && steps < MAX_NOTCHES, "{steps}");
        // Twenty at once reach the same limit.
        let mut state = ViewState::default();
        assert_eq!(
            viewer.apply(&mut state, Input::Wheel { notches: -20, at }),
            Effect::Changed
        );
        assert_eq!(state, stepped);
        assert_eq!(
            viewer.apply(&mut state, Input::Wheel { notches: -1, at }),
            Effect::Nothing
        );
    }

    #[test]
    fn a_perspective_view_zooms_out_no_wider_than_the_limit() {
        let viewer = perspective_viewer();
        let mut state = ViewState::default();
        let at = DVec2::new(320.0, 240.0);
        viewer.apply(
            &mut state,
            Input::Wheel {
                notches: -MAX_NOTCHES,
                at,
            },
        );
        let field =
            |notches: i32| 2.0 * ((30.0f64.to_radians()).tan() / ZOOM_STEP.powi(notches)).atan();
        // The widest view within the limit, one notch short of past it.
        assert!(state.notches < 0);
        assert!(
            field(state.notches) <= MAX_PERSPECTIVE_FOV,
            "{}",
            state.notches
        );
        assert!(field(state.notches - 1) > MAX_PERSPECTIVE_FOV);
        // A wide scene camera keeps its own field: zooming in is allowed,
        // and back out to it.
        let wide = SceneOverrides {
            projection: Some(Projection::Perspective),
            fov: Some(150.0),
            ..SceneOverrides::default()
        };
        let viewer = Viewer::new(&paper_scene(&wide).unwrap());
        let mut state = ViewState::default();
        viewer.apply(&mut state, Input::Wheel { notches: 2, at });
        assert_eq!(state.notches, 2);
        viewer.apply(&mut state, Input::Wheel { notches: -5, at });
        assert_eq!(state.notches, 0);
    }

    #[test]
    fn reset_goes_back_to_the_opening_view_at_the_frame_shown() {
        let viewer = paper();
        let mut state = viewer.opening();
        let at = DVec2::new(100.0, 60.0);
        viewer.apply(&mut state, Input::Drag(DVec2::new(-24.0, 8.0)));
        viewer.apply(&mut state, Input::Wheel { notches: 3, at });
        viewer.apply(&mut state, Input::Key(Key::RotateLeft));
        viewer.apply(&mut state, Input::Key(Key::M));
        assert_eq!(
            viewer.apply(&mut state, Input::Key(Key::Reset)),
            Effect::Changed
        );
        assert_eq!(
            state,
            ViewState {
                reuse: false,
                ..viewer.opening()
            }
        );
        assert_eq!(
            viewer.apply(&mut state, Input::Key(Key::Reset)),
            Effect::Nothing
        );
    }

    #[test]
    fn keys_step_frames_and_toggle() {
        let viewer = paper();
        let mut state = ViewState::default();
        // The paper scene has one frame: stepping changes nothing.
        assert_eq!(
            viewer.apply(&mut state, Input::Key(Key::Period)),
            Effect::Nothing
        );
        assert_eq!(
            viewer.apply(&mut state, Input::Key(Key::M)),
            Effect::Changed
        );
        assert!(!state.reuse);
        assert_eq!(
            viewer.apply(&mut state, Input::Key(Key::Quit)),
            Effect::Quit
        );
        viewer.apply(&mut state, Input::Key(Key::RotateLeft));
        viewer.apply(&mut state, Input::Key(Key::RotateRight));
        assert_eq!(state.rotate, 0.0);
        assert!(Viewer::is_camera_view(&state));
    }
}
