//! A matrix file resolved into a [`MatrixPlan`] before any work starts: every preset, override
//! and scene checked, each scene's dataset identity computed (scenes to simulate are planned by
//! the simulator, which loads them), and the cells (method x scene x seed) with their keys,
//! sorted by key.
//!
//! Results layout: `<results>/<scene>/<method>/<key>/` per cell (the trainer's run folder:
//! `config.toml`, `checkpoint.bin`, `log.csv`; then `eval/NN.png` and `metrics.json`), and
//! `<results>/datasets/<hash>/` per simulated dataset (`hash` = the first 16 hex digits of its
//! identity).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use trainer::config::{apply_overrides, TrainConfig};
use trainer::presets::{self, Preset, Scale};

use super::config::{DatasetOverrides, MatrixConfig};
use super::identity::{cell_key, folder_identity, KEY_LEN};
use crate::error::BenchError;

/// Results folder when neither the file nor the command line gives one.
pub const DEFAULT_RESULTS: &str = "runs/bench";
/// Folder under the results that holds simulated datasets (a reserved scene name).
pub const DATASETS_DIR: &str = "datasets";
/// Folder under the results that holds a sweep's shared frame cache.
pub const FRAMES_DIR: &str = "frames";
/// Folder under the results that holds a sweep's tables and figures.
pub const SWEEP_DIR: &str = "sweep";
/// Folders under the results that are not scenes (reserved scene names).
pub const RESERVED_DIRS: [&str; 3] = [DATASETS_DIR, FRAMES_DIR, SWEEP_DIR];

/// A resolved run matrix.
#[derive(Debug)]
pub struct MatrixPlan {
    /// The matrix file.
    pub file: PathBuf,
    /// The results folder.
    pub results: PathBuf,
    /// The presets' scale.
    pub scale: Scale,
    /// The methods, in file order.
    pub methods: Vec<MethodPlan>,
    /// The scenes, in file order.
    pub scenes: Vec<ScenePlan>,
    /// Every cell, sorted by key.
    pub cells: Vec<Cell>,
}

/// A method: a preset with overrides.
#[derive(Clone, Debug)]
pub struct MethodPlan {
    /// Row label and folder name.
    pub name: String,
    /// The preset.
    pub preset: &'static Preset,
    /// Every override applied (the matrix's, then the method's own), in order.
    pub set: Vec<String>,
    /// The method's own overrides (its switches in the ablation table).
    pub switches: Vec<String>,
    /// The configuration with the overrides and the iteration count applied (seed 0).
    pub config: TrainConfig,
}

/// Where a scene's dataset comes from.
#[derive(Debug)]
pub enum SceneSource {
    /// Simulated into `<results>/datasets/<hash>/` from this plan.
    Simulate(Box<simulator::dataset::Plan>),
    /// An existing dataset folder.
    Folder(PathBuf),
}

/// A scene: where its dataset comes from and what it is.
#[derive(Debug)]
pub struct ScenePlan {
    /// Column label and folder name.
    pub name: String,
    /// Where the dataset comes from.
    pub source: SceneSource,
    /// The dataset identity (64 hex digits; module `identity`).
    pub identity: String,
}

impl ScenePlan {
    /// The dataset folder the cells of this scene train on.
    pub fn dataset_dir(&self, results: &Path) -> PathBuf {
        match &self.source {
            SceneSource::Simulate(_) => results.join(DATASETS_DIR).join(&self.identity[..KEY_LEN]),
            SceneSource::Folder(dir) => dir.clone(),
        }
    }
}

/// One training run: a method on a scene with a seed.
#[derive(Clone, Debug)]
pub struct Cell {
    /// The key (16 hex digits).
    pub key: String,
    /// Index into [`MatrixPlan::methods`].
    pub method: usize,
    /// Index into [`MatrixPlan::scenes`].
    pub scene: usize,
    /// Training seed.
    pub seed: u64,
    /// The method's configuration with this seed (threads 0: chosen at run time).
    pub config: TrainConfig,
}

impl MatrixPlan {
    /// Reads and resolves the matrix file `file`; `results` replaces the file's results folder.
    pub fn load(file: &Path, results: Option<&Path>) -> Result<MatrixPlan, BenchError> {
        let text = std::fs::read_to_string(file)
            .map_err(|e| BenchError::config(file, "file", format!("cannot read ({e}); check the path")))?;
        let cfg: MatrixConfig = toml::from_str(&text).map_err(|e| parse_error(file, &text, &e))?;
        MatrixPlan::resolve(file, &cfg, results)
    }

