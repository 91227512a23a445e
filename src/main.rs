//! The `mirage` command line: `render`, `view`, `info`, `converge`, `samplers`, `png` and `diff`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

/// `println!` for the command's results: a closed stdout (`mirage info S | head -1`) ends the
/// process quietly instead of panicking, as other command-line tools do; any other write error
/// is reported and exits non-zero.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            eprintln!("mirage: cannot write to stdout: {e}");
            std::process::exit(1);
        }
    }};
}

use mirage::accel::Accel;
use mirage::color::luminance;
use mirage::options::RenderArgs;
use mirage::output::{self, Aovs};
use mirage::render::{self, SceneSource};
use mirage::scene::{CameraSettings, Light};

/// mirage: a physically based CPU renderer for diffuse scenes (Metropolis Instant Radiosity,
/// path tracing). Images are linear HDR EXR (float32) plus a tone-mapped PNG.
#[derive(Parser, Debug)]
#[command(name = "mirage", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render an image to EXR and PNG.
    Render(Box<RenderArgs>),
    /// Walk through a scene in a window (MIR + packet gather every frame), or run the same frame
    /// loop headless for benchmarks.
    View(Box<mirage::view::ViewArgs>),
    /// Describe a scene: triangles, emitters and their power, bounds, camera.
    Info {
        /// Scene file or built-in scene name (default: the built-in Cornell box).
        scene: Option<String>,
        /// Lights added to the scene (as in `render`).
        #[command(flatten)]
        lights: mirage::options::LightArgs,
    },
    /// Error-vs-time report: relMSE against a cached path-traced reference after each time
    /// budget, for every method; writes markdown and an SVG plot per scene.
    Converge(ReportArgs),
    /// VPL-sampler report (papers/002 §7.3–7.5): generation time, rejection rate and
    /// single-frame relMSE of every strategy, same gather and clamp for all.
    Samplers(ReportArgs),
    /// Tone-map an EXR into a PNG with the operators of `render` (to look at two images at the
    /// same exposure: `--tonemap exposure --exposure S`).
    Png {
        /// Input EXR.
        input: PathBuf,
        /// Output PNG (default: the input with extension .png).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Tone mapping.
        #[arg(long, value_enum, default_value_t = mirage::options::TonemapArg::Filmic)]
        tonemap: mirage::options::TonemapArg,
        /// Exposure in stops (filmic: added to the automatic exposure; exposure: 2^stops).
        #[arg(long, allow_hyphen_values = true)]
        exposure: Option<f32>,
    },
    /// Compare two EXR images: MSE, relMSE (mean of (a−b)²/(b²+0.01)), nMSE (MSE / m², m = B's
    /// mean luminance), mean bias; B is the reference.
    Diff {
        /// Test image.
        a: PathBuf,
        /// Reference image.
        b: PathBuf,
        /// Also write each pixel's squared error over m² (its share of nMSE, mean of the three
        /// channels) as an EXR, to see where an error comes from.
        #[arg(long, value_name = "EXR")]
        map: Option<PathBuf>,
    },
}

