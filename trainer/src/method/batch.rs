//! A step's batch: what each group of rays is (an image pixel or an event pair), the rays,
//! the per-thread workers and the buffers reused across steps, and the losses a step reports.

use crate::blur::awp::AwpWorkspace;
use crate::data::dataset::Dataset;
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::{RayGrad, Renderer, SampleCounts};
use crate::events::loss::EventWorkspace;

use super::rays::{prepare, PreparedRay};

#[derive(Clone, Copy, Debug)]
pub(super) enum Kind {
    /// Pixel (`i`, `j`) of `view`: target colour and EDI target (NaN: none); `slot` is its
    /// index among the view's pixels of the step (the DSK's batch).
    Image { view: u32, i: u32, j: u32, slot: u32, target: [f32; 3], edi: [f32; 3] },
    /// An event pair (two rays: t_j, t_k) with the last event's polarity (the eCRF's input)
    /// and the target log change (polarities times thresholds, summed over the hopped events);
    /// channel 3 = luma.
    Event { polarity: i8, target: f32, channel: u8 },
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Group {
    pub(super) first: usize,
    pub(super) n: usize,
    pub(super) kind: Kind,
}

/// Per-thread state of a step.
#[derive(Clone, Debug, Default)]
pub struct Worker {
    pub(super) renderer: Renderer,
    pub(super) d_rays: Vec<RayGrad<f32>>,
    pub(super) dc: Vec<[f32; 3]>,
    pub(super) df: Vec<[f32; 3]>,
    pub(super) events: EventWorkspace,
    /// Kernel gradients per view: K x (dR 9 + dt 3), then K + 1 weight gradients, then (with
    /// the AWP) the embedding's gradient from the AWP.
    pub(super) kgrad: Vec<f64>,
    pub(super) awp_ws: AwpWorkspace<f32>,
    /// dL/d features of the chunk's last pass (from the AWP).
    pub(super) dfeat: Vec<f32>,
    /// Per-pixel kernel gradients (DSK): for each group in `pgrad_groups`, K x (d offset 2,
    /// d origin 3, d weight 1).
    pub(super) pgrad: Vec<f64>,
    pub(super) pgrad_groups: Vec<u32>,
}

/// Buffers reused across steps.
#[derive(Debug, Default)]
pub struct StepBuffers {
    pub(super) grads: GradBuffers,
    pub(super) workers: Vec<Worker>,
    pub(super) sum: Vec<f32>,
}

impl StepBuffers {
    /// Buffers for `threads` workers (the cut of every batch, hence the reproducibility unit).
    pub fn new(threads: usize) -> StepBuffers {
        StepBuffers { grads: GradBuffers::default(), workers: vec![Worker::default(); threads.max(1)], sum: Vec::new() }
    }

    /// The samples every worker has rendered and evaluated so far.
    pub fn sample_counts(&self) -> SampleCounts {
        self.workers.iter().map(|w| w.renderer.counts()).fold(SampleCounts::default(), |a, b| SampleCounts {
            rays: a.rays + b.rays,
            rendered: a.rendered + b.rendered,
            density: a.density + b.density,
            alive: a.alive + b.alive,
        })
    }
}

/// Mean losses of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepLosses {
    /// Image loss (both passes, mean over pixels and channels).
    pub image: f64,
    /// PSNR of the fine pass's (blurry) colour on the batch.
    pub psnr: f64,
    /// Event loss (both passes, mean over events, unweighted).
    pub event: f64,
    /// EDI loss (both passes, mean over pixels and channels, unweighted).
    pub edi: f64,
    /// AWP colour loss (fine pass, mean over the kernel's pixels and channels, unweighted; 0
    /// without the AWP or before the kernel starts).
    pub awp: f64,
}

#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Sums {
    pub(super) image: [f64; 2],
    pub(super) event: f64,
    pub(super) edi: f64,
    pub(super) awp: f64,
}

/// The batch of one step: rays (NDC, their world form and blending weight) and groups.
pub(super) struct Batch {
    pub(super) rays: Vec<PreparedRay>,
    pub(super) world: Vec<Ray>,
    /// Each ray's weight in its pixel's blurry colour (unused for plain pixels and events).
    pub(super) weights: Vec<f32>,
    pub(super) groups: Vec<Group>,
    pub(super) pixels: usize,
    pub(super) events: usize,
}

impl Batch {
    pub(super) fn push(&mut self, data: &Dataset, ray: Ray, weight: f32) {
        self.rays.push(prepare(data, &ray));
        self.world.push(ray);
        self.weights.push(weight);
    }
}

/// What a group of the step is, before its rays are made.
#[derive(Clone, Copy, Debug)]
pub(super) enum Pick {
    Pixel { v: usize, i: u32, j: u32, slot: u32 },
    Event { j: usize, k: usize, target: f32 },
}
