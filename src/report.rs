//! Measurement reports: error against a cached reference as a function of render time for
//! every mode (`mirage converge`), and the VPL-sampler comparison of papers/002 §7.3–7.5
//! (`mirage samplers`). Both write markdown (and an SVG plot for convergence) for
//! benches/results/.
//!
//! The reference of a scene is a long path-traced render, cached under `target/reference/`
//! and keyed by scene name, resolution and sample count, so reports re-run cheaply.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::progress::NoProgress;

use crate::accel::Accel;
use crate::film::Image;
use crate::frame::{self, FrameSettings};
use crate::offline::mlt::MltSettings;
use crate::offline::pssmlt::PssmltSettings;
use crate::offline::{self, Budget, OfflineSettings};
use crate::options::{KernelArg, Mode, RenderOptions, SamplerConfig, VplSamplerArg};
use crate::output;
use crate::render;
use crate::scene::Scene;

/// A rendering method in a report.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Path tracing.
    Pt,
    /// Bidirectional path tracing.
    Bdpt,
    /// Primary-sample-space MLT over the bidirectional sampler (its default settings).
    Pssmlt,
    /// Path-space MLT (its default settings).
    Mlt,
    /// Path-space MLT with the chains over every path (`--mlt-direct 0`).
    MltAllPaths,
    /// A VPL sampler with the frame pipeline (ir or mir).
    Vpl {
        /// The sampler.
        sampler: VplSamplerArg,
        /// Its settings.
        config: SamplerConfig,
        /// The clamp compensated (as `render` draws; suffix `-uncompensated` turns it off).
        compensate: bool,
        /// The discontinuity buffer: faded out over the frames as `render` does (default),
        /// throughout (suffix `-filtered`) or off (`-unfiltered`).
        filter: FilterUse,
    },
}

/// How a VPL method in a report uses the discontinuity buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterUse {
    /// Faded out as frames accumulate (`render`'s `--filter-fade auto`).
    Faded,
    /// Filtered throughout (`--filter-fade never`; the viewer's image).
    Always,
    /// Off (`--no-filter`).
    Off,
}

impl Method {
    /// Parses `pt`, `bdpt`, `sir`, `sir-cdf`, `bir`, `mh`, `mtmh`, with optional suffixes
    /// `-pss` (primary-sample-space kernel) and `-cdf` (light-source CDF) for mh / mtmh, then
    /// `-uncompensated` (the clamp left uncompensated) and `-unfiltered` (no discontinuity
    /// buffer) or `-filtered` (the buffer not faded out) for any VPL method, in that order.
    pub fn parse(s: &str) -> Result<Method, String> {
        let whole = s;
        let (s, filter) = if let Some(base) = s.strip_suffix("-unfiltered") {
            (base, FilterUse::Off)
        } else if let Some(base) = s.strip_suffix("-filtered") {
            (base, FilterUse::Always)
        } else {
            (s, FilterUse::Faded)
        };
        let (s, compensate) = match s.strip_suffix("-uncompensated") {
            Some(base) => (base, false),
            None => (s, true),
        };
        if !(compensate && filter == FilterUse::Faded)
            && matches!(s, "pt" | "bdpt" | "pssmlt" | "mlt" | "mlt-all-paths")
        {
            return Err(format!("'{whole}': -uncompensated, -filtered and -unfiltered apply to VPL methods only"));
        }
        let mut config = SamplerConfig::default();
        let sampler = match s {
            "pt" => return Ok(Method::Pt),
            "bdpt" => return Ok(Method::Bdpt),
            "pssmlt" => return Ok(Method::Pssmlt),
            "mlt" => return Ok(Method::Mlt),
            "mlt-all-paths" => return Ok(Method::MltAllPaths),
            "sir" => VplSamplerArg::Sir,
            "sir-cdf" => VplSamplerArg::SirCdf,
            "bir" => VplSamplerArg::Bir,
            other => {
                let mut parts = other.split('-');
                let base = match parts.next() {
                    Some("mh") => VplSamplerArg::Mh,
                    Some("mtmh") => VplSamplerArg::Mtmh,
                    _ => {
                        return Err(format!(
                            "unknown method '{s}' (pt, bdpt, pssmlt, mlt, sir, sir-cdf, bir, mh[-pss][-cdf], mtmh[-pss][-cdf])"
                        ));
                    }
                };
                for p in parts {
                    match p {
                        "pss" => config.kernel = KernelArg::Pss,
                        "bidir" => config.kernel = KernelArg::Bidir,
                        "cdf" => config.light_cdf = true,
                        _ => return Err(format!("unknown suffix '-{p}' in method '{s}'")),
                    }
                }
                base
            }
        };
        Ok(Method::Vpl { sampler, config, compensate, filter })
    }

