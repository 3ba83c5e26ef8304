//! Deterministic procedural textures (8-bit sRGB [`RgbImage`]s) with detail at several scales,
//! which is what makes an event camera fire: stripes, checkers, tiles with grout, bricks,
//! value-noise fBm through a colour ramp, wood rings, and text from a built-in 5x7 bitmap font.
//!
//! All randomness comes from a seed: per-tile jitter from [`Rng`], noise lattices from the
//! [`mix64`] hash of (seed, octave, cell), so the same arguments give the same pixels.
//! Noise, checkers, tiles and bricks tile seamlessly when their cell counts divide the image.
//!
//! Colours are sRGB bytes (`[u8; 3]`), as stored in the PNG. Data textures for the
//! metallic-roughness slot are linear: see [`roughness_metallic`].

use glam::Vec2;
use image::{Rgb, RgbImage};

use crate::base::sampling::{mix64, Rng};

/// An sRGB colour as stored in the image.
pub type Srgb = [u8; 3];

/// Mix two colours: `t = 0` gives `a`, `t = 1` gives `b` (in sRGB bytes; fine for textures).
pub fn mix(a: Srgb, b: Srgb, t: f32) -> Srgb {
    let t = t.clamp(0.0, 1.0);
    [0, 1, 2].map(|i| (a[i] as f32 + (b[i] as f32 - a[i] as f32) * t).round() as u8)
}

/// Scale a colour by `k` (clamped to the byte range).
pub fn shade(c: Srgb, k: f32) -> Srgb {
    c.map(|v| (v as f32 * k).round().clamp(0.0, 255.0) as u8)
}

/// Piecewise-linear colour ramp through `stops` = (position in [0, 1], colour), sorted by position.
pub fn ramp(stops: &[(f32, Srgb)], t: f32) -> Srgb {
    let Some(first) = stops.first() else { return [0; 3] };
    if t <= first.0 {
        return first.1;
    }
    for w in stops.windows(2) {
        let ((t0, c0), (t1, c1)) = (w[0], w[1]);
        if t <= t1 {
            return mix(c0, c1, if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 });
        }
    }
    stops[stops.len() - 1].1
}

/// Parallel stripes of period `period_px` (pixels, across the stripes) at `angle_deg` from the
/// image's x axis, half `a` half `b`, 4x4 supersampled at the edges.
pub fn stripes(width: u32, height: u32, angle_deg: f32, period_px: f32, a: Srgb, b: Srgb) -> RgbImage {
    let (s, c) = angle_deg.to_radians().sin_cos();
    // the stripe coordinate grows along the normal to the stripes
    let normal = Vec2::new(-s, c);
    supersample(width, height, |p| if (normal.dot(p) / period_px).rem_euclid(1.0) < 0.5 { 0.0 } else { 1.0 }, a, b)
}

/// A checkerboard of square cells `cell_px` pixels wide.
pub fn checker(width: u32, height: u32, cell_px: u32, a: Srgb, b: Srgb) -> RgbImage {
    let cell = cell_px.max(1);
    RgbImage::from_fn(width, height, |x, y| Rgb(if (x / cell + y / cell).is_multiple_of(2) { a } else { b }))
}

/// Evaluate a coverage function `f(p) in [0, 1]` at 4x4 sub-pixel points and mix `a`-`b`.
fn supersample(width: u32, height: u32, f: impl Fn(Vec2) -> f32, a: Srgb, b: Srgb) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let mut t = 0.0;
        for j in 0..4 {
            for i in 0..4 {
                t += f(Vec2::new(x as f32 + (i as f32 + 0.5) / 4.0, y as f32 + (j as f32 + 0.5) / 4.0));
            }
        }
        Rgb(mix(a, b, t / 16.0))
    })
}

