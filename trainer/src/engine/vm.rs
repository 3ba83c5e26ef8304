//! TensoRF vector-matrix (VM) volume (Chen et al. 2022, eq. 3-4): a 3-D feature grid factored
//! into three plane-line pairs. Pair m pairs the plane over axes `MAT[m]` with the line along
//! axis `VEC[m]`; with `n_m` components it gives n_m features
//! f_{m,k}(x) = P_{m,k}(x_u, x_v) * L_{m,k}(x_w) (bilinear on the plane, linear on the line),
//! and the three groups are concatenated (sum n_m values) and mapped by a basis matrix B (no
//! bias) to the volume's feature vector.
//!
//! Storage puts the component index innermost (`plane[(v * res_u + u) * n + k]`,
//! `line[w * n + k]`), so one grid tap is a contiguous run of n values: gathers and the
//! gradient scatter are vector loops. Coordinates span an axis-aligned box (in NDC) with
//! grid-sample `align_corners = true` (min -> index 0, max -> index res - 1 on each axis); points outside are
//! clamped to the border, where the position gradient is zero.
//!
//! The TV regulariser (TensoRF's `TVLoss`) on each plane is 2 (h_tv / count_h + w_tv / count_w)
//! with h_tv the sum of squared differences between neighbouring rows and count_h the number of
//! such differences; each line has the same term along its axis.

use super::mlp::{Act, Dense};
use super::params::{Layout, LrClass};
use super::real::Real;
use rayon::prelude::*;

/// Plane axes of the three pairs (TensoRF's `matMode`).
pub const MAT: [[usize; 2]; 3] = [[0, 1], [0, 2], [1, 2]];
/// Line axis of the three pairs (TensoRF's `vecMode`).
pub const VEC: [usize; 3] = [2, 1, 0];

/// A VM volume: grid shape, components, basis and parameter offsets.
#[derive(Clone, Debug, PartialEq)]
pub struct VmVolume {
    /// Grid resolution per axis.
    pub res: [usize; 3],
    /// Component count of each plane-line pair.
    pub comps: [usize; 3],
    /// Offsets of the three planes.
    pub planes: [usize; 3],
    /// Offsets of the three lines.
    pub lines: [usize; 3],
    /// Basis matrix: sum(comps) -> features, no bias.
    pub basis: Dense,
    /// Box covered by the grid: (min corner, max corner).
    pub bounds: ([f64; 3], [f64; 3]),
}

/// Where one point falls in one plane-line pair: tap indices and weights.
#[derive(Clone, Copy, Debug)]
struct Taps<R> {
    /// Element offsets (relative to the plane start) of the four bilinear taps.
    p: [usize; 4],
    /// Bilinear weights of the taps.
    pw: [R; 4],
    /// Element offsets (relative to the line start) of the two linear taps.
    l: [usize; 2],
    /// Fractions (fu, fv, fw) and whether each axis is inside the box (gradient flows).
    f: [R; 3],
    inside: [bool; 3],
}

impl VmVolume {
    /// Allocates the planes, lines and basis of a volume in `layout`.
    pub fn new(
        layout: &mut Layout,
        name: &str,
        res: [usize; 3],
        comps: [usize; 3],
        features: usize,
        bounds: ([f64; 3], [f64; 3]),
    ) -> VmVolume {
        let mut planes = [0; 3];
        let mut lines = [0; 3];
        for m in 0..3 {
            let [a, b] = MAT[m];
            planes[m] = layout.alloc(format!("{name}.plane{m}"), res[a] * res[b] * comps[m], LrClass::Volume);
            lines[m] = layout.alloc(format!("{name}.line{m}"), res[VEC[m]] * comps[m], LrClass::Volume);
        }
        let basis = Dense::new(layout, &format!("{name}.basis"), comps.iter().sum(), features, false, Act::None);
        VmVolume { res, comps, planes, lines, basis, bounds }
    }

    /// Number of raw VM components (the basis input width).
    pub fn n_comps(&self) -> usize {
        self.comps.iter().sum()
    }

