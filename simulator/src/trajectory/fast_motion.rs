//! The `fast_motion` preset: a smooth, fast, continuous camera move around a target, like the
//! fast continuous motion of the Ev-DeblurBlender sequences, for scenes that give only a target
//! and a radius.
//!
//! Key `j` of `n` (`u = j / (n - 1)`) is at time `u * duration`, azimuth
//! `phi = start_azimuth + u * sweep` about the up axis (+Y), on a circle of `radius` around the
//! target at height `height + 0.5 * bob * sin(2 pi u)`, looking at the target:
//! `p = target + (radius sin phi, height + 0.5 bob sin(2 pi u), radius cos phi)`.
//! Keys are evenly spaced, so the camera moves at a near-constant speed without stopping.

use serde::{Deserialize, Serialize};

use super::error::TrajectoryError;
use super::interpolate::Trajectory;
use super::keys::{resolve_keys, KeyPoseConfig};

/// Parameters of the fast orbit preset. Only `target` and `radius` are required in a file.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FastMotion {
    /// World-space point the camera keeps looking at (m).
    pub target: [f64; 3],
    /// Horizontal distance from the target to the camera (m). Larger radius, same sweep: faster
    /// linear motion and more blur.
    pub radius: f64,
    /// Camera height above the target (m); default 0.3 x radius.
    #[serde(default)]
    pub height: Option<f64>,
    /// Azimuth of the first key about +Y (deg); 0 puts the camera on the target's +Z side.
    #[serde(default)]
    pub start_azimuth_deg: f64,
    /// Azimuth swept over the whole move (deg, signed); default 45. More sweep, more blur.
    #[serde(default = "default_sweep_deg")]
    pub sweep_deg: f64,
    /// Peak-to-peak vertical bob over the move (m); default 0.1 x radius. Makes the motion
    /// non-planar (both rotation axes change).
    #[serde(default)]
    pub bob: Option<f64>,
    /// Length of the move (s); default 1.
    #[serde(default = "default_duration")]
    pub duration: f64,
    /// Number of key poses generated along the arc (>= 2); default 9. More keys follow the
    /// circle more closely.
    #[serde(default = "default_keys")]
    pub keys: usize,
}

fn default_sweep_deg() -> f64 {
    45.0
}
fn default_duration() -> f64 {
    1.0
}
fn default_keys() -> usize {
    9
}

impl FastMotion {
    /// The preset around `target` at `radius` (m) with every other field at its default.
    pub fn new(target: [f64; 3], radius: f64) -> FastMotion {
        FastMotion {
            target,
            radius,
            height: None,
            start_azimuth_deg: 0.0,
            sweep_deg: default_sweep_deg(),
            bob: None,
            duration: default_duration(),
            keys: default_keys(),
        }
    }

    /// The generated key poses (times from 0 s), before validation.
    pub fn key_configs(&self) -> Result<Vec<KeyPoseConfig>, TrajectoryError> {
        let bad = |field: &str, message: String| TrajectoryError::config(format!("fast_motion.{field}"), message);
        if !(self.radius > 0.0 && self.radius.is_finite()) {
            return Err(bad("radius", format!("{} is not a positive distance in metres", self.radius)));
        }
        if !(self.duration > 0.0 && self.duration.is_finite()) {
            return Err(bad("duration", format!("{} is not a positive time in seconds", self.duration)));
        }
        if self.keys < 2 {
            return Err(bad("keys", format!("{} key(s); generate at least 2", self.keys)));
        }
        let height = self.height.unwrap_or(0.3 * self.radius);
        let bob = self.bob.unwrap_or(0.1 * self.radius);
        for (field, v) in [
            ("height", height),
            ("start_azimuth_deg", self.start_azimuth_deg),
            ("sweep_deg", self.sweep_deg),
            ("bob", bob),
        ] {
            if !v.is_finite() {
                return Err(bad(field, format!("{v} is not finite")));
            }
        }
        let n = self.keys;
        Ok((0..n)
            .map(|j| {
                let u = j as f64 / (n - 1) as f64;
                let phi = (self.start_azimuth_deg + u * self.sweep_deg).to_radians();
                let y = height + 0.5 * bob * (std::f64::consts::TAU * u).sin();
                let [tx, ty, tz] = self.target;
                KeyPoseConfig {
                    t: u * self.duration,
                    position: [tx + self.radius * phi.sin(), ty + y, tz + self.radius * phi.cos()],
                    look_at: Some(self.target),
                    up: None,
                    quaternion: None,
                }
            })
            .collect())
    }

    /// Validate and build the trajectory.
    pub fn trajectory(&self) -> Result<Trajectory, TrajectoryError> {
        Trajectory::new(resolve_keys(&self.key_configs()?)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn fast_motion_orbits_and_looks_at_target() {
        let preset = FastMotion::new([1.0, 0.0, -2.0], 4.0);
        let traj = preset.trajectory().unwrap();
        assert_eq!(traj.duration_ns(), 1_000_000_000);
        let target = DVec3::new(1.0, 0.0, -2.0);
        for f in traj.sample(100.0).unwrap().times_ns {
            let pose = traj.pose_at(f).unwrap();
            let offset = pose.position - target;
            let r = (offset.x * offset.x + offset.z * offset.z).sqrt();
            assert!((r - 4.0).abs() < 0.01 * 4.0, "radius {r} at {f} ns");
            // the view direction (-Z) points at the target within ~1 degree between keys
            let forward = -pose.rotation_matrix().z_axis;
            assert!(forward.dot(-offset.normalize()) > 0.9998, "t={f}");
        }
        // it really moves: 45 degrees at radius 4 is ~3.1 m of arc
        let a = traj.pose_at(0).unwrap().position;
        let b = traj.pose_at(traj.end_ns()).unwrap().position;
        assert!((a - b).length() > 2.5);
    }

    #[test]
    fn fast_motion_errors_name_the_field() {
        let mut p = FastMotion::new([0.0; 3], 0.0);
        assert!(p.trajectory().unwrap_err().to_string().contains("fast_motion.radius"));
        p.radius = 1.0;
        p.keys = 1;
        assert!(p.trajectory().unwrap_err().to_string().contains("fast_motion.keys"));
        p.keys = 9;
        p.duration = -1.0;
        assert!(p.trajectory().unwrap_err().to_string().contains("fast_motion.duration"));
    }
}
