//! A sweep file resolved into one [`MatrixPlan`] per point (a combination of the axes' values)
//! before any work starts: every point's overrides are checked by the simulator and the trainer,
//! so a typo in a setting or a bad value is reported with the file and the axis.
//!
//! All points share one results folder: a point's cells have their own keys (the dataset
//! identity or the training configuration differs), and its datasets their own hashes.

use std::path::{Path, PathBuf};

use super::config::{AxisSpec, SweepSpec};
use crate::error::BenchError;
use crate::matrix::config::{DatasetOverrides, MatrixConfig};
use crate::matrix::MatrixPlan;

/// Where a swept setting goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Setting {
    /// A key of the matrix's `dataset` table: of the scene file's `[dataset]` table, or a
    /// shorthand of the simulator's overrides.
    Dataset(String),
    /// An `evtrain --set` key.
    Train(String),
}

/// One value of an axis.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisValue {
    /// Where it is plotted.
    pub x: f64,
    /// How it is printed (`5`, `0.25`, `[0.3, 0.3]`).
    pub text: String,
    /// The value as given.
    pub value: toml::Value,
}

/// A resolved axis.
#[derive(Clone, Debug)]
pub struct Axis {
    /// The setting as written (`dataset.exposure_ms`).
    pub name: String,
    /// Where it goes.
    pub setting: Setting,
    /// Axis label.
    pub label: String,
    /// The values, in order.
    pub values: Vec<AxisValue>,
}

/// One point of the sweep: a value index per axis and its matrix.
#[derive(Debug)]
pub struct Point {
    /// Index into each axis's values.
    pub index: Vec<usize>,
    /// The matrix with this point's overrides.
    pub plan: MatrixPlan,
}

/// A resolved sweep.
#[derive(Debug)]
pub struct SweepPlan {
    /// The sweep file.
    pub file: PathBuf,
    /// Title of the tables and figures.
    pub title: String,
    /// One or two axes.
    pub axes: Vec<Axis>,
    /// Every combination, the first axis varying fastest.
    pub points: Vec<Point>,
    /// The shared results folder.
    pub results: PathBuf,
}

impl SweepPlan {
    /// Reads and resolves the sweep file `file`; `results` replaces the file's results folder.
    pub fn load(file: &Path, results: Option<&Path>) -> Result<SweepPlan, BenchError> {
        let bad = |field: &str, message: String| BenchError::config(file, field, message);
        let text =
            std::fs::read_to_string(file).map_err(|e| bad("file", format!("cannot read ({e}); check the path")))?;
        let mut table: toml::Table = toml::from_str(&text).map_err(|e| bad("toml", e.message().trim_end().into()))?;
        let spec = table.remove("sweep").ok_or_else(|| {
            bad(
                "sweep",
                "missing; add a [sweep] table with [[sweep.axes]] setting = \"dataset.exposure_ms\", values = [5, 10] \
                 (or run a plain matrix with evbench run)"
                    .into(),
            )
        })?;
        let spec: SweepSpec =
            spec.try_into().map_err(|e: toml::de::Error| bad("sweep", e.message().trim_end().into()))?;
        let cfg: MatrixConfig = toml::Value::Table(table).try_into().map_err(|e: toml::de::Error| {
            bad("matrix", format!("{}; see benchmark/src/matrix/config.rs", e.message().trim_end()))
        })?;
        SweepPlan::resolve(file, &cfg, &spec, results)
    }

    /// Resolves a parsed sweep (see [`SweepPlan::load`]).
    pub fn resolve(
        file: &Path,
        cfg: &MatrixConfig,
        spec: &SweepSpec,
        results: Option<&Path>,
    ) -> Result<SweepPlan, BenchError> {
        let bad = |field: String, message: String| BenchError::config(file, field, message);
        if spec.axes.is_empty() || spec.axes.len() > 2 {
            return Err(bad(
                "sweep.axes".into(),
                format!("has {} axes; give one or two [[sweep.axes]] tables", spec.axes.len()),
            ));
        }
        let axes: Vec<Axis> = spec
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| resolve_axis(a).map_err(|m| bad(format!("sweep.axes[{i}]"), m)))
            .collect::<Result<_, _>>()?;
        if axes.len() == 2 && axes[0].name == axes[1].name {
            return Err(bad(
                "sweep.axes[1].setting".into(),
                format!("`{}` is swept twice; drop one axis", axes[0].name),
            ));
        }
        let mut points = Vec::new();
        let n0 = axes[0].values.len();
        let n1 = axes.get(1).map_or(1, |a| a.values.len());
        for j in 0..n1 {
            for i in 0..n0 {
                let index: Vec<usize> = if axes.len() == 2 { vec![i, j] } else { vec![i] };
                let mut point_cfg = cfg.clone();
                let mut where_ = Vec::new();
                for (a, &v) in axes.iter().zip(&index) {
                    apply(&mut point_cfg, &a.setting, &a.values[v].value)
                        .map_err(|m| bad(format!("sweep.axes: {} = {}", a.name, a.values[v].text), m))?;
                    where_.push(format!("{} = {}", a.name, a.values[v].text));
                }
                let plan = MatrixPlan::resolve(file, &point_cfg, results).map_err(|e| match e {
                    BenchError::Config { file, field, message } => {
                        BenchError::Config { file, field: format!("{field} (at {})", where_.join(", ")), message }
                    }
                    other => other,
                })?;
                points.push(Point { index, plan });
            }
        }
        // Every value must change something: a point whose cells are another point's cells
        // (an override that the matrix or a method overrides again) would repeat one result.
        let mut seen: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
        for (p, point) in points.iter().enumerate() {
            for cell in &point.plan.cells {
                if let Some(&q) = seen.get(cell.key.as_str()) {
                    let method = &point.plan.methods[cell.method].name;
                    return Err(bad(
                        "sweep.axes".into(),
                        format!(
                            "`{}` and `{}` give method `{method}` the same configuration (cell {}): the swept \
                             setting does not reach it (a method's own `set` of the same key wins); sweep \
                             another setting or drop that method's override",
                            point_text(&axes, &points[q].index),
                            point_text(&axes, &point.index),
                            cell.key
                        ),
                    ));
                }
                seen.insert(&cell.key, p);
            }
        }
        let title = spec.title.clone().unwrap_or_else(|| {
            file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "sweep".into())
        });
        let results = points[0].plan.results.clone();
        Ok(SweepPlan { file: file.to_owned(), title, axes, points, results })
    }
}

