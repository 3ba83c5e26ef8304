//! Blur statistics: how far the image content moves during each blurry view's exposure.
//!
//! For a blurry view with window `[t_s, t_e]` around its mid-time `t_m`, every `stride`-th pixel
//! centre `p` is traced from the camera at `t_m`: a hit gives the world point `X`, a miss the
//! direction `d` (a point at infinity, which moves with the camera's rotation only). `X` is
//! projected into the cameras at `t_s` and `t_e`; the pixel's displacement is the distance between
//! the two projections, `|pi_e(X) - pi_s(X)|` in pixels: the length of its blur streak for
//! near-linear motion (the definition of the paper's mean / max pixel displacement). Points that
//! fall behind either camera are skipped.
//!
//! Per view: the mean and the maximum over pixels, and the mean displacement vector (its
//! direction is the view's dominant blur direction). Per scene: the mean of the views' means, the
//! maximum of their maxima, and the *direction consistency* `R = |sum_i u_i| / n` of the views'
//! unit blur axes `u_i` (axes, not directions: a streak has no sign, so the angles are doubled
//! before averaging): 1 when every view blurs along the same axis, about 0 when the axes are
//! spread evenly. Image-only deblurring finds consistent axes hardest.

use glam::{DVec3, Vec2};
use rayon::prelude::*;

use super::plan::Plan;
use super::DatasetError;
use crate::exposure::Exposure;
use crate::render::accel::Accel;
use crate::trajectory::Pose;

/// Blur of one view (pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewBlur {
    /// View index.
    pub view: usize,
    /// Mean displacement over the sampled pixels (px).
    pub mean: f64,
    /// Largest displacement (px).
    pub max: f64,
    /// Mean displacement vector (px, image x right, y down).
    pub mean_vector: [f64; 2],
}

/// Blur over all blurry views.
#[derive(Clone, Debug, PartialEq)]
pub struct BlurStats {
    /// One entry per blurry view.
    pub views: Vec<ViewBlur>,
    /// Mean of the views' means (px).
    pub mean: f64,
    /// Maximum of the views' maxima (px).
    pub max: f64,
    /// Consistency of the views' blur axes in [0, 1] (1 = all the same axis).
    pub direction_consistency: f64,
}

/// Pixel coordinates of world point `x` (homogeneous weight `w`: 1 = point, 0 = direction) seen
/// from `pose`, or `None` behind the camera. Inverse of [`crate::scene::Camera::direction`].
pub fn project(pose: &Pose, x: DVec3, w: f64, tan_half: f64, width: f64, height: f64) -> Option<[f64; 2]> {
    let v = pose.rotation.inverse() * (x - w * pose.position);
    if v.z >= -1e-9 {
        return None;
    }
    let aspect = width / height;
    let (nx, ny) = (v.x / -v.z / (tan_half * aspect), v.y / -v.z / tan_half);
    Some([(nx + 1.0) * 0.5 * width, (1.0 - ny) * 0.5 * height])
}

/// Displacement vectors (end minus start projection, px) of the pixels of one view.
pub fn view_displacements(
    plan: &Plan,
    accel: &Accel,
    mid: &Pose,
    start: &Pose,
    end: &Pose,
    stride: u32,
) -> Vec<[f64; 2]> {
    let (w, h) = (plan.config.width, plan.config.height);
    let cam = mid.camera(plan.yfov as f32);
    let tan_half = (0.5 * plan.yfov).tan();
    let rows: Vec<u32> = (0..h).step_by(stride.max(1) as usize).collect();
    rows.par_iter()
        .flat_map_iter(|&y| {
            let cam = &cam;
            (0..w).step_by(stride.max(1) as usize).filter_map(move |x| {
                let dir = cam.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), w, h);
                let (point, weight) = match accel.intersect(cam.origin(), dir, 0.0, f32::INFINITY) {
                    Some(hit) => (mid.position + hit.t as f64 * dir.as_dvec3(), 1.0),
                    None => (dir.as_dvec3(), 0.0),
                };
                let a = project(start, point, weight, tan_half, w as f64, h as f64)?;
                let b = project(end, point, weight, tan_half, w as f64, h as f64)?;
                Some([b[0] - a[0], b[1] - a[1]])
            })
        })
        .collect()
}