    /// A label for tables.
    pub fn label(&self) -> String {
        match self {
            Method::Pt => "pt".into(),
            Method::Bdpt => "bdpt".into(),
            Method::Pssmlt => "pssmlt".into(),
            Method::Mlt => "mlt".into(),
            Method::MltAllPaths => "mlt-all-paths".into(),
            Method::Vpl { sampler, config, compensate, filter } => {
                let mut l = sampler.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_default();
                if sampler.is_metropolis() {
                    l += if config.kernel == KernelArg::Pss { "-pss" } else { "-bidir" };
                    if config.light_cdf {
                        l += "-cdf";
                    }
                }
                if !compensate {
                    l += "-uncompensated";
                }
                match filter {
                    FilterUse::Faded => {}
                    FilterUse::Always => l += "-filtered",
                    FilterUse::Off => l += "-unfiltered",
                }
                l
            }
        }
    }
}

use clap::ValueEnum as _;

/// What one timed render produced.
#[derive(Clone, Debug)]
pub struct Run {
    /// The image.
    pub image: Image,
    /// Wall-clock time.
    pub elapsed: Duration,
    /// Samples per pixel (pt, bdpt) or frames (VPL methods).
    pub passes: u32,
    /// Metropolis acceptance rate, when the method has one.
    pub acceptance: Option<f64>,
}

/// Renders `scene` with `method` under `budget`, through [`crate::render::render`] (the mode's
/// flow as `mirage render` runs it).
pub fn run(
    scene: &Scene,
    accel: &Accel,
    method: &Method,
    budget: Budget,
    seed: u64,
    frame_settings: &FrameSettings,
) -> Run {
    let mut options = RenderOptions {
        mode: Mode::Pt,
        offline: OfflineSettings { budget, seed, ..OfflineSettings::preview() },
        tonemap: Default::default(),
        debug_strategy: None,
        vpl_sampler: VplSamplerArg::Sir,
        sampler: SamplerConfig::default(),
        frame: *frame_settings,
        filter_fade: None,
        pssmlt: PssmltSettings::default(),
        mlt: MltSettings::default(),
    };
    match method {
        Method::Pt => options.mode = Mode::Pt,
        Method::Bdpt => options.mode = Mode::Bdpt,
        Method::Pssmlt => options.mode = Mode::Pssmlt,
        Method::Mlt => options.mode = Mode::Mlt,
        Method::MltAllPaths => {
            options.mode = Mode::Mlt;
            options.mlt.direct = 0;
        }
        Method::Vpl { sampler, config, compensate, filter } => {
            options.mode = if sampler.is_metropolis() { Mode::Mir } else { Mode::Ir };
            (options.vpl_sampler, options.sampler) = (*sampler, *config);
            options.filter_fade =
                (*filter == FilterUse::Faded).then(|| frame_settings.interleave.0 * frame_settings.interleave.1);
            options.frame = FrameSettings {
                compensate: frame_settings.compensate && *compensate,
                filter: frame_settings.filter.filter(|_| *filter != FilterUse::Off),
                ..*frame_settings
            };
        }
    }
    let r = render::render(scene, accel, &options, &NoProgress);
    let acceptance = match (&r.frame, &r.pssmlt, &r.mlt) {
        (Some(st), _, _) => st.sampler.acceptance_rate(),
        (_, Some(st), _) => {
            let (p, a) = (st.large.0 + st.small.0, st.large.1 + st.small.1);
            (p > 0).then(|| a as f64 / p as f64)
        }
        (_, _, Some(st)) => st.acceptance(),
        _ => None,
    };
    Run { image: r.out.film.image(), elapsed: r.out.elapsed, passes: r.out.spp, acceptance }
}

