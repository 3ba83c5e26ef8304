//! The learnable event camera response function (eCRF) of Ev-DeblurNeRF.
//!
//! Events fire on changes of log intensity as the event pixel sees it, which need not be the
//! linear colour the field renders. Per colour channel c a small MLP bends the linear value x:
//!
//!   y = eCRF_c(x, p) = sigmoid(x + s m_c(x, [p = +1], [p = -1])),
//!
//! with s = `scale` (reference 0.1) and m_c an MLP of `layers` hidden layers of `hidden` units
//! (reference three of 16, ReLU) and a linear output, biases everywhere. The polarity one-hot is
//! an input only with `polarity` ("eCRF w/ p" of the ablation); a polarity of 0 gives both
//! features zero. Before iteration `start` the trainer zeroes the gradients of [`Ecrf::ranges`],
//! holding the eCRF at its start.
//!
//! Identity start. y = x needs m(x) = (logit(x) - x) / s, which diverges at 0 and 1 (-46 at
//! x = 0.01); the event loss takes log(y + 1e-5), so the start must be an identity in log terms
//! in the dark, not only absolutely. A ReLU MLP of x is a linear spline in x, and a good one
//! needs knots spaced geometrically towards both ends. Trained by Adam from PyTorch-uniform init
//! (3000 steps of 256 points, absolute + log loss, several sampling and step-size schedules),
//! the MLP reached only max log errors of 0.06-0.2 on [0.01, 1] and absolute errors of
//! 0.02-0.08, and some channels collapsed to a sigmoid of a linear m or to a constant (the
//! reference's own pre-fit, absolute error on uniform x, leaves |y - x| ~ 0.08 and a log error of
//! about 2 at x = 0.01). So the start is constructed, in about 10 ms for the three channels:
//!
//! 1. Unit j of the first hidden layer is a hinge with knot k_j: unit 0 is x itself (k = 0),
//!    then dark hinges relu(k_j - x) with k_j geometric in [0.005, 0.3] and bright hinges
//!    relu(x - k_j) with 1 - k_j geometric in [0.01, 0.25] (10 and 5 of them for 16 units).
//!    The polarity rows are zero, so the start is the same for both polarities.
//! 2. The deeper hidden layers pass each unit through (diagonal weights, zero biases).
//! 3. The output weights and bias are the weighted least-squares spline of m on a grid dense at
//!    both ends, weights (1 - x)^2 (the log error is about (1 - y) s |dm|), then reweighted by
//!    Lawson's iterations towards the smallest maximum of the exact error
//!    max(|y - x|, |log(y + 1e-5) - log(x + 1e-5)|) (the log term from x = 0.003 up).
//! 4. ReLU is positively homogeneous, so each unit's coefficient can be split over the layers
//!    on its path freely; the split makes the output equally sensitive to every parameter on it
//!    (the dark units need large coefficients, and all of them on one layer would make Adam's
//!    steps of a few 1e-3 jolt the dark end).
//!
//! Measured on the f32 parameters, every channel and polarity (`identity_start_bounds`):
//! max |y - x| over [0, 1] 0.0072 and max |log(y + 1e-5) - log(x + 1e-5)| over [0.01, 1]
//! 0.0141 (0.02 from x = 0.003); y(0) = 1.4e-3, y(1) = 0.9987. Below x = 0.003 y stops
//! following x in log terms (y(0.001) = 1.8e-3). Being a spline, the curve's log-log slope is
//! off locally (by up to 25 % below x = 0.1, more towards 1 where the sigmoid saturates); over
//! a log step of 0.25 (an event's contrast) by at most 11 % on [0.005, 1]. The start does not
//! depend on the seed. 200 steps of the reference Adam (5e-3) on a log-identity loss keep it
//! within 0.03 in log terms (`reference_adam_keeps_the_start_near_the_identity`).
//!
//! [`Ecrf::forward`] maps a batch of one channel; [`Ecrf::backward`] takes dL/dy back to the
//! layers and to x.

use crate::engine::mlp::{Act, Dense};
use crate::engine::params::Layout;
use crate::engine::real::Real;
use std::ops::Range;

