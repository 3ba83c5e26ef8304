//! Rays for the renderer: the NDC form of a world ray and its columns, the camera response
//! applied to a linear colour, the NDC box every camera of a dataset sees, and the samples per
//! ray its rays need.

use glam::DVec3;

use crate::data::dataset::Dataset;
use crate::data::rays::{Intrinsics, Ray};
use crate::engine::model::{Aabb, ModelConfig};
use crate::engine::real::Real;
use simulator::trajectory::Pose;

/// Near plane of the NDC warp (the reference's 1, in the loader's scaled world).
pub const NDC_NEAR: f64 = 1.0;
/// Lower clamp of the linear colour before the camera response (keeps g' finite).
pub const RESPONSE_FLOOR: f32 = 1e-4;

/// g(c) and g'(c) for the response exponent `inv_gamma` = 1 / gamma.
#[inline]
pub fn response<R: Real>(c: R, inv_gamma: R) -> (R, R) {
    let floor = R::of(RESPONSE_FLOOR as f64);
    if c <= floor {
        (floor.powf(inv_gamma), R::zero())
    } else {
        let y = c.powf(inv_gamma);
        (y, inv_gamma * y / c)
    }
}

/// A camera ray prepared for the renderer: NDC origin and direction, world view direction.
#[derive(Clone, Copy, Debug, Default)]
pub struct PreparedRay {
    /// NDC origin.
    pub origin: [f32; 3],
    /// NDC direction.
    pub dir: [f32; 3],
    /// Unit world direction.
    pub viewdir: [f32; 3],
}

/// The NDC form of a world ray (module [`crate::data::rays`]).
pub fn prepare(data: &Dataset, ray: &Ray) -> PreparedRay {
    let ndc = data.intrinsics.ndc(ray, NDC_NEAR);
    let f = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
    PreparedRay { origin: f(ndc.origin), dir: f(ndc.direction), viewdir: f(ray.direction.normalize()) }
}

/// Origins, directions and view directions, as [`unzip`] returns them.
pub type RayColumns = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 3]>);

/// Splits prepared rays into the renderer's three slices.
pub fn unzip(rays: &[PreparedRay]) -> RayColumns {
    (
        rays.iter().map(|r| r.origin).collect(),
        rays.iter().map(|r| r.dir).collect(),
        rays.iter().map(|r| r.viewdir).collect(),
    )
}

/// The poses whose views bound what the cameras of `data` see: every view's and every 10th
/// of the dense trajectory.
fn camera_poses(data: &Dataset) -> Vec<Pose> {
    let mut poses: Vec<_> = data.views.iter().map(|v| v.pose).collect();
    let times = data.trajectory.times_us();
    poses.extend(times.iter().step_by(10).filter_map(|&t| data.trajectory.pose_at(t)));
    poses
}

/// The NDC rays of the border pixels (every 8 px) of cameras `k` at `poses`.
pub fn border_rays(k: &Intrinsics, poses: &[Pose]) -> Vec<Ray> {
    let (w, h) = (k.width, k.height);
    let mut border: Vec<(u32, u32)> = Vec::new();
    for i in (0..w).step_by(8).chain([w - 1]) {
        border.extend([(i, 0), (i, h - 1)]);
    }
    for j in (0..h).step_by(8).chain([h - 1]) {
        border.extend([(0, j), (w - 1, j)]);
    }
    let ray = |pose, (i, j)| k.ndc(&k.ray(pose, i, j), NDC_NEAR);
    poses.iter().flat_map(|pose| border.iter().map(move |&p| ray(pose, p))).collect()
}

/// The NDC box every camera of `data` sees (the [`border_rays`] of every view's pose and every
/// 10th pose of the dense trajectory at depths t = 0, 0.5, 0.9, 1 along each NDC ray, t = 1
/// being infinity), padded by 5% of its size per side; z spans the full NDC [-1, 1].
pub fn scene_bounds(data: &Dataset) -> Aabb {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for r in border_rays(&data.intrinsics, &camera_poses(data)) {
        for t in [0.0, 0.5, 0.9, 1.0] {
            let p = r.origin + t * r.direction;
            for (a, v) in [p.x, p.y].into_iter().enumerate() {
                if v.is_finite() {
                    lo[a] = lo[a].min(v);
                    hi[a] = hi[a].max(v);
                }
            }
        }
    }
    let pad = |a: usize| 0.05 * (hi[a] - lo[a]);
    Aabb { min: [lo[0] - pad(0), lo[1] - pad(1), -1.0], max: [hi[0] + pad(0), hi[1] + pad(1), 1.0] }
}

/// Stratified and importance samples per ray for `model` over the box `bounds` on `data`:
/// [`samples_for`] its cameras' [`border_rays`] (as [`scene_bounds`] takes them).
pub fn sample_counts(data: &Dataset, model: &ModelConfig, bounds: &Aabb) -> (usize, usize) {
    match model.coarse_step {
        None => (model.n_coarse, model.n_fine),
        Some(_) => samples_for(&border_rays(&data.intrinsics, &camera_poses(data)), model, bounds),
    }
}

/// Stratified and importance samples per ray for `model` over the box `bounds`: as
/// configured, or, with `model.coarse_step`, raised so that the longest of `rays` (NDC rays:
/// the path from the near plane to infinity, counted in voxels of the coarse volume) gets a
/// stratified sample at least every `coarse_step` voxels, with the importance samples raised
/// in proportion. Why: a camera that sweeps far sideways shears its rays across the shared NDC
/// box, and at fixed counts their samples fall many voxels apart.
pub fn samples_for(rays: &[Ray], model: &ModelConfig, bounds: &Aabb) -> (usize, usize) {
    let Some(step) = model.coarse_step else { return (model.n_coarse, model.n_fine) };
    let g = bounds.grid(model.coarse_volume.res);
    let voxel: [f64; 3] = std::array::from_fn(|a| (bounds.max[a] - bounds.min[a]) / (g[a] - 1) as f64);
    let voxels = |d: DVec3| ((d.x / voxel[0]).powi(2) + (d.y / voxel[1]).powi(2) + (d.z / voxel[2]).powi(2)).sqrt();
    let longest = rays.iter().map(|r| voxels(r.direction)).filter(|v| v.is_finite()).fold(0.0, f64::max);
    let n = (longest / step).ceil() as usize;
    if n <= model.n_coarse {
        return (model.n_coarse, model.n_fine);
    }
    (n, (model.n_fine as f64 * n as f64 / model.n_coarse as f64).round() as usize)
}