/// Square-grid tiles separated by grout lines.
#[derive(Clone, Debug, PartialEq)]
pub struct Tiles {
    /// Tiles across the image width (tiles are `width / cols` x `height / rows` pixels).
    pub cols: u32,
    /// Tiles down the image height.
    pub rows: u32,
    /// Grout line width (pixels).
    pub grout_px: u32,
    /// Grout colour.
    pub grout: Srgb,
    /// Tile colours: picked at random, or cycled diagonally (a checker with two colours).
    pub colors: Vec<Srgb>,
    /// Pick colours at random (true) or alternate them in a checker pattern (false).
    pub random_pick: bool,
    /// Per-tile brightness jitter: each tile's colour is scaled by `1 + jitter * U(-1, 1)`.
    pub jitter: f32,
    /// Seed of the per-tile choices.
    pub seed: u64,
}

/// Tiles with grout and per-tile colour jitter.
pub fn tiles(width: u32, height: u32, t: &Tiles) -> RgbImage {
    let (cols, rows) = (t.cols.max(1), t.rows.max(1));
    let mut rng = Rng::new(t.seed, 0x711e5);
    let n = t.colors.len().max(1);
    let colors: Vec<Srgb> = (0..cols * rows)
        .map(|k| {
            let base = t.colors.get(if t.random_pick {
                rng.next_u32() as usize % n
            } else {
                ((k % cols + k / cols) as usize) % n
            });
            let k = 1.0 + t.jitter * (2.0 * rng.next_f32() - 1.0);
            shade(base.copied().unwrap_or([200; 3]), k)
        })
        .collect();
    let (tw, th) = (width as f32 / cols as f32, height as f32 / rows as f32);
    RgbImage::from_fn(width, height, |x, y| {
        let (cx, cy) = (((x as f32 / tw) as u32).min(cols - 1), ((y as f32 / th) as u32).min(rows - 1));
        // distance to the cell's left/top edge: grout on the leading edges tiles seamlessly
        let (ex, ey) = (x as f32 - cx as f32 * tw, y as f32 - cy as f32 * th);
        let g = t.grout_px as f32;
        Rgb(if ex < g || ey < g { t.grout } else { colors[(cy * cols + cx) as usize] })
    })
}

/// Running-bond brickwork.
#[derive(Clone, Debug, PartialEq)]
pub struct Bricks {
    /// Courses down the image.
    pub rows: u32,
    /// Bricks per course across the image (odd courses are shifted by half a brick).
    pub per_row: u32,
    /// Mortar joint width (pixels).
    pub mortar_px: u32,
    /// Brick colour.
    pub brick: Srgb,
    /// Mortar colour.
    pub mortar: Srgb,
    /// Per-brick brightness jitter (see [`Tiles::jitter`]).
    pub jitter: f32,
    /// Amplitude of fine noise within each brick (0 = flat bricks).
    pub grain: f32,
    /// Seed.
    pub seed: u64,
}

/// Brickwork with per-brick colour jitter and fine grain.
pub fn bricks(width: u32, height: u32, b: &Bricks) -> RgbImage {
    let (rows, per_row) = (b.rows.max(1), b.per_row.max(1));
    let mut rng = Rng::new(b.seed, 0xb51c);
    let k: Vec<f32> = (0..rows * per_row).map(|_| 1.0 + b.jitter * (2.0 * rng.next_f32() - 1.0)).collect();
    let grain = fbm_values(width, height, &Fbm { cells: per_row * 4, octaves: 3, gain: 0.5, seed: b.seed ^ 0x9a });
    let (bw, bh) = (width as f32 / per_row as f32, height as f32 / rows as f32);
    RgbImage::from_fn(width, height, |x, y| {
        let row = ((y as f32 / bh) as u32).min(rows - 1);
        let shift = if row % 2 == 1 { 0.5 * bw } else { 0.0 };
        let xs = (x as f32 + shift).rem_euclid(width as f32);
        let col = ((xs / bw) as u32).min(per_row - 1);
        let (ex, ey) = (xs - col as f32 * bw, y as f32 - row as f32 * bh);
        let m = b.mortar_px as f32;
        if ex < m || ey < m {
            return Rgb(b.mortar);
        }
        let g = 1.0 + b.grain * (grain[(y * width + x) as usize] - 0.5);
        Rgb(shade(b.brick, k[(row * per_row + col) as usize] * g))
    })
}

