//! A small deterministic RNG with independent streams, so a ray's random numbers depend only on
//! `(seed, stream)` (e.g. stream = the ray's index in the run), never on which thread draws them.
//!
//! Generator: xoshiro256++ (Blackman and Vigna), 256-bit state, period 2^256 - 1. Seeding: the
//! key `mix(mix(seed) ^ stream)` (SplitMix64's finaliser `mix`, a bijection, so distinct streams
//! of one seed get distinct keys) starts a SplitMix64 sequence whose first four outputs are the
//! state (never all zero).
//!
//! Conversions:
//! - `uniform_f32 = (x >> 40) 2^-24`, `uniform_f64 = (x >> 11) 2^-53`: in [0, 1), every value a
//!   multiple of the format's ulp at 1/2, so 1 is never returned.
//! - `normal_*`: Box-Muller, `r = sqrt(-2 ln(1 - u1))`, `theta = 2 pi u2`; the first call returns
//!   `r cos theta` and keeps `r sin theta` for the next call.
//! - `below(n)`: Lemire's multiply-and-reject, exactly uniform on `0..n`.

/// SplitMix64's increment (the golden ratio in 64-bit fixed point).
const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function (a bijection of u64).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// xoshiro256++ with a Box-Muller spare; see the module doc.
#[derive(Clone, Debug)]
pub struct Rng {
    s: [u64; 4],
    /// The second normal deviate of the last Box-Muller pair, if not yet returned.
    spare: Option<f64>,
}

