//! The frames of a dataset's sequence as every stage sees them, the one frame stream the
//! writer, the preview, the noise measurement and the fidelity check all drive: the path
//! tracer's render of frame `k`, then, with `[dataset] denoise`, the temporal window
//! ([`crate::render::temporal`], `temporal_radius` frames on each side) and the spatial filter
//! ([`crate::render::denoise`]), rounded to the stored precision (half floats, what the frame
//! cache holds: [`SequenceRenderer::frame`], or [`SequenceRenderer::frame_or_cached`] through
//! the cache); the event model then sees it times the sensor gain ([`at_sensor`]) and the
//! exposures average it as it is.
//!
//! Frames are asked for in increasing order. The raw renders (with their feature buffers) of
//! the window around the current frame stay in memory, so each frame is rendered once however
//! many windows it serves; asking for a frame further on drops what no later window needs. A
//! frame is a pure function of the plan and its index: a run that starts at frame `m` (a resumed
//! run) re-renders the `radius` frames before it and gets the same bytes as one that started at
//! 0. Memory: the current frame and the `radius` after it (about 11 MB each at 600x400, lighting,
//! reflectance and the raw render in half floats) and the `radius` before it reduced to what a
//! neighbour needs (6.7 MB each): about 0.6 GB at the default radius of 32.

use std::borrow::Cow;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::cache::{round_to_f16, FrameCache};
use super::plan::Plan;
use super::writer::render_settings;
use super::DatasetError;
use crate::base::image::Image;
use crate::render::denoise::{denoise, DenoiseParams};
use crate::render::integrator::Renderer;
use crate::render::temporal::{gather_sources, SequenceFrame, Source, TemporalParams};

/// Renders and filters the frames of a plan's sequence (see the [module docs](self)).
pub struct SequenceRenderer<'p, 'r> {
    plan: &'p Plan,
    renderer: &'r Renderer<'p>,
    spp: u32,
    /// Adaptive sampling's most samples per pixel (0 = off).
    spp_max: u32,
    temporal: TemporalParams,
    /// The window reads every `stride`-th frame on each side of its centre.
    stride: usize,
    /// Consecutive raw renders `(index, frame)` (only with denoising).
    window: VecDeque<(usize, SequenceFrame)>,
    /// Raw renders made so far.
    pub renders: usize,
    /// Shaded samples of those renders (all pixels; more than `spp` each with adaptive
    /// sampling).
    pub samples: u64,
    /// Wall time spent rendering.
    pub render_time: Duration,
    /// Of `render_time`, the part spent rasterising the camera rays' visibility.
    pub raster_time: Duration,
    /// Wall time spent filtering (temporal window and spatial filter).
    pub denoise_time: Duration,
    /// Of `denoise_time`, the part spent in the temporal window.
    pub gather_time: Duration,
}

impl<'p, 'r> SequenceRenderer<'p, 'r> {
    /// Frames of `plan` rendered with `renderer` at `spp` samples per pixel (the plan's own
    /// `spp` for the dataset; the noise measurement also renders its reference through here).
    pub fn new(plan: &'p Plan, renderer: &'r Renderer<'p>, spp: u32) -> SequenceRenderer<'p, 'r> {
        let c = &plan.config;
        let radius = if c.denoise && c.shading == super::Shading::PathTraced { c.temporal_radius as usize } else { 0 };
        SequenceRenderer {
            plan,
            renderer,
            spp,
            spp_max: c.spp_max,
            temporal: TemporalParams { radius, ..TemporalParams::default() },
            stride: c.window_stride() as usize,
            window: VecDeque::new(),
            renders: 0,
            samples: 0,
            render_time: Duration::ZERO,
            raster_time: Duration::ZERO,
            denoise_time: Duration::ZERO,
            gather_time: Duration::ZERO,
        }
    }

    /// The same frames with `spp` samples in every pixel (no adaptive sampling): the noise
    /// measurement's reference.
    pub fn uniform(mut self) -> Self {
        self.spp_max = 0;
        self
    }

    /// Whether [`SequenceRenderer::raw`] has the unfiltered renders: denoised path-traced
    /// frames (surface-cache frames have no image filter and keep no raw renders).
    pub fn keeps_raw(&self) -> bool {
        self.plan.config.denoise && self.plan.config.shading == super::Shading::PathTraced
    }

    /// Frame `k` as the dataset's stages see it, rounded to halves. `k` must not be smaller
    /// than in the previous call (a programming error otherwise).
    pub fn frame(&mut self, k: usize) -> Result<Image, DatasetError> {
        let mut img = self.render(k)?;
        round_to_f16(&mut img);
        Ok(img)
    }

