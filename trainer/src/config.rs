//! Training configuration: everything a run needs besides the dataset, as one serde struct that
//! a preset builds and a run folder records (`config.toml`). Unknown keys are rejected.

use crate::engine::adam::AdamConfig;
use crate::engine::model::ModelConfig;

/// Which images supervise the colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImageSource {
    /// The blurry training views of `images_1/`.
    Blurry,
    /// The sharp renders of the same views from `images_sharp_1/` (the upper bound).
    Sharp,
}

/// A whole training run's settings.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// The radiance field and its sampling.
    pub model: ModelConfig,
    /// Optimiser and learning-rate schedule.
    pub adam: AdamConfig,
    /// Training iterations (reference: 30 000).
    pub iterations: u64,
    /// Image rays per iteration (reference: 1024).
    pub batch_rays: usize,
    /// Rays rendered per field call (more: bigger matrix products; fewer: less memory).
    pub chunk_rays: usize,
    /// Which images supervise the colour.
    pub images: ImageSource,
    /// Camera response exponent: the network's linear colour c is shown as c^(1/gamma)
    /// (reference synthetic data: 2.2).
    pub response_gamma: f64,
    /// Seed of initialisation, ray batches, jitter and density noise.
    pub seed: u64,
    /// Write a checkpoint every this many iterations (and at the end).
    pub checkpoint_every: u64,
    /// Evaluate the test views every this many iterations for the log (0: only at the end).
    pub eval_every: u64,
    /// Worker threads (0: all cores). Results are bit-reproducible for a given count.
    pub threads: usize,
}

impl TrainConfig {
    /// Checks values a preset or a hand-edited `config.toml` could get wrong; the message names
    /// the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        let m = &self.model;
        let positive = [
            ("iterations", self.iterations as f64),
            ("batch_rays", self.batch_rays as f64),
            ("chunk_rays", self.chunk_rays as f64),
            ("checkpoint_every", self.checkpoint_every as f64),
            ("response_gamma", self.response_gamma),
            ("model.n_coarse", m.n_coarse as f64 - 2.0),
            ("model.coarse_volume.res", m.coarse_volume.res as f64 - 1.0),
            ("adam.decay_steps", self.adam.decay_steps),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} is out of range; it must be a positive number (n_coarse >= 3, res >= 2)"));
            }
        }
        let non_negative = [
            ("model.density_noise", m.density_noise),
            ("model.tv_plane", m.tv_plane),
            ("model.tv_line", m.tv_line),
            ("adam.lr_volume", self.adam.lr_volume),
            ("adam.lr_network", self.adam.lr_network),
            ("adam.lr_embedding", self.adam.lr_embedding),
            ("adam.eps", self.adam.eps),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} = {v}; it must be a finite number >= 0"));
            }
        }
        for (name, b) in
            [("adam.beta1", self.adam.beta1), ("adam.beta2", self.adam.beta2), ("adam.decay", self.adam.decay)]
        {
            if !(0.0..=1.0).contains(&b) {
                return Err(format!("{name} = {b}; it must be in [0, 1]"));
            }
        }
        Ok(())
    }
}
