//! A sweep file: a run matrix (every field of `benchmark/src/matrix/config.rs`) plus a `[sweep]`
//! table naming one or two settings and their values:
//!
//! ```toml
//! scale = "cpu"
//! [[methods]]
//! preset = "ev-deblurnerf"
//! [[scenes]]
//! scene = "../../scenes/factory/scene.toml"
//!
//! [sweep]
//! title = "Robustness to blur"
//! [[sweep.axes]]
//! setting = "dataset.exposure_ms"     # a simulator override (a re-simulated dataset per value)
//! values = [5, 10, 20, 30, 40]
//! label = "exposure (ms)"
//! ```
//!
//! A `dataset.<key>` setting is a key of the matrix's `[dataset]` table (the simulator's
//! overrides, `simulator::dataset::Overrides`): a key of the scene file's `[dataset]` table
//! (`exposure_ms`, `views`, `width`, ...) or a shorthand (`threshold`, `threshold_sigma`,
//! `leak_rate_hz`, `shot_noise_rate_hz`, `refractory_ms`, `speed`), set on every scene over the
//! scene's own value. A `train.<key>` setting is an `evtrain --set` key (`events.threshold`,
//! `iterations`, ...) appended to the matrix's `set`, so a method's own `set` of the same key wins.

use serde::Deserialize;

/// The `[sweep]` table.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Title of the tables and figures; default the file's stem.
    pub title: Option<String>,
    /// One or two swept settings. The first is the x axis; a second one splits every method's
    /// line into one line per value.
    pub axes: Vec<AxisSpec>,
}

/// One swept setting (`[[sweep.axes]]`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// `dataset.<key>` (a simulator override) or `train.<key>` (an `evtrain --set` key).
    pub setting: String,
    /// The values, in plotting order: numbers, or arrays of numbers (plotted at their first
    /// element, e.g. `events.threshold = [0.3, 0.3]`).
    pub values: Vec<toml::Value>,
    /// Axis label (with its unit); default the setting.
    pub label: Option<String>,
}
