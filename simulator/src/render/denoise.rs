//! An edge-avoiding À-Trous wavelet denoiser guided by first-hit features (the spatial filter
//! of SVGF: Schied et al. 2017, "Spatiotemporal Variance-Guided Filtering"; Dammertz et al. 2010).
//!
//! Why: at a few samples per pixel, path-tracing noise changes from frame to frame as the camera
//! moves, and an event camera sees those changes as contrast: they fire false events. Filtering
//! each frame removes most of that noise while the guides keep what is real:
//! - the filter works on *demodulated* light ([`Features::irradiance`]: reflected light over the
//!   first hits' reflectance, formed per sample by the renderer), so texture is never blurred,
//!   only the lighting, and remodulates it at the end with [`Features::albedo`] (averaged over
//!   more camera rays than are shaded when `feature_spp > spp`);
//! - taps across a depth discontinuity, a crease (normal) or a lighting edge larger than the
//!   local noise (luminance against the pixel's estimated standard deviation) get no weight.
//!
//! The filter is a pure function of its inputs, applied per pixel in parallel: the same image
//! and features give the same bytes whatever the thread count. It is biased (very fine shading
//! detail, such as a contact shadow thinner than the filter's noise scale, is softened);
//! `evsim dataset-noise` reports the events it removes against an unfiltered reference.

use glam::Vec3;
use rayon::prelude::*;

use super::integrator::{Features, MISS_DEPTH};
use crate::base::colour::luminance;
use crate::base::image::Image;

/// The filter's settings (SVGF's defaults).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DenoiseParams {
    /// À-Trous passes; pass `k` spaces its 5x5 taps `2^k` pixels apart (5 = a 125-pixel reach).
    pub iterations: u32,
    /// Luminance edge stop, in estimated standard deviations of the pixel's noise.
    pub sigma_luminance: f32,
    /// Normal edge stop: the exponent of the taps' normal dot product.
    pub sigma_normal: f32,
    /// Depth edge stop, relative to the local depth gradient.
    pub sigma_depth: f32,
}

impl Default for DenoiseParams {
    fn default() -> DenoiseParams {
        DenoiseParams { iterations: 5, sigma_luminance: 4.0, sigma_normal: 128.0, sigma_depth: 1.0 }
    }
}

impl DenoiseParams {
    /// Check the settings: every field finite, iterations 1..=8, sigmas > 0. The error names the
    /// field and its allowed range.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=8).contains(&self.iterations) {
            return Err(format!("iterations = {} must be in 1..=8", self.iterations));
        }
        for (name, v) in [
            ("sigma_luminance", self.sigma_luminance),
            ("sigma_normal", self.sigma_normal),
            ("sigma_depth", self.sigma_depth),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("{name} = {v} must be a positive finite number"));
            }
        }
        Ok(())
    }
}

/// B3-spline weights of the 5 taps along each axis.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Smallest reflectance divided out (darker first hits are demodulated by this).
const MIN_ALBEDO: f32 = 1e-3;