/// Flags of the report subcommands.
#[derive(clap::Args, Debug)]
struct ReportArgs {
    /// Scenes (files or built-in names).
    #[arg(long, value_delimiter = ',', default_value = "cornell,ajar-door,left-right,direct-indirect,light-box")]
    scenes: Vec<String>,
    /// Methods: pt, bdpt, pssmlt, mlt, mlt-all-paths (mlt with --mlt-direct 0), sir, sir-cdf, bir, mh, mtmh (with -pss / -cdf suffixes for mh, mtmh, and a
    /// final -uncompensated for any VPL method: its clamp not compensated).
    #[arg(long, value_delimiter = ',', default_value = "pt,bdpt,sir,bir,mtmh")]
    methods: Vec<String>,
    /// Time budgets in seconds (converge).
    #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1,2,4")]
    times: Vec<f64>,
    /// VPL counts (samplers).
    #[arg(long, value_delimiter = ',', default_value = "256,1024")]
    vpls: Vec<usize>,
    /// Frames averaged per sampler row (samplers).
    #[arg(long, default_value_t = 4)]
    frames: u32,
    /// Image width.
    #[arg(long, default_value_t = 256)]
    width: u32,
    /// Image height.
    #[arg(long, default_value_t = 192)]
    height: u32,
    /// Samples per pixel of the cached path-traced references (target/reference/).
    #[arg(long, default_value_t = 4096)]
    reference_spp: u32,
    /// Independent runs (seeds 1..=K) per method and budget (converge): the table gives the
    /// median relMSE and its range over the runs, since one run hides a heavy tail.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    seeds: u32,
    /// The frame workload of the VPL methods (converge): `default` (256 VPLs a frame at
    /// --width × --height) or `paper` (papers/002 §7: 1024×768, 1024 VPLs a frame, 8×8
    /// interleave; overrides --width and --height).
    #[arg(long, value_enum, default_value_t = Workload::Default)]
    workload: Workload,
    /// The error the converge table gives: `relmse` ((x − r)² / (r² + 0.01), which on dark
    /// scenes is close to an absolute error), `nmse` (MSE / m², m the reference's mean
    /// luminance: it does not change with exposure) or `nmse-excess` (nMSE less the
    /// reference's own noise, measured from its two independent halves: the error against the
    /// true image, however noisy the reference).
    #[arg(long, value_enum, default_value_t = mirage::report::Metric::Relmse)]
    metric: mirage::report::Metric,
    /// Write the markdown here (and SVG plots beside it); default: print only.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Frame workloads of the reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Workload {
    /// The interactive defaults at the report's image size.
    Default,
    /// Segovia et al.'s measurements: 1024×768, 1024 VPLs, 8×8 interleave.
    Paper,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => cmd_render(&args),
        Command::View(args) => mirage::view::run(&args).map_err(|e| anyhow::anyhow!(e)),
        Command::Info { scene, lights } => cmd_info(scene.as_deref(), &lights),
        Command::Diff { a, b, map } => cmd_diff(&a, &b, map.as_deref()),
        Command::Png { input, output, tonemap, exposure } => cmd_png(&input, output.as_deref(), tonemap, exposure),
        Command::Converge(args) => cmd_report(&args, false),
        Command::Samplers(args) => cmd_report(&args, true),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mirage: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The terminal progress bar the library reports to ([`mirage::progress::Progress`]).
struct Bar(ProgressBar);

impl mirage::progress::Progress for Bar {
    fn set_length(&self, len: u64) {
        self.0.set_length(len);
    }
    fn set_position(&self, pos: u64) {
        self.0.set_position(pos);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

fn progress_bar(quiet: bool) -> Bar {
    if quiet {
        return Bar(ProgressBar::hidden());
    }
    let pb = ProgressBar::new(1);
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed_precise}] {wide_bar} {percent:>3}% (eta {eta})")
            .expect("valid progress template"),
    );
    Bar(pb)
}

