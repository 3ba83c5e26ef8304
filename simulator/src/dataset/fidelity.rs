//! Do a dataset's events tell the scene's true brightness changes? A segment of the trajectory
//! is rendered as the dataset renders it (its frame stream, [`super::sequence`]) and as a
//! converged reference (full paths, `ref_spp` samples per pixel, no filter, new random numbers
//! in every frame), and the dataset's events are scored against the reference's log intensity
//! `L(t) = ln(eps + I(t))` (the event model's `eps`, sensor and gain; linear in time between
//! frames, as the event model interpolates).
//!
//! The scores, each `r2 = 1 - sum (pred - target)^2 / sum target^2` (1 = exact, 0 = no better
//! than "nothing changed"):
//! - **pairs**, the event loss's pair: event `j` and the next event `k` at the same pixel;
//!   `target = p_k C`, `pred = L(t_k) - L(t_j)`; beside it the *sign agreement*, the share of
//!   pairs whose reference change has the polarity's sign;
//! - **windows** of `w` ms (1, 4 and 24 by default), every pixel and every whole window of the
//!   segment: `target = C x` (signed events in the window), `pred = L(end) - L(start)`.
//!
//! Beside the dataset's scores stand two ideal simulators, ESIM's model run on reference frames:
//! on the reference itself (*ideal*: pairs score 1 by construction, windows show the limit of
//! the threshold's quantisation) and on a second reference rendered with other random numbers
//! (*ceiling*: what even a perfect simulator fed one converged-but-finite render scores against
//! another; the reference's own noise caps every figure there). Beside them, the old count
//! measure: events per pixel and polarity over the segment, the dataset's against the ideal
//! simulator's ([`Comparison`]).
//!
//! The event model runs without its non-idealities (threshold mismatch, refractory period,
//! leak, shot noise) for every sequence here: this measures the frames, not the sensor model.
//! Reference frames are kept in a cache folder (half-float EXR, keyed by everything that
//! changes their pixels), so a second measurement of the same segment renders none.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::cache::{round_to_f16, FrameCache};
use super::noise::Comparison;
use super::plan::Plan;
use super::sequence::{at_sensor, SequenceRenderer};
use super::writer::render_settings;
use super::{DatasetError, NoisePattern};
use crate::base::image::Image;
use crate::events::{Event, EventConfig, EventSimulator, NoiseConfig, VecSink};
use crate::render::film::RenderSettings;
use crate::render::integrator::Renderer;

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct FidelityOptions {
    /// First frame of the segment (default: the middle of the trajectory).
    pub start_frame: Option<usize>,
    /// Frames in the segment (>= 2); 25 frames at 1000 FPS span 24 ms.
    pub frames: usize,
    /// Samples per pixel of the reference renders (>= 1).
    pub ref_spp: u32,
    /// Window lengths (ns, each > 0); windows longer than the segment are skipped.
    pub windows_ns: Vec<i64>,
    /// Also render the second reference and score the two-reference ceiling.
    pub ceiling: bool,
    /// Score every `pixel_stride`-th pixel of every `pixel_stride`-th row (>= 1): the reference
    /// is rendered at those pixels alone (`pixel_stride^2` times faster); the dataset's frames
    /// are made whole, as always.
    pub pixel_stride: u32,
    /// The references' random numbers frame to frame: the same in every frame (`Fixed`: the
    /// remaining noise changes only as the content under a pixel changes, so short-time
    /// differences are nearly free of it) or new in every frame.
    pub reference_pattern: NoisePattern,
    /// Where reference frames are cached (`None`: not cached).
    pub reference_cache: Option<PathBuf>,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for FidelityOptions {
    fn default() -> FidelityOptions {
        FidelityOptions {
            start_frame: None,
            frames: 25,
            ref_spp: 512,
            windows_ns: vec![1_000_000, 4_000_000, 24_000_000],
            ceiling: true,
            pixel_stride: 1,
            reference_pattern: NoisePattern::Fixed,
            reference_cache: None,
            progress: false,
        }
    }
}

/// How well one sequence's events explain a reference (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq)]
pub struct Scores {
    /// Events scored.
    pub events: u64,
    /// Event pairs (an event and the next at its pixel).
    pub pairs: u64,
    /// r2 of the pairs.
    pub pair_r2: f64,
    /// Share of pairs whose reference change has the second event's sign.
    pub sign_agreement: f64,
    /// `(window length ns, r2)` for every window length that fits the segment.
    pub windows: Vec<(i64, f64)>,
}

/// The measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct FidelityReport {
    /// Frames of the segment.
    pub frames: usize,
    /// First frame of the segment.
    pub start_frame: usize,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Scored pixels: every `pixel_stride`-th of every `pixel_stride`-th row.
    pub pixel_stride: u32,
    /// Samples per pixel of the references.
    pub ref_spp: u32,
    /// The dataset's events against the reference.
    pub dataset: Scores,
    /// ESIM on the reference itself.
    pub ideal: Scores,
    /// ESIM on the second reference, against the first (with [`FidelityOptions::ceiling`]).
    pub ceiling: Option<Scores>,
    /// Event counts per pixel and polarity over the segment: the dataset's against the ideal
    /// simulator's.
    pub counts: Comparison,
    /// Wall time making the dataset's frames.
    pub dataset_time: Duration,
    /// Wall time rendering (or reading) the references.
    pub reference_time: Duration,
    /// Reference frames read from the cache (not rendered).
    pub reference_cached: usize,
}

