//! Deblur-NeRF's deformable sparse kernel in a step: per view, the kernel MLP gives each batch
//! pixel K points (an image offset, a camera-frame origin shift, a weight); a pixel's rays pass
//! through them. PDRF (`progressive`) first renders a kernel without features through the
//! coarse pass (the *first stage*): its rays' integrated features feed the second kernel, and
//! the coarse loss averages both stages' blurry colours.
//!
//! A pixel's record: K x (d offset 2, d origin 3, d weight 1), then (PDRF) dL/d the first
//! stage's blurry colour (3). At the end of the step the records go back through the kernel MLP
//! (with the alignment loss while it is on), then PDRF's first stage: its rays replayed
//! backward, then its kernel.

use std::ops::Range;

use crate::blur::dsk::{Dsk, DskWorkspace};
use crate::blur::MAX_RAYS;
use crate::data::dataset::{Dataset, View};
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::{RayChunk, RayGrad};
use crate::engine::rng::Rng;

use super::super::batch::{Batch, Kind, Worker};
use super::super::kernel::{blur_loss, dsk_ray, dsk_ray_backward, ray_features, ray_features_backward};
use super::super::pixel_loss::PixelRays;
use super::super::rays::{prepare, unzip, PreparedRay};
use super::{kernel_noise, BackwardInput, Records, StepBlur, StepContext};

/// A view's kernels in a step.
#[derive(Debug, Default)]
pub(in crate::method) struct DskView {
    /// The kernels of the view's batch pixels, in slot order.
    ws: DskWorkspace<f32>,
    /// PDRF's first stage (progressive kernels only).
    probe: Option<Probe>,
}

/// PDRF's first stage for one view's batch pixels (slot order).
#[derive(Debug, Default)]
struct Probe {
    /// The kernel without features.
    ws: DskWorkspace<f32>,
    /// Each point's coarse colour.
    cols: Vec<[f32; 3]>,
    /// Each point's coarse features integrated along its ray (K x features per pixel).
    feats: Vec<f32>,
    /// dL/d those features (from the second stage's kernel).
    d_feats: Vec<f32>,
    /// dL/d each pixel's first-stage blurry colour sum_k w'_k c'_k (from the coarse loss).
    d_blur: Vec<[f32; 3]>,
}

impl StepBlur for Dsk {
    type View = DskView;

    fn k(&self) -> usize {
        self.config.k
    }

    fn learns_rays(&self) -> bool {
        true
    }

    fn pixel_record(&self) -> usize {
        6 * self.config.k + if self.config.progressive { 3 } else { 0 }
    }

