//! One cell: train the method on the scene's dataset in the cell's folder (a trainer run folder,
//! resumed from its checkpoint when one is there), then score the test views and write
//! `metrics.json`.
//!
//! The folder's `config.toml` is written as `evtrain` writes it, so `evtrain train --resume
//! --out <cell>` and `evtrain eval <cell>` work on it too. A resumed run continues bit for bit
//! when it runs with the same thread count (the trainer's guarantee); the count is recorded in
//! `metrics.json`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use trainer::config::TrainConfig;
use trainer::data::dataset::{Dataset, LoadOptions};
use trainer::run::RunPlan;
use trainer::train::{TrainOptions, Trainer};

use super::evaluate::{means, score_views};
use super::progress::Progress;
use crate::error::BenchError;
use crate::lpips::Lpips;
use crate::matrix::{Cell, MatrixPlan};
use crate::metrics::{CellMetrics, Machine, Session, FORMAT};

/// The last dataset loaded, kept for the next cell on the same scene.
#[derive(Default)]
pub struct DatasetCache {
    loaded: Option<(PathBuf, bool, Dataset)>,
}

impl DatasetCache {
    /// The dataset in `dir`, with its events when `events` (loaded unless the last one fits).
    pub fn get(&mut self, dir: &Path, events: bool) -> Result<&Dataset, BenchError> {
        let hit = matches!(&self.loaded, Some((d, e, _)) if d == dir && (*e || !events));
        if !hit {
            self.loaded = None;
            let opts = LoadOptions { read_events: events, read_sharp: true, ..LoadOptions::default() };
            self.loaded = Some((dir.to_owned(), events, Dataset::load(dir, &opts)?));
        }
        Ok(&self.loaded.as_ref().expect("loaded above").2)
    }
}

/// The file in a cell's folder that carries the wall time of its earlier sessions (s) from an
/// interrupted session to the one that resumes it.
pub const WALL_FILE: &str = "wall.seconds";

/// The wall time `dir`'s [`WALL_FILE`] records, 0 when there is none or it does not read as a
/// time (it only adds to a figure; a missing or damaged one loses the earlier sessions' time).
fn read_wall(dir: &Path) -> f64 {
    let text = std::fs::read_to_string(dir.join(WALL_FILE)).unwrap_or_default();
    text.trim().parse::<f64>().ok().filter(|s| s.is_finite() && *s >= 0.0).unwrap_or(0.0)
}

/// Writes `seconds` to `dir`'s [`WALL_FILE`] atomically.
fn write_wall(dir: &Path, seconds: f64) -> Result<(), BenchError> {
    write_record(dir, WALL_FILE, &format!("{seconds}\n"))
}

/// Writes `text` to `dir/name` atomically (a record carried from one session to the next).
fn write_record(dir: &Path, name: &str, text: &str) -> Result<(), BenchError> {
    let path = dir.join(name);
    simulator::image_io::write_atomic(&path, text.as_bytes()).map_err(|e| BenchError::results(&path, format!("{e:#}")))
}

/// The file in a cell's folder that lists the sessions that trained it so far, each with its
/// binary's commit (JSON, [`Session`]s), for the session that resumes or scores it again.
pub const SESSIONS_FILE: &str = "sessions.json";

/// The sessions that trained steps `0..from` (the checkpoint's): those `dir`'s
/// [`SESSIONS_FILE`] records, in order and inside `0..from`, with any steps no session recorded
/// (a session killed outright, an older evbench, a missing or damaged file) as `unknown`.
fn sessions_before(dir: &Path, from: u64) -> Vec<Session> {
    let text = std::fs::read_to_string(dir.join(SESSIONS_FILE)).unwrap_or_default();
    let recorded: Vec<Session> = serde_json::from_str(&text).unwrap_or_default();
    let mut out: Vec<Session> = Vec::new();
    let mut at = 0;
    for s in recorded {
        if s.from < at || s.to <= s.from || s.to > from {
            continue;
        }
        if s.from > at {
            out.push(Session { from: at, to: s.from, git_commit: "unknown".into() });
        }
        at = s.to;
        out.push(s);
    }
    if at < from {
        out.push(Session { from: at, to: from, git_commit: "unknown".into() });
    }
    out
}

