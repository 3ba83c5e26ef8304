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
    ($t:ty, $f:path) => {
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
                // SAFETY: the asserts above keep every strided access inside the slices, and `c`
                // is a unique borrow that aliases neither `a` nor `b`.
                unsafe {
                    $f(m, k, n, alpha, a.0.as_ptr(), a.1, a.2, b.0.as_ptr(), b.1, b.2, beta, c.0.as_mut_ptr(), c.1, c.2)
                }
            }

            fn of(x: f64) -> Self {
                x as $t
            }
        }
    };
}

impl_real!(f32, matrixmultiply::sgemm);
impl_real!(f64, matrixmultiply::dgemm);

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
}
