//! Image quality metrics, PSNR and SSIM, computed as scikit-image computes them, so that our
//! numbers can be compared with published tables.
//!
//! Images are [`ImageRef`]s: `width x height` pixels of `channels` interleaved f32 values,
//! row-major, row 0 at the top, nominally in [0, 1] (data range `L = 1`). Values are neither
//! clamped nor checked; NaN propagates into the result. Everything is computed in f64.
//!
//! - [`psnr`]: `PSNR = 10 log10(L^2 / MSE)`, `MSE = mean((a - b)^2)` over every value, as
//!   `skimage.metrics.peak_signal_noise_ratio(a, b, data_range=1)`. Identical images have
//!   `MSE = 0` and give `f64::INFINITY` (skimage: `inf`, with a divide-by-zero warning).
//! - [`ssim`]: the mean structural similarity (Wang et al. 2004, eq. 13) per pixel,
//!
//!   `SSIM = (2 mu_x mu_y + C1)(2 sigma_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(sigma_x^2 + sigma_y^2 + C2))`,
//!
//!   with the defaults of `skimage.metrics.structural_similarity(a, b, channel_axis=-1,
//!   data_range=1)`: local statistics over a 7x7 uniform window; `C1 = (K1 L)^2`, `C2 = (K2 L)^2`
//!   with `K1 = 0.01`, `K2 = 0.03`; sample (co)variances, i.e. times `NP / (NP - 1)` with
//!   `NP = 49`; the SSIM map averaged over the pixels at least `(7 - 1) / 2 = 3` from every border,
//!   then over channels. (skimage filters with `uniform_filter` in 'reflect' mode and crops
//!   3 pixels afterwards, so every window it averages lies inside the image and the reflected
//!   values never count: we sum only those windows.) Images smaller than 7x7 are an error, as
//!   in skimage.
//!
//! The window sums are separable running sums (a ring of 7 row sums), O(1) per pixel: a 600x400
//! RGB image takes a few milliseconds.
//!
//! We match skimage given the f32 values widened to float64 (to about 1e-12, checked by
//! `tests/metrics_skimage.rs`); given float32 arrays, skimage computes in float32 and differs from
//! that by up to about 1e-6 in SSIM.

use crate::data::RgbImage;

/// SSIM window side (pixels).
const WIN: usize = 7;
/// Pixels cropped from each border before averaging the SSIM map.
const PAD: usize = (WIN - 1) / 2;
/// SSIM luminance constant: `C1 = (K1 L)^2`.
const K1: f64 = 0.01;
/// SSIM contrast constant: `C2 = (K2 L)^2`.
const K2: f64 = 0.03;
/// Data range `L` (images in [0, 1]).
const DATA_RANGE: f64 = 1.0;

/// Why a metric could not be computed; each variant gives the sizes involved and the fix.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MetricError {
    /// A dimension is zero.
    #[error("empty image ({width}x{height}, {channels} channel(s)); give at least one pixel and one channel")]
    Empty {
        /// Width (pixels).
        width: usize,
        /// Height (pixels).
        height: usize,
        /// Values per pixel.
        channels: usize,
    },
    /// The data slice does not hold `width * height * channels` values.
    #[error(
        "image data holds {actual} values but {width}x{height} with {channels} channel(s) needs {expected}; \
         pass the interleaved row-major buffer of exactly that image"
    )]
    DataLength {
        /// Width (pixels).
        width: usize,
        /// Height (pixels).
        height: usize,
        /// Values per pixel.
        channels: usize,
        /// `width * height * channels`.
        expected: u128,
        /// Length of the slice given.
        actual: usize,
    },
    /// The two images differ in width, height or channel count.
    #[error(
        "images differ in size: {}x{}x{} vs {}x{}x{} (width x height x channels); compare images of one size",
        a[0], a[1], a[2], b[0], b[1], b[2]
    )]
    SizeMismatch {
        /// First image: width, height, channels.
        a: [usize; 3],
        /// Second image: width, height, channels.
        b: [usize; 3],
    },
    /// SSIM's 7x7 window does not fit in the image.
    #[error("SSIM needs at least {WIN}x{WIN} pixels (its window), got {width}x{height}; compare larger images")]
    TooSmallForSsim {
        /// Width (pixels).
        width: usize,
        /// Height (pixels).
        height: usize,
    },
}

