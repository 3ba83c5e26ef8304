//! How many events does path-tracing noise fire? A short segment of the trajectory is rendered
//! twice, at the dataset's `spp` and at `factor x spp` (the reference), with the dataset's noise
//! pattern; both sequences go through the same event model, and the events are compared
//! per pixel, polarity and time window.
//!
//! With `n_test(b)` and `n_ref(b)` the event counts in bin `b = (pixel, polarity, window)`
//! (by default one window spans the whole segment: within it, *when* a pixel crosses a level
//! depends on the phase of its reference level, which any difference in the first frame shifts,
//! so finer windows also count timing jitter of real events):
//! - *noise fraction* `sum_b max(0, n_test - n_ref) / sum_b n_test`: the share of the test events
//!   the reference does not have (false events);
//! - *missed fraction* `sum_b max(0, n_ref - n_test) / sum_b n_ref`: reference events the test
//!   lacks (noise can also mask real changes).
//!
//! The reference has residual noise of its own (its standard deviation is `1/sqrt(factor)` of
//! the test's), so both fractions are slight underestimates of the truth for small factors;
//! 16x keeps that residual at a quarter of the test's noise.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use super::cache::round_to_f16;
use super::plan::Plan;
use super::settings::NoisePattern;
use super::DatasetError;
use crate::events::{EventSimulator, VecSink};
use crate::render::film::RenderSettings;
use crate::render::integrator::Renderer;

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseOptions {
    /// First frame of the segment (default: the middle of the trajectory).
    pub start_frame: Option<usize>,
    /// Frames in the segment (>= 2).
    pub frames: usize,
    /// Reference samples per pixel = `factor * spp` (>= 2).
    pub factor: u32,
    /// Width of the comparison windows (ns, > 0); `None` = the whole segment.
    pub window_ns: Option<i64>,
    /// Side of the square pixel blocks events are pooled over (1 = per pixel); 2 or 3 forgives
    /// an edge event landing one pixel over, which sub-pixel sampling differences cause.
    pub pool: u32,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for NoiseOptions {
    fn default() -> NoiseOptions {
        NoiseOptions { start_frame: None, frames: 30, factor: 16, window_ns: None, pool: 1, progress: false }
    }
}

/// The measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseReport {
    /// Frames compared.
    pub frames: usize,
    /// Image size.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the test sequence.
    pub spp: u32,
    /// Samples per pixel of the reference.
    pub ref_spp: u32,
    /// Events of the test sequence.
    pub test_events: u64,
    /// Events of the reference.
    pub ref_events: u64,
    /// Test events the reference does not have.
    pub excess: u64,
    /// Reference events the test does not have.
    pub missing: u64,
    /// Wall time rendering the test sequence.
    pub test_time: Duration,
    /// Wall time rendering the reference.
    pub ref_time: Duration,
}

impl NoiseReport {
    /// `excess / test_events` (0 when there are no events).
    pub fn noise_fraction(&self) -> f64 {
        self.excess as f64 / self.test_events.max(1) as f64
    }
    /// `missing / ref_events` (0 when there are no events).
    pub fn missed_fraction(&self) -> f64 {
        self.missing as f64 / self.ref_events.max(1) as f64
    }
}

/// Event counts per (pixel block, polarity is ON, window).
type BinCounts = std::collections::HashMap<(u32, bool, i64), u32>;

