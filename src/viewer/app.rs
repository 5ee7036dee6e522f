//! The interactive viewer: a winit window showing the same frame graph as capture, with a fly
//! camera, live shadow-method and debug-view switching, a UI (egui) and screenshots. Scripted
//! input (`--script`) drives exactly the same handlers as the keyboard, the mouse and the UI.

mod handlers;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{CursorGrabMode, Window, WindowId};

use super::camera::FlyCamera;
use super::clock::{timestamp_name, FrameRate, Playback};
use super::command::{Command, BOOKMARKS};
use super::input::{InputEvent, InputState, Key};
use super::interactive::{Interactive, MovingStats};
use super::presenter::{Drawn, Presenter};
use super::script::ScriptStep;
use super::settings::ViewerSettings;
use super::ui::{Ui, UiMeshes, UiView};
use crate::renderer::{OutputKind, Renderer};
use crate::scene::Scene;
use crate::vk::{GpuContext, GpuOptions};

pub struct ViewerOptions {
    pub scene: Scene,
    /// Where screenshots and captures go: `--out-dir`, else beside the scene file (or the
    /// working directory).
    pub screenshot_dir: PathBuf,
    /// Seconds each frame moves the camera by: `--fixed-dt`, 1/60 for scripts by default, so a
    /// script gives the same images on a fast and a slow machine; None follows the clock.
    pub fixed_dt: Option<f32>,
    pub title: String,
    pub size: (u32, u32),
    pub validate: bool,
    pub device: Option<String>,
    /// What shadow rays traverse at start (B switches it).
    pub shadow_backend: crate::config::ShadowBackend,
    /// Present with FIFO (paced to the display) instead of mailbox.
    pub vsync: bool,
    /// The frame rate held while the view or the scene moves (`interactive`); 0: moving frames
    /// are drawn like still ones.
    pub moving_fps: f64,
    /// Close after this many presented frames.
    /// (Script `frames N` counts turns of the loop, drawn or not, so it also runs while minimised.)
    pub frames: Option<u64>,
    pub script: Vec<ScriptStep>,
}

/// What a viewer session did, for the CLI to report.
#[derive(Debug, Default)]
pub struct ViewerReport {
    /// Frames presented.
    pub frames: u64,
    /// Turns with nothing presented (minimised, or the swapchain being recreated).
    pub skipped: u64,
    pub validation_messages: usize,
    /// Files written by F12 and the script's `screenshot` (a render at the window's size).
    pub screenshots: Vec<PathBuf>,
    /// Files written by the script's `capture` (the presented frame as shown).
    pub captures: Vec<PathBuf>,
    /// Screenshots and captures that failed, one line each (logged as they failed): the
    /// session went on, but the run ends in failure.
    pub failures: Vec<String>,
    /// The swapchain's present mode, as Vulkan names it.
    pub present_mode: Option<String>,
    /// Frames drawn while the view or the scene moved, and their rate.
    pub moving: MovingStats,
    /// The UI's cost: frames it was drawn in, and their summed GPU time of the `ui` pass and
    /// host time laying it out (egui's layout and tessellation), in milliseconds.
    pub ui: UiCost,
}

#[derive(Debug, Default, Clone, Copy)]
pub struct UiCost {
    pub gpu_frames: u64,
    pub gpu_ms: f64,
    pub cpu_frames: u64,
    pub cpu_ms: f64,
}

/// Opens the window and runs until it is closed, `--frames` are drawn or the script ends.
pub fn run(options: ViewerOptions) -> Result<ViewerReport> {
    let event_loop = event_loop().map_err(|e| {
        anyhow::anyhow!("cannot open a window: {} (is there a display? try xvfb-run)", without_source_path(&e))
    })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App { options, running: None, error: None, report: ViewerReport::default() };
    event_loop.run_app(&mut app).context("window event loop")?;
    if let Some(e) = app.error {
        return Err(e);
    }
    Ok(app.report)
}