    fn views(&self, ctx: &StepContext, workers: &mut [Worker], pool: &mut GradBuffers) -> Vec<Option<DskView>> {
        let k = self.config.k;
        let size = [ctx.data.intrinsics.width as f32, ctx.data.intrinsics.height as f32];
        let mut views: Vec<Option<DskView>> = ctx.view_pixels.iter().map(|_| None).collect();
        let used = |v: &usize| !ctx.view_pixels[*v].is_empty();
        if self.config.progressive {
            // The first stage: its kernels, then its rays through the coarse pass.
            let mut noise = Rng::new(ctx.seed, 4 << 40 | ctx.step);
            for v in (0..views.len()).filter(used) {
                let pixels = ctx.centres(v);
                let jitter: Vec<[f32; 2]> =
                    (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
                let mut ws = DskWorkspace::default();
                self.forward(ctx.params, &mut ws, v, &pixels, size, Some(&jitter), None);
                views[v] = Some(DskView { probe: Some(Probe { ws, ..Probe::default() }), ..DskView::default() });
            }
            let pass = ProbePass::new(ctx, k);
            let (p, vs): (&[f32], &[Option<DskView>]) = (ctx.params, &views);
            let out = pool.run(0, pass.pixels.len(), workers, |range, g, wk| pass.run(p, vs, range, g, wk, false));
            let per = k * (3 + self.features);
            for (n, x) in out.concat().chunks_exact(per).enumerate() {
                let (v, _) = pass.pixels[n];
                let pr = probe_mut(&mut views, v);
                pr.cols.extend(x[..3 * k].chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                pr.feats.extend_from_slice(&x[3 * k..]);
            }
        }
        let mut noise = kernel_noise(ctx.seed, ctx.step);
        for v in (0..views.len()).filter(used) {
            let pixels = ctx.centres(v);
            let jitter: Vec<[f32; 2]> =
                (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
            let view = views[v].get_or_insert_with(DskView::default);
            let features = view.probe.as_ref().map(|p| &p.feats[..]);
            self.forward(ctx.params, &mut view.ws, v, &pixels, size, Some(&jitter), features);
        }
        views
    }

    fn rays(
        &self,
        s: &DskView,
        data: &Dataset,
        view: &View,
        _: &Ray,
        i: u32,
        j: u32,
        slot: usize,
        b: &mut Batch,
    ) -> f32 {
        let k = self.config.k;
        for q in slot * k..(slot + 1) * k {
            let (o, t) = (s.ws.offsets[q].map(f64::from), s.ws.origins[q].map(f64::from));
            b.push(data, dsk_ray(&data.intrinsics, &view.pose, i, j, o, t), s.ws.weights[q]);
        }
        0.0
    }

    fn blend(
        &self,
        views: &[Option<DskView>],
        px: &PixelRays,
        pass: usize,
        cols: &[[f32; 3]],
        weights: &[f32],
        target: [f32; 3],
        inv_gamma: f32,
        scale: f32,
        d_cols: &mut [[f32; 3]],
        rec: &mut Records,
    ) -> f32 {
        let m = cols.len();
        let mut dw = [0.0f32; MAX_RAYS];
        let probe = views[px.view as usize].as_ref().and_then(|v| v.probe.as_ref()).filter(|_| pass == 0);
        let loss = match probe {
            // PDRF's coarse loss: (first stage's blurry colour + this one) / 2.
            Some(pr) => {
                let (s, k) = (px.slot as usize, self.config.k);
                let mut a_col = [0.0f32; 3];
                for q in s * k..(s + 1) * k {
                    for (x, &y) in a_col.iter_mut().zip(&pr.cols[q]) {
                        *x += pr.ws.weights[q] * y;
                    }
                }
                let mut cols2 = [[0.0f32; 3]; MAX_RAYS + 1];
                let mut w2 = [0.0f32; MAX_RAYS + 1];
                cols2[..m].copy_from_slice(cols);
                cols2[m] = a_col;
                for (x, &wq) in w2.iter_mut().zip(weights) {
                    *x = 0.5 * wq;
                }
                w2[m] = 0.5;
                let (mut dc2, mut dw2) = ([[0.0f32; 3]; MAX_RAYS + 1], [0.0f32; MAX_RAYS + 1]);
                let loss = blur_loss(
                    &cols2[..m + 1],
                    Some(&w2[..m + 1]),
                    target,
                    inv_gamma,
                    scale,
                    &mut dc2[..m + 1],
                    &mut dw2[..m + 1],
                );
                d_cols.copy_from_slice(&dc2[..m]);
                for q in 0..m {
                    dw[q] = 0.5 * dw2[q];
                }
                for (x, &y) in rec.pixel[6 * k..6 * k + 3].iter_mut().zip(&dc2[m]) {
                    *x += y as f64;
                }
                loss
            }
            None => blur_loss(cols, Some(weights), target, inv_gamma, scale, d_cols, &mut dw[..m]),
        };
        self.weight_grads(&dw[..m], rec);
        loss
    }

    fn weight_grads(&self, dw: &[f32], rec: &mut Records) {
        for (q, d) in dw[..self.config.k].iter().enumerate() {
            rec.pixel[6 * q + 5] += *d as f64;
        }
    }

    fn ray_backward(
        &self,
        data: &Dataset,
        view: usize,
        _: u32,
        _: u32,
        world: &[Ray],
        d_rays: &[RayGrad<f32>],
        rec: &mut Records,
    ) {
        // World ray o = c + R t, d = R (d_cam(x + o) - t): back to the pixel offset and the
        // camera-frame origin shift.
        let pose = &data.views[view].pose;
        for q in 0..self.config.k {
            let (d_off, d_t) = dsk_ray_backward(&data.intrinsics, pose, &world[q], &d_rays[q]);
            let out = &mut rec.pixel[6 * q..6 * q + 5];
            for (o, d) in out.iter_mut().zip(d_off.iter().chain(&d_t)) {
                *o += d;
            }
        }
    }

    fn backward(&self, views: &mut [Option<DskView>], input: BackwardInput, grads: &mut [f32]) {
        let BackwardInput { ctx, batch, workers, pool, .. } = input;
        let (k_rays, pstride, params) = (self.config.k, self.pixel_record(), ctx.params);
        // Each pixel's gradients from the worker that rendered it, in slot order per view.
        let mut per_group: Vec<Option<&[f64]>> = vec![None; batch.groups.len()];
        for wk in workers.iter() {
            for (n, &gi) in wk.pgrad_groups.iter().enumerate() {
                per_group[gi as usize] = Some(&wk.pgrad[pstride * n..pstride * (n + 1)]);
            }
        }
        let mut by_view: Vec<Vec<&[f64]>> = vec![Vec::new(); views.len()];
        for (gr, pg) in batch.groups.iter().zip(&per_group) {
            if let (Kind::Image { view, slot, .. }, Some(pg)) = (gr.kind, pg) {
                debug_assert_eq!(by_view[view as usize].len(), slot as usize);
                by_view[view as usize].push(pg);
            }
        }
        let dc = &self.config;
        let align_scale =
            if ctx.step < dc.align_until { (dc.align_weight / batch.pixels.max(1) as f64) as f32 } else { 0.0 };
        for (v, vk) in views.iter_mut().enumerate() {
            let Some(vk) = vk.as_mut() else { continue };
            let pix = &by_view[v];
            let entries = pix.iter().flat_map(|pg| pg[..6 * k_rays].chunks_exact(6));
            let mut d_off: Vec<[f32; 2]> = entries.clone().map(|e| [e[0] as f32, e[1] as f32]).collect();
            let mut d_org: Vec<[f32; 3]> = entries.clone().map(|e| [e[2] as f32, e[3] as f32, e[4] as f32]).collect();
            let d_w: Vec<f32> = entries.map(|e| e[5] as f32).collect();
            if align_scale > 0.0 {
                self.align_backward(&vk.ws, align_scale, &mut d_off, &mut d_org);
            }
            Dsk::backward(self, params, grads, &mut vk.ws, &d_off, &d_org, &d_w);
            if let Some(pr) = vk.probe.as_mut() {
                pr.d_feats.clone_from(&vk.ws.d_features);
                pr.d_blur = pix.iter().map(|pg| std::array::from_fn(|c| pg[6 * k_rays + c] as f32)).collect();
            }
        }
        if !self.config.progressive {
            return;
        }
        // PDRF's first stage: its rays' backward (replayed with the same samples), then its
        // kernel's.
        let pass = ProbePass::new(ctx, k_rays);
        let vs: &[Option<DskView>] = views;
        let out = pool.run(ctx.model.layout.len(), pass.pixels.len(), workers, |range, g, wk| {
            pass.run(params, vs, range, g, wk, true)
        });
        pool.sum_into(grads);
        let out = out.concat();
        let mut at = 0;
        for (v, vk) in views.iter_mut().enumerate() {
            let Some(pr) = vk.as_mut().and_then(|vk| vk.probe.as_mut()) else { continue };
            let n = ctx.view_pixels[v].len() * k_rays;
            let d = &out[5 * at..5 * (at + n)];
            at += n;
            let d_off: Vec<[f32; 2]> = d.chunks_exact(5).map(|e| [e[0], e[1]]).collect();
            let d_org: Vec<[f32; 3]> = d.chunks_exact(5).map(|e| [e[2], e[3], e[4]]).collect();
            // dL/dw'_k = <c'_k, dL/dA> of its pixel.
            let d_w: Vec<f32> =
                (0..n).map(|q| (0..3).map(|c| pr.cols[q][c] * pr.d_blur[q / k_rays][c]).sum()).collect();
            Dsk::backward(self, params, grads, &mut pr.ws, &d_off, &d_org, &d_w);
        }
    }
}

/// The first stage's probe of view `v` (made before).
fn probe_mut(views: &mut [Option<DskView>], v: usize) -> &mut Probe {
    views[v].as_mut().and_then(|vk| vk.probe.as_mut()).expect("probed view")
}

/// The rendering of PDRF's first-stage rays, forward or backward.
struct ProbePass<'a> {
    ctx: &'a StepContext<'a>,
    /// (view, slot) of every probed pixel, in order.
    pixels: Vec<(usize, usize)>,
    k: usize,
    seed: u64,
}

impl<'a> ProbePass<'a> {
    /// The pass over every batch pixel, views in order.
    fn new(ctx: &'a StepContext<'a>, k: usize) -> ProbePass<'a> {
        let pixels =
            ctx.view_pixels.iter().enumerate().flat_map(|(v, px)| (0..px.len()).map(move |s| (v, s))).collect();
        ProbePass { ctx, pixels, k, seed: ctx.step_seed ^ 0x7064_7266 }
    }

    /// Renders the K first-stage rays (kernels in the views' probes) of the pixels `range`
    /// with the coarse pass only, in chunks of at most `chunk_rays` rays (at least one pixel);
    /// ray r of the stage draws from `Rng::new(seed, r)`, so the backward replays the
    /// forward's samples. Forward: returns per pixel K colours then K x features integrated
    /// features. Backward (`back`): accumulates the field's gradients into `g` from the
    /// probes' dL/d blurry colour and dL/d features (render weights held fixed) and returns per
    /// point dL/d offset (2), origin shift (3).
    fn run(
        &self,
        p: &[f32],
        views: &[Option<DskView>],
        range: Range<usize>,
        g: &mut [f32],
        wk: &mut Worker,
        back: bool,
    ) -> Vec<f32> {
        let (k, data, model) = (self.k, self.ctx.data, self.ctx.model);
        let probe = |v: usize| views[v].as_ref().and_then(|vk| vk.probe.as_ref()).expect("probed view");
        let per = (self.ctx.chunk_rays / k).max(1);
        let mut out = Vec::new();
        let mut p0 = range.start;
        while p0 < range.end {
            let p1 = (p0 + per).min(range.end);
            let mut world = Vec::with_capacity((p1 - p0) * k);
            for &(v, s) in &self.pixels[p0..p1] {
                let pr = probe(v);
                let (i, j) = self.ctx.view_pixels[v][s];
                for q in s * k..(s + 1) * k {
                    let (o, t) = (pr.ws.offsets[q].map(f64::from), pr.ws.origins[q].map(f64::from));
                    world.push(dsk_ray(&data.intrinsics, &data.views[v].pose, i, j, o, t));
                }
            }
            let prepared: Vec<PreparedRay> = world.iter().map(|r| prepare(data, r)).collect();
            let (o, d, vd) = unzip(&prepared);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (p0 * k..p1 * k).map(|r| Rng::new(self.seed, r as u64)).collect();
            wk.renderer.forward_coarse(model, p, &chunk, Some(&mut rngs));
            let n = world.len();
            let ps = wk.renderer.last_pass(model);
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
                    let pr = probe(v);
                    for q in 0..k {
                        let (r, pq) = (b * k + q, s * k + q);
                        wk.dc[r] = pr.d_blur[s].map(|x| x * pr.ws.weights[pq]);
                        let df = &pr.d_feats[pq * nf..(pq + 1) * nf];
                        ray_features_backward(&ps, r, df, &mut wk.dfeat[r * spr * nf..(r + 1) * spr * nf]);
                    }
                }
                wk.d_rays.resize(n, RayGrad::zero());
                wk.renderer.backward(model, p, g, &chunk, &wk.dc, &wk.df, Some(&mut wk.d_rays[..n]), Some(&wk.dfeat));
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
