//! Checking our renderer against Mitsuba 3, the reference renderer of record.
//!
//! - [`compare`]: relMSE and tile z-scores of an image against a ground truth.
//! - [`mitsuba`]: finding the Mitsuba venv, running `tests/mitsuba/render.py` on an exported
//!   scene, and ground truths cached under `~/.cache/evblur/mitsuba-gt`.
//!
//! Used by the reference test (`tests/mitsuba_reference.rs`) and by `evsim bench render`.

pub mod compare;
pub mod mitsuba;
