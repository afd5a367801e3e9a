//! The viewer's window: winit over X11, pictures presented with softbuffer.
//!
//! The window's thread only turns input into view states, hands them to
//! the render thread, and presents the latest finished picture: input is
//! never blocked by tracing, and with nothing asked and nothing playing
//! the thread sleeps until the next event.

use std::rc::Rc;
use std::time::{Duration, Instant};

use glam::DVec2;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, StartCause, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, EventLoopProxy};
use winit::keyboard::{Key as WinitKey, NamedKey};
use winit::platform::x11::EventLoopBuilderExtX11;
use winit::window::{Window, WindowId};

use crate::accel::BackendKind;
use crate::clock;
use crate::scene::Scene;

use super::state::{Effect, Input, Key, ViewState, Viewer};
use super::worker::{Picture, RenderThread};

/// What the window's owner does with presented pictures and saves.
pub trait Hooks {
    /// A picture was presented for the first time; `latency_ms` from the
    /// input it answers (or the opening) to its presentation, `first_ms`
    /// to the first picture shown for that input (a coarse one, or the
    /// complete one). Refined pictures of the same input follow it.
    fn presented(&mut self, picture: &Picture, latency_ms: f64, first_ms: f64, title: &str);
    /// `s` was pressed: save `image` (the picture as shown); returns where
    /// it went.
    fn save(&mut self, image: &image::RgbImage) -> Result<String, String>;
}

/// The render thread has finished a picture.
struct Wake;

/// Opens the window on `scene` (its title starting `retrace view: NAME`)
/// and runs until it is closed, `q` or Escape; idle, pictures are refined
/// up to `refine_spp` samples a pixel.
pub fn run_window(
    scene: Scene,
    name: &str,
    backend: BackendKind,
    grid_resolution: Option<[u32; 3]>,
    refine_spp: u32,
    sample_memory: Option<u64>,
    hooks: &mut dyn Hooks,
) -> Result<(), String> {
    let event_loop = open_display()?;
    let proxy: EventLoopProxy<Wake> = event_loop.create_proxy();
    let viewer = Viewer::new(&scene);
    let notify = Box::new(move || {
        let _ = proxy.send_event(Wake);
    });
    let thread = RenderThread::spawn(
        scene,
        backend,
        grid_resolution,
        false,
        refine_spp,
        sample_memory,
        notify,
    )?;
    let state = viewer.opening();
    let mut app = App {
        name: name.to_string(),
        viewer,
        thread,
        state,
        generation: 0,
        asked: Vec::new(),
        window: None,
        surface: None,
        cursor: DVec2::ZERO,
        dragging: false,
        playing: None,
        overlay: false,
        presented: (0, false, 0),
        first_shown: None,
        answered: None,
        surface_size: (0, 0),
        hooks,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|err| format!("the window's event loop failed: {err}"))?;
    match app.error {
        Some(err) => Err(err),
        None => Ok(()),
    }
}

/// The X11 event loop, or why there is none. A library missing at run
/// time makes winit panic deep inside: that becomes an error naming it.
fn open_display() -> Result<EventLoop<Wake>, String> {
    const NEEDS: &str = "retrace view needs an X11 display: set DISPLAY, or use --script FILE \
                         without one";
    if std::env::var_os("DISPLAY").map_or(true, |d| d.is_empty()) {
        return Err(format!(
            "cannot open a window: DISPLAY is not set ({NEEDS})"
        ));
    }
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let built = std::panic::catch_unwind(|| {
        EventLoop::<Wake>::with_user_event()
            .with_any_thread(true)
            .build()
    });
    std::panic::set_hook(previous);
    match built {
        Ok(Ok(event_loop)) => Ok(event_loop),
        Ok(Err(err)) => {
            // winit's words start with where in its source they were said.
            let text = err.to_string();
            let said = text.rsplit_once(".rs:").map_or(text.as_str(), |(_, rest)| {
                rest.split_once(": ").map_or(rest, |(_, said)| said)
            });
            Err(format!("cannot open a window: {said} ({NEEDS})"))
        }
        Err(panic) => {
            let text = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown failure");
            Err(format!(
                "cannot open a window: {text} (on Debian the window needs libx11-6 \
                 libx11-xcb1 libxcursor1 libxi6 libxkbcommon-x11-0)"
            ))
        }
    }
}

