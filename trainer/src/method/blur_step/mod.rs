//! The blur models in a training step. Each model implements [`StepBlur`]: it makes its rays
//! for a view's batch pixels, blends their colours into the blurry colour (and routes the
//! blending weights' gradients), takes its rays' gradients after the renderer's backward, and
//! turns everything into its parameters' gradients at the end of the step. The step itself
//! ([`super::step`]) is generic over the model and holds no model-specific code.
//!
//! - [`rigid`]: DP-NeRF's rigid kernel (K warped rays + the origin ray, learned weights).
//! - [`trajectory`]: virtual cameras inside the exposure (BAD-NeRF learned, E2NeRF fixed).
//! - [`dsk`]: Deblur-NeRF's deformable sparse kernel, with PDRF's first stage.
//! - [`NoBlur`]: one plain ray per pixel (no model, or before the model's start).

pub(super) mod dsk;
pub(super) mod rigid;
pub(super) mod trajectory;

use crate::blur::se3;
use crate::blur::MAX_RAYS;
use crate::data::dataset::{Dataset, View};
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::RayGrad;
use crate::engine::rng::Rng;

use super::batch::{Batch, Worker};
use super::kernel::{blur_loss, kernel_ray_backward};
use super::pixel_loss::PixelRays;

/// What the blur model's parts of a step read.
pub(super) struct StepContext<'a> {
    /// The parameters.
    pub(super) params: &'a [f32],
    /// The dataset.
    pub(super) data: &'a Dataset,
    /// The model (for PDRF's first-stage rendering).
    pub(super) model: &'a crate::engine::model::Model,
    /// Each view's batch pixels (slot order).
    pub(super) view_pixels: &'a [Vec<(u32, u32)>],
    /// The run's seed.
    pub(super) seed: u64,
    /// The step.
    pub(super) step: u64,
    /// The step's ray seed (ray r draws its samples from `Rng::new(step_seed, r)`).
    pub(super) step_seed: u64,
    /// Most rays per chunk.
    pub(super) chunk_rays: usize,
}

impl StepContext<'_> {
    /// Pixel centres of view `v`'s batch pixels, in slot order.
    pub(super) fn centres(&self, v: usize) -> Vec<[f32; 2]> {
        self.view_pixels[v].iter().map(|&(i, j)| [i as f32 + 0.5, j as f32 + 0.5]).collect()
    }
}

/// Where one image pixel writes its blur-model gradients in a worker: its view's record (the
/// model's per-view size, summed over the pixels of the view) and its own record (the model's
/// per-pixel size).
pub(super) struct Records<'w> {
    /// The view's record in `Worker::kgrad` (empty when the model keeps none).
    pub(super) view: &'w mut [f64],
    /// The pixel's record in `Worker::pgrad` (empty when the model keeps none).
    pub(super) pixel: &'w mut [f64],
}

/// What the end of a step's blur backward works on.
pub(super) struct BackwardInput<'s> {
    /// The step's context.
    pub(super) ctx: &'s StepContext<'s>,
    /// The step's batch.
    pub(super) batch: &'s Batch,
    /// The size of a view's record in the workers (`StepBlur::view_record`).
    pub(super) view_stride: usize,
    /// The workers (their records, and threads for PDRF's replay).
    pub(super) workers: &'s mut [Worker],
    /// The gradient buffers of the parallel runs.
    pub(super) pool: &'s mut GradBuffers,
}

/// A blur model's part in a training step (module doc).
pub(super) trait StepBlur: Sync {
    /// One view's state in a step (the kernel at its batch pixels).
    type View: Send + Sync;

    /// Rays per blurry pixel (besides the origin ray).
    fn k(&self) -> usize;

    /// Whether the rays move with the parameters (the renderer returns their gradients).
    fn learns_rays(&self) -> bool;

    /// Whether the origin ray's colour is part of the blurry colour (its weight learns).
    fn blends_origin(&self) -> bool {
        false
    }

    /// Size of a view's gradient record in each worker (`emb_dim`: the AWP's embedding size).
    fn view_record(&self, _emb_dim: usize) -> usize {
        0
    }

    /// Size of a blurred pixel's gradient record in each worker.
    fn pixel_record(&self) -> usize {
        0
    }

    /// (parameter offset of the views' embeddings, offset in a view's record) for the AWP,
    /// which only the rigid kernel feeds.
    fn awp_slots(&self) -> Option<(usize, usize)> {
        None
    }

    /// The state of every view with pixels in the batch (`None` for the others).
    fn views(&self, ctx: &StepContext, workers: &mut [Worker], pool: &mut GradBuffers) -> Vec<Option<Self::View>>;

