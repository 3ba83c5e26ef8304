//! Depth seen from a camera: the z-depth (distance along the viewing axis) of the first surface
//! through pixel centres, and the LLFF near/far bounds taken from it.
//!
//! LLFF's `imgs2poses` takes `near, far` as the 0.1 and 99.9 percentiles of the depths of the
//! scene points a camera sees; we do the same with the rendered depths of a grid of pixel
//! centres (every `stride`-th pixel in x and y). Rays that leave the scene (environment) have
//! no depth and are ignored.

use glam::Vec2;
use rayon::prelude::*;

use crate::render::accel::Accel;
use crate::scene::Camera;

/// Lower percentile of the near bound (LLFF: 0.1 %).
pub const NEAR_PERCENTILE: f64 = 0.1;
/// Upper percentile of the far bound (LLFF: 99.9 %).
pub const FAR_PERCENTILE: f64 = 99.9;

/// Z-depths (m) through the centres of every `stride`-th pixel (row-major over the grid
/// `ceil(w / stride) x ceil(h / stride)`); `None` where the ray hits nothing.
pub fn depth_grid(accel: &Accel, cam: &Camera, width: u32, height: u32, stride: u32) -> Vec<Option<f32>> {
    let stride = stride.max(1);
    let origin = cam.origin();
    let forward = -cam.to_world.z_axis.truncate().normalize();
    let rows: Vec<u32> = (0..height).step_by(stride as usize).collect();
    rows.par_iter()
        .flat_map_iter(|&y| {
            (0..width).step_by(stride as usize).map(move |x| {
                let dir = cam.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), width, height);
                accel.intersect(origin, dir, 0.0, f32::INFINITY).map(|hit| hit.t * dir.dot(forward))
            })
        })
        .collect()
}

/// The `p`-th percentile (0..=100) of sorted values, linear between ranks (numpy's default).
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    let rank = p / 100.0 * (sorted.len() - 1) as f64;
    let (lo, hi) = (rank.floor() as usize, rank.ceil() as usize);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (rank - lo as f64)
}

/// LLFF near/far bounds (m) from the depths a camera sees; `None` when it sees no surface.
pub fn bounds(depths: &[Option<f32>]) -> Option<(f64, f64)> {
    let mut z: Vec<f64> = depths.iter().flatten().filter(|d| **d > 0.0).map(|&d| d as f64).collect();
    if z.is_empty() {
        return None;
    }
    z.sort_by(f64::total_cmp);
    let near = percentile(&z, NEAR_PERCENTILE);
    let mut far = percentile(&z, FAR_PERCENTILE);
    if far <= near {
        far = near * 1.01; // a single flat depth (a wall seen head-on): keep near < far
    }
    Some((near, far))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::TriangleMesh;
    use glam::Vec3;

    #[test]
    fn percentiles_match_numpy() {
        let v: Vec<f64> = (0..11).map(|i| i as f64).collect();
        assert_eq!(percentile(&v, 50.0), 5.0);
        assert!((percentile(&v, 0.1) - 0.01).abs() < 1e-12);
        assert!((percentile(&v, 99.9) - 9.99).abs() < 1e-12);
    }

    #[test]
    fn a_wall_head_on_has_its_distance_as_depth() {
        // a large quad at z = -3 seen from the origin looking down -Z: every z-depth is 3
        let positions = vec![
            Vec3::new(-50.0, -50.0, -3.0),
            Vec3::new(50.0, -50.0, -3.0),
            Vec3::new(50.0, 50.0, -3.0),
            Vec3::new(-50.0, 50.0, -3.0),
        ];
        let mesh = TriangleMesh {
            normals: vec![Vec3::Z; 4],
            uvs: vec![glam::Vec2::ZERO; 4],
            positions,
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material: vec![0, 0],
        };
        let accel = Accel::build(&mesh, Default::default());
        let cam = Camera::look_at(Vec3::ZERO, -Vec3::Z, Vec3::Y, 1.0);
        let d = depth_grid(&accel, &cam, 40, 30, 3);
        assert_eq!(d.len(), 14 * 10);
        assert!(d.iter().all(|z| (z.unwrap() - 3.0).abs() < 1e-4), "{d:?}");
        let (near, far) = bounds(&d).unwrap();
        assert!((near - 3.0).abs() < 1e-4 && far > near && far < 3.1);
        // looking away: nothing
        let away = Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y, 1.0);
        assert_eq!(bounds(&depth_grid(&accel, &away, 8, 8, 1)), None);
    }
}
