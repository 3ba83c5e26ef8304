//! Step benchmarks: time whole optimisation steps (forward, backward, TV, Adam) on synthetic
//! rays, report the median and the achieved GFLOP/s (forward multiply-adds x 2 flops x 3 for
//! forward + backward, the usual convention).
//!
//! The reference step of the trainer issue: 1024 rays x 128 samples through the reference
//! coarse level (VM 256^3 [64,16,16] -> 32, 64-wide MLPs), one sampling pass.

use std::time::Instant;

use crate::config::TrainConfig;
use crate::engine::adam::Adam;
use crate::engine::model::{Model, ModelConfig};
use crate::engine::rng::Rng;
use crate::presets::{nerf, paper_model, Scale};
use crate::train::{image_step, PreparedRay, StepBuffers};

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

/// Times `reps` steps of `cfg` (after one warm-up step) on the current rayon pool.
pub fn time_steps(name: &str, cfg: &TrainConfig, reps: usize, threads: usize) -> StepTiming {
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
    let mut sorted = times_ms.clone();
    sorted.sort_by(f64::total_cmp);
    let median_ms = sorted[sorted.len() / 2];
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
