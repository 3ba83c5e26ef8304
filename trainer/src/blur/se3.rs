//! The exponential map of se(3) (rigid-body motions), as DP-NeRF's rigid blurring kernel uses it
//! to move a ray's origin and origin + direction.
//!
//! A twist xi = (r, v) (rotation r, translation v) maps to the motion x -> R x + t with
//! (Rodrigues; theta = |r|, K = [r]_x):
//!
//! ```text
//! R = I + A K + B K^2,   t = (I + B K + C K^2) v,
//! A = sin(theta) / theta,  B = (1 - cos(theta)) / theta^2,  C = (theta - sin(theta)) / theta^3
//! ```
//!
//! Near theta = 0 the coefficients come from their Taylor series in theta^2, so the map and its
//! derivative are smooth at the identity (where the blur kernel starts). The backward pass
//! (dL/dR, dL/dt -> dL/dxi) is exact: the forward is evaluated once more on dual numbers
//! carrying the six partial derivatives.

use std::ops::{Add, Mul, Sub};

/// A rigid motion x -> r x + t.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    /// Rotation (row-major).
    pub r: [[f64; 3]; 3],
    /// Translation.
    pub t: [f64; 3],
}

impl Rigid {
    /// Applies the motion to a point.
    pub fn point(&self, x: [f64; 3]) -> [f64; 3] {
        let d = self.vector(x);
        [d[0] + self.t[0], d[1] + self.t[1], d[2] + self.t[2]]
    }

    /// Applies the rotation to a vector (a ray direction).
    pub fn vector(&self, x: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| self.r[i][0] * x[0] + self.r[i][1] * x[1] + self.r[i][2] * x[2])
    }
}

/// A value with its partial derivatives with respect to the six twist coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Dual {
    v: f64,
    d: [f64; 6],
}

impl Dual {
    fn constant(v: f64) -> Dual {
        Dual { v, d: [0.0; 6] }
    }
    fn variable(v: f64, i: usize) -> Dual {
        let mut d = [0.0; 6];
        d[i] = 1.0;
        Dual { v, d }
    }
    /// f(self) with f' given.
    fn chain(self, f: f64, df: f64) -> Dual {
        Dual { v: f, d: self.d.map(|x| x * df) }
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        Dual { v: self.v + o.v, d: std::array::from_fn(|i| self.d[i] + o.d[i]) }
    }
}

impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        Dual { v: self.v - o.v, d: std::array::from_fn(|i| self.d[i] - o.d[i]) }
    }
}

impl Mul for Dual {
    type Output = Dual;
    // The product rule: (uv)' = u'v + uv'.
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn mul(self, o: Dual) -> Dual {
        Dual { v: self.v * o.v, d: std::array::from_fn(|i| self.d[i] * o.v + self.v * o.d[i]) }
    }
}

/// Below this theta^2 the coefficients use their series (error < 1e-17).
const SERIES_BELOW: f64 = 1e-6;

/// (A, B, C) of the module doc as functions of theta^2.
fn coefficients(th2: Dual) -> (Dual, Dual, Dual) {
    if th2.v < SERIES_BELOW {
        // Taylor series in theta^2 up to theta^4.
        let s = |c0: f64, c1: f64, c2: f64| Dual::constant(c0) + th2 * (Dual::constant(c1) + th2 * Dual::constant(c2));
        (s(1.0, -1.0 / 6.0, 1.0 / 120.0), s(0.5, -1.0 / 24.0, 1.0 / 720.0), s(1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0))
    } else {
        let th = th2.v.sqrt();
        let (s, c) = th.sin_cos();
        // d/d(theta^2) = (1 / (2 theta)) d/d(theta).
        let k = 0.5 / th;
        let a = s / th;
        let b = (1.0 - c) / th2.v;
        let cc = (th - s) / (th2.v * th);
        let da = (c / th - s / th2.v) * k;
        let db = (s / th2.v - 2.0 * (1.0 - c) / (th2.v * th)) * k;
        let dc = ((1.0 - c) / (th2.v * th) - 3.0 * (th - s) / (th2.v * th2.v)) * k;
        (th2.chain(a, da), th2.chain(b, db), th2.chain(cc, dc))
    }
}

/// exp of a twist on dual numbers: (R, t).
fn exp_dual(xi: [Dual; 6]) -> ([[Dual; 3]; 3], [Dual; 3]) {
    let (r, v) = ([xi[0], xi[1], xi[2]], [xi[3], xi[4], xi[5]]);
    let zero = Dual::constant(0.0);
    let k = [[zero, zero - r[2], r[1]], [r[2], zero, zero - r[0]], [zero - r[1], r[0], zero]];
    let k2: [[Dual; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| k[i][0] * k[0][j] + k[i][1] * k[1][j] + k[i][2] * k[2][j]));
    let th2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    let (a, b, c) = coefficients(th2);
    let eye = |i: usize, j: usize| Dual::constant(if i == j { 1.0 } else { 0.0 });
    let rot = std::array::from_fn(|i| std::array::from_fn(|j| eye(i, j) + a * k[i][j] + b * k2[i][j]));
    let vm: [[Dual; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| eye(i, j) + b * k[i][j] + c * k2[i][j]));
    let t = std::array::from_fn(|i| vm[i][0] * v[0] + vm[i][1] * v[1] + vm[i][2] * v[2]);
    (rot, t)
}

