//! The training loop: batches of random pixels of the training views, both sampling passes
//! rendered and differentiated in parallel chunks, the image loss through the camera response,
//! the TV regulariser, one Adam step; checkpoints, a log and periodic test-view evaluation.
//!
//! Image loss (both passes): L = mean over rays and channels of (g(C) - y)^2, with
//! g(c) = max(c, 1e-4)^(1 / gamma) the camera response applied to the linear colour C and y the
//! pixel's value in [0, 1]. Reproducibility: the batch, the jitter and the density noise of
//! step s come from generators seeded by (seed, s) and the ray index, and the gradient is summed
//! in a fixed order for a given thread count, so a resumed run repeats the uninterrupted one
//! bit for bit.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::checkpoint::Checkpoint;
use crate::config::{ImageSource, TrainConfig};
use crate::data::dataset::Dataset;
use crate::engine::adam::Adam;
use crate::engine::model::Model;
use crate::engine::parallel::GradBuffers;
use crate::engine::params::Layout;
use crate::engine::renderer::{RayChunk, Renderer};
use crate::engine::rng::Rng;
use crate::error::TrainError;
use crate::method::rays::{response, unzip, PreparedRay};
use crate::method::{self, Method, StepData, StepLosses};
use simulator::dataset::check::EventsUnit;
use simulator::lock::{FolderLock, LockError};

/// What a run folder's `config.toml` holds (written by `evtrain train` and `evbench run`, read
/// on resume and evaluation).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// The preset's name.
    pub preset: String,
    /// Its scale.
    pub scale: crate::presets::Scale,
    /// The dataset folder (absolute).
    pub data: PathBuf,
    /// The resolved configuration (volume box and event model filled in from the dataset).
    pub config: TrainConfig,
    /// The unit of the dataset's event times when forced (`evtrain train --events-unit`);
    /// `Auto` (left out of the file): detected when the dataset is loaded.
    #[serde(default, skip_serializing_if = "EventsUnit::is_auto")]
    pub events_unit: EventsUnit,
}

/// Files of a run folder.
#[derive(Clone, Debug)]
pub struct RunPaths {
    /// The folder.
    pub dir: PathBuf,
}

impl RunPaths {
    /// The run in `dir`.
    pub fn new(dir: &Path) -> RunPaths {
        RunPaths { dir: dir.to_path_buf() }
    }
    /// The resolved configuration.
    pub fn config(&self) -> PathBuf {
        self.dir.join("config.toml")
    }
    /// The dataset the run trains on (one line, the path).
    pub fn data(&self) -> PathBuf {
        self.dir.join("dataset.txt")
    }
    /// The latest checkpoint.
    pub fn checkpoint(&self) -> PathBuf {
        self.dir.join("checkpoint.bin")
    }
    /// The training log (CSV).
    pub fn log(&self) -> PathBuf {
        self.dir.join("log.csv")
    }
    /// Evaluation outputs.
    pub fn eval(&self) -> PathBuf {
        self.dir.join("eval")
    }

    /// Lock the run folder (which must exist) for this process: another process training or
    /// evaluating it is refused with its pid. Removes the temporary files a killed process left
    /// there (a half-written `.checkpoint.bin.tmp<pid>`). Hold it while writing the run.
    pub fn lock(&self) -> Result<FolderLock, TrainError> {
        let lock = FolderLock::acquire(&self.dir).map_err(|e| match e {
            LockError::Held { pid, .. } => TrainError::run(
                &self.dir,
                format!("another process (pid {pid}) is training or evaluating this run"),
                "wait for it to finish or stop it, or choose another --out",
            ),
            LockError::Io { path, source } => {
                TrainError::io(&path, source, "check that the run folder exists and is writable")
            }
        })?;
        simulator::lock::remove_stale_temps(&self.dir, 1) // the run folder and eval/
            .map_err(|e| TrainError::io(&self.dir, e, "remove the temporary files by hand"))?;
        Ok(lock)
    }

