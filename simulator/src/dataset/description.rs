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

/// The tables of a description that `--set` may change: the ones a dataset reads from it (the
/// scene loader reads the render part from the file itself).
pub const SETTABLE: [&str; 3] = ["dataset", "events", "trajectory"];

/// As [`parse`], with `sets` applied to the file's TOML first
/// ([`crate::base::settings::apply_sets`]; keys under [`SETTABLE`] only, missing tables
/// created); the typed read that follows checks every key and value. When the file cannot be
/// read by itself either, its own error is reported (it names the line and the key; a typed
/// read of the changed document could not).
pub fn parse_with_sets(text: &str, path: &Path, sets: &[String]) -> Result<DatasetDescription, SceneError> {
    let as_written = parse(text, path);
    match (sets_applied(text, path, sets), as_written) {
        (Ok(desc), _) => Ok(desc),
        (Err(_), Err(own)) => Err(own),
        (Err(e), Ok(_)) => Err(e),
    }
}

/// The file's TOML with `sets` applied, read as a description.
fn sets_applied(text: &str, path: &Path, sets: &[String]) -> Result<DatasetDescription, SceneError> {
    use crate::base::settings::{apply_sets, SetWording};
    let invalid = |message: String| SceneError::invalid(path, "--set", message);
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| SceneError::invalid(path, "TOML", e.to_string().trim_end().to_string()))?;
    for s in sets {
        let table_name = s.split(['.', '=']).next().unwrap_or("").trim();
        if !SETTABLE.contains(&table_name) {
            return Err(invalid(format!(
                "{s}: only settings of [dataset], [events] and [trajectory] can be set (e.g. \
                 dataset.exposure_ms=40); change the rest of the scene in its file"
            )));
        }
    }
    let wording = SetWording {
        flag: "--set",
        example: "dataset.exposure_ms=40 or events.noise.leak_rate_hz=0.1",
        missing: "misspelt? the tables are [dataset], [events] and [trajectory]",
        create_tables: true,
    };
    // (the error's element is `--set` already)
    apply_sets(&mut table, sets, wording).map_err(|e| invalid(e.trim_start_matches("--set ").to_string()))?;
    table.try_into().map_err(|e: toml::de::Error| {
        invalid(format!(
            "after {}: {}; the settings are explained in docs/simulator.md (the [dataset] keys are listed \
                 under --set in `evsim dataset --help`)",
            sets.join(", "),
            e.message().trim_end()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_report_the_files_own_mistakes_with_their_line_and_their_own_by_the_set() {
        let path = Path::new("scene.toml");
        let file = |spp: &str| format!("scene = \"s.obj\"\n[dataset]\nspp = {spp}\n");
        let e = parse_with_sets(&file("\"two\""), path, &["dataset.width=8".into()]).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("spp"), "{e}");
        let e = parse_with_sets(&file("2"), path, &["dataset.width=wide".into()]).unwrap_err().to_string();
        assert!(e.contains("dataset.width=wide") && e.contains("invalid type"), "{e}");
        // a set may replace what the file gets wrong
        let d = parse_with_sets(&file("\"two\""), path, &["dataset.spp=2".into()]).unwrap();
        assert_eq!(d.dataset.map(|d| d.spp), Some(2));
    }
}