    /// Frame `k` from `cache` when it holds it at the plan's size (with `None`), else rendered
    /// as [`SequenceRenderer::frame`] (with the path the caller stores it at once it is done
    /// with it, [`FrameCache::store`]).
    pub fn frame_or_cached(&mut self, k: usize, cache: &FrameCache) -> Result<(Image, Option<PathBuf>), DatasetError> {
        let c = &self.plan.config;
        let path = cache.frame_path(c.fps, self.spp, c.noise_pattern, k);
        if let Some(img) = FrameCache::load(&path)?.filter(|i| (i.width, i.height) == (c.width, c.height)) {
            return Ok((img, None));
        }
        Ok((self.frame(k)?, Some(path)))
    }

    /// Frame `k` before the rounding to halves.
    fn render(&mut self, k: usize) -> Result<Image, DatasetError> {
        if self.plan.config.shading == super::Shading::SurfaceCache {
            let settings = self.settings(k)?;
            let t = Instant::now();
            let (img, _) = super::writer::render_frame(self.renderer, &settings, self.plan);
            self.renders += 1;
            self.samples += settings.feature_spp.max(settings.spp) as u64 * img.pixels.len() as u64;
            self.render_time += t.elapsed();
            return Ok(img);
        }
        if !self.plan.config.denoise {
            let settings = self.settings(k)?;
            let t = Instant::now();
            let img = self.renderer.render(&settings, None);
            self.renders += 1;
            self.samples += settings.spp as u64 * img.pixels.len() as u64;
            self.render_time += t.elapsed();
            return Ok(img);
        }
        assert!(self.window.front().is_none_or(|(i, _)| *i <= k), "frames asked out of order");
        let r = self.temporal.radius;
        let (lo, hi) = (k.saturating_sub(r), (k + r).min(self.plan.clock.n_frames - 1));
        self.fill(lo, hi)?;
        // frames before k are neighbours from now on, never centres again
        for (_, f) in self.window.iter_mut().filter(|(i, _)| *i < k) {
            f.keep_neighbour_data();
        }
        let t = Instant::now();
        let window = self.window.make_contiguous();
        debug_assert_eq!(window[k - lo].0, k);
        let stride = self.stride;
        let sources: Vec<Source> =
            (lo..=hi).filter(|&j| j != k && j.abs_diff(k) % stride == 0).map(|j| window[j - lo].1.source()).collect();
        let (img, features) = gather_sources(&window[k - lo].1, &sources, &self.temporal);
        self.gather_time += t.elapsed();
        let out = denoise(&img, &features, &DenoiseParams::default());
        self.denoise_time += t.elapsed();
        Ok(out)
    }

    /// The unfiltered render of frame `k` (rounded to halves) when it is in the window with its
    /// pixels (denoising on and `k` the frame asked for last, or one after it within the window).
    pub fn raw(&self, k: usize) -> Option<Image> {
        self.window.iter().find(|(i, _)| *i == k).map(|(_, f)| f.image()).filter(|img| !img.pixels.is_empty())
    }

    /// Make the window hold exactly the raw renders `lo..=hi` (rendering the missing ones).
    fn fill(&mut self, lo: usize, hi: usize) -> Result<(), DatasetError> {
        while self.window.front().is_some_and(|(i, _)| *i < lo) {
            self.window.pop_front();
        }
        let mut next = self.window.back().map_or(lo, |(i, _)| i + 1);
        while next <= hi {
            let settings = self.settings(next)?;
            let t = Instant::now();
            let vis = self.renderer.visibility(&settings, settings.feature_spp.max(settings.spp));
            self.raster_time += t.elapsed();
            let (image, features) = self.renderer.shade_with_features(&settings, &vis);
            drop(vis);
            self.renders += 1;
            self.samples += features.samples;
            self.render_time += t.elapsed();
            self.window.push_back((next, SequenceFrame::new(settings.camera, &image, &features)));
            next += 1;
        }
        Ok(())
    }

    /// Render settings of frame `k`.
    fn settings(&self, k: usize) -> Result<crate::render::film::RenderSettings, DatasetError> {
        let pose = self
            .plan
            .trajectory
            .pose_at(self.plan.clock.time_ns(k))
            .map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        let mut s = render_settings(self.plan, &pose, k, false);
        s.spp = self.spp;
        s.spp_max = self.spp_max;
        Ok(s)
    }
}

/// What the event model sees of a stored frame: its linear values times the sensor `gain`
/// (the frame itself when the gain is 1).
pub fn at_sensor(frame: &Image, gain: f32) -> Cow<'_, Image> {
    if gain == 1.0 {
        return Cow::Borrowed(frame);
    }
    let mut scaled = frame.clone();
    scaled.pixels.iter_mut().for_each(|p| *p *= gain);
    Cow::Owned(scaled)
}
