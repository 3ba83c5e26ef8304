//! Errors of training and evaluation: each names the file or field and the fix.

use std::path::PathBuf;

use crate::data::error::LoadError;

/// What can stop a run.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The dataset could not be loaded.
    #[error(transparent)]
    Data(#[from] LoadError),
    /// A setting is out of range.
    #[error("config: {0}")]
    Config(String),
    /// The dataset lacks something the preset needs.
    #[error("{path}: {what}; {fix}")]
    Missing {
        /// The dataset or run folder.
        path: PathBuf,
        /// What is missing.
        what: String,
        /// How to get it.
        fix: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}; {fix}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
        /// How to fix it.
        fix: &'static str,
    },
    /// A checkpoint or run folder is unusable.
    #[error("{path}: {what}; {fix}")]
    Run {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
        /// How to fix it.
        fix: String,
    },
}

impl TrainError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error, fix: &'static str) -> TrainError {
        TrainError::Io { path: path.into(), source, fix }
    }

    /// A problem with a run file.
    pub fn run(path: impl Into<PathBuf>, what: impl Into<String>, fix: impl Into<String>) -> TrainError {
        TrainError::Run { path: path.into(), what: what.into(), fix: fix.into() }
    }
}
