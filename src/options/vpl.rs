//! The VPL modes' flags (`render --mode ir|mir` and `view`): the frame pipeline's, the
//! Metropolis samplers', the sampler choice, and their parsers.

use super::*;

/// Mutation kernels of the MIR chains.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum KernelArg {
    /// Path-space bidirectional mutation: regenerate the light sub-path from a cut, or the
    /// camera end (Veach & Guibas 1997, as papers/002 §7.1).
    Bidir,
    /// Primary-sample-space mutation: small perturbations of the random numbers or a large step
    /// (Kelemen et al. 2002).
    Pss,
}

/// How the gather traces rays (`--rays`); the image is the same, only speed differs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum RaysArg {
    /// One ray at a time.
    Single,
    /// 8-wide packets for primary rays, single shadow rays (fastest measured).
    #[default]
    Primary,
    /// 8-wide packets; shadow packets share a VPL (pixels of a row gathering the same subset).
    SharedEnd,
    /// 8-wide packets; shadow packets share a pixel (its VPL subset).
    SharedOrigin,
}

impl From<RaysArg> for crate::gather::Tracing {
    fn from(r: RaysArg) -> Self {
        match r {
            RaysArg::Single => Self::Single,
            RaysArg::Primary => Self::PrimaryPackets,
            RaysArg::SharedEnd => Self::SharedEnd,
            RaysArg::SharedOrigin => Self::SharedOrigin,
        }
    }
}

/// Flags of the VPL frame pipeline shared by `render --mode ir|mir` and `view`.
#[derive(Args, Clone, Debug)]
pub struct GatherArgs {
    /// VPLs per frame.
    #[arg(long, default_value_t = 256)]
    pub vpls: usize,
    /// Interleaved-sampling tile "NxM"; 1x1 disables interleaving.
    #[arg(long, value_parser = parse_interleave, default_value = "8x8")]
    pub interleave: (u32, u32),
    /// Bound on the VPL geometry term G, in units of 1/(scene bounds diagonal)²; 0 = no clamp
    /// (unbiased with unbounded variance: splotches near corners; in mir mode behind slits,
    /// light comes back only through rare VPLs). With --compensate on (the render default)
    /// the clamp costs no bias.
    #[arg(long, default_value_t = 300.0, allow_hyphen_values = true)]
    pub clamp: f32,
    /// Do not apply the discontinuity buffer after the gather (in the viewer: start with it off).
    #[arg(long)]
    pub no_filter: bool,
    /// Compensate the clamp (Kollig & Keller 2004): a short path from each pixel adds back, in
    /// expectation, the light the clamp removed, so the image is unbiased at any --clamp.
    /// Default: on (in the viewer at one pixel in two, about 18 % of a Cornell frame at 512²;
    /// key B turns it off)
    #[arg(long, value_enum)]
    pub compensate: Option<Switch>,
    /// Trace the compensation at one pixel in N (a checkerboard for 2, its phase changing every
    /// frame), weighted by N: the same expectation at 1/N of the cost, with more noise for the
    /// filter to average. Default: 1 for `render` and `converge`, 2 in the viewer
    #[arg(long, value_name = "N")]
    pub compensate_stride: Option<u32>,
    /// Ray tracing of the gather: 8-wide packets for primary rays and single shadow rays
    /// (default), shadow packets grouped by shared VPL or by shared pixel, or single rays
    /// everywhere. Same image; see benches/gather.rs.
    #[arg(long, value_enum, default_value_t = RaysArg::Primary)]
    pub rays: RaysArg,
    /// Fade the discontinuity buffer out as frames accumulate (in `render`, and in the viewer
    /// while the camera stands still): after N frames the image is w·filtered + (1 − w)·unfiltered
    /// with w = K/(K + N), so it converges to the unbiased, unfiltered mean. `auto`: K = the
    /// interleave tile's pixel count (64 for 8x8); a number: that K; `never`: filtered
    /// throughout, with the filter's blur where light changes within a few pixels (the lit
    /// faces of a slit).
    #[arg(long, value_parser = parse_filter_fade, default_value = "auto", value_name = "auto|never|K")]
    pub filter_fade: FilterFade,
    /// Split a VPL that brings more than B times the median VPL's light (MIR's VPLs where a
    /// chain stayed long) into copies gathered by several interleave subsets, so that its light
    /// is not one subset's bright dots: the same expectation, less noise per frame, a few more
    /// VPLs to gather. 0: never split.
    #[arg(long, value_name = "B", default_value_t = crate::frame::FrameSettings::interactive().split_strong)]
    pub split_strong: f32,
    /// Discontinuity buffer: largest normal angle between pixels averaged together, degrees.
    #[arg(long, default_value_t = 20.0)]
    pub filter_angle: f32,
    /// Discontinuity buffer: largest relative depth difference between pixels averaged together.
    #[arg(long, default_value_t = 0.05)]
    pub filter_depth: f32,
}

