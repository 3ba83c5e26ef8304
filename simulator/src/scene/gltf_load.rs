//! TODO(helper): gltf_load.

use std::path::Path;

use super::Scene;
use crate::error::SceneError;

/// Load a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    Err(SceneError::unsupported(path, "loader", "gltf_load not implemented yet"))
}
