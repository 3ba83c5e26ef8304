//! Cross-crate and reference checks; see the files beside this one.
//!
//! - [`compare`]: relMSE and tile z-scores used by `mitsuba_reference.rs`.

pub mod compare;