/// Filter `img` guided by `features` (from [`super::integrator::Renderer::render_with_features`]
/// of the same render). Panics if the buffers' sizes differ (a programming error).
pub fn denoise(img: &Image, features: &Features, p: &DenoiseParams) -> Image {
    let (w, h) = (img.width as usize, img.height as usize);
    assert!(
        features.width == img.width && features.height == img.height && features.albedo.len() == w * h,
        "features of a different render"
    );
    let n = w * h;
    // the guides, one plane per number so that a row's taps vectorise
    let guides = Guides::new(features, w, h);
    // only reflected light is filtered: what the camera sees directly (emitters, the sky) is
    // taken out first and added back unfiltered
    let mut irr = Planes::new(n);
    irr.chunks_mut(w)
        .zip(features.irradiance.par_chunks(w))
        .zip(features.variance.par_chunks(w))
        .zip(features.albedo.par_chunks(w))
        .for_each(|(((row, ir), v), a)| {
            for x in 0..ir.len() {
                let (c, a) = (ir[x], a[x].max(Vec3::splat(MIN_ALBEDO)));
                (row.r[x], row.g[x], row.b[x]) = (c.x, c.y, c.z);
                row.var[x] = v[x] / luminance(a).max(MIN_ALBEDO).powi(2);
            }
        });
    let mut next = Planes::new(n);
    let mut lum = vec![0.0f32; n];
    let mut inv_l = vec![0.0f32; n];
    for k in 0..p.iterations {
        let step = 1usize << k;
        // per pixel: luminance, and the luminance stop from the 3x3-blurred variance
        lum.par_chunks_mut(w).zip(inv_l.par_chunks_mut(w)).enumerate().for_each(|(y, (lum_row, inv_row))| {
            let i = y * w;
            let rgb = irr.r[i..i + w].iter().zip(&irr.g[i..i + w]).zip(&irr.b[i..i + w]);
            for (l, ((&r, &g), &b)) in lum_row.iter_mut().zip(rgb) {
                *l = luminance(Vec3::new(r, g, b));
            }
            blur3_row(&irr.var, w, h, y, inv_row);
            for v in inv_row.iter_mut() {
                *v = 1.0 / (p.sigma_luminance * v.max(0.0).sqrt() + 1e-6);
            }
        });
        let (src, lum, inv_l, g) = (&irr, &lum, &inv_l, &guides);
        next.chunks_mut(w).enumerate().for_each(|(y, row)| atrous_row(src, lum, inv_l, g, p, y, step, row));
        std::mem::swap(&mut irr, &mut next);
    }
    let pixels = (0..n)
        .into_par_iter()
        .map(|i| Vec3::new(irr.r[i], irr.g[i], irr.b[i]) * features.albedo[i] + features.emission[i])
        .collect();
    Image { width: img.width, height: img.height, pixels }
}

/// Demodulated light and its variance, one plane per number.
struct Planes {
    r: Vec<f32>,
    g: Vec<f32>,
    b: Vec<f32>,
    var: Vec<f32>,
}

/// One row of [`Planes`], to write.
struct PlanesRow<'a> {
    r: &'a mut [f32],
    g: &'a mut [f32],
    b: &'a mut [f32],
    var: &'a mut [f32],
}

impl Planes {
    fn new(n: usize) -> Planes {
        Planes { r: vec![0.0; n], g: vec![0.0; n], b: vec![0.0; n], var: vec![0.0; n] }
    }

    /// The rows of `w` pixels, in parallel.
    fn chunks_mut(&mut self, w: usize) -> impl IndexedParallelIterator<Item = PlanesRow<'_>> {
        self.r
            .par_chunks_mut(w)
            .zip(self.g.par_chunks_mut(w))
            .zip(self.b.par_chunks_mut(w))
            .zip(self.var.par_chunks_mut(w))
            .map(|(((r, g), b), var)| PlanesRow { r, g, b, var })
    }
}

/// The edge-stopping guides: shading normal, first-hit distance and its gradients.
struct Guides {
    nx: Vec<f32>,
    ny: Vec<f32>,
    nz: Vec<f32>,
    z: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
}

impl Guides {
    fn new(f: &Features, w: usize, h: usize) -> Guides {
        let z = &f.depth;
        // per-pixel |dz/dx| and |dz/dy|: the smaller of the one-sided differences, so that a
        // pixel on a silhouette takes the slope of its own surface, not the jump to the background
        let one_sided = |i: usize, a: Option<usize>, b: Option<usize>| {
            let d = |j: Option<usize>| j.map(|j| (z[j] - z[i]).abs()).unwrap_or(f32::INFINITY);
            let g = d(a).min(d(b));
            if g.is_finite() {
                g
            } else {
                0.0
            }
        };
        let (gx, gy) = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let gx = one_sided(i, (x > 0).then(|| i - 1), (x + 1 < w).then(|| i + 1));
                let gy = one_sided(i, (y > 0).then(|| i - w), (y + 1 < h).then(|| i + w));
                (gx, gy)
            })
            .unzip();
        Guides {
            nx: f.normal.iter().map(|n| n.x).collect(),
            ny: f.normal.iter().map(|n| n.y).collect(),
            nz: f.normal.iter().map(|n| n.z).collect(),
            z: z.clone(),
            gx,
            gy,
        }
    }
}

