//! `furbake view INPUT`: shows a runtime world live in a window — one job, the interactive host
//! of the same world and renderer `furbake preview` draws headless. INPUT is a runtime scene
//! (`.toml`) or a pack, which gets a default scene ([`session::pack_world`]). The world steps at
//! the scene's time step in real time; the keys and the mouse drive the camera, time, clips and
//! effects ([`VIEW_CONTROLS`]); the window title reports the frame time and the slowest
//! simulation stage. `--frames N` runs unattended (one time step per frame, no pacing) and
//! `--screenshot FILE.png` writes the last frame.
//!
//! Arguments become a validated [`ViewPlan`], and the world is loaded and checked against
//! `--max-memory`, before any window opens. Then a winit event loop ([`App`]) owns the window;
//! [`screen`] is its GPU host, [`session`] the world and what the keys do to it.

mod screen;
mod session;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use furbake_runtime::Camera;
use glam::Vec3;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use crate::args::ViewArgs;
use crate::failure::Failure;
use crate::preview_cmd::{self, InputKind};
use screen::Screen;
use session::Session;

/// Most time steps taken in one frame to keep up with real time; a frame that needs more drops
/// the rest (the scene then runs in slow motion, which the title shows).
const MAX_STEPS_PER_FRAME: u32 = 4;
/// Longest wall-clock gap counted between two frames, seconds (a stall, e.g. a window drag, is
/// not caught up).
const MAX_FRAME_GAP_S: f64 = 0.25;
/// How often the window title is rewritten.
const TITLE_EVERY: Duration = Duration::from_millis(250);
/// Weight of the newest frame in the smoothed frame time (exponential moving average).
const FRAME_TIME_SMOOTHING: f64 = 0.1;
/// Time steps one Left/Right press moves.
const SCRUB_STEPS: u64 = 1;
/// Time steps one Shift+Left/Right press moves.
const SHIFT_SCRUB_STEPS: u64 = 10;
/// Orbit rate, radians per pixel dragged.
const ORBIT_RAD_PER_PX: f32 = 0.008;
/// Zoom factor per wheel notch (in: the distance shrinks by this).
const ZOOM_PER_NOTCH: f32 = 0.88;
/// Frames in a row the surface may refuse to give a texture in an unattended run before it
/// fails (the window never became drawable).
const MAX_SKIPPED_FRAMES: u32 = 600;

/// The controls, printed on stderr when an interactive viewer starts (the same text ends
/// `furbake view --help`).
pub const VIEW_CONTROLS: &str = "\
controls: left drag orbit · right drag or shift+left drag pan · wheel zoom
          Space play/pause · Right step forward (Shift: 10 steps) · Left step back (Shift: 10; re-simulates from 0)
          C next animation clip · 1-9 switch the n-th declared effect off/on · R reset · Esc or Q quit
          S shading on/off (flat) · F fins on/off · T alpha blend/test · [ ] halve/double the shells · L shell level of detail on/off · G grass culling on/off";

/// What `furbake view` will do, validated.
#[derive(Debug)]
pub struct ViewPlan {
    /// The scene or pack.
    input: PathBuf,
    /// Which of the two it is.
    kind: InputKind,
    /// Window size in pixels.
    size: (u32, u32),
    /// `--frames N`: unattended, N frames; `None`: interactive.
    frames: Option<u32>,
    /// `--screenshot`: where the last unattended frame goes.
    screenshot: Option<PathBuf>,
    /// `--max-memory`, bytes.
    max_memory: u64,
    /// `--shells`, `--no-fins`, `--blend`, `--flat`, …: over the scene's `[render]`.
    render: furbake_runtime::RenderOptions,
}

/// Runs `furbake view`.
pub fn run(args: ViewArgs, quiet: bool) -> Result<(), Failure> {
    let plan = plan(args)?;
    let (w, h) = plan.size;
    let target_bytes = screen::TARGET_BYTES_PER_PIXEL * w as u64 * h as u64;
    let world = match plan.kind {
        InputKind::Scene => preview_cmd::open_scene_world(&plan.input, target_bytes, plan.max_memory)?,
        InputKind::Pack => session::pack_world(&plan.input, w as f32 / h as f32, target_bytes, plan.max_memory)?,
    };
    let session = Session::new(&plan.input, world);
    let event_loop = EventLoop::new().map_err(|e| no_display(&os_message(&e.to_string())))?;
    if !quiet && plan.frames.is_none() {
        eprintln!("{VIEW_CONTROLS}");
        eprintln!("{}", effect_keys(&session));
    }
    let mut app = App::new(plan, session, quiet);
    let ran = event_loop.run_app(&mut app);
    if let Some(failure) = app.failure {
        return Err(failure);
    }
    ran.map_err(|e| Failure::Input(anyhow!("{}: the window's event loop failed: {e}", app.session.path.display())))
}

