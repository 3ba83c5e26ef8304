//! The manifest beside each table (`<form>.manifest.json`): the tool version and source commit
//! that made the table, the machine, and per cell (by key) its method, preset, overrides,
//! scale, scene, dataset identity, seed, steps, thread count, machine, commit (and the commit
//! of each session that trained it) and times (train, final scoring and the wall time over its
//! sessions, seconds).

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{format, Table};
use crate::error::BenchError;
use crate::metrics::{git_commit, CellMetrics, Machine, Session};

/// One cell in the manifest.
#[derive(Serialize)]
struct ManifestCell<'a> {
    /// The cell's folder, relative to the results.
    folder: &'a Path,
    #[serde(flatten)]
    metrics: ManifestMetrics<'a>,
}

/// The fields of a cell's metrics the manifest repeats (not the scores: they are the table).
#[derive(Serialize)]
struct ManifestMetrics<'a> {
    key: &'a str,
    method: &'a str,
    preset: &'a str,
    set: &'a [String],
    scale: trainer::presets::Scale,
    scene: &'a str,
    dataset: &'a str,
    seed: u64,
    steps: u64,
    threads: usize,
    machine: &'a Machine,
    git_commit: &'a str,
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    sessions: &'a [Session],
    tool_version: &'a str,
    train_seconds: f64,
    eval_seconds: f64,
    wall_seconds: f64,
}

impl<'a> From<&'a CellMetrics> for ManifestMetrics<'a> {
    fn from(m: &'a CellMetrics) -> ManifestMetrics<'a> {
        ManifestMetrics {
            key: &m.key,
            method: &m.method,
            preset: &m.preset,
            set: &m.set,
            scale: m.scale,
            scene: &m.scene,
            dataset: &m.dataset,
            seed: m.seed,
            steps: m.steps,
            threads: m.threads,
            machine: &m.machine,
            git_commit: &m.git_commit,
            sessions: &m.sessions,
            tool_version: &m.tool_version,
            train_seconds: m.train_seconds,
            eval_seconds: m.eval_seconds,
            wall_seconds: m.wall_seconds,
        }
    }
}

/// The manifest.
#[derive(Serialize)]
struct Manifest<'a> {
    tool: &'static str,
    version: &'static str,
    git_commit: &'static str,
    machine: Machine,
    form: &'static str,
    results: &'a Path,
    scenes: &'a [String],
    rows: Vec<&'a str>,
    seeds: Vec<u64>,
    total_wall_seconds: f64,
    cells: Vec<ManifestCell<'a>>,
}

/// The manifest of `table` (made from `results`) as pretty JSON.
pub fn manifest_json(table: &Table, results: &Path) -> String {
    let mut seeds: Vec<u64> = table.cells.iter().map(|(_, m)| m.seed).collect();
    seeds.sort_unstable();
    seeds.dedup();
    let manifest = Manifest {
        tool: "evbench",
        version: env!("CARGO_PKG_VERSION"),
        git_commit: git_commit(),
        machine: Machine::current(),
        form: table.form.name(),
        results,
        scenes: &table.scenes,
        rows: table.rows.iter().map(|r| r.label.as_str()).collect(),
        seeds,
        total_wall_seconds: table.cells.iter().map(|(_, m)| m.wall_seconds).sum(),
        cells: table
            .cells
            .iter()
            .map(|(folder, m)| ManifestCell { folder, metrics: ManifestMetrics::from(m) })
            .collect(),
    };
    serde_json::to_string_pretty(&manifest).expect("plain data serialises") + "\n"
}

/// Writes `<out>/<form>.{md,csv,tex,manifest.json}` atomically; returns their paths.
pub fn write_all(table: &Table, results: &Path, out: &Path) -> Result<Vec<PathBuf>, BenchError> {
    write_named(table, results, out, table.form.name())
}

/// Writes `<out>/<stem>.{md,csv,tex,manifest.json}` atomically; returns their paths.
pub fn write_named(table: &Table, results: &Path, out: &Path, stem: &str) -> Result<Vec<PathBuf>, BenchError> {
    let files = [
        (format!("{stem}.md"), format::markdown(table)),
        (format!("{stem}.csv"), format::csv(table)),
        (format!("{stem}.tex"), format::latex(table)),
        (format!("{stem}.manifest.json"), manifest_json(table, results)),
    ];
    let mut written = Vec::new();
    for (name, text) in files {
        let path = out.join(name);
        simulator::image_io::write_atomic(&path, text.as_bytes())
            .map_err(|e| BenchError::results(&path, format!("{e:#}")))?;
        written.push(path);
    }
    Ok(written)
}
