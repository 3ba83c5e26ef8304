//! [`LoadError`]: why a dataset folder could not be loaded, naming the file, the field and the fix.

use std::path::PathBuf;

/// An error while loading a dataset; every variant names the file and says how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The schema check (`simulator::dataset::check`) could not open the folder.
    #[error("{0}")]
    NoFolder(String),
    /// The schema check found problems; `report` holds its full output (one line per check).
    #[error("{}: the dataset check found {count} problem(s); fix them and load again:\n{report}", dir.display())]
    Check {
        /// The dataset folder.
        dir: PathBuf,
        /// Number of problems.
        count: usize,
        /// The check's report, as printed by `evsim check`.
        report: String,
    },
    /// A file cannot be read (I/O error, truncated, not the format).
    #[error("{file}: cannot be read: {message}; {fix}")]
    Unreadable {
        /// The file, relative to the dataset folder.
        file: String,
        /// The reader's reason.
        message: String,
        /// How to fix it.
        fix: String,
    },
    /// A field holds values the loader cannot use (shapes, ranges, sizes that disagree).
    #[error("{file}: {field}: {problem}; {fix}")]
    Invalid {
        /// The file, relative to the dataset folder.
        file: String,
        /// The array, dataset, row or entry.
        field: String,
        /// What is wrong.
        problem: String,
        /// The fix.
        fix: String,
    },
}

impl LoadError {
    /// Shorthand for [`LoadError::Unreadable`].
    pub(crate) fn unreadable(file: &str, message: impl ToString, fix: &str) -> LoadError {
        LoadError::Unreadable { file: file.into(), message: message.to_string(), fix: fix.into() }
    }

    /// Shorthand for [`LoadError::Invalid`].
    pub(crate) fn invalid(file: &str, field: impl Into<String>, problem: impl Into<String>, fix: &str) -> LoadError {
        LoadError::Invalid { file: file.into(), field: field.into(), problem: problem.into(), fix: fix.into() }
    }
}
