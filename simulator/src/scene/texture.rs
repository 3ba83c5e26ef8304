//! Decoded textures: RGBA f32 in linear light, with glTF wrap modes and bilinear lookup.
//!
//! Colour textures (base colour, emission) are stored in sRGB and decoded to linear at load time
//! with the exact sRGB EOTF; data textures (metallic-roughness) are read as they are. Texel
//! centres sit at half-integer positions and `v = 0` is the first (top) row of the file, as in
//! glTF.

use std::path::Path;

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
#[derive(Clone, Debug, PartialEq)]
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
}

/// The sRGB electro-optical transfer function: encoded value in `[0, 1]` to linear light.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Inverse of [`srgb_to_linear`]: linear light to the encoded value (input clamped to `[0, 1]`).
pub fn linear_to_srgb(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.0031308 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

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
        Texture { name: name.to_string(), width, height, texels, wrap_u: WrapMode::Repeat, wrap_v: WrapMode::Repeat }
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

    /// The texel at integer coordinates after wrapping.
    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = wrap(x, self.width as i64, self.wrap_u);
        let y = wrap(y, self.height as i64, self.wrap_v);
        self.texels[(y * self.width as i64 + x) as usize]
    }

    /// Bilinear lookup at texture coordinate `uv` (glTF: (0,0) is the top-left of the image).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return self.texels[0];
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0) * (1.0 - fx) + self.texel(x0 + 1, y0) * fx;
        let bottom = self.texel(x0, y0 + 1) * (1.0 - fx) + self.texel(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
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
        Texture {
            name: "t".into(),
            width: 2,
            height: 2,
            texels: vec![
                Vec4::new(1.0, 0.0, 0.0, 1.0),
                Vec4::new(0.0, 1.0, 0.0, 1.0),
                Vec4::new(0.0, 0.0, 1.0, 1.0),
                Vec4::ONE,
            ],
            wrap_u: WrapMode::Repeat,
            wrap_v: WrapMode::Repeat,
        }
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
    fn wrap_modes() {
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
    fn srgb_round_trip() {
        for i in 0..=255 {
            let c = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.214041).abs() < 1e-5);
    }
}