/// Writes `sessions` to `dir`'s [`SESSIONS_FILE`] atomically.
fn write_sessions(dir: &Path, sessions: &[Session]) -> Result<(), BenchError> {
    write_record(dir, SESSIONS_FILE, &(serde_json::to_string_pretty(sessions).expect("plain data serialises") + "\n"))
}

/// How a cell ended.
#[derive(Debug)]
pub enum Outcome {
    /// Scored; `from` is the step training started at (0: a new run; the iteration count:
    /// only scored).
    Finished {
        /// The metrics written.
        metrics: Box<CellMetrics>,
        /// First step trained in this session.
        from: u64,
    },
    /// Stopped (Ctrl-C) at this step, with a checkpoint.
    Interrupted {
        /// Iterations done.
        step: u64,
    },
}

/// What a cell needs from the run.
pub struct CellRun<'a> {
    /// The plan.
    pub plan: &'a MatrixPlan,
    /// LPIPS, when weights were given.
    pub lpips: Option<&'a Lpips>,
    /// Worker threads (0: all cores).
    pub threads: usize,
    /// The evaluation pool (`threads` workers).
    pub pool: &'a rayon::ThreadPool,
    /// Set by Ctrl-C: stop after the current step.
    pub stop: Option<&'a AtomicBool>,
    /// Stop as Ctrl-C would after this many steps (tests).
    pub stop_after_steps: Option<u64>,
    /// The bars.
    pub progress: &'a Progress,
    /// This binary's source commit ([`crate::metrics::git_commit`]), recorded in the metrics.
    pub git_commit: &'a str,
}