/// The event loop on Wayland where a compositor is there, else X11. winit tries Wayland
/// whenever WAYLAND_DISPLAY is set and does not fall back (nor can a second event loop be
/// made), so a stale WAYLAND_DISPLAY beside a working DISPLAY (an ssh session, say) would end
/// the run: X11 is chosen up front when the Wayland socket is not there.
fn event_loop() -> Result<EventLoop<()>, winit::error::EventLoopError> {
    use winit::platform::x11::EventLoopBuilderExtX11;
    let mut builder = EventLoop::builder();
    let socket =
        std::env::var_os("WAYLAND_DISPLAY").filter(|_| std::env::var_os("WAYLAND_SOCKET").is_none()).map(|name| {
            let name = PathBuf::from(name);
            match std::env::var_os("XDG_RUNTIME_DIR") {
                Some(dir) if name.is_relative() => PathBuf::from(dir).join(name),
                _ => name,
            }
        });
    if let Some(socket) = socket.filter(|s| !s.exists()) {
        if std::env::var_os("DISPLAY").is_some() {
            log::info!("no Wayland compositor at {} (WAYLAND_DISPLAY); using X11", socket.display());
            builder.with_x11();
        }
    }
    builder.build()
}

/// winit's error without the `os error at src/…/mod.rs:765:` prefix naming its own source file,
/// which tells a user nothing: "neither WAYLAND_DISPLAY nor … DISPLAY is set".
fn without_source_path(e: &impl std::fmt::Display) -> String {
    let text = e.to_string();
    let Some(rest) = text.strip_prefix("os error at ") else { return text };
    // `FILE:LINE: reason`: the reason follows the first ": " after the line number.
    let reason = rest.split_once(".rs:").and_then(|(_, after)| after.split_once(": ")).map(|(_, r)| r);
    reason.unwrap_or(rest).trim_end_matches('.').to_owned()
}

struct App {
    options: ViewerOptions,
    running: Option<Running>,
    error: Option<anyhow::Error>,
    report: ViewerReport,
}

