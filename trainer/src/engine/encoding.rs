//! NeRF's positional encoding (Mildenhall et al. 2020, eq. 4), raw input included:
//! gamma(x) = [x, sin(2^0 x), cos(2^0 x), ..., sin(2^{L-1} x), cos(2^{L-1} x)], each term over the
//! three coordinates, so the width is 3 + 6L (63 for L = 10, 27 for L = 4).
//!
//! The sines and cosines of the doubled frequencies come from the double-angle formulas
//! (sin 2a = 2 sin a cos a, cos 2a = 1 - 2 sin^2 a), one `sin_cos` per coordinate instead of L:
//! the error grows by about 2x per octave, which in f32 at L = 10 (~3e-5) is the size of the
//! rounding error of forming 512 x itself.

use super::real::Real;

/// Width of the encoding of 3-vectors with `freqs` frequencies.
pub const fn width(freqs: usize) -> usize {
    3 + 6 * freqs
}

/// Writes gamma(x) (width(freqs) values) into `out`.
pub fn encode<R: Real>(x: [R; 3], freqs: usize, out: &mut [R]) {
    out[..3].copy_from_slice(&x);
    for d in 0..3 {
        let (mut s, mut c) = x[d].sin_cos();
        for l in 0..freqs {
            out[3 + 6 * l + d] = s;
            out[6 + 6 * l + d] = c;
            // Double the angle for the next octave.
            let s2 = R::of(2.0) * s * c;
            c = R::one() - R::of(2.0) * s * s;
            s = s2;
        }
    }
}

/// Backward of [`encode`]: dL/dx from dL/dgamma, using the forward output `enc`
/// (d sin(f x)/dx = f cos(f x), d cos(f x)/dx = -f sin(f x)).
pub fn backward<R: Real>(enc: &[R], d_enc: &[R], freqs: usize) -> [R; 3] {
    let mut dx = [d_enc[0], d_enc[1], d_enc[2]];
    for (d, g) in dx.iter_mut().enumerate() {
        let mut f = R::one();
        for l in 0..freqs {
            let s = enc[3 + 6 * l + d];
            let c = enc[6 + 6 * l + d];
            *g += f * (c * d_enc[3 + 6 * l + d] - s * d_enc[6 + 6 * l + d]);
            f = f + f;
        }
    }
    dx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_direct_sines_and_cosines() {
        let x = [0.3f64, -0.71, 0.05];
        let mut out = vec![0.0; width(10)];
        encode(x, 10, &mut out);
        for l in 0..10 {
            let f = (1u32 << l) as f64;
            for d in 0..3 {
                assert!((out[3 + 6 * l + d] - (f * x[d]).sin()).abs() < 1e-10);
                assert!((out[6 + 6 * l + d] - (f * x[d]).cos()).abs() < 1e-10);
            }
        }
        // f32 stays within the documented ~3e-5 at the top octave.
        let mut out32 = vec![0.0f32; width(10)];
        encode([0.3f32, -0.71, 0.05], 10, &mut out32);
        let err = out.iter().zip(&out32).map(|(a, b)| (a - *b as f64).abs()).fold(0.0, f64::max);
        assert!(err < 1e-4, "f32 encoding error {err}");
    }

    #[test]
    fn backward_matches_finite_differences() {
        let x = [0.37f64, -0.52, 0.11];
        let freqs = 6;
        let w: Vec<f64> = (0..width(freqs)).map(|i| ((i * 7 % 11) as f64 - 5.0) * 0.1).collect();
        let loss = |x: [f64; 3]| {
            let mut e = vec![0.0; width(freqs)];
            encode(x, freqs, &mut e);
            e.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>()
        };
        let mut e = vec![0.0; width(freqs)];
        encode(x, freqs, &mut e);
        let g = backward(&e, &w, freqs);
        for d in 0..3 {
            let h = 1e-6;
            let (mut xp, mut xm) = (x, x);
            xp[d] += h;
            xm[d] -= h;
            let fd = (loss(xp) - loss(xm)) / (2.0 * h);
            assert!((fd - g[d]).abs() <= 1e-6 * (1.0 + fd.abs()), "d{d}: fd {fd} analytic {}", g[d]);
            assert!(g[d].abs() > 1e-3);
        }
    }
}
