//! The flags of `mirage view` and their validation into [`ViewOptions`]. The window and the
//! headless loop take the same scene, camera and quality flags, so a benchmark measures what
//! the window shows.

use std::path::PathBuf;

use clap::Args;

use super::error::ViewError;
use super::path::CameraPath;
use super::session::{Ahead, SessionSettings, default_sampler};
use crate::film::Tonemap;
use crate::options::TonemapArg;
use crate::options::{CameraArgs, GatherArgs, VplSamplerArg};

/// Frames of a headless run without `--frames`.
pub const DEFAULT_HEADLESS_FRAMES: u64 = 100;

/// The window's keys, shown after the flags in `mirage view --help`.
pub const CONTROLS_HELP: &str = "Window controls:
  W A S D / Q E   move forward, left, back, right / down, up      mouse drag   look
  wheel           movement speed                                 R            reset the camera
  1-9, Tab        VPL sampler (sir, sir-cdf, bir, mh, mtmh)      = / -        VPLs ×2 / ÷2
  I               interleave tile 1, 2, 4, 8, 16                 C            clamp on/off (. , ×10 ÷10)
  F               discontinuity filter on/off                    K            chain + VPL reuse / fresh chains
  B               clamp compensation on/off (cost: COMP in HUD)  P, F12       screenshot (EXR + PNG)
  [ / ]           exposure −1 / +1 stop (shown in the HUD)        H / F1       HUD / key help
  Esc             quit";

/// Flags of `mirage view`.
#[derive(Args, Clone, Debug)]
#[command(after_help = CONTROLS_HELP)]
pub struct ViewArgs {
    /// Scene file (.gltf, .glb, .obj) or built-in scene name (default: the built-in Cornell box).
    pub scene: Option<String>,
    /// VPL sampler at start (keys 1-9 / Tab switch it). Default: mtmh when built in, else sir.
    #[arg(long, value_enum)]
    pub vpl_sampler: Option<VplSamplerArg>,
    /// The VPL frame pipeline's flags.
    #[command(flatten)]
    pub gather: GatherArgs,
    /// The Metropolis samplers' flags.
    #[command(flatten)]
    pub mir: crate::options::MirArgs,
    /// Maximum number of scattering events of the sampler's paths.
    #[arg(long, default_value_t = 128)]
    pub max_depth: u32,
    /// Base seed: frame i uses a hash of (seed, i), so headless runs are reproducible.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Render resolution relative to the window (0.5: half the pixels per side, upscaled).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    /// Tone mapping of the window and of --record frames (the same operators as `render`'s PNG;
    /// the filmic exposure adapts smoothly between frames).
    #[arg(long, value_enum, default_value_t = TonemapArg::Filmic)]
    pub tonemap: TonemapArg,
    /// Exposure in stops: added to the filmic operator's automatic exposure, or the linear
    /// scale 2^stops of `--tonemap exposure`; [ and ] change it by a stop in the window.
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f32>,
    /// Run the frame loop without a window (benchmarks, tests, measures); ends with a summary.
    #[arg(long)]
    pub headless: bool,
    /// Frames to render: headless, the run's length (default 100); in a window, close after N.
    #[arg(long)]
    pub frames: Option<u64>,
    /// Scripted camera: a keyframe file (lines "ex ey ez tx ty tz") or a built-in path:
    /// orbit, dolly, pan.
    #[arg(long, value_name = "FILE|orbit|dolly|pan")]
    pub camera_path: Option<String>,
    /// Write every displayed frame to DIR as frame-NNNNN.png.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// With --record, also write the linear image of every frame as frame-NNNNN.exr.
    #[arg(long, requires = "record")]
    pub record_exr: bool,
    /// Headless: print the flicker measure (mean relative luminance difference between
    /// consecutive individual frames).
    #[arg(long, requires = "headless")]
    pub flicker: bool,
    /// Reset the VPL sampler before every frame instead of continuing its chain, and reuse no
    /// VPLs (K toggles it in the window): the baseline of the flicker measure.
    #[arg(long)]
    pub fresh_chains: bool,
    /// VPL reuse while the camera moves a little: each frame samples ⌈m/K⌉ new VPLs and gathers
    /// them with the most recent VPLs of the previous frame, m in all, so consecutive frames
    /// share about (K−1)/K of their VPLs. 1 turns reuse off; a still camera never reuses.
    #[arg(long, value_name = "K", default_value_t = 4)]
    pub vpl_reuse: u32,
    /// While the camera stands still, trace the G-buffer (camera rays, receivers) every K-th
    /// frame and gather the frames in between from it: they differ only in their VPLs. The first
    /// K frames after the camera stops are each traced with a new anti-aliasing jitter; after
    /// them the jitter moves every K frames. 1 traces every frame.
    #[arg(long, value_name = "K", default_value_t = 4)]
    pub gbuffer_frames: u32,
    /// While the camera stands still, sample the next frame's VPLs during this frame's gather,
    /// on the cores the gather leaves idle (the same VPLs: same seed, same sampler state); the
    /// stage times then overlap and no longer add up to the frame time. auto: when the sampler
    /// takes 1 ms or more (MIR, sir-cdf, bir); never: each frame samples its VPLs when it starts.
    #[arg(long, value_enum, value_name = "WHEN", default_value_t = Ahead::Auto)]
    pub vpls_ahead: Ahead,
    /// Headless, still camera: print the relMSE of the accumulated image against this EXR
    /// after 1, 2, 4, 8… frames.
    #[arg(long, value_name = "REF.exr", requires = "headless", conflicts_with = "camera_path")]
    pub reference: Option<PathBuf>,
    /// Start with the HUD hidden (H toggles it).
    #[arg(long)]
    pub no_hud: bool,
    /// Directory for screenshots (key P).
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub screenshot_dir: PathBuf,
    /// Write a screenshot (this PNG and an EXR beside it) when the loop ends.
    #[arg(long, value_name = "FILE.png")]
    pub screenshot_on_exit: Option<PathBuf>,
    /// Camera and window size (--width/--height: the window, or the headless image).
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Lights added to the scene (sun, sky, environment).
    #[command(flatten)]
    pub lights: crate::options::LightArgs,
}

