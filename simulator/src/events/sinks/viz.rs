//! Event visualisation: a [`VizSink`] that turns the event stream into one image per time window
//! and an event-rate table, for looking at a simulated sequence without a Python notebook.
//!
//! # Window images
//! Time is cut into windows of [`VizConfig::window_ns`] aligned to multiples of it
//! (`k = floor(t / window_ns)`). Image `DIR/events_{i:06}.png` shows window `k0 + i`, where `k0`
//! is the window of the first event, i.e. the events with
//! `t in [(k0 + i) window_ns, (k0 + i + 1) window_ns)`. Windows without events in between are
//! written too (blank), so the image index maps to time; [`VizSummary::t_first_window_ns`] gives
//! `k0 window_ns`. The image is `width x height` 8-bit RGB (stored as is, no sRGB curve) on a
//! **white** background. Per pixel, with `on` and `off` its event counts in the window,
//! `n = on + off` and `a = min(n, saturate_count) / saturate_count`, the colour is chosen by
//! **majority** and its strength by `n`: the channels that are not the colour fade from 255 to 0,
//! `f = round(255 (1 - a))`:
//! - `on > off`: red `(255, f, f)`;
//! - `off > on`: blue `(f, f, 255)`;
//! - `on == off > 0`: magenta `(255, f, 255)`;
//! - no event: white `(255, 255, 255)`.
//!
//! # Event rate
//! Events are also counted per rate bin of [`VizConfig::rate_bin_ns`] (aligned the same way,
//! from the first event's bin to the last's, empty bins included). `finish()` writes
//! `DIR/event_rate.csv` with the columns `t_start_s,on,off,total,rate_hz` (`t_start_s` the bin
//! start in seconds with 9 exact decimals, `rate_hz = total 1e9 / rate_bin_ns`) and returns a
//! [`VizSummary`]: the ON/OFF totals, the peak rate and its bin, the mean rate over the binned span.
//!
//! # Memory and files
//! Streamed: memory is one window of per-pixel counts (`4 width height` bytes) plus the rate
//! bins, a `Vec` of 16 bytes per bin that grows with the covered time (1 ms bins: 16 kB per
//! second). Every file is written atomically ([`write_atomic`]); a window image is written when a
//! later event closes its window. A sink dropped without `finish()` leaves the images of the
//! windows closed so far, never the last window nor `event_rate.csv` (its presence marks a
//! complete run). Files of an earlier run in `DIR` are not removed.

use std::io::{self, Cursor};
use std::path::{Path, PathBuf};

use crate::events::{Event, EventSink};
use crate::image_io::write_atomic;

/// Name of the event-rate table in the visualisation folder.
pub const RATE_CSV: &str = "event_rate.csv";

/// What to draw and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VizConfig {
    /// Folder of the window images and `event_rate.csv` (created if missing).
    pub dir: PathBuf,
    /// Length of one image window, ns (> 0). Shorter windows show faster motion, with fewer
    /// events per image.
    pub window_ns: i64,
    /// Length of one event-rate bin, ns (> 0).
    pub rate_bin_ns: i64,
    /// Events per pixel and window at which its colour is full (>= 1); fewer fade to white.
    pub saturate_count: u16,
}

impl VizConfig {
    /// Default window: 10 ms.
    pub const DEFAULT_WINDOW_NS: i64 = 10_000_000;
    /// Default rate bin: 1 ms.
    pub const DEFAULT_RATE_BIN_NS: i64 = 1_000_000;
    /// Default saturating count: 4 events.
    pub const DEFAULT_SATURATE_COUNT: u16 = 4;

    /// The defaults (10 ms windows, 1 ms rate bins, full colour at 4 events) into `dir`.
    pub fn new(dir: impl Into<PathBuf>) -> VizConfig {
        VizConfig {
            dir: dir.into(),
            window_ns: Self::DEFAULT_WINDOW_NS,
            rate_bin_ns: Self::DEFAULT_RATE_BIN_NS,
            saturate_count: Self::DEFAULT_SATURATE_COUNT,
        }
    }

    /// Check the lengths and the count.
    pub fn validate(&self) -> Result<(), VizConfigError> {
        for (field, value) in [("window_ns", self.window_ns), ("rate_bin_ns", self.rate_bin_ns)] {
            if value <= 0 {
                return Err(VizConfigError::NotPositive { field, value });
            }
        }
        if self.saturate_count == 0 {
            return Err(VizConfigError::NotPositive { field: "saturate_count", value: 0 });
        }
        Ok(())
    }
}

