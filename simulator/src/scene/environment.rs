//! Environment light: radiance arriving from infinitely far away.
//!
//! - [`Environment::Constant`]: the same radiance from every direction (Mitsuba `constant`);
//!   sampled uniformly over the sphere.
//! - [`Environment::Map`]: an equirectangular (latitude-longitude) image, `.exr` (first layer
//!   with R, G, B channels, read as f32) or Radiance `.hdr`, times `scale`, rotated by
//!   `to_world` (Mitsuba `envmap`).
//!
//! # Map lookup (exactly Mitsuba's `envmap`)
//! For a world direction `d` pointing away from the scene, take the local direction
//! `l = to_world^-1 d`, then
//! `u = atan2(l.x, -l.z) / 2pi` (wrapped to [0, 1)) and `v = acos(l.y) / pi`.
//! So row 0 is +Y (up), the image centre (u = 0.5, v = 0.5) is +Z, u = 0.25 is +X and
//! u = 0.75 is -X (seen from inside the sphere, looking at +Z with +Y up, +X is on the left:
//! the panorama appears unmirrored). The inverse map is
//! `l = (sin theta sin phi, cos theta, -sin theta cos phi)` with `theta = pi v`, `phi = 2pi u`.
//! Texel centres sit at half-integer positions; the lookup is bilinear with u wrapping around
//! and v clamped at the poles.
//!
//! # Importance sampling
//! A piecewise-constant [`Distribution2D`] over the pixels picks `(u, v)`; the direction's
//! density w.r.t. solid angle is `pdf(u, v) / (2 pi^2 sin theta)` (the Jacobian of the map
//! above, `dw = 2 pi^2 sin theta du dv`). Pixel weights are `sin theta` at the row centre times
//! the **integral of the bilinear reconstruction's luminance over the pixel's area**: per axis a
//! pixel's area sees its own texel with weight 3/4 and each neighbour with 1/8, i.e. a separable
//! [1/8, 3/4, 1/8] blur (u wrapping, v clamped) of the Rec.709 luminance. This keeps the sampled
//! mass proportional to the true mass and, since the bilinear lookup at any point only mixes
//! the 3x3 texels around its pixel, makes the pdf positive wherever the radiance is (so the
//! estimator is unbiased even though lookup is bilinear and sampling piecewise constant).
//! Luminance uses non-negative coefficients, so a coloured texel is never given zero weight.

use std::f32::consts::PI;
use std::path::Path;

use glam::{Mat3, Vec2, Vec3};

use crate::base::sampling::{uniform_sphere, Distribution2D, UNIFORM_SPHERE_PDF};
use crate::error::SceneError;

/// Light from infinitely far away, as a function of direction.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An importance-sampled equirectangular radiance map.
    Map(Box<EnvMap>),
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Constant(Vec3::ZERO)
    }
}

/// A direction sampled towards the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvSample {
    /// Unit world direction towards the environment.
    pub wi: Vec3,
    /// Radiance arriving along `-wi`.
    pub radiance: Vec3,
    /// Density w.r.t. solid angle.
    pub pdf: f32,
}

impl Environment {
    /// Radiance arriving from direction `d` (unit, pointing away from the scene).
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(m) => m.radiance(d),
        }
    }
    /// True when no light comes from the environment.
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
            Environment::Map(m) => m.is_black(),
        }
    }
    /// Sample a direction (importance-sampled for maps, uniform sphere for constants).
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        match self {
            Environment::Constant(c) => {
                Some(EnvSample { wi: uniform_sphere(u), radiance: *c, pdf: UNIFORM_SPHERE_PDF })
            }
            Environment::Map(m) => m.sample(u),
        }
    }
    /// Integral over the sphere of the luminance of the radiance (sr * W/m^2/sr), for light
    /// selection by power.
    pub fn power_integral(&self) -> f32 {
        match self {
            Environment::Constant(c) => 4.0 * std::f32::consts::PI * crate::base::colour::luminance(*c),
            Environment::Map(m) => m.power_integral(),
        }
    }
    /// Density of [`Environment::sample`] for direction `d`, w.r.t. solid angle.
    pub fn pdf(&self, d: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => UNIFORM_SPHERE_PDF,
            Environment::Map(m) => m.pdf(d),
        }
    }
}