/// Everything that exists while the window is open. Field order is drop order.
struct Running {
    presenter: Presenter,
    renderer: Renderer,
    window: Arc<Window>,
    ctx: Arc<GpuContext>,
    camera: FlyCamera,
    input: InputState,
    settings: ViewerSettings,
    /// The UI's state (egui's context and its winit state, the font atlas, the plot's
    /// history); drawn while `settings.ui`.
    ui: Ui,
    /// Camera poses saved by Shift+1..4 or the UI, restored by 1..4.
    bookmarks: [Option<FlyCamera>; BOOKMARKS],
    script: std::collections::VecDeque<ScriptStep>,
    /// Frames the script still lets run before its next step.
    script_frames: u64,
    script_wait_until: Option<Instant>,
    last_frame: Instant,
    /// When the last frame was presented.
    last_presented: Option<Instant>,
    /// A moving scene's clock: the instant shown, and whether it runs.
    playback: Option<Playback>,
    /// Moving frames' size and rays.
    interactive: Interactive,
    fps: FrameRate,
    timings: Vec<(&'static str, f64)>,
    screenshot_dir: PathBuf,
    screenshots: Vec<PathBuf>,
    /// Screenshots that failed, for the report (`ViewerReport::failures`).
    failures: Vec<String>,
    /// A capture of the next presented frame, by name.
    pending_capture: Option<String>,
    /// Why the last frame was too large for the device, so it is logged once per size; while
    /// set, the loop idles as for a minimised window. Cleared when a frame is drawn.
    too_large_noted: Option<String>,
    quit: bool,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(r) => self.running = Some(r),
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.running.as_mut() else { return };
        // egui sees the events while the UI shows (hidden, it would only queue them), and what
        // it takes (a click on a control, keys for a field being edited, the wheel over it)
        // goes no further.
        let taken = r.settings.ui && r.ui.on_window_event(&r.window, &event);
        let ui_has = |pointer: bool| r.settings.ui && if pointer { r.ui.pointer_over() } else { r.ui.wants_keyboard() };
        let input = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                return;
            }
            WindowEvent::Resized(size) => Some(InputEvent::Resize(size.width, size.height)),
            WindowEvent::KeyboardInput { .. } if ui_has(false) => None,
            WindowEvent::KeyboardInput { event, .. } => match event.physical_key {
                PhysicalKey::Code(code) => map_key(code).map(|k| match event.state {
                    ElementState::Pressed if !event.repeat => InputEvent::KeyDown(k),
                    ElementState::Pressed => InputEvent::KeyRepeat(k),
                    ElementState::Released => InputEvent::KeyUp(k),
                }),
                _ => None,
            },
            WindowEvent::MouseInput { button: MouseButton::Right, state, .. } => {
                let pressed = state == ElementState::Pressed;
                (!(pressed && (taken || ui_has(true)))).then_some(InputEvent::RightButton(pressed))
            }
            WindowEvent::MouseWheel { .. } if taken || ui_has(true) => None,
            WindowEvent::DroppedFile(path) => {
                r.command(Command::Open(path));
                None
            }
            WindowEvent::MouseWheel { delta, .. } => Some(InputEvent::Scroll(match delta {
                MouseScrollDelta::LineDelta(_, y) => y,
                MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
            })),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame(event_loop) {
                    self.fail(event_loop, e);
                }
                return;
            }
            _ => None,
        };
        if let Some(ev) = input {
            r.handle(ev);
            if r.quit {
                event_loop.exit();
            }
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let (Some(r), DeviceEvent::MouseMotion { delta }) = (self.running.as_mut(), event) {
            r.handle(InputEvent::MouseMotion { dx: delta.0 as f32, dy: delta.1 as f32 });
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(r) = &self.running else { return };
        if r.presenter.is_minimised() || r.too_large_noted.is_some() {
            // Nothing to draw, and a minimised window may get no redraws: tick the script and
            // frame counters here instead, without spinning. The same while the window is too
            // large to draw, until a frame is drawn again.
            event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + Duration::from_millis(16)));
            if let Err(e) = self.frame(event_loop) {
                self.fail(event_loop, e);
            }
        } else {
            event_loop.set_control_flow(ControlFlow::Poll);
            r.window.request_redraw();
        }
    }

    fn exiting(&mut self, _: &ActiveEventLoop) {
        if let Some(mut r) = self.running.take() {
            // An F12 just before the window closed has no frame after it to report it.
            self.report.screenshots.append(&mut r.screenshots);
            self.report.failures.append(&mut r.failures);
            let _ = r.presenter.wait_idle();
            let ctx = r.ctx.clone();
            drop(r);
            self.report.validation_messages = ctx.validation_messages();
        }
    }
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Running> {
        let o = &self.options;
        let attributes = Window::default_attributes()
            .with_title(o.title.clone())
            .with_inner_size(PhysicalSize::new(o.size.0, o.size.1));
        let window = Arc::new(event_loop.create_window(attributes).context("creating the window")?);
        let display = window.display_handle().context("display handle")?.as_raw();
        let handle = window.window_handle().context("window handle")?.as_raw();
        let gpu = GpuOptions { validate: o.validate, device_name: o.device.clone() };
        let (ctx, surface) = GpuContext::with_window(&gpu, display, handle)?;
        if o.shadow_backend == crate::config::ShadowBackend::RayQuery && !ctx.capabilities.ray_query {
            anyhow::bail!(
                "--shadow-backend ray-query: {} ({}) has no VK_KHR_ray_query; use compute (umbra devices lists what each device has)",
                ctx.device_name(),
                ctx.driver
            );
        }
        let renderer = Renderer::new(ctx.clone(), o.scene.clone()).context("preparing the scene")?;
        // The UI shows pass times: find how this driver can time passes (a fraction of a
        // second, once) so they are right rather than plain stamps that some drivers defer.
        renderer.calibrate_timings().context("calibrating pass timings")?;
        let settings = ViewerSettings {
            shadow_backend: o.shadow_backend,
            ..ViewerSettings::for_scene(&o.scene, super::settings::DEFAULT_SOFT_SPP)
        };
        let camera = FlyCamera::from_scene(&o.scene.camera);
        // A size asked for that no frame fits is refused now: waiting for the window to get
        // smaller (as after a resize) would wait for ever if it never does.
        let mut asked = settings.render_settings(camera.to_camera(o.scene.camera.vfov_deg));
        (asked.width, asked.height) = o.size;
        renderer.check_frame_size(&asked).map_err(anyhow::Error::msg)?;
        let size = window.inner_size();
        let presenter = Presenter::new(surface, size.width, size.height, o.vsync)?;
        log::info!("viewer on {} ({:?})", ctx.device_name(), presenter.present_mode());
        Ok(Running {
            presenter,
            camera,
            settings,
            renderer,
            ui: Ui::new(&window),
            bookmarks: Default::default(),
            window,
            ctx,
            input: InputState::default(),
            script: o.script.iter().cloned().collect(),
            script_frames: 0,
            script_wait_until: None,
            last_frame: Instant::now(),
            last_presented: None,
            playback: Playback::of(&o.scene),
            interactive: Interactive::new(o.moving_fps),
            fps: FrameRate::default(),
            timings: Vec::new(),
            screenshot_dir: o.screenshot_dir.clone(),
            screenshots: Vec::new(),
            failures: Vec::new(),
            pending_capture: None,
            too_large_noted: None,
            quit: false,
        })
    }

    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let Some(r) = self.running.as_mut() else { return Ok(()) };
        let draw = r.run_script(event_loop)?;
        self.report.screenshots.append(&mut r.screenshots);
        self.report.failures.append(&mut r.failures);
        if !draw {
            return Ok(());
        }
        // The UI first: what its controls change shows in this frame.
        let laid_out = Instant::now();
        let meshes = r.settings.ui.then(|| r.lay_out_ui());
        if meshes.is_some() {
            self.report.ui.cpu_frames += 1;
            self.report.ui.cpu_ms += laid_out.elapsed().as_secs_f64() * 1e3;
        }
        let now = Instant::now();
        let dt = self.options.fixed_dt.unwrap_or((now - r.last_frame).as_secs_f32().min(0.25));
        r.last_frame = now;
        r.camera.update(&r.input, dt);
        if let Some(p) = &mut r.playback {
            p.advance(f64::from(dt));
            r.renderer.set_time(p.time);
        }
        let camera = r.camera.to_camera(r.renderer.scene().camera.vfov_deg);
        let mut settings = r.settings.render_settings(camera);
        settings.time = r.playback.as_ref().map(|p| p.time);
        r.interactive.begin(&camera, r.playback.as_ref().is_some_and(|p| p.playing));
        r.interactive.apply(&mut settings, r.renderer.scene().lights.len());
        // A still view that converges over frames (soft shadows, occlusion) converges to the
        // anti-aliased image, as `umbra render` does over its frames.
        settings.antialias = crate::passes::accumulate::accumulates(&settings, r.renderer.scene());
        // A technique's view of a light it cannot serve (volumes on an open caster, say)
        // shows the shaded frame instead.
        if r.renderer.check_debug_view(&settings).is_err() {
            settings.debug_view = None;
        }
        let capture = r.pending_capture.take();
        let scale = r.interactive.scale();
        let ui = meshes.as_ref().map(|m| (m, &r.ui.atlas));
        match r.presenter.draw(&r.renderer, &settings, ui, capture.is_some(), scale)? {
            Drawn::Frame { timings, captured } => {
                r.interactive.end((now - r.last_presented.unwrap_or(now)).as_secs_f64() * 1e3);
                r.last_presented = Some(now);
                self.report.moving = r.interactive.stats();
                r.too_large_noted = None;
                self.report.present_mode = r.presenter.present_mode().map(|m| format!("{m:?}"));
                if !timings.is_empty() {
                    if let Some((_, ms)) = timings.iter().find(|t| t.0 == "ui") {
                        self.report.ui.gpu_frames += 1;
                        self.report.ui.gpu_ms += ms;
                    }
                    r.ui.record_timings(&timings);
                    r.timings = timings;
                }
                if let (Some(name), Some(frame)) = (capture, captured) {
                    let path = r.screenshot_dir.join(format!("{name}.png"));
                    // A full or read-only disk costs the file, not the session (as F12).
                    match crate::output::write_image_with(&frame, &path, &r.screenshot_options()) {
                        Ok(()) => self.report.captures.push(path),
                        Err(e) => failed(&mut self.report.failures, "capture", &refused(e)),
                    }
                }
                r.fps.tick(now);
                self.report.frames += 1;
                r.script_frames = r.script_frames.saturating_sub(1);
            }
            Drawn::Skipped => {
                // Nothing was shown: a capture waits for the next frame that is.
                r.pending_capture = r.pending_capture.take().or(capture);
                self.report.skipped += 1;
                r.script_frames = r.script_frames.saturating_sub(1);
            }
            Drawn::TooLarge(why) => {
                // A window larger than the device can draw (a huge monitor, a scripted resize)
                // waits for a smaller size instead of ending the session; said once per size.
                if r.too_large_noted.replace(why.clone()).as_ref() != Some(&why) {
                    log::warn!("{why}; nothing is drawn until the window is smaller");
                }
                r.pending_capture = r.pending_capture.take().or(capture);
                self.report.skipped += 1;
                r.script_frames = r.script_frames.saturating_sub(1);
            }
        }
        self.report.screenshots.append(&mut r.screenshots);
        self.report.failures.append(&mut r.failures);
        if self.options.frames.is_some_and(|n| self.report.frames >= n) {
            event_loop.exit();
        }
        Ok(())
    }
}

