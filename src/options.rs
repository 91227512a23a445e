//! Command-line arguments (clap) → validated [`RenderOptions`].
//!
//! The scene file says what to render (geometry, materials, camera); the command line says how
//! (mode, budget, resolution, seed), as papers/000 §4.2.5 recommends. Every flag's help text is
//! its documentation.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};
use glam::{Vec2, Vec3};

use crate::film::{FilterKind, Tonemap};
use crate::offline::{Budget, OfflineSettings};
use crate::scene::CameraSettings;

/// Rendering modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Path tracing with next-event estimation and MIS: the reference.
    Pt,
    /// Bidirectional path tracing: all (s, t) strategies with power-heuristic MIS and
    /// light-tracing splats.
    Bdpt,
    /// Instant radiosity: VPLs from --vpl-sampler (sir, sir-cdf, bir), gathered with
    /// interleaved sampling and the discontinuity buffer; independent VPL sets accumulate under
    /// --spp / --time.
    Ir,
    /// Metropolis instant radiosity (the default): VPLs from an MH or MTMH chain over complete
    /// paths (--vpl-sampler mh|mtmh, --kernel, --candidates), gathered like ir.
    Mir,
    /// Primary-sample-space Metropolis light transport (Kelemen et al. 2002) over the
    /// bidirectional path sampler, one path depth per chain with the strategy chosen inside the
    /// chain (multiplexed, as pbrt-v4); --mlt-chains, --bootstrap, --large-step, --sigma. For
    /// light that arrives through slits and holes, and caustics.
    Pssmlt,
}

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

impl Mode {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Pt => "pt",
            Mode::Bdpt => "bdpt",
            Mode::Ir => "ir",
            Mode::Mir => "mir",
            Mode::Pssmlt => "pssmlt",
        }
    }
}

/// Pixel filters as command-line values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FilterArg {
    /// Box of radius ½ pixel: the mean radiance through each pixel (default).
    Box,
    /// Tent of radius 1.
    Tent,
    /// Gaussian, σ = ½, radius 1.5.
    Gaussian,
    /// Mitchell–Netravali, B = C = ⅓, radius 2.
    Mitchell,
    /// Lanczos (a = 2), radius 2.
    Lanczos,
}

/// Tone-mapping operators for the PNG and the window.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TonemapArg {
    /// Exposure from the image (its median lit luminance to mid grey) plus --exposure stops,
    /// then the ACES fitted filmic curve on each pixel's largest channel: hue kept, highlights
    /// rolled off (default).
    Filmic,
    /// Reinhard et al. 2002, global photographic operator (key 0.18; it takes no --exposure).
    Reinhard,
    /// Linear: multiply by 2^--exposure, clamp, sRGB.
    Exposure,
}

impl TonemapArg {
    /// The operator with `--exposure` (stops, default 0), or an error when the combination
    /// means nothing (Reinhard sets its own key).
    pub fn with_exposure(self, exposure: Option<f32>) -> Result<Tonemap, String> {
        if let Some(e) = exposure
            && !e.is_finite()
        {
            return Err(format!("--exposure {e} must be a finite number of stops"));
        }
        let stops = exposure.unwrap_or(0.0);
        Ok(match self {
            TonemapArg::Filmic => Tonemap::Filmic(stops),
            TonemapArg::Exposure => Tonemap::Exposure(stops),
            TonemapArg::Reinhard if exposure.is_some() => {
                return Err(
                    "--exposure has no effect with --tonemap reinhard (it sets its own key); use filmic or exposure"
                        .into(),
                );
            }
            TonemapArg::Reinhard => Tonemap::Reinhard,
        })
    }
}

/// The camera flags shared by `render` and `view`.
#[derive(Args, Clone, Debug, Default)]
pub struct CameraArgs {
    /// Image width in pixels (default: the scene's, else 512).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's, else from the aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    /// Camera position "x,y,z" (overrides the scene's camera).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point the camera looks at, "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Camera up vector, "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees.
    #[arg(long = "fov-y")]
    pub fov_y: Option<f32>,
    /// Thin-lens aperture radius in scene units (0 = pinhole).
    #[arg(long, default_value_t = 0.0)]
    pub lens_radius: f32,
    /// Distance of the plane in focus (default: eye to target).
    #[arg(long)]
    pub focus_distance: Option<f32>,
    /// Focus on whatever is seen through this image point "x,y" (pixels): the focus distance
    /// is found with a ray through it (papers/000 Fig. 11).
    #[arg(long, value_parser = parse_vec2)]
    pub focus_at: Option<Vec2>,
}

