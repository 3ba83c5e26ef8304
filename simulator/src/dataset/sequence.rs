//! The frames of a dataset's sequence as every stage sees them: the path tracer's render of
//! frame `k`, then, with `[dataset] denoise`, the temporal window
//! ([`crate::render::temporal`], `temporal_radius` frames on each side) and the spatial filter
//! ([`crate::render::denoise`]).
//!
//! Frames are asked for in increasing order. The raw renders (with their feature buffers) of
//! the window around the current frame stay in memory, so each frame is rendered once however
//! many windows it serves; asking for a frame further on drops what no later window needs. A
//! frame is a pure function of the plan and its index: a run that starts at frame `m` (a resumed
//! run) re-renders the `radius` frames before it and gets the same bytes as one that started at
//! 0. Memory: the `radius` frames after the current one (about 10.6 MB each at 600x400), the
//! `radius` before it reduced to what a neighbour needs (7.7 MB each) and the blocks of
//! [`BLOCK_FRAMES`] frames spanning the window (7.7 MB each): about 1.3 GB at a radius of 64.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::plan::Plan;
use super::writer::render_settings;
use super::DatasetError;
use crate::render::denoise::{denoise, DenoiseParams};
use crate::render::film::Image;
use crate::render::integrator::Renderer;
use crate::render::temporal::{gather_sources, Block, SequenceFrame, Source, TemporalParams, BLOCK_FRAMES};

/// Renders and filters the frames of a plan's sequence (see the [module docs](self)).
pub struct SequenceRenderer<'p, 'r> {
    plan: &'p Plan,
    renderer: &'r Renderer<'p>,
    spp: u32,
    temporal: TemporalParams,
    /// Consecutive raw renders `(index, frame)` (only with denoising).
    window: VecDeque<(usize, SequenceFrame)>,
    /// Blocks `(b, block)` of the frames `b B..(b + 1) B` merged (see
    /// [`crate::render::temporal`]), for the window's sides; only with a radius of at least `B`.
    blocks: VecDeque<(usize, Block)>,
    /// Raw renders made so far.
    pub renders: usize,
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
        let radius = if c.denoise { c.temporal_radius as usize } else { 0 };
        SequenceRenderer {
            plan,
            renderer,
            spp,
            temporal: TemporalParams { radius, ..TemporalParams::default() },
            window: VecDeque::new(),
            blocks: VecDeque::new(),
            renders: 0,
            render_time: Duration::ZERO,
            raster_time: Duration::ZERO,
            denoise_time: Duration::ZERO,
            gather_time: Duration::ZERO,
        }
    }

    /// Frame `k` as the dataset's stages see it (not yet rounded to halves). `k` must not be
    /// smaller than in the previous call (a programming error otherwise).
    pub fn frame(&mut self, k: usize) -> Result<Image, DatasetError> {
        if !self.plan.config.denoise {
            let settings = self.settings(k)?;
            let t = Instant::now();
            let img = self.renderer.render(&settings, None);
            self.renders += 1;
            self.render_time += t.elapsed();
            return Ok(img);
        }
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
        // each side of the window: whole blocks where they fit, single frames elsewhere
        let mut sources: Vec<Source> = Vec::with_capacity(2 * r);
        for (a, z) in [(lo, k), (k + 1, hi + 1)] {
            let mut j = a;
            while j < z {
                let block = (j % BLOCK_FRAMES == 0 && j + BLOCK_FRAMES <= z)
                    .then(|| self.blocks.iter().find(|(b, _)| *b == j / BLOCK_FRAMES))
                    .flatten();
                match block {
                    Some((_, b)) => {
                        sources.push(b.source());
                        j += BLOCK_FRAMES;
                    }
                    None => {
                        sources.push(window[j - lo].1.source());
                        j += 1;
                    }
                }
            }
        }
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
        assert!(self.window.front().is_none_or(|(i, _)| *i <= lo + self.temporal.radius), "frames asked out of order");
        while self.window.front().is_some_and(|(i, _)| *i < lo) {
            self.window.pop_front();
        }
        while self.blocks.front().is_some_and(|(b, _)| (b + 1) * BLOCK_FRAMES <= lo) {
            self.blocks.pop_front();
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
            self.render_time += t.elapsed();
            self.window.push_back((next, SequenceFrame::new(settings.camera, &image, &features)));
            // a block is merged as soon as its last frame is rendered
            let first = (next + 1).wrapping_sub(BLOCK_FRAMES);
            if self.temporal.radius >= BLOCK_FRAMES
                && (next + 1).is_multiple_of(BLOCK_FRAMES)
                && self.window.front().is_some_and(|(i, _)| *i <= first)
            {
                let t = Instant::now();
                let frames: Vec<&SequenceFrame> =
                    self.window.iter().filter(|(i, _)| *i >= first).map(|(_, f)| f).collect();
                self.blocks.push_back((first / BLOCK_FRAMES, Block::merge(&frames, &self.temporal)));
                self.denoise_time += t.elapsed();
                self.gather_time += t.elapsed();
            }
            next += 1;
        }
        Ok(())
    }

    fn settings(&self, k: usize) -> Result<crate::render::film::RenderSettings, DatasetError> {
        let pose = self
            .plan
            .trajectory
            .pose_at(self.plan.clock.time_ns(k))
            .map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        let mut s = render_settings(self.plan, &pose, k, false);
        s.spp = self.spp;
        Ok(s)
    }
}
