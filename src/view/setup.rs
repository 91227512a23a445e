//! Preparing the scene for the viewer: the same loading as `mirage render` (built-in name or
//! file, the command line's lights, `--add-light` among them), the BVH, and `--focus-at`.

use super::error::ViewError;
use crate::accel::Accel;
use crate::options::CameraArgs;
use crate::render::{self, SceneSource};
use crate::scene::Scene;

/// Loads, lights, validates and builds the BVH of the scene; resolves `--focus-at`. Returns the
/// scene, its BVH and a short name.
pub fn prepare(
    scene_arg: Option<&str>,
    camera: &CameraArgs,
    lights: &crate::options::LightArgs,
) -> Result<(Scene, Accel, String), ViewError> {
    let source = SceneSource::from_arg(scene_arg);
    let mut scene = render::load_scene_lit(&source, &camera.settings(), lights)?;
    let accel = Accel::build(&scene.mesh);
    if let Some(at) = camera.focus_at {
        render::focus_at(&mut scene, &accel, at)?;
    }
    Ok((scene, accel, source.name()))
}
