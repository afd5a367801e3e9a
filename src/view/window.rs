//! The viewer's window: winit over X11, pictures presented with softbuffer.
//!
//! The window's thread only turns input into view states, hands them to
//! the render thread, and presents the latest finished picture: input is
//! never blocked by tracing, and with nothing asked and nothing playing
//! the thread sleeps until the next event.
//!
//! Every way the window ends is an [`Ending`] handed back to its owner,
//! who writes what it was asked for and says why, except one: on losing
//! the X server, Xlib prints its own line and ends the process from inside
//! the event loop. That exit runs the exiting thread's thread-local
//! destructors (C++'s rule, which glibc follows), so a guard kept in one
//! says the program's `error:` and has the owner write what it was asked
//! for before the process goes.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::time::{Duration, Instant};

use glam::DVec2;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{
    DeviceEvent, DeviceId, ElementState, MouseButton, MouseScrollDelta, StartCause, WindowEvent,
};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, EventLoopProxy};
use winit::keyboard::{Key as WinitKey, NamedKey};
use winit::platform::x11::EventLoopBuilderExtX11;
use winit::window::{Fullscreen, Window, WindowId};
use x11rb::connection::Connection as _;
use x11rb::protocol::xproto::{ConnectionExt as _, EventMask, InputFocus};
use x11rb::rust_connection::RustConnection;

use crate::accel::BackendKind;
use crate::clock;
use crate::scene::Scene;

use super::help;
use super::state::{Effect, Input, Key, ViewState, Viewer, ZOOM_STEP};
use super::worker::{Picture, RenderThread};

/// What the window's owner does with presented pictures and saves.
pub trait Hooks {
    /// A picture was presented for the first time; `latency_ms` from the
    /// input it answers (or the opening) to its presentation, `first_ms`
    /// to the first picture shown for that input (a coarse one, or the
    /// complete one). Refined pictures of the same input follow it.
    fn presented(&mut self, picture: &Picture, latency_ms: f64, first_ms: f64, title: &str);
    /// The picture shown was drawn again, or drawn with the help or the
    /// overlay turned on or off (a new picture is [`Hooks::presented`]
    /// first); `asked` is the view the window asks for now.
    fn redrawn(&mut self, picture: &Picture, asked: &ViewState, shown: Shown);
    /// `s` was pressed: save `image` (the picture as shown); returns where
    /// it went.
    fn save(&mut self, image: &image::RgbImage) -> Result<String, String>;
    /// The window is open: `stop` ends it ([`Ending::Interrupted`]) from
    /// any thread, as an interrupt's handler does.
    fn opened(&mut self, stop: Stop);
    /// What to do if the X server is lost: called with the program's words
    /// for it on the window's thread while the process exits (exit status
    /// 1), it says them and writes what was asked for.
    fn when_display_lost(&mut self) -> LastWords;
}

/// Ends the window from another thread.
pub type Stop = Box<dyn FnOnce() + Send>;

/// Said and done as the process exits on losing the X server.
pub type LastWords = Box<dyn FnOnce(&str)>;

/// What is drawn over the picture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Shown {
    /// The help (`h`).
    pub help: bool,
    /// The picture painted where the last reuse picture traced (`t`).
    pub overlay: bool,
}

/// Why the window ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ending {
    /// `q` or Escape.
    Quit,
    /// Closed by its window manager (the user's close button).
    Closed,
    /// Destroyed by the window manager or another program.
    Destroyed,
    /// An interrupt (Ctrl-C, SIGTERM, SIGHUP) asked it to stop.
    Interrupted,
    /// It could not go on.
    Failed(String),
}

impl Ending {
    /// Why it ended, in words.
    pub fn why(&self) -> String {
        match self {
            Ending::Quit => "q or Escape pressed".to_string(),
            Ending::Closed => "the window was closed".to_string(),
            Ending::Destroyed => {
                "the window was destroyed (by its window manager or another program)".to_string()
            }
            Ending::Interrupted => "interrupted".to_string(),
            Ending::Failed(err) => err.clone(),
        }
    }
}

/// What wakes the window's thread besides X.
enum Wake {
    /// The render thread has finished a picture.
    Picture,
    /// An interrupt: end the window.
    Stop,
}

thread_local! {
    /// Said if the process ends on this thread while the window runs.
    static LAST_WORDS: RefCell<Option<Pending>> = const { RefCell::new(None) };
}

/// Words said when dropped, unless taken back first.
struct Pending(Option<Box<dyn FnOnce()>>);

impl Drop for Pending {
    fn drop(&mut self) {
        if let Some(say) = self.0.take() {
            say();
        }
    }
}

/// Keeps the last words ready while it lives; returning or unwinding, it
/// takes them back unsaid (a panic's exit is not a lost display).
struct Armed;

impl Armed {
    fn new(say: Box<dyn FnOnce()>) -> Armed {
        LAST_WORDS.with(|slot| *slot.borrow_mut() = Some(Pending(Some(say))));
        Armed
    }
}

