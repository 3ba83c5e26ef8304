//! Deblur-NeRF's deformable sparse kernel (DSK; Ma et al., CVPR 2022, sec. 4): a blurry pixel
//! is the weighted sum of the linear colours of K rays near it, c_blur = sum_k w_k c(r_k).
//!
//! Per image i, K canonical kernel points q_{i,k} (2-D, learned) are bounded to a window of
//! half-size `window` pixels, c_k = window tanh(q_{i,k}); in training each gets a Gaussian
//! jitter, u_k = c_k + jitter n_k (n_k ~ N(0, 1), drawn per pixel and point). For a pixel at
//! (x, y) of a `width` x `height` image, each point's MLP input is
//!
//! ```text
//! [ gamma(u_k pi / window) | e_i | gamma(2 pi x / width - pi, 2 pi y / height - pi) ]
//! ```
//!
//! (gamma: NeRF's positional encoding of a 2-vector, input included; e_i: the image's learned
//! embedding, zero at start). The MLP (ReLU hidden layers; with `shortcut` the last hidden
//! layer reads [input | previous layer]) gives per point a raw offset delta_k, a weight logit
//! l_k and, with `origin_offsets`, a raw origin shift tau_k. The kernel is
//!
//! ```text
//! offset  o_k = u_k + offset_scale delta_k              (pixels: the ray goes through (x, y) + o_k)
//! origin  t_k = (origin_scale tau_k, 0)                 (camera frame, x and y only)
//! weight  w_k = exp(l_k) / sum_j exp(l_j)
//! ```
//!
//! The reference's ray for a point pivots about the shifted pixel's point at camera depth 1:
//! camera-frame origin t_k and direction `d(x + o_x, y + o_y) - t_k`, where d(u, v) is
//! [`camera_direction_at`](crate::data::rays::Intrinsics::camera_direction_at) (z = -1); both
//! are then taken to the world by the pose.
//!
//! Alignment: no point is pinned to the pixel centre. As in the reference, the first point
//! (k = 0) is the designated reference point and is pulled there by a loss, per pixel
//! `a = mean(|o_0|) + 10 mean(|t_0|)` (means over the two coordinates), weighted by
//! `align_weight` and averaged over the batch ([`Dsk::align`], [`Dsk::align_backward`]).
//!
//! Initialisation follows the reference: layers Xavier-normal with zero biases (the output
//! layer's gain `init_scale`), canonical points q ~ N(0, pattern_init^2), embeddings zero. With
//! the reference settings the K points start about `window * pattern_init` (~1 px) around the
//! pixel centre, the MLP moves them by up to about a pixel more, the weights are within ~50% of
//! 1/K and the origin shifts ~0.01: near the identity, but not exactly at it.
//!
//! [`Dsk::forward`] runs a batch of pixels of one image into a [`DskWorkspace`];
//! [`Dsk::backward`] takes dL/d offsets, origins and weights back to the layers, the image's
//! embedding and its canonical points.
//!
//! **PDRF** (Peng & Chellappa, AAAI 2023; `progressive`, the reference's kernel type "PBE")
//! uses the same network twice per step. Its MLP input gains the coarse field's features of the
//! point's ray, `[ gamma(u_k pi / window) | e_i | f_k | gamma(pixel) ]`, and point 0 is pinned
//! to the pixel (o_0 = 0, t_0 = 0; no alignment loss). Stage 1 runs the kernel with f = 0 and
//! renders its rays with the coarse pass only: colours c'_k and features f_k (the coarse
//! density MLP's features integrated along the ray with its render weights). Stage 2 runs the
//! kernel with those f_k; its rays are rendered fully. The losses are the fine blurry colour
//! sum_k w_k C_k against the image and the coarse one averaged with stage 1's,
//! (sum_k w'_k c'_k + sum_k w_k c_k) / 2 (`crate::method`). [`Dsk::backward`] also returns dL/df
//! (`DskWorkspace::d_features`), which reaches the field through stage 1's rays; as with the
//! AWP, the render weights of that integration are held fixed in the backward pass.

use crate::engine::encoding;
use crate::engine::mlp::{backward_stack, forward_stack, softmax, Act, Dense};
use crate::engine::params::{Layout, LrClass};
use crate::engine::real::Real;
use std::f64::consts::PI;

/// Weight of the origin term in the alignment loss (reference).
const ALIGN_ORIGIN: f64 = 10.0;

