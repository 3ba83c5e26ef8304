//! The pixel loop's parts: a pixel's samples and their sums (colour and first-hit features),
//! adaptive samples per pixel, and the feature buffers of the denoiser.

use super::*;

impl Renderer<'_> {
    /// The colour of pixel (`x`, `y`): the mean of its `spp` traced samples.
    pub(super) fn pixel_color(&self, s: &RenderSettings, x: u32, y: u32, cache: Option<&RadianceCache>) -> Vec3 {
        let (shade, feats) = self.pixel_sums(s, x, y, 0, None, cache);
        finish_pixel(&shade, &feats).0
    }

    /// The sums a pixel's colour and first-hit features are finished from ([`finish_pixel`]):
    /// its first `spp` camera rays shaded and all `max(spp, feature_spp)` rays' first hits; with
    /// `vis`, the rays' first triangles come from it (see [`Renderer::camera_hit`]).
    pub(super) fn pixel_sums(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        feature_spp: u32,
        vis: Option<&Visibility>,
        cache: Option<&RadianceCache>,
    ) -> (ShadeSums, FirstHitSums) {
        let key = pixel_key(s.seed, y as u64 * s.width as u64 + x as u64, s.frame);
        let film_rays = s.camera.film_rays(s.width, s.height);
        let mut shade = ShadeSums::default();
        let mut feats = FirstHitSums::default();
        self.shade_samples(s, x, y, 0..s.spp, vis, cache, key, &film_rays, &mut shade, Some(&mut feats));
        // the camera rays that only see the first hit
        self.first_hit_rays(s, x, y, s.spp..s.spp.max(feature_spp), vis, &film_rays, key, &mut feats);
        (shade, feats)
    }

    /// Shade camera samples `samples` of pixel (`x`, `y`) into `shade`, adding their first hits
    /// to `feats` when given (not for samples whose first hits are already in them: adaptive
    /// samples shade rays that were first-hit-only rays).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn shade_samples(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        samples: std::ops::Range<u32>,
        vis: Option<&Visibility>,
        cache: Option<&RadianceCache>,
        key: u64,
        film_rays: &FilmRays,
        shade: &mut ShadeSums,
        mut feats: Option<&mut FirstHitSums>,
    ) {
        let origin = s.camera.origin();
        for i in samples {
            let mut rng = SampleStream::new(s.sampler, key, i);
            // the film offset: from the visibility buffer when it holds this sample
            let c = match vis.filter(|v| i < v.samples) {
                Some(v) => {
                    rng.skip_4d();
                    v.offset(x, y, i)
                }
                None => {
                    let c = rng.next_4d();
                    Vec2::new(c[0], c[1])
                }
            };
            let film = Vec2::new(x as f32 + c.x, y as f32 + c.y);
            let dir = film_rays.direction(film);
            let mut first = FirstHit::new(-dir);
            let spread = self.camera_spread(s, film);
            let hit = self.camera_hit(vis.filter(|v| i < v.samples).map(|v| v.prim(x, y, i)), origin, dir);
            let l =
                self.li_first(origin, dir, s, &mut rng, &mut first, spread, Some(hit), cache, PathMode::camera(cache));
            shade.attempted += 1;
            if let Some(f) = feats.as_deref_mut() {
                f.albedo += first.albedo;
                f.normal += first.normal;
                f.depth += first.depth;
            }
            // a non-finite sample would poison the pixel: drop it (counts as black)
            if !l.is_finite() {
                if let Some(f) = feats.as_deref_mut() {
                    f.dropped += 1;
                }
                continue;
            }
            shade.add(l, &first);
            if let Some(f) = feats.as_deref_mut() {
                f.emission += first.emission;
                f.rays += 1;
            }
        }
    }
}

/// Depth recorded for camera rays that escape (far beyond any scene; world units).
pub const MISS_DEPTH: f32 = 1e6;

