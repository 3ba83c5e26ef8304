//! Volume rendering of one ray (NeRF eq. 3, as NeRF's `raw2outputs`), forward and backward.
//!
//! A ray with `S` samples at sorted depths `t_i` and direction `d` (not normalised) has, per
//! sample, a raw density `sigma_raw_i` (the field's output before the ReLU), a colour `c_i` (three
//! values, already through the sigmoid, linear) and, in training, density noise `n_i` (NeRF's
//! `raw_noise_std`; none at evaluation):
//!
//! ```text
//! sigma_i = relu(sigma_raw_i + n_i)
//! delta_i = (t_{i+1} - t_i) |d|          (delta_{S-1} = 1e10 |d|: the last alpha is 1)
//! alpha_i = 1 - exp(-sigma_i delta_i)
//! T_i     = prod_{j<i} (1 - alpha_j + 1e-10)      (NeRF's cumprod, with its 1e-10)
//! w_i     = alpha_i T_i
//! C = sum_i w_i c_i,   acc = sum_i w_i,   depth = sum_i w_i t_i
//! ```
//!
//! **Backward.** With `G_i = dL/dw_i = <dL/dC, c_i> + dL/dacc + dL/ddepth t_i + (dL/dw_i)_direct`
//! (the last term is the upstream gradient on the weights, e.g. from [`integrate`]) and
//! `p_i = 1 - alpha_i + 1e-10`, the weights depend on `sigma_k` through `alpha_k` (in `w_k`) and
//! through `p_k` (in every `w_i`, `i > k`), with `dalpha_k/dsigma_k = -dp_k/dsigma_k =
//! delta_k exp(-sigma_k delta_k)`. Collecting the second kind in the suffix sum
//! `U_k = sum_{i>k} G_i alpha_i prod_{k<j<i} p_j` (`U_{S-1} = 0`, `U_{k-1} = G_k alpha_k + p_k U_k`):
//!
//! ```text
//! dL/dsigma_raw_k = [sigma_raw_k + n_k > 0] delta_k exp(-sigma_k delta_k) T_k (G_k - U_k)
//! dL/dc_k         = w_k dL/dC
//! dL/d|d|         = sum_k (delta_k / |d|) sigma_k exp(-sigma_k delta_k) T_k (G_k - U_k)
//! ```
//!
//! (`G_k - U_k`: the sample's own colour against the colour expected behind it.) Both passes are
//! O(S) and allocate nothing; the backward pass recomputes `exp(-sigma delta)` from its inputs,
//! so nothing but the weights needs to be kept between the passes, and the depths `t` get no
//! gradient (sampling is not differentiated).
//!
//! **Features along the ray** ([`integrate`], used by AWP): `f = sum_i w_i f_i` for per-sample
//! feature vectors `f_i`, with `dL/df_i = w_i dL/df` and `dL/dw_i = <f_i, dL/df>`, the latter fed
//! to [`render_backward`] as [`RenderGrad::d_weights`].

use super::real::Real;

/// One ray's samples, the input of [`render`] and [`render_backward`] (`S` samples).
#[derive(Clone, Copy, Debug)]
pub struct RaySamples<'a, R> {
    /// Sample depths along the ray, sorted ascending (length `S`), in units of `|d|`.
    pub t: &'a [R],
    /// `|d|`, the norm of the ray direction the samples are `o + t d` along (NeRF scales the
    /// intervals by it).
    pub dir_norm: R,
    /// Raw densities, before noise and ReLU (length `S`).
    pub sigma_raw: &'a [R],
    /// Colours, row-major `S x 3`, already through the sigmoid (linear).
    pub rgb: &'a [R],
    /// Density noise added before the ReLU (length `S`), or `None` (evaluation: zero).
    pub noise: Option<&'a [R]>,
}

