//! One training step: draws the batch (pixels, event pairs), builds the blur models' rays,
//! renders and differentiates the chunks in parallel (image loss, EDI prior, AWP, event loss),
//! then the kernel gradients, TV and one Adam update.

use crate::config::{EventLossConfig, TrainConfig};
use crate::data::dataset::Dataset;
use crate::engine::adam::Adam;
use crate::engine::renderer::{RayChunk, RayGrad};
use crate::engine::rng::Rng;
use crate::events::loss::{event_losses, EventPair, PairRule, BT601};

use super::batch::*;
use super::blur_step::{BackwardInput, NoBlur, Records, StepBlur, StepContext};
use super::pixel_loss::{PixelLosses, PixelRays};
use super::rays::unzip;
use super::*;

/// One optimisation step (module doc); returns its losses.
#[allow(clippy::too_many_arguments)]
pub fn step(
    bufs: &mut StepBuffers,
    method: &Method,
    params: &mut [f32],
    adam: &mut Adam,
    cfg: &TrainConfig,
    data: &Dataset,
    sd: &StepData,
    step: u64,
) -> StepLosses {
    let started = cfg.blur.as_ref().is_some_and(|b| step >= b.start);
    let args = StepArgs { method, cfg, data, sd, step };
    match method.blur.as_ref().filter(|_| started) {
        Some(Blur::Rigid(k)) => step_with(k, bufs, params, adam, &args),
        Some(Blur::Trajectory(t)) => step_with(t, bufs, params, adam, &args),
        Some(Blur::Dsk(d)) => step_with(d, bufs, params, adam, &args),
        None => step_with(&NoBlur, bufs, params, adam, &args),
    }
}

/// What a step reads besides its buffers, parameters and optimiser.
struct StepArgs<'a> {
    method: &'a Method,
    cfg: &'a TrainConfig,
    data: &'a Dataset,
    sd: &'a StepData,
    step: u64,
}