impl Running {
    fn handle(&mut self, event: InputEvent) {
        self.input.apply(&event);
        match event {
            InputEvent::Resize(w, h) => self.presenter.resize(w, h),
            InputEvent::MouseMotion { dx, dy } if self.input.looking() => self.camera.look(dx, dy),
            InputEvent::RightButton(held) => {
                // Raw motion with a hidden, confined cursor while looking around.
                self.window.set_cursor_visible(!held);
                let mode = if held { CursorGrabMode::Confined } else { CursorGrabMode::None };
                if self.window.set_cursor_grab(mode).is_err() && held {
                    let _ = self.window.set_cursor_grab(CursorGrabMode::Locked);
                }
            }
            InputEvent::Scroll(steps) => self.camera.scroll(steps),
            InputEvent::Time(t) => match &mut self.playback {
                Some(p) => {
                    p.time = t;
                    p.playing = false;
                }
                None => log::warn!("time {t}: nothing in the scene moves"),
            },
            InputEvent::KeyDown(key) => match key {
                Key::Home => self.camera.reset(&self.renderer.scene().camera),
                Key::Escape => self.quit = true,
                Key::Space | Key::Comma | Key::Period => match &mut self.playback {
                    Some(p) => p.on_key(key),
                    None => log::warn!("{key:?}: nothing in the scene moves"),
                },
                Key::F12 => {
                    if let Err(e) = self.screenshot(None) {
                        failed(&mut self.failures, "screenshot", &e);
                    }
                }
                Key::One | Key::Two | Key::Three | Key::Four => {
                    let slot = [Key::One, Key::Two, Key::Three, Key::Four].iter().position(|&k| k == key);
                    let save = self.input.held(Key::Shift);
                    self.command(Command::Bookmark { slot: slot.unwrap_or(0), save });
                }
                Key::B if !self.ctx.capabilities.ray_query => {
                    log::warn!("B: {} has no ray query; shadows stay on the compute BVH", self.ctx.device_name())
                }
                _ => self.settings.on_key(key),
            },
            _ => {}
        }
    }

