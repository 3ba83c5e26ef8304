//! Why a benchmark could not be planned, run or tabulated. Every message names the file (and,
//! for a matrix file, the field) and says how to fix it.

use std::path::{Path, PathBuf};

/// A benchmark failure.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A run-matrix file is unreadable, malformed or has a bad value.
    #[error("{}: {field}: {message}", file.display())]
    Config {
        /// The matrix file.
        file: PathBuf,
        /// The field, e.g. `methods[1].preset`.
        field: String,
        /// What is wrong and the fix.
        message: String,
    },
    /// A file or folder of the results could not be read, parsed or written.
    #[error("{}: {message}", path.display())]
    Results {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// Planning or simulating a dataset failed.
    #[error(transparent)]
    Dataset(#[from] simulator::dataset::DatasetError),
    /// Loading a dataset, training or evaluating failed.
    #[error(transparent)]
    Train(#[from] trainer::error::TrainError),
    /// A figure could not be drawn (no drawable point, a bad value, a drawing failure).
    #[error("figure \"{title}\": {message}")]
    Plot {
        /// The figure's title.
        title: String,
        /// What is wrong and the fix.
        message: String,
    },
    /// Loading LPIPS weights or scoring an image failed.
    #[error(transparent)]
    Lpips(#[from] crate::lpips::LpipsError),
}

impl BenchError {
    /// A problem with `field` of the matrix file `file`.
    pub fn config(file: &Path, field: impl Into<String>, message: impl Into<String>) -> BenchError {
        BenchError::Config { file: file.to_owned(), field: field.into(), message: message.into() }
    }

    /// A problem with a results file or folder.
    pub fn results(path: &Path, message: impl Into<String>) -> BenchError {
        BenchError::Results { path: path.to_owned(), message: message.into() }
    }

    /// A problem drawing the figure titled `title`.
    pub fn plot(title: &str, message: impl Into<String>) -> BenchError {
        BenchError::Plot { title: title.to_owned(), message: message.into() }
    }
}

impl From<trainer::data::error::LoadError> for BenchError {
    fn from(e: trainer::data::error::LoadError) -> BenchError {
        BenchError::Train(e.into())
    }
}
