//! Progress of a matrix run: one bar for the matrix (training steps of the cells this shard
//! still has to train, so that its ETA weighs long cells) and one for the current cell (its
//! steps, with ETA), drawn on stderr; log lines go above them. Without bars (not a terminal, or
//! `--quiet`) the lines go to stdout, and `quiet` silences them too.
//!
//! The trainer reports each step through `TrainOptions::on_step`, which moves both bars
//! ([`Progress::move_cell_to`]).

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_move_the_cell_and_the_matrix_bars_forward_only() {
        let p = Progress::new(false, true, 100);
        p.cell_start("x", 10, 60);
        p.move_cell_to(50);
        assert_eq!((p.cell.position(), p.matrix.position()), (50, 40));
        // Backwards or past the cell's end: nothing moves.
        p.move_cell_to(30);
        p.move_cell_to(61);
        assert_eq!((p.cell.position(), p.matrix.position()), (50, 40));
    }
}