/// Lights added from the command line (`render` and `view`): a panel over the model, the sun
/// and the sky.
#[derive(Args, Clone, Debug, Default)]
pub struct LightArgs {
    /// Add an area light for geometry-only models (e.g. ../shared/models/sponza.obj): a
    /// downward-facing panel of radiance LE just above the model's bounds, covering its
    /// footprint like a sky over an open courtyard (+y is up). Without a camera in the file,
    /// the camera is placed inside, looking along the longer horizontal axis.
    #[arg(long, value_name = "LE", num_args = 0..=1, default_missing_value = "1", allow_negative_numbers = true)]
    pub add_light: Option<f32>,
    /// Add a sun "AZIMUTH,ELEVATION,ILLUMINANCE": azimuth in degrees from +z towards +x,
    /// elevation in degrees above the horizon (+y is up), illuminance in W/m² (lux) on a surface
    /// facing it, white.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, value_name = "AZ,EL,E")]
    pub sun: Option<Vec3>,
    /// Angular diameter of the --sun in degrees (0: parallel light, no ray can hit it).
    #[arg(long, default_value_t = 0.53, value_name = "DEG")]
    pub sun_diameter: f32,
    /// Add a constant sky of radiance "R,G,B" (W/(m²·sr)) from every direction.
    #[arg(long, value_parser = parse_vec3, value_name = "R,G,B")]
    pub sky: Option<Vec3>,
    /// Add an environment light from an equirectangular map (.exr or .hdr; +y up, the top row
    /// the zenith), importance-sampled by its luminance.
    #[arg(long, value_name = "FILE")]
    pub environment: Option<PathBuf>,
    /// Rotate the --environment about +y by this many degrees.
    #[arg(long, default_value_t = 0.0, value_name = "DEG", allow_hyphen_values = true)]
    pub environment_rotate: f32,
}

impl LightArgs {
    /// Checks the flags that no scene check covers.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(le) = self.add_light
            && !(le > 0.0 && le.is_finite())
        {
            return Err(format!("--add-light {le} must be a positive radiance"));
        }
        Ok(())
    }

    /// Adds the requested lights to `desc` (reading the environment file); warnings about the
    /// file go into the scene's warnings.
    pub fn apply(&self, desc: &mut crate::load::SceneDesc) -> Result<(), crate::load::LoadError> {
        use crate::load::{EnvironmentDesc, PunctualDesc};
        if let Some(le) = self.add_light {
            crate::load::add_sky_light(desc, Vec3::splat(le));
        }
        if let Some(Vec3 { x: az, y: el, z: e }) = self.sun {
            let (az, el) = (az.to_radians(), el.to_radians());
            let towards = Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
            desc.lights.push(PunctualDesc::Directional {
                direction: -towards,
                illuminance: Vec3::splat(e),
                angular_diameter: self.sun_diameter.to_radians(),
            });
        }
        if let Some(l) = self.sky {
            desc.lights.push(PunctualDesc::Environment(EnvironmentDesc::Constant(l)));
        }
        if let Some(path) = &self.environment {
            let (env, warning) = crate::load::load_environment(path, self.environment_rotate.to_radians())?;
            desc.lights.push(PunctualDesc::Environment(env));
            desc.warnings.extend(warning);
        }
        Ok(())
    }
}

impl CameraArgs {
    /// The camera overrides for scene validation (the focus point is resolved later, with a ray).
    pub fn settings(&self) -> CameraSettings {
        CameraSettings {
            width: self.width,
            height: self.height,
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov_y_deg: self.fov_y,
            lens_radius: self.lens_radius,
            focus_distance: self.focus_distance,
        }
    }
}