/// A borrowed image: `width x height` pixels of `channels` interleaved f32 values, row-major,
/// row 0 at the top, nominally in [0, 1]. Built by [`ImageRef::new`], which checks the sizes.
#[derive(Clone, Copy, Debug)]
pub struct ImageRef<'a> {
    width: usize,
    height: usize,
    channels: usize,
    data: &'a [f32],
}

impl<'a> ImageRef<'a> {
    /// A view of `data`, value `(j * width + i) * channels + c` for column `i`, row `j`,
    /// channel `c`. Errors if a dimension is zero or `data` has another length.
    pub fn new(width: usize, height: usize, channels: usize, data: &'a [f32]) -> Result<ImageRef<'a>, MetricError> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(MetricError::Empty { width, height, channels });
        }
        let expected = width as u128 * height as u128 * channels as u128;
        if expected != data.len() as u128 {
            return Err(MetricError::DataLength { width, height, channels, expected, actual: data.len() });
        }
        Ok(ImageRef { width, height, channels, data })
    }

    /// Width (pixels).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height (pixels).
    pub fn height(&self) -> usize {
        self.height
    }

    /// Values per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The interleaved values.
    pub fn data(&self) -> &'a [f32] {
        self.data
    }

    /// [width, height, channels], for error messages.
    fn dims(&self) -> [usize; 3] {
        [self.width, self.height, self.channels]
    }
}

impl<'a> TryFrom<&'a RgbImage> for ImageRef<'a> {
    type Error = MetricError;

    /// The loader's RGB image as a 3-channel view (checked, its fields being public).
    fn try_from(img: &'a RgbImage) -> Result<ImageRef<'a>, MetricError> {
        ImageRef::new(img.width as usize, img.height as usize, 3, &img.data)
    }
}

/// Errors unless `a` and `b` have one size.
fn same_size(a: &ImageRef, b: &ImageRef) -> Result<(), MetricError> {
    if a.dims() != b.dims() {
        return Err(MetricError::SizeMismatch { a: a.dims(), b: b.dims() });
    }
    Ok(())
}

/// Peak signal-to-noise ratio (dB) of `b` against `a` for data range 1:
/// `10 log10(1 / mean((a - b)^2))`; symmetric. `f64::INFINITY` for identical images.
pub fn psnr(a: ImageRef, b: ImageRef) -> Result<f64, MetricError> {
    same_size(&a, &b)?;
    let sum_sq: f64 = a.data.iter().zip(b.data).map(|(&x, &y)| (x as f64 - y as f64).powi(2)).sum();
    let mse = sum_sq / a.data.len() as f64;
    if mse == 0.0 {
        return Ok(f64::INFINITY);
    }
    Ok(10.0 * (DATA_RANGE * DATA_RANGE / mse).log10())
}

/// Mean structural similarity of `a` and `b` (skimage's defaults, see the module doc): the
/// 7x7-window SSIM map averaged over the interior 3 pixels in from every border, then over
/// channels. 1 for identical images; symmetric. Errors if the sizes differ or are below 7x7.
pub fn ssim(a: ImageRef, b: ImageRef) -> Result<f64, MetricError> {
    same_size(&a, &b)?;
    if a.width < WIN || a.height < WIN {
        return Err(MetricError::TooSmallForSsim { width: a.width, height: a.height });
    }
    let total: f64 = (0..a.channels).map(|c| ssim_channel(&a, &b, c)).sum();
    Ok(total / a.channels as f64)
}

/// The window sums of one pixel: x, y, x^2, y^2, x y.
type Sums = [f64; 5];

/// The sums' terms for the value at flat index `k`.
#[inline]
fn terms(a: &ImageRef, b: &ImageRef, k: usize) -> Sums {
    let x = a.data[k] as f64;
    let y = b.data[k] as f64;
    [x, y, x * x, y * y, x * y]
}