    /// The checkpoint to resume from (saved for `layout`), or `None` when the run has not
    /// reached its first one (`checkpoint_every` steps); a checkpoint missing once one was due
    /// (the log records that many steps, or the `.seconds` sidecar of a written one remains) is
    /// an error, not a silent restart at step 0.
    pub fn resume_checkpoint(&self, layout: &Layout, checkpoint_every: u64) -> Result<Option<Checkpoint>, TrainError> {
        let path = self.checkpoint();
        if path.is_file() {
            return Checkpoint::load(layout, &path).map(Some);
        }
        let logged = std::fs::read_to_string(self.log()).map_or(0, |t| t.lines().skip(1).count() as u64);
        let sidecar = crate::checkpoint::seconds_path(&path);
        if logged >= checkpoint_every || sidecar.is_file() {
            let sidecar_note = if sidecar.is_file() {
                format!(" and {} shows one was written", sidecar.display())
            } else {
                String::new()
            };
            let why = format!(
                "missing, but log.csv records {logged} steps (a checkpoint is written every {checkpoint_every} and at \
                 the end){sidecar_note}"
            );
            return Err(TrainError::run(
                path,
                why,
                "restore the checkpoint, or delete the run folder to train from step 0",
            ));
        }
        Ok(None)
    }
}

/// One line of the log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRow {
    /// Iterations done.
    pub step: u64,
    /// Training time (s).
    pub seconds: f64,
    /// Mean image loss of the step (both passes).
    pub loss: f64,
    /// PSNR of the fine pass on the step's batch (display space).
    pub psnr_batch: f64,
    /// Event loss of the step (unweighted; 0 without events).
    pub event_loss: f64,
    /// EDI loss of the step (unweighted; 0 without the prior).
    pub edi_loss: f64,
    /// AWP colour loss of the step (unweighted; 0 without the AWP or before the kernel starts).
    pub awp_loss: f64,
    /// Mean test-view PSNR, when evaluated at this step.
    pub psnr_test: Option<f64>,
}

/// Options that do not change the result.
#[derive(Clone, Copy, Default)]
pub struct TrainOptions<'a> {
    /// Show a progress bar.
    pub progress: bool,
    /// Set (e.g. by Ctrl-C) to stop after the current step with a checkpoint.
    pub stop: Option<&'a AtomicBool>,
    /// Stop after this many iterations even if the config asks for more (tests, benchmarks).
    pub max_steps: Option<u64>,
    /// Called after every step with its number, once the step is logged (e.g. to move a
    /// caller's progress bar).
    pub on_step: Option<&'a (dyn Fn(u64) + Sync)>,
}

impl std::fmt::Debug for TrainOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrainOptions")
            .field("progress", &self.progress)
            .field("stop", &self.stop)
            .field("max_steps", &self.max_steps)
            .field("on_step", &self.on_step.is_some())
            .finish()
    }
}

/// The state of a training run.
pub struct Trainer<'a> {
    data: &'a Dataset,
    /// The configuration.
    pub cfg: TrainConfig,
    /// The method's parameters (field, blur kernel, eCRF).
    pub method: Method,
    /// Parameters.
    pub params: Vec<f32>,
    /// Optimiser state.
    pub adam: Adam,
    /// Iterations done.
    pub step: u64,
    /// Training time so far (s).
    pub seconds: f64,
    engine: method::StepBuffers,
    /// What every step reads besides the parameters (event candidates, EDI and replacement
    /// training images).
    pub step_data: StepData,
    threads: usize,
    pool: rayon::ThreadPool,
}

/// The training images of `data` for `source`, or an error naming what is missing.
fn check_images(data: &Dataset, source: &ImageSource) -> Result<Vec<usize>, TrainError> {
    let train = data.split.train.clone();
    if train.is_empty() {
        return Err(TrainError::Missing {
            path: data.dir.clone(),
            what: "no training views (every view is a test view)".into(),
            fix: "write a dataset with more views (evsim dataset --set dataset.views=N)".into(),
        });
    }
    if *source == ImageSource::Sharp && train.iter().any(|&v| data.views[v].sharp.is_none()) {
        return Err(TrainError::Missing {
            path: data.dir.join("images_sharp_1"),
            what: "the sharp training views are missing (the preset trains on them)".into(),
            fix: "write the dataset with evsim dataset, which adds images_sharp_1/, or choose preset nerf".into(),
        });
    }
    Ok(train)
}

