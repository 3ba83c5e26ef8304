//! DP-NeRF's adaptive weight proposal (AWP): new blending weights for the K + 1 rays of a
//! blurry pixel, from what the rays see.
//!
//! For each ray k of a pixel (the K warped rays, then the origin ray):
//! 1. every sample's density-MLP features f_{k,i} go through the sample-embedding MLP (ReLU
//!    layers; reference 4 x 64): s_{k,i};
//! 2. they are integrated along the ray with the render weights: h_k = sum_i omega_{k,i} s_{k,i}
//!    (the render weights are held fixed: the AWP loss reaches the densities only through the
//!    colours, not through the weights of this integral);
//! 3. h_k, the image's kernel embedding and the positional encoding of the origin ray's view
//!    direction go through the motion-embedding MLP (ReLU; reference 2 x 32): g_k;
//! 4. motion aggregation across the K + 1 rays by single-head self-attention with a residual:
//!    q, k, v = g W_q, g W_k, g W_v (width/2), A = softmax_rows(q k^T / sqrt(width/2)),
//!    m_k = leaky_relu(g_k + (A v)_k W_o, 0.2); with `attention` off, m_k = g_k;
//! 5. the mean over k of m_k, a linear layer to K + 1 logits l, and
//!    w_k = sigmoid(l_k) / sum_j sigmoid(l_j).
//!
//! The reference's aggregation module is simplified: it also attends from each ray to the
//! per-sample features of every ray ("curves", intra- and inter-ray softmax pooling) and has a
//! batch norm; here the rays attend only to each other's integrated features, and there is no
//! normalisation layer (batch statistics would couple the pixels of a batch).
//!
//! [`Awp::forward`] runs one pixel's rays into an [`AwpWorkspace`]; [`Awp::backward`] takes
//! dL/dw back to the parameters, the per-sample features and the image embedding.

use crate::engine::encoding;
use crate::engine::mlp::{backward_stack, forward_stack, softmax, Act, Dense};
use crate::engine::params::Layout;
use crate::engine::real::Real;

/// Shape and schedule of the AWP.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AwpConfig {
    /// Widths of the sample-embedding MLP (reference: [64, 64, 64, 64]).
    pub sample_hidden: Vec<usize>,
    /// Widths of the motion-embedding MLP (reference: [32, 32]).
    pub motion_hidden: Vec<usize>,
    /// Positional-encoding frequencies of the ray direction (reference: 2).
    pub dir_freqs: usize,
    /// Attention across the rays (module doc, step 4); off: plain mean of the motion features.
    pub attention: bool,
    /// Weight l of the AWP colour in the image loss,
    /// `(1 - l) [blur_fine + blur_coarse] + l awp`, stepping through these values
    /// (reference: 0.1, 0.196, 0.42, 0.9) ...
    pub mix: Vec<f64>,
    /// ... every this many iterations (reference: 10 000).
    pub mix_every: u64,
}

impl AwpConfig {
    /// The reference settings.
    pub fn reference() -> AwpConfig {
        AwpConfig {
            sample_hidden: vec![64; 4],
            motion_hidden: vec![32; 2],
            dir_freqs: 2,
            attention: true,
            mix: vec![0.1, 0.196, 0.42, 0.9],
            mix_every: 10_000,
        }
    }

    /// The mixing weight l at iteration `step`.
    pub fn mix_at(&self, step: u64) -> f64 {
        let i = (step / self.mix_every.max(1)) as usize;
        self.mix.get(i.min(self.mix.len().saturating_sub(1))).copied().unwrap_or(0.0)
    }

    /// Checks the shape and the schedule; the message names the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        if self.sample_hidden.is_empty() || self.sample_hidden.contains(&0) {
            return Err("blur.awp.sample_hidden must list at least one positive width".into());
        }
        if self.motion_hidden.is_empty() || self.motion_hidden.contains(&0) {
            return Err("blur.awp.motion_hidden must list at least one positive width".into());
        }
        if self.attention && *self.motion_hidden.last().expect("non-empty") < 2 {
            return Err("blur.awp.motion_hidden's last width must be >= 2 with attention on".into());
        }
        if self.mix.is_empty() || self.mix.iter().any(|l| !(l.is_finite() && (0.0..=1.0).contains(l))) {
            return Err("blur.awp.mix must list weights in [0, 1] (reference: [0.1, 0.196, 0.42, 0.9])".into());
        }
        if self.mix_every == 0 {
            return Err("blur.awp.mix_every must be positive (reference: 10000)".into());
        }
        Ok(())
    }
}