    /// Resolves a parsed matrix file (see [`MatrixPlan::load`]).
    pub fn resolve(file: &Path, cfg: &MatrixConfig, results: Option<&Path>) -> Result<MatrixPlan, BenchError> {
        let bad = |field: String, message: String| BenchError::config(file, field, message);
        let base = file.parent().unwrap_or(Path::new(""));
        if cfg.seeds.is_empty() {
            return Err(bad("seeds".into(), "is empty; give at least one, e.g. seeds = [0]".into()));
        }
        if let Some(s) = cfg.seeds.iter().enumerate().find_map(|(i, s)| cfg.seeds[..i].contains(s).then_some(s)) {
            return Err(bad("seeds".into(), format!("{s} appears twice; list each seed once")));
        }
        if cfg.iterations == Some(0) {
            return Err(bad("iterations".into(), "0; give a positive count or drop it for the presets' own".into()));
        }
        let methods = resolve_methods(file, cfg)?;
        let scenes = resolve_scenes(file, base, cfg)?;

        let mut cells = Vec::new();
        let mut seen: HashMap<String, usize> = HashMap::new();
        for (m, method) in methods.iter().enumerate() {
            for (s, scene) in scenes.iter().enumerate() {
                for &seed in &cfg.seeds {
                    let config = TrainConfig { seed, ..method.config.clone() };
                    let key = cell_key(method.preset.name, cfg.scale, &scene.identity, &config);
                    if let Some(&other) = seen.get(&key) {
                        return Err(bad(
                            format!("methods[{m}]"),
                            format!(
                                "`{}` resolves to the same configuration as methods[{other}] `{}`; drop one of them",
                                method.name, methods[other].name
                            ),
                        ));
                    }
                    seen.insert(key.clone(), m);
                    cells.push(Cell { key, method: m, scene: s, seed, config });
                }
            }
        }
        cells.sort_by(|a, b| a.key.cmp(&b.key));
        let results = results
            .map(Path::to_owned)
            .or_else(|| cfg.results.clone())
            .unwrap_or_else(|| PathBuf::from(DEFAULT_RESULTS));
        Ok(MatrixPlan { file: file.to_owned(), results, scale: cfg.scale, methods, scenes, cells })
    }

    /// The run folder of `cell`: `<results>/<scene>/<method>/<key>/`.
    pub fn cell_dir(&self, cell: &Cell) -> PathBuf {
        self.results.join(&self.scenes[cell.scene].name).join(&self.methods[cell.method].name).join(&cell.key)
    }
}

/// A TOML error as the field error of `file`: its line and the parser's message.
fn parse_error(file: &Path, text: &str, e: &toml::de::Error) -> BenchError {
    let line = e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
    BenchError::config(
        file,
        line.map_or("toml".into(), |l| format!("line {l}")),
        format!("{}; every field is documented in benchmark/src/matrix/config.rs", e.message().trim_end()),
    )
}

/// Whether `name` can be a table label and a folder name.
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '+'))
}

const NAME_RULE: &str = "use letters, digits, '-', '_', '.' and '+' (not first '.')";

fn resolve_methods(file: &Path, cfg: &MatrixConfig) -> Result<Vec<MethodPlan>, BenchError> {
    let bad = |field: String, message: String| BenchError::config(file, field, message);
    if cfg.methods.is_empty() {
        return Err(bad("methods".into(), "is empty; add a [[methods]] table with preset = \"nerf\"".into()));
    }
    let mut out: Vec<MethodPlan> = Vec::new();
    for (i, m) in cfg.methods.iter().enumerate() {
        let Some(preset) = presets::preset(&m.preset) else {
            return Err(bad(
                format!("methods[{i}].preset"),
                format!("`{}` is not a preset; choose one of {}", m.preset, presets::names().join(", ")),
            ));
        };
        let name = match (&m.name, m.set.is_empty()) {
            (Some(n), _) => n.clone(),
            (None, true) => preset.name.to_string(),
            (None, false) => {
                return Err(bad(
                    format!("methods[{i}].name"),
                    "missing; a method with `set` needs a name (its table row and results folder)".into(),
                ))
            }
        };
        if !valid_name(&name) {
            return Err(bad(format!("methods[{i}].name"), format!("`{name}`: {NAME_RULE}")));
        }
        if let Some(j) = out.iter().position(|o| o.name == name) {
            return Err(bad(
                format!("methods[{i}].name"),
                format!("`{name}` is also methods[{j}]'s name; give each method its own name"),
            ));
        }
        // the more specific wins: the preset, the matrix's iterations, its set, the method's set
        let mut base = (preset.build)(cfg.scale);
        if let Some(n) = cfg.iterations {
            base.iterations = n;
            base.validate().map_err(|e| bad("iterations".into(), format!("{e} (methods[{i}])")))?;
        }
        let base = apply_overrides(&base, &cfg.set)
            .map_err(|e| bad("set".into(), format!("{e} (preset {} of methods[{i}])", preset.name)))?;
        let config = apply_overrides(&base, &m.set)
            .map_err(|e| bad(format!("methods[{i}].set"), format!("{e} (preset {})", preset.name)))?;
        let set: Vec<String> = cfg.set.iter().chain(&m.set).cloned().collect();
        out.push(MethodPlan { name, preset, set, switches: m.set.clone(), config });
    }
    Ok(out)
}