struct App<'h> {
    name: String,
    viewer: Viewer,
    thread: RenderThread,
    state: ViewState,
    generation: u64,
    /// When each request not yet presented was made.
    asked: Vec<(u64, Instant)>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    cursor: DVec2,
    dragging: bool,
    /// When the next frame of a playing timeline is due.
    playing: Option<Instant>,
    /// Showing the picture painted where it traced.
    overlay: bool,
    /// The request of the picture last presented, whether it was
    /// complete, and its samples a pixel.
    presented: (u64, bool, u32),
    /// The request whose coarse picture was presented, and its latency.
    first_shown: Option<(u64, f64)>,
    /// The request last answered by a complete picture, and when it was
    /// made (its refined pictures are timed from then).
    answered: Option<(u64, Instant)>,
    /// The window's drawing buffer, pixels.
    surface_size: (u32, u32),
    hooks: &'h mut dyn Hooks,
    error: Option<String>,
}

impl App<'_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, err: String) {
        self.error.get_or_insert(err);
        event_loop.exit();
    }

    fn ask(&mut self) {
        self.generation += 1;
        self.asked.push((self.generation, Instant::now()));
        self.thread.request(self.generation, self.state.clone());
    }

    fn frame_period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.viewer.fps().max(0.1))
    }

    fn act(&mut self, event_loop: &ActiveEventLoop, input: Input) {
        match self.viewer.apply(&mut self.state, input) {
            Effect::Changed => self.ask(),
            Effect::Nothing => {}
            Effect::TogglePlay => {
                self.playing = match self.playing {
                    Some(_) => None,
                    None if self.viewer.frames() > 1 => Some(Instant::now()),
                    None => None,
                };
                self.show_title();
            }
            Effect::ToggleOverlay => {
                self.overlay = !self.overlay;
                if let Some(window) = &self.window {
                    window.request_redraw();
                }
            }
            Effect::Save => {
                let Some(picture) = self.thread.latest() else {
                    return;
                };
                match self.hooks.save(picture.shown(self.overlay)) {
                    Ok(_) => {}
                    Err(err) => self.fail(event_loop, err),
                }
            }
            Effect::Quit => event_loop.exit(),
        }
    }

    fn title(&self, picture: Option<&Picture>) -> String {
        let mut title = format!("retrace view: {}", self.name);
        if !self.viewer.scene_viewports().is_empty() {
            // Which view is shown (`v` cycles): the picture's, or the one
            // asked for before any picture.
            let state = picture.map_or(&self.state, |p| &p.state);
            title.push_str(&format!(" | {}", self.viewer.shown_name(state)));
        }
        if let Some(p) = picture {
            title.push_str(&format!(
                " | {} spp | {:.1} ms | {:.1}% traced | reuse {} ({})",
                p.samples,
                p.stats.total_ms(),
                100.0 * p.traced_share(),
                if p.state.reuse { "on" } else { "off" },
                p.mode()
            ));
        }
        let frames = self.viewer.frames();
        if frames > 1 {
            title.push_str(&format!(" | frame {}/{frames}", self.state.frame));
            if self.playing.is_some() {
                title.push_str(" playing");
            }
        }
        title
    }

    fn show_title(&self) {
        if let Some(window) = &self.window {
            window.set_title(&self.title(self.thread.latest().as_deref()));
        }
    }

    /// Presents the latest picture (again, after an expose).
    fn present(&mut self, event_loop: &ActiveEventLoop) {
        let Some(picture) = self.thread.latest() else {
            return;
        };
        let Some(surface) = self.surface.as_mut() else {
            return;
        };
        let mut buffer = match surface.buffer_mut() {
            Ok(buffer) => buffer,
            Err(err) => return self.fail(event_loop, format!("cannot draw the window: {err}")),
        };
        let shown = picture.shown(self.overlay);
        // Until the picture of a new size is ready, the last one shows in
        // the corner of the resized window.
        let width = self.surface_size.0 as usize;
        if (shown.width(), shown.height()) != self.surface_size {
            buffer.fill(0);
        }
        for (row, line) in buffer
            .chunks_exact_mut(width.max(1))
            .zip(shown.as_raw().chunks_exact(3 * shown.width() as usize))
        {
            for (word, p) in row.iter_mut().zip(line.chunks_exact(3)) {
                *word = u32::from(p[0]) << 16 | u32::from(p[1]) << 8 | u32::from(p[2]);
            }
        }
        if let Err(err) = buffer.present() {
            return self.fail(event_loop, format!("cannot draw the window: {err}"));
        }
        let key = (picture.generation, picture.complete, picture.samples);
        if key > self.presented {
            self.presented = key;
            let now = Instant::now();
            let asked_at = match self.answered {
                Some((g, at)) if g == picture.generation => Some(at),
                _ => self
                    .asked
                    .iter()
                    .find(|(g, _)| *g <= picture.generation)
                    .map(|(_, at)| *at),
            };
            let since = asked_at.map_or(0.0, |at| clock::ms(now.duration_since(at)));
            let first = match self.first_shown {
                Some((g, ms)) if g == picture.generation => ms,
                _ => since,
            };
            if picture.complete {
                if let Some(at) = asked_at {
                    self.answered = Some((picture.generation, at));
                }
                self.asked.retain(|(g, _)| *g > picture.generation);
            } else {
                self.first_shown = Some((picture.generation, since));
            }
            let title = self.title(Some(&picture));
            if let Some(window) = &self.window {
                window.set_title(&title);
            }
            self.hooks.presented(&picture, since, first, &title);
        }
    }
}