/// Per-(pixel, polarity, window) event counts of a sequence rendered at `spp`.
fn event_counts(
    plan: &Plan,
    renderer: &Renderer,
    frames: std::ops::Range<usize>,
    spp: u32,
    opts: &NoiseOptions,
    pb: &ProgressBar,
) -> Result<(BinCounts, u64), DatasetError> {
    let c = &plan.config;
    let mut sim = EventSimulator::new(plan.events.clone(), c.width, c.height)
        .map_err(|e| DatasetError::config(&plan.scene_file, "events", e.to_string()))?;
    let t_start = plan.clock.time_ns(frames.start);
    let mut counts = std::collections::HashMap::new();
    let mut total = 0u64;
    for k in frames {
        let t_ns = plan.clock.time_ns(k);
        let pose = plan.trajectory.pose_at(t_ns).map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        let mut s = RenderSettings::new(pose.camera(plan.yfov as f32));
        (s.width, s.height, s.spp, s.max_depth, s.seed, s.sampler) =
            (c.width, c.height, spp, c.max_depth, c.seed, c.sampler);
        s.clamp = c.clamp;
        s.light_samples = c.light_samples;
        s.frame = match c.noise_pattern {
            NoisePattern::Fixed => 0,
            NoisePattern::PerFrame => k as u64,
        };
        let mut img = renderer.render(&s, None);
        round_to_f16(&mut img);
        img.pixels.iter_mut().for_each(|p| *p *= c.gain);
        let mut sink = VecSink::default();
        sim.step(&img, t_ns, &mut sink).map_err(|e| DatasetError::stage(format!("frame {k}: event model"), e))?;
        for e in &sink.events {
            let (bx, by) = (e.x as u32 / opts.pool, e.y as u32 / opts.pool);
            let key = (by * c.width + bx, e.p > 0, (e.t_ns - t_start) / opts.window_ns.unwrap_or(i64::MAX));
            *counts.entry(key).or_insert(0) += 1;
            total += 1;
        }
        pb.inc(spp as u64);
    }
    Ok((counts, total))
}

/// Measure the noise-induced events of `plan`'s settings on a segment (see the module docs).
pub fn measure(plan: &Plan, opts: &NoiseOptions) -> Result<NoiseReport, DatasetError> {
    let bad = |field: &str, m: String| DatasetError::config(&plan.scene_file, field, m);
    if opts.frames < 2 || opts.factor < 2 || opts.window_ns.is_some_and(|w| w <= 0) || opts.pool == 0 {
        return Err(bad(
            "noise",
            "need at least 2 frames, a factor of at least 2, a positive window and a pool of at least 1 pixel".into(),
        ));
    }
    let n = plan.clock.n_frames;
    let frames = opts.frames.min(n);
    let start = opts.start_frame.unwrap_or((n - frames) / 2);
    if start + frames > n {
        return Err(bad(
            "noise",
            format!("frames {start}..{} lie outside the {n} frames of the trajectory", start + frames),
        ));
    }
    let c = &plan.config;
    let ref_spp = c.spp * opts.factor;
    let pb = if opts.progress { ProgressBar::new(0) } else { ProgressBar::hidden() };
    pb.set_style(
        ProgressStyle::with_template("{msg:12} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta_precise}")
            .expect("valid template"),
    );
    pb.set_length(frames as u64 * (c.spp + ref_spp) as u64);
    let renderer = Renderer::with_preset(&plan.scene, c.bvh);
    let range = start..start + frames;
    pb.set_message("test");
    let t = Instant::now();
    let (test, test_events) = event_counts(plan, &renderer, range.clone(), c.spp, opts, &pb)?;
    let test_time = t.elapsed();
    pb.set_message("reference");
    let t = Instant::now();
    let (reference, ref_events) = event_counts(plan, &renderer, range, ref_spp, opts, &pb)?;
    let ref_time = t.elapsed();
    pb.finish_and_clear();
    let excess = test.iter().map(|(k, &n)| n.saturating_sub(*reference.get(k).unwrap_or(&0)) as u64).sum();
    let missing = reference.iter().map(|(k, &n)| n.saturating_sub(*test.get(k).unwrap_or(&0)) as u64).sum();
    Ok(NoiseReport {
        frames,
        width: c.width,
        height: c.height,
        spp: c.spp,
        ref_spp,
        test_events,
        ref_events,
        excess,
        missing,
        test_time,
        ref_time,
    })
}