impl<'a> Trainer<'a> {
    /// A fresh run (parameters from the seed) or, with `checkpoint`, a resumed one; the EDI
    /// targets (if any) are computed in memory.
    pub fn new(data: &'a Dataset, cfg: TrainConfig, checkpoint: Option<Checkpoint>) -> Result<Trainer<'a>, TrainError> {
        Trainer::new_in(data, cfg, checkpoint, None)
    }

    /// As [`Trainer::new`], caching the EDI targets and deblurred images under `cache` (the run
    /// folder: `edi/`, `deblurred/`).
    pub fn new_in(
        data: &'a Dataset,
        cfg: TrainConfig,
        checkpoint: Option<Checkpoint>,
        cache: Option<&Path>,
    ) -> Result<Trainer<'a>, TrainError> {
        let mut cfg = cfg;
        cfg.validate().map_err(TrainError::Config)?;
        method::resolve(&mut cfg, data);
        let train_views = check_images(data, &cfg.images)?;
        if cfg.needs_events() && data.events.is_empty() {
            return Err(TrainError::Missing {
                path: data.dir.join("events.h5"),
                what: "the method needs events but none were loaded".into(),
                fix: "load the dataset with its events (LoadOptions::read_events) or choose an image-only preset"
                    .into(),
            });
        }
        let mut method = Method::new(&cfg, data.views.len());
        if let Some(c) = &checkpoint {
            method.restore_occupancy(c)?;
        }
        let threads = if cfg.threads == 0 { rayon::current_num_threads() } else { cfg.threads };
        check_memory(&cfg, method.layout(), threads, available_memory()).map_err(TrainError::Config)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| TrainError::Config(format!("threads = {threads}: cannot start the workers ({e})")))?;
        let step_data = pool.install(|| StepData::new(data, &cfg, train_views, cache))?;
        let (params, adam, step, seconds) = match checkpoint {
            Some(c) => (c.params, c.adam, c.step, c.seconds),
            None => (method.init(cfg.seed), Adam::new(method.layout()), 0, 0.0),
        };
        Ok(Trainer {
            data,
            cfg,
            method,
            params,
            adam,
            step,
            seconds,
            engine: method::StepBuffers::new(threads),
            step_data,
            threads,
            pool,
        })
    }

    /// The checkpoint of the current state.
    pub fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            step: self.step,
            seconds: self.seconds,
            params: self.params.clone(),
            adam: self.adam.clone(),
            occupancy: self.method.model.occupancy.as_ref().map(|g| g.bits.clone()),
        }
    }

    /// The samples this trainer's steps have rendered and evaluated so far.
    pub fn sample_counts(&self) -> crate::engine::renderer::SampleCounts {
        self.engine.sample_counts()
    }

    /// Rebuilds the occupancy grid (if the model has one) from the current parameters, as the
    /// step about to run would on its schedule.
    pub fn rebuild_occupancy(&mut self) {
        let (model, params, seed, step) = (&mut self.method.model, &self.params, self.cfg.seed, self.step);
        self.pool.install(|| model.rebuild_occupancy(params, seed, step));
    }

    /// One iteration; returns its losses.
    pub fn step(&mut self) -> StepLosses {
        let t0 = Instant::now();
        if self.method.model.occupancy_due(self.step) {
            self.rebuild_occupancy();
        }
        let (cfg, data, sd) = (&self.cfg, self.data, &self.step_data);
        let out = self.pool.install(|| {
            method::step(&mut self.engine, &self.method, &mut self.params, &mut self.adam, cfg, data, sd, self.step)
        });
        self.step += 1;
        self.seconds += t0.elapsed().as_secs_f64();
        out
    }

    /// Trains to the configured number of iterations (or until stopped), writing checkpoints
    /// and the log into `run`; returns the log rows written by this call.
    pub fn train(&mut self, run: &RunPaths, opts: &TrainOptions) -> Result<Vec<LogRow>, TrainError> {
        let end = opts.max_steps.map_or(self.cfg.iterations, |m| m.min(self.cfg.iterations));
        let bar = if opts.progress { ProgressBar::new(end) } else { ProgressBar::hidden() };
        bar.set_style(
            ProgressStyle::with_template("{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})")
                .expect("valid template"),
        );
        bar.set_position(self.step);
        let mut rows = Vec::new();
        let mut log = LogFile::open(run, self.step)?;
        while self.step < end {
            let l = self.step();
            let (loss, psnr) = (l.image, l.psnr);
            let mut row = LogRow {
                step: self.step,
                seconds: self.seconds,
                loss,
                psnr_batch: psnr,
                event_loss: l.event,
                edi_loss: l.edi,
                awp_loss: l.awp,
                psnr_test: None,
            };
            let eval_now = self.cfg.eval_every > 0 && self.step.is_multiple_of(self.cfg.eval_every);
            if eval_now || self.step == self.cfg.iterations {
                let scores =
                    crate::eval::evaluate(self.data, &self.method, &self.params, &self.cfg, self.threads, None)?;
                row.psnr_test = Some(scores.mean_psnr());
            }
            bar.set_message(format!("loss {loss:.4} psnr {psnr:.2}"));
            bar.set_position(self.step);
            log.push(&row)?;
            rows.push(row);
            if let Some(f) = opts.on_step {
                f(self.step);
            }
            let stop = opts.stop.is_some_and(|s| s.load(Ordering::SeqCst));
            if self.step.is_multiple_of(self.cfg.checkpoint_every) || self.step == end || stop {
                self.checkpoint().save(self.method.layout(), &run.checkpoint())?;
            }
            if stop {
                break;
            }
        }
        bar.finish_and_clear();
        Ok(rows)
    }
}

