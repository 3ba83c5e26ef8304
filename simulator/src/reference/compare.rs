//! Image comparison statistics for reference checks.
//!
//! - relative MSE: `relMSE = mean_{pixels, channels} (x - gt)^2 / (gt^2 + 1e-2)`;
//! - tile z-scores: for each `tile x tile` block and channel, with `d = x - gt` per pixel,
//!   `z = mean(d) / (std(d) / sqrt(n))`. Unbiased estimators give |z| of order 1; a bias shows as
//!   large |z| in the tiles where it lives. The standard error is floored at
//!   `1e-5 * mean(|gt|) + 1e-9` of the tile: in noiseless regions (a constant background both
//!   renderers see directly) the two differ only by float rounding (~1e-7 relative), which is no
//!   bias, while a real noiseless difference (>= 1e-3 relative) still scores |z| >= 100.

use crate::base::image::Image;

/// Relative mean squared error of `x` against `gt` (same size), averaged over pixels and channels.
pub fn rel_mse(x: &Image, gt: &Image) -> f64 {
    assert_eq!((x.width, x.height), (gt.width, gt.height), "images differ in size");
    let mut sum = 0.0f64;
    for (a, b) in x.pixels.iter().zip(&gt.pixels) {
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            sum += (a - b) * (a - b) / (b * b + 1e-2);
        }
    }
    sum / (3 * x.pixels.len()).max(1) as f64
}

/// The z-score of one tile and channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileZ {
    /// Tile column (in tiles).
    pub tx: u32,
    /// Tile row (in tiles).
    pub ty: u32,
    /// Channel 0 = R, 1 = G, 2 = B.
    pub channel: usize,
    /// `mean(d) / (std(d) / sqrt(n))`.
    pub z: f64,
}

/// Tile z-scores of `x - gt` over `tile x tile` blocks (edge tiles may be smaller).
pub fn tile_z(x: &Image, gt: &Image, tile: u32) -> Vec<TileZ> {
    assert_eq!((x.width, x.height), (gt.width, gt.height), "images differ in size");
    let mut out = Vec::new();
    for ty in 0..x.height.div_ceil(tile) {
        for tx in 0..x.width.div_ceil(tile) {
            for channel in 0..3 {
                let (mut n, mut sum, mut sum2, mut gt_abs) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
                for y in ty * tile..((ty + 1) * tile).min(x.height) {
                    for px in tx * tile..((tx + 1) * tile).min(x.width) {
                        let d = (x.get(px, y)[channel] - gt.get(px, y)[channel]) as f64;
                        n += 1.0;
                        sum += d;
                        sum2 += d * d;
                        gt_abs += (gt.get(px, y)[channel] as f64).abs();
                    }
                }
                let mean = sum / n;
                // sample standard deviation (n - 1); a single pixel has no spread estimate
                let var = if n > 1.0 { ((sum2 - n * mean * mean) / (n - 1.0)).max(0.0) } else { 0.0 };
                let se = (var / n).sqrt().max(1e-5 * gt_abs / n + 1e-9);
                let z = mean / se;
                out.push(TileZ { tx, ty, channel, z });
            }
        }
    }
    out
}

/// Largest |z| of a set of tile scores (0 for none).
pub fn max_abs_z(zs: &[TileZ]) -> f64 {
    zs.iter().map(|t| t.z.abs()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A smooth image plus deterministic pseudo-random noise of amplitude `noise`, offset by `bias`.
    fn image(w: u32, h: u32, noise: f32, bias: f32, seed: u64) -> Image {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let mut rnd = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) - 0.5
        };
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let base = Vec3::new(x as f32 / w as f32, y as f32 / h as f32, 0.5);
                img.pixels[(y * w + x) as usize] = base + Vec3::new(rnd(), rnd(), rnd()) * noise + Vec3::splat(bias);
            }
        }
        img
    }

    #[test]
    fn identical_images_have_zero_error_and_z() {
        let a = image(60, 40, 0.1, 0.0, 1);
        assert_eq!(rel_mse(&a, &a), 0.0);
        let zs = tile_z(&a, &a, 20);
        assert_eq!(zs.len(), 3 * 2 * 3);
        assert_eq!(max_abs_z(&zs), 0.0);
    }

    #[test]
    fn unbiased_noise_has_small_z_and_bias_has_large_z() {
        let gt = image(100, 60, 0.0, 0.0, 0);
        let noisy = image(100, 60, 0.2, 0.0, 7);
        let biased = image(100, 60, 0.2, 0.05, 7);
        assert!(max_abs_z(&tile_z(&noisy, &gt, 20)) < 4.5);
        // bias 0.05 against a standard error of 0.2 / sqrt(12) / 20 = 0.003: z of about 17
        assert!(max_abs_z(&tile_z(&biased, &gt, 20)) > 10.0);
        assert!(rel_mse(&biased, &gt) > rel_mse(&noisy, &gt));
    }

    #[test]
    fn noiseless_difference_is_a_large_z_but_rounding_is_not() {
        let gt = image(20, 20, 0.0, 0.0, 0);
        let off = image(20, 20, 0.0, 0.01, 0);
        assert!(max_abs_z(&tile_z(&off, &gt, 20)) > 100.0);
        let rounding = image(20, 20, 0.0, 1e-7, 0);
        assert!(max_abs_z(&tile_z(&rounding, &gt, 20)) < 1.0);
        // relMSE by hand for a constant offset: mean of 1e-4 / (gt^2 + 1e-2)
        let want: f64 = gt
            .pixels
            .iter()
            .flat_map(|p| p.to_array())
            .map(|g| {
                let off = ((g + 0.01) - g) as f64; // the f32 round trip, as in the image
                off * off / ((g as f64).powi(2) + 1e-2)
            })
            .sum::<f64>()
            / (3.0 * 400.0);
        assert!((rel_mse(&off, &gt) - want).abs() < 1e-12);
    }
}