impl<R: Real> RaySamples<'_, R> {
    /// The number of samples `S`.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when the ray has no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Panics unless every per-sample slice has the length `t` has.
    fn check(&self) {
        let s = self.len();
        assert_eq!(self.sigma_raw.len(), s, "volume: sigma_raw has {} values for {s} samples", self.sigma_raw.len());
        assert_eq!(self.rgb.len(), 3 * s, "volume: rgb has {} values for {s} samples x 3", self.rgb.len());
        if let Some(noise) = self.noise {
            assert_eq!(noise.len(), s, "volume: noise has {} values for {s} samples", noise.len());
        }
    }

    /// Sample `i`'s `(sigma_raw + noise, sigma, interval delta before scaling by |d|, delta)`.
    #[inline]
    fn segment(&self, i: usize) -> (R, R, R, R) {
        let x = self.sigma_raw[i] + self.noise.map_or(R::zero(), |n| n[i]);
        let sigma = x.max(R::zero());
        // delta_i = t_{i+1} - t_i, the last one 1e10, times |d|.
        let dt = if i + 1 < self.len() { self.t[i + 1] - self.t[i] } else { R::of(1e10) };
        (x, sigma, dt, dt * self.dir_norm)
    }

    /// Sample `i`'s colour.
    #[inline]
    fn colour(&self, i: usize) -> [R; 3] {
        [self.rgb[3 * i], self.rgb[3 * i + 1], self.rgb[3 * i + 2]]
    }
}

/// What [`render`] returns besides the weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rendered<R> {
    /// `C = sum_i w_i c_i` (linear RGB).
    pub rgb: [R; 3],
    /// `acc = sum_i w_i` (opacity, in [0, 1]).
    pub acc: R,
    /// `depth = sum_i w_i t_i` (expected depth, in units of `|d|`; not normalised by `acc`).
    pub depth: R,
}

/// The upstream gradient of [`render_backward`]: `dL/d` of each output of [`render`].
#[derive(Clone, Copy, Debug)]
pub struct RenderGrad<'a, R> {
    /// `dL/dC` (three values).
    pub d_rgb: [R; 3],
    /// `dL/dacc` (zero if unused).
    pub d_acc: R,
    /// `dL/ddepth` (zero if unused).
    pub d_depth: R,
    /// `dL/dw` applied to the weights directly (length `S`), e.g. from [`integrate_backward`].
    pub d_weights: Option<&'a [R]>,
}

impl<R: Real> RenderGrad<'_, R> {
    /// The gradient of a loss on the colour only.
    pub fn rgb(d_rgb: [R; 3]) -> Self {
        Self { d_rgb, d_acc: R::zero(), d_depth: R::zero(), d_weights: None }
    }
}

/// The forward pass (module doc): writes the weights `w_i` to `weights` (length `S`) and returns
/// the colour, opacity and depth.
pub fn render<R: Real>(ray: &RaySamples<R>, weights: &mut [R]) -> Rendered<R> {
    render_until(ray, ray.len(), weights)
}

/// The first sample whose transmittance `T_i` is below `cutoff` (`S` if none is): where early
/// ray termination ends the ray.
pub fn termination<R: Real>(ray: &RaySamples<R>, cutoff: R) -> usize {
    let eps = R::of(1e-10);
    let mut trans = R::one();
    for i in 0..ray.len() {
        if trans < cutoff {
            return i;
        }
        let (_, sigma, _, delta) = ray.segment(i);
        let alpha = R::one() - (-sigma * delta).exp();
        trans *= R::one() - alpha + eps;
    }
    ray.len()
}

/// [`render`] of a ray that ends before sample `end` (early ray termination): samples `end..`
/// get weight 0 and add nothing (the colour, opacity and depth of the first `end` samples, with
/// their own intervals).
pub fn render_until<R: Real>(ray: &RaySamples<R>, end: usize, weights: &mut [R]) -> Rendered<R> {
    ray.check();
    assert_eq!(weights.len(), ray.len(), "render: weights has {} slots for {} samples", weights.len(), ray.len());
    assert!(end <= ray.len(), "render: the ray ends at {end}, past its {} samples", ray.len());
    let mut out = Rendered { rgb: [R::zero(); 3], acc: R::zero(), depth: R::zero() };
    let eps = R::of(1e-10);
    let mut trans = R::one(); // T_i
    weights[end..].fill(R::zero());
    for (i, w) in weights[..end].iter_mut().enumerate() {
        let (_, sigma, _, delta) = ray.segment(i);
        // alpha_i = 1 - exp(-sigma_i delta_i), w_i = alpha_i T_i.
        let alpha = R::one() - (-sigma * delta).exp();
        *w = alpha * trans;
        let c = ray.colour(i);
        for (acc_c, c) in out.rgb.iter_mut().zip(c) {
            *acc_c += *w * c;
        }
        out.acc += *w;
        out.depth += *w * ray.t[i];
        // T_{i+1} = T_i (1 - alpha_i + 1e-10).
        trans *= R::one() - alpha + eps;
    }
    out
}

