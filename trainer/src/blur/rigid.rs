//! DP-NeRF's rigid blurring kernel, per image: a learned embedding e_i (32-d, zero at start)
//! feeds three heads of one hidden layer each (ReLU), predicting for K warped rays an se(3)
//! twist (rotation r_k and translation v_k, both scaled by 0.1) and, for the K warped rays plus
//! the un-warped origin ray, a blending logit; the blending weights are
//! w_k = sigmoid(l_k) / sum_j sigmoid(l_j). The last layer of each twist head starts near zero
//! (weights scaled by `init_scale`), so every warped ray starts at the origin ray.
//!
//! [`RigidKernel::forward`] gives one image's twists and weights; [`RigidKernel::backward`]
//! takes dL/dtwists and dL/dweights back to the embedding and the heads.

use crate::engine::mlp::{Act, Dense};
use crate::engine::params::{Layout, LrClass};
use crate::engine::real::Real;

/// Shape of the kernel.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidConfig {
    /// Warped rays per pixel, besides the origin ray (reference: 9).
    pub k: usize,
    /// Embedding size (reference: 32).
    pub embedding: usize,
    /// Hidden width of each head (reference: 32).
    pub hidden: usize,
    /// Scale of the twist outputs (reference: 0.1).
    pub twist_scale: f64,
    /// Scale of the twist heads' last-layer initialisation (near zero).
    pub init_scale: f64,
}

impl RigidConfig {
    /// Checks the shape (the error names the `blur.kernel` key).
    pub fn validate(&self) -> Result<(), String> {
        if self.k == 0 || self.embedding == 0 || self.hidden == 0 {
            return Err("blur.kernel: k, embedding and hidden must be >= 1".into());
        }
        if self.k + 1 > super::MAX_RAYS {
            return Err(format!("blur.kernel.k = {}; at most {} warped rays", self.k, super::MAX_RAYS - 1));
        }
        for (name, v) in [("blur.kernel.twist_scale", self.twist_scale), ("blur.kernel.init_scale", self.init_scale)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} = {v}; it must be a finite number >= 0"));
            }
        }
        Ok(())
    }
}

/// The kernel's layers and the offset of the per-image embeddings.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidKernel {
    /// The shape.
    pub config: RigidConfig,
    /// Number of images (embeddings).
    pub images: usize,
    /// Offset of the embeddings (images x embedding).
    pub embeddings: usize,
    /// Rotation head: embedding -> hidden -> 3K.
    pub rot: [Dense; 2],
    /// Translation head: embedding -> hidden -> 3K.
    pub trans: [Dense; 2],
    /// Weight head: embedding -> hidden -> K + 1 logits.
    pub weight: [Dense; 2],
}

/// One image's kernel: twists (r, v) per warped ray and the K + 1 blending weights (the origin
/// ray's last), plus what the backward pass needs.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelOut<R> {
    /// K twists (r, v).
    pub twists: Vec<[R; 6]>,
    /// K + 1 weights summing to 1.
    pub weights: Vec<R>,
    hidden: [Vec<R>; 3],
    raw: [Vec<R>; 3],
}

impl RigidKernel {
    /// Allocates embeddings for `images` images and the heads in `layout`.
    pub fn new(layout: &mut Layout, config: &RigidConfig, images: usize) -> RigidKernel {
        let (e, h, k) = (config.embedding, config.hidden, config.k);
        let embeddings = layout.alloc("rbk.embedding", images * e, LrClass::Embedding);
        let head = |l: &mut Layout, name: &str, out: usize| {
            [
                Dense::new(l, &format!("rbk.{name}.0"), e, h, true, Act::Relu),
                Dense::new(l, &format!("rbk.{name}.1"), h, out, true, Act::None),
            ]
        };
        let rot = head(layout, "rot", 3 * k);
        let trans = head(layout, "trans", 3 * k);
        let weight = head(layout, "weight", k + 1);
        RigidKernel { config: config.clone(), images, embeddings, rot, trans, weight }
    }

    /// Initialises the heads (embeddings stay zero): PyTorch-uniform layers, the twist heads'
    /// last layers scaled by `init_scale`.
    pub fn init<R: Real>(&self, params: &mut [R], uniform: &mut impl FnMut() -> f64) {
        for head in [&self.rot, &self.trans, &self.weight] {
            head[0].init(params, uniform);
            head[1].init(params, uniform);
        }
        for head in [&self.rot, &self.trans] {
            let l = &head[1];
            for p in &mut params[l.w..l.w + l.n_in * l.n_out] {
                *p *= R::of(self.config.init_scale);
            }
            if let Some(b) = l.b {
                for p in &mut params[b..b + l.n_out] {
                    *p *= R::of(self.config.init_scale);
                }
            }
        }
    }

    fn heads(&self) -> [&[Dense; 2]; 3] {
        [&self.rot, &self.trans, &self.weight]
    }

    /// The kernel of image `image`.
    pub fn forward<R: Real>(&self, params: &[R], image: usize) -> KernelOut<R> {
        let (e, k) = (self.config.embedding, self.config.k);
        let emb = &params[self.embeddings + image * e..self.embeddings + (image + 1) * e];
        let mut hidden: [Vec<R>; 3] = Default::default();
        let mut raw: [Vec<R>; 3] = Default::default();
        for (i, head) in self.heads().into_iter().enumerate() {
            hidden[i] = vec![R::zero(); head[0].n_out];
            head[0].forward(params, 1, emb, e, &mut hidden[i], head[0].n_out);
            raw[i] = vec![R::zero(); head[1].n_out];
            head[1].forward(params, 1, &hidden[i], head[1].n_out, &mut raw[i], head[1].n_out);
        }
        let s = R::of(self.config.twist_scale);
        let twists = (0..k)
            .map(|j| std::array::from_fn(|c| s * if c < 3 { raw[0][3 * j + c] } else { raw[1][3 * j + c - 3] }))
            .collect();
        // w = sigmoid(l) / sum sigmoid(l).
        let sig: Vec<R> = raw[2].iter().map(|&l| R::one() / (R::one() + (-l).exp())).collect();
        let total: R = sig.iter().copied().sum();
        let weights = sig.iter().map(|&x| x / total).collect();
        KernelOut { twists, weights, hidden, raw }
    }