/// Mean SSIM of channel `c` over the windows that lie inside the image (sizes checked).
fn ssim_channel(a: &ImageRef, b: &ImageRef, c: usize) -> f64 {
    let (w, h, nc) = (a.width, a.height, a.channels);
    // Window centres kept after the crop: columns PAD..w-PAD, rows PAD..h-PAD.
    let (ow, oh) = (w - 2 * PAD, h - 2 * PAD);
    let np = (WIN * WIN) as f64;
    let cov_norm = np / (np - 1.0);
    let c1 = (K1 * DATA_RANGE).powi(2);
    let c2 = (K2 * DATA_RANGE).powi(2);
    // ring[r % WIN]: horizontal window sums of row r (one per kept column); col: their sum over
    // the last WIN rows, i.e. the 7x7 window sums.
    let mut ring = vec![[0.0; 5]; WIN * ow];
    let mut col = vec![[0.0; 5]; ow];
    let mut total = 0.0;
    for r in 0..h {
        let slot = &mut ring[(r % WIN) * ow..][..ow];
        // Horizontal running sum along row r: window [i, i + WIN) for output column i.
        let base = r * w * nc + c;
        let mut s: Sums = [0.0; 5];
        for i in 0..WIN - 1 {
            add(&mut s, terms(a, b, base + i * nc));
        }
        for (i, out) in slot.iter_mut().enumerate() {
            add(&mut s, terms(a, b, base + (i + WIN - 1) * nc));
            // Vertical running sum: row r enters, row r - WIN (the slot's old content) leaves.
            for q in 0..5 {
                col[i][q] += s[q] - out[q];
            }
            *out = s;
            sub(&mut s, terms(a, b, base + i * nc));
        }
        if r + 1 < WIN {
            continue;
        }
        // SSIM at the window centres of row r - PAD (Wang et al. 2004, eq. 13), as skimage
        // evaluates it: uniform means, then sample (co)variances.
        let mut row_total = 0.0;
        for s in &col {
            let [ux, uy, uxx, uyy, uxy] = s.map(|v| v / np);
            let vx = cov_norm * (uxx - ux * ux);
            let vy = cov_norm * (uyy - uy * uy);
            let vxy = cov_norm * (uxy - ux * uy);
            let (a1, a2) = (2.0 * ux * uy + c1, 2.0 * vxy + c2);
            let (b1, b2) = (ux * ux + uy * uy + c1, vx + vy + c2);
            row_total += (a1 * a2) / (b1 * b2);
        }
        total += row_total;
    }
    total / (ow * oh) as f64
}

/// `s += t`.
#[inline]
fn add(s: &mut Sums, t: Sums) {
    for q in 0..5 {
        s[q] += t[q];
    }
}

/// `s -= t`.
#[inline]
fn sub(s: &mut Sums, t: Sums) {
    for q in 0..5 {
        s[q] -= t[q];
    }
}

#[cfg(test)]
mod tests {
    use simulator::base::sampling::Rng;

    use super::*;

    /// A smooth image (gradients and a blob) plus uniform noise of amplitude `noise`, clamped to [0, 1].
    fn image(w: usize, h: usize, nc: usize, noise: f32, seed: u64) -> Vec<f32> {
        let mut rng = Rng::new(seed, 7);
        let mut data = Vec::with_capacity(w * h * nc);
        for j in 0..h {
            for i in 0..w {
                for c in 0..nc {
                    let (u, v) = (i as f32 / w as f32, j as f32 / h as f32);
                    let blob = (-((u - 0.4).powi(2) + (v - 0.6).powi(2)) * 8.0).exp();
                    let base = 0.2 + 0.3 * u + 0.2 * v * (c as f32 + 1.0) / nc as f32 + 0.25 * blob;
                    data.push((base + noise * (rng.next_f32() - 0.5)).clamp(0.0, 1.0));
                }
            }
        }
        data
    }

