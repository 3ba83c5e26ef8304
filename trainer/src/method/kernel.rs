//! The ray chains the blur models share, forward and backward: the image loss through the
//! blurry colour, a ray's integrated features, the NDC warp, the rigid warp and the DSK ray,
//! each finite-difference checked in the tests. The models themselves are in `blur_step`.

use glam::DVec3;

use crate::blur::se3::{self, Rigid};
use crate::data::rays::{ndc_ray_backward, Intrinsics, Ray};
use crate::engine::real::Real;
use crate::engine::renderer::{PassSamples, RayGrad};
use simulator::trajectory::Pose;

use super::rays::{response, NDC_NEAR};

/// A ray's features integrated with its render weights, `f = sum_s w_s feat_s`, for ray `r` of
/// a pass (`out`: the pass's feature width).
pub fn ray_features<R: Real>(ps: &PassSamples<R>, r: usize, out: &mut [R]) {
    out.fill(R::zero());
    for i in r * ps.per_ray..(r + 1) * ps.per_ray {
        let row = &ps.features[i * ps.stride..i * ps.stride + ps.width];
        for (x, &y) in out.iter_mut().zip(row) {
            *x += ps.weights[i] * y;
        }
    }
}

/// Backward of [`ray_features`] with the render weights held fixed: dL/d feat_s = w_s dL/df
/// for every sample of ray `r` (`out`: samples x width, what
/// [`Renderer::backward`]'s `d_features` takes for that ray).
pub fn ray_features_backward<R: Real>(ps: &PassSamples<R>, r: usize, d: &[R], out: &mut [R]) {
    for (s, row) in out.chunks_exact_mut(ps.width).enumerate() {
        let w = ps.weights[r * ps.per_ray + s];
        for (x, &y) in row.iter_mut().zip(d) {
            *x = w * y;
        }
    }
}

/// `ray` moved by the world-frame rigid motion `m`.
pub(crate) fn warp(m: &Rigid, ray: &Ray) -> Ray {
    Ray { origin: to_dvec(m.point(ray.origin.to_array())), direction: to_dvec(m.vector(ray.direction.to_array())) }
}

pub(super) fn to_dvec(v: [f64; 3]) -> DVec3 {
    DVec3::from_array(v)
}

/// The world ray of a DSK kernel point of pixel (`i`, `j`) for a camera at `pose`: through
/// the image point (i + 0.5, j + 0.5) + `offset` (pixels), from the camera-frame origin shift
/// `origin`, pivoting about the shifted image point at camera depth 1 (Deblur-NeRF's rays):
/// o = c + R t, d = R (d_cam(x + o) - t).
pub fn dsk_ray(k: &Intrinsics, pose: &Pose, i: u32, j: u32, offset: [f64; 2], origin: [f64; 3]) -> Ray {
    let t = DVec3::from_array(origin);
    let d = k.camera_direction_at(i as f64 + 0.5 + offset[0], j as f64 + 0.5 + offset[1]);
    Ray { origin: pose.position + pose.rotation * t, direction: pose.rotation * (d - t) }
}

/// Backward of [`dsk_ray`] from the ray's renderer gradients: (dL/d offset, dL/d origin shift).
pub fn dsk_ray_backward<R: Real>(k: &Intrinsics, pose: &Pose, world: &Ray, g: &RayGrad<R>) -> ([f64; 2], [f64; 3]) {
    let (d_o, d_d) = warped_ray_backward(k, world, g);
    let inv = pose.rotation.inverse();
    let (d_oc, d_dc) = (inv * d_o, inv * d_d);
    // d_cam(u, v) = ((u - W/2) / f, -(v - H/2) / f, -1).
    ([d_dc.x / k.focal, -d_dc.y / k.focal], (d_oc - d_dc).to_array())
}

/// The image loss of one pixel on one pass: the blurry colour `B = sum_k w_k C_k` (or the one
/// ray's colour when `weights` is `None`), `sum_c (g(B_c) - y_c)^2`. Writes dL/dC_k (times
/// `scale`) into `d_cols` and dL/dw_k (times `scale`) into `d_weights`; returns the unscaled loss.
pub fn blur_loss<R: Real>(
    cols: &[[R; 3]],
    weights: Option<&[R]>,
    target: [R; 3],
    inv_gamma: R,
    scale: R,
    d_cols: &mut [[R; 3]],
    d_weights: &mut [R],
) -> R {
    let mut blur = [R::zero(); 3];
    match weights {
        None => blur = cols[cols.len() - 1],
        Some(w) => {
            for (q, &wq) in w.iter().enumerate() {
                for c in 0..3 {
                    blur[c] += wq * cols[q][c];
                }
            }
        }
    }
    let mut loss = R::zero();
    let mut d_blur = [R::zero(); 3];
    for c in 0..3 {
        let (gc, dg) = response(blur[c], inv_gamma);
        let e = gc - target[c];
        loss += e * e;
        d_blur[c] = R::of(2.0) * e * dg * scale;
    }
    match weights {
        None => {
            let last = cols.len() - 1;
            d_cols[last] = d_blur;
        }
        Some(w) => {
            for (q, &wq) in w.iter().enumerate() {
                d_cols[q] = d_blur.map(|x| x * wq);
                d_weights[q] = (0..3).map(|c| d_blur[c] * cols[q][c]).sum();
            }
        }
    }
    loss
}

/// dL/d(world origin), dL/d(world direction) of a warped ray from its renderer gradients:
/// through the NDC warp and the view direction's normalisation.
pub fn warped_ray_backward<R: Real>(k: &Intrinsics, world: &Ray, g: &RayGrad<R>) -> (DVec3, DVec3) {
    let f = |a: [R; 3]| {
        DVec3::new(a[0].to_f64().unwrap_or(0.0), a[1].to_f64().unwrap_or(0.0), a[2].to_f64().unwrap_or(0.0))
    };
    let (d_o, mut d_d) = ndc_ray_backward(k.width, k.height, k.focal, NDC_NEAR, world, f(g.origin), f(g.dir));
    // v = d / |d|: dL/dd = (dL/dv - v (v . dL/dv)) / |d|.
    let n = world.direction.length();
    let v = world.direction / n;
    let gv = f(g.viewdir);
    d_d += (gv - v * v.dot(gv)) / n;
    (d_o, d_d)
}

/// dL/dR and dL/dt of the rigid motion that moved `original` to `warped`, from the warped
/// ray's renderer gradients ([`warped_ray_backward`], then the rigid warp's backward).
pub fn kernel_ray_backward<R: Real>(
    k: &Intrinsics,
    original: &Ray,
    warped: &Ray,
    g: &RayGrad<R>,
) -> ([[f64; 3]; 3], [f64; 3]) {
    let (d_o, d_d) = warped_ray_backward(k, warped, g);
    let (mut d_r, mut d_t) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    se3::warp_backward(
        original.origin.to_array(),
        original.direction.to_array(),
        d_o.to_array(),
        d_d.to_array(),
        &mut d_r,
        &mut d_t,
    );
    (d_r, d_t)
}
