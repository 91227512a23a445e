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
use crate::sampling::PixelSamplerKind;
use crate::scene::CameraSettings;

mod vpl;

pub use vpl::{
    FilterFade, GatherArgs, KernelArg, MirArgs, RaysArg, SamplerConfig, Switch, VplSamplerArg, parse_filter_fade,
    parse_interleave,
};

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
    /// Path-space Metropolis light transport (Veach & Guibas 1997): chains over complete paths
    /// with the bidirectional mutation, the lens, caustic and multi-chain perturbations and the
    /// lens sub-path mutation (--mutations),
    /// started without bias from a bidirectional bootstrap (--mlt-chains, --bootstrap). For
    /// caustics and light through slits and holes. Not with lights at infinity.
    Mlt,
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
            Mode::Mlt => "mlt",
        }
    }
}

/// The offline modes' per-pixel numbers as command-line values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SamplerArg {
    /// Owen-scrambled Sobol, padded per draw (default): stratified pixel positions, light
    /// points and first-bounce directions; same expectation, lower variance.
    Sobol,
    /// Independent uniform numbers (a hashed PCG32 stream per pixel sample).
    Independent,
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
    /// The numbers pt and bdpt draw per pixel sample.
    #[arg(long, value_enum, default_value_t = SamplerArg::Sobol)]
    pub sampler: SamplerArg,
    /// VPL sampler (default: sir for --mode ir, mtmh for --mode mir).
    #[arg(long, value_enum)]
    pub vpl_sampler: Option<VplSamplerArg>,
    /// The Metropolis samplers' flags (mir).
    #[command(flatten)]
    pub mir: MirArgs,
    /// The VPL frame pipeline's flags (ir, mir).
    #[command(flatten)]
    pub gather: GatherArgs,
    /// mlt: the mutation types, comma-separated: bidir (bidirectional: delete and regrow part of
    /// the path), lens (move the image point, keep the specular chain), caustic (turn the
    /// direction into a specular chain), multichain (move the image point and turn the
    /// direction at each diffuse vertex before a specular chain), subpath (lens sub-path: a new
    /// camera ray from a rover that stratifies the chains over the pixels, the same specular
    /// bounces, joined to the kept light end; off by default: at its share it cost accuracy on
    /// the slit and the glass sphere). The bidirectional mutation takes --bidir-share of the
    /// proposals, the others that apply to the path share the rest.
    #[arg(long, default_value = "bidir,lens,caustic,multichain")]
    pub mutations: String,
    /// mlt: probability of the bidirectional mutation (the other types in use that apply to the
    /// path share the rest). More helps where the light comes through holes (the perturbations
    /// fail there), less where lens perturbations can follow it (a slit).
    #[arg(long, default_value_t = crate::offline::mlt::MltSettings::default().bidir_share)]
    pub bidir_share: f64,
    /// mlt, pssmlt: path-traced samples per pixel and pass for the direct part, which the
    /// chains then leave to it, so that they spend their mutations on indirect light and
    /// caustics; 0: the chains take every path. mlt's direct part: lights and directly lit
    /// surfaces, seen directly or through mirrors and glass, and paths no connection can make,
    /// which no mutation could move; pssmlt's: the paths of depth 0 and 1 (lights seen directly
    /// and direct lighting). Default: 1 for mlt; for pssmlt 1 when a quick path-traced estimate
    /// puts at least a fifth of the light in depths 0–1, else 0 (the split cuts the Cornell
    /// box's error 45× and raises the thick-walled slit's 1.8×:
    /// benches/results/2026-12-07-pssmlt-direct.md).
    #[arg(long)]
    pub mlt_direct: Option<u32>,
    /// pssmlt, mlt: independent Markov chains (the count, not the thread count, fixes the image).
    #[arg(long, default_value_t = crate::offline::pssmlt::PssmltSettings::default().chains)]
    pub mlt_chains: usize,
    /// pssmlt, mlt: independent paths that estimate the image's brightness (the normalisation b)
    /// and from which the chains start, chosen ∝ their contribution. pssmlt draws more (up to
    /// 16×) where a pilot finds that fewer than four a chain would reach the camera.
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
    /// mlt: the chains' settings.
    pub mlt: crate::offline::mlt::MltSettings,
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
            direct: self.mlt_direct,
        };
        pssmlt.validate().map_err(OptionsError)?;
        if !(self.bidir_share > 0.0 && self.bidir_share <= 1.0) {
            return Err(OptionsError(format!("--bidir-share {} must be in (0, 1]", self.bidir_share)));
        }
        let mlt = crate::offline::mlt::MltSettings {
            chains: self.mlt_chains,
            bootstrap: self.bootstrap,
            mutations: crate::offline::mlt::MutationKind::parse_list(&self.mutations).map_err(OptionsError)?,
            direct: self.mlt_direct.unwrap_or(crate::offline::mlt::MltSettings::default().direct),
            bidir_share: self.bidir_share,
        };
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
            offline: OfflineSettings {
                budget,
                seed: self.seed,
                max_depth: self.max_depth,
                filter,
                aovs: self.aov,
                sampler: match self.sampler {
                    SamplerArg::Sobol => PixelSamplerKind::Sobol,
                    SamplerArg::Independent => PixelSamplerKind::Independent,
                },
            },
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
            mlt,
            filter_fade: self.gather.filter_fade.constant(self.gather.interleave),
        })
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

#[cfg(test)]
mod tests {
    use super::RenderArgs;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        render: RenderArgs,
    }

    /// The flags' defaults give the library's default MLT settings (the `--mutations` string
    /// and `MltSettings::default` name the same types).
    #[test]
    fn the_mlt_flags_default_to_the_librarys_settings() {
        let options = Wrapper::parse_from(["mirage"]).render.options().unwrap();
        assert_eq!(options.mlt, crate::offline::mlt::MltSettings::default());
    }
}
