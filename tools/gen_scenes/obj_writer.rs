//! [`SceneDesc`] → Wavefront OBJ + MTL + `camera.json`, for the OBJ loader's test scene.
//!
//! One `o` per mesh (named like the glTF meshes), `usemtl` before its faces, `v` (and `vn`
//! when present) lines, 1-based `f` lines indexing into the file-wide vertex list. The MTL
//! gives `Kd` for every material, `Ke` for emitters (an OBJ emitter is single-sided: it emits
//! from the counter-clockwise front face only) and `illum 2`. Only what this maps exactly is
//! accepted: diffuse, single-sided materials without textures; anything else is an error.
//! Floats use Rust's shortest round-trip formatting, so the output is deterministic.

use std::fmt::Write;

use mirage::load::{ScatterDesc, SceneDesc};
use serde::Serialize;

use super::gltf_writer::{compact_number_arrays, mesh_name};

/// The three files of an OBJ scene.
pub struct ObjFiles {
    /// `<stem>.obj`.
    pub obj: String,
    /// `<stem>.mtl`.
    pub mtl: String,
    /// `camera.json`.
    pub camera_json: String,
}

#[derive(Serialize)]
struct CameraJson {
    eye: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    fov_y_deg: f32,
    width: u32,
    height: u32,
}

fn vec3_line(out: &mut String, tag: &str, v: glam::Vec3) {
    writeln!(out, "{tag} {} {} {}", v.x, v.y, v.z).unwrap();
}

/// The OBJ, MTL (referred to as `<stem>.mtl`) and camera.json for `desc`.
pub fn write_obj(desc: &SceneDesc, stem: &str) -> Result<ObjFiles, String> {
    if !desc.lights.is_empty() || !desc.textures.is_empty() {
        return Err("the OBJ writer supports neither punctual lights nor textures".into());
    }
    let mut mtl = String::from("# mirage gen_scenes: materials of the built-in Cornell box\n");
    for m in &desc.materials {
        if m.scatter != ScatterDesc::Diffuse || m.base_color_texture.is_some() || m.emission_texture.is_some() {
            return Err(format!("material '{}': the OBJ writer supports only untextured diffuse materials", m.name));
        }
        let emits = m.emission.max_element() > 0.0;
        if emits && m.double_sided {
            return Err(format!("material '{}': an OBJ emitter cannot be double-sided", m.name));
        }
        writeln!(mtl, "\nnewmtl {}", m.name).unwrap();
        vec3_line(&mut mtl, "Kd", m.base_color);
        if emits {
            vec3_line(&mut mtl, "Ke", m.emission);
        }
        mtl.push_str("illum 2\n");
    }

    let mut obj = format!(
        "# mirage gen_scenes: the built-in Cornell box (world space; the box is 5.5 units wide)\nmtllib {stem}.mtl\n"
    );
    let (mut v_base, mut vn_base) = (1usize, 1usize);
    for m in &desc.meshes {
        writeln!(obj, "\no {}\nusemtl {}", mesh_name(m), desc.materials[m.material].name).unwrap();
        m.positions.iter().for_each(|&p| vec3_line(&mut obj, "v", p));
        m.normals.iter().for_each(|&n| vec3_line(&mut obj, "vn", n));
        for t in m.indices.chunks_exact(3) {
            obj.push('f');
            for &i in t {
                let v = v_base + i as usize;
                if m.normals.is_empty() {
                    write!(obj, " {v}").unwrap();
                } else {
                    write!(obj, " {v}//{}", vn_base + i as usize).unwrap();
                }
            }
            obj.push('\n');
        }
        v_base += m.positions.len();
        vn_base += m.normals.len();
    }

    let cam = desc.camera.as_ref().ok_or("the OBJ writer needs a camera for camera.json")?;
    let (width, height) = cam.width.zip(cam.height).ok_or("the OBJ writer needs the camera's resolution")?;
    let camera = CameraJson {
        eye: cam.eye.to_array(),
        target: cam.target.to_array(),
        up: cam.up.to_array(),
        fov_y_deg: cam.fov_y_deg,
        width,
        height,
    };
    let camera_json = serde_json::to_string_pretty(&camera).map_err(|e| format!("camera.json: {e}"))?;
    let camera_json = compact_number_arrays(&camera_json) + "\n";
    Ok(ObjFiles { obj, mtl, camera_json })
}
