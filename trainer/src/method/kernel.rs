//! The blur models' part of a step: each view's kernel rays for its batch pixels (rigid,
//! trajectory, DSK), PDRF's first-stage probe pass, and the ray chains' backward passes (the
//! image loss through the blurry colour, the NDC warp, the rigid warp, the DSK ray), each
//! finite-difference checked in the tests.

use std::ops::Range;

use glam::DVec3;

use crate::blur::dsk::DskWorkspace;
use crate::blur::rigid::KernelOut;
use crate::blur::se3::{self, Rigid};
use crate::data::dataset::{Dataset, View};
use crate::data::rays::{ndc_ray_backward, Intrinsics, Ray};
use crate::engine::model::Model;
use crate::engine::real::Real;
use crate::engine::renderer::{PassSamples, RayChunk, RayGrad};
use crate::engine::rng::Rng;
use simulator::trajectory::Pose;

use super::batch::*;
use super::rays::{prepare, response, unzip, PreparedRay, NDC_NEAR};
use super::*;

/// One view's blur model in this step.
pub(super) struct ViewKernel {
    /// The rigid kernel's output (twists and K + 1 weights).
    pub(super) rigid: Option<KernelOut<f32>>,
    /// Twists of the K rays (rigid kernel, learned trajectory).
    pub(super) twists: Vec<[f64; 6]>,
    /// Their world-frame motions.
    pub(super) motions: Vec<Rigid>,
    /// Poses of the K virtual cameras (fixed trajectory).
    pub(super) poses: Vec<Pose>,
    /// The DSK's kernels of the view's pixels, in slot order.
    pub(super) dsk: Option<DskWorkspace<f32>>,
    /// Rays per pixel.
    pub(super) k: usize,
}

impl ViewKernel {
    /// The model of view `v` whose batch pixels (slot order, pixel centres) are `pixels`
    /// (`features`: a progressive DSK's feature input, from PDRF's first stage).
    pub(super) fn new(
        blur: &Blur,
        params: &[f32],
        data: &Dataset,
        v: usize,
        pixels: &[[f32; 2]],
        noise: &mut Rng,
        features: Option<&[f32]>,
    ) -> ViewKernel {
        let mut vk = ViewKernel {
            rigid: None,
            twists: Vec::new(),
            motions: Vec::new(),
            poses: Vec::new(),
            dsk: None,
            k: blur.rays(),
        };
        match blur {
            Blur::Rigid(kernel) => {
                let out = kernel.forward(params, v);
                vk.twists = out.twists.iter().map(|t| t.map(|x| x as f64)).collect();
                vk.rigid = Some(out);
            }
            Blur::Trajectory(t) if t.config.learned => vk.twists = t.twists(params, v),
            Blur::Trajectory(t) => {
                let view = &data.views[v];
                vk.poses = (0..t.config.k)
                    .map(|k| {
                        let time = view.t_start_us + t.tau(k) * (view.t_end_us - view.t_start_us);
                        data.trajectory.pose_at(time).unwrap_or(view.pose)
                    })
                    .collect();
            }
            Blur::Dsk(dsk) => {
                let k = dsk.config.k;
                let jitter: Vec<[f32; 2]> =
                    (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
                let size = [data.intrinsics.width as f32, data.intrinsics.height as f32];
                let mut ws = DskWorkspace::default();
                dsk.forward(params, &mut ws, v, pixels, size, Some(&jitter), features);
                vk.dsk = Some(ws);
            }
        }
        vk.motions = vk.twists.iter().map(|&t| se3::exp(t)).collect();
        vk
    }

    /// Pushes the K rays of pixel (`i`, `j`) (world ray `ray`, DSK slot `slot`) with their
    /// weights; returns the origin ray's weight.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rays(
        &self,
        data: &Dataset,
        view: &View,
        ray: &Ray,
        i: u32,
        j: u32,
        slot: usize,
        batch: &mut Batch,
    ) -> f32 {
        match (&self.rigid, &self.dsk, self.poses.is_empty()) {
            (Some(out), _, _) => {
                for (m, &w) in self.motions.iter().zip(&out.weights) {
                    batch.push(data, warp(m, ray), w);
                }
                out.weights[self.motions.len()]
            }
            (None, Some(ws), _) => {
                let k = self.k;
                for q in slot * k..(slot + 1) * k {
                    let (o, t) = (ws.offsets[q].map(f64::from), ws.origins[q].map(f64::from));
                    batch.push(data, dsk_ray(&data.intrinsics, &view.pose, i, j, o, t), ws.weights[q]);
                }
                0.0
            }
            (None, None, false) => {
                let w = 1.0 / self.poses.len() as f32;
                for pose in &self.poses {
                    batch.push(data, data.intrinsics.ray(pose, i, j), w);
                }
                0.0
            }
            (None, None, true) => {
                let w = 1.0 / self.motions.len() as f32;
                for m in &self.motions {
                    batch.push(data, warp(m, ray), w);
                }
                0.0
            }
        }
    }
}