/// Buffers reused across steps: per-thread gradients and renderers.
#[derive(Debug, Default)]
pub struct StepBuffers {
    grads: GradBuffers,
    renderers: Vec<Renderer>,
    sum: Vec<f32>,
}

impl StepBuffers {
    /// Buffers for `threads` workers (the cut of every batch, hence the reproducibility unit).
    pub fn new(threads: usize) -> StepBuffers {
        StepBuffers {
            grads: GradBuffers::default(),
            renderers: vec![Renderer::default(); threads.max(1)],
            sum: Vec::new(),
        }
    }
}

/// One optimisation step of the image loss on given rays and target pixels (display-referred):
/// both passes forward and backward in parallel chunks on the current rayon pool, the TV
/// regulariser, Adam. Returns (mean image loss of both passes, fine-pass PSNR of the batch).
#[allow(clippy::too_many_arguments)]
pub fn image_step(
    bufs: &mut StepBuffers,
    model: &Model,
    params: &mut [f32],
    adam: &mut Adam,
    cfg: &TrainConfig,
    step: u64,
    rays: &[PreparedRay],
    targets: &[[f32; 3]],
) -> (f64, f64) {
    let n = rays.len();
    let inv_gamma = (1.0 / cfg.response_gamma) as f32;
    let scale = 1.0 / (3.0 * n as f32);
    let step_seed = cfg.seed ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let chunk_rays = cfg.chunk_rays.max(1);
    let p: &[f32] = params;
    let sums = bufs.grads.run(model.layout.len(), n, &mut bufs.renderers, |range, g, renderer| {
        let mut sums = (0.0f64, 0.0f64);
        let (mut dc, mut df) = (Vec::new(), Vec::new());
        for start in range.clone().step_by(chunk_rays) {
            let end = (start + chunk_rays).min(range.end);
            let (o, d, vd) = unzip(&rays[start..end]);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (start..end).map(|r| Rng::new(step_seed, r as u64)).collect();
            renderer.forward(model, p, &chunk, Some(&mut rngs));
            dc.clear();
            df.clear();
            for (k, y) in targets[start..end].iter().enumerate() {
                // Image loss through the camera response, both passes.
                for (out, d, sum) in
                    [(renderer.coarse()[k], &mut dc, &mut sums.0), (renderer.fine()[k], &mut df, &mut sums.1)]
                {
                    let mut grad = [0.0f32; 3];
                    for c in 0..3 {
                        let (gc, dg) = response(out[c], inv_gamma);
                        let e = gc - y[c];
                        *sum += (e * e) as f64;
                        grad[c] = 2.0 * e * dg * scale;
                    }
                    d.push(grad);
                }
            }
            renderer.backward(model, p, g, &chunk, &dc, &df, None, None);
        }
        sums
    });
    let g = &mut bufs.sum;
    g.clear();
    g.resize(model.layout.len(), 0.0);
    bufs.grads.sum_into(g);
    let (sc, sf) = sums.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    model.tv(params, g);
    adam.step(&cfg.adam, &model.layout, params, g);
    let mse_f = sf / (3 * n) as f64;
    ((sc + sf) / (3 * n) as f64, -10.0 * mse_f.log10())
}

/// The CSV log, truncated to the rows up to the checkpoint when a run resumes.
struct LogFile {
    path: PathBuf,
    text: String,
}

impl LogFile {
    const HEADER: &'static str = "step,seconds,loss,psnr_batch,event_loss,edi_loss,awp_loss,psnr_test\n";

    fn open(run: &RunPaths, step: u64) -> Result<LogFile, TrainError> {
        let path = run.log();
        let mut text = String::from(Self::HEADER);
        if let Ok(old) = std::fs::read_to_string(&path) {
            for line in old.lines().skip(1) {
                let s: u64 = line.split(',').next().and_then(|s| s.parse().ok()).unwrap_or(u64::MAX);
                if s <= step {
                    text.push_str(line);
                    text.push('\n');
                }
            }
        }
        Ok(LogFile { path, text })
    }

