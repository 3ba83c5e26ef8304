//! Adam (Kingma & Ba 2015) over the flat parameter vector, PyTorch's form:
//! m = b1 m + (1 - b1) g, v = b2 v + (1 - b2) g^2,
//! p -= lr * (m / (1 - b1^t)) / (sqrt(v / (1 - b2^t)) + eps),
//! with one learning rate per [`LrClass`] and the reference's exponential decay
//! lr(step) = lr0 * gamma^(step / decay_steps). Element-wise and parallel; the result does not
//! depend on the thread count.

use super::params::{Layout, LrClass};
use rayon::prelude::*;

/// Adam hyper-parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdamConfig {
    /// Initial learning rate of the volumes.
    pub lr_volume: f64,
    /// Initial learning rate of the networks (MLPs, basis matrices).
    pub lr_network: f64,
    /// Initial learning rate of per-image embeddings and pose corrections.
    pub lr_embedding: f64,
    /// First-moment decay (reference 0.9).
    pub beta1: f64,
    /// Second-moment decay (reference 0.999).
    pub beta2: f64,
    /// Denominator offset (PyTorch default 1e-8).
    pub eps: f64,
    /// Decay factor reached after `decay_steps` (reference 0.1).
    pub decay: f64,
    /// Steps over which the rate falls by `decay` (reference 10 000).
    pub decay_steps: f64,
}

impl AdamConfig {
    /// The learning rate of `class` at `step` (0-based).
    pub fn lr(&self, class: LrClass, step: u64) -> f64 {
        let lr0 = match class {
            LrClass::Volume => self.lr_volume,
            LrClass::Network => self.lr_network,
            LrClass::Embedding => self.lr_embedding,
        };
        lr0 * self.decay.powf(step as f64 / self.decay_steps)
    }
}

/// Adam's state: both moments and the step count.
#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    /// First moments.
    pub m: Vec<f32>,
    /// Second moments.
    pub v: Vec<f32>,
    /// Steps taken.
    pub t: u64,
}

impl Adam {
    /// Zero state for `layout`.
    pub fn new(layout: &Layout) -> Adam {
        Adam { m: layout.zeros(), v: layout.zeros(), t: 0 }
    }

    /// One step with gradients `grads`, learning rates at step `self.t`.
    pub fn step(&mut self, cfg: &AdamConfig, layout: &Layout, params: &mut [f32], grads: &[f32]) {
        let lrs: Vec<f64> = layout.tensors.iter().map(|t| cfg.lr(t.class, self.t)).collect();
        self.t += 1;
        let bc1 = 1.0 - cfg.beta1.powi(self.t as i32);
        let bc2 = 1.0 - cfg.beta2.powi(self.t as i32);
        let (b1, b2, eps) = (cfg.beta1 as f32, cfg.beta2 as f32, cfg.eps as f32);
        const BLOCK: usize = 1 << 14;
        for (tensor, lr) in layout.tensors.iter().zip(lrs) {
            let r = tensor.range.clone();
            let step_size = (lr / bc1) as f32;
            let inv_bc2_sqrt = (1.0 / bc2.sqrt()) as f32;
            params[r.clone()]
                .par_chunks_mut(BLOCK)
                .zip(self.m[r.clone()].par_chunks_mut(BLOCK))
                .zip(self.v[r.clone()].par_chunks_mut(BLOCK))
                .zip(grads[r].par_chunks(BLOCK))
                .for_each(|(((p, m), v), g)| {
                    for i in 0..p.len() {
                        m[i] = b1 * m[i] + (1.0 - b1) * g[i];
                        v[i] = b2 * v[i] + (1.0 - b2) * g[i] * g[i];
                        p[i] -= step_size * m[i] / (v[i].sqrt() * inv_bc2_sqrt + eps);
                    }
                });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> AdamConfig {
        AdamConfig {
            lr_volume: 0.02,
            lr_network: 0.001,
            lr_embedding: 0.0,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            decay: 0.1,
            decay_steps: 10_000.0,
        }
    }

    #[test]
    fn matches_pytorch_formula_step_by_step() {
        let mut layout = Layout::default();
        layout.alloc("a", 2, LrClass::Volume);
        layout.alloc("b", 1, LrClass::Network);
        let mut p = vec![1.0f32, -2.0, 0.5];
        let mut adam = Adam::new(&layout);
        let c = cfg();
        // Reference in f64, written independently.
        let (mut pr, mut mr, mut vr) = ([1.0f64, -2.0, 0.5], [0.0; 3], [0.0; 3]);
        for t in 1..=5u64 {
            let g = [0.3 * t as f32, -0.1, 2.0 / t as f32];
            adam.step(&c, &layout, &mut p, &g);
            for i in 0..3 {
                let lr0 = if i < 2 { 0.02 } else { 0.001 };
                let lr = lr0 * 0.1f64.powf((t - 1) as f64 / 10_000.0);
                mr[i] = 0.9 * mr[i] + 0.1 * g[i] as f64;
                vr[i] = 0.999 * vr[i] + 0.001 * (g[i] as f64).powi(2);
                let mh = mr[i] / (1.0 - 0.9f64.powi(t as i32));
                let vh = vr[i] / (1.0 - 0.999f64.powi(t as i32));
                pr[i] -= lr * mh / (vh.sqrt() + 1e-8);
                assert!((p[i] as f64 - pr[i]).abs() < 1e-5, "t {t} i {i}: {} vs {}", p[i], pr[i]);
            }
        }
        // The first step moves each parameter by about lr (Adam's scale invariance).
        assert!((pr[0] - 1.0).abs() > 0.05);
    }

    #[test]
    fn decay_reaches_a_tenth_after_decay_steps() {
        let c = cfg();
        assert!((c.lr(LrClass::Volume, 10_000) - 0.002).abs() < 1e-12);
        assert!((c.lr(LrClass::Network, 30_000) - 1e-6).abs() < 1e-15);
    }
}
