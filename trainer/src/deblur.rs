//! Pluggable image deblurring before training: the "2-D deblurring network, then NeRF"
//! baselines (MPRNet, PVDNet, EFNet + NeRF) as any program that reads a blurry PNG and writes a
//! deblurred one.
//!
//! [`deblur_views`] runs `images.deblur`'s shell command once per training view, with
//! `{input}` replaced by the view's PNG in `images_1/` and `{output}` by the PNG to write (both
//! shell-quoted). Results are cached under the run folder in `deblurred/`: `<view>.png` and
//! `<view>.key` (the command and a hash of the input file), so a resumed run or a second run with
//! the same command reuses them; a changed command or input reruns the view. The output is
//! written to a temporary name and renamed once the command succeeded and the file checked.
//! The event double integral (`images = "edi"`) is the built-in deblurring stage.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::data::dataset::Dataset;
use crate::data::image::RgbImage;
use crate::error::TrainError;

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(FNV_OFFSET, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3))
}

/// `s` quoted for `sh` (single quotes, embedded ones escaped).
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// The deblurred images of `views` (indices into `data.views`), in that order, by `command`
/// (module doc), cached in `run/deblurred/` (a temporary folder when `run` is `None`).
pub fn deblur_views(
    data: &Dataset,
    views: &[usize],
    command: &str,
    run: Option<&Path>,
) -> Result<Vec<RgbImage>, TrainError> {
    let dir = match run {
        Some(r) => r.join("deblurred"),
        None => std::env::temp_dir().join(format!("evblur-deblur-{}", std::process::id())),
    };
    std::fs::create_dir_all(&dir)
        .map_err(|e| TrainError::io(&dir, e, "make the run folder writable or choose another --out"))?;
    views.iter().map(|&v| deblur_one(data, v, command, &dir)).collect()
}

fn deblur_one(data: &Dataset, v: usize, command: &str, dir: &Path) -> Result<RgbImage, TrainError> {
    let view = &data.views[v];
    let input = data.dir.join("images_1").join(&view.name);
    let bytes = std::fs::read(&input)
        .map_err(|e| TrainError::io(&input, e, "the deblurring command reads the dataset's blurry PNGs"))?;
    let key = format!("{command}\n{:016x}\n", fnv1a(&bytes));
    let stem = Path::new(&view.name).file_stem().map_or_else(|| view.name.clone(), |s| s.to_string_lossy().into());
    let (out, key_path) = (dir.join(format!("{stem}.png")), dir.join(format!("{stem}.key")));
    if std::fs::read_to_string(&key_path).ok().as_deref() == Some(key.as_str()) {
        if let Ok(img) = read_output(&out, view.image.width, view.image.height, command) {
            return Ok(img);
        }
    }
    let tmp: PathBuf = dir.join(format!("{stem}.tmp.png"));
    let _ = std::fs::remove_file(&tmp);
    let line = command
        .replace("{input}", &quote(&input.to_string_lossy()))
        .replace("{output}", &quote(&tmp.to_string_lossy()));
    let result = Command::new("sh")
        .arg("-c")
        .arg(&line)
        .output()
        .map_err(|e| TrainError::io(&input, e, "the deblurring command runs through sh; install a POSIX shell"))?;
    if !result.status.success() {
        let stderr = String::from_utf8_lossy(&result.stderr);
        return Err(TrainError::Run {
            path: input,
            what: format!(
                "the deblurring command `{line}` failed ({}){}",
                result.status,
                if stderr.trim().is_empty() { String::new() } else { format!(": {}", stderr.trim()) }
            ),
            fix: "fix images.deblur (run the command by hand on this file) or train on the blurry images".into(),
        });
    }
    let img = read_output(&tmp, view.image.width, view.image.height, command)?;
    std::fs::rename(&tmp, &out).map_err(|e| TrainError::io(&out, e, "make the run folder writable"))?;
    simulator::image_io::write_atomic(&key_path, key.as_bytes()).map_err(|e| {
        TrainError::run(&key_path, format!("cannot write the cache key: {e:#}"), "make the run folder writable")
    })?;
    Ok(img)
}

/// Reads a command's output PNG and checks its size.
fn read_output(path: &Path, width: u32, height: u32, command: &str) -> Result<RgbImage, TrainError> {
    if !path.exists() {
        return Err(TrainError::Run {
            path: path.to_path_buf(),
            what: format!("the deblurring command `{command}` succeeded but wrote no image"),
            fix: "make the command write an 8-bit RGB PNG to {output}".into(),
        });
    }
    let img = RgbImage::read_png(path, &path.to_string_lossy())?;
    if (img.width, img.height) != (width, height) {
        return Err(TrainError::Run {
            path: path.to_path_buf(),
            what: format!("the deblurred image is {}x{}, the view {width}x{height}", img.width, img.height),
            fix: "make the command keep the image size".into(),
        });
    }
    Ok(img)
}
