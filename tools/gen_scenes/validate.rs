//! Reads written files back and checks them against the [`SceneDesc`] they came from: the glTF
//! with the `gltf` crate (which validates the document), the OBJ + MTL with `tobj`.
//!
//! The material check applies the inverse of the mapping in `gltf_writer`, as the glTF loader
//! does, so a change to one side without the other fails here.

use std::path::Path;

use glam::{Quat, Vec3};
use mirage::load::{ScatterDesc, SceneDesc};

use super::gltf_writer::{ZNEAR, mesh_name, roughness_from_phong_exponent};

/// Relative tolerance for values that pass through a division (emission, camera frame).
const TOLERANCE: f32 = 1e-5;

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= TOLERANCE * a.abs().max_element().max(b.abs().max_element()).max(1.0)
}

/// Checks that `bytes` is a valid glTF whose meshes, materials and camera reproduce `desc`.
pub fn check_gltf(bytes: &[u8], desc: &SceneDesc) -> Result<(), String> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| format!("invalid glTF: {e}"))?;
    let buffers =
        gltf::import_buffers(&gltf.document, None, gltf.blob.clone()).map_err(|e| format!("buffer import: {e}"))?;
    let doc = &gltf.document;
    if doc.meshes().len() != desc.meshes.len() || doc.materials().len() != desc.materials.len() {
        return Err(format!(
            "{} meshes and {} materials read back, {} and {} written",
            doc.meshes().len(),
            doc.materials().len(),
            desc.meshes.len(),
            desc.materials.len()
        ));
    }
    let scene = doc.default_scene().ok_or("no default scene")?;
    if scene.nodes().len() != doc.nodes().len() {
        return Err("the scene does not list every node".into());
    }
    for (mesh, m) in doc.meshes().zip(&desc.meshes) {
        let name = mesh_name(m);
        let fail = |what: &str| Err(format!("mesh '{name}': {what} differ after reading back"));
        let prims: Vec<_> = mesh.primitives().collect();
        if prims.len() != 1 || prims[0].mode() != gltf::mesh::Mode::Triangles {
            return fail("primitives");
        }
        let reader = prims[0].reader(|b| Some(&buffers[b.index()]));
        let indices: Vec<u32> = reader.read_indices().ok_or("no indices")?.into_u32().collect();
        if indices.len() / 3 != m.indices.len() / 3 {
            return fail(&format!("triangle counts ({} vs {})", indices.len() / 3, m.indices.len() / 3));
        }
        if indices != m.indices {
            return fail("indices");
        }
        let positions: Vec<Vec3> = reader.read_positions().ok_or("no positions")?.map(Vec3::from).collect();
        if positions != m.positions {
            return fail("positions");
        }
        let normals: Vec<Vec3> = reader.read_normals().into_iter().flatten().map(Vec3::from).collect();
        if normals != m.normals {
            return fail("normals");
        }
        if prims[0].material().index() != Some(m.material) || mesh.name() != Some(name.as_str()) {
            return fail("material or name");
        }
    }
    for node in doc.nodes().filter(|n| n.mesh().is_some()) {
        let (t, r, s) = node.transform().decomposed();
        if t != [0.0; 3] || r != [0.0, 0.0, 0.0, 1.0] || s != [1.0; 3] {
            return Err(format!("mesh node {} has a transform", node.index()));
        }
    }
    for (mat, m) in doc.materials().zip(&desc.materials) {
        let fail = |what: &str| Err(format!("material '{}': {what} differ after reading back", m.name));
        let pbr = mat.pbr_metallic_roughness();
        let emission = Vec3::from(mat.emissive_factor()) * mat.emissive_strength().unwrap_or(1.0);
        if !close(emission, m.emission) || mat.double_sided() != m.double_sided {
            return fail("emission or doubleSided");
        }
        if Vec3::from_slice(&pbr.base_color_factor()) != m.base_color || mat.name() != Some(m.name.as_str()) {
            return fail("base colour or name");
        }
        let transmission = mat.transmission().map(|t| t.transmission_factor());
        let expected = match m.scatter {
            ScatterDesc::Diffuse => (0.0, 1.0, None, None),
            ScatterDesc::Glossy { exponent, .. } => (0.0, roughness_from_phong_exponent(exponent), None, None),
            ScatterDesc::Mirror => (1.0, 0.0, None, None),
            ScatterDesc::Dielectric { ior } => (0.0, 0.0, Some(1.0), Some(ior)),
        };
        if (pbr.metallic_factor(), pbr.roughness_factor(), transmission, mat.ior()) != expected {
            return fail("scattering parameters");
        }
    }
    check_camera(doc, desc)
}

