//! The scalar type of the engine's kernels: `f32` for training, `f64` for the finite-difference
//! gradient checks, so every kernel is written once.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{AddAssign, MulAssign, SubAssign};

/// A floating-point scalar the kernels are generic over (`f32` or `f64`).
pub trait Real:
    num_traits::Float + AddAssign + SubAssign + MulAssign + Sum + Default + Debug + Send + Sync + 'static
{
    /// `c = alpha * a @ b + beta * c` with `a` m x k, `b` k x n, `c` m x n, each given by its
    /// row and column strides (in elements).
    #[allow(clippy::too_many_arguments)]
    fn gemm(
        m: usize,
        k: usize,
        n: usize,
        alpha: Self,
        a: (&[Self], isize, isize),
        b: (&[Self], isize, isize),
        beta: Self,
        c: (&mut [Self], isize, isize),
    );

    /// Converts from `f64` (constants, test inputs).
    fn of(x: f64) -> Self;
}

/// Checks that a strided m x n matrix with strides (rs, cs) fits in a slice of `len` elements.
fn fits(len: usize, m: usize, n: usize, rs: isize, cs: isize) -> bool {
    if m == 0 || n == 0 {
        return true;
    }
    rs >= 0 && cs >= 0 && (m - 1) * (rs as usize) + (n - 1) * (cs as usize) < len
}

macro_rules! impl_real {
    ($t:ty) => {
        impl Real for $t {
            fn gemm(
                m: usize,
                k: usize,
                n: usize,
                alpha: Self,
                a: (&[Self], isize, isize),
                b: (&[Self], isize, isize),
                beta: Self,
                c: (&mut [Self], isize, isize),
            ) {
                assert!(fits(a.0.len(), m, k, a.1, a.2), "gemm: a out of bounds");
                assert!(fits(b.0.len(), k, n, b.1, b.2), "gemm: b out of bounds");
                assert!(fits(c.0.len(), m, n, c.1, c.2), "gemm: c out of bounds");
                if m == 0 || n == 0 {
                    return;
                }
                // The gemm crate computes dst = alpha' dst + beta' lhs rhs, reading dst only when
                // asked: beta = 0 must not read `c` (it may hold anything, NaN included). One
                // thread: the callers run their chunks in parallel, and the sum order (so the
                // bits) must not depend on the thread count.
                // SAFETY: the asserts above keep every strided access inside the slices, and `c`
                // is a unique borrow that aliases neither `a` nor `b`.
                unsafe {
                    gemm::gemm(
                        m,
                        n,
                        k,
                        c.0.as_mut_ptr(),
                        c.2,
                        c.1,
                        beta != 0.0,
                        a.0.as_ptr(),
                        a.2,
                        a.1,
                        b.0.as_ptr(),
                        b.2,
                        b.1,
                        beta,
                        alpha,
                        false,
                        false,
                        false,
                        gemm::Parallelism::None,
                    )
                }
            }

            fn of(x: f64) -> Self {
                x as $t
            }
        }
    };
}

impl_real!(f32);
impl_real!(f64);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gemm_matches_naive_with_transposed_operands() {
        let (m, k, n) = (5, 7, 3);
        let a: Vec<f64> = (0..m * k).map(|i| (i as f64 * 0.37).sin()).collect();
        let bt: Vec<f64> = (0..n * k).map(|i| (i as f64 * 0.11).cos()).collect(); // n x k
        let mut c = vec![1.0; m * n];
        // c = 2 a b + 0.5 c, with b given transposed (strides 1, k).
        f64::gemm(m, k, n, 2.0, (&a, k as isize, 1), (&bt, 1, k as isize), 0.5, (&mut c, n as isize, 1));
        for i in 0..m {
            for j in 0..n {
                let dot: f64 = (0..k).map(|l| a[i * k + l] * bt[j * k + l]).sum();
                assert!((c[i * n + j] - (2.0 * dot + 0.5)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn gemm_without_beta_ignores_what_c_held_and_strided_rows_match_naive() {
        // The MLP shapes: many rows, narrow operands, row strides wider than the rows.
        for (m, k, n) in [(300, 95, 64), (257, 64, 3), (33, 42, 16), (4, 0, 5)] {
            let (lda, ldc) = (k + 3, n + 2);
            let a: Vec<f32> = (0..m * lda).map(|i| ((i * 7919) % 1000) as f32 / 500.0 - 1.0).collect();
            let b: Vec<f32> = (0..k * n).map(|i| ((i * 104_729) % 1000) as f32 / 500.0 - 1.0).collect();
            let mut c = vec![f32::NAN; m * ldc];
            f32::gemm(m, k, n, 1.0, (&a, lda as isize, 1), (&b, n as isize, 1), 0.0, (&mut c, ldc as isize, 1));
            for i in 0..m {
                for j in 0..n {
                    let dot: f64 = (0..k).map(|l| a[i * lda + l] as f64 * b[l * n + j] as f64).sum();
                    let got = c[i * ldc + j] as f64;
                    assert!((got - dot).abs() <= 1e-4 * (1.0 + dot.abs()), "{m}x{k}x{n} [{i},{j}]: {got} vs {dot}");
                }
                // The padding between rows is not written.
                assert!(c[i * ldc + n..(i + 1) * ldc].iter().all(|v| v.is_nan()));
            }
        }
    }
}
