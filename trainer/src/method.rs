//! One training step of any method: the image loss through an optional blur kernel, the event
//! loss through an optional eCRF, the EDI prior, TV and Adam.
//!
//! A step's batch is a list of *groups* of rays, each worker's share holding its part of the
//! pixels and then its part of the events:
//! - an image pixel of a training view: one plain ray, or (blur kernel on) the K warped rays and
//!   the origin ray last. Its blurry colour is `B = sum_k w_k C_k` (linear), the loss
//!   `(g(B) - y)^2` per channel on both passes, g the camera response. The EDI prior adds
//!   `lambda_EDI (g(C_origin) - y_EDI)^2` on both passes.
//! - an event pair: event j and its successor k at the same pixel; the pixel's rays at the
//!   trajectory poses of t_j and t_k (no blur kernel). With L = luma(eCRF(C)) (or the event's
//!   Bayer channel for colour events), the loss is
//!   `(log(L_k + eps) - log(L_j + eps) - p_k Theta_{p_k})^2` on both passes.
//!
//! Each term is a mean over its pixels (x 3 channels) or events and the passes add. The kernel's
//! gradient reaches the twists through the renderer's ray gradients, the NDC warp's backward,
//! the view direction's normalisation and the rigid warp (all finite-difference checked).

use std::ops::Range;
use std::path::Path;

use glam::DVec3;

use crate::blur::awp::{Awp, AwpWorkspace};
use crate::blur::dsk::{Dsk, DskWorkspace};
use crate::blur::rigid::{KernelOut, RigidKernel};
use crate::blur::se3::{self, Rigid};
use crate::blur::trajectory::Trajectory;
use crate::config::{ImageSource, TrainConfig};
use crate::data::dataset::{Dataset, View};
use crate::data::events::Events;
use crate::data::image::RgbImage;
use crate::data::rays::{ndc_ray_backward, Intrinsics, Ray};
use crate::engine::adam::Adam;
use crate::engine::model::Model;
use crate::engine::parallel::GradBuffers;
use crate::engine::params::Layout;
use crate::engine::real::Real;
use crate::engine::renderer::{PassSamples, RayChunk, RayGrad, Renderer, SampleCounts};
use crate::engine::rng::Rng;
use crate::error::TrainError;
use crate::events::ecrf::{Ecrf, EcrfWorkspace};
use crate::train::{prepare, response, scene_bounds, unzip, PreparedRay, NDC_NEAR};
use simulator::events::{EventConfig, Sensor};
use simulator::trajectory::Pose;

/// The reference luma of monochrome events (BT.601), used when the dataset does not say.
pub const BT601: [f64; 3] = [0.299, 0.587, 0.114];
/// Rec.709 luma, what `evsim`'s monochrome sensor sees.
pub const REC709: [f64; 3] = [0.2126, 0.7152, 0.0722];
/// Weights of colour events by Bayer channel (R, G, B), as the reference.
pub const COLOUR_WEIGHTS: [f32; 3] = [0.4, 0.2, 0.4];

/// A blur model's parameters (module `crate::blur`).
#[derive(Clone, Debug)]
pub enum Blur {
    /// DP-NeRF's rigid blurring kernel (embeddings for every view of the dataset).
    Rigid(RigidKernel),
    /// Virtual cameras inside the exposure (BAD-NeRF learned, E2NeRF fixed).
    Trajectory(Trajectory),
    /// Deblur-NeRF's deformable sparse kernel.
    Dsk(Dsk),
}

impl Blur {
    /// Rays per blurry pixel (besides the origin ray).
    pub fn rays(&self) -> usize {
        match self {
            Blur::Rigid(k) => k.config.k,
            Blur::Trajectory(t) => t.config.k,
            Blur::Dsk(d) => d.config.k,
        }
    }

    /// The rigid kernel, if this is one.
    pub fn rigid(&self) -> Option<&RigidKernel> {
        match self {
            Blur::Rigid(k) => Some(k),
            _ => None,
        }
    }
}

/// A method's parameters: the radiance field, then (when configured) the blur model, the eCRF
/// and the AWP, all in one layout (one parameter vector, one Adam, one checkpoint).
#[derive(Clone, Debug)]
pub struct Method {
    /// The radiance field (its layout holds every parameter of the method).
    pub model: Model,
    /// The blur model.
    pub blur: Option<Blur>,
    /// The event camera response.
    pub ecrf: Option<Ecrf>,
    /// The adaptive weight proposal (with the kernel).
    pub awp: Option<Awp>,
}

impl Method {
    /// The parameters of `cfg` for a dataset of `views` views.
    pub fn new(cfg: &TrainConfig, views: usize) -> Method {
        let mut model = Model::new(&cfg.model);
        let coarse_features = model.coarse.shape.features;
        let blur = cfg.blur.as_ref().map(|b| {
            let l = &mut model.layout;
            match (&b.kernel, &b.dsk, &b.trajectory) {
                (Some(k), _, _) => Blur::Rigid(RigidKernel::new(l, k, views)),
                (None, Some(d), _) => Blur::Dsk(Dsk::new(l, d, views, coarse_features)),
                (None, None, Some(t)) => Blur::Trajectory(Trajectory::new(l, t, views)),
                (None, None, None) => unreachable!("validated: one blur model"),
            }
        });
        let ecrf = cfg.ecrf.as_ref().map(|c| Ecrf::new(&mut model.layout, c));
        let awp = cfg.blur.as_ref().and_then(|b| {
            let (a, k) = (b.awp.as_ref()?, b.kernel.as_ref()?);
            let features = model.fine_field().shape.features;
            Some(Awp::new(&mut model.layout, a, k.k + 1, features, k.embedding))
        });
        Method { model, blur, ecrf, awp }
    }

    /// The layout of every parameter.
    pub fn layout(&self) -> &Layout {
        &self.model.layout
    }

    /// Fresh parameters from `seed` (the field as `Model::init`, then the kernel and the eCRF).
    pub fn init(&self, seed: u64) -> Vec<f32> {
        let mut params = self.model.init(seed);
        let mut rng = Rng::new(seed, 0x1419);
        match &self.blur {
            Some(Blur::Rigid(k)) => k.init(&mut params, &mut || rng.uniform_f64()),
            Some(Blur::Dsk(d)) => d.init(&mut params, &mut || rng.uniform_f64()),
            Some(Blur::Trajectory(_)) | None => {} // twists start at zero: the dataset's poses
        }
        if let Some(e) = &self.ecrf {
            e.init(&mut params, seed);
        }
        if let Some(a) = &self.awp {
            let mut rng = Rng::new(seed, 0xa3b);
            a.init(&mut params, &mut || rng.uniform_f64());
        }
        params
    }
}

/// Fills in what a configuration leaves to the dataset: the volume box (fitted to the cameras)
/// and the event model (threshold, log offset, luma from `dataset.toml`, else the reference's).
pub fn resolve(cfg: &mut TrainConfig, data: &Dataset) {
    if cfg.model.bounds.is_none() {
        cfg.model.bounds = Some(scene_bounds(data));
    }
    let Some(ev) = cfg.events.as_mut() else { return };
    let model = event_model(data);
    if ev.threshold.is_none() {
        ev.threshold = Some(dataset_thresholds(data).unwrap_or([0.2, 0.2]));
    }
    if ev.log_eps.is_none() {
        ev.log_eps = Some(model.map_or(1e-5, |m| m.log_eps as f64));
    }
    if ev.luma.is_none() {
        ev.luma = Some(if model.is_some_and(|m| m.sensor == Sensor::Mono) { REC709 } else { BT601 });
    }
}