/// One À-Trous pass over row `y` with taps `step` pixels apart, from `src` into `out`. The 25
/// taps are visited in the same order for every pixel; a tap's pixels are a contiguous run, so
/// the inner loops have no bounds to test and vectorise.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn atrous_row(
    src: &Planes,
    lum: &[f32],
    inv_l: &[f32],
    g: &Guides,
    p: &DenoiseParams,
    y: usize,
    step: usize,
    out: PlanesRow,
) {
    let (w, h) = (out.r.len(), lum.len() / out.r.len());
    let row = y * w;
    let z_floor: Vec<f32> = g.z[row..row + w].iter().map(|z| 1e-3 * z.min(MISS_DEPTH)).collect();
    let mut acc = Acc { r: vec![0.0; w], g: vec![0.0; w], b: vec![0.0; w], v: vec![0.0; w], wsum: vec![0.0; w] };
    for (j, kj) in KERNEL.iter().enumerate() {
        let Some(qy) = offset(y, j, step, h) else { continue };
        let dy = (qy as f32 - y as f32).abs();
        for (i2, ki) in KERNEL.iter().enumerate() {
            let dx = (i2 as isize - 2) * step as isize;
            // the pixels x0..x1 whose tap x + dx lies in the row
            let (x0, x1) = ((-dx).max(0) as usize, (w as isize - dx.max(0)).max(0) as usize);
            if x0 >= x1 {
                continue;
            }
            let (c0, c1) = (row + x0, row + x1);
            let (q0, q1) = (((qy * w + x0) as isize + dx) as usize, ((qy * w + x1) as isize + dx) as usize);
            let tap = Tap { r: &src.r[q0..q1], g: &src.g[q0..q1], b: &src.b[q0..q1], var: &src.var[q0..q1] };
            let acc = acc.range(x0, x1);
            if dx == 0 && qy == y {
                // the centre tap: no edge stops
                acc.add(&tap, |_| ki * kj);
                continue;
            }
            let centre = GuideRun::new(g, lum, c0, c1);
            let other = GuideRun::new(g, lum, q0, q1);
            let stops = Stops {
                kk: ki * kj,
                dx: dx.unsigned_abs() as f32,
                dy,
                inv_l: &inv_l[c0..c1],
                z_floor: &z_floor[x0..x1],
                sigma_depth: p.sigma_depth,
            };
            // below -20 the weight is under 2e-9 of the centre tap's: none
            if p.sigma_normal == 128.0 {
                acc.add(&tap, |k| {
                    let (arg, cos) = stops.at(&centre, &other, k);
                    let weight = stops.kk * pow_128(cos) * fast_exp(arg);
                    if arg < -20.0 {
                        0.0
                    } else {
                        weight
                    }
                });
            } else {
                acc.add(&tap, |k| {
                    let (arg, cos) = stops.at(&centre, &other, k);
                    if arg < -20.0 {
                        0.0
                    } else {
                        stops.kk * cos.max(0.0).powf(p.sigma_normal) * fast_exp(arg)
                    }
                });
            }
        }
    }
    // the centre tap always has weight, so wsum > 0
    for x in 0..w {
        out.r[x] = acc.r[x] / acc.wsum[x];
        out.g[x] = acc.g[x] / acc.wsum[x];
        out.b[x] = acc.b[x] / acc.wsum[x];
        out.var[x] = acc.v[x] / (acc.wsum[x] * acc.wsum[x]);
    }
}

/// The guides of a run of pixels.
struct GuideRun<'a> {
    z: &'a [f32],
    lum: &'a [f32],
    gx: &'a [f32],
    gy: &'a [f32],
    n: [&'a [f32]; 3],
}

