//! The frame loop body that the window and the headless runner share: render a frame through
//! the [`Session`], tone-map the running mean for display, feed the measures (flicker,
//! convergence), record, and keep per-stage times.
//!
//! Timed stages, per frame: `vpls` (the sampler), `primary` (G-buffer rays), `shadow` (the
//! gather, with its `compensation` part), `filter` (discontinuity buffer), `display` (running mean + tone mapping). The frame
//! time is the wall clock from the frame's start to its display; measures and file writes are
//! outside it. It is the stages' sum, except that VPLs sampled ahead during the previous frame's
//! gather ([`super::session`]) report the time they took beside it.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::error::ViewError;
use super::measure::{FlickerMeter, is_checkpoint};
use super::present::{self, Mapping};
use super::session::{FrameOutcome, Motion, Session};
use crate::film::Tonemap;
use crate::film::{Image, ImageErrors};
use crate::output::{self, Aovs};

/// Seconds per stage (one frame, a sum, or a smoothed value).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// VPL sampling.
    pub vpls: f64,
    /// Primary rays (G-buffer).
    pub primary: f64,
    /// Gather (shadow rays).
    pub shadow: f64,
    /// The clamp compensation's part of `shadow`.
    pub compensation: f64,
    /// Discontinuity buffer.
    pub filter: f64,
    /// Accumulation and tone mapping.
    pub display: f64,
    /// The whole frame (wall clock).
    pub frame: f64,
}

impl StageTimes {
    fn of(o: &FrameOutcome, display: Duration, frame: Duration) -> Self {
        StageTimes {
            vpls: o.stats.vpl_time.as_secs_f64(),
            primary: o.stats.primary_time.as_secs_f64(),
            shadow: o.stats.shadow_time.as_secs_f64(),
            compensation: o.stats.compensation_time.as_secs_f64(),
            filter: o.stats.filter_time.as_secs_f64(),
            display: display.as_secs_f64(),
            frame: frame.as_secs_f64(),
        }
    }

    fn zip(self, o: StageTimes, f: impl Fn(f64, f64) -> f64) -> StageTimes {
        StageTimes {
            vpls: f(self.vpls, o.vpls),
            primary: f(self.primary, o.primary),
            shadow: f(self.shadow, o.shadow),
            compensation: f(self.compensation, o.compensation),
            filter: f(self.filter, o.filter),
            display: f(self.display, o.display),
            frame: f(self.frame, o.frame),
        }
    }

    /// Exponential moving average towards `x` with weight `alpha` (HUD smoothing).
    pub fn smooth(&mut self, x: StageTimes, alpha: f64) {
        *self = if self.frame == 0.0 { x } else { self.zip(x, |a, b| a + alpha * (b - a)) };
    }

    /// Every stage multiplied by `k`.
    pub fn scaled(self, k: f64) -> StageTimes {
        self.zip(self, |a, _| a * k)
    }
}

/// "fresh chains", or "chain reuse" with the VPL reuse factor.
pub fn chains_label(fresh: bool, reuse_frames: u32) -> String {
    match (fresh, reuse_frames) {
        (true, _) => "fresh chains".into(),
        (false, k) if k > 1 => format!("chain reuse, VPL reuse ×{k}"),
        (false, _) => "chain reuse".into(),
    }
}

/// Sums over the frames of a run.
#[derive(Clone, Debug, Default)]
pub struct Totals {
    /// Frames rendered.
    pub frames: u64,
    /// Summed stage times.
    pub times: StageTimes,
    /// Rays of the G-buffer, the gather and the sampler.
    pub rays: u64,
    /// Metropolis proposals accepted.
    pub accepted: u64,
    /// Metropolis proposals.
    pub proposed: u64,
    /// Non-finite pixels replaced by black.
    pub non_finite: u64,
    /// Frames after which the camera jumped (chain restarted).
    pub jumps: u64,
    /// VPLs gathered.
    pub vpls: u64,
    /// Of which reused from the previous frame.
    pub vpls_reused: u64,
    /// Frames gathered from a held G-buffer (still camera, no camera rays).
    pub gbuffers_reused: u64,
    /// Frames whose VPLs were sampled during the previous frame's gather.
    pub vpls_ahead: u64,
}

