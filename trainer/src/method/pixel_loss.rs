//! A pixel's colour terms in a step: the image loss on both passes through the blurry colour
//! (PDRF's coarse pass averaged with its first stage's), the EDI prior on the origin ray, and
//! the AWP's colour on the fine pass; each adds its gradients to the worker's colour buffers
//! and the view's kernel record.

use crate::blur::awp::Awp;
use crate::engine::model::Model;

use super::batch::*;
use super::kernel::*;
use super::rays::{response, PreparedRay};
use crate::blur::MAX_RAYS;

/// One image pixel's rays in a chunk.
#[derive(Clone, Copy)]
pub(super) struct PixelRays {
    /// Its training view.
    pub(super) view: u32,
    /// Its slot among the view's batch pixels.
    pub(super) slot: u32,
    /// The target colour (display-referred).
    pub(super) target: [f32; 3],
    /// The EDI target (NaN: none).
    pub(super) edi: [f32; 3],
    /// Its first ray in the batch.
    pub(super) first: usize,
    /// Its first ray in the chunk.
    pub(super) a: usize,
    /// Its rays (K blurred rays then the origin ray, or one plain ray).
    pub(super) m: usize,
    /// Its DSK record in the worker's `pgrad`.
    pub(super) pg: Option<usize>,
}

/// What the colour terms of a step share.
pub(super) struct PixelLosses<'a> {
    /// 1 / gamma of the camera response.
    pub(super) inv_gamma: f32,
    /// Weight of a plain pixel's loss: 1 / (3 pixels).
    pub(super) img_scale: f32,
    /// Weight of a blurred pixel's loss (the AWP's share taken off).
    pub(super) blur_scale: f32,
    /// Weight of the EDI prior.
    pub(super) edi_scale: f32,
    /// Pixels in the batch.
    pub(super) pixels: usize,
    /// The blur model is the rigid kernel (its blending weights learn).
    pub(super) rigid: bool,
    /// Rays per pixel of the blur model (K).
    pub(super) k_rays: usize,
    /// A view's record in the workers' `kgrad`.
    pub(super) kstride: usize,
    /// Offset of the rigid kernel's embeddings (the AWP's input; 0 without the kernel).
    pub(super) embeddings: usize,
    /// PDRF's first stage, per view.
    pub(super) probes: &'a [Option<Probe>],
    /// The batch's blending weights.
    pub(super) weights: &'a [f32],
    /// The batch's rays.
    pub(super) rays: &'a [PreparedRay],
}