impl<'a> GuideRun<'a> {
    fn new(g: &'a Guides, lum: &'a [f32], i0: usize, i1: usize) -> GuideRun<'a> {
        GuideRun {
            z: &g.z[i0..i1],
            lum: &lum[i0..i1],
            gx: &g.gx[i0..i1],
            gy: &g.gy[i0..i1],
            n: [&g.nx[i0..i1], &g.ny[i0..i1], &g.nz[i0..i1]],
        }
    }
}

/// What one tap's edge stops need besides the guides.
struct Stops<'a> {
    /// The tap's kernel weight.
    kk: f32,
    /// The tap's offsets in pixels.
    dx: f32,
    dy: f32,
    /// Per centre pixel: the luminance stop's scale and the depth stop's floor.
    inv_l: &'a [f32],
    z_floor: &'a [f32],
    sigma_depth: f32,
}

impl Stops<'_> {
    /// The `k`-th pixel's exponent of the depth and luminance stops, and the normals' cosine.
    #[inline(always)]
    fn at(&self, c: &GuideRun, q: &GuideRun, k: usize) -> (f32, f32) {
        let dz = (c.z[k] - q.z[k]).abs();
        let reach = self.sigma_depth * (c.gx[k] * self.dx + c.gy[k] * self.dy) + self.z_floor[k];
        let arg = -dz / reach - (c.lum[k] - q.lum[k]).abs() * self.inv_l[k];
        let cos = (c.n[0][k] * q.n[0][k]) + (c.n[1][k] * q.n[1][k]) + (c.n[2][k] * q.n[2][k]);
        (arg, cos)
    }
}

/// One tap's source pixels for a run of centre pixels.
struct Tap<'a> {
    r: &'a [f32],
    g: &'a [f32],
    b: &'a [f32],
    var: &'a [f32],
}

/// A row's weighted sums: light, variance (weights squared) and weights.
struct Acc<T> {
    r: T,
    g: T,
    b: T,
    v: T,
    wsum: T,
}

impl Acc<Vec<f32>> {
    fn range(&mut self, x0: usize, x1: usize) -> Acc<&mut [f32]> {
        Acc {
            r: &mut self.r[x0..x1],
            g: &mut self.g[x0..x1],
            b: &mut self.b[x0..x1],
            v: &mut self.v[x0..x1],
            wsum: &mut self.wsum[x0..x1],
        }
    }
}

impl Acc<&mut [f32]> {
    /// Add `tap` with the weight `weight(k)` for the `k`-th pixel of the run.
    #[inline(always)]
    fn add(self, tap: &Tap, weight: impl Fn(usize) -> f32) {
        let m = self.r.len();
        let (r, g, b, v, wsum) = (self.r, &mut self.g[..m], &mut self.b[..m], &mut self.v[..m], &mut self.wsum[..m]);
        let (tr, tg, tb, tv) = (&tap.r[..m], &tap.g[..m], &tap.b[..m], &tap.var[..m]);
        for k in 0..m {
            let weight = weight(k);
            r[k] += tr[k] * weight;
            g[k] += tg[k] * weight;
            b[k] += tb[k] * weight;
            v[k] += tv[k] * weight * weight;
            wsum[k] += weight;
        }
    }
}

/// Index `c + (tap - 2) * step` if it lies in `0..n`.
#[inline]
fn offset(c: usize, tap: usize, step: usize, n: usize) -> Option<usize> {
    let q = c as i64 + (tap as i64 - 2) * step as i64;
    (q >= 0 && q < n as i64).then_some(q as usize)
}

/// `e^x` for `x` in [-20, 0] to about 1e-4 relative (a weight, not a measurement):
/// `2^(x log2 e)` with the integer part in the exponent bits and a degree-4 polynomial for the
/// fraction. Pure arithmetic, so the same on every machine and thread.
#[inline(always)]
fn fast_exp(x: f32) -> f32 {
    let t = x * std::f32::consts::LOG2_E;
    let fl = t.floor();
    // 2^f = sqrt(2) 2^g with g = f - 1/2 in [-1/2, 1/2): Taylor to degree 4 (error < 2e-5)
    let g = t - fl - 0.5;
    let p = std::f32::consts::SQRT_2
        * (1.0 + g * (std::f32::consts::LN_2 + g * (0.240_226_5 + g * (0.055_504_1 + g * 0.009_618_1))));
    // 2^fl from the exponent bits; `fl + 127 + 2^23` holds the integer `fl + 127` in its low
    // mantissa bits (exact for |fl| < 2^22), which vectorises where a float-to-int cast does not
    let biased = (fl + (127.0 + 8_388_608.0)).to_bits().wrapping_sub(0x4B00_0000);
    f32::from_bits(biased << 23) * p
}

