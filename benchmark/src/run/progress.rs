//! Progress of a matrix run: one bar for the matrix (training steps of the cells this shard
//! still has to train, so that its ETA weighs long cells) and one for the current cell (its
//! steps, with ETA), drawn on stderr; log lines go above them. Without bars (not a terminal, or
//! `--quiet`) the lines go to stdout, and `quiet` silences them too.
//!
//! The trainer reports no steps while it trains, so the cell bar follows the run's `log.csv`
//! (flushed every 50 steps and at every evaluation), polled by [`Progress::watch`].

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The two bars and the log.
pub struct Progress {
    multi: MultiProgress,
    matrix: ProgressBar,
    cell: ProgressBar,
    /// The cell bar while it trains.
    steps_style: ProgressStyle,
    /// The cell bar in the phases without steps.
    phase_style: ProgressStyle,
    bars: bool,
    quiet: bool,
}

impl Progress {
    /// Bars when `bars` (the caller checks for a terminal); log lines unless `quiet`.
    pub fn new(bars: bool, quiet: bool, total_steps: u64) -> Progress {
        let bars = bars && !quiet;
        let target = if bars { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        let multi = MultiProgress::with_draw_target(target);
        let style = |t: &str| ProgressStyle::with_template(t).expect("valid template").progress_chars("=> ");
        let matrix = multi.add(ProgressBar::new(total_steps));
        matrix.set_style(style("matrix {msg:>12} [{elapsed_precise}] {wide_bar} {pos}/{len} steps (eta {eta})"));
        let cell = multi.add(ProgressBar::new(0));
        let steps_style = style("{msg:>19} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})");
        let phase_style = style("{msg:>19} [{elapsed_precise}]");
        cell.set_style(phase_style.clone());
        Progress { multi, matrix, cell, steps_style, phase_style, bars, quiet }
    }

    /// Prints a line above the bars (or to stdout without them).
    pub fn line(&self, text: &str) {
        if self.quiet {
            return;
        }
        if self.bars {
            let _ = self.multi.println(text);
        } else {
            println!("{text}");
        }
    }

    /// Shows which cell runs (`n` of `of`).
    pub fn matrix_message(&self, n: usize, of: usize) {
        self.matrix.set_message(format!("cell {n}/{of}"));
    }

    /// Adds finished steps to the matrix bar.
    pub fn matrix_advance(&self, steps: u64) {
        self.matrix.inc(steps);
    }

    /// Starts the cell bar: `msg`, at `start` of `len` steps.
    pub fn cell_start(&self, msg: &str, start: u64, len: u64) {
        self.cell.set_style(self.steps_style.clone());
        self.cell.set_length(len);
        self.cell.set_position(start);
        self.cell.reset_elapsed();
        self.cell.reset_eta();
        self.cell.set_message(msg.to_string());
    }

    /// Shows a phase of the current cell without steps (loading, simulating, evaluating).
    pub fn cell_phase(&self, msg: &str) {
        self.cell.set_style(self.phase_style.clone());
        self.cell.set_message(msg.to_string());
    }

    /// Moves the cell bar (and the matrix bar by as much) while `f` runs, from the steps in
    /// `log` (the run's `log.csv`); returns `f`'s result.
    pub fn watch<T>(&self, log: &Path, f: impl FnOnce() -> T) -> T {
        let done = AtomicBool::new(false);
        std::thread::scope(|s| {
            s.spawn(|| {
                while !done.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(250));
                    if let Some(step) = last_step(log) {
                        self.move_cell_to(step);
                    }
                }
            });
            let out = f();
            done.store(true, Ordering::Relaxed);
            out
        })
    }

    /// Moves the cell bar forward to `step` and the matrix bar by the same number of steps.
    pub fn move_cell_to(&self, step: u64) {
        let pos = self.cell.position();
        if step > pos && step <= self.cell.length().unwrap_or(0) {
            self.cell.set_position(step);
            self.matrix.inc(step - pos);
        }
    }

    /// Clears the bars.
    pub fn finish(&self) {
        self.cell.finish_and_clear();
        self.matrix.finish_and_clear();
    }
}

/// The step of the last row of a trainer log (`step,...` lines after a header).
fn last_step(log: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(log).ok()?;
    text.lines().last()?.split(',').next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_log_row_gives_the_step() {
        let dir = std::env::temp_dir().join(format!("evbench-progress-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let log = dir.join("log.csv");
        assert_eq!(last_step(&log), None);
        std::fs::write(&log, "step,seconds\n").unwrap();
        assert_eq!(last_step(&log), None);
        std::fs::write(&log, "step,seconds\n1,0.1\n50,2.0\n").unwrap();
        assert_eq!(last_step(&log), Some(50));
        let p = Progress::new(false, true, 100);
        p.cell_start("x", 0, 60);
        p.watch(&log, || std::thread::sleep(Duration::from_millis(600)));
        assert_eq!(p.cell.position(), 50);
        assert_eq!(p.matrix.position(), 50);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