impl PixelLosses<'_> {
    /// The image loss of both passes and the EDI prior of `px`.
    pub(super) fn colour(&self, wk: &mut Worker, px: &PixelRays, sums: &mut Sums) {
        let PixelRays { view, slot, target, edi, first, a, m, pg } = *px;
        let (origin, blurred, k_rays, kstride) = (a + m - 1, m > 1, self.k_rays, self.kstride);
        for pass in 0..2 {
            let (cols, dcol) =
                if pass == 0 { (wk.renderer.coarse(), &mut wk.dc) } else { (wk.renderer.fine(), &mut wk.df) };
            let weights = blurred.then(|| &self.weights[first..first + m]);
            let mut dw = [0.0f32; MAX_RAYS];
            let scale = if blurred { self.blur_scale } else { self.img_scale };
            let probe = self.probes[view as usize].as_ref().filter(|_| blurred && pass == 0);
            if let (Some(pr), Some(weights), Some(pg)) = (probe, weights, pg) {
                // PDRF's coarse loss: (first stage's blurry colour + this one) / 2.
                let (s, k) = (slot as usize, k_rays);
                let mut a_col = [0.0f32; 3];
                for q in s * k..(s + 1) * k {
                    for (x, &y) in a_col.iter_mut().zip(&pr.cols[q]) {
                        *x += pr.ws.weights[q] * y;
                    }
                }
                let mut cols2 = [[0.0f32; 3]; MAX_RAYS + 1];
                let mut w2 = [0.0f32; MAX_RAYS + 1];
                cols2[..m].copy_from_slice(&cols[a..a + m]);
                cols2[m] = a_col;
                for (x, &wq) in w2.iter_mut().zip(weights) {
                    *x = 0.5 * wq;
                }
                w2[m] = 0.5;
                let (mut dc2, mut dw2) = ([[0.0f32; 3]; MAX_RAYS + 1], [0.0f32; MAX_RAYS + 1]);
                sums.image[pass] += blur_loss(
                    &cols2[..m + 1],
                    Some(&w2[..m + 1]),
                    target,
                    self.inv_gamma,
                    scale,
                    &mut dc2[..m + 1],
                    &mut dw2[..m + 1],
                ) as f64;
                dcol[a..a + m].copy_from_slice(&dc2[..m]);
                for q in 0..m {
                    dw[q] = 0.5 * dw2[q];
                }
                for (x, &y) in wk.pgrad[pg + 6 * k..pg + 6 * k + 3].iter_mut().zip(&dc2[m]) {
                    *x += y as f64;
                }
            } else {
                sums.image[pass] += blur_loss(
                    &cols[a..a + m],
                    weights,
                    target,
                    self.inv_gamma,
                    scale,
                    &mut dcol[a..a + m],
                    &mut dw[..m],
                ) as f64;
            }
            if blurred && self.rigid {
                let base = view as usize * kstride + 12 * k_rays;
                for (q, d) in dw[..m].iter().enumerate() {
                    wk.kgrad[base + q] += *d as f64;
                }
            }
            if let Some(pg) = pg {
                for (q, d) in dw[..k_rays].iter().enumerate() {
                    wk.pgrad[pg + 6 * q + 5] += *d as f64;
                }
            }
            if self.edi_scale > 0.0 && !edi[0].is_nan() {
                for c in 0..3 {
                    let (gc, dg) = response(cols[origin][c], self.inv_gamma);
                    let e = gc - edi[c];
                    sums.edi += (e * e) as f64 / (3 * self.pixels.max(1)) as f64;
                    dcol[origin][c] += 2.0 * e * dg * self.edi_scale;
                }
            }
        }
    }

    /// The AWP's colour of `px` on the fine pass, mixed in with weight `mix`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn awp_colour(
        &self,
        awp: &Awp,
        mix: f32,
        model: &Model,
        p: &[f32],
        g: &mut [f32],
        wk: &mut Worker,
        px: &PixelRays,
        sums: &mut Sums,
    ) {
        let PixelRays { view, target, first, a, m, .. } = *px;
        let emb_dim = awp.embedding;
        let ps = wk.renderer.last_pass(model);
        let (s, nf) = (ps.per_ray, ps.width);
        let feats = &ps.features[a * s * ps.stride..];
        let om = &ps.weights[a * s..(a + m) * s];
        let e0 = self.embeddings + view as usize * emb_dim;
        let dir = self.rays[first + m - 1].viewdir;
        awp.forward(p, &mut wk.awp_ws, feats, ps.stride, s, om, &p[e0..e0 + emb_dim], dir);
        let (mut d_cols, mut dw) = ([[0.0f32; 3]; MAX_RAYS], [0.0f32; MAX_RAYS]);
        sums.awp += blur_loss(
            &wk.renderer.fine()[a..a + m],
            Some(&wk.awp_ws.weights),
            target,
            self.inv_gamma,
            mix * self.img_scale,
            &mut d_cols[..m],
            &mut dw[..m],
        ) as f64;
        for (d, dc) in wk.df[a..a + m].iter_mut().zip(&d_cols) {
            for c in 0..3 {
                d[c] += dc[c];
            }
        }
        awp.backward(p, g, &mut wk.awp_ws, feats, ps.stride, om, &dw[..m]);
        wk.dfeat[a * s * nf..(a + m) * s * nf].copy_from_slice(&wk.awp_ws.d_features);
        let base = view as usize * self.kstride + 13 * self.k_rays + 1;
        for (k, d) in wk.awp_ws.d_embedding.iter().enumerate() {
            wk.kgrad[base + k] += *d as f64;
        }
    }
}