/// The AWP's layers.
#[derive(Clone, Debug, PartialEq)]
pub struct Awp {
    /// The shape.
    pub config: AwpConfig,
    /// Rays per pixel (K + 1).
    pub rays: usize,
    /// Features per sample (the field's).
    pub features: usize,
    /// Size of the image embedding.
    pub embedding: usize,
    /// Sample-embedding MLP (features -> ... , ReLU).
    pub sample: Vec<Dense>,
    /// Motion-embedding MLP (integrated | embedding | PE(dir) -> ..., ReLU).
    pub motion: Vec<Dense>,
    /// Attention maps W_q, W_k, W_v (width -> width/2) and W_o (width/2 -> width), no biases.
    pub attention: Option<[Dense; 4]>,
    /// Pooled motion feature -> K + 1 logits.
    pub out: Dense,
}

/// One pixel's activations (reused across pixels).
#[derive(Clone, Debug, Default)]
pub struct AwpWorkspace<R> {
    n: usize,
    s: usize,
    sample: Vec<Vec<R>>,
    /// Motion MLP input, n x (integrated | embedding | PE(dir)).
    x_motion: Vec<R>,
    motion: Vec<Vec<R>>,
    q: Vec<R>,
    k: Vec<R>,
    v: Vec<R>,
    a: Vec<R>,
    ctx: Vec<R>,
    o: Vec<R>,
    m: Vec<R>,
    pooled: Vec<R>,
    logits: Vec<R>,
    sig: Vec<R>,
    /// The proposed weights (n, summing to 1).
    pub weights: Vec<R>,
    g_a: Vec<R>,
    g_b: Vec<R>,
    g_x: Vec<R>,
    g_m: Vec<R>,
    g_q: Vec<R>,
    g_k: Vec<R>,
    g_v: Vec<R>,
    g_ctx: Vec<R>,
    /// dL/d features of the last backward (n x s x features, contiguous).
    pub d_features: Vec<R>,
    /// dL/d embedding of the last backward.
    pub d_embedding: Vec<R>,
}

const LEAK: f64 = 0.2;

impl Awp {
    /// Allocates the layers in `layout` for pixels of `rays` rays, fields with `features`
    /// features per sample and kernels with `embedding`-d image embeddings.
    pub fn new(layout: &mut Layout, config: &AwpConfig, rays: usize, features: usize, embedding: usize) -> Awp {
        let stack = |l: &mut Layout, name: &str, n_in: usize, widths: &[usize]| {
            let mut n = n_in;
            widths
                .iter()
                .enumerate()
                .map(|(i, &w)| {
                    let d = Dense::new(l, &format!("awp.{name}.{i}"), n, w, true, Act::Relu);
                    n = w;
                    d
                })
                .collect::<Vec<_>>()
        };
        let sample = stack(layout, "sample", features, &config.sample_hidden);
        let ws = *config.sample_hidden.last().expect("validated");
        let motion_in = ws + embedding + encoding::width(config.dir_freqs);
        let motion = stack(layout, "motion", motion_in, &config.motion_hidden);
        let wm = *config.motion_hidden.last().expect("validated");
        let attention = config.attention.then(|| {
            let da = wm / 2;
            [
                Dense::new(layout, "awp.attention.q", wm, da, false, Act::None),
                Dense::new(layout, "awp.attention.k", wm, da, false, Act::None),
                Dense::new(layout, "awp.attention.v", wm, da, false, Act::None),
                Dense::new(layout, "awp.attention.o", da, wm, false, Act::None),
            ]
        });
        let out = Dense::new(layout, "awp.out", wm, rays, true, Act::None);
        Awp { config: config.clone(), rays, features, embedding, sample, motion, attention, out }
    }