/// The thresholds `[c_pos, c_neg]` the dataset's events were simulated with (its
/// `dataset.toml`), if it records them.
pub fn dataset_thresholds(data: &Dataset) -> Option<[f64; 2]> {
    event_model(data).map(|m| [m.c_pos as f64, m.c_neg as f64])
}

/// The event model of the dataset's manifest (`dataset.toml`, written by `evsim`), if any.
pub fn event_model(data: &Dataset) -> Option<&EventConfig> {
    data.manifest.as_ref().map(|m| &m.event_model)
}

/// The events the loss samples from: indices of events with a successor (`min_hops`
/// successors, for event windows) inside the trajectory (and, with `inside_exposures`, whose
/// pair lies inside one training view's exposure).
pub fn event_candidates(data: &Dataset, train_views: &[usize], inside_exposures: bool, min_hops: u32) -> Vec<u32> {
    let ev = &data.events;
    let mut windows: Vec<(f64, f64)> =
        train_views.iter().map(|&v| (data.views[v].t_start_us, data.views[v].t_end_us)).collect();
    windows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let inside = |a: f64, b: f64| {
        // the last window starting at or before a
        let i = windows.partition_point(|w| w.0 <= a);
        i > 0 && b <= windows[i - 1].1
    };
    let nth = |i: usize| (0..min_hops.max(1)).try_fold(i, |e, _| ev.successor(e));
    (0..ev.len() as u32)
        .filter(|&i| match nth(i as usize) {
            None => false,
            Some(k) => {
                let (a, b) = (ev.t_us[i as usize], ev.t_us[k]);
                data.trajectory.contains(a) && data.trajectory.contains(b) && (!inside_exposures || inside(a, b))
            }
        })
        .collect()
}

/// The end of an event window: from event `j`, up to `hops` events on at its pixel (fewer
/// where the pixel's events, or those inside the trajectory (`contains`) and at most
/// `max_span_us` after event `j`, end first), and the target log change, the hopped events'
/// polarities times `threshold` (ON, OFF) summed. None when `j` has no successor.
pub fn event_window(
    ev: &Events,
    contains: impl Fn(f64) -> bool,
    j: usize,
    hops: u32,
    max_span_us: f64,
    threshold: [f32; 2],
) -> Option<(usize, f32)> {
    let (mut k, mut counts) = (j, [0u32; 2]);
    let t0 = ev.t_us[j];
    for h in 0..hops {
        // the first successor is the caller's to check (candidates are inside the trajectory)
        match ev.successor(k).filter(|&n| h == 0 || (contains(ev.t_us[n]) && ev.t_us[n] - t0 <= max_span_us)) {
            Some(n) => {
                k = n;
                counts[usize::from(ev.polarity[n] < 0)] += 1;
            }
            None => break,
        }
    }
    // one ON event: 1 * C_on - 0 * C_off, exactly C_on (and -C_off for one OFF event)
    (k != j).then(|| (k, counts[0] as f32 * threshold[0] - counts[1] as f32 * threshold[1]))
}

/// What a step needs besides the parameters, prepared once per run.
#[derive(Clone, Debug, Default)]
pub struct StepData {
    /// Training views.
    pub train_views: Vec<usize>,
    /// Events the loss samples from.
    pub candidates: Vec<u32>,
    /// EDI targets per view (display-referred), for the training views.
    pub edi: Vec<Option<RgbImage>>,
    /// Replacement training images per view (EDI- or command-deblurred, display-referred);
    /// `None`: the dataset's.
    pub targets: Vec<Option<RgbImage>>,
}

impl StepData {
    /// Prepares the event candidates, the EDI targets and the deblurred training images (cached
    /// under the run folder `cache`, when given).
    pub fn new(
        data: &Dataset,
        cfg: &TrainConfig,
        train_views: Vec<usize>,
        cache: Option<&Path>,
    ) -> Result<StepData, TrainError> {
        let mut candidates = Vec::new();
        if let Some(e) = &cfg.events {
            if e.colour && event_model(data).is_some_and(|m| m.sensor == Sensor::Mono) {
                return Err(TrainError::Config(format!(
                    "events.colour = true, but {} says the events are monochrome (sensor = \"mono\"); set events.colour = false or write the dataset with the rggb sensor",
                    data.dir.join("dataset.toml").display()
                )));
            }
            candidates = event_candidates(data, &train_views, e.inside_exposures, e.window.map_or(1, |w| w[0]));
            if candidates.is_empty() {
                return Err(TrainError::Missing {
                    path: data.dir.join("events.h5"),
                    what: "no event has a successor at the same pixel (the event loss has nothing to sample)".into(),
                    fix: "write the dataset with events (evsim dataset), or choose a preset without events".into(),
                });
            }
        }
        let edi_images = |bins: usize| -> Result<Vec<RgbImage>, TrainError> {
            let [on, off] = event_thresholds(cfg, data);
            Ok(match cache {
                Some(dir) => crate::events::edi::precompute(
                    data,
                    &train_views,
                    bins,
                    (on, off),
                    cfg.response_gamma,
                    &dir.join("edi"),
                )?,
                None => train_views
                    .iter()
                    .map(|&v| {
                        let (w, h) = (data.intrinsics.width, data.intrinsics.height);
                        crate::events::edi::edi_image(
                            &data.views[v],
                            &data.events,
                            w,
                            h,
                            bins,
                            (on, off),
                            cfg.response_gamma,
                        )
                    })
                    .collect(),
            })
        };
        let per_view = |images: Vec<RgbImage>| {
            let mut out = vec![None; data.views.len()];
            for (&v, img) in train_views.iter().zip(images) {
                out[v] = Some(img);
            }
            out
        };
        let edi = match &cfg.edi {
            Some(d) => per_view(edi_images(d.bins)?),
            None => vec![None; data.views.len()],
        };
        let targets = match &cfg.images {
            ImageSource::Edi => match &cfg.edi {
                Some(_) => edi.clone(),
                None => per_view(edi_images(crate::events::edi::EdiConfig::reference_real().bins)?),
            },
            ImageSource::Deblur(command) => per_view(crate::deblur::deblur_views(data, &train_views, command, cache)?),
            ImageSource::Blurry | ImageSource::Sharp => vec![None; data.views.len()],
        };
        Ok(StepData { train_views, candidates, edi, targets })
    }
}

/// The training thresholds (resolved, else the dataset's, else 0.2).
pub(crate) fn event_thresholds(cfg: &TrainConfig, data: &Dataset) -> [f64; 2] {
    // the training threshold if the configuration has events, else (edi-nerf) the dataset's own
    cfg.events.as_ref().and_then(|e| e.threshold).or_else(|| dataset_thresholds(data)).unwrap_or([0.2, 0.2])
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Pixel (`i`, `j`) of `view`: target colour and EDI target (NaN: none); `slot` is its
    /// index among the view's pixels of the step (the DSK's batch).
    Image { view: u32, i: u32, j: u32, slot: u32, target: [f32; 3], edi: [f32; 3] },
    /// An event pair (two rays: t_j, t_k) with the last event's polarity (the eCRF's input)
    /// and the target log change (polarities times thresholds, summed over the hopped events);
    /// channel 3 = luma.
    Event { polarity: i8, target: f32, channel: u8 },
}

#[derive(Clone, Copy, Debug)]
struct Group {
    first: usize,
    n: usize,
    kind: Kind,
}

