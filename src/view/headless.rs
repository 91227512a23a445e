//! The headless frame loop (`mirage view --headless`): the window's per-frame code
//! ([`FrameLoop::frame`]) with no window, for tests, benchmarks and the flicker and convergence
//! measures. The camera stands still (frames accumulate) or follows `--camera-path`; the run
//! ends with one summary line: frames per second and milliseconds per stage.

use super::args::{DEFAULT_HEADLESS_FRAMES, ViewOptions};
use super::error::ViewError;
use super::fly::FlyCamera;
use super::frame_loop::{FrameLoop, chains_label};
use super::measure::FLICKER_EPSILON;

/// Runs `--frames` frames and prints the measures and the summary.
pub fn run(mut fl: FrameLoop, mut fly: FlyCamera, opts: &ViewOptions, name: &str) -> Result<(), ViewError> {
    let frames = opts.frames.unwrap_or(DEFAULT_HEADLESS_FRAMES);
    let home = fly.pose();
    let (w, h) = fl.size();
    if let Some((path, _)) = &fl.reference {
        println!("convergence of the accumulated image against {} (still camera):", path.display());
    }
    for i in 0..frames {
        if let Some(p) = &opts.camera_path {
            fly.set_pose(p.pose(home, fly.world_up, i, frames));
            fl.session.set_camera(fly.camera(w, h));
        }
        let report = fl.frame()?;
        if let Some(e) = report.errors {
            println!("  {:>7} frames: relMSE {:.5e}, nMSE {:.5e}", fl.session.accumulated(), e.rel_mse, e.nmse);
        }
    }
    if let Some(m) = &fl.flicker {
        let chains = chains_label(opts.session.fresh_chains, opts.session.reuse_frames);
        let camera = opts.camera_path.as_ref().map_or("still camera".to_string(), |p| format!("path {}", p.describe()));
        match m.mean() {
            Some(f) => println!(
                "flicker {f:.5}: mean over {} frame pairs of mean |Y_t - Y_t-1| / (Y_t-1 + eps), eps = {FLICKER_EPSILON} \
                 × mean Y of both ({}, {chains}, {camera})",
                m.pairs(),
                fl.session.sampler_name()
            ),
            None => println!("flicker: needs at least 2 frames"),
        }
    }
    if let Some(png) = &opts.screenshot_on_exit {
        fl.screenshot(png)?;
        println!("screenshot → {} (+ .exr)", png.display());
    }
    println!("{}", fl.summary(name, "headless"));
    Ok(())
}