    /// Feeds script steps until one asks for frames or time to pass. Returns false to skip
    /// drawing this turn (waiting on the clock, or quitting).
    fn run_script(&mut self, event_loop: &ActiveEventLoop) -> Result<bool> {
        if let Some(t) = self.script_wait_until {
            if Instant::now() < t {
                return Ok(false);
            }
            self.script_wait_until = None;
        }
        while self.script_frames == 0 {
            let Some(step) = self.script.pop_front() else { return Ok(true) };
            match step {
                ScriptStep::Frames(n) => self.script_frames = n,
                ScriptStep::Input(ev) => {
                    if let InputEvent::Resize(w, h) = ev {
                        // Ask the window system too; the resulting Resized event is handled
                        // like any other.
                        let _ = self.window.request_inner_size(PhysicalSize::new(w.max(1), h.max(1)));
                    }
                    self.handle(ev);
                    // Esc quits from a script as from the keyboard.
                    if self.quit {
                        event_loop.exit();
                        return Ok(false);
                    }
                }
                ScriptStep::Minimise(on) => {
                    // Without a window manager (Xvfb) iconifying may do nothing, so the 0x0
                    // size a minimised window reports is fed in directly as well.
                    self.window.set_minimized(on);
                    let size = self.window.inner_size();
                    self.handle(if on {
                        InputEvent::Resize(0, 0)
                    } else {
                        InputEvent::Resize(size.width, size.height)
                    });
                }
                // Taken at this point of the script, before any later step changes the view.
                ScriptStep::Screenshot(name) => {
                    // Logged and carried on from, as F12 is: a full or read-only disk costs the
                    // file, not the session (which then ends in failure).
                    if let Err(e) = self.screenshot(Some(name)) {
                        failed(&mut self.failures, "screenshot", &e);
                    }
                }
                // Draws the frame it captures before the script goes on.
                ScriptStep::Capture(name) => {
                    self.pending_capture = Some(name);
                    self.script_frames = 1;
                }
                ScriptStep::Wait(d) => {
                    self.script_wait_until = Some(Instant::now() + d);
                    return Ok(false);
                }
                ScriptStep::Scale(share) => self.interactive.pin(share),
                ScriptStep::Command(c) => self.command(c),
                ScriptStep::Quit => {
                    self.quit = true;
                    event_loop.exit();
                    return Ok(false);
                }
            }
        }
        Ok(true)
    }

