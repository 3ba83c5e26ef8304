//! The datasets of a matrix: scenes to simulate are written by the simulator library into
//! `<results>/datasets/<hash>/`, reused when there.
//!
//! Each shard writes into its own `<hash>.part-<i>of<n>/` (resumable: the simulator keeps its
//! frame cache there until the dataset is complete) and renames it to `<hash>/` when done, so
//! array jobs sharing a results folder never write one folder at once; if another shard got
//! there first, its copy is used (the same settings give the same bytes) and ours is removed.

use std::path::{Path, PathBuf};

use simulator::dataset::{write_dataset, RunOptions, Summary};

use crate::error::BenchError;
use crate::matrix::{ScenePlan, SceneSource, Shard};

/// Whether the dataset folder `dir` is complete (its manifest, written last, is there).
pub fn is_complete(dir: &Path) -> bool {
    dir.join("dataset.toml").is_file()
}

/// The dataset folder of `scene`, simulated first when needed (with `frames_cache` as the
/// simulator's frame cache if given); returns the folder and, if it was simulated now, the
/// simulator's summary (frames rendered or read from the cache, timings).
pub fn ensure(
    scene: &ScenePlan,
    results: &Path,
    shard: Shard,
    frames_cache: Option<&Path>,
) -> Result<(PathBuf, Option<Summary>), BenchError> {
    let dir = scene.dataset_dir(results);
    let plan = match &scene.source {
        SceneSource::Folder(_) => return Ok((dir, None)),
        SceneSource::Simulate(_) if is_complete(&dir) => return Ok((dir, None)),
        SceneSource::Simulate(plan) => plan,
    };
    let name = dir.file_name().expect("a hash folder").to_string_lossy().into_owned();
    let part = dir.with_file_name(format!("{name}.part-{}of{}", shard.index, shard.count));
    let opts = RunOptions {
        out: part.clone(),
        frames_cache: frames_cache.map(Path::to_owned),
        progress: false,
        ..RunOptions::default()
    };
    let summary = write_dataset(plan, &opts)?;
    match std::fs::rename(&part, &dir) {
        Ok(()) => Ok((dir, Some(summary))),
        Err(_) if is_complete(&dir) => {
            std::fs::remove_dir_all(&part).map_err(|e| {
                BenchError::results(
                    &part,
                    format!("cannot remove this duplicate of {} ({e}); delete it", dir.display()),
                )
            })?;
            Ok((dir, Some(summary)))
        }
        Err(e) => Err(BenchError::results(
            &part,
            format!("cannot move the finished dataset to {} ({e}); check the results folder", dir.display()),
        )),
    }
}
