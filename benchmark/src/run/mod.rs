//! `evbench run`: the cells of a shard, one after the other, each using every worker thread.
//!
//! For each cell (taken in scene, method, seed order for dataset reuse): skip it when its
//! `metrics.json` is there (and has LPIPS, or no weights were given: then only the scoring runs
//! again); otherwise simulate its dataset if missing ([`dataset`]), train or resume it and score
//! it ([`cell`]). A failing cell is reported and the others go on; Ctrl-C (the `stop` flag)
//! ends the current cell's training with a checkpoint and stops the run.
//!
//! - [`dataset`]: simulated datasets under `<results>/datasets/`.
//! - [`cell`]: training and scoring one cell; the run record.
//! - [`evaluate`]: rendering and scoring the test views.
//! - [`progress`]: the matrix and cell bars.

pub mod cell;
pub mod dataset;
pub mod evaluate;
pub mod progress;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::BenchError;
use crate::lpips::Lpips;
use crate::matrix::{Cell, MatrixPlan, Shard};
use crate::metrics::{self, CellMetrics};
use cell::{CellRun, DatasetCache, Outcome};
use progress::Progress;

/// How to run a matrix.
#[derive(Clone, Debug, Default)]
pub struct RunOptions<'a> {
    /// The part of the matrix to run.
    pub shard: Shard,
    /// LPIPS weights (`None`: LPIPS is recorded as missing).
    pub lpips_weights: Option<PathBuf>,
    /// Worker threads for training and scoring (0: all cores).
    pub threads: usize,
    /// Draw progress bars (the caller checks stderr is a terminal).
    pub bars: bool,
    /// Print nothing.
    pub quiet: bool,
    /// Set (by Ctrl-C) to stop after the current training step.
    pub stop: Option<&'a AtomicBool>,
    /// Stop as Ctrl-C would after training this many steps of a cell (tests).
    pub stop_after_steps: Option<u64>,
    /// A frame cache shared by the simulated datasets (sweeps: datasets that differ only in
    /// exposure or event settings reuse the rendered frames); `None`: each dataset's own,
    /// deleted when it is complete.
    pub frames_cache: Option<PathBuf>,
    /// The position of the matrix's first cell in a larger numbering (a sweep numbers the cells
    /// of all its points one after the other, so that its shards split the whole sweep).
    pub first_position: usize,
}

/// Where a cell stands.
#[derive(Clone, Debug, PartialEq)]
pub enum CellStatus {
    /// Finished: `metrics.json` is there.
    Done {
        /// It has LPIPS scores.
        lpips: bool,
    },
    /// Started: a checkpoint at this step.
    Partial {
        /// Iterations done.
        step: u64,
    },
    /// Not started.
    Todo,
}

/// The status of `cell` from its folder.
pub fn status(plan: &MatrixPlan, cell: &Cell) -> Result<CellStatus, BenchError> {
    let dir = plan.cell_dir(cell);
    let metrics = dir.join(metrics::FILE);
    if metrics.is_file() {
        let m = CellMetrics::read(&metrics)?;
        return Ok(CellStatus::Done { lpips: m.lpips.is_some() });
    }
    let sidecar = trainer::checkpoint::seconds_path(&dir.join("checkpoint.bin"));
    let step = std::fs::read_to_string(sidecar).ok().and_then(|t| t.split_whitespace().next()?.parse().ok());
    Ok(step.map_or(CellStatus::Todo, |step| CellStatus::Partial { step }))
}

/// The cells of `shard`, in key order; the first cell is at position `first` (0 for a matrix
/// of its own).
pub fn shard_cells(plan: &MatrixPlan, shard: Shard, first: usize) -> Vec<&Cell> {
    plan.cells.iter().enumerate().filter(|(p, _)| shard.contains(first + *p)).map(|(_, c)| c).collect()
}

/// What a run did.
#[derive(Debug, Default)]
pub struct RunSummary {
    /// Cells in the shard.
    pub cells: usize,
    /// Cells already finished (nothing done).
    pub skipped: usize,
    /// Cells trained from step 0 and scored.
    pub trained: usize,
    /// Cells trained on from a checkpoint and scored.
    pub resumed: usize,
    /// Cells only scored (trained before; e.g. LPIPS weights given now).
    pub scored: usize,
    /// Datasets simulated.
    pub simulated: usize,
    /// Cells that failed: their folder and the error.
    pub failed: Vec<(PathBuf, BenchError)>,
    /// Stopped by the `stop` flag before the shard was done.
    pub interrupted: bool,
}

