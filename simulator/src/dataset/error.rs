//! The dataset pipeline's typed errors: each names the file, the field and the fix.

use std::path::{Path, PathBuf};

/// Why a dataset could not be planned or written.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A setting is missing or out of range.
    #[error("{file}: {field}: {message}")]
    Config {
        /// The settings file.
        file: PathBuf,
        /// The field, e.g. `dataset.exposure_ms`.
        field: String,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {what}: {cause}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What was being done, and the fix where there is one.
        what: String,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] crate::SceneError),
    /// The output folder holds a different dataset, or a frame cache does not match.
    #[error("{path}: {message}")]
    Conflict {
        /// The folder or file.
        path: PathBuf,
        /// What differs and what to do.
        message: String,
    },
    /// A later stage failed (events, exposure, encoding), with the file or frame it was on.
    #[error("{context}: {message}")]
    Stage {
        /// Where (file or frame).
        context: String,
        /// What went wrong.
        message: String,
    },
    /// Another process is writing the dataset folder, or it cannot be locked.
    #[error(transparent)]
    Locked(#[from] crate::lock::LockError),
    /// The run was stopped on request (tests and Ctrl-C) after `frames` frames.
    #[error("interrupted after {frames} rendered frames; run the same command again to resume")]
    Interrupted {
        /// Frames rendered in this run before stopping.
        frames: usize,
    },
}

impl DatasetError {
    /// Shorthand for [`DatasetError::Config`].
    pub fn config(file: &Path, field: &str, message: String) -> DatasetError {
        DatasetError::Config { file: file.to_path_buf(), field: field.to_string(), message }
    }
    /// Shorthand for [`DatasetError::Io`].
    pub fn io(path: impl AsRef<Path>, what: &str, cause: std::io::Error) -> DatasetError {
        DatasetError::Io { path: path.as_ref().to_path_buf(), what: what.to_string(), cause }
    }
    /// Shorthand for [`DatasetError::Stage`].
    pub fn stage(context: impl std::fmt::Display, message: impl std::fmt::Display) -> DatasetError {
        DatasetError::Stage { context: context.to_string(), message: message.to_string() }
    }
}
