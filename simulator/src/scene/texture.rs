//! Decoded textures: RGBA f32 in linear light, with glTF wrap modes, bilinear lookup and
//! filtered (mip-mapped, anisotropic) lookup over a footprint.
//!
//! Colour textures (base colour, emission) are stored in sRGB and decoded to linear at load time
//! with the exact sRGB EOTF; data textures (metallic-roughness) are read as they are. Texel
//! centres sit at half-integer positions and `v = 0` is the first (top) row of the file, as in
//! glTF.

use crate::base::colour::srgb_to_linear;
use std::path::Path;
use std::sync::OnceLock;

use glam::{Vec2, Vec4};

use crate::error::SceneError;

/// How texture coordinates outside [0, 1] are mapped back in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WrapMode {
    /// Tile the texture (glTF REPEAT, the default).
    #[default]
    Repeat,
    /// Clamp to the edge texel (glTF CLAMP_TO_EDGE).
    ClampToEdge,
    /// Tile, mirroring every other copy (glTF MIRRORED_REPEAT).
    MirroredRepeat,
}

/// A decoded 2D texture.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Name (file name or glTF image name), for messages.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major texels, row 0 first (the top of the image file).
    pub texels: Vec<Vec4>,
    /// Wrap mode along u.
    pub wrap_u: WrapMode,
    /// Wrap mode along v.
    pub wrap_v: WrapMode,
    /// The box-filtered reductions of `texels` (level 1 = half size, down to 1x1), built on the
    /// first filtered lookup.
    pyramid: OnceLock<Vec<Level>>,
    /// `texels` as palette indices (see [`Compact`]), built on the first lookup; None when a
    /// channel has more than 256 distinct values.
    compact: OnceLock<Option<Compact>>,
}

/// A texture's texels as four bytes each: per channel, an index into that channel's palette of
/// at most 256 values. Exact (the palettes hold the texels' values bit for bit; an 8-bit image
/// has at most 256 per channel), and a quarter of the memory, so that the lookups of a frame's
/// many camera rays stay in cache.
#[derive(Clone, Debug)]
struct Compact {
    palette: Box<[[f32; 256]; 4]>,
    index: Vec<[u8; 4]>,
}

impl Compact {
    /// The palettes and indices of `texels`, or None if a channel has over 256 distinct values.
    fn new(texels: &[Vec4]) -> Option<Compact> {
        let mut palette = Box::new([[0.0f32; 256]; 4]);
        let mut values: Vec<Vec<u32>> = Vec::with_capacity(4);
        for (c, pal) in palette.iter_mut().enumerate() {
            let mut v: Vec<u32> = texels.iter().map(|t| t[c].to_bits()).collect();
            v.sort_unstable();
            v.dedup();
            if v.len() > 256 {
                return None;
            }
            for (p, bits) in pal.iter_mut().zip(&v) {
                *p = f32::from_bits(*bits);
            }
            values.push(v);
        }
        let index = texels
            .iter()
            .map(|t| {
                // every value is in its palette, so the search finds it
                std::array::from_fn(|c| values[c].binary_search(&t[c].to_bits()).unwrap_or(0) as u8)
            })
            .collect();
        Some(Compact { palette, index })
    }

    /// Texel `i`, bit for bit as it was given.
    #[inline(always)]
    fn texel(&self, i: usize) -> Vec4 {
        let [r, g, b, a] = self.index[i];
        let p = &self.palette;
        Vec4::new(p[0][r as usize], p[1][g as usize], p[2][b as usize], p[3][a as usize])
    }
}

impl PartialEq for Texture {
    /// Same name, size, texels and wrap modes (the pyramid follows from them).
    fn eq(&self, o: &Texture) -> bool {
        self.name == o.name
            && (self.width, self.height) == (o.width, o.height)
            && self.texels == o.texels
            && (self.wrap_u, self.wrap_v) == (o.wrap_u, o.wrap_v)
    }
}

/// One reduction of a texture.
#[derive(Clone, Debug, PartialEq)]
struct Level {
    width: u32,
    height: u32,
    texels: Vec<Vec4>,
}

/// Most lookups one filtered lookup spreads along a stretched footprint (the ratio of its long
/// to its short axis beyond which the footprint is treated as wider than it is).
pub const MAX_ANISOTROPY: u32 = 8;

