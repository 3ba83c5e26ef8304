//! Fully connected layers over a chunk of samples, forward and backward.
//!
//! A chunk holds `p` samples as rows: `x` is p x n_in (row stride `ldx`, so a layer can read a
//! column block of a wider buffer, e.g. a concatenated input), `y = act(x W + b)` is p x n_out.
//! W is stored row-major n_in x n_out in the flat parameter vector. Backward, from dL/dy:
//! dL/dz = dL/dy * act'(z) (computed from y), dW += x^T dz, db += sum_rows dz, dx = dz W^T.

use super::params::{Layout, LrClass};
use super::real::Real;

/// Activation after the affine map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// Identity.
    None,
    /// max(0, z).
    Relu,
    /// 1 / (1 + exp(-z)).
    Sigmoid,
}

/// One dense layer: its shape, activation and parameter offsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dense {
    /// Input width.
    pub n_in: usize,
    /// Output width.
    pub n_out: usize,
    /// Activation.
    pub act: Act,
    /// Offset of W (n_in x n_out, row-major).
    pub w: usize,
    /// Offset of the bias (n_out), if the layer has one.
    pub b: Option<usize>,
}

impl Dense {
    /// Allocates W (and b) in `layout`.
    pub fn new(layout: &mut Layout, name: &str, n_in: usize, n_out: usize, bias: bool, act: Act) -> Dense {
        let w = layout.alloc(format!("{name}.w"), n_in * n_out, LrClass::Network);
        let b = bias.then(|| layout.alloc(format!("{name}.b"), n_out, LrClass::Network));
        Dense { n_in, n_out, act, w, b }
    }

    /// PyTorch's default initialisation: W and b uniform in +-1/sqrt(n_in).
    pub fn init<R: Real>(&self, params: &mut [R], rng: &mut impl FnMut() -> f64) {
        let bound = 1.0 / (self.n_in as f64).sqrt();
        for v in &mut params[self.w..self.w + self.n_in * self.n_out] {
            *v = R::of((2.0 * rng() - 1.0) * bound);
        }
        if let Some(b) = self.b {
            for v in &mut params[b..b + self.n_out] {
                *v = R::of((2.0 * rng() - 1.0) * bound);
            }
        }
    }

    /// y (p x n_out, row stride ldy) = act(x W + b) for p rows of x (row stride ldx).
    pub fn forward<R: Real>(&self, params: &[R], p: usize, x: &[R], ldx: usize, y: &mut [R], ldy: usize) {
        let w = &params[self.w..self.w + self.n_in * self.n_out];
        let beta = match self.b {
            Some(b) => {
                let bias = &params[b..b + self.n_out];
                for r in 0..p {
                    y[r * ldy..r * ldy + self.n_out].copy_from_slice(bias);
                }
                R::one()
            }
            None => R::zero(),
        };
        R::gemm(
            p,
            self.n_in,
            self.n_out,
            R::one(),
            (x, ldx as isize, 1),
            (w, self.n_out as isize, 1),
            beta,
            (y, ldy as isize, 1),
        );
        self.activate(p, y, ldy);
    }

    /// y = act(y) over p rows (stride ldy).
    fn activate<R: Real>(&self, p: usize, y: &mut [R], ldy: usize) {
        match self.act {
            Act::None => {}
            Act::Relu => {
                for r in 0..p {
                    for v in &mut y[r * ldy..r * ldy + self.n_out] {
                        *v = v.max(R::zero());
                    }
                }
            }
            Act::Sigmoid => {
                for r in 0..p {
                    for v in &mut y[r * ldy..r * ldy + self.n_out] {
                        *v = R::one() / (R::one() + (-*v).exp());
                    }
                }
            }
        }
    }

    /// dy = dL/dy * act'(z) over p rows (stride ldy), from the outputs y; then db += its
    /// column sums.
    fn act_backward<R: Real>(&self, grads: &mut [R], p: usize, y: &[R], dy: &mut [R], ldy: usize) {
        match self.act {
            Act::None => {}
            Act::Relu => {
                for r in 0..p {
                    let (yr, dr) = (&y[r * ldy..r * ldy + self.n_out], &mut dy[r * ldy..r * ldy + self.n_out]);
                    for (d, &v) in dr.iter_mut().zip(yr) {
                        *d = if v > R::zero() { *d } else { R::zero() };
                    }
                }
            }
            Act::Sigmoid => {
                for r in 0..p {
                    let (yr, dr) = (&y[r * ldy..r * ldy + self.n_out], &mut dy[r * ldy..r * ldy + self.n_out]);
                    for (d, &s) in dr.iter_mut().zip(yr) {
                        *d *= s * (R::one() - s);
                    }
                }
            }
        }
        if let Some(b) = self.b {
            let db = &mut grads[b..b + self.n_out];
            for r in 0..p {
                for (g, &d) in db.iter_mut().zip(&dy[r * ldy..r * ldy + self.n_out]) {
                    *g += d;
                }
            }
        }
    }