/// Shape, initialisation and schedule of the DSK.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DskConfig {
    /// Kernel points (rays) per pixel (reference `kernel_ptnum`: 5).
    pub k: usize,
    /// Size of the per-image embedding (reference `kernel_img_embed`: 32).
    pub embedding: usize,
    /// Hidden widths of the MLP, ReLU (reference: 4 + 1 layers of 64).
    pub hidden: Vec<usize>,
    /// The last hidden layer also reads the MLP input (reference `kernel_shortcut`: on).
    pub shortcut: bool,
    /// Positional-encoding frequencies of the pixel position (reference `kernel_spatial_embed`:
    /// 2).
    pub pe_pixel: usize,
    /// Positional-encoding frequencies of the canonical kernel point (reference
    /// `kernel_rand_embed`: 2).
    pub pe_kernel: usize,
    /// Half-size of the window bounding the canonical points, pixels (reference
    /// `kernel_hwindow`: 10).
    pub window: f64,
    /// Standard deviation of the canonical points' raw initialisation, before the tanh
    /// (reference `kernel_pattern_init_radius`: 0.1, i.e. ~1 px with a 10 px window).
    pub pattern_init: f64,
    /// Standard deviation of the training jitter of the canonical points, pixels (reference
    /// configs `kernel_random_hwindow`: 0.15).
    pub jitter: f64,
    /// Predict per-point origin shifts (reference `kernel_spatialvariant_trans`: on).
    pub origin_offsets: bool,
    /// Pixels per unit of the MLP's offset output (reference: 1).
    pub offset_scale: f64,
    /// Camera-frame units per unit of the MLP's origin output (reference: 0.01).
    pub origin_scale: f64,
    /// Gain of the output layer's Xavier initialisation (reference: 1 with origin offsets, 0.1
    /// without: it scales output layers of 2 or 3 rows only).
    pub init_scale: f64,
    /// Weight of the alignment loss (reference `kernel_align_weight`: 0.1).
    pub align_weight: f64,
    /// Iteration after which the alignment loss is dropped (reference: 180 000 of 200 000).
    /// The kernel itself starts at `blur.start` (reference `kernel_start_iter`: 1200).
    pub align_until: u64,
    /// PDRF's progressive blur estimation (kernel type "PBE"; module doc): point 0 is pinned
    /// to the pixel, there is no alignment loss, and the MLP also reads the coarse field's
    /// features of a first-stage kernel's rays. Off: Deblur-NeRF's DSK.
    #[serde(default)]
    pub progressive: bool,
}

impl DskConfig {
    /// The settings of the reference's `*_full` configs.
    pub fn reference() -> DskConfig {
        DskConfig {
            k: 5,
            embedding: 32,
            hidden: vec![64; 5],
            shortcut: true,
            pe_pixel: 2,
            pe_kernel: 2,
            window: 10.0,
            pattern_init: 0.1,
            jitter: 0.15,
            origin_offsets: true,
            offset_scale: 1.0,
            origin_scale: 0.01,
            init_scale: 1.0,
            align_weight: 0.1,
            align_until: 180_000,
            progressive: false,
        }
    }

    /// PDRF's kernel (its `*_full` configs): 10 points, 4 + 1 hidden layers of 64 with the
    /// shortcut, progressive.
    pub fn pdrf() -> DskConfig {
        DskConfig { k: 10, hidden: vec![64; 5], progressive: true, ..DskConfig::reference() }
    }

    /// Checks the shape and the scales; the message names the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let non_negative = |x: f64| x.is_finite() && x >= 0.0;
        if self.k < 2 {
            return Err("blur.dsk.k must be at least 2 kernel points (reference: 5)".into());
        }
        if self.hidden.is_empty() || self.hidden.contains(&0) {
            return Err(
                "blur.dsk.hidden must list at least one positive width (reference: [64, 64, 64, 64, 64])".into()
            );
        }
        if self.shortcut && self.hidden.len() < 2 {
            return Err("blur.dsk.hidden needs at least two widths with blur.dsk.shortcut on".into());
        }
        if !positive(self.window) {
            return Err("blur.dsk.window must be a positive number of pixels (reference: 10)".into());
        }
        if !non_negative(self.pattern_init) {
            return Err("blur.dsk.pattern_init must be finite and >= 0 (reference: 0.1)".into());
        }
        if !non_negative(self.jitter) {
            return Err("blur.dsk.jitter must be finite and >= 0 pixels (reference: 0.15)".into());
        }
        if !positive(self.offset_scale) {
            return Err("blur.dsk.offset_scale must be positive (reference: 1)".into());
        }
        if !positive(self.origin_scale) {
            return Err("blur.dsk.origin_scale must be positive (reference: 0.01)".into());
        }
        if !positive(self.init_scale) {
            return Err("blur.dsk.init_scale must be positive (reference: 1, or 0.1 without origin offsets)".into());
        }
        if !non_negative(self.align_weight) {
            return Err("blur.dsk.align_weight must be finite and >= 0 (reference: 0.1)".into());
        }
        Ok(())
    }
}

