//! The per-pixel event model: [`EventSimulator`] (ESIM's ideal model plus the optional v2e
//! non-idealities of [`NoiseConfig`](super::NoiseConfig)).

use glam::Vec3;
use rayon::prelude::*;

use super::config::{EventConfig, MismatchMode, Refractory, RefractoryMode, Sensor};
use super::noise;
use super::sink::{Event, EventSink};
use super::EventError;
use crate::base::image::Image;
use crate::base::sampling::Rng;

/// Rec.709 luma weights applied to linear RGB in [`Sensor::Mono`].
pub const LUMA_709: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// Rows per parallel work item; the output does not depend on it.
const ROWS_PER_CHUNK: usize = 4;

/// `last_t` of a pixel that has not fired yet.
const NO_EVENT: i64 = i64::MIN;

/// The hot per-pixel state, touched every frame.
#[derive(Clone, Copy, Debug, Default)]
struct Pixel {
    /// Reference level `ref` (log units): the level of the last crossing.
    ref_l: f32,
    /// Log intensity at the previous frame (after the photoreceptor filter when it is on).
    l: f32,
    /// This pixel's ON threshold.
    c_pos: f32,
    /// This pixel's OFF threshold.
    c_neg: f32,
}

/// The cold per-pixel state, touched only by the non-idealities and by crossings.
#[derive(Clone, Debug)]
struct PixelNoise {
    /// The pixel's own random stream.
    rng: Rng,
    /// Time of the pixel's last (emitted) event, ns, or [`NO_EVENT`].
    last_t: i64,
    /// Time of the pixel's next shot-noise event, ns.
    next_shot_t: i64,
}

/// What one frame interval produced, and the adaptive-sampling hint.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// ON events emitted in the interval.
    pub on: u64,
    /// OFF events emitted in the interval.
    pub off: u64,
    /// Largest per-pixel `|L1 - L0| / C` of the interval (C = the pixel's threshold in the
    /// direction of the change). Above 1 the linear interpolation between frames may have
    /// missed or misplaced crossings: render frames closer together.
    pub max_change_c: f32,
}

impl FrameStats {
    /// All events of the interval.
    pub fn events(&self) -> u64 {
        self.on + self.off
    }

    /// True when some pixel changed by more than one threshold in the interval.
    pub fn undersampled(&self) -> bool {
        self.max_change_c > 1.0
    }

    /// ESIM's adaptive step: the interval after which the fastest pixel would change by
    /// `lambda` thresholds at the current rate (ESIM uses `lambda = 0.5`); `None` when nothing
    /// changed.
    pub fn suggested_interval_ns(&self, dt_ns: i64, lambda: f32) -> Option<i64> {
        (self.max_change_c > 0.0)
            .then(|| ((dt_ns as f64 * lambda as f64 / self.max_change_c as f64).round() as i64).max(1))
    }

    /// The counts of `events` with the given largest change.
    fn of(events: &[Event], max_change_c: f32) -> FrameStats {
        let on = events.iter().filter(|e| e.p > 0).count() as u64;
        FrameStats { on, off: events.len() as u64 - on, max_change_c }
    }

    fn merge(self, o: FrameStats) -> FrameStats {
        FrameStats { on: self.on + o.on, off: self.off + o.off, max_change_c: self.max_change_c.max(o.max_change_c) }
    }
}

/// A frame as the model reads it: per pixel the intensity `I` ([`intensity`]) and its log
/// `ln(log_eps + I)`, row-major. [`EventSimulator::step`] reads an [`Image`] and computes both
/// per pixel; [`EventSimulator::step_log`] takes them ready-made, so a source with few distinct
/// levels (8-bit frames in `evsim events`) computes each level once. Holding the values
/// `step` would compute, it gives the same events.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogFrame {
    width: u32,
    height: u32,
    intensity: Vec<f32>,
    log: Vec<f32>,
}

