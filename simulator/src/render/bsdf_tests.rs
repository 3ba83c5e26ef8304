//! Tests of `bsdf.rs`.

use super::*;
use crate::base::sampling::{uniform_sphere, Frame, Rng};
use crate::render::chi2::{chi2_test, Chi2Config, Chi2Result};

/// (name, bsdf) for every material of the grid.
fn materials() -> Vec<(&'static str, Bsdf)> {
    let base = Vec3::new(0.8, 0.6, 0.3);
    let mut v = vec![("lambert s=0 m=0", Bsdf::new(base, 0.0, 0.0, 0.7))];
    for (name, r) in [("dielectric r=0.1", 0.1), ("dielectric r=0.5", 0.5), ("dielectric r=1.0", 1.0)] {
        v.push((name, Bsdf::new(base, 0.0, 1.0, r)));
    }
    for (name, r) in [("metal r=0.05", 0.05), ("metal r=0.2", 0.2), ("metal r=0.6", 0.6), ("metal r=1.0", 1.0)] {
        v.push((name, Bsdf::new(Vec3::new(0.95, 0.64, 0.54), 1.0, 1.0, r)));
    }
    v.push(("half-metal r=0.4", Bsdf::new(base, 0.5, 1.0, 0.4)));
    v
}

const THETA_DEG: [f32; 4] = [0.0, 30.0, 60.0, 85.0];

fn wo_at(theta_deg: f32) -> Vec3 {
    // a non-zero azimuth so the test is not aligned with the bins
    let (t, phi) = (theta_deg.to_radians(), 0.7f32);
    Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos())
}

/// A bijection of the sphere that magnifies the neighbourhood of the pole `r` (the mirror
/// direction), so that the chi-square bins and its midpoint-rule pdf integration resolve
/// lobes a fraction of a degree wide. In a frame with `r` as +Z, with `t = 1 - cos(theta)`,
/// `t' = 2 ln(1 + t/c) / ln(1 + 2/c)` and phi unchanged. Solid angle is `dt dphi`, so the
/// warped density is `pdf * dt/dt' = pdf * ln(1 + 2/c) (t + c) / 2`.
struct PoleWarp {
    frame: Frame,
    c: f32,
    log_span: f32,
}

impl PoleWarp {
    fn new(r: Vec3, c: f32) -> PoleWarp {
        PoleWarp { frame: Frame::from_normal(r), c, log_span: (1.0 + 2.0 / c).ln() }
    }
    /// `t = 1 - cos` and `sin` of a unit vector about +Z, without cancellation near the pole.
    fn t_sin(v: Vec3) -> (f32, f32) {
        let sin2 = (v.x * v.x + v.y * v.y).min(1.0);
        let t = if v.z >= 0.0 { sin2 / (1.0 + v.z) } else { 1.0 - v.z };
        (t, sin2.sqrt())
    }
    /// The unit vector with the given `t` and the azimuth of `like`.
    fn with_t(like: Vec3, t: f32) -> Vec3 {
        let (_, s_old) = Self::t_sin(like);
        let s_new = (t * (2.0 - t)).max(0.0).sqrt();
        let (cx, cy) = if s_old > 0.0 { (like.x / s_old, like.y / s_old) } else { (1.0, 0.0) };
        Vec3::new(cx * s_new, cy * s_new, 1.0 - t)
    }
    fn forward(&self, wi: Vec3) -> Vec3 {
        let v = self.frame.to_local(wi);
        let (t, _) = Self::t_sin(v);
        let tw = 2.0 * (t / self.c).ln_1p() / self.log_span;
        Self::with_t(v, tw.min(2.0))
    }
    /// Inverse map and the Jacobian factor dt/dt'.
    fn inverse(&self, d: Vec3) -> (Vec3, f32) {
        let (tw, _) = Self::t_sin(d);
        let t = (self.c * (0.5 * tw * self.log_span).exp_m1()).min(2.0);
        let v = Self::with_t(d, t);
        (self.frame.to_world(v), 0.5 * self.log_span * (t + self.c))
    }
}