impl Totals {
    /// Frames per second over the run.
    pub fn fps(&self) -> f64 {
        self.frames as f64 / self.times.frame.max(1e-12)
    }

    /// Mean times per frame.
    pub fn per_frame(&self) -> StageTimes {
        self.times.scaled(1.0 / self.frames.max(1) as f64)
    }

    /// Rays per second.
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.times.frame.max(1e-12)
    }

    /// Acceptance rate of a Metropolis sampler.
    pub fn acceptance(&self) -> Option<f64> {
        (self.proposed > 0).then(|| self.accepted as f64 / self.proposed as f64)
    }
}

/// What one pass of the loop produced (for the HUD and the headless report).
#[derive(Clone, Debug)]
pub struct FrameReport {
    /// Stage times of this frame.
    pub times: StageTimes,
    /// Rays of this frame.
    pub rays: u64,
    /// Acceptance rate of this frame's proposals.
    pub acceptance: Option<f64>,
    /// VPLs gathered (new and reused).
    pub vpls: usize,
    /// Of which reused from the previous frame.
    pub vpls_reused: usize,
    /// How the camera changed before it.
    pub motion: Motion,
    /// d_t of the flicker measure, when measured.
    pub flicker: Option<f64>,
    /// Errors of the running mean against the reference, at checkpoints.
    pub errors: Option<ImageErrors>,
    /// Gathered from a held G-buffer (no camera rays).
    pub gbuffer_held: bool,
    /// Its VPLs were sampled during the previous frame's gather.
    pub vpls_ahead: bool,
}

/// The share of the way the window's filmic exposure moves per frame towards the current
/// image's (a time constant of about three frames).
pub const EXPOSURE_ADAPT: f32 = 0.3;

/// The tone mapping as the HUD shows it: "FILMIC +1 EV", "REINHARD", "LINEAR -2 EV".
pub fn tonemap_label(t: Tonemap) -> String {
    match t {
        Tonemap::Filmic(s) => format!("FILMIC {s:+} EV"),
        Tonemap::Reinhard => "REINHARD".into(),
        Tonemap::Exposure(s) => format!("LINEAR {s:+} EV"),
    }
}

/// The shared loop body and its state.
pub struct FrameLoop {
    /// Scene, sampler and running mean.
    pub session: Session,
    /// Display tone mapping ([ and ] change its stops).
    pub tonemap: Tonemap,
    /// The filmic operator's automatic exposure (log2), smoothed over frames.
    auto_ev: Option<f32>,
    /// The tone-mapped running mean at render resolution (0x00RRGGBB).
    pub displayed: Vec<u32>,
    /// Flicker measure, when requested.
    pub flicker: Option<FlickerMeter>,
    /// Reference image for the convergence report.
    pub reference: Option<(PathBuf, Image)>,
    /// (accumulated frames, errors) at the checkpoints.
    pub convergence: Vec<(u64, ImageErrors)>,
    /// Directory of recorded frames and whether EXRs are written too.
    pub record: Option<(PathBuf, bool)>,
    /// Sums over the run.
    pub totals: Totals,
}

impl FrameLoop {
    /// A loop over `session`.
    pub fn new(session: Session, tonemap: Tonemap) -> Self {
        let n = session.camera().pixel_count();
        FrameLoop {
            session,
            tonemap,
            auto_ev: None,
            displayed: vec![0; n],
            flicker: None,
            reference: None,
            convergence: Vec::new(),
            record: None,
            totals: Totals::default(),
        }
    }

    /// Reads the reference of the convergence report; it must have the render's size.
    pub fn set_reference(&mut self, path: PathBuf) -> Result<(), ViewError> {
        let img = output::read_exr(&path)?;
        let cam = self.session.camera();
        if (img.width, img.height) != (cam.width, cam.height) {
            return Err(ViewError::Reference {
                path,
                message: format!(
                    "reference is {}×{} but the frames are {}×{} (render it with the same --width/--height)",
                    img.width, img.height, cam.width, cam.height
                ),
            });
        }
        self.reference = Some((path, img));
        Ok(())
    }

    /// Creates the recording directory.
    pub fn set_record(&mut self, dir: PathBuf, exr: bool) -> Result<(), ViewError> {
        std::fs::create_dir_all(&dir).map_err(|e| {
            ViewError::Save(output::SaveError { path: dir.clone(), message: format!("cannot create directory: {e}") })
        })?;
        self.record = Some((dir, exr));
        Ok(())
    }