/// The backward pass (module doc): overwrites `d_sigma_raw` (length `S`) and `d_rgb` (`S x 3`)
/// with `dL/dsigma_raw` and `dL/dc`, and returns `dL/d|d|`. Recomputes what it needs from `ray`
/// (the same inputs [`render`] saw, noise included); allocation-free, O(S).
pub fn render_backward<R: Real>(
    ray: &RaySamples<R>,
    grad: &RenderGrad<R>,
    d_sigma_raw: &mut [R],
    d_rgb: &mut [R],
) -> R {
    render_backward_until(ray, ray.len(), grad, d_sigma_raw, d_rgb)
}

/// The backward pass of [`render_until`]: the samples `end..` get zero gradients.
pub fn render_backward_until<R: Real>(
    ray: &RaySamples<R>,
    end: usize,
    grad: &RenderGrad<R>,
    d_sigma_raw: &mut [R],
    d_rgb: &mut [R],
) -> R {
    ray.check();
    let s = ray.len();
    assert!(end <= s, "render_backward: the ray ends at {end}, past its {s} samples");
    assert_eq!(d_sigma_raw.len(), s, "render_backward: d_sigma_raw has {} slots for {s} samples", d_sigma_raw.len());
    assert_eq!(d_rgb.len(), 3 * s, "render_backward: d_rgb has {} slots for {s} samples x 3", d_rgb.len());
    if let Some(dw) = grad.d_weights {
        assert_eq!(dw.len(), s, "render_backward: d_weights has {} values for {s} samples", dw.len());
    }
    let eps = R::of(1e-10);
    // Back to front: U_k (the suffix sum), and G_k - U_k. Sample k's two slots of d_rgb hold
    // e_k = exp(-sigma_k delta_k) and G_k - U_k until the front-to-back sweep overwrites them.
    d_sigma_raw[end..].fill(R::zero());
    d_rgb[3 * end..].fill(R::zero());
    let mut u = R::zero(); // U_k
    for k in (0..end).rev() {
        let (_, sigma, _, delta) = ray.segment(k);
        let e = (-sigma * delta).exp();
        let alpha = R::one() - e;
        let c = ray.colour(k);
        // G_k = <dL/dC, c_k> + dL/dacc + dL/ddepth t_k + (dL/dw_k)_direct.
        let mut g = grad.d_rgb[0] * c[0] + grad.d_rgb[1] * c[1] + grad.d_rgb[2] * c[2];
        g += grad.d_acc + grad.d_depth * ray.t[k];
        if let Some(dw) = grad.d_weights {
            g += dw[k];
        }
        d_rgb[3 * k] = e;
        d_rgb[3 * k + 1] = g - u;
        // U_{k-1} = G_k alpha_k + p_k U_k.
        u = g * alpha + (R::one() - alpha + eps) * u;
    }
    // Front to back: T_k, then the gradients.
    let mut trans = R::one();
    let mut d_dir_norm = R::zero();
    for k in 0..end {
        let (x, sigma, dt, delta) = ray.segment(k);
        let (e, g_minus_u) = (d_rgb[3 * k], d_rgb[3 * k + 1]);
        let alpha = R::one() - e;
        // dL/dsigma_k / delta_k = e_k T_k (G_k - U_k); the ReLU passes it where x > 0.
        let q = e * trans * g_minus_u;
        d_sigma_raw[k] = if x > R::zero() { delta * q } else { R::zero() };
        d_dir_norm += dt * sigma * q;
        // dL/dc_k = w_k dL/dC.
        let w = alpha * trans;
        for (d, g) in d_rgb[3 * k..3 * k + 3].iter_mut().zip(grad.d_rgb) {
            *d = w * g;
        }
        trans *= R::one() - alpha + eps;
    }
    d_dir_norm
}

/// Integrates per-sample features with the render weights: `out = sum_i w_i f_i`, with
/// `features` row-major `S x F` and `out` of length `F` (overwritten).
pub fn integrate<R: Real>(weights: &[R], features: &[R], out: &mut [R]) {
    let f = out.len();
    assert_eq!(features.len(), weights.len() * f, "integrate: features is not S x F = {} x {f}", weights.len());
    out.fill(R::zero());
    for (w, row) in weights.iter().zip(features.chunks_exact(f.max(1))) {
        for (o, x) in out.iter_mut().zip(row) {
            *o += *w * *x;
        }
    }
}