/// Number of colour channels, each with its own MLP.
pub const CHANNELS: usize = 3;

/// The offset inside log(y + LOG_EPS) of the event loss, which the identity start follows.
pub const LOG_EPS: f64 = 1e-5;

/// Shape and schedule of the eCRF.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EcrfConfig {
    /// Width of each hidden layer (reference 16).
    pub hidden: usize,
    /// Number of hidden layers (reference 3); at least 1.
    pub layers: usize,
    /// Whether the polarity one-hot is an input ("eCRF w/ p" of the ablation).
    pub polarity: bool,
    /// Scale s of the MLP's output, added to x before the sigmoid (reference 0.1).
    pub scale: f64,
    /// Iteration from which the eCRF learns; before it, it is held at its identity start.
    pub start: u64,
}

impl EcrfConfig {
    /// Ev-DeblurNeRF's eCRF: 1 (+2) -> 16 -> 16 -> 16 -> 1, scale 0.1, learning from 1200.
    pub fn reference() -> EcrfConfig {
        EcrfConfig { hidden: 16, layers: 3, polarity: true, scale: 0.1, start: 1200 }
    }

    /// Input width of the MLP: x, plus the polarity one-hot.
    pub fn n_in(&self) -> usize {
        if self.polarity {
            3
        } else {
            1
        }
    }
}

/// Knots and fit grid of the constructed identity start (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
struct IdentityFit {
    /// Share of the hinge units (all but the linear unit 0) with a knot on the dark side.
    dark_share: f64,
    /// Range of the dark knots k (geometric).
    dark: (f64, f64),
    /// Range of the bright knots' 1 - k (geometric).
    bright: (f64, f64),
    /// From this x up the fit follows the log error; below it, only the absolute error.
    log_from: f64,
    /// Points in each part of the fit grid (dark, bright, uniform).
    grid: usize,
    /// Lawson reweighting iterations.
    lawson: usize,
}

const IDENTITY: IdentityFit = IdentityFit {
    dark_share: 2.0 / 3.0,
    dark: (0.005, 0.3),
    bright: (0.01, 0.25),
    log_from: 0.003,
    grid: 256,
    lawson: 30,
};

/// The three channels' MLPs.
#[derive(Clone, Debug, PartialEq)]
pub struct Ecrf {
    /// Shape and schedule.
    pub config: EcrfConfig,
    /// Per channel: the hidden layers (ReLU), then the linear output layer.
    pub channels: Vec<Vec<Dense>>,
}

/// Per-batch state of [`Ecrf::forward`] kept for [`Ecrf::backward`]; buffers only grow, so a
/// warm workspace does not allocate.
#[derive(Clone, Debug, Default)]
pub struct EcrfWorkspace<R> {
    /// Batch size of the last forward.
    p: usize,
    /// Channel of the last forward.
    channel: usize,
    /// MLP inputs, p x n_in.
    input: Vec<R>,
    /// Hidden activations per layer, p x hidden each.
    hidden: Vec<Vec<R>>,
    /// MLP outputs m, p.
    m: Vec<R>,
    /// eCRF outputs y, p.
    y: Vec<R>,
    /// dL/dm, p.
    d_m: Vec<R>,
    /// dL/dh of two consecutive hidden layers, p x hidden each.
    d_hidden: [Vec<R>; 2],
    /// dL/d input, p x n_in.
    d_input: Vec<R>,
}

/// Makes `v` at least `n` long (never shrinks).
fn grow<R: Real>(v: &mut Vec<R>, n: usize) {
    if v.len() < n {
        v.resize(n, R::zero());
    }
}

/// `n` values geometric from `lo` to `hi` (their geometric mean when n = 1).
fn geometric(n: usize, (lo, hi): (f64, f64)) -> impl Iterator<Item = f64> {
    (0..n).map(move |i| {
        let t = if n == 1 { 0.5 } else { i as f64 / (n - 1) as f64 };
        (lo.ln() + t * (hi / lo).ln()).exp()
    })
}

