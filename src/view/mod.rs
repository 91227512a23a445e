//! The interactive walkthrough (`mirage view`): the last arrow of the pipeline, from the VPL
//! frame ([`crate::frame::render_frame`]: VPLs → G-buffer → interleaved gather →
//! discontinuity buffer) to a window, every frame.
//!
//! ```text
//! flags ──args──► ViewOptions        scene ──setup──► Scene + BVH (+ --add-light sky panel)
//!                      │                                   │
//!   window (winit + softbuffer, keys, mouse) ─┐            ▼
//!   headless (--frames, --camera-path) ───────┴─► FrameLoop::frame ─► Session::step
//!                                                   │                   (sampler state kept across
//!                                                   │                    frames; running mean)
//!                                                   ├─► present: tone map, upscale, HUD
//!                                                   ├─► measure: flicker, relMSE vs reference
//!                                                   └─► record: PNG / EXR per frame
//! ```
//!
//! Files, in flow order: [`args`] (flags → [`ViewOptions`]), [`setup`] (scene, `--add-light`),
//! [`session`] (per-frame rendering, chain reuse, accumulation), [`reuse`] (temporal VPL reuse), [`frame_loop`] (the body
//! shared by window and headless, stage times, summary), [`present`] (tone mapping, scaling,
//! screenshots), [`measure`] (flicker, convergence), [`path`] (camera path files), [`fly`]
//! (walkthrough camera), [`controls`] (keys), [`hud`] + [`font`] (text overlay), [`window`],
//! [`headless`], [`error`].
//!
//! What this module must not do: change a stage of the pipeline. It drives
//! `frame::render_frame` as `render --mode ir` does, and owns only what happens around it:
//! which camera, which sampler state, how frames are combined and shown.
//!
//! Temporal coherence (papers/002 §8, docs/design.md §3.6): the sampler lives as long as the viewer;
//! a small camera move calls `camera_moved(false)` (a Metropolis chain continues), a jump or
//! R calls `camera_moved(true)`; thresholds in [`session`]. While the camera stands still the
//! window shows the running mean of frames, which converges.

pub mod args;
pub mod controls;
pub mod error;
pub mod fly;
pub mod font;
pub mod frame_loop;
pub mod headless;
pub mod hud;
pub mod measure;
pub mod path;
pub mod present;
pub mod reuse;
pub mod session;
pub mod setup;
pub mod window;

pub use args::{ViewArgs, ViewOptions};
pub use error::ViewError;
pub use session::default_sampler;

use glam::Vec3;

use self::fly::FlyCamera;
use self::frame_loop::FrameLoop;
use self::measure::FlickerMeter;
use self::session::Session;

/// Render resolution for a window of `size` at `scale` (at least 1×1; 0×0 stays 0×0).
pub fn render_size(size: (u32, u32), scale: f32) -> (u32, u32) {
    let s = |v: u32| if v == 0 { 0 } else { ((v as f32 * scale).round() as u32).max(1) };
    (s(size.0), s(size.1))
}

/// True when a window system is reachable through the environment (X11 or Wayland).
fn display_configured() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"].iter().any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Runs the viewer: a window, or the headless loop with `--headless`.
pub fn run(args: &ViewArgs) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    Ok(run_view(args)?)
}

fn run_view(args: &ViewArgs) -> Result<(), ViewError> {
    let opts = args.options()?;
    if !opts.headless && !display_configured() {
        return Err(ViewError::NoDisplay("neither DISPLAY nor WAYLAND_DISPLAY is set".into()));
    }
    if let Some(t) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .map_err(|e| ViewError::Options(format!("--threads {t}: cannot set up the worker threads: {e}")))?;
    }
    let (scene, accel, name) = setup::prepare(args.scene.as_deref(), &args.camera, &args.lights)?;
    for w in &scene.warnings {
        eprintln!("mirage: warning: {w}");
    }
    let window_size = (scene.camera.width, scene.camera.height);
    let (rw, rh) = render_size(window_size, opts.scale);
    let fly = FlyCamera::from_camera(&scene.camera, args.camera.up.unwrap_or(Vec3::Y), scene.bounds.diagonal());
    let camera = fly.camera(rw, rh);
    let mut fl = FrameLoop::new(Session::new(scene, accel, camera, opts.session.clone()), opts.tonemap);
    if opts.flicker {
        fl.flicker = Some(FlickerMeter::default());
    }
    if let Some(r) = &opts.reference {
        fl.set_reference(r.clone())?;
    }
    if let Some(d) = &opts.record {
        fl.set_record(d.clone(), opts.record_exr)?;
    }
    if opts.headless { headless::run(fl, fly, &opts, &name) } else { window::run(fl, fly, window_size, &opts, &name) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_size_scales_and_never_reaches_zero_unless_minimised() {
        assert_eq!(render_size((512, 256), 0.5), (256, 128));
        assert_eq!(render_size((3, 3), 0.05), (1, 1));
        assert_eq!(render_size((0, 0), 1.0), (0, 0));
    }
}
