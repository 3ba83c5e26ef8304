//! The CPU radiance-field engine: fused kernels over chunks of samples, forward and backward
//! written by hand, generic over [`real::Real`] so training runs in f32 and the gradient checks
//! in f64.
//!
//! What lives where:
//! - [`real`]: the scalar trait and its matrix product (the gemm crate).
//! - [`params`]: the flat parameter vector and its named tensors.
//! - [`mlp`]: dense layers; [`encoding`]: positional encoding; [`vm`]: TensoRF VM volumes + TV.
//! - [`field`]: one field level (volumes + density and colour MLPs).
//! - [`rng`]: counter-seeded generator; [`sampling`]: stratified and importance samples;
//!   [`volume`]: volume rendering (NeRF eq. 3) and its backward.
//! - [`model`]: coarse + fine levels over shared volumes; [`renderer`]: a chunk of rays through
//!   both passes, forward and backward.
//! - [`adam`]: the optimiser and learning-rate schedule.

// Kernels walk several parallel per-sample arrays with one index; that reads as the maths does.
#![allow(clippy::needless_range_loop)]

pub mod adam;
pub mod encoding;
pub mod field;
#[cfg(test)]
mod field_tests;
pub mod mlp;
pub mod model;
pub mod occupancy;
pub mod parallel;
pub mod params;
pub mod real;
pub mod renderer;
#[cfg(test)]
mod renderer_tests;
pub mod rng;
pub mod sampling;
pub mod vm;
pub mod volume;
