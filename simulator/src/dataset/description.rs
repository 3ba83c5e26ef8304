//! The dataset's reading of a `.toml` scene description: the render part the scene loader reads
//! (`scene`, `[camera]`, `[environment]`; [`crate::scene::description`]) plus the tables a
//! dataset needs: `[trajectory]`, `[dataset]` and `[events]`, typed and checked field by field.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::settings::DatasetConfig;
use crate::error::SceneError;
use crate::events::EventConfig;
use crate::scene::description::{CameraDesc, EnvironmentDesc};
use crate::trajectory::TrajectoryConfig;

/// The whole description file, as a dataset reads it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DatasetDescription {
    /// The mesh file (`.obj`, `.gltf` or `.glb`), relative to the description's folder.
    pub scene: PathBuf,
    /// The camera that frames the views (the FOV; the trajectory gives the poses).
    pub camera: Option<CameraDesc>,
    /// Environment replacing the mesh file's.
    pub environment: Option<EnvironmentDesc>,
    /// Camera path of the dataset.
    pub trajectory: Option<TrajectoryConfig>,
    /// Dataset settings (resolution, frame rate, exposure, views, ...); see [`super::settings`].
    pub dataset: Option<DatasetConfig>,
    /// Event-camera settings; see [`EventConfig`].
    pub events: Option<EventConfig>,
}

/// Parse a description from TOML text; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<DatasetDescription, SceneError> {
    toml::from_str(text).map_err(|e| SceneError::invalid(path, "TOML", e.to_string().trim_end().to_string()))
}
