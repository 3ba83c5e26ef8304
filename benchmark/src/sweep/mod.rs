//! `evbench sweep`: the paper's robustness studies as commands. A sweep file is a run matrix
//! plus one or two swept settings ([`config`]); it is resolved into one matrix per point
//! ([`plan`]), whose cells run like any matrix's (resumable, shardable), and reported as a
//! table and a figure per scene ([`report`]). With `--data-only` the datasets are simulated and
//! measured without training ([`data`]).
//!
//! Work is reused: all points simulate through one frame cache, `<results>/frames/`, so points
//! that differ in exposure or event settings render nothing new (the render key leaves them
//! out), and points that differ only in training settings share their dataset.

pub mod config;
pub mod data;
pub mod plan;
pub mod report;

pub use crate::matrix::plan::{FRAMES_DIR, SWEEP_DIR};
pub use plan::SweepPlan;
