//! `dataset.toml`, the manifest `evsim dataset` writes last (its presence marks a complete
//! dataset): every setting, the keys and the counts. Read strictly: an unparsable file, an
//! unknown key or a missing event-model value is an error, never a silent default (the trainer
//! takes its thresholds from here).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::settings::DatasetConfig;
use crate::events::EventConfig;
use crate::trajectory::TrajectoryConfig;

/// The file name, in the dataset folder.
pub const FILE: &str = "dataset.toml";

/// The first line of the file.
const HEADER: &str = "# evsim dataset manifest: written last, so its presence marks a complete dataset\n";

/// The manifest (no timings, so that the same inputs give the same bytes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetManifest {
    /// `evsim`.
    pub tool: String,
    /// The writing tool's version.
    pub version: String,
    /// The simulation pipeline's version (see [`super::plan::PIPELINE_VERSION`]).
    pub pipeline_version: u32,
    /// The scene file.
    pub scene: String,
    /// Hash of the scene's content.
    pub scene_key: String,
    /// Hash of everything that fixes the rendered frames.
    pub render_key: String,
    /// Hash of every setting.
    pub settings_hash: String,
    /// Rendered frames.
    pub frames: usize,
    /// Time between frames (ns).
    pub frame_period_ns: i64,
    /// Time of the first frame (ns).
    pub first_frame_ns: i64,
    /// Views (images in `images_1/`).
    pub views: usize,
    /// The sharp test views.
    pub sharp_views: Vec<usize>,
    /// Exposure of the blurry views (ns).
    pub exposure_ns: i64,
    /// Samples per pixel of the sharp renders; absent when they are the sequence frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sharp_spp: Option<u32>,
    /// Vertical field of view (degrees).
    pub yfov_deg: f64,
    /// Events in `events.h5`.
    pub events: u64,
    /// ON events.
    pub events_on: u64,
    /// OFF events.
    pub events_off: u64,
    /// The `[dataset]` settings.
    pub dataset: DatasetConfig,
    /// The event model.
    pub event_model: EventConfig,
    /// The camera trajectory.
    pub trajectory: TrajectoryConfig,
}

/// Event-model values a manifest must state (the struct would otherwise default them).
const REQUIRED_EVENT_MODEL: [&str; 3] = ["c_pos", "c_neg", "log_eps"];

impl DatasetManifest {
    /// The file's text.
    pub fn to_toml(&self) -> Result<String, String> {
        Ok(format!("{HEADER}{}", toml::to_string(self).map_err(|e| e.to_string())?))
    }

    /// Parses a manifest's text; the message says what is wrong (the caller names the file).
    pub fn parse(text: &str) -> Result<DatasetManifest, String> {
        let value: toml::Table = toml::from_str(text).map_err(|e| format!("not valid TOML: {e}"))?;
        let model = value.get("event_model").and_then(|m| m.as_table());
        for key in REQUIRED_EVENT_MODEL {
            if model.is_none_or(|m| !m.contains_key(key)) {
                return Err(format!("[event_model] has no {key}"));
            }
        }
        let m: DatasetManifest = toml::from_str(text).map_err(|e| e.to_string())?;
        let e = &m.event_model;
        for (key, v) in [("c_pos", e.c_pos), ("c_neg", e.c_neg), ("log_eps", e.log_eps)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("[event_model] {key} = {v}; it must be a positive number"));
            }
        }
        if m.events != m.events_on + m.events_off {
            return Err(format!("events = {} but events_on + events_off = {}", m.events, m.events_on + m.events_off));
        }
        Ok(m)
    }

    /// A small valid manifest (9 views of `scenes/tiny`, 30 events): for tests of readers.
    pub fn example() -> DatasetManifest {
        DatasetManifest {
            tool: "evsim".into(),
            version: "0.1.0".into(),
            pipeline_version: 10,
            scene: "scenes/tiny/scene.toml".into(),
            scene_key: "a".into(),
            render_key: "b".into(),
            settings_hash: "c".into(),
            frames: 250,
            frame_period_ns: 1_000_000,
            first_frame_ns: 0,
            views: 9,
            sharp_views: vec![0, 8],
            exposure_ns: 20_000_000,
            sharp_spp: None,
            yfov_deg: 39.3,
            events: 30,
            events_on: 10,
            events_off: 20,
            dataset: DatasetConfig::default(),
            event_model: EventConfig { c_pos: 0.5, c_neg: 0.4, ..EventConfig::default() },
            trajectory: TrajectoryConfig::FastMotion(crate::trajectory::FastMotion {
                target: [0.0; 3],
                radius: 3.9,
                height: Some(0.4),
                start_azimuth_deg: -12.0,
                sweep_deg: 24.0,
                bob: Some(0.3),
                duration: 0.25,
                keys: 9,
            }),
        }
    }

    /// Reads `dir/dataset.toml`: `Ok(None)` when there is none (public datasets have none).
    pub fn read(dir: &Path) -> Result<Option<DatasetManifest>, String> {
        let path = dir.join(FILE);
        if !path.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| format!("cannot be read: {e}"))?;
        DatasetManifest::parse(&text).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest() -> DatasetManifest {
        DatasetManifest::example()
    }

    #[test]
    fn a_manifest_reads_back_and_damage_is_refused_by_name() {
        let text = manifest().to_toml().unwrap();
        assert_eq!(DatasetManifest::parse(&text), Ok(manifest()));
        // a broken line appended (it used to be read as no manifest: threshold 0.2 for 0.5)
        let e = DatasetManifest::parse(&format!("{text}c_pos = \n")).unwrap_err();
        assert!(e.contains("not valid TOML") && e.contains("line"), "{e}");
        // an unknown key, at the top and inside a table
        let e = DatasetManifest::parse(&text.replace("tool = ", "colour = 1\ntool = ")).unwrap_err();
        assert!(e.contains("unknown field `colour`"), "{e}");
        let e = DatasetManifest::parse(&text.replace("c_pos = ", "c_pso = 0.5\nc_pos = ")).unwrap_err();
        assert!(e.contains("unknown field `c_pso`"), "{e}");
        // a missing threshold is not defaulted
        let without: String = text.lines().filter(|l| !l.starts_with("c_neg")).map(|l| format!("{l}\n")).collect();
        let e = DatasetManifest::parse(&without).unwrap_err();
        assert!(e.contains("[event_model] has no c_neg"), "{e}");
        let e = DatasetManifest::parse(&text.replace("c_pos = 0.5", "c_pos = -0.5")).unwrap_err();
        assert!(e.contains("c_pos = -0.5"), "{e}");
        let e = DatasetManifest::parse(&text.replace("events = 30", "events = 31")).unwrap_err();
        assert!(e.contains("events = 31"), "{e}");
        // no file is no manifest
        assert_eq!(DatasetManifest::read(Path::new("/nonexistent")), Ok(None));
    }
}
