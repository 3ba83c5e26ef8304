//! DP-NeRF's rigid kernel in a step: per view, K rigid motions and K + 1 blending weights from
//! the view's embedding; a pixel's rays are its ray moved by each motion, then the origin ray.
//! A view's record: K x (dR 9, dt 3), the K + 1 weights' gradients, then (with the AWP) the
//! embedding's gradient from the AWP.

use crate::blur::rigid::{KernelOut, RigidKernel};
use crate::blur::se3::{self, Rigid};
use crate::data::dataset::{Dataset, View};
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::RayGrad;

use super::super::batch::{Batch, Worker};
use super::super::kernel::warp;
use super::{motion_ray_backward, twist_grads, BackwardInput, Records, StepBlur, StepContext};

/// A view's rigid kernel in a step.
pub(in crate::method) struct RigidView {
    /// The kernel's output (twists and K + 1 weights).
    out: KernelOut<f32>,
    /// The twists in f64.
    twists: Vec<[f64; 6]>,
    /// Their world-frame motions.
    motions: Vec<Rigid>,
}

impl StepBlur for RigidKernel {
    type View = RigidView;

    fn k(&self) -> usize {
        self.config.k
    }

    fn learns_rays(&self) -> bool {
        true
    }

    fn blends_origin(&self) -> bool {
        true
    }

    fn view_record(&self, emb_dim: usize) -> usize {
        13 * self.config.k + 1 + emb_dim
    }

    fn awp_slots(&self) -> Option<(usize, usize)> {
        Some((self.embeddings, 13 * self.config.k + 1))
    }

    fn views(&self, ctx: &StepContext, _: &mut [Worker], _: &mut GradBuffers) -> Vec<Option<RigidView>> {
        let views = ctx.view_pixels.iter().enumerate();
        views
            .map(|(v, px)| {
                (!px.is_empty()).then(|| {
                    let out = self.forward(ctx.params, v);
                    let twists: Vec<[f64; 6]> = out.twists.iter().map(|t| t.map(|x| x as f64)).collect();
                    let motions = twists.iter().map(|&t| se3::exp(t)).collect();
                    RigidView { out, twists, motions }
                })
            })
            .collect()
    }

    fn rays(&self, s: &RigidView, data: &Dataset, _: &View, ray: &Ray, _: u32, _: u32, _: usize, b: &mut Batch) -> f32 {
        for (m, &w) in s.motions.iter().zip(&s.out.weights) {
            b.push(data, warp(m, ray), w);
        }
        s.out.weights[s.motions.len()]
    }

    fn weight_grads(&self, dw: &[f32], rec: &mut Records) {
        let base = 12 * self.config.k;
        for (q, d) in dw.iter().enumerate() {
            rec.view[base + q] += *d as f64;
        }
    }

    fn ray_backward(
        &self,
        data: &Dataset,
        view: usize,
        i: u32,
        j: u32,
        world: &[Ray],
        d_rays: &[RayGrad<f32>],
        rec: &mut Records,
    ) {
        let k = self.config.k;
        motion_ray_backward(data, view, i, j, &world[..k], &d_rays[..k], rec.view);
    }

    fn backward(&self, views: &mut [Option<RigidView>], input: BackwardInput, grads: &mut [f32]) {
        let k = self.config.k;
        let workers = &*input.workers;
        let stride = input.view_stride;
        let emb_dim = stride - (13 * k + 1);
        for (v, vk) in views.iter().enumerate() {
            let Some(vk) = vk else { continue };
            let base = v * stride;
            let total = |i: usize| workers.iter().map(|wk| wk.kgrad[base + i]).sum::<f64>();
            let d_twists = twist_grads(workers, base, &vk.twists);
            let d_weights: Vec<f32> = (0..=k).map(|q| total(12 * k + q) as f32).collect();
            let e0 = self.embeddings + v * emb_dim;
            for e in 0..emb_dim {
                grads[e0 + e] += total(13 * k + 1 + e) as f32;
            }
            let d_twists: Vec<[f32; 6]> = d_twists.iter().map(|t| t.map(|x| x as f32)).collect();
            RigidKernel::backward(self, input.ctx.params, grads, v, &vk.out, &d_twists, &d_weights);
        }
    }
}