/// Chi-square of `sample` against `pdf` for one material and `wo`. Sharp lobes
/// (alpha < 0.05, a fraction of a degree to a few degrees wide) are too narrow for the
/// test's bins and midpoint-rule pdf integration, so they are tested on the half vector
/// instead: `h = normalize(wo + wi)` is a bijection from the sphere (minus `-wo`) onto
/// `{h : wo.h > 0}` with `dw_i / dw_h = 4 wo.h`, under which every lobe peaks at `h = +Z`
/// and stays round (in `wi` it is squeezed by `cos(theta_o)` at grazing `wo`); a
/// [`PoleWarp`] with `c = alpha^2` then spreads it over the bins.
fn chi2_case(b: &Bsdf, wo: Vec3, alpha: f64, seed: u64) -> (Chi2Result, bool) {
    let cfg = Chi2Config { n_samples: 300_000, alpha, seed, ..Chi2Config::default() };
    if b.alpha >= 0.05 {
        let r = chi2_test(cfg, |ul, u| b.sample(wo, ul, u).map(|s| s.wi), |d| b.pdf(wo, d));
        return (r, false);
    }
    let warp = PoleWarp::new(Vec3::Z, b.alpha * b.alpha);
    let cfg = Chi2Config { substeps: 12, ..cfg };
    let r = chi2_test(
        cfg,
        |ul, u| b.sample(wo, ul, u).map(|s| warp.forward((wo + s.wi).normalize())),
        |d| {
            let (h, jac) = warp.inverse(d);
            let wo_h = wo.dot(h);
            if wo_h <= 0.0 {
                return 0.0;
            }
            // density of h = density of wi = reflect(wo, h) times dw_i / dw_h = 4 wo.h
            let wi = 2.0 * wo_h * h - wo;
            b.pdf(wo, wi) * 4.0 * wo_h * jac
        },
    );
    (r, true)
}

/// `eval_affine` is `eval` split by the base colour: equal for random lobes and directions,
/// whatever the colour (f64 is not needed: both sides are the same f32 formula regrouped).
#[test]
fn eval_affine_matches_eval() {
    let mut rng = crate::render::sampler::SampleStream::new(crate::render::sampler::SamplerKind::Independent, 7, 0);
    let mut worst: f32 = 0.0;
    for _ in 0..20000 {
        let a = rng.next_4d();
        let b = rng.next_4d();
        let c = rng.next_4d();
        let dir = |u: f32, v: f32| {
            let z = 2.0 * u - 1.0;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * std::f32::consts::PI * v;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        let (wo, wi) = (dir(a[0], a[1]), dir(a[2], a[3]));
        let metallic = if b[3] < 0.3 {
            0.0
        } else if b[3] < 0.5 {
            1.0
        } else {
            b[0]
        };
        let bsdf = Bsdf::new(Vec3::new(c[0], c[1], c[2]), metallic, b[1], b[2]);
        let (p, q) = bsdf.eval_affine(wo, wi);
        let f = bsdf.eval(wo, wi);
        let g = bsdf.base_color * p + Vec3::splat(q);
        let err = (f - g).abs().max_element() / f.max_element().max(1e-3);
        worst = worst.max(err);
    }
    assert!(worst < 1e-4, "eval_affine differs from eval by {worst} (relative)");
}

#[test]
fn pole_warp_round_trips() {
    let warp = PoleWarp::new(wo_at(60.0) * Vec3::new(-1.0, -1.0, 1.0), 1e-5);
    let mut rng = Rng::new(5, 6);
    for _ in 0..1000 {
        let v = uniform_sphere(rng.next_2d());
        let (back, jac) = warp.inverse(warp.forward(v));
        assert!((back - v).length() < 1e-3 && jac > 0.0, "{v} -> {back}");
    }
}

const SEED_BASE: u64 = 100;

#[test]
fn chi2_sampling_matches_pdf() {
    let cases: Vec<(&str, Bsdf, f32)> =
        materials().into_iter().flat_map(|(n, b)| THETA_DEG.iter().map(move |&t| (n, b, t))).collect();
    // Bonferroni: the configured significance shared over all cases
    let alpha = Chi2Config::default().alpha / cases.len() as f64;
    let mut failures = Vec::new();
    let (mut p_min, mut p_max) = (1.0f64, 0.0f64);
    for (i, (name, b, theta)) in cases.iter().enumerate() {
        let wo = wo_at(*theta);
        // an independent sample stream per case
        let (r, warped) = chi2_case(b, wo, alpha, SEED_BASE + i as u64);
        eprintln!(
            "{name:>20} theta={theta:>4} warped={warped:>5} p={:.4} dof={} int-acc={:+.5}",
            r.p_value,
            r.dof,
            r.pdf_integral - r.accepted
        );
        p_min = p_min.min(r.p_value);
        p_max = p_max.max(r.p_value);
        let integral_ok = (r.pdf_integral - r.accepted).abs() < 5e-3;
        if !r.passed || !integral_ok {
            failures.push(format!("{name} theta={theta} warped={warped}: {r:?}"));
        }
        // a white GGX at alpha = 1 and normal incidence reflects exactly half of its samples
        // below the horizon; no case of the grid loses more
        assert!(r.accepted > 0.49, "{name} theta={theta}: {r:?}");
    }
    eprintln!("chi2 p-values over {} cases: min {p_min:.3e}, max {p_max:.3}", cases.len());
    assert!(failures.is_empty(), "chi-square failures:\n{}", failures.join("\n"));
}

#[test]
fn chi2_rejects_a_wrong_pdf() {
    // the test must have power: a pdf that ignores the lobe mixture (specular only) fails
    let b = Bsdf::new(Vec3::splat(0.8), 0.0, 1.0, 0.5);
    let wo = wo_at(30.0);
    let cfg = Chi2Config { n_samples: 300_000, ..Chi2Config::default() };
    let wrong = Bsdf { base_color: Vec3::ZERO, ..b };
    let r = chi2_test(cfg, |ul, u| b.sample(wo, ul, u).map(|s| s.wi), |d| wrong.pdf(wo, d));
    assert!(!r.passed, "{r:?}");
}

#[test]
fn sample_weight_and_pdf_agree_with_eval_and_pdf() {
    let mut rng = Rng::new(11, 12);
    for (name, b) in materials() {
        for theta in THETA_DEG {
            let wo = wo_at(theta);
            let mut n = 0;
            for _ in 0..2000 {
                let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) else { continue };
                n += 1;
                assert!(s.wi.z > 0.0 && (s.wi.length() - 1.0).abs() < 1e-4, "{name}: {s:?}");
                let pdf = b.pdf(wo, s.wi);
                let f = b.eval(wo, s.wi);
                // eval is eval_and_pdf's value, bit for bit
                assert_eq!((f, pdf), b.eval_and_pdf(wo, s.wi), "{name} theta={theta}");
                assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "{name} theta={theta}: pdf {pdf} vs {s:?}");
                let w = f / pdf;
                let tol = 1e-3 * w.max_element().max(1e-6);
                assert!((w - s.weight).abs().max_element() <= tol, "{name} theta={theta}: {w} vs {s:?}");
            }
            assert!(n > 1000, "{name} theta={theta}: only {n} samples accepted");
        }
    }
}

