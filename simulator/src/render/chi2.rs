//! Chi-square goodness-of-fit test for direction samplers (after Mitsuba's `ChiSquareTest`).
//!
//! The sphere is cut into `n_theta` x `n_phi` bins of equal area (uniform in cos theta and phi).
//! We draw `n_samples` directions with the sampler and histogram them, integrate the claimed pdf
//! over each bin (midpoint rule on a sub-grid) to get the expected counts, pool bins whose
//! expected count is below 5, and reject when the chi-square p-value is below `alpha`.
//! A sampler that returns `None` (an absorbed sample) is fine: its probability mass is then
//! simply missing from both sides, so the pdf must integrate to the acceptance rate.

use glam::{Vec2, Vec3};

use crate::base::sampling::Rng;

/// Settings of a chi-square test.
#[derive(Clone, Copy, Debug)]
pub struct Chi2Config {
    /// Bins along cos(theta).
    pub n_theta: usize,
    /// Bins along phi.
    pub n_phi: usize,
    /// Number of samples drawn.
    pub n_samples: usize,
    /// Midpoint-rule sub-steps per bin and axis when integrating the pdf.
    pub substeps: usize,
    /// Significance level (already corrected for the number of tests run).
    pub alpha: f64,
    /// Seed of the sample stream.
    pub seed: u64,
}

impl Default for Chi2Config {
    fn default() -> Self {
        Chi2Config { n_theta: 20, n_phi: 40, n_samples: 400_000, substeps: 8, alpha: 1e-3, seed: 7 }
    }
}

/// The outcome of a chi-square test.
#[derive(Clone, Debug)]
pub struct Chi2Result {
    /// The statistic.
    pub chi2: f64,
    /// Degrees of freedom after pooling.
    pub dof: usize,
    /// P-value of the statistic.
    pub p_value: f64,
    /// Integral of the pdf over the sphere (should equal the fraction of accepted samples).
    pub pdf_integral: f64,
    /// Fraction of calls that returned a direction.
    pub accepted: f64,
    /// Whether the test passed at `alpha`.
    pub passed: bool,
}

/// Map a direction to its (theta, phi) bin.
fn bin_of(d: Vec3, cfg: &Chi2Config) -> usize {
    let cos_t = d.z.clamp(-1.0, 1.0) as f64;
    let phi = (d.y as f64).atan2(d.x as f64).rem_euclid(std::f64::consts::TAU);
    let i = (((1.0 - cos_t) * 0.5 * cfg.n_theta as f64) as usize).min(cfg.n_theta - 1);
    let j = ((phi / std::f64::consts::TAU * cfg.n_phi as f64) as usize).min(cfg.n_phi - 1);
    i * cfg.n_phi + j
}

