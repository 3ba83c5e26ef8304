//! Camera trajectories: time-stamped key poses, interpolation, frame times and LLFF poses.
//!
//! A scene's `[trajectory]` table is either explicit keys or the `fast_motion` preset:
//!
//! ```toml
//! [trajectory]
//! type = "keys"
//! [[trajectory.keys]]
//! t = 0.0                        # s, strictly increasing
//! position = [0.0, 1.0, 5.0]     # m
//! look_at = [0.0, 0.5, 0.0]      # m; optional `up` (default [0, 1, 0])
//! [[trajectory.keys]]
//! t = 1.0
//! position = [2.0, 1.2, 4.5]
//! quaternion = [0.0, 0.2, 0.0, 0.98]   # x, y, z, w camera-to-world (normalised on load)
//! ```
//!
//! or `type = "fast_motion"` with `target = [x, y, z]` and `radius = r` (a ~1 s orbit arc).
//!
//! Conventions: time is integer nanoseconds (`t` in the file is seconds, rounded to ns); a
//! camera looks down its local -Z with +Y up and +X right (as [`crate::scene::camera::Camera`]);
//! poses are f64. Rotation is slerped on the shortest arc, position follows a C1 cubic Hermite
//! spline with non-uniform three-point tangents (formulas in [`interpolate`]).
//! [`Trajectory::pose_at`] refuses times outside the keys instead of clamping.
//!
//! What lives where:
//! - [`keys`]: the serde config ([`TrajectoryConfig`], [`KeyPoseConfig`]) and its validation.
//! - [`interpolate`]: [`Pose`], [`Trajectory`] and shortest-arc slerp.
//! - [`sample`]: frame times at a frame rate (default 1000 FPS), integer ns.
//! - [`fast_motion`]: the built-in fast continuous orbit preset.
//! - [`llff`]: a pose <-> a 17-float64 `poses_bounds.npy` row, with the pure-rotation check.
//! - [`error`]: [`TrajectoryError`] (config, range and sampling errors).

pub mod error;
pub mod fast_motion;
pub mod interpolate;
pub mod keys;
pub mod llff;
pub mod sample;

pub use error::TrajectoryError;
pub use fast_motion::FastMotion;
pub use interpolate::{Pose, Trajectory};
pub use keys::{KeyPose, KeyPoseConfig, TrajectoryConfig};
pub use llff::{LlffCamera, LlffError};
pub use sample::{frame_times, FrameTimes, DEFAULT_FPS};
