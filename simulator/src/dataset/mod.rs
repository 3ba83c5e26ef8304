//! The Ev-DeblurBlender dataset: settings, the writer pipeline and the schema check.
//!
//! What lives where:
//! - [`check`]: opens a dataset folder (ours or a public Ev-DeblurBlender one) and verifies
//!   shapes, dtypes, sortedness, rotations, timestamps and the sharp/blurry marking; its parts:
//!   `check_images` (the PNG folders), `check_arrays` (the `.npy` / `.npz` files) and
//!   `check_events` (`events.h5`, streamed in chunks).

pub mod check;
mod check_arrays;
mod check_events;
mod check_images;
