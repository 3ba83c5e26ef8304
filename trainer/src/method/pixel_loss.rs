//! A pixel's colour terms in a step: the image loss on both passes through the blurry colour
//! (PDRF's coarse pass averaged with its first stage's), the EDI prior on the origin ray, and
//! the AWP's colour on the fine pass; each adds its gradients to the worker's colour buffers
//! and (through the blur model's blending) to the pixel's and its view's records.

use crate::blur::awp::Awp;
use crate::engine::model::Model;

use super::batch::*;
use super::blur_step::{Records, StepBlur};
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
pub(super) struct PixelLosses<'a, B: StepBlur> {
    /// The blur model (its blending).
    pub(super) blur: &'a B,
    /// Its views' state in the step.
    pub(super) views: &'a [Option<B::View>],
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
    /// A view's record in the workers' `kgrad`.
    pub(super) kstride: usize,
    /// The batch's blending weights.
    pub(super) weights: &'a [f32],
    /// The batch's rays.
    pub(super) rays: &'a [PreparedRay],
}

impl<B: StepBlur> PixelLosses<'_, B> {
    /// The image loss of both passes and the EDI prior of `px`.
    pub(super) fn colour(&self, wk: &mut Worker, px: &PixelRays, sums: &mut Sums) {
        let PixelRays { view, target, edi, first, a, m, pg, .. } = *px;
        let (origin, blurred) = (a + m - 1, m > 1);
        let v0 = view as usize * self.kstride;
        let mut rec = Records {
            view: &mut wk.kgrad[v0..v0 + self.kstride],
            pixel: match pg {
                Some(pg) => &mut wk.pgrad[pg..pg + self.blur.pixel_record()],
                None => &mut [],
            },
        };
        for pass in 0..2 {
            let (cols, dcol) =
                if pass == 0 { (wk.renderer.coarse(), &mut wk.dc) } else { (wk.renderer.fine(), &mut wk.df) };
            sums.image[pass] += if blurred {
                let weights = &self.weights[first..first + m];
                let (cols, d_cols) = (&cols[a..a + m], &mut dcol[a..a + m]);
                let (ig, s) = (self.inv_gamma, self.blur_scale);
                self.blur.blend(self.views, px, pass, cols, weights, target, ig, s, d_cols, &mut rec)
            } else {
                let mut dw = [0.0f32; 1];
                let (ig, s) = (self.inv_gamma, self.img_scale);
                blur_loss(&cols[a..a + m], None, target, ig, s, &mut dcol[a..a + m], &mut dw)
            } as f64;
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
        let (embeddings, record) = self.blur.awp_slots().expect("the AWP comes with the rigid kernel");
        let emb_dim = awp.embedding;
        let ps = wk.renderer.last_pass(model);
        let (s, nf) = (ps.per_ray, ps.width);
        let feats = &ps.features[a * s * ps.stride..];
        let om = &ps.weights[a * s..(a + m) * s];
        let e0 = embeddings + view as usize * emb_dim;
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
        let base = view as usize * self.kstride + record;
        for (k, d) in wk.awp_ws.d_embedding.iter().enumerate() {
            wk.kgrad[base + k] += *d as f64;
        }
    }
}
