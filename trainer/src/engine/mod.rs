//! The CPU radiance-field engine: fused kernels over chunks of samples, forward and backward
//! written by hand, generic over [`real::Real`] so training runs in f32 and the gradient checks
//! in f64.
//!
//! What lives where:
//! - [`real`]: the scalar trait and its matrix product (matrixmultiply).
//! - [`params`]: the flat parameter vector and its named tensors.
//! - [`mlp`]: dense layers; [`encoding`]: positional encoding; [`vm`]: TensoRF VM volumes + TV.
//! - [`field`]: one field level (volumes + density and colour MLPs).
//! - [`adam`]: the optimiser and learning-rate schedule.

pub mod adam;
pub mod encoding;
pub mod field;
#[cfg(test)]
mod field_tests;
pub mod mlp;
pub mod parallel;
pub mod params;
pub mod real;
pub mod vm;
