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
//!
//! What lives where: this module holds a method's parameters ([`Method`]) and what a run
//! prepares once ([`StepData`]); `batch` the step's groups (drawn, then their rays
//! assembled), workers and buffers; `blur_step` the blur models' part of a step, one file per
//! model behind one trait (rays, blending, ray and parameter backward); `kernel` the ray
//! chains they share; `pixel_loss` a pixel's colour terms (image loss, EDI prior, AWP colour);
//! [`step`](fn@step) the step itself, generic over the blur model (draw, kernels, render and
//! differentiate the chunks, Adam); [`rays`] the NDC form of rays, the camera response and the
//! scene box; the event loss is `crate::events::loss`.

mod batch;
mod blur_step;
mod kernel;
mod pixel_loss;
pub mod rays;
mod step;

pub use batch::{StepBuffers, StepLosses, Worker};
pub use kernel::{
    blur_loss, dsk_ray, dsk_ray_backward, kernel_ray_backward, ray_features, ray_features_backward, warped_ray_backward,
};
pub use step::step;

use std::path::Path;

pub(crate) use self::kernel::warp;
use self::rays::{sample_counts, scene_bounds};
use crate::blur::awp::Awp;
use crate::blur::dsk::Dsk;
use crate::blur::rigid::RigidKernel;
use crate::blur::trajectory::Trajectory;
use crate::config::{BlurModel, ImageSource, TrainConfig};
use crate::data::dataset::Dataset;
use crate::data::image::RgbImage;
use crate::engine::model::Model;
use crate::engine::params::Layout;
use crate::engine::rng::Rng;
use crate::error::TrainError;
use crate::events::ecrf::Ecrf;
use crate::events::loss::{dataset_thresholds, event_candidates, event_model, BT601, REC709};
use simulator::events::Sensor;

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
    /// Installs the occupancy grid a checkpoint saved (none if it has none: the next training
    /// step builds one).
    pub fn restore_occupancy(&mut self, ck: &crate::checkpoint::Checkpoint) -> Result<(), crate::error::TrainError> {
        self.model.set_occupancy_bits(ck.occupancy.clone()).map_err(|e| {
            crate::error::TrainError::Config(format!(
                "checkpoint of step {}: {e}; train the run again from scratch or restore its config.toml",
                ck.step
            ))
        })
    }

    /// The world-frame motion that takes a test view at time `t` into the frame the field was
    /// learned in, for a learned camera trajectory (BAD-NeRF): its training views' mid-exposure
    /// twists (xi_s + xi_e) / 2, interpolated linearly in time between the training views
    /// (`train`: view and mid-exposure time) just before and just after `t` (the nearest one
    /// past either end), then exp. Nothing anchors those twists to the dataset's poses: they
    /// drift, smoothly along the trajectory, and the field with them, so a test view rendered at
    /// its dataset pose would see a shifted scene. Only training parameters go in (no test
    /// image). `None` for every other method: their rays are the dataset's (the rigid and DSK
    /// kernels keep the un-moved origin ray).
    pub fn test_alignment(&self, params: &[f32], train: &[(usize, f64)], t: f64) -> Option<crate::blur::se3::Rigid> {
        let Some(Blur::Trajectory(tr)) = &self.blur else { return None };
        if !tr.config.learned {
            return None;
        }
        let before = train.iter().filter(|v| v.1 <= t).max_by(|a, b| a.1.total_cmp(&b.1));
        let after = train.iter().filter(|v| v.1 >= t).min_by(|a, b| a.1.total_cmp(&b.1));
        let xi = match (before, after) {
            (Some(&(a, ta)), Some(&(b, tb))) if tb > ta => {
                let (xa, xb, f) = (tr.mid_twist(params, a), tr.mid_twist(params, b), (t - ta) / (tb - ta));
                std::array::from_fn(|c| xa[c] + f * (xb[c] - xa[c]))
            }
            (Some(&(a, _)), _) | (None, Some(&(a, _))) => tr.mid_twist(params, a),
            (None, None) => return None,
        };
        Some(crate::blur::se3::exp(xi))
    }

    /// The parameters of `cfg` for a dataset of `views` views.
    pub fn new(cfg: &TrainConfig, views: usize) -> Method {
        let mut model = Model::new(&cfg.model);
        let coarse_features = model.coarse.shape.features;
        let blur = cfg.blur.as_ref().map(|b| {
            let l = &mut model.layout;
            match &b.model {
                BlurModel::Rigid { kernel, .. } => Blur::Rigid(RigidKernel::new(l, kernel, views)),
                BlurModel::Dsk(d) => Blur::Dsk(Dsk::new(l, d, views, coarse_features)),
                BlurModel::Trajectory(t) => Blur::Trajectory(Trajectory::new(l, t, views)),
            }
        });
        // The layout order (blur model, eCRF, AWP) is the checkpoints' parameter order.
        let ecrf = cfg.ecrf.as_ref().map(|c| Ecrf::new(&mut model.layout, c));
        let awp = cfg.blur.as_ref().and_then(|b| match &b.model {
            BlurModel::Rigid { kernel, awp: Some(a) } => {
                let features = model.fine_field().shape.features;
                Some(Awp::new(&mut model.layout, a, kernel.k + 1, features, kernel.embedding))
            }
            _ => None,
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

/// Fills in what a configuration leaves to the dataset: the volume box (fitted to the cameras),
/// the samples per ray (with `model.coarse_step`, see [`sample_counts`]) and the event model
/// (threshold, log offset, luma from `dataset.toml`, else the reference's). Resolving twice
/// changes nothing.
pub fn resolve(cfg: &mut TrainConfig, data: &Dataset) {
    let bounds = *cfg.model.bounds.get_or_insert_with(|| scene_bounds(data));
    (cfg.model.n_coarse, cfg.model.n_fine) = sample_counts(data, &cfg.model, &bounds);
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

#[cfg(test)]
mod tests;