impl Rng {
    /// The generator of stream `stream` of seed `seed` (e.g. the run seed and a ray index).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut sm = mix(mix(seed) ^ stream);
        let mut next = || {
            sm = sm.wrapping_add(GAMMA);
            mix(sm)
        };
        Self { s: [next(), next(), next(), next()], spare: None }
    }

    /// The next 64 random bits (xoshiro256++).
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1) with 24 random bits.
    pub fn uniform_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (mean 0, variance 1), Box-Muller in f64.
    pub fn normal_f64(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // 1 - u in (0, 1], so the log is finite.
        let r = (-2.0 * (1.0 - self.uniform_f64()).ln()).sqrt();
        let theta = std::f64::consts::TAU * self.uniform_f64();
        self.spare = Some(r * theta.sin());
        r * theta.cos()
    }

    /// Standard normal (mean 0, variance 1), drawn in f64 and rounded.
    pub fn normal_f32(&mut self) -> f32 {
        self.normal_f64() as f32
    }

    /// Uniform integer in `0..n`, without bias (Lemire's method). Panics if `n == 0`.
    pub fn below(&mut self, n: u64) -> u64 {
        assert!(n > 0, "Rng::below(0): the range 0..0 is empty");
        // x n = hi 2^64 + lo; hi is uniform once the lo values below 2^64 mod n are rejected.
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = self.next_u64() as u128 * n as u128;
            if (m as u64) >= threshold {
                return (m >> 64) as u64;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xoshiro_matches_the_reference_sequence() {
        // The reference implementation's outputs from the state [1, 2, 3, 4].
        let mut rng = Rng { s: [1, 2, 3, 4], spare: None };
        let expected: [u64; 10] = [
            41943041,
            58720359,
            3588806011781223,
            3591011842654386,
            9228616714210784205,
            9973669472204895162,
            14011001112246962877,
            12406186145184390807,
            15849039046786891736,
            10450023813501588000,
        ];
        for e in expected {
            assert_eq!(rng.next_u64(), e);
        }
    }

    #[test]
    fn same_seed_and_stream_give_the_same_sequence_and_streams_differ() {
        let draw = |seed, stream| {
            let mut rng = Rng::new(seed, stream);
            (0..64).map(|_| rng.next_u64()).collect::<Vec<_>>()
        };
        assert_eq!(draw(7, 3), draw(7, 3));
        assert_ne!(draw(7, 3), draw(7, 4));
        assert_ne!(draw(7, 3), draw(8, 3));
        // Neighbouring streams are uncorrelated at the first draw (the one a ray uses first).
        let firsts: Vec<f64> = (0..20_000).map(|s| Rng::new(1, s).uniform_f64()).collect();
        let mean = firsts.iter().sum::<f64>() / firsts.len() as f64;
        let lag1 = firsts.windows(2).map(|w| (w[0] - 0.5) * (w[1] - 0.5)).sum::<f64>() / firsts.len() as f64;
        assert!((mean - 0.5).abs() < 0.01, "mean {mean}");
        assert!((lag1 / (1.0 / 12.0)).abs() < 0.03, "lag-1 correlation {}", lag1 * 12.0);
    }

    /// Pearson's chi-square statistic of `counts` against equal expected counts.
    fn chi_square(counts: &[u64]) -> f64 {
        let n: u64 = counts.iter().sum();
        let e = n as f64 / counts.len() as f64;
        counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum()
    }

    #[test]
    fn uniforms_have_uniform_histograms_and_moments() {
        let mut rng = Rng::new(42, 0);
        let n = 200_000;
        let (mut c32, mut c64) = ([0u64; 32], [0u64; 32]);
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let u = rng.uniform_f32();
            assert!((0.0..1.0).contains(&u));
            c32[(u * 32.0) as usize] += 1;
            let v = rng.uniform_f64();
            assert!((0.0..1.0).contains(&v));
            c64[(v * 32.0) as usize] += 1;
            s1 += v;
            s2 += v * v;
        }
        // 31 degrees of freedom: the 99.9% quantile is 61.1.
        assert!(chi_square(&c32) < 61.1, "chi2 f32 {}", chi_square(&c32));
        assert!(chi_square(&c64) < 61.1, "chi2 f64 {}", chi_square(&c64));
        let mean = s1 / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 0.003, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.001, "variance {var}");
        // The largest output stays below 1.
        assert!(((u64::MAX >> 40) as f32 * (1.0 / (1u64 << 24) as f32)) < 1.0);
        assert!(((u64::MAX >> 11) as f64 * (1.0 / (1u64 << 53) as f64)) < 1.0);
    }

    #[test]
    fn normals_have_standard_moments() {
        let mut rng = Rng::new(9, 5);
        let n = 400_000;
        let mut m = [0.0f64; 4];
        for _ in 0..n {
            let z = rng.normal_f32() as f64;
            assert!(z.is_finite());
            let mut p = 1.0;
            for mk in &mut m {
                p *= z;
                *mk += p;
            }
        }
        let m = m.map(|s| s / n as f64);
        // Standard errors: sqrt(1/n), sqrt(2/n), sqrt(15/n), sqrt(96/n) ~ 0.0016, 0.0022, 0.006, 0.015.
        assert!(m[0].abs() < 0.008, "mean {}", m[0]);
        assert!((m[1] - 1.0).abs() < 0.011, "variance {}", m[1]);
        assert!(m[2].abs() < 0.03, "third moment {}", m[2]);
        assert!((m[3] - 3.0).abs() < 0.075, "fourth moment {}", m[3]);
        // The fraction inside one standard deviation (0.6827, standard error 0.0007).
        let inside = (0..n).filter(|_| rng.normal_f64().abs() < 1.0).count() as f64 / n as f64;
        assert!((inside - 0.682_689).abs() < 0.004, "P(|z| < 1) = {inside}");
    }

    #[test]
    fn below_is_uniform_and_in_range() {
        let mut rng = Rng::new(3, 1);
        assert!((0..100).all(|_| rng.below(1) == 0));
        let mut counts = [0u64; 7];
        for _ in 0..140_000 {
            counts[rng.below(7) as usize] += 1;
        }
        // 6 degrees of freedom: the 99.9% quantile is 22.5.
        assert!(chi_square(&counts) < 22.5, "chi2 {}", chi_square(&counts));
        // n = 3 2^62: x n / 2^64 = 3x/4, so without rejection x = 4k, 4k+1, 4k+2, 4k+3 would give
        // 3k, 3k, 3k+1, 3k+2 and multiples of 3 would have probability 1/2 instead of 1/3.
        let n = 3u64 << 62;
        let third = (0..30_000).filter(|_| rng.below(n).is_multiple_of(3)).count() as f64 / 30_000.0;
        assert!((third - 1.0 / 3.0).abs() < 0.012, "P(x = 0 mod 3) = {third}");
    }
}