    /// Render resolution.
    pub fn size(&self) -> (u32, u32) {
        let c = self.session.camera();
        (c.width, c.height)
    }

    /// One frame: render, accumulate, tone-map, measure, record.
    pub fn frame(&mut self) -> Result<FrameReport, ViewError> {
        let t0 = Instant::now();
        let outcome = self.session.step();
        let td = Instant::now();
        let n = self.session.camera().pixel_count();
        if self.displayed.len() != n {
            self.displayed = vec![0; n];
        }
        let mapping = self.mapping();
        present::tonemap(self.session.mean(), mapping, &mut self.displayed);
        let display = td.elapsed() + outcome.accumulate_time;
        let times = StageTimes::of(&outcome, display, t0.elapsed());

        let s = &outcome.stats;
        let rays = s.rays.rays() + s.sampler.rays.rays();
        let t = &mut self.totals;
        t.frames += 1;
        t.times = t.times.zip(times, |a, b| a + b);
        t.rays += rays;
        t.accepted += s.sampler.accepted;
        t.proposed += s.sampler.proposed;
        t.non_finite += outcome.non_finite as u64;
        t.jumps += (outcome.motion == Motion::Jump && t.frames > 1) as u64;
        t.vpls += outcome.vpls_gathered as u64;
        t.vpls_reused += outcome.vpls_reused as u64;
        t.gbuffers_reused += s.gbuffer_reused;
        t.vpls_ahead += outcome.vpls_ahead as u64;

        let flicker = self.flicker.as_mut().and_then(|m| m.push(&outcome.image));
        self.session.recycle(outcome.image);
        let accumulated = self.session.accumulated() as u64;
        let errors = match &self.reference {
            Some((_, r)) if is_checkpoint(accumulated) => {
                let e = self.mean_image().errors(r);
                self.convergence.push((accumulated, e));
                Some(e)
            }
            _ => None,
        };
        if let Some((dir, exr)) = &self.record {
            let index = self.session.frames_rendered() - 1;
            let png = dir.join(format!("frame-{index:05}.png"));
            let (w, h) = self.size();
            present::write_png_rgb(&png, &self.displayed, w, h)?;
            if *exr {
                output::write_exr(&png.with_extension("exr"), &self.mean_image(), Aovs::default())?;
            }
        }
        Ok(FrameReport {
            times,
            rays,
            acceptance: s.sampler.acceptance_rate(),
            vpls: outcome.vpls_gathered,
            vpls_reused: outcome.vpls_reused,
            motion: outcome.motion,
            flicker,
            errors,
            gbuffer_held: s.gbuffer_reused > 0,
            vpls_ahead: outcome.vpls_ahead,
        })
    }

    /// This frame's display mapping. The filmic exposure moves a fraction [`EXPOSURE_ADAPT`] of
    /// the way (in stops) from the last frame's towards the running mean's automatic exposure,
    /// so a camera jump (a fresh mean) changes the brightness over a few frames instead of at
    /// once, and noise in early frames does not make it pump; the first frame takes it as is
    /// (one still frame is `render`'s PNG).
    fn mapping(&mut self) -> Mapping {
        let Tonemap::Filmic(stops) = self.tonemap else { return Mapping::of_still(self.tonemap, &[]) };
        let target = present::auto_exposure(self.session.mean()).log2();
        let ev = match self.auto_ev {
            Some(ev) => ev + EXPOSURE_ADAPT * (target - ev),
            None => target,
        };
        self.auto_ev = Some(ev);
        Mapping::Filmic { scale: (ev + stops).exp2() }
    }

    /// Changes the exposure by `stops` (the [ and ] keys); returns the HUD's message.
    pub fn adjust_exposure(&mut self, stops: f32) -> String {
        self.tonemap = match self.tonemap {
            Tonemap::Filmic(s) => Tonemap::Filmic((s + stops).clamp(-20.0, 20.0)),
            Tonemap::Exposure(s) => Tonemap::Exposure((s + stops).clamp(-20.0, 20.0)),
            Tonemap::Reinhard => return "reinhard sets its own exposure (--tonemap filmic or exposure)".into(),
        };
        format!("exposure {}", tonemap_label(self.tonemap).to_lowercase())
    }

