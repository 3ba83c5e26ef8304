//! evblur simulator: turns 3D scenes into images, events and (soon) event-camera datasets.
//!
//! What lives where:
//! - [`base`]: what every part uses and that imports none of them: the linear-light image, the
//!   random numbers and sampling routines, colour helpers.
//! - [`scene`]: the in-memory scene (triangles, materials, textures, lights, environment, cameras)
//!   and its loaders (glTF 2.0, OBJ/MTL, the `.toml` render description).
//! - [`trajectory`]: camera trajectories (key poses, slerp + C1 cubic interpolation, frame times
//!   in integer ns, the `fast_motion` preset) and LLFF pose rows.
//! - [`events`]: the event camera (ESIM model + optional v2e non-idealities), frames in, events
//!   out to a sink.
//! - [`render`]: the BVH, sampling, BSDFs, lights and the path tracer that turn a scene into a
//!   linear-light image.
//! - [`exposure`]: exposure averaging: streamed linear frames -> box-filtered blurry (or sharp)
//!   views, and the camera response (sRGB / gamma) to 8-bit PNG.
//! - [`image_io`]: writing linear EXR and 8-bit sRGB PNG, atomically.
//! - [`npy`]: NumPy `.npy` / `.npz` files, written (stored zip, atomically) and read (stored or
//!   deflated), for the dataset's poses and timestamps and the event `.npz` sink.
//! - [`export`]: writing a scene for Mitsuba 3 (PLY + EXR + `scene.json`).
//! - [`scenegen`]: procedural scenes: a glTF 2.0 writer, mesh primitives, procedural textures
//!   and the registry behind `evsim scene generate`.
//! - [`reference`](mod@reference): comparison statistics and the Mitsuba 3 driver for reference checks.
//! - [`error`]: the typed errors every loader returns.

#![allow(clippy::neg_cmp_op_on_partial_ord)] // `!(x > 0.0)` is deliberate: it is also true for NaN
#![warn(missing_docs)]

pub mod base;
pub mod dataset;
pub mod error;
pub mod events;
pub mod export;
pub mod exposure;
pub mod image_io;
pub mod lock;
pub mod npy;
pub mod reference;
pub mod render;
pub mod scene;
pub mod scenegen;
pub mod trajectory;

pub use error::SceneError;
