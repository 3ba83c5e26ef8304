//! The camera response: linear radiance to 8-bit display values, and back.
//!
//! `v = curve(clamp(scale * L, 0, 1))`, `q = round(255 v)` (round half away from zero), with the
//! curve one of: sRGB (IEC 61966-2-1 OETF), gamma `v = x^(1/gamma)`, or linear `v = x`. NaN
//! radiance maps to 0. The inverse `L = curve^-1(q / 255)` is what a loader that linearises would
//! compute; `quantise(decode(q)) == q` for every `q` (tested).

use std::io::Cursor;

use serde::{Deserialize, Serialize};

use super::ExposureError;
use crate::base::colour::{linear_to_srgb, srgb_to_linear};
use crate::base::image::Image;

/// The curve from linear radiance to display values. In a config file:
/// `response = { type = "gamma", gamma = 2.2 }`, `{ type = "srgb" }` or `{ type = "linear" }`.
///
/// Unknown keys are rejected for every variant (serde ignores extra keys of unit variants in
/// internally tagged enums, so parsing goes through a private mirror with struct variants).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "RawResponse", into = "RawResponse")]
pub enum CameraResponse {
    /// The sRGB OETF (linear segment below 0.0031308, then `1.055 x^(1/2.4) - 0.055`).
    Srgb,
    /// A pure power law `v = x^(1/gamma)`; the reference configs use gamma 2.2 (the default).
    Gamma {
        /// The display gamma (unitless, > 0, default 2.2); the encoding exponent is `1/gamma`.
        gamma: f32,
    },
    /// No curve: `v = x` (for tests and linear-display experiments).
    Linear,
}

/// The on-disk form of [`CameraResponse`]: struct variants so that `deny_unknown_fields` holds.
#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum RawResponse {
    Srgb {},
    Gamma {
        #[serde(default = "default_gamma")]
        gamma: f32,
    },
    Linear {},
}

impl From<RawResponse> for CameraResponse {
    fn from(r: RawResponse) -> Self {
        match r {
            RawResponse::Srgb {} => CameraResponse::Srgb,
            RawResponse::Gamma { gamma } => CameraResponse::Gamma { gamma },
            RawResponse::Linear {} => CameraResponse::Linear,
        }
    }
}

impl From<CameraResponse> for RawResponse {
    fn from(r: CameraResponse) -> Self {
        match r {
            CameraResponse::Srgb => RawResponse::Srgb {},
            CameraResponse::Gamma { gamma } => RawResponse::Gamma { gamma },
            CameraResponse::Linear => RawResponse::Linear {},
        }
    }
}

fn default_gamma() -> f32 {
    2.2
}

impl Default for CameraResponse {
    /// Gamma 2.2, as in the reference configs.
    fn default() -> Self {
        CameraResponse::Gamma { gamma: default_gamma() }
    }
}

impl CameraResponse {
    /// Reject parameters out of range (gamma must be finite and > 0).
    pub fn validate(&self) -> Result<(), ExposureError> {
        match *self {
            CameraResponse::Gamma { gamma } if !(gamma > 0.0) || !gamma.is_finite() => Err(ExposureError::Response {
                field: "gamma",
                value: gamma.to_string(),
                message: "must be finite and > 0 (the reference configs use 2.2)",
            }),
            _ => Ok(()),
        }
    }

    /// Display value in `[0, 1]` of linear radiance `l` (clamped to `[0, 1]`; NaN -> 0).
    pub fn encode(&self, l: f32) -> f32 {
        let x = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
        match *self {
            CameraResponse::Srgb => linear_to_srgb(x),
            CameraResponse::Gamma { gamma } => x.powf(1.0 / gamma),
            CameraResponse::Linear => x,
        }
    }

    /// Linear radiance of display value `v` in `[0, 1]` (the inverse of [`encode`](Self::encode)).
    pub fn decode(&self, v: f32) -> f32 {
        let v = v.clamp(0.0, 1.0);
        match *self {
            CameraResponse::Srgb => srgb_to_linear(v),
            CameraResponse::Gamma { gamma } => v.powf(gamma),
            CameraResponse::Linear => v,
        }
    }

    /// The 8-bit value of linear radiance `l` after the exposure `scale`:
    /// `round(255 * encode(scale * l))`, rounding half away from zero.
    pub fn quantise(&self, l: f32, scale: f32) -> u8 {
        (self.encode(scale * l) * 255.0).round() as u8
    }

    /// Linear radiance of the 8-bit value `q`: `decode(q / 255)`.
    pub fn decode_u8(&self, q: u8) -> f32 {
        self.decode(q as f32 / 255.0)
    }

    /// An 8-bit display image of a linear image (each channel through [`quantise`](Self::quantise)).
    pub fn to_rgb8(&self, img: &Image, scale: f32) -> image::RgbImage {
        let mut out = image::RgbImage::new(img.width, img.height);
        for (dst, src) in out.pixels_mut().zip(&img.pixels) {
            *dst = image::Rgb([self.quantise(src.x, scale), self.quantise(src.y, scale), self.quantise(src.z, scale)]);
        }
        out
    }

