//! The Ev-DeblurBlender dataset: settings, the writer pipeline and the schema check.
//!
//! What lives where:
//! - [`check`]: opens a dataset folder (ours or a public Ev-DeblurBlender one) and verifies
//!   shapes, dtypes, sortedness, rotations, timestamps and the sharp/blurry marking.

pub mod check;
