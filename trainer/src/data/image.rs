//! RGB images as f32 in [0, 1]: the 8-bit PNG value / 255, display-referred (not linearised, as
//! the reference loader).

use std::path::Path;

use super::error::LoadError;

/// An RGB image, row-major, row 0 at the top, 3 f32 per pixel in [0, 1] (display-referred).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// `3 * width * height` values, `(j * width + i) * 3 + channel`.
    pub data: Vec<f32>,
}

impl RgbImage {
    /// The colour of pixel (`i`, `j`) = (column, row).
    pub fn pixel(&self, i: u32, j: u32) -> [f32; 3] {
        let k = 3 * (j as usize * self.width as usize + i as usize);
        [self.data[k], self.data[k + 1], self.data[k + 2]]
    }

    /// Read an 8-bit PNG (RGB, or RGBA with alpha dropped) as value / 255; `file` names it in
    /// errors (relative to the dataset folder).
    pub fn read_png(path: &Path, file: &str) -> Result<RgbImage, LoadError> {
        let img = image::open(path)
            .map_err(|e| LoadError::unreadable(file, e, "write it again as an 8-bit RGB PNG (evsim dataset)"))?;
        if !matches!(img.color(), image::ColorType::Rgb8 | image::ColorType::Rgba8) {
            return Err(LoadError::invalid(
                file,
                "colour type",
                format!("{:?}, expected 8-bit RGB", img.color()),
                "write 8-bit RGB PNGs",
            ));
        }
        let rgb = img.to_rgb8();
        let (width, height) = rgb.dimensions();
        let data = rgb.into_raw().into_iter().map(|v| v as f32 / 255.0).collect();
        Ok(RgbImage { width, height, data })
    }
}