/// Stage two of argument parsing.
fn plan(args: ViewArgs) -> Result<ViewPlan, Failure> {
    let kind = preview_cmd::input_kind(&args.input)?;
    let render = preview_cmd::render_options(&args.render)?;
    if args.screenshot.is_some() && args.frames.is_none() {
        // clap enforces it; this is the message should that ever change.
        return Err(Failure::Usage(anyhow!("--screenshot needs --frames N (the frame it writes is the last)")));
    }
    if let Some(png) = &args.screenshot {
        // The screenshot may not replace what is viewed (docs/design.md "Safe outputs").
        crate::files::Files::with_inputs([args.input.as_path()]).output("--screenshot", png)?;
    }
    Ok(ViewPlan {
        input: args.input,
        kind,
        size: args.size,
        frames: args.frames,
        screenshot: args.screenshot,
        max_memory: args.max_memory,
        render,
    })
}

/// No display to open a window on: bad input (exit 1), saying what to set or run.
fn no_display(detail: &str) -> Failure {
    let var = |name| std::env::var(name).map_or("unset".to_string(), |v| format!("{v:?}"));
    Failure::Input(anyhow!(
        "cannot open a window: {detail} (DISPLAY is {}, WAYLAND_DISPLAY is {}). `furbake view` needs a display: \
         set DISPLAY (X11) or WAYLAND_DISPLAY (Wayland), or run it under a virtual X server: \
         xvfb-run -a furbake view INPUT --frames N --screenshot FILE.png (Debian/Ubuntu: apt-get install xvfb)",
        var("DISPLAY"),
        var("WAYLAND_DISPLAY")
    ))
}

/// winit's message without the source location it prefixes OS errors with
/// (`os error at FILE:LINE: message`).
fn os_message(message: &str) -> String {
    match message.strip_prefix("os error at ").and_then(|rest| rest.split_once(": ")) {
        Some((_, inner)) => inner.trim_end_matches('.').to_string(),
        None => message.to_string(),
    }
}

/// Which number key switches which effect, for the start-up message.
fn effect_keys(session: &Session) -> String {
    if session.effects.is_empty() {
        return "effects: none declared".into();
    }
    let keys: Vec<String> = session
        .effects
        .iter()
        .enumerate()
        .map(|(i, &(effect, _))| {
            let name = session::effect_name(effect);
            match (i < 9, session::is_switchable(effect)) {
                (true, true) => format!("{} {name}", i + 1),
                (true, false) => format!("{} {name} (fixed)", i + 1),
                (false, _) => format!("{name} (no key)"),
            }
        })
        .collect();
    format!("effects: {}", keys.join(" · "))
}

/// The viewer's camera once the user moves it: an orbit around `target` (yaw about +Y from +Z,
/// pitch above the horizontal, radians) at `distance_m`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct OrbitCamera {
    target: Vec3,
    distance_m: f32,
    yaw: f32,
    pitch: f32,
    up: Vec3,
    fov_y_deg: f32,
}

impl OrbitCamera {
    /// The orbit that sees what `camera` sees.
    fn around(camera: &Camera) -> OrbitCamera {
        let (eye, target) = (Vec3::from(camera.eye), Vec3::from(camera.target));
        let offset = eye - target;
        let distance_m = offset.length().max(1e-4);
        let dir = offset / distance_m;
        OrbitCamera {
            target,
            distance_m,
            yaw: dir.x.atan2(dir.z),
            pitch: dir.y.clamp(-1.0, 1.0).asin(),
            up: Vec3::from(camera.up),
            fov_y_deg: camera.fov_y_deg,
        }
    }

    fn camera(&self) -> Camera {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        let eye = self.target + Vec3::new(cp * sy, sp, cp * cy) * self.distance_m;
        Camera {
            eye: eye.to_array(),
            target: self.target.to_array(),
            up: self.up.to_array(),
            fov_y_deg: self.fov_y_deg,
        }
    }

