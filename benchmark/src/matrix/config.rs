//! The run-matrix file as written: methods x scenes x seeds at one scale. Unknown keys are
//! errors; [`super::plan`] checks the values and resolves the file into cells.
//!
//! ```toml
//! scale = "cpu"                    # cpu | paper: the presets' scale
//! iterations = 400                 # optional: every cell's training iterations (a `set` wins)
//! seeds = [0]                      # training seeds; one cell per method x scene x seed
//! results = "runs/quick"           # optional: results folder (relative to the working dir)
//! set = ["eval_every=0"]           # optional: overrides for every method (evtrain --set)
//!
//! [dataset]                        # optional: simulator overrides for every simulated scene
//! width = 300
//! height = 200
//!
//! [[methods]]
//! preset = "nerf"                  # evtrain presets
//!
//! [[methods]]
//! preset = "ev-deblurnerf"
//! name = "ev-deblurnerf-no-edi"    # needed with `set`: the table row and results folder
//! set = ["edi=none"]
//!
//! [[scenes]]
//! scene = "../../scenes/tiny/scene.toml"   # simulated (relative to this file)
//! dataset = { spp = 2 }                     # optional: this scene's overrides
//! # (keys of the scene file's [dataset] table, the shorthands threshold, threshold_sigma,
//! # leak_rate_hz, shot_noise_rate_hz, refractory_ms and speed, and any setting of the scene
//! # file: set = ["events.c_pos=0.3"]; simulator::dataset::Overrides)
//!
//! [[scenes]]
//! name = "blurfactory"
//! data = "/data/ev-deblurblender/blurfactory"  # an existing dataset folder
//! ```

use std::path::PathBuf;

use serde::Deserialize;
use simulator::dataset::Overrides;
use trainer::presets::Scale;

/// A run-matrix file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatrixConfig {
    /// The presets' scale: `cpu` (sized for 2 cores) or `paper` (the reference settings).
    pub scale: Scale,
    /// Training iterations of every cell (count); default: each preset's at this scale. A
    /// `set = ["iterations=N"]` (the matrix's or a method's) wins over it.
    #[serde(default)]
    pub iterations: Option<u64>,
    /// Training seeds (initialisation, batches, noise); each method x scene runs once per seed.
    #[serde(default = "default_seeds")]
    pub seeds: Vec<u64>,
    /// The results folder, relative to the working directory (not to this file);
    /// `evbench run --results` overrides it. Default `runs/bench`.
    #[serde(default)]
    pub results: Option<PathBuf>,
    /// Overrides applied to every method before its own, `KEY=VALUE` in `evtrain --set` syntax
    /// (a dotted path of `evtrain presets --show NAME`; `none` switches a part off).
    #[serde(default)]
    pub set: Vec<String>,
    /// Simulator overrides for every simulated scene (a scene's own `dataset` wins key by key).
    #[serde(default)]
    pub dataset: DatasetOverrides,
    /// The methods: the rows of the table.
    pub methods: Vec<MethodEntry>,
    /// The scenes: the column groups of the table.
    pub scenes: Vec<SceneEntry>,
}

fn default_seeds() -> Vec<u64> {
    vec![0]
}

/// One method (a row of the table).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodEntry {
    /// A preset of the trainer's registry (`evtrain presets`).
    pub preset: String,
    /// The row label and results folder name (letters, digits, `-`, `_`, `.`, `+`); default the
    /// preset name, required when `set` is given.
    #[serde(default)]
    pub name: Option<String>,
    /// This method's overrides, `KEY=VALUE` in `evtrain --set` syntax, applied after the
    /// matrix's `set` (the ablation switches: `edi=none`, `blur.awp=none`, ...).
    #[serde(default)]
    pub set: Vec<String>,
}

/// One scene (a column group of the table): exactly one of `scene` and `data`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneEntry {
    /// The column label and results folder name (letters, digits, `-`, `_`, `.`, `+`); default
    /// the scene's folder name (`scenes/tiny/scene.toml` -> `tiny`) or the dataset folder's.
    #[serde(default)]
    pub name: Option<String>,
    /// A scene file (`scene.toml` with a `[trajectory]`, or its folder) to simulate, relative
    /// to this matrix file; the dataset goes to `<results>/datasets/<hash>/` (reused if there).
    #[serde(default)]
    pub scene: Option<PathBuf>,
    /// An existing dataset folder (ours or a public Ev-DeblurBlender one), relative to this
    /// matrix file; used as it is (no overrides).
    #[serde(default)]
    pub data: Option<PathBuf>,
    /// This scene's simulator overrides, over the matrix's `[dataset]` key by key (its `set`
    /// after the matrix's).
    #[serde(default)]
    pub dataset: DatasetOverrides,
}

/// Simulator overrides of a matrix's or a scene's `dataset` table (the simulator's own type):
/// keys of the scene file's `[dataset]` table, the shorthands `threshold`, `threshold_sigma`,
/// `leak_rate_hz`, `shot_noise_rate_hz`, `refractory_ms`, `speed`, and `set`; any other key is
/// rejected when the matrix is planned.
pub type DatasetOverrides = Overrides;
