//! LLFF pose rows (`poses_bounds.npy`, `all_poses_bounds.npy`): conversion from and to [`Pose`].
//!
//! A row is 17 float64: the 3x5 matrix `[c0 c1 c2 | t | hwf]` flattened row-major, then near and
//! far. `c0, c1, c2` are the camera's **down**, **right** and **backward** axes in world space
//! (camera-to-world), `t` the camera centre and `hwf = (height, width, focal)` in pixels, with
//! `f = 0.5 h / tan(yfov / 2)`. Our camera's columns are (right, up, backward) = (+X, +Y, +Z), so
//! `[c0 c1 c2] = [-Y, X, Z]`; the reference loader's `[c1, -c0, c2]` gives back `[X, Y, Z]`.
//! Reading a row checks that the rotation is a pure rotation (orthonormal and det +1 within
//! 1e-6), as the reference loader asserts.

use glam::{DMat3, DQuat, DVec3};

use super::interpolate::Pose;

/// Tolerance of the pure-rotation check (max abs deviation of `R^T R` from `I`, and of det from 1).
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// An error in an LLFF row or in the values used to build one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LlffError {
    /// A value is out of range (non-finite pose, non-positive size or focal, bad bounds).
    #[error("LLFF row: {field}: {message}")]
    Invalid {
        /// Which value, e.g. `near`.
        field: &'static str,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// The 3x3 part is not a pure rotation.
    #[error(
        "LLFF row: rotation is not pure (max |R^T R - I| = {orthonormality_error:e}, det = {det}); \
         the columns must be orthonormal unit down/right/backward axes with det +1 (tolerance {ROTATION_TOLERANCE:e})"
    )]
    NotRotation {
        /// Largest absolute entry of `R^T R - I`.
        orthonormality_error: f64,
        /// Determinant of the 3x3 part.
        det: f64,
    },
}

/// An LLFF camera: pose, intrinsics and depth bounds (one row of `poses_bounds.npy`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LlffCamera {
    /// Camera pose (our convention: looks down -Z, +Y up).
    pub pose: Pose,
    /// Image height (pixels).
    pub height: f64,
    /// Image width (pixels).
    pub width: f64,
    /// Focal length (pixels), square pixels.
    pub focal: f64,
    /// Nearest scene depth seen by this camera (scene units, m), > 0.
    pub near: f64,
    /// Farthest scene depth seen by this camera (m), > near.
    pub far: f64,
}

/// Focal length in pixels for an image `height` pixels tall with full vertical FOV `yfov` (rad):
/// `f = 0.5 h / tan(yfov / 2)`.
pub fn focal_from_yfov(height: f64, yfov: f64) -> f64 {
    0.5 * height / (0.5 * yfov).tan()
}

impl LlffCamera {
    /// An LLFF camera for `pose`, a `width` x `height` image with full vertical FOV `yfov` (rad)
    /// and depth bounds `near` < `far` (m). Errors on non-finite or out-of-range values.
    pub fn new(pose: Pose, width: u32, height: u32, yfov: f64, near: f64, far: f64) -> Result<LlffCamera, LlffError> {
        if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
            return Err(LlffError::Invalid { field: "yfov", message: format!("{yfov} rad is not in (0, pi)") });
        }
        let cam = LlffCamera {
            pose,
            height: height as f64,
            width: width as f64,
            focal: focal_from_yfov(height as f64, yfov),
            near,
            far,
        };
        cam.validate()?;
        Ok(cam)
    }

    /// Full vertical field of view (rad): `2 atan(0.5 h / f)`.
    pub fn yfov(&self) -> f64 {
        2.0 * (0.5 * self.height / self.focal).atan()
    }

    fn validate(&self) -> Result<(), LlffError> {
        if !self.pose.position.is_finite() || !self.pose.rotation.is_finite() {
            return Err(LlffError::Invalid { field: "t", message: "pose has a non-finite value".into() });
        }
        for (field, v) in [("height", self.height), ("width", self.width), ("focal", self.focal)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(LlffError::Invalid { field, message: format!("{v} is not a positive number of pixels") });
            }
        }
        if !(self.near > 0.0 && self.near.is_finite()) {
            return Err(LlffError::Invalid {
                field: "near",
                message: format!("{} is not a positive depth; use the nearest rendered depth", self.near),
            });
        }
        if !(self.far > self.near && self.far.is_finite()) {
            return Err(LlffError::Invalid {
                field: "far",
                message: format!("{} is not a finite depth beyond near = {}", self.far, self.near),
            });
        }
        Ok(())
    }

    /// The 17-float64 row: `[c0 c1 c2 t hwf]` (3x5, row-major) then near, far.
    pub fn to_row(&self) -> [f64; 17] {
        let r = self.pose.rotation_matrix();
        // LLFF columns: down, right, backward
        let cols = [-r.y_axis, r.x_axis, r.z_axis, self.pose.position, DVec3::new(self.height, self.width, self.focal)];
        let mut row = [0.0; 17];
        for i in 0..3 {
            for (j, c) in cols.iter().enumerate() {
                row[5 * i + j] = c[i];
            }
        }
        row[15] = self.near;
        row[16] = self.far;
        row
    }

    /// Read a row (inverse of [`LlffCamera::to_row`]); rejects rotations that are not pure.
    pub fn from_row(row: &[f64; 17]) -> Result<LlffCamera, LlffError> {
        if let Some(i) = row.iter().position(|v| !v.is_finite()) {
            return Err(LlffError::Invalid { field: "row", message: format!("entry {i} is {}", row[i]) });
        }
        check_pure_rotation(&Self::rotation_of(row))?;
        let cam = Self::from_row_unchecked(row);
        cam.validate()?;
        Ok(cam)
    }

    /// The rotation columns of a row as the reference loader reads them, `[c1, -c0, c2]`:
    /// (right, up, backward) = our (+X, +Y, +Z).
    fn rotation_of(row: &[f64; 17]) -> DMat3 {
        let col = |j: usize| DVec3::new(row[j], row[5 + j], row[10 + j]);
        DMat3::from_cols(col(1), -col(0), col(2))
    }

    /// Read a row without any check (for readers that checked the file already, with their own
    /// tolerance); the rotation is the nearest unit quaternion of the 3x3 part.
    pub fn from_row_unchecked(row: &[f64; 17]) -> LlffCamera {
        LlffCamera {
            pose: Pose {
                rotation: DQuat::from_mat3(&Self::rotation_of(row)).normalize(),
                position: DVec3::new(row[3], row[8], row[13]),
            },
            height: row[4],
            width: row[9],
            focal: row[14],
            near: row[15],
            far: row[16],
        }
    }
}

