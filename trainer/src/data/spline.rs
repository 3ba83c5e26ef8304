//! Interpolating cubic spline with not-a-knot ends, for the camera translation along the dense
//! trajectory.
//!
//! This is the spline of `scipy.interpolate.CubicSpline(x, y)` (default `bc_type = "not-a-knot"`)
//! and of `interp1d(x, y, kind = "cubic")`, which builds the same not-a-knot B-spline: with knots
//! `x_0 < ... < x_{n-1}`, `h_i = x_{i+1} - x_i` and chord slopes `d_i = (y_{i+1} - y_i) / h_i`, the
//! knot slopes `s_i` solve the tridiagonal system (C2 continuity at interior knots)
//!
//! `h_i s_{i-1} + 2 (h_{i-1} + h_i) s_i + h_{i-1} s_{i+1} = 3 (h_i d_{i-1} + h_{i-1} d_i)`,
//!
//! closed by not-a-knot rows (the third derivative is continuous at `x_1` and `x_{n-2}`):
//!
//! `h_1 s_0 + (h_0 + h_1) s_1 = ((h_0 + 2 (h_0 + h_1)) h_1 d_0 + h_0^2 d_1) / (h_0 + h_1)` and its
//! mirror at the end. Two knots give the line, three the parabola (as scipy). Each segment is the
//! cubic Hermite polynomial of its end values and slopes. A cubic polynomial is reproduced exactly.

use glam::DVec3;

/// A not-a-knot cubic spline through `(x_i, y_i)` with 3-vector values.
#[derive(Clone, Debug, PartialEq)]
pub struct CubicSpline {
    x: Vec<f64>,
    y: Vec<DVec3>,
    /// Slope dy/dx at each knot.
    s: Vec<DVec3>,
}

impl CubicSpline {
    /// The spline through the knots `x` (strictly increasing, at least 2) and values `y`;
    /// `None` if the lengths differ, there are fewer than 2 knots or `x` is not increasing.
    pub fn not_a_knot(x: Vec<f64>, y: Vec<DVec3>) -> Option<CubicSpline> {
        let n = x.len();
        if n < 2 || y.len() != n || !x.windows(2).all(|w| w[1] > w[0]) {
            return None;
        }
        let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
        let d: Vec<DVec3> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
        let s = match n {
            2 => vec![d[0], d[0]],
            // the parabola through three points: its slope at each knot
            3 => {
                let (h0, h1) = (h[0], h[1]);
                let m1 = (h1 * d[0] + h0 * d[1]) / (h0 + h1);
                vec![2.0 * d[0] - m1, m1, 2.0 * d[1] - m1]
            }
            _ => slopes_not_a_knot(&h, &d),
        };
        Some(CubicSpline { x, y, s })
    }

    /// The knots.
    pub fn knots(&self) -> &[f64] {
        &self.x
    }

    /// The value at `t`, or `None` outside `[x_0, x_{n-1}]` (no extrapolation).
    pub fn eval(&self, t: f64) -> Option<DVec3> {
        let i = segment(&self.x, t)?;
        let h = self.x[i + 1] - self.x[i];
        let u = (t - self.x[i]) / h;
        // cubic Hermite basis on the segment
        let (u2, u3) = (u * u, u * u * u);
        let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
        let h10 = u3 - 2.0 * u2 + u;
        let h01 = -2.0 * u3 + 3.0 * u2;
        let h11 = u3 - u2;
        Some(self.y[i] * h00 + self.s[i] * (h10 * h) + self.y[i + 1] * h01 + self.s[i + 1] * (h11 * h))
    }
}

/// The segment `i` with `x_i <= t <= x_{i+1}` (the last segment for `t = x_{n-1}`).
pub(crate) fn segment(x: &[f64], t: f64) -> Option<usize> {
    let n = x.len();
    if n < 2 || !(t >= x[0] && t <= x[n - 1]) {
        return None;
    }
    // first knot strictly greater than t, minus one
    let i = x.partition_point(|&v| v <= t);
    Some(i.saturating_sub(1).min(n - 2))
}

