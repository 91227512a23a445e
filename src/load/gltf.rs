//! glTF 2.0 loader (stub, replaced by the full loader).

use std::path::Path;

use super::{LoadError, LoadErrorKind, SceneDesc};

/// Reads a `.gltf` or `.glb` file.
pub fn load_gltf(path: &Path) -> Result<SceneDesc, LoadError> {
    Err(LoadError::new(path, LoadErrorKind::Unsupported, "glTF loading is not implemented yet"))
}