    /// The frame's status for the UI: rate and size, the scene, playback, the selected
    /// light and the view, moving frames, accumulation.
    fn status_lines(&self) -> Vec<String> {
        let extent = self.presenter.extent().map_or((0, 0), |e| (e.width, e.height));
        let mut lines =
            vec![format!("{:6.1} fps {:7.2} ms  {}x{}", self.fps.fps(), self.fps.frame_ms(), extent.0, extent.1)];
        let scene = self.renderer.scene();
        lines.push(format!("{} triangles  {} lights", self.renderer.triangle_count(), scene.lights.len()));
        if let Some(p) = &self.playback {
            lines.push(p.describe());
        }
        lines.extend(self.settings.describe(&scene.lights));
        lines.push(self.interactive.describe(extent.0, extent.1));
        if self.presenter.accumulated_frames() > 0 {
            lines.push(format!("accumulated {} frames", self.presenter.accumulated_frames()));
        }
        lines
    }

    /// Lays the UI out for this frame and applies what its controls changed.
    fn lay_out_ui(&mut self) -> UiMeshes {
        let size = match self.presenter.extent() {
            Some(e) => [e.width, e.height],
            None => self.window.inner_size().into(),
        };
        let view = UiView {
            settings: &self.settings,
            lights: &self.renderer.scene().lights,
            status: self.status_lines(),
            bookmarks: std::array::from_fn(|i| self.bookmarks[i].is_some()),
            ray_query: self.ctx.capabilities.ray_query,
        };
        let (meshes, commands) = self.ui.frame(&self.window, &view, size);
        for c in commands {
            self.command(c);
        }
        meshes
    }

    /// How screenshots and captures are written: never over a file the scene was read from
    /// (they go beside the scene file by default, where `sky.exr` may be its environment map).
    fn screenshot_options(&self) -> crate::output::WriteOptions {
        crate::output::WriteOptions { inputs: self.renderer.scene().sources.clone(), ..Default::default() }
    }

