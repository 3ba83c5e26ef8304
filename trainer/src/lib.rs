//! Trainer: radiance fields, blur models and losses .
//!
//! What lives where:
//! - [`data`]: the dataset loader (the Ev-DeblurBlender layout): images, poses in the recentred,
//!   scaled world, the dense trajectory with pose interpolation, events with successors, rays.
//! - [`engine`]: the CPU radiance-field engine (kernels, gradients, optimiser).
//! - [`config`]: a run's settings; [`presets`]: the registry of named methods.
//! - [`method`]: one training step of any method (blur kernel, event loss, eCRF, EDI);
//!   [`train`]: the training loop; [`run`]: opening a run folder (new, resumed) as
//!   `evtrain` and `evbench` both do; [`checkpoint`]: saved states; [`eval`]: test-view scores.
//! - [`blur`]: blur models (rigid kernel, AWP, the se(3) exponential map).
//! - [`events`]: event supervision: the eCRF and the EDI prior.
//! - [`deblur`]: pluggable image deblurring before training (a command per view, cached).
//! - [`metrics`]: PSNR and SSIM of images as scikit-image computes them ([`metrics::ImageRef`]).
#![warn(missing_docs)]

pub mod bench;
pub mod blur;
pub mod checkpoint;
pub mod config;
pub mod data;
pub mod deblur;
pub mod diagnose;
pub mod engine;
pub mod error;
pub mod eval;
pub mod events;
pub mod method;
pub mod metrics;
pub mod presets;
pub mod run;
pub mod train;