fn check_camera(doc: &gltf::Document, desc: &SceneDesc) -> Result<(), String> {
    let nodes: Vec<_> = doc.nodes().filter(|n| n.camera().is_some()).collect();
    let Some(cam) = &desc.camera else {
        return if nodes.is_empty() { Ok(()) } else { Err("camera written for a scene without one".into()) };
    };
    let [node] = nodes.as_slice() else {
        return Err(format!("{} camera nodes, expected 1", nodes.len()));
    };
    let camera = node.camera().ok_or("camera node without a camera")?;
    let gltf::camera::Projection::Perspective(p) = camera.projection() else {
        return Err("camera is not perspective".into());
    };
    let aspect = cam.width.zip(cam.height).map(|(w, h)| w as f32 / h as f32).or(cam.aspect);
    if (p.yfov() - cam.fov_y_deg.to_radians()).abs() > TOLERANCE || p.aspect_ratio() != aspect || p.znear() != ZNEAR {
        return Err("camera projection differs after reading back".into());
    }
    let (t, r, _) = node.transform().decomposed();
    let q = Quat::from_array(r);
    let forward = (cam.target - cam.eye).normalize();
    let right = forward.cross(cam.up).normalize();
    if Vec3::from(t) != cam.eye || !close(q * Vec3::NEG_Z, forward) || !close(q * Vec3::X, right) {
        return Err(format!(
            "camera node: local −Z maps to {} (want {forward}), +X to {} (want {right})",
            q * Vec3::NEG_Z,
            q * Vec3::X
        ));
    }
    if (q * Vec3::Y).dot(cam.up) <= 0.0 {
        return Err("camera node: local +Y points away from the desc's up".into());
    }
    Ok(())
}

/// Checks that the OBJ at `path` (with its MTL) has the meshes, triangles and materials of `desc`.
pub fn check_obj(path: &Path, desc: &SceneDesc) -> Result<(), String> {
    let options = tobj::LoadOptions { triangulate: true, ..Default::default() };
    let (models, materials) = tobj::load_obj(path, &options).map_err(|e| format!("{}: {e}", path.display()))?;
    let materials = materials.map_err(|e| format!("{}: MTL: {e}", path.display()))?;
    if models.len() != desc.meshes.len() || materials.len() != desc.materials.len() {
        return Err(format!("{}: object or material count differs after reading back", path.display()));
    }
    for (model, m) in models.iter().zip(&desc.meshes) {
        let name = mesh_name(m);
        if model.name != name || model.mesh.material_id != Some(m.material) {
            return Err(format!("{}: object '{}' differs from mesh '{name}'", path.display(), model.name));
        }
        if model.mesh.indices.len() != m.indices.len() || model.mesh.positions.len() != 3 * m.positions.len() {
            return Err(format!("{}: object '{name}' has a different triangle or vertex count", path.display()));
        }
    }
    for (mat, m) in materials.iter().zip(&desc.materials) {
        let emits = m.emission.max_element() > 0.0;
        let ke_ok = mat.emissive.map(Vec3::from) == emits.then_some(m.emission);
        if mat.name != m.name || mat.diffuse.map(Vec3::from) != Some(m.base_color) || !ke_ok {
            return Err(format!("{}: material '{}' differs after reading back", path.display(), m.name));
        }
    }
    Ok(())
}
