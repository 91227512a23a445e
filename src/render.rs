//! One short function per step of a render, in pipeline order (like pbrt's `RenderCPU`):
//! resolve the scene argument, load and validate, build the BVH, resolve the focus point, run
//! the mode.

use std::fmt;
use std::path::PathBuf;

use crate::progress::Progress;
use glam::{Vec2, vec2};

use crate::accel::Accel;
use crate::frame::{self, FrameStats};
use crate::load::{self, LoadError, builtin};
use crate::offline::bdpt::{BdptOptions, StrategyFilter};
use crate::offline::mlt::{self, MltStats};
use crate::offline::pssmlt::{self, PssmltStats};
use crate::offline::{self, RenderOutput};
use crate::options::{Mode, RenderOptions};
use crate::scene::{CameraSettings, Scene, SceneError};

/// Where a scene comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// A scene built into the binary.
    Builtin(String),
    /// A scene file.
    File(PathBuf),
}

impl SceneSource {
    /// Interprets the SCENE argument: none → the built-in Cornell box; the name of a built-in
    /// scene (when no file of that name exists) → that scene; anything else → a file path.
    pub fn from_arg(arg: Option<&str>) -> SceneSource {
        match arg {
            None => SceneSource::Builtin("cornell".into()),
            Some(a)
                if (builtin::NAMES.contains(&a) || builtin::BENCH_NAMES.contains(&a))
                    && !std::path::Path::new(a).exists() =>
            {
                SceneSource::Builtin(a.into())
            }
            Some(a) => SceneSource::File(PathBuf::from(a)),
        }
    }

    /// A short name for output files and summaries.
    pub fn name(&self) -> String {
        match self {
            SceneSource::Builtin(n) => n.clone(),
            SceneSource::File(p) => {
                p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into())
            }
        }
    }
}

/// Why a scene could not be prepared.
#[derive(Debug)]
pub enum PrepareError {
    /// Reading the file failed.
    Load(LoadError),
    /// The scene is not renderable.
    Scene(SceneError),
    /// The focus point sees nothing.
    Focus(String),
}

impl fmt::Display for PrepareError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PrepareError::Load(e) => e.fmt(f),
            PrepareError::Scene(e) => e.fmt(f),
            PrepareError::Focus(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for PrepareError {}

/// Loads and validates a scene.
pub fn load_scene(source: &SceneSource, camera: &CameraSettings) -> Result<Scene, PrepareError> {
    load_scene_lit(source, camera, &crate::options::LightArgs::default())
}

/// Loads a scene, adds the command line's lights (sun, sky, environment) and validates it.
pub fn load_scene_lit(
    source: &SceneSource,
    camera: &CameraSettings,
    lights: &crate::options::LightArgs,
) -> Result<Scene, PrepareError> {
    let mut desc = match source {
        SceneSource::Builtin(name) => builtin::by_name(name).expect("built-in scene names are checked in from_arg"),
        SceneSource::File(path) => load::load(path).map_err(PrepareError::Load)?,
    };
    lights.apply(&mut desc).map_err(PrepareError::Load)?;
    Scene::from_desc(desc, camera).map_err(PrepareError::Scene)
}

/// Sets the thin lens's focus distance to the depth (along the view axis) of whatever is seen
/// through raster point `at` (papers/000 Fig. 11).
pub fn focus_at(scene: &mut Scene, accel: &Accel, at: Vec2) -> Result<(), PrepareError> {
    let cam = &scene.camera;
    if !(at.x >= 0.0 && at.y >= 0.0 && at.x < cam.width as f32 && at.y < cam.height as f32) {
        return Err(PrepareError::Focus(format!(
            "--focus-at {},{} lies outside the {}×{} image",
            at.x, at.y, cam.width, cam.height
        )));
    }
    let pinhole = cam.clone().with_lens(0.0, cam.focus_distance);
    let ray = pinhole.generate_ray(at, vec2(0.5, 0.5));
    let hit = accel.intersect(ray.origin, ray.dir, f32::INFINITY).ok_or_else(|| {
        PrepareError::Focus(format!("--focus-at {},{}: the ray through that point hits nothing", at.x, at.y))
    })?;
    let depth = hit.t * ray.dir.dot(cam.forward);
    scene.camera = cam.clone().with_lens(cam.lens_radius, depth);
    Ok(())
}

/// What a render produced, with the statistics of the mode that made it.
pub struct Rendered {
    /// Film, ray counts, time.
    pub out: RenderOutput,
    /// VPL modes: per-stage statistics.
    pub frame: Option<FrameStats>,
    /// pssmlt: the chains' statistics.
    pub pssmlt: Option<PssmltStats>,
    /// mlt: the chains' statistics.
    pub mlt: Option<MltStats>,
}

/// Runs the requested mode.
pub fn render(scene: &Scene, accel: &Accel, options: &RenderOptions, progress: &dyn Progress) -> Rendered {
    let plain = |out| Rendered { out, frame: None, pssmlt: None, mlt: None };
    match options.mode {
        Mode::Pt => plain(offline::render_pt(scene, accel, &options.offline, progress)),
        Mode::Bdpt => {
            let opts = BdptOptions { max_depth: options.offline.max_depth, only: None, path_edges: None };
            plain(offline::render_bdpt(scene, accel, &options.offline, &opts, progress))
        }
        Mode::Pssmlt => {
            let (out, st) = pssmlt::render_pssmlt(scene, accel, &options.offline, &options.pssmlt, progress);
            Rendered { out, frame: None, pssmlt: Some(st), mlt: None }
        }
        Mode::Mlt => {
            let (out, st) = mlt::render_mlt(scene, accel, &options.offline, &options.mlt, progress);
            Rendered { out, frame: None, pssmlt: None, mlt: Some(st) }
        }
        Mode::Ir | Mode::Mir => {
            let mut sampler = options.vpl_sampler.build_with(&options.sampler);
            let o = &options.offline;
            let acc =
                frame::Accumulation { budget: o.budget, seed: o.seed, aovs: o.aovs, filter_fade: options.filter_fade };
            let (out, stats) = frame::render_progressive(scene, accel, sampler.as_mut(), &options.frame, acc, progress);
            Rendered { out, frame: Some(stats), pssmlt: None, mlt: None }
        }
    }
}

/// Renders one BDPT strategy alone, weighted and unweighted (`--debug-strategy`).
pub fn render_strategy(
    scene: &Scene,
    accel: &Accel,
    options: &RenderOptions,
    (s, t): (usize, usize),
    progress: &dyn Progress,
) -> (RenderOutput, RenderOutput) {
    let run = |weighted| {
        let opts = BdptOptions {
            max_depth: options.offline.max_depth,
            only: Some(StrategyFilter { s: Some(s), t: Some(t), weighted }),
            path_edges: None,
        };
        offline::render_bdpt(scene, accel, &options.offline, &opts, progress)
    };
    (run(true), run(false))
}