    /// Turns around the target: `dx`, `dy` pixels dragged (right, down).
    fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * ORBIT_RAD_PER_PX;
        self.pitch = (self.pitch + dy * ORBIT_RAD_PER_PX).clamp(-1.55, 1.55);
    }

    /// Moves the target with the scene under the cursor: `dx`, `dy` pixels dragged in a window
    /// `height_px` tall.
    fn pan(&mut self, dx: f32, dy: f32, height_px: f32) {
        let c = self.camera();
        let forward = (self.target - Vec3::from(c.eye)).normalize_or_zero();
        let right = forward.cross(self.up).normalize_or_zero();
        let up = right.cross(forward);
        let metres_per_px = 2.0 * self.distance_m * (self.fov_y_deg.to_radians() * 0.5).tan() / height_px.max(1.0);
        self.target += (up * dy - right * dx) * metres_per_px;
    }

    /// Moves toward the target (`notches` > 0) or away.
    fn zoom(&mut self, notches: f32) {
        self.distance_m = (self.distance_m * ZOOM_PER_NOTCH.powf(notches)).clamp(1e-3, 1e6);
    }
}

/// Mouse buttons and modifiers held.
#[derive(Default)]
struct Pointer {
    position: Option<(f64, f64)>,
    left: bool,
    right: bool,
    shift: bool,
}

/// Frame timing: the smoothed frame time and real-time pacing.
struct Clock {
    /// When the last frame was presented.
    last_frame: Option<Instant>,
    /// Smoothed wall time of a frame (its steps, drawing and presenting), seconds.
    frame_s: Option<f64>,
    /// Wall time not yet simulated, seconds, and when it was last counted.
    pending_s: f64,
    last_tick: Option<Instant>,
    /// When the title was last written, and the scene time then.
    title_at: Option<(Instant, f64)>,
    /// Scene seconds per wall second over the last title period (1 = real time).
    speed: f64,
    /// When the first frame was presented, and frames presented since.
    first_frame: Option<Instant>,
    frames: u32,
}

/// The winit application: the window, its GPU host and the world.
struct App {
    plan: ViewPlan,
    session: Session,
    quiet: bool,
    screen: Option<Screen>,
    pointer: Pointer,
    /// `None` until the user moves the camera: then the scene's camera (as last drawn) is left.
    orbit: Option<OrbitCamera>,
    /// The camera of the last frame drawn.
    shown: Option<Camera>,
    clock: Clock,
    /// Frames in a row the surface gave no texture.
    skipped: u32,
    /// Something changed that the next frame must show (while paused).
    dirty: bool,
    /// Why the viewer stopped, when it failed.
    failure: Option<Failure>,
}

impl App {
    fn new(plan: ViewPlan, session: Session, quiet: bool) -> App {
        App {
            plan,
            session,
            quiet,
            screen: None,
            pointer: Pointer::default(),
            orbit: None,
            shown: None,
            clock: Clock {
                last_frame: None,
                frame_s: None,
                pending_s: 0.0,
                last_tick: None,
                title_at: None,
                speed: 1.0,
                first_frame: None,
                frames: 0,
            },
            skipped: 0,
            dirty: true,
            failure: None,
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, failure: Failure) {
        self.failure.get_or_insert(failure);
        event_loop.exit();
    }

    fn open_window(&mut self, event_loop: &ActiveEventLoop) -> Result<(), Failure> {
        let (w, h) = self.plan.size;
        let attributes = Window::default_attributes()
            .with_title(format!("furbake view {}", self.session.path.display()))
            .with_inner_size(PhysicalSize::new(w, h))
            // An unattended run keeps its size: the screenshot is --size.
            .with_resizable(self.plan.frames.is_none());
        let window = event_loop.create_window(attributes).map_err(|e| no_display(&os_message(&e.to_string())))?;
        let vsync = self.plan.frames.is_none();
        let screen = Screen::new(Arc::new(window), &self.session.world, &self.session.path, vsync, self.plan.render)?;
        if !self.quiet && screen.size() != self.plan.size {
            eprintln!(
                "furbake: note: the window is {}x{}, not the --size asked for (the window system chose)",
                screen.size().0,
                screen.size().1
            );
        }
        screen.window.request_redraw();
        self.screen = Some(screen);
        Ok(())
    }

    /// One frame: steps the world (real time, or one step unattended), draws and presents,
    /// rewrites the title, and after an unattended run's last frame writes the screenshot and
    /// ends the loop.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), Failure> {
        let unattended = self.plan.frames.is_some();
        let started = Instant::now();
        if !unattended {
            self.advance_real_time(started)?;
        }
        let Some(screen) = self.screen.as_mut() else { return Ok(()) };
        let Some(texture) = screen.acquire(&self.session.path)? else {
            self.skipped += 1;
            if unattended && self.skipped > MAX_SKIPPED_FRAMES {
                return Err(Failure::Input(anyhow!(
                    "{}: the window's surface gave no texture for {MAX_SKIPPED_FRAMES} frames in a row",
                    self.session.path.display()
                )));
            }
            return Ok(());
        };
        self.skipped = 0;
        if unattended {
            self.session.step()?;
        }
        let mut view = screen.world_view(&self.session.world);
        if let Some(orbit) = &self.orbit {
            view.camera = orbit.camera();
        }
        screen.draw(texture, &self.session.world, &view, &self.session.path)?;
        self.shown = Some(view.camera);
        self.dirty = false;
        self.count_frame(started, Instant::now());
        if self.plan.frames.is_some_and(|frames| self.clock.frames >= frames) {
            self.finish(event_loop)?;
        }
        Ok(())
    }

