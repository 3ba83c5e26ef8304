//! The dataset schema check: open a dataset folder (ours or a public Ev-DeblurBlender /
//! Ev-DeblurCDAVIS one) and verify it against `docs/dataset-format.md`, the layout the reference
//! loader reads.
//!
//! [`check_dataset`] runs every check it can and collects the outcome of each in a
//! [`CheckReport`] (one [`CheckLine`] per check: ok, warning, absent optional file, or a
//! [`CheckError`] naming the file, the field and the fix); a problem in one file does not stop the
//! checks of the others. Only a folder that cannot be listed at all is an `Err`.
//!
//! | file | checked |
//! |---|---|
//! | `images_1/*.png` | zero-padded names in sequence, one size, 8-bit RGB (RGBA: warning), count N |
//! | `images_1/timestamps.npz` | `timestamps`, `timestamps_start`, `timestamps_end`: float64 (N,), finite, > 0, start <= mid <= end, mid non-decreasing, sharp (start == end) views follow the test-view policy |
//! | `poses_bounds.npy` | float64 (N, 17), pure rotations (`[c1, -c0, c2]`, tolerance 1e-4), hwf = (H, W, f > 0), 0 < near < far |
//! | `all_poses_bounds.npy`, `all_timestamps.npy` | the same rows (M, 17); float64 (M,) strictly increasing; every exposure window inside their range |
//! | `events.h5` | `x`, `y`, `t`, `p` 1-D of equal length, integer (float: rectified), `t` non-decreasing and inside the trajectory's range (ns or us, auto-detected), `p` in {0, 1} or {-1, +1}, 0 <= x < W, 0 <= y < H; streamed in chunks |
//! | `ev_map.npz` (optional) | `inv_mapx`, `inv_mapy` of shape (H, W) |
//! | `images_sharp_1/` (optional, ours) | the same PNG names and size as `images_1/` |
//! | `dataset.toml` (optional, ours) | parsed strictly ([`super::manifest::DatasetManifest`]); `views`, `width` x `height` and `events` agree with the files |
//!
//! Test-view policies: synthetic scenes hold out every 8th image (index 0, 8, 16, ...:
//! `llffhold = 8`), the real-camera scenes the last 5; [`TestViewPolicy::Auto`] accepts either
//! and reports which one matched.
//!
//! What lives where: this file holds the options, the report, the error and the order of the
//! checks; `check_arrays` the `.npy` / `.npz` checks; `check_images` the PNG folders;
//! `check_events` the event file.

use std::fmt;
use std::path::{Path, PathBuf};

use super::check_arrays::{check_dense, check_ev_map, check_poses, check_timestamps};
use super::check_events::check_events;
use super::check_images::{check_images, check_sharp_images};

/// Which images are the sharp test views.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum TestViewPolicy {
    /// Accept either policy below and report which one matched.
    #[default]
    Auto,
    /// Every 8th image, index 0, 8, 16, ... (`llffhold = 8`, the synthetic scenes).
    Every8,
    /// The last 5 images (the real-camera scenes).
    Last5,
}

impl TestViewPolicy {
    /// True if image `i` of `n` is a sharp test view under this policy (`Auto`: never asked).
    pub fn is_sharp(self, i: usize, n: usize) -> bool {
        match self {
            TestViewPolicy::Every8 => i.is_multiple_of(8),
            TestViewPolicy::Last5 => i + 5 >= n,
            TestViewPolicy::Auto => false,
        }
    }
}

impl fmt::Display for TestViewPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TestViewPolicy::Auto => "auto",
            TestViewPolicy::Every8 => "every8 (llffhold = 8)",
            TestViewPolicy::Last5 => "last5",
        })
    }
}

/// The unit of the event times `t` in `events.h5`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EventsUnit {
    /// Decide from the magnitude of `t` against `all_timestamps.npy` (microseconds).
    #[default]
    Auto,
    /// Nanoseconds (the synthetic scenes, `events_tms_unit = ns`).
    Ns,
    /// Microseconds.
    Us,
}

impl EventsUnit {
    /// True for [`EventsUnit::Auto`] (a record leaves the default out).
    pub fn is_auto(&self) -> bool {
        *self == EventsUnit::Auto
    }

    /// Microseconds per unit of `t` (`Auto`: ns, the spec's default).
    pub fn us_per_unit(self) -> f64 {
        match self {
            EventsUnit::Ns | EventsUnit::Auto => 1e-3,
            EventsUnit::Us => 1.0,
        }
    }
}

impl fmt::Display for EventsUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EventsUnit::Auto => "auto",
            EventsUnit::Ns => "ns",
            EventsUnit::Us => "us",
        })
    }
}

/// What [`check_dataset`] expects where the format leaves a choice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckOptions {
    /// Which images must be the sharp test views.
    pub test_views: TestViewPolicy,
    /// Unit of the event times.
    pub events_unit: EventsUnit,
    /// Largest accepted deviation of `R^T R` from `I` and of `det R` from 1 (dimensionless);
    /// 1e-4 accepts the float32-derived rotations of the public files.
    pub rotation_tolerance: f64,
    /// Events read per column per chunk (memory: about 32 bytes per event of a chunk).
    pub event_chunk: usize,
}