/// The DSK's parameters: per-image embeddings and canonical points, and the MLP.
#[derive(Clone, Debug, PartialEq)]
pub struct Dsk {
    /// The shape.
    pub config: DskConfig,
    /// Number of images.
    pub images: usize,
    /// Offset of the embeddings (images x embedding).
    pub embeddings: usize,
    /// Offset of the raw canonical points q (images x K x 2).
    pub pattern: usize,
    /// Width of the per-point feature input (the coarse field's features; 0 unless
    /// progressive).
    pub features: usize,
    /// Hidden layers before the shortcut (all of them without it).
    pub trunk: Vec<Dense>,
    /// The layers after the trunk: the shortcut layer (reading [input | trunk]) if any, then
    /// the output layer (offset x, y, logit, then origin x, y with `origin_offsets`).
    pub head: Vec<Dense>,
}

/// Activations of a batch of pixels of one image (reused across batches).
#[derive(Clone, Debug, Default)]
pub struct DskWorkspace<R> {
    n: usize,
    image: usize,
    /// MLP input, (n K) x (gamma(u) | e | gamma(pixel)).
    x: Vec<R>,
    trunk: Vec<Vec<R>>,
    /// [input | trunk output] with the shortcut.
    wide: Vec<R>,
    head: Vec<Vec<R>>,
    enc: Vec<R>,
    pix: Vec<R>,
    d_enc: Vec<R>,
    g_a: Vec<R>,
    g_b: Vec<R>,
    g_x: Vec<R>,
    g_head: Vec<R>,
    /// Each point's pixel offset o_k (pixels), pixel-major (K per pixel).
    pub offsets: Vec<[R; 2]>,
    /// Each point's camera-frame origin shift t_k (z = 0; all zero without origin offsets).
    pub origins: Vec<[R; 3]>,
    /// Each point's weight w_k (summing to 1 over a pixel's K points).
    pub weights: Vec<R>,
    /// dL/d the feature input of each point (rows x features), written by the backward.
    pub d_features: Vec<R>,
}

/// Width of the encoding of a 2-vector with `freqs` frequencies: 2 + 4 freqs.
const fn width2(freqs: usize) -> usize {
    2 + 4 * freqs
}

/// gamma of a 2-vector (layout as [`encoding::encode`]'s, without the third coordinate):
/// encodes (x, y, 0) into `full` and keeps the x and y entries of each block.
fn encode2<R: Real>(x: [R; 2], freqs: usize, full: &mut Vec<R>, out: &mut [R]) {
    full.resize(encoding::width(freqs), R::zero());
    encoding::encode([x[0], x[1], R::zero()], freqs, full);
    for b in 0..1 + 2 * freqs {
        out[2 * b..2 * b + 2].copy_from_slice(&full[3 * b..3 * b + 2]);
    }
}

/// Backward of [`encode2`]: dL/dx from dL/dgamma and the forward output `enc`.
fn backward2<R: Real>(enc: &[R], d_enc: &[R], freqs: usize, full: &mut Vec<R>, d_full: &mut Vec<R>) -> [R; 2] {
    full.clear();
    full.resize(encoding::width(freqs), R::zero());
    d_full.clear();
    d_full.resize(encoding::width(freqs), R::zero());
    for b in 0..1 + 2 * freqs {
        full[3 * b..3 * b + 2].copy_from_slice(&enc[2 * b..2 * b + 2]);
        d_full[3 * b..3 * b + 2].copy_from_slice(&d_enc[2 * b..2 * b + 2]);
    }
    let d = encoding::backward(full, d_full, freqs);
    [d[0], d[1]]
}