/// Monte Carlo directional albedo: mean of the sample weights and its standard error.
fn albedo(b: &Bsdf, wo: Vec3, n: usize, seed: u64) -> (Vec3, Vec3) {
    let mut rng = Rng::new(seed, 3);
    // accumulate in f64: 1e5 f32 additions would drift by ~1e-4
    let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) {
            let w = s.weight.as_dvec3();
            sum += w;
            sum2 += w * w;
        }
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).powf(0.5).as_vec3())
}

#[test]
fn white_furnace_is_bounded() {
    for metallic in [0.0, 0.5, 1.0] {
        for roughness in [0.0, 0.05, 0.2, 0.5, 1.0] {
            let b = Bsdf::new(Vec3::ONE, metallic, 1.0, roughness);
            for theta in [0.0, 30.0, 60.0, 85.0, 89.0] {
                let (a, sigma) = albedo(&b, wo_at(theta), 100_000, 1);
                // the glTF layering gains energy at grazing angles for non-metals (module
                // doc): the strict bound holds for metals at every angle and for everything
                // up to 30 degrees; beyond that the lobes' own bounds apply, diffuse
                // <= (1 - m)(1 - 0.04 s) and specular <= F90 = 1 (so at most 1.96)
                let bound = if metallic == 1.0 || theta <= 30.0 { 1.0 } else { (1.0 - metallic) * (1.0 - 0.04) + 1.0 };
                assert!(
                    (a - 3.0 * sigma).max_element() <= bound,
                    "m={metallic} r={roughness} theta={theta}: albedo {a} +- {sigma} > {bound}"
                );
                assert!(a.min_element() > 0.25, "m={metallic} r={roughness} theta={theta}: albedo {a}");
            }
        }
    }
    // the documented gain: a smooth white dielectric seen at 85 degrees reflects > 1.5
    let (a, _) = albedo(&Bsdf::new(Vec3::ONE, 0.0, 1.0, 0.0), wo_at(85.0), 100_000, 5);
    assert!(a.x > 1.5 && a.x < 1.7, "smooth dielectric at 85 deg: {a}");
    // pure Lambert: every weight is base_color, so the albedo is base_color
    let base = Vec3::new(0.2, 0.5, 0.9);
    let lambert = Bsdf::new(base, 0.0, 0.0, 0.3);
    for theta in THETA_DEG {
        let (a, _) = albedo(&lambert, wo_at(theta), 100_000, 2);
        assert!((a - base).abs().max_element() < 1e-5, "lambert theta={theta}: {a}");
    }
    // a near-mirror white metal at normal incidence reflects (almost) everything: G ~ 1
    let mirror = Bsdf::new(Vec3::ONE, 1.0, 1.0, 0.02);
    let (a, _) = albedo(&mirror, Vec3::Z, 100_000, 3);
    assert!((a - Vec3::ONE).abs().max_element() < 2e-3, "mirror albedo {a}");
    // and a rough one loses energy to the single-scattering G
    let rough = Bsdf::new(Vec3::ONE, 1.0, 1.0, 1.0);
    let (a, _) = albedo(&rough, Vec3::Z, 100_000, 4);
    assert!(a.x < 0.95, "rough metal albedo {a}");
}