impl LogFrame {
    /// A frame from per-pixel intensities and their logs (`width * height` each, row-major).
    /// Rejects a wrong length, an intensity that is not finite and >= 0, or a log that is not
    /// finite.
    pub fn new(width: u32, height: u32, intensity: Vec<f32>, log: Vec<f32>) -> Result<LogFrame, EventError> {
        let n = width as usize * height as usize;
        if intensity.len() != n || log.len() != n {
            return Err(EventError::FrameLength { width, height, intensity: intensity.len(), log: log.len() });
        }
        let good = |(&i, &l): (&f32, &f32)| i.is_finite() & (i >= 0.0) & l.is_finite();
        let all_good = intensity
            .par_chunks(1 << 14)
            .zip(log.par_chunks(1 << 14))
            .all(|(i, l)| i.iter().zip(l).fold(true, |ok, p| ok & good(p)));
        if !all_good {
            let k = intensity.iter().zip(&log).position(|p| !good(p)).unwrap_or(0);
            let w = width.max(1) as usize;
            return Err(EventError::BadIntensity { x: (k % w) as u32, y: (k / w) as u32, rgb: [intensity[k]; 3] });
        }
        Ok(LogFrame { width, height, intensity, log })
    }

    /// [`new`](Self::new) without the value check, for values that come from a table whose
    /// entries were checked (the lengths are still checked).
    pub(crate) fn from_checked_levels(
        width: u32,
        height: u32,
        intensity: Vec<f32>,
        log: Vec<f32>,
    ) -> Result<LogFrame, EventError> {
        let n = width as usize * height as usize;
        if intensity.len() != n || log.len() != n {
            return Err(EventError::FrameLength { width, height, intensity: intensity.len(), log: log.len() });
        }
        Ok(LogFrame { width, height, intensity, log })
    }

    /// What [`EventSimulator::step`] reads from `image` under `cfg` (intensities checked as it
    /// checks them).
    pub fn from_image(image: &Image, cfg: &EventConfig) -> Result<LogFrame, EventError> {
        let w = image.width as usize;
        let intensity: Vec<f32> = image
            .pixels
            .par_iter()
            .enumerate()
            .map(|(k, &rgb)| intensity(cfg.sensor, rgb, k % w.max(1), k / w.max(1)))
            .collect();
        if let Some(k) = image.pixels.iter().position(|p| !(p.is_finite() && p.min_element() >= 0.0)) {
            return Err(EventError::BadIntensity {
                x: (k % w) as u32,
                y: (k / w) as u32,
                rgb: image.pixels[k].to_array(),
            });
        }
        let log = intensity.par_iter().map(|&i| (cfg.log_eps + i).ln()).collect();
        LogFrame::new(image.width, image.height, intensity, log)
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Give back the two arrays (to reuse their memory).
    pub fn into_parts(self) -> (Vec<f32>, Vec<f32>) {
        (self.intensity, self.log)
    }
}

/// A frame's per-pixel intensity and log intensity, however it is stored.
trait Levels: Sync {
    /// Intensity and `ln(log_eps + intensity)` of pixel `k` (row-major index) at column `x`,
    /// row `y`.
    fn level(&self, k: usize, x: usize, y: usize) -> (f32, f32);
}

/// An [`Image`] read under a config: the intensity and its log computed per pixel.
struct ImageLevels<'a> {
    image: &'a Image,
    sensor: Sensor,
    log_eps: f32,
}

impl Levels for ImageLevels<'_> {
    #[inline]
    fn level(&self, k: usize, x: usize, y: usize) -> (f32, f32) {
        let i = intensity(self.sensor, self.image.pixels[k], x, y);
        (i, (self.log_eps + i).ln())
    }
}

impl Levels for LogFrame {
    #[inline]
    fn level(&self, k: usize, _x: usize, _y: usize) -> (f32, f32) {
        (self.intensity[k], self.log[k])
    }
}

/// The event camera: per-pixel state fed one frame at a time.
///
/// Memory is `O(pixels + events of one interval)`, independent of the sequence length.
pub struct EventSimulator {
    cfg: EventConfig,
    width: u32,
    height: u32,
    pixels: Vec<Pixel>,
    noise: Vec<PixelNoise>,
    /// Time of the previous frame; `None` before the first.
    t_prev: Option<i64>,
    /// One event buffer per row chunk and frame of a batch, reused across batches.
    buffers: Vec<Vec<Event>>,
    /// The merged, sorted events of each frame of the current batch.
    merged: Vec<Vec<Event>>,
}

