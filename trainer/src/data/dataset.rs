//! [`Dataset::load`]: check a dataset folder, then read it into the loader's world.
//!
//! Order: the schema check (`simulator::dataset::check::check_dataset`) runs first and a dataset
//! with any problem is refused with the check's report; then images, timestamps, poses (LLFF
//! conversion, scale, recentring: [`super::world`]), the dense trajectory, events and the optional
//! `ev_map.npz` and `images_sharp_1/` are read.

use std::path::{Path, PathBuf};

use simulator::dataset::check::{check_dataset, CheckOptions, EventsUnit, TestViewPolicy};
use simulator::dataset::manifest::DatasetManifest;
use simulator::npy::{read_npy, read_npz, NpyArray};
use simulator::trajectory::Pose;

use super::error::LoadError;
use super::events::{EvMap, Events};
use super::image::RgbImage;
use super::rays::{Intrinsics, Ray};
use super::trajectory::DenseTrajectory;
use super::world::{LlffRow, WorldTransform};

/// Choices the format leaves open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Which images are the sharp test views; `Auto` takes the policy the sharp marking of
    /// `timestamps.npz` matches (every 8th for the synthetic scenes, the last 5 for real ones).
    pub test_views: TestViewPolicy,
    /// Unit of the event times in `events.h5`: `Auto` (default: detected from the magnitude of
    /// `t` against the dense trajectory's times, as `evsim check` does), ns (the synthetic
    /// scenes' `events_tms_unit = ns`) or us.
    pub events_unit: EventsUnit,
    /// Read the events (false: skip `events.h5`, e.g. for image-only presets and evaluation).
    pub read_events: bool,
    /// Read `images_sharp_1/` when present (the sharp versions of every view, ours).
    pub read_sharp: bool,
    /// Events read per column per chunk (memory while reading: about 32 bytes per event of a chunk).
    pub event_chunk: usize,
}

impl Default for LoadOptions {
    fn default() -> LoadOptions {
        LoadOptions {
            test_views: TestViewPolicy::Auto,
            events_unit: EventsUnit::Auto,
            read_events: true,
            read_sharp: true,
            event_chunk: 1 << 20,
        }
    }
}

/// One image of `images_1/` with its camera and exposure.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// File name in `images_1/`.
    pub name: String,
    /// The image (blurry training view or sharp test view), display-referred [0, 1].
    pub image: RgbImage,
    /// The sharp version from `images_sharp_1/` (ours; `None` for public data).
    pub sharp: Option<RgbImage>,
    /// Mid-exposure camera-to-world pose in the loader's world.
    pub pose: Pose,
    /// Near bound, scaled.
    pub near: f64,
    /// Far bound, scaled.
    pub far: f64,
    /// Mid-exposure time (us).
    pub t_mid_us: f64,
    /// Exposure start (us).
    pub t_start_us: f64,
    /// Exposure end (us); equal to the start for a sharp view.
    pub t_end_us: f64,
}

impl View {
    /// True for a sharp view (`timestamps_start == timestamps_end`).
    pub fn is_sharp(&self) -> bool {
        self.t_start_us == self.t_end_us
    }
}

/// The train / test split.
#[derive(Clone, Debug, PartialEq)]
pub struct Split {
    /// The policy used (never `Auto`).
    pub policy: TestViewPolicy,
    /// Training view indices (blurry).
    pub train: Vec<usize>,
    /// Test view indices (sharp).
    pub test: Vec<usize>,
}