/// The flags of `mirage render`.
#[derive(Args, Clone, Debug)]
pub struct RenderArgs {
    /// Scene file (.gltf, .glb, .obj) or the name of a built-in scene (cornell, furnace,
    /// ajar-door, left-right, direct-indirect, light-box, glass-sphere; the hard-visibility
    /// ajar-door-thick, light-box-thick, deep-shaft). Default: the built-in Cornell box.
    pub scene: Option<String>,
    /// Rendering mode.
    #[arg(long, value_enum, default_value_t = Mode::Mir)]
    pub mode: Mode,
    /// Samples per pixel (pt, bdpt) or independent VPL sets accumulated (ir, mir); default 64
    /// when no --time is given.
    #[arg(long, conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Render progressively for this many seconds instead of a fixed sample count.
    #[arg(long, allow_hyphen_values = true)]
    pub time: Option<f64>,
    /// Seed of every random stream: the same seed gives the same image at any thread count.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Maximum number of scattering events per path (Russian roulette ends most paths earlier).
    #[arg(long, default_value_t = 128)]
    pub max_depth: u32,
    /// Pixel reconstruction filter (offline modes).
    #[arg(long, value_enum, default_value_t = FilterArg::Box)]
    pub pixel_filter: FilterArg,
    /// VPL sampler (default: sir for --mode ir, mtmh for --mode mir).
    #[arg(long, value_enum)]
    pub vpl_sampler: Option<VplSamplerArg>,
    /// The Metropolis samplers' flags (mir).
    #[command(flatten)]
    pub mir: MirArgs,
    /// The VPL frame pipeline's flags (ir, mir).
    #[command(flatten)]
    pub gather: GatherArgs,
    /// pssmlt: independent Markov chains (the count, not the thread count, fixes the image).
    #[arg(long, default_value_t = crate::offline::pssmlt::PssmltSettings::default().chains)]
    pub mlt_chains: usize,
    /// pssmlt: independent paths that estimate the image's brightness (the normalisation b)
    /// and from which the chains start, chosen ∝ their contribution.
    #[arg(long, default_value_t = crate::offline::pssmlt::PssmltSettings::default().bootstrap)]
    pub bootstrap: usize,
    /// pssmlt: probability of a large step (every random number drawn anew).
    #[arg(long, default_value_t = crate::offline::pssmlt::PssmltSettings::default().large_step)]
    pub large_step: f32,
    /// pssmlt: standard deviation of a small step of each random number.
    #[arg(long, default_value_t = crate::offline::pssmlt::PssmltSettings::default().sigma)]
    pub sigma: f32,
    /// Also write albedo, normal and depth layers into the EXR.
    #[arg(long)]
    pub aov: bool,
    /// Tone mapping for the PNG (the EXR is the linear measurement).
    #[arg(long, value_enum, default_value_t = TonemapArg::Filmic)]
    pub tonemap: TonemapArg,
    /// Exposure in stops: added to the filmic operator's automatic exposure, or the linear
    /// scale 2^stops of `--tonemap exposure`.
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f32>,
    /// Output EXR path; a PNG is written beside it. Default: out/<scene>-<mode>.exr.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// bdpt only: also write the weighted and the unweighted image of strategy "s,t" alone
    /// (s light vertices, t camera vertices), for diagnosing MIS.
    #[arg(long, value_parser = parse_strategy)]
    pub debug_strategy: Option<(usize, usize)>,
    /// Do not show a progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Camera settings.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Lights added to the scene.
    #[command(flatten)]
    pub lights: LightArgs,
}

/// A command-line value that makes no sense, with the flag it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct OptionsError(pub String);

impl std::fmt::Display for OptionsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for OptionsError {}

/// Validated settings of a render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Mode.
    pub mode: Mode,
    /// Settings of the offline estimators.
    pub offline: OfflineSettings,
    /// PNG tone mapping.
    pub tonemap: Tonemap,
    /// bdpt: the strategy to write alone as well.
    pub debug_strategy: Option<(usize, usize)>,
    /// ir / mir: the VPL sampler.
    pub vpl_sampler: VplSamplerArg,
    /// ir / mir: sampler settings.
    pub sampler: SamplerConfig,
    /// ir: the frame pipeline settings.
    pub frame: crate::frame::FrameSettings,
    /// ir / mir: the discontinuity buffer's fade constant ([`crate::frame::Accumulation`]).
    pub filter_fade: Option<u32>,
    /// pssmlt: the chains' settings.
    pub pssmlt: crate::offline::pssmlt::PssmltSettings,
}