/// A path-traced reference made of two independent halves, so that its own noise is known.
///
/// With r = (r₁ + r₂)/2 and the halves independent and equally sampled, Var(r) = E[(r₁ − r₂)²]/4
/// per pixel; and for an image x independent of r, E[(x − r)²] = E[(x − μ)²] + Var(r), μ the
/// true image. So `mse − noise_mse` estimates x's own error without bias however noisy r is: a
/// 4096-spp pt reference of the deep shaft has nMSE ≈ 2.4 of its own, which otherwise hides every
/// method's error below it.
#[derive(Clone, Debug)]
pub struct Reference {
    /// The mean of the two halves.
    pub image: Image,
    /// Mean over pixels and channels of (r₁ − r₂)² / 4: the reference's own variance.
    pub noise_mse: f64,
}

impl Reference {
    /// The reference of two independent halves.
    pub fn from_halves(a: &Image, b: &Image) -> Reference {
        assert_eq!((a.width, a.height), (b.width, b.height), "reference halves differ in size");
        let data = a.data.iter().zip(&b.data).map(|(p, q)| (*p + *q) * 0.5).collect();
        let image = Image { width: a.width, height: a.height, data };
        // (r₁ − r₂)² / 4 is the squared error of r₁ against r: the MSE of one half against the mean.
        let noise_mse = a.errors(&image).mse;
        Reference { image, noise_mse }
    }
}

/// The cached path-traced reference of `name` at the scene camera's resolution: two halves of
/// `spp / 2` samples each (seeds 0x5eed and 0x5eee), cached separately.
pub fn reference(
    scene: &Scene,
    accel: &Accel,
    name: &str,
    spp: u32,
    dir: &Path,
) -> Result<Reference, output::SaveError> {
    let c = &scene.camera;
    let half_spp = (spp / 2).max(1);
    let mut halves = Vec::with_capacity(2);
    for (k, seed) in [(1, 0x5eed), (2, 0x5eee)] {
        let path = dir.join(format!("{name}-{}x{}-pt{spp}-half{k}.exr", c.width, c.height));
        if let Ok(img) = output::read_exr(&path)
            && (img.width, img.height) == (c.width, c.height)
        {
            halves.push(img);
            continue;
        }
        std::fs::create_dir_all(dir)
            .map_err(|e| output::SaveError { path: dir.to_path_buf(), message: e.to_string() })?;
        let settings = OfflineSettings { budget: Budget::Samples(half_spp), seed, ..OfflineSettings::preview() };
        let img = offline::render_pt(scene, accel, &settings, &NoProgress).film.image();
        output::write_exr(&path, &img, Default::default())?;
        halves.push(img);
    }
    Ok(Reference::from_halves(&halves[0], &halves[1]))
}

/// Default reference cache directory.
pub fn reference_dir() -> PathBuf {
    PathBuf::from("target").join("reference")
}