fn cmd_render(args: &RenderArgs) -> Result<()> {
    let options = args.options()?;
    if let Some(t) = args.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t).build_global().context("cannot set up worker threads")?;
    }
    let source = SceneSource::from_arg(args.scene.as_deref());
    let t0 = Instant::now();
    let mut scene = render::load_scene_lit(&source, &args.camera.settings(), &args.lights)?;
    for w in &scene.warnings {
        eprintln!("mirage: warning: {w}");
    }
    let accel = Accel::build(&scene.mesh);
    if let Some(at) = args.camera.focus_at {
        render::focus_at(&mut scene, &accel, at)?;
    }
    let setup = t0.elapsed();
    let exr_path = match &args.output {
        Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) => p.with_extension("exr"),
        Some(p) => p.clone(),
        None => PathBuf::from("out").join(format!("{}-{}.exr", source.name(), options.mode.name())),
    };
    let png_path = exr_path.with_extension("png");
    if let Some(dir) = exr_path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create output directory", dir.display()))?;
    }
    let pb = progress_bar(args.quiet);
    pb.0.set_message(format!("{} {}", options.mode.name(), source.name()));
    if options.mode == mirage::options::Mode::Mlt {
        mirage::offline::mlt::supported(&scene).map_err(|e| anyhow::anyhow!("{}: {e}", source.name()))?;
    }
    let render::Rendered { out, frame: frame_stats, pssmlt, mlt } = render::render(&scene, &accel, &options, &pb);
    let image = out.film.image();
    let aovs = out.film.aov_images();
    // The compensation layer only where a VPL mode compensated the clamp.
    let compensated = frame_stats.is_some() && options.frame.compensate && options.frame.clamp > 0.0;
    let aov_refs = match &aovs {
        Some(a) => Aovs {
            albedo: Some(&a.albedo),
            normal: Some(&a.normal),
            depth: Some(&a.depth),
            compensation: compensated.then_some(&a.compensation),
        },
        None => Aovs::default(),
    };
    output::write_exr(&exr_path, &image, aov_refs)?;
    output::write_png(&png_path, &image, options.tonemap)?;
    if let Some(st) = options.debug_strategy {
        let (weighted, unweighted) = render::render_strategy(&scene, &accel, &options, st, &pb);
        for (tag, o) in [("weighted", weighted), ("unweighted", unweighted)] {
            let p = exr_path.with_file_name(format!(
                "{}-s{}-t{}-{tag}.exr",
                exr_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
                st.0,
                st.1
            ));
            let img = o.film.image();
            output::write_exr(&p, &img, Aovs::default())?;
            output::write_png(&p.with_extension("png"), &img, options.tonemap)?;
            out!("strategy s={} t={} {tag} → {}", st.0, st.1, p.display());
        }
    }
    let secs = out.elapsed.as_secs_f64().max(1e-9);
    out!(
        "{} {}: {}×{}, {} spp in {:.2} s (+{:.2} s setup), {:.2} Msamples/s, {:.2} Mrays/s{} → {}, {}",
        options.mode.name(),
        source.name(),
        scene.camera.width,
        scene.camera.height,
        out.spp,
        secs,
        setup.as_secs_f64(),
        out.stats.samples as f64 / secs / 1e6,
        out.stats.rays() as f64 / secs / 1e6,
        if out.stats.discarded > 0 {
            format!(", {} non-finite samples discarded", out.stats.discarded)
        } else {
            String::new()
        },
        exr_path.display(),
        png_path.display()
    );
    if let Some(m) = pssmlt {
        let (large, small) = m.rejected();
        out!(
            "  {} chains ({} accepted nothing), b = {:.4e} from {} bootstrap paths ({} non-zero){}; rejected: large steps {:.1} %, small steps {:.1} %",
            options.pssmlt.chains,
            m.stuck_chains,
            m.b,
            m.bootstrap_states,
            m.bootstrap_nonzero,
            if m.direct > 0 {
                format!(
                    ", depths 2 and up; depths 0–1 ({:.0} % of the light) path traced at {} spp a pass",
                    100.0 * m.direct_share,
                    m.direct
                )
            } else {
                ", every depth".to_string()
            },
            100.0 * large,
            100.0 * small
        );
    }
    if let Some(m) = mlt {
        let per_type: Vec<String> = mirage::offline::mlt::MutationKind::ALL
            .iter()
            .zip(&m.counts)
            .filter(|(_, c)| c.proposed > 0)
            .map(|(k, c)| {
                let pct = |x: u64| 100.0 * x as f64 / c.proposed.max(1) as f64;
                format!("{} {:.1} % rejected ({:.1} % failed)", k.name(), 100.0 - pct(c.accepted), 100.0 - pct(c.made))
            })
            .collect();
        out!(
            "  {} chains ({} accepted nothing), mean path {:.1} vertices, b = {:.4e} from {} bootstrap samples ({} non-zero){}; {}",
            options.mlt.chains,
            m.stuck_chains,
            m.mean_path(),
            m.b,
            options.mlt.bootstrap,
            m.bootstrap_nonzero,
            if options.mlt.direct > 0 {
                format!(
                    ", paths outside the direct part; the direct part path traced at {} spp a pass",
                    options.mlt.direct
                )
            } else {
                String::new()
            },
            per_type.join(", ")
        );
        if m.idle_steps > 0 {
            out!("  {:.1} % of the steps stayed: no mutation in use applied to the path", 100.0 * m.idle_fraction());
        }
    }
    if let Some(fs) = frame_stats {
        for w in &fs.sampler.warnings {
            eprintln!("mirage: warning: {w}");
        }
        let frames = out.spp.max(1) as f64;
        let compensated = options.frame.compensate && options.frame.clamp > 0.0;
        let shadow_s = fs.shadow_time.as_secs_f64().max(1e-9);
        out!(
            "  {} × {} VPLs ({}): VPLs {:.1} ms/frame, primary {:.1} ms, gather {:.1} ms ({:.2} M shadow rays/s{}), filter {:.1} ms{}; {}{}{}",
            out.spp,
            options.frame.vpls,
            options.vpl_sampler.build_with(&options.sampler).name(),
            fs.vpl_time.as_secs_f64() * 1e3 / frames,
            fs.primary_time.as_secs_f64() * 1e3 / frames,
            fs.shadow_time.as_secs_f64() * 1e3 / frames,
            fs.rays.shadow as f64 / shadow_s / 1e6,
            if compensated {
                format!(", of which compensation {:.1} ms", fs.compensation_time.as_secs_f64() * 1e3 / frames)
            } else {
                String::new()
            },
            fs.filter_time.as_secs_f64() * 1e3 / frames,
            match (options.frame.filter, options.filter_fade) {
                (Some(_), Some(k)) => {
                    let w = mirage::frame::filter_weight(Some(k), out.spp);
                    format!(" (faded out: weight {w:.3} after {} frames)", out.spp)
                }
                _ => String::new(),
            },
            clamp_summary(&fs.energy, compensated),
            fs.sampler.acceptance_rate().map(|a| format!(", acceptance {:.1} %", 100.0 * a)).unwrap_or_default(),
            power_summary(&fs.power_ratios)
        );
    }
    Ok(())
}