/// The rigid motion of twist `xi` = (r, v).
pub fn exp(xi: [f64; 6]) -> Rigid {
    let (r, t) = exp_dual(xi.map(Dual::constant));
    Rigid { r: r.map(|row| row.map(|x| x.v)), t: t.map(|x| x.v) }
}

/// Backward of [`exp`]: dL/dxi from dL/dR (row-major) and dL/dt.
pub fn exp_backward(xi: [f64; 6], d_r: &[[f64; 3]; 3], d_t: &[f64; 3]) -> [f64; 6] {
    let vars: [Dual; 6] = std::array::from_fn(|i| Dual::variable(xi[i], i));
    let (r, t) = exp_dual(vars);
    let mut g = [0.0; 6];
    for (k, gk) in g.iter_mut().enumerate() {
        for i in 0..3 {
            for j in 0..3 {
                *gk += d_r[i][j] * r[i][j].d[k];
            }
            *gk += d_t[i] * t[i].d[k];
        }
    }
    g
}

/// Backward of warping a ray: from dL/do' and dL/dd' of o' = R o + t, d' = R d, the gradients
/// dL/dR (added to `d_r`) and dL/dt (added to `d_t`).
pub fn warp_backward(
    o: [f64; 3],
    d: [f64; 3],
    d_o: [f64; 3],
    d_d: [f64; 3],
    d_r: &mut [[f64; 3]; 3],
    d_t: &mut [f64; 3],
) {
    for i in 0..3 {
        for j in 0..3 {
            d_r[i][j] += d_o[i] * o[j] + d_d[i] * d[j];
        }
        d_t[i] += d_o[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(r: &[[f64; 3]; 3]) -> f64 {
        r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0])
    }

    #[test]
    fn rotations_are_orthonormal_and_known_cases_hold() {
        for xi in [[0.3, -0.2, 0.5, 1.0, 2.0, -1.0], [1e-5, 2e-5, -1e-5, 0.1, 0.0, 0.0], [0.0; 6]] {
            let m = exp(xi);
            for i in 0..3 {
                for j in 0..3 {
                    let dot: f64 = (0..3).map(|k| m.r[k][i] * m.r[k][j]).sum();
                    assert!((dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
            assert!((det(&m.r) - 1.0).abs() < 1e-12);
        }
        // A quarter turn about z maps x to y; a pure translation moves by v.
        let m = exp([0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0, 0.0]);
        let y = m.point([1.0, 0.0, 0.0]);
        assert!((y[0]).abs() < 1e-12 && (y[1] - 1.0).abs() < 1e-12);
        assert_eq!(exp([0.0, 0.0, 0.0, 1.0, -2.0, 3.0]).point([0.0; 3]), [1.0, -2.0, 3.0]);
        // Rotation about the translation's axis: t = v (the screw's pitch part).
        let t = exp([0.0, 0.0, 0.7, 0.0, 0.0, 2.0]).t;
        assert!(t[0].abs() < 1e-12 && t[1].abs() < 1e-12 && (t[2] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn backward_matches_finite_differences_including_near_the_identity() {
        let o = [0.2, -0.4, 1.3];
        let d = [0.1, 0.3, -1.0];
        let (wo, wd) = ([0.7, -0.2, 0.4], [-0.3, 0.5, 0.9]);
        let loss = |xi: [f64; 6]| {
            let m = exp(xi);
            let (o2, d2) = (m.point(o), m.vector(d));
            (0..3).map(|i| wo[i] * o2[i] + wd[i] * d2[i]).sum::<f64>()
        };
        for xi in [[0.3, -0.2, 0.5, 0.4, -0.1, 0.2], [1e-4, -2e-4, 5e-5, 0.01, 0.02, -0.03], [0.0; 6]] {
            let (mut d_r, mut d_t) = ([[0.0; 3]; 3], [0.0; 3]);
            warp_backward(o, d, wo, wd, &mut d_r, &mut d_t);
            let g = exp_backward(xi, &d_r, &d_t);
            for k in 0..6 {
                let h = 1e-6;
                let (mut p, mut m) = (xi, xi);
                p[k] += h;
                m[k] -= h;
                let fd = (loss(p) - loss(m)) / (2.0 * h);
                assert!((fd - g[k]).abs() < 1e-7 * (1.0 + fd.abs()), "xi {xi:?} k {k}: fd {fd} analytic {}", g[k]);
                assert!(g[k].abs() > 1e-6, "xi {xi:?} k {k}: zero gradient");
            }
        }
    }
}