impl GatherArgs {
    /// Rejects absurd values with a one-line message naming the flag.
    pub fn validate(&self) -> Result<(), String> {
        if self.vpls == 0 || self.vpls > 10_000_000 {
            return Err(format!("--vpls {} is outside 1…10000000", self.vpls));
        }
        if !(self.clamp >= 0.0 && self.clamp.is_finite()) {
            return Err(format!("--clamp {} must be finite and ≥ 0", self.clamp));
        }
        if self.compensate_stride.is_some_and(|n| !(1..=64).contains(&n)) {
            return Err(format!("--compensate-stride {} is outside 1…64", self.compensate_stride.unwrap_or(0)));
        }
        if !(self.split_strong == 0.0 || (1.0..=1e6).contains(&self.split_strong)) {
            return Err(format!("--split-strong {} must be 0 (off) or in 1…1000000", self.split_strong));
        }
        let angle_ok = self.filter_angle > 0.0 && self.filter_angle <= 180.0;
        let depth_ok = self.filter_depth > 0.0 && self.filter_depth.is_finite();
        if !angle_ok || !depth_ok {
            return Err("--filter-angle must be in (0, 180] and --filter-depth > 0".into());
        }
        Ok(())
    }

    /// The frame settings these flags give (interactive defaults for the rest).
    pub fn frame_settings(&self) -> crate::frame::FrameSettings {
        crate::frame::FrameSettings {
            vpls: self.vpls,
            interleave: self.interleave,
            clamp: self.clamp,
            filter: if self.no_filter { None } else { Some((self.filter_angle, self.filter_depth)) },
            tracing: self.rays.into(),
            compensate: self.compensate_or(true),
            compensation_stride: self.compensate_stride.unwrap_or(2),
            split_strong: self.split_strong,
            ..crate::frame::FrameSettings::interactive()
        }
    }
}

/// On or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

impl GatherArgs {
    /// Whether the clamp is compensated, `default` when no --compensate was given.
    pub fn compensate_or(&self, default: bool) -> bool {
        self.compensate.map_or(default, |s| s == Switch::On)
    }
}

/// Flags of the Metropolis VPL samplers (mh, mtmh) shared by `render --mode mir` and `view`.
#[derive(Args, Clone, Debug)]
pub struct MirArgs {
    /// Mutation kernel of the mir chains.
    #[arg(long, value_enum, default_value_t = KernelArg::Bidir)]
    pub kernel: KernelArg,
    /// Candidates per MTMH step (p).
    #[arg(long, default_value_t = 10)]
    pub candidates: usize,
    /// mir: choose lights with a light-source CDF estimated from the camera (papers/002 §7.4).
    #[arg(long)]
    pub light_cdf: bool,
    /// mir: independent Metropolis chains run side by side, each giving its share of the VPL
    /// locations (the count, not the thread count, fixes the image).
    #[arg(long, default_value_t = crate::vpl::metropolis::MirSettings::mtmh().chains)]
    pub chains: usize,
    /// mir: independent bidirectional samples estimating the camera power P_c each frame (papers/002
    /// §5.1): its error scales the whole frame, so behind slits and holes, where few samples
    /// carry light, more of them lower the image's error.
    #[arg(long, default_value_t = crate::vpl::metropolis::MirSettings::mtmh().pc_samples)]
    pub pc_samples: usize,
    /// mir: camera probes per batch estimating each VPL's camera response P′ (papers/002 §5.4);
    /// a VPL seen by few probes takes further batches.
    #[arg(long, default_value_t = crate::vpl::metropolis::MirSettings::mtmh().probes)]
    pub probes: usize,
    /// mir: continue the last frame's chains while the camera stands still (the paper's
    /// temporal coherence) instead of starting each frame's chains from fresh picks of the P_c
    /// samples (drawn ∝ their weight; the default). Fresh picks make frames independent: where
    /// the chains move between regions of the image only every few thousand states (light
    /// through small holes), carried chains keep each region's share of VPLs for many frames
    /// and the image converges slowly
    #[arg(long)]
    pub carry_chains: bool,
    /// mir: share of the camera ends (P_c samples, camera-end mutations) and of the probes
    /// drawn where the last frame's chains looked on the screen (the rest uniform; every weight
    /// divides by the mixture's density, so the expectation is unchanged). 0: all uniform
    #[arg(long, default_value_t = crate::vpl::metropolis::MirSettings::mtmh().guided_probes)]
    pub guide: f64,
}