/// A standard normal sample from two uniforms (Box-Muller).
fn normal(uniform: &mut impl FnMut() -> f64) -> f64 {
    let (u1, u2) = (1.0 - uniform(), uniform());
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

impl Dsk {
    /// Allocates the embeddings and canonical points of `images` images and the MLP in
    /// `layout`; a progressive kernel's MLP also reads `features` values per point.
    pub fn new(layout: &mut Layout, config: &DskConfig, images: usize, features: usize) -> Dsk {
        let k = config.k;
        let features = if config.progressive { features } else { 0 };
        let embeddings = layout.alloc("dsk.embedding", images * config.embedding, LrClass::Embedding);
        let pattern = layout.alloc("dsk.pattern", images * k * 2, LrClass::Embedding);
        let d_in = width2(config.pe_kernel) + config.embedding + features + width2(config.pe_pixel);
        let n_trunk = config.hidden.len() - usize::from(config.shortcut);
        let mut n = d_in;
        let mut trunk = Vec::new();
        for (i, &w) in config.hidden[..n_trunk].iter().enumerate() {
            trunk.push(Dense::new(layout, &format!("dsk.hidden.{i}"), n, w, true, Act::Relu));
            n = w;
        }
        let mut head = Vec::new();
        if config.shortcut {
            let w = *config.hidden.last().expect("validated");
            head.push(Dense::new(layout, &format!("dsk.hidden.{n_trunk}"), d_in + n, w, true, Act::Relu));
            n = w;
        }
        let n_out = if config.origin_offsets { 5 } else { 3 };
        head.push(Dense::new(layout, "dsk.out", n, n_out, true, Act::None));
        Dsk { config: config.clone(), images, embeddings, pattern, features, trunk, head }
    }

    /// Width of the MLP input.
    fn input_width(&self) -> usize {
        width2(self.config.pe_kernel) + self.config.embedding + self.features + width2(self.config.pe_pixel)
    }

    /// The reference's initialisation: Xavier-normal layers with zero biases (the output
    /// layer's gain `init_scale`), canonical points N(0, pattern_init^2), zero embeddings.
    pub fn init<R: Real>(&self, params: &mut [R], uniform: &mut impl FnMut() -> f64) {
        let last = self.head.len() - 1;
        for (i, l) in self.trunk.iter().chain(&self.head).enumerate() {
            let gain = if i == self.trunk.len() + last { self.config.init_scale } else { 1.0 };
            let std = gain * (2.0 / (l.n_in + l.n_out) as f64).sqrt();
            for p in &mut params[l.w..l.w + l.n_in * l.n_out] {
                *p = R::of(std * normal(uniform));
            }
            if let Some(b) = l.b {
                params[b..b + l.n_out].fill(R::zero());
            }
        }
        let k = self.config.k;
        for p in &mut params[self.pattern..self.pattern + self.images * k * 2] {
            *p = R::of(self.config.pattern_init * normal(uniform));
        }
        params[self.embeddings..self.embeddings + self.images * self.config.embedding].fill(R::zero());
    }

    /// The kernels of a batch of pixels of image `image`: `pixels` are positions (x, y) =
    /// (column, row) in pixels (pixel centres at +0.5), `size` = (width, height) normalises them
    /// for the encoding. `noise` (K standard-normal 2-vectors per pixel, pixel-major) jitters the
    /// canonical points by `jitter` pixels in training; `None` evaluates without jitter.
    /// `features` (progressive kernels: `features` values per point, pixel-major) is the
    /// feature input; `None` feeds zeros (PDRF's first stage). The kernels end up in
    /// `ws.offsets`, `ws.origins` and `ws.weights`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward<R: Real>(
        &self,
        params: &[R],
        ws: &mut DskWorkspace<R>,
        image: usize,
        pixels: &[[R; 2]],
        size: [R; 2],
        noise: Option<&[[R; 2]]>,
        features: Option<&[R]>,
    ) {
        let (k, e, nf) = (self.config.k, self.config.embedding, self.features);
        let (wk, wp) = (width2(self.config.pe_kernel), width2(self.config.pe_pixel));
        let d_in = self.input_width();
        let n = pixels.len();
        let rows = n * k;
        ws.n = n;
        ws.image = image;
        let (pi, window) = (R::of(PI), R::of(self.config.window));
        let emb = &params[self.embeddings + image * e..self.embeddings + (image + 1) * e];
        let q = &params[self.pattern + image * k * 2..self.pattern + (image + 1) * k * 2];
        // Canonical points c_k = window tanh(q_k).
        let c: Vec<[R; 2]> = (0..k).map(|j| [window * q[2 * j].tanh(), window * q[2 * j + 1].tanh()]).collect();
        // Inputs [gamma(u pi / window) | e | gamma(pixel)]; the offsets start as u.
        ws.x.resize(rows * d_in, R::zero());
        ws.pix.resize(wp, R::zero());
        ws.offsets.clear();
        for (p, xy) in pixels.iter().enumerate() {
            let s: [R; 2] = std::array::from_fn(|a| R::of(2.0) * pi * xy[a] / size[a] - pi);
            encode2(s, self.config.pe_pixel, &mut ws.enc, &mut ws.pix);
            for (j, cj) in c.iter().enumerate() {
                let r = p * k + j;
                let u: [R; 2] = match noise {
                    Some(z) => std::array::from_fn(|a| cj[a] + R::of(self.config.jitter) * z[r][a]),
                    None => *cj,
                };
                let row = &mut ws.x[r * d_in..(r + 1) * d_in];
                encode2([u[0] * pi / window, u[1] * pi / window], self.config.pe_kernel, &mut ws.enc, &mut row[..wk]);
                row[wk..wk + e].copy_from_slice(emb);
                match features {
                    Some(f) => row[wk + e..wk + e + nf].copy_from_slice(&f[r * nf..(r + 1) * nf]),
                    None => row[wk + e..wk + e + nf].fill(R::zero()),
                }
                row[wk + e + nf..].copy_from_slice(&ws.pix);
                ws.offsets.push(u);
            }
        }
        // The MLP: trunk, then [input | trunk] through the shortcut layer, then the output.
        ws.trunk.resize(self.trunk.len(), Vec::new());
        for (h, l) in ws.trunk.iter_mut().zip(&self.trunk) {
            h.resize(rows * l.n_out, R::zero());
        }
        forward_stack(&self.trunk, params, rows, &ws.x, d_in, &mut ws.trunk);
        ws.head.resize(self.head.len(), Vec::new());
        for (h, l) in ws.head.iter_mut().zip(&self.head) {
            h.resize(rows * l.n_out, R::zero());
        }
        if self.config.shortcut {
            let t = ws.trunk.last().expect("validated");
            let wt = t.len() / rows.max(1);
            ws.wide.resize(rows * (d_in + wt), R::zero());
            for r in 0..rows {
                let dst = &mut ws.wide[r * (d_in + wt)..(r + 1) * (d_in + wt)];
                dst[..d_in].copy_from_slice(&ws.x[r * d_in..(r + 1) * d_in]);
                dst[d_in..].copy_from_slice(&t[r * wt..(r + 1) * wt]);
            }
            forward_stack(&self.head, params, rows, &ws.wide, d_in + wt, &mut ws.head);
        } else {
            let t = ws.trunk.last().expect("validated");
            forward_stack(&self.head, params, rows, t, self.head[0].n_in, &mut ws.head);
        }
        // o = u + offset_scale delta, t = (origin_scale tau, 0), w = softmax(l) per pixel.
        let out = ws.head.last().expect("output layer");
        let n_out = self.head.last().expect("output layer").n_out;
        let (so, st) = (R::of(self.config.offset_scale), R::of(self.config.origin_scale));
        ws.origins.clear();
        ws.weights.clear();
        for r in 0..rows {
            let y = &out[r * n_out..(r + 1) * n_out];
            ws.offsets[r][0] += so * y[0];
            ws.offsets[r][1] += so * y[1];
            ws.origins.push(if self.config.origin_offsets {
                [st * y[3], st * y[4], R::zero()]
            } else {
                [R::zero(); 3]
            });
            ws.weights.push(y[2]);
        }
        for p in 0..n {
            softmax(&mut ws.weights[p * k..(p + 1) * k]);
            if self.config.progressive {
                // PDRF pins the reference point to the pixel.
                ws.offsets[p * k] = [R::zero(); 2];
                ws.origins[p * k] = [R::zero(); 3];
            }
        }
    }

    /// Backward of the last [`forward`](Self::forward) on `ws`, from dL/d offsets, dL/d origins
    /// (read only with `origin_offsets`) and dL/d weights, laid out as the workspace's outputs:
    /// accumulates into `grads` the layers' gradients and those of the image's embedding and
    /// canonical points.
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        ws: &mut DskWorkspace<R>,
        d_offsets: &[[R; 2]],
        d_origins: &[[R; 3]],
        d_weights: &[R],
    ) {
        let (k, e, image) = (self.config.k, self.config.embedding, ws.image);
        let (wk, d_in) = (width2(self.config.pe_kernel), self.input_width());
        let rows = ws.n * k;
        let n_out = self.head.last().expect("output layer").n_out;
        let widest = self.trunk.iter().chain(&self.head).map(|l| l.n_out).max().unwrap_or(0);
        // dL/d raw outputs; through the softmax, dL/dl_j = w_j (dL/dw_j - sum_k w_k dL/dw_k).
        let (so, st) = (R::of(self.config.offset_scale), R::of(self.config.origin_scale));
        ws.g_a.clear();
        ws.g_a.resize(rows * widest.max(n_out), R::zero());
        for p in 0..ws.n {
            let (w, dw) = (&ws.weights[p * k..(p + 1) * k], &d_weights[p * k..(p + 1) * k]);
            let mean: R = w.iter().zip(dw).map(|(&a, &b)| a * b).sum();
            for j in 0..k {
                let r = p * k + j;
                let g = &mut ws.g_a[r * n_out..(r + 1) * n_out];
                g[2] = w[j] * (dw[j] - mean);
                if self.config.progressive && j == 0 {
                    // The pinned point's offset and origin do not depend on the MLP.
                    continue;
                }
                g[0] = so * d_offsets[r][0];
                g[1] = so * d_offsets[r][1];
                if self.config.origin_offsets {
                    g[3] = st * d_origins[r][0];
                    g[4] = st * d_origins[r][1];
                }
            }
        }
        // Head, then the trunk; with the shortcut the head's input gradient splits into the
        // MLP input's part and the trunk's.
        ws.g_b.resize(rows * widest, R::zero());
        let head_in = self.head[0].n_in;
        ws.g_head.resize(rows * head_in, R::zero());
        let wide_in: (&[R], usize) =
            if self.config.shortcut { (&ws.wide, head_in) } else { (ws.trunk.last().expect("validated"), head_in) };
        backward_stack(
            &self.head,
            params,
            grads,
            rows,
            wide_in,
            &ws.head,
            &mut ws.g_a,
            &mut ws.g_b,
            &mut ws.g_head,
            head_in,
        );
        let wt = self.trunk.last().expect("validated").n_out;
        let skip = if self.config.shortcut { d_in } else { 0 };
        ws.g_a.clear();
        ws.g_a.resize(rows * widest, R::zero());
        for r in 0..rows {
            ws.g_a[r * wt..(r + 1) * wt].copy_from_slice(&ws.g_head[r * head_in + skip..(r + 1) * head_in]);
        }
        ws.g_x.resize(rows * d_in, R::zero());
        backward_stack(
            &self.trunk,
            params,
            grads,
            rows,
            (&ws.x, d_in),
            &ws.trunk,
            &mut ws.g_a,
            &mut ws.g_b,
            &mut ws.g_x,
            d_in,
        );
        if self.config.shortcut {
            for r in 0..rows {
                for c in 0..d_in {
                    ws.g_x[r * d_in + c] += ws.g_head[r * head_in + c];
                }
            }
        }
        // Embedding: the sum over rows. Canonical points: dL/du = dL/do + (pi / window)
        // gamma'^T dL/dgamma, summed over pixels, then dc/dq = window (1 - tanh^2 q).
        let (pi, window) = (R::of(PI), R::of(self.config.window));
        let mut d_emb = vec![R::zero(); e];
        let mut d_c = vec![[R::zero(); 2]; k];
        let nf = self.features;
        ws.d_features.clear();
        for r in 0..rows {
            let gx = &ws.g_x[r * d_in..(r + 1) * d_in];
            for (d, &g) in d_emb.iter_mut().zip(&gx[wk..wk + e]) {
                *d += g;
            }
            ws.d_features.extend_from_slice(&gx[wk + e..wk + e + nf]);
            let x = &ws.x[r * d_in..r * d_in + wk];
            let du = backward2(x, &gx[..wk], self.config.pe_kernel, &mut ws.enc, &mut ws.d_enc);
            // o = u + ... except for a pinned point.
            let direct = if self.config.progressive && r % k == 0 { [R::zero(); 2] } else { d_offsets[r] };
            for a in 0..2 {
                d_c[r % k][a] += direct[a] + du[a] * pi / window;
            }
        }
        let emb = self.embeddings + image * e;
        for (g, d) in grads[emb..emb + e].iter_mut().zip(&d_emb) {
            *g += *d;
        }
        let pat = self.pattern + image * k * 2;
        for j in 0..k {
            for a in 0..2 {
                let t = params[pat + 2 * j + a].tanh();
                grads[pat + 2 * j + a] += d_c[j][a] * window * (R::one() - t * t);
            }
        }
    }

    /// The alignment loss of the last forward, summed over its pixels: per pixel
    /// mean(|o_0|) + 10 mean(|t_0|) over the reference point's coordinates. The reference
    /// averages it over the batch and weights it by `align_weight`.
    pub fn align<R: Real>(&self, ws: &DskWorkspace<R>) -> R {
        let k = self.config.k;
        let half = R::of(0.5);
        (0..ws.n)
            .map(|p| {
                let (o, t) = (ws.offsets[p * k], ws.origins[p * k]);
                half * (o[0].abs() + o[1].abs()) + R::of(ALIGN_ORIGIN) * half * (t[0].abs() + t[1].abs())
            })
            .sum()
    }

    /// Adds `scale` times the gradient of [`align`](Self::align) to `d_offsets` and
    /// `d_origins` (pass `scale` = align_weight / batch pixels for the reference's loss).
    pub fn align_backward<R: Real>(
        &self,
        ws: &DskWorkspace<R>,
        scale: R,
        d_offsets: &mut [[R; 2]],
        d_origins: &mut [[R; 3]],
    ) {
        let k = self.config.k;
        let sign = |x: R| {
            if x > R::zero() {
                R::one()
            } else if x < R::zero() {
                -R::one()
            } else {
                R::zero()
            }
        };
        let (a, b) = (scale * R::of(0.5), scale * R::of(0.5 * ALIGN_ORIGIN));
        for p in 0..ws.n {
            let r = p * k;
            for c in 0..2 {
                d_offsets[r][c] += a * sign(ws.offsets[r][c]);
                if self.config.origin_offsets {
                    d_origins[r][c] += b * sign(ws.origins[r][c]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn small(shortcut: bool, origin_offsets: bool, progressive: bool) -> DskConfig {
        DskConfig {
            k: 3,
            embedding: 4,
            hidden: vec![6, 5, 4],
            shortcut,
            pe_pixel: 1,
            pe_kernel: 2,
            window: 3.0,
            pattern_init: 0.3,
            jitter: 0.2,
            origin_offsets,
            offset_scale: 0.7,
            origin_scale: 0.05,
            init_scale: 0.5,
            progressive,
            ..DskConfig::reference()
        }
    }

    fn setup(cfg: &DskConfig) -> (Dsk, Layout, Vec<f64>) {
        let mut layout = Layout::default();
        let dsk = Dsk::new(&mut layout, cfg, 2, 3);
        let mut params = layout.zeros::<f64>();
        dsk.init(&mut params, &mut lcg(5));
        (dsk, layout, params)
    }

    const PIXELS: [[f64; 2]; 4] = [[0.5, 0.5], [3.5, 1.5], [7.5, 4.5], [2.5, 5.5]];
    const SIZE: [f64; 2] = [8.0, 6.0];

    #[allow(clippy::needless_range_loop)]
    fn check(shortcut: bool, origin_offsets: bool, progressive: bool) {
        let cfg = small(shortcut, origin_offsets, progressive);
        let (dsk, layout, mut params) = setup(&cfg);
        // Move away from the zero embedding and biases so every path carries gradient.
        let mut u = lcg(3);
        for p in params.iter_mut() {
            *p += 0.5 * (u() - 0.5);
        }
        for l in dsk.trunk.iter().chain(&dsk.head) {
            for p in &mut params[l.b.unwrap()..l.b.unwrap() + l.n_out] {
                *p = p.abs() + 0.1;
            }
        }
        let (image, k, n) = (1, cfg.k, PIXELS.len());
        let noise: Vec<[f64; 2]> = (0..n * k).map(|r| [(r as f64 * 0.9).sin(), (r as f64 * 1.7).cos()]).collect();
        let a: Vec<[f64; 2]> = (0..n * k).map(|r| [(r as f64 * 0.37).sin(), (r as f64 * 0.53).cos()]).collect();
        let b: Vec<[f64; 3]> = (0..n * k).map(|r| std::array::from_fn(|c| ((3 * r + c) as f64 * 0.29).cos())).collect();
        let c: Vec<f64> = (0..n * k).map(|r| (r as f64 * 1.3).sin()).collect();
        let nf = dsk.features;
        let f0: Vec<f64> = (0..n * k * nf).map(|i| (i as f64 * 0.71).sin()).collect();
        let feats = progressive.then_some(&f0[..]);
        let align_scale = 0.3;
        let loss_f = |p: &[f64], f: Option<&[f64]>| {
            let mut ws = DskWorkspace::default();
            dsk.forward(p, &mut ws, image, &PIXELS, SIZE, Some(&noise), f);
            let lo: f64 = ws.offsets.iter().zip(&a).map(|(o, a)| o[0] * a[0] + o[1] * a[1]).sum();
            let lt: f64 = ws.origins.iter().zip(&b).map(|(t, b)| (0..3).map(|i| t[i] * b[i]).sum::<f64>()).sum();
            let lw: f64 = ws.weights.iter().zip(&c).map(|(w, c)| w * c).sum();
            lo + lt + lw + align_scale * dsk.align(&ws)
        };
        let loss = |p: &[f64]| loss_f(p, feats);
        let mut ws = DskWorkspace::default();
        dsk.forward(&params, &mut ws, image, &PIXELS, SIZE, Some(&noise), feats);
        for p in 0..n {
            assert!((ws.weights[p * k..(p + 1) * k].iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        assert!(ws.origins.iter().all(|t| t[2] == 0.0));
        assert_eq!(ws.origins.iter().any(|t| t[0] != 0.0), origin_offsets);
        let (mut d_o, mut d_t) = (a.clone(), b.clone());
        dsk.align_backward(&ws, align_scale, &mut d_o, &mut d_t);
        let mut grads = layout.zeros::<f64>();
        dsk.backward(&params, &mut grads, &mut ws, &d_o, &d_t, &c);
        let h = 1e-6;
        for i in 0..params.len() {
            let (mut p, mut m) = (params.clone(), params.clone());
            p[i] += h;
            m[i] -= h;
            let fd = (loss(&p) - loss(&m)) / (2.0 * h);
            assert!((fd - grads[i]).abs() <= 1e-7 * (1.0 + fd.abs()), "param {i}: fd {fd} analytic {}", grads[i]);
        }
        // The feature input (progressive): dL/df against finite differences; point 0 pinned.
        assert_eq!(nf, if progressive { 3 } else { 0 });
        assert_eq!(ws.d_features.len(), n * k * nf);
        for i in 0..f0.len() {
            let (mut p, mut m) = (f0.clone(), f0.clone());
            p[i] += h;
            m[i] -= h;
            let fd = (loss_f(&params, Some(&p)) - loss_f(&params, Some(&m))) / (2.0 * h);
            let an = ws.d_features[i];
            assert!((fd - an).abs() <= 1e-7 * (1.0 + fd.abs()), "feature {i}: fd {fd} analytic {an}");
            assert!(an.abs() > 1e-9, "feature {i} has no gradient");
        }
        if progressive {
            for p in 0..n {
                assert_eq!(ws.offsets[p * k], [0.0; 2]);
                assert_eq!(ws.origins[p * k], [0.0; 3]);
                assert!(ws.offsets[p * k + 1] != [0.0; 2]);
            }
        }
        // Image 0's embedding and points get exactly nothing, image 1's every entry something;
        // every layer tensor is reached.
        let (e, pat) = (cfg.embedding, dsk.pattern);
        assert!(grads[dsk.embeddings..dsk.embeddings + e].iter().all(|&g| g == 0.0));
        assert!(grads[pat..pat + 2 * k].iter().all(|&g| g == 0.0));
        assert!(grads[dsk.embeddings + e..dsk.embeddings + 2 * e].iter().all(|g| g.abs() > 1e-9));
        assert!(grads[pat + 2 * k..pat + 4 * k].iter().all(|g| g.abs() > 1e-9));
        for t in &layout.tensors {
            assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-9), "{} receives no gradient", t.name);
        }
    }

    #[test]
    fn backward_matches_finite_differences_with_shortcut_and_origins() {
        check(true, true, false);
    }

    #[test]
    fn backward_matches_finite_differences_plain() {
        check(false, false, false);
    }

    #[test]
    fn progressive_backward_matches_finite_differences() {
        check(true, true, true);
    }

    #[test]
    fn reference_kernel_starts_near_the_identity() {
        let cfg = DskConfig::reference();
        let mut layout = Layout::default();
        let dsk = Dsk::new(&mut layout, &cfg, 3, 0);
        let mut params = layout.zeros::<f32>();
        dsk.init(&mut params, &mut lcg(17));
        let size = [400.0f32, 300.0];
        let pixels: Vec<[f32; 2]> =
            (0..50).map(|i| [(i * 37 % 400) as f32 + 0.5, (i * 53 % 300) as f32 + 0.5]).collect();
        let mut ws = DskWorkspace::default();
        dsk.forward(&params, &mut ws, 2, &pixels, size, None, None);
        // The reference's start (same bounds hold over 40 seeds): the points within a few
        // pixels of the centre, each within ~2 px of its image's canonical point window tanh(q)
        // (spread ~ window * pattern_init = 1 px), weights within ~50% of 1/K, origin shifts
        // ~0.01.
        let k = cfg.k;
        let rms = (ws.offsets.iter().map(|o| o[0] * o[0] + o[1] * o[1]).sum::<f32>() / ws.offsets.len() as f32).sqrt();
        assert!(rms < 3.0, "offset rms {rms} px");
        assert!(ws.offsets.iter().flatten().all(|x| x.abs() < 6.0), "{:?}", ws.offsets);
        assert!(ws.weights.iter().all(|&w| (w * k as f32 - 1.0).abs() < 0.6), "{:?}", ws.weights);
        assert!(ws.origins.iter().flatten().all(|x| x.abs() < 0.05), "{:?}", ws.origins);
        let q = &params[dsk.pattern + 2 * k * 2..dsk.pattern + 3 * k * 2];
        for (r, o) in ws.offsets.iter().enumerate() {
            for a in 0..2 {
                let c = cfg.window as f32 * q[2 * (r % k) + a].tanh();
                assert!((o[a] - c).abs() < 2.5, "point {}: offset {} canonical {c}", r % k, o[a]);
            }
        }
    }

    #[test]
    fn validate_names_the_field() {
        let cfg = DskConfig::reference();
        assert!(cfg.validate().is_ok());
        let bad = |c: DskConfig| c.validate().unwrap_err();
        assert!(bad(DskConfig { k: 1, ..cfg.clone() }).contains("blur.dsk.k"));
        assert!(bad(DskConfig { hidden: vec![64, 0], ..cfg.clone() }).contains("blur.dsk.hidden"));
        assert!(bad(DskConfig { hidden: vec![64], ..cfg.clone() }).contains("blur.dsk.shortcut"));
        assert!(bad(DskConfig { window: 0.0, ..cfg.clone() }).contains("blur.dsk.window"));
        assert!(bad(DskConfig { jitter: f64::NAN, ..cfg.clone() }).contains("blur.dsk.jitter"));
        assert!(bad(DskConfig { origin_scale: -1.0, ..cfg.clone() }).contains("blur.dsk.origin_scale"));
        assert!(bad(DskConfig { init_scale: 0.0, ..cfg.clone() }).contains("blur.dsk.init_scale"));
        assert!(DskConfig { hidden: vec![64], shortcut: false, ..cfg }.validate().is_ok());
    }

    #[test]
    fn config_rejects_unknown_keys() {
        let text = toml::to_string(&DskConfig::reference()).unwrap();
        assert_eq!(toml::from_str::<DskConfig>(&text).unwrap(), DskConfig::reference());
        assert!(toml::from_str::<DskConfig>(&format!("{text}\nkernel_ptnum = 5\n")).is_err());
    }
}