/// The error a convergence report measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Metric {
    /// Mean of (x − r)² / (r² + 0.01) over pixels and channels: the constant keeps black pixels
    /// finite, and dominates where the image is darker than 0.1.
    Relmse,
    /// MSE / m², m the reference's mean luminance: independent of exposure, so dark scenes are
    /// compared too, and a noisy reference adds the same constant to every method.
    Nmse,
    /// (MSE − the reference's own variance) / m²: the nMSE the image has against the true image,
    /// estimated without bias from a reference of any noise ([`Reference::noise_mse`]). It can
    /// come out below zero when the image is closer to the truth than the reference's noise
    /// resolves.
    NmseExcess,
}

impl Metric {
    /// This metric's value for the errors `e` of an image against `reference`.
    pub fn of(self, e: &crate::film::ImageErrors, reference: &Reference) -> f64 {
        match self {
            Metric::Relmse => e.rel_mse,
            Metric::Nmse => e.nmse,
            Metric::NmseExcess => {
                let m = reference.image.mean_luminance();
                let m2 = if m > 0.0 { m * m } else { 1.0 };
                (e.mse - reference.noise_mse) / m2
            }
        }
    }

    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Relmse => "relMSE",
            Metric::Nmse => "nMSE",
            Metric::NmseExcess => "excess nMSE",
        }
    }

    /// Its definition, for a report's header.
    pub fn definition(self) -> &'static str {
        match self {
            Metric::Relmse => "relMSE = mean over pixels and channels of (x − r)² / (r² + 0.01)",
            Metric::Nmse => {
                "nMSE = mean over pixels and channels of (x − r)², divided by m², m the reference's mean luminance (the MSE of both images scaled to mean 1: it does not depend on exposure; the reference's own noise adds the same Var(r)/m² to every method)"
            }
            Metric::NmseExcess => {
                "excess nMSE = (mean over pixels and channels of (x − r)² − V) / m², m the reference's mean luminance and V the reference's own variance, measured from its two independent halves r₁, r₂ as the mean of (r₁ − r₂)²/4: an unbiased estimate of the image's nMSE against the true image however noisy the reference (E[(x − r)²] = E[(x − μ)²] + Var(r)); it can be negative when the error is below what the reference resolves"
            }
        }
    }
}

/// One row of a convergence report.
#[derive(Clone, Debug)]
pub struct ConvergeRow {
    /// Scene name.
    pub scene: String,
    /// Method label.
    pub method: String,
    /// Time budget, seconds.
    pub budget: f64,
    /// Time actually spent.
    pub elapsed: f64,
    /// Samples per pixel or frames.
    pub passes: u32,
    /// The error against the reference in the report's metric (the median over the runs).
    pub error: f64,
    /// Lowest and highest error over the runs, when there was more than one.
    pub range: Option<(f64, f64)>,
}

/// The error (in `metric`) of every method at every time budget, from `seeds` independent runs
/// each (seeds 1..=`seeds`): the median, and the range when there is more than one run.
#[allow(clippy::too_many_arguments)]
pub fn converge(
    scene: &Scene,
    accel: &Accel,
    name: &str,
    methods: &[Method],
    times: &[f64],
    seeds: u32,
    reference: &Reference,
    frame_settings: &FrameSettings,
    metric: Metric,
    progress: &dyn Fn(&str),
) -> Vec<ConvergeRow> {
    let mut rows = Vec::new();
    for m in methods {
        for &t in times {
            progress(&format!("{name}: {} for {t} s ({} run(s))", m.label(), seeds.max(1)));
            let mut runs: Vec<(f64, f64, u32)> = (1..=seeds.max(1) as u64)
                .map(|seed| {
                    let r = run(scene, accel, m, Budget::Time(Duration::from_secs_f64(t)), seed, frame_settings);
                    (metric.of(&r.image.errors(&reference.image), reference), r.elapsed.as_secs_f64(), r.passes)
                })
                .collect();
            runs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (error, elapsed, passes) = runs[runs.len() / 2];
            let range = (runs.len() > 1).then(|| (runs[0].0, runs[runs.len() - 1].0));
            rows.push(ConvergeRow {
                scene: name.to_string(),
                method: m.label(),
                budget: t,
                elapsed,
                passes,
                error,
                range,
            });
        }
    }
    rows
}

