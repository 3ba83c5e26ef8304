//! One training step: draws the batch (pixels, event pairs), builds the blur models' rays,
//! renders and differentiates the chunks in parallel (image loss, EDI prior, AWP, event loss),
//! then the kernel gradients, TV and one Adam update.

use crate::blur::dsk::DskWorkspace;
use crate::config::{EventLossConfig, TrainConfig};
use crate::data::dataset::Dataset;
use crate::engine::adam::Adam;
use crate::engine::renderer::{RayChunk, RayGrad};
use crate::engine::rng::Rng;
use crate::events::loss::{event_losses, EventPair, PairRule, BT601};

use super::batch::*;
use super::blur_grads::{blur_backward, BlurViews, KernelSizes};
use super::kernel::*;
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
    let model = &method.model;
    let (w, h) = (data.intrinsics.width, data.intrinsics.height);
    let blur = method.blur.as_ref().filter(|_| cfg.blur.as_ref().is_some_and(|b| step >= b.start));
    let blur_on = blur.is_some();
    let n_views = data.views.len();
    let edi_w = cfg.edi.as_ref().map_or(0.0, |d| d.weight_at(step));
    let evc = cfg.events.as_ref();
    let (picks, slots) = draw(cfg, data, sd, step, bufs.workers.len());
    // Each view's batch pixels in slot order.
    let mut view_pixels: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_views];
    for p in &picks {
        if let Pick::Pixel { v, i, j, .. } = *p {
            view_pixels[v].push((i, j));
        }
    }
    let centres =
        |v: usize| -> Vec<[f32; 2]> { view_pixels[v].iter().map(|&(i, j)| [i as f32 + 0.5, j as f32 + 0.5]).collect() };
    let step_seed = cfg.seed ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let chunk_rays = cfg.chunk_rays.max(1);
    // PDRF's first stage: the kernel without features, its rays through the coarse pass.
    let progressive = match blur {
        Some(Blur::Dsk(d)) if d.config.progressive => Some(d),
        _ => None,
    };
    let mut probes: Vec<Option<Probe>> = (0..n_views).map(|_| None).collect();
    let mut probe_pixels: Vec<(usize, usize)> = Vec::new();
    let probe_seed = step_seed ^ 0x7064_7266;
    if let Some(dsk) = progressive {
        let mut noise = Rng::new(cfg.seed, 4 << 40 | step);
        let k = dsk.config.k;
        let size = [w as f32, h as f32];
        for v in (0..n_views).filter(|&v| slots[v] > 0) {
            let pixels = centres(v);
            let jitter: Vec<[f32; 2]> =
                (0..pixels.len() * k).map(|_| [noise.normal_f32(), noise.normal_f32()]).collect();
            let mut ws = DskWorkspace::default();
            dsk.forward(params, &mut ws, v, &pixels, size, Some(&jitter), None);
            probe_pixels.extend((0..pixels.len()).map(|s| (v, s)));
            probes[v] = Some(Probe { ws, ..Probe::default() });
        }
    }
    let probe_pass = progressive.map(|dsk| ProbePass {
        model,
        data,
        pixels: &probe_pixels,
        view_pixels: &view_pixels,
        k: dsk.config.k,
        chunk_rays,
        seed: probe_seed,
    });
    if let (Some(dsk), Some(pass)) = (progressive, &probe_pass) {
        let (k, p, pr): (usize, &[f32], &[Option<Probe>]) = (dsk.config.k, params, &probes);
        let out = bufs
            .grads
            .run(0, probe_pixels.len(), &mut bufs.workers, |range, g, wk| pass.run(p, pr, range, g, wk, false));
        let nf = dsk.features;
        let per = k * (3 + nf);
        for (n, x) in out.concat().chunks_exact(per).enumerate() {
            let (v, _) = probe_pixels[n];
            let pr = probes[v].as_mut().expect("probed view");
            pr.cols.extend(x[..3 * k].chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            pr.feats.extend_from_slice(&x[3 * k..]);
        }
    }
    // The blur model of every view with pixels in the batch.
    let mut kernels: Vec<Option<ViewKernel>> = (0..n_views).map(|_| None).collect();
    if let Some(blur) = blur {
        let mut noise = Rng::new(cfg.seed, 3 << 40 | step);
        for v in (0..n_views).filter(|&v| slots[v] > 0) {
            let features = probes[v].as_ref().map(|p| &p.feats[..]);
            kernels[v] = Some(ViewKernel::new(blur, params, data, v, &centres(v), &mut noise, features));
        }
    }
    // The origin ray closes every blurred pixel's group when something reads it: the rigid
    // kernel's weight, the AWP, the EDI prior.
    let with_origin = matches!(blur, Some(Blur::Rigid(_))) || cfg.edi.is_some();
    let batch = assemble(picks, cfg, data, sd, &kernels, with_origin);
    let inv_gamma = (1.0 / cfg.response_gamma) as f32;
    let img_scale = 1.0 / (3.0 * batch.pixels.max(1) as f32);
    let ev_scale = evc.map_or(0.0, |e| e.weight as f32) / batch.events.max(1) as f32;
    let edi_scale = edi_w as f32 * img_scale;
    let k_rays = blur.map_or(0, |b| b.rays());
    // Blur models whose rays move with their parameters take the rays' gradients.
    let learns_rays = match blur {
        Some(Blur::Trajectory(t)) => t.config.learned,
        Some(_) => true,
        None => false,
    };
    let is_dsk = matches!(blur, Some(Blur::Dsk(_)));
    let awp = method.awp.as_ref().filter(|_| blur_on);
    let mix = awp.map_or(0.0, |a| a.config.mix_at(step)) as f32;
    // The image loss mixes the kernel's colours and the AWP's: (1 - l) [coarse + fine] + l awp.
    let blur_scale = img_scale * (1.0 - mix);
    let emb_dim = awp.map_or(0, |a| a.embedding);
    let kstride = 12 * k_rays + k_rays + 1 + emb_dim;
    let luma = evc.and_then(|e| e.luma).unwrap_or(BT601).map(|x| x as f32);
    let log_eps = evc.and_then(|e| e.log_eps).unwrap_or(1e-5) as f32;
    let cut = pair_rule(evc);
    // A DSK pixel's gradients: K x (offset 2, origin 3, weight 1), then (PDRF) dL/d the first
    // stage's coarse blurry colour.
    let pstride = 6 * k_rays + if progressive.is_some() { 3 } else { 0 };
    let p: &[f32] = params;
    let ecrf = method.ecrf.as_ref();
    let batch_ref = &batch;
    let n_groups = batch.groups.len();
    let pixel_losses = PixelLosses {
        inv_gamma,
        img_scale,
        blur_scale,
        edi_scale,
        pixels: batch.pixels,
        rigid: matches!(blur, Some(Blur::Rigid(_))),
        k_rays,
        kstride,
        embeddings: blur.and_then(Blur::rigid).map_or(0, |k| k.embeddings),
        probes: &probes,
        weights: &batch.weights,
        rays: &batch.rays,
    };
    let sums = bufs.grads.run(model.layout.len(), n_groups, &mut bufs.workers, |range, g, wk| {
        let mut sums = Sums::default();
        wk.kgrad.clear();
        wk.kgrad.resize(if blur_on { n_views * kstride } else { 0 }, 0.0);
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
                let pg = (blurred && is_dsk).then(|| {
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
                    let pose = &data.views[view as usize].pose;
                    if is_dsk {
                        // World ray o = c + R t, d = R (d_cam(x + o) - t): back to the pixel
                        // offset and the camera-frame origin shift.
                        let pg = chunk_pg[gi];
                        for q in 0..k_rays {
                            let r = gr.first + q;
                            let (d_off, d_t) =
                                dsk_ray_backward(&data.intrinsics, pose, &batch_ref.world[r], &wk.d_rays[r - r0]);
                            let out = &mut wk.pgrad[pg + 6 * q..pg + 6 * q + 5];
                            for (o, d) in out.iter_mut().zip(d_off.iter().chain(&d_t)) {
                                *o += d;
                            }
                        }
                        continue;
                    }
                    let orig = data.intrinsics.ray(pose, i, j);
                    let base = view as usize * kstride;
                    for q in 0..k_rays {
                        let r = gr.first + q;
                        let (d_r, d_t) =
                            kernel_ray_backward(&data.intrinsics, &orig, &batch_ref.world[r], &wk.d_rays[r - r0]);
                        let kg = &mut wk.kgrad[base + 12 * q..base + 12 * q + 12];
                        for (i, row) in d_r.iter().enumerate() {
                            for (jx, v) in row.iter().enumerate() {
                                kg[3 * i + jx] += v;
                            }
                        }
                        for i in 0..3 {
                            kg[9 + i] += d_t[i];
                        }
                    }
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
    // The blur model's parameters: the kernels' gradients, summed over workers in order.
    if let Some(blur) = blur {
        let sizes = KernelSizes { k_rays, kstride, emb_dim, pstride };
        let views = BlurViews { kernels: &mut kernels, probes: &mut probes, probe_pass: probe_pass.as_ref() };
        let (workers, pool) = (&mut bufs.workers, &mut bufs.grads);
        blur_backward(blur, learns_rays, views, &sizes, &batch, step, params, grads, workers, pool);
    }
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
