//! OBJ + MTL loader (stub, replaced by the full loader).

use std::path::Path;

use super::{LoadError, LoadErrorKind, SceneDesc};

/// Reads an `.obj` file with its `.mtl` libraries and an optional `camera.json` beside it.
pub fn load_obj(path: &Path) -> Result<SceneDesc, LoadError> {
    Err(LoadError::new(path, LoadErrorKind::Unsupported, "OBJ loading is not implemented yet"))
}