/// The backward pass of [`integrate`]: overwrites `d_features` (`S x F`) with `w_i dL/dout` and
/// *adds* `<f_i, dL/dout>` to `d_weights` (length `S`), since the weights' gradient collects
/// several consumers before it is passed to [`render_backward`] (zero it first).
pub fn integrate_backward<R: Real>(
    weights: &[R],
    features: &[R],
    d_out: &[R],
    d_features: &mut [R],
    d_weights: &mut [R],
) {
    let f = d_out.len();
    let s = weights.len();
    assert_eq!(features.len(), s * f, "integrate_backward: features is not S x F = {s} x {f}");
    assert_eq!(d_features.len(), s * f, "integrate_backward: d_features is not S x F = {s} x {f}");
    assert_eq!(d_weights.len(), s, "integrate_backward: d_weights has {} slots for {s} samples", d_weights.len());
    if f == 0 {
        return;
    }
    for (i, (row, d_row)) in features.chunks_exact(f).zip(d_features.chunks_exact_mut(f)).enumerate() {
        let mut dot = R::zero();
        for ((x, d), g) in row.iter().zip(d_row.iter_mut()).zip(d_out) {
            *d = weights[i] * *g;
            dot += *x * *g;
        }
        d_weights[i] += dot;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::rng::Rng;

    /// An owned ray for the tests.
    struct TestRay {
        t: Vec<f64>,
        dir_norm: f64,
        sigma_raw: Vec<f64>,
        rgb: Vec<f64>,
        noise: Option<Vec<f64>>,
    }

    impl TestRay {
        fn view(&self) -> RaySamples<'_, f64> {
            RaySamples {
                t: &self.t,
                dir_norm: self.dir_norm,
                sigma_raw: &self.sigma_raw,
                rgb: &self.rgb,
                noise: self.noise.as_deref(),
            }
        }
    }

    /// A ray with `s` samples: densities that make T fall to ~0.1 along it, every third sample
    /// with its ReLU inactive, and every `sigma_raw + noise` at least 0.2 from the kink.
    fn random_ray(s: usize, seed: u64, with_noise: bool) -> TestRay {
        let mut rng = Rng::new(seed, 0);
        let mut t: Vec<f64> = (0..s).map(|_| 0.2 + 2.0 * rng.uniform_f64()).collect();
        t.sort_by(f64::total_cmp);
        let noise: Option<Vec<f64>> = with_noise.then(|| (0..s).map(|_| 0.3 * rng.normal_f64()).collect());
        let sigma_raw = (0..s)
            .map(|i| {
                let n = noise.as_ref().map_or(0.0, |n| n[i]);
                // x = sigma_raw + noise: negative (inactive) or positive, |x| >= 0.2.
                let x = if i % 3 == 1 { -0.2 - rng.uniform_f64() } else { 0.2 + 1.5 * rng.uniform_f64() };
                x - n
            })
            .collect();
        let rgb = (0..3 * s).map(|_| 0.05 + 0.9 * rng.uniform_f64()).collect();
        TestRay { t, dir_norm: 1.3, sigma_raw, rgb, noise }
    }

    /// The loss `<a, C> + b acc + c depth + <g, w>` and its upstream gradient.
    #[derive(Clone)]
    struct Loss {
        a: [f64; 3],
        b: f64,
        c: f64,
        g: Option<Vec<f64>>,
    }

    impl Loss {
        fn eval(&self, ray: &TestRay) -> f64 {
            let mut w = vec![0.0; ray.t.len()];
            let out = render(&ray.view(), &mut w);
            let mut l = (0..3).map(|c| self.a[c] * out.rgb[c]).sum::<f64>() + self.b * out.acc + self.c * out.depth;
            if let Some(g) = &self.g {
                l += g.iter().zip(&w).map(|(g, w)| g * w).sum::<f64>();
            }
            l
        }

        fn grad(&self) -> RenderGrad<'_, f64> {
            RenderGrad { d_rgb: self.a, d_acc: self.b, d_depth: self.c, d_weights: self.g.as_deref() }
        }
    }

    /// Central difference of `f` in the variable `x` (restored afterwards).
    fn central<T>(state: &mut T, x: impl Fn(&mut T) -> &mut f64, f: impl Fn(&T) -> f64) -> f64 {
        let h = 1e-6;
        let x0 = *x(state);
        *x(state) = x0 + h;
        let plus = f(state);
        *x(state) = x0 - h;
        let minus = f(state);
        *x(state) = x0;
        (plus - minus) / (2.0 * h)
    }

    /// Asserts analytic == numeric to relative 1e-6 (absolute 1e-9 for values near zero), and
    /// that the analytic gradient is not all zeros.
    fn assert_close(what: &str, analytic: &[f64], numeric: &[f64]) {
        assert_eq!(analytic.len(), numeric.len());
        for (i, (a, n)) in analytic.iter().zip(numeric).enumerate() {
            let err = (a - n).abs();
            assert!(
                err <= 1e-6 * a.abs().max(n.abs()) + 1e-9,
                "{what}[{i}]: analytic {a:e}, numeric {n:e}, error {err:e}"
            );
        }
        let largest = analytic.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        assert!(largest > 1e-3, "{what}: the analytic gradient is (nearly) all zeros, the check is empty");
    }

    /// Checks dL/dsigma_raw, dL/dc and dL/d|d| of `loss` against central differences.
    fn check_render_gradients(ray: &mut TestRay, loss: &Loss, what: &str) {
        let s = ray.t.len();
        let (mut d_sigma, mut d_rgb) = (vec![0.0; s], vec![0.0; 3 * s]);
        let d_dir = render_backward(&ray.view(), &loss.grad(), &mut d_sigma, &mut d_rgb);
        let f = |r: &TestRay| loss.eval(r);
        let num_sigma: Vec<f64> = (0..s).map(|k| central(ray, |r| &mut r.sigma_raw[k], f)).collect();
        let num_rgb: Vec<f64> = (0..3 * s).map(|k| central(ray, |r| &mut r.rgb[k], f)).collect();
        let num_dir = central(ray, |r| &mut r.dir_norm, f);
        assert_close(&format!("{what}: d_sigma_raw"), &d_sigma, &num_sigma);
        if loss.a != [0.0; 3] {
            assert_close(&format!("{what}: d_rgb"), &d_rgb, &num_rgb);
        } else {
            assert!(d_rgb.iter().all(|&d| d == 0.0) && num_rgb.iter().all(|&d| d == 0.0), "{what}: d_rgb");
        }
        assert_close(&format!("{what}: d_dir_norm"), &[d_dir], &[num_dir]);
        // Inactive ReLUs pass no gradient, and the finite difference agrees exactly.
        for k in 0..s {
            let x = ray.sigma_raw[k] + ray.noise.as_ref().map_or(0.0, |n| n[k]);
            if x <= 0.0 {
                assert_eq!((d_sigma[k], num_sigma[k]), (0.0, 0.0), "{what}: inactive sample {k}");
            }
        }
    }

    #[test]
    fn gradients_of_every_output_match_finite_differences() {
        let mut rng = Rng::new(11, 0);
        let g: Vec<f64> = (0..14).map(|_| rng.normal_f64()).collect();
        let losses = [
            ("colour", Loss { a: [0.7, -1.1, 0.4], b: 0.0, c: 0.0, g: None }),
            ("acc", Loss { a: [0.0; 3], b: 1.3, c: 0.0, g: None }),
            ("depth", Loss { a: [0.0; 3], b: 0.0, c: -0.8, g: None }),
            ("weights", Loss { a: [0.0; 3], b: 0.0, c: 0.0, g: Some(g[..13].to_vec()) }),
            ("all", Loss { a: [0.3, 0.5, -0.9], b: 0.6, c: 0.25, g: Some(g[..13].to_vec()) }),
        ];
        // 13 samples: the last one is dense (alpha = 1); 14: its ReLU is inactive (alpha = 0).
        for s in [13, 14] {
            for with_noise in [false, true] {
                let mut ray = random_ray(s, 3, with_noise);
                assert!((0..s).any(|k| ray.view().segment(k).0 < 0.0), "the test ray has no inactive ReLU");
                let last_dense = ray.view().segment(s - 1).0 > 0.0;
                assert_eq!(last_dense, s == 13);
                for (name, loss) in &losses {
                    let mut loss = Loss { g: loss.g.as_ref().map(|_| g[..s].to_vec()), ..*loss };
                    if *name == "acc" && last_dense {
                        // acc = 1 - T_S + 1e-10 sum T_i = 1 when the last alpha is 1: its gradient
                        // is ~0 (a known answer, not a check); add the colour to test something.
                        let (mut ds, mut dc) = (vec![0.0; s], vec![0.0; 3 * s]);
                        render_backward(&ray.view(), &loss.grad(), &mut ds, &mut dc);
                        assert!(ds.iter().all(|d| d.abs() < 1e-8), "{ds:?}");
                        loss.a = [0.1, 0.2, -0.3];
                    }
                    check_render_gradients(&mut ray, &loss, &format!("{name} (S {s}, noise {with_noise})"));
                }
            }
        }
    }

    #[test]
    fn feature_integration_gradients_match_finite_differences() {
        // L = <h, sum_i w_i f_i> + <a, C>: d_f, and dL/dsigma_raw through d_weights.
        let (s, nf) = (11, 5);
        let mut rng = Rng::new(12, 0);
        let h: Vec<f64> = (0..nf).map(|_| rng.normal_f64()).collect();
        let a = [0.2, -0.4, 0.9];
        let mut state = (random_ray(s, 4, true), (0..s * nf).map(|_| rng.normal_f64()).collect::<Vec<f64>>());
        let loss = |(ray, feats): &(TestRay, Vec<f64>)| {
            let mut w = vec![0.0; s];
            let out = render(&ray.view(), &mut w);
            let mut fsum = vec![0.0; nf];
            integrate(&w, feats, &mut fsum);
            h.iter().zip(&fsum).map(|(h, f)| h * f).sum::<f64>() + (0..3).map(|c| a[c] * out.rgb[c]).sum::<f64>()
        };
        // Analytic: integrate_backward, then render_backward with the accumulated d_weights.
        let (ray, feats) = &state;
        let mut w = vec![0.0; s];
        render(&ray.view(), &mut w);
        let (mut d_feats, mut d_w) = (vec![0.0; s * nf], vec![0.0; s]);
        integrate_backward(&w, feats, &h, &mut d_feats, &mut d_w);
        let grad = RenderGrad { d_rgb: a, d_acc: 0.0, d_depth: 0.0, d_weights: Some(&d_w) };
        let (mut d_sigma, mut d_rgb) = (vec![0.0; s], vec![0.0; 3 * s]);
        render_backward(&ray.view(), &grad, &mut d_sigma, &mut d_rgb);
        let num_feats: Vec<f64> = (0..s * nf).map(|k| central(&mut state, |st| &mut st.1[k], loss)).collect();
        let num_sigma: Vec<f64> = (0..s).map(|k| central(&mut state, |st| &mut st.0.sigma_raw[k], loss)).collect();
        assert_close("d_features", &d_feats, &num_feats);
        assert_close("d_sigma_raw via d_weights", &d_sigma, &num_sigma);
        // integrate_backward accumulates into d_weights.
        let mut twice = d_w.clone();
        integrate_backward(&w, &state.1, &h, &mut d_feats, &mut twice);
        assert!(twice.iter().zip(&d_w).all(|(t, d)| (t - 2.0 * d).abs() <= 1e-15 * d.abs().max(1.0)));
    }

    #[test]
    fn homogeneous_medium_has_the_beer_lambert_opacity() {
        // Constant sigma over S - 1 equal intervals, the last sample empty: acc = 1 - exp(-sigma L |d|).
        let (s, sigma, dt, dir_norm) = (32, 0.8, 0.05, 1.5);
        let t: Vec<f64> = (0..s).map(|i| 1.0 + dt * i as f64).collect();
        let mut sigma_raw = vec![sigma; s];
        sigma_raw[s - 1] = -1.0;
        let rgb: Vec<f64> = (0..s).flat_map(|_| [0.2, 0.5, 0.9]).collect();
        let ray = RaySamples { t: &t, dir_norm, sigma_raw: &sigma_raw, rgb: &rgb, noise: None };
        let mut w = vec![0.0; s];
        let out = render(&ray, &mut w);
        let acc = 1.0 - (-sigma * dt * (s - 1) as f64 * dir_norm).exp();
        assert!((out.acc - acc).abs() < 1e-8, "acc {} vs {acc}", out.acc);
        for (c, v) in [0.2, 0.5, 0.9].iter().enumerate() {
            assert!((out.rgb[c] - v * acc).abs() < 1e-8);
        }
        // w_i = (1 - e) e^i with e = exp(-sigma dt |d|) (up to NeRF's 1e-10).
        let e = (-sigma * dt * dir_norm).exp();
        for (i, wi) in w.iter().enumerate().take(s - 1) {
            assert!((wi - (1.0 - e) * e.powi(i as i32)).abs() < 1e-8);
        }
        assert_eq!(w[s - 1], 0.0);
        // Expected depth of the truncated exponential: sum_i w_i t_i.
        let depth: f64 = (0..s - 1).map(|i| (1.0 - e) * e.powi(i as i32) * t[i]).sum();
        assert!((out.depth - depth).abs() < 1e-8);
    }

    #[test]
    fn an_opaque_sample_takes_all_the_weight_and_the_last_alpha_is_one() {
        let s = 8;
        let t: Vec<f64> = (0..s).map(|i| 0.1 * (i + 1) as f64).collect();
        let rgb: Vec<f64> = (0..3 * s).map(|i| i as f64 / (3 * s) as f64).collect();
        // A wall at sample 3 (empty before it).
        let mut sigma_raw = vec![-1.0; s];
        sigma_raw[3] = 1e4;
        let ray = RaySamples { t: &t, dir_norm: 1.0, sigma_raw: &sigma_raw, rgb: &rgb, noise: None };
        let mut w = vec![0.0; s];
        let out = render(&ray, &mut w);
        assert_eq!(&w[..3], &[0.0; 3]);
        // T_3 = (1 + 1e-10)^3: NeRF's 1e-10 lifts the transmittance of empty space above 1.
        assert!((w[3] - 1.0).abs() < 1e-9 && w[4..].iter().all(|&x| x < 1e-9), "{w:?}");
        assert!((out.depth - t[3]).abs() < 1e-9 && (out.acc - 1.0).abs() < 1e-9);
        for c in 0..3 {
            assert!((out.rgb[c] - rgb[9 + c]).abs() < 1e-9);
        }
        // Nearly empty space with a little density at the end: the last sample takes the rest.
        let mut thin = vec![1e-3; s];
        thin[2] = -0.5;
        let ray = RaySamples { sigma_raw: &thin, ..ray };
        let out = render(&ray, &mut w);
        // acc = 1 - T_S + 1e-10 sum_i T_i, T_S ~ 1e-10: 1 up to NeRF's 1e-10s.
        assert!((out.acc - 1.0).abs() < 1e-8, "acc {}", out.acc);
        assert!(w[s - 1] > 0.99);
    }

    #[test]
    fn f32_matches_f64() {
        let ray = random_ray(64, 7, true);
        let to32 = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let (t, sr, rgb, noise) =
            (to32(&ray.t), to32(&ray.sigma_raw), to32(&ray.rgb), to32(ray.noise.as_ref().unwrap()));
        let ray32 = RaySamples { t: &t, dir_norm: 1.3f32, sigma_raw: &sr, rgb: &rgb, noise: Some(&noise) };
        let (mut w64, mut w32) = (vec![0.0f64; 64], vec![0.0f32; 64]);
        let o64 = render(&ray.view(), &mut w64);
        let o32 = render(&ray32, &mut w32);
        assert!((0..3).all(|c| (o64.rgb[c] - o32.rgb[c] as f64).abs() < 1e-5));
        assert!((o64.depth - o32.depth as f64).abs() < 1e-5);
        let (mut ds64, mut dc64) = (vec![0.0f64; 64], vec![0.0f64; 192]);
        let (mut ds32, mut dc32) = (vec![0.0f32; 64], vec![0.0f32; 192]);
        let dd64 = render_backward(&ray.view(), &RenderGrad::rgb([1.0, -0.5, 0.25]), &mut ds64, &mut dc64);
        let dd32 = render_backward(&ray32, &RenderGrad::rgb([1.0, -0.5, 0.25]), &mut ds32, &mut dc32);
        assert!(ds64.iter().zip(&ds32).all(|(a, b)| (a - *b as f64).abs() < 1e-5));
        assert!(dc64.iter().zip(&dc32).all(|(a, b)| (a - *b as f64).abs() < 1e-5));
        assert!((dd64 - dd32 as f64).abs() < 1e-4 * dd64.abs().max(1.0));
    }
}
