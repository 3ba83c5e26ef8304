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
use std::sync::OnceLock;

use anyhow::{bail, ensure, Context, Result};
use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::sinks::{BackgroundWriter, SinkKind, VizConfig, VizSink, VizSummary};
use super::{intensity, EventConfig, EventSimulator, EventSink, LogFrame, Sensor, Tee};
use crate::base::colour::srgb_to_linear;
use crate::base::image::Image;

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
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    if ext.as_deref() == Some("exr") {
        return crate::image_io::read_exr(path);
    }
    let decoded = image::open(path)
        .with_context(|| format!("{}: cannot read as a PNG image; replace or remove the file", path.display()))?;
    Ok(decode_generic(decoded, linear_input))
}

/// What a frame file stores: `"EXR"`, or `"<n>-bit PNG"`.
fn frame_kind(bits: u16) -> String {
    if bits == 0 {
        "EXR".to_string()
    } else {
        format!("{bits}-bit PNG")
    }
}

/// Any decoded image to linear RGB: the image crate's conversion to `[0, 1]` floats, then the
/// sRGB curve unless `linear_input`.
fn decode_generic(decoded: image::DynamicImage, linear_input: bool) -> Image {
    let rgb = decoded.into_rgb32f();
    let mut img = Image::new(rgb.width(), rgb.height());
    let decode = |v: f32| if linear_input { v } else { srgb_to_linear(v) };
    for (dst, src) in img.pixels.iter_mut().zip(rgb.pixels()) {
        *dst = Vec3::new(decode(src.0[0]), decode(src.0[1]), decode(src.0[2]));
    }
    img
}

/// The PNG sample layouts read through tables: 8- and 16-bit grey, grey + alpha, RGB, RGBA.
const TABLED: usize = 8;

