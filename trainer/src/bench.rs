//! Step benchmarks: time whole optimisation steps (forward, backward, TV, Adam) on synthetic
//! rays, report the median and the achieved GFLOP/s (forward multiply-adds x 2 flops x 3 for
//! forward + backward, the usual convention).
//!
//! The reference step of the trainer issue: 1024 rays x 128 samples through the reference
//! coarse level (VM 256^3 [64,16,16] -> 32, 64-wide MLPs), one sampling pass.
//!
//! [`time_family`]: a preset's whole step (its blur model, events, AWP) on a trained field and
//! its dataset, the dense engine and the one that skips samples alternating step by step, with
//! the samples each evaluated per ray (`evtrain bench --run RUN`). On synthetic rays through a
//! fresh field the densities are noise, so only a trained field says what skipping saves.
//! [`BenchSettings`] override settings on both paths or on the dense one only (the engine a
//! change is measured against, e.g. its former sample counts).

use std::time::Instant;

use crate::checkpoint::Checkpoint;
use crate::config::{apply_overrides, TrainConfig};
use crate::data::dataset::Dataset;
use crate::engine::adam::Adam;
use crate::engine::model::{Aabb, Model, ModelConfig};
use crate::engine::params::Layout;
use crate::engine::renderer::SampleCounts;
use crate::engine::rng::Rng;
use crate::error::TrainError;
use crate::method::rays::PreparedRay;
use crate::method::Method;
use crate::presets::{self, nerf, paper_model, Scale};
use crate::train::{image_step, StepBuffers, Trainer};

/// Timing of one benchmarked step shape.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StepTiming {
    /// What was timed.
    pub name: String,
    /// Rays per step.
    pub rays: usize,
    /// Field evaluations per ray (both passes).
    pub samples_per_ray: usize,
    /// Per-step wall times (ms), in run order.
    pub times_ms: Vec<f64>,
    /// Median (ms).
    pub median_ms: f64,
    /// Achieved GFLOP/s at the median.
    pub gflops: f64,
    /// Threads used.
    pub threads: usize,
}

/// The reference step's configuration: the paper's coarse level, 128 stratified samples.
pub fn reference_config() -> TrainConfig {
    let paper = paper_model();
    TrainConfig {
        model: ModelConfig { fine_volume: None, fine: None, n_coarse: 128, n_fine: 0, ..paper },
        batch_rays: 1024,
        ..nerf(Scale::Paper)
    }
}

/// Synthetic NDC rays through the volume with random targets.
fn synthetic_batch(n: usize, seed: u64) -> (Vec<PreparedRay>, Vec<[f32; 3]>) {
    let mut rng = Rng::new(seed, 77);
    let mut rays = Vec::with_capacity(n);
    let mut targets = Vec::with_capacity(n);
    for _ in 0..n {
        let (x, y) = (rng.uniform_f32() * 1.8 - 0.9, rng.uniform_f32() * 1.8 - 0.9);
        let (dx, dy) = (rng.uniform_f32() * 0.2 - 0.1, rng.uniform_f32() * 0.2 - 0.1);
        let d = [dx, dy, 2.0];
        let n = (dx * dx + dy * dy + 4.0).sqrt();
        rays.push(PreparedRay { origin: [x, y, -1.0], dir: d, viewdir: [dx / n, dy / n, 2.0 / n] });
        targets.push([rng.uniform_f32(), rng.uniform_f32(), rng.uniform_f32()]);
    }
    (rays, targets)
}