/// Load an equirectangular environment map (`.exr` or `.hdr`) as [`Environment::Map`].
/// `scale` multiplies the radiance; `to_world` rotates the map (local -> world).
pub fn load_map(path: &Path, scale: f32, to_world: Mat3) -> Result<Environment, SceneError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let (width, height, texels) = match ext.as_deref() {
        Some("exr") => read_exr(path)?,
        Some("hdr") => read_hdr(path)?,
        _ => {
            return Err(SceneError::unsupported(
                path,
                "environment map",
                "expected an equirectangular .exr or .hdr file",
            ))
        }
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let map = EnvMap::new(&name, width, height, texels, scale, to_world)
        .map_err(|(element, message)| SceneError::invalid(path, element, message))?;
    Ok(Environment::Map(Box::new(map)))
}

/// Read the first RGB(A) layer of an OpenEXR file as f32 RGB.
fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), SceneError> {
    if !path.exists() {
        return Err(SceneError::io(path, std::io::Error::from(std::io::ErrorKind::NotFound)));
    }
    let image = crate::image_io::read_exr_raw(path).map_err(|e| match e {
        exr::error::Error::Io(io) => SceneError::io(path, io),
        e => SceneError::invalid(
            path,
            "environment map",
            format!("cannot read as an RGB OpenEXR image ({e}); the first layer needs R, G and B channels"),
        ),
    })?;
    Ok((image.width, image.height, image.pixels))
}

/// Read a Radiance `.hdr` file as f32 RGB.
fn read_hdr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), SceneError> {
    let reader = image::ImageReader::open(path).map_err(|e| SceneError::io(path, e))?;
    let img = reader
        .with_guessed_format()
        .map_err(|e| SceneError::io(path, e))?
        .decode()
        .map_err(|e| SceneError::invalid(path, "environment map", format!("cannot decode Radiance HDR: {e}")))?;
    let rgb = img.to_rgb32f();
    let (w, h) = rgb.dimensions();
    Ok((w, h, rgb.pixels().map(|p| Vec3::from(p.0)).collect()))
}

/// An equirectangular radiance map with its sampling distribution (see the module doc).
#[derive(Clone, PartialEq)]
pub struct EnvMap {
    /// File name, for messages.
    pub name: String,
    /// Width in pixels (along u, i.e. phi).
    pub width: u32,
    /// Height in pixels (along v, i.e. theta; row 0 is +Y).
    pub height: u32,
    /// Row-major linear RGB radiance texels (before `scale`).
    pub texels: Vec<Vec3>,
    /// Multiplier on the texels.
    pub scale: f32,
    /// Map-local to world rotation.
    pub to_world: Mat3,
    /// Inverse of `to_world`.
    to_local: Mat3,
    /// Pixel distribution over (u, v) in [0,1)^2.
    distribution: Distribution2D,
}

impl std::fmt::Debug for EnvMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvMap")
            .field("name", &self.name)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("scale", &self.scale)
            .field("to_world", &self.to_world)
            .finish_non_exhaustive()
    }
}

/// Rec.709 luminance (non-negative coefficients).
fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