    /// Takes the time steps the wall time since the last frame calls for (none while paused).
    fn advance_real_time(&mut self, now: Instant) -> Result<(), Failure> {
        let elapsed = self.clock.last_tick.replace(now).map_or(0.0, |t| (now - t).as_secs_f64().min(MAX_FRAME_GAP_S));
        if !self.session.playing {
            self.clock.pending_s = 0.0;
            return Ok(());
        }
        self.clock.pending_s += elapsed;
        let dt = self.session.time_step_s();
        let mut steps = 0;
        while self.clock.pending_s >= dt && steps < MAX_STEPS_PER_FRAME {
            self.session.step()?;
            self.clock.pending_s -= dt;
            steps += 1;
        }
        // Behind by more than a frame's worth of steps: drop the rest (slow motion).
        self.clock.pending_s = self.clock.pending_s.min(dt);
        Ok(())
    }

    /// Books a frame whose work (steps, draw, present) ran from `started` to `now`.
    fn count_frame(&mut self, started: Instant, now: Instant) {
        let c = &mut self.clock;
        // The frame's own wall time: back to back while time runs this is the time between
        // frames; while paused (frames only on input) it is still the cost of one.
        let work = (now - started).as_secs_f64();
        c.frame_s = Some(c.frame_s.map_or(work, |s| s + (work - s) * FRAME_TIME_SMOOTHING));
        c.last_frame = Some(now);
        c.first_frame.get_or_insert(now);
        c.frames += 1;
        let time_s = self.session.world.time_s();
        let due = c.title_at.is_none_or(|(at, _)| now - at >= TITLE_EVERY);
        if due {
            if let Some((at, t0)) = c.title_at {
                c.speed = (time_s - t0) / (now - at).as_secs_f64().max(1e-9);
            }
            c.title_at = Some((now, time_s));
            let title = self.title();
            if let Some(screen) = &self.screen {
                screen.window.set_title(&title);
            }
        }
    }

    /// `furbake view fox_and_grass.toml — 41.7 ms/frame · t 1.24 s · playing 0.48× · clip Walk ·
    /// off: wind · slowest fur_solver (fox) 850 µs`
    fn title(&self) -> String {
        let name = self
            .session
            .path
            .file_name()
            .map_or_else(|| self.session.path.display().to_string(), |n| n.to_string_lossy().into_owned());
        let mut parts = Vec::new();
        if let Some(s) = self.clock.frame_s {
            parts.push(format!("{:.1} ms/frame", s * 1e3));
        }
        parts.push(format!("t {:.2} s", self.session.world.time_s()));
        parts.push(match (self.session.playing, self.plan.frames) {
            (false, _) => "paused".to_string(),
            (true, Some(_)) => "unattended".to_string(),
            (true, None) => format!("playing {:.2}×", self.clock.speed),
        });
        if let Some(clip) = self.session.clip() {
            parts.push(format!("clip {clip}"));
        }
        let off = self.session.switched_off();
        if !off.is_empty() {
            parts.push(format!("off: {}", off.join(", ")));
        }
        if let Some(drawn) = self.screen.as_ref().and_then(Screen::drawn) {
            parts.push(drawn);
        }
        if let Some(stage) = self.session.slowest_stage() {
            parts.push(format!("slowest {} ({}) {} µs", stage.name, stage.pack, stage.mean().as_micros()));
        }
        format!("furbake view {name} — {}", parts.join(" · "))
    }