    /// Number of output features.
    pub fn n_features(&self) -> usize {
        self.basis.n_out
    }

    /// TensoRF's initialisation: planes and lines 0.1 * N(0, 1); the basis as a linear layer.
    pub fn init<R: Real>(&self, params: &mut [R], normal: &mut impl FnMut() -> f64, uniform: &mut impl FnMut() -> f64) {
        for m in 0..3 {
            let [a, b] = MAT[m];
            let n = self.comps[m];
            for v in &mut params[self.planes[m]..self.planes[m] + self.res[a] * self.res[b] * n] {
                *v = R::of(0.1 * normal());
            }
            for v in &mut params[self.lines[m]..self.lines[m] + self.res[VEC[m]] * n] {
                *v = R::of(0.1 * normal());
            }
        }
        self.basis.init(params, uniform);
    }

    /// Grid coordinate of `x` on `axis`, its clamped cell and fraction, and whether it is inside.
    fn cell<R: Real>(&self, x: R, axis: usize) -> (usize, R, bool) {
        let n = self.res[axis];
        let (lo, hi) = (self.bounds.0[axis], self.bounds.1[axis]);
        let g = (x - R::of(lo)) * R::of((n - 1) as f64 / (hi - lo));
        let inside = g >= R::zero() && g <= R::of((n - 1) as f64);
        let g = g.max(R::zero()).min(R::of((n - 1) as f64));
        let i = g.floor().to_usize().unwrap_or(0).min(n - 2);
        (i, g - R::of(i as f64), inside)
    }

    fn taps<R: Real>(&self, pos: [R; 3], m: usize) -> Taps<R> {
        let [a, b] = MAT[m];
        let n = self.comps[m];
        let (iu, fu, in_u) = self.cell(pos[a], a);
        let (iv, fv, in_v) = self.cell(pos[b], b);
        let (iw, fw, in_w) = self.cell(pos[VEC[m]], VEC[m]);
        let ru = self.res[a];
        let o = |u: usize, v: usize| (v * ru + u) * n;
        let one = R::one();
        Taps {
            p: [o(iu, iv), o(iu + 1, iv), o(iu, iv + 1), o(iu + 1, iv + 1)],
            pw: [(one - fu) * (one - fv), fu * (one - fv), (one - fu) * fv, fu * fv],
            l: [iw * n, (iw + 1) * n],
            f: [fu, fv, fw],
            inside: [in_u, in_v, in_w],
        }
    }

    /// Raw VM components of one point: `out[sum comps]` = f_{m,k}(pos).
    pub fn components<R: Real>(&self, params: &[R], pos: [R; 3], out: &mut [R]) {
        let mut o = 0;
        for m in 0..3 {
            let n = self.comps[m];
            let t = self.taps(pos, m);
            let plane = &params[self.planes[m]..];
            let line = &params[self.lines[m]..];
            let fw = t.f[2];
            let out = &mut out[o..o + n];
            let (p0, p1, p2, p3) = (
                &plane[t.p[0]..t.p[0] + n],
                &plane[t.p[1]..t.p[1] + n],
                &plane[t.p[2]..t.p[2] + n],
                &plane[t.p[3]..t.p[3] + n],
            );
            let (l0, l1) = (&line[t.l[0]..t.l[0] + n], &line[t.l[1]..t.l[1] + n]);
            for k in 0..n {
                let pv = t.pw[0] * p0[k] + t.pw[1] * p1[k] + t.pw[2] * p2[k] + t.pw[3] * p3[k];
                let lv = l0[k] + fw * (l1[k] - l0[k]);
                out[k] = pv * lv;
            }
            o += n;
        }
    }

