//! Key-pose configuration (the `[trajectory]` table of `scenes/<name>/scene.toml`) and its
//! resolution into validated keys.
//!
//! Stage 1 is the raw, serde-facing [`KeyPoseConfig`] (optional `look_at` / `quaternion` fields,
//! so a typo is an error that names the key); stage 2 is [`KeyPose`]: integer-nanosecond time,
//! f64 position and a unit camera-to-world quaternion.

use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

use super::error::TrajectoryError;
use super::fast_motion::FastMotion;
use super::interpolate::Trajectory;

/// How a trajectory is given: explicit key poses or a named preset.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum TrajectoryConfig {
    /// Explicit, time-stamped key poses (at least two).
    Keys {
        /// The key poses, in strictly increasing time.
        keys: Vec<KeyPoseConfig>,
    },
    /// The built-in fast continuous move around a target (see [`FastMotion`]).
    FastMotion(FastMotion),
}

impl TrajectoryConfig {
    /// Validate the configuration and build the interpolating trajectory.
    pub fn resolve(&self) -> Result<Trajectory, TrajectoryError> {
        match self {
            TrajectoryConfig::Keys { keys } => Trajectory::new(resolve_keys(keys)?),
            TrajectoryConfig::FastMotion(preset) => preset.trajectory(),
        }
    }

    /// The same path travelled `speed` times as fast: every key time (and the preset's
    /// duration) divided by `speed` (> 0).
    pub fn time_scaled(&self, speed: f64) -> TrajectoryConfig {
        match self {
            TrajectoryConfig::Keys { keys } => TrajectoryConfig::Keys {
                keys: keys.iter().map(|k| KeyPoseConfig { t: k.t / speed, ..k.clone() }).collect(),
            },
            TrajectoryConfig::FastMotion(p) => {
                TrajectoryConfig::FastMotion(FastMotion { duration: p.duration / speed, ..p.clone() })
            }
        }
    }
}

/// One key pose as written in the scene file. Give exactly one of `look_at` or `quaternion`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct KeyPoseConfig {
    /// Time of the key (s). Keys must be strictly increasing in time (after rounding to ns).
    pub t: f64,
    /// Camera centre in world space (m).
    pub position: [f64; 3],
    /// World-space point the camera looks at (m). Excludes `quaternion`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub look_at: Option<[f64; 3]>,
    /// World-space "roughly up" direction for `look_at` (unitless, any length > 0); default +Y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// Camera-to-world rotation as a quaternion `[x, y, z, w]` (glam order; normalised on load,
    /// camera looks down its local -Z with +Y up). Excludes `look_at`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quaternion: Option<[f64; 4]>,
}

/// The resolved orientation of a key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Orientation {
    /// Look from the key position at `target`, with `up` roughly up.
    LookAt {
        /// World-space point looked at (m).
        target: DVec3,
        /// Roughly-up direction (unitless).
        up: DVec3,
    },
    /// An explicit camera-to-world rotation (unit quaternion).
    Quaternion(DQuat),
}

/// A validated key pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyPose {
    /// Time of the key (ns).
    pub t_ns: i64,
    /// Camera centre in world space (m).
    pub position: DVec3,
    /// Unit camera-to-world rotation.
    pub rotation: DQuat,
}

/// Largest key time we accept (s): about 292 years of ns fit in an `i64`; we stop well before.
const MAX_ABS_T_S: f64 = 1.0e9;

/// Turn a time in seconds into integer nanoseconds, rounding half away from zero.
pub fn seconds_to_ns(t: f64) -> i64 {
    (t * 1e9).round() as i64
}

/// Camera-to-world rotation of a camera at `position` looking at `target` with `up` roughly up:
/// columns (right, true up, backward), the camera looks down -Z (as `Camera::look_at`).
/// Returns `None` when `target == position` or the view direction is parallel to `up`.
pub fn look_at_rotation(position: DVec3, target: DVec3, up: DVec3) -> Option<DQuat> {
    let forward = (target - position).try_normalize()?;
    let right = forward.cross(up.try_normalize()?);
    if right.length() < 1e-6 {
        return None; // view direction parallel to up: the roll is undefined
    }
    let right = right.normalize();
    let true_up = right.cross(forward);
    let m = DMat3::from_cols(right, true_up, -forward);
    Some(DQuat::from_mat3(&m).normalize())
}

