//! The linear-frame cache: every rendered frame as a half-float OpenEXR file, keyed by the
//! render key, so that an interrupted run resumes from the last finished frame and exposure or
//! event sweeps re-use the frames instead of re-rendering.
//!
//! Layout under the cache root:
//! ```text
//! <root>/<render key, 16 hex>/key.toml                          the full key and what it covers
//! <root>/<render key>/frames_<fps>fps_<spp>spp_<pattern>/f000123.exr   frame 123
//! <root>/<render key>/sharp_<spp>spp/t000000123000000.exr           sharp render at 123 ms
//! ```
//! Frames are stored as half floats (ZIP-compressed, lossless for halves) and the pipeline always
//! works on the half-rounded values, fresh or cached, so a resumed run writes the same bytes as
//! an uninterrupted one. Half precision (relative step 2^-11, log step 5e-4) is far below any
//! event threshold or 8-bit quantisation step.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use exr::prelude::f16;

use super::plan::Plan;
use super::settings::NoisePattern;
use super::DatasetError;
use crate::base::image::Image;
use crate::image_io::{read_exr_raw, write_atomic};

/// A frame cache for one render key.
#[derive(Clone, Debug)]
pub struct FrameCache {
    /// `<root>/<render key, 16 hex>`.
    pub dir: PathBuf,
}

/// Round every channel to the nearest half float (what the cache stores).
pub fn round_to_f16(img: &mut Image) {
    for p in &mut img.pixels {
        *p = glam::Vec3::new(f16::from_f32(p.x).to_f32(), f16::from_f32(p.y).to_f32(), f16::from_f32(p.z).to_f32());
    }
}

/// Encode an image as half-float RGB EXR bytes (ZIP, lossless for halves).
pub fn encode_exr_f16(img: &Image) -> Vec<u8> {
    use exr::prelude::{Encoding, SpecificChannels, Vec2, WritableImage};
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = img.pixels[pos.y() * w + pos.x()];
        (f16::from_f32(p.x), f16::from_f32(p.y), f16::from_f32(p.z))
    });
    let image = exr::image::Image::from_encoded_channels(
        (w, img.height as usize),
        Encoding { compression: exr::compression::Compression::ZIP16, ..Encoding::FAST_LOSSLESS },
        channels,
    );
    let mut out = Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).expect("writing EXR to memory cannot fail");
    out.into_inner()
}

impl FrameCache {
    /// Open (create) the cache for `plan` under `root`; writes `key.toml`, or checks that an
    /// existing one has the same full key.
    pub fn open(root: &Path, plan: &Plan) -> Result<FrameCache, DatasetError> {
        let dir = root.join(&plan.render_key[..16]);
        std::fs::create_dir_all(&dir)
            .map_err(|e| DatasetError::io(&dir, "cannot create the frame cache (choose another --frames-cache)", e))?;
        let key_file = dir.join("key.toml");
        let text = format!(
            "# evsim frame cache: frames of this scene and these render settings\nrender_key = \"{}\"\nscene = \"{}\"\nscene_key = \"{}\"\nwidth = {}\nheight = {}\n",
            plan.render_key,
            plan.scene_file.display(),
            plan.scene_key,
            plan.config.width,
            plan.config.height
        );
        match std::fs::read_to_string(&key_file) {
            Ok(old) => {
                let key = old.lines().find_map(|l| l.strip_prefix("render_key = \"")).map(|k| k.trim_end_matches('"'));
                if key != Some(plan.render_key.as_str()) {
                    return Err(DatasetError::Conflict {
                        path: key_file,
                        message: "belongs to other render settings (a 64-bit key prefix collision or an edited file); \
                                  delete this cache folder"
                            .into(),
                    });
                }
            }
            Err(_) => write_atomic(&key_file, text.as_bytes())
                .map_err(|e| DatasetError::stage(key_file.display(), format!("{e:#}")))?,
        }
        Ok(FrameCache { dir })
    }

    /// Where frame `k` of a sequence at `fps`, `spp` and `pattern` lives.
    pub fn frame_path(&self, fps: f64, spp: u32, pattern: NoisePattern, k: usize) -> PathBuf {
        let pattern = match pattern {
            NoisePattern::Fixed => "fixed",
            NoisePattern::PerFrame => "per_frame",
        };
        self.dir.join(format!("frames_{fps}fps_{spp}spp_{pattern}")).join(format!("f{k:06}.exr"))
    }

    /// Where the sharp render at time `t_ns` with `spp` samples lives.
    pub fn sharp_path(&self, spp: u32, t_ns: i64) -> PathBuf {
        self.dir.join(format!("sharp_{spp}spp")).join(format!("t{t_ns:015}.exr"))
    }

    /// The cached image at `path`, or `None` when it is not there yet.
    pub fn load(path: &Path) -> Result<Option<Image>, DatasetError> {
        if !path.exists() {
            return Ok(None);
        }
        read_exr_raw(path).map(Some).map_err(|e| {
            DatasetError::stage(
                path.display(),
                format!("cannot read the cached frame ({e}); delete the file to re-render it"),
            )
        })
    }

    /// Store `img` (already rounded to halves) at `path`, atomically.
    pub fn store(path: &Path, img: &Image) -> Result<(), DatasetError> {
        write_atomic(path, &encode_exr_f16(img)).map_err(|e| DatasetError::stage(path.display(), format!("{e:#}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_exr_round_trip_is_exact_on_rounded_values() {
        let mut img = Image::new(7, 5);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = glam::Vec3::new(i as f32 * 0.013, 1.0 / (1.0 + i as f32), 100.0 + i as f32 * 0.7);
        }
        round_to_f16(&mut img);
        let dir = std::env::temp_dir().join(format!("evblur-cache-{}", std::process::id()));
        let path = dir.join("x.exr");
        FrameCache::store(&path, &img).unwrap();
        assert_eq!(FrameCache::load(&path).unwrap().unwrap(), img);
        assert!(FrameCache::load(&dir.join("missing.exr")).unwrap().is_none());
        std::fs::write(dir.join("bad.exr"), b"not an exr").unwrap();
        let e = FrameCache::load(&dir.join("bad.exr")).unwrap_err().to_string();
        assert!(e.contains("bad.exr") && e.contains("delete"), "{e}");
    }
}
