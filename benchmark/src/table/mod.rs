//! `evbench table`: every finished cell under a results folder (its `metrics.json`) merged into
//! the paper's tables, whichever shard or machine ran it.
//!
//! - **Table 1 form**: a row per method (in the preset registry's order, then by name), a
//!   column group per scene (by name) and the average over the scenes, each with PSNR (dB, up
//!   is better), LPIPS (down) and SSIM (up).
//! - **Ablation form**: a row per switch combination (a method's own overrides), the same
//!   columns; rows by preset, then by the number of switches.
//!
//! A row's score on a scene is the mean over its seeds; the average column needs every scene
//! (`-` otherwise) and LPIPS on every scene (`n/a` otherwise, as for a scene scored without
//! LPIPS weights). The best value of each column is bold (compared as printed; only with two
//! rows or more). Two results for one method, scene and seed (e.g. a stale cell from an older
//! matrix) are an error: delete one, or pass the matrix to keep its cells only.
//!
//! - [`format`](mod@format): Markdown, CSV and LaTeX.
//! - [`manifest`]: what a table was made from (versions, commits, keys, seeds, machines, times).
//! - [`figure`]: per scene, the blurry input, each row's render and the sharp ground truth of
//!   the test views side by side.

pub mod figure;
pub mod format;
pub mod manifest;

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::error::BenchError;
use crate::matrix::plan::RESERVED_DIRS;
use crate::metrics::{self, CellMetrics};

/// Which table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// Rows = methods (the paper's Table 1).
    Table1,
    /// Rows = switch combinations (the ablation table).
    Ablation,
}

impl Form {
    /// The file stem of this form's outputs.
    pub fn name(self) -> &'static str {
        match self {
            Form::Table1 => "table1",
            Form::Ablation => "ablation",
        }
    }
}

impl FromStr for Form {
    type Err = String;

    fn from_str(s: &str) -> Result<Form, String> {
        match s {
            "table1" => Ok(Form::Table1),
            "ablation" => Ok(Form::Ablation),
            _ => Err(format!("`{s}`: choose table1 or ablation")),
        }
    }
}

/// Scores of one row on one scene (or the average).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// PSNR (dB).
    pub psnr: f64,
    /// LPIPS; `None` when a cell has none.
    pub lpips: Option<f64>,
    /// SSIM.
    pub ssim: f64,
}

/// A row of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The label: the method's name (Table 1) or its switches (ablation).
    pub label: String,
    /// The preset.
    pub preset: String,
    /// The switches (the method's own overrides).
    pub switches: Vec<String>,
    /// Per scene (the table's order), then the average; `None` where no cell finished.
    pub scores: Vec<Option<Scores>>,
}

/// A table: scene column groups (plus the average) and rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Which form.
    pub form: Form,
    /// The scenes, in column order.
    pub scenes: Vec<String>,
    /// The rows, in order.
    pub rows: Vec<Row>,
    /// Whether the rows' scores end with the average over the scenes (an `Average` group).
    pub average: bool,
    /// The cells behind it, by key, with their folders relative to the results.
    pub cells: Vec<(PathBuf, CellMetrics)>,
}

/// Every `metrics.json` under `results` (not under `datasets/` or hidden folders), with the
/// folder relative to `results`; with `keys`, only those cells. Sorted by key.
pub fn collect(results: &Path, keys: Option<&HashSet<String>>) -> Result<Vec<(PathBuf, CellMetrics)>, BenchError> {
    if !results.is_dir() {
        return Err(BenchError::results(results, "is not a folder; give the results folder of evbench run"));
    }
    let mut found = Vec::new();
    walk(results, results, &mut found)?;
    if let Some(keys) = keys {
        found.retain(|(_, m)| keys.contains(&m.key));
    }
    found.sort_by(|a, b| a.1.key.cmp(&b.1.key).then_with(|| a.0.cmp(&b.0)));
    Ok(found)
}

fn walk(root: &Path, dir: &Path, out: &mut Vec<(PathBuf, CellMetrics)>) -> Result<(), BenchError> {
    let entries = std::fs::read_dir(dir).map_err(|e| BenchError::results(dir, format!("cannot list ({e})")))?;
    let mut entries: Vec<_> = entries.filter_map(Result::ok).map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if name.starts_with('.') || (dir == root && RESERVED_DIRS.contains(&name.as_str())) {
            continue;
        }
        if path.is_dir() {
            walk(root, &path, out)?;
        } else if name == metrics::FILE {
            let rel = dir.strip_prefix(root).expect("below the root").to_owned();
            out.push((rel, CellMetrics::read(&path)?));
        }
    }
    Ok(())
}