/// Per-thread state of a step.
#[derive(Clone, Debug, Default)]
pub struct Worker {
    renderer: Renderer,
    d_rays: Vec<RayGrad<f32>>,
    dc: Vec<[f32; 3]>,
    df: Vec<[f32; 3]>,
    ecrf_ws: [EcrfWorkspace<f32>; 3],
    ex: [Vec<f32>; 3],
    ey: [Vec<f32>; 3],
    edy: [Vec<f32>; 3],
    edx: Vec<f32>,
    epol: Vec<i8>,
    /// Kernel gradients per view: K x (dR 9 + dt 3), then K + 1 weight gradients, then (with
    /// the AWP) the embedding's gradient from the AWP.
    kgrad: Vec<f64>,
    awp_ws: AwpWorkspace<f32>,
    /// dL/d features of the chunk's last pass (from the AWP).
    dfeat: Vec<f32>,
    /// Per-pixel kernel gradients (DSK): for each group in `pgrad_groups`, K x (d offset 2,
    /// d origin 3, d weight 1).
    pgrad: Vec<f64>,
    pgrad_groups: Vec<u32>,
}

/// Buffers reused across steps.
#[derive(Debug, Default)]
pub struct StepBuffers {
    grads: GradBuffers,
    workers: Vec<Worker>,
    sum: Vec<f32>,
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
struct Sums {
    image: [f64; 2],
    event: f64,
    edi: f64,
    awp: f64,
}

/// The batch of one step: rays (NDC, their world form and blending weight) and groups.
struct Batch {
    rays: Vec<PreparedRay>,
    world: Vec<Ray>,
    /// Each ray's weight in its pixel's blurry colour (unused for plain pixels and events).
    weights: Vec<f32>,
    groups: Vec<Group>,
    pixels: usize,
    events: usize,
}

impl Batch {
    fn push(&mut self, data: &Dataset, ray: Ray, weight: f32) {
        self.rays.push(prepare(data, &ray));
        self.world.push(ray);
        self.weights.push(weight);
    }
}

/// What a group of the step is, before its rays are made.
#[derive(Clone, Copy, Debug)]
enum Pick {
    Pixel { v: usize, i: u32, j: u32, slot: u32 },
    Event { j: usize, k: usize, target: f32 },
}

/// One view's blur model in this step.
struct ViewKernel {
    /// The rigid kernel's output (twists and K + 1 weights).
    rigid: Option<KernelOut<f32>>,
    /// Twists of the K rays (rigid kernel, learned trajectory).
    twists: Vec<[f64; 6]>,
    /// Their world-frame motions.
    motions: Vec<Rigid>,
    /// Poses of the K virtual cameras (fixed trajectory).
    poses: Vec<Pose>,
    /// The DSK's kernels of the view's pixels, in slot order.
    dsk: Option<DskWorkspace<f32>>,
    /// Rays per pixel.
    k: usize,
}

impl ViewKernel {
    /// The model of view `v` whose batch pixels (slot order, pixel centres) are `pixels`
    /// (`features`: a progressive DSK's feature input, from PDRF's first stage).
    fn new(
        blur: &Blur,
        params: &[f32],
        data: &Dataset,
        v: usize,
        pixels: &[[f32; 2]],
        noise: &mut Rng,
        features: Option<&[f32]>,
    ) -> ViewKernel {
        let mut vk = ViewKernel {
            rigid: None,
            twists: Vec::new(),
            motions: Vec::new(),
            poses: Vec::new(),
            dsk: None,
            k: blur.rays(),
        };
        match blur {
            Blur::Rigid(kernel) => {
                let out = kernel.forward(params, v);
                vk.twists = out.twists.iter().map(|t| t.map(|x| x as f64)).collect();
                vk.rigid = Some(out);
            }
            Blur::Trajectory(t) if t.config.learned => vk.twists = t.twists(params, v),
            Blur::Trajectory(t) => {
                let view = &data.views[v];
                vk.poses = (0..t.config.k)
                    .map(|k| {
                        let time = view.t_start_us + t.tau(k) * (view.t_end_us - view.t_start_us);
                        data.trajectory.pose_at(time).unwrap_or(view.pose)
                    })
                    .collect();
            }
            Blur::Dsk(dsk) => {
                let k = dsk.config.k;
                let jitter: Vec<[f32; 2]> =
                    (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
                let size = [data.intrinsics.width as f32, data.intrinsics.height as f32];
                let mut ws = DskWorkspace::default();
                dsk.forward(params, &mut ws, v, pixels, size, Some(&jitter), features);
                vk.dsk = Some(ws);
            }
        }
        vk.motions = vk.twists.iter().map(|&t| se3::exp(t)).collect();
        vk
    }

    /// Pushes the K rays of pixel (`i`, `j`) (world ray `ray`, DSK slot `slot`) with their
    /// weights; returns the origin ray's weight.
    #[allow(clippy::too_many_arguments)]
    fn rays(&self, data: &Dataset, view: &View, ray: &Ray, i: u32, j: u32, slot: usize, batch: &mut Batch) -> f32 {
        match (&self.rigid, &self.dsk, self.poses.is_empty()) {
            (Some(out), _, _) => {
                for (m, &w) in self.motions.iter().zip(&out.weights) {
                    batch.push(data, warp(m, ray), w);
                }
                out.weights[self.motions.len()]
            }
            (None, Some(ws), _) => {
                let k = self.k;
                for q in slot * k..(slot + 1) * k {
                    let (o, t) = (ws.offsets[q].map(f64::from), ws.origins[q].map(f64::from));
                    batch.push(data, dsk_ray(&data.intrinsics, &view.pose, i, j, o, t), ws.weights[q]);
                }
                0.0
            }
            (None, None, false) => {
                let w = 1.0 / self.poses.len() as f32;
                for pose in &self.poses {
                    batch.push(data, data.intrinsics.ray(pose, i, j), w);
                }
                0.0
            }
            (None, None, true) => {
                let w = 1.0 / self.motions.len() as f32;
                for m in &self.motions {
                    batch.push(data, warp(m, ray), w);
                }
                0.0
            }
        }
    }
}

/// PDRF's first stage for one view's batch pixels (slot order).
#[derive(Debug, Default)]
struct Probe {
    /// The kernel without features.
    ws: DskWorkspace<f32>,
    /// Each point's coarse colour.
    cols: Vec<[f32; 3]>,
    /// Each point's coarse features integrated along its ray (K x features per pixel).
    feats: Vec<f32>,
    /// dL/d those features (from the second stage's kernel).
    d_feats: Vec<f32>,
    /// dL/d each pixel's first-stage blurry colour sum_k w'_k c'_k (from the coarse loss).
    d_blur: Vec<[f32; 3]>,
}

/// The rendering of PDRF's first-stage rays, forward or backward.
struct ProbePass<'a> {
    model: &'a Model,
    data: &'a Dataset,
    /// (view, slot) of every probed pixel, in order.
    pixels: &'a [(usize, usize)],
    view_pixels: &'a [Vec<(u32, u32)>],
    k: usize,
    chunk_rays: usize,
    seed: u64,
}

impl ProbePass<'_> {
    /// Renders the K first-stage rays (kernels in `probes`) of the pixels `range` with the
    /// coarse pass only, in
    /// chunks of at most `chunk_rays` rays (at least one pixel); ray r of the stage draws from
    /// `Rng::new(seed, r)`, so the backward replays the forward's samples. Forward: returns per
    /// pixel K colours then K x features integrated features. Backward (`back`): accumulates
    /// the field's gradients into `g` from the probes' dL/d blurry colour and dL/d features
    /// (render weights held fixed) and returns per point dL/d offset (2), origin shift (3).
    fn run(
        &self,
        p: &[f32],
        probes: &[Option<Probe>],
        range: Range<usize>,
        g: &mut [f32],
        wk: &mut Worker,
        back: bool,
    ) -> Vec<f32> {
        let (k, data) = (self.k, self.data);
        let per = (self.chunk_rays / k).max(1);
        let mut out = Vec::new();
        let mut p0 = range.start;
        while p0 < range.end {
            let p1 = (p0 + per).min(range.end);
            let mut world = Vec::with_capacity((p1 - p0) * k);
            for &(v, s) in &self.pixels[p0..p1] {
                let pr = probes[v].as_ref().expect("probed view");
                let (i, j) = self.view_pixels[v][s];
                for q in s * k..(s + 1) * k {
                    let (o, t) = (pr.ws.offsets[q].map(f64::from), pr.ws.origins[q].map(f64::from));
                    world.push(dsk_ray(&data.intrinsics, &data.views[v].pose, i, j, o, t));
                }
            }
            let prepared: Vec<PreparedRay> = world.iter().map(|r| prepare(data, r)).collect();
            let (o, d, vd) = unzip(&prepared);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (p0 * k..p1 * k).map(|r| Rng::new(self.seed, r as u64)).collect();
            wk.renderer.forward_coarse(self.model, p, &chunk, Some(&mut rngs));
            let n = world.len();
            let ps = wk.renderer.last_pass(self.model);
            let (spr, nf) = (ps.per_ray, ps.width);
            if !back {
                for (b, _) in self.pixels[p0..p1].iter().enumerate() {
                    for r in b * k..(b + 1) * k {
                        out.extend_from_slice(&wk.renderer.coarse()[r]);
                    }
                    for r in b * k..(b + 1) * k {
                        let at = out.len();
                        out.resize(at + nf, 0.0);
                        ray_features(&ps, r, &mut out[at..]);
                    }
                }
            } else {
                wk.dc.clear();
                wk.dc.resize(n, [0.0; 3]);
                wk.df.clear();
                wk.df.resize(n, [0.0; 3]);
                wk.dfeat.clear();
                wk.dfeat.resize(n * spr * nf, 0.0);
                for (b, &(v, s)) in self.pixels[p0..p1].iter().enumerate() {
                    let pr = probes[v].as_ref().expect("probed view");
                    for q in 0..k {
                        let (r, pq) = (b * k + q, s * k + q);
                        wk.dc[r] = pr.d_blur[s].map(|x| x * pr.ws.weights[pq]);
                        let df = &pr.d_feats[pq * nf..(pq + 1) * nf];
                        ray_features_backward(&ps, r, df, &mut wk.dfeat[r * spr * nf..(r + 1) * spr * nf]);
                    }
                }
                wk.d_rays.resize(n, RayGrad::zero());
                wk.renderer.backward(
                    self.model,
                    p,
                    g,
                    &chunk,
                    &wk.dc,
                    &wk.df,
                    Some(&mut wk.d_rays[..n]),
                    Some(&wk.dfeat),
                );
                for (b, &(v, _)) in self.pixels[p0..p1].iter().enumerate() {
                    let pose = &data.views[v].pose;
                    for (ray, g) in world[b * k..(b + 1) * k].iter().zip(&wk.d_rays[b * k..(b + 1) * k]) {
                        let (d_off, d_org) = dsk_ray_backward(&data.intrinsics, pose, ray, g);
                        out.extend(d_off.iter().chain(&d_org).map(|&x| x as f32));
                    }
                }
            }
            p0 = p1;
        }
        out
    }
}