impl Default for CheckOptions {
    fn default() -> CheckOptions {
        CheckOptions {
            test_views: TestViewPolicy::Auto,
            events_unit: EventsUnit::Auto,
            rotation_tolerance: 1e-4,
            event_chunk: 1 << 20,
        }
    }
}

/// One problem found in a dataset (or the folder that could not be opened).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// The folder itself cannot be listed.
    #[error("{}: cannot open the dataset folder ({message}); pass the folder that holds images_1/ and poses_bounds.npy", dir.display())]
    NoFolder {
        /// The folder.
        dir: PathBuf,
        /// The system's reason.
        message: String,
    },
    /// A required file or folder is missing.
    #[error("{file}: missing; {fix}")]
    Missing {
        /// The file, relative to the dataset folder.
        file: String,
        /// What writes it.
        fix: String,
    },
    /// A file exists but cannot be read as what it should be (truncated, not the format).
    #[error("{file}: cannot be read: {message}; {fix}")]
    Unreadable {
        /// The file, relative to the dataset folder.
        file: String,
        /// The reader's reason.
        message: String,
        /// How to write it again.
        fix: String,
    },
    /// A field (array, dataset, row, image) holds values the format does not allow.
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

/// The outcome of one check.
#[derive(Debug, Clone, PartialEq)]
pub enum CheckLine {
    /// The check passed; `detail` says what was found.
    Ok {
        /// The file or field checked.
        check: String,
        /// What was found (counts, dtypes, ranges).
        detail: String,
    },
    /// Accepted, but not the strict form the format asks for.
    Warning {
        /// The file or field checked.
        check: String,
        /// What is lenient about it.
        detail: String,
    },
    /// What a file holds, when it also has problems (so the counts are still shown).
    Info {
        /// The file.
        check: String,
        /// What was found.
        detail: String,
    },
    /// An optional file is not there.
    Absent {
        /// The file.
        file: String,
        /// What it would be for.
        detail: String,
    },
    /// A problem: the dataset does not follow the format.
    Problem(CheckError),
}

/// What the events file holds (filled when `events.h5` could be read).
#[derive(Debug, Clone, PartialEq)]
pub struct EventSummary {
    /// Number of events.
    pub count: u64,
    /// First and last `t`, in the file's unit (None when there are no events).
    pub t_range: Option<(f64, f64)>,
    /// The unit used for `t` (never `Auto`).
    pub unit: EventsUnit,
    /// Events with `p > 0`.
    pub on: u64,
    /// Events with `p <= 0`.
    pub off: u64,
}

/// Everything [`check_dataset`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// The dataset folder.
    pub dir: PathBuf,
    /// One line per check, in the order they ran.
    pub lines: Vec<CheckLine>,
    /// Number of images in `images_1/` (None if the folder is missing).
    pub n_images: Option<usize>,
    /// Image (width, height) in pixels, if the images agree on one.
    pub image_size: Option<(u32, u32)>,
    /// The test-view policy the sharp marking matched (never `Auto`).
    pub test_views: Option<TestViewPolicy>,
    /// The events, when `events.h5` could be read.
    pub events: Option<EventSummary>,
}

impl CheckReport {
    /// True if no check found a problem (warnings and absent optional files are fine).
    pub fn is_ok(&self) -> bool {
        self.problems().next().is_none()
    }

    /// The problems, in order.
    pub fn problems(&self) -> impl Iterator<Item = &CheckError> {
        self.lines.iter().filter_map(|l| match l {
            CheckLine::Problem(e) => Some(e),
            _ => None,
        })
    }

    /// The warnings, as `check: detail`.
    pub fn warnings(&self) -> impl Iterator<Item = String> + '_ {
        self.lines.iter().filter_map(|l| match l {
            CheckLine::Warning { check, detail } => Some(format!("{check}: {detail}")),
            _ => None,
        })
    }
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "dataset check of {}", self.dir.display())?;
        for line in &self.lines {
            match line {
                CheckLine::Ok { check, detail } => writeln!(f, "  ok       {check}: {detail}")?,
                CheckLine::Warning { check, detail } => writeln!(f, "  warning  {check}: {detail}")?,
                CheckLine::Info { check, detail } => writeln!(f, "  info     {check}: {detail}")?,
                CheckLine::Absent { file, detail } => writeln!(f, "  absent   {file} (optional): {detail}")?,
                CheckLine::Problem(e) => writeln!(f, "  PROBLEM  {e}")?,
            }
        }
        match self.problems().count() {
            0 => write!(f, "all checks passed"),
            n => write!(f, "{n} problem(s) found"),
        }
    }
}

/// The lines collected so far, with shorthands for the checks.
pub(super) struct Lines(pub Vec<CheckLine>);