impl SweepPlan {
    /// Point `p`'s values, printed (`dataset.exposure_ms = 5, train.events.threshold = [0.3, 0.3]`).
    pub fn point_text(&self, p: usize) -> String {
        point_text(&self.axes, &self.points[p].index)
    }
}

fn point_text(axes: &[Axis], index: &[usize]) -> String {
    let v: Vec<String> = axes.iter().zip(index).map(|(a, &i)| format!("{} = {}", a.name, a.values[i].text)).collect();
    v.join(", ")
}

fn resolve_axis(a: &AxisSpec) -> Result<Axis, String> {
    let setting = match a.setting.split_once('.') {
        Some(("dataset", f)) if !f.is_empty() => Setting::Dataset(f.to_string()),
        Some(("train", "seed")) => {
            return Err("setting `train.seed`: the matrix's `seeds` list gives the seeds; list them there".into())
        }
        Some(("train", k)) if !k.is_empty() => Setting::Train(k.to_string()),
        _ => {
            return Err(format!(
                "setting `{}`: expected dataset.<key> (a key of the scene file's [dataset] table or a \
                 shorthand such as threshold; e.g. dataset.exposure_ms) or train.<key> (e.g. \
                 train.events.threshold)",
                a.setting
            ))
        }
    };
    if a.values.is_empty() {
        return Err("values is empty; list the values to sweep".into());
    }
    let mut values: Vec<AxisValue> = Vec::new();
    for v in &a.values {
        let x = match v {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) => Some(*f),
            toml::Value::Array(items) => match items.first() {
                Some(toml::Value::Integer(i)) => Some(*i as f64),
                Some(toml::Value::Float(f)) => Some(*f),
                _ => None,
            },
            _ => None,
        };
        let text = v.to_string();
        let Some(x) = x.filter(|x| x.is_finite()) else {
            return Err(format!("value {text}: give finite numbers, or arrays of numbers (plotted at the first)"));
        };
        if values.iter().any(|o| o.text == text) {
            return Err(format!("value {text} appears twice; list each value once"));
        }
        values.push(AxisValue { x, text, value: v.clone() });
    }
    let label = a.label.clone().unwrap_or_else(|| a.setting.clone());
    Ok(Axis { name: a.setting.clone(), setting, label, values })
}

/// Puts one axis value into a matrix configuration.
fn apply(cfg: &mut MatrixConfig, setting: &Setting, value: &toml::Value) -> Result<(), String> {
    match setting {
        Setting::Dataset(field) => {
            let mut t = toml::Table::new();
            t.insert(field.clone(), value.clone());
            let keys = "dataset.<key> takes a key of a scene file's [dataset] table (exposure_ms, views, width, ...: \
                        simulator::dataset::DatasetConfig, docs/simulator.md) or a shorthand of \
                        simulator::dataset::Overrides (threshold, threshold_sigma, leak_rate_hz, shot_noise_rate_hz, \
                        refractory_ms, speed)";
            let o: DatasetOverrides = toml::Value::Table(t)
                .try_into()
                .map_err(|e: toml::de::Error| format!("{}; {keys}", e.message().trim_end()))?;
            if field == "set" {
                return Err(format!("dataset.set cannot be swept; {keys}"));
            }
            o.validate().map_err(|(_, message)| message)?;
            cfg.dataset = cfg.dataset.merged(&o);
            for s in &mut cfg.scenes {
                s.dataset = s.dataset.merged(&o);
            }
        }
        // the matrix's own `iterations` would be applied after `set`: sweep that instead
        Setting::Train(key) if key == "iterations" => match value.as_integer() {
            Some(n) if n > 0 => cfg.iterations = Some(n as u64),
            _ => return Err(format!("iterations must be a positive integer, not {value}")),
        },
        Setting::Train(key) => cfg.set.push(format!("{key}={value}")),
    }
    Ok(())
}
