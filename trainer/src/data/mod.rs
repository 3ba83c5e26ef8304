//! The dataset loader: the Ev-DeblurBlender layout (`docs/dataset-format.md`), read as the public
//! reference loader reads it, into the loader's world (LLFF poses converted, scaled by
//! `1 / (0.75 min near)` and recentred on the average pose).
//!
//! What lives where:
//! - [`dataset`]: [`Dataset::load`] (schema check first, then everything below), [`LoadOptions`],
//!   the views ([`View`]) and the train / test [`Split`].
//! - [`world`]: LLFF row conversion (`[c1, -c0, c2]`), scene scale and recentring ([`WorldTransform`]).
//! - [`trajectory`]: the dense trajectory and pose interpolation (slerp + cubic spline).
//! - [`spline`]: the not-a-knot cubic spline (scipy's `CubicSpline` default).
//! - [`events`]: `events.h5` on the image clock, successors at the same pixel, `ev_map.npz`.
//! - [`rays`]: pinhole rays through pixel centres and the NDC warp.
//! - [`image`]: PNG -> f32 RGB in [0, 1] (display-referred).
//! - [`error`] holds [`LoadError`].

pub mod dataset;
pub mod error;
pub mod events;
pub mod image;
pub mod rays;
pub mod spline;
pub mod trajectory;
pub mod world;

pub use dataset::{Dataset, LoadOptions, Split, View};
pub use error::LoadError;
pub use events::{EvMap, Events};
pub use image::RgbImage;
pub use rays::{ndc_ray, Intrinsics, Ray};
pub use trajectory::DenseTrajectory;
pub use world::WorldTransform;

#[cfg(test)]
mod public_style_tests;