    /// Backward. `dy` (p x n_out, stride ldy) holds dL/dy on entry and dL/dz on return; `y` is
    /// the forward output. Accumulates dW and db into `grads`; writes (`dx_beta` = 0) or adds
    /// (`dx_beta` = 1) dL/dx into `dx` when given.
    #[allow(clippy::too_many_arguments)]
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        p: usize,
        x: &[R],
        ldx: usize,
        y: &[R],
        dy: &mut [R],
        ldy: usize,
        dx: Option<(&mut [R], usize, R)>,
    ) {
        // dL/dz from dL/dy through the activation, using y; db += column sums of dz.
        self.act_backward(grads, p, y, dy, ldy);
        // dW += x^T dz  (n_in x p) (p x n_out).
        R::gemm(
            self.n_in,
            p,
            self.n_out,
            R::one(),
            (x, 1, ldx as isize),
            (dy, ldy as isize, 1),
            R::one(),
            (&mut grads[self.w..self.w + self.n_in * self.n_out], self.n_out as isize, 1),
        );
        if let Some((dx, lddx, beta)) = dx {
            self.input_grad_cols(params, p, dy, ldy, (dx, lddx, beta), 0..self.n_in);
        }
    }

    /// dx = dz W[cols]^T (p x n_out)(n_out x |cols|) for the input columns `cols` only (`dx`
    /// holds just those, its column 0 being `cols.start`), written (`beta` = 0) or added
    /// (`beta` = 1); `dz` (p x n_out, stride ldz) as [`backward`](Self::backward) leaves it. An
    /// input block nobody differentiates, such as a positional encoding, then costs no
    /// multiply-adds.
    pub fn input_grad_cols<R: Real>(
        &self,
        params: &[R],
        p: usize,
        dz: &[R],
        ldz: usize,
        dx: (&mut [R], usize, R),
        cols: std::ops::Range<usize>,
    ) {
        assert!(cols.end <= self.n_in, "Dense::input_grad_cols: columns {cols:?} of {}", self.n_in);
        let (dx, lddx, beta) = dx;
        let w = &params[self.w + cols.start * self.n_out..self.w + cols.end * self.n_out];
        R::gemm(
            p,
            self.n_out,
            cols.len(),
            R::one(),
            (dz, ldz as isize, 1),
            (w, 1, self.n_out as isize),
            beta,
            (dx, lddx as isize, 1),
        );
    }
}

/// Rows of a chunk grouped in runs that share the input columns `split..n_in` of one
/// [`Dense`] layer (a ray's samples share its encoded view direction): `starts` holds each
/// run's first row and, last, the row count; `x` holds each run's shared columns (runs x
/// (n_in - split), contiguous). [`Dense::forward_runs`] then multiplies the shared columns
/// once per run instead of once per row.
#[derive(Clone, Copy, Debug)]
pub struct Runs<'a, R> {
    /// First row of each run, then the row count.
    pub starts: &'a [u32],
    /// The shared input columns of each run.
    pub x: &'a [R],
}

impl<R> Runs<'_, R> {
    fn len(&self) -> usize {
        self.starts.len() - 1
    }

    fn rows(&self, r: usize) -> std::ops::Range<usize> {
        self.starts[r] as usize..self.starts[r + 1] as usize
    }
}