/// Blur statistics of every blurry view of `plan`, tracing every `stride`-th pixel.
pub fn blur_stats(plan: &Plan, accel: &Accel, stride: u32) -> Result<BlurStats, DatasetError> {
    let mut views = Vec::new();
    for v in &plan.views {
        let Exposure::Box { tau_ns } = v.exposure else { continue };
        let pose = |t: i64| plan.trajectory.pose_at(t).map_err(|e| DatasetError::stage(format!("view {}", v.id), e));
        // the window's ends, rounded inwards to whole nanoseconds
        let (mid, start, end) = (pose(v.mid_ns)?, pose(v.mid_ns - tau_ns / 2)?, pose(v.mid_ns + tau_ns / 2)?);
        let d = view_displacements(plan, accel, &mid, &start, &end, stride);
        if d.is_empty() {
            continue;
        }
        let n = d.len() as f64;
        let len = |v: &[f64; 2]| v[0].hypot(v[1]);
        let mean = d.iter().map(len).sum::<f64>() / n;
        let max = d.iter().map(len).fold(0.0, f64::max);
        let mean_vector = [d.iter().map(|v| v[0]).sum::<f64>() / n, d.iter().map(|v| v[1]).sum::<f64>() / n];
        views.push(ViewBlur { view: v.id, mean, max, mean_vector });
    }
    let k = views.len().max(1) as f64;
    let mean = views.iter().map(|v| v.mean).sum::<f64>() / k;
    let max = views.iter().map(|v| v.max).fold(0.0, f64::max);
    // axial mean: double the angles so that opposite streak directions count as the same axis
    let (c, s) = views.iter().fold((0.0, 0.0), |(c, s), v| {
        let a = 2.0 * v.mean_vector[1].atan2(v.mean_vector[0]);
        (c + a.cos(), s + a.sin())
    });
    let direction_consistency = c.hypot(s) / k;
    Ok(BlurStats { views, mean, max, direction_consistency })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, Vec3};

    #[test]
    fn projection_inverts_the_camera_ray() {
        let pose = Pose {
            rotation: DQuat::from_rotation_y(0.3) * DQuat::from_rotation_x(-0.2),
            position: DVec3::new(1.0, 2.0, 3.0),
        };
        let yfov = 0.8f32;
        let cam = pose.camera(yfov);
        let (w, h) = (64u32, 48u32);
        for (px, py) in [(0.5f32, 0.5f32), (31.5, 20.5), (63.5, 47.5)] {
            let dir = cam.direction(Vec2::new(px, py), w, h).as_dvec3();
            let x = pose.position + 7.0 * dir;
            let p = project(&pose, x, 1.0, (0.5 * yfov as f64).tan(), w as f64, h as f64).unwrap();
            assert!((p[0] - px as f64).abs() < 1e-3 && (p[1] - py as f64).abs() < 1e-3, "{p:?} vs {px},{py}");
            // a direction projects to the same pixel
            let q = project(&pose, dir, 0.0, (0.5 * yfov as f64).tan(), w as f64, h as f64).unwrap();
            assert!((q[0] - px as f64).abs() < 1e-3 && (q[1] - py as f64).abs() < 1e-3);
        }
        // behind the camera
        let behind = pose.position - 3.0 * (pose.rotation * -DVec3::Z);
        assert_eq!(project(&pose, behind, 1.0, 0.4, 64.0, 48.0), None);
        let _ = Vec3::ZERO;
    }

    #[test]
    fn sideways_translation_moves_a_wall_by_f_times_shift_over_depth() {
        // camera translating 0.1 m along +X in front of a wall 5 m away: every pixel moves
        // f * 0.1 / 5 px (f = 0.5 h / tan(yfov / 2))
        let (w, h, yfov) = (60.0, 40.0, 0.7f64);
        let f = 0.5 * h / (0.5 * yfov).tan();
        let rot = DQuat::IDENTITY;
        let start = Pose { rotation: rot, position: DVec3::new(-0.05, 0.0, 0.0) };
        let end = Pose { rotation: rot, position: DVec3::new(0.05, 0.0, 0.0) };
        let x = DVec3::new(0.3, 0.2, -5.0);
        let a = project(&start, x, 1.0, (0.5 * yfov).tan(), w, h).unwrap();
        let b = project(&end, x, 1.0, (0.5 * yfov).tan(), w, h).unwrap();
        assert!(((a[0] - b[0]).abs() - f * 0.1 / 5.0).abs() < 1e-9);
        assert!((a[1] - b[1]).abs() < 1e-12);
    }
}