/// What a row chunk needs to know about the current interval.
struct Interval<'a> {
    cfg: &'a EventConfig,
    width: usize,
    t0: i64,
    t1: i64,
    /// `t1 - t0` in ns.
    dt: f64,
    /// `t1 - t0` in seconds.
    dt_s: f32,
}

impl EventSimulator {
    /// A simulator for `width` x `height` frames (each at most 65536, as events store `u16`).
    pub fn new(cfg: EventConfig, width: u32, height: u32) -> Result<EventSimulator, EventError> {
        cfg.validate()?;
        for (field, v) in [("width", width), ("height", height)] {
            if v == 0 || v > 65536 {
                return Err(EventError::Config { field, value: v.to_string(), message: "must be in 1..=65536" });
            }
        }
        let n = width as usize * height as usize;
        let chunks = (height as usize).div_ceil(ROWS_PER_CHUNK);
        Ok(EventSimulator {
            cfg,
            width,
            height,
            pixels: vec![Pixel::default(); n],
            noise: vec![PixelNoise { rng: Rng::new(0, 0), last_t: NO_EVENT, next_shot_t: i64::MAX }; n],
            t_prev: None,
            buffers: vec![Vec::new(); chunks],
            merged: Vec::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &EventConfig {
        &self.cfg
    }

    /// Time of the last accepted frame, ns.
    pub fn last_time_ns(&self) -> Option<i64> {
        self.t_prev
    }

    /// Feed the frame taken at `t_ns`. The first frame sets the references and emits nothing;
    /// every later one emits the events of `(previous time, t_ns]`, time-sorted, to `sink`.
    /// A rejected frame changes nothing.
    pub fn step(&mut self, frame: &Image, t_ns: i64, sink: &mut dyn EventSink) -> Result<FrameStats, EventError> {
        self.check(frame, t_ns)?;
        let levels = ImageLevels { image: frame, sensor: self.cfg.sensor, log_eps: self.cfg.log_eps };
        self.advance(&[levels], &[t_ns], sink).map(|stats| stats[0])
    }

    /// [`step`](Self::step) with the intensities and their logs given (see [`LogFrame`]).
    pub fn step_log(
        &mut self,
        frame: &LogFrame,
        t_ns: i64,
        sink: &mut dyn EventSink,
    ) -> Result<FrameStats, EventError> {
        self.step_log_batch(std::slice::from_ref(frame), &[t_ns], sink).map(|stats| stats[0])
    }

    /// [`step_log`](Self::step_log) for each frame in turn (the same events, pushed to `sink`
    /// frame by frame, and the same stats), in one parallel pass over the pixels: cheaper than
    /// one call per frame when frames are small. Every frame and time is checked first; a
    /// rejected batch changes nothing.
    pub fn step_log_batch(
        &mut self,
        frames: &[LogFrame],
        times: &[i64],
        sink: &mut dyn EventSink,
    ) -> Result<Vec<FrameStats>, EventError> {
        if frames.len() != times.len() {
            return Err(EventError::Config {
                field: "times",
                value: times.len().to_string(),
                message: "give one time per frame",
            });
        }
        let mut prev = self.t_prev;
        for (frame, &t_ns) in frames.iter().zip(times) {
            self.check_size(frame.width, frame.height, frame.intensity.len())?;
            if let Some(p) = prev.filter(|&p| t_ns <= p) {
                return Err(EventError::NonIncreasingTime { prev_ns: p, t_ns });
            }
            prev = Some(t_ns);
        }
        self.advance(frames, times, sink)
    }

    /// Advance every pixel through the (checked) frames at `times`, pushing each frame's
    /// events in turn.
    fn advance<L: Levels>(
        &mut self,
        frames: &[L],
        times: &[i64],
        sink: &mut dyn EventSink,
    ) -> Result<Vec<FrameStats>, EventError> {
        let mut stats = Vec::with_capacity(frames.len());
        let (mut frames, mut times) = (frames, times);
        if self.t_prev.is_none() {
            let (Some(first), Some(&t)) = (frames.first(), times.first()) else {
                return Ok(stats);
            };
            self.first_frame(first, t);
            self.t_prev = Some(t);
            stats.push(FrameStats::default());
            (frames, times) = (&frames[1..], &times[1..]);
        }
        let Some(mut t0) = self.t_prev.filter(|_| !frames.is_empty()) else {
            return Ok(stats);
        };
        let (w, nf) = (self.width as usize, frames.len());
        let intervals: Vec<Interval> = times
            .iter()
            .map(|&t1| {
                let iv = Interval {
                    cfg: &self.cfg,
                    width: w,
                    t0,
                    t1,
                    dt: (t1 - t0) as f64,
                    dt_s: ((t1 - t0) as f64 * 1e-9) as f32,
                };
                t0 = t1;
                iv
            })
            .collect();
        // chunk c's events of frame f go to buffers[c * nf + f]
        let chunks = (self.height as usize).div_ceil(ROWS_PER_CHUNK);
        self.buffers.resize_with(chunks * nf, Vec::new);
        let ideal = self.cfg.noise.is_off();
        let n = w * ROWS_PER_CHUNK;
        let per_chunk: Vec<Vec<FrameStats>> = self
            .pixels
            .par_chunks_mut(n)
            .zip(self.noise.par_chunks_mut(n))
            .zip(self.buffers.par_chunks_mut(nf))
            .enumerate()
            .map(|(c, ((px, nz), outs))| {
                let y0 = c * ROWS_PER_CHUNK;
                (intervals.iter().zip(frames).zip(outs))
                    .map(|((iv, frame), out)| {
                        out.clear();
                        if ideal {
                            iv.chunk_ideal(y0, px, nz, frame, out) // sorted once merged
                        } else {
                            let stats = iv.chunk(y0, px, nz, frame, out);
                            sort_events(out, iv.t0, iv.t1); // stable: ties keep (y, x, emission) order
                            stats
                        }
                    })
                    .collect()
            })
            .collect();
        self.t_prev = Some(t0); // the last frame's time
                                // merge each frame's chunk runs: chunks are in row order, so a stable merge by (t, y, x)
                                // gives the same order as a stable sort of the (y, x, emission)-ordered concatenation,
                                // whatever the chunking; the run-detecting stable sort does the k-way merge (ideal: see
                                // `sort_ideal`)
        let buffers = &self.buffers;
        let merge = |f: usize, merged: &mut Vec<Event>| {
            merged.clear();
            for c in 0..chunks {
                merged.extend_from_slice(&buffers[c * nf + f]);
            }
        };
        self.merged.resize_with(nf, Vec::new);
        if nf == 1 {
            // one frame: sort it on all cores
            merge(0, &mut self.merged[0]);
            par_sort_events(&mut self.merged[0], &intervals[0], ideal);
        } else {
            self.merged.par_iter_mut().enumerate().for_each(|(f, merged)| {
                merge(f, merged);
                seq_sort_events(merged, &intervals[f], ideal);
            });
        }
        for (f, merged) in self.merged.iter().enumerate() {
            let frame_stats = per_chunk.iter().map(|s| s[f]).fold(FrameStats::default(), FrameStats::merge);
            sink.push(merged)?;
            stats.push(frame_stats);
        }
        Ok(stats)
    }

    /// A frame of another size is rejected.
    fn check_size(&self, width: u32, height: u32, len: usize) -> Result<(), EventError> {
        if width != self.width || height != self.height || len != self.pixels.len() {
            return Err(EventError::FrameSize {
                width: self.width,
                height: self.height,
                got_width: width,
                got_height: height,
            });
        }
        Ok(())
    }

    /// A frame time not after the previous one is rejected.
    fn check_time(&self, t_ns: i64) -> Result<(), EventError> {
        match self.t_prev {
            Some(prev) if t_ns <= prev => Err(EventError::NonIncreasingTime { prev_ns: prev, t_ns }),
            _ => Ok(()),
        }
    }

    /// Validate a frame before any state changes.
    fn check(&self, frame: &Image, t_ns: i64) -> Result<(), EventError> {
        self.check_size(frame.width, frame.height, frame.pixels.len())?;
        self.check_time(t_ns)?;
        // a branch-free scan per chunk; the position only when a chunk has a bad pixel
        let good = |p: &Vec3| p.is_finite() & (p.min_element() >= 0.0);
        let n = self.width as usize * ROWS_PER_CHUNK;
        let bad = frame
            .pixels
            .par_chunks(n)
            .enumerate()
            .filter(|(_, ch)| !ch.iter().fold(true, |ok, p| ok & good(p)))
            .map(|(c, ch)| c * n + ch.iter().position(|p| !good(p)).unwrap_or(0))
            .min();
        if let Some(i) = bad {
            let w = self.width as usize;
            return Err(EventError::BadIntensity {
                x: (i % w) as u32,
                y: (i / w) as u32,
                rgb: frame.pixels[i].to_array(),
            });
        }
        Ok(())
    }

    /// Set every pixel's reference to its log intensity and draw its fixed random quantities.
    fn first_frame<L: Levels>(&mut self, frame: &L, t_ns: i64) {
        let (cfg, w) = (&self.cfg, self.width as usize);
        self.pixels.par_iter_mut().zip(self.noise.par_iter_mut()).enumerate().for_each(|(i, (px, nz))| {
            let mut rng = noise::pixel_rng(cfg.seed, i as u64);
            let (c_pos, c_neg) = match cfg.noise.threshold_mismatch {
                Some(m) => noise::draw_thresholds(&mut rng, cfg.c_pos, cfg.c_neg, m.sigma),
                None => (cfg.c_pos, cfg.c_neg),
            };
            let (_, l) = frame.level(i, i % w, i / w);
            let phase = if cfg.noise.leak_rate_hz > 0.0 { noise::leak_phase(&mut rng, c_pos) } else { 0.0 };
            let wait = noise::exp_wait_ns(&mut rng, cfg.noise.shot_noise_rate_hz);
            *px = Pixel { ref_l: l - phase, l, c_pos, c_neg };
            *nz = PixelNoise { rng, last_t: NO_EVENT, next_shot_t: t_ns.saturating_add(wait) };
        });
    }
}

/// A frame's merged events into `(t, y, x)` order on all cores: the stable sort, or in the
/// `ideal` model an unstable one (see [`seq_sort_events`]).
fn par_sort_events(events: &mut [Event], iv: &Interval, ideal: bool) {
    if iv.t1 - iv.t0 >= 1 << 32 {
        events.par_sort_by_key(Event::order_key);
    } else if ideal {
        events.par_sort_unstable_by_key(|e| short_key(e, iv.t0));
    } else {
        events.par_sort_by_key(|e| short_key(e, iv.t0));
    }
}

/// [`par_sort_events`] on one thread. In the `ideal` model a pixel's events of one interval all
/// have one polarity (its `D` moves linearly), so events with equal keys are equal and an
/// unstable sort gives the stable sort's order.
fn seq_sort_events(events: &mut [Event], iv: &Interval, ideal: bool) {
    if iv.t1 - iv.t0 >= 1 << 32 {
        events.sort_by_key(Event::order_key);
    } else if ideal {
        events.sort_unstable_by_key(|e| short_key(e, iv.t0));
    } else {
        sort_events(events, iv.t0, iv.t1);
    }
}

/// Stable sort of the events of the interval `(t0, t1]` by `(t, y, x)`; with a single `u64`
/// key `(t - t0) << 32 | y << 16 | x` when the interval is shorter than 2^32 ns (4.3 s).
fn sort_events(events: &mut [Event], t0: i64, t1: i64) {
    if t1 - t0 < 1 << 32 {
        events.sort_by_key(|e| short_key(e, t0));
    } else {
        events.sort_by_key(Event::order_key);
    }
}

/// `(t - t0) << 32 | y << 16 | x`: the `(t, y, x)` order of an interval shorter than 2^32 ns.
#[inline]
fn short_key(e: &Event, t0: i64) -> u64 {
    ((e.t_ns - t0) as u64) << 32 | (e.y as u64) << 16 | e.x as u64
}

/// The one intensity a pixel takes the log of: Rec.709 luma, or its RGGB mosaic channel.
#[inline]
pub fn intensity(sensor: Sensor, rgb: Vec3, x: usize, y: usize) -> f32 {
    match sensor {
        Sensor::Mono => rgb.dot(LUMA_709),
        Sensor::Rggb => match (x & 1, y & 1) {
            (0, 0) => rgb.x,
            (1, 1) => rgb.z,
            _ => rgb.y,
        },
    }
}

/// Earliest fraction `u` in `[u_lo, 1]` of the interval at which `d0 + u k >= c`.
#[inline]
fn first_reach(d0: f64, k: f64, c: f64, u_lo: f64) -> Option<f64> {
    if d0 + u_lo * k >= c {
        return Some(u_lo); // already beyond (a crossing left pending by the refractory period)
    }
    if k <= 0.0 {
        return None;
    }
    let u = (c - d0) / k;
    (u <= 1.0).then_some(u)
}

impl Interval<'_> {
    /// [`chunk`](Self::chunk) when every non-ideality is off (same events and stats): no
    /// per-pixel noise, leak or threshold draws, and the largest change in thresholds from the
    /// extreme changes (dividing by one positive threshold keeps the order, so it is exact).
    fn chunk_ideal<L: Levels>(
        &self,
        y0: usize,
        px: &mut [Pixel],
        nz: &mut [PixelNoise],
        frame: &L,
        out: &mut Vec<Event>,
    ) -> FrameStats {
        let (cp, cm) = (self.cfg.c_pos, self.cfg.c_neg);
        let (mut hi, mut lo) = (0.0f32, 0.0f32);
        let before = out.len();
        let rows = px.chunks_exact_mut(self.width).zip(nz.chunks_exact_mut(self.width));
        for (r, (px, nz)) in rows.enumerate() {
            let y = y0 + r;
            let row = y * self.width;
            for (x, (p, n)) in px.iter_mut().zip(nz.iter_mut()).enumerate() {
                let (_, l1) = frame.level(row + x, x, y);
                let dl = l1 - p.l;
                // plain compares (the logs are finite): keeps hi and lo in registers
                hi = if dl > hi { dl } else { hi };
                lo = if dl < lo { dl } else { lo };
                let d0 = p.l - p.ref_l;
                let d1 = l1 - p.ref_l;
                if !(d0 < cp && d0 > -cm && d1 < cp && d1 > -cm) {
                    let (d0, k) = (p.l as f64 - p.ref_l as f64, l1 as f64 - p.l as f64);
                    let shift = self.crossings(d0, k, p, n, x as u16, y as u16, out);
                    p.ref_l = (p.ref_l as f64 + shift) as f32;
                }
                p.l = l1;
            }
        }
        FrameStats::of(&out[before..], 0.0f32.max(hi / cp).max(-lo / cm))
    }

    /// Advance the pixels of rows `y0..` over the interval, appending their events to `out`.
    fn chunk<L: Levels>(
        &self,
        y0: usize,
        px: &mut [Pixel],
        nz: &mut [PixelNoise],
        frame: &L,
        out: &mut Vec<Event>,
    ) -> FrameStats {
        let cfg = self.cfg;
        let nc = &cfg.noise;
        let redraw = nc.threshold_mismatch.filter(|m| m.mode == MismatchMode::PerInterval).map(|m| m.sigma);
        let leak_per_c = nc.leak_rate_hz * self.dt_s; // leak drift in units of C_p
        let shot = nc.shot_noise_rate_hz > 0.0;
        let mut max_change = 0.0f32;
        let before = out.len();
        let rows = px.chunks_exact_mut(self.width).zip(nz.chunks_exact_mut(self.width));
        for (r, (px, nz)) in rows.enumerate() {
            let y = y0 + r;
            let row = y * self.width;
            for (x, (p, n)) in px.iter_mut().zip(nz.iter_mut()).enumerate() {
                // log intensity at t1, through the photoreceptor filter when it is on
                let (i1, mut l1) = frame.level(row + x, x, y);
                if let Some(pr) = nc.photoreceptor {
                    l1 = noise::low_pass(p.l, l1, i1, self.dt_s, pr.cutoff_hz);
                }
                if let Some(sigma) = redraw {
                    (p.c_pos, p.c_neg) = noise::draw_thresholds(&mut n.rng, cfg.c_pos, cfg.c_neg, sigma);
                }
                // adaptive-sampling hint: the change in thresholds
                let dl = l1 - p.l;
                max_change = max_change.max((dl / p.c_pos).max(-dl / p.c_neg));
                // D(u) = L(u) - ref(u) is linear in u in [0, 1]; the leak lowers ref, raising D
                let leak = leak_per_c * p.c_pos;
                let d0 = p.l - p.ref_l;
                let d1 = l1 - p.ref_l + leak;
                if d0 < p.c_pos && d0 > -p.c_neg && d1 < p.c_pos && d1 > -p.c_neg {
                    p.ref_l -= leak; // no crossing (D stays inside (-C_m, C_p) over the interval)
                } else {
                    // exact in f64: differences of f32 values
                    let (d0, k) = (p.l as f64 - p.ref_l as f64, l1 as f64 - p.l as f64 + leak as f64);
                    let shift = self.crossings(d0, k, p, n, x as u16, y as u16, out);
                    p.ref_l = (p.ref_l as f64 - leak as f64 + shift) as f32;
                }
                p.l = l1;
                // shot noise: a Poisson process, independent of ref and of the refractory period
                if shot {
                    while n.next_shot_t <= self.t1 {
                        let pol = if n.rng.next_u32() & 1 == 0 { 1 } else { -1 };
                        out.push(Event { x: x as u16, y: y as u16, t_ns: n.next_shot_t, p: pol });
                        n.next_shot_t =
                            n.next_shot_t.saturating_add(noise::exp_wait_ns(&mut n.rng, nc.shot_noise_rate_hz));
                    }
                }
            }
        }
        FrameStats::of(&out[before..], max_change)
    }

    /// Emit the threshold crossings of one pixel whose `D = L - ref` goes from `d0` to `d0 + k`
    /// over the interval: an ON event each time D reaches `C_p` (then `ref += C_p`), an OFF event
    /// each time it reaches `-C_m` (then `ref -= C_m`), at the linearly interpolated time
    /// `t0 + round(u (t1 - t0))`. Returns the total move of `ref` (consumed crossings included).
    #[allow(clippy::too_many_arguments)]
    #[inline(never)] // the rare path: kept out of the pixel loops
    fn crossings(&self, d0: f64, k: f64, p: &Pixel, n: &mut PixelNoise, x: u16, y: u16, out: &mut Vec<Event>) -> f64 {
        let (cp, cm) = (p.c_pos as f64, p.c_neg as f64);
        let refractory: Option<Refractory> = self.cfg.noise.refractory.filter(|r| r.period_ns > 0);
        let mut shift = 0.0f64; // sum of pol * C applied to ref so far
        let mut u_lo = 0.0f64;
        let mut min_t = i64::MIN; // fire-later: the first time the period allows
        loop {
            let d = d0 - shift;
            let on = first_reach(d, k, cp, u_lo);
            let off = first_reach(-d, -k, cm, u_lo);
            let (u, pol, c) = match (on, off) {
                (Some(a), Some(b)) if b < a => (b, -1i8, cm),
                (Some(a), _) => (a, 1i8, cp),
                (None, Some(b)) => (b, -1i8, cm),
                (None, None) => break,
            };
            let t = (self.t0 + (u * self.dt).round() as i64).max(min_t);
            if let Some(r) = refractory {
                if n.last_t != NO_EVENT && t - n.last_t < r.period_ns {
                    match r.mode {
                        // ESIM: drop the event, consume the crossing
                        RefractoryMode::Consume => {
                            shift += pol as f64 * c;
                            u_lo = u;
                            continue;
                        }
                        // v2e: keep the crossing pending until the period has passed
                        RefractoryMode::FireLater => {
                            min_t = n.last_t + r.period_ns;
                            if min_t > self.t1 {
                                break;
                            }
                            u_lo = (min_t - self.t0) as f64 / self.dt;
                            continue;
                        }
                    }
                }
            }
            out.push(Event { x, y, t_ns: t, p: pol });
            n.last_t = t;
            shift += pol as f64 * c;
            u_lo = u.max(u_lo);
        }
        shift
    }
}

#[cfg(test)]
#[path = "model_tests.rs"]
mod tests;
