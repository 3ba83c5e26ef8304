//! The dense camera trajectory (`all_poses_bounds.npy` + `all_timestamps.npy`) and pose
//! interpolation at any time inside it.
//!
//! As the reference loader: rotation by slerp between the two neighbouring poses (scipy's `Slerp`,
//! which follows the shortest arc), translation by a cubic spline through all positions (the
//! not-a-knot spline of scipy's `CubicSpline` / `interp1d(kind = "cubic")`, see [`super::spline`]).
//! Times outside the trajectory are refused, not extrapolated.
//!
//! Poses here are already in the loader's world (scaled and recentred, [`super::world`]); both
//! interpolants commute with that similarity transform, so interpolating before or after it is
//! the same.

use glam::DQuat;
use simulator::trajectory::interpolate::slerp_shortest;
use simulator::trajectory::Pose;

use super::spline::{segment, CubicSpline};

/// The dense trajectory: one pose per timestamp (us, strictly increasing).
#[derive(Clone, Debug, PartialEq)]
pub struct DenseTrajectory {
    times_us: Vec<f64>,
    rotations: Vec<DQuat>,
    translation: CubicSpline,
}

impl DenseTrajectory {
    /// A trajectory through `poses` at `times_us` (strictly increasing, at least 2); `None`
    /// otherwise.
    pub fn new(times_us: Vec<f64>, poses: &[Pose]) -> Option<DenseTrajectory> {
        let positions = poses.iter().map(|p| p.position).collect();
        let translation = CubicSpline::not_a_knot(times_us.clone(), positions)?;
        Some(DenseTrajectory { times_us, rotations: poses.iter().map(|p| p.rotation).collect(), translation })
    }

    /// The timestamps (us).
    pub fn times_us(&self) -> &[f64] {
        &self.times_us
    }

    /// First and last timestamp (us).
    pub fn range_us(&self) -> (f64, f64) {
        (self.times_us[0], self.times_us[self.times_us.len() - 1])
    }

    /// True if `t_us` lies inside the trajectory's time range (ends included).
    pub fn contains(&self, t_us: f64) -> bool {
        let (lo, hi) = self.range_us();
        t_us >= lo && t_us <= hi
    }

    /// The pose at `t_us`: slerp of the neighbouring rotations, not-a-knot cubic spline of the
    /// positions. `None` outside [`DenseTrajectory::range_us`].
    pub fn pose_at(&self, t_us: f64) -> Option<Pose> {
        let i = segment(&self.times_us, t_us)?;
        let s = (t_us - self.times_us[i]) / (self.times_us[i + 1] - self.times_us[i]);
        let rotation = slerp_shortest(self.rotations[i], self.rotations[i + 1], s);
        Some(Pose { rotation, position: self.translation.eval(t_us)? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn rotation_is_slerp_between_neighbours() {
        let q0 = DQuat::from_rotation_y(0.1);
        let q1 = DQuat::from_rotation_y(0.5);
        let poses = [
            Pose { rotation: q0, position: DVec3::ZERO },
            Pose { rotation: -q1, position: DVec3::X }, // the sign of a quaternion does not matter
        ];
        let tr = DenseTrajectory::new(vec![10.0, 20.0], &poses).unwrap();
        let p = tr.pose_at(12.5).unwrap();
        let want = DQuat::from_rotation_y(0.2);
        assert!(p.rotation.dot(want).abs() > 1.0 - 1e-12, "{:?}", p.rotation);
        assert!((p.position - DVec3::new(0.25, 0.0, 0.0)).length() < 1e-12);
        assert!(tr.pose_at(9.9).is_none() && tr.pose_at(20.1).is_none());
    }
}