impl Texture {
    /// A texture from an already-decoded image. With `srgb`, RGB (not alpha) is decoded from sRGB.
    pub fn from_image(name: &str, img: image::DynamicImage, srgb: bool) -> Texture {
        let rgba = img.to_rgba32f();
        let (width, height) = rgba.dimensions();
        let texels = rgba
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                if srgb {
                    Vec4::new(srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a)
                } else {
                    Vec4::new(r, g, b, a)
                }
            })
            .collect();
        Texture::new(name, width, height, texels)
    }

    /// A texture from linear RGBA texels (row-major, `width * height` of them), wrap mode
    /// [`WrapMode::Repeat`] both ways.
    pub fn new(name: &str, width: u32, height: u32, texels: Vec<Vec4>) -> Texture {
        Texture {
            name: name.to_string(),
            width,
            height,
            texels,
            wrap_u: WrapMode::Repeat,
            wrap_v: WrapMode::Repeat,
            pyramid: OnceLock::new(),
            compact: OnceLock::new(),
        }
    }

    /// Decode an image file (PNG or JPEG). `element` names the referring element for messages.
    pub fn load(path: &Path, srgb: bool, element: &str) -> Result<Texture, SceneError> {
        let bytes = std::fs::read(path).map_err(|e| {
            SceneError::invalid(
                path,
                element,
                format!("texture file cannot be read ({e}); check the path, which is relative to the scene file"),
            )
        })?;
        Self::decode(&bytes, path, srgb, element)
    }

    /// Decode an in-memory image (PNG or JPEG); `path` is the file it came from, for messages.
    pub fn decode(bytes: &[u8], path: &Path, srgb: bool, element: &str) -> Result<Texture, SceneError> {
        let img = image::load_from_memory(bytes).map_err(|e| {
            SceneError::invalid(path, element, format!("texture cannot be decoded: {e}; use PNG or JPEG"))
        })?;
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        Ok(Self::from_image(&name, img, srgb))
    }

    /// Bilinear lookup at texture coordinate `uv` (glTF: (0,0) is the top-left of the image).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let wrap = (self.wrap_u, self.wrap_v);
        match self.compact.get_or_init(|| Compact::new(&self.texels)) {
            Some(c) => bilinear(|i| c.texel(i), self.width, self.height, wrap, uv),
            None => bilinear(|i| self.texels[i], self.width, self.height, wrap, uv),
        }
    }

    /// Filtered lookup: the texture averaged over the footprint spanned by the texture-coordinate
    /// offsets `du` and `dv` around `uv` (for a camera ray: how `uv` changes from one pixel to
    /// the next along x and along y). Trilinear mip-mapping at the footprint's short axis, with
    /// up to [`MAX_ANISOTROPY`] such lookups spread along its long axis (as GPUs filter). A
    /// footprint smaller than a texel is a plain [`Texture::sample`].
    pub fn sample_footprint(&self, uv: Vec2, du: Vec2, dv: Vec2) -> Vec4 {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let (a, b) = (du * size, dv * size); // in texels
        let (la, lb) = (a.length(), b.length());
        if !(la.is_finite() && lb.is_finite()) || la.max(lb) <= 1.0 {
            return self.sample(uv);
        }
        let (major_uv, major, minor) = if la >= lb { (du, la, lb) } else { (dv, lb, la) };
        let taps = ((major / minor.max(1e-6)).ceil() as u32).clamp(1, MAX_ANISOTROPY);
        let width = (major / taps as f32).max(minor);
        let lod = width.log2();
        if taps == 1 {
            return self.trilinear(uv, lod);
        }
        let mut sum = Vec4::ZERO;
        for i in 0..taps {
            let s = (i as f32 + 0.5) / taps as f32 - 0.5;
            sum += self.trilinear(uv + major_uv * s, lod);
        }
        sum / taps as f32
    }

    /// Lookup at level of detail `lod` (0 = the texels, 1 = the half-size level, ...;
    /// fractional levels blend the two nearest), bilinear within a level.
    fn trilinear(&self, uv: Vec2, lod: f32) -> Vec4 {
        if lod.is_nan() || lod <= 0.0 {
            return self.sample(uv);
        }
        let levels = self.pyramid.get_or_init(|| build_pyramid(&self.texels, self.width, self.height));
        let top = levels.len() as f32;
        let lod = lod.min(top);
        let i = lod.floor() as usize;
        let f = lod - i as f32;
        let at = |k: usize| -> Vec4 {
            if k == 0 {
                self.sample(uv)
            } else {
                let l = &levels[k - 1];
                bilinear(|i| l.texels[i], l.width, l.height, (self.wrap_u, self.wrap_v), uv)
            }
        };
        if f <= 0.0 || i >= levels.len() {
            at(i)
        } else {
            at(i) * (1.0 - f) + at(i + 1) * f
        }
    }
}