/// A loaded dataset in the loader's world (scaled by `1 / (0.75 min near)` and recentred).
#[derive(Clone, Debug)]
pub struct Dataset {
    /// The folder.
    pub dir: PathBuf,
    /// Intrinsics shared by every view (from the first row's hwf, as the reference).
    pub intrinsics: Intrinsics,
    /// The views of `images_1/`, in sequence order.
    pub views: Vec<View>,
    /// Which views train and which test.
    pub split: Split,
    /// The dense trajectory in the loader's world.
    pub trajectory: DenseTrajectory,
    /// The events (empty when [`LoadOptions::read_events`] is false).
    pub events: Events,
    /// The colour-event map, when `ev_map.npz` is present.
    pub ev_map: Option<EvMap>,
    /// From the file's world to the loader's.
    pub transform: WorldTransform,
    /// The schema check's warnings (lenient forms that were accepted).
    pub warnings: Vec<String>,
    /// The `evsim` manifest (`dataset.toml`), when the folder has one (public datasets have none).
    pub manifest: Option<DatasetManifest>,
}

const POSES: &str = "poses_bounds.npy";
const ALL_POSES: &str = "all_poses_bounds.npy";
const ALL_TIMES: &str = "all_timestamps.npy";
const TIMES: &str = "images_1/timestamps.npz";

/// An `(N, 17)` float64 array as rows.
fn read_rows(dir: &Path, file: &str) -> Result<Vec<LlffRow>, LoadError> {
    let a = read_npy(&dir.join(file)).map_err(|e| LoadError::unreadable(file, e, "write it again (evsim dataset)"))?;
    let [_, 17] = a.shape() else {
        return Err(LoadError::invalid(file, "shape", format!("{:?}, expected (N, 17)", a.shape()), "write LLFF rows"));
    };
    Ok(a.data()
        .to_f64()
        .chunks_exact(17)
        .map(|r| LlffRow::from_row_unchecked(r.try_into().expect("17 values")))
        .collect())
}

/// A named 1-D array of `npz` as f64, of length `n`.
fn vector(arrays: &[(String, NpyArray)], file: &str, name: &str, n: usize) -> Result<Vec<f64>, LoadError> {
    let (_, a) = arrays.iter().find(|(k, _)| k == name).ok_or_else(|| {
        LoadError::invalid(file, name, "missing", "write timestamps, timestamps_start, timestamps_end")
    })?;
    if a.shape() != [n] {
        return Err(LoadError::invalid(file, name, format!("shape {:?}, expected ({n},)", a.shape()), "one per image"));
    }
    Ok(a.data().to_f64())
}

impl Dataset {
    /// Check and load the dataset in `dir`.
    pub fn load(dir: &Path, opts: &LoadOptions) -> Result<Dataset, LoadError> {
        // 1. the schema check: refuse any dataset with a problem, with the check's lines
        let check_opts = CheckOptions {
            test_views: opts.test_views,
            events_unit: opts.events_unit,
            event_chunk: opts.event_chunk,
            ..CheckOptions::default()
        };
        let report = check_dataset(dir, &check_opts).map_err(|e| LoadError::NoFolder(e.to_string()))?;
        if !report.is_ok() {
            return Err(LoadError::Check {
                dir: dir.to_path_buf(),
                count: report.problems().count(),
                report: report.to_string(),
            });
        }
        let warnings = report.warnings().collect();
        let policy = report.test_views.unwrap_or(TestViewPolicy::Every8);
        let unit = report.events.as_ref().map_or(EventsUnit::Ns, |e| e.unit);
        // the check has parsed it strictly; read the typed copy the trainer uses
        let manifest = DatasetManifest::read(dir)
            .map_err(|e| LoadError::unreadable("dataset.toml", e, "simulate the dataset again (evsim dataset)"))?;

        // 2. poses: LLFF conversion, scale, recentring
        let rows = read_rows(dir, POSES)?;
        let n = rows.len();
        if n == 0 {
            return Err(LoadError::invalid(POSES, "rows", "no images", "write at least one view"));
        }
        let transform = WorldTransform::from_rows(&rows);
        let first = rows[0];
        let intrinsics = Intrinsics { width: first.width as u32, height: first.height as u32, focal: first.focal };

        // 3. timestamps
        let ts = read_npz(&dir.join(TIMES)).map_err(|e| LoadError::unreadable(TIMES, e, "write it again"))?;
        let (t_mid, t_start, t_end) = (
            vector(&ts, TIMES, "timestamps", n)?,
            vector(&ts, TIMES, "timestamps_start", n)?,
            vector(&ts, TIMES, "timestamps_end", n)?,
        );

        // 4. images (sorted names, as the check listed them)
        let names = png_names(&dir.join("images_1"))?;
        if names.len() != n {
            return Err(LoadError::invalid(
                "images_1",
                "count",
                format!("{} PNGs, {n} pose rows", names.len()),
                "one row per image",
            ));
        }
        let sharp_dir = dir.join("images_sharp_1");
        let read_sharp = opts.read_sharp && sharp_dir.is_dir();
        let mut views = Vec::with_capacity(n);
        for (i, name) in names.into_iter().enumerate() {
            let file = format!("images_1/{name}");
            let image = RgbImage::read_png(&dir.join(&file), &file)?;
            let sharp = if read_sharp {
                let file = format!("images_sharp_1/{name}");
                Some(RgbImage::read_png(&sharp_dir.join(&name), &file)?)
            } else {
                None
            };
            views.push(View {
                name,
                image,
                sharp,
                pose: transform.apply(&rows[i].pose),
                near: rows[i].near * transform.scale,
                far: rows[i].far * transform.scale,
                t_mid_us: t_mid[i],
                t_start_us: t_start[i],
                t_end_us: t_end[i],
            });
        }
        let (test, train): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| policy.is_sharp(i, n));
        let split = Split { policy, train, test };

