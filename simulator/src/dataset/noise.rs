//! How many events does path-tracing noise fire? A short segment of the trajectory is rendered
//! twice, at the dataset's `spp` and at `factor x spp` (the reference; with adaptive sampling,
//! `factor` times the test's mean samples per pixel, rounded up, in every pixel), with the
//! dataset's noise pattern; both sequences go through the dataset's filters ([`super::sequence`]: the temporal
//! window, which also renders the `temporal_radius` frames on each side of the segment, and the
//! spatial filter) and the same event model, and the events are compared per pixel, polarity
//! and time window.
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

use super::plan::Plan;
use super::sequence::{at_sensor, SequenceRenderer};
use super::DatasetError;
use crate::events::{EventSimulator, VecSink};
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

/// Event counts of one sequence compared with another's.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Events of the tested sequence.
    pub test_events: u64,
    /// Events of the reference.
    pub ref_events: u64,
    /// Test events the reference does not have.
    pub excess: u64,
    /// Reference events the test does not have.
    pub missing: u64,
}

impl Comparison {
    /// `excess / test_events` (0 when there are no events).
    pub fn noise_fraction(&self) -> f64 {
        self.excess as f64 / self.test_events.max(1) as f64
    }
    /// `missing / ref_events` (0 when there are no events).
    pub fn missed_fraction(&self) -> f64 {
        self.missing as f64 / self.ref_events.max(1) as f64
    }

    /// Per block of `pool` x `pool` pixels (row-major over the `width` x `height` image's
    /// blocks): `[excess, missing]` events.
    fn map(test: &Counted, reference: &Counted, pool: u32, blocks: (u32, u32)) -> DiffMap {
        let n = (blocks.0 * blocks.1) as usize;
        let (mut excess, mut missing) = (vec![0u32; n], vec![0u32; n]);
        for (k, &t) in &test.bins {
            excess[k.0 as usize] += t.saturating_sub(*reference.bins.get(k).unwrap_or(&0));
        }
        for (k, &r) in &reference.bins {
            missing[k.0 as usize] += r.saturating_sub(*test.bins.get(k).unwrap_or(&0));
        }
        DiffMap { pool, width: blocks.0, height: blocks.1, excess, missing }
    }

    /// Two event lists compared by their counts per pixel and polarity (one window).
    pub fn of_events(test: &[crate::events::Event], reference: &[crate::events::Event]) -> Comparison {
        let count = |events: &[crate::events::Event]| {
            let mut c = Counted::default();
            for e in events {
                *c.bins.entry(((e.y as u32) << 16 | e.x as u32, e.p > 0, 0)).or_insert(0) += 1;
                c.total += 1;
            }
            c
        };
        Comparison::of(&count(test), &count(reference))
    }

    fn of(test: &Counted, reference: &Counted) -> Comparison {
        let excess =
            test.bins.iter().map(|(k, &n)| n.saturating_sub(*reference.bins.get(k).unwrap_or(&0)) as u64).sum();
        let missing =
            reference.bins.iter().map(|(k, &n)| n.saturating_sub(*test.bins.get(k).unwrap_or(&0)) as u64).sum();
        Comparison { test_events: test.total, ref_events: reference.total, excess, missing }
    }
}

/// Where the dataset's events differ from the reference's: per block of `pool` x `pool` pixels,
/// row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffMap {
    /// Side of a block (pixels).
    pub pool: u32,
    /// Blocks per row.
    pub width: u32,
    /// Block rows.
    pub height: u32,
    /// Test events the reference does not have, per block.
    pub excess: Vec<u32>,
    /// Reference events the test does not have, per block.
    pub missing: Vec<u32>,
}

impl DiffMap {
    /// The map drawn over `frame` (dimmed to grey): excess events in red, missing ones in blue
    /// (full colour from 2 events per block on), as a linear image of `frame`'s size.
    pub fn overlay(&self, frame: &crate::base::image::Image) -> crate::base::image::Image {
        let (w, h) = (frame.width, frame.height);
        let pool = self.pool.max(1);
        let pixels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let b = ((y / pool) * self.width + x / pool) as usize;
                let grey = 0.25 * crate::base::colour::luminance(frame.pixels[i as usize]).clamp(0.0, 1.0);
                let level = |n: u32| (n as f32 / 2.0).min(1.0);
                let (e, m) = (level(self.excess[b]), level(self.missing[b]));
                glam::Vec3::new(grey + (1.0 - grey) * e, grey * (1.0 - e.max(m)), grey + (1.0 - grey) * m)
            })
            .collect();
        crate::base::image::Image { width: w, height: h, pixels }
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
    /// Whether the dataset's frames are filtered (`[dataset] denoise` on path-traced frames;
    /// surface-cache frames have no image filter).
    pub denoised: bool,
    /// The dataset's frames at `spp` against the same pipeline at `ref_spp`: the noise measure.
    pub pipeline: Comparison,
    /// Where the events of [`NoiseReport::pipeline`] differ.
    pub pipeline_map: DiffMap,
    /// The segment's first frame as the dataset renders it (linear), to show the map on.
    pub first_frame: crate::base::image::Image,
    /// With denoising on (path-traced frames; surface-cache frames have no image filter, so
    /// there is no unfiltered sequence to compare): the denoised frames at `spp`
    /// against *unfiltered* frames at `ref_spp`
    /// (what the filter changes besides noise shows up here, next to the reference's own noise).
    pub vs_unfiltered: Option<Comparison>,
    /// With denoising on (path-traced frames): unfiltered frames at `spp` against unfiltered
    /// frames at `ref_spp`
    /// (the measure without the filter, from the same renders).
    pub unfiltered: Option<Comparison>,
    /// Frames rendered per sequence: the segment plus the temporal window's margins.
    pub renders: usize,
    /// Mean shaded samples per pixel of the test sequence's renders (`spp`, or more with
    /// adaptive sampling).
    pub mean_spp: f64,
    /// Wall time rendering the test sequence (and filtering it).
    pub test_time: Duration,
    /// Wall time rendering the reference (and filtering it).
    pub ref_time: Duration,
}