    /// Backward of [`components`](Self::components) for one point: scatters dL/dplane and
    /// dL/dline into `grads` and, with `want_dpos`, returns dL/dpos (zero along axes clamped at
    /// the border; all zero without `want_dpos`, which skips its arithmetic).
    pub fn components_backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        pos: [R; 3],
        d_out: &[R],
        want_dpos: bool,
    ) -> [R; 3] {
        if want_dpos {
            self.components_backward_impl::<R, true>(params, grads, pos, d_out)
        } else {
            self.components_backward_impl::<R, false>(params, grads, pos, d_out)
        }
    }

    fn components_backward_impl<R: Real, const DPOS: bool>(
        &self,
        params: &[R],
        grads: &mut [R],
        pos: [R; 3],
        d_out: &[R],
    ) -> [R; 3] {
        let mut dpos = [R::zero(); 3];
        let mut o = 0;
        for m in 0..3 {
            let n = self.comps[m];
            let [a, b] = MAT[m];
            let t = self.taps(pos, m);
            let (fu, fv, fw) = (t.f[0], t.f[1], t.f[2]);
            let one = R::one();
            let d_out = &d_out[o..o + n];
            let (mut du, mut dv, mut dw) = (R::zero(), R::zero(), R::zero());
            // Blocks of components: gather and reduce first, then scatter contiguous runs.
            const B: usize = 16;
            let mut k0 = 0;
            while k0 < n {
                let nb = B.min(n - k0);
                let mut gl = [R::zero(); B];
                let mut gp = [R::zero(); B];
                {
                    let plane = &params[self.planes[m]..];
                    let line = &params[self.lines[m]..];
                    let q = |tap: usize| &plane[t.p[tap] + k0..t.p[tap] + k0 + nb];
                    let (q0, q1, q2, q3) = (q(0), q(1), q(2), q(3));
                    let l0 = &line[t.l[0] + k0..t.l[0] + k0 + nb];
                    let l1 = &line[t.l[1] + k0..t.l[1] + k0 + nb];
                    for k in 0..nb {
                        let pv = t.pw[0] * q0[k] + t.pw[1] * q1[k] + t.pw[2] * q2[k] + t.pw[3] * q3[k];
                        let lv = l0[k] + fw * (l1[k] - l0[k]);
                        let g = d_out[k0 + k];
                        // d f / d plane taps = w_tap * lv; d f / d line taps = (1 - fw, fw) * pv.
                        gl[k] = g * lv;
                        gp[k] = g * pv;
                        // Position: d pv / d fu, d pv / d fv, d lv / d fw.
                        if DPOS {
                            du += gl[k] * ((one - fv) * (q1[k] - q0[k]) + fv * (q3[k] - q2[k]));
                            dv += gl[k] * ((one - fu) * (q2[k] - q0[k]) + fu * (q3[k] - q1[k]));
                            dw += gp[k] * (l1[k] - l0[k]);
                        }
                    }
                }
                let gplane = &mut grads[self.planes[m]..];
                for (&tap, &w) in t.p.iter().zip(&t.pw) {
                    for (g, &x) in gplane[tap + k0..tap + k0 + nb].iter_mut().zip(&gl[..nb]) {
                        *g += w * x;
                    }
                }
                let gline = &mut grads[self.lines[m]..];
                for (g, &x) in gline[t.l[0] + k0..t.l[0] + k0 + nb].iter_mut().zip(&gp[..nb]) {
                    *g += (one - fw) * x;
                }
                for (g, &x) in gline[t.l[1] + k0..t.l[1] + k0 + nb].iter_mut().zip(&gp[..nb]) {
                    *g += fw * x;
                }
                k0 += nb;
            }
            let axes = [a, b, VEC[m]];
            for (j, d) in [du, dv, dw].into_iter().enumerate() {
                if t.inside[j] {
                    let (lo, hi) = (self.bounds.0[axes[j]], self.bounds.1[axes[j]]);
                    let scale = R::of((self.res[axes[j]] - 1) as f64 / (hi - lo));
                    dpos[axes[j]] += d * scale;
                }
            }
            o += n;
        }
        dpos
    }

    /// TV regulariser over all planes (weight `w_plane`) and lines (weight `w_line`): returns the
    /// loss and adds its gradient to `grads`. Parallel over grid rows; deterministic.
    pub fn tv<R: Real>(&self, params: &[R], grads: &mut [R], w_plane: f64, w_line: f64) -> f64 {
        self.tv_terms(params, grads, w_plane, w_line, true)
    }

    /// The gradient of [`tv`](Self::tv) alone, bit for bit the same, without summing the loss
    /// (what a training step needs; the loss's serial sum would take most of the time).
    pub fn tv_grad<R: Real>(&self, params: &[R], grads: &mut [R], w_plane: f64, w_line: f64) {
        self.tv_terms(params, grads, w_plane, w_line, false);
    }

    fn tv_terms<R: Real>(&self, params: &[R], grads: &mut [R], w_plane: f64, w_line: f64, loss: bool) -> f64 {
        let mut total = 0.0;
        for m in 0..3 {
            let [a, b] = MAT[m];
            let n = self.comps[m];
            let (ru, rv) = (self.res[a], self.res[b]);
            let plane = &params[self.planes[m]..self.planes[m] + ru * rv * n];
            // Row pairs (v, v+1) give h terms, neighbours within a row give w terms.
            let c_h = R::of(2.0 * w_plane / (n * (rv - 1) * ru) as f64);
            let c_w = R::of(2.0 * w_plane / (n * rv * (ru - 1)) as f64);
            let g = &mut grads[self.planes[m]..self.planes[m] + ru * rv * n];
            total += tv_grid(plane, g, (rv, ru * n, n), c_h, c_w, loss);
            let rl = self.res[VEC[m]];
            let line = &params[self.lines[m]..self.lines[m] + rl * n];
            let c_l = R::of(2.0 * w_line / (n * (rl - 1)) as f64);
            total += tv_grid(line, &mut grads[self.lines[m]..self.lines[m] + rl * n], (rl, n, n), c_l, R::zero(), loss);
        }
        total
    }
}

