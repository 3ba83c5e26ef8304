//! Turning a [`Scene`](crate::scene::Scene) into an image.
//!
//! - [`sampler`]: where a camera sample's numbers come from (independent or Owen-scrambled Sobol).
//! - [`accel`]: the obvhs BVH over the scene's triangles; closest-hit and shadow queries.
//! - [`raster`]: primary visibility by rasterisation (which triangle each camera sample sees).
//! - [`radiance_cache`]: a world-space cache of reflected light that ends paths early.
//! - [`bsdf`]: Lambert + GGX metallic-roughness (sample / eval / pdf).
//! - [`lights`]: emissive triangles sampled by power, punctual lights, environment.
//! - [`integrator`]: the unidirectional path tracer with next-event estimation and MIS.
//! - [`frame_caches`]: what a renderer keeps from one frame to the next (radiance and surface
//!   caches, film offsets).
//! - [`film`]: the settings of one render (the random numbers, the image and colour helpers
//!   are in [`crate::base`]).
//! - [`denoise`]: the feature-guided À-Trous denoiser applied to dataset frames.
//! - [`temporal`]: reprojection of neighbouring frames' lighting before the denoiser.
//! - `chi2` (tests only): a chi-square goodness-of-fit test for direction samplers.

pub mod accel;
pub mod bsdf;
#[cfg(test)]
pub(crate) mod chi2;
pub mod denoise;
pub mod film;
pub mod frame_caches;
pub mod integrator;
pub mod lights;
pub mod radiance_cache;
pub mod raster;
pub mod sampler;
pub mod temporal;