/// The samples of a frame in one of the [`TABLED`] layouts.
enum Samples<'a> {
    /// 8-bit samples, this many per pixel.
    U8(&'a [u8], usize),
    /// 16-bit samples, this many per pixel.
    U16(&'a [u16], usize),
}

/// Which of the [`TABLED`] layouts `image` has (if any), and its samples.
fn tabled(image: &image::DynamicImage) -> Option<(usize, Samples<'_>)> {
    use image::DynamicImage as D;
    use Samples::{U16, U8};
    Some(match image {
        D::ImageLuma8(b) => (0, U8(b.as_raw(), 1)),
        D::ImageLumaA8(b) => (1, U8(b.as_raw(), 2)),
        D::ImageRgb8(b) => (2, U8(b.as_raw(), 3)),
        D::ImageRgba8(b) => (3, U8(b.as_raw(), 4)),
        D::ImageLuma16(b) => (4, U16(b.as_raw(), 1)),
        D::ImageLumaA16(b) => (5, U16(b.as_raw(), 2)),
        D::ImageRgb16(b) => (6, U16(b.as_raw(), 3)),
        D::ImageRgba16(b) => (7, U16(b.as_raw(), 4)),
        _ => return None,
    })
}

/// What [`decode_generic`] makes of every level in layout `kind` (an image of that layout whose
/// pixel `i` has every channel at level `i`): the same conversion as the frames', per layout.
fn level_values(kind: usize, linear_input: bool) -> Vec<f32> {
    use image::{DynamicImage as D, ImageBuffer, Luma, LumaA, Rgb, Rgba};
    let n = if kind < 4 { 256 } else { 65536 };
    let img = match kind {
        0 => D::ImageLuma8(ImageBuffer::from_fn(n, 1, |x, _| Luma([x as u8]))),
        1 => D::ImageLumaA8(ImageBuffer::from_fn(n, 1, |x, _| LumaA([x as u8; 2]))),
        2 => D::ImageRgb8(ImageBuffer::from_fn(n, 1, |x, _| Rgb([x as u8; 3]))),
        3 => D::ImageRgba8(ImageBuffer::from_fn(n, 1, |x, _| Rgba([x as u8; 4]))),
        4 => D::ImageLuma16(ImageBuffer::from_fn(n, 1, |x, _| Luma([x as u16]))),
        5 => D::ImageLumaA16(ImageBuffer::from_fn(n, 1, |x, _| LumaA([x as u16; 2]))),
        6 => D::ImageRgb16(ImageBuffer::from_fn(n, 1, |x, _| Rgb([x as u16; 3]))),
        _ => D::ImageRgba16(ImageBuffer::from_fn(n, 1, |x, _| Rgba([x as u16; 4]))),
    };
    decode_generic(img, linear_input).pixels.iter().map(|p| p.x).collect()
}

/// What the model reads for each level of an 8- or 16-bit frame, made once per run: the
/// decoded channel value ([`decode_generic`]'s), its log, and a grey level's intensity and log.
/// Each entry is computed as [`EventSimulator::step`] computes it from the decoded image.
struct LevelTable {
    value: Vec<f32>,
    value_log: Vec<f32>,
    grey: Vec<f32>,
    grey_log: Vec<f32>,
}

impl LevelTable {
    fn new(values: &[f32], cfg: &EventConfig) -> LevelTable {
        let log = |i: f32| (cfg.log_eps + i).ln();
        let grey: Vec<f32> = values.iter().map(|&v| intensity(cfg.sensor, Vec3::splat(v), 0, 0)).collect();
        let table = LevelTable {
            value: values.to_vec(),
            value_log: values.iter().map(|&v| log(v)).collect(),
            grey_log: grey.iter().map(|&i| log(i)).collect(),
            grey,
        };
        // what LogFrame::new checks per pixel, once per level (decoded levels are in [0, 1])
        let good = |i: &f32, l: &f32| i.is_finite() && *i >= 0.0 && l.is_finite();
        assert!(
            table
                .value
                .iter()
                .zip(&table.value_log)
                .chain(table.grey.iter().zip(&table.grey_log))
                .all(|(i, l)| good(i, l)),
            "a decoded level is not a finite, non-negative intensity"
        );
        table
    }
}

/// The model's view of the frames of one run: tables for 8- and 16-bit PNGs (made on first
/// use), the rest through a decoded [`Image`].
struct FrameReader {
    linear_input: bool,
    cfg: EventConfig,
    /// One table per layout of [`tabled`], made on first use.
    tables: [OnceLock<LevelTable>; TABLED],
}

impl FrameReader {
    fn new(linear_input: bool, cfg: &EventConfig) -> FrameReader {
        FrameReader { linear_input, cfg: cfg.clone(), tables: Default::default() }
    }

    fn table(&self, kind: usize) -> &LevelTable {
        self.tables[kind].get_or_init(|| LevelTable::new(&level_values(kind, self.linear_input), &self.cfg))
    }

    /// One frame as the model reads it, and its bits per channel (0: EXR).
    fn read(&self, path: &Path) -> Result<(LogFrame, u16)> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        let bad = |e| anyhow::Error::new(e).context(format!("{}: bad pixel values", path.display()));
        if ext.as_deref() == Some("exr") {
            let img = crate::image_io::read_exr(path)?;
            return Ok((LogFrame::from_image(&img, &self.cfg).map_err(bad)?, 0));
        }
        let decoded = image::open(path)
            .with_context(|| format!("{}: cannot read as a PNG image; replace or remove the file", path.display()))?;
        let color = decoded.color();
        let bits = color.bits_per_pixel() / u16::from(color.channel_count());
        let width = decoded.width();
        let levels = tabled(&decoded).map(|(kind, samples)| match samples {
            Samples::U8(v, n) => self.levels(width, v, n, self.table(kind)),
            Samples::U16(v, n) => self.levels(width, v, n, self.table(kind)),
        });
        let frame = match levels {
            Some((i, l)) => LogFrame::from_checked_levels(decoded.width(), decoded.height(), i, l),
            None => LogFrame::from_image(&decode_generic(decoded, self.linear_input), &self.cfg),
        };
        Ok((frame.map_err(bad)?, bits))
    }

    /// Intensities and logs of a frame of `n` samples per pixel (grey or RGB first, alpha
    /// ignored) through `table`.
    fn levels<T: Copy + Into<usize>>(
        &self,
        width: u32,
        samples: &[T],
        n: usize,
        table: &LevelTable,
    ) -> (Vec<f32>, Vec<f32>) {
        let pixels = samples.len() / n;
        let (mut inten, mut log) = (vec![0.0f32; pixels], vec![0.0f32; pixels]);
        let w = width.max(1) as usize;
        let out = inten.iter_mut().zip(log.iter_mut()).zip(samples.chunks_exact(n));
        match (n < 3, self.cfg.sensor) {
            // grey: one table lookup each
            (true, _) => {
                for ((i, l), s) in out {
                    (*i, *l) = (table.grey[s[0].into()], table.grey_log[s[0].into()]);
                }
            }
            // RGB on a mosaic: the pixel's channel
            (false, Sensor::Rggb) => {
                for (k, ((i, l), s)) in out.enumerate() {
                    let c = s[channel_of(k % w, k / w)].into();
                    (*i, *l) = (table.value[c], table.value_log[c]);
                }
            }
            // RGB luma: the logarithm per pixel
            (false, Sensor::Mono) => {
                for ((i, l), s) in out {
                    let rgb = Vec3::new(table.value[s[0].into()], table.value[s[1].into()], table.value[s[2].into()]);
                    *i = intensity(Sensor::Mono, rgb, 0, 0);
                    *l = (self.cfg.log_eps + *i).ln();
                }
            }
        }
        (inten, log)
    }
}