impl FidelityReport {
    /// `dataset / ceiling` of the pair r2 and of each window's r2 (with a ceiling).
    pub fn ratios(&self) -> Option<(f64, Vec<(i64, f64)>)> {
        let c = self.ceiling.as_ref()?;
        let w = self.dataset.windows.iter().zip(&c.windows).map(|(d, c)| (d.0, d.1 / c.1)).collect();
        Some((self.dataset.pair_r2 / c.pair_r2, w))
    }
}

/// Salt of the two references' seeds (apart from the dataset's own streams).
const REFERENCE_SALT: [u64; 2] = [0x5eed_0fae_f1de_0001, 0x5eed_0fae_f1de_0002];

/// Per frame of the segment, the log intensity of every scored pixel.
struct LogFrames {
    /// Full-image pixel column and row of scored pixel (0, 0), and the step between scored
    /// pixels.
    grid: Grid,
    /// Frame times (ns).
    times: Vec<i64>,
    /// `ln(eps + I)` per frame, row-major.
    logs: Vec<Vec<f32>>,
}

impl LogFrames {
    fn new(grid: Grid, times: Vec<i64>) -> LogFrames {
        LogFrames { grid, logs: Vec::with_capacity(times.len()), times }
    }

    /// `L(t)` of pixel `i`, linear between the frames around `t` (clamped to the segment).
    fn at(&self, i: usize, t: i64) -> f64 {
        let k = self.times.partition_point(|&s| s < t);
        if k == 0 {
            return self.logs[0][i] as f64;
        }
        if k >= self.times.len() {
            return self.logs[self.times.len() - 1][i] as f64;
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let u = (t - t0) as f64 / (t1 - t0) as f64;
        let (a, b) = (self.logs[k - 1][i] as f64, self.logs[k][i] as f64);
        a + (b - a) * u
    }
}

/// The scored pixels: every `step`-th pixel from (`offset`, `offset`) on.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Grid {
    step: u32,
    offset: u32,
    /// Scored pixels per row and rows.
    width: u32,
    height: u32,
}

impl Grid {
    fn new(width: u32, height: u32, step: u32) -> Grid {
        let offset = (step / 2).min(width - 1).min(height - 1);
        Grid { step, offset, width: (width - offset).div_ceil(step), height: (height - offset).div_ceil(step) }
    }

    /// The full-image pixel of scored pixel (`i`, `j`).
    fn pixel(&self, i: u32, j: u32) -> (u32, u32) {
        (self.offset + i * self.step, self.offset + j * self.step)
    }

