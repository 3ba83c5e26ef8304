//! Event files: [`EventSink`]s that stream events to disk in the formats people use.
//!
//! | [`SinkKind`] | extension | layout | time |
//! |---|---|---|---|
//! | [`SinkKind::NerfH5`] | `.h5` (`--format nerf`, the default) | root datasets `x` u16, `y` u16, `t` i64, `p` i8 (+1 ON / -1 OFF) | ns |
//! | [`SinkKind::DsecH5`] | `.h5` (`--format dsec`) | `/events/{x u16, y u16, t u32, p u8 (1 ON / 0 OFF)}`, `/t_offset` i64, `/ms_to_idx` u64 | us, `t + t_offset` |
//! | [`SinkKind::Text`] | `.txt` | one line `t x y p` (RPG/ECD), `p` in {0, 1} | s, 9 decimals |
//! | [`SinkKind::Npz`] | `.npz` | `x` u16, `y` u16, `t` i64, `p` i8 (+1 / -1) | ns |
//!
//! Every writer streams (memory is independent of the event count: at most one batch plus a
//! compression chunk) and is atomic: it writes to a hidden temporary sibling of the target
//! (`.name.tmp<pid>`) and renames it into place in `finish()`. A writer dropped without
//! `finish()` (an error, a panic) removes its temporary files and leaves no file at the target.
//!
//! # What lives where
//! - this file: [`SinkKind`], [`H5Layout`], [`EventWriter`] (the closed set of writers),
//!   [`EventFileError`] and the temporary-file guards shared by the writers.
//! - [`background`]: [`BackgroundWriter`], any of them on a thread of its own.
//! - [`h5`]: [`NerfH5Sink`] and [`DsecH5Sink`] (pure-Rust HDF5, chunked + deflate).
//! - [`text`]: the RPG/ECD lines, [`TextSink`].
//! - [`npz`]: [`NpzSink`] (stored zip of `.npy` files, no ZIP64: at most 4 GiB).
//! - [`viz`]: [`VizSink`], not an event file but a picture of one: a PNG per time window and an
//!   event-rate table (`evsim events --viz-dir`).

pub mod background;
pub mod h5;
pub mod npz;
pub mod text;
pub mod viz;

use std::io;
use std::path::{Path, PathBuf};

pub use background::BackgroundWriter;
pub use h5::{DsecH5Sink, NerfH5Sink};
pub use npz::NpzSink;
pub use text::TextSink;
pub use viz::{VizConfig, VizConfigError, VizSink, VizSummary};

use super::{Event, EventSink};

/// The layout of an `.h5` event file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum H5Layout {
    /// Ev-DeblurNeRF: root datasets `x`, `y`, `t` (ns), `p` (+1/-1).
    #[default]
    Nerf,
    /// DSEC: `/events/{x, y, t (us), p (0/1)}`, `/t_offset`, `/ms_to_idx`.
    Dsec,
}

impl std::fmt::Display for H5Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            H5Layout::Nerf => "nerf",
            H5Layout::Dsec => "dsec",
        })
    }
}

/// Which writer an output path gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SinkKind {
    /// Ev-DeblurNeRF `.h5` ([`NerfH5Sink`]).
    NerfH5,
    /// DSEC `.h5` ([`DsecH5Sink`]).
    DsecH5,
    /// RPG/ECD text ([`TextSink`]).
    Text,
    /// NumPy `.npz` ([`NpzSink`]).
    Npz,
}

/// Why an event file could not be chosen.
#[derive(Debug, thiserror::Error)]
pub enum EventFileError {
    /// The extension is none of the supported ones.
    #[error("{path}: unknown event file type; name it .h5 (with --format nerf|dsec), .txt or .npz")]
    UnknownExtension {
        /// The output path.
        path: PathBuf,
    },
    /// An `.h5` layout was asked for a file that is not `.h5`.
    #[error("{path}: --format {layout} applies only to .h5 files; drop --format or name the file .h5")]
    LayoutNotH5 {
        /// The output path.
        path: PathBuf,
        /// The layout that was asked for.
        layout: H5Layout,
    },
}

impl SinkKind {
    /// Choose the writer from the extension (`.h5`/`.hdf5`, `.txt`, `.npz`, any case); `layout`
    /// picks the `.h5` layout (default [`H5Layout::Nerf`]) and is an error for other extensions.
    pub fn from_path(path: &Path, layout: Option<H5Layout>) -> Result<SinkKind, EventFileError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        let kind = match ext.as_deref() {
            Some("h5" | "hdf5") => {
                return Ok(match layout.unwrap_or_default() {
                    H5Layout::Nerf => SinkKind::NerfH5,
                    H5Layout::Dsec => SinkKind::DsecH5,
                })
            }
            Some("txt") => SinkKind::Text,
            Some("npz") => SinkKind::Npz,
            _ => return Err(EventFileError::UnknownExtension { path: path.to_path_buf() }),
        };
        match layout {
            Some(layout) => Err(EventFileError::LayoutNotH5 { path: path.to_path_buf(), layout }),
            None => Ok(kind),
        }
    }
}

#[cfg(test)]
mod kind_tests {
    use super::*;