/// Run the test: `sample(u_lobe, u)` draws a direction, `pdf(d)` is the density it claims.
pub fn chi2_test(
    cfg: Chi2Config,
    mut sample: impl FnMut(f32, Vec2) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f32,
) -> Chi2Result {
    let nbins = cfg.n_theta * cfg.n_phi;
    let mut observed = vec![0f64; nbins];
    let mut rng = Rng::new(cfg.seed, 0x5eed);
    let mut accepted = 0usize;
    for _ in 0..cfg.n_samples {
        let u_lobe = rng.next_f32();
        let u = rng.next_2d();
        if let Some(d) = sample(u_lobe, u) {
            if d.is_finite() && (d.length() - 1.0).abs() < 1e-3 {
                observed[bin_of(d, &cfg)] += 1.0;
                accepted += 1;
            }
        }
    }
    // expected counts: integrate the pdf over each bin on a (cos theta, phi) midpoint grid
    let mut expected = vec![0f64; nbins];
    let (dz, dphi) = (2.0 / cfg.n_theta as f64, std::f64::consts::TAU / cfg.n_phi as f64);
    let s = cfg.substeps;
    let cell = dz * dphi / (s * s) as f64;
    let mut integral = 0.0;
    for i in 0..cfg.n_theta {
        for j in 0..cfg.n_phi {
            let mut acc = 0.0;
            for a in 0..s {
                let z = 1.0 - (i as f64 + (a as f64 + 0.5) / s as f64) * dz;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for b in 0..s {
                    let phi = (j as f64 + (b as f64 + 0.5) / s as f64) * dphi;
                    let d = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                    acc += pdf(d) as f64 * cell;
                }
            }
            integral += acc;
            expected[i * cfg.n_phi + j] = acc * cfg.n_samples as f64;
        }
    }
    // pool low-expectation bins into one; an observation where nothing is expected fails
    let mut order: Vec<usize> = (0..nbins).collect();
    order.sort_by(|&a, &b| expected[a].partial_cmp(&expected[b]).unwrap());
    let (mut pooled_obs, mut pooled_exp, mut chi2, mut dof) = (0.0, 0.0, 0.0, 0usize);
    let mut impossible = false;
    for &k in &order {
        if expected[k] == 0.0 && observed[k] > 0.0 {
            impossible = true;
        }
        if expected[k] < 5.0 {
            pooled_obs += observed[k];
            pooled_exp += expected[k];
        } else {
            chi2 += (observed[k] - expected[k]).powi(2) / expected[k];
            dof += 1;
        }
    }
    if pooled_exp > 0.0 {
        chi2 += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
        dof += 1;
    } else if pooled_obs > 0.0 {
        impossible = true;
    }
    let dof = dof.saturating_sub(1).max(1);
    let p_value = if impossible { 0.0 } else { chi2_sf(chi2, dof as f64) };
    let acc_rate = accepted as f64 / cfg.n_samples as f64;
    Chi2Result { chi2, dof, p_value, pdf_integral: integral, accepted: acc_rate, passed: p_value >= cfg.alpha }
}

/// Survival function of the chi-square distribution: P(X > x) for `k` degrees of freedom.
pub fn chi2_sf(x: f64, k: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(k).expect("a positive number of degrees of freedom").sf(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, uniform_sphere, UNIFORM_SPHERE_PDF};

    #[test]
    fn chi2_sf_known_values() {
        // scipy.stats.chi2.sf(3.84146, 1) = 0.05; chi2.sf(18.307, 10) = 0.05; chi2.sf(100, 80) = 0.064570 (numerical integration of the pdf)
        assert!((chi2_sf(3.841459, 1.0) - 0.05).abs() < 1e-5);
        assert!((chi2_sf(18.307038, 10.0) - 0.05).abs() < 1e-5);
        assert!((chi2_sf(100.0, 80.0) - 0.064570).abs() < 1e-5);
    }

    #[test]
    fn accepts_correct_samplers() {
        let r = chi2_test(Chi2Config::default(), |_, u| Some(uniform_sphere(u)), |_| UNIFORM_SPHERE_PDF);
        assert!(r.passed && (r.pdf_integral - 1.0).abs() < 1e-3, "{r:?}");
        let r = chi2_test(Chi2Config::default(), |_, u| Some(cosine_hemisphere(u)), |d| cosine_hemisphere_pdf(d.z));
        assert!(r.passed && (r.pdf_integral - 1.0).abs() < 1e-3, "{r:?}");
    }

    #[test]
    fn rejects_a_wrong_pdf() {
        // cosine samples checked against a uniform-hemisphere pdf must fail
        let r = chi2_test(
            Chi2Config::default(),
            |_, u| Some(cosine_hemisphere(u)),
            |d| if d.z > 0.0 { 1.0 / std::f32::consts::TAU } else { 0.0 },
        );
        assert!(!r.passed, "{r:?}");
        // the p-value is the statistic's survival at the pooled degrees of freedom
        assert_eq!(r.p_value, chi2_sf(r.chi2, r.dof as f64), "{r:?}");
    }
}