    /// The scored pixels of a full image.
    #[cfg(test)]
    fn pick(&self, img: &Image) -> Image {
        let pixels = (0..self.height)
            .flat_map(|j| (0..self.width).map(move |i| (i, j)))
            .map(|(i, j)| {
                let (x, y) = self.pixel(i, j);
                img.pixels[(y * img.width + x) as usize]
            })
            .collect();
        Image { width: self.width, height: self.height, pixels }
    }

    /// The scored pixel of full-image event `e`, if it is one.
    fn index(&self, e: &Event) -> Option<usize> {
        let (x, y) = (e.x as u32, e.y as u32);
        let on = |v: u32| v >= self.offset && (v - self.offset).is_multiple_of(self.step);
        (on(x) && on(y))
            .then(|| (((y - self.offset) / self.step) * self.width + (x - self.offset) / self.step) as usize)
    }
}

/// The log intensity the event model takes of `img` (already rounded to halves and scaled by the
/// gain), whose pixel (`i`, `j`) is full-image pixel `grid.pixel(i, j)`.
fn log_intensity(cfg: &EventConfig, img: &Image, grid: &Grid) -> Vec<f32> {
    let w = img.width;
    img.pixels
        .iter()
        .enumerate()
        .map(|(i, &rgb)| {
            let (x, y) = grid.pixel(i as u32 % w, i as u32 / w);
            (cfg.log_eps + crate::events::intensity(cfg.sensor, rgb, x as usize, y as usize)).ln()
        })
        .collect()
}

/// Score `events` (time-sorted, full-image pixels; events at pixels the reference does not
/// score are left out) against `reference`.
fn score(events: &[Event], reference: &LogFrames, cfg: &EventConfig, windows_ns: &[i64]) -> Scores {
    let grid = reference.grid;
    let events: Vec<(usize, Event)> = events.iter().filter_map(|e| grid.index(e).map(|i| (i, *e))).collect();
    let n_pixels = reference.logs[0].len();
    let c_of = |p: i8| if p > 0 { cfg.c_pos as f64 } else { cfg.c_neg as f64 };
    // pairs: each event with the previous one at its pixel
    let mut last: Vec<Option<i64>> = vec![None; n_pixels];
    let (mut se, mut st, mut agree, mut pairs) = (0.0f64, 0.0f64, 0u64, 0u64);
    for &(i, e) in &events {
        if let Some(tj) = last[i] {
            let target = e.p as f64 * c_of(e.p);
            let pred = reference.at(i, e.t_ns) - reference.at(i, tj);
            se += (pred - target) * (pred - target);
            st += target * target;
            agree += u64::from(pred * target > 0.0);
            pairs += 1;
        }
        last[i] = Some(e.t_ns);
    }
    let (t_start, t_end) = (reference.times[0], *reference.times.last().expect("frames"));
    let windows = windows_ns
        .iter()
        .filter(|&&len| len > 0 && len <= t_end - t_start)
        .map(|&len| {
            let n_win = ((t_end - t_start) / len) as usize;
            // signed, threshold-weighted event sums per (window, pixel); events in (start, end]
            let mut sums = vec![0.0f64; n_win * n_pixels];
            for &(i, e) in &events {
                let m = ((e.t_ns - t_start - 1).max(0) / len) as usize;
                if m < n_win {
                    sums[m * n_pixels + i] += e.p as f64 * c_of(e.p);
                }
            }
            let (mut se, mut st) = (0.0f64, 0.0f64);
            for m in 0..n_win {
                let (a, b) = (t_start + m as i64 * len, t_start + (m as i64 + 1) * len);
                for i in 0..n_pixels {
                    let target = sums[m * n_pixels + i];
                    let pred = reference.at(i, b) - reference.at(i, a);
                    se += (pred - target) * (pred - target);
                    st += target * target;
                }
            }
            (len, r2(se, st))
        })
        .collect();
    Scores {
        events: events.len() as u64,
        pairs,
        pair_r2: r2(se, st),
        sign_agreement: agree as f64 / pairs.max(1) as f64,
        windows,
    }
}