/// Why a [`VizConfig`] is invalid.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum VizConfigError {
    /// A length or count is zero or negative.
    #[error("visualisation {field} = {value}; it must be positive (at least 1 ns / 1 event)")]
    NotPositive {
        /// The field.
        field: &'static str,
        /// Its value.
        value: i64,
    },
}

/// What a visualisation run wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VizSummary {
    /// ON events seen.
    pub on: u64,
    /// OFF events seen.
    pub off: u64,
    /// Window images written (blank ones included).
    pub windows: u64,
    /// Start of the window of image 0, ns (None without events).
    pub t_first_window_ns: Option<i64>,
    /// Largest per-bin rate, events per second (0 without events).
    pub peak_rate_hz: f64,
    /// Start of the bin of the peak rate, ns (the first such bin on ties; 0 without events).
    pub peak_t_ns: i64,
    /// Events per second over the binned span (first event's bin to the last's).
    pub mean_rate_hz: f64,
}

/// Draws event windows into PNG images and counts the event rate; see the [module](self) docs.
pub struct VizSink {
    cfg: VizConfig,
    width: u32,
    height: u32,
    /// Per-pixel `[on, off]` counts of the open window (saturating), row-major.
    counts: Vec<[u16; 2]>,
    /// Window index `floor(t / window_ns)` of the first event (None before any).
    first_window: Option<i64>,
    /// Window index of the open window.
    open_window: i64,
    /// Images written.
    windows: u64,
    /// The encoded blank image, made on the first gap.
    blank_png: Option<Vec<u8>>,
    /// Bin index `floor(t / rate_bin_ns)` of `bins[0]`.
    first_bin: i64,
    /// `[on, off]` per rate bin from the first event's bin on.
    bins: Vec<[u64; 2]>,
}

impl VizSink {
    /// A sink for `width x height` events drawing into `cfg.dir` (created now).
    pub fn create(cfg: VizConfig, width: u32, height: u32) -> io::Result<VizSink> {
        cfg.validate().map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        std::fs::create_dir_all(&cfg.dir).map_err(|e| {
            super::io_err(&cfg.dir, "cannot create the visualisation folder; choose another --viz-dir", e)
        })?;
        Ok(VizSink {
            cfg,
            width,
            height,
            counts: vec![[0; 2]; width as usize * height as usize],
            first_window: None,
            open_window: 0,
            windows: 0,
            blank_png: None,
            first_bin: 0,
            bins: Vec::new(),
        })
    }

    /// The path of image `index`.
    pub fn window_path(dir: &Path, index: u64) -> PathBuf {
        dir.join(format!("events_{index:06}.png"))
    }

    /// Write the open window's image and clear the counts.
    fn close_window(&mut self) -> io::Result<()> {
        let png = encode_rgb_png(self.width, self.height, window_rgb(&self.counts, self.cfg.saturate_count))?;
        self.write_next(&png)?;
        self.counts.fill([0; 2]);
        Ok(())
    }

    /// Write `png` as the next image.
    fn write_next(&mut self, png: &[u8]) -> io::Result<()> {
        let path = Self::window_path(&self.cfg.dir, self.windows);
        write_atomic(&path, png).map_err(|e| io::Error::other(format!("{e:#}")))?;
        self.windows += 1;
        Ok(())
    }

    /// Close the open window and write blank images up to (not including) window `k`.
    fn advance_to(&mut self, k: i64) -> io::Result<()> {
        self.close_window()?;
        for _ in self.open_window + 1..k {
            let blank = match self.blank_png.take() {
                Some(b) => b,
                None => encode_rgb_png(self.width, self.height, window_rgb(&self.counts, self.cfg.saturate_count))?,
            };
            let r = self.write_next(&blank);
            self.blank_png = Some(blank);
            r?;
        }
        self.open_window = k;
        Ok(())
    }