/// Event counts per (pixel block, polarity is ON, window).
type BinCounts = std::collections::HashMap<(u32, bool, i64), u32>;

/// The binned events of one sequence.
#[derive(Default)]
struct Counted {
    bins: BinCounts,
    total: u64,
}

/// What [`event_counts`] returns: the binned events, the renders made and their shaded
/// samples, and the segment's first frame.
type SequenceCounts = (Vec<Counted>, (usize, u64), crate::base::image::Image);

/// Binned events of a sequence rendered at `spp` (`spp` in every pixel when `uniform`, else
/// with the plan's adaptive sampling): `[as the dataset renders it, unfiltered]` (the second
/// only for denoised path-traced frames; both from the same renders).
fn event_counts(
    plan: &Plan,
    renderer: &Renderer,
    frames: std::ops::Range<usize>,
    spp: u32,
    uniform: bool,
    opts: &NoiseOptions,
    pb: &ProgressBar,
) -> Result<SequenceCounts, DatasetError> {
    let c = &plan.config;
    let mut seq = SequenceRenderer::new(plan, renderer, spp);
    if uniform {
        seq = seq.uniform();
    }
    let variants = if seq.keeps_raw() { 2 } else { 1 };
    let mut sims = (0..variants)
        .map(|_| EventSimulator::new(plan.events.clone(), c.width, c.height))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| DatasetError::config(&plan.scene_file, "events", e.to_string()))?;
    let t_start = plan.clock.time_ns(frames.start);
    let mut out: Vec<Counted> = (0..variants).map(|_| Counted::default()).collect();
    let mut first = None;
    for k in frames {
        let t_ns = plan.clock.time_ns(k);
        let mut images = vec![seq.frame(k)?];
        if variants == 2 {
            images.push(seq.raw(k).expect("denoised path-traced frames keep the window's raw renders"));
        }
        for ((img, sim), counted) in images.into_iter().zip(&mut sims).zip(&mut out) {
            // (a raw render is kept in halves already)
            let img = at_sensor(&img, c.gain).into_owned();
            if first.is_none() {
                first = Some(img.clone());
            }
            let mut sink = VecSink::default();
            sim.step(&img, t_ns, &mut sink).map_err(|e| DatasetError::stage(format!("frame {k}: event model"), e))?;
            for e in &sink.events {
                let (bx, by) = (e.x as u32 / opts.pool, e.y as u32 / opts.pool);
                let key = (
                    by * c.width.div_ceil(opts.pool) + bx,
                    e.p > 0,
                    (e.t_ns - t_start) / opts.window_ns.unwrap_or(i64::MAX),
                );
                *counted.bins.entry(key).or_insert(0) += 1;
                counted.total += 1;
            }
        }
        pb.inc(spp as u64);
    }
    let first = first.expect("a segment has at least 2 frames");
    Ok((out, (seq.renders, seq.samples), first))
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
    let pb = if opts.progress { ProgressBar::new(0) } else { ProgressBar::hidden() };
    pb.set_style(
        ProgressStyle::with_template("{msg:12} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta_precise}")
            .expect("valid template"),
    );
    // (with adaptive sampling the reference's share is an upper bound until the test is done)
    pb.set_length(frames as u64 * (c.spp + opts.factor * c.spp.max(c.spp_max)) as u64);
    let renderer = Renderer::with_preset(&plan.scene, c.bvh);
    let range = start..start + frames;
    pb.set_message("test");
    let t = Instant::now();
    let (test, (renders, samples), first_frame) =
        event_counts(plan, &renderer, range.clone(), c.spp, false, opts, &pb)?;
    let test_time = t.elapsed();
    // factor x the test's mean samples per pixel (rounded up), in every pixel: `factor x spp`
    // without adaptive sampling
    let pixels = renders.max(1) as u64 * (c.width * c.height) as u64;
    let ref_spp = opts.factor * samples.div_ceil(pixels).max(1) as u32;
    pb.set_length(frames as u64 * (c.spp + ref_spp) as u64);
    pb.set_message("reference");
    let t = Instant::now();
    let (reference, _, _) = event_counts(plan, &renderer, range, ref_spp, true, opts, &pb)?;
    let ref_time = t.elapsed();
    pb.finish_and_clear();
    Ok(NoiseReport {
        frames,
        width: c.width,
        height: c.height,
        spp: c.spp,
        ref_spp,
        denoised: test.len() == 2,
        pipeline: Comparison::of(&test[0], &reference[0]),
        pipeline_map: Comparison::map(
            &test[0],
            &reference[0],
            opts.pool,
            (c.width.div_ceil(opts.pool), c.height.div_ceil(opts.pool)),
        ),
        first_frame,
        vs_unfiltered: (test.len() == 2).then(|| Comparison::of(&test[0], &reference[1])),
        unfiltered: (test.len() == 2).then(|| Comparison::of(&test[1], &reference[1])),
        renders,
        mean_spp: samples as f64 / (renders.max(1) as f64 * (c.width * c.height) as f64),
        test_time,
        ref_time,
    })
}