/// `1 - se / st` (0 when there is nothing to explain).
fn r2(se: f64, st: f64) -> f64 {
    if st > 0.0 {
        1.0 - se / st
    } else {
        0.0
    }
}

/// Feed frames (already rounded to halves, not yet scaled by the gain) to an ideal event model
/// and keep every event.
struct EventRun {
    sim: EventSimulator,
    gain: f32,
    sink: VecSink,
}

impl EventRun {
    /// A model of `width` x `height` pixels.
    fn new(cfg: &EventConfig, plan: &Plan, (width, height): (u32, u32)) -> Result<EventRun, DatasetError> {
        let sim = EventSimulator::new(cfg.clone(), width, height)
            .map_err(|e| DatasetError::config(&plan.scene_file, "events", e.to_string()))?;
        Ok(EventRun { sim, gain: plan.config.gain, sink: VecSink::default() })
    }

    /// Step the model with `img` at `t_ns`; returns the gained image.
    fn step(&mut self, img: Image, t_ns: i64, k: usize) -> Result<Image, DatasetError> {
        let img = at_sensor(&img, self.gain).into_owned();
        self.sim
            .step(&img, t_ns, &mut self.sink)
            .map_err(|e| DatasetError::stage(format!("frame {k}: event model"), e))?;
        Ok(img)
    }
}

/// The reference's render settings for frame `k` with seed number `which` (0 or 1).
fn reference_settings(
    plan: &Plan,
    k: usize,
    which: usize,
    spp: u32,
    pattern: NoisePattern,
) -> Result<RenderSettings, DatasetError> {
    let pose =
        plan.trajectory.pose_at(plan.clock.time_ns(k)).map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
    let mut s = render_settings(plan, &pose, k, false);
    s.spp = spp;
    s.spp_max = 0;
    s.frame = match pattern {
        NoisePattern::Fixed => 0,
        NoisePattern::PerFrame => k as u64,
    };
    s.seed = plan.config.seed ^ REFERENCE_SALT[which];
    // full paths, no sample clamping, no texture filtering: the plain path tracer
    s.radiance_cache = 0;
    s.clamp = 0.0;
    s.texture_filter = 0.0;
    s.feature_spp = 0;
    Ok(s)
}

/// Version of the reference renders: bump when the path tracer's output changes.
const REFERENCE_VERSION: u32 = 1;

/// Where the reference frame of `s` at the pixels of `grid` lives in `cache`: a key of the
/// scene, every setting the plain path tracer reads and the grid.
fn reference_path(cache: &Path, plan: &Plan, s: &RenderSettings, grid: &Grid) -> PathBuf {
    let mut h = Sha256::new();
    h.update(plan.scene_key.as_bytes());
    let settings = (s.width, s.height, s.spp, s.max_depth, s.rr_depth, s.seed, s.frame, s.sampler, s.light_samples);
    h.update(format!("{REFERENCE_VERSION}|{settings:?}|{:?}|{grid:?}", s.camera).as_bytes());
    let key: String = h.finalize().iter().take(16).map(|b| format!("{b:02x}")).collect();
    cache.join(format!("ref_{key}.exr"))
}

/// The reference render of `s` at the pixels of `grid` (full paths, `s.spp` samples each).
fn render_reference(renderer: &Renderer, s: &RenderSettings, grid: &Grid) -> Image {
    let rows: Vec<Vec<glam::Vec3>> = (0..grid.height)
        .into_par_iter()
        .map(|j| {
            (0..grid.width)
                .map(|i| {
                    let (x, y) = grid.pixel(i, j);
                    renderer.pixel(s, x, y)
                })
                .collect()
        })
        .collect();
    Image { width: grid.width, height: grid.height, pixels: rows.concat() }
}

