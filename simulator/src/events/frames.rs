//! The event model over a folder of frames: what `evsim events` runs.
//!
//! Frames are the `.png` and `.exr` files of a folder, sorted by file name (zero-pad the
//! numbers); other files are ignored. EXR is linear light; PNG is decoded to `[0, 1]` and
//! linearised with the sRGB curve unless `linear_input` is set. Frame times come from a text file,
//! one number per line (blank lines and `#` comments skipped), in seconds, microseconds or
//! nanoseconds, converted to integer nanoseconds (rounded to nearest).
//!
//! Everything that can be checked before the first event is (frame list, timestamp count and
//! order, the config, the output type); a frame that fails later (unreadable, another size,
//! another format or bit depth than the first) stops the run and, the writer being atomic, leaves no output file.
//!
//! With [`FramesJob::viz`] set, the events also go (through a [`Tee`]) to a [`VizSink`]: one PNG
//! per time window and an event-rate table, whose summary is [`FramesSummary::viz`].

use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use indicatif::ProgressBar;

use super::sinks::{EventWriter, SinkKind, VizConfig, VizSink, VizSummary};
use super::{EventConfig, EventSimulator, EventSink, Tee};
use crate::render::film::Image;
use crate::scene::texture::srgb_to_linear;

/// The unit of the numbers in a timestamps file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum TimeUnit {
    /// Seconds (may have decimals).
    #[default]
    S,
    /// Microseconds.
    Us,
    /// Nanoseconds.
    Ns,
}

impl TimeUnit {
    /// Nanoseconds per unit.
    pub fn ns(self) -> f64 {
        match self {
            TimeUnit::S => 1e9,
            TimeUnit::Us => 1e3,
            TimeUnit::Ns => 1.0,
        }
    }
}

/// Everything one run needs, resolved.
#[derive(Clone, Debug)]
pub struct FramesJob {
    /// Folder of `.png` / `.exr` frames.
    pub frames: PathBuf,
    /// Text file with one frame time per line.
    pub timestamps: PathBuf,
    /// Unit of the frame times.
    pub unit: TimeUnit,
    /// PNG frames already hold linear values (skip the sRGB decoding).
    pub linear_input: bool,
    /// The event file to write.
    pub out: PathBuf,
    /// Its format.
    pub kind: SinkKind,
    /// The event model's settings.
    pub config: EventConfig,
    /// Also draw the events (window images + event-rate table) into a folder; None: do not.
    pub viz: Option<VizConfig>,
}

/// What a run produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FramesSummary {
    /// Frames read.
    pub frames: usize,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// ON events written.
    pub on: u64,
    /// OFF events written.
    pub off: u64,
    /// Largest per-pixel `|dL| / C` over all frame intervals; above 1 the frame rate is too low.
    pub max_change_c: f32,
    /// Frame intervals where some pixel changed by more than one threshold.
    pub undersampled_intervals: usize,
    /// What the visualisation wrote (when [`FramesJob::viz`] is set).
    pub viz: Option<VizSummary>,
}

/// The frame files of `dir` (`.png`, `.exr`, any case), sorted by name.
pub fn list_frames(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).with_context(|| {
        format!("{}: cannot list the frames folder; pass an existing folder to --frames", dir.display())
    })?;
    let mut frames = Vec::new();
    for entry in entries {
        let path = entry.with_context(|| format!("{}: cannot list the frames folder", dir.display()))?.path();
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("png" | "exr")) && path.is_file() {
            frames.push(path);
        }
    }
    frames.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    ensure!(
        frames.len() >= 2,
        "{}: holds {} .png/.exr frame(s); the event model needs at least 2",
        dir.display(),
        frames.len()
    );
    Ok(frames)
}

/// Read a timestamps file into strictly increasing integer nanoseconds.
pub fn read_timestamps(path: &Path, unit: TimeUnit) -> Result<Vec<i64>> {
    let text = std::fs::read_to_string(path).with_context(|| {
        format!("{}: cannot read the timestamps file; pass an existing text file to --timestamps", path.display())
    })?;
    let mut times: Vec<i64> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = || {
            format!("{}: line {}: \"{line}\" is not one number; write one frame time per line", path.display(), i + 1)
        };
        // Integers convert exactly; decimals through f64, rounded to the nearest ns.
        let t = match line.parse::<i64>() {
            Ok(v) if unit == TimeUnit::Ns => Some(v),
            _ => line
                .parse::<f64>()
                .ok()
                .map(|v| v * unit.ns())
                .filter(|v| v.is_finite() && v.abs() < 9e18)
                .map(|v| v.round() as i64),
        };
        let t = t.with_context(bad)?;
        if let Some(&prev) = times.last() {
            ensure!(
                t > prev,
                "{}: line {}: time {t} ns is not after the previous one ({prev} ns); frame times must strictly increase (is --timestamps-unit right?)",
                path.display(),
                i + 1
            );
        }
        times.push(t);
    }
    Ok(times)
}

/// Read one frame as linear RGB (PNG decoded from sRGB unless `linear_input`).
pub fn read_frame(path: &Path, linear_input: bool) -> Result<Image> {
    read_frame_kind(path, linear_input).map(|(img, _)| img)
}

/// What a frame file stores: `"EXR"`, or `"<n>-bit PNG"`.
fn frame_kind(bits: u16) -> String {
    if bits == 0 {
        "EXR".to_string()
    } else {
        format!("{bits}-bit PNG")
    }
}

