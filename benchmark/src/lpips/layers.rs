//! AlexNet's layers on planar feature maps, in f32: convolution as im2col + one matrix product
//! (matrixmultiply), ReLU, and max pooling without padding (floor mode, as PyTorch's default).

use rayon::prelude::*;

use super::weights::ConvSpec;

/// Output rows computed per parallel task of a convolution's matrix product.
const ROWS_PER_TASK: usize = 32;

/// A feature map: `c` channels of `h x w` values, planar (channel-major, then row-major).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Map {
    pub c: usize,
    pub h: usize,
    pub w: usize,
    pub data: Vec<f32>,
}

/// Output length of a window of `k` taps sliding by `stride` over `len + 2 pad` values, or
/// `None` when not even one window fits (PyTorch's floor mode).
pub(crate) fn out_len(len: usize, k: usize, stride: usize, pad: usize) -> Option<usize> {
    (len + 2 * pad).checked_sub(k).map(|room| room / stride + 1)
}

/// One convolution with its weights: `weight` is `c_out x (c_in k k)` row-major (PyTorch's
/// `(c_out, c_in, k, k)`), `bias` has `c_out` values.
pub(crate) struct Conv {
    pub spec: ConvSpec,
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

impl Conv {
    /// `relu(conv(x) + bias)`. The caller has checked that the output is at least 1x1.
    pub fn forward_relu(&self, x: &Map) -> Map {
        let ConvSpec { c_out, c_in, k, stride, pad, .. } = self.spec;
        assert_eq!(x.c, c_in, "conv input channels");
        let (ho, wo) = (out_len(x.h, k, stride, pad).unwrap(), out_len(x.w, k, stride, pad).unwrap());
        let n = ho * wo;
        let cols = im2col(x, k, stride, pad, ho, wo);

        // out = W cols + bias (c_out x n), in blocks of output rows.
        let kk = c_in * k * k;
        let mut out = vec![0f32; c_out * n];
        out.par_chunks_mut(ROWS_PER_TASK * n).enumerate().for_each(|(block, o)| {
            let r0 = block * ROWS_PER_TASK;
            let rows = o.len() / n;
            for (row, b) in o.chunks_exact_mut(n).zip(&self.bias[r0..r0 + rows]) {
                row.fill(*b);
            }
            let w = &self.weight[r0 * kk..(r0 + rows) * kk];
            // SAFETY: `w` is rows x kk, `cols` kk x n and `o` rows x n, all row-major and
            // exactly that long; `o` is a unique borrow aliasing neither input.
            unsafe {
                matrixmultiply::sgemm(
                    rows,
                    kk,
                    n,
                    1.0,
                    w.as_ptr(),
                    kk as isize,
                    1,
                    cols.as_ptr(),
                    n as isize,
                    1,
                    1.0,
                    o.as_mut_ptr(),
                    n as isize,
                    1,
                )
            }
            // ReLU.
            o.iter_mut().for_each(|v| *v = v.max(0.0));
        });
        Map { c: c_out, h: ho, w: wo, data: out }
    }
}

/// The im2col matrix of `x`: row `(ci, ky, kx)`, column `(oy, ox)` holds the input value
/// `x[ci, oy stride + ky - pad, ox stride + kx - pad]`, zero outside the image.
fn im2col(x: &Map, k: usize, stride: usize, pad: usize, ho: usize, wo: usize) -> Vec<f32> {
    let n = ho * wo;
    let mut cols = vec![0f32; x.c * k * k * n];
    cols.par_chunks_mut(k * k * n).enumerate().for_each(|(ci, block)| {
        let plane = &x.data[ci * x.h * x.w..(ci + 1) * x.h * x.w];
        for ky in 0..k {
            for kx in 0..k {
                let row = &mut block[(ky * k + kx) * n..(ky * k + kx + 1) * n];
                // Output columns whose input column ox stride + kx - pad lies in [0, w).
                let (ox0, ox1) = valid_range(x.w, kx, stride, pad, wo);
                for oy in 0..ho {
                    let Some(iy) = (oy * stride + ky).checked_sub(pad).filter(|&iy| iy < x.h) else { continue };
                    let src = &plane[iy * x.w..(iy + 1) * x.w];
                    let dst = &mut row[oy * wo..(oy + 1) * wo];
                    for ox in ox0..ox1 {
                        dst[ox] = src[ox * stride + kx - pad];
                    }
                }
            }
        }
    });
    cols
}

/// The outputs `o` in `[o0, o1)` whose input `o stride + tap - pad` lies in `[0, len)`.
fn valid_range(len: usize, tap: usize, stride: usize, pad: usize, out: usize) -> (usize, usize) {
    let o0 = pad.saturating_sub(tap).div_ceil(stride);
    // Largest o with o stride + tap - pad <= len - 1.
    let o1 = match (len + pad).checked_sub(tap + 1) {
        Some(last) => (last / stride + 1).min(out),
        None => 0,
    };
    (o0.min(o1), o1)
}

/// 3x3 max pool with stride 2, no padding, floor mode. The caller has checked that the output
/// is at least 1x1.
pub(crate) fn max_pool(x: &Map) -> Map {
    let (k, s) = (3, 2);
    let (ho, wo) = (out_len(x.h, k, s, 0).unwrap(), out_len(x.w, k, s, 0).unwrap());
    let mut out = vec![0f32; x.c * ho * wo];
    out.par_chunks_mut(ho * wo).enumerate().for_each(|(ci, o)| {
        let plane = &x.data[ci * x.h * x.w..(ci + 1) * x.h * x.w];
        for oy in 0..ho {
            for ox in 0..wo {
                let mut m = f32::NEG_INFINITY;
                for iy in oy * s..oy * s + k {
                    for ix in ox * s..ox * s + k {
                        m = m.max(plane[iy * x.w + ix]);
                    }
                }
                o[oy * wo + ox] = m;
            }
        }
    });
    Map { c: x.c, h: ho, w: wo, data: out }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random value in [-1, 1).
    fn noise(i: usize) -> f32 {
        let z = (i as u64 + 1).wrapping_mul(0x9e3779b97f4a7c15);
        let z = (z ^ (z >> 31)).wrapping_mul(0xbf58476d1ce4e5b9);
        ((z >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    fn map(c: usize, h: usize, w: usize, seed: usize) -> Map {
        Map { c, h, w, data: (0..c * h * w).map(|i| noise(i + seed)).collect() }
    }

    /// The convolution by its definition: sums over channels and taps, in f64.
    fn conv_brute(conv: &Conv, x: &Map) -> Map {
        let ConvSpec { c_out, c_in, k, stride, pad, .. } = conv.spec;
        let (ho, wo) = (out_len(x.h, k, stride, pad).unwrap(), out_len(x.w, k, stride, pad).unwrap());
        let mut data = Vec::new();
        for co in 0..c_out {
            for oy in 0..ho {
                for ox in 0..wo {
                    let mut acc = conv.bias[co] as f64;
                    for ci in 0..c_in {
                        for ky in 0..k {
                            for kx in 0..k {
                                let (iy, ix) = (
                                    (oy * stride + ky) as isize - pad as isize,
                                    (ox * stride + kx) as isize - pad as isize,
                                );
                                if iy < 0 || ix < 0 || iy >= x.h as isize || ix >= x.w as isize {
                                    continue;
                                }
                                let v = x.data[(ci * x.h + iy as usize) * x.w + ix as usize] as f64;
                                acc += conv.weight[((co * c_in + ci) * k + ky) * k + kx] as f64 * v;
                            }
                        }
                    }
                    data.push(acc.max(0.0) as f32);
                }
            }
        }
        Map { c: c_out, h: ho, w: wo, data }
    }

    #[test]
    fn conv_matches_its_definition() {
        // Strides, paddings larger and smaller than the kernel radius, odd sizes, more output
        // rows than one parallel task.
        for (c_out, c_in, k, stride, pad, h, w) in [
            (5, 3, 11, 4, 2, 23, 30),
            (70, 4, 5, 1, 2, 7, 9),
            (6, 2, 3, 1, 1, 1, 4),
            (3, 2, 3, 2, 4, 5, 6),
            (4, 3, 4, 3, 0, 13, 10),
        ] {
            let spec = ConvSpec { weight: "w", bias: "b", c_out, c_in, k, stride, pad };
            let weight = (0..c_out * c_in * k * k).map(|i| noise(i + 7) * 0.5).collect();
            let bias = (0..c_out).map(|i| noise(i + 99) * 0.1).collect();
            let conv = Conv { spec, weight, bias };
            let x = map(c_in, h, w, 1000);
            let (fast, brute) = (conv.forward_relu(&x), conv_brute(&conv, &x));
            assert_eq!((fast.c, fast.h, fast.w), (brute.c, brute.h, brute.w));
            for (i, (a, b)) in fast.data.iter().zip(&brute.data).enumerate() {
                assert!((a - b).abs() <= 1e-5 * (1.0 + b.abs()), "{spec:?} at {i}: {a} vs {b}");
            }
            assert!(fast.data.iter().any(|&v| v > 0.0) && fast.data.contains(&0.0));
        }
    }

    #[test]
    fn max_pool_matches_its_definition() {
        for (h, w) in [(3, 3), (4, 7), (8, 5), (15, 16)] {
            let x = map(3, h, w, 5);
            let y = max_pool(&x);
            assert_eq!((y.h, y.w), ((h - 3) / 2 + 1, (w - 3) / 2 + 1));
            for c in 0..3 {
                for oy in 0..y.h {
                    for ox in 0..y.w {
                        let window = (0..9).map(|t| x.data[(c * h + 2 * oy + t / 3) * w + 2 * ox + t % 3]);
                        assert_eq!(y.data[(c * y.h + oy) * y.w + ox], window.fold(f32::MIN, f32::max));
                    }
                }
            }
        }
    }

    #[test]
    fn valid_range_by_brute_force() {
        for len in 1..12 {
            for (k, stride, pad) in [(11, 4, 2), (5, 1, 2), (3, 1, 1), (3, 2, 4)] {
                let Some(out) = out_len(len, k, stride, pad) else { continue };
                for tap in 0..k {
                    let inside = |o: usize| (o * stride + tap).checked_sub(pad).is_some_and(|i| i < len);
                    let want: Vec<usize> = (0..out).filter(|&o| inside(o)).collect();
                    let (o0, o1) = valid_range(len, tap, stride, pad, out);
                    assert_eq!((o0..o1).collect::<Vec<_>>(), want, "len {len} k {k} tap {tap}");
                }
            }
        }
    }
}