/// `max(0, cos)^128` by seven squarings (the default normal stop) instead of a `powf`.
#[inline(always)]
fn pow_128(cos: f32) -> f32 {
    let mut x = cos.max(0.0);
    for _ in 0..7 {
        x *= x;
    }
    x
}

/// [`blur3_at`] of every pixel of row `y`, into `out` (bit for bit: the same sums in the same
/// order, the interior in vector lanes).
fn blur3_row(v: &[f32], w: usize, h: usize, y: usize, out: &mut [f32]) {
    if w < 3 {
        for (x, o) in out.iter_mut().enumerate() {
            *o = blur3_at(v, w, h, x, y);
        }
        return;
    }
    let row = |r: usize| &v[r * w..(r + 1) * w];
    let (r0, r1, r2) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)));
    let ((a0, b0, c0), (a1, b1, c1), (a2, b2, c2)) = (taps3(r0), taps3(r1), taps3(r2));
    // the weights `ky * kx` of `blur3_at`, products of powers of two (exact)
    let (corner, side, centre) = (0.25f32 * 0.25, 0.25f32 * 0.5, 0.5f32 * 0.5);
    for (x, o) in out[1..w - 1].iter_mut().enumerate() {
        let mut s = 0.0;
        s += corner * a0[x];
        s += side * b0[x];
        s += corner * c0[x];
        s += side * a1[x];
        s += centre * b1[x];
        s += side * c1[x];
        s += corner * a2[x];
        s += side * b2[x];
        s += corner * c2[x];
        *o = s;
    }
    out[0] = blur3_at(v, w, h, 0, y);
    out[w - 1] = blur3_at(v, w, h, w - 1, y);
}

/// A row's left neighbours, centres and right neighbours of its interior (row length >= 2).
fn taps3(r: &[f32]) -> (&[f32], &[f32], &[f32]) {
    let n = r.len();
    (&r[..n - 2], &r[1..n - 1], &r[2..])
}