    /// Writes NAME.png (as shown) and NAME.exr (linear radiance) into the screenshot directory,
    /// rendering the current view through the capture path at the window's size.
    fn screenshot(&mut self, name: Option<String>) -> Result<()> {
        let stem = name.unwrap_or_else(timestamp_name);
        let extent = self.presenter.extent().unwrap_or(ash::vk::Extent2D { width: 320, height: 240 });
        let mut settings = self.settings.render_settings(self.camera.to_camera(self.renderer.scene().camera.vfov_deg));
        settings.time = self.playback.map(|p| p.time);
        settings.width = extent.width;
        settings.height = extent.height;
        settings.timestamps = false;
        if self.renderer.check_debug_view(&settings).is_err() {
            settings.debug_view = None;
        }
        let options = self.screenshot_options();
        let shots = [("png", OutputKind::Display), ("exr", OutputKind::SceneLinear)]
            .map(|(ext, output)| (self.screenshot_dir.join(format!("{stem}.{ext}")), output));
        // Both files or neither: `sky` beside an input sky.exr wrote sky.png, then refused.
        for (path, _) in &shots {
            crate::output::check_output(path, &options).map_err(refused)?;
        }
        for (path, output) in shots {
            settings.output = output;
            let frame = self.renderer.render(&settings)?;
            crate::output::write_image_with(&frame, &path, &options).map_err(refused)?;
            log::info!("screenshot: {}", path.display());
            self.screenshots.push(path);
        }
        Ok(())
    }
}

/// Logs a screenshot or capture that failed and keeps the line for the report.
fn failed(failures: &mut Vec<String>, what: &str, e: &anyhow::Error) {
    let line = format!("{what} failed: {e:#}");
    log::error!("{line}");
    failures.push(line);
}

/// Why a screenshot or capture file was refused, in the viewer's terms: `umbra view` has no
/// `--force` (the writer's own message suggests it), so a read-only file or an input of the
/// scene is kept, and another name or `--out-dir` is the way out.
fn refused(e: crate::output::OutputError) -> anyhow::Error {
    use crate::output::OutputError;
    match e {
        OutputError::ReadOnly { path } => anyhow::anyhow!(
            "{}: the file exists and is read-only; the viewer never replaces it: choose another name or --out-dir",
            path.display()
        ),
        OutputError::IsInput { path, input } => anyhow::anyhow!(
            "{}: is an input of this scene ({}); the viewer never replaces it: choose another name or --out-dir",
            path.display(),
            input.display()
        ),
        e => e.into(),
    }
}

fn map_key(code: KeyCode) -> Option<Key> {
    Some(match code {
        KeyCode::KeyW => Key::W,
        KeyCode::KeyA => Key::A,
        KeyCode::KeyS => Key::S,
        KeyCode::KeyD => Key::D,
        KeyCode::KeyQ => Key::Q,
        KeyCode::KeyE => Key::E,
        KeyCode::ShiftLeft | KeyCode::ShiftRight => Key::Shift,
        KeyCode::Home => Key::Home,
        KeyCode::F1 => Key::F1,
        KeyCode::F12 => Key::F12,
        KeyCode::KeyL => Key::L,
        KeyCode::KeyT => Key::T,
        KeyCode::KeyV => Key::V,
        KeyCode::KeyB => Key::B,
        KeyCode::KeyH => Key::H,
        KeyCode::KeyR => Key::R,
        KeyCode::KeyP => Key::P,
        KeyCode::KeyG => Key::G,
        KeyCode::KeyC => Key::C,
        KeyCode::Digit1 => Key::One,
        KeyCode::Digit2 => Key::Two,
        KeyCode::Digit3 => Key::Three,
        KeyCode::Digit4 => Key::Four,
        KeyCode::Equal | KeyCode::NumpadAdd => Key::Plus,
        KeyCode::Minus | KeyCode::NumpadSubtract => Key::Minus,
        KeyCode::BracketLeft => Key::BracketLeft,
        KeyCode::BracketRight => Key::BracketRight,
        KeyCode::Escape => Key::Escape,
        KeyCode::Space => Key::Space,
        KeyCode::Comma => Key::Comma,
        KeyCode::Period => Key::Period,
        _ => return None,
    })
}
