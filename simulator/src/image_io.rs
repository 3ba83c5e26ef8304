//! Writing images: linear float EXR and 8-bit sRGB PNG, both atomically (written to a temporary
//! file beside the target, then renamed), so an interrupted run never leaves a half-written file.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::base::colour::linear_to_srgb;
use crate::base::image::Image;

/// The temporary sibling a file is first written to.
fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

/// Write `bytes` to `path` atomically (temporary file + rename), creating missing folders.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create the output folder; choose another --out", parent.display()))?;
    }
    let tmp = temp_path(path);
    std::fs::write(&tmp, bytes).inspect_err(|_| drop(std::fs::remove_file(&tmp))).with_context(|| {
        format!("{}: cannot write (is the folder there and writable? create it or choose another --out)", tmp.display())
    })?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot move into place", path.display()))?;
    Ok(())
}

/// Encode an image as 8-bit sRGB PNG bytes (linear values clamped to `[0, 1]`, then the sRGB OETF,
/// rounded to nearest).
pub fn encode_png(img: &Image) -> Result<Vec<u8>> {
    let mut buf = image::RgbImage::new(img.width, img.height);
    for (dst, src) in buf.pixels_mut().zip(&img.pixels) {
        let q = |v: f32| (linear_to_srgb(if v.is_finite() { v } else { 0.0 }) * 255.0).round() as u8;
        *dst = image::Rgb([q(src.x), q(src.y), q(src.z)]);
    }
    let mut out = Vec::new();
    buf.write_to(&mut Cursor::new(&mut out), image::ImageFormat::Png).context("encoding PNG")?;
    Ok(out)
}

/// Encode an image as a linear float32 RGB OpenEXR file's bytes.
pub fn encode_exr(img: &Image) -> Result<Vec<u8>> {
    use exr::prelude::{SpecificChannels, Vec2, WritableImage};
    let (w, h) = (img.width as usize, img.height as usize);
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = img.pixels[pos.y() * w + pos.x()];
        (p.x, p.y, p.z)
    });
    let image = exr::image::Image::from_channels((w, h), channels);
    let mut out = Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).context("encoding EXR")?;
    Ok(out.into_inner())
}

/// Write `img` to `path`, as EXR or PNG by the extension.
pub fn write_image(img: &Image, path: &Path) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("exr") => encode_exr(img)?,
        Some("png") => encode_png(img)?,
        _ => bail!("{}: unknown image type; use a .exr (linear float) or .png (8-bit sRGB) file name", path.display()),
    };
    write_atomic(path, &bytes)
}

/// Read the first layer of an OpenEXR file (R, G and B channels; alpha ignored) into an
/// [`Image`], keeping the `exr` crate's error for callers that map it to their own type.
pub fn read_exr_raw(path: &Path) -> Result<Image, exr::error::Error> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.width() as u32, res.height() as u32),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = glam::Vec3::new(r, g, b);
        },
    )?;
    Ok(img.layer_data.channel_data.pixels)
}

/// Read a linear RGB EXR file (first layer, R, G and B channels) into an [`Image`].
pub fn read_exr(path: &Path) -> Result<Image> {
    read_exr_raw(path).with_context(|| format!("{}: cannot read as an RGB OpenEXR image", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn exr_round_trip_is_exact() {
        let mut img = Image::new(5, 3);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Vec3::new(i as f32 * 0.37, 1e-6 * i as f32, 123.5 - i as f32);
        }
        let dir = std::env::temp_dir().join(format!("evblur-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.exr");
        write_image(&img, &path).unwrap();
        assert_eq!(read_exr(&path).unwrap(), img);
        assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().contains("tmp")));
    }

    #[test]
    fn png_uses_the_srgb_curve() {
        let mut img = Image::new(3, 1);
        img.pixels =
            vec![Vec3::ZERO, Vec3::splat(crate::base::colour::srgb_to_linear(128.0 / 255.0)), Vec3::splat(7.0)];
        let png = image::load_from_memory(&encode_png(&img).unwrap()).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(png.get_pixel(1, 0).0, [128, 128, 128]);
        assert_eq!(png.get_pixel(2, 0).0, [255, 255, 255]);
    }

    #[test]
    fn unwritable_output_is_a_clear_error() {
        let img = Image::new(1, 1);
        let err = write_image(&img, Path::new("/proc/nonexistent-dir/x.png")).unwrap_err();
        assert!(format!("{err:#}").contains("/proc/nonexistent-dir"), "{err:#}");
        let err = write_image(&img, Path::new("x.bmp")).unwrap_err();
        assert!(format!("{err:#}").contains(".exr"), "{err:#}");
    }
}
