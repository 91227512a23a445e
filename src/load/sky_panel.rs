//! `--add-light`: a light for geometry-only models such as Sponza, which have no emitter and no
//! camera.
//!
//! The added light is a "sky": one rectangle of constant radiance just above the model's
//! bounds (1 % of the diagonal higher), covering its horizontal footprint, emitting downwards
//! (+y is up). In a courtyard building like Sponza it lights the atrium through the opening in
//! the roof, and the galleries only indirectly: the case where VPLs placed for the camera pay
//! off. When the file has no camera, one is put inside, a fifth of the way along the longer
//! horizontal axis, at a quarter of the height, looking along that axis.

use glam::Vec3;

use super::{CameraDesc, MaterialDesc, MeshDesc, Origin, SceneDesc};

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::builtin;
    use crate::scene::{CameraSettings, Scene};

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