    /// The end of an unattended run: the screenshot, a summary, the loop's end.
    fn finish(&mut self, event_loop: &ActiveEventLoop) -> Result<(), Failure> {
        let Some(screen) = &self.screen else { return Ok(()) };
        if let Some(png) = &self.plan.screenshot {
            let image = screen.screenshot(&self.session.path)?;
            preview_cmd::write_png(png, &image)?;
        }
        if !self.quiet {
            let c = &self.clock;
            let wall = c.first_frame.zip(c.last_frame).map_or(0.0, |(a, b)| (b - a).as_secs_f64());
            let mean_ms = if c.frames > 1 { wall / (c.frames - 1) as f64 * 1e3 } else { 0.0 };
            let (w, h) = screen.size();
            let written = self.plan.screenshot.as_ref().map_or(String::new(), |p| format!(" → {}", p.display()));
            eprintln!(
                "viewed {} on {}: {} frames of {w}×{h}, {mean_ms:.1} ms/frame mean, {:.3} s scene time{written}",
                self.session.path.display(),
                screen.adapter,
                c.frames,
                self.session.world.time_s()
            );
            eprintln!("last title: {}", self.title());
        }
        event_loop.exit();
        Ok(())
    }

    fn key(&mut self, event: &KeyEvent, event_loop: &ActiveEventLoop) -> Result<(), Failure> {
        let steps = if self.pointer.shift { SHIFT_SCRUB_STEPS } else { SCRUB_STEPS };
        let say = |message: String| {
            if !self.quiet {
                eprintln!("{message}");
            }
        };
        match event.logical_key.as_ref() {
            Key::Named(NamedKey::Escape) => event_loop.exit(),
            Key::Named(NamedKey::Space) => {
                self.session.playing = !self.session.playing;
                self.clock.pending_s = 0.0;
            }
            Key::Named(NamedKey::ArrowRight) => {
                self.session.playing = false;
                for _ in 0..steps {
                    self.session.step()?;
                }
            }
            Key::Named(NamedKey::ArrowLeft) => self.session.step_back(steps)?,
            Key::Character(c) => match c.to_ascii_lowercase().as_str() {
                "q" => event_loop.exit(),
                "r" => {
                    self.session.reset()?;
                    self.orbit = None;
                    self.clock.pending_s = 0.0;
                }
                "c" => match self.session.next_clip()? {
                    Some(clips) => say(format!("clip: {clips}")),
                    None => say("clip: no pack of this scene is animated".into()),
                },
                "s" | "f" | "t" | "[" | "]" | "l" => {
                    let Some(screen) = self.screen.as_mut() else { return Ok(()) };
                    let path = &self.session.path;
                    let message = screen
                        .toggle_render(c.to_ascii_lowercase().as_str(), &self.session.world)
                        .map_err(|e| crate::preview_cmd::render_failure(e, path))?;
                    say(message);
                }
                "g" => {
                    let Some(screen) = self.screen.as_mut() else { return Ok(()) };
                    let path = &self.session.path;
                    match screen
                        .toggle_grass_culling(&self.session.world)
                        .map_err(|e| crate::preview_cmd::render_failure(e, path))?
                    {
                        Some(true) => say("grass: culled, distance LOD (the scene's [grass_culling])".into()),
                        Some(false) => say("grass: every blade at full detail (culling off)".into()),
                        None => say("grass: this scene has no grass".into()),
                    }
                }
                digit => {
                    if let Some(n) = digit.parse::<usize>().ok().filter(|n| (1..=9).contains(n)) {
                        let message = self.session.toggle_effect(n - 1)?;
                        say(message);
                    }
                }
            },
            _ => return Ok(()),
        }
        // Scene time may have jumped: the next title starts a new speed measurement.
        self.clock.title_at = None;
        self.dirty = true;
        Ok(())
    }