    fn push(&mut self, r: &LogRow) -> Result<(), TrainError> {
        let test = r.psnr_test.map_or(String::new(), |p| format!("{p:.4}"));
        self.text.push_str(&format!(
            "{},{:.3},{:.6},{:.4},{:.6},{:.6},{:.6},{}\n",
            r.step, r.seconds, r.loss, r.psnr_batch, r.event_loss, r.edi_loss, r.awp_loss, test
        ));
        if r.psnr_test.is_some() || r.step.is_multiple_of(50) {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&self) -> Result<(), TrainError> {
        simulator::image_io::write_atomic(&self.path, self.text.as_bytes()).map_err(|e| {
            TrainError::run(&self.path, format!("cannot write the log: {e:#}"), "check the run folder is writable")
        })
    }
}

impl Drop for LogFile {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}

/// Bytes per parameter a run holds: the value, Adam's two moments, the summed gradient and one
/// gradient buffer per worker thread, all `f32`.
fn bytes_per_parameter(threads: usize) -> u64 {
    4 * (4 + threads as u64)
}

/// Refuses `cfg` (for a dataset of `views` views) when its training state cannot fit in this
/// machine's available memory; the message names the volume settings that size it. The trainer
/// checks this itself; call it to refuse before writing anything.
pub fn check_fits_in_memory(cfg: &TrainConfig, views: usize) -> Result<(), String> {
    let threads = if cfg.threads == 0 { rayon::current_num_threads() } else { cfg.threads };
    check_memory(cfg, Method::new(cfg, views).layout(), threads, available_memory())
}

/// The memory this machine has available (`MemAvailable` of `/proc/meminfo`), when known.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Refuses a model whose training state cannot fit in `available` bytes (a mistyped volume
/// resolution would otherwise abort the process on allocation), naming the settings that size it.
fn check_memory(cfg: &TrainConfig, layout: &Layout, threads: usize, available: Option<u64>) -> Result<(), String> {
    let parameters = layout.len();
    let need = (parameters as u64).saturating_mul(bytes_per_parameter(threads));
    let Some(available) = available else { return Ok(()) };
    if need <= available {
        return Ok(());
    }
    let gb = |b: u64| b as f64 / 1e9;
    let m = &cfg.model;
    let volumes = match &m.fine_volume {
        Some(f) => format!(
            "model.coarse_volume.res = {} (comps {:?}), model.fine_volume.res = {} (comps {:?})",
            m.coarse_volume.res, m.coarse_volume.comps, f.res, f.comps
        ),
        None => format!("model.coarse_volume.res = {} (comps {:?})", m.coarse_volume.res, m.coarse_volume.comps),
    };
    let largest = layout
        .tensors
        .iter()
        .max_by_key(|t| t.range.len())
        .map_or_else(String::new, |t| format!("; its largest tensor is {} ({} parameters)", t.name, t.range.len()));
    Err(format!(
        "the model has {parameters} parameters{largest}: training needs about {:.1} GB (parameters, Adam state and \
         {threads} gradient buffers) but {:.1} GB of memory is available; {volumes} and the MLP widths \
         (model.coarse.density_hidden, ...) size it; lower them (the cpu presets use res 256, the paper presets \
         256 and 512)",
        gb(need),
        gb(available)
    ))
}

#[cfg(test)]
mod memory_tests {
    use super::*;
    use crate::engine::model::Model;

    #[test]
    fn a_model_too_big_for_the_memory_is_refused_by_name_and_a_preset_fits() {
        let mut cfg = crate::presets::nerf(crate::presets::Scale::Cpu);
        let n = &Model::new(&cfg.model).layout;
        // 24 GB, this project's reference machine
        let machine = Some(24_000_000_000);
        assert_eq!(check_memory(&cfg, n, 2, machine), Ok(()));
        assert_eq!(check_memory(&cfg, n, 2, None), Ok(()));
        cfg.model.coarse_volume.res = 100_000;
        let n = &Model::new(&cfg.model).layout;
        let e = check_memory(&cfg, n, 2, machine).unwrap_err();
        assert!(e.contains("model.coarse_volume.res = 100000") && e.contains("GB of memory is available"), "{e}");
        assert!(e.contains("largest tensor is"), "{e}");
        // an unknown amount of memory refuses nothing
        assert_eq!(check_memory(&cfg, n, 2, None), Ok(()));
    }
}