/// Runs the cells of `opts.shard` (see the module doc). Errors that concern one cell are in
/// [`RunSummary::failed`]; an `Err` means nothing could run (LPIPS weights, worker threads).
pub fn run(plan: &MatrixPlan, opts: &RunOptions) -> Result<RunSummary, BenchError> {
    let lpips = opts.lpips_weights.as_deref().map(Lpips::load).transpose()?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(opts.threads).build().map_err(|e| {
        BenchError::results(&plan.results, format!("cannot start {} worker threads ({e})", opts.threads))
    })?;
    let mut cells = shard_cells(plan, opts.shard, opts.first_position);
    cells.sort_by_key(|c| (c.scene, c.method, c.seed));
    let mut summary = RunSummary { cells: cells.len(), ..RunSummary::default() };

    // What is left: cells to train (and from which step) or only to score.
    let mut todo = Vec::new();
    let mut steps = 0;
    for cell in cells {
        let from = match status(plan, cell) {
            Ok(CellStatus::Done { lpips: has }) if has || lpips.is_none() => {
                summary.skipped += 1;
                continue;
            }
            Ok(CellStatus::Done { .. }) => cell.config.iterations,
            Ok(CellStatus::Partial { step }) => step.min(cell.config.iterations),
            Ok(CellStatus::Todo) => 0,
            Err(e) => {
                summary.failed.push((plan.cell_dir(cell), e));
                continue;
            }
        };
        steps += cell.config.iterations - from;
        todo.push(cell);
    }

    let progress = Progress::new(opts.bars, opts.quiet, steps);
    progress.line(&format!(
        "{}: {} cells in shard {} ({} done), {} to run; results in {}",
        plan.file.display(),
        summary.cells,
        opts.shard,
        summary.skipped,
        todo.len(),
        plan.results.display()
    ));
    let git_commit = metrics::git_commit();
    let runner = CellRun {
        plan,
        lpips: lpips.as_ref(),
        threads: opts.threads,
        pool: &pool,
        stop: opts.stop,
        stop_after_steps: opts.stop_after_steps,
        progress: &progress,
        git_commit,
    };
    let mut datasets = DatasetCache::default();
    let mut scene_errors: Vec<Option<String>> = vec![None; plan.scenes.len()];
    let n = todo.len();
    for (i, cell) in todo.into_iter().enumerate() {
        if opts.stop.is_some_and(|s| s.load(Ordering::SeqCst)) {
            summary.interrupted = true;
            break;
        }
        progress.matrix_message(i + 1, n);
        let scene = &plan.scenes[cell.scene];
        let dir = plan.cell_dir(cell);
        if let Some(e) = &scene_errors[cell.scene] {
            summary.failed.push((dir, BenchError::results(&scene.dataset_dir(&plan.results), e.clone())));
            continue;
        }
        if !dataset::is_complete(&scene.dataset_dir(&plan.results)) {
            progress.cell_phase(&format!("{} simulating", scene.name));
        }
        let data_dir = match dataset::ensure(scene, &plan.results, opts.shard, opts.frames_cache.as_deref()) {
            Ok((d, simulated)) => {
                if simulated.is_some() {
                    summary.simulated += 1;
                    progress.line(&format!("{}: simulated into {}", scene.name, d.display()));
                }
                d
            }
            Err(e) => {
                scene_errors[cell.scene] = Some(format!("the dataset could not be simulated: {e}"));
                summary.failed.push((dir, e));
                continue;
            }
        };
        if opts.stop.is_some_and(|s| s.load(Ordering::SeqCst)) {
            // Stopped while the dataset was simulated (it is complete).
            summary.interrupted = true;
            break;
        }
        let label = format!("{}/{} seed {} [{}]", scene.name, plan.methods[cell.method].name, cell.seed, cell.key);
        match runner.run(cell, &data_dir, &mut datasets) {
            Ok(Outcome::Finished { metrics: m, from }) => {
                let lpips = m.lpips.map_or("n/a".to_string(), |l| format!("{l:.4}"));
                progress.line(&format!(
                    "{label}: PSNR {:.2} dB, SSIM {:.4}, LPIPS {lpips} ({} steps, train {:.1} s, wall {:.1} s)",
                    m.psnr, m.ssim, m.steps, m.train_seconds, m.wall_seconds
                ));
                match from {
                    0 => summary.trained += 1,
                    f if f >= m.steps => summary.scored += 1,
                    _ => summary.resumed += 1,
                }
            }
            Ok(Outcome::Interrupted { step }) => {
                progress.line(&format!("{label}: stopped at step {step} (checkpoint written; run again to resume)"));
                summary.interrupted = true;
                break;
            }
            Err(e) => {
                progress.line(&format!("{label}: FAILED: {e}"));
                summary.failed.push((dir, e));
            }
        }
    }
    progress.finish();
    Ok(summary)
}