    fn view(w: usize, h: usize, nc: usize, data: &[f32]) -> ImageRef<'_> {
        ImageRef::new(w, h, nc, data).unwrap()
    }

    /// Brute force SSIM: every interior window summed directly.
    fn ssim_brute(a: ImageRef, b: ImageRef) -> f64 {
        let (w, h, nc) = (a.width, a.height, a.channels);
        let mut per_channel = 0.0;
        for c in 0..nc {
            let mut total = 0.0;
            for j in PAD..h - PAD {
                for i in PAD..w - PAD {
                    let mut s = [0.0; 5];
                    for dj in 0..WIN {
                        for di in 0..WIN {
                            add(&mut s, terms(&a, &b, ((j + dj - PAD) * w + i + di - PAD) * nc + c));
                        }
                    }
                    let [ux, uy, uxx, uyy, uxy] = s.map(|v| v / 49.0);
                    let (vx, vy, vxy) = (uxx - ux * ux, uyy - uy * uy, uxy - ux * uy);
                    let (vx, vy, vxy) = (vx * 49.0 / 48.0, vy * 49.0 / 48.0, vxy * 49.0 / 48.0);
                    let (c1, c2) = (1e-4, 9e-4);
                    total += (2.0 * ux * uy + c1) * (2.0 * vxy + c2) / ((ux * ux + uy * uy + c1) * (vx + vy + c2));
                }
            }
            per_channel += total / ((w - 2 * PAD) * (h - 2 * PAD)) as f64;
        }
        per_channel / nc as f64
    }

    #[test]
    fn identical_images_give_ssim_one_and_psnr_infinity() {
        for (w, h, nc) in [(7, 7, 1), (13, 9, 3), (40, 31, 2)] {
            let a = image(w, h, nc, 0.3, 1);
            assert_eq!(psnr(view(w, h, nc, &a), view(w, h, nc, &a)).unwrap(), f64::INFINITY);
            let s = ssim(view(w, h, nc, &a), view(w, h, nc, &a)).unwrap();
            assert!((s - 1.0).abs() < 1e-12, "{w}x{h}x{nc}: {s}");
        }
    }

    #[test]
    fn constant_offset_gives_analytic_psnr_and_ssim() {
        // a on a 1/256 grid in [0, 0.5]: a + 0.25 is exact in f32, so MSE = 0.25^2.
        let (w, h) = (23, 17);
        let a: Vec<f32> = (0..w * h).map(|k| ((k * 37) % 128) as f32 / 256.0).collect();
        let b: Vec<f32> = a.iter().map(|v| v + 0.25).collect();
        let p = psnr(view(w, h, 1, &a), view(w, h, 1, &b)).unwrap();
        assert!((p - (-20.0 * 0.25f64.log10())).abs() < 1e-12, "{p}");
        // Constant images x = 0.25, y = 0.5: no variance, so SSIM = (2 x y + C1) / (x^2 + y^2 + C1).
        let x = vec![0.25f32; w * h * 3];
        let y = vec![0.5f32; w * h * 3];
        let s = ssim(view(w, h, 3, &x), view(w, h, 3, &y)).unwrap();
        let want = (2.0 * 0.25 * 0.5 + 1e-4) / (0.25f64.powi(2) + 0.5f64.powi(2) + 1e-4);
        assert!((s - want).abs() < 1e-12, "{s} vs {want}");
    }

    #[test]
    fn ssim_matches_brute_force_windows() {
        for (w, h, nc, seed) in [(7, 7, 1, 2), (8, 11, 3, 3), (29, 19, 1, 4), (31, 24, 3, 5)] {
            let a = image(w, h, nc, 0.1, seed);
            let b = image(w, h, nc, 0.4, seed + 100);
            let fast = ssim(view(w, h, nc, &a), view(w, h, nc, &b)).unwrap();
            let brute = ssim_brute(view(w, h, nc, &a), view(w, h, nc, &b));
            assert!((fast - brute).abs() < 1e-12, "{w}x{h}x{nc}: {fast} vs {brute}");
        }
    }

    #[test]
    fn metrics_are_symmetric() {
        let (w, h, nc) = (33, 21, 3);
        let a = image(w, h, nc, 0.05, 6);
        let b = image(w, h, nc, 0.3, 7);
        let (va, vb) = (view(w, h, nc, &a), view(w, h, nc, &b));
        assert_eq!(psnr(va, vb).unwrap(), psnr(vb, va).unwrap());
        assert!((ssim(va, vb).unwrap() - ssim(vb, va).unwrap()).abs() < 1e-14);
    }

    #[test]
    fn ssim_is_the_mean_over_channels() {
        let (w, h, nc) = (19, 15, 3);
        let a = image(w, h, nc, 0.1, 8);
        let b = image(w, h, nc, 0.3, 9);
        let plane = |d: &[f32], c: usize| d.iter().skip(c).step_by(nc).copied().collect::<Vec<f32>>();
        let mean: f64 =
            (0..nc).map(|c| ssim(view(w, h, 1, &plane(&a, c)), view(w, h, 1, &plane(&b, c))).unwrap()).sum::<f64>()
                / nc as f64;
        let s = ssim(view(w, h, nc, &a), view(w, h, nc, &b)).unwrap();
        assert!((s - mean).abs() < 1e-14, "{s} vs {mean}");
    }

    #[test]
    fn more_noise_scores_lower() {
        let (w, h, nc) = (48, 32, 3);
        let clean = image(w, h, nc, 0.0, 10);
        let scores: Vec<(f64, f64)> = [0.02, 0.1, 0.4]
            .iter()
            .map(|&n| {
                let noisy = image(w, h, nc, n, 10);
                let (a, b) = (view(w, h, nc, &clean), view(w, h, nc, &noisy));
                (psnr(a, b).unwrap(), ssim(a, b).unwrap())
            })
            .collect();
        for pair in scores.windows(2) {
            assert!(pair[1].0 < pair[0].0 && pair[1].1 < pair[0].1, "{scores:?}");
        }
    }

    #[test]
    fn bad_sizes_are_typed_errors() {
        let d = vec![0.5f32; 7 * 7 * 3];
        assert_eq!(ImageRef::new(0, 7, 3, &[]).unwrap_err(), MetricError::Empty { width: 0, height: 7, channels: 3 });
        assert!(matches!(ImageRef::new(7, 7, 0, &[]), Err(MetricError::Empty { .. })));
        assert_eq!(
            ImageRef::new(7, 7, 2, &d).unwrap_err(),
            MetricError::DataLength { width: 7, height: 7, channels: 2, expected: 98, actual: 147 }
        );
        // A product that overflows usize is a length error, not a panic.
        assert!(matches!(ImageRef::new(usize::MAX, 3, 3, &d), Err(MetricError::DataLength { .. })));
        let a = view(7, 7, 3, &d);
        let b = view(21, 7, 1, &d);
        let err = MetricError::SizeMismatch { a: [7, 7, 3], b: [21, 7, 1] };
        assert_eq!(psnr(a, b).unwrap_err(), err);
        assert_eq!(ssim(a, b).unwrap_err(), err);
        assert!(err.to_string().contains("7x7x3 vs 21x7x1"), "{err}");
        let small = view(6, 24, 1, &d[..144]);
        assert_eq!(ssim(small, small).unwrap_err(), MetricError::TooSmallForSsim { width: 6, height: 24 });
        assert_eq!(psnr(small, small).unwrap(), f64::INFINITY);
    }

    #[test]
    fn rgb_image_converts_checked() {
        let img = RgbImage { width: 8, height: 7, data: image(8, 7, 3, 0.2, 11) };
        let v = ImageRef::try_from(&img).unwrap();
        assert_eq!((v.width(), v.height(), v.channels(), v.data().len()), (8, 7, 3, 168));
        let bad = RgbImage { width: 9, height: 7, data: img.data.clone() };
        assert!(matches!(ImageRef::try_from(&bad), Err(MetricError::DataLength { .. })));
    }
}