/// Markdown table of convergence rows: one line per (scene, method), one column per budget.
pub fn converge_markdown(rows: &[ConvergeRow], times: &[f64]) -> String {
    let mut s = String::new();
    let _ = write!(s, "| scene | method |");
    for t in times {
        let _ = write!(s, " {t} s |");
    }
    s.push('\n');
    let _ = write!(s, "|---|---|");
    for _ in times {
        s.push_str("--:|");
    }
    s.push('\n');
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in rows {
        let k = (r.scene.clone(), r.method.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (scene, method) in keys {
        let _ = write!(s, "| {scene} | {method} |");
        for t in times {
            match rows.iter().find(|r| r.scene == scene && r.method == method && r.budget == *t) {
                Some(r) => match r.range {
                    Some((lo, hi)) => {
                        let _ = write!(s, " {:.4} [{lo:.4}–{hi:.4}] ({}) |", r.error, r.passes);
                    }
                    None => {
                        let _ = write!(s, " {:.4} ({}) |", r.error, r.passes);
                    }
                },
                None => s.push_str(" – |"),
            }
        }
        s.push('\n');
    }
    s
}

/// An SVG plot of the error (in `metric`) against time (log–log), one line per method, for one
/// scene.
pub fn converge_svg(rows: &[ConvergeRow], scene: &str, metric: Metric) -> String {
    let rows: Vec<&ConvergeRow> = rows.iter().filter(|r| r.scene == scene && r.error > 0.0).collect();
    let (w, h, pad) = (640.0, 400.0, 60.0);
    let lx = |t: f64| t.max(1e-3).log10();
    let (tmin, tmax) = rows.iter().fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(lx(r.elapsed)), b.max(lx(r.elapsed))));
    let (emin, emax) =
        rows.iter().fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.error.log10()), b.max(r.error.log10())));
    let (tmin, tmax) = (tmin.floor(), tmax.ceil().max(tmin.floor() + 1.0));
    let (emin, emax) = (emin.floor(), emax.ceil().max(emin.floor() + 1.0));
    let px = |t: f64| pad + (lx(t) - tmin) / (tmax - tmin) * (w - 2.0 * pad);
    let py = |e: f64| h - pad - (e.log10() - emin) / (emax - emin) * (h - 2.0 * pad);
    let colors = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#17becf"];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{}\" y=\"20\" text-anchor=\"middle\">{scene}: {} vs render time (log–log)</text>\n",
        w / 2.0,
        metric.name()
    );
    let _ =
        writeln!(s, "<line x1=\"{pad}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>", h - pad, w - pad, h - pad);
    let _ = writeln!(s, "<line x1=\"{pad}\" y1=\"{pad}\" x2=\"{pad}\" y2=\"{}\" stroke=\"black\"/>", h - pad);
    for d in tmin as i32..=tmax as i32 {
        let x = pad + (d as f64 - tmin) / (tmax - tmin) * (w - 2.0 * pad);
        let _ =
            writeln!(s, "<text x=\"{x}\" y=\"{}\" text-anchor=\"middle\">{} s</text>", h - pad + 18.0, 10f64.powi(d));
    }
    for d in emin as i32..=emax as i32 {
        let y = h - pad - (d as f64 - emin) / (emax - emin) * (h - 2.0 * pad);
        let _ = writeln!(s, "<text x=\"{}\" y=\"{y}\" text-anchor=\"end\">1e{d}</text>", pad - 6.0);
    }
    let mut methods: Vec<&str> = Vec::new();
    for r in &rows {
        if !methods.contains(&r.method.as_str()) {
            methods.push(&r.method);
        }
    }
    for (i, m) in methods.iter().enumerate() {
        let c = colors[i % colors.len()];
        let pts: Vec<String> = rows
            .iter()
            .filter(|r| r.method == *m)
            .map(|r| format!("{:.1},{:.1}", px(r.elapsed), py(r.error)))
            .collect();
        let _ = writeln!(s, "<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"2\" points=\"{}\"/>", pts.join(" "));
        let _ =
            writeln!(s, "<text x=\"{}\" y=\"{}\" fill=\"{c}\">{m}</text>", w - pad + 4.0 - 60.0, pad + 16.0 * i as f64);
    }
    s.push_str("</svg>\n");
    s
}

