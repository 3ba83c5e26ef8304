//! Writing a [`Scene`](crate::scene::Scene) out for other renderers.
//!
//! - [`mitsuba`]: a directory with PLY meshes, EXR textures and a `scene.json` describing the
//!   Mitsuba 3 scene dictionary; `tests/mitsuba/render.py` turns it into a Mitsuba render. Used
//!   by the reference check in `tests/mitsuba_reference.rs`.

pub mod mitsuba;

use std::path::PathBuf;

pub use mitsuba::export_mitsuba;

/// An error while exporting a scene.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The scene uses a feature the target renderer cannot reproduce exactly.
    #[error("{element}: not exportable: {message}")]
    NotExportable {
        /// The offending element, e.g. `material 2 "Bronze"`.
        element: String,
        /// What cannot be expressed and what to use instead.
        message: String,
    },
    /// A file could not be written.
    #[error("{path}: cannot write: {message}")]
    Write {
        /// The file being written.
        path: PathBuf,
        /// The underlying error.
        message: String,
    },
}

impl ExportError {
    /// Shorthand for [`ExportError::NotExportable`].
    pub fn not_exportable(element: impl Into<String>, message: impl Into<String>) -> Self {
        ExportError::NotExportable { element: element.into(), message: message.into() }
    }
    /// Shorthand for [`ExportError::Write`].
    pub fn write(path: impl Into<PathBuf>, message: impl ToString) -> Self {
        ExportError::Write { path: path.into(), message: message.to_string() }
    }
}