impl MirArgs {
    /// Rejects absurd values with a one-line message naming the flag.
    pub fn validate(&self) -> Result<(), String> {
        if self.candidates == 0 || self.candidates > 1000 {
            return Err(format!("--candidates {} is outside 1…1000", self.candidates));
        }
        if self.chains == 0 || self.chains > 4096 {
            return Err(format!("--chains {} is outside 1…4096", self.chains));
        }
        if !(0.0..=0.9).contains(&self.guide) {
            return Err(format!("--guide {} is outside 0…0.9", self.guide));
        }
        if self.pc_samples == 0 || self.pc_samples > 1 << 26 {
            return Err(format!("--pc-samples {} is outside 1…{}", self.pc_samples, 1 << 26));
        }
        if self.probes == 0 || self.probes > 1 << 22 {
            return Err(format!("--probes {} is outside 1…{}", self.probes, 1 << 22));
        }
        Ok(())
    }

    /// The samplers' settings these flags give, for paths of at most `max_depth` events.
    pub fn config(&self, max_depth: u32) -> SamplerConfig {
        SamplerConfig {
            max_depth,
            kernel: self.kernel,
            candidates: self.candidates,
            light_cdf: self.light_cdf,
            chains: self.chains,
            pc_samples: self.pc_samples,
            probes: self.probes,
            carry_chains: self.carry_chains,
            guide: self.guide,
        }
    }
}

/// Settings of the samplers beyond their kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerConfig {
    /// Longest light sub-path (vertices) for SIR-style samplers.
    pub max_depth: u32,
    /// MIR mutation kernel.
    pub kernel: KernelArg,
    /// MTMH candidates.
    pub candidates: usize,
    /// MIR: choose lights with a light-source CDF.
    pub light_cdf: bool,
    /// MIR: independent chains run side by side.
    pub chains: usize,
    /// MIR: independent samples estimating the camera power P_c each frame (N).
    pub pc_samples: usize,
    /// MIR: camera probes per batch estimating each VPL's camera response P′ (K).
    pub probes: usize,
    /// MIR: continue the last frame's chains while the camera stands still.
    pub carry_chains: bool,
    /// MIR: share of the screen guide in camera ends and probes (0: uniform).
    pub guide: f64,
}

impl Default for SamplerConfig {
    fn default() -> Self {
        SamplerConfig {
            max_depth: 64,
            kernel: KernelArg::Bidir,
            candidates: 10,
            light_cdf: false,
            chains: crate::vpl::metropolis::MirSettings::mtmh().chains,
            pc_samples: crate::vpl::metropolis::MirSettings::mtmh().pc_samples,
            probes: crate::vpl::metropolis::MirSettings::mtmh().probes,
            carry_chains: crate::vpl::metropolis::MirSettings::mtmh().carry,
            guide: crate::vpl::metropolis::MirSettings::mtmh().guided_probes,
        }
    }
}