impl RenderArgs {
    /// Checks the numeric flags and builds the options.
    pub fn options(&self) -> Result<RenderOptions, OptionsError> {
        let budget = match (self.spp, self.time) {
            (Some(0), _) => return Err(OptionsError("--spp must be at least 1".into())),
            (Some(n), _) if n > 1 << 24 => {
                return Err(OptionsError(format!("--spp {n} is absurdly large (max 16777216)")));
            }
            (Some(n), _) => Budget::Samples(n),
            (None, Some(t)) if !(t > 0.0 && t.is_finite() && t < 1e7) => {
                return Err(OptionsError(format!("--time {t} must be a positive number of seconds")));
            }
            (None, Some(t)) => Budget::Time(Duration::from_secs_f64(t)),
            (None, None) => Budget::Samples(64),
        };
        if self.max_depth > 100_000 {
            return Err(OptionsError(format!("--max-depth {} is absurdly large (max 100000)", self.max_depth)));
        }
        if let Some(t) = self.threads
            && t == 0
        {
            return Err(OptionsError("--threads must be at least 1".into()));
        }
        if let Some(e) = self.exposure
            && !e.is_finite()
        {
            return Err(OptionsError("--exposure must be finite".into()));
        }
        for (flag, v) in [("--width", self.camera.width), ("--height", self.camera.height)] {
            if let Some(v) = v
                && !(1..=16384).contains(&v)
            {
                return Err(OptionsError(format!("{flag} {v} is outside 1…16384")));
            }
        }
        self.gather.validate().map_err(OptionsError)?;
        self.lights.validate().map_err(OptionsError)?;
        let vpl_sampler = match (self.mode, self.vpl_sampler) {
            (Mode::Mir, None) => VplSamplerArg::Mtmh,
            (_, None) => VplSamplerArg::Sir,
            (Mode::Mir, Some(s)) if !s.is_metropolis() => {
                return Err(OptionsError(format!(
                    "--mode mir takes --vpl-sampler mh or mtmh; use --mode ir for {}",
                    s.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_default()
                )));
            }
            (_, Some(s)) => s,
        };
        self.mir.validate().map_err(OptionsError)?;
        if self.debug_strategy.is_some() && self.mode != Mode::Bdpt {
            return Err(OptionsError("--debug-strategy needs --mode bdpt".into()));
        }
        if let Some((s, t)) = self.debug_strategy
            && s + t - 2 > self.max_depth as usize
        {
            return Err(OptionsError(format!(
                "--debug-strategy {s},{t} is longer than --max-depth {}",
                self.max_depth
            )));
        }
        let pssmlt = crate::offline::pssmlt::PssmltSettings {
            chains: self.mlt_chains,
            bootstrap: self.bootstrap,
            large_step: self.large_step,
            sigma: self.sigma,
        };
        pssmlt.validate().map_err(OptionsError)?;
        let filter = match self.pixel_filter {
            FilterArg::Box => FilterKind::Box,
            FilterArg::Tent => FilterKind::Tent,
            FilterArg::Gaussian => FilterKind::Gaussian,
            FilterArg::Mitchell => FilterKind::Mitchell,
            FilterArg::Lanczos => FilterKind::Lanczos,
        };
        let tonemap = self.tonemap.with_exposure(self.exposure).map_err(OptionsError)?;
        Ok(RenderOptions {
            mode: self.mode,
            offline: OfflineSettings { budget, seed: self.seed, max_depth: self.max_depth, filter, aovs: self.aov },
            tonemap,
            debug_strategy: self.debug_strategy,
            vpl_sampler,
            sampler: self.mir.config(self.max_depth),
            frame: crate::frame::FrameSettings {
                max_specular: 8,
                compensate: self.gather.compensate_or(true),
                compensation_stride: self.gather.compensate_stride.unwrap_or(1),
                vpl_power: true,
                ..self.gather.frame_settings()
            },
            pssmlt,
            filter_fade: self.gather.filter_fade.constant(self.gather.interleave),
        })
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

/// Parses "s,t".
pub fn parse_strategy(v: &str) -> Result<(usize, usize), String> {
    let parts: Vec<&str> = v.split(',').collect();
    match parts.as_slice() {
        [s, t] => {
            let s: usize = s.trim().parse().map_err(|e| format!("'{v}': {e}"))?;
            let t: usize = t.trim().parse().map_err(|e| format!("'{v}': {e}"))?;
            if t == 0 || s + t < 2 {
                return Err(format!("'{v}': strategies need t ≥ 1 and s + t ≥ 2"));
            }
            Ok((s, t))
        }
        _ => Err(format!("'{v}' is not two integers s,t")),
    }
}

/// Parses "x,y,z".
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> =
        s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|e| format!("'{s}': {e}"))?;
    match v.as_slice() {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(format!("'{s}' is not three finite numbers x,y,z")),
    }
}

/// Parses "x,y".
pub fn parse_vec2(s: &str) -> Result<Vec2, String> {
    let v: Vec<f32> =
        s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|e| format!("'{s}': {e}"))?;
    match v.as_slice() {
        [x, y] if x.is_finite() && y.is_finite() => Ok(Vec2::new(*x, *y)),
        _ => Err(format!("'{s}' is not two finite numbers x,y")),
    }
}
