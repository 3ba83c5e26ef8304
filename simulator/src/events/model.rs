//! The per-pixel event model: [`EventSimulator`] (ESIM's ideal model plus the optional v2e
//! non-idealities of [`NoiseConfig`](super::NoiseConfig)).

use glam::Vec3;
use rayon::prelude::*;

use super::config::{EventConfig, MismatchMode, Refractory, RefractoryMode, Sensor};
use super::noise;
use super::sink::{Event, EventSink};
use super::EventError;
use crate::render::film::Image;
use crate::render::sampling::Rng;

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

    fn merge(self, o: FrameStats) -> FrameStats {
        FrameStats { on: self.on + o.on, off: self.off + o.off, max_change_c: self.max_change_c.max(o.max_change_c) }
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
    /// One event buffer per row chunk, reused across frames.
    buffers: Vec<Vec<Event>>,
    /// The merged, sorted events of the current interval.
    merged: Vec<Event>,
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
        let Some(t0) = self.t_prev else {
            self.first_frame(frame, t_ns);
            self.t_prev = Some(t_ns);
            return Ok(FrameStats::default());
        };
        let iv = Interval {
            cfg: &self.cfg,
            width: self.width as usize,
            t0,
            t1: t_ns,
            dt: (t_ns - t0) as f64,
            dt_s: ((t_ns - t0) as f64 * 1e-9) as f32,
        };
        let n = iv.width * ROWS_PER_CHUNK;
        let stats = self
            .pixels
            .par_chunks_mut(n)
            .zip(self.noise.par_chunks_mut(n))
            .zip(frame.pixels.par_chunks(n))
            .zip(self.buffers.par_iter_mut())
            .enumerate()
            .map(|(c, (((px, nz), rgb), out))| {
                out.clear();
                let stats = iv.chunk(c * ROWS_PER_CHUNK, px, nz, rgb, out);
                sort_events(out, t0, t_ns); // stable: ties keep (y, x, emission) order
                stats
            })
            .reduce(FrameStats::default, FrameStats::merge);
        self.t_prev = Some(t_ns);
        // merge the sorted chunk runs: chunks are in row order, so a stable merge by (t, y, x)
        // gives the same order as a stable sort of the (y, x, emission)-ordered concatenation,
        // whatever the chunking; the run-detecting stable sort does the k-way merge
        self.merged.clear();
        for b in &self.buffers {
            self.merged.extend_from_slice(b);
        }
        par_sort_events(&mut self.merged, t0, t_ns);
        sink.push(&self.merged)?;
        Ok(stats)
    }

    /// Validate a frame before any state changes.
    fn check(&self, frame: &Image, t_ns: i64) -> Result<(), EventError> {
        if frame.width != self.width || frame.height != self.height || frame.pixels.len() != self.pixels.len() {
            return Err(EventError::FrameSize {
                width: self.width,
                height: self.height,
                got_width: frame.width,
                got_height: frame.height,
            });
        }
        if let Some(prev) = self.t_prev {
            if t_ns <= prev {
                return Err(EventError::NonIncreasingTime { prev_ns: prev, t_ns });
            }
        }
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
    fn first_frame(&mut self, frame: &Image, t_ns: i64) {
        let (cfg, w) = (&self.cfg, self.width as usize);
        self.pixels.par_iter_mut().zip(self.noise.par_iter_mut()).zip(&frame.pixels).enumerate().for_each(
            |(i, ((px, nz), &rgb))| {
                let mut rng = noise::pixel_rng(cfg.seed, i as u64);
                let (c_pos, c_neg) = match cfg.noise.threshold_mismatch {
                    Some(m) => noise::draw_thresholds(&mut rng, cfg.c_pos, cfg.c_neg, m.sigma),
                    None => (cfg.c_pos, cfg.c_neg),
                };
                let l = (cfg.log_eps + intensity(cfg.sensor, rgb, i % w, i / w)).ln();
                let phase = if cfg.noise.leak_rate_hz > 0.0 { noise::leak_phase(&mut rng, c_pos) } else { 0.0 };
                let wait = noise::exp_wait_ns(&mut rng, cfg.noise.shot_noise_rate_hz);
                *px = Pixel { ref_l: l - phase, l, c_pos, c_neg };
                *nz = PixelNoise { rng, last_t: NO_EVENT, next_shot_t: t_ns.saturating_add(wait) };
            },
        );
    }
}

/// [`sort_events`] on all cores (stable as well, so the order is the same).
fn par_sort_events(events: &mut [Event], t0: i64, t1: i64) {
    if t1 - t0 < 1 << 32 {
        events.par_sort_by_key(|e| ((e.t_ns - t0) as u64) << 32 | (e.y as u64) << 16 | e.x as u64);
    } else {
        events.par_sort_by_key(Event::order_key);
    }
}

/// Stable sort of the events of the interval `(t0, t1]` by `(t, y, x)`; with a single `u64`
/// key `(t - t0) << 32 | y << 16 | x` when the interval is shorter than 2^32 ns (4.3 s).
fn sort_events(events: &mut [Event], t0: i64, t1: i64) {
    if t1 - t0 < 1 << 32 {
        events.sort_by_key(|e| ((e.t_ns - t0) as u64) << 32 | (e.y as u64) << 16 | e.x as u64);
    } else {
        events.sort_by_key(Event::order_key);
    }
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
    /// Advance the pixels of rows `y0..` over the interval, appending their events to `out`.
    fn chunk(
        &self,
        y0: usize,
        px: &mut [Pixel],
        nz: &mut [PixelNoise],
        rgb: &[Vec3],
        out: &mut Vec<Event>,
    ) -> FrameStats {
        let cfg = self.cfg;
        let nc = &cfg.noise;
        let redraw = nc.threshold_mismatch.filter(|m| m.mode == MismatchMode::PerInterval).map(|m| m.sigma);
        let leak_per_c = nc.leak_rate_hz * self.dt_s; // leak drift in units of C_p
        let shot = nc.shot_noise_rate_hz > 0.0;
        let mut max_change = 0.0f32;
        let before = out.len();
        let rows =
            px.chunks_exact_mut(self.width).zip(nz.chunks_exact_mut(self.width)).zip(rgb.chunks_exact(self.width));
        for (r, ((px, nz), rgb)) in rows.enumerate() {
            let y = y0 + r;
            for (x, ((p, n), &c)) in px.iter_mut().zip(nz.iter_mut()).zip(rgb).enumerate() {
                // log intensity at t1, through the photoreceptor filter when it is on
                let i1 = intensity(cfg.sensor, c, x, y);
                let mut l1 = (cfg.log_eps + i1).ln();
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
        let new = &out[before..];
        let on = new.iter().filter(|e| e.p > 0).count() as u64;
        FrameStats { on, off: new.len() as u64 - on, max_change_c: max_change }
    }

    /// Emit the threshold crossings of one pixel whose `D = L - ref` goes from `d0` to `d0 + k`
    /// over the interval: an ON event each time D reaches `C_p` (then `ref += C_p`), an OFF event
    /// each time it reaches `-C_m` (then `ref -= C_m`), at the linearly interpolated time
    /// `t0 + round(u (t1 - t0))`. Returns the total move of `ref` (consumed crossings included).
    #[allow(clippy::too_many_arguments)]
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