/// Bilinear lookup in a row-major `width` x `height` grid of texels, texel `i` being `texel(i)`.
#[inline(always)]
fn bilinear(
    texel: impl Fn(usize) -> Vec4,
    width: u32,
    height: u32,
    (wrap_u, wrap_v): (WrapMode, WrapMode),
    uv: Vec2,
) -> Vec4 {
    let x = uv.x * width as f32 - 0.5;
    let y = uv.y * height as f32 - 0.5;
    if !(x.is_finite() && y.is_finite()) {
        return texel(0);
    }
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (w, h) = (width as i64, height as i64);
    let (xa, xb) = wrap_pair(x0, w, wrap_u);
    let (ya, yb) = wrap_pair(y0, h, wrap_v);
    let (ya, yb) = (ya * w, yb * w);
    let t = |x: i64, y: i64| texel((y + x) as usize);
    let top = t(xa, ya) * (1.0 - fx) + t(xb, ya) * fx;
    let bottom = t(xa, yb) * (1.0 - fx) + t(xb, yb) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The reductions of a texture down to 1x1: each level halves each side (rounding down, at
/// least 1) and each of its texels is the exact box average of the area it covers in the level
/// below (fractional texels weighted by the part covered, so odd sizes lose nothing).
fn build_pyramid(texels: &[Vec4], width: u32, height: u32) -> Vec<Level> {
    let mut levels: Vec<Level> = Vec::new();
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let src = levels.last().map_or(texels, |l| &l.texels[..]);
        // rows first (along x), then columns (along y)
        let wx = box_weights(w, nw);
        let mut rows = vec![Vec4::ZERO; (nw * h) as usize];
        for y in 0..h as usize {
            for (x, taps) in wx.iter().enumerate() {
                rows[y * nw as usize + x] = taps.iter().map(|&(i, k)| src[y * w as usize + i] * k).sum();
            }
        }
        let wy = box_weights(h, nh);
        let mut out = vec![Vec4::ZERO; (nw * nh) as usize];
        for (y, taps) in wy.iter().enumerate() {
            for x in 0..nw as usize {
                out[y * nw as usize + x] = taps.iter().map(|&(i, k)| rows[i * nw as usize + x] * k).sum();
            }
        }
        levels.push(Level { width: nw, height: nh, texels: out });
        (w, h) = (nw, nh);
    }
    levels
}

/// For each of `m` output cells over `n` input cells (m <= n): the input cells it overlaps and
/// the weight of each (the overlap over the output cell's length; the weights sum to 1).
fn box_weights(n: u32, m: u32) -> Vec<Vec<(usize, f32)>> {
    let scale = n as f64 / m as f64;
    (0..m)
        .map(|j| {
            let (lo, hi) = (j as f64 * scale, (j + 1) as f64 * scale);
            let first = lo.floor() as usize;
            let last = (hi.ceil() as usize).min(n as usize);
            (first..last)
                .map(|i| {
                    let overlap = (hi.min(i as f64 + 1.0) - lo.max(i as f64)).max(0.0);
                    (i, (overlap / scale) as f32)
                })
                .filter(|&(_, k)| k > 0.0)
                .collect()
        })
        .collect()
}

/// [`wrap`] of `i` and `i + 1` (one division instead of two for the repeat mode).
#[inline]
fn wrap_pair(i: i64, n: i64, mode: WrapMode) -> (i64, i64) {
    match mode {
        WrapMode::Repeat => {
            // a power-of-two size (most textures) wraps by a mask, which equals `rem_euclid` in
            // two's complement and costs a cycle where a 64-bit division costs tens
            let a = if n & (n - 1) == 0 { i & (n - 1) } else { i.rem_euclid(n) };
            (a, if a + 1 == n { 0 } else { a + 1 })
        }
        _ => (wrap(i, n, mode), wrap(i + 1, n, mode)),
    }
}

/// Map an integer texel coordinate into [0, n) by the wrap mode.
fn wrap(i: i64, n: i64, mode: WrapMode) -> i64 {
    match mode {
        WrapMode::Repeat => i.rem_euclid(n),
        WrapMode::ClampToEdge => i.clamp(0, n - 1),
        WrapMode::MirroredRepeat => {
            let period = 2 * n;
            let m = i.rem_euclid(period);
            if m < n {
                m
            } else {
                period - 1 - m
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        // 2x2: red, green / blue, white
        Texture::new(
            "t",
            2,
            2,
            vec![
                Vec4::new(1.0, 0.0, 0.0, 1.0),
                Vec4::new(0.0, 1.0, 0.0, 1.0),
                Vec4::new(0.0, 0.0, 1.0, 1.0),
                Vec4::ONE,
            ],
        )
    }

    /// A `w` x `h` texture of pseudo-random grey levels (a hash of the texel index).
    fn noise(w: u32, h: u32) -> Texture {
        let texels = (0..w * h)
            .map(|i| {
                let v = ((i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40) as f32 / (1u64 << 24) as f32;
                Vec4::new(v, 1.0 - v, 0.5 * v, 1.0)
            })
            .collect();
        Texture::new("noise", w, h, texels)
    }

    #[test]
    fn pyramid_levels_are_exact_box_means() {
        for (w, h) in [(8, 8), (7, 5), (13, 1), (1, 6)] {
            let t = noise(w, h);
            let levels = build_pyramid(&t.texels, w, h);
            let mean = t.texels.iter().copied().sum::<Vec4>() / (w * h) as f32;
            let last = levels.last().unwrap();
            assert_eq!((last.width, last.height), (1, 1), "{w}x{h}");
            // every level keeps the mean (exact box weights), and the top is that mean
            for l in &levels {
                let m = l.texels.iter().copied().sum::<Vec4>() / (l.width * l.height) as f32;
                assert!((m - mean).abs().max_element() < 1e-5, "{w}x{h} level {}x{}", l.width, l.height);
            }
            assert!((last.texels[0] - mean).abs().max_element() < 1e-5);
        }
        // a 2x2 block average on an even size
        let t = noise(4, 2);
        let l1 = &build_pyramid(&t.texels, 4, 2)[0];
        let want = (t.texels[0] + t.texels[1] + t.texels[4] + t.texels[5]) / 4.0;
        assert!((l1.texels[0] - want).abs().max_element() < 1e-6);
        // 3 -> 1: thirds
        let w = box_weights(3, 1);
        assert_eq!(w[0].len(), 3);
        assert!(w[0].iter().all(|&(_, k)| (k - 1.0 / 3.0).abs() < 1e-6));
        // 5 -> 2: 1, 1, 0.5 | 0.5, 1, 1 (over 2.5)
        let w = box_weights(5, 2);
        assert_eq!(w[0].iter().map(|&(i, _)| i).collect::<Vec<_>>(), vec![0, 1, 2]);
        assert!((w[0][2].1 - 0.2).abs() < 1e-6 && (w[1][0].1 - 0.2).abs() < 1e-6);
    }

    #[test]
    fn small_footprints_are_bilinear_and_large_ones_average() {
        let t = noise(64, 32);
        let uv = Vec2::new(0.37, 0.61);
        // under a texel: exactly the bilinear lookup
        let tiny = Vec2::new(0.5 / 64.0, 0.0);
        assert_eq!(t.sample_footprint(uv, tiny, Vec2::new(0.0, 0.5 / 32.0)), t.sample(uv));
        // a footprint covering the whole texture: its mean
        let mean = t.texels.iter().copied().sum::<Vec4>() / (64 * 32) as f32;
        let all = t.sample_footprint(uv, Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0));
        assert!((all - mean).abs().max_element() < 1e-4, "{all} vs {mean}");
        // a footprint of 8 texels: close to the box mean over it (the noise's mean is 0.5 in x,
        // a single texel deviates by up to 0.5)
        let mid = t.sample_footprint(uv, Vec2::new(8.0 / 64.0, 0.0), Vec2::new(0.0, 8.0 / 32.0));
        let (x0, y0) = ((uv.x * 64.0 - 4.0) as u32, (uv.y * 32.0 - 4.0) as u32);
        let mut box_mean = Vec4::ZERO;
        for y in y0..y0 + 8 {
            for x in x0..x0 + 8 {
                box_mean += t.texels[(y * 64 + x) as usize] / 64.0;
            }
        }
        assert!((mid - box_mean).abs().max_element() < 0.08, "{mid} vs {box_mean}");
        assert!((mid - t.sample(uv)).abs().max_element() > 1e-3, "the footprint changed the lookup");
    }

    #[test]
    fn stretched_footprints_spread_along_their_long_axis() {
        // vertical stripes one texel wide: a footprint long along v (across no stripes) and one
        // texel wide along u must not blur the stripes, one long along u must
        let texels = (0..64 * 64).map(|i| if i % 2 == 0 { Vec4::ONE } else { Vec4::ZERO }).collect();
        let t = Texture::new("stripes", 64, 64, texels);
        let uv = Vec2::new(10.5 / 64.0, 0.5);
        let along_v = t.sample_footprint(uv, Vec2::new(1.0 / 64.0, 0.0), Vec2::new(0.0, 8.0 / 64.0));
        assert!((along_v.x - t.sample(uv).x).abs() < 1e-4, "{along_v} vs {}", t.sample(uv));
        let along_u = t.sample_footprint(uv, Vec2::new(8.0 / 64.0, 0.0), Vec2::new(0.0, 1.0 / 64.0));
        assert!((along_u.x - 0.5).abs() < 0.05, "{along_u}");
        // rotating the footprint's axes (du and dv swapped) gives the same answer
        let swapped = t.sample_footprint(uv, Vec2::new(0.0, 8.0 / 64.0), Vec2::new(1.0 / 64.0, 0.0));
        assert_eq!(swapped, along_v);
    }

    #[test]
    fn texel_centres_are_exact() {
        let t = checker();
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec4::new(1.0, 0.0, 0.0, 1.0));
        assert_eq!(t.sample(Vec2::new(0.75, 0.75)), Vec4::ONE);
        // halfway between red and green
        let m = t.sample(Vec2::new(0.5, 0.25));
        assert!((m - Vec4::new(0.5, 0.5, 0.0, 1.0)).abs().max_element() < 1e-6);
    }

    #[test]
    fn palette_lookups_equal_full_texel_lookups_bit_for_bit() {
        // an 8-bit sRGB image (at most 256 values per channel: palettes) and a texture with
        // more distinct values than a palette holds (full texels)
        let (w, h) = (37, 23);
        let bytes = |i: u32, k: u32| ((i.wrapping_mul(2_654_435_761) >> (8 * k)) & 0xff) as f32 / 255.0;
        let eight_bit: Vec<Vec4> = (0..w * h)
            .map(|i| Vec4::new(srgb_to_linear(bytes(i, 0)), srgb_to_linear(bytes(i, 1)), bytes(i, 2), -0.0))
            .collect();
        let mut rng = crate::base::sampling::Rng::new(7, 0);
        for (t, paletted) in [(Texture::new("8-bit", w, h, eight_bit), true), (noise(300, 2), false)] {
            for wrap in [WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat] {
                let t = Texture { wrap_u: wrap, wrap_v: wrap, ..t.clone() };
                for _ in 0..2000 {
                    let uv = Vec2::new(rng.next_f32() * 6.0 - 3.0, rng.next_f32() * 6.0 - 3.0);
                    let full = bilinear(|i| t.texels[i], t.width, t.height, (wrap, wrap), uv);
                    assert_eq!(t.sample(uv).to_array().map(f32::to_bits), full.to_array().map(f32::to_bits));
                }
                assert_eq!(t.compact.get().map(Option::is_some), Some(paletted), "{}", t.name);
            }
        }
    }

    #[test]
    fn wrap_modes() {
        // the pair's masked power-of-two path and its division agree everywhere
        for n in [1i64, 2, 3, 4, 6, 8, 48, 64, 96, 256] {
            for i in (-3 * n - 2)..(3 * n + 2) {
                let (a, b) = wrap_pair(i, n, WrapMode::Repeat);
                assert_eq!((a, b), (wrap(i, n, WrapMode::Repeat), wrap(i + 1, n, WrapMode::Repeat)), "i {i} n {n}");
            }
            let far = i64::from(i32::MAX) * 7 + 5;
            assert_eq!(wrap_pair(-far, n, WrapMode::Repeat).0, (-far).rem_euclid(n));
        }
        assert_eq!(wrap(-1, 4, WrapMode::Repeat), 3);
        assert_eq!(wrap(5, 4, WrapMode::Repeat), 1);
        assert_eq!(wrap(-1, 4, WrapMode::ClampToEdge), 0);
        assert_eq!(wrap(9, 4, WrapMode::ClampToEdge), 3);
        assert_eq!(wrap(4, 4, WrapMode::MirroredRepeat), 3);
        assert_eq!(wrap(-1, 4, WrapMode::MirroredRepeat), 0);
        assert_eq!(wrap(8, 4, WrapMode::MirroredRepeat), 0);
        // at u = 0 the repeat wrap blends the first and last column equally
        let t = checker();
        let m = t.sample(Vec2::new(0.0, 0.25));
        assert!((m - Vec4::new(0.5, 0.5, 0.0, 1.0)).abs().max_element() < 1e-6);
    }

    #[test]
    fn wrapped_pairs_are_the_wrapped_neighbours() {
        for mode in [WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat] {
            for n in [1, 2, 5] {
                for i in -12..12 {
                    assert_eq!(wrap_pair(i, n, mode), (wrap(i, n, mode), wrap(i + 1, n, mode)), "{mode:?} {n} {i}");
                }
            }
        }
    }
}