    /// Pushes the K rays of pixel (`i`, `j`) of `view` (world ray `ray`, slot `slot` among the
    /// view's batch pixels) with their blending weights; returns the origin ray's weight.
    #[allow(clippy::too_many_arguments)]
    fn rays(
        &self,
        state: &Self::View,
        data: &Dataset,
        view: &View,
        ray: &Ray,
        i: u32,
        j: u32,
        slot: usize,
        batch: &mut Batch,
    ) -> f32;

    /// The image loss of a blurred pixel on `pass` (0 coarse, 1 fine): blends the pixel's
    /// colours `cols` with `weights` into the blurry colour, writes dL/dC (times `scale`) into
    /// `d_cols` and the weights' gradients into `rec`; returns the unscaled loss.
    #[allow(clippy::too_many_arguments)]
    fn blend(
        &self,
        _views: &[Option<Self::View>],
        _px: &PixelRays,
        _pass: usize,
        cols: &[[f32; 3]],
        weights: &[f32],
        target: [f32; 3],
        inv_gamma: f32,
        scale: f32,
        d_cols: &mut [[f32; 3]],
        rec: &mut Records,
    ) -> f32 {
        let mut dw = [0.0f32; MAX_RAYS];
        let m = cols.len();
        let loss = blur_loss(cols, Some(weights), target, inv_gamma, scale, d_cols, &mut dw[..m]);
        self.weight_grads(&dw[..m], rec);
        loss
    }

    /// Adds the blending weights' gradients `dw` (one per ray of the pixel) to its records.
    fn weight_grads(&self, _dw: &[f32], _rec: &mut Records) {}

    /// Takes the ray gradients `d_rays` of a blurred pixel (`i`, `j`) of `view` (its rays
    /// `world`, K first) into its records.
    #[allow(clippy::too_many_arguments)]
    fn ray_backward(
        &self,
        _data: &Dataset,
        _view: usize,
        _i: u32,
        _j: u32,
        _world: &[Ray],
        _d_rays: &[RayGrad<f32>],
        _rec: &mut Records,
    ) {
    }

    /// Adds the model's parameter gradients of this step to `grads`, from every worker's
    /// records (summed over the workers in order).
    fn backward(&self, views: &mut [Option<Self::View>], input: BackwardInput, grads: &mut [f32]);
}

/// No blur model: one plain ray per pixel.
pub(super) struct NoBlur;

impl StepBlur for NoBlur {
    type View = ();

    fn k(&self) -> usize {
        0
    }

    fn learns_rays(&self) -> bool {
        false
    }

    fn views(&self, ctx: &StepContext, _: &mut [Worker], _: &mut GradBuffers) -> Vec<Option<()>> {
        ctx.view_pixels.iter().map(|_| None).collect()
    }

    fn rays(&self, _: &(), _: &Dataset, _: &View, _: &Ray, _: u32, _: u32, _: usize, _: &mut Batch) -> f32 {
        unreachable!("NoBlur has no view state, so no pixel asks it for rays")
    }

    fn backward(&self, _: &mut [Option<()>], _: BackwardInput, _: &mut [f32]) {}
}

/// Ray gradients of a pixel's K warped rays (`world`) back to their rigid motions, into
/// `record` as K x (dR 9, dt 3) (the rigid kernel and a learned trajectory).
pub(super) fn motion_ray_backward(
    data: &Dataset,
    view: usize,
    i: u32,
    j: u32,
    world: &[Ray],
    d_rays: &[RayGrad<f32>],
    record: &mut [f64],
) {
    let orig = data.intrinsics.ray(&data.views[view].pose, i, j);
    for (q, (w, g)) in world.iter().zip(d_rays).enumerate() {
        let (d_r, d_t) = kernel_ray_backward(&data.intrinsics, &orig, w, g);
        let kg = &mut record[12 * q..12 * q + 12];
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

/// The twists' gradients of view record `base` (K x (dR 9, dt 3) summed over the workers in
/// order) through the se(3) exponential map.
pub(super) fn twist_grads(workers: &[Worker], base: usize, twists: &[[f64; 6]]) -> Vec<[f64; 6]> {
    let total = |i: usize| workers.iter().map(|wk| wk.kgrad[base + i]).sum::<f64>();
    twists
        .iter()
        .enumerate()
        .map(|(q, &twist)| {
            let d_r: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| total(12 * q + 3 * i + j)));
            let d_t: [f64; 3] = std::array::from_fn(|i| total(12 * q + 9 + i));
            se3::exp_backward(twist, &d_r, &d_t)
        })
        .collect()
}

/// A fresh RNG for the kernels' jitter of `step`.
pub(super) fn kernel_noise(seed: u64, step: u64) -> Rng {
    Rng::new(seed, 3 << 40 | step)
}