/// One row of the VPL-sampler comparison.
#[derive(Clone, Debug)]
pub struct SamplerRow {
    /// Scene name.
    pub scene: String,
    /// Sampler label.
    pub sampler: String,
    /// VPLs requested.
    pub m: usize,
    /// Mean VPL generation time per set, milliseconds.
    pub time_ms: f64,
    /// VPLs produced (mean).
    pub vpls: f64,
    /// Rejection rate of a Metropolis sampler.
    pub rejection: Option<f64>,
    /// Mean relMSE of single-frame images against the reference.
    pub rel_mse: f64,
}

/// Generation time, rejection rate and single-frame relMSE for `sampler` with m VPLs, mean
/// over `frames` independent frames (fresh sampler state each).
pub fn sampler_row(
    scene: &Scene,
    accel: &Accel,
    name: &str,
    method: &Method,
    m: usize,
    frames: u32,
    reference: &Image,
    frame_settings: &FrameSettings,
) -> SamplerRow {
    let Method::Vpl { sampler, config, compensate, filter } = method else { panic!("sampler rows need a VPL method") };
    let settings = FrameSettings {
        vpls: m,
        compensate: frame_settings.compensate && *compensate,
        filter: frame_settings.filter.filter(|_| *filter != FilterUse::Off),
        ..*frame_settings
    };
    let (mut time, mut vpls, mut rel, mut acc, mut prop) = (0.0, 0.0, 0.0, 0u64, 0u64);
    for f in 0..frames {
        let mut s = sampler.build_with(config);
        let t = Instant::now();
        let fr = frame::render_frame(scene, accel, &scene.camera, s.as_mut(), &settings, 1000 + f as u64);
        let _ = t;
        time += fr.stats.vpl_time.as_secs_f64() * 1e3;
        vpls += fr.vpls.len() as f64;
        acc += fr.stats.sampler.accepted;
        prop += fr.stats.sampler.proposed;
        let img = Image { width: scene.camera.width, height: scene.camera.height, data: fr.image };
        rel += img.errors(reference).rel_mse;
    }
    let n = frames.max(1) as f64;
    SamplerRow {
        scene: name.to_string(),
        sampler: method.label(),
        m,
        time_ms: time / n,
        vpls: vpls / n,
        rejection: (prop > 0).then(|| 1.0 - acc as f64 / prop as f64),
        rel_mse: rel / n,
    }
}