impl Dense {
    /// [`forward`](Self::forward) for rows whose columns `split..` are `runs`' (so `x` needs
    /// only its first `split` columns filled): y = act(x[:, ..split] W[..split] + x_run
    /// W[split..] + b). `base` is scratch.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_runs<R: Real>(
        &self,
        params: &[R],
        (x, ldx): (&[R], usize),
        split: usize,
        runs: Runs<'_, R>,
        y: &mut [R],
        ldy: usize,
        base: &mut Vec<R>,
    ) {
        let (n, k2, nr) = (self.n_out, self.n_in - split, runs.len());
        let p = runs.starts[nr] as usize;
        let w = &params[self.w..self.w + self.n_in * n];
        base.clear();
        base.resize(nr * n, R::zero());
        let beta = match self.b {
            Some(b) => {
                for row in base.chunks_exact_mut(n) {
                    row.copy_from_slice(&params[b..b + n]);
                }
                R::one()
            }
            None => R::zero(),
        };
        R::gemm(
            nr,
            k2,
            n,
            R::one(),
            (runs.x, k2 as isize, 1),
            (&w[split * n..], n as isize, 1),
            beta,
            (base, n as isize, 1),
        );
        for r in 0..nr {
            for i in runs.rows(r) {
                y[i * ldy..i * ldy + n].copy_from_slice(&base[r * n..(r + 1) * n]);
            }
        }
        R::gemm(p, split, n, R::one(), (x, ldx as isize, 1), (w, n as isize, 1), R::one(), (y, ldy as isize, 1));
        self.activate(p, y, ldy);
    }

    /// Backward of [`forward_runs`](Self::forward_runs): `dy` (stride ldy) holds dL/dy on
    /// entry and dL/dz on return; accumulates dW and db into `grads` (the shared columns' part
    /// from each run's summed dz, left in `dz_runs`, runs x n_out). The input gradients then
    /// come from [`input_grad_cols`](Self::input_grad_cols): of the rows' columns from `dy`,
    /// of the runs' from `dz_runs`.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_runs<R: Real>(
        &self,
        grads: &mut [R],
        (x, ldx): (&[R], usize),
        split: usize,
        runs: Runs<'_, R>,
        y: &[R],
        dy: &mut [R],
        ldy: usize,
        dz_runs: &mut Vec<R>,
    ) {
        let (n, k2, nr) = (self.n_out, self.n_in - split, runs.len());
        let p = runs.starts[nr] as usize;
        self.act_backward(grads, p, y, dy, ldy);
        R::gemm(
            split,
            p,
            n,
            R::one(),
            (x, 1, ldx as isize),
            (dy, ldy as isize, 1),
            R::one(),
            (&mut grads[self.w..self.w + split * n], n as isize, 1),
        );
        dz_runs.clear();
        dz_runs.resize(nr * n, R::zero());
        for r in 0..nr {
            let acc = &mut dz_runs[r * n..(r + 1) * n];
            for i in runs.rows(r) {
                for (a, d) in acc.iter_mut().zip(&dy[i * ldy..i * ldy + n]) {
                    *a += *d;
                }
            }
        }
        R::gemm(
            k2,
            nr,
            n,
            R::one(),
            (runs.x, 1, k2 as isize),
            (dz_runs, n as isize, 1),
            R::one(),
            (&mut grads[self.w + split * n..self.w + self.n_in * n], n as isize, 1),
        );
    }
}

/// In-place softmax of a row.
pub fn softmax<R: Real>(row: &mut [R]) {
    let max = row.iter().copied().fold(R::neg_infinity(), R::max);
    let mut total = R::zero();
    for x in row.iter_mut() {
        *x = (*x - max).exp();
        total += *x;
    }
    for x in row.iter_mut() {
        *x = *x / total;
    }
}

/// Forward through a stack of layers: `h[0] = l0(x)` (x: p rows of stride `ldx`),
/// `h[i] = li(h[i-1])`; each `h[i]` is p x n_out, contiguous.
pub fn forward_stack<R: Real>(layers: &[Dense], params: &[R], p: usize, x: &[R], ldx: usize, h: &mut [Vec<R>]) {
    for (i, l) in layers.iter().enumerate() {
        let (before, after) = h.split_at_mut(i);
        let (input, ld): (&[R], usize) = if i == 0 { (x, ldx) } else { (&before[i - 1], l.n_in) };
        l.forward(params, p, input, ld, &mut after[0], l.n_out);
    }
}

/// Backward through a stack run by [`forward_stack`] on `x` = (rows, stride): `g_out` holds
/// dL/d(last output) on entry; on return `g_x` holds dL/dx (p x n_in of the first layer,
/// contiguous) in its first `x_cols` columns (the others are not written). `g_out` and `g_tmp`
/// are scratch.
#[allow(clippy::too_many_arguments)]
pub fn backward_stack<R: Real>(
    layers: &[Dense],
    params: &[R],
    grads: &mut [R],
    p: usize,
    x: (&[R], usize),
    h: &[Vec<R>],
    g_out: &mut Vec<R>,
    g_tmp: &mut Vec<R>,
    g_x: &mut Vec<R>,
    x_cols: usize,
) {
    for i in (0..layers.len()).rev() {
        let l = &layers[i];
        let (input, ld): (&[R], usize) = if i == 0 { x } else { (&h[i - 1], l.n_in) };
        let target: &mut Vec<R> = if i == 0 { g_x } else { g_tmp };
        if i == 0 && x_cols < l.n_in {
            l.backward(params, grads, p, input, ld, &h[i], g_out, l.n_out, None);
            l.input_grad_cols(params, p, g_out, l.n_out, (&mut target[..], l.n_in, R::zero()), 0..x_cols);
        } else {
            l.backward(params, grads, p, input, ld, &h[i], g_out, l.n_out, Some((&mut target[..], l.n_in, R::zero())));
        }
        if i > 0 {
            std::mem::swap(g_out, g_tmp);
        }
    }
}