/// What a camera ray hit first.
pub(super) struct FirstHit {
    /// Reflectance hint of the surface ([`Bsdf::albedo_hint`]); 0 for escaped rays (and at
    /// `max_depth` 1, where nothing is reflected).
    pub(super) albedo: Vec3,
    /// Shading normal facing the camera; `-dir` for escaped rays.
    pub(super) normal: Vec3,
    /// Distance along the ray ([`MISS_DEPTH`] for escaped rays).
    pub(super) depth: f32,
    /// Radiance the camera ray sees directly: the hit's emission or, escaped, the environment.
    pub(super) emission: Vec3,
}

impl FirstHit {
    /// Nothing hit yet; `normal` is the one recorded if the ray escapes.
    pub(super) fn new(normal: Vec3) -> FirstHit {
        FirstHit { albedo: Vec3::ZERO, normal, depth: MISS_DEPTH, emission: Vec3::ZERO }
    }
}

/// One pixel's features: the means over its samples.
#[derive(Debug)]
pub(super) struct PixelFeatures {
    pub(super) albedo: Vec3,
    pub(super) normal: Vec3,
    pub(super) depth: f32,
    pub(super) variance: f32,
    pub(super) emission: Vec3,
    pub(super) irradiance: Vec3,
}

/// Running sums over one pixel's shaded samples: radiance, reflected light (radiance minus
/// what the camera ray sees directly), the first-hit reflectance of the same samples, and the
/// moments of their luminances (for the variance of the ratio estimate).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ShadeSums {
    pub(super) sum: Vec3,
    pub(super) reflected: Vec3,
    pub(super) refl_albedo: Vec3,
    pub(super) r1: f64,
    pub(super) r2: f64,
    pub(super) a1: f64,
    pub(super) a2: f64,
    pub(super) ra: f64,
    /// Samples with a finite value.
    pub(super) shaded: u32,
    /// Samples shot (the image is their mean; non-finite ones count as black).
    pub(super) attempted: u32,
}

impl ShadeSums {
    /// Add a finite sample `l` whose camera ray hit `first`.
    #[inline]
    pub(super) fn add(&mut self, l: Vec3, first: &FirstHit) {
        self.sum += l;
        let refl = (l - first.emission).max(Vec3::ZERO);
        self.reflected += refl;
        self.refl_albedo += first.albedo;
        let (r, a) = (luminance(refl) as f64, luminance(first.albedo) as f64);
        (self.r1, self.r2, self.a1, self.a2, self.ra) =
            (self.r1 + r, self.r2 + r * r, self.a1 + a, self.a2 + a * a, self.ra + r * a);
        self.shaded += 1;
    }

    /// The reflected light per unit reflectance (luminance) and the variance of one sample's
    /// estimate of it: the ratio estimate's residual variance over the squared mean reflectance
    /// (delta method); None below 2 samples.
    pub(super) fn ratio_and_sample_variance(&self) -> Option<(f64, f64)> {
        let m = self.shaded as f64;
        if self.shaded < 2 {
            return None;
        }
        let e = self.r1 / self.a1.max(MIN_REFLECTANCE as f64 * m);
        let resid2 = (self.r2 - 2.0 * e * self.ra + e * e * self.a2).max(0.0);
        let a_mean = (self.a1 / m).max(MIN_REFLECTANCE as f64);
        Some((e, resid2 / (m - 1.0) / (a_mean * a_mean)))
    }
}

/// Adaptive sampling: the shaded samples each pixel gets in all (`spp..=spp_max`), from the
/// first `spp`: enough for the relative variance of its reflected light's estimate to reach
/// `adaptive_target`, judged by the per-sample relative variance averaged over the pixel's
/// 3x3 neighbourhood (a few samples per pixel are too few to judge one pixel by).
pub(super) fn adaptive_spp(sums: &[(ShadeSums, FirstHitSums)], w: u32, h: u32, s: &RenderSettings) -> Vec<u32> {
    let rel: Vec<f32> = sums
        .par_iter()
        .map(|(shade, _)| match shade.ratio_and_sample_variance() {
            Some((e, v)) if e > 0.0 => (v / (e * e)) as f32,
            _ => 0.0,
        })
        .collect();
    let (w, h) = (w as usize, h as usize);
    let t = s.adaptive_variance;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (mut sum, mut n) = (0.0f32, 0u32);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    sum += rel[yy * w + xx];
                    n += 1;
                }
            }
            let want = (sum / n as f32 / t).ceil();
            if want.is_finite() {
                (want as u32).clamp(s.spp, s.spp_max)
            } else {
                s.spp_max
            }
        })
        .collect()
}