/// Measure `plan`'s frames on a segment (see the [module docs](self)).
pub fn measure(plan: &Plan, opts: &FidelityOptions) -> Result<FidelityReport, DatasetError> {
    let bad = |m: String| DatasetError::config(&plan.scene_file, "fidelity", m);
    if opts.frames < 2 || opts.ref_spp == 0 || opts.windows_ns.iter().any(|&w| w <= 0) || opts.pixel_stride == 0 {
        return Err(bad(
            "need at least 2 frames, at least 1 reference sample per pixel, positive windows and a pixel stride of \
             at least 1"
                .into(),
        ));
    }
    if opts.pixel_stride > 1 && plan.events.sensor != crate::events::Sensor::Mono {
        return Err(bad("a colour (RGGB) sensor is scored at every pixel: use a pixel stride of 1".into()));
    }
    let (w, h) = (plan.config.width, plan.config.height);
    let grid = Grid::new(w, h, opts.pixel_stride.min(w).min(h));
    let n = plan.clock.n_frames;
    let frames = opts.frames.min(n);
    let start = opts.start_frame.unwrap_or((n - frames) / 2);
    if start + frames > n {
        return Err(bad(format!("frames {start}..{} lie outside the {n} frames of the trajectory", start + frames)));
    }
    let range = start..start + frames;
    let times: Vec<i64> = range.clone().map(|k| plan.clock.time_ns(k)).collect();
    // the ideal model: no non-idealities
    let cfg = EventConfig { noise: NoiseConfig::default(), ..plan.events.clone() };
    let pb = if opts.progress { ProgressBar::new(0) } else { ProgressBar::hidden() };
    pb.set_style(
        ProgressStyle::with_template("{msg:12} [{elapsed_precise}] {wide_bar} {pos}/{len} frames ETA {eta_precise}")
            .expect("valid template"),
    );
    let refs = if opts.ceiling { 2 } else { 1 };
    pb.set_length((frames * (1 + refs)) as u64);
    let renderer = Renderer::with_preset(&plan.scene, plan.config.bvh);

    // the references, and the ideal simulators run on them
    pb.set_message("reference");
    let t = Instant::now();
    let mut cached = 0;
    let mut ref_logs = Vec::new();
    let mut ideal_events = Vec::new();
    for which in 0..refs {
        let mut logs = LogFrames::new(grid, times.clone());
        let mut run = EventRun::new(&cfg, plan, (grid.width, grid.height))?;
        for k in range.clone() {
            let s = reference_settings(plan, k, which, opts.ref_spp, opts.reference_pattern)?;
            let path = opts.reference_cache.as_deref().map(|c| reference_path(c, plan, &s, &grid));
            let img = match path.as_deref().map(FrameCache::load).transpose()?.flatten() {
                Some(img) if img.width == grid.width && img.height == grid.height => {
                    cached += 1;
                    img
                }
                _ => {
                    let mut img = render_reference(&renderer, &s, &grid);
                    round_to_f16(&mut img);
                    if let Some(p) = &path {
                        FrameCache::store(p, &img)?;
                    }
                    img
                }
            };
            let img = run.step(img, plan.clock.time_ns(k), k)?;
            logs.logs.push(log_intensity(&cfg, &img, &grid));
            pb.inc(1);
        }
        ref_logs.push(logs);
        // back to full-image pixels
        let full = run.sink.events.iter().map(|e| {
            let (x, y) = grid.pixel(e.x as u32, e.y as u32);
            Event { x: x as u16, y: y as u16, ..*e }
        });
        ideal_events.push(full.collect::<Vec<_>>());
    }
    let reference_time = t.elapsed();

    // the dataset's frames
    pb.set_message("dataset");
    let t = Instant::now();
    let mut run = EventRun::new(&cfg, plan, (w, h))?;
    let mut seq = SequenceRenderer::new(plan, &renderer, plan.config.spp);
    for k in range.clone() {
        let img = seq.frame(k)?;
        run.step(img, plan.clock.time_ns(k), k)?;
        pb.inc(1);
    }
    let dataset_time = t.elapsed();
    pb.finish_and_clear();

    let reference = &ref_logs[0];
    let windows = &opts.windows_ns;
    Ok(FidelityReport {
        frames,
        start_frame: start,
        width: w,
        height: h,
        pixel_stride: grid.step,
        ref_spp: opts.ref_spp,
        dataset: score(&run.sink.events, reference, &cfg, windows),
        ideal: score(&ideal_events[0], reference, &cfg, windows),
        ceiling: ideal_events.get(1).map(|ev| score(ev, reference, &cfg, windows)),
        counts: Comparison::of_events(
            &run.sink.events.iter().filter(|e| grid.index(e).is_some()).copied().collect::<Vec<_>>(),
            &ideal_events[0],
        ),
        dataset_time,
        reference_time,
        reference_cached: cached,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(values: &[[f32; 2]]) -> LogFrames {
        LogFrames {
            grid: Grid::new(2, 1, 1),
            times: (0..values.len() as i64).map(|k| k * 1000).collect(),
            logs: values.iter().map(|v| v.to_vec()).collect(),
        }
    }

    fn ev(x: u16, t_ns: i64, p: i8) -> Event {
        Event { x, y: 0, t_ns, p }
    }

    #[test]
    fn exact_pairs_score_one_and_wrong_signs_score_below_zero() {
        let cfg = EventConfig { c_pos: 0.2, c_neg: 0.2, ..EventConfig::default() };
        // pixel 0 rises by 0.2 per ms, pixel 1 stays
        let r = frames(&[[0.0, 1.0], [0.2, 1.0], [0.4, 1.0], [0.6, 1.0]]);
        let exact = [ev(0, 1000, 1), ev(0, 2000, 1), ev(0, 3000, 1)];
        let s = score(&exact, &r, &cfg, &[1000, 3000]);
        assert_eq!(s.pairs, 2);
        assert!((s.pair_r2 - 1.0).abs() < 1e-9 && s.sign_agreement == 1.0, "{s:?}");
        // windows: each 1 ms window of pixel 0 holds one ON event = its change; pixel 1 none
        assert!(s.windows.iter().all(|&(_, r2)| (r2 - 1.0).abs() < 1e-6), "{s:?}");
        let wrong = [ev(0, 1000, -1), ev(0, 2000, -1), ev(0, 3000, -1)];
        let s = score(&wrong, &r, &cfg, &[1000]);
        assert!(s.pair_r2 < -2.0 && s.sign_agreement == 0.0, "{s:?}");
        // events on the pixel that does not change: pairs explain nothing (r2 0)
        let noise = [ev(1, 1000, 1), ev(1, 2000, -1), ev(1, 3000, 1)];
        let s = score(&noise, &r, &cfg, &[1000]);
        assert!(s.pair_r2.abs() < 1e-9, "{s:?}");
        assert!(s.windows[0].1 < 0.0, "the missing rise and the spurious events cost: {s:?}");
    }

    #[test]
    fn a_grid_picks_every_step_th_pixel_and_maps_events_back() {
        let g = Grid::new(7, 5, 2);
        assert_eq!((g.offset, g.width, g.height), (1, 3, 2));
        assert_eq!(g.pixel(2, 1), (5, 3));
        assert_eq!(g.index(&Event { x: 5, y: 3, t_ns: 0, p: 1 }), Some(5));
        assert_eq!(g.index(&Event { x: 4, y: 3, t_ns: 0, p: 1 }), None);
        assert_eq!(g.index(&Event { x: 0, y: 1, t_ns: 0, p: 1 }), None);
        let mut img = Image::new(7, 5);
        img.pixels[3 * 7 + 5] = glam::Vec3::ONE;
        assert_eq!(g.pick(&img).pixels[5], glam::Vec3::ONE);
    }

    #[test]
    fn reference_is_linear_between_frames() {
        let r = frames(&[[0.0, 0.0], [1.0, 0.0]]);
        assert!((r.at(0, 250) - 0.25).abs() < 1e-9);
        assert_eq!(r.at(0, -5), 0.0);
        assert_eq!(r.at(0, 5000), 1.0);
    }
}
