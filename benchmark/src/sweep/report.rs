//! A sweep's results as tables and figures: one per scene, written to `<results>/sweep/`.
//!
//! - Table (`<stem>-<scene>.{md,csv,tex,manifest.json}`): a row per line (a method, or a method
//!   and a value of the second axis), a column group per value of the first axis (PSNR / LPIPS /
//!   SSIM), best in bold; whatever cells are finished (`-` for the others).
//! - Figure (`<stem>-<scene>.png`): the metric vs the swept value, one line per row, PSNR solid
//!   on the left axis and LPIPS dashed on the right (SSIM when no cell has LPIPS: no weights).

use std::path::{Path, PathBuf};

use super::plan::SweepPlan;
use super::SWEEP_DIR;
use crate::error::BenchError;
use crate::metrics::{self, CellMetrics};
use crate::plot::{self, Figure, Series};
use crate::table::{manifest, Form, Row, Scores, Table};

/// The table of one scene.
pub fn scene_table(plan: &SweepPlan, scene: usize) -> Result<Table, BenchError> {
    let base = &plan.points[0].plan;
    let axis0 = &plan.axes[0];
    let lines1 = plan.axes.get(1).map_or(1, |a| a.values.len());
    let mut rows = Vec::new();
    let mut cells: Vec<(PathBuf, CellMetrics)> = Vec::new();
    for j in 0..lines1 {
        for (m, method) in base.methods.iter().enumerate() {
            let label = match plan.axes.get(1) {
                Some(a) => format!("{}, {} = {}", method.name, a.label, a.values[j].text),
                None => method.name.clone(),
            };
            let mut scores = Vec::with_capacity(axis0.values.len());
            for i in 0..axis0.values.len() {
                let point = plan.points.iter().find(|p| p.index[0] == i && p.index.get(1).is_none_or(|&b| b == j));
                let point = point.expect("every combination is a point");
                let mut found = Vec::new();
                for cell in point.plan.cells.iter().filter(|c| c.method == m && c.scene == scene) {
                    let dir = point.plan.cell_dir(cell);
                    let file = dir.join(metrics::FILE);
                    if file.is_file() {
                        let metrics = CellMetrics::read(&file)?;
                        let folder = dir.strip_prefix(&plan.results).unwrap_or(&dir).to_path_buf();
                        found.push(metrics.clone());
                        cells.push((folder, metrics));
                    }
                }
                scores.push(mean(&found));
            }
            rows.push(Row { label, preset: method.preset.name.to_string(), switches: method.switches.clone(), scores });
        }
    }
    let columns = axis0.values.iter().map(|v| format!("{} = {}", axis0.label, v.text)).collect();
    cells.sort_by(|a, b| a.1.key.cmp(&b.1.key));
    Ok(Table { form: Form::Table1, scenes: columns, rows, average: false, cells })
}

/// Mean scores over seeds; LPIPS only if every seed has it.
fn mean(found: &[CellMetrics]) -> Option<Scores> {
    if found.is_empty() {
        return None;
    }
    let n = found.len() as f64;
    let lpips = found.iter().map(|m| m.lpips).sum::<Option<f64>>().map(|s| s / n);
    Some(Scores {
        psnr: found.iter().map(|m| m.psnr).sum::<f64>() / n,
        lpips,
        ssim: found.iter().map(|m| m.ssim).sum::<f64>() / n,
    })
}

/// The figure of one scene's table (see the module doc); `None` when no cell is finished.
pub fn figure(plan: &SweepPlan, scene_name: &str, table: &Table) -> Option<Figure> {
    let axis0 = &plan.axes[0];
    let xs: Vec<f64> = axis0.values.iter().map(|v| v.x).collect();
    // Legend labels: the method, and the second axis's value (its name goes into the title).
    let methods = &plan.points[0].plan.methods;
    let label = |r: usize| match plan.axes.get(1) {
        Some(a) => format!("{}, {}", methods[r % methods.len()].name, a.values[r / methods.len()].text),
        None => methods[r % methods.len()].name.clone(),
    };
    let series = |f: &dyn Fn(&Scores) -> Option<f64>| -> Vec<Series> {
        table
            .rows
            .iter()
            .enumerate()
            .map(|(i, r)| Series {
                label: label(i),
                points: xs
                    .iter()
                    .zip(&r.scores)
                    .map(|(&x, s)| (x, s.as_ref().and_then(f).unwrap_or(f64::NAN)))
                    .collect(),
            })
            .collect()
    };
    let left = series(&|s| Some(s.psnr));
    if left.iter().all(|s| s.points.iter().all(|p| p.1.is_nan())) {
        return None;
    }
    let has_lpips = table.rows.iter().flat_map(|r| &r.scores).flatten().any(|s| s.lpips.is_some());
    let (right_label, right) = if has_lpips {
        ("LPIPS (dashed, lower is better)".to_string(), series(&|s| s.lpips))
    } else {
        ("SSIM (dashed; LPIPS: no weights)".to_string(), series(&|s| Some(s.ssim)))
    };
    // the scene goes into the title unless the sweep's title already names it
    let head =
        if plan.title.contains(scene_name) { plan.title.clone() } else { format!("{}: {scene_name}", plan.title) };
    Some(Figure {
        title: match plan.axes.get(1) {
            Some(a) => format!("{head}; lines: method, {}", a.label),
            None => head,
        },
        x_label: axis0.label.clone(),
        left_label: "PSNR (dB, solid)".into(),
        left,
        right_label: Some(right_label),
        right,
        x_ticks: axis0.values.iter().map(|v| (v.x, v.text.clone())).collect(),
    })
}

/// Writes every scene's table and figure under `<results>/sweep/`; returns the files written.
pub fn write(plan: &SweepPlan) -> Result<Vec<PathBuf>, BenchError> {
    let out = plan.results.join(SWEEP_DIR);
    std::fs::create_dir_all(&out)
        .map_err(|e| BenchError::results(&out, format!("cannot create ({e}); check the results folder")))?;
    let stem = file_stem(&plan.file);
    let mut written = Vec::new();
    for (s, scene) in plan.points[0].plan.scenes.iter().enumerate() {
        let table = scene_table(plan, s)?;
        let name = format!("{stem}-{}", scene.name);
        written.extend(manifest::write_named(&table, &plan.results, &out, &name)?);
        if let Some(fig) = figure(plan, &scene.name, &table) {
            let png = out.join(format!("{name}.png"));
            plot::write_png(&fig, &png)?;
            written.push(png);
        }
    }
    Ok(written)
}

fn file_stem(file: &Path) -> String {
    file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "sweep".into())
}