/// The RGB channel an RGGB mosaic reads at `(x, y)` (as [`intensity`]).
fn channel_of(x: usize, y: usize) -> usize {
    match (x & 1, y & 1) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// Frames decoded ahead at once, in parallel: enough to keep the cores busy, at most about
/// 64 MB of decoded frames (two batches are alive: the one stepped and the next decoded).
fn decode_batch_len(width: u32, height: u32) -> usize {
    let frame_bytes = width as usize * height as usize * 2 * std::mem::size_of::<f32>();
    ((64 << 20) / frame_bytes.max(1)).clamp(2, 32)
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
    let reader = FrameReader::new(job.linear_input, &job.config);
    let (first, first_bits) = reader.read(&frames[0])?;
    let (width, height) = (first.width(), first.height());
    let mut sim = EventSimulator::new(job.config.clone(), width, height)?;
    let mut sink = BackgroundWriter::create(&job.out, job.kind)?;
    let mut viz = job.viz.clone().map(|cfg| VizSink::create(cfg, width, height)).transpose()?;
    if let Some(pb) = progress {
        pb.set_length(frames.len() as u64);
    }

    let mut summary = FramesSummary { frames: frames.len(), width, height, ..FramesSummary::default() };
    // is a decoded frame like the first?
    let check = |path: &Path, decoded: Result<(LogFrame, u16)>| -> Result<LogFrame> {
        let (img, bits) = decoded?;
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
        if (img.width(), img.height()) != (width, height) {
            bail!(
                "{}: is {}x{} but {} is {width}x{height}; every frame must have the same size",
                path.display(),
                img.width(),
                img.height(),
                frames[0].display()
            );
        }
        Ok(img)
    };
    // the model over consecutive good frames
    let mut step = |paths: &[PathBuf], times: &[i64], batch: &[LogFrame]| -> Result<()> {
        let stats = match viz.as_mut() {
            Some(viz) => sim.step_log_batch(batch, times, &mut Tee { a: &mut sink, b: viz } as &mut dyn EventSink),
            None => sim.step_log_batch(batch, times, &mut sink as &mut dyn EventSink),
        };
        let stats = stats.with_context(|| {
            format!(
                "{} .. {}: event model failed on these frames",
                paths[0].display(),
                paths[paths.len() - 1].display()
            )
        })?;
        for s in stats {
            summary.on += s.on;
            summary.off += s.off;
            summary.max_change_c = summary.max_change_c.max(s.max_change_c);
            summary.undersampled_intervals += usize::from(s.undersampled());
        }
        if let Some(pb) = progress {
            pb.inc(batch.len() as u64);
        }
        Ok(())
    };
    // frame 0 sets the references; the rest are decoded a batch at a time in parallel (the next
    // batch while the model runs through the current one), then run through the model at once
    step(&frames[..1], &times[..1], &[first])?;
    let batch = decode_batch_len(width, height);
    let batches: Vec<(&[PathBuf], &[i64])> = frames[1..].chunks(batch).zip(times[1..].chunks(batch)).collect();
    let decode =
        |paths: &[PathBuf]| -> Vec<Result<(LogFrame, u16)>> { paths.par_iter().map(|p| reader.read(p)).collect() };
    let mut next = batches.first().map(|(paths, _)| decode(paths)).unwrap_or_default();
    for (i, &(paths, ts)) in batches.iter().enumerate() {
        let current = std::mem::take(&mut next);
        // in place: the event sink need not be Send; the decode runs on the pool meanwhile
        rayon::in_place_scope(|scope| {
            if let Some((paths, _)) = batches.get(i + 1) {
                let next = &mut next;
                scope.spawn(move |_| *next = decode(paths));
            }
            // the frames before the first bad one go through the model, then its error
            let mut good = Vec::with_capacity(current.len());
            let mut bad = None;
            for (path, decoded) in paths.iter().zip(current) {
                match check(path, decoded) {
                    Ok(frame) => good.push(frame),
                    Err(e) => {
                        bad = Some(e);
                        break;
                    }
                }
            }
            if !good.is_empty() {
                step(&paths[..good.len()], &ts[..good.len()], &good)?;
            }
            bad.map_or(Ok(()), Err)
        })?;
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
    fn png_levels_from_tables_equal_the_decoded_image_path() {
        let dir = std::env::temp_dir().join(format!("evblur-frames-levels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (7u32, 5u32);
        let mut state = 0x9e3779b97f4a7c15u64;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let mut v8 = |n: usize| (0..n).map(|_| next() as u8).collect::<Vec<u8>>();
        let px = (w * h) as usize;
        let images = [
            ("l8", image::DynamicImage::ImageLuma8(image::ImageBuffer::from_raw(w, h, v8(px)).unwrap())),
            ("la8", image::DynamicImage::ImageLumaA8(image::ImageBuffer::from_raw(w, h, v8(2 * px)).unwrap())),
            ("rgb8", image::DynamicImage::ImageRgb8(image::ImageBuffer::from_raw(w, h, v8(3 * px)).unwrap())),
            ("rgba8", image::DynamicImage::ImageRgba8(image::ImageBuffer::from_raw(w, h, v8(4 * px)).unwrap())),
            (
                "l16",
                image::DynamicImage::ImageLuma16(
                    image::ImageBuffer::from_raw(w, h, v8(px).iter().map(|&b| u16::from(b) * 257 + 3).collect())
                        .unwrap(),
                ),
            ),
            (
                "rgb16",
                image::DynamicImage::ImageRgb16(
                    image::ImageBuffer::from_raw(w, h, v8(3 * px).iter().map(|&b| u16::from(b) * 251).collect())
                        .unwrap(),
                ),
            ),
        ];
        for (name, img) in images {
            let path = dir.join(format!("{name}.png"));
            img.save(&path).unwrap();
            for sensor in [Sensor::Mono, Sensor::Rggb] {
                for linear in [false, true] {
                    let cfg = EventConfig { sensor, log_eps: 0.01, ..EventConfig::default() };
                    let (frame, bits) = FrameReader::new(linear, &cfg).read(&path).unwrap();
                    let reference = LogFrame::from_image(&read_frame(&path, linear).unwrap(), &cfg).unwrap();
                    assert_eq!(bits, if name.ends_with("16") { 16 } else { 8 });
                    let (a, b) = (frame.into_parts(), reference.into_parts());
                    let bits_of = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits_of(&a.0), bits_of(&b.0), "{name} {sensor:?} linear {linear}: intensity");
                    assert_eq!(bits_of(&a.1), bits_of(&b.1), "{name} {sensor:?} linear {linear}: log");
                }
            }
        }
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
