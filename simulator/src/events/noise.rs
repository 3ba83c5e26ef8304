//! The random parts of the non-idealities, each drawn from the pixel's own seeded stream so
//! that the output does not depend on the thread count or the processing order.

use crate::base::sampling::{mix64, Rng};

/// Smallest threshold a mismatch draw may give (v2e and ESIM clamp to 0.01).
pub const MIN_THRESHOLD: f32 = 0.01;

/// The random stream of pixel `index`: a function of (seed, pixel index) only.
pub fn pixel_rng(seed: u64, index: u64) -> Rng {
    let key = mix64(seed ^ mix64(index ^ 0x6576_656e_7473_0001)); // "events" salt
    Rng::new(key, mix64(key ^ 0x2545f4914f6cdd1d))
}

/// A pair of independent standard normals (Box-Muller).
pub fn normal_pair(rng: &mut Rng) -> (f32, f32) {
    let u1 = 1.0 - rng.next_f32(); // in (0, 1], so ln is finite
    let u2 = rng.next_f32();
    let r = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f32::consts::TAU * u2).sin_cos();
    (r * c, r * s)
}

/// Per-pixel thresholds `(C_p, C_m) ~ N(C, sigma)`, clamped to [`MIN_THRESHOLD`].
pub fn draw_thresholds(rng: &mut Rng, c_pos: f32, c_neg: f32, sigma: f32) -> (f32, f32) {
    let (a, b) = normal_pair(rng);
    ((c_pos + sigma * a).max(MIN_THRESHOLD), (c_neg + sigma * b).max(MIN_THRESHOLD))
}

/// An exponential waiting time of a Poisson process with `rate_hz` events per second, in ns
/// (`i64::MAX` when the rate is 0).
pub fn exp_wait_ns(rng: &mut Rng, rate_hz: f32) -> i64 {
    if rate_hz <= 0.0 {
        return i64::MAX;
    }
    let u = 1.0 - rng.next_f32() as f64; // (0, 1]
    let wait = -u.ln() / rate_hz as f64 * 1e9;
    (wait.round() as i64).max(1)
}

/// The photoreceptor low-pass step (v2e): `tau = 1 / (2 pi f)`,
/// `a = min(((255 I + 20) / 275) * dt / tau, 1)`, returning `lp + a (L - lp)`.
/// `I` is linear intensity with 1 = full scale (v2e's 255).
#[inline]
pub fn low_pass(lp: f32, l: f32, intensity: f32, dt_s: f32, cutoff_hz: f32) -> f32 {
    let a = ((255.0 * intensity + 20.0) / 275.0 * dt_s * std::f32::consts::TAU * cutoff_hz).min(1.0);
    lp + a * (l - lp)
}

/// Random initial phase of the leak: the reference starts `u * C_p` below the log intensity,
/// `u ~ U[0, 1)`, so that leak events of a uniform scene do not all fire at once (v2e).
pub fn leak_phase(rng: &mut Rng, c_pos: f32) -> f32 {
    rng.next_f32() * c_pos
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_pair_has_unit_moments() {
        let mut rng = pixel_rng(3, 7);
        let n = 200_000;
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n / 2 {
            let (a, b) = normal_pair(&mut rng);
            s += (a + b) as f64;
            s2 += (a * a + b * b) as f64;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "var {var}");
    }

    #[test]
    fn exp_wait_has_the_right_mean() {
        let mut rng = pixel_rng(1, 2);
        let n = 100_000;
        let mean = (0..n).map(|_| exp_wait_ns(&mut rng, 100.0) as f64).sum::<f64>() / n as f64;
        assert!((mean / 1e7 - 1.0).abs() < 0.02, "mean wait {mean} ns, expected 1e7");
        assert_eq!(exp_wait_ns(&mut rng, 0.0), i64::MAX);
    }

    #[test]
    fn low_pass_is_faster_when_bright_and_saturates() {
        let dark = low_pass(0.0, 1.0, 0.0, 1e-3, 100.0);
        let bright = low_pass(0.0, 1.0, 1.0, 1e-3, 100.0);
        assert!(dark > 0.0 && dark < bright && bright < 1.0, "{dark} {bright}");
        assert!((dark - 20.0 / 275.0 * 1e-3 * std::f32::consts::TAU * 100.0).abs() < 1e-6);
        assert_eq!(low_pass(0.0, 1.0, 1.0, 1.0, 100.0), 1.0);
    }
}