    /// PyTorch-uniform initialisation of every layer.
    pub fn init<R: Real>(&self, params: &mut [R], uniform: &mut impl FnMut() -> f64) {
        for l in self.sample.iter().chain(&self.motion).chain(self.attention.iter().flatten()) {
            l.init(params, uniform);
        }
        self.out.init(params, uniform);
    }

    fn motion_width(&self) -> usize {
        self.motion.last().expect("validated").n_out
    }

    /// Proposes weights for one pixel: `features` rows (ray-major, `s` samples per ray, row
    /// stride `stride`, `self.features` values each), their render `weights`, the image
    /// `embedding` and the origin ray's unit view direction `dir`. The weights end up in
    /// `ws.weights`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward<R: Real>(
        &self,
        params: &[R],
        ws: &mut AwpWorkspace<R>,
        features: &[R],
        stride: usize,
        s: usize,
        weights: &[R],
        embedding: &[R],
        dir: [R; 3],
    ) {
        let n = self.rays;
        let rows = n * s;
        ws.n = n;
        ws.s = s;
        ws.sample.resize(self.sample.len(), Vec::new());
        for (h, l) in ws.sample.iter_mut().zip(&self.sample) {
            h.resize(rows * l.n_out, R::zero());
        }
        forward_stack(&self.sample, params, rows, features, stride, &mut ws.sample);
        // Integrate along each ray with the render weights.
        let w_s = self.sample.last().expect("validated").n_out;
        let pe = encoding::width(self.config.dir_freqs);
        let d_in = w_s + self.embedding + pe;
        ws.x_motion.clear();
        ws.x_motion.resize(n * d_in, R::zero());
        let last = ws.sample.last().expect("validated");
        let mut enc = vec![R::zero(); pe];
        encoding::encode(dir, self.config.dir_freqs, &mut enc);
        for k in 0..n {
            let row = &mut ws.x_motion[k * d_in..(k + 1) * d_in];
            for i in 0..s {
                let (om, si) = (weights[k * s + i], &last[(k * s + i) * w_s..(k * s + i + 1) * w_s]);
                for (h, &v) in row[..w_s].iter_mut().zip(si) {
                    *h += om * v;
                }
            }
            row[w_s..w_s + self.embedding].copy_from_slice(embedding);
            row[w_s + self.embedding..].copy_from_slice(&enc);
        }
        ws.motion.resize(self.motion.len(), Vec::new());
        for (h, l) in ws.motion.iter_mut().zip(&self.motion) {
            h.resize(n * l.n_out, R::zero());
        }
        forward_stack(&self.motion, params, n, &ws.x_motion, d_in, &mut ws.motion);
        let wm = self.motion_width();
        let g = ws.motion.last().expect("validated");
        ws.m.clear();
        ws.m.extend_from_slice(g);
        if let Some([lq, lk, lv, lo]) = &self.attention {
            let da = lq.n_out;
            for b in [&mut ws.q, &mut ws.k, &mut ws.v, &mut ws.ctx] {
                b.resize(n * da, R::zero());
            }
            lq.forward(params, n, g, wm, &mut ws.q, da);
            lk.forward(params, n, g, wm, &mut ws.k, da);
            lv.forward(params, n, g, wm, &mut ws.v, da);
            let scale = R::one() / R::of(da as f64).sqrt();
            ws.a.resize(n * n, R::zero());
            for r in 0..n {
                let qr = &ws.q[r * da..(r + 1) * da];
                let row = &mut ws.a[r * n..(r + 1) * n];
                for (c, a) in row.iter_mut().enumerate() {
                    *a = scale * qr.iter().zip(&ws.k[c * da..(c + 1) * da]).map(|(&x, &y)| x * y).sum::<R>();
                }
                softmax(row);
                let ctx = &mut ws.ctx[r * da..(r + 1) * da];
                ctx.fill(R::zero());
                for (c, &a) in row.iter().enumerate() {
                    for (x, &v) in ctx.iter_mut().zip(&ws.v[c * da..(c + 1) * da]) {
                        *x += a * v;
                    }
                }
            }
            ws.o.resize(n * wm, R::zero());
            lo.forward(params, n, &ws.ctx, da, &mut ws.o, wm);
            for (m, &o) in ws.m.iter_mut().zip(&ws.o) {
                let z = *m + o;
                *m = if z > R::zero() { z } else { R::of(LEAK) * z };
            }
        }
        ws.pooled.clear();
        ws.pooled.resize(wm, R::zero());
        let inv_n = R::one() / R::of(n as f64);
        for k in 0..n {
            for (p, &m) in ws.pooled.iter_mut().zip(&ws.m[k * wm..(k + 1) * wm]) {
                *p += m * inv_n;
            }
        }
        ws.logits.resize(n, R::zero());
        self.out.forward(params, 1, &ws.pooled, wm, &mut ws.logits, n);
        ws.sig.clear();
        ws.sig.extend(ws.logits.iter().map(|&l| R::one() / (R::one() + (-l).exp())));
        let total: R = ws.sig.iter().copied().sum();
        ws.weights.clear();
        ws.weights.extend(ws.sig.iter().map(|&x| x / total));
    }

    /// Backward of the last [`forward`](Self::forward) on `ws` (same `features`, `stride` and
    /// `weights`) from dL/dw: accumulates parameter gradients into `grads` and leaves dL/d
    /// features in `ws.d_features` and dL/d embedding in `ws.d_embedding`.
    #[allow(clippy::too_many_arguments)]
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        ws: &mut AwpWorkspace<R>,
        features: &[R],
        stride: usize,
        weights: &[R],
        d_weights: &[R],
    ) {
        let (n, s, wm) = (ws.n, ws.s, self.motion_width());
        // w = sig / S: dL/dsig_j = (dL/dw_j - sum_k dL/dw_k w_k) / S; dsig/dl = sig (1 - sig).
        let total: R = ws.sig.iter().copied().sum();
        let mean: R = d_weights.iter().zip(&ws.weights).map(|(&g, &w)| g * w).sum();
        let mut d_logits: Vec<R> =
            (0..n).map(|j| (d_weights[j] - mean) / total * ws.sig[j] * (R::one() - ws.sig[j])).collect();
        let mut d_pooled = vec![R::zero(); wm];
        self.out.backward(
            params,
            grads,
            1,
            &ws.pooled,
            wm,
            &ws.logits,
            &mut d_logits,
            n,
            Some((&mut d_pooled, wm, R::zero())),
        );
        // dL/dm_k = dL/dpooled / n.
        let inv_n = R::one() / R::of(n as f64);
        ws.g_m.clear();
        for _ in 0..n {
            ws.g_m.extend(d_pooled.iter().map(|&d| d * inv_n));
        }
        if let Some([lq, lk, lv, lo]) = &self.attention {
            let da = lq.n_out;
            // Through the leaky ReLU (m has the sign of its input): dL/dz, which is both the
            // residual's dL/dg and dL/do.
            for (d, &m) in ws.g_m.iter_mut().zip(&ws.m) {
                if m <= R::zero() {
                    *d *= R::of(LEAK);
                }
            }
            let mut d_o = ws.g_m.clone();
            ws.g_ctx.resize(n * da, R::zero());
            lo.backward(params, grads, n, &ws.ctx, da, &ws.o, &mut d_o, wm, Some((&mut ws.g_ctx, da, R::zero())));
            // ctx_r = sum_c A_rc v_c; A_r = softmax(scale q_r . k_c).
            let scale = R::one() / R::of(da as f64).sqrt();
            for b in [&mut ws.g_q, &mut ws.g_k, &mut ws.g_v] {
                b.clear();
                b.resize(n * da, R::zero());
            }
            for r in 0..n {
                let a = &ws.a[r * n..(r + 1) * n];
                let dctx = &ws.g_ctx[r * da..(r + 1) * da];
                let d_a: Vec<R> = (0..n)
                    .map(|c| dctx.iter().zip(&ws.v[c * da..(c + 1) * da]).map(|(&x, &y)| x * y).sum::<R>())
                    .collect();
                for (c, &ac) in a.iter().enumerate() {
                    for (gv, &d) in ws.g_v[c * da..(c + 1) * da].iter_mut().zip(dctx) {
                        *gv += ac * d;
                    }
                }
                let dot: R = a.iter().zip(&d_a).map(|(&x, &y)| x * y).sum();
                for c in 0..n {
                    let d_score = a[c] * (d_a[c] - dot) * scale;
                    for e in 0..da {
                        ws.g_q[r * da + e] += d_score * ws.k[c * da + e];
                        ws.g_k[c * da + e] += d_score * ws.q[r * da + e];
                    }
                }
            }
            let g = ws.motion.last().expect("validated");
            for (l, y, d) in [(lq, &ws.q, &mut ws.g_q), (lk, &ws.k, &mut ws.g_k), (lv, &ws.v, &mut ws.g_v)] {
                l.backward(params, grads, n, g, wm, y, d, da, Some((&mut ws.g_m, wm, R::one())));
            }
        }
        // Motion MLP, down to its input.
        let w_s = self.sample.last().expect("validated").n_out;
        let d_in = w_s + self.embedding + encoding::width(self.config.dir_freqs);
        let widest = self.motion.iter().map(|l| l.n_out).max().unwrap_or(0);
        ws.g_a.clear();
        ws.g_a.extend_from_slice(&ws.g_m);
        ws.g_a.resize(n * widest, R::zero());
        ws.g_b.resize(n * widest, R::zero());
        ws.g_x.resize(n * d_in, R::zero());
        backward_stack(
            &self.motion,
            params,
            grads,
            n,
            (&ws.x_motion, d_in),
            &ws.motion,
            &mut ws.g_a,
            &mut ws.g_b,
            &mut ws.g_x,
            d_in,
        );
        ws.d_embedding.clear();
        ws.d_embedding.resize(self.embedding, R::zero());
        for k in 0..n {
            for (d, &g) in ws.d_embedding.iter_mut().zip(&ws.g_x[k * d_in + w_s..k * d_in + w_s + self.embedding]) {
                *d += g;
            }
        }
        // Integration: dL/ds_{k,i} = omega_{k,i} dL/dh_k.
        let rows = n * s;
        ws.g_a.clear();
        ws.g_a.resize(rows * w_s, R::zero());
        for k in 0..n {
            for i in 0..s {
                let om = weights[k * s + i];
                let dst = &mut ws.g_a[(k * s + i) * w_s..(k * s + i + 1) * w_s];
                for (d, &g) in dst.iter_mut().zip(&ws.g_x[k * d_in..k * d_in + w_s]) {
                    *d = om * g;
                }
            }
        }
        let mut d_features = std::mem::take(&mut ws.d_features);
        d_features.resize(rows * self.features, R::zero());
        let widest = self.sample.iter().map(|l| l.n_out).max().unwrap_or(0);
        ws.g_a.resize(rows * widest, R::zero());
        let mut g_b = std::mem::take(&mut ws.g_b);
        g_b.resize(rows * widest, R::zero());
        backward_stack(
            &self.sample,
            params,
            grads,
            rows,
            (features, stride),
            &ws.sample,
            &mut ws.g_a,
            &mut g_b,
            &mut d_features,
            self.sample[0].n_in,
        );
        ws.g_b = g_b;
        ws.d_features = d_features;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup(attention: bool) -> (Awp, Layout, Vec<f64>) {
        let mut layout = Layout::default();
        let cfg = AwpConfig {
            sample_hidden: vec![6, 5],
            motion_hidden: vec![7, 6],
            dir_freqs: 2,
            attention,
            mix: vec![0.1, 0.9],
            mix_every: 10,
        };
        let awp = Awp::new(&mut layout, &cfg, 4, 3, 2);
        let mut params = layout.zeros::<f64>();
        let mut st = 11u64;
        let mut u = || {
            st = st.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (st >> 11) as f64 / (1u64 << 53) as f64
        };
        awp.init(&mut params, &mut u);
        // Positive biases keep most ReLUs active, so every path carries gradient.
        for l in awp.sample.iter().chain(&awp.motion) {
            for p in &mut params[l.b.unwrap()..l.b.unwrap() + l.n_out] {
                *p = p.abs() + 0.1;
            }
        }
        (awp, layout, params)
    }

    struct Inputs {
        feats: Vec<f64>,
        stride: usize,
        s: usize,
        om: Vec<f64>,
        emb: Vec<f64>,
        dir: [f64; 3],
    }

    fn inputs() -> Inputs {
        let (n, s, stride) = (4, 5, 4);
        let feats = (0..n * s * stride).map(|i| ((i as f64) * 0.71).sin()).collect();
        let om = (0..n * s).map(|i| 0.2 + 0.15 * ((i as f64) * 1.3).cos()).collect();
        Inputs { feats, stride, s, om, emb: vec![0.3, -0.4], dir: [0.36, 0.48, 0.8] }
    }

    #[allow(clippy::needless_range_loop)]
    fn check(attention: bool) {
        let (awp, layout, params) = setup(attention);
        let mut x = inputs();
        let dw = [0.7, -1.1, 0.4, 0.9];
        let loss = |p: &[f64], x: &Inputs| {
            let mut ws = AwpWorkspace::default();
            awp.forward(p, &mut ws, &x.feats, x.stride, x.s, &x.om, &x.emb, x.dir);
            ws.weights.iter().zip(&dw).map(|(w, d)| w * d).sum::<f64>()
        };
        let mut ws = AwpWorkspace::default();
        awp.forward(&params, &mut ws, &x.feats, x.stride, x.s, &x.om, &x.emb, x.dir);
        assert!((ws.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let mut grads = layout.zeros::<f64>();
        awp.backward(&params, &mut grads, &mut ws, &x.feats, x.stride, &x.om, &dw);
        let h = 1e-6;
        let close = |fd: f64, an: f64| (fd - an).abs() <= 1e-7 * (1.0 + fd.abs());
        for i in 0..params.len() {
            let (mut p, mut m) = (params.clone(), params.clone());
            p[i] += h;
            m[i] -= h;
            let fd = (loss(&p, &x) - loss(&m, &x)) / (2.0 * h);
            assert!(close(fd, grads[i]), "param {i}: fd {fd} analytic {}", grads[i]);
        }
        for t in &layout.tensors {
            assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-9), "{} receives no gradient", t.name);
        }
        // Features (the first 3 of each row of stride 4) and the embedding.
        let (d_feat, d_emb) = (ws.d_features.clone(), ws.d_embedding.clone());
        for row in 0..x.om.len() {
            for c in 0..3 {
                let j = row * x.stride + c;
                x.feats[j] += h;
                let lp = loss(&params, &x);
                x.feats[j] -= 2.0 * h;
                let lm = loss(&params, &x);
                x.feats[j] += h;
                let fd = (lp - lm) / (2.0 * h);
                assert!(close(fd, d_feat[row * 3 + c]), "feature {row},{c}: fd {fd} analytic {}", d_feat[row * 3 + c]);
            }
        }
        assert!(d_feat.iter().any(|g| g.abs() > 1e-9));
        for e in 0..2 {
            x.emb[e] += h;
            let lp = loss(&params, &x);
            x.emb[e] -= 2.0 * h;
            let lm = loss(&params, &x);
            x.emb[e] += h;
            let fd = (lp - lm) / (2.0 * h);
            assert!(close(fd, d_emb[e]) && d_emb[e].abs() > 1e-9, "embedding {e}: fd {fd} analytic {}", d_emb[e]);
        }
    }

    #[test]
    fn backward_matches_finite_differences_with_attention() {
        check(true);
    }

    #[test]
    fn backward_matches_finite_differences_with_mean_aggregation() {
        check(false);
    }

    #[test]
    fn mix_steps_through_the_schedule_and_holds_the_last_value() {
        let cfg = AwpConfig::reference();
        assert_eq!(cfg.mix_at(0), 0.1);
        assert_eq!(cfg.mix_at(19_999), 0.196);
        assert_eq!(cfg.mix_at(35_000), 0.9);
        assert_eq!(cfg.mix_at(1_000_000), 0.9);
        assert!(cfg.validate().is_ok());
        assert!(AwpConfig { mix: vec![1.5], ..cfg.clone() }.validate().unwrap_err().contains("blur.awp.mix"));
        assert!(AwpConfig { sample_hidden: vec![], ..cfg }.validate().unwrap_err().contains("sample_hidden"));
    }
}