/// The 3x3 binomial blur (edges clamped) of `v` at pixel (x, y), for a steadier noise estimate.
#[inline]
fn blur3_at(v: &[f32], w: usize, h: usize, x: usize, y: usize) -> f32 {
    const K: [f32; 3] = [0.25, 0.5, 0.25];
    let mut s = 0.0;
    for (dy, ky) in K.iter().enumerate() {
        let yy = (y + dy).saturating_sub(1).min(h - 1);
        for (dx, kx) in K.iter().enumerate() {
            let xx = (x + dx).saturating_sub(1).min(w - 1);
            s += ky * kx * v[yy * w + xx];
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::sampling::Rng;

    /// Features of a flat, camera-facing plane at depth `z` with reflectance `albedo`.
    fn plane(w: u32, h: u32, z: f32, albedo: Vec3, variance: f32) -> Features {
        let n = (w * h) as usize;
        Features {
            width: w,
            height: h,
            albedo: vec![albedo; n],
            normal: vec![Vec3::Z; n],
            depth: vec![z; n],
            variance: vec![variance; n],
            emission: vec![Vec3::ZERO; n],
            irradiance: vec![Vec3::ZERO; n],
            samples: 0,
        }
    }

    /// [`denoise`] with the features' irradiance demodulated from `img` per pixel.
    fn run(img: &Image, f: &Features, p: &DenoiseParams) -> Image {
        let mut f = f.clone();
        f.demodulate(img);
        denoise(img, &f, p)
    }

    /// `irradiance * albedo` plus Gaussian-ish noise of standard deviation `sigma` (relative).
    fn noisy(f: &Features, irradiance: impl Fn(usize) -> f32, sigma: f32, seed: u64) -> Image {
        let mut rng = Rng::new(seed, 7);
        let pixels = (0..f.albedo.len())
            .map(|i| {
                // sum of 4 uniforms: mean 2, variance 1/3
                let g = ((0..4).map(|_| rng.next_f32()).sum::<f32>() - 2.0) * 3f32.sqrt();
                f.albedo[i] * irradiance(i) * (1.0 + sigma * g)
            })
            .collect();
        Image { width: f.width, height: f.height, pixels }
    }

    fn mean_var(v: impl Iterator<Item = f32>) -> (f64, f64) {
        let v: Vec<f64> = v.map(|x| x as f64).collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (m, v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64)
    }

    #[test]
    fn a_noiseless_image_keeps_its_texture_exactly() {
        // a checkerboard reflectance under uniform light: demodulation leaves a constant to filter
        let (w, h) = (40, 30);
        let mut f = plane(w, h, 3.0, Vec3::ONE, 0.0);
        for (i, a) in f.albedo.iter_mut().enumerate() {
            *a = if (i % 40 / 3 + i / 40 / 3) % 2 == 0 { Vec3::new(0.8, 0.2, 0.1) } else { Vec3::splat(0.05) };
        }
        let img = Image { width: w, height: h, pixels: f.albedo.iter().map(|a| *a * 0.7).collect() };
        let out = run(&img, &f, &DenoiseParams::default());
        for (a, b) in img.pixels.iter().zip(&out.pixels) {
            assert!((*a - *b).abs().max_element() < 1e-5, "{a} -> {b}");
        }
    }

    #[test]
    fn noise_on_a_flat_plane_drops_by_more_than_ten_times_and_the_mean_stays() {
        let (w, h) = (64, 48);
        let sigma = 0.3;
        let f = plane(w, h, 2.0, Vec3::splat(0.5), (0.5f32 * sigma).powi(2));
        let img = noisy(&f, |_| 1.0, sigma, 1);
        let out = run(&img, &f, &DenoiseParams::default());
        let (m0, v0) = mean_var(img.pixels.iter().map(|p| p.x));
        let (m1, v1) = mean_var(out.pixels.iter().map(|p| p.x));
        assert!((m1 - m0).abs() < 0.01 * m0, "mean {m0} -> {m1}");
        assert!(v1 * 10.0 < v0, "variance {v0} -> {v1}");
    }

    #[test]
    fn light_does_not_bleed_across_a_depth_edge_or_a_crease() {
        // left half: a near bright plane; right half: a far dark plane (or a plane at 90 degrees)
        let (w, h) = (48, 32);
        for crease in [false, true] {
            let mut f = plane(w, h, 1.0, Vec3::splat(0.5), 0.01 * 0.01);
            for i in 0..(w * h) as usize {
                if i % w as usize >= (w / 2) as usize {
                    if crease {
                        f.normal[i] = Vec3::X;
                    } else {
                        f.depth[i] = 5.0;
                    }
                }
            }
            let right = |i: usize| i % w as usize >= (w / 2) as usize;
            let img = noisy(&f, |i| if right(i) { 0.05 } else { 1.0 }, 0.02, 2);
            let out = run(&img, &f, &DenoiseParams { sigma_luminance: 1e6, ..DenoiseParams::default() });
            // the columns next to the edge keep their own side's level (within the noise)
            for y in 0..h as usize {
                let (l, r) = (y * w as usize + (w / 2 - 1) as usize, y * w as usize + (w / 2) as usize);
                assert!((out.pixels[l].x / 0.5 - 1.0).abs() < 0.05, "crease {crease}: left {}", out.pixels[l]);
                assert!((out.pixels[r].x / 0.5 / 0.05 - 1.0).abs() < 0.05, "crease {crease}: right {}", out.pixels[r]);
            }
        }
    }

    #[test]
    fn a_lighting_edge_larger_than_the_noise_stays_sharp() {
        // one plane, a shadow edge down the middle; only the luminance stop can keep it
        let (w, h) = (48, 32);
        let sigma = 0.05;
        let f = plane(w, h, 2.0, Vec3::ONE, sigma * sigma);
        let right = |i: usize| i % w as usize >= (w / 2) as usize;
        let img = noisy(&f, |i| if right(i) { 0.2 } else { 1.0 }, sigma, 3);
        let out = run(&img, &f, &DenoiseParams::default());
        for y in 0..h as usize {
            let (l, r) = (y * w as usize + (w / 2 - 1) as usize, y * w as usize + (w / 2) as usize);
            assert!(out.pixels[l].x > 0.85 && out.pixels[r].x < 0.3, "row {y}: {} | {}", out.pixels[l], out.pixels[r]);
        }
    }

    #[test]
    fn the_output_does_not_depend_on_the_thread_count() {
        let (w, h) = (37, 23);
        let mut f = plane(w, h, 2.0, Vec3::splat(0.3), 0.02);
        for (i, z) in f.depth.iter_mut().enumerate() {
            *z += (i % 7) as f32 * 0.01;
        }
        let img = noisy(&f, |i| 1.0 + (i % 5) as f32 * 0.1, 0.3, 4);
        let run = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
                .install(|| run(&img, &f, &DenoiseParams::default()))
        };
        assert_eq!(run(1), run(3));
    }

    /// The filter as a plain per-pixel loop over its 25 taps (what [`denoise`] computes, row by
    /// row and plane by plane).
    fn denoise_per_pixel(features: &Features, p: &DenoiseParams) -> Vec<Vec3> {
        let (w, h) = (features.width as usize, features.height as usize);
        let albedo: Vec<Vec3> = features.albedo.iter().map(|a| a.max(Vec3::splat(MIN_ALBEDO))).collect();
        let mut irr = features.irradiance.clone();
        let mut var: Vec<f32> =
            features.variance.iter().zip(&albedo).map(|(v, a)| v / luminance(*a).max(MIN_ALBEDO).powi(2)).collect();
        let g = Guides::new(features, w, h);
        for k in 0..p.iterations {
            let step = 1usize << k;
            let lum: Vec<f32> = irr.iter().map(|c| luminance(*c)).collect();
            let (mut next_irr, mut next_var) = (irr.clone(), var.clone());
            for y in 0..h {
                for x in 0..w {
                    let i = y * w + x;
                    let (zp, np, lp) = (features.depth[i], features.normal[i], lum[i]);
                    let inv_l = 1.0 / (p.sigma_luminance * blur3_at(&var, w, h, x, y).max(0.0).sqrt() + 1e-6);
                    let (mut c, mut v, mut wsum) = (Vec3::ZERO, 0.0f32, 0.0f32);
                    for (j, kj) in KERNEL.iter().enumerate() {
                        let Some(qy) = offset(y, j, step, h) else { continue };
                        let dy = (qy as f32 - y as f32).abs();
                        for (i2, ki) in KERNEL.iter().enumerate() {
                            let Some(qx) = offset(x, i2, step, w) else { continue };
                            let q = qy * w + qx;
                            let weight = if q == i {
                                ki * kj
                            } else {
                                let dx = (qx as f32 - x as f32).abs();
                                let dz = (zp - features.depth[q]).abs();
                                let reach = p.sigma_depth * (g.gx[i] * dx + g.gy[i] * dy) + 1e-3 * zp.min(MISS_DEPTH);
                                let arg = -dz / reach - (lp - lum[q]).abs() * inv_l;
                                if arg < -20.0 {
                                    continue;
                                }
                                let cos = np.dot(features.normal[q]);
                                let nw = if p.sigma_normal == 128.0 {
                                    pow_128(cos)
                                } else {
                                    cos.max(0.0).powf(p.sigma_normal)
                                };
                                ki * kj * nw * fast_exp(arg)
                            };
                            c += irr[q] * weight;
                            v += var[q] * weight * weight;
                            wsum += weight;
                        }
                    }
                    next_irr[i] = c / wsum;
                    next_var[i] = v / (wsum * wsum);
                }
            }
            (irr, var) = (next_irr, next_var);
        }
        irr.iter().zip(&features.emission).zip(&features.albedo).map(|((c, e), a)| *c * *a + *e).collect()
    }

    #[test]
    fn rows_and_planes_give_the_per_pixel_loop_bit_for_bit() {
        // a random scene: depth steps, tilted normals, emitters, texture and noise
        let (w, h) = (45, 29);
        let mut rng = Rng::new(11, 3);
        let mut f = plane(w, h, 2.0, Vec3::splat(0.4), 0.0);
        for i in 0..(w * h) as usize {
            f.depth[i] = if rng.next_f32() < 0.1 { MISS_DEPTH } else { 1.0 + 3.0 * rng.next_f32() };
            f.normal[i] = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 1.0).normalize();
            f.albedo[i] = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.9;
            f.variance[i] = rng.next_f32() * 0.05;
            f.irradiance[i] = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
            if rng.next_f32() < 0.05 {
                f.emission[i] = Vec3::splat(3.0);
            }
        }
        let img = Image { width: w, height: h, pixels: vec![Vec3::ZERO; (w * h) as usize] };
        for p in
            [DenoiseParams::default(), DenoiseParams { sigma_normal: 60.0, iterations: 3, ..DenoiseParams::default() }]
        {
            let fast = denoise(&img, &f, &p).pixels;
            let slow = denoise_per_pixel(&f, &p);
            for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
                assert!(a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits), "pixel {i}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn blur3_row_is_blur3_at_bit_for_bit_at_every_size() {
        let mut rng = Rng::new(5, 1);
        for (w, h) in [(1, 1), (2, 1), (1, 3), (3, 2), (4, 4), (17, 5)] {
            let v: Vec<f32> = (0..w * h).map(|_| rng.next_f32() * 3.0 - 0.5).collect();
            for y in 0..h {
                let mut row = vec![f32::NAN; w];
                blur3_row(&v, w, h, y, &mut row);
                for (x, r) in row.iter().enumerate() {
                    assert_eq!(r.to_bits(), blur3_at(&v, w, h, x, y).to_bits(), "{w}x{h} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn fast_exp_matches_exp_on_the_weights_range() {
        for i in 0..=20_000 {
            let x = -20.0 * i as f32 / 20_000.0;
            let (a, b) = (fast_exp(x), x.exp());
            assert!(((a - b) / b).abs() < 2e-4, "x = {x}: {a} vs {b}");
        }
    }

    #[test]
    fn fast_exp_exponent_bits_equal_an_integer_cast_on_the_weights_range() {
        for i in 0..=20_000 {
            let x = -20.0 * i as f32 / 20_000.0;
            let fl = (x * std::f32::consts::LOG2_E).floor();
            let cast = f32::from_bits(((fl as i32 + 127) as u32) << 23);
            let g = x * std::f32::consts::LOG2_E - fl - 0.5;
            let p = std::f32::consts::SQRT_2
                * (1.0 + g * (std::f32::consts::LN_2 + g * (0.240_226_5 + g * (0.055_504_1 + g * 0.009_618_1))));
            assert_eq!(fast_exp(x).to_bits(), (cast * p).to_bits(), "x = {x}");
        }
    }

    #[test]
    fn bad_settings_name_the_field() {
        let ok = DenoiseParams::default();
        assert!(ok.validate().is_ok());
        let e = DenoiseParams { iterations: 0, ..ok }.validate().unwrap_err();
        assert!(e.contains("iterations"), "{e}");
        let e = DenoiseParams { sigma_depth: f32::NAN, ..ok }.validate().unwrap_err();
        assert!(e.contains("sigma_depth"), "{e}");
        let e = DenoiseParams { sigma_luminance: -1.0, ..ok }.validate().unwrap_err();
        assert!(e.contains("sigma_luminance"), "{e}");
    }
}