/// Check that `m` is orthonormal with det +1 within [`ROTATION_TOLERANCE`].
pub fn check_pure_rotation(m: &DMat3) -> Result<(), LlffError> {
    let e = m.transpose() * *m - DMat3::IDENTITY;
    let orthonormality_error = e.to_cols_array().iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let det = m.determinant();
    if orthonormality_error > ROTATION_TOLERANCE || (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(LlffError::NotRotation { orthonormality_error, det });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::EulerRot;

    fn pose() -> Pose {
        Pose { rotation: DQuat::from_euler(EulerRot::YXZ, 2.1, -0.4, 0.3), position: DVec3::new(-1.5, 2.25, 7.0) }
    }

    #[test]
    fn row_layout_matches_dataset_format() {
        // identity: down = -Y, right = +X, backward = +Z
        let p = Pose { rotation: DQuat::IDENTITY, position: DVec3::new(1.0, 2.0, 3.0) };
        let yfov = 2.0 * (0.5f64).atan(); // tan(yfov/2) = 0.5 -> f = h
        let row = LlffCamera::new(p, 600, 400, yfov, 0.5, 10.0).unwrap().to_row();
        #[rustfmt::skip]
        let want = [
            0.0, 1.0, 0.0, 1.0, 400.0,
           -1.0, 0.0, 0.0, 2.0, 600.0,
            0.0, 0.0, 1.0, 3.0, 400.0,
            0.5, 10.0,
        ];
        for (a, b) in row.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{row:?}");
        }
    }

    #[test]
    fn llff_round_trip_is_exact_to_1e_12() {
        let cam = LlffCamera::new(pose(), 600, 400, 0.6, 0.8, 12.0).unwrap();
        let back = LlffCamera::from_row(&cam.to_row()).unwrap();
        let q = back.pose.rotation;
        let q = if q.dot(cam.pose.rotation) < 0.0 { -q } else { q };
        assert!((q - cam.pose.rotation).length() < 1e-12, "{q:?} vs {:?}", cam.pose.rotation);
        assert!((back.pose.rotation_matrix() - cam.pose.rotation_matrix()).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!((back.pose.position - cam.pose.position).length() < 1e-12);
        assert_eq!((back.height, back.width, back.near, back.far), (400.0, 600.0, 0.8, 12.0));
        assert!((back.yfov() - 0.6).abs() < 1e-12);
    }

    #[test]
    fn loader_transform_gives_camera_axes() {
        let p = pose();
        let row = LlffCamera::new(p, 600, 400, 0.6, 0.8, 12.0).unwrap().to_row();
        let col = |j: usize| DVec3::new(row[j], row[5 + j], row[10 + j]);
        // the reference loader: [c1, -c0, c2] -> (right, up, backward)
        let (right, up, backward) = (col(1), -col(0), col(2));
        let cam = p.camera(0.6);
        for (a, b) in [(right, cam.to_world.x_axis), (up, cam.to_world.y_axis), (backward, cam.to_world.z_axis)] {
            assert!((a.as_vec3() - b.truncate()).length() < 1e-6, "{a} vs {b}");
        }
        assert!((col(3).as_vec3() - cam.origin()).length() < 1e-6);
    }

    #[test]
    fn non_rotation_rows_are_rejected() {
        let good = LlffCamera::new(pose(), 600, 400, 0.6, 0.8, 12.0).unwrap().to_row();
        // scaled column: not orthonormal
        let mut row = good;
        for i in 0..3 {
            row[5 * i] *= 1.01;
        }
        assert!(matches!(LlffCamera::from_row(&row), Err(LlffError::NotRotation { .. })));
        // sheared
        let mut row = good;
        row[1] += 1e-3;
        assert!(matches!(LlffCamera::from_row(&row), Err(LlffError::NotRotation { .. })));
        // reflection: orthonormal but det -1 (swap down and right)
        let mut row = good;
        for i in 0..3 {
            row.swap(5 * i, 5 * i + 1);
        }
        match LlffCamera::from_row(&row) {
            Err(LlffError::NotRotation { det, .. }) => assert!((det + 1.0).abs() < 1e-9),
            other => panic!("reflection accepted: {other:?}"),
        }
        // bad bounds
        let mut row = good;
        row[16] = row[15];
        assert!(matches!(LlffCamera::from_row(&row), Err(LlffError::Invalid { field: "far", .. })));
        let mut row = good;
        row[15] = 0.0;
        assert!(matches!(LlffCamera::from_row(&row), Err(LlffError::Invalid { field: "near", .. })));
    }
}