/// The frames' VPL power spread ([`mirage::gather::power_ratio`]): the median frame's and the
/// worst frame's ratio of the strongest VPL to the median one.
fn power_summary(ratios: &[f32]) -> String {
    let mut r = ratios.to_vec();
    r.sort_by(f32::total_cmp);
    match (r.get(r.len() / 2), r.last()) {
        (Some(median), Some(worst)) => {
            format!("; strongest VPL / median VPL in the image {median:.1} (median frame), {worst:.1} (worst frame)")
        }
        _ => String::new(),
    }
}

/// What the clamp removed and what its compensation added back, in % of the unclamped
/// gathered light: "removed" is the VPLs' own estimate of the removed light (heavy-tailed), the
/// compensation another, unbiased, estimate of the same; their difference estimates the bias
/// left (zero in expectation, but for what the compensation does not follow: specular
/// receivers, paths beyond its depth).
fn clamp_summary(e: &mirage::gather::GatherEnergy, compensated: bool) -> String {
    let total = (e.kept + e.removed).max(f64::MIN_POSITIVE);
    let removed = 100.0 * e.removed / total;
    if compensated {
        let recovered = 100.0 * e.recovered / total;
        format!(
            "clamping removed {removed:.2} % of the gathered light, compensation recovered {recovered:.2} % (net bias estimate {:+.2} %)",
            recovered - removed
        )
    } else if e.removed > 0.0 {
        format!("clamping removed {removed:.2} % of the gathered light, not compensated (biased: darker)")
    } else {
        "nothing clamped, not compensated".to_string()
    }
}