/// A pixel's colour and features from its sums (see [`Renderer::pixel_sums`]).
pub(super) fn finish_pixel(shade: &ShadeSums, feats: &FirstHitSums) -> (Vec3, PixelFeatures) {
    let n = shade.attempted.max(1) as f32;
    let rays = (feats.rays + feats.dropped).max(1) as f32;
    let albedo = feats.albedo / rays;
    // reflected light per unit reflectance: a ratio over the same samples, so that texture
    // detail inside the pixel (which samples happened to land on) cancels out
    let irradiance = shade.reflected / shade.refl_albedo.max(Vec3::splat(MIN_REFLECTANCE));
    // variance of the pixel's reflected light `albedo * irradiance`: the ratio estimate's
    // (delta method) variance, scaled by the reflectance luminance
    let m = shade.shaded.max(1) as f64;
    let e = luminance(irradiance) as f64;
    let resid2 = (shade.r2 - 2.0 * e * shade.ra + e * e * shade.a2).max(0.0);
    let a_mean = (shade.a1 / m).max(MIN_REFLECTANCE as f64);
    let la = luminance(albedo) as f64;
    let variance = if shade.shaded > 1 { (resid2 / (m - 1.0) / m / (a_mean * a_mean) * la * la) as f32 } else { 0.0 };
    let features = PixelFeatures {
        albedo,
        normal: feats.normal.try_normalize().unwrap_or(Vec3::Z),
        depth: feats.depth / rays,
        variance,
        emission: feats.emission / feats.rays.max(1) as f32,
        irradiance,
    };
    (shade.sum / n, features)
}

/// Per-pixel first-hit buffers of one render (row-major like [`Image`]), the guides of
/// [`crate::render::denoise`].
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Mean reflectance hint of the first hits (0 where rays escaped).
    pub albedo: Vec<Vec3>,
    /// Normalised mean shading normal of the first hits.
    pub normal: Vec<Vec3>,
    /// Mean first-hit distance ([`MISS_DEPTH`] for escaped rays).
    pub depth: Vec<f32>,
    /// Variance of the luminance of the pixel's reflected light `albedo * irradiance` (its
    /// sampling error over the `spp` shaded samples).
    pub variance: Vec<f32>,
    /// Mean radiance the camera rays see directly (emitters, the environment): not reflected
    /// light, so the filters leave it alone (a lamp's pixels must not bleed into the ceiling).
    pub emission: Vec<Vec3>,
    /// Reflected light per unit reflectance (demodulated): the shaded samples' radiance minus
    /// their directly seen emission, summed, over the sum of their reflectances. The filters
    /// smooth this and multiply it back by `albedo`; texture detail within a pixel does not
    /// enter it.
    pub irradiance: Vec<Vec3>,
    /// Shaded samples of the render, all pixels together (with adaptive sampling, more than
    /// `spp` per pixel; 0 where unknown).
    pub samples: u64,
}

impl Features {
    /// Empty buffers (albedo 1, normal +z, depth 0, variance 0, no emission, irradiance 0).
    pub fn new(width: u32, height: u32) -> Features {
        let n = (width * height) as usize;
        Features {
            width,
            height,
            albedo: vec![Vec3::ONE; n],
            normal: vec![Vec3::Z; n],
            depth: vec![0.0; n],
            variance: vec![0.0; n],
            emission: vec![Vec3::ZERO; n],
            irradiance: vec![Vec3::ZERO; n],
            samples: 0,
        }
    }

    /// Set `irradiance` from an image as `(pixel - emission) / albedo` per pixel (for images
    /// made without the renderer's per-sample buffers, such as test images).
    pub fn demodulate(&mut self, img: &Image) {
        for (i, c) in img.pixels.iter().enumerate() {
            self.irradiance[i] =
                (*c - self.emission[i]).max(Vec3::ZERO) / self.albedo[i].max(Vec3::splat(MIN_REFLECTANCE));
        }
    }
}
