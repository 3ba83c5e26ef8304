//! Sample generators: where every random number of a camera sample comes from.
//!
//! A path asks for its numbers in 4D *dimension sets* ([`SampleStream::next_4d`]): the camera
//! uses one set, every bounce two (light sample + selection, BSDF sample + lobe + roulette). The
//! two generators differ in how a set is made:
//! - [`SamplerKind::Independent`]: PCG32 uniforms, as Mitsuba's `independent` sampler;
//! - [`SamplerKind::Sobol`] (default): Owen-scrambled Sobol points with Burley's hash-based
//!   scrambling and per-set index shuffling (Burley 2020, "Practical Hash-based Owen
//!   Scrambling"). Each pixel and each dimension set gets its own scramble and shuffle, so
//!   pixels stay independent (the error of one pixel tells nothing about its neighbour's) while
//!   the samples within a pixel are stratified: lower error at equal spp, especially for
//!   direct light and in powers of two.
//!
//! Both are functions of (seed, pixel, frame, sample index) only, so images do not depend on
//! the thread count.

use crate::base::sampling::{mix64, Rng};

/// Which generator a render uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerKind {
    /// Independent uniform random numbers (PCG32).
    Independent,
    /// Owen-scrambled, index-shuffled Sobol points (stratified within each pixel).
    #[default]
    Sobol,
}

/// Direction numbers of the first four Sobol dimensions (Joe-Kuo), built at compile time from
/// their primitive polynomials: dimension 0 is van der Corput; dimensions 1-3 use
/// (s, a, m) = (1, 0, [1]), (2, 1, [1, 3]), (3, 1, [1, 3, 1]).
const SOBOL: [[u32; 32]; 4] = {
    let mut v = [[0u32; 32]; 4];
    let mut i = 0;
    while i < 32 {
        v[0][i] = 1 << (31 - i);
        i += 1;
    }
    let params: [(usize, u32, [u32; 3]); 3] = [(1, 0, [1, 0, 0]), (2, 1, [1, 3, 0]), (3, 1, [1, 3, 1])];
    let mut d = 0;
    while d < 3 {
        let (s, a, m) = params[d];
        let mut i = 0;
        while i < 32 {
            v[d + 1][i] = if i < s {
                m[i] << (31 - i)
            } else {
                let mut x = v[d + 1][i - s] ^ (v[d + 1][i - s] >> s);
                let mut k = 1;
                while k < s {
                    if (a >> (s - 1 - k)) & 1 == 1 {
                        x ^= v[d + 1][i - k];
                    }
                    k += 1;
                }
                x
            };
            i += 1;
        }
        d += 1;
    }
    v
};

/// Byte tables of the Sobol matrices in the bit-reversed domain: `SOBOL_REV_BYTES[d][k][v]` is
/// the bit reversal of the XOR of the direction numbers of dimension `d` selected by the bits of
/// `reverse8(v)` at byte position `3 - k` of the index. So for any `y`,
/// `XOR_k SOBOL_REV_BYTES[d][k][byte k of y] = reverse_bits(sobol(reverse_bits(y), d))`: four
/// lookups instead of a loop over 32 bits, and, since the Owen scramble works on reversed bits,
/// two bit reversals fewer per dimension.
static SOBOL_REV_BYTES: [[[u32; 256]; 4]; 4] = {
    let mut t = [[[0u32; 256]; 4]; 4];
    let mut d = 0;
    while d < 4 {
        let mut k = 0;
        while k < 4 {
            let mut v = 0;
            while v < 256 {
                let bits = (v as u8).reverse_bits();
                let (mut x, mut bit) = (0u32, 0);
                while bit < 8 {
                    if (bits >> bit) & 1 == 1 {
                        x ^= SOBOL[d][(3 - k) * 8 + bit];
                    }
                    bit += 1;
                }
                t[d][k][v] = x.reverse_bits();
                v += 1;
            }
            k += 1;
        }
        d += 1;
    }
    t
};

/// `reverse_bits(sobol(reverse_bits(y), dim))` by four table lookups.
#[inline]
fn sobol_reversed(y: u32, dim: usize) -> u32 {
    let t = &SOBOL_REV_BYTES[dim];
    let b = y.to_le_bytes();
    t[0][b[0] as usize] ^ t[1][b[1] as usize] ^ t[2][b[2] as usize] ^ t[3][b[3] as usize]
}

/// The `index`-th point of Sobol dimension `dim` by definition: the XOR of the direction numbers
/// of the set bits (the reference the tables are tested against).
#[cfg(test)]
fn sobol(mut index: u32, dim: usize) -> u32 {
    let (mut x, mut bit) = (0, 0);
    while index != 0 {
        if index & 1 == 1 {
            x ^= SOBOL[dim][bit];
        }
        index >>= 1;
        bit += 1;
    }
    x
}