/// The step with blur model `blur` (`NoBlur`: none, or not started yet).
fn step_with<B: StepBlur>(
    blur: &B,
    bufs: &mut StepBuffers,
    params: &mut [f32],
    adam: &mut Adam,
    args: &StepArgs,
) -> StepLosses {
    let StepArgs { method, cfg, data, sd, step } = *args;
    let model = &method.model;
    let blur_on = blur.k() > 0;
    let n_views = data.views.len();
    let edi_w = cfg.edi.as_ref().map_or(0.0, |d| d.weight_at(step));
    let evc = cfg.events.as_ref();
    let (picks, _) = draw(cfg, data, sd, step, bufs.workers.len());
    // Each view's batch pixels in slot order.
    let mut view_pixels: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_views];
    for p in &picks {
        if let Pick::Pixel { v, i, j, .. } = *p {
            view_pixels[v].push((i, j));
        }
    }
    let step_seed = cfg.seed ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let chunk_rays = cfg.chunk_rays.max(1);
    let p: &[f32] = params;
    let ctx =
        StepContext { params: p, data, model, view_pixels: &view_pixels, seed: cfg.seed, step, step_seed, chunk_rays };
    // The blur model of every view with pixels in the batch.
    let mut views = blur.views(&ctx, &mut bufs.workers, &mut bufs.grads);
    // The origin ray closes every blurred pixel's group when something reads it: the rigid
    // kernel's weight, the AWP, the EDI prior.
    let with_origin = blur.blends_origin() || cfg.edi.is_some();
    let batch = assemble(picks, cfg, data, sd, blur, &views, with_origin);
    let inv_gamma = (1.0 / cfg.response_gamma) as f32;
    let img_scale = 1.0 / (3.0 * batch.pixels.max(1) as f32);
    let ev_scale = evc.map_or(0.0, |e| e.weight as f32) / batch.events.max(1) as f32;
    let edi_scale = edi_w as f32 * img_scale;
    // Blur models whose rays move with their parameters take the rays' gradients.
    let learns_rays = blur.learns_rays();
    let awp = method.awp.as_ref().filter(|_| blur_on);
    let mix = awp.map_or(0.0, |a| a.config.mix_at(step)) as f32;
    // The image loss mixes the kernel's colours and the AWP's: (1 - l) [coarse + fine] + l awp.
    let blur_scale = img_scale * (1.0 - mix);
    let emb_dim = awp.map_or(0, |a| a.embedding);
    let kstride = blur.view_record(emb_dim);
    let pstride = blur.pixel_record();
    let luma = evc.and_then(|e| e.luma).unwrap_or(BT601).map(|x| x as f32);
    let log_eps = evc.and_then(|e| e.log_eps).unwrap_or(1e-5) as f32;
    let cut = pair_rule(evc);
    let ecrf = method.ecrf.as_ref();
    let batch_ref = &batch;
    let n_groups = batch.groups.len();
    let pixel_losses = PixelLosses {
        blur,
        views: &views,
        inv_gamma,
        img_scale,
        blur_scale,
        edi_scale,
        pixels: batch.pixels,
        kstride,
        weights: &batch.weights,
        rays: &batch.rays,
    };
    let sums = bufs.grads.run(model.layout.len(), n_groups, &mut bufs.workers, |range, g, wk| {
        let mut sums = Sums::default();
        wk.kgrad.clear();
        wk.kgrad.resize(n_views * kstride, 0.0);
        wk.pgrad.clear();
        wk.pgrad_groups.clear();
        let groups = &batch_ref.groups;
        let mut g0 = range.start;
        while g0 < range.end {
            let r0 = groups[g0].first;
            let is_image = |g: &Group| matches!(g.kind, Kind::Image { .. });
            let kind = is_image(&groups[g0]);
            let mut g1 = g0 + 1;
            while g1 < range.end && groups[g1].first + groups[g1].n - r0 <= chunk_rays && is_image(&groups[g1]) == kind
            {
                g1 += 1;
            }
            let r1 = groups[g1 - 1].first + groups[g1 - 1].n;
            let (o, d, vd) = unzip(&batch_ref.rays[r0..r1]);
            let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &vd };
            let mut rngs: Vec<Rng> = (r0..r1).map(|r| Rng::new(step_seed, r as u64)).collect();
            wk.renderer.forward(model, p, &chunk, Some(&mut rngs));
            let n = r1 - r0;
            wk.dc.clear();
            wk.dc.resize(n, [0.0; 3]);
            wk.df.clear();
            wk.df.resize(n, [0.0; 3]);
            let mut any_kernel = false;
            let mut any_awp = false;
            let mut chunk_pg = vec![usize::MAX; g1 - g0];
            for (gi, gr) in groups[g0..g1].iter().enumerate() {
                let Kind::Image { view, slot, target, edi, .. } = gr.kind else { continue };
                let (a, m) = (gr.first - r0, gr.n);
                let blurred = m > 1;
                any_kernel |= blurred;
                let pg = (blurred && pstride > 0).then(|| {
                    wk.pgrad_groups.push((g0 + gi) as u32);
                    wk.pgrad.resize(wk.pgrad.len() + pstride, 0.0);
                    wk.pgrad.len() - pstride
                });
                chunk_pg[gi] = pg.unwrap_or(usize::MAX);
                let px = PixelRays { view, slot, target, edi, first: gr.first, a, m, pg };
                pixel_losses.colour(wk, &px, &mut sums);
                // The AWP's colour: its weights over the fine colours of the same rays.
                if let (Some(awp), true) = (awp, blurred && mix > 0.0) {
                    if !any_awp {
                        let ps = wk.renderer.last_pass(model);
                        wk.dfeat.clear();
                        wk.dfeat.resize(n * ps.per_ray * ps.width, 0.0);
                        any_awp = true;
                    }
                    pixel_losses.awp_colour(awp, mix, model, p, g, wk, &px, &mut sums);
                }
            }
            let pairs: Vec<EventPair> = groups[g0..g1]
                .iter()
                .filter_map(|gr| match gr.kind {
                    Kind::Event { polarity, target, channel } => {
                        Some(EventPair { first: gr.first - r0, polarity, target, channel })
                    }
                    _ => None,
                })
                .collect();
            let colours = [wk.renderer.coarse(), wk.renderer.fine()];
            let d_colours = [&mut wk.dc[..], &mut wk.df[..]];
            sums.event +=
                event_losses(&mut wk.events, ecrf, p, g, &pairs, colours, d_colours, luma, log_eps, cut, ev_scale);
            let with_rays = learns_rays && any_kernel;
            if with_rays {
                wk.d_rays.resize(n, RayGrad::zero());
            }
            let d_rays = if with_rays { Some(&mut wk.d_rays[..n]) } else { None };
            let d_feat = if any_awp { Some(&wk.dfeat[..]) } else { None };
            wk.renderer.backward(model, p, g, &chunk, &wk.dc, &wk.df, d_rays, d_feat);
            if with_rays {
                for (gi, gr) in groups[g0..g1].iter().enumerate() {
                    let Kind::Image { view, i, j, .. } = gr.kind else { continue };
                    if gr.n == 1 {
                        continue;
                    }
                    let (v0, pg) = (view as usize * kstride, chunk_pg[gi]);
                    let mut rec = Records {
                        view: &mut wk.kgrad[v0..v0 + kstride],
                        pixel: if pg == usize::MAX { &mut [] } else { &mut wk.pgrad[pg..pg + pstride] },
                    };
                    let (world, d_rays) = (&batch_ref.world[gr.first..], &wk.d_rays[gr.first - r0..n]);
                    blur.ray_backward(data, view as usize, i, j, world, d_rays, &mut rec);
                }
            }
            g0 = g1;
        }
        sums
    });
    let grads = &mut bufs.sum;
    grads.clear();
    grads.resize(model.layout.len(), 0.0);
    bufs.grads.sum_into(grads);
    // The blur model's parameters: its records' gradients, summed over workers in order.
    let input = BackwardInput {
        ctx: &ctx,
        batch: &batch,
        view_stride: kstride,
        workers: &mut bufs.workers,
        pool: &mut bufs.grads,
    };
    blur.backward(&mut views, input, grads);
    // The eCRF learns from its start iteration on (before: held at the identity).
    if let (Some(e), Some(c)) = (ecrf, cfg.ecrf.as_ref()) {
        if step < c.start {
            for r in e.ranges() {
                grads[r].fill(0.0);
            }
        }
    }
    let s = sums.iter().fold(Sums::default(), |a, b| Sums {
        image: [a.image[0] + b.image[0], a.image[1] + b.image[1]],
        event: a.event + b.event,
        edi: a.edi + b.edi,
        awp: a.awp + b.awp,
    });
    model.tv(params, grads);
    adam.step(&cfg.adam, &model.layout, params, grads);
    let np = (3 * batch.pixels.max(1)) as f64;
    StepLosses {
        image: (s.image[0] + s.image[1]) / np,
        psnr: -10.0 * (s.image[1] / np).log10(),
        event: s.event / batch.events.max(1) as f64,
        edi: s.edi,
        awp: s.awp / np,
    }
}

/// The pair rule of an event loss configuration (every pair, the square, when unset).
fn pair_rule(e: Option<&EventLossConfig>) -> PairRule {
    PairRule {
        saturation: e.and_then(|e| e.saturation).map_or(f32::INFINITY, |s| s as f32),
        dark: e.and_then(|e| e.dark).map_or(f32::NEG_INFINITY, |s| s as f32),
        huber: e.and_then(|e| e.huber).map_or(f32::INFINITY, |s| s as f32),
    }
}