impl EnvMap {
    /// Build a map from row-major texels. On bad input returns `(element, message)` (the
    /// loader adds the file name).
    pub fn new(
        name: &str,
        width: u32,
        height: u32,
        texels: Vec<Vec3>,
        scale: f32,
        to_world: Mat3,
    ) -> Result<EnvMap, (String, String)> {
        if width == 0 || height == 0 || texels.len() != (width * height) as usize {
            return Err(("size".into(), format!("the image is {width}x{height} pixels; it must not be empty")));
        }
        if let Some(i) = texels.iter().position(|t| !t.is_finite() || t.min_element() < 0.0) {
            let (x, y) = (i as u32 % width, i as u32 / width);
            return Err((
                format!("pixel (x {x}, y {y})"),
                format!("radiance {} must be finite and non-negative", texels[i]),
            ));
        }
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(("scale".into(), format!("{scale} must be finite and non-negative")));
        }
        let det = to_world.determinant();
        if !(det.is_finite() && det.abs() > 1e-6) {
            return Err(("to_world".into(), "the rotation must be invertible".into()));
        }
        let (w, h) = (width as usize, height as usize);
        // pixel weight: area integral of the bilinear luminance ([1/8, 3/4, 1/8] per axis)
        let lum: Vec<f32> = texels.iter().map(|&t| luminance(t)).collect();
        const K: [f32; 3] = [0.125, 0.75, 0.125];
        let mut blur_u = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                blur_u[y * w + x] = (0..3).map(|k| K[k] * lum[y * w + (x + w + k - 1) % w]).sum();
            }
        }
        let mut weights = vec![0f32; w * h];
        for y in 0..h {
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            for x in 0..w {
                let blurred: f32 = (0..3).map(|k| K[k] * blur_u[(y + k).saturating_sub(1).min(h - 1) * w + x]).sum();
                weights[y * w + x] = blurred * sin_theta;
            }
        }
        Ok(EnvMap {
            name: name.to_string(),
            width,
            height,
            texels,
            scale,
            to_world,
            to_local: to_world.inverse(),
            distribution: Distribution2D::new(&weights, w, h),
        })
    }

    /// True when the map emits nothing.
    /// Integral of the luminance of the radiance over the sphere (texel sums, `sin theta` weighted).
    pub fn power_integral(&self) -> f32 {
        let (w, h) = (self.width as usize, self.height as usize);
        let d_omega = (std::f64::consts::TAU / w as f64) * (std::f64::consts::PI / h as f64);
        let mut sum = 0.0f64;
        for y in 0..h {
            let sin_theta = (std::f64::consts::PI * (y as f64 + 0.5) / h as f64).sin();
            let row: f64 =
                self.texels[y * w..(y + 1) * w].iter().map(|&t| crate::base::colour::luminance(t) as f64).sum();
            sum += row * sin_theta * d_omega;
        }
        (sum * self.scale as f64) as f32
    }

    /// True when the map adds no light.
    pub fn is_black(&self) -> bool {
        self.scale == 0.0 || self.distribution.marginal.total <= 0.0
    }

    /// (u, v) of a world direction.
    pub fn uv(&self, d: Vec3) -> Vec2 {
        let l = (self.to_local * d).normalize_or_zero();
        let u = l.x.atan2(-l.z) * (0.5 / PI);
        let u = u - u.floor();
        Vec2::new(if u >= 1.0 { 0.0 } else { u }, l.y.clamp(-1.0, 1.0).acos() / PI)
    }

    /// World direction of map coordinates (u, v) (inverse of [`EnvMap::uv`]).
    pub fn direction(&self, uv: Vec2) -> Vec3 {
        let (theta, phi) = (PI * uv.y, 2.0 * PI * uv.x);
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        (self.to_world * Vec3::new(st * sp, ct, -st * cp)).normalize()
    }

    /// Bilinear lookup of the (unscaled) texels at map coordinates `uv`.
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return Vec3::ZERO;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // u wraps around, v clamps at the poles
        let texel = |xi: i64, yi: i64| self.texels[(yi.clamp(0, h - 1) * w + xi.rem_euclid(w)) as usize];
        let top = texel(x0, y0) * (1.0 - fx) + texel(x0 + 1, y0) * fx;
        let bottom = texel(x0, y0 + 1) * (1.0 - fx) + texel(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Radiance arriving from world direction `d` (pointing away from the scene).
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        self.scale * self.lookup(self.uv(d))
    }

    /// Importance-sample a direction: pixel by the 2D distribution, then the Jacobian.
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        let (uv, pdf_uv) = self.distribution.sample(u);
        let sin_theta = (PI * uv.y).sin();
        if pdf_uv <= 0.0 || sin_theta <= 0.0 {
            return None;
        }
        let wi = self.direction(uv);
        // dw = 2 pi^2 sin(theta) du dv
        let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
        Some(EnvSample { wi, radiance: self.scale * self.lookup(uv), pdf })
    }

    /// Density of [`EnvMap::sample`] w.r.t. solid angle for world direction `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        let uv = self.uv(d);
        let sin_theta = (PI * uv.y).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::sampling::Rng;
    use crate::render::chi2::{chi2_test, Chi2Config};

    /// A 64x32 map: a gradient from the top, plus a bright sun blob at (u, v) = (0.3, 0.3).
    fn sun_and_gradient(to_world: Mat3) -> EnvMap {
        let (w, h) = (64u32, 32u32);
        let mut texels = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                let r2 = ((u - 0.3) * w as f32).powi(2) + ((v - 0.3) * h as f32).powi(2);
                let sun = 50.0 * (-r2 / (2.0 * 1.5f32.powi(2))).exp();
                let sky = Vec3::new(0.2, 0.4, 1.0) * (1.0 - v) + Vec3::splat(0.05);
                texels.push(sky + Vec3::new(1.0, 0.9, 0.7) * sun);
            }
        }
        EnvMap::new("sun", w, h, texels, 2.0, to_world).unwrap()
    }

    /// A map whose texel (x, y) holds (x, y, 1), to find where directions land.
    fn index_map() -> EnvMap {
        let (w, h) = (8u32, 4u32);
        let texels = (0..w * h).map(|i| Vec3::new((i % w) as f32, (i / w) as f32, 1.0)).collect();
        EnvMap::new("index", w, h, texels, 1.0, Mat3::IDENTITY).unwrap()
    }

    #[test]
    fn lookup_convention_matches_mitsuba() {
        let m = index_map();
        let near = |a: Vec2, b: Vec2| (a - b).length() < 1e-5;
        // +Z: image centre; +Y: row 0 (v = 0); -Y: v = 1
        assert!(near(m.uv(Vec3::Z), Vec2::new(0.5, 0.5)));
        assert!(m.uv(Vec3::Y).y.abs() < 1e-6 && (m.uv(-Vec3::Y).y - 1.0).abs() < 1e-6);
        // atan2(x, -z): +X -> pi/2 -> u = 0.25, -X -> -pi/2 -> u = 0.75, -Z -> u = 0 (seam)
        assert!(near(m.uv(Vec3::X), Vec2::new(0.25, 0.5)));
        assert!(near(m.uv(-Vec3::X), Vec2::new(0.75, 0.5)));
        assert!(m.uv(-Vec3::Z).x < 1e-6 || m.uv(-Vec3::Z).x > 1.0 - 1e-6);
        // direction() inverts uv()
        let mut r = Rng::new(5, 6);
        for _ in 0..100 {
            let d = uniform_sphere(r.next_2d());
            assert!((m.direction(m.uv(d)) - d).length() < 1e-4);
        }
        // texel centres: +X at u = 0.25 lies between columns 1 and 2 of 8, v = 0.5 between rows 1, 2
        assert!((m.radiance(Vec3::X) - Vec3::new(1.5, 1.5, 1.0)).length() < 1e-5);
        // exactly at a texel centre: column 5 (u = 5.5/8), row 0 (v = 0.5/4) -> (5, 0, 1)
        let d = m.direction(Vec2::new(5.5 / 8.0, 0.5 / 4.0));
        assert!((m.radiance(d) - Vec3::new(5.0, 0.0, 1.0)).length() < 1e-4);
        // near the top pole v clamps to row 0; across the seam u wraps (columns 7 and 0 blend)
        assert!(m.lookup(Vec2::new(5.5 / 8.0, 0.0)).y.abs() < 1e-6);
        assert!((m.lookup(Vec2::new(0.0, 0.5 / 4.0)).x - 3.5).abs() < 1e-5);
    }

    #[test]
    fn rotation_applies_to_lookup_and_sampling() {
        let rot = Mat3::from_rotation_y(0.7) * Mat3::from_rotation_x(0.3);
        let a = sun_and_gradient(Mat3::IDENTITY);
        let b = sun_and_gradient(rot);
        let mut r = Rng::new(1, 1);
        for _ in 0..100 {
            let d = uniform_sphere(r.next_2d());
            assert!((b.radiance(rot * d) - a.radiance(d)).length() < 1e-3 * a.radiance(d).length().max(1.0));
            assert!((b.pdf(rot * d) - a.pdf(d)).abs() < 1e-3 * a.pdf(d).max(1.0));
        }
    }

    #[test]
    fn chi2_sampler_matches_pdf() {
        let rot = Mat3::from_rotation_z(0.4);
        for m in [sun_and_gradient(Mat3::IDENTITY), sun_and_gradient(rot)] {
            let cfg = Chi2Config { substeps: 16, ..Default::default() };
            let r = chi2_test(cfg, |_, u| m.sample(u).map(|s| s.wi), |d| m.pdf(d));
            assert!(r.passed, "{r:?}");
            assert!((r.pdf_integral - 1.0).abs() < 2e-3, "{r:?}");
            // sample() and pdf() agree pointwise, radiance matches the lookup
            let mut rng = Rng::new(3, 3);
            for _ in 0..1000 {
                let s = m.sample(rng.next_2d()).unwrap();
                assert!((m.pdf(s.wi) - s.pdf).abs() < 1e-3 * s.pdf, "{} vs {}", m.pdf(s.wi), s.pdf);
                assert!((m.radiance(s.wi) - s.radiance).length() < 1e-3 * s.radiance.length().max(1e-3));
            }
        }
    }

    #[test]
    fn pdf_positive_wherever_radiance_is() {
        // a single lit texel: its bilinear footprint covers the 3x3 pixels around it
        let (w, h) = (16u32, 8u32);
        let mut texels = vec![Vec3::ZERO; (w * h) as usize];
        texels[(3 * w + 15) as usize] = Vec3::new(0.0, 0.0, 4.0); // pure blue, last column
        let m = EnvMap::new("dot", w, h, texels, 1.0, Mat3::IDENTITY).unwrap();
        let mut r = Rng::new(9, 9);
        let mut lit = 0;
        for _ in 0..20_000 {
            let d = uniform_sphere(r.next_2d());
            if m.radiance(d).max_element() > 0.0 {
                lit += 1;
                assert!(m.pdf(d) > 0.0, "radiance without pdf at {d}");
            }
        }
        assert!(lit > 50);
        assert!(!m.is_black());
    }

    #[test]
    fn importance_sampled_irradiance_matches_quadrature() {
        // E = integral over the hemisphere around n of L(w) (n . w) dw
        let m = sun_and_gradient(Mat3::from_rotation_y(1.0));
        let n = Vec3::new(0.3, 0.8, 0.2).normalize();
        // brute force: midpoint rule in (u, v) with dw = 2 pi^2 sin(theta) du dv
        let (nu, nv) = (1024, 512);
        let mut quad = 0f64;
        for j in 0..nv {
            for i in 0..nu {
                let uv = Vec2::new((i as f32 + 0.5) / nu as f32, (j as f32 + 0.5) / nv as f32);
                let d = m.direction(uv);
                let cos = n.dot(d).max(0.0) as f64;
                let jac = 2.0 * (PI as f64).powi(2) * ((PI * uv.y).sin() as f64) / (nu * nv) as f64;
                quad += luminance(m.radiance(d)) as f64 * cos * jac;
            }
        }
        // Monte Carlo with the importance sampler
        let (mut sum, mut sum2, count) = (0f64, 0f64, 200_000);
        let mut r = Rng::new(11, 12);
        for _ in 0..count {
            let f = match m.sample(r.next_2d()) {
                Some(s) => luminance(s.radiance) as f64 * n.dot(s.wi).max(0.0) as f64 / s.pdf as f64,
                None => 0.0,
            };
            sum += f;
            sum2 += f * f;
        }
        let mean = sum / count as f64;
        let std_err = ((sum2 / count as f64 - mean * mean) / count as f64).sqrt();
        assert!((mean - quad).abs() < 4.0 * std_err + 1e-3 * quad, "MC {mean} +- {std_err}, quadrature {quad}");
        assert!(std_err < 0.02 * quad, "importance sampling should be efficient: {std_err} vs {quad}");
    }

    #[test]
    fn constant_environment_samples_the_sphere() {
        let e = Environment::Constant(Vec3::splat(2.0));
        let r = chi2_test(Chi2Config::default(), |_, u| e.sample(u).map(|s| s.wi), |d| e.pdf(d));
        assert!(r.passed, "{r:?}");
        assert_eq!(e.sample(Vec2::new(0.3, 0.6)).unwrap().radiance, Vec3::splat(2.0));
        assert!(Environment::default().is_black());
    }

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("evblur-env-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn load_map_reads_exr_and_hdr_and_names_errors() {
        let dir = temp_dir("load");
        let exr_path = dir.join("sky.exr");
        exr::prelude::write_rgb_file(&exr_path, 4, 2, |x, y| (x as f32, y as f32, 0.5f32)).unwrap();
        let Environment::Map(m) = load_map(&exr_path, 3.0, Mat3::IDENTITY).unwrap() else { panic!() };
        assert_eq!((m.width, m.height), (4, 2));
        assert_eq!(m.texels[4 + 2], Vec3::new(2.0, 1.0, 0.5));
        assert_eq!(m.scale, 3.0);

        let hdr_path = dir.join("sky.hdr");
        let img = image::Rgb32FImage::from_fn(4, 2, |x, y| image::Rgb([x as f32, y as f32, 0.5]));
        image::DynamicImage::ImageRgb32F(img).save(&hdr_path).unwrap();
        let Environment::Map(m) = load_map(&hdr_path, 1.0, Mat3::IDENTITY).unwrap() else { panic!() };
        assert_eq!((m.width, m.height), (4, 2));
        assert!((m.texels[4 + 2] - Vec3::new(2.0, 1.0, 0.5)).length() < 0.02);

        let e = load_map(&dir.join("none.exr"), 1.0, Mat3::IDENTITY).unwrap_err().to_string();
        assert!(e.contains("none.exr"), "{e}");
        let bad = dir.join("nan.exr");
        exr::prelude::write_rgb_file(&bad, 4, 2, |x, y| {
            (if (x, y) == (3, 1) { f32::NAN } else { 1.0 }, 0.0f32, 0.0f32)
        })
        .unwrap();
        let e = load_map(&bad, 1.0, Mat3::IDENTITY).unwrap_err().to_string();
        assert!(e.contains("nan.exr") && e.contains("pixel (x 3, y 1)"), "{e}");
        let neg = dir.join("neg.exr");
        exr::prelude::write_rgb_file(&neg, 2, 2, |_, _| (-1.0f32, 0.0f32, 0.0f32)).unwrap();
        assert!(load_map(&neg, 1.0, Mat3::IDENTITY).unwrap_err().to_string().contains("non-negative"));
        let e = load_map(&dir.join("sky.png"), 1.0, Mat3::IDENTITY).unwrap_err().to_string();
        assert!(e.contains(".exr or .hdr"), "{e}");
    }
}