impl Lines {
    /// A passed check.
    pub fn ok(&mut self, check: impl Into<String>, detail: impl Into<String>) {
        self.0.push(CheckLine::Ok { check: check.into(), detail: detail.into() });
    }
    /// A lenient form.
    pub fn warn(&mut self, check: impl Into<String>, detail: impl Into<String>) {
        self.0.push(CheckLine::Warning { check: check.into(), detail: detail.into() });
    }
    /// What a file holds, beside its problems.
    pub fn info(&mut self, check: impl Into<String>, detail: impl Into<String>) {
        self.0.push(CheckLine::Info { check: check.into(), detail: detail.into() });
    }
    /// A problem.
    pub fn problem(&mut self, e: CheckError) {
        self.0.push(CheckLine::Problem(e));
    }
    /// A field with a bad value.
    pub fn invalid(
        &mut self,
        file: &str,
        field: impl Into<String>,
        problem: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.problem(CheckError::Invalid {
            file: file.into(),
            field: field.into(),
            problem: problem.into(),
            fix: fix.into(),
        });
    }
    /// A missing required file.
    pub fn missing(&mut self, file: &str, fix: impl Into<String>) {
        self.problem(CheckError::Missing { file: file.into(), fix: fix.into() });
    }
    /// A file that cannot be read.
    pub fn unreadable(&mut self, file: &str, message: impl fmt::Display, fix: impl Into<String>) {
        self.problem(CheckError::Unreadable { file: file.into(), message: message.to_string(), fix: fix.into() });
    }
    /// Number of problems so far.
    pub fn problem_count(&self) -> usize {
        self.0.iter().filter(|l| matches!(l, CheckLine::Problem(_))).count()
    }
}

/// The image timestamps (us) the later checks compare against.
pub(super) struct ImageTimes {
    /// `timestamps_start`.
    pub start: Vec<f64>,
    /// `timestamps_end`.
    pub end: Vec<f64>,
}

/// Check the dataset in `dir` against the format; every problem found is a line of the report.
/// `Err` only when `dir` cannot be listed.
pub fn check_dataset(dir: &Path, opts: &CheckOptions) -> Result<CheckReport, CheckError> {
    if let Err(e) = std::fs::read_dir(dir) {
        return Err(CheckError::NoFolder { dir: dir.to_path_buf(), message: e.to_string() });
    }
    let mut lines = Lines(Vec::new());
    let images = check_images(dir, &mut lines);
    let (n, size) = (images.as_ref().map(|i| i.names.len()), images.as_ref().and_then(|i| i.size));
    let (times, test_views) = check_timestamps(dir, n, opts.test_views, &mut lines);
    check_poses(dir, "poses_bounds.npy", n, size, opts.rotation_tolerance, &mut lines);
    let dense_range = check_dense(dir, size, times.as_ref(), opts.rotation_tolerance, &mut lines);
    let events = check_events(dir, size, dense_range, opts, &mut lines);
    check_ev_map(dir, size, &mut lines);
    if let Some(images) = &images {
        check_sharp_images(dir, images, &mut lines);
    }
    match super::manifest::DatasetManifest::read(dir) {
        Ok(Some(m)) => {
            let fix = "the folder mixes two datasets or the manifest was edited; simulate it again (evsim dataset)";
            if n.is_some_and(|n| n != m.views) {
                lines.invalid(
                    "dataset.toml",
                    "views",
                    format!("{} views, but images_1/ has {}", m.views, n.unwrap_or(0)),
                    fix,
                );
            } else if let Some((w, h)) = size.filter(|&s| s != (m.dataset.width, m.dataset.height)) {
                lines.invalid(
                    "dataset.toml",
                    "dataset.width, dataset.height",
                    format!("{}x{}, but the images are {w}x{h}", m.dataset.width, m.dataset.height),
                    fix,
                );
            } else if let Some(e) = events.as_ref().filter(|e| e.count != m.events) {
                lines.invalid(
                    "dataset.toml",
                    "events",
                    format!("{} events, but events.h5 has {}", m.events, e.count),
                    fix,
                );
            } else {
                let c = &m.event_model;
                lines.ok(
                    "dataset.toml",
                    format!("evblur manifest: thresholds {}/{}, log_eps {}", c.c_pos, c.c_neg, c.log_eps),
                );
            }
        }
        Ok(None) => lines.0.push(CheckLine::Absent {
            file: "dataset.toml".into(),
            detail: "the evblur manifest (public datasets have none; the trainer then takes the reference event model)"
                .into(),
        }),
        Err(e) => lines.invalid(
            "dataset.toml",
            "manifest",
            e,
            "restore the file evsim wrote (simulate the dataset again), or delete it to use the reference event model",
        ),
    }
    Ok(CheckReport { dir: dir.to_path_buf(), lines: lines.0, n_images: n, image_size: size, test_views, events })
}

#[cfg(test)]
#[path = "check_tests.rs"]
mod tests;