fn cmd_info(scene: Option<&str>, lights: &mirage::options::LightArgs) -> Result<()> {
    lights.validate().map_err(|e| anyhow::anyhow!(e))?;
    let source = SceneSource::from_arg(scene);
    let scene = render::load_scene_lit(&source, &CameraSettings::default(), lights)?;
    for w in &scene.warnings {
        eprintln!("mirage: warning: {w}");
    }
    let b = scene.bounds;
    out!("scene      {}", source.name());
    out!("triangles  {}", scene.mesh.len());
    out!("materials  {}", scene.materials.len());
    out!("textures   {}", scene.textures.len());
    out!(
        "bounds     [{:.4}, {:.4}, {:.4}] – [{:.4}, {:.4}, {:.4}]",
        b.min.x,
        b.min.y,
        b.min.z,
        b.max.x,
        b.max.y,
        b.max.z
    );
    let c = &scene.camera;
    out!(
        "camera     eye [{:.4}, {:.4}, {:.4}] forward [{:.3}, {:.3}, {:.3}] fov_y {:.2}° {}×{}{}",
        c.position.x,
        c.position.y,
        c.position.z,
        c.forward.x,
        c.forward.y,
        c.forward.z,
        c.fov_y_radians.to_degrees(),
        c.width,
        c.height,
        if c.lens_radius > 0.0 { format!(" lens {} focus {}", c.lens_radius, c.focus_distance) } else { String::new() }
    );
    let total = scene.lights.total_power();
    let area = scene.lights.list.iter().filter(|l| matches!(l, Light::Area { .. })).count();
    let infinite = scene.lights.list.iter().filter(|l| l.at_infinity()).count();
    out!(
        "emitters   {} ({} emissive triangles, {} punctual, {} at infinity), total power [{:.4}, {:.4}, {:.4}] W",
        scene.lights.list.len(),
        area,
        scene.lights.list.len() - area - infinite,
        infinite,
        total.x,
        total.y,
        total.z
    );
    // Group emissive triangles by material for a readable list.
    let mut by_material: Vec<(String, usize, glam::Vec3)> = Vec::new();
    for (light, power) in scene.lights.list.iter().zip(&scene.lights.power) {
        let name = match light {
            Light::Area { tri, .. } => format!("material '{}'", scene.material_of(*tri).name),
            Light::Point { position, .. } => {
                format!("point light at [{:.3}, {:.3}, {:.3}]", position.x, position.y, position.z)
            }
            Light::Spot { position, .. } => {
                format!("spot light at [{:.3}, {:.3}, {:.3}]", position.x, position.y, position.z)
            }
            Light::Sun(sun) => {
                let (wi, e) = (sun.wi(), sun.irradiance);
                let diameter = 2.0 * sun.half_angle.to_degrees();
                format!(
                    "sun towards [{:.3}, {:.3}, {:.3}], illuminance [{:.4}, {:.4}, {:.4}] W/m², diameter {diameter:.2}° (power through the scene's disk)",
                    wi.x, wi.y, wi.z, e.x, e.y, e.z
                )
            }
            Light::Sky(mirage::scene::sky::Environment::Constant(l)) => {
                format!("constant sky, radiance [{:.4}, {:.4}, {:.4}] (power through the scene's disk)", l.x, l.y, l.z)
            }
            Light::Sky(mirage::scene::sky::Environment::Map(m)) => {
                format!("environment map {}×{} (power through the scene's disk)", m.width, m.height)
            }
        };
        match by_material.iter_mut().find(|(n, _, _)| *n == name) {
            Some(e) => {
                e.1 += 1;
                e.2 += *power;
            }
            None => by_material.push((name, 1, *power)),
        }
    }
    for (name, count, power) in by_material {
        out!(
            "  {name}: {count} emitter(s), power [{:.4}, {:.4}, {:.4}] W ({:.1} % of luminance)",
            power.x,
            power.y,
            power.z,
            100.0 * luminance(power) / luminance(total).max(1e-30)
        );
    }
    let accel = Accel::build(&scene.mesh);
    let (mesh, bvh) = (scene.mesh.heap_bytes(), accel.heap_bytes());
    let mib = |b: usize| b as f64 / (1 << 20) as f64;
    out!(
        "memory     mesh {:.1} MiB, BVH {:.1} MiB: {:.0} bytes a triangle (kept while rendering)",
        mib(mesh),
        mib(bvh),
        (mesh + bvh) as f64 / scene.mesh.len().max(1) as f64
    );
    Ok(())
}

fn cmd_png(
    input: &Path,
    output: Option<&Path>,
    tonemap: mirage::options::TonemapArg,
    exposure: Option<f32>,
) -> Result<()> {
    let tm = tonemap.with_exposure(exposure).map_err(|e| anyhow::anyhow!(e))?;
    let img = output::read_exr(input)?;
    let out = output.map_or_else(|| input.with_extension("png"), Path::to_path_buf);
    output::write_png(&out, &img, tm)?;
    out!("{} → {}", input.display(), out.display());
    Ok(())
}

fn cmd_diff(a: &Path, b: &Path, map: Option<&Path>) -> Result<()> {
    let ia = output::read_exr(a)?;
    let ib = output::read_exr(b)?;
    if (ia.width, ia.height) != (ib.width, ib.height) {
        bail!("{} is {}×{} but {} is {}×{}", a.display(), ia.width, ia.height, b.display(), ib.width, ib.height);
    }
    let e = ia.errors(&ib);
    out!("mse {:.6e}  relmse {:.6e}  nmse {:.6e}  mean_bias {:+.4} %", e.mse, e.rel_mse, e.nmse, 100.0 * e.mean_bias);
    if let Some(path) = map {
        let m = ib.mean_luminance();
        let m2 = if m > 0.0 { (m * m) as f32 } else { 1.0 };
        let data = ia
            .data
            .iter()
            .zip(&ib.data)
            .map(|(x, r)| {
                let d = (*x - *r) * (*x - *r) / m2;
                glam::Vec3::splat((d.x + d.y + d.z) / 3.0)
            })
            .collect();
        let img = mirage::film::Image { width: ia.width, height: ia.height, data };
        output::write_exr(path, &img, Default::default())?;
        out!("per-pixel squared error / m² → {}", path.display());
    }
    Ok(())
}

