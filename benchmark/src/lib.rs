//! Benchmark: image metrics beyond the trainer's PSNR / SSIM; the run matrix, sweeps and tables
//! are to come (see the issue tracker).
//!
//! - [`lpips`]: LPIPS (Zhang et al. 2018, AlexNet, v0.1) from a weights file exported from the
//!   `lpips` Python package by `scripts/export_lpips_weights.py`.

pub mod lpips;
