//! A step's batch: what each group of rays is (an image pixel or an event pair), the rays,
//! the per-thread workers and the buffers reused across steps, and the losses a step reports.

use crate::blur::awp::AwpWorkspace;
use crate::data::dataset::Dataset;
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::{RayGrad, Renderer, SampleCounts};
use crate::events::loss::EventWorkspace;

use super::blur_step::StepBlur;
use super::rays::{prepare, PreparedRay};
use super::StepData;
use crate::config::{ImageSource, TrainConfig};
use crate::engine::rng::Rng;
use crate::events::loss::{bayer, event_window};

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
    /// The blur model's gradient record of every view (`StepBlur::view_record` each).
    pub(super) kgrad: Vec<f64>,
    pub(super) awp_ws: AwpWorkspace<f32>,
    /// dL/d features of the chunk's last pass (from the AWP).
    pub(super) dfeat: Vec<f32>,
    /// The blur model's gradient record of every blurred pixel the worker rendered
    /// (`StepBlur::pixel_record` each), for the groups in `pgrad_groups`.
    pub(super) pgrad: Vec<f64>,
    /// The groups of the records in `pgrad`.
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
            coloured: a.coloured + b.coloured,
            ended: a.ended + b.ended,
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

/// Draws a step's groups, in the workers' order: each worker's range of groups (as
/// `GradBuffers::run` cuts them for `threads` workers) holds its share of the pixels, then its
/// share of the events, so chunks never mix the two and only pixel chunks pay for ray
/// gradients. Returns the picks and each view's number of pixels (a pixel's slot is its index
/// among its view's).
pub(super) fn draw(
    cfg: &TrainConfig,
    data: &Dataset,
    sd: &StepData,
    step: u64,
    threads: usize,
) -> (Vec<Pick>, Vec<u32>) {
    let (w, h) = (data.intrinsics.width, data.intrinsics.height);
    let n_pix = cfg.batch_rays;
    let evc = cfg.events.as_ref();
    let n_ev = evc.map_or(0, |e| e.batch);
    let [th_on, th_off] = evc.and_then(|e| e.threshold).unwrap_or([0.2, 0.2]);
    let ev = &data.events;
    let mut pick = Rng::new(cfg.seed, 1 << 40 | step);
    let mut pick_ev = Rng::new(cfg.seed, 2 << 40 | step);
    let total = n_pix + n_ev;
    let kinds = (0..threads).flat_map(|t| {
        let len = total * (t + 1) / threads - total * t / threads;
        let images = (n_pix * (t + 1) / threads - n_pix * t / threads).min(len);
        (0..len).map(move |i| i < images)
    });
    // What each group is, in the workers' order; a pixel's slot is its index among its view's.
    let mut picks = Vec::with_capacity(total);
    let mut slots = vec![0u32; data.views.len()];
    for is_image in kinds {
        if is_image {
            let v = sd.train_views[pick.below(sd.train_views.len() as u64) as usize];
            let (i, j) = (pick.below(w as u64) as u32, pick.below(h as u64) as u32);
            picks.push(Pick::Pixel { v, i, j, slot: slots[v] });
            slots[v] += 1;
        } else {
            let j = sd.candidates[pick_ev.below(sd.candidates.len() as u64) as usize] as usize;
            // (a window of one width draws nothing: [1, 1] is the single-event loss bit for bit)
            let hops = match evc.and_then(|e| e.window) {
                Some([lo, hi]) if hi > lo => lo + pick_ev.below(u64::from(hi - lo) + 1) as u32,
                Some([lo, _]) => lo,
                None => 1,
            };
            let span_us = evc.and_then(|e| e.window_ms).map_or(f64::INFINITY, |ms| ms * 1e3);
            let inside = |t: f64| data.trajectory.contains(t);
            let (k, target) = event_window(ev, inside, j, hops, span_us, [th_on as f32, th_off as f32])
                .expect("candidates have successors");
            picks.push(Pick::Event { j, k, target });
        }
    }
    (picks, slots)
}

/// The rays of the step's groups: a pixel's blur-model rays (`blur` with its view's state in
/// `views`) and, `with_origin`, its origin ray last, or one plain ray; an event pair's two rays
/// at the trajectory poses of its events (a pair whose pose is missing is dropped).
#[allow(clippy::too_many_arguments)]
pub(super) fn assemble<B: StepBlur>(
    picks: Vec<Pick>,
    cfg: &TrainConfig,
    data: &Dataset,
    sd: &StepData,
    blur: &B,
    views: &[Option<B::View>],
    with_origin: bool,
) -> Batch {
    let mut batch =
        Batch { rays: Vec::new(), world: Vec::new(), weights: Vec::new(), groups: Vec::new(), pixels: 0, events: 0 };
    let (ev, evc) = (&data.events, cfg.events.as_ref());
    for p in picks {
        let first = batch.rays.len();
        match p {
            Pick::Pixel { v, i, j, slot } => {
                let view = &data.views[v];
                let img = match (&sd.targets[v], &cfg.images) {
                    (Some(t), _) => t,
                    (None, ImageSource::Sharp) => view.sharp.as_ref().expect("checked in Trainer::new"),
                    (None, _) => &view.image,
                };
                let edi = sd.edi.get(v).and_then(|e| e.as_ref()).map_or([f32::NAN; 3], |e| e.pixel(i, j));
                let ray = data.intrinsics.ray(&view.pose, i, j);
                match &views[v] {
                    Some(state) => {
                        let origin_weight = blur.rays(state, data, view, &ray, i, j, slot as usize, &mut batch);
                        if with_origin {
                            batch.push(data, ray, origin_weight);
                        }
                    }
                    None => batch.push(data, ray, 1.0),
                }
                batch.pixels += 1;
                let kind = Kind::Image { view: v as u32, i, j, slot, target: img.pixel(i, j), edi };
                batch.groups.push(Group { first, n: batch.rays.len() - first, kind });
            }
            Pick::Event { j, k, target } => {
                let (x, y) = (ev.x[j] as f64, ev.y[j] as f64);
                let rays = [ev.t_us[j], ev.t_us[k]].map(|t| {
                    data.trajectory.pose_at(t).map(|pose| data.intrinsics.ray_through(&pose, x + 0.5, y + 0.5))
                });
                let [Some(a), Some(b)] = rays else { continue };
                batch.push(data, a, 0.0);
                batch.push(data, b, 0.0);
                batch.events += 1;
                let channel = if evc.is_some_and(|e| e.colour) { bayer(x, y) } else { 3 };
                batch.groups.push(Group {
                    first,
                    n: 2,
                    kind: Kind::Event { polarity: ev.polarity[k], target, channel },
                });
            }
        }
    }
    batch
}
