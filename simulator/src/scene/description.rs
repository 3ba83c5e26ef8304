//! TODO(helper): description.

use std::path::Path;

use super::Scene;
use crate::error::SceneError;

/// Load a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    Err(SceneError::unsupported(path, "loader", "description not implemented yet"))
}