/// Fractal (multi-octave) value noise.
#[derive(Clone, Debug, PartialEq)]
pub struct Fbm {
    /// Lattice cells across the image width at the first octave (each octave doubles it); the
    /// height gets `cells * height / width` (rounded, >= 1), so the noise tiles.
    pub cells: u32,
    /// Number of octaves (>= 1): more octaves add finer detail.
    pub octaves: u32,
    /// Amplitude ratio between octaves (0.5 is classic fBm; higher = rougher).
    pub gain: f32,
    /// Seed of the lattice values.
    pub seed: u64,
}

/// fBm values in [0, 1], row-major, normalised by the sum of the octave amplitudes.
pub fn fbm_values(width: u32, height: u32, f: &Fbm) -> Vec<f32> {
    let mut out = vec![0.0f32; (width * height) as usize];
    let (mut amp, mut total) = (1.0f32, 0.0f32);
    for o in 0..f.octaves.max(1) {
        let cx = (f.cells.max(1) as i64) << o.min(16);
        let cy = ((cx as f32 * height as f32 / width as f32).round() as i64).max(1);
        let lattice = |i: i64, j: i64| {
            let h = mix64(f.seed ^ mix64((o as u64) << 48 ^ (i.rem_euclid(cx) as u64) << 24 ^ j.rem_euclid(cy) as u64));
            (h >> 40) as f32 / (1u64 << 24) as f32
        };
        for y in 0..height {
            let v = (y as f32 + 0.5) / height as f32 * cy as f32;
            let (j, fy) = (v.floor() as i64, smooth(v.fract()));
            for x in 0..width {
                let u = (x as f32 + 0.5) / width as f32 * cx as f32;
                let (i, fx) = (u.floor() as i64, smooth(u.fract()));
                let top = lattice(i, j) * (1.0 - fx) + lattice(i + 1, j) * fx;
                let bottom = lattice(i, j + 1) * (1.0 - fx) + lattice(i + 1, j + 1) * fx;
                out[(y * width + x) as usize] += amp * (top * (1.0 - fy) + bottom * fy);
            }
        }
        total += amp;
        amp *= f.gain;
    }
    out.iter_mut().for_each(|v| *v /= total);
    out
}

/// Smoothstep fade of value-noise interpolation.
fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// fBm noise mapped through a colour ramp (stops as in [`ramp`]). fBm values cluster around
/// 0.5, so put the interesting stops in roughly [0.25, 0.75].
pub fn fbm(width: u32, height: u32, f: &Fbm, stops: &[(f32, Srgb)]) -> RgbImage {
    let v = fbm_values(width, height, f);
    RgbImage::from_fn(width, height, |x, y| Rgb(ramp(stops, v[(y * width + x) as usize])))
}

/// Copy `src` onto `dst` with its top-left corner at (`x`, `y`), clipped to `dst` (e.g. a sign
/// or a poster pasted on a wall texture).
pub fn blit(dst: &mut RgbImage, src: &RgbImage, x: i64, y: i64) {
    for (sx, sy, p) in src.enumerate_pixels() {
        let (dx, dy) = (x + sx as i64, y + sy as i64);
        if (0..dst.width() as i64).contains(&dx) && (0..dst.height() as i64).contains(&dy) {
            dst.put_pixel(dx as u32, dy as u32, *p);
        }
    }
}

/// Darken `img` by fBm grime: each pixel is scaled by `1 - strength * noise` (noise in [0, 1]).
pub fn grime(img: &mut RgbImage, f: &Fbm, strength: f32) {
    let v = fbm_values(img.width(), img.height(), f);
    for (p, n) in img.pixels_mut().zip(v) {
        p.0 = shade(p.0, 1.0 - strength * n);
    }
}

/// Wood: growth rings around an axis, distorted by noise.
#[derive(Clone, Debug, PartialEq)]
pub struct Wood {
    /// Ring spacing (pixels).
    pub ring_px: f32,
    /// Ring distortion by fBm (in ring periods).
    pub distortion: f32,
    /// Stretch of the rings along the image's x axis (grain direction; > 1 gives long planks).
    pub stretch: f32,
    /// Early-wood (light) colour.
    pub light: Srgb,
    /// Late-wood (dark) colour.
    pub dark: Srgb,
    /// Seed of the distortion noise.
    pub seed: u64,
}

