//! Deterministic parallel gradient accumulation.
//!
//! A batch of work items (rays, ray groups, events) is cut into one contiguous range per
//! thread; each thread accumulates into its own full-size gradient buffer, in item order, and
//! the buffers are then summed element-wise in thread order. The result depends on the thread
//! count (the cut) but not on scheduling, so a run is bit-reproducible for a given count.

use rayon::prelude::*;
use std::ops::Range;

/// Per-thread gradient buffers, kept between steps to avoid re-allocation.
#[derive(Debug, Default)]
pub struct GradBuffers {
    bufs: Vec<Vec<f32>>,
}

impl GradBuffers {
    /// Runs `work(range, grads, state)` on `states.len()` contiguous ranges of `0..n_items` in
    /// parallel, each with a zeroed buffer of `len` values and its own state (e.g. a renderer),
    /// and returns the per-range results in order. The summed gradient is then available
    /// through [`GradBuffers::sum_into`].
    pub fn run<S: Send, T: Send>(
        &mut self,
        len: usize,
        n_items: usize,
        states: &mut [S],
        work: impl Fn(Range<usize>, &mut [f32], &mut S) -> T + Sync,
    ) -> Vec<T> {
        let threads = states.len();
        assert!(threads > 0, "GradBuffers::run needs at least one state");
        self.bufs.resize_with(threads, Vec::new);
        self.bufs.truncate(threads);
        self.bufs.par_iter_mut().for_each(|b| {
            b.clear();
            b.resize(len, 0.0);
        });
        self.bufs
            .par_iter_mut()
            .zip(states.par_iter_mut())
            .enumerate()
            .map(|(t, (buf, state))| {
                let range = (n_items * t / threads)..(n_items * (t + 1) / threads);
                work(range, buf, state)
            })
            .collect()
    }

    /// Adds the sum of the buffers (in thread order) to `out`.
    pub fn sum_into(&self, out: &mut [f32]) {
        const BLOCK: usize = 1 << 14;
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(c, o)| {
            let start = c * BLOCK;
            let n = o.len();
            for b in &self.bufs {
                for (x, y) in o.iter_mut().zip(&b[start..start + n]) {
                    *x += *y;
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_every_item_once_and_is_repeatable() {
        let mut g = GradBuffers::default();
        let run = |g: &mut GradBuffers, threads| {
            g.run(4, 1000, &mut vec![(); threads], |r, buf, _| {
                for i in r {
                    buf[i % 4] += 1.0 / (1.0 + i as f32);
                }
            });
            let mut out = vec![0.0f32; 4];
            g.sum_into(&mut out);
            out
        };
        let a = run(&mut g, 3);
        let b = run(&mut g, 3);
        assert_eq!(a, b);
        let total: f64 = (0..1000).map(|i| 1.0 / (1.0 + i as f64)).sum();
        assert!((a.iter().map(|&x| x as f64).sum::<f64>() - total).abs() < 1e-3);
    }
}