        // 5. the dense trajectory, mapped the same way
        let dense = read_rows(dir, ALL_POSES)?;
        let times =
            read_npy(&dir.join(ALL_TIMES)).map_err(|e| LoadError::unreadable(ALL_TIMES, e, "write it again"))?;
        let times = times.data().to_f64();
        let poses: Vec<Pose> = dense.iter().map(|r| transform.apply(&r.pose)).collect();
        let trajectory = DenseTrajectory::new(times, &poses).ok_or_else(|| {
            LoadError::invalid(
                ALL_TIMES,
                "timestamps",
                "fewer than 2, or not strictly increasing, or not one per row of all_poses_bounds.npy",
                "write the dense trajectory (every rendered frame)",
            )
        })?;

        // 6. events and the colour-event map
        let size = (intrinsics.width, intrinsics.height);
        let events = if opts.read_events {
            Events::read(dir, unit, trajectory.range_us(), size, opts.event_chunk)?
        } else {
            Events::default()
        };
        let ev_map = EvMap::read(dir, size)?;
        Ok(Dataset {
            dir: dir.to_path_buf(),
            intrinsics,
            views,
            split,
            trajectory,
            events,
            ev_map,
            transform,
            warnings,
            manifest,
        })
    }

    /// The rays of `pixels` ((column, row) pairs) of view `view`, at its mid-exposure pose, in the
    /// loader's world (not NDC; see [`Intrinsics::ndc`]).
    pub fn rays(&self, view: usize, pixels: &[(u32, u32)]) -> Vec<Ray> {
        let pose = &self.views[view].pose;
        pixels.iter().map(|&(i, j)| self.intrinsics.ray(pose, i, j)).collect()
    }

    /// The ray of pixel (`i`, `j`) at time `t_us` on the dense trajectory (for events); `None`
    /// outside the trajectory.
    pub fn ray_at(&self, t_us: f64, i: u32, j: u32) -> Option<Ray> {
        Some(self.intrinsics.ray(&self.trajectory.pose_at(t_us)?, i, j))
    }
}

/// The sorted `.png` names of a folder.
fn png_names(dir: &Path) -> Result<Vec<String>, LoadError> {
    let entries = std::fs::read_dir(dir).map_err(|e| LoadError::unreadable("images_1", e, "write the images"))?;
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.to_ascii_lowercase().ends_with(".png") && !n.starts_with('.'))
        .collect();
    names.sort();
    Ok(names)
}

#[cfg(test)]
#[path = "dataset_tests.rs"]
mod tests;