/// Wood-grain-like rings: the ring index is the (stretched) distance from a centre below the
/// image plus fBm distortion; each ring fades from light to a sharp dark edge.
pub fn wood(width: u32, height: u32, w: &Wood) -> RgbImage {
    let noise = fbm_values(width, height, &Fbm { cells: 4, octaves: 5, gain: 0.55, seed: w.seed });
    let centre = Vec2::new(width as f32 * 0.37, height as f32 * 1.6);
    RgbImage::from_fn(width, height, |x, y| {
        let d = (Vec2::new(x as f32, y as f32) - centre) * Vec2::new(1.0 / w.stretch.max(1e-3), 1.0);
        let r = d.length() / w.ring_px + w.distortion * noise[(y * width + x) as usize];
        let t = r.fract().powf(3.0);
        Rgb(mix(w.light, w.dark, t))
    })
}

/// A linear metallic-roughness texture (glTF: roughness in G, metallic in B, R unused) from
/// values in [0, 1] (e.g. [`fbm_values`]): roughness = `mix(rough_lo, rough_hi, value)`.
pub fn roughness_metallic(
    width: u32,
    height: u32,
    values: &[f32],
    rough_lo: f32,
    rough_hi: f32,
    metallic: f32,
) -> RgbImage {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    RgbImage::from_fn(width, height, |x, y| {
        let v = values[(y * width + x) as usize];
        Rgb([0, q(rough_lo + (rough_hi - rough_lo) * v), q(metallic)])
    })
}

// ----------------------------------------------------------------------------------------------
// Text: a 5x7 bitmap font

/// Glyph cell width in font pixels (5 columns + 1 spacing).
pub const GLYPH_ADVANCE: u32 = 6;
/// Line height in font pixels (7 rows + 2 spacing).
pub const LINE_HEIGHT: u32 = 9;

