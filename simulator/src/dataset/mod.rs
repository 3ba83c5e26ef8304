//! The Ev-DeblurBlender dataset: settings, the writer pipeline and the schema check.
//!
//! What lives where:
//! - [`settings`]: the `[dataset]` table of a scene file and the command-line overrides.
//! - [`description`]: the scene file as a dataset reads it (its `[trajectory]`, `[dataset]` and
//!   `[events]` tables typed).
//! - [`plan`]: scene file + overrides -> a checked [`Plan`] (frame clock, views, content keys).
//! - [`cache`]: the half-float EXR frame cache (resume, and sweeps without re-rendering).
//! - [`writer`]: the pipeline: frames -> events, exposure, sharp renders, metadata, manifest.
//! - `frame_tail`: what follows each frame (cache, depth bounds, events, views), on a thread
//!   of its own beside the next frame's render.
//! - [`blur`]: how far image content moves during each exposure (mean / max pixel displacement).
//! - [`depth`]: z-depth through pixel centres and the LLFF near/far bounds.
//! - [`check`]: opens a dataset folder (ours or a public Ev-DeblurBlender one) and verifies
//!   shapes, dtypes, sortedness, rotations, timestamps and the sharp/blurry marking; its parts:
//!   `check_images` (the PNG folders), `check_arrays` (the `.npy` / `.npz` files) and
//!   `check_events` (`events.h5`, streamed in chunks; its column reader
//!   [`EventColumnReader`] is public for the trainer's loader).
//! - [`preview`]: a contact sheet of one view (sharp, blurry, events).
//! - [`noise`]: how many events path-tracing noise fires (a segment at spp vs 16x spp).
//! - [`fidelity`]: how well the events explain a converged reference's brightness changes.
//! - [`error`] holds [`DatasetError`].

pub mod blur;
pub mod cache;
pub mod check;
mod check_arrays;
mod check_events;
mod check_images;
pub mod depth;
pub mod description;
pub mod error;
pub mod fidelity;
mod frame_tail;
pub mod manifest;
pub mod noise;
pub mod plan;
pub mod preview;
pub mod sequence;
pub mod settings;
pub mod writer;

pub use check_events::{Col as EventCol, EventColumnReader};
pub use error::DatasetError;
pub use plan::Plan;
pub use settings::{DatasetConfig, NoisePattern, Overrides, Shading};
pub use writer::{write_dataset, RunOptions, Summary};