/// Checks that the cells tell one story: one result per method, scene and seed, and a method
/// name always meaning the same preset, overrides, scale and iteration count.
fn check(results: &Path, cells: &[(PathBuf, CellMetrics)]) -> Result<(), BenchError> {
    let mut by_cell: BTreeMap<(&str, &str, u64), &PathBuf> = BTreeMap::new();
    let mut by_method: BTreeMap<&str, (&PathBuf, &CellMetrics)> = BTreeMap::new();
    for (dir, m) in cells {
        if let Some(other) = by_cell.insert((&m.method, &m.scene, m.seed), dir) {
            return Err(BenchError::results(
                results,
                format!(
                    "two results for {} on {} with seed {}: {} and {}; delete the stale one or pass --config to keep the matrix's cells",
                    m.method,
                    m.scene,
                    m.seed,
                    other.display(),
                    dir.display()
                ),
            ));
        }
        match by_method.get(m.method.as_str()) {
            Some((odir, o)) if (&o.preset, &o.set, o.scale, o.steps) != (&m.preset, &m.set, m.scale, m.steps) => {
                return Err(BenchError::results(
                    results,
                    format!(
                        "method {} means two things: {} ({} {:?}, {:?}, {} steps) and {} ({} {:?}, {:?}, {} steps); \
                         delete the stale cells or pass --config to keep the matrix's",
                        m.method,
                        odir.display(),
                        o.preset,
                        o.set,
                        o.scale,
                        o.steps,
                        dir.display(),
                        m.preset,
                        m.set,
                        m.scale,
                        m.steps
                    ),
                ))
            }
            Some(_) => {}
            None => {
                by_method.insert(&m.method, (dir, m));
            }
        }
    }
    Ok(())
}

/// Position of `preset` in the registry (unknown presets last).
fn registry_index(preset: &str) -> usize {
    trainer::presets::PRESETS.iter().position(|p| p.name == preset).unwrap_or(usize::MAX)
}

/// The ablation label of `switches` (and of the preset when the table has several).
fn switch_label(preset: &str, switches: &[String], several_presets: bool) -> String {
    let s = if switches.is_empty() { "(preset)".to_string() } else { switches.join(", ") };
    if several_presets {
        format!("{preset}: {s}")
    } else {
        s
    }
}

/// Mean of `values` (`None` if empty).
fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// The mean scores of `cells` (`None` if empty); LPIPS only when every cell has it.
fn mean_scores(cells: &[&CellMetrics]) -> Option<Scores> {
    let lpips: Option<Vec<f64>> = cells.iter().map(|m| m.lpips).collect();
    Some(Scores {
        psnr: mean(cells.iter().map(|m| m.psnr))?,
        lpips: lpips.and_then(|l| mean(l.into_iter())),
        ssim: mean(cells.iter().map(|m| m.ssim))?,
    })
}

/// A matrix's part of a results folder: its cells' keys and its scenes in column order.
#[derive(Clone, Debug, Default)]
pub struct Selection {
    /// Keys of the cells to keep.
    pub keys: HashSet<String>,
    /// Scene names in column order.
    pub scenes: Vec<String>,
}

impl Selection {
    /// The cells and scene order of a resolved matrix.
    pub fn of(plan: &crate::matrix::MatrixPlan) -> Selection {
        Selection {
            keys: plan.cells.iter().map(|c| c.key.clone()).collect(),
            scenes: plan.scenes.iter().map(|s| s.name.clone()).collect(),
        }
    }
}

/// Builds the table of `form` from the cells under `results`: all of them, scenes by name, or
/// with `selection` those of a matrix, scenes in its order.
pub fn build(results: &Path, form: Form, selection: Option<&Selection>) -> Result<Table, BenchError> {
    let cells = collect(results, selection.map(|s| &s.keys))?;
    if cells.is_empty() {
        return Err(BenchError::results(
            results,
            "holds no finished cell (metrics.json); run evbench run first, or check the folder",
        ));
    }
    check(results, &cells)?;
    let present: std::collections::BTreeSet<String> = cells.iter().map(|(_, m)| m.scene.clone()).collect();
    let scenes: Vec<String> = match selection {
        Some(sel) => sel.scenes.iter().filter(|s| present.contains(*s)).cloned().collect(),
        None => present.into_iter().collect(),
    };
    let presets: HashSet<&str> = cells.iter().map(|(_, m)| m.preset.as_str()).collect();

    // Rows: (order key, label, preset, switches) -> cells.
    type RowKey = (usize, usize, String, String, Vec<String>);
    let mut groups: BTreeMap<RowKey, Vec<&CellMetrics>> = BTreeMap::new();
    for (_, m) in &cells {
        let key = match form {
            Form::Table1 => (registry_index(&m.preset), 0, m.method.clone(), m.preset.clone(), m.switches.clone()),
            Form::Ablation => {
                let label = switch_label(&m.preset, &m.switches, presets.len() > 1);
                (registry_index(&m.preset), m.switches.len(), label, m.preset.clone(), m.switches.clone())
            }
        };
        groups.entry(key).or_default().push(m);
    }
    let rows = groups
        .into_iter()
        .map(|((_, _, label, preset, switches), members)| {
            let mut scores: Vec<Option<Scores>> = scenes
                .iter()
                .map(|s| mean_scores(&members.iter().copied().filter(|m| &m.scene == s).collect::<Vec<_>>()))
                .collect();
            let average = scores.iter().copied().collect::<Option<Vec<Scores>>>().map(|per_scene| Scores {
                psnr: mean(per_scene.iter().map(|s| s.psnr)).expect("at least one scene"),
                lpips: per_scene
                    .iter()
                    .map(|s| s.lpips)
                    .collect::<Option<Vec<f64>>>()
                    .and_then(|l| mean(l.into_iter())),
                ssim: mean(per_scene.iter().map(|s| s.ssim)).expect("at least one scene"),
            });
            scores.push(average);
            Row { label, preset, switches, scores }
        })
        .collect();
    Ok(Table { form, scenes, rows, average: true, cells })
}

#[cfg(test)]
mod tests;
