//! Typed errors for trajectory configuration, interpolation and frame sampling. Every message
//! names the key (or field) and the fix.

/// An error while resolving a trajectory configuration or evaluating a trajectory.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    /// A configuration field is invalid, e.g. `keys[2].look_at`.
    #[error("trajectory: {field}: {message}")]
    Config {
        /// Which field is bad, with the key index, e.g. `keys[2].quaternion`.
        field: String,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A pose was asked for outside the time range covered by the keys.
    #[error(
        "trajectory: time {t_ns} ns is outside the key range [{start_ns}, {end_ns}] ns; \
         sample inside the keys or add a key that covers it"
    )]
    OutOfRange {
        /// The requested time (ns).
        t_ns: i64,
        /// Time of the first key (ns).
        start_ns: i64,
        /// Time of the last key (ns).
        end_ns: i64,
    },
    /// Frame-sampling arguments are invalid (frame rate, time window).
    #[error("frame sampling: {0}")]
    Sampling(String),
}

impl TrajectoryError {
    /// Shorthand for [`TrajectoryError::Config`].
    pub fn config(field: impl Into<String>, message: impl Into<String>) -> Self {
        TrajectoryError::Config { field: field.into(), message: message.into() }
    }
}