/// PDRF's first stage for one view's batch pixels (slot order).
#[derive(Debug, Default)]
pub(super) struct Probe {
    /// The kernel without features.
    pub(super) ws: DskWorkspace<f32>,
    /// Each point's coarse colour.
    pub(super) cols: Vec<[f32; 3]>,
    /// Each point's coarse features integrated along its ray (K x features per pixel).
    pub(super) feats: Vec<f32>,
    /// dL/d those features (from the second stage's kernel).
    pub(super) d_feats: Vec<f32>,
    /// dL/d each pixel's first-stage blurry colour sum_k w'_k c'_k (from the coarse loss).
    pub(super) d_blur: Vec<[f32; 3]>,
}

/// The rendering of PDRF's first-stage rays, forward or backward.
pub(super) struct ProbePass<'a> {
    pub(super) model: &'a Model,
    pub(super) data: &'a Dataset,
    /// (view, slot) of every probed pixel, in order.
    pub(super) pixels: &'a [(usize, usize)],
    pub(super) view_pixels: &'a [Vec<(u32, u32)>],
    pub(super) k: usize,
    pub(super) chunk_rays: usize,
    pub(super) seed: u64,
}

impl ProbePass<'_> {
    /// Renders the K first-stage rays (kernels in `probes`) of the pixels `range` with the
    /// coarse pass only, in
    /// chunks of at most `chunk_rays` rays (at least one pixel); ray r of the stage draws from
    /// `Rng::new(seed, r)`, so the backward replays the forward's samples. Forward: returns per
    /// pixel K colours then K x features integrated features. Backward (`back`): accumulates
    /// the field's gradients into `g` from the probes' dL/d blurry colour and dL/d features
    /// (render weights held fixed) and returns per point dL/d offset (2), origin shift (3).
    pub(super) fn run(
        &self,
        p: &[f32],
        probes: &[Option<Probe>],
        range: Range<usize>,
        g: &mut [f32],
        wk: &mut Worker,
        back: bool,
    ) -> Vec<f32> {
        let (k, data) = (self.k, self.data);
        let per = (self.chunk_rays / k).max(1);
        let mut out = Vec::new();
        let mut p0 = range.start;
        while p0 < range.end {
            let p1 = (p0 + per).min(range.end);
            let mut world = Vec::with_capacity((p1 - p0) * k);
            for &(v, s) in &self.pixels[p0..p1] {
                let pr = probes[v].as_ref().expect("probed view");
                let (i, j) = self.view_pixels[v][s];
                for q in s * k..(s + 1) * k {
                    let (o, t) = (pr.ws.offsets[q].map(f64::from), pr.ws.origins[q].map(f64::from));
                    world.push(dsk_ray(&data.intrinsics, &data.views[v].pose, i, j, o, t));
                }
            }
            let prepared: Vec<PreparedRay> = world.iter().map(|r| prepare(data, r)).collect();
            let (o, d, vd) = unzip(&prepared);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (p0 * k..p1 * k).map(|r| Rng::new(self.seed, r as u64)).collect();
            wk.renderer.forward_coarse(self.model, p, &chunk, Some(&mut rngs));
            let n = world.len();
            let ps = wk.renderer.last_pass(self.model);
            let (spr, nf) = (ps.per_ray, ps.width);
            if !back {
                for (b, _) in self.pixels[p0..p1].iter().enumerate() {
                    for r in b * k..(b + 1) * k {
                        out.extend_from_slice(&wk.renderer.coarse()[r]);
                    }
                    for r in b * k..(b + 1) * k {
                        let at = out.len();
                        out.resize(at + nf, 0.0);
                        ray_features(&ps, r, &mut out[at..]);
                    }
                }
            } else {
                wk.dc.clear();
                wk.dc.resize(n, [0.0; 3]);
                wk.df.clear();
                wk.df.resize(n, [0.0; 3]);
                wk.dfeat.clear();
                wk.dfeat.resize(n * spr * nf, 0.0);
                for (b, &(v, s)) in self.pixels[p0..p1].iter().enumerate() {
                    let pr = probes[v].as_ref().expect("probed view");
                    for q in 0..k {
                        let (r, pq) = (b * k + q, s * k + q);
                        wk.dc[r] = pr.d_blur[s].map(|x| x * pr.ws.weights[pq]);
                        let df = &pr.d_feats[pq * nf..(pq + 1) * nf];
                        ray_features_backward(&ps, r, df, &mut wk.dfeat[r * spr * nf..(r + 1) * spr * nf]);
                    }
                }
                wk.d_rays.resize(n, RayGrad::zero());
                wk.renderer.backward(
                    self.model,
                    p,
                    g,
                    &chunk,
                    &wk.dc,
                    &wk.df,
                    Some(&mut wk.d_rays[..n]),
                    Some(&wk.dfeat),
                );
                for (b, &(v, _)) in self.pixels[p0..p1].iter().enumerate() {
                    let pose = &data.views[v].pose;
                    for (ray, g) in world[b * k..(b + 1) * k].iter().zip(&wk.d_rays[b * k..(b + 1) * k]) {
                        let (d_off, d_org) = dsk_ray_backward(&data.intrinsics, pose, ray, g);
                        out.extend(d_off.iter().chain(&d_org).map(|&x| x as f32));
                    }
                }
            }
            p0 = p1;
        }
        out
    }
}

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
pub(super) fn warp(m: &Rigid, ray: &Ray) -> Ray {
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