impl CellRun<'_> {
    /// Trains (or resumes) `cell` on the dataset in `data_dir` and scores it.
    pub fn run(&self, cell: &Cell, data_dir: &Path, datasets: &mut DatasetCache) -> Result<Outcome, BenchError> {
        let t0 = Instant::now();
        let (plan, method, scene) = (self.plan, &self.plan.methods[cell.method], &self.plan.scenes[cell.scene]);
        let dir = plan.cell_dir(cell);
        let label = format!("{}/{} s{}", scene.name, method.name, cell.seed);
        self.progress.cell_phase(&format!("{label} loading"));
        let data = datasets.get(data_dir, cell.config.needs_events())?;
        let data_abs = std::fs::canonicalize(data_dir)
            .map_err(|e| BenchError::results(data_dir, format!("cannot resolve the dataset folder ({e})")))?;

        // One process per cell (shards sharing a results folder never run the same cell, but two
        // runs of one matrix might): the plan holds the folder's lock. The run record is the
        // cell's own when it was started before, else a new one; the thread count it starts
        // with is recorded (evtrain resumes bit for bit with it).
        let new = || {
            let config = TrainConfig { threads: self.threads, ..cell.config.clone() };
            let preset = method.preset.name;
            trainer::run::new_record(preset, plan.scale, data_abs.clone(), config, data, Default::default())
        };
        let mut run_plan = RunPlan::open(&dir, new)?;
        let record = &mut run_plan.record;
        if record.preset != method.preset.name {
            return Err(BenchError::results(
                &run_plan.paths.config(),
                format!(
                    "holds a run of preset {}, not {}; delete the cell's folder to train it again",
                    record.preset, method.preset.name
                ),
            ));
        }
        if record.data != data_abs {
            // The results folder moved; the key says it is the same dataset.
            record.data = data_abs;
            run_plan.save_record()?;
        }
        let checkpoint = run_plan.checkpoint(data.views.len())?;
        // The wall time of the sessions before this one: what an interrupted session recorded,
        // and at least the training time the checkpoint carries (a session killed outright
        // records nothing).
        let resumed_at = checkpoint.as_ref().map_or(0.0, |c| c.seconds);
        let earlier = if checkpoint.is_some() { read_wall(&dir).max(resumed_at) } else { 0.0 };
        if checkpoint.is_none() {
            // A fresh run: a record left by an earlier run of this folder is not its own.
            write_wall(&dir, 0.0)?;
        }
        let (run, mut record) = (&run_plan.paths, run_plan.record.clone());
        record.config.threads = self.threads;
        let iterations = record.config.iterations;

        let mut trainer = Trainer::new_in(data, record.config.clone(), checkpoint, Some(&dir))?;
        let from = trainer.step;
        // Which binaries trained the checkpoint's steps, then this one's. Written back at once:
        // a fresh run drops a stale record, and a session killed outright leaves the steps
        // before it right.
        let mut sessions = sessions_before(&dir, from);
        write_sessions(&dir, &sessions)?;
        let this = |to: u64| Session { from, to, git_commit: self.git_commit.into() };
        if from < iterations {
            self.progress.cell_start(&label, from, iterations);
            let max_steps = self.stop_after_steps.map(|n| from + n);
            let on_step = |step: u64| self.progress.move_cell_to(step);
            let opts = TrainOptions { progress: false, stop: self.stop, max_steps, on_step: Some(&on_step) };
            trainer.train(run, &opts)?;
            self.progress.move_cell_to(trainer.step);
            let stopped = self.stop.is_some_and(|s| s.load(Ordering::SeqCst)) || max_steps.is_some();
            if trainer.step < iterations && stopped {
                sessions.extend((trainer.step > from).then(|| this(trainer.step)));
                write_sessions(&dir, &sessions)?;
                write_wall(&dir, earlier + t0.elapsed().as_secs_f64())?;
                return Ok(Outcome::Interrupted { step: trainer.step });
            }
        }

        self.progress.cell_phase(&format!("{label} scoring"));
        let t_eval = Instant::now();
        let views =
            score_views(data, &trainer.method, &trainer.params, &trainer.cfg, self.lpips, self.pool, &run.eval())?;
        let (psnr, ssim, lpips) = means(&views);
        sessions.extend((trainer.step > from).then(|| this(trainer.step)));
        // Kept for a later session that only scores the cell again (LPIPS weights given later,
        // or metrics.json deleted).
        write_sessions(&dir, &sessions)?;
        let metrics = CellMetrics {
            format: FORMAT,
            tool_version: env!("CARGO_PKG_VERSION").into(),
            key: cell.key.clone(),
            method: method.name.clone(),
            preset: method.preset.name.into(),
            switches: method.switches.clone(),
            set: method.set.clone(),
            scale: plan.scale,
            scene: scene.name.clone(),
            dataset: scene.identity.clone(),
            seed: cell.seed,
            steps: trainer.step,
            psnr,
            ssim,
            lpips,
            views,
            train_seconds: trainer.seconds,
            eval_seconds: t_eval.elapsed().as_secs_f64(),
            wall_seconds: earlier + t0.elapsed().as_secs_f64(),
            threads: if self.threads == 0 { rayon::current_num_threads() } else { self.threads },
            machine: Machine::current(),
            git_commit: self.git_commit.into(),
            sessions,
        };
        metrics.write(&dir)?;
        Ok(Outcome::Finished { metrics: Box::new(metrics), from })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session(from: u64, to: u64, commit: &str) -> Session {
        Session { from, to, git_commit: commit.into() }
    }

    #[test]
    fn the_sessions_before_a_checkpoint_fill_unrecorded_steps_as_unknown() {
        let dir = std::env::temp_dir().join(format!("evbench-sessions-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // No file: the checkpoint's steps came from an unrecorded session.
        assert_eq!(sessions_before(&dir, 0), []);
        assert_eq!(sessions_before(&dir, 300), [session(0, 300, "unknown")]);
        // Two recorded sessions with a gap (a session killed outright between them).
        write_sessions(&dir, &[session(0, 100, "a"), session(150, 200, "b")]).unwrap();
        assert_eq!(
            sessions_before(&dir, 260),
            [session(0, 100, "a"), session(100, 150, "unknown"), session(150, 200, "b"), session(200, 260, "unknown")]
        );
        assert_eq!(
            sessions_before(&dir, 200),
            [session(0, 100, "a"), session(100, 150, "unknown"), session(150, 200, "b")]
        );
        // A record beyond the checkpoint (an older checkpoint) is dropped; a new run sees none.
        assert_eq!(sessions_before(&dir, 120), [session(0, 100, "a"), session(100, 120, "unknown")]);
        assert_eq!(sessions_before(&dir, 0), []);
        // A damaged file loses the record, not the run.
        std::fs::write(dir.join(SESSIONS_FILE), "[{\"from\": 0").unwrap();
        assert_eq!(sessions_before(&dir, 50), [session(0, 50, "unknown")]);
        // Written atomically: no temporary file is left.
        write_sessions(&dir, &[session(0, 5, "c")]).unwrap();
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, [SESSIONS_FILE]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