    /// The linear image of an 8-bit display image (each channel through [`decode_u8`](Self::decode_u8)).
    pub fn from_rgb8(&self, img: &image::RgbImage) -> Image {
        let mut out = Image::new(img.width(), img.height());
        for (dst, src) in out.pixels.iter_mut().zip(img.pixels()) {
            *dst = glam::Vec3::new(self.decode_u8(src[0]), self.decode_u8(src[1]), self.decode_u8(src[2]));
        }
        out
    }

    /// PNG file bytes (8-bit RGB) of a linear image through this response.
    pub fn encode_png(&self, img: &Image, scale: f32) -> Result<Vec<u8>, image::ImageError> {
        let mut out = Vec::new();
        self.to_rgb8(img, scale).write_to(&mut Cursor::new(&mut out), image::ImageFormat::Png)?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [CameraResponse; 3] =
        [CameraResponse::Srgb, CameraResponse::Gamma { gamma: 2.2 }, CameraResponse::Linear];

    #[test]
    fn known_values() {
        assert_eq!(CameraResponse::Srgb.quantise(0.5, 1.0), 188);
        assert_eq!(CameraResponse::Gamma { gamma: 2.2 }.quantise(0.5, 1.0), 186);
        assert_eq!(CameraResponse::Linear.quantise(0.5, 1.0), 128); // 127.5 rounds half away from zero
        assert_eq!(CameraResponse::default(), CameraResponse::Gamma { gamma: 2.2 });
        // sRGB linear segment: 0.001 * 12.92 * 255 = 3.29 -> 3.
        assert_eq!(CameraResponse::Srgb.quantise(0.001, 1.0), 3);
        // Exposure scale: 0.25 * 2 = 0.5.
        assert_eq!(CameraResponse::Srgb.quantise(0.25, 2.0), 188);
    }

    #[test]
    fn clamps_and_maps_nan_to_black() {
        for r in ALL {
            assert_eq!(r.quantise(-3.0, 1.0), 0);
            assert_eq!(r.quantise(0.0, 1.0), 0);
            assert_eq!(r.quantise(1.0, 1.0), 255);
            assert_eq!(r.quantise(7.5, 1.0), 255);
            assert_eq!(r.quantise(f32::INFINITY, 1.0), 255);
            assert_eq!(r.quantise(f32::NAN, 1.0), 0);
        }
    }

    #[test]
    fn monotonic() {
        for r in ALL {
            let mut prev_v = -1.0;
            let mut prev_q = 0u8;
            for i in 0..=10_000 {
                let l = i as f32 / 10_000.0;
                let (v, q) = (r.encode(l), r.quantise(l, 1.0));
                assert!(v > prev_v, "{r:?} at {l}");
                assert!(q >= prev_q, "{r:?} at {l}");
                (prev_v, prev_q) = (v, q);
            }
        }
    }

    #[test]
    fn round_trip_every_8_bit_value() {
        for r in ALL.into_iter().chain([CameraResponse::Gamma { gamma: 1.8 }]) {
            for q in 0..=255u8 {
                assert_eq!(r.quantise(r.decode_u8(q), 1.0), q, "{r:?} value {q}");
            }
        }
    }

    #[test]
    fn images_and_png_round_trip() {
        let r = CameraResponse::Srgb;
        let mut img = Image::new(3, 2);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = glam::Vec3::new(i as f32 / 5.0, 0.5, 2.0);
        }
        let rgb = r.to_rgb8(&img, 1.0);
        assert_eq!(rgb.get_pixel(0, 0).0, [0, 188, 255]);
        assert_eq!(rgb.get_pixel(2, 1).0, [255, 188, 255]);
        let back = r.from_rgb8(&rgb);
        assert_eq!(r.to_rgb8(&back, 1.0), rgb);
        let png = r.encode_png(&img, 1.0).unwrap();
        let decoded = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(decoded, rgb);
    }

    #[test]
    fn config_parsing_rejects_unknown_keys_and_bad_gamma() {
        #[derive(Deserialize)]
        struct Cfg {
            response: CameraResponse,
        }
        #[derive(Serialize)]
        struct Cfg2 {
            response: CameraResponse,
        }
        let p = |s: &str| toml::from_str::<Cfg>(s).map(|c| c.response);
        assert_eq!(p("response = { type = \"srgb\" }").unwrap(), CameraResponse::Srgb);
        assert_eq!(p("response = { type = \"gamma\" }").unwrap(), CameraResponse::Gamma { gamma: 2.2 });
        assert_eq!(p("response = { type = \"gamma\", gamma = 1.8 }").unwrap(), CameraResponse::Gamma { gamma: 1.8 });
        assert_eq!(p("response = { type = \"linear\" }").unwrap(), CameraResponse::Linear);
        assert!(p("response = { type = \"gamma\", gamm = 2.2 }").is_err(), "typo rejected");
        assert!(p("response = { type = \"srgb\", gamma = 2.2 }").is_err(), "unknown key rejected");
        assert!(p("response = { type = \"log\" }").is_err());
        for r in ALL {
            let text = toml::to_string(&Cfg2 { response: r }).unwrap();
            assert_eq!(p(&text).unwrap(), r, "{text}");
        }
        for g in [0.0, -2.2, f32::NAN, f32::INFINITY] {
            let e = CameraResponse::Gamma { gamma: g }.validate().unwrap_err();
            assert!(e.to_string().contains("gamma"), "{e}");
        }
        assert!(CameraResponse::default().validate().is_ok());
    }
}
