//! Camera motion inside the exposure as K virtual cameras whose images average to the blurry
//! one, in two flavours:
//! - learned (BAD-NeRF, Wang et al. CVPR 2023): per image a start and an end perturbation
//!   (se(3) twists xi_s, xi_e, zero at start: both poses at the dataset's pose); virtual camera
//!   k at tau_k = k / (K - 1) moves the image's rays by the world-frame rigid motion
//!   exp((1 - tau_k) xi_s + tau_k xi_e). Interpolating the twists linearly is BAD-NeRF's
//!   geodesic interpolation T_s exp(tau log(T_s^-1 T_e)) to first order in the perturbations
//!   (they are small: the motion of one exposure).
//! - fixed (E2NeRF-style): the virtual cameras are the dataset trajectory's poses at the
//!   midpoints of K equal parts of the exposure; nothing is learned.
//!
//! In both the weights are 1/K. [`Trajectory::twists`] gives an image's K twists;
//! [`Trajectory::backward`] takes dL/d twists to xi_s and xi_e.

use crate::engine::params::{Layout, LrClass};
use crate::engine::real::Real;

/// Shape of the trajectory model.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Virtual cameras per exposure (BAD-NeRF: 7 for synthetic scenes).
    pub k: usize,
    /// Learn each image's start and end poses (BAD-NeRF); `false`: the dataset trajectory's
    /// poses inside the exposure, fixed (E2NeRF).
    pub learned: bool,
}

impl TrajectoryConfig {
    /// Checks the settings; the message names the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        if self.k < 2 || self.k > crate::blur::MAX_RAYS - 1 {
            return Err(format!(
                "blur.trajectory.k = {}; use 2 to {} virtual cameras (BAD-NeRF: 7)",
                self.k,
                crate::blur::MAX_RAYS - 1
            ));
        }
        Ok(())
    }
}

/// The learned start and end perturbations of every image.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// The shape.
    pub config: TrajectoryConfig,
    /// Number of images.
    pub images: usize,
    /// Offset of the twists (images x [xi_s (6) | xi_e (6)]); unused when not learned.
    pub offset: usize,
}

impl Trajectory {
    /// Allocates the twists of `images` images (when learned; zero = the dataset's poses).
    pub fn new(layout: &mut Layout, config: &TrajectoryConfig, images: usize) -> Trajectory {
        let offset = if config.learned {
            layout.alloc("trajectory.twists", images * 12, LrClass::Embedding)
        } else {
            layout.len()
        };
        Trajectory { config: config.clone(), images, offset }
    }

    /// Where virtual camera `k` sits in the exposure, in [0, 1]: tau_k = k / (K - 1) for the
    /// learned model, the midpoint (k + 0.5) / K of part k for the fixed one.
    pub fn tau(&self, k: usize) -> f64 {
        let n = self.config.k;
        if self.config.learned {
            k as f64 / (n - 1) as f64
        } else {
            (k as f64 + 0.5) / n as f64
        }
    }

    /// The K world-frame twists of image `image` (learned model).
    pub fn twists<R: Real>(&self, params: &[R], image: usize) -> Vec<[f64; 6]> {
        let p = &params[self.offset + 12 * image..self.offset + 12 * image + 12];
        (0..self.config.k)
            .map(|k| {
                let t = self.tau(k);
                std::array::from_fn(|c| (1.0 - t) * p[c].to_f64().unwrap_or(0.0) + t * p[6 + c].to_f64().unwrap_or(0.0))
            })
            .collect()
    }

    /// Image `image`'s mid-exposure twist (xi_s + xi_e) / 2 (learned model).
    pub fn mid_twist<R: Real>(&self, params: &[R], image: usize) -> [f64; 6] {
        let p = &params[self.offset + 12 * image..self.offset + 12 * image + 12];
        std::array::from_fn(|c| 0.5 * (p[c].to_f64().unwrap_or(0.0) + p[6 + c].to_f64().unwrap_or(0.0)))
    }

    /// Adds dL/d xi_s and dL/d xi_e of image `image` to `grads` from dL/d of its K twists.
    pub fn backward<R: Real>(&self, grads: &mut [R], image: usize, d_twists: &[[f64; 6]]) {
        let mut d = [0.0f64; 12];
        for (k, dt) in d_twists.iter().enumerate() {
            let t = self.tau(k);
            for c in 0..6 {
                d[c] += (1.0 - t) * dt[c];
                d[6 + c] += t * dt[c];
            }
        }
        for (g, v) in grads[self.offset + 12 * image..self.offset + 12 * image + 12].iter_mut().zip(d) {
            *g += R::of(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backward_matches_finite_differences() {
        let mut layout = Layout::default();
        let tr = Trajectory::new(&mut layout, &TrajectoryConfig { k: 4, learned: true }, 3);
        let mut params: Vec<f64> = (0..layout.len()).map(|i| ((i as f64) * 0.37).sin() * 0.1).collect();
        let w: Vec<[f64; 6]> = (0..4).map(|k| std::array::from_fn(|c| ((k * 6 + c) as f64 * 0.71).cos())).collect();
        let loss = |p: &[f64]| -> f64 {
            tr.twists(p, 1).iter().zip(&w).map(|(t, w)| (0..6).map(|c| t[c] * w[c]).sum::<f64>()).sum()
        };
        let mut grads = vec![0.0; params.len()];
        tr.backward(&mut grads, 1, &w);
        for i in 0..params.len() {
            let h = 1e-6;
            params[i] += h;
            let lp = loss(&params);
            params[i] -= 2.0 * h;
            let lm = loss(&params);
            params[i] += h;
            let fd = (lp - lm) / (2.0 * h);
            assert!((fd - grads[i]).abs() < 1e-8, "param {i}: fd {fd} analytic {}", grads[i]);
        }
        // Only image 1's twists get gradient, all of them.
        assert!(grads[..12].iter().chain(&grads[24..]).all(|&g| g == 0.0));
        assert!(grads[12..24].iter().all(|g| g.abs() > 1e-9));
    }

    #[test]
    fn virtual_cameras_span_the_exposure() {
        let mut layout = Layout::default();
        let learned = Trajectory::new(&mut layout, &TrajectoryConfig { k: 5, learned: true }, 1);
        assert_eq!((learned.tau(0), learned.tau(4)), (0.0, 1.0));
        let fixed = Trajectory::new(&mut layout, &TrajectoryConfig { k: 4, learned: false }, 1);
        assert_eq!((0..4).map(|k| fixed.tau(k)).collect::<Vec<_>>(), vec![0.125, 0.375, 0.625, 0.875]);
        assert_eq!(layout.len(), 12, "the fixed model has no parameters");
        assert!(TrajectoryConfig { k: 1, learned: true }.validate().unwrap_err().contains("blur.trajectory.k"));
    }
}