/// VPL sampling strategies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VplSamplerArg {
    /// Standard instant radiosity (Keller 1997): light paths, lights chosen ∝ power.
    Sir,
    /// SIR with lights chosen ∝ their estimated contribution to the image (Wald et al. 2003).
    SirCdf,
    /// Bidirectional instant radiosity: R·m candidates from light and camera paths, resampled.
    Bir,
    /// Metropolis instant radiosity with a Metropolis–Hastings chain.
    Mh,
    /// Metropolis instant radiosity with a multiple-try Metropolis–Hastings chain (default of
    /// --mode mir).
    Mtmh,
}

impl VplSamplerArg {
    /// The sampler object with default settings.
    pub fn build(self, max_depth: u32) -> Box<dyn crate::vpl::VplSampler> {
        self.build_with(&SamplerConfig { max_depth, ..Default::default() })
    }

    /// True for the Metropolis samplers.
    pub fn is_metropolis(self) -> bool {
        matches!(self, VplSamplerArg::Mh | VplSamplerArg::Mtmh)
    }

    /// The sampler object.
    pub fn build_with(self, c: &SamplerConfig) -> Box<dyn crate::vpl::VplSampler> {
        use crate::vpl::metropolis::{Chain, Mir, MirSettings};
        use crate::vpl::mutation::{Bidirectional, PrimarySample};
        let mir = |chain| MirSettings {
            chain,
            light_cdf: c.light_cdf,
            chains: c.chains.max(1),
            pc_samples: c.pc_samples.max(1),
            probes: c.probes.max(1),
            carry: c.carry_chains,
            guided_probes: c.guide,
            ..MirSettings::mtmh()
        };
        let chain = if self == VplSamplerArg::Mh { Chain::Mh } else { Chain::Mtmh(c.candidates.max(1)) };
        match (self, c.kernel) {
            (VplSamplerArg::Sir, _) => Box::new(crate::vpl::sir::Sir::new(c.max_depth)),
            (VplSamplerArg::SirCdf, _) => Box::new(crate::vpl::cdf::SirCdf::new(c.max_depth)),
            (VplSamplerArg::Bir, _) => Box::new(crate::vpl::bir::Bir::new(c.max_depth)),
            (_, KernelArg::Bidir) => Box::new(Mir::new(Bidirectional::default(), mir(chain))),
            (_, KernelArg::Pss) => Box::new(Mir::new(PrimarySample::default(), mir(chain))),
        }
    }
}

/// `--filter-fade`: how the discontinuity buffer fades out of an accumulated render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterFade {
    /// K = n·m of the interleave tile.
    Auto,
    /// Filtered throughout.
    Never,
    /// This K.
    Frames(u32),
}

impl FilterFade {
    /// The fade constant for an n×m interleave, `None` for never.
    pub fn constant(self, (n, m): (u32, u32)) -> Option<u32> {
        match self {
            FilterFade::Auto => Some(n * m),
            FilterFade::Never => None,
            FilterFade::Frames(k) => Some(k),
        }
    }
}

/// Parses `--filter-fade`: auto, never, or K (1…1000000).
pub fn parse_filter_fade(v: &str) -> Result<FilterFade, String> {
    match v {
        "auto" => Ok(FilterFade::Auto),
        "never" => Ok(FilterFade::Never),
        _ => match v.parse::<u32>() {
            Ok(k) if (1..=1_000_000).contains(&k) => Ok(FilterFade::Frames(k)),
            _ => Err(format!("'{v}' is not auto, never or a frame count 1…1000000")),
        },
    }
}

/// Parses "NxM" (each 1…64).
pub fn parse_interleave(v: &str) -> Result<(u32, u32), String> {
    let parts: Vec<&str> = v.split(['x', 'X']).collect();
    match parts.as_slice() {
        [n, m] => {
            let n: u32 = n.trim().parse().map_err(|e| format!("'{v}': {e}"))?;
            let m: u32 = m.trim().parse().map_err(|e| format!("'{v}': {e}"))?;
            if !(1..=64).contains(&n) || !(1..=64).contains(&m) {
                return Err(format!("'{v}': tile sides must be 1…64"));
            }
            Ok((n, m))
        }
        _ => Err(format!("'{v}' is not NxM (e.g. 8x8)")),
    }
}