/// Knot slopes of the not-a-knot spline (n >= 4 knots) by the Thomas algorithm.
fn slopes_not_a_knot(h: &[f64], d: &[DVec3]) -> Vec<DVec3> {
    let n = h.len() + 1;
    // rows: sub[i] s_{i-1} + diag[i] s_i + sup[i] s_{i+1} = rhs[i]
    let (mut sub, mut diag, mut sup, mut rhs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![DVec3::ZERO; n]);
    // first row: not-a-knot at x_1
    let w = h[0] + h[1];
    diag[0] = h[1];
    sup[0] = w;
    rhs[0] = ((h[0] + 2.0 * w) * h[1] * d[0] + h[0] * h[0] * d[1]) / w;
    // interior rows: C2 continuity
    for i in 1..n - 1 {
        sub[i] = h[i];
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        sup[i] = h[i - 1];
        rhs[i] = 3.0 * (h[i] * d[i - 1] + h[i - 1] * d[i]);
    }
    // last row: not-a-knot at x_{n-2}
    let w = h[n - 2] + h[n - 3];
    sub[n - 1] = w;
    diag[n - 1] = h[n - 3];
    rhs[n - 1] = (h[n - 2] * h[n - 2] * d[n - 3] + (2.0 * w + h[n - 2]) * h[n - 3] * d[n - 2]) / w;
    // forward elimination
    for i in 1..n {
        let m = sub[i] / diag[i - 1];
        diag[i] -= m * sup[i - 1];
        rhs[i] = rhs[i] - rhs[i - 1] * m;
    }
    // back substitution
    let mut s = vec![DVec3::ZERO; n];
    s[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        s[i] = (rhs[i] - s[i + 1] * sup[i]) / diag[i];
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic(t: f64) -> DVec3 {
        DVec3::new(1.0 - 2.0 * t + 0.5 * t * t * t, 3.0 * t * t - t * t * t, 0.25 + t)
    }

    #[test]
    fn reproduces_a_cubic_on_uneven_knots() {
        // not-a-knot (unlike natural) is exact for any cubic polynomial
        let x = vec![0.0, 0.3, 0.5, 1.1, 1.2, 2.0, 2.7];
        let y = x.iter().map(|&t| cubic(t)).collect();
        let sp = CubicSpline::not_a_knot(x, y).unwrap();
        for k in 0..=270 {
            let t = k as f64 * 0.01;
            let e = (sp.eval(t).unwrap() - cubic(t)).length();
            assert!(e < 1e-10, "t = {t}: error {e}");
        }
        assert_eq!(sp.eval(-0.01), None);
        assert_eq!(sp.eval(2.71), None);
    }

    #[test]
    fn few_knots_are_line_and_parabola() {
        let sp = CubicSpline::not_a_knot(vec![1.0, 3.0], vec![DVec3::ZERO, DVec3::splat(2.0)]).unwrap();
        assert!((sp.eval(2.5).unwrap() - DVec3::splat(1.5)).length() < 1e-12);
        let p = |t: f64| DVec3::new(t * t, 1.0 - t, 2.0 * t * t - t);
        let x = vec![0.0, 0.4, 1.5];
        let sp = CubicSpline::not_a_knot(x.clone(), x.iter().map(|&t| p(t)).collect()).unwrap();
        for t in [0.0, 0.2, 0.9, 1.5] {
            assert!((sp.eval(t).unwrap() - p(t)).length() < 1e-12, "t = {t}");
        }
        assert!(CubicSpline::not_a_knot(vec![0.0, 0.0, 1.0], vec![DVec3::ZERO; 3]).is_none());
    }

    #[test]
    fn interpolates_knots_and_is_c2() {
        let x: Vec<f64> = (0..12).map(|i| i as f64 * 0.7 + (i as f64).sin() * 0.2).collect();
        let y: Vec<DVec3> = x.iter().map(|&t| DVec3::new(t.sin(), (2.0 * t).cos(), t.sqrt())).collect();
        let sp = CubicSpline::not_a_knot(x.clone(), y.clone()).unwrap();
        for (t, v) in x.iter().zip(&y) {
            assert!((sp.eval(*t).unwrap() - *v).length() < 1e-12);
        }
        // second differences across an interior knot agree from both sides
        let e = 1e-4;
        for &k in &x[1..11] {
            let left = (sp.eval(k).unwrap() - 2.0 * sp.eval(k - e).unwrap() + sp.eval(k - 2.0 * e).unwrap()) / (e * e);
            let right = (sp.eval(k + 2.0 * e).unwrap() - 2.0 * sp.eval(k + e).unwrap() + sp.eval(k).unwrap()) / (e * e);
            assert!((left - right).length() < 1e-2 * (1.0 + left.length()), "knot {k}: {left} vs {right}");
        }
    }
}