/// The default scene name: the folder of `scene.toml`, or the file's stem, or the folder's name.
fn default_scene_name(path: &Path) -> String {
    let file_name = |p: &Path| p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    if path.is_dir() {
        return file_name(path);
    }
    match (path.file_name().and_then(|n| n.to_str()), path.parent()) {
        (Some("scene.toml"), Some(parent)) => file_name(parent),
        _ => path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
    }
}

fn resolve_scenes(file: &Path, base: &Path, cfg: &MatrixConfig) -> Result<Vec<ScenePlan>, BenchError> {
    let bad = |field: String, message: String| BenchError::config(file, field, message);
    if cfg.scenes.is_empty() {
        return Err(bad(
            "scenes".into(),
            "is empty; add a [[scenes]] table with scene = \"path/to/scene.toml\" or data = \"dataset folder\"".into(),
        ));
    }
    // the dataset tables' keys and shorthands, named as in the matrix before any scene is read
    let in_table = |key: String| if key.starts_with("dataset.") { key } else { format!("dataset.{key}") };
    cfg.dataset.validate().map_err(|(key, message)| bad(in_table(key), message))?;
    for (i, s) in cfg.scenes.iter().enumerate() {
        s.dataset.validate().map_err(|(key, message)| bad(format!("scenes[{i}].{}", in_table(key)), message))?;
    }
    let mut out: Vec<ScenePlan> = Vec::new();
    for (i, s) in cfg.scenes.iter().enumerate() {
        let (path, simulate) = match (&s.scene, &s.data) {
            (Some(p), None) => (base.join(p), true),
            (None, Some(p)) => (base.join(p), false),
            _ => {
                return Err(bad(
                    format!("scenes[{i}]"),
                    "give exactly one of `scene` (a scene.toml to simulate) and `data` (a dataset folder)".into(),
                ))
            }
        };
        let field = format!("scenes[{i}].{}", if simulate { "scene" } else { "data" });
        if !path.exists() {
            return Err(bad(field, format!("{} does not exist; paths are relative to this file", path.display())));
        }
        let name = s.name.clone().unwrap_or_else(|| default_scene_name(&path));
        if !valid_name(&name) || RESERVED_DIRS.contains(&name.as_str()) {
            return Err(bad(
                format!("scenes[{i}].name"),
                format!("`{name}`: {NAME_RULE}; {} are reserved (set name = ...)", RESERVED_DIRS.join(", ")),
            ));
        }
        if let Some(j) = out.iter().position(|o| o.name == name) {
            return Err(bad(
                format!("scenes[{i}].name"),
                format!("`{name}` is also scenes[{j}]'s name; set name = ... on one of them"),
            ));
        }
        let (source, identity) = if simulate {
            let overrides: DatasetOverrides = cfg.dataset.merged(&s.dataset);
            let plan = simulator::dataset::Plan::resolve(&path, &overrides).map_err(|e| bad(field, format!("{e}")))?;
            let identity = plan.settings_hash.clone();
            (SceneSource::Simulate(Box::new(plan)), identity)
        } else {
            if !s.dataset.is_empty() || !cfg.dataset.is_empty() {
                return Err(bad(
                    format!("scenes[{i}].dataset"),
                    "a dataset folder is used as it is; drop the dataset overrides (also the matrix's [dataset]) \
                     or give its scene.toml as `scene`"
                        .into(),
                ));
            }
            if !path.is_dir() {
                return Err(bad(field, format!("{} is not a folder; give the dataset folder", path.display())));
            }
            let identity = folder_identity(&path)?;
            (SceneSource::Folder(path), identity)
        };
        out.push(ScenePlan { name, source, identity });
    }
    Ok(out)
}

#[cfg(test)]
#[path = "plan_tests.rs"]
mod tests;