/// Per hidden unit, the knot k and the side: +1 for relu(x - k), -1 for relu(k - x). Unit 0 is
/// the linear unit relu(x) = x on [0, 1].
fn knots(h: usize, fit: &IdentityFit) -> Vec<(f64, f64)> {
    let hinges = h.saturating_sub(1);
    let dark = ((fit.dark_share * hinges as f64).round() as usize).min(hinges);
    let mut k = vec![(0.0, 1.0)];
    k.extend(geometric(dark, fit.dark).map(|k| (k, -1.0)));
    k.extend(geometric(hinges - dark, fit.bright).map(|d| (1.0 - d, 1.0)));
    k.truncate(h);
    k
}

/// The error the identity start minimises the maximum of at x (module doc, step 3).
fn identity_error(x: f64, y: f64, log_from: f64) -> f64 {
    let abs = (y - x).abs();
    if x >= log_from {
        abs.max(((y + LOG_EPS).ln() - (x + LOG_EPS).ln()).abs())
    } else {
        abs
    }
}

/// Solves the symmetric positive definite system a x = b (k x k, row-major) by Cholesky.
fn cholesky_solve(a: &mut [f64], mut b: Vec<f64>, k: usize) -> Vec<f64> {
    for j in 0..k {
        let d = (a[j * k + j] - (0..j).map(|q| a[j * k + q] * a[j * k + q]).sum::<f64>()).sqrt();
        a[j * k + j] = d;
        for i in j + 1..k {
            a[i * k + j] = (a[i * k + j] - (0..j).map(|q| a[i * k + q] * a[j * k + q]).sum::<f64>()) / d;
        }
    }
    for i in 0..k {
        b[i] = (b[i] - (0..i).map(|q| a[i * k + q] * b[q]).sum::<f64>()) / a[i * k + i];
    }
    for i in (0..k).rev() {
        b[i] = (b[i] - (i + 1..k).map(|q| a[q * k + i] * b[q]).sum::<f64>()) / a[i * k + i];
    }
    b
}

impl Ecrf {
    /// Allocates the three channels' layers in `layout` (names `ecrf.<c>.<layer>`, `LrClass::Network`).
    pub fn new(layout: &mut Layout, config: &EcrfConfig) -> Ecrf {
        assert!(config.layers >= 1 && config.hidden >= 1, "eCRF: needs at least one hidden layer of one unit");
        let channels = (0..CHANNELS)
            .map(|c| {
                let mut layers: Vec<Dense> = (0..config.layers)
                    .map(|l| {
                        let n_in = if l == 0 { config.n_in() } else { config.hidden };
                        Dense::new(layout, &format!("ecrf.{c}.{l}"), n_in, config.hidden, true, Act::Relu)
                    })
                    .collect();
                let name = format!("ecrf.{c}.{}", config.layers);
                layers.push(Dense::new(layout, &name, config.hidden, 1, true, Act::None));
                layers
            })
            .collect();
        Ecrf { config: config.clone(), channels }
    }

    /// The parameter ranges it owns, one per channel (so the trainer can zero their gradients
    /// before `start`).
    pub fn ranges(&self) -> Vec<Range<usize>> {
        self.channels
            .iter()
            .map(|layers| {
                let (first, last) = (&layers[0], &layers[layers.len() - 1]);
                first.w..last.b.map_or(last.w + last.n_in * last.n_out, |b| b + last.n_out)
            })
            .collect()
    }

    /// The identity start of every channel (module doc); writes only the eCRF's ranges of
    /// `params`. The start is constructed, not drawn, so it does not depend on the seed.
    pub fn init(&self, params: &mut [f32], _seed: u64) {
        // Build in f64 on a copy at offset 0 (same allocation order, so the same layout shifted).
        let mut layout = Layout::default();
        let local = Ecrf::new(&mut layout, &self.config);
        let mut theta = layout.zeros::<f64>();
        for c in 0..CHANNELS {
            local.construct_identity(&mut theta, c, &IDENTITY);
        }
        for (dst, src) in self.ranges().into_iter().zip(local.ranges()) {
            for (p, &t) in params[dst].iter_mut().zip(&theta[src]) {
                *p = t as f32;
            }
        }
    }