/// Times `reps` steps of `cfg` (after one warm-up step) on the current rayon pool, on the
/// dense engine (every sample through the whole field, so the flop count is exact).
pub fn time_steps(name: &str, cfg: &TrainConfig, reps: usize, threads: usize) -> StepTiming {
    let mut cfg = cfg.clone();
    cfg.model.dense = true;
    let cfg = &cfg;
    let model = Model::new(&cfg.model);
    let mut params = model.init(cfg.seed);
    let mut adam = Adam::new(&model.layout);
    let mut bufs = StepBuffers::new(threads);
    let mut times_ms = Vec::with_capacity(reps);
    for step in 0..=reps as u64 {
        let (rays, targets) = synthetic_batch(cfg.batch_rays, step);
        let t0 = Instant::now();
        image_step(&mut bufs, &model, &mut params, &mut adam, cfg, step, &rays, &targets);
        if step > 0 {
            times_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    let median_ms = median(&times_ms);
    let spr = cfg.model.n_coarse + if cfg.model.n_fine > 0 { model.samples_fine() } else { 0 };
    let macs = cfg.model.n_coarse * model.coarse.macs_per_sample()
        + if cfg.model.n_fine > 0 { model.samples_fine() * model.fine_field().macs_per_sample() } else { 0 };
    let flops = 6.0 * macs as f64 * cfg.batch_rays as f64;
    StepTiming {
        name: name.to_string(),
        rays: cfg.batch_rays,
        samples_per_ray: spr,
        times_ms,
        median_ms,
        gflops: flops / (median_ms * 1e-3) / 1e9,
        threads,
    }
}

/// The preset families `evtrain bench --run` times, as (family, preset): one preset per way a
/// step renders rays.
pub const FAMILIES: &[(&str, &str)] = &[
    ("plain", "nerf"),
    ("rigid kernel + AWP", "dp-nerf"),
    ("DSK", "deblur-nerf"),
    ("PDRF", "pdrf"),
    ("trajectory", "bad-nerf"),
    ("event batch", "e-nerf"),
    ("full method", "ev-deblurnerf"),
];

/// One engine path's steps in a [`FamilyTiming`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PathTiming {
    /// Per-step wall times (ms), in run order.
    pub times_ms: Vec<f64>,
    /// Median (ms).
    pub median_ms: f64,
    /// Samples volume-rendered per ray (both passes).
    pub rendered_per_ray: f64,
    /// Samples whose density the field evaluated, per ray.
    pub density_per_ray: f64,
    /// Samples of positive density (their density's backward), per ray.
    pub alive_per_ray: f64,
    /// Samples through the colour MLP (forward and backward), per ray.
    pub coloured_per_ray: f64,
    /// Samples past the end of their ray (early ray termination), per ray.
    pub ended_per_ray: f64,
    /// One rebuild of the occupancy grid (ms; 0 without a grid), and the steps between rebuilds.
    pub occupancy_ms: f64,
    /// Steps between rebuilds of the occupancy grid (0 without a grid).
    pub occupancy_every: u64,
}

impl PathTiming {
    /// The median step plus the occupancy grid's rebuild spread over the steps it serves (ms).
    pub fn per_step_ms(&self) -> f64 {
        self.median_ms + if self.occupancy_every > 0 { self.occupancy_ms / self.occupancy_every as f64 } else { 0.0 }
    }
}

/// A preset's step on a trained field, the dense engine against the one that skips samples.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FamilyTiming {
    /// The family.
    pub family: String,
    /// The preset timed for it.
    pub preset: String,
    /// Tensors of the preset's layout that start from the trained run (the rest start fresh).
    pub from_run: usize,
    /// Tensors of the preset's layout.
    pub tensors: usize,
    /// Every sample through the whole field (`model.dense = true`).
    pub dense: PathTiming,
    /// Samples of zero density skipped, the coarse evaluations re-used (the default).
    pub skipping: PathTiming,
}

/// What [`time_family`] times: the preset's cpu configuration with `set` applied (both paths),
/// then `dense_set` on the dense path.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchSettings {
    /// `KEY=VALUE` overrides for both paths ([`apply_overrides`]).
    pub set: Vec<String>,
    /// Overrides for the dense path only, after `set`; `model.dense=true` is always applied.
    pub dense_set: Vec<String>,
    /// Timed steps per path (after one warm-up).
    pub reps: usize,
    /// Worker threads (0: all cores).
    pub threads: usize,
}