/// The built-in 5x7 font: each glyph is 7 rows top to bottom, bit 4 the leftmost column.
/// Covers A-Z (lower case draws as upper case), 0-9, space and `-.,:!?/+=%#()'*`.
const FONT: &[(char, [u8; 7])] = &[
    ('A', [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11]),
    ('B', [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E]),
    ('C', [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E]),
    ('D', [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C]),
    ('E', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F]),
    ('F', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10]),
    ('G', [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F]),
    ('H', [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11]),
    ('I', [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('J', [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C]),
    ('K', [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11]),
    ('L', [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F]),
    ('M', [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11]),
    ('N', [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11]),
    ('O', [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('P', [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10]),
    ('Q', [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D]),
    ('R', [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11]),
    ('S', [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E]),
    ('T', [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04]),
    ('U', [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('V', [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04]),
    ('W', [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A]),
    ('X', [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11]),
    ('Y', [0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04]),
    ('Z', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F]),
    ('0', [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E]),
    ('1', [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('2', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F]),
    ('3', [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E]),
    ('4', [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02]),
    ('5', [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E]),
    ('6', [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E]),
    ('7', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08]),
    ('8', [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E]),
    ('9', [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C]),
    (' ', [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
    ('-', [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00]),
    ('.', [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C]),
    (',', [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08]),
    (':', [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00]),
    ('!', [0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04]),
    ('?', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04]),
    ('/', [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00]),
    ('+', [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00]),
    ('=', [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00]),
    ('%', [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03]),
    ('#', [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A]),
    ('(', [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02]),
    (')', [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08]),
    ('\'', [0x04, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00]),
    ('*', [0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00]),
];

/// The 7 rows of `c`'s glyph (bit 4 = leftmost column); lower case maps to upper case and
/// characters outside the font to `?`.
pub fn glyph(c: char) -> [u8; 7] {
    let c = c.to_ascii_uppercase();
    FONT.iter().find(|(g, _)| *g == c).or_else(|| FONT.iter().find(|(g, _)| *g == '?')).map(|(_, rows)| *rows).unwrap()
}

/// Width in pixels of `text` drawn at `scale` (pixels per font pixel), without trailing spacing.
pub fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    (n * GLYPH_ADVANCE).saturating_sub(1) * scale
}

/// Draw `text` on one line with its top-left corner at (`x`, `y`), each font pixel a
/// `scale` x `scale` block of `color`; pixels outside the image are clipped.
pub fn draw_text(img: &mut RgbImage, text: &str, x: i64, y: i64, scale: u32, color: Srgb) {
    let s = scale.max(1) as i64;
    for (k, c) in text.chars().enumerate() {
        let x0 = x + k as i64 * GLYPH_ADVANCE as i64 * s;
        for (row, bits) in glyph(c).into_iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) == 0 {
                    continue;
                }
                for dy in 0..s {
                    for dx in 0..s {
                        let (px, py) = (x0 + col * s + dx, y + row as i64 * s + dy);
                        if (0..img.width() as i64).contains(&px) && (0..img.height() as i64).contains(&py) {
                            img.put_pixel(px as u32, py as u32, Rgb(color));
                        }
                    }
                }
            }
        }
    }
}

/// A sign: `lines` centred in rows on a `background`, with a `border_px` frame in `color`.
pub fn sign(
    width: u32,
    height: u32,
    lines: &[&str],
    scale: u32,
    color: Srgb,
    background: Srgb,
    border_px: u32,
) -> RgbImage {
    let mut img = RgbImage::from_fn(width, height, |x, y| {
        let b = border_px;
        Rgb(if x < b || y < b || x + b >= width || y + b >= height { color } else { background })
    });
    let block = (lines.len() as u32 * LINE_HEIGHT).saturating_sub(2) * scale;
    let top = (height as i64 - block as i64) / 2;
    for (i, line) in lines.iter().enumerate() {
        let x = (width as i64 - text_width(line, scale) as i64) / 2;
        draw_text(&mut img, line, x, top + (i as u32 * LINE_HEIGHT * scale) as i64, scale, color);
    }
    img
}

/// A page of pseudo-text (posters, labels, notice boards): random words of 2-7 letters filling
/// rows left to right from a `margin_px` margin, in `color` on `background`.
pub fn text_page(
    width: u32,
    height: u32,
    scale: u32,
    color: Srgb,
    background: Srgb,
    margin_px: u32,
    seed: u64,
) -> RgbImage {
    const LETTERS: &[u8] = b"ETAOINSHRDLUCMFWYPGBVK0123456789";
    let mut img = RgbImage::from_pixel(width, height, Rgb(background));
    let mut rng = Rng::new(seed, 0x7e47);
    let (adv, line) = ((GLYPH_ADVANCE * scale) as i64, (LINE_HEIGHT * scale) as i64);
    let (left, right, bottom) = (margin_px as i64, width as i64 - margin_px as i64, height as i64 - margin_px as i64);
    let mut y = margin_px as i64;
    while y + 7 * scale as i64 <= bottom {
        let mut x = left;
        loop {
            let len = 2 + rng.next_u32() as i64 % 6;
            if x + len * adv - scale as i64 > right {
                break;
            }
            let word: String = (0..len).map(|_| LETTERS[rng.next_u32() as usize % LETTERS.len()] as char).collect();
            draw_text(&mut img, &word, x, y, scale, color);
            x += (len + 1) * adv;
        }
        y += line;
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letter_a_draws_known_pixels() {
        let (bg, fg) = ([0u8; 3], [255u8; 3]);
        let mut img = RgbImage::from_pixel(12, 16, Rgb(bg));
        draw_text(&mut img, "a", 1, 1, 2, fg);
        let on = |x: u32, y: u32| img.get_pixel(x, y).0 == fg;
        // row 0 of A is .###. : font column 0 off, 1-3 on, 4 off (each a 2x2 block at offset 1)
        assert!(!on(1, 1) && !on(2, 2));
        assert!(on(3, 1) && on(4, 2) && on(7, 1) && on(8, 2));
        assert!(!on(9, 1) && !on(10, 2));
        // row 3 (the bar) is all on; row 4 has only the two legs
        assert!((0..5).all(|c| on(1 + 2 * c, 1 + 2 * 3)));
        assert!(on(1, 9) && !on(3, 9) && !on(5, 9) && !on(7, 9) && on(9, 9));
        // 2x2 blocks: the count of lit pixels is 4x the glyph's set bits
        let bits: u32 = glyph('A').iter().map(|r| r.count_ones()).sum();
        assert_eq!(img.pixels().filter(|p| p.0 == fg).count() as u32, 4 * bits);
        assert_eq!(bits, 18);
    }

    #[test]
    fn unknown_characters_draw_as_question_mark_and_width_is_exact() {
        assert_eq!(glyph('~'), glyph('?'));
        assert_eq!(text_width("AB", 3), 11 * 3);
        assert_eq!(text_width("", 3), 0);
    }

    #[test]
    fn generators_are_deterministic_and_detailed() {
        let f = Fbm { cells: 4, octaves: 5, gain: 0.5, seed: 7 };
        assert_eq!(fbm_values(64, 32, &f), fbm_values(64, 32, &f));
        let v = fbm_values(64, 32, &f);
        assert!(v.iter().all(|x| (0.0..=1.0).contains(x)));
        // fBm tiles: the first column continues the last as smoothly as neighbours do
        let col = |x: u32| (0..32).map(|y| v[(y * 64 + x) as usize]).collect::<Vec<_>>();
        let (first, last, second) = (col(0), col(63), col(1));
        let wrap: f32 = first.iter().zip(&last).map(|(a, b)| (a - b).abs()).sum();
        let step: f32 = first.iter().zip(&second).map(|(a, b)| (a - b).abs()).sum();
        assert!(wrap < 3.0 * step + 1e-3, "wrap {wrap} step {step}");
        let t = Tiles {
            cols: 4,
            rows: 4,
            grout_px: 2,
            grout: [50; 3],
            colors: vec![[200, 180, 160]],
            random_pick: true,
            jitter: 0.2,
            seed: 3,
        };
        assert_eq!(tiles(64, 64, &t), tiles(64, 64, &t));
        let b = Bricks {
            rows: 8,
            per_row: 4,
            mortar_px: 2,
            brick: [150, 60, 40],
            mortar: [200; 3],
            jitter: 0.15,
            grain: 0.3,
            seed: 1,
        };
        let img = bricks(64, 64, &b);
        assert_eq!(img.get_pixel(0, 0).0, [200; 3]);
        let w =
            Wood { ring_px: 6.0, distortion: 2.0, stretch: 4.0, light: [200, 150, 100], dark: [90, 50, 20], seed: 2 };
        assert_eq!(wood(32, 32, &w), wood(32, 32, &w));
        // stripes of period 8 along x: alternating 4-pixel runs
        let s = stripes(16, 1, -90.0, 8.0, [0; 3], [255; 3]);
        let row: Vec<u8> = (0..16).map(|x| s.get_pixel(x, 0).0[0]).collect();
        assert_eq!(&row[..8], &[0, 0, 0, 0, 255, 255, 255, 255]);
        assert_eq!(&row[8..], &row[..8]);
        // a text page has text
        let page = text_page(64, 64, 1, [0; 3], [255; 3], 2, 5);
        assert!(page.pixels().filter(|p| p.0 == [0; 3]).count() > 200);
    }

    #[test]
    fn blit_copies_and_clips() {
        let mut dst = RgbImage::from_pixel(4, 4, Rgb([0; 3]));
        blit(&mut dst, &RgbImage::from_pixel(3, 3, Rgb([9; 3])), 2, -1);
        let lit: Vec<(u32, u32)> = dst.enumerate_pixels().filter(|p| p.2 .0 == [9; 3]).map(|p| (p.0, p.1)).collect();
        assert_eq!(lit, vec![(2, 0), (3, 0), (2, 1), (3, 1)]);
    }

    #[test]
    fn ramp_interpolates_and_clamps() {
        let stops = [(0.25, [0, 0, 0]), (0.75, [200, 100, 0])];
        assert_eq!(ramp(&stops, 0.0), [0, 0, 0]);
        assert_eq!(ramp(&stops, 0.5), [100, 50, 0]);
        assert_eq!(ramp(&stops, 1.0), [200, 100, 0]);
    }
}