/// Laine-Karras style hash permutation (Burley 2020, listing 4 constants).
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Nested uniform (Owen) scramble of 32 fixed-point bits (the definition the reversed-domain
/// code in [`SampleStream::next_4d`] is tested against).
#[cfg(test)]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// 32 fixed-point bits to a float in [0, 1).
#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The scrambling key of one pixel of one frame: computed once per pixel, shared by its samples.
#[inline]
pub fn pixel_key(seed: u64, pixel: u64, frame: u64) -> u64 {
    mix64(seed ^ mix64(pixel ^ mix64(frame.wrapping_add(0x632b_e59b_d9b4_e019))))
}

/// The random numbers of one camera sample.
#[derive(Clone, Debug)]
pub struct SampleStream {
    kind: SamplerKind,
    /// Independent generator (unused by the Sobol kind).
    rng: Rng,
    /// The pixel's key (see [`pixel_key`]).
    key: u64,
    /// Sample index within the pixel.
    index: u32,
    /// Dimension sets handed out so far.
    set: u32,
}

impl SampleStream {
    /// The stream of sample `sample` of the pixel whose key is `key` ([`pixel_key`]).
    #[inline]
    pub fn new(kind: SamplerKind, key: u64, sample: u32) -> SampleStream {
        let rng = match kind {
            SamplerKind::Independent => {
                let k = mix64(key ^ (sample as u64).wrapping_mul(0xd1b5_4a32_d192_ed03));
                Rng::new(k, k >> 1)
            }
            SamplerKind::Sobol => Rng::new(0, 0),
        };
        SampleStream { kind, rng, key, index: sample, set: 0 }
    }

    /// Step past the next four numbers without computing them where that is possible (the
    /// stream then continues as if [`SampleStream::next_4d`] had been called).
    #[inline]
    pub fn skip_4d(&mut self) {
        match self.kind {
            SamplerKind::Independent => {
                self.next_4d();
            }
            SamplerKind::Sobol => self.set += 1,
        }
    }

    /// The first two of the next four numbers ([`SampleStream::next_4d`]'s components 0 and 1;
    /// the stream moves on past all four), for film positions.
    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        match self.kind {
            SamplerKind::Independent => {
                let c = self.next_4d();
                [c[0], c[1]]
            }
            SamplerKind::Sobol => {
                let set = self.set;
                self.set += 1;
                let (y, seeds) = self.sobol_set(set);
                [0, 1].map(|d| to_unit(laine_karras(sobol_reversed(y, d), seeds[d]).reverse_bits()))
            }
        }
    }

    /// The shuffled, bit-reversed index and the dimension scrambles of dimension set `set`.
    #[inline]
    fn sobol_set(&self, set: u32) -> (u32, [u32; 4]) {
        // per (pixel, set): an index shuffle and four dimension scrambles, from two hashes
        let h = mix64(self.key ^ (set as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let g = mix64(h);
        let seeds = [h as u32, (h >> 32) as u32, g as u32, (g >> 32) as u32];
        // all in the bit-reversed domain: y = reverse(shuffled index), and
        // owen_scramble(sobol(reverse(y)), s) = reverse(laine_karras(sobol_reversed(y), s))
        let y = laine_karras(self.index.reverse_bits(), seeds[0] ^ seeds[2].rotate_left(16));
        (y, seeds)
    }

    /// The next four numbers in [0, 1). With Sobol, components 0 and 1 are the best stratified
    /// pair: put 2D warps there.
    #[inline]
    pub fn next_4d(&mut self) -> [f32; 4] {
        let set = self.set;
        self.set += 1;
        match self.kind {
            SamplerKind::Independent => {
                [self.rng.next_f32(), self.rng.next_f32(), self.rng.next_f32(), self.rng.next_f32()]
            }
            SamplerKind::Sobol => {
                let (y, seeds) = self.sobol_set(set);
                let mut out = [0.0; 4];
                for (d, o) in out.iter_mut().enumerate() {
                    *o = to_unit(laine_karras(sobol_reversed(y, d), seeds[d]).reverse_bits());
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_numbers_match_the_published_table() {
        // Burley 2020 lists dimension 1 as 0x80000000, 0xc0000000, 0xa0000000, 0xf0000000, ...
        assert_eq!(
            &SOBOL[1][..8],
            &[0x8000_0000, 0xc000_0000, 0xa000_0000, 0xf000_0000, 0x8800_0000, 0xcc00_0000, 0xaa00_0000, 0xff00_0000]
        );
        assert_eq!(SOBOL[1][31], 0xffff_ffff);
        // dimension 2 (x^2 + x + 1, m = 1, 3): v1 = 1/2, v2 = 3/4, v3 = v1 ^ v1/4 ^ v2 = 3/8, so in
        // natural (not Gray-code) order the points are 0, v1, v2, v1^v2, v3, v1^v3
        let pts: Vec<f64> = (0..6).map(|i| sobol(i, 2) as f64 / 4294967296.0).collect();
        assert_eq!(pts, vec![0.0, 0.5, 0.75, 0.25, 0.375, 0.875]);
        // the byte tables agree with the definition, and the reversed-domain path with the
        // plain Owen scramble of the plain Sobol point
        let mut r = crate::base::sampling::Rng::new(5, 6);
        for _ in 0..10_000 {
            let (i, seed) = (r.next_u32(), r.next_u32());
            for d in 0..4 {
                assert_eq!(sobol_reversed(i, d), sobol(i.reverse_bits(), d).reverse_bits());
                let shuffled = owen_scramble(i, seed);
                assert_eq!(
                    laine_karras(sobol_reversed(laine_karras(i.reverse_bits(), seed), d), seed ^ 1).reverse_bits(),
                    owen_scramble(sobol(shuffled, d), seed ^ 1)
                );
            }
        }
    }

    #[test]
    fn skipping_a_set_continues_the_stream() {
        for kind in [SamplerKind::Independent, SamplerKind::Sobol] {
            for i in 0..16 {
                let mut a = SampleStream::new(kind, 0x1234_5678 + i as u64, i);
                let mut b = a.clone();
                a.next_4d();
                b.skip_4d();
                assert_eq!(a.next_4d(), b.next_4d(), "{kind:?}");
                assert_eq!(a.next_4d(), b.next_4d(), "{kind:?}");
            }
            // next_2d: the first two of next_4d's numbers, and the same stream after them
            let (mut a, mut b) = (SampleStream::new(kind, 99, 3), SampleStream::new(kind, 99, 3));
            let c = a.next_4d();
            assert_eq!(b.next_2d(), [c[0], c[1]], "{kind:?}");
            assert_eq!(a.next_4d(), b.next_4d(), "{kind:?}");
        }
    }

    /// Count points per elementary interval of shape 2^-a x 2^-(k-a).
    fn is_02_net(pts: &[(f32, f32)], k: u32) -> bool {
        (0..=k).all(|a| {
            let (nx, ny) = (1usize << a, 1usize << (k - a));
            let mut count = vec![0u32; nx * ny];
            for &(x, y) in pts {
                count[(y * ny as f32) as usize * nx + (x * nx as f32) as usize] += 1;
            }
            count.iter().all(|&c| c == 1)
        })
    }

    #[test]
    fn every_pixel_and_set_is_a_02_net_in_its_first_two_dimensions() {
        for pixel in 0..20u64 {
            for set in 0..6 {
                let pts: Vec<(f32, f32)> = (0..64)
                    .map(|s| {
                        let mut st = SampleStream::new(SamplerKind::Sobol, pixel_key(1, pixel, 0), s);
                        for _ in 0..set {
                            st.next_4d();
                        }
                        let p = st.next_4d();
                        (p[0], p[1])
                    })
                    .collect();
                assert!(is_02_net(&pts, 6), "pixel {pixel} set {set}");
                // the other two dimensions are stratified in 1D
                for d in [2, 3] {
                    let mut seen = [false; 64];
                    for s in 0..64 {
                        let mut st = SampleStream::new(SamplerKind::Sobol, pixel_key(1, pixel, 0), s);
                        for _ in 0..set {
                            st.next_4d();
                        }
                        seen[(st.next_4d()[d] * 64.0) as usize] = true;
                    }
                    assert!(seen.iter().all(|&b| b), "pixel {pixel} set {set} dim {d}");
                }
            }
        }
        // an independent stream is (almost surely) not a net
        let pts: Vec<(f32, f32)> = (0..64)
            .map(|s| {
                let p = SampleStream::new(SamplerKind::Independent, pixel_key(1, 0, 0), s).next_4d();
                (p[0], p[1])
            })
            .collect();
        assert!(!is_02_net(&pts, 6));
    }

    #[test]
    fn pixels_and_sets_are_decorrelated_and_uniform() {
        // the mean of a product of two sets (and of two pixels) is 1/4 for independent uniforms
        let n = 200_000u32;
        let (mut sets, mut pixels, mut mean) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let pixel = (i / 64) as u64;
            let mut a = SampleStream::new(SamplerKind::Sobol, pixel_key(9, pixel, 0), i % 64);
            let x = a.next_4d();
            let y = a.next_4d();
            let z = SampleStream::new(SamplerKind::Sobol, pixel_key(9, pixel + 100_000, 0), i % 64).next_4d();
            sets += (x[0] * y[0]) as f64;
            pixels += (x[1] * z[1]) as f64;
            mean += x[2] as f64;
        }
        let n = n as f64;
        assert!((sets / n - 0.25).abs() < 0.003, "{}", sets / n);
        assert!((pixels / n - 0.25).abs() < 0.003, "{}", pixels / n);
        assert!((mean / n - 0.5).abs() < 0.003, "{}", mean / n);
    }
}