    #[test]
    fn kind_follows_the_extension_and_format() {
        let k = |p: &str, l| SinkKind::from_path(Path::new(p), l);
        assert_eq!(k("a/events.h5", None).unwrap(), SinkKind::NerfH5);
        assert_eq!(k("e.HDF5", Some(H5Layout::Dsec)).unwrap(), SinkKind::DsecH5);
        assert_eq!(k("e.txt", None).unwrap(), SinkKind::Text);
        assert_eq!(k("e.npz", None).unwrap(), SinkKind::Npz);
        let e = k("e.txt", Some(H5Layout::Nerf)).unwrap_err().to_string();
        assert!(e.contains("e.txt") && e.contains("--format nerf applies only to .h5"), "{e}");
        let e = k("e.bin", None).unwrap_err().to_string();
        assert!(e.contains("e.bin") && e.contains(".npz"), "{e}");
    }
}

/// One of the event file writers; [`EventWriter::finish`] must be called to keep the file.
pub enum EventWriter {
    /// Ev-DeblurNeRF `.h5`.
    NerfH5(NerfH5Sink),
    /// DSEC `.h5`.
    DsecH5(DsecH5Sink),
    /// RPG/ECD text.
    Text(TextSink),
    /// NumPy `.npz`.
    Npz(NpzSink),
}

impl EventWriter {
    /// Start writing `path` (its temporary sibling until [`finish`](Self::finish)), creating
    /// missing folders.
    pub fn create(path: &Path, kind: SinkKind) -> io::Result<EventWriter> {
        Ok(match kind {
            SinkKind::NerfH5 => EventWriter::NerfH5(NerfH5Sink::create(path)?),
            SinkKind::DsecH5 => EventWriter::DsecH5(DsecH5Sink::create(path)?),
            SinkKind::Text => EventWriter::Text(TextSink::create(path)?),
            SinkKind::Npz => EventWriter::Npz(NpzSink::create(path)?),
        })
    }

    /// Complete the file and move it into place; returns the number of events written.
    pub fn finish(self) -> io::Result<u64> {
        match self {
            EventWriter::NerfH5(s) => s.finish(),
            EventWriter::DsecH5(s) => s.finish(),
            EventWriter::Text(s) => s.finish(),
            EventWriter::Npz(s) => s.finish(),
        }
    }
}

impl EventSink for EventWriter {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        match self {
            EventWriter::NerfH5(s) => s.push(events),
            EventWriter::DsecH5(s) => s.push(events),
            EventWriter::Text(s) => s.push(events),
            EventWriter::Npz(s) => s.push(events),
        }
    }
}

/// An I/O error that names the file and what was being done.
pub(crate) fn io_err(path: &Path, what: &str, e: impl std::fmt::Display) -> io::Error {
    io::Error::other(format!("{}: {what}: {e}", path.display()))
}

/// A hidden temporary sibling of `path`: `.name<suffix>.tmp<pid>`.
fn temp_sibling(path: &Path, suffix: &str) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}{suffix}.tmp{}", std::process::id()))
}

/// A file written under a temporary name and renamed to its target on [`commit`](Self::commit);
/// dropped uncommitted, it removes the temporary file.
pub(crate) struct AtomicTarget {
    /// The final path.
    pub path: PathBuf,
    /// The temporary sibling being written.
    pub tmp: PathBuf,
    committed: bool,
}

impl AtomicTarget {
    /// Reserve `path`, creating its missing parent folders.
    pub fn new(path: &Path) -> io::Result<AtomicTarget> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .map_err(|e| io_err(parent, "cannot create the output folder; choose another --out", e))?;
        }
        Ok(AtomicTarget { path: path.to_path_buf(), tmp: temp_sibling(path, ""), committed: false })
    }

    /// Rename the finished temporary file to the target (once; later drops keep it).
    pub fn commit_ref(&mut self) -> io::Result<()> {
        std::fs::rename(&self.tmp, &self.path).map_err(|e| io_err(&self.path, "cannot move into place", e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for AtomicTarget {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A scratch file beside an output (`.name<suffix>.tmp<pid>`), removed when dropped.
pub(crate) struct ScratchFile {
    /// Its path.
    pub path: PathBuf,
}

impl ScratchFile {
    /// Name a scratch file beside `target`.
    pub fn beside(target: &Path, suffix: &str) -> ScratchFile {
        ScratchFile { path: temp_sibling(target, suffix) }
    }
}

impl Drop for ScratchFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
pub(crate) mod test_util {
    //! Known event lists and temporary folders for the writers' tests.
    use super::super::Event;
    use std::path::{Path, PathBuf};

    /// A fresh, empty folder under the system temp dir.
    pub fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("evblur-sinks-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// `n` time-sorted events with varied coordinates, polarities and (tied) times spanning
    /// several milliseconds, starting at `t0` ns.
    pub fn known_events(n: usize, t0: i64) -> Vec<Event> {
        (0..n)
            .map(|i| Event {
                x: (i * 7 % 640) as u16,
                y: (i * 13 % 480) as u16,
                t_ns: t0 + (i as i64 / 3) * 1_733,
                p: if i % 5 < 2 { 1 } else { -1 },
            })
            .collect()
    }

    /// The names of the files in `dir`.
    pub fn files(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }
}
