//! LLFF rows -> poses in the loader's world: the reference loader's (LLFF `load_llff_data`)
//! conversion, scene scaling and recentring.
//!
//! 1. Columns: a row's 3x5 matrix `[c0 c1 c2 | t | hwf]` has the camera's down, right and
//!    backward axes; `[c1, -c0, c2]` gives (right, up, backward), our camera convention (looks
//!    down -Z, +Y up). The rotation must be pure (checked by the schema check, tolerance 1e-4).
//! 2. Scale: `sc = 1 / (0.75 * min(bounds))` over the rows of `poses_bounds.npy` (`bd_factor =
//!    0.75`; the smallest bound is the smallest near); translations and bounds are multiplied by it.
//! 3. Recentre (`recenter_poses`): the average pose `c2w_avg` has centre `c` = mean of the
//!    (scaled) centres, backward axis `z = normalize(sum of backward axes)`, right
//!    `x = normalize(cross(sum of up axes, z))` and up `y = normalize(cross(z, x))`; every pose
//!    becomes `c2w_avg^-1 * pose`, i.e. `R' = A^T R`, `t' = A^T (t - c)`.
//!
//! The dense trajectory is mapped by the same `sc` and `c2w_avg` (those of the image poses).

use glam::{DMat3, DQuat, DVec3};
use simulator::trajectory::llff::LlffCamera;
use simulator::trajectory::Pose;

/// One LLFF row, before scaling: the simulator's [`LlffCamera`] (pose as right, up, backward,
/// intrinsics, bounds in file units), read with
/// [`LlffCamera::from_row_unchecked`] (the schema check tested the rotations already, with the
/// tolerance the public float32-derived files need).
pub type LlffRow = LlffCamera;

/// The similarity from the file's world to the loader's: `x' = A^T (sc x - c)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldTransform {
    /// Scene scale `sc = 1 / (0.75 * min near)` (1 / file unit).
    pub scale: f64,
    /// The average pose's rotation `A` (columns right, up, backward), in the scaled world.
    pub avg_rotation: DMat3,
    /// The average pose's centre `c`, in the scaled world.
    pub avg_center: DVec3,
}

/// The reference's `bd_factor`: the nearest content lands at depth 1 / 0.75 after scaling.
pub const BD_FACTOR: f64 = 0.75;

impl WorldTransform {
    /// The transform of the reference loader for the image rows (`poses_bounds.npy`).
    pub fn from_rows(rows: &[LlffRow]) -> WorldTransform {
        let min_bound = rows.iter().flat_map(|r| [r.near, r.far]).fold(f64::INFINITY, f64::min);
        let scale = 1.0 / (BD_FACTOR * min_bound);
        // poses_avg: mean centre, summed backward and up axes, then viewmatrix
        let n = rows.len() as f64;
        let avg_center = rows.iter().map(|r| r.pose.position * scale).sum::<DVec3>() / n;
        let z_sum: DVec3 = rows.iter().map(|r| r.pose.rotation_matrix().z_axis).sum();
        let up_sum: DVec3 = rows.iter().map(|r| r.pose.rotation_matrix().y_axis).sum();
        let z = z_sum.normalize();
        let x = up_sum.cross(z).normalize();
        let y = z.cross(x).normalize();
        WorldTransform { scale, avg_rotation: DMat3::from_cols(x, y, z), avg_center }
    }

    /// The identity (no scaling, no recentring).
    pub const IDENTITY: WorldTransform =
        WorldTransform { scale: 1.0, avg_rotation: DMat3::IDENTITY, avg_center: DVec3::ZERO };

    /// A pose of the file's world in the loader's world.
    pub fn apply(&self, pose: &Pose) -> Pose {
        let a_t = self.avg_rotation.transpose();
        Pose {
            rotation: (DQuat::from_mat3(&a_t) * pose.rotation).normalize(),
            position: a_t * (pose.position * self.scale - self.avg_center),
        }
    }

    /// A point of the file's world in the loader's world.
    pub fn apply_point(&self, p: DVec3) -> DVec3 {
        self.avg_rotation.transpose() * (p * self.scale - self.avg_center)
    }

    /// Undo [`WorldTransform::apply`]: a loader pose back in the file's world.
    pub fn undo(&self, pose: &Pose) -> Pose {
        Pose {
            rotation: (DQuat::from_mat3(&self.avg_rotation) * pose.rotation).normalize(),
            position: (self.avg_rotation * pose.position + self.avg_center) / self.scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::EulerRot;

    fn row(pose: Pose, near: f64, far: f64) -> LlffRow {
        LlffRow { pose, height: 32.0, width: 48.0, focal: 40.0, near, far }
    }

    #[test]
    fn recentred_poses_average_to_identity() {
        let rows: Vec<LlffRow> = (0..5)
            .map(|i| {
                let a = i as f64 * 0.1;
                let pose = Pose {
                    rotation: DQuat::from_euler(EulerRot::YXZ, 0.3 + a, -0.1 * a, 0.05),
                    position: DVec3::new(2.0 + a, 1.0 - a, 4.0 + 0.5 * a),
                };
                row(pose, 2.0 + a, 9.0)
            })
            .collect();
        let w = WorldTransform::from_rows(&rows);
        assert!((w.scale - 1.0 / (0.75 * 2.0)).abs() < 1e-15);
        let poses: Vec<Pose> = rows.iter().map(|r| w.apply(&r.pose)).collect();
        // mean centre at the origin; summed backward axis along +Z; summed up axis in the YZ plane
        let c = poses.iter().map(|p| p.position).sum::<DVec3>() / 5.0;
        assert!(c.length() < 1e-12, "{c}");
        let z: DVec3 = poses.iter().map(|p| p.rotation_matrix().z_axis).sum();
        assert!(z.normalize().abs_diff_eq(DVec3::Z, 1e-12), "{z}");
        let y: DVec3 = poses.iter().map(|p| p.rotation_matrix().y_axis).sum();
        assert!(y.x.abs() < 1e-12, "{y}");
        for (r, p) in rows.iter().zip(&poses) {
            let back = w.undo(p);
            assert!((back.position - r.pose.position).length() < 1e-12);
            assert!(back.rotation.dot(r.pose.rotation).abs() > 1.0 - 1e-12);
            assert!((w.apply_point(r.pose.position) - p.position).length() < 1e-12);
        }
    }

    #[test]
    fn row_columns_become_right_up_backward() {
        // identity camera in LLFF columns: down = -Y, right = +X, backward = +Z
        #[rustfmt::skip]
        let r = [
            0.0, 1.0, 0.0, 1.0, 32.0,
           -1.0, 0.0, 0.0, 2.0, 48.0,
            0.0, 0.0, 1.0, 3.0, 40.0,
            0.5, 10.0,
        ];
        let row = LlffRow::from_row_unchecked(&r);
        assert!(row.pose.rotation.abs_diff_eq(DQuat::IDENTITY, 1e-12), "{:?}", row.pose.rotation);
        assert_eq!(row.pose.position, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!((row.height, row.width, row.focal, row.near, row.far), (32.0, 48.0, 40.0, 0.5, 10.0));
    }
}
