//! The window: winit 0.30 (`ApplicationHandler`) for events, softbuffer 0.4 for pixels.
//!
//! One frame per `RedrawRequested`; `about_to_wait` asks for the next redraw while the window
//! can show something, so input is handled between frames and the event loop never blocks for
//! longer than one frame. A zero-sized (minimised) or occluded window renders nothing and the
//! loop sleeps until it changes. Resizing reallocates the surface and restarts accumulation
//! (the render resolution follows the window × `--scale`).

use std::num::NonZeroU32;
use std::rc::Rc;
use std::time::{Duration, Instant};

use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::args::ViewOptions;
use super::controls::{self, Action, ControlState, HELP};
use super::error::ViewError;
use super::fly::{FlyCamera, MoveInput};
use super::frame_loop::{FrameLoop, StageTimes};
use super::hud::{self, HudData};
use super::present::resample_nearest;
use super::render_size;

/// Frames of one pass of a camera path in the window when `--frames` is not given (the path
/// then loops; with `--frames N` it plays once over the N frames and the window closes).
const DEFAULT_PATH_FRAMES: u64 = 240;
/// How long a status message stays on the HUD.
const STATUS_TIME: Duration = Duration::from_secs(3);
/// Weight of the newest frame in the HUD's moving averages.
const SMOOTHING: f64 = 0.2;

/// Movement keys, in the order of [`App::held`].
const MOVE_KEYS: [KeyCode; 6] =
    [KeyCode::KeyW, KeyCode::KeyS, KeyCode::KeyD, KeyCode::KeyA, KeyCode::KeyE, KeyCode::KeyQ];

struct Gfx {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
    _context: softbuffer::Context<Rc<Window>>,
}

struct App {
    fl: FrameLoop,
    opts: ViewOptions,
    name: String,
    fly: FlyCamera,
    home: FlyCamera,
    gfx: Option<Gfx>,
    window_size: (u32, u32),
    occluded: bool,
    held: [bool; 6],
    dragging: bool,
    cursor: Option<PhysicalPosition<f64>>,
    look: (f32, f32),
    teleport: bool,
    last_redraw: Option<Instant>,
    smooth: StageTimes,
    fps: f64,
    rays_per_second: f64,
    hud: bool,
    help: bool,
    status: Option<(String, Instant)>,
    controls: ControlState,
    frames: u64,
    last_vpls: (usize, usize),
    last_acceptance: Option<f64>,
    last_gbuffer_held: bool,
    last_vpls_ahead: bool,
    error: Option<ViewError>,
    done: bool,
}