    fn pointer_moved(&mut self, x: f64, y: f64) {
        let last = self.pointer.position.replace((x, y));
        let (Some((lx, ly)), Some(screen)) = (last, &self.screen) else { return };
        let (dx, dy) = ((x - lx) as f32, (y - ly) as f32);
        let pan = self.pointer.right || (self.pointer.left && self.pointer.shift);
        if !(pan || self.pointer.left) {
            return;
        }
        let Some(shown) = self.shown else { return };
        let orbit = self.orbit.get_or_insert_with(|| OrbitCamera::around(&shown));
        if pan {
            orbit.pan(dx, dy, screen.size().1 as f32);
        } else {
            orbit.orbit(dx, dy);
        }
        self.dirty = true;
    }

    fn zoom(&mut self, notches: f32) {
        let Some(shown) = self.shown else { return };
        self.orbit.get_or_insert_with(|| OrbitCamera::around(&shown)).zoom(notches);
        self.dirty = true;
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.screen.is_some() {
            return;
        }
        if let Err(failure) = self.open_window(event_loop) {
            self.fail(event_loop, failure);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _window: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                if let Some(screen) = &mut self.screen {
                    screen.resize(size.width, size.height);
                }
                self.dirty = true;
                Ok(())
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                self.key(&event, event_loop)
            }
            WindowEvent::ModifiersChanged(modifiers) => {
                self.pointer.shift = modifiers.state().shift_key();
                Ok(())
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let down = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => self.pointer.left = down,
                    MouseButton::Right => self.pointer.right = down,
                    _ => {}
                }
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.pointer_moved(position.x, position.y);
                Ok(())
            }
            WindowEvent::CursorLeft { .. } => {
                self.pointer.position = None;
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                self.zoom(match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                });
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(failure) = result {
            self.fail(event_loop, failure);
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        // Continuous frames while time runs (or unattended); while paused, only after a change.
        let busy = self.plan.frames.is_some() || self.session.playing || self.dirty;
        if let (true, Some(screen)) = (busy, &self.screen) {
            screen.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_orbit_around_a_camera_sees_what_it_sees() {
        let cameras = [
            Camera { eye: [1.6, 1.0, 2.2], target: [0.0, 0.3, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
            Camera { eye: [-3.0, -0.5, 0.1], target: [0.2, 0.0, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 60.0 },
        ];
        for c in &cameras {
            let back = OrbitCamera::around(c).camera();
            for (a, b) in back.eye.iter().zip(&c.eye).chain(back.target.iter().zip(&c.target)) {
                assert!((a - b).abs() < 1e-5, "{back:?} vs {c:?}");
            }
        }
        assert_eq!(cameras.len(), 2);
    }

    #[test]
    fn orbit_pan_and_zoom_keep_what_they_should() {
        let c = Camera { eye: [0.0, 0.0, 2.0], target: [0.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 };
        let mut orbit = OrbitCamera::around(&c);
        orbit.orbit(100.0, -50.0);
        let eye = Vec3::from(orbit.camera().eye);
        assert!((eye.length() - 2.0).abs() < 1e-5, "orbiting keeps the distance: {eye}");
        assert!(eye.x < 0.0 && eye.y < 0.0, "dragging right turns left, dragging up lowers the eye: {eye}");
        let before = orbit;
        orbit.pan(0.0, 0.0, 480.0);
        assert_eq!(orbit, before, "no drag, no pan");
        orbit.pan(48.0, 0.0, 480.0);
        let moved = orbit.target - before.target;
        assert!(moved.length() > 0.0 && (orbit.distance_m - 2.0).abs() < 1e-6, "panning keeps the distance");
        orbit.zoom(1.0);
        assert!((orbit.distance_m - 2.0 * ZOOM_PER_NOTCH).abs() < 1e-6);
        orbit.zoom(-1.0);
        assert!((orbit.distance_m - 2.0).abs() < 1e-5);
    }

    #[test]
    fn os_messages_lose_their_source_location() {
        let cases = [
            ("os error at /src/linux/mod.rs:765: neither DISPLAY nor X is set.", "neither DISPLAY nor X is set"),
            ("the X server refused", "the X server refused"),
        ];
        for (raw, clean) in cases {
            assert_eq!(os_message(raw), clean);
        }
        assert_eq!(cases.len(), 2);
    }

    #[test]
    fn a_screenshot_needs_frames() {
        let args = ViewArgs {
            input: "scene.toml".into(),
            size: (320, 240),
            frames: None,
            screenshot: Some("shot.png".into()),
            max_memory: 1 << 30,
            render: Default::default(),
        };
        assert!(matches!(plan(args), Err(Failure::Usage(_))));
    }
}