    /// Writes a screenshot of the running mean: `png` as displayed and an EXR beside it.
    pub fn screenshot(&self, png: &std::path::Path) -> Result<(), ViewError> {
        let (w, h) = self.size();
        present::screenshot(png, self.session.mean(), &self.displayed, w, h)?;
        Ok(())
    }

    /// The closing line of a run: frames per second and milliseconds per stage.
    pub fn summary(&self, scene: &str, mode: &str) -> String {
        let t = &self.totals;
        let pf = t.per_frame();
        let ms = |s: f64| s * 1e3;
        let s = self.session.settings();
        let (w, h) = self.size();
        let (n, m) = s.frame.interleave;
        format!(
            "view {scene} ({mode}): {} frames {w}×{h}, {} VPLs {}, interleave {n}x{m}, clamp {}, filter {}, {}: \
             {:.2} frames/s ({:.1} ms/frame: VPLs {:.1}, primary {:.1}, shadow {:.1}{}, filter {:.1}, display {:.1} ms), \
             {:.2} Mrays/s, acceptance {}{}{}{}{}{}",
            t.frames,
            s.frame.vpls,
            self.session.sampler_name(),
            match (s.frame.clamp > 0.0, s.frame.compensate) {
                (true, true) => format!("{} compensated", s.frame.clamp),
                (true, false) => format!("{}", s.frame.clamp),
                _ => "off".into(),
            },
            match (s.frame.filter, self.session.filter_weight()) {
                (Some(_), Some(w)) => format!("on (faded out: weight {w:.3} at the end)"),
                (Some(_), None) => "on".into(),
                (None, _) => "off".into(),
            },
            chains_label(s.fresh_chains, s.reuse_frames),
            t.fps(),
            ms(pf.frame),
            ms(pf.vpls),
            ms(pf.primary),
            ms(pf.shadow),
            if s.frame.compensate && s.frame.clamp > 0.0 {
                format!(" (compensation {:.1})", ms(pf.compensation))
            } else {
                String::new()
            },
            ms(pf.filter),
            ms(pf.display),
            t.rays_per_second() / 1e6,
            t.acceptance().map_or("-".to_string(), |a| format!("{:.1} %", 100.0 * a)),
            if t.vpls_reused > 0 {
                format!(", {:.0} % of gathered VPLs reused", 100.0 * t.vpls_reused as f64 / t.vpls.max(1) as f64)
            } else {
                String::new()
            },
            if t.gbuffers_reused > 0 {
                format!(
                    ", {} of {} frames gathered from a held G-buffer (traced every {} while still)",
                    t.gbuffers_reused, t.frames, s.gbuffer_frames
                )
            } else {
                String::new()
            },
            if t.vpls_ahead > 0 {
                format!(
                    ", VPLs of {} frames sampled during the previous gather (their VPL time overlaps it)",
                    t.vpls_ahead
                )
            } else {
                String::new()
            },
            if t.jumps > 0 { format!(", {} camera jumps", t.jumps) } else { String::new() },
            if t.non_finite > 0 { format!(", {} non-finite pixels dropped", t.non_finite) } else { String::new() },
        )
    }

    /// The running mean as an image.
    pub fn mean_image(&self) -> Image {
        let (w, h) = self.size();
        Image { width: w, height: h, data: self.session.mean().to_vec() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smoothing_starts_at_the_first_value_then_follows() {
        let mut s = StageTimes::default();
        let a = StageTimes { frame: 1.0, shadow: 0.5, ..Default::default() };
        s.smooth(a, 0.25);
        assert_eq!(s, a);
        s.smooth(StageTimes { frame: 2.0, ..Default::default() }, 0.25);
        assert!((s.frame - 1.25).abs() < 1e-12 && (s.shadow - 0.375).abs() < 1e-12);
    }

    #[test]
    fn totals_give_rates_per_frame() {
        let t = Totals {
            frames: 4,
            times: StageTimes { frame: 2.0, vpls: 0.4, ..Default::default() },
            rays: 1000,
            ..Default::default()
        };
        assert_eq!(t.fps(), 2.0);
        assert!((t.per_frame().vpls - 0.1).abs() < 1e-12);
        assert_eq!(t.rays_per_second(), 500.0);
        assert_eq!(t.acceptance(), None);
    }
}