/// Times `reps` steps (after one warm-up) of `preset` at the cpu scale, on both engine paths,
/// alternating a dense step and a skipping step so both see the same machine. The field starts
/// from `trained` (tensors with the same name and size as the preset's), fitted to the same
/// box `bounds`, at step `iterations / 2` (blur models, events and schedules switched on), with
/// a fresh optimiser.
pub fn time_family(
    family: &str,
    preset: &str,
    data: &Dataset,
    trained: (&Layout, &[f32]),
    bounds: Option<Aabb>,
    settings: &BenchSettings,
) -> Result<FamilyTiming, TrainError> {
    let (trained_layout, trained) = trained;
    let build = presets::preset(preset)
        .ok_or_else(|| TrainError::Config(format!("bench: no preset {preset} (presets: {:?})", presets::names())))?
        .build;
    let overrides = |cfg: &TrainConfig, sets: &[String]| {
        apply_overrides(cfg, sets).map_err(|e| TrainError::Config(format!("bench {preset}: {e}")))
    };
    let mut cfg = overrides(&build(Scale::Cpu), &settings.set)?;
    cfg.model.bounds = bounds;
    cfg.threads = settings.threads;
    let mut dense_cfg = overrides(&cfg, &settings.dense_set)?;
    dense_cfg.model.dense = true;
    let reps = settings.reps;
    let mut from_run = 0;
    let mut make = |dense: bool| -> Result<Trainer, TrainError> {
        let cfg = if dense { dense_cfg.clone() } else { cfg.clone() };
        let method = Method::new(&cfg, data.views.len());
        let mut params = method.init(cfg.seed);
        from_run = 0;
        for t in &method.layout().tensors {
            if let Some(src) =
                trained_layout.tensors.iter().find(|s| s.name == t.name && s.range.len() == t.range.len())
            {
                params[t.range.clone()].copy_from_slice(&trained[src.range.clone()]);
                from_run += 1;
            }
        }
        let adam = Adam::new(method.layout());
        let ck = Checkpoint { step: cfg.iterations / 2, seconds: 0.0, params, adam, occupancy: None };
        Trainer::new(data, cfg, Some(ck))
    };
    let (mut dense, mut skipping) = (make(true)?, make(false)?);
    let tensors = skipping.method.layout().tensors.len();
    dense.step();
    skipping.step();
    // The occupancy grid's rebuild, timed apart (the timed steps do not fall on its schedule).
    let grid_ms = |t: &mut Trainer| -> (f64, u64) {
        match t.cfg.model.occupancy.as_ref().map(|o| o.every).filter(|_| !t.cfg.model.dense) {
            Some(every) => {
                let t0 = Instant::now();
                t.rebuild_occupancy();
                (t0.elapsed().as_secs_f64() * 1e3, every)
            }
            None => (0.0, 0),
        }
    };
    let (dense_grid, skip_grid) = (grid_ms(&mut dense), grid_ms(&mut skipping));
    let (c0, k0) = (dense.sample_counts(), skipping.sample_counts());
    let (mut td, mut tk) = (Vec::with_capacity(reps), Vec::with_capacity(reps));
    for _ in 0..reps {
        for (trainer, times) in [(&mut dense, &mut td), (&mut skipping, &mut tk)] {
            let t0 = Instant::now();
            trainer.step();
            times.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    let path = |times: Vec<f64>, before: SampleCounts, after: SampleCounts, grid: (f64, u64)| {
        let rays = (after.rays - before.rays).max(1) as f64;
        PathTiming {
            median_ms: median(&times),
            times_ms: times,
            rendered_per_ray: (after.rendered - before.rendered) as f64 / rays,
            density_per_ray: (after.density - before.density) as f64 / rays,
            alive_per_ray: (after.alive - before.alive) as f64 / rays,
            coloured_per_ray: (after.coloured - before.coloured) as f64 / rays,
            ended_per_ray: (after.ended - before.ended) as f64 / rays,
            occupancy_ms: grid.0,
            occupancy_every: grid.1,
        }
    };
    Ok(FamilyTiming {
        family: family.to_string(),
        preset: preset.to_string(),
        from_run,
        tensors,
        dense: path(td, c0, dense.sample_counts(), dense_grid),
        skipping: path(tk, k0, skipping.sample_counts(), skip_grid),
    })
}

fn median(times: &[f64]) -> f64 {
    let mut sorted = times.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN)
}