/// Opens the window and runs until it is closed (or `--frames` frames are shown).
pub fn run(
    fl: FrameLoop,
    fly: FlyCamera,
    window_size: (u32, u32),
    opts: &ViewOptions,
    name: &str,
) -> Result<(), ViewError> {
    let event_loop = EventLoop::new().map_err(|e| ViewError::NoDisplay(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Wait);
    let controls = ControlState::new(&fl.session.settings().frame);
    let mut app = App {
        fl,
        opts: opts.clone(),
        name: name.to_string(),
        home: fly.clone(),
        fly,
        gfx: None,
        window_size,
        occluded: false,
        held: [false; 6],
        dragging: false,
        cursor: None,
        look: (0.0, 0.0),
        teleport: false,
        last_redraw: None,
        smooth: StageTimes::default(),
        fps: 0.0,
        rays_per_second: 0.0,
        hud: opts.hud,
        help: false,
        status: None,
        controls,
        frames: 0,
        last_vpls: (0, 0),
        last_acceptance: None,
        last_gbuffer_held: false,
        last_vpls_ahead: false,
        error: None,
        done: false,
    };
    event_loop.run_app(&mut app).map_err(|e| ViewError::Window(format!("window event loop failed: {e}")))?;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    if app.fl.totals.frames > 0 {
        println!("{}", app.fl.summary(&app.name, "window"));
    }
    Ok(())
}

impl App {
    fn fail(&mut self, el: &ActiveEventLoop, e: ViewError) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        self.done = true;
        el.exit();
    }

    fn set_status(&mut self, s: String) {
        self.status = Some((s, Instant::now()));
    }

    fn renderable(&self) -> bool {
        !self.done && !self.occluded && self.window_size.0 > 0 && self.window_size.1 > 0
    }

    fn move_input(&self) -> MoveInput {
        let axis = |p: usize, n: usize| self.held[p] as i32 as f32 - self.held[n] as i32 as f32;
        MoveInput { forward: axis(0, 1), right: axis(2, 3), up: axis(4, 5) }
    }

    fn create_window(&mut self, el: &ActiveEventLoop) -> Result<(), ViewError> {
        let (w, h) = self.window_size;
        let attrs = Window::default_attributes()
            .with_title(format!("mirage view: {}", self.name))
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Rc::new(el.create_window(attrs).map_err(|e| ViewError::NoDisplay(e.to_string()))?);
        let context = softbuffer::Context::new(window.clone())
            .map_err(|e| ViewError::NoDisplay(format!("softbuffer context: {e}")))?;
        let surface = softbuffer::Surface::new(&context, window.clone())
            .map_err(|e| ViewError::Window(format!("softbuffer surface: {e}")))?;
        let size = window.inner_size();
        window.request_redraw();
        self.gfx = Some(Gfx { window, surface, _context: context });
        self.resize(size)
    }

    fn resize(&mut self, size: PhysicalSize<u32>) -> Result<(), ViewError> {
        self.window_size = (size.width, size.height);
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else { return Ok(()) };
        if let Some(g) = &mut self.gfx {
            g.surface.resize(w, h).map_err(|e| ViewError::Window(format!("cannot resize the window surface: {e}")))?;
        }
        Ok(())
    }

    fn key(&mut self, el: &ActiveEventLoop, event: KeyEvent) {
        let PhysicalKey::Code(code) = event.physical_key else { return };
        let pressed = event.state == ElementState::Pressed;
        if let Some(i) = MOVE_KEYS.iter().position(|k| *k == code) {
            self.held[i] = pressed;
            return;
        }
        if !pressed || event.repeat {
            return;
        }
        let Some(action) = controls::action_for(code) else { return };
        if let Some(msg) = controls::apply(action, &mut self.fl.session, &mut self.controls) {
            self.set_status(msg);
            return;
        }
        match action {
            Action::Quit => self.finish(el),
            Action::ToggleHud => self.hud = !self.hud,
            Action::ToggleHelp => self.help = !self.help,
            Action::ExposureDown | Action::ExposureUp => {
                let msg = self.fl.adjust_exposure(if action == Action::ExposureUp { 1.0 } else { -1.0 });
                self.set_status(msg);
            }
            Action::Reset => {
                self.fly = self.home.clone();
                self.teleport = true;
                self.set_status("camera reset".into());
            }
            Action::Screenshot => {
                let png = self.opts.screenshot_dir.join(format!(
                    "mirage-{}-{:05}.png",
                    self.name,
                    self.fl.session.frames_rendered()
                ));
                match self.fl.screenshot(&png) {
                    Ok(()) => {
                        println!("screenshot → {} (+ .exr)", png.display());
                        self.set_status(format!("saved {}", png.display()));
                    }
                    Err(e) => self.set_status(format!("screenshot failed: {e}")),
                }
            }
            _ => {}
        }
    }

    /// Ends the loop, writing `--screenshot-on-exit` first.
    fn finish(&mut self, el: &ActiveEventLoop) {
        if self.done {
            return;
        }
        if let Some(png) = self.opts.screenshot_on_exit.clone() {
            if self.fl.totals.frames == 0 {
                return self.fail(el, ViewError::Window("no frame was rendered before exit: no screenshot".into()));
            }
            if let Err(e) = self.fl.screenshot(&png) {
                return self.fail(el, e);
            }
            println!("screenshot → {} (+ .exr)", png.display());
        }
        self.done = true;
        el.exit();
    }

    fn redraw(&mut self, el: &ActiveEventLoop) {
        if !self.renderable() || self.gfx.is_none() {
            return;
        }
        let now = Instant::now();
        let dt = self.last_redraw.map_or(0.0, |t| (now - t).as_secs_f32());
        self.last_redraw = Some(now);

        if let Some(path) = &self.opts.camera_path {
            let n = self.opts.frames.unwrap_or(DEFAULT_PATH_FRAMES);
            self.fly.set_pose(path.pose(self.home.pose(), self.home.world_up, self.frames % n, n));
        } else {
            self.fly.look(self.look.0, self.look.1);
            self.fly.advance(self.move_input(), dt);
        }
        self.look = (0.0, 0.0);
        let (ww, wh) = self.window_size;
        let (rw, rh) = render_size((ww, wh), self.opts.scale);
        let camera = self.fly.camera(rw, rh);
        if std::mem::take(&mut self.teleport) {
            self.fl.session.teleport(camera);
        } else {
            self.fl.session.set_camera(camera);
        }
        let report = match self.fl.frame() {
            Ok(r) => r,
            Err(e) => return self.fail(el, e),
        };
        self.smooth.smooth(report.times, SMOOTHING);
        if dt > 0.0 {
            let fps = 1.0 / dt as f64;
            self.fps = if self.fps == 0.0 { fps } else { self.fps + SMOOTHING * (fps - self.fps) };
        }
        let rps = report.rays as f64 / report.times.frame.max(1e-9);
        self.rays_per_second +=
            if self.rays_per_second == 0.0 { rps } else { SMOOTHING * (rps - self.rays_per_second) };
        self.last_vpls = (report.vpls, report.vpls_reused);
        self.last_acceptance = report.acceptance;
        self.last_gbuffer_held = report.gbuffer_held;
        self.last_vpls_ahead = report.vpls_ahead;
        if self.status.as_ref().is_some_and(|(_, t)| t.elapsed() > STATUS_TIME) {
            self.status = None;
        }
        if let Err(e) = self.present() {
            return self.fail(el, e);
        }
        self.frames += 1;
        if self.opts.frames.is_some_and(|n| self.frames >= n) {
            self.finish(el);
        }
    }

    fn present(&mut self) -> Result<(), ViewError> {
        let (ww, wh) = self.window_size;
        let (rw, rh) = self.fl.size();
        let settings = self.fl.session.settings().clone();
        let lines: Vec<String> = if self.help {
            HELP.iter().map(|s| s.to_string()).collect()
        } else if self.hud {
            hud::lines(&HudData {
                fps: self.fps,
                times: self.smooth,
                sampler: self.fl.session.sampler_name(),
                settings: settings.frame,
                fresh_chains: settings.fresh_chains,
                reuse_frames: settings.reuse_frames,
                vpls: self.last_vpls.0,
                vpls_reused: self.last_vpls.1,
                rays_per_second: self.rays_per_second,
                acceptance: self.last_acceptance,
                gbuffer_held: self.last_gbuffer_held,
                vpls_ahead: self.last_vpls_ahead,
                accumulated: self.fl.session.accumulated(),
                filter_weight: self.fl.session.filter_weight(),
                render_size: (rw, rh),
                tonemap: self.fl.tonemap,
                status: self.status.as_ref().map(|(s, _)| s.as_str()),
            })
        } else {
            Vec::new()
        };
        let Some(g) = &mut self.gfx else { return Ok(()) };
        let mut buffer =
            g.surface.buffer_mut().map_err(|e| ViewError::Window(format!("cannot get the window buffer: {e}")))?;
        if buffer.len() != (ww * wh) as usize {
            // The surface has not caught up with a resize yet; skip this presentation.
            return Ok(());
        }
        resample_nearest(&self.fl.displayed, rw, rh, &mut buffer, ww, wh);
        hud::draw(&mut buffer, ww, wh, &lines, hud::text_scale(ww));
        buffer.present().map_err(|e| ViewError::Window(format!("cannot present the frame: {e}")))?;
        g.window.pre_present_notify();
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.gfx.is_none()
            && let Err(e) = self.create_window(el)
        {
            self.fail(el, e);
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => self.finish(el),
            WindowEvent::Resized(size) => {
                if let Err(e) = self.resize(size) {
                    self.fail(el, e);
                }
            }
            WindowEvent::Occluded(o) => self.occluded = o,
            WindowEvent::Focused(false) => {
                self.held = [false; 6];
                self.dragging = false;
            }
            WindowEvent::KeyboardInput { event, .. } => self.key(el, event),
            WindowEvent::MouseInput { state, button: MouseButton::Left, .. } => {
                self.dragging = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if self.dragging
                    && let Some(c) = self.cursor
                {
                    self.look.0 += (position.x - c.x) as f32;
                    self.look.1 += (position.y - c.y) as f32;
                }
                self.cursor = Some(position);
            }
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                self.fly.scale_speed(notches);
                self.set_status(format!("speed {:.3} units/s", self.fly.speed));
            }
            WindowEvent::RedrawRequested => self.redraw(el),
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _el: &ActiveEventLoop) {
        if self.renderable()
            && let Some(g) = &self.gfx
        {
            g.window.request_redraw();
        }
    }
}