/// Markdown table of sampler rows.
pub fn sampler_markdown(rows: &[SamplerRow]) -> String {
    let mut s = String::from(
        "| scene | sampler | m | VPL time (ms) | VPLs | rejection | relMSE (1 frame) |\n|---|---|--:|--:|--:|--:|--:|\n",
    );
    for r in rows {
        let rej = r.rejection.map(|x| format!("{:.1} %", 100.0 * x)).unwrap_or_else(|| "–".into());
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.0} | {} | {:.4} |",
            r.scene, r.sampler, r.m, r.time_ms, r.vpls, rej, r.rel_mse
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Several runs per cell: the median run's relMSE and passes, with the range over the runs;
    /// one run: the value alone.
    #[test]
    fn converge_table_gives_the_median_and_the_range_of_several_runs() {
        let row = |method: &str, budget: f64, error: f64, range| ConvergeRow {
            scene: "s".into(),
            method: method.into(),
            budget,
            elapsed: budget,
            passes: 7,
            error,
            range,
        };
        let rows = vec![row("mtmh", 1.0, 0.02, Some((0.01, 0.5))), row("sir", 1.0, 0.03, None)];
        let md = converge_markdown(&rows, &[1.0]);
        assert!(md.contains("| s | mtmh | 0.0200 [0.0100–0.5000] (7) |"), "{md}");
        assert!(md.contains("| s | sir | 0.0300 (7) |"), "{md}");
    }

    /// The excess nMSE removes the reference's own noise: an image whose true error is known
    /// (uniform noise of variance σ² = 1/12 around μ = 1) measured against references of very
    /// different noise gives σ²/μ² within the estimate's sampling spread, while plain nMSE grows
    /// with the reference's noise. A metric that ignored the halves' difference fails this.
    #[test]
    fn excess_nmse_is_the_error_against_the_true_image_whatever_the_reference_noise() {
        use crate::sampling::Pcg32;
        use glam::Vec3;
        let (w, h) = (256u32, 256u32);
        let noisy = |rng: &mut Pcg32, amp: f32| Image {
            width: w,
            height: h,
            data: (0..w * h)
                .map(|_| Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * amp + Vec3::ONE)
                .collect(),
        };
        let mut rng = Pcg32::new(7);
        let x = noisy(&mut rng, 1.0);
        let truth = 1.0 / 12.0;
        // 3·w·h samples of (x − μ)² (variance 1/180 each) and of the halves' noise.
        for amp in [0.0f32, 1.0, 4.0] {
            let r = Reference::from_halves(&noisy(&mut rng, amp), &noisy(&mut rng, amp));
            let e = x.errors(&r.image);
            let excess = Metric::NmseExcess.of(&e, &r);
            let ref_var = (amp * amp / 12.0 / 2.0) as f64;
            let n = 3.0 * (w * h) as f64;
            // Spread: (x − r)² and the halves' (r₁ − r₂)²/4 each have a variance ≈ 2 (σ² + Var r)² per sample.
            let sd = (2.0 * (truth + ref_var).powi(2) * 2.0 / n).sqrt();
            assert!((excess - truth).abs() < 5.0 * sd, "amp {amp}: excess {excess} vs {truth} (sd {sd})");
            assert!((r.noise_mse - ref_var).abs() < 5.0 * sd + 1e-9, "amp {amp}: noise {} vs {ref_var}", r.noise_mse);
            assert!((Metric::Nmse.of(&e, &r) - (truth + ref_var)).abs() < 5.0 * sd);
        }
    }

    #[test]
    fn methods_parse_with_their_suffixes_and_label_back() {
        for m in [
            "pt",
            "bdpt",
            "pssmlt",
            "mlt",
            "mlt-all-paths",
            "sir",
            "sir-uncompensated",
            "sir-unfiltered",
            "mtmh-filtered",
            "mtmh-bidir",
            "mtmh-pss-cdf-uncompensated-unfiltered",
            "mh-pss",
        ] {
            let label = Method::parse(m).unwrap().label();
            assert_eq!(Method::parse(&label).unwrap(), Method::parse(m).unwrap(), "{m} → {label}");
        }
        assert!(matches!(Method::parse("sir-uncompensated"), Ok(Method::Vpl { compensate: false, .. })));
        assert!(Method::parse("pt-uncompensated").unwrap_err().contains("VPL methods only"));
        assert!(Method::parse("bdpt-unfiltered").unwrap_err().contains("VPL methods only"));
        assert!(matches!(
            Method::parse("mtmh-unfiltered"),
            Ok(Method::Vpl { filter: FilterUse::Off, compensate: true, .. })
        ));
        assert!(matches!(Method::parse("sir-filtered"), Ok(Method::Vpl { filter: FilterUse::Always, .. })));
        assert!(Method::parse("mtmh-foo").is_err());
    }
}