impl Drop for Armed {
    fn drop(&mut self) {
        let _ = LAST_WORDS.try_with(|slot| {
            if let Some(pending) = slot.borrow_mut().as_mut() {
                pending.0 = None;
            }
        });
    }
}

/// The window's own X connection where no window manager runs: without
/// one nobody gives the window the keyboard's focus, nor a fullscreen
/// window the screen's size, so the window does both itself.
struct Unmanaged {
    connection: RustConnection,
}

impl Unmanaged {
    /// None where a window manager runs (the client that redirects the
    /// root window's children to itself), or the display cannot be
    /// reached this way.
    fn find() -> Option<Unmanaged> {
        let (connection, screen) = RustConnection::connect(None).ok()?;
        let root = connection.setup().roots.get(screen)?.root;
        let attributes = connection.get_window_attributes(root).ok()?.reply().ok()?;
        if attributes
            .all_event_masks
            .contains(EventMask::SUBSTRUCTURE_REDIRECT)
        {
            return None;
        }
        Some(Unmanaged { connection })
    }

    /// Gives `window` the keyboard's focus; whether the server took it (a
    /// window not mapped yet cannot have it).
    fn focus(&self, window: &Window) -> bool {
        let Ok(id) = u32::try_from(u64::from(window.id())) else {
            return false;
        };
        self.connection
            .set_input_focus(InputFocus::PARENT, id, x11rb::CURRENT_TIME)
            .ok()
            .and_then(|cookie| cookie.check().ok())
            .is_some()
    }
}