/// A ray's features integrated with its render weights, `f = sum_s w_s feat_s`, for ray `r` of
/// a pass (`out`: the pass's feature width).
pub fn ray_features<R: Real>(ps: &PassSamples<R>, r: usize, out: &mut [R]) {
    out.fill(R::zero());
    for i in r * ps.per_ray..(r + 1) * ps.per_ray {
        let row = &ps.features[i * ps.stride..i * ps.stride + ps.width];
        for (x, &y) in out.iter_mut().zip(row) {
            *x += ps.weights[i] * y;
        }
    }
}

/// Backward of [`ray_features`] with the render weights held fixed: dL/d feat_s = w_s dL/df
/// for every sample of ray `r` (`out`: samples x width, what
/// [`Renderer::backward`]'s `d_features` takes for that ray).
pub fn ray_features_backward<R: Real>(ps: &PassSamples<R>, r: usize, d: &[R], out: &mut [R]) {
    for (s, row) in out.chunks_exact_mut(ps.width).enumerate() {
        let w = ps.weights[r * ps.per_ray + s];
        for (x, &y) in row.iter_mut().zip(d) {
            *x = w * y;
        }
    }
}

/// `ray` moved by the world-frame rigid motion `m`.
fn warp(m: &Rigid, ray: &Ray) -> Ray {
    Ray { origin: to_dvec(m.point(ray.origin.to_array())), direction: to_dvec(m.vector(ray.direction.to_array())) }
}

fn to_dvec(v: [f64; 3]) -> DVec3 {
    DVec3::from_array(v)
}