fn finite<const N: usize>(v: &[f64; N]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Validate raw keys and resolve their orientations. Rules (each error names `keys[i].field`):
/// at least two keys; finite numbers; strictly increasing times; exactly one of `look_at` /
/// `quaternion`; `up` only with `look_at`; non-degenerate `look_at`; non-zero quaternion.
pub fn resolve_keys(keys: &[KeyPoseConfig]) -> Result<Vec<KeyPose>, TrajectoryError> {
    if keys.len() < 2 {
        return Err(TrajectoryError::config(
            "keys",
            format!("{} key(s) given; a trajectory needs at least 2 `[[trajectory.keys]]`", keys.len()),
        ));
    }
    let mut out: Vec<KeyPose> = Vec::with_capacity(keys.len());
    for (i, k) in keys.iter().enumerate() {
        let field = |name: &str| format!("keys[{i}].{name}");
        if !k.t.is_finite() || k.t.abs() > MAX_ABS_T_S {
            return Err(TrajectoryError::config(
                field("t"),
                format!("{} is not a finite time within +-1e9 s; give the key time in seconds", k.t),
            ));
        }
        let t_ns = seconds_to_ns(k.t);
        if let Some(prev) = out.last() {
            if t_ns <= prev.t_ns {
                return Err(TrajectoryError::config(
                    field("t"),
                    format!(
                        "{} s is not after keys[{}].t = {} s (times must strictly increase, compared in ns); \
                         reorder the keys or fix the time",
                        k.t,
                        i - 1,
                        keys[i - 1].t
                    ),
                ));
            }
        }
        if !finite(&k.position) {
            return Err(TrajectoryError::config(
                field("position"),
                format!("{:?} has a non-finite coordinate; give [x, y, z] in metres", k.position),
            ));
        }
        let position = DVec3::from_array(k.position);
        let orientation = match (k.look_at, k.quaternion) {
            (Some(_), Some(_)) => {
                return Err(TrajectoryError::config(
                    field("look_at"),
                    "both `look_at` and `quaternion` are given; keep exactly one",
                ))
            }
            (None, None) => {
                return Err(TrajectoryError::config(
                    field("look_at"),
                    "no orientation; add `look_at = [x, y, z]` or `quaternion = [x, y, z, w]`",
                ))
            }
            (Some(target), None) => {
                if !finite(&target) {
                    return Err(TrajectoryError::config(
                        field("look_at"),
                        format!("{target:?} has a non-finite coordinate"),
                    ));
                }
                let up = k.up.unwrap_or([0.0, 1.0, 0.0]);
                if !finite(&up) || DVec3::from_array(up).length() == 0.0 {
                    return Err(TrajectoryError::config(
                        field("up"),
                        format!("{up:?} is not a finite non-zero direction; e.g. up = [0, 1, 0]"),
                    ));
                }
                Orientation::LookAt { target: DVec3::from_array(target), up: DVec3::from_array(up) }
            }
            (None, Some(q)) => {
                if k.up.is_some() {
                    return Err(TrajectoryError::config(
                        field("up"),
                        "`up` only applies to `look_at`; remove it or use `look_at`",
                    ));
                }
                if !finite(&q) {
                    return Err(TrajectoryError::config(
                        field("quaternion"),
                        format!("{q:?} has a non-finite component"),
                    ));
                }
                let q = DQuat::from_array(q);
                if q.length() < 1e-6 {
                    return Err(TrajectoryError::config(
                        field("quaternion"),
                        "is (close to) zero and is no rotation; identity is [0, 0, 0, 1] (x, y, z, w)",
                    ));
                }
                Orientation::Quaternion(q.normalize())
            }
        };
        let rotation = match orientation {
            Orientation::Quaternion(q) => q,
            Orientation::LookAt { target, up } => look_at_rotation(position, target, up).ok_or_else(|| {
                TrajectoryError::config(
                    field("look_at"),
                    format!(
                        "degenerate: target {:?} equals the position or the view direction is parallel \
                         to up {:?}; move the target or change `up`",
                        target.to_array(),
                        up.to_array()
                    ),
                )
            })?,
        };
        out.push(KeyPose { t_ns, position, rotation });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: f64) -> KeyPoseConfig {
        KeyPoseConfig { t, position: [0.0, 0.0, 5.0], look_at: Some([0.0; 3]), up: None, quaternion: None }
    }

    fn err_field(keys: &[KeyPoseConfig]) -> String {
        match resolve_keys(keys) {
            Err(TrajectoryError::Config { field, .. }) => field,
            other => panic!("expected a config error, got {other:?}"),
        }
    }

    #[test]
    fn parses_toml_with_both_orientation_forms() {
        let cfg: TrajectoryConfig = toml::from_str(
            r#"
            type = "keys"
            [[keys]]
            t = 0.0
            position = [0.0, 1.0, 5.0]
            look_at = [0.0, 0.0, 0.0]
            [[keys]]
            t = 0.5
            position = [1.0, 1.0, 5.0]
            quaternion = [0.0, 0.0, 0.0, 2.0]
            "#,
        )
        .unwrap();
        let traj = cfg.resolve().unwrap();
        assert_eq!(traj.keys().len(), 2);
        assert_eq!(traj.keys()[1].t_ns, 500_000_000);
        assert!((traj.keys()[1].rotation.length() - 1.0).abs() < 1e-15, "quaternion normalised");
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let bad_key = "type = \"keys\"\n[[keys]]\nt = 0.0\nposition = [0.0, 0.0, 1.0]\nlookat = [0.0, 0.0, 0.0]\n";
        assert!(toml::from_str::<TrajectoryConfig>(bad_key).unwrap_err().to_string().contains("lookat"));
        let bad_top = "type = \"keys\"\nkeys = []\nspeed = 2.0\n";
        assert!(toml::from_str::<TrajectoryConfig>(bad_top).unwrap_err().to_string().contains("speed"));
        let bad_preset = "type = \"fast_motion\"\ntarget = [0.0, 0.0, 0.0]\nradius = 3.0\nwobble = 1.0\n";
        assert!(toml::from_str::<TrajectoryConfig>(bad_preset).unwrap_err().to_string().contains("wobble"));
    }

    #[test]
    fn config_errors_name_key_and_field() {
        assert_eq!(err_field(&[key(0.0)]), "keys");
        assert_eq!(err_field(&[key(0.0), key(f64::NAN)]), "keys[1].t");
        assert_eq!(err_field(&[key(0.0), key(0.0)]), "keys[1].t");
        assert_eq!(err_field(&[key(1.0), key(0.5)]), "keys[1].t");
        let mut k = key(1.0);
        k.position[1] = f64::INFINITY;
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].position");
        let mut k = key(1.0);
        k.look_at = Some([0.0, 0.0, 5.0]); // target == position
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].look_at");
        let mut k = key(1.0);
        k.look_at = Some([0.0, 3.0, 5.0]); // straight up, parallel to default up
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].look_at");
        let mut k = key(1.0);
        k.look_at = Some([f64::NAN, 0.0, 0.0]);
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].look_at");
        let mut k = key(1.0);
        k.up = Some([0.0, 0.0, 0.0]);
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].up");
        let mut k = key(1.0);
        k.quaternion = Some([0.0, 0.0, 0.0, 1.0]); // both orientations
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].look_at");
        let mut k = key(1.0);
        k.look_at = None; // no orientation
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].look_at");
        let mut k = key(1.0);
        k.look_at = None;
        k.quaternion = Some([0.0; 4]);
        assert_eq!(err_field(&[key(0.0), k.clone()]), "keys[1].quaternion");
        k.quaternion = Some([0.0, 0.0, f64::NAN, 1.0]);
        assert_eq!(err_field(&[key(0.0), k.clone()]), "keys[1].quaternion");
        k.quaternion = Some([0.0, 0.0, 0.0, 1.0]);
        k.up = Some([0.0, 1.0, 0.0]);
        assert_eq!(err_field(&[key(0.0), k]), "keys[1].up");
        // the message carries the fix
        let msg = resolve_keys(&[key(0.0)]).unwrap_err().to_string();
        assert!(msg.contains("at least 2"), "{msg}");
    }

    #[test]
    fn look_at_matches_camera_look_at() {
        let (o, t, up) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(-1.0, 0.5, 0.0), DVec3::Y);
        let q = look_at_rotation(o, t, up).unwrap();
        let cam = crate::scene::camera::Camera::look_at(o.as_vec3(), t.as_vec3(), up.as_vec3(), 1.0);
        let m = DMat3::from_quat(q);
        for (a, b) in [
            (m.x_axis, cam.to_world.x_axis.truncate()),
            (m.y_axis, cam.to_world.y_axis.truncate()),
            (m.z_axis, cam.to_world.z_axis.truncate()),
        ] {
            assert!((a.as_vec3() - b).length() < 1e-6, "{a} vs {b}");
        }
    }
}
