//! Typed errors for scene loading and output. Every message names the file, the element and,
//! where there is one, the fix.

use std::path::PathBuf;

/// An error while reading a scene or one of its resources.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read at all (missing, permissions, ...).
    #[error("{path}: cannot read file: {cause}")]
    Io {
        /// The file that failed.
        path: PathBuf,
        /// The underlying error (already part of the message).
        cause: std::io::Error,
    },
    /// The file was read but its content is not valid for its format.
    #[error("{path}: {element}: {message}")]
    Invalid {
        /// The file that holds the bad element.
        path: PathBuf,
        /// Which element is bad, e.g. `mesh 3 "Chair" primitive 0 attribute POSITION`.
        element: String,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// The file uses a feature we do not implement.
    #[error("{path}: {element}: unsupported: {message}")]
    Unsupported {
        /// The file that uses the feature.
        path: PathBuf,
        /// The element that uses it.
        element: String,
        /// What is unsupported and what to do instead.
        message: String,
    },
}

impl SceneError {
    /// Shorthand for [`SceneError::Invalid`].
    pub fn invalid(path: impl Into<PathBuf>, element: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError::Invalid { path: path.into(), element: element.into(), message: message.into() }
    }
    /// Shorthand for [`SceneError::Unsupported`].
    pub fn unsupported(path: impl Into<PathBuf>, element: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError::Unsupported { path: path.into(), element: element.into(), message: message.into() }
    }
    /// Shorthand for [`SceneError::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        SceneError::Io { path: path.into(), cause: source }
    }
}
