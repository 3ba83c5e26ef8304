//! Opening a run folder, the one way `evtrain train` and `evbench run` both do it: lock the
//! folder, read its record (`config.toml`) or write a new one resolved against the dataset, and
//! find the checkpoint to resume from.
//!
//! ```text
//! RunPlan::start(dir, record)   a new run; a folder that holds one is refused
//! RunPlan::resume(dir)          the run in dir; a folder without one is refused
//! RunPlan::open(dir, new)       the run in dir, or a new one from `new` (evbench's cells)
//! plan.checkpoint(views)        the newest checkpoint, checked against the run's layout
//! ```

use std::path::{Path, PathBuf};

use crate::checkpoint::Checkpoint;
use crate::config::TrainConfig;
use crate::data::dataset::Dataset;
use crate::error::TrainError;
use crate::method::Method;
use crate::presets::Scale;
use crate::train::{check_fits_in_memory, RunPaths, RunRecord};
use simulator::dataset::check::EventsUnit;
use simulator::lock::FolderLock;

/// A new run's record: `config` with what it leaves to the dataset filled in (the volume box
/// fitted to the cameras, the event model from `dataset.toml`), refused when its training state
/// cannot fit in this machine's memory. `data` should be absolute (runs resume from elsewhere).
pub fn new_record(
    preset: &str,
    scale: Scale,
    data: PathBuf,
    mut config: TrainConfig,
    dataset: &Dataset,
    events_unit: EventsUnit,
) -> Result<RunRecord, TrainError> {
    crate::method::resolve(&mut config, dataset);
    check_fits_in_memory(&config, dataset.views.len()).map_err(TrainError::Config)?;
    Ok(RunRecord { preset: preset.to_string(), scale, data, config, events_unit })
}

/// An open run folder, locked for this process while the plan lives, and its record.
#[derive(Debug)]
pub struct RunPlan {
    /// The folder's files.
    pub paths: RunPaths,
    /// What `config.toml` holds (or was just written with).
    pub record: RunRecord,
    /// Whether this plan wrote the record (a new run).
    pub fresh: bool,
    _lock: FolderLock,
}

impl RunPlan {
    /// Starts a new run in `dir` (created when missing) with `record`: a folder that already
    /// holds a run (`config.toml`) is refused, also when another process started one there
    /// between the caller's check and this lock.
    pub fn start(dir: &Path, record: RunRecord) -> Result<RunPlan, TrainError> {
        let paths = RunPaths::new(dir);
        refuse_existing(&paths, "")?;
        create(dir)?;
        let lock = paths.lock()?;
        refuse_existing(&paths, " meanwhile")?;
        write_record(&paths.config(), &record)?;
        Ok(RunPlan { paths, record, fresh: true, _lock: lock })
    }

    /// The run in `dir`, to resume or evaluate: a folder without a run record is refused.
    pub fn resume(dir: &Path) -> Result<RunPlan, TrainError> {
        let paths = RunPaths::new(dir);
        if !paths.config().is_file() {
            return Err(TrainError::run(
                paths.config(),
                "not a run folder (no config.toml)",
                "train a run there first (evtrain train without --resume), or check the path",
            ));
        }
        let lock = paths.lock()?;
        let record = read_record(&paths.config())?;
        Ok(RunPlan { paths, record, fresh: false, _lock: lock })
    }

    /// The run in `dir` (created when missing) if it holds one, else a new one with the record
    /// `new` makes (called under the lock, so two processes never both start it).
    pub fn open(dir: &Path, new: impl FnOnce() -> Result<RunRecord, TrainError>) -> Result<RunPlan, TrainError> {
        let paths = RunPaths::new(dir);
        create(dir)?;
        let lock = paths.lock()?;
        if paths.config().is_file() {
            let record = read_record(&paths.config())?;
            return Ok(RunPlan { paths, record, fresh: false, _lock: lock });
        }
        let record = new()?;
        write_record(&paths.config(), &record)?;
        Ok(RunPlan { paths, record, fresh: true, _lock: lock })
    }

    /// The checkpoint to resume from, for a dataset of `views` views: `None` for a new run or
    /// one that has not reached its first checkpoint; a checkpoint of another layout, or one
    /// missing once it was due, is an error (see [`RunPaths::resume_checkpoint`]).
    pub fn checkpoint(&self, views: usize) -> Result<Option<Checkpoint>, TrainError> {
        if self.fresh {
            return Ok(None);
        }
        let layout = Method::new(&self.record.config, views);
        self.paths.resume_checkpoint(layout.layout(), self.record.config.checkpoint_every)
    }

    /// Writes the record again after a change (more iterations, a moved dataset folder),
    /// validating it first.
    pub fn save_record(&self) -> Result<(), TrainError> {
        self.record.config.validate().map_err(TrainError::Config)?;
        write_record(&self.paths.config(), &self.record)
    }
}

/// Reads a run record (`config.toml`) at `path`, validated as a new run's settings are.
pub fn read_record(path: &Path) -> Result<RunRecord, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e, "check the run folder"))?;
    let record: RunRecord = toml::from_str(&text).map_err(|e| {
        TrainError::run(
            path,
            format!("not a run record ({})", e.message().trim()),
            "delete the run folder to train it again",
        )
    })?;
    record
        .config
        .validate()
        .map_err(|e| TrainError::run(path, e, "fix it, or delete the run folder to train it again"))?;
    Ok(record)
}

/// Writes `record` to `path` atomically.
pub fn write_record(path: &Path, record: &RunRecord) -> Result<(), TrainError> {
    let text = toml::to_string(record)
        .map_err(|e| TrainError::run(path, format!("cannot encode the run record ({e})"), "report this"))?;
    simulator::image_io::write_atomic(path, text.as_bytes())
        .map_err(|e| TrainError::run(path, format!("cannot write ({e:#})"), "check that the run folder is writable"))
}

fn create(dir: &Path) -> Result<(), TrainError> {
    std::fs::create_dir_all(dir).map_err(|e| TrainError::io(dir, e, "choose a writable run folder"))
}

fn refuse_existing(paths: &RunPaths, when: &str) -> Result<(), TrainError> {
    if paths.config().exists() {
        return Err(TrainError::run(
            &paths.dir,
            format!("a run was started there{when}"),
            "pass --resume to continue it or choose another --out",
        ));
    }
    Ok(())
}