    /// Backward of [`forward`](Self::forward) for image `image`: accumulates into `grads`.
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        image: usize,
        out: &KernelOut<R>,
        d_twists: &[[R; 6]],
        d_weights: &[R],
    ) {
        let (e, k) = (self.config.embedding, self.config.k);
        let s = R::of(self.config.twist_scale);
        let mut d_raw: [Vec<R>; 3] = [vec![R::zero(); 3 * k], vec![R::zero(); 3 * k], vec![R::zero(); k + 1]];
        for j in 0..k {
            for c in 0..3 {
                d_raw[0][3 * j + c] = s * d_twists[j][c];
                d_raw[1][3 * j + c] = s * d_twists[j][c + 3];
            }
        }
        // w_k = s_k / S: dL/ds_j = (dL/dw_j - sum_k dL/dw_k w_k) / S, then ds/dl = s (1 - s).
        let sig: Vec<R> = out.raw[2].iter().map(|&l| R::one() / (R::one() + (-l).exp())).collect();
        let total: R = sig.iter().copied().sum();
        let mean: R = d_weights.iter().zip(&out.weights).map(|(&g, &w)| g * w).sum();
        for j in 0..=k {
            d_raw[2][j] = (d_weights[j] - mean) / total * sig[j] * (R::one() - sig[j]);
        }
        let emb_range = self.embeddings + image * e..self.embeddings + (image + 1) * e;
        let emb: Vec<R> = params[emb_range.clone()].to_vec();
        let mut d_emb = vec![R::zero(); e];
        for (i, head) in self.heads().into_iter().enumerate() {
            let mut d_hidden = vec![R::zero(); head[0].n_out];
            let mut dr = d_raw[i].clone();
            let n1 = head[1].n_out;
            head[1].backward(
                params,
                grads,
                1,
                &out.hidden[i],
                head[0].n_out,
                &out.raw[i],
                &mut dr,
                n1,
                Some((&mut d_hidden, head[0].n_out, R::zero())),
            );
            let n0 = head[0].n_out;
            head[0].backward(
                params,
                grads,
                1,
                &emb,
                e,
                &out.hidden[i],
                &mut d_hidden,
                n0,
                Some((&mut d_emb, e, R::one())),
            );
        }
        for (g, d) in grads[emb_range].iter_mut().zip(&d_emb) {
            *g += *d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kernel() -> (RigidKernel, Layout, Vec<f64>) {
        let mut layout = Layout::default();
        let cfg = RigidConfig { k: 3, embedding: 5, hidden: 4, twist_scale: 0.1, init_scale: 0.01 };
        let rk = RigidKernel::new(&mut layout, &cfg, 2);
        let mut params = layout.zeros::<f64>();
        let mut s = 7u64;
        let mut u = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        rk.init(&mut params, &mut u);
        (rk, layout, params)
    }

    #[test]
    fn starts_near_the_identity_with_weights_summing_to_one() {
        let (rk, _, params) = kernel();
        let out = rk.forward(&params, 1);
        assert!((out.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(out.twists.iter().flatten().all(|x| x.abs() < 0.01), "{:?}", out.twists);
    }

    #[test]
    fn backward_matches_finite_differences() {
        let (rk, layout, mut params) = kernel();
        // Move away from the zero embedding so every path carries gradient.
        let mut s = 3u64;
        for p in params.iter_mut() {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            *p += 0.5 * ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
        }
        let image = 1;
        let dt: Vec<[f64; 6]> = (0..3).map(|j| std::array::from_fn(|c| ((j * 6 + c) as f64 * 0.37).sin())).collect();
        let dw: Vec<f64> = (0..4).map(|j| (j as f64 * 1.3).cos()).collect();
        let loss = |p: &[f64]| {
            let o = rk.forward(p, image);
            let a: f64 = o.twists.iter().zip(&dt).map(|(t, d)| (0..6).map(|c| t[c] * d[c]).sum::<f64>()).sum();
            a + o.weights.iter().zip(&dw).map(|(w, d)| w * d).sum::<f64>()
        };
        let out = rk.forward(&params, image);
        let mut grads = layout.zeros::<f64>();
        rk.backward(&params, &mut grads, image, &out, &dt, &dw);
        for i in 0..params.len() {
            let h = 1e-6;
            let (mut p, mut m) = (params.clone(), params.clone());
            p[i] += h;
            m[i] -= h;
            let fd = (loss(&p) - loss(&m)) / (2.0 * h);
            assert!((fd - grads[i]).abs() <= 1e-7 * (1.0 + fd.abs()), "param {i}: fd {fd} analytic {}", grads[i]);
        }
        // The other image's embedding gets nothing; every tensor is reached (inactive ReLUs
        // leave some single entries at zero).
        let other = rk.embeddings..rk.embeddings + rk.config.embedding;
        assert!(grads[other.clone()].iter().all(|&g| g == 0.0));
        assert!(grads[other.end..other.end + rk.config.embedding].iter().all(|g| g.abs() > 1e-9));
        for t in layout.tensors.iter().filter(|t| t.name != "rbk.embedding") {
            assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-9), "{} receives no gradient", t.name);
        }
    }
}