#[test]
fn eval_is_reciprocal() {
    let mut rng = Rng::new(21, 22);
    for (name, b) in materials() {
        let mut checked = 0;
        for i in 0..5000 {
            let wo = uniform_sphere(rng.next_2d());
            // half the pairs near the mirror configuration so sharp lobes are non-zero
            let wi = if i % 2 == 0 {
                uniform_sphere(rng.next_2d())
            } else {
                let jitter = 3.0 * b.alpha * uniform_sphere(rng.next_2d());
                (Vec3::new(-wo.x, -wo.y, wo.z) + jitter).normalize()
            };
            if wo.z <= 1e-3 || wi.z <= 1e-3 {
                continue;
            }
            checked += 1;
            let a = b.eval(wo, wi) / wi.z;
            let c = b.eval(wi, wo) / wo.z;
            let tol = 1e-4 * a.max_element().max(1e-6);
            assert!((a - c).abs().max_element() <= tol, "{name}: {wo} {wi}: {a} vs {c}");
        }
        assert!(checked > 1000, "{name}");
    }
}

#[test]
fn below_the_surface_is_zero() {
    for (name, b) in materials() {
        let up = wo_at(30.0);
        let down = Vec3::new(up.x, up.y, -up.z);
        for (wo, wi) in [(up, down), (down, up), (down, down), (Vec3::X, up), (up, Vec3::Y)] {
            assert_eq!(b.eval(wo, wi), Vec3::ZERO, "{name}");
            assert_eq!(b.pdf(wo, wi), 0.0, "{name}");
        }
        assert!(b.sample(down, 0.5, Vec2::splat(0.5)).is_none(), "{name}");
    }
}

#[test]
fn lambert_known_values() {
    let base = Vec3::new(0.25, 0.5, 0.75);
    let b = Bsdf::new(base, 0.0, 0.0, 0.5);
    for theta in THETA_DEG {
        let f = b.eval(wo_at(theta), Vec3::Z);
        assert!((f - base * FRAC_1_PI).abs().max_element() < 1e-7, "theta={theta}: {f}");
    }
    // s = 0, m = 0 is exactly Lambertian: the specular lobe is never sampled
    let mut rng = Rng::new(31, 32);
    for _ in 0..10_000 {
        let wo = wo_at(85.0);
        let s = b.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
        assert!((s.pdf - s.wi.z * FRAC_1_PI).abs() < 1e-6 * s.pdf.max(1.0), "{s:?}");
        assert!((s.weight - base).abs().max_element() < 1e-6, "{s:?}");
    }
    // a glTF dielectric (s = 1) at normal incidence: diffuse (1 - 0.04) base / pi plus the
    // specular peak F0 D(n) G1 G1 / 4 with D(n) = 1 / (pi alpha^2)
    let d = Bsdf::new(base, 0.0, 1.0, 0.5);
    let f = d.eval(Vec3::Z, Vec3::Z);
    // (alpha = 0.5^2 = 0.25, G1(n) = 1)
    let expect = 0.96 * base / PI + Vec3::splat(0.04 / (PI * 0.0625) / 4.0);
    assert!((f - expect).abs().max_element() < 1e-5, "{f} vs {expect}");
    // a metal: F0 = base, no diffuse
    let m = Bsdf::new(base, 1.0, 0.0, 0.5);
    let f = m.eval(Vec3::Z, Vec3::Z);
    assert!((f - base / (PI * 0.0625 * 4.0)).abs().max_element() < 1e-5, "{f}");
}

