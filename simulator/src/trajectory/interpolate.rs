//! Interpolation between key poses: slerp for rotation, a C1 cubic Hermite spline for position.
//!
//! Segment `i` spans keys `i` and `i+1`, `h_i = t_{i+1} - t_i` (s), local `s = (t - t_i) / h_i`.
//! - Position: `p(s) = h00(s) p_i + h10(s) h_i m_i + h01(s) p_{i+1} + h11(s) h_i m_{i+1}` with the
//!   Hermite basis `h00 = 2s^3 - 3s^2 + 1`, `h10 = s^3 - 2s^2 + s`, `h01 = -2s^3 + 3s^2`,
//!   `h11 = s^3 - s^2`. Tangents (m/s) are the derivative of the parabola through three keys,
//!   which accounts for unequal spacing:
//!   `m_i = (h_i d_{i-1} + h_{i-1} d_i) / (h_{i-1} + h_i)`, `d_i = (p_{i+1} - p_i) / h_i`;
//!   one-sided `m_0 = d_0`, `m_{n-1} = d_{n-2}` at the ends. Each key has one tangent shared by
//!   both segments, so velocity is continuous (C1); uniform-speed straight lines stay exact.
//! - Rotation: `slerp(q_i, ±q_{i+1}, s)` on the shortest arc (the sign of `q_{i+1}` is flipped
//!   when `q_i · q_{i+1} < 0`). Angular velocity is constant within a segment (C0 at keys).

use glam::{DMat3, DQuat, DVec3, DVec4, Mat4};

use super::error::TrajectoryError;
use super::keys::KeyPose;
use crate::scene::camera::Camera;

/// A rigid camera pose: camera-to-world rotation and camera centre, in f64.
///
/// The camera looks down its local -Z with +Y up and +X right, as [`Camera`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Unit camera-to-world rotation.
    pub rotation: DQuat,
    /// Camera centre in world space (m).
    pub position: DVec3,
}

impl Pose {
    /// The renderer's camera for this pose with full vertical field of view `yfov` (rad):
    /// `to_world` = rotation then translation, no scale (rounded to f32).
    pub fn camera(&self, yfov: f32) -> Camera {
        let to_world = Mat4::from_rotation_translation(self.rotation.as_quat().normalize(), self.position.as_vec3());
        Camera { name: "trajectory".into(), to_world, yfov }
    }

    /// Camera-to-world rotation as a 3x3 matrix with columns (right, up, backward).
    pub fn rotation_matrix(&self) -> DMat3 {
        DMat3::from_quat(self.rotation)
    }
}

/// Spherical linear interpolation from `q0` (s = 0) to `q1` (s = 1) along the shortest arc:
/// `q1` is negated first when `q0 · q1 < 0` (q and -q are the same rotation).
pub fn slerp_shortest(q0: DQuat, q1: DQuat, s: f64) -> DQuat {
    let a = DVec4::from(q0);
    let mut b = DVec4::from(q1);
    if a.dot(b) < 0.0 {
        b = -b; // take the short way round
    }
    // half the angle between the 4-vectors, computed stably from chord lengths
    let theta = 2.0 * (a - b).length().atan2((a + b).length());
    let sin_theta = theta.sin();
    let v = if sin_theta < 1e-12 {
        a.lerp(b, s) // (nearly) identical rotations: lerp avoids 0/0
    } else {
        a * (((1.0 - s) * theta).sin() / sin_theta) + b * ((s * theta).sin() / sin_theta)
    };
    DQuat::from_vec4(v).normalize()
}

/// A trajectory through validated key poses, evaluated at integer-nanosecond times.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    keys: Vec<KeyPose>,
    /// Position tangent at each key (m/s).
    tangents: Vec<DVec3>,
}

impl Trajectory {
    /// Build from validated keys (see [`super::keys::resolve_keys`]): needs >= 2 keys with
    /// strictly increasing times.
    pub fn new(keys: Vec<KeyPose>) -> Result<Trajectory, TrajectoryError> {
        if keys.len() < 2 {
            return Err(TrajectoryError::config("keys", "a trajectory needs at least 2 keys"));
        }
        if let Some(i) = (1..keys.len()).find(|&i| keys[i].t_ns <= keys[i - 1].t_ns) {
            return Err(TrajectoryError::config(format!("keys[{i}].t"), "times must strictly increase"));
        }
        let n = keys.len();
        let h = |i: usize| (keys[i + 1].t_ns - keys[i].t_ns) as f64 * 1e-9;
        let d = |i: usize| (keys[i + 1].position - keys[i].position) / h(i);
        let tangents = (0..n)
            .map(|i| {
                if i == 0 {
                    d(0)
                } else if i == n - 1 {
                    d(n - 2)
                } else {
                    // derivative at t_i of the parabola through keys i-1, i, i+1
                    (h(i) * d(i - 1) + h(i - 1) * d(i)) / (h(i - 1) + h(i))
                }
            })
            .collect();
        Ok(Trajectory { keys, tangents })
    }