    /// Write the last window and `event_rate.csv`; returns the summary.
    pub fn finish(mut self) -> io::Result<VizSummary> {
        if self.first_window.is_some() {
            self.close_window()?;
        }
        let mut csv = String::from("t_start_s,on,off,total,rate_hz\n");
        let (mut on, mut off) = (0u64, 0u64);
        let (mut peak, mut peak_t_ns) = (0.0f64, 0i64);
        for (i, &[n_on, n_off]) in self.bins.iter().enumerate() {
            let t_ns = (self.first_bin + i as i64) * self.cfg.rate_bin_ns;
            let total = n_on + n_off;
            let rate = total as f64 * 1e9 / self.cfg.rate_bin_ns as f64;
            if rate > peak {
                (peak, peak_t_ns) = (rate, t_ns);
            }
            (on, off) = (on + n_on, off + n_off);
            csv.push_str(&format!("{},{n_on},{n_off},{total},{rate}\n", seconds(t_ns)));
        }
        write_atomic(&self.cfg.dir.join(RATE_CSV), csv.as_bytes()).map_err(|e| io::Error::other(format!("{e:#}")))?;
        let span_ns = self.bins.len() as f64 * self.cfg.rate_bin_ns as f64;
        Ok(VizSummary {
            on,
            off,
            windows: self.windows,
            t_first_window_ns: self.first_window.map(|k| k * self.cfg.window_ns),
            peak_rate_hz: peak,
            peak_t_ns,
            mean_rate_hz: if span_ns > 0.0 { (on + off) as f64 * 1e9 / span_ns } else { 0.0 },
        })
    }
}

impl EventSink for VizSink {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        for e in events {
            if e.x as u32 >= self.width || e.y as u32 >= self.height {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("event at ({}, {}) is outside the {}x{} visualisation", e.x, e.y, self.width, self.height),
                ));
            }
            // Window: close the open one (and write blank ones) when the event is past it.
            let k = e.t_ns.div_euclid(self.cfg.window_ns);
            match self.first_window {
                None => (self.first_window, self.open_window) = (Some(k), k),
                Some(_) if k > self.open_window => self.advance_to(k)?,
                Some(_) if k < self.open_window => {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        format!("event at t = {} ns goes back in time to an already written window", e.t_ns),
                    ))
                }
                Some(_) => {}
            }
            let c = &mut self.counts[e.y as usize * self.width as usize + e.x as usize];
            let pol = usize::from(e.p <= 0);
            c[pol] = c[pol].saturating_add(1);

            // Rate bin: grow the table up to this event's bin.
            let b = e.t_ns.div_euclid(self.cfg.rate_bin_ns);
            if self.bins.is_empty() {
                self.first_bin = b;
            }
            let i = (b - self.first_bin) as usize;
            if i >= self.bins.len() {
                self.bins.resize(i + 1, [0; 2]);
            }
            self.bins[i][pol] += 1;
        }
        Ok(())
    }
}

/// The colour of a pixel with `on` and `off` events (see the module docs).
pub fn pixel_rgb(on: u16, off: u16, saturate_count: u16) -> [u8; 3] {
    let n = (on as u32 + off as u32).min(saturate_count as u32);
    let f = (255.0 * (1.0 - n as f32 / saturate_count as f32)).round() as u8;
    match on.cmp(&off) {
        std::cmp::Ordering::Greater => [255, f, f],
        std::cmp::Ordering::Less => [f, f, 255],
        std::cmp::Ordering::Equal => [255, f, 255],
    }
}

/// The RGB bytes of one window image.
fn window_rgb(counts: &[[u16; 2]], saturate_count: u16) -> Vec<u8> {
    counts.iter().flat_map(|&[on, off]| pixel_rgb(on, off, saturate_count)).collect()
}

/// Encode 8-bit RGB bytes as PNG, stored as is.
fn encode_rgb_png(width: u32, height: u32, rgb: Vec<u8>) -> io::Result<Vec<u8>> {
    let img = image::RgbImage::from_raw(width, height, rgb).expect("one RGB triple per pixel");
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), image::ImageFormat::Png).map_err(io::Error::other)?;
    Ok(out)
}

/// `t_ns` as seconds with 9 exact decimals.
fn seconds(t_ns: i64) -> String {
    let sign = if t_ns < 0 { "-" } else { "" };
    let a = t_ns.unsigned_abs();
    format!("{sign}{}.{:09}", a / 1_000_000_000, a % 1_000_000_000)
}

#[cfg(test)]
#[path = "viz_tests.rs"]
mod tests;
