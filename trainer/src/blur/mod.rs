//! Blur models (issue 7 onwards). What lives where:
//! - [`awp`]: DP-NeRF's adaptive weight proposal (blending weights from what the rays see).
//! - [`dsk`]: Deblur-NeRF's deformable sparse kernel (per-pixel ray offsets, origin shifts and
//!   weights from an MLP over the image embedding, kernel point and pixel position).
//! - [`rigid`]: DP-NeRF's rigid blurring kernel heads (per-image twists and blending weights).
//! - [`trajectory`]: virtual cameras inside the exposure (BAD-NeRF learned, E2NeRF fixed).
//! - [`se3`]: the exponential map of se(3) twists to rigid motions, and its backward.

pub mod awp;
pub mod dsk;
pub mod rigid;
pub mod se3;
pub mod trajectory;

/// Most rays a pixel group can have (the origin ray and up to 31 warped rays).
pub const MAX_RAYS: usize = 32;