fn cmd_report(args: &ReportArgs, samplers: bool) -> Result<()> {
    use mirage::frame::FrameSettings;
    use mirage::report::{self, Method};
    let methods: Vec<Method> =
        args.methods.iter().map(|m| Method::parse(m)).collect::<Result<_, _>>().map_err(|e| anyhow::anyhow!(e))?;
    if args.times.iter().any(|t| !(*t > 0.0 && t.is_finite())) {
        bail!("--times must be positive numbers of seconds");
    }
    let (width, height, vpls) = match args.workload {
        Workload::Default => (args.width, args.height, FrameSettings::interactive().vpls),
        Workload::Paper => (1024, 768, 1024),
    };
    let camera = CameraSettings { width: Some(width), height: Some(height), ..Default::default() };
    // As `mirage render` draws: clamp compensated (methods with -uncompensated turn it off).
    let frame_settings = FrameSettings { vpls, compensate: true, max_specular: 8, ..FrameSettings::interactive() };
    let mut md = String::new();
    let mut svgs = Vec::new();
    let machine = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_default();
    md += &format!(
        "Machine: {machine}, {} threads. Images {}×{}; references: pt, {} spp in two independent halves (target/reference/). VPL methods: {} VPLs/frame, {}×{} interleave, clamp {} compensated, discontinuity buffer faded out over the frames (weight n·m / (n·m + frames); -filtered: throughout, -unfiltered: off). {} run(s) per cell.\n\n",
        rayon::current_num_threads(),
        width,
        height,
        args.reference_spp,
        frame_settings.vpls,
        frame_settings.interleave.0,
        frame_settings.interleave.1,
        frame_settings.clamp,
        args.seeds
    );
    let mut conv_rows = Vec::new();
    let mut sampler_rows = Vec::new();
    let mut ref_notes = Vec::new();
    for name in &args.scenes {
        let source = SceneSource::from_arg(Some(name));
        let scene = render::load_scene(&source, &camera)?;
        let accel = Accel::build(&scene.mesh);
        eprintln!("{name}: reference ({} spp, cached)…", args.reference_spp);
        let reference =
            report::reference(&scene, &accel, &source.name(), args.reference_spp, &report::reference_dir())?;
        let m = reference.image.mean_luminance();
        ref_notes.push(format!(
            "{}: mean luminance {m:.4e}, the reference's own nMSE {:.4}",
            source.name(),
            reference.noise_mse / (m * m).max(f64::MIN_POSITIVE)
        ));
        if samplers {
            for &m in &args.vpls {
                for method in methods.iter().filter(|m| matches!(m, Method::Vpl { .. })) {
                    eprintln!("{name}: {} with {m} VPLs", method.label());
                    sampler_rows.push(report::sampler_row(
                        &scene,
                        &accel,
                        &source.name(),
                        method,
                        m,
                        args.frames,
                        &reference.image,
                        &frame_settings,
                    ));
                }
            }
        } else {
            let rows = report::converge(
                &scene,
                &accel,
                &source.name(),
                &methods,
                &args.times,
                args.seeds,
                &reference,
                &frame_settings,
                args.metric,
                &|m| eprintln!("{m}"),
            );
            svgs.push((source.name(), report::converge_svg(&rows, &source.name(), args.metric)));
            conv_rows.extend(rows);
        }
    }
    if samplers {
        md += &report::sampler_markdown(&sampler_rows);
    } else {
        let name = args.metric.name();
        md += &if args.seeds > 1 {
            format!(
                "Median {name} against the reference after each time budget over the runs, [lowest–highest] (passes of the median run in parentheses: spp for pt/bdpt, frames for VPL methods).\n\n"
            )
        } else {
            format!(
                "{name} against the reference after each time budget (passes in parentheses: spp for pt/bdpt, frames for VPL methods).\n\n"
            )
        };
        md += &format!("{}.\n\n", args.metric.definition());
        md += &report::converge_markdown(&conv_rows, &args.times);
    }
    md += "\nReferences (their own noise, Var(r)/m², from the halves' difference):\n\n";
    for n in &ref_notes {
        md += &format!("- {n}\n");
    }
    out!("{md}");
    if let Some(out) = &args.output {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(out, &md).with_context(|| format!("{}: cannot write report", out.display()))?;
        for (name, svg) in svgs {
            let p = out.with_file_name(format!(
                "{}-{name}.svg",
                out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
            ));
            std::fs::write(&p, svg).with_context(|| format!("{}: cannot write plot", p.display()))?;
        }
    }
    Ok(())
}