/// One optimisation step (module doc); returns its losses.
#[allow(clippy::too_many_arguments)]
pub fn step(
    bufs: &mut StepBuffers,
    method: &Method,
    params: &mut [f32],
    adam: &mut Adam,
    cfg: &TrainConfig,
    data: &Dataset,
    sd: &StepData,
    step: u64,
) -> StepLosses {
    let model = &method.model;
    let (w, h) = (data.intrinsics.width, data.intrinsics.height);
    let blur = method.blur.as_ref().filter(|_| cfg.blur.as_ref().is_some_and(|b| step >= b.start));
    let blur_on = blur.is_some();
    let n_views = data.views.len();
    let n_pix = cfg.batch_rays;
    let n_ev = if cfg.events.is_some() { cfg.events.as_ref().map_or(0, |e| e.batch) } else { 0 };
    let mut pick = Rng::new(cfg.seed, 1 << 40 | step);
    let mut pick_ev = Rng::new(cfg.seed, 2 << 40 | step);
    let edi_w = cfg.edi.as_ref().map_or(0.0, |d| d.weight_at(step));
    let ev = &data.events;
    let evc = cfg.events.as_ref();
    let [th_on, th_off] = evc.and_then(|e| e.threshold).unwrap_or([0.2, 0.2]);
    // Each worker's range of groups (as `GradBuffers::run` cuts them) holds its share of the
    // pixels, then its share of the events: chunks never mix the two, so only pixel chunks pay
    // for ray gradients.
    let threads = bufs.workers.len();
    let total = n_pix + n_ev;
    let kinds = (0..threads).flat_map(|t| {
        let len = total * (t + 1) / threads - total * t / threads;
        let images = (n_pix * (t + 1) / threads - n_pix * t / threads).min(len);
        (0..len).map(move |i| i < images)
    });
    // What each group is, in the workers' order; a pixel's slot is its index among its view's.
    let mut picks = Vec::with_capacity(total);
    let mut slots = vec![0u32; n_views];
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
    // Each view's batch pixels in slot order.
    let mut view_pixels: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_views];
    for p in &picks {
        if let Pick::Pixel { v, i, j, .. } = *p {
            view_pixels[v].push((i, j));
        }
    }
    let centres =
        |v: usize| -> Vec<[f32; 2]> { view_pixels[v].iter().map(|&(i, j)| [i as f32 + 0.5, j as f32 + 0.5]).collect() };
    let step_seed = cfg.seed ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let chunk_rays = cfg.chunk_rays.max(1);
    // PDRF's first stage: the kernel without features, its rays through the coarse pass.
    let progressive = match blur {
        Some(Blur::Dsk(d)) if d.config.progressive => Some(d),
        _ => None,
    };
    let mut probes: Vec<Option<Probe>> = (0..n_views).map(|_| None).collect();
    let mut probe_pixels: Vec<(usize, usize)> = Vec::new();
    let probe_seed = step_seed ^ 0x7064_7266;
    if let Some(dsk) = progressive {
        let mut noise = Rng::new(cfg.seed, 4 << 40 | step);
        let k = dsk.config.k;
        let size = [w as f32, h as f32];
        for v in (0..n_views).filter(|&v| slots[v] > 0) {
            let pixels = centres(v);
            let jitter: Vec<[f32; 2]> =
                (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
            let mut ws = DskWorkspace::default();
            dsk.forward(params, &mut ws, v, &pixels, size, Some(&jitter), None);
            probe_pixels.extend((0..pixels.len()).map(|s| (v, s)));
            probes[v] = Some(Probe { ws, ..Probe::default() });
        }
    }
    let probe_pass = progressive.map(|dsk| ProbePass {
        model,
        data,
        pixels: &probe_pixels,
        view_pixels: &view_pixels,
        k: dsk.config.k,
        chunk_rays,
        seed: probe_seed,
    });
    if let (Some(dsk), Some(pass)) = (progressive, &probe_pass) {
        let (k, p, pr): (usize, &[f32], &[Option<Probe>]) = (dsk.config.k, params, &probes);
        let out = bufs
            .grads
            .run(0, probe_pixels.len(), &mut bufs.workers, |range, g, wk| pass.run(p, pr, range, g, wk, false));
        let nf = dsk.features;
        let per = k * (3 + nf);
        for (n, x) in out.concat().chunks_exact(per).enumerate() {
            let (v, _) = probe_pixels[n];
            let pr = probes[v].as_mut().expect("probed view");
            pr.cols.extend(x[..3 * k].chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            pr.feats.extend_from_slice(&x[3 * k..]);
        }
    }
    // The blur model of every view with pixels in the batch.
    let mut kernels: Vec<Option<ViewKernel>> = (0..n_views).map(|_| None).collect();
    if let Some(blur) = blur {
        let mut noise = Rng::new(cfg.seed, 3 << 40 | step);
        for v in (0..n_views).filter(|&v| slots[v] > 0) {
            let features = probes[v].as_ref().map(|p| &p.feats[..]);
            kernels[v] = Some(ViewKernel::new(blur, params, data, v, &centres(v), &mut noise, features));
        }
    }
    // The origin ray closes every blurred pixel's group when something reads it: the rigid
    // kernel's weight, the AWP, the EDI prior.
    let with_origin = matches!(blur, Some(Blur::Rigid(_))) || cfg.edi.is_some();
    let mut batch =
        Batch { rays: Vec::new(), world: Vec::new(), weights: Vec::new(), groups: Vec::new(), pixels: 0, events: 0 };
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
                match &kernels[v] {
                    Some(vk) => {
                        let origin_weight = vk.rays(data, view, &ray, i, j, slot as usize, &mut batch);
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
    let inv_gamma = (1.0 / cfg.response_gamma) as f32;
    let img_scale = 1.0 / (3.0 * batch.pixels.max(1) as f32);
    let ev_scale = evc.map_or(0.0, |e| e.weight as f32) / batch.events.max(1) as f32;
    let edi_scale = edi_w as f32 * img_scale;
    let k_rays = blur.map_or(0, |b| b.rays());
    // Blur models whose rays move with their parameters take the rays' gradients.
    let learns_rays = match blur {
        Some(Blur::Trajectory(t)) => t.config.learned,
        Some(_) => true,
        None => false,
    };
    let is_dsk = matches!(blur, Some(Blur::Dsk(_)));
    let awp = method.awp.as_ref().filter(|_| blur_on);
    let mix = awp.map_or(0.0, |a| a.config.mix_at(step)) as f32;
    // The image loss mixes the kernel's colours and the AWP's: (1 - l) [coarse + fine] + l awp.
    let blur_scale = img_scale * (1.0 - mix);
    let emb_dim = awp.map_or(0, |a| a.embedding);
    let kstride = 12 * k_rays + k_rays + 1 + emb_dim;
    let luma = evc.and_then(|e| e.luma).unwrap_or(BT601).map(|x| x as f32);
    let log_eps = evc.and_then(|e| e.log_eps).unwrap_or(1e-5) as f32;
    let saturation = evc.and_then(|e| e.saturation).map_or(f32::INFINITY, |s| s as f32);
    // A DSK pixel's gradients: K x (offset 2, origin 3, weight 1), then (PDRF) dL/d the first
    // stage's coarse blurry colour.
    let pstride = 6 * k_rays + if progressive.is_some() { 3 } else { 0 };
    let probes_ref = &probes;
    let p: &[f32] = params;
    let ecrf = method.ecrf.as_ref();
    let batch_ref = &batch;
    let n_groups = batch.groups.len();
    let sums = bufs.grads.run(model.layout.len(), n_groups, &mut bufs.workers, |range, g, wk| {
        let mut sums = Sums::default();
        wk.kgrad.clear();
        wk.kgrad.resize(if blur_on { n_views * kstride } else { 0 }, 0.0);
        wk.pgrad.clear();
        wk.pgrad_groups.clear();
        let groups = &batch_ref.groups;
        let mut g0 = range.start;
        while g0 < range.end {
            let r0 = groups[g0].first;
            let is_image = |g: &Group| matches!(g.kind, Kind::Image { .. });
            let kind = is_image(&groups[g0]);
            let mut g1 = g0 + 1;
            while g1 < range.end && groups[g1].first + groups[g1].n - r0 <= chunk_rays && is_image(&groups[g1]) == kind
            {
                g1 += 1;
            }
            let r1 = groups[g1 - 1].first + groups[g1 - 1].n;
            let (o, d, vd) = unzip(&batch_ref.rays[r0..r1]);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (r0..r1).map(|r| Rng::new(step_seed, r as u64)).collect();
            wk.renderer.forward(model, p, &chunk, Some(&mut rngs));
            let n = r1 - r0;
            wk.dc.clear();
            wk.dc.resize(n, [0.0; 3]);
            wk.df.clear();
            wk.df.resize(n, [0.0; 3]);
            let mut any_kernel = false;
            let mut any_awp = false;
            let mut chunk_pg = vec![usize::MAX; g1 - g0];
            for (gi, gr) in groups[g0..g1].iter().enumerate() {
                let Kind::Image { view, target, edi, .. } = gr.kind else { continue };
                let (a, m) = (gr.first - r0, gr.n);
                let origin = a + m - 1;
                let blurred = m > 1;
                any_kernel |= blurred;
                let pg = (blurred && is_dsk).then(|| {
                    wk.pgrad_groups.push((g0 + gi) as u32);
                    wk.pgrad.resize(wk.pgrad.len() + pstride, 0.0);
                    wk.pgrad.len() - pstride
                });
                chunk_pg[gi] = pg.unwrap_or(usize::MAX);
                for pass in 0..2 {
                    let (cols, dcol) =
                        if pass == 0 { (wk.renderer.coarse(), &mut wk.dc) } else { (wk.renderer.fine(), &mut wk.df) };
                    let weights = blurred.then(|| &batch_ref.weights[gr.first..gr.first + m]);
                    let mut dw = [0.0f32; MAX_RAYS];
                    let scale = if blurred { blur_scale } else { img_scale };
                    let probe = probes_ref[view as usize].as_ref().filter(|_| blurred && pass == 0);
                    if let (Some(pr), Kind::Image { slot, .. }, Some(weights), Some(pg)) = (probe, gr.kind, weights, pg)
                    {
                        // PDRF's coarse loss: (first stage's blurry colour + this one) / 2.
                        let (s, k) = (slot as usize, k_rays);
                        let mut a_col = [0.0f32; 3];
                        for q in s * k..(s + 1) * k {
                            for (x, &y) in a_col.iter_mut().zip(&pr.cols[q]) {
                                *x += pr.ws.weights[q] * y;
                            }
                        }
                        let mut cols2 = [[0.0f32; 3]; MAX_RAYS + 1];
                        let mut w2 = [0.0f32; MAX_RAYS + 1];
                        cols2[..m].copy_from_slice(&cols[a..a + m]);
                        cols2[m] = a_col;
                        for (x, &wq) in w2.iter_mut().zip(weights) {
                            *x = 0.5 * wq;
                        }
                        w2[m] = 0.5;
                        let (mut dc2, mut dw2) = ([[0.0f32; 3]; MAX_RAYS + 1], [0.0f32; MAX_RAYS + 1]);
                        sums.image[pass] += blur_loss(
                            &cols2[..m + 1],
                            Some(&w2[..m + 1]),
                            target,
                            inv_gamma,
                            scale,
                            &mut dc2[..m + 1],
                            &mut dw2[..m + 1],
                        ) as f64;
                        dcol[a..a + m].copy_from_slice(&dc2[..m]);
                        for q in 0..m {
                            dw[q] = 0.5 * dw2[q];
                        }
                        for (x, &y) in wk.pgrad[pg + 6 * k..pg + 6 * k + 3].iter_mut().zip(&dc2[m]) {
                            *x += y as f64;
                        }
                    } else {
                        sums.image[pass] += blur_loss(
                            &cols[a..a + m],
                            weights,
                            target,
                            inv_gamma,
                            scale,
                            &mut dcol[a..a + m],
                            &mut dw[..m],
                        ) as f64;
                    }
                    if blurred && matches!(blur, Some(Blur::Rigid(_))) {
                        let base = view as usize * kstride + 12 * k_rays;
                        for (q, d) in dw[..m].iter().enumerate() {
                            wk.kgrad[base + q] += *d as f64;
                        }
                    }
                    if let Some(pg) = pg {
                        for (q, d) in dw[..k_rays].iter().enumerate() {
                            wk.pgrad[pg + 6 * q + 5] += *d as f64;
                        }
                    }
                    if edi_scale > 0.0 && !edi[0].is_nan() {
                        for c in 0..3 {
                            let (gc, dg) = response(cols[origin][c], inv_gamma);
                            let e = gc - edi[c];
                            sums.edi += (e * e) as f64 / (3 * batch_ref.pixels.max(1)) as f64;
                            dcol[origin][c] += 2.0 * e * dg * edi_scale;
                        }
                    }
                }
                // The AWP's colour: its weights over the fine colours of the same rays.
                if let (Some(awp), true) = (awp, blurred && mix > 0.0) {
                    let ps = wk.renderer.last_pass(model);
                    let (s, nf) = (ps.per_ray, ps.width);
                    if !any_awp {
                        wk.dfeat.clear();
                        wk.dfeat.resize(n * s * nf, 0.0);
                        any_awp = true;
                    }
                    let feats = &ps.features[a * s * ps.stride..];
                    let om = &ps.weights[a * s..(a + m) * s];
                    let e0 = blur.and_then(Blur::rigid).expect("the AWP needs the rigid kernel").embeddings
                        + view as usize * emb_dim;
                    let dir = batch_ref.rays[gr.first + m - 1].viewdir;
                    awp.forward(p, &mut wk.awp_ws, feats, ps.stride, s, om, &p[e0..e0 + emb_dim], dir);
                    let (mut d_cols, mut dw) = ([[0.0f32; 3]; MAX_RAYS], [0.0f32; MAX_RAYS]);
                    sums.awp += blur_loss(
                        &wk.renderer.fine()[a..a + m],
                        Some(&wk.awp_ws.weights),
                        target,
                        inv_gamma,
                        mix * img_scale,
                        &mut d_cols[..m],
                        &mut dw[..m],
                    ) as f64;
                    for (d, dc) in wk.df[a..a + m].iter_mut().zip(&d_cols) {
                        for c in 0..3 {
                            d[c] += dc[c];
                        }
                    }
                    awp.backward(p, g, &mut wk.awp_ws, feats, ps.stride, om, &dw[..m]);
                    wk.dfeat[a * s * nf..(a + m) * s * nf].copy_from_slice(&wk.awp_ws.d_features);
                    let base = view as usize * kstride + 13 * k_rays + 1;
                    for (k, d) in wk.awp_ws.d_embedding.iter().enumerate() {
                        wk.kgrad[base + k] += *d as f64;
                    }
                }
            }
            sums.event += event_losses(wk, ecrf, p, g, &groups[g0..g1], r0, luma, log_eps, saturation, ev_scale);
            let with_rays = learns_rays && any_kernel;
            if with_rays {
                wk.d_rays.resize(n, RayGrad::zero());
            }
            let d_rays = if with_rays { Some(&mut wk.d_rays[..n]) } else { None };
            let d_feat = if any_awp { Some(&wk.dfeat[..]) } else { None };
            wk.renderer.backward(model, p, g, &chunk, &wk.dc, &wk.df, d_rays, d_feat);
            if with_rays {
                for (gi, gr) in groups[g0..g1].iter().enumerate() {
                    let Kind::Image { view, i, j, .. } = gr.kind else { continue };
                    if gr.n == 1 {
                        continue;
                    }
                    let pose = &data.views[view as usize].pose;
                    if is_dsk {
                        // World ray o = c + R t, d = R (d_cam(x + o) - t): back to the pixel
                        // offset and the camera-frame origin shift.
                        let pg = chunk_pg[gi];
                        for q in 0..k_rays {
                            let r = gr.first + q;
                            let (d_off, d_t) =
                                dsk_ray_backward(&data.intrinsics, pose, &batch_ref.world[r], &wk.d_rays[r - r0]);
                            let out = &mut wk.pgrad[pg + 6 * q..pg + 6 * q + 5];
                            for (o, d) in out.iter_mut().zip(d_off.iter().chain(&d_t)) {
                                *o += d;
                            }
                        }
                        continue;
                    }
                    let orig = data.intrinsics.ray(pose, i, j);
                    let base = view as usize * kstride;
                    for q in 0..k_rays {
                        let r = gr.first + q;
                        let (d_r, d_t) =
                            kernel_ray_backward(&data.intrinsics, &orig, &batch_ref.world[r], &wk.d_rays[r - r0]);
                        let kg = &mut wk.kgrad[base + 12 * q..base + 12 * q + 12];
                        for (i, row) in d_r.iter().enumerate() {
                            for (jx, v) in row.iter().enumerate() {
                                kg[3 * i + jx] += v;
                            }
                        }
                        for i in 0..3 {
                            kg[9 + i] += d_t[i];
                        }
                    }
                }
            }
            g0 = g1;
        }
        sums
    });
    let grads = &mut bufs.sum;
    grads.clear();
    grads.resize(model.layout.len(), 0.0);
    bufs.grads.sum_into(grads);
    // The kernel: twists and weights of every view of the batch, summed over workers in order.
    match blur {
        Some(Blur::Rigid(_)) | Some(Blur::Trajectory(_)) if learns_rays => {
            for (v, vk) in kernels.iter().enumerate() {
                let Some(vk) = vk else { continue };
                let base = v * kstride;
                let total = |i: usize| bufs.workers.iter().map(|wk| wk.kgrad[base + i]).sum::<f64>();
                let d_twists: Vec<[f64; 6]> = (0..k_rays)
                    .map(|q| {
                        let d_r: [[f64; 3]; 3] =
                            std::array::from_fn(|i| std::array::from_fn(|j| total(12 * q + 3 * i + j)));
                        let d_t: [f64; 3] = std::array::from_fn(|i| total(12 * q + 9 + i));
                        se3::exp_backward(vk.twists[q], &d_r, &d_t)
                    })
                    .collect();
                match blur {
                    Some(Blur::Rigid(kernel)) => {
                        let d_weights: Vec<f32> = (0..=k_rays).map(|q| total(12 * k_rays + q) as f32).collect();
                        let e0 = kernel.embeddings + v * emb_dim;
                        for k in 0..emb_dim {
                            grads[e0 + k] += total(13 * k_rays + 1 + k) as f32;
                        }
                        let d_twists: Vec<[f32; 6]> = d_twists.iter().map(|t| t.map(|x| x as f32)).collect();
                        let out = vk.rigid.as_ref().expect("rigid kernel output");
                        kernel.backward(params, grads, v, out, &d_twists, &d_weights);
                    }
                    Some(Blur::Trajectory(t)) => t.backward(grads, v, &d_twists),
                    _ => unreachable!("matched above"),
                }
            }
        }
        Some(Blur::Dsk(dsk)) => {
            // Each pixel's gradients from the worker that rendered it, in slot order per view.
            let mut per_group: Vec<Option<&[f64]>> = vec![None; batch.groups.len()];
            for wk in &bufs.workers {
                for (n, &gi) in wk.pgrad_groups.iter().enumerate() {
                    per_group[gi as usize] = Some(&wk.pgrad[pstride * n..pstride * (n + 1)]);
                }
            }
            let mut by_view: Vec<Vec<&[f64]>> = vec![Vec::new(); n_views];
            for (gr, pg) in batch.groups.iter().zip(&per_group) {
                if let (Kind::Image { view, slot, .. }, Some(pg)) = (gr.kind, pg) {
                    debug_assert_eq!(by_view[view as usize].len(), slot as usize);
                    by_view[view as usize].push(pg);
                }
            }
            let dc = cfg.blur.as_ref().and_then(|b| b.dsk.as_ref()).expect("DSK config");
            let align_scale =
                if step < dc.align_until { (dc.align_weight / batch.pixels.max(1) as f64) as f32 } else { 0.0 };
            for (v, vk) in kernels.iter_mut().enumerate() {
                let Some(ws) = vk.as_mut().and_then(|vk| vk.dsk.as_mut()) else { continue };
                let pix = &by_view[v];
                let entries = pix.iter().flat_map(|pg| pg[..6 * k_rays].chunks_exact(6));
                let mut d_off: Vec<[f32; 2]> = entries.clone().map(|e| [e[0] as f32, e[1] as f32]).collect();
                let mut d_org: Vec<[f32; 3]> =
                    entries.clone().map(|e| [e[2] as f32, e[3] as f32, e[4] as f32]).collect();
                let d_w: Vec<f32> = entries.map(|e| e[5] as f32).collect();
                if align_scale > 0.0 {
                    dsk.align_backward(ws, align_scale, &mut d_off, &mut d_org);
                }
                dsk.backward(params, grads, ws, &d_off, &d_org, &d_w);
                if let Some(pr) = probes[v].as_mut() {
                    pr.d_feats.clone_from(&ws.d_features);
                    pr.d_blur = pix.iter().map(|pg| std::array::from_fn(|c| pg[6 * k_rays + c] as f32)).collect();
                }
            }
            // PDRF's first stage: its rays' backward (replayed with the same samples), then
            // its kernel's.
            if let Some(pass) = &probe_pass {
                let (p, pr): (&[f32], &[Option<Probe>]) = (params, &probes);
                let out = bufs.grads.run(model.layout.len(), probe_pixels.len(), &mut bufs.workers, |range, g, wk| {
                    pass.run(p, pr, range, g, wk, true)
                });
                bufs.grads.sum_into(grads);
                let out = out.concat();
                let mut at = 0;
                for (v, pr) in probes.iter_mut().enumerate() {
                    let Some(pr) = pr.as_mut() else { continue };
                    let n = view_pixels[v].len() * k_rays;
                    let d = &out[5 * at..5 * (at + n)];
                    at += n;
                    let d_off: Vec<[f32; 2]> = d.chunks_exact(5).map(|e| [e[0], e[1]]).collect();
                    let d_org: Vec<[f32; 3]> = d.chunks_exact(5).map(|e| [e[2], e[3], e[4]]).collect();
                    // dL/dw'_k = <c'_k, dL/dA> of its pixel.
                    let d_w: Vec<f32> =
                        (0..n).map(|q| (0..3).map(|c| pr.cols[q][c] * pr.d_blur[q / k_rays][c]).sum()).collect();
                    dsk.backward(params, grads, &mut pr.ws, &d_off, &d_org, &d_w);
                }
            }
        }
        _ => {}
    }
    // The eCRF learns from its start iteration on (before: held at the identity).
    if let (Some(e), Some(c)) = (ecrf, cfg.ecrf.as_ref()) {
        if step < c.start {
            for r in e.ranges() {
                grads[r].fill(0.0);
            }
        }
    }
    let s = sums.iter().fold(Sums::default(), |a, b| Sums {
        image: [a.image[0] + b.image[0], a.image[1] + b.image[1]],
        event: a.event + b.event,
        edi: a.edi + b.edi,
        awp: a.awp + b.awp,
    });
    model.tv(params, grads);
    adam.step(&cfg.adam, &model.layout, params, grads);
    let np = (3 * batch.pixels.max(1)) as f64;
    StepLosses {
        image: (s.image[0] + s.image[1]) / np,
        psnr: -10.0 * (s.image[1] / np).log10(),
        event: s.event / batch.events.max(1) as f64,
        edi: s.edi,
        awp: s.awp / np,
    }
}

/// The world ray of a DSK kernel point of pixel (`i`, `j`) for a camera at `pose`: through
/// the image point (i + 0.5, j + 0.5) + `offset` (pixels), from the camera-frame origin shift
/// `origin`, pivoting about the shifted image point at camera depth 1 (Deblur-NeRF's rays):
/// o = c + R t, d = R (d_cam(x + o) - t).
pub fn dsk_ray(k: &Intrinsics, pose: &Pose, i: u32, j: u32, offset: [f64; 2], origin: [f64; 3]) -> Ray {
    let t = DVec3::from_array(origin);
    let d = k.camera_direction_at(i as f64 + 0.5 + offset[0], j as f64 + 0.5 + offset[1]);
    Ray { origin: pose.position + pose.rotation * t, direction: pose.rotation * (d - t) }
}

/// Backward of [`dsk_ray`] from the ray's renderer gradients: (dL/d offset, dL/d origin shift).
pub fn dsk_ray_backward<R: Real>(k: &Intrinsics, pose: &Pose, world: &Ray, g: &RayGrad<R>) -> ([f64; 2], [f64; 3]) {
    let (d_o, d_d) = warped_ray_backward(k, world, g);
    let inv = pose.rotation.inverse();
    let (d_oc, d_dc) = (inv * d_o, inv * d_d);
    // d_cam(u, v) = ((u - W/2) / f, -(v - H/2) / f, -1).
    ([d_dc.x / k.focal, -d_dc.y / k.focal], (d_oc - d_dc).to_array())
}

/// Most rays a pixel group can have (the origin ray and up to 31 warped rays).
pub const MAX_RAYS: usize = 32;

/// The image loss of one pixel on one pass: the blurry colour `B = sum_k w_k C_k` (or the one
/// ray's colour when `weights` is `None`), `sum_c (g(B_c) - y_c)^2`. Writes dL/dC_k (times
/// `scale`) into `d_cols` and dL/dw_k (times `scale`) into `d_weights`; returns the unscaled loss.
pub fn blur_loss<R: Real>(
    cols: &[[R; 3]],
    weights: Option<&[R]>,
    target: [R; 3],
    inv_gamma: R,
    scale: R,
    d_cols: &mut [[R; 3]],
    d_weights: &mut [R],
) -> R {
    let mut blur = [R::zero(); 3];
    match weights {
        None => blur = cols[cols.len() - 1],
        Some(w) => {
            for (q, &wq) in w.iter().enumerate() {
                for c in 0..3 {
                    blur[c] += wq * cols[q][c];
                }
            }
        }
    }
    let mut loss = R::zero();
    let mut d_blur = [R::zero(); 3];
    for c in 0..3 {
        let (gc, dg) = response(blur[c], inv_gamma);
        let e = gc - target[c];
        loss += e * e;
        d_blur[c] = R::of(2.0) * e * dg * scale;
    }
    match weights {
        None => {
            let last = cols.len() - 1;
            d_cols[last] = d_blur;
        }
        Some(w) => {
            for (q, &wq) in w.iter().enumerate() {
                d_cols[q] = d_blur.map(|x| x * wq);
                d_weights[q] = (0..3).map(|c| d_blur[c] * cols[q][c]).sum();
            }
        }
    }
    loss
}

/// One event pair's loss on one pass: with L = <luma, y> of the eCRF outputs y at t_j and t_k,
/// `weight (log(L_k + eps) - log(L_j + eps) - target)^2`, the target `p Theta` for a single
/// event (the sum over the hopped events for a window).
#[derive(Clone, Copy, Debug)]
pub struct EventTerm<R> {
    /// Luma weights (a one-hot channel for colour events).
    pub luma: [R; 3],
    /// Weight of the event (colour events: by channel).
    pub weight: R,
    /// The log change the events say: polarity times threshold, summed over the pair's
    /// events after the first.
    pub target: R,
    /// Offset of the log.
    pub log_eps: R,
}

impl<R: Real> EventTerm<R> {
    /// (loss, dL/dy_j, dL/dy_k), the gradients times `scale`.
    pub fn loss(&self, yj: [R; 3], yk: [R; 3], scale: R) -> (R, [R; 3], [R; 3]) {
        let l = |y: [R; 3]| (0..3).map(|c| self.luma[c] * y[c]).sum::<R>();
        let (lj, lk) = (l(yj), l(yk));
        let r = (lk + self.log_eps).ln() - (lj + self.log_eps).ln() - self.target;
        let dr = R::of(2.0) * self.weight * r * scale;
        let (dlk, dlj) = (dr / (lk + self.log_eps), -dr / (lj + self.log_eps));
        (self.weight * r * r, self.luma.map(|w| w * dlj), self.luma.map(|w| w * dlk))
    }
}

/// The Bayer channel (RGGB) of a pixel: (even x, even y) R, (odd, odd) B, else G.
pub fn bayer(x: f64, y: f64) -> u8 {
    let (xi, yi) = (x.round() as i64, y.round() as i64);
    match (xi.rem_euclid(2), yi.rem_euclid(2)) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// dL/d(world origin), dL/d(world direction) of a warped ray from its renderer gradients:
/// through the NDC warp and the view direction's normalisation.
pub fn warped_ray_backward<R: Real>(k: &Intrinsics, world: &Ray, g: &RayGrad<R>) -> (DVec3, DVec3) {
    let f = |a: [R; 3]| {
        DVec3::new(a[0].to_f64().unwrap_or(0.0), a[1].to_f64().unwrap_or(0.0), a[2].to_f64().unwrap_or(0.0))
    };
    let (d_o, mut d_d) = ndc_ray_backward(k.width, k.height, k.focal, NDC_NEAR, world, f(g.origin), f(g.dir));
    // v = d / |d|: dL/dd = (dL/dv - v (v . dL/dv)) / |d|.
    let n = world.direction.length();
    let v = world.direction / n;
    let gv = f(g.viewdir);
    d_d += (gv - v * v.dot(gv)) / n;
    (d_o, d_d)
}

/// dL/dR and dL/dt of the rigid motion that moved `original` to `warped`, from the warped
/// ray's renderer gradients ([`warped_ray_backward`], then the rigid warp's backward).
pub fn kernel_ray_backward<R: Real>(
    k: &Intrinsics,
    original: &Ray,
    warped: &Ray,
    g: &RayGrad<R>,
) -> ([[f64; 3]; 3], [f64; 3]) {
    let (d_o, d_d) = warped_ray_backward(k, warped, g);
    let (mut d_r, mut d_t) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    se3::warp_backward(
        original.origin.to_array(),
        original.direction.to_array(),
        d_o.to_array(),
        d_d.to_array(),
        &mut d_r,
        &mut d_t,
    );
    (d_r, d_t)
}

/// The event loss of the event groups among `groups` (rays from `r0` on in the worker's
/// renderer): adds dL/dC (scaled by `scale` = weight / events) to the worker's `dc`/`df` and
/// the eCRF's gradient to `g`; returns the unweighted loss summed over its events and passes.
/// A pair whose linear luma reaches `saturation` at either end adds nothing.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn event_losses(
    wk: &mut Worker,
    ecrf: Option<&Ecrf>,
    p: &[f32],
    g: &mut [f32],
    groups: &[Group],
    r0: usize,
    luma: [f32; 3],
    log_eps: f32,
    saturation: f32,
    scale: f32,
) -> f64 {
    let evs: Vec<(usize, i8, f32, u8)> = groups
        .iter()
        .filter_map(|gr| match gr.kind {
            Kind::Event { polarity, target, channel } => Some((gr.first - r0, polarity, target, channel)),
            _ => None,
        })
        .collect();
    if evs.is_empty() || scale == 0.0 {
        return 0.0;
    }
    let m = 2 * evs.len();
    let mut total = 0.0f64;
    for pass in 0..2 {
        let cols = if pass == 0 { wk.renderer.coarse() } else { wk.renderer.fine() };
        wk.epol.clear();
        for c in 0..3 {
            wk.ex[c].clear();
            for &(a, pol, _, _) in &evs {
                wk.ex[c].extend([cols[a][c], cols[a + 1][c]]);
                if c == 0 {
                    wk.epol.extend([pol, pol]);
                }
            }
            wk.ey[c].resize(m, 0.0);
            match ecrf {
                Some(e) => e.forward(p, c, &wk.ex[c], &wk.epol, &mut wk.ey[c], &mut wk.ecrf_ws[c]),
                None => wk.ey[c].copy_from_slice(&wk.ex[c]),
            }
            wk.edy[c].clear();
            wk.edy[c].resize(m, 0.0);
        }
        for (e, &(_, _, target, channel)) in evs.iter().enumerate() {
            let (weight, lum): (f32, [f32; 3]) = if channel < 3 {
                let mut l = [0.0; 3];
                l[channel as usize] = 1.0;
                (COLOUR_WEIGHTS[channel as usize], l)
            } else {
                (1.0, luma)
            };
            let linear = |i: usize| (0..3).map(|c| lum[c] * wk.ex[c][i]).sum::<f32>();
            if linear(2 * e) >= saturation || linear(2 * e + 1) >= saturation {
                continue;
            }
            let y = |i: usize| [wk.ey[0][i], wk.ey[1][i], wk.ey[2][i]];
            let t = EventTerm { luma: lum, weight, target, log_eps };
            let (loss, dj, dk) = t.loss(y(2 * e), y(2 * e + 1), scale);
            total += loss as f64;
            for c in 0..3 {
                wk.edy[c][2 * e] = dj[c];
                wk.edy[c][2 * e + 1] = dk[c];
            }
        }
        for c in 0..3 {
            wk.edx.resize(m, 0.0);
            match ecrf {
                Some(e) => e.backward(p, g, c, &wk.edy[c], &mut wk.edx, &mut wk.ecrf_ws[c]),
                None => wk.edx.copy_from_slice(&wk.edy[c]),
            }
            let dcol = if pass == 0 { &mut wk.dc } else { &mut wk.df };
            for (e, &(a, _, _, _)) in evs.iter().enumerate() {
                dcol[a][c] += wk.edx[2 * e];
                dcol[a + 1][c] += wk.edx[2 * e + 1];
            }
        }
    }
    total
}

#[cfg(test)]
#[path = "method_tests.rs"]
mod tests;