impl ApplicationHandler<Wake> for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (width, height) = self.viewer.size();
        let attributes = Window::default_attributes()
            .with_title(self.title(None))
            .with_inner_size(PhysicalSize::new(width, height))
            .with_resizable(true);
        let window = match event_loop.create_window(attributes) {
            Ok(window) => Rc::new(window),
            Err(err) => return self.fail(event_loop, format!("cannot open a window: {err}")),
        };
        let surface = softbuffer::Context::new(Rc::clone(&window))
            .and_then(|context| softbuffer::Surface::new(&context, Rc::clone(&window)));
        let mut surface = match surface {
            Ok(surface) => surface,
            Err(err) => return self.fail(event_loop, format!("cannot draw the window: {err}")),
        };
        let size = (
            std::num::NonZeroU32::new(width),
            std::num::NonZeroU32::new(height),
        );
        if let (Some(w), Some(h)) = size {
            if let Err(err) = surface.resize(w, h) {
                return self.fail(event_loop, format!("cannot draw the window: {err}"));
            }
        }
        self.window = Some(window);
        self.surface = Some(surface);
        self.surface_size = (width, height);
        self.ask();
    }

    fn new_events(&mut self, event_loop: &ActiveEventLoop, cause: StartCause) {
        if let (StartCause::ResumeTimeReached { .. }, Some(due)) = (cause, self.playing) {
            if Instant::now() >= due {
                if self.viewer.advance(&mut self.state) == Effect::Changed {
                    self.ask();
                }
                // Late frames are dropped, not caught up.
                self.playing = Some((due + self.frame_period()).max(Instant::now()));
                self.show_title();
            }
        }
        let _ = event_loop;
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, _: Wake) {
        if let Some(err) = self.thread.failure() {
            return self.fail(event_loop, err);
        }
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => self.present(event_loop),
            WindowEvent::Resized(size) => {
                let (Some(width), Some(height)) = (
                    std::num::NonZeroU32::new(size.width),
                    std::num::NonZeroU32::new(size.height),
                ) else {
                    return;
                };
                if (size.width, size.height) == self.surface_size {
                    return;
                }
                if let Some(surface) = self.surface.as_mut() {
                    if let Err(err) = surface.resize(width, height) {
                        return self.fail(event_loop, format!("cannot draw the window: {err}"));
                    }
                }
                self.surface_size = (size.width, size.height);
                self.act(event_loop, Input::Resize(size.width, size.height));
                if let Some(window) = &self.window {
                    window.request_redraw();
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let at = DVec2::new(position.x, position.y);
                let delta = at - self.cursor;
                self.cursor = at;
                if self.dragging && delta != DVec2::ZERO {
                    self.act(event_loop, Input::Drag(delta));
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => self.dragging = state == ElementState::Pressed,
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(y),
                    // A touchpad's pixels: about a notch per 40.
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                let notches = lines.round() as i32;
                if notches != 0 {
                    let at = self.cursor;
                    self.act(event_loop, Input::Wheel { notches, at });
                }
            }
            WindowEvent::KeyboardInput {
                event,
                is_synthetic,
                ..
            } => {
                // Keys held when the window gains focus come back as
                // synthetic presses: not the user's.
                if is_synthetic || event.state != ElementState::Pressed {
                    return;
                }
                let key = match &event.logical_key {
                    WinitKey::Named(NamedKey::ArrowLeft) => Some(Key::Left),
                    WinitKey::Named(NamedKey::ArrowRight) => Some(Key::Right),
                    WinitKey::Named(NamedKey::ArrowUp) => Some(Key::Up),
                    WinitKey::Named(NamedKey::ArrowDown) => Some(Key::Down),
                    WinitKey::Named(NamedKey::Space) => Some(Key::Space),
                    WinitKey::Named(NamedKey::Escape) => Some(Key::Quit),
                    WinitKey::Character(text) => Key::parse(text),
                    _ => None,
                };
                if let Some(key) = key {
                    self.act(event_loop, Input::Key(key));
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        event_loop.set_control_flow(match self.playing {
            Some(due) => ControlFlow::WaitUntil(due),
            None => ControlFlow::Wait,
        });
    }
}