/// Validated viewer settings.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// Sampler, pipeline, seed and chain mode.
    pub session: SessionSettings,
    /// Render resolution / window resolution.
    pub scale: f32,
    /// Display tone mapping.
    pub tonemap: Tonemap,
    /// No window.
    pub headless: bool,
    /// Frames to render (headless: always set).
    pub frames: Option<u64>,
    /// Scripted camera.
    pub camera_path: Option<CameraPath>,
    /// Directory of recorded frames.
    pub record: Option<PathBuf>,
    /// Record EXRs too.
    pub record_exr: bool,
    /// Measure flicker.
    pub flicker: bool,
    /// Reference image for the convergence report.
    pub reference: Option<PathBuf>,
    /// HUD visible at start.
    pub hud: bool,
    /// Screenshot directory.
    pub screenshot_dir: PathBuf,
    /// Screenshot written when the loop ends.
    pub screenshot_on_exit: Option<PathBuf>,
}

impl ViewArgs {
    /// Checks the flags and builds the options (the camera path file is read here).
    pub fn options(&self) -> Result<ViewOptions, ViewError> {
        let bad = |m: String| Err(ViewError::Options(m));
        if let Err(e) = self.gather.validate().and_then(|_| self.mir.validate()) {
            return bad(e);
        }
        if self.max_depth > 100_000 {
            return bad(format!("--max-depth {} is absurdly large (max 100000)", self.max_depth));
        }
        if !(self.scale >= 0.05 && self.scale <= 4.0) {
            return bad(format!("--scale {} is outside 0.05…4", self.scale));
        }
        let tonemap = match self.tonemap.with_exposure(self.exposure) {
            Ok(t) => t,
            Err(e) => return bad(e),
        };
        if !(1..=64).contains(&self.vpl_reuse) {
            return bad(format!("--vpl-reuse {} is outside 1…64", self.vpl_reuse));
        }
        if !(1..=64).contains(&self.gbuffer_frames) {
            return bad(format!("--gbuffer-frames {} is outside 1…64", self.gbuffer_frames));
        }
        if self.threads == Some(0) {
            return bad("--threads must be at least 1".into());
        }
        if let Some(n) = self.frames
            && !(1..=1_000_000_000).contains(&n)
        {
            return bad(format!("--frames {n} is outside 1…1000000000"));
        }
        if let Err(e) = self.lights.validate() {
            return bad(e);
        }
        for (flag, v) in [("--width", self.camera.width), ("--height", self.camera.height)] {
            if let Some(v) = v
                && !(1..=16384).contains(&v)
            {
                return bad(format!("{flag} {v} is outside 1…16384"));
            }
        }
        let camera_path = self.camera_path.as_deref().map(CameraPath::from_arg).transpose()?;
        Ok(ViewOptions {
            session: SessionSettings {
                sampler: self.vpl_sampler.unwrap_or_else(default_sampler),
                max_depth: self.max_depth,
                mir: self.mir.config(self.max_depth),
                frame: self.gather.frame_settings(),
                seed: self.seed,
                fresh_chains: self.fresh_chains,
                reuse_frames: self.vpl_reuse,
                gbuffer_frames: self.gbuffer_frames,
                ahead: self.vpls_ahead,
                filter_fade: self.gather.filter_fade,
            },
            scale: self.scale,
            tonemap,
            headless: self.headless,
            frames: if self.headless { Some(self.frames.unwrap_or(DEFAULT_HEADLESS_FRAMES)) } else { self.frames },
            camera_path,
            record: self.record.clone(),
            record_exr: self.record_exr,
            flicker: self.flicker,
            reference: self.reference.clone(),
            hud: !self.no_hud,
            screenshot_dir: self.screenshot_dir.clone(),
            screenshot_on_exit: self.screenshot_on_exit.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::view::session::sampler_name;
    use clap::{Parser, ValueEnum};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        view: ViewArgs,
    }

    fn parse(args: &[&str]) -> ViewArgs {
        Cli::try_parse_from(std::iter::once("view").chain(args.iter().copied())).unwrap().view
    }

    #[test]
    fn defaults_are_the_interactive_settings_and_the_preferred_sampler() {
        let o = parse(&[]).options().unwrap();
        assert_eq!(o.session, SessionSettings::default());
        assert_eq!(o.session.frame.vpls, 256);
        assert_eq!(o.session.frame.interleave, (8, 8));
        assert_eq!(sampler_name(o.session.sampler), if sampler_exists("mtmh") { "mtmh" } else { "sir" });
        assert_eq!(o.frames, None);
        assert_eq!(parse(&["--headless"]).options().unwrap().frames, Some(DEFAULT_HEADLESS_FRAMES));
        assert_eq!(parse(&["--add-light"]).lights.add_light, Some(1.0));
        assert_eq!(parse(&["--add-light", "5"]).lights.add_light, Some(5.0));
    }

    fn sampler_exists(name: &str) -> bool {
        VplSamplerArg::value_variants().iter().any(|v| sampler_name(*v) == name)
    }

    #[test]
    fn absurd_values_are_rejected_naming_the_flag() {
        for (args, flag) in [
            (&["--vpls", "0"][..], "--vpls"),
            (&["--scale", "0"][..], "--scale"),
            (&["--clamp", "-1"][..], "--clamp"),
            (&["--frames", "0"][..], "--frames"),
            (&["--width", "0"][..], "--width"),
            (&["--add-light", "-2"][..], "--add-light"),
            (&["--vpl-reuse", "0"][..], "--vpl-reuse"),
            (&["--gbuffer-frames", "0"][..], "--gbuffer-frames"),
            (&["--gbuffer-frames", "65"][..], "--gbuffer-frames"),
        ] {
            let e = parse(args).options().unwrap_err().to_string();
            assert!(e.contains(flag), "{args:?}: {e}");
        }
        assert!(Cli::try_parse_from(["view", "--flicker"]).is_err(), "--flicker needs --headless");
    }
}
