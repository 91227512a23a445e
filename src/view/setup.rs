//! Preparing the scene for the viewer: the same loading as `mirage render` (built-in name or
//! file), plus `--add-light` for geometry-only models such as Sponza, which have no emitter and
//! no camera.
//!
//! The added light is a "sky": one rectangle of constant radiance just above the model's
//! bounds (1 % of the diagonal higher), covering its horizontal footprint, emitting downwards
//! (+y is up). In a courtyard building like Sponza it lights the atrium through the opening in
//! the roof, and the galleries only indirectly: the case where VPLs placed for the camera pay
//! off. When the file has no camera, one is put inside, a fifth of the way along the longer
//! horizontal axis, at a quarter of the height, looking along that axis.

use glam::Vec3;

use super::error::ViewError;
use crate::accel::Accel;
use crate::load::{self, CameraDesc, MaterialDesc, MeshDesc, Origin, SceneDesc, builtin};
use crate::options::CameraArgs;
use crate::render::{self, PrepareError, SceneSource};
use crate::scene::Scene;

/// Axis-aligned bounds of the finite vertex positions of `desc`, if there are any.
fn desc_bounds(desc: &SceneDesc) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in desc.meshes.iter().flat_map(|m| &m.positions).filter(|p| p.is_finite()) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo.x <= hi.x).then_some((lo, hi))
}

/// Adds the sky panel of radiance `le` (and an inside camera when there is none) to `desc`.
pub fn add_sky_light(desc: &mut SceneDesc, le: Vec3) {
    let Some((lo, hi)) = desc_bounds(desc) else { return };
    let y = hi.y + 0.01 * (hi - lo).length().max(1e-6);
    let material = desc.materials.len();
    let mut m = MaterialDesc::diffuse("added sky light", Vec3::ZERO);
    m.emission = le;
    desc.materials.push(m);
    // (x0, z0) → (x1, z0) → (x1, z1): front normal (b − a) × (c − a) points down (−y).
    let positions =
        vec![Vec3::new(lo.x, y, lo.z), Vec3::new(hi.x, y, lo.z), Vec3::new(hi.x, y, hi.z), Vec3::new(lo.x, y, hi.z)];
    desc.meshes.push(MeshDesc {
        origin: Origin::Builtin("--add-light sky panel".into()),
        positions,
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: vec![0, 1, 2, 0, 2, 3],
        material,
    });
    if desc.camera.is_none() {
        let c = 0.5 * (lo + hi);
        let along_x = hi.x - lo.x >= hi.z - lo.z;
        let axis = if along_x { Vec3::X } else { Vec3::Z };
        let (a0, a1) = if along_x { (lo.x, hi.x) } else { (lo.z, hi.z) };
        let h = lo.y + 0.25 * (hi.y - lo.y);
        let eye = Vec3::new(c.x, h, c.z) + axis * (a0 + 0.2 * (a1 - a0) - axis.dot(c));
        let target = Vec3::new(c.x, lo.y + 0.3 * (hi.y - lo.y), c.z) + axis * (a1 - axis.dot(c));
        desc.camera =
            Some(CameraDesc { eye, target, up: Vec3::Y, fov_y_deg: 60.0, aspect: None, width: None, height: None });
    }
}

/// Loads, lights (with `add_light`), validates and builds the BVH of the scene; resolves
/// `--focus-at`. Returns the scene, its BVH and a short name.
pub fn prepare(
    scene_arg: Option<&str>,
    add_light: Option<f32>,
    camera: &CameraArgs,
    lights: &crate::options::LightArgs,
) -> Result<(Scene, Accel, String), ViewError> {
    let source = SceneSource::from_arg(scene_arg);
    let mut scene = match add_light {
        None => render::load_scene_lit(&source, &camera.settings(), lights)?,
        Some(le) => {
            let mut desc = match &source {
                SceneSource::Builtin(name) => builtin::by_name(name).expect("built-in names are checked in from_arg"),
                SceneSource::File(path) => load::load(path).map_err(PrepareError::Load)?,
            };
            add_sky_light(&mut desc, Vec3::splat(le));
            lights.apply(&mut desc).map_err(PrepareError::Load)?;
            Scene::from_desc(desc, &camera.settings()).map_err(PrepareError::Scene)?
        }
    };
    let accel = Accel::build(&scene.mesh);
    if let Some(at) = camera.focus_at {
        render::focus_at(&mut scene, &accel, at)?;
    }
    Ok((scene, accel, source.name()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::CameraSettings;

    #[test]
    fn the_sky_panel_makes_a_geometry_only_model_renderable_and_faces_down() {
        let mut desc = builtin::cornell();
        // Strip the emitters and the camera: geometry only.
        for m in &mut desc.materials {
            m.emission = Vec3::ZERO;
        }
        desc.camera = None;
        assert!(Scene::from_desc(desc.clone(), &CameraSettings::default()).is_err());
        add_sky_light(&mut desc, Vec3::ONE);
        let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
        assert!(scene.lights.total_power().x > 0.0);
        let sky = scene.mesh.triangles.len() - 1;
        let [a, b, c] = scene.mesh.triangles[sky].map(|i| scene.mesh.positions[i as usize]);
        assert!((b - a).cross(c - a).y < 0.0, "the panel must emit downwards");
        assert!(a.y > scene.bounds.min.y + 0.99 * (scene.bounds.max.y - scene.bounds.min.y));
        // The camera is inside the bounds.
        let p = scene.camera.position;
        assert!(p.cmpge(scene.bounds.min).all() && p.cmple(scene.bounds.max).all(), "{p}");
    }
}