/// [`read_frame`], also returning the bits per channel of a PNG (0 for EXR).
fn read_frame_kind(path: &Path, linear_input: bool) -> Result<(Image, u16)> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    if ext.as_deref() == Some("exr") {
        return crate::image_io::read_exr(path).map(|img| (img, 0));
    }
    let decoded = image::open(path)
        .with_context(|| format!("{}: cannot read as a PNG image; replace or remove the file", path.display()))?;
    let color = decoded.color();
    let bits = color.bits_per_pixel() / u16::from(color.channel_count());
    let rgb = decoded.into_rgb32f();
    let mut img = Image::new(rgb.width(), rgb.height());
    let decode = |v: f32| if linear_input { v } else { srgb_to_linear(v) };
    for (dst, src) in img.pixels.iter_mut().zip(rgb.pixels()) {
        *dst = glam::Vec3::new(decode(src.0[0]), decode(src.0[1]), decode(src.0[2]));
    }
    Ok((img, bits))
}

/// Run the event model over the frames of `job` and write the event file; `progress` (if any)
/// counts frames.
pub fn run_on_frames(job: &FramesJob, progress: Option<&ProgressBar>) -> Result<FramesSummary> {
    // Check what can be checked before writing anything.
    let frames = list_frames(&job.frames)?;
    let times = read_timestamps(&job.timestamps, job.unit)?;
    if times.len() != frames.len() {
        bail!(
            "{}: has {} timestamps but {} holds {} frames; give exactly one time per frame",
            job.timestamps.display(),
            times.len(),
            job.frames.display(),
            frames.len()
        );
    }
    job.config.validate()?;
    if let Some(viz) = &job.viz {
        viz.validate()?;
    }
    let (first, first_bits) = read_frame_kind(&frames[0], job.linear_input)?;
    let (width, height) = (first.width, first.height);
    let mut sim = EventSimulator::new(job.config.clone(), width, height)?;
    let mut sink = EventWriter::create(&job.out, job.kind)?;
    let mut viz = job.viz.clone().map(|cfg| VizSink::create(cfg, width, height)).transpose()?;
    if let Some(pb) = progress {
        pb.set_length(frames.len() as u64);
    }

    let mut summary = FramesSummary { frames: frames.len(), width, height, ..FramesSummary::default() };
    let mut frame = Some(first);
    for (path, &t_ns) in frames.iter().zip(&times) {
        let img = match frame.take() {
            Some(img) => img,
            None => {
                let (img, bits) = read_frame_kind(path, job.linear_input)?;
                // another depth or format quantises the scene differently: events at every pixel
                if bits != first_bits {
                    bail!(
                        "{}: is a {} but {} is a {}; every frame must have the same format and bit depth \
                         (re-export the sequence in one)",
                        path.display(),
                        frame_kind(bits),
                        frames[0].display(),
                        frame_kind(first_bits)
                    );
                }
                img
            }
        };
        if (img.width, img.height) != (width, height) {
            bail!(
                "{}: is {}x{} but {} is {width}x{height}; every frame must have the same size",
                path.display(),
                img.width,
                img.height,
                frames[0].display()
            );
        }
        let stats = match viz.as_mut() {
            Some(viz) => sim.step(&img, t_ns, &mut Tee { a: &mut sink, b: viz } as &mut dyn EventSink),
            None => sim.step(&img, t_ns, &mut sink as &mut dyn EventSink),
        };
        let stats = stats.with_context(|| format!("{}: event model failed on this frame", path.display()))?;
        summary.on += stats.on;
        summary.off += stats.off;
        summary.max_change_c = summary.max_change_c.max(stats.max_change_c);
        summary.undersampled_intervals += usize::from(stats.undersampled());
        if let Some(pb) = progress {
            pb.inc(1);
        }
    }
    let written = sink.finish()?;
    debug_assert_eq!(written, summary.on + summary.off);
    summary.viz = viz.map(VizSink::finish).transpose()?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        std::fs::create_dir_all(dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn timestamps_parse_in_every_unit() {
        let dir = std::env::temp_dir().join(format!("evblur-frames-ts-{}", std::process::id()));
        let p = write(&dir, "t.txt", "# frame times\n0.0\n\n0.001\n0.0025\n");
        assert_eq!(read_timestamps(&p, TimeUnit::S).unwrap(), [0, 1_000_000, 2_500_000]);
        let p = write(&dir, "us.txt", "10\n20.5\n");
        assert_eq!(read_timestamps(&p, TimeUnit::Us).unwrap(), [10_000, 20_500]);
        let p = write(&dir, "ns.txt", "1700000000000000001\n1700000000000000002\n");
        assert_eq!(read_timestamps(&p, TimeUnit::Ns).unwrap(), [1_700_000_000_000_000_001, 1_700_000_000_000_000_002]);
    }

    #[test]
    fn bad_timestamps_name_the_line_and_the_fix() {
        let dir = std::env::temp_dir().join(format!("evblur-frames-bad-{}", std::process::id()));
        let p = write(&dir, "dec.txt", "0.1\n0.2\n0.2\n");
        let e = format!("{:#}", read_timestamps(&p, TimeUnit::S).unwrap_err());
        assert!(e.contains("dec.txt: line 3") && e.contains("strictly increase"), "{e}");
        let p = write(&dir, "two.txt", "0 0.1\n");
        let e = format!("{:#}", read_timestamps(&p, TimeUnit::S).unwrap_err());
        assert!(e.contains("two.txt: line 1") && e.contains("one frame time per line"), "{e}");
    }
}
