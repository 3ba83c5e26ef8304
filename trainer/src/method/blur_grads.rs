//! The blur models' gradients at the end of a step, once every chunk is rendered: the rigid
//! kernel's and a learned trajectory's twists (and the kernel's blending weights and the AWP's
//! embedding input) summed over the workers in order, back through the se(3) exponential map
//! and the heads; the DSK's per-point gradients back through its MLP (with the alignment loss
//! while it is on), then PDRF's first stage (its rays replayed, then its kernel).

use crate::blur::se3;
use crate::engine::parallel::GradBuffers;

use super::batch::*;
use super::kernel::*;
use super::*;

/// Sizes of the per-view gradient records workers fill (`Worker::kgrad`, `Worker::pgrad`).
pub(super) struct KernelSizes {
    /// Rays per pixel of the blur model (K).
    pub(super) k_rays: usize,
    /// A view's record in `kgrad`: K twists' rotation and translation gradients (12 each),
    /// K + 1 blending weights, the AWP's embedding.
    pub(super) kstride: usize,
    /// The AWP's embedding size (0 without the AWP).
    pub(super) emb_dim: usize,
    /// A DSK pixel's record in `pgrad`: K x (offset 2, origin 3, weight 1), then (PDRF) the
    /// first stage's blurry colour (3).
    pub(super) pstride: usize,
}

/// The step's per-view blur state.
pub(super) struct BlurViews<'s, 'p> {
    /// Each view's kernel (`None`: no pixel of the view in the batch).
    pub(super) kernels: &'s mut [Option<ViewKernel>],
    /// PDRF's first-stage kernels and colours per view.
    pub(super) probes: &'s mut [Option<Probe>],
    /// PDRF's first-stage rendering, to replay backward.
    pub(super) probe_pass: Option<&'s ProbePass<'p>>,
}

/// Adds the blur model's parameter gradients of this step to `grads` (see the module doc).
#[allow(clippy::too_many_arguments)]
pub(super) fn blur_backward(
    blur: &Blur,
    learns_rays: bool,
    views: BlurViews,
    sizes: &KernelSizes,
    batch: &Batch,
    step: u64,
    params: &[f32],
    grads: &mut [f32],
    workers: &mut [Worker],
    pool: &mut GradBuffers,
) {
    let KernelSizes { k_rays, kstride, emb_dim, pstride } = *sizes;
    match blur {
        Blur::Rigid(_) | Blur::Trajectory(_) if learns_rays => {
            for (v, vk) in views.kernels.iter().enumerate() {
                let Some(vk) = vk else { continue };
                let base = v * kstride;
                let total = |i: usize| workers.iter().map(|wk| wk.kgrad[base + i]).sum::<f64>();
                let d_twists: Vec<[f64; 6]> = (0..k_rays)
                    .map(|q| {
                        let d_r: [[f64; 3]; 3] =
                            std::array::from_fn(|i| std::array::from_fn(|j| total(12 * q + 3 * i + j)));
                        let d_t: [f64; 3] = std::array::from_fn(|i| total(12 * q + 9 + i));
                        se3::exp_backward(vk.twists[q], &d_r, &d_t)
                    })
                    .collect();
                match blur {
                    Blur::Rigid(kernel) => {
                        let d_weights: Vec<f32> = (0..=k_rays).map(|q| total(12 * k_rays + q) as f32).collect();
                        let e0 = kernel.embeddings + v * emb_dim;
                        for k in 0..emb_dim {
                            grads[e0 + k] += total(13 * k_rays + 1 + k) as f32;
                        }
                        let d_twists: Vec<[f32; 6]> = d_twists.iter().map(|t| t.map(|x| x as f32)).collect();
                        let out = vk.rigid.as_ref().expect("rigid kernel output");
                        kernel.backward(params, grads, v, out, &d_twists, &d_weights);
                    }
                    Blur::Trajectory(t) => t.backward(grads, v, &d_twists),
                    Blur::Dsk(_) => unreachable!("matched above"),
                }
            }
        }
        Blur::Dsk(dsk) => {
            // Each pixel's gradients from the worker that rendered it, in slot order per view.
            let mut per_group: Vec<Option<&[f64]>> = vec![None; batch.groups.len()];
            for wk in workers.iter() {
                for (n, &gi) in wk.pgrad_groups.iter().enumerate() {
                    per_group[gi as usize] = Some(&wk.pgrad[pstride * n..pstride * (n + 1)]);
                }
            }
            let mut by_view: Vec<Vec<&[f64]>> = vec![Vec::new(); views.kernels.len()];
            for (gr, pg) in batch.groups.iter().zip(&per_group) {
                if let (Kind::Image { view, slot, .. }, Some(pg)) = (gr.kind, pg) {
                    debug_assert_eq!(by_view[view as usize].len(), slot as usize);
                    by_view[view as usize].push(pg);
                }
            }
            let dc = &dsk.config;
            let align_scale =
                if step < dc.align_until { (dc.align_weight / batch.pixels.max(1) as f64) as f32 } else { 0.0 };
            for (v, vk) in views.kernels.iter_mut().enumerate() {
                let Some(ws) = vk.as_mut().and_then(|vk| vk.dsk.as_mut()) else { continue };
                let pix = &by_view[v];
                let entries = pix.iter().flat_map(|pg| pg[..6 * k_rays].chunks_exact(6));
                let mut d_off: Vec<[f32; 2]> = entries.clone().map(|e| [e[0] as f32, e[1] as f32]).collect();
                let mut d_org: Vec<[f32; 3]> =
                    entries.clone().map(|e| [e[2] as f32, e[3] as f32, e[4] as f32]).collect();
                let d_w: Vec<f32> = entries.map(|e| e[5] as f32).collect();
                if align_scale > 0.0 {
                    dsk.align_backward(ws, align_scale, &mut d_off, &mut d_org);
                }
                dsk.backward(params, grads, ws, &d_off, &d_org, &d_w);
                if let Some(pr) = views.probes[v].as_mut() {
                    pr.d_feats.clone_from(&ws.d_features);
                    pr.d_blur = pix.iter().map(|pg| std::array::from_fn(|c| pg[6 * k_rays + c] as f32)).collect();
                }
            }
            // PDRF's first stage: its rays' backward (replayed with the same samples), then
            // its kernel's.
            if let Some(pass) = views.probe_pass {
                let (p, pr): (&[f32], &[Option<Probe>]) = (params, &*views.probes);
                let out = pool.run(pass.model.layout.len(), pass.pixels.len(), workers, |range, g, wk| {
                    pass.run(p, pr, range, g, wk, true)
                });
                pool.sum_into(grads);
                let out = out.concat();
                let mut at = 0;
                for (v, pr) in views.probes.iter_mut().enumerate() {
                    let Some(pr) = pr.as_mut() else { continue };
                    let n = pass.view_pixels[v].len() * k_rays;
                    let d = &out[5 * at..5 * (at + n)];
                    at += n;
                    let d_off: Vec<[f32; 2]> = d.chunks_exact(5).map(|e| [e[0], e[1]]).collect();
                    let d_org: Vec<[f32; 3]> = d.chunks_exact(5).map(|e| [e[2], e[3], e[4]]).collect();
                    // dL/dw'_k = <c'_k, dL/dA> of its pixel.
                    let d_w: Vec<f32> =
                        (0..n).map(|q| (0..3).map(|c| pr.cols[q][c] * pr.d_blur[q / k_rays][c]).sum()).collect();
                    dsk.backward(params, grads, &mut pr.ws, &d_off, &d_org, &d_w);
                }
            }
        }
        _ => {}
    }
}