    /// Writes channel `c`'s identity start into `theta` (module doc, steps 1-4).
    fn construct_identity(&self, theta: &mut [f64], c: usize, fit: &IdentityFit) {
        let (h, nl, s) = (self.config.hidden, self.config.layers, self.config.scale);
        let knots = knots(h, fit);
        // Fit grid: log-spaced towards 0 and towards 1, uniform, and both ends.
        let n = fit.grid;
        let mut x: Vec<f64> = geometric(n, (1e-3, 0.5)).collect();
        x.extend(geometric(n, (1e-4, 0.5)).map(|d| 1.0 - d));
        x.extend((0..n).map(|i| (i as f64 + 0.5) / n as f64));
        x.extend([0.0, 1.0]);
        // The spline basis phi (row i: every unit at x_i at unit gains, then 1 for the bias),
        // the target m = (logit(x) - x) / s and the weights (1 - x)^2, tapered below log_from.
        let k = h + 1;
        let phi: Vec<f64> = x
            .iter()
            .flat_map(|&x| knots.iter().map(move |&(kj, side)| (side * (x - kj)).max(0.0)).chain([1.0]))
            .collect();
        let target: Vec<f64> = x
            .iter()
            .map(|&x| {
                let xc = x.clamp(1e-6, 1.0 - 1e-6);
                ((xc / (1.0 - xc)).ln() - x) / s
            })
            .collect();
        let weight: Vec<f64> = x.iter().map(|&x| ((1.0 - x) * (x / fit.log_from).min(1.0)).powi(2)).collect();
        // Weighted least squares of m, then Lawson's reweighting u <- u e / mean(u e) with the
        // exact errors e; the iterate with the smallest maximum error wins.
        let mut u = vec![1.0; x.len()];
        let (mut best, mut best_err) = (vec![0.0; k], f64::INFINITY);
        for _ in 0..=fit.lawson {
            let (mut a, mut b) = (vec![0.0; k * k], vec![0.0; k]);
            for (i, row) in phi.chunks_exact(k).enumerate() {
                let w = weight[i] * u[i];
                for p in 0..k {
                    b[p] += w * row[p] * target[i];
                    for q in 0..k {
                        a[p * k + q] += w * row[p] * row[q];
                    }
                }
            }
            for d in 0..k {
                a[d * k + d] *= 1.0 + 1e-12;
            }
            let coef = cholesky_solve(&mut a, b, k);
            let err: Vec<f64> = phi
                .chunks_exact(k)
                .zip(&x)
                .map(|(row, &xi)| {
                    let m: f64 = row.iter().zip(&coef).map(|(f, a)| f * a).sum();
                    identity_error(xi, 1.0 / (1.0 + (-(xi + s * m)).exp()), fit.log_from)
                })
                .collect();
            let max = err.iter().copied().fold(0.0, f64::max);
            if max < best_err {
                (best, best_err) = (coef, max);
            }
            let mean = u.iter().zip(&err).map(|(u, e)| u * e).sum::<f64>() / x.len() as f64;
            for (u, e) in u.iter_mut().zip(&err) {
                *u *= e / mean;
            }
        }
        // Gains (step 4): unit j's path is w_j relu(side (x - k_j)), then d_j in every deeper
        // hidden layer and o_j out, with w_j d_j^(nl - 1) o_j = |a_j|. Over the unit's active
        // part of [0, 1], of length kappa_j, dm/db_j = |a_j| / w_j and dm/dd_j, dm/do_j are at
        // most |a_j| kappa_j / d_j; equal sensitivities give d_j = o_j = kappa_j w_j.
        let mut w_gain = vec![1.0; h];
        let mut d_gain = vec![1.0; h];
        for j in 0..h {
            let (kj, side) = knots[j];
            let kappa = if side < 0.0 { kj } else { 1.0 - kj };
            let a = best[j].abs();
            if a > 0.0 {
                w_gain[j] = (a / kappa.powi(nl as i32)).powf(1.0 / (nl + 1) as f64);
                d_gain[j] = kappa * w_gain[j];
            }
        }
        let layers = &self.channels[c];
        let (first, out) = (&layers[0], &layers[nl]);
        theta[first.w..first.w + first.n_in * h].fill(0.0);
        for j in 0..h {
            let (kj, side) = knots[j];
            theta[first.w + j] = side * w_gain[j];
            theta[first.b.expect("eCRF layers have biases") + j] = -side * w_gain[j] * kj;
        }
        for layer in &layers[1..nl] {
            theta[layer.w..layer.w + h * h].fill(0.0);
            for j in 0..h {
                theta[layer.w + j * h + j] = d_gain[j];
            }
            let b = layer.b.expect("eCRF layers have biases");
            theta[b..b + h].fill(0.0);
        }
        for j in 0..h {
            theta[out.w + j] = best[j] / (w_gain[j] * d_gain[j].powi(nl as i32 - 1));
        }
        theta[out.b.expect("eCRF layers have biases")] = best[h];
    }

