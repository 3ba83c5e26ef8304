//! Blur models (issue 7 onwards). What lives where:
//! - [`se3`]: the exponential map of se(3) twists to rigid motions, and its backward.

pub mod se3;