/// Sum over a grid of `rows` rows of `row_len` values of c_h (x[r+1] - x[r])^2 between rows and
/// c_w (x[i+step] - x[i])^2 within rows (`step` = components per cell): adds the gradient,
/// row-parallel, and returns the sum when `loss` (else 0).
fn tv_grid<R: Real>(x: &[R], g: &mut [R], shape: (usize, usize, usize), c_h: R, c_w: R, loss: bool) -> f64 {
    let (rows, row_len, step) = shape;
    let two = R::of(2.0);
    g.par_chunks_mut(row_len)
        .enumerate()
        .map(|(r, gr)| {
            let row = &x[r * row_len..(r + 1) * row_len];
            let next = (r + 1 < rows).then(|| &x[(r + 1) * row_len..(r + 2) * row_len]);
            let prev = (r > 0).then(|| &x[(r - 1) * row_len..r * row_len]);
            // Each gradient value gets its terms in one order (next row, previous row, left
            // neighbour, right neighbour), in loops free of carried sums so they vectorise.
            if let Some(next) = next {
                for ((gi, a), b) in gr.iter_mut().zip(row).zip(next) {
                    *gi -= two * c_h * (*b - *a);
                }
            }
            if let Some(prev) = prev {
                for ((gi, a), p) in gr.iter_mut().zip(row).zip(prev) {
                    *gi += two * c_h * (*a - *p);
                }
            }
            let inner = row_len - step;
            if c_w != R::zero() {
                for ((gi, a), b) in gr[step..].iter_mut().zip(&row[..inner]).zip(&row[step..]) {
                    *gi += two * c_w * (*b - *a);
                }
                for ((gi, a), b) in gr[..inner].iter_mut().zip(&row[..inner]).zip(&row[step..]) {
                    *gi -= two * c_w * (*b - *a);
                }
            }
            if !loss {
                return 0.0;
            }
            let mut sum = R::zero();
            if let Some(next) = next {
                for (a, b) in row.iter().zip(next) {
                    sum += c_h * (*b - *a) * (*b - *a);
                }
            }
            if c_w != R::zero() {
                for (a, b) in row[..inner].iter().zip(&row[step..]) {
                    sum += c_w * (*b - *a) * (*b - *a);
                }
            }
            sum.to_f64().unwrap_or(f64::NAN)
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum()
}