#[test]
fn fresnel_derivation() {
    // metallic = 0: the specular lobe's F is s F_d, and F90 follows s
    for s in [0.0, 0.3, 1.0] {
        let b = Bsdf::new(Vec3::splat(0.5), 0.0, s, 0.5);
        for c in [0.0, 0.2, 0.7, 1.0] {
            let f_d = 0.04 + 0.96 * (1.0f32 - c).powi(5);
            assert!((b.fresnel(c) - Vec3::splat(s * f_d)).abs().max_element() < 1e-6);
        }
    }
    // metallic = 1: conductor Schlick with F0 = base, F90 = 1
    let base = Vec3::new(0.9, 0.5, 0.1);
    let b = Bsdf::new(base, 1.0, 0.0, 0.5);
    assert!((b.fresnel(1.0) - base).abs().max_element() < 1e-6);
    assert!((b.fresnel(0.0) - Vec3::ONE).abs().max_element() < 1e-6);
    // lobe selection: exactly 0 / 1 when a lobe vanishes
    assert_eq!(Bsdf::new(base, 0.0, 0.0, 0.5).specular_share(wo_at(85.0)), 0.0);
    assert_eq!(Bsdf::new(base, 1.0, 1.0, 0.5).specular_share(wo_at(0.0)), 1.0);
    assert_eq!(Bsdf::new(Vec3::ZERO, 0.0, 1.0, 0.5).specular_share(wo_at(30.0)), 1.0);
    let p = Bsdf::new(base, 0.0, 1.0, 0.5).specular_share(wo_at(30.0));
    assert!(p > 0.0 && p < 0.2, "{p}");
}

#[test]
fn ggx_d_integrates_to_one_over_projected_area() {
    for roughness in [0.2, 0.5, 0.8, 1.0] {
        let b = Bsdf::new(Vec3::ONE, 1.0, 1.0, roughness);
        // integral of D(h) cos(theta_h) d(omega_h) = 2 pi int D sin cos d(theta), midpoint rule
        let n = 200_000;
        let dt = std::f64::consts::FRAC_PI_2 / n as f64;
        let mut sum = 0.0f64;
        for i in 0..n {
            let t = (i as f64 + 0.5) * dt;
            let h = Vec3::new(t.sin() as f32, 0.0, t.cos() as f32);
            sum += b.d(h) as f64 * t.cos() * t.sin() * dt;
        }
        let integral = sum * std::f64::consts::TAU;
        assert!((integral - 1.0).abs() < 1e-3, "alpha {}: {integral}", b.alpha);
    }
}

#[test]
fn no_nan_at_extremes() {
    let grazing = [
        Vec3::new(1.0, 0.0, 1e-7).normalize(),
        Vec3::new(0.0, 1.0, f32::MIN_POSITIVE),
        Vec3::new(0.6, 0.8, 1e-30),
        Vec3::Z,
    ];
    let mut rng = Rng::new(41, 42);
    for b in [
        Bsdf::new(Vec3::ONE, 1.0, 1.0, 0.0),
        Bsdf::new(Vec3::splat(0.5), 0.0, 1.0, 0.0),
        Bsdf::new(Vec3::splat(0.5), 0.5, 1.0, 1.0),
        Bsdf::new(Vec3::splat(f32::NAN), f32::NAN, f32::NAN, f32::NAN),
    ] {
        assert!(b.alpha >= MIN_ALPHA && b.base_color.is_finite());
        for wo in grazing {
            for _ in 0..2000 {
                if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_2d()) {
                    assert!(s.wi.is_finite() && s.weight.is_finite() && s.pdf > 0.0, "{b:?} {wo}: {s:?}");
                    assert!(s.weight.min_element() >= 0.0);
                }
                let wi = uniform_sphere(rng.next_2d());
                assert!(b.eval(wo, wi).is_finite() && b.pdf(wo, wi).is_finite());
            }
            // v.h near 0: both directions grazing and nearly opposite
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            assert!(b.eval(wo, wi).is_finite() && b.pdf(wo, wi).is_finite(), "{b:?} {wo}");
            // corner random numbers
            for (ul, u) in [(0.0, Vec2::ZERO), (0.999_999_9, Vec2::splat(0.999_999_9)), (0.5, Vec2::new(0.0, 1.0))] {
                if let Some(s) = b.sample(wo, ul, u) {
                    assert!(s.weight.is_finite() && s.pdf > 0.0, "{b:?} {wo}: {s:?}");
                }
            }
        }
        let h = b.albedo_hint();
        assert!(h.min_element() >= 0.0 && h.max_element() <= 1.0, "{h}");
    }
}
