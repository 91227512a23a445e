//! ① Scene files → [`SceneDesc`]: the input I/O boundary.
//!
//! Owns parsing of glTF 2.0 (`.gltf`, `.glb`) and OBJ + MTL (with an optional `camera.json`
//! beside the file), and the built-in scenes. Produces world-space meshes and raw materials;
//! it does not validate geometry (that is `scene`'s job) and knows nothing about rendering.
//! Every error is a [`LoadError`] naming the file and the place in it.

pub mod builtin;
pub mod camera_json;
pub mod desc;
pub mod environment;
pub mod error;
pub mod gltf;
pub mod obj;
pub mod sky_panel;

use std::path::Path;

pub use desc::{
    CameraDesc, EnvironmentDesc, MaterialDesc, MeshDesc, Origin, PunctualDesc, ScatterDesc, SceneDesc, TextureDesc,
};
pub use environment::load_environment;
pub use error::{LoadError, LoadErrorKind};
pub use sky_panel::add_sky_light;

/// Reads a scene file, choosing the parser by extension (`.gltf`, `.glb`, `.obj`).
pub fn load(path: &Path) -> Result<SceneDesc, LoadError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    if !path.exists() {
        return Err(LoadError::io(path, std::io::Error::from(std::io::ErrorKind::NotFound)));
    }
    match ext.as_str() {
        "gltf" | "glb" => gltf::load_gltf(path),
        "obj" => obj::load_obj(path),
        _ => Err(LoadError::new(
            path,
            LoadErrorKind::UnknownFormat,
            format!("unsupported scene format '.{ext}' (mirage reads .gltf, .glb and .obj)"),
        )),
    }
}