/// Opens the window on `scene` (its title starting `retrace view: NAME`)
/// and runs until it ends ([`Ending`]); idle, pictures are refined up to
/// `refine_spp` samples a pixel. An error: no window was opened.
pub fn run_window(
    scene: Scene,
    name: &str,
    backend: BackendKind,
    grid_resolution: Option<[u32; 3]>,
    refine_spp: u32,
    sample_memory: Option<u64>,
    hooks: &mut dyn Hooks,
) -> Result<Ending, String> {
    let event_loop = open_display()?;
    let proxy: EventLoopProxy<Wake> = event_loop.create_proxy();
    let viewer = Viewer::new(&scene);
    let wake = proxy.clone();
    let notify = Box::new(move || {
        let _ = wake.send_event(Wake::Picture);
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
    hooks.opened(Box::new(move || {
        let _ = proxy.send_event(Wake::Stop);
    }));
    let display = std::env::var("DISPLAY").unwrap_or_default();
    let last_words = hooks.when_display_lost();
    let armed = Armed::new(Box::new(move || {
        last_words(&format!(
            "lost the connection to the X server (DISPLAY {display}): it stopped, or closed \
             this program's connection"
        ))
    }));
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
        ending: None,
        help: false,
        windowed_size: None,
        unmanaged: Unmanaged::find(),
        focused: false,
        focus_given: false,
        wheel_release_due: false,
        zoom_limited: false,
        shown_at: VecDeque::new(),
        reported: None,
    };
    let ran = event_loop.run_app(&mut app);
    let ending = app.ending.take();
    // The window goes before the last words are taken back: closing it on
    // a lost server ends the process too.
    drop(app);
    drop(armed);
    Ok(match (ran, ending) {
        (Err(err), _) => Ending::Failed(format!("the window's event loop failed: {err}")),
        (Ok(()), Some(ending)) => ending,
        (Ok(()), None) => Ending::Closed,
    })
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
    /// Why the window is ending, once it is.
    ending: Option<Ending>,
    /// Showing the help over the picture.
    help: bool,
    /// The window's size before fullscreen, where the window sized itself
    /// to the screen (no window manager).
    windowed_size: Option<PhysicalSize<u32>>,
    unmanaged: Option<Unmanaged>,
    focused: bool,
    /// Whether the window gave itself the focus once it was shown.
    focus_given: bool,
    /// X reports a wheel click as a press and a release of button 4 or 5,
    /// each as a raw event and then the window's; winit 0.30 turns both
    /// window events into wheel notches. True between a raw release and
    /// the wheel event it echoes.
    wheel_release_due: bool,
    /// Whether the last wheel input stopped at the zoom limit.
    zoom_limited: bool,
    /// When the pictures of the last second were presented.
    shown_at: VecDeque<Instant>,
    /// The picture and what was drawn over it when last reported.
    reported: Option<((u64, bool, u32), Shown)>,
}

impl App<'_> {
    fn end(&mut self, event_loop: &ActiveEventLoop, ending: Ending) {
        self.ending.get_or_insert(ending);
        event_loop.exit();
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, err: String) {
        self.end(event_loop, Ending::Failed(err));
    }

    fn shown(&self) -> Shown {
        Shown {
            help: self.help,
            overlay: self.overlay,
        }
    }

    /// Pictures presented a second, over the last second (None: fewer
    /// than two).
    fn pictures_per_second(&self) -> Option<f64> {
        let (first, last) = (self.shown_at.front()?, self.shown_at.back()?);
        let seconds = last.duration_since(*first).as_secs_f64();
        (self.shown_at.len() > 1 && seconds > 0.0)
            .then(|| (self.shown_at.len() - 1) as f64 / seconds)
    }

    /// The keyboard's focus for the window where no window manager gives
    /// it: once the window is shown, and when the pointer comes in.
    fn take_focus(&mut self) {
        if self.focused {
            return;
        }
        if let (Some(unmanaged), Some(window)) = (&self.unmanaged, &self.window) {
            self.focus_given |= unmanaged.focus(window);
        }
    }

    fn toggle_fullscreen(&mut self) {
        let Some(window) = &self.window else {
            return;
        };
        if window.fullscreen().is_some() {
            window.set_fullscreen(None);
            if let Some(size) = self.windowed_size.take() {
                let _ = window.request_inner_size(size);
            }
            return;
        }
        let size = window.inner_size();
        window.set_fullscreen(Some(Fullscreen::Borderless(None)));
        // A window manager sizes a fullscreen window; without one the
        // window takes the screen's size itself.
        if self.unmanaged.is_some() {
            if let Some(monitor) = window.current_monitor() {
                self.windowed_size = Some(size);
                let _ = window.request_inner_size(monitor.size());
            }
        }
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
        let before = self.viewer.notches_of(&self.state);
        let effect = self.viewer.apply(&mut self.state, input);
        match input {
            // Told in the title: a wheel that stopped short of its notches.
            Input::Wheel { notches, .. } => {
                self.zoom_limited = self.viewer.notches_of(&self.state) - before != notches;
                self.show_title();
            }
            _ if effect == Effect::Changed => self.zoom_limited = false,
            _ => {}
        }
        match effect {
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
            Effect::ToggleOverlay | Effect::ToggleHelp => {
                match effect {
                    Effect::ToggleOverlay => self.overlay = !self.overlay,
                    _ => self.help = !self.help,
                }
                self.show_title();
                if let Some(window) = &self.window {
                    window.request_redraw();
                }
            }
            Effect::ToggleFullscreen => self.toggle_fullscreen(),
            Effect::Save => {
                let Some(picture) = self.thread.latest() else {
                    return;
                };
                match self.hooks.save(picture.shown(self.overlay)) {
                    Ok(_) => {}
                    Err(err) => self.fail(event_loop, err),
                }
            }
            Effect::Quit => self.end(event_loop, Ending::Quit),
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
        let notches = self.viewer.notches_of(&self.state);
        if notches != 0 || self.zoom_limited {
            title.push_str(&format!(" | zoom {:.2}x", ZOOM_STEP.powi(notches)));
            if self.zoom_limited {
                title.push_str(" (the limit)");
            }
        }
        if let Some(rate) = self.pictures_per_second() {
            title.push_str(&format!(" | {rate:.1} fps"));
        }
        if self.overlay {
            title.push_str(" | t: black where reuse traced");
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
        if self.help {
            help::draw(&mut buffer, width);
        }
        if let Err(err) = buffer.present() {
            return self.fail(event_loop, format!("cannot draw the window: {err}"));
        }
        self.take_focus();
        let key = (picture.generation, picture.complete, picture.samples);
        let new = key > self.presented;
        if new {
            self.presented = key;
            let now = Instant::now();
            self.shown_at.push_back(now);
            while self
                .shown_at
                .front()
                .is_some_and(|at| now.duration_since(*at) > Duration::from_secs(1))
            {
                self.shown_at.pop_front();
            }
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
        let reported = (key, self.shown());
        if !new || self.reported.is_some_and(|(_, shown)| shown != reported.1) {
            self.hooks.redrawn(&picture, &self.state, reported.1);
        }
        self.reported = Some(reported);
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

    fn user_event(&mut self, event_loop: &ActiveEventLoop, wake: Wake) {
        if let Wake::Stop = wake {
            return self.end(event_loop, Ending::Interrupted);
        }
        if let Some(err) = self.thread.failure() {
            return self.fail(event_loop, err);
        }
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => self.end(event_loop, Ending::Closed),
            WindowEvent::Destroyed => self.end(event_loop, Ending::Destroyed),
            WindowEvent::Focused(focused) => self.focused = focused,
            WindowEvent::CursorEntered { .. } => self.take_focus(),
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
                if std::mem::take(&mut self.wheel_release_due) {
                    return;
                }
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
                    WinitKey::Named(NamedKey::Home) => Some(Key::Reset),
                    WinitKey::Named(NamedKey::F1) => Some(Key::Help),
                    WinitKey::Named(NamedKey::F11) => Some(Key::Fullscreen),
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

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        // The raw event of a wheel button's release comes just before the
        // window's (X sends a raw event before the event it becomes); any
        // other raw event comes before the next input.
        self.wheel_release_due = matches!(
            event,
            DeviceEvent::Button {
                button: 4..=7,
                state: ElementState::Released
            }
        );
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        event_loop.set_control_flow(match self.playing {
            Some(due) => ControlFlow::WaitUntil(due),
            None => ControlFlow::Wait,
        });
    }
}