    /// The validated keys.
    pub fn keys(&self) -> &[KeyPose] {
        &self.keys
    }

    /// Time of the first key (ns).
    pub fn start_ns(&self) -> i64 {
        self.keys[0].t_ns
    }

    /// Time of the last key (ns).
    pub fn end_ns(&self) -> i64 {
        self.keys[self.keys.len() - 1].t_ns
    }

    /// Time from the first to the last key (ns).
    pub fn duration_ns(&self) -> i64 {
        self.end_ns() - self.start_ns()
    }

    /// The pose at time `t_ns` (ns). Keys are hit exactly at their times. Times outside
    /// `[start_ns, end_ns]` are an error ([`TrajectoryError::OutOfRange`]), never clamped:
    /// a sampler that leaves the keys has a bug worth seeing.
    pub fn pose_at(&self, t_ns: i64) -> Result<Pose, TrajectoryError> {
        if t_ns < self.start_ns() || t_ns > self.end_ns() {
            return Err(TrajectoryError::OutOfRange { t_ns, start_ns: self.start_ns(), end_ns: self.end_ns() });
        }
        // first key strictly after t; the segment starts one before it
        let next = self.keys.partition_point(|k| k.t_ns <= t_ns);
        let i = next - 1;
        let k0 = &self.keys[i];
        if k0.t_ns == t_ns {
            return Ok(Pose { rotation: k0.rotation, position: k0.position });
        }
        let k1 = &self.keys[i + 1];
        let h = (k1.t_ns - k0.t_ns) as f64 * 1e-9;
        let s = (t_ns - k0.t_ns) as f64 / (k1.t_ns - k0.t_ns) as f64;
        // cubic Hermite basis
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let position =
            h00 * k0.position + h10 * h * self.tangents[i] + h01 * k1.position + h11 * h * self.tangents[i + 1];
        let rotation = slerp_shortest(k0.rotation, k1.rotation, s);
        Ok(Pose { rotation, position })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: i64 = 1_000_000_000;

    fn key(t_ns: i64, position: DVec3, rotation: DQuat) -> KeyPose {
        KeyPose { t_ns, position, rotation }
    }

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).abs().max_element() <= tol
    }

    fn same_rotation(a: DQuat, b: DQuat, tol: f64) -> bool {
        a.dot(b).abs() >= 1.0 - tol
    }

    /// Four keys at uneven times on a curved path with changing rotations.
    fn curvy() -> Trajectory {
        Trajectory::new(vec![
            key(0, DVec3::new(0.0, 0.0, 0.0), DQuat::IDENTITY),
            key(S / 4, DVec3::new(1.0, 0.5, 0.0), DQuat::from_rotation_y(0.3)),
            key(S, DVec3::new(2.0, -0.5, 1.0), DQuat::from_rotation_x(0.4)),
            key(S + S / 10, DVec3::new(2.5, 0.0, 1.5), -DQuat::from_rotation_z(0.2)),
        ])
        .unwrap()
    }

    #[test]
    fn keys_are_hit_exactly() {
        let traj = curvy();
        for k in traj.keys() {
            let p = traj.pose_at(k.t_ns).unwrap();
            assert_eq!(p.position, k.position);
            assert_eq!(p.rotation, k.rotation);
        }
    }

    #[test]
    fn midpoint_of_90_degree_yaw_is_45_degrees() {
        let q1 = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let traj = Trajectory::new(vec![key(0, DVec3::ZERO, DQuat::IDENTITY), key(S, DVec3::X, q1)]).unwrap();
        let mid = traj.pose_at(S / 2).unwrap();
        let want = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_4);
        assert!(same_rotation(mid.rotation, want, 1e-14), "{:?}", mid.rotation);
        // also with the end key given as -q (same rotation, other hemisphere)
        let traj = Trajectory::new(vec![key(0, DVec3::ZERO, DQuat::IDENTITY), key(S, DVec3::X, -q1)]).unwrap();
        assert!(same_rotation(traj.pose_at(S / 2).unwrap().rotation, want, 1e-14));
    }

    #[test]
    fn slerp_takes_short_arc_with_negated_quaternion() {
        let q0 = DQuat::from_rotation_z(0.2);
        let q1 = DQuat::from_rotation_z(0.6);
        for end in [q1, -q1] {
            for s in [0.25, 0.5, 0.75] {
                let q = slerp_shortest(q0, end, s);
                let want = DQuat::from_rotation_z(0.2 + 0.4 * s);
                // a long-arc slerp would rotate by 0.2 - (2*pi - 0.4) * s instead
                assert!(same_rotation(q, want, 1e-14), "s={s} end={end:?} got {q:?}");
            }
        }
        // equal inputs give the input (no 0/0)
        assert!(same_rotation(slerp_shortest(q0, q0, 0.3), q0, 1e-15));
        assert!(same_rotation(slerp_shortest(q0, -q0, 0.3), q0, 1e-15));
    }

    #[test]
    fn uniform_straight_line_is_linear() {
        // uneven key spacing, constant velocity v along a straight line
        let v = DVec3::new(1.0, -2.0, 0.5);
        let times = [0, S / 10, S / 2, S, 3 * S];
        let keys = times.iter().map(|&t| key(t, v * (t as f64 * 1e-9), DQuat::IDENTITY)).collect();
        let traj = Trajectory::new(keys).unwrap();
        for k in 0..=300 {
            let t = k * S / 100;
            let p = traj.pose_at(t).unwrap().position;
            assert!(close(p, v * (t as f64 * 1e-9), 1e-12), "t={t} p={p}");
        }
    }

    /// Central finite-difference velocities just before and just after `t_ns`.
    fn one_sided_velocities(pos: impl Fn(i64) -> DVec3, t_ns: i64, dt: i64) -> (DVec3, DVec3) {
        let sec = dt as f64 * 1e-9;
        let left = (pos(t_ns) - pos(t_ns - dt)) / sec;
        let right = (pos(t_ns + dt) - pos(t_ns)) / sec;
        (left, right)
    }

    #[test]
    fn velocity_is_continuous_across_keys() {
        let traj = curvy();
        let dt = 10_000; // 10 us
        for k in &traj.keys()[1..traj.keys().len() - 1] {
            let (l, r) = one_sided_velocities(|t| traj.pose_at(t).unwrap().position, k.t_ns, dt);
            assert!(close(l, r, 1e-2), "key at {} ns: left {l} right {r}", k.t_ns);
        }
        // the same check fails for a C0 piecewise-linear interpolation of the same keys
        let lin = |t: i64| {
            let ks = traj.keys();
            let i = ks.partition_point(|k| k.t_ns <= t).clamp(1, ks.len() - 1) - 1;
            let s = (t - ks[i].t_ns) as f64 / (ks[i + 1].t_ns - ks[i].t_ns) as f64;
            ks[i].position.lerp(ks[i + 1].position, s)
        };
        let k = traj.keys()[1];
        let (l, r) = one_sided_velocities(lin, k.t_ns, dt);
        assert!(!close(l, r, 1e-2), "piecewise-linear should have a velocity jump: {l} vs {r}");
    }

    #[test]
    fn tangents_account_for_unequal_spacing() {
        // p(t) = a t^2: the three-point parabola tangent is exact at interior keys, whereas a
        // uniform Catmull-Rom tangent (d_{i-1} + d_i) / 2 would be off for uneven spacing.
        let a = DVec3::new(0.5, -1.0, 2.0);
        let times = [0, S / 5, S, 3 * S / 2];
        let keys = times.iter().map(|&t| key(t, a * (t as f64 * 1e-9).powi(2), DQuat::IDENTITY)).collect();
        let traj = Trajectory::new(keys).unwrap();
        for (i, &t_ns) in times.iter().enumerate().take(3).skip(1) {
            let t_s = t_ns as f64 * 1e-9;
            assert!(close(traj.tangents[i], 2.0 * a * t_s, 1e-12), "key {i}: {}", traj.tangents[i]);
            let (l, r) = one_sided_velocities(|t| traj.pose_at(t).unwrap().position, t_ns, 1_000);
            assert!(close(l, 2.0 * a * t_s, 1e-4) && close(r, 2.0 * a * t_s, 1e-4), "{l} {r}");
        }
    }

    #[test]
    fn outside_the_keys_is_an_error() {
        let traj = curvy();
        assert!(matches!(traj.pose_at(-1), Err(TrajectoryError::OutOfRange { .. })));
        assert!(matches!(traj.pose_at(traj.end_ns() + 1), Err(TrajectoryError::OutOfRange { .. })));
        assert!(traj.pose_at(traj.end_ns()).is_ok());
        assert_eq!(traj.duration_ns(), S + S / 10);
    }

    #[test]
    fn camera_matches_rotation_and_position() {
        let pose = Pose {
            rotation: DQuat::from_euler(glam::EulerRot::YXZ, 0.3, -0.2, 0.1),
            position: DVec3::new(1.0, 2.0, 3.0),
        };
        let cam = pose.camera(0.7);
        let m = pose.rotation_matrix();
        assert!((cam.to_world.x_axis.truncate() - m.x_axis.as_vec3()).length() < 1e-6);
        assert!((cam.to_world.y_axis.truncate() - m.y_axis.as_vec3()).length() < 1e-6);
        assert!((cam.to_world.z_axis.truncate() - m.z_axis.as_vec3()).length() < 1e-6);
        assert!((cam.origin() - pose.position.as_vec3()).length() < 1e-6);
        assert_eq!(cam.yfov, 0.7);
        // the camera looks along -Z of the rotation
        let dir = cam.direction(glam::Vec2::new(300.0, 200.0), 600, 400);
        assert!((dir + m.z_axis.as_vec3()).length() < 1e-5);
    }
}