    /// Batched forward for one channel: `y[i] = eCRF_c(x[i], pol[i])`; keeps what backward needs
    /// in `ws`. `pol` holds +1 / -1 (0: no polarity) and is read only with `polarity`.
    pub fn forward<R: Real>(
        &self,
        params: &[R],
        channel: usize,
        x: &[R],
        pol: &[i8],
        y: &mut [R],
        ws: &mut EcrfWorkspace<R>,
    ) {
        let (p, n_in, h) = (x.len(), self.config.n_in(), self.config.hidden);
        assert_eq!(y.len(), p, "eCRF forward: y and x differ in length");
        if self.config.polarity {
            assert_eq!(pol.len(), p, "eCRF forward: pol and x differ in length");
        }
        let layers = &self.channels[channel];
        ws.p = p;
        ws.channel = channel;
        grow(&mut ws.input, p * n_in);
        ws.hidden.resize_with(self.config.layers, Vec::new);
        for buf in &mut ws.hidden {
            grow(buf, p * h);
        }
        for buf in [&mut ws.m, &mut ws.y, &mut ws.d_m] {
            grow(buf, p);
        }
        for buf in &mut ws.d_hidden {
            grow(buf, p * h);
        }
        grow(&mut ws.d_input, p * n_in);
        // MLP input: x and the one-hot [p = +1, p = -1].
        for i in 0..p {
            let row = &mut ws.input[i * n_in..(i + 1) * n_in];
            row[0] = x[i];
            if self.config.polarity {
                row[1] = if pol[i] == 1 { R::one() } else { R::zero() };
                row[2] = if pol[i] == -1 { R::one() } else { R::zero() };
            }
        }
        // Hidden layers (ReLU), then the linear output m.
        for l in 0..self.config.layers {
            let (before, rest) = ws.hidden.split_at_mut(l);
            let (src, ld) = if l == 0 { (&ws.input[..], n_in) } else { (&before[l - 1][..], h) };
            layers[l].forward(params, p, src, ld, &mut rest[0], h);
        }
        layers[self.config.layers].forward(params, p, &ws.hidden[self.config.layers - 1], h, &mut ws.m, 1);
        // y = sigmoid(x + s m).
        let s = R::of(self.config.scale);
        for i in 0..p {
            ws.y[i] = R::one() / (R::one() + (-(x[i] + s * ws.m[i])).exp());
            y[i] = ws.y[i];
        }
    }

