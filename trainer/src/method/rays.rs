//! Rays for the renderer: the NDC form of a world ray and its columns, the camera response
//! applied to a linear colour, and the NDC box every camera of a dataset sees.

use glam::DVec3;

use crate::data::dataset::Dataset;
use crate::data::rays::Ray;
use crate::engine::model::Aabb;
use crate::engine::real::Real;

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

/// The NDC box every camera of `data` sees (every view's pose and every 10th pose of the dense
/// trajectory; border pixels every 8 px; depths t = 0, 0.5, 0.9, 1 along each NDC ray, t = 1
/// being infinity), padded by 5% of its size per side; z spans the full NDC [-1, 1].
pub fn scene_bounds(data: &Dataset) -> Aabb {
    let (w, h) = (data.intrinsics.width, data.intrinsics.height);
    let mut border: Vec<(u32, u32)> = Vec::new();
    for i in (0..w).step_by(8).chain([w - 1]) {
        border.extend([(i, 0), (i, h - 1)]);
    }
    for j in (0..h).step_by(8).chain([h - 1]) {
        border.extend([(0, j), (w - 1, j)]);
    }
    let mut poses: Vec<_> = data.views.iter().map(|v| v.pose).collect();
    let times = data.trajectory.times_us();
    poses.extend(times.iter().step_by(10).filter_map(|&t| data.trajectory.pose_at(t)));
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for pose in &poses {
        for &(i, j) in &border {
            let r = data.intrinsics.ndc(&data.intrinsics.ray(pose, i, j), NDC_NEAR);
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
    }
    let pad = |a: usize| 0.05 * (hi[a] - lo[a]);
    Aabb { min: [lo[0] - pad(0), lo[1] - pad(1), -1.0], max: [hi[0] + pad(0), hi[1] + pad(1), 1.0] }
}
