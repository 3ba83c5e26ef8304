//! Random numbers and the warps that turn them into directions and points.
//!
//! Every camera sample owns a [`Rng`] whose stream is a hash of (seed, pixel, frame, sample
//! index), so an image is the same bytes whatever the thread count or tile order.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// SplitMix64 finaliser: a strong 64-bit mix.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

/// A PCG32 generator (O'Neill's XSH-RR variant).
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// The stream of one camera sample: a function of the seed, pixel, frame and sample index only.
    pub fn for_sample(seed: u64, pixel: u64, frame: u64, sample: u64) -> Rng {
        let key = mix64(seed ^ mix64(pixel ^ mix64(frame.wrapping_add(0x9e3779b97f4a7c15) ^ mix64(sample))));
        Rng::new(key, mix64(key ^ 0x2545f4914f6cdd1d))
    }

    /// A generator from a state and stream selector.
    pub fn new(state: u64, stream: u64) -> Rng {
        let mut r = Rng { state: 0, inc: (stream << 1) | 1 };
        r.next_u32();
        r.state = r.state.wrapping_add(state);
        r.next_u32();
        r
    }

    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6364136223846793005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1) (24 bits, so never exactly 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two uniforms in [0, 1).
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// Cosine-weighted direction on the hemisphere around +Z (Malley's method on a concentric disk).
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] w.r.t. solid angle.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Shirley-Chiu concentric map from the unit square to the unit disk.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, PI / 4.0 * (o.y / o.x)) } else { (o.y, PI / 2.0 - PI / 4.0 * (o.x / o.y)) };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Uniform direction on the unit sphere.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_sphere`] w.r.t. solid angle.
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// Uniform barycentrics (b1, b2) on a triangle (the square-root parameterisation).
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let su = u.x.sqrt();
    Vec2::new(1.0 - su, u.y * su)
}

/// Power heuristic (beta = 2) weight for a strategy with density `a` against one with `b`.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2.is_infinite() {
        return 1.0;
    }
    if a2 + b2 == 0.0 {
        return 0.0;
    }
    a2 / (a2 + b2)
}

/// An orthonormal frame around a unit normal (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Tangent.
    pub s: Vec3,
    /// Bitangent.
    pub t: Vec3,
    /// Normal (local +Z).
    pub n: Vec3,
}

impl Frame {
    /// A frame whose +Z is the unit vector `n`.
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }
    /// World to local.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local to world.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// A piecewise-constant 1D distribution over `n` equal bins of [0, 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution1D {
    /// Unnormalised non-negative bin weights.
    pub func: Vec<f32>,
    /// Normalised CDF, `n + 1` entries from 0 to 1.
    pub cdf: Vec<f32>,
    /// Sum of `func` (0 when all weights are zero).
    pub total: f32,
}

impl Distribution1D {
    /// Build from non-negative weights (negative or NaN weights count as zero). When all are
    /// zero the distribution is uniform but `total` stays 0.
    pub fn new(weights: &[f32]) -> Distribution1D {
        let n = weights.len().max(1);
        let func: Vec<f32> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 }).collect();
        let mut cdf = Vec::with_capacity(n + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for &w in &func {
            acc += w as f64;
            cdf.push(acc as f32);
        }
        let total = acc as f32;
        if total > 0.0 {
            for c in cdf.iter_mut() {
                *c = (*c as f64 / acc) as f32;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / func.len().max(1) as f32;
            }
        }
        *cdf.last_mut().unwrap() = 1.0;
        Distribution1D { func, cdf, total }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True with no bins.
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Pick a bin with probability proportional to its weight. Returns the bin, its discrete
    /// probability and `u` rescaled to [0,1) within the bin (for reuse).
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let i = self.find(u);
        let lo = self.cdf[i];
        let width = self.cdf[i + 1] - lo;
        let reused = if width > 0.0 { ((u - lo) / width).clamp(0.0, 1.0 - f32::EPSILON) } else { 0.0 };
        (i, width, reused)
    }

    /// Discrete probability of bin `i`.
    pub fn pmf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Sample a continuous position in [0,1); returns it, its density and the bin.
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let (i, p, r) = self.sample_discrete(u);
        let n = self.func.len() as f32;
        ((i as f32 + r) / n, p * n, i)
    }

    /// The bin `i` with `cdf[i] <= u < cdf[i+1]`, skipping zero-width bins.
    fn find(&self, u: f32) -> usize {
        // partition_point gives the first index with cdf > u; the bin is one before it
        let idx = self.cdf.partition_point(|&c| c <= u);
        idx.saturating_sub(1).min(self.func.len() - 1)
    }
}

/// A piecewise-constant 2D distribution on [0,1)^2: a marginal over rows, conditionals per row.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    /// One distribution over columns per row.
    pub conditional: Vec<Distribution1D>,
    /// Distribution over rows.
    pub marginal: Distribution1D,
}

impl Distribution2D {
    /// Build from a row-major `width` x `height` weight grid.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> =
            (0..height).map(|y| Distribution1D::new(&weights[y * width..(y + 1) * width])).collect();
        let row_sums: Vec<f32> = conditional.iter().map(|d| d.total).collect();
        Distribution2D { marginal: Distribution1D::new(&row_sums), conditional }
    }

    /// Sample a point (x = column coordinate, y = row coordinate) and its density on [0,1)^2.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, pdf_y, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_x, _) = self.conditional[row].sample_continuous(u.x);
        (Vec2::new(x, y), pdf_x * pdf_y)
    }

    /// Density at a point of [0,1)^2.
    pub fn pdf(&self, p: Vec2) -> f32 {
        let h = self.conditional.len();
        let w = self.conditional[0].len();
        let row = ((p.y * h as f32) as usize).min(h - 1);
        let col = ((p.x * w as f32) as usize).min(w - 1);
        self.marginal.pmf(row) * h as f32 * self.conditional[row].pmf(col) * w as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_streams_are_deterministic_and_distinct() {
        let a: Vec<u32> = (0..4).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 4), |r, _| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..4).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 4), |r, _| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..4).map(|_| 0).scan(Rng::for_sample(1, 2, 3, 5), |r, _| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        let mut r = Rng::for_sample(7, 0, 0, 0);
        let mean: f32 = (0..100_000).map(|_| r.next_f32()).sum::<f32>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    }

    #[test]
    fn distribution1d_matches_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        assert!((d.pmf(0) - 0.25).abs() < 1e-6);
        assert_eq!(d.pmf(1), 0.0);
        assert_eq!(d.sample_discrete(0.1).0, 0);
        assert_eq!(d.sample_discrete(0.25).0, 2);
        assert_eq!(d.sample_discrete(0.999).0, 2);
        let (x, pdf, _) = d.sample_continuous(0.625);
        assert!((x - (2.0 + 0.5) / 3.0).abs() < 1e-6);
        assert!((pdf - 0.75 * 3.0).abs() < 1e-5);
    }

    #[test]
    fn distribution2d_pdf_integrates_to_one() {
        let w: Vec<f32> = (0..12).map(|i| (i % 5) as f32).collect();
        let d = Distribution2D::new(&w, 4, 3);
        let mut sum = 0.0;
        for y in 0..3 {
            for x in 0..4 {
                sum += d.pdf(Vec2::new((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 3.0)) / 12.0;
            }
        }
        assert!((sum - 1.0).abs() < 1e-5);
        let mut r = Rng::new(1, 2);
        for _ in 0..1000 {
            let (p, pdf) = d.sample(r.next_2d());
            assert!((d.pdf(p) - pdf).abs() < 1e-4 * pdf.max(1.0));
            assert!(pdf > 0.0);
        }
    }

    #[test]
    fn frame_is_orthonormal() {
        let mut r = Rng::new(3, 4);
        for _ in 0..100 {
            let n = uniform_sphere(r.next_2d());
            let f = Frame::from_normal(n);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            assert!((f.s.cross(f.t) - n).length() < 1e-4);
            let v = uniform_sphere(r.next_2d());
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }
}