    /// Backward of the last forward of `ws`: adds parameter gradients into `grads` and writes
    /// dL/dx into `d_x`, from `d_y`.
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        channel: usize,
        d_y: &[R],
        d_x: &mut [R],
        ws: &mut EcrfWorkspace<R>,
    ) {
        let (p, n_in, h) = (ws.p, self.config.n_in(), self.config.hidden);
        assert_eq!(channel, ws.channel, "eCRF backward: channel differs from the last forward's");
        assert!(d_y.len() == p && d_x.len() == p, "eCRF backward: d_y or d_x differ from the batch size");
        let layers = &self.channels[channel];
        let EcrfWorkspace { input, hidden, m, y, d_m, d_hidden, d_input, .. } = ws;
        // Through the sigmoid: dL/dz = dL/dy y (1 - y) with z = x + s m; dz/dx = 1, dz/dm = s.
        let s = R::of(self.config.scale);
        for i in 0..p {
            d_x[i] = d_y[i] * y[i] * (R::one() - y[i]);
            d_m[i] = s * d_x[i];
        }
        // Output layer, then the hidden layers down to the input, ping-ponging dL/dh.
        let [da, db] = d_hidden;
        let (mut d_out, mut d_in) = (da, db);
        let top = self.config.layers;
        layers[top].backward(params, grads, p, &hidden[top - 1], h, m, d_m, 1, Some((d_out, h, R::zero())));
        for l in (0..top).rev() {
            if l == 0 {
                layers[0].backward(
                    params,
                    grads,
                    p,
                    input,
                    n_in,
                    &hidden[0],
                    d_out,
                    h,
                    Some((d_input, n_in, R::zero())),
                );
            } else {
                layers[l].backward(
                    params,
                    grads,
                    p,
                    &hidden[l - 1],
                    h,
                    &hidden[l],
                    d_out,
                    h,
                    Some((d_in, h, R::zero())),
                );
                std::mem::swap(&mut d_out, &mut d_in);
            }
        }
        // dL/dx += dL/d input[0] (the path through the MLP).
        for i in 0..p {
            d_x[i] += d_input[i * n_in];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::params::LrClass;
    use crate::engine::rng::Rng;

    /// An eCRF after a placeholder tensor, so its offsets are not zero.
    fn ecrf(polarity: bool) -> (Ecrf, Layout) {
        let mut layout = Layout::default();
        layout.alloc("before", 5, LrClass::Volume);
        let e = Ecrf::new(&mut layout, &EcrfConfig { polarity, ..EcrfConfig::reference() });
        layout.alloc("after", 3, LrClass::Volume);
        (e, layout)
    }

    /// y for inputs `x` (given in f64) through channel `c`.
    fn run<R: Real>(e: &Ecrf, params: &[R], c: usize, x: &[f64], pol: &[i8]) -> Vec<R> {
        let x: Vec<R> = x.iter().map(|&v| R::of(v)).collect();
        let mut y = vec![R::zero(); x.len()];
        e.forward(params, c, &x, pol, &mut y, &mut EcrfWorkspace::default());
        y
    }

    /// Max |y - x| over [0, 1] and max |log(y + eps) - log(x + eps)| over [0.01, 1] of every
    /// channel and polarity, on a uniform grid and a log grid.
    fn identity_errors(e: &Ecrf, params: &[f32]) -> (f64, f64) {
        let mut grid: Vec<f64> = (0..=20_000).map(|i| i as f64 / 20_000.0).collect();
        grid.extend((0..=4000).map(|i| 0.01f64.powf(1.0 - i as f64 / 4000.0)));
        grid.extend((0..=4000).map(|i| 1.0 - 1e-4f64.powf(1.0 - i as f64 / 4000.0) * 0.5));
        let (mut abs, mut log) = (0.0f64, 0.0f64);
        for c in 0..CHANNELS {
            for pol in [1i8, -1, 0] {
                let y = run::<f32>(e, params, c, &grid, &vec![pol; grid.len()]);
                for (&x, &y) in grid.iter().zip(&y) {
                    let y = y as f64;
                    abs = abs.max((y - x).abs());
                    if x >= 0.01 {
                        log = log.max(((y + LOG_EPS).ln() - (x + LOG_EPS).ln()).abs());
                    }
                }
            }
        }
        (abs, log)
    }

    #[test]
    fn identity_start_bounds() {
        let (e, layout) = ecrf(true);
        let mut params = layout.zeros::<f32>();
        let t0 = std::time::Instant::now();
        e.init(&mut params, 1);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let (abs, log) = identity_errors(&e, &params);
        let ends = run::<f32>(&e, &params, 0, &[0.0, 1.0], &[1, 1]);
        eprintln!("identity start in {ms:.1} ms: max |y - x| {abs:.5}, max log error on [0.01, 1] {log:.5}");
        eprintln!("y(0) = {:.2e}, y(1) = {:.5}", ends[0], ends[1]);
        assert!(abs <= 0.008, "max |y - x| = {abs}");
        assert!(log <= 0.015, "max log error = {log}");
        // Without polarity inputs the same start.
        let (e1, layout1) = ecrf(false);
        let mut p1 = layout1.zeros::<f32>();
        e1.init(&mut p1, 1);
        let (abs1, log1) = identity_errors(&e1, &p1);
        assert!(abs1 <= 0.008 && log1 <= 0.015, "without polarity: {abs1} {log1}");
    }

    #[test]
    fn init_is_deterministic_and_writes_only_its_ranges() {
        let (e, layout) = ecrf(true);
        let mut a = vec![f32::NAN; layout.len()];
        let mut b = vec![7.0f32; layout.len()];
        let mut other_seed = vec![0.0f32; layout.len()];
        e.init(&mut a, 3);
        e.init(&mut b, 3);
        e.init(&mut other_seed, 4);
        let ranges = e.ranges();
        for i in 0..layout.len() {
            if ranges.iter().any(|r| r.contains(&i)) {
                // Same bytes every time, and (constructed, not drawn) for every seed.
                assert_eq!(a[i].to_bits(), b[i].to_bits(), "param {i}");
                assert_eq!(a[i].to_bits(), other_seed[i].to_bits(), "param {i}");
                assert!(a[i].is_finite());
            } else {
                assert!(a[i].is_nan() && b[i] == 7.0, "param {i} outside the eCRF was written");
            }
        }
        // The ranges are exactly the eCRF's tensors.
        let owned: usize = ranges.iter().map(|r| r.len()).sum();
        let tensors: usize = layout.tensors.iter().filter(|t| t.name.starts_with("ecrf.")).map(|t| t.range.len()).sum();
        assert_eq!(owned, tensors);
        assert!(layout.tensors.iter().filter(|t| t.name.starts_with("ecrf.")).all(|t| t.class == LrClass::Network));
    }

    #[test]
    fn polarity_changes_the_output_once_its_weights_move() {
        let (e, layout) = ecrf(true);
        let mut params = layout.zeros::<f32>();
        e.init(&mut params, 1);
        let x = [0.02, 0.3, 0.7];
        // At the start the polarity rows are zero: the same curve for both polarities.
        assert_eq!(run::<f32>(&e, &params, 1, &x, &[1; 3]), run::<f32>(&e, &params, 1, &x, &[-1; 3]));
        let first = e.channels[1][0];
        let mut rng = Rng::new(2, 0);
        for v in &mut params[first.w + first.n_out..first.w + 3 * first.n_out] {
            *v = rng.uniform_f32() - 0.5;
        }
        let (pos, neg) = (run::<f32>(&e, &params, 1, &x, &[1; 3]), run::<f32>(&e, &params, 1, &x, &[-1; 3]));
        assert!(pos.iter().zip(&neg).all(|(a, b)| (a - b).abs() > 1e-4), "{pos:?} {neg:?}");
        // Without polarity inputs `pol` is not read.
        let (e1, layout1) = ecrf(false);
        let mut p1 = layout1.zeros::<f32>();
        e1.init(&mut p1, 1);
        assert_eq!(run::<f32>(&e1, &p1, 0, &x, &[]).len(), 3);
    }

    #[test]
    fn backward_matches_finite_differences() {
        for polarity in [false, true] {
            let (e, layout) = ecrf(polarity);
            // PyTorch-uniform layers, polarity rows included, away from the identity start.
            let mut params = layout.zeros::<f64>();
            let mut rng = Rng::new(5, polarity as u64);
            for layer in e.channels.iter().flatten() {
                layer.init(&mut params, &mut || rng.uniform_f64());
            }
            for v in params.iter_mut() {
                *v *= 3.0;
            }
            let p = 9;
            let x: Vec<f64> = (0..p).map(|_| rng.uniform_f64()).collect();
            let pol: Vec<i8> = (0..p).map(|i| [1, -1, 0][i % 3]).collect();
            let w: Vec<f64> = (0..p).map(|_| rng.uniform_f64() - 0.5).collect();
            // L = sum_i w_i y_i, so dL/dy = w.
            let loss = |params: &[f64], c: usize, x: &[f64]| -> f64 {
                run::<f64>(&e, params, c, x, &pol).iter().zip(&w).map(|(y, w)| y * w).sum()
            };
            let mut ws = EcrfWorkspace::default();
            for c in 0..CHANNELS {
                let mut y = vec![0.0; p];
                e.forward(&params, c, &x, &pol, &mut y, &mut ws);
                let (mut grads, mut d_x) = (layout.zeros::<f64>(), vec![0.0; p]);
                e.backward(&params, &mut grads, c, &w, &mut d_x, &mut ws);
                let h = 1e-6;
                let close = |fd: f64, an: f64| (fd - an).abs() <= 1e-6 * fd.abs() + 1e-9;
                for i in 0..params.len() {
                    let (mut a, mut b) = (params.clone(), params.clone());
                    a[i] += h;
                    b[i] -= h;
                    let fd = (loss(&a, c, &x) - loss(&b, c, &x)) / (2.0 * h);
                    assert!(
                        close(fd, grads[i]),
                        "polarity {polarity} channel {c} param {i}: fd {fd} analytic {}",
                        grads[i]
                    );
                }
                for i in 0..p {
                    let (mut a, mut b) = (x.clone(), x.clone());
                    a[i] += h;
                    b[i] -= h;
                    let fd = (loss(&params, c, &a) - loss(&params, c, &b)) / (2.0 * h);
                    assert!(close(fd, d_x[i]), "polarity {polarity} channel {c} x {i}: fd {fd} analytic {}", d_x[i]);
                }
                // Only this channel's parameters get gradient, and every tensor of it some.
                let r = e.ranges()[c].clone();
                assert!(grads[..r.start].iter().chain(&grads[r.end..]).all(|&g| g == 0.0));
                for t in layout.tensors.iter().filter(|t| t.name.starts_with(&format!("ecrf.{c}."))) {
                    assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-9), "{} receives no gradient", t.name);
                }
                assert!(d_x.iter().all(|g| g.abs() > 1e-9), "{d_x:?}");
            }
        }
    }

    #[test]
    fn reference_adam_keeps_the_start_near_the_identity() {
        // The steep dark end needs large weights; with the gains spread by sensitivity (module
        // doc, step 4), Adam at the reference rate on a log-identity loss stays near the start.
        let (e, layout) = ecrf(true);
        let mut params = layout.zeros::<f32>();
        e.init(&mut params, 1);
        let config = crate::presets::paper_adam();
        let mut adam = crate::engine::adam::Adam::new(&layout);
        let (mut grads, mut ws, mut rng) = (layout.zeros::<f32>(), EcrfWorkspace::default(), Rng::new(4, 0));
        let n = 256;
        let (mut y, mut d_y, mut d_x) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        let pol: Vec<i8> = (0..n).map(|i| if i % 2 == 0 { 1 } else { -1 }).collect();
        for _ in 0..200 {
            grads.fill(0.0);
            for c in 0..CHANNELS {
                // x log-uniform in [0.01, 1); L = mean (log(y + eps) - log(x + eps))^2.
                let x: Vec<f32> = (0..n).map(|_| 0.01f32.powf(rng.uniform_f32())).collect();
                e.forward(&params, c, &x, &pol, &mut y, &mut ws);
                let eps = LOG_EPS as f32;
                for i in 0..n {
                    d_y[i] = 2.0 * ((y[i] + eps).ln() - (x[i] + eps).ln()) / (y[i] + eps) / n as f32;
                }
                e.backward(&params, &mut grads, c, &d_y, &mut d_x, &mut ws);
            }
            adam.step(&config, &layout, &mut params, &grads);
        }
        let (abs, log) = identity_errors(&e, &params);
        eprintln!("after 200 Adam steps at 5e-3: max |y - x| {abs:.5}, max log error {log:.5}");
        assert!(abs <= 0.02 && log <= 0.06, "{abs} {log}");
    }

    #[test]
    fn config_rejects_unknown_keys() {
        let text = "hidden = 16\nlayers = 3\npolarity = true\nscale = 0.1\nstart = 1200\n";
        assert_eq!(toml::from_str::<EcrfConfig>(text).unwrap(), EcrfConfig::reference());
        assert!(toml::from_str::<EcrfConfig>(&format!("{text}width = 3\n")).is_err());
    }
}
