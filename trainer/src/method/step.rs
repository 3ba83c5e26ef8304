//! One training step: draws the batch (pixels, event pairs), builds the blur models' rays,
//! renders and differentiates the chunks in parallel (image loss, EDI prior, AWP, event loss),
//! then the kernel gradients, TV and one Adam update.

use crate::blur::dsk::DskWorkspace;
use crate::blur::se3;
use crate::config::{EventLossConfig, ImageSource, TrainConfig};
use crate::data::dataset::Dataset;
use crate::engine::adam::Adam;
use crate::engine::renderer::{RayChunk, RayGrad};
use crate::engine::rng::Rng;
use crate::events::loss::{bayer, event_losses, event_window, EventPair, PairRule, BT601};

use super::batch::*;
use super::kernel::*;
use super::rays::{response, unzip};
use super::*;
use crate::blur::MAX_RAYS;

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
    let n_pix = cfg.batch_rays;
    let n_ev = if cfg.events.is_some() { cfg.events.as_ref().map_or(0, |e| e.batch) } else { 0 };
    let mut pick = Rng::new(cfg.seed, 1 << 40 | step);
    let mut pick_ev = Rng::new(cfg.seed, 2 << 40 | step);
    let edi_w = cfg.edi.as_ref().map_or(0.0, |d| d.weight_at(step));
    let ev = &data.events;
    let evc = cfg.events.as_ref();
    let [th_on, th_off] = evc.and_then(|e| e.threshold).unwrap_or([0.2, 0.2]);
    // Each worker's range of groups (as `GradBuffers::run` cuts them) holds its share of the
    // pixels, then its share of the events: chunks never mix the two, so only pixel chunks pay
    // for ray gradients.
    let threads = bufs.workers.len();
    let total = n_pix + n_ev;
    let kinds = (0..threads).flat_map(|t| {
        let len = total * (t + 1) / threads - total * t / threads;
        let images = (n_pix * (t + 1) / threads - n_pix * t / threads).min(len);
        (0..len).map(move |i| i < images)
    });
    // What each group is, in the workers' order; a pixel's slot is its index among its view's.
    let mut picks = Vec::with_capacity(total);
    let mut slots = vec![0u32; n_views];
    for is_image in kinds {
        if is_image {
            let v = sd.train_views[pick.below(sd.train_views.len() as u64) as usize];
            let (i, j) = (pick.below(w as u64) as u32, pick.below(h as u64) as u32);
            picks.push(Pick::Pixel { v, i, j, slot: slots[v] });
            slots[v] += 1;
        } else {
            let j = sd.candidates[pick_ev.below(sd.candidates.len() as u64) as usize] as usize;
            // (a window of one width draws nothing: [1, 1] is the single-event loss bit for bit)
            let hops = match evc.and_then(|e| e.window) {
                Some([lo, hi]) if hi > lo => lo + pick_ev.below(u64::from(hi - lo) + 1) as u32,
                Some([lo, _]) => lo,
                None => 1,
            };
            let span_us = evc.and_then(|e| e.window_ms).map_or(f64::INFINITY, |ms| ms * 1e3);
            let inside = |t: f64| data.trajectory.contains(t);
            let (k, target) = event_window(ev, inside, j, hops, span_us, [th_on as f32, th_off as f32])
                .expect("candidates have successors");
            picks.push(Pick::Event { j, k, target });
        }
    }
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
    let mut batch =
        Batch { rays: Vec::new(), world: Vec::new(), weights: Vec::new(), groups: Vec::new(), pixels: 0, events: 0 };
    for p in picks {
        let first = batch.rays.len();
        match p {
            Pick::Pixel { v, i, j, slot } => {
                let view = &data.views[v];
                let img = match (&sd.targets[v], &cfg.images) {
                    (Some(t), _) => t,
                    (None, ImageSource::Sharp) => view.sharp.as_ref().expect("checked in Trainer::new"),
                    (None, _) => &view.image,
                };
                let edi = sd.edi.get(v).and_then(|e| e.as_ref()).map_or([f32::NAN; 3], |e| e.pixel(i, j));
                let ray = data.intrinsics.ray(&view.pose, i, j);
                match &kernels[v] {
                    Some(vk) => {
                        let origin_weight = vk.rays(data, view, &ray, i, j, slot as usize, &mut batch);
                        if with_origin {
                            batch.push(data, ray, origin_weight);
                        }
                    }
                    None => batch.push(data, ray, 1.0),
                }
                batch.pixels += 1;
                let kind = Kind::Image { view: v as u32, i, j, slot, target: img.pixel(i, j), edi };
                batch.groups.push(Group { first, n: batch.rays.len() - first, kind });
            }
            Pick::Event { j, k, target } => {
                let (x, y) = (ev.x[j] as f64, ev.y[j] as f64);
                let rays = [ev.t_us[j], ev.t_us[k]].map(|t| {
                    data.trajectory.pose_at(t).map(|pose| data.intrinsics.ray_through(&pose, x + 0.5, y + 0.5))
                });
                let [Some(a), Some(b)] = rays else { continue };
                batch.push(data, a, 0.0);
                batch.push(data, b, 0.0);
                batch.events += 1;
                let channel = if evc.is_some_and(|e| e.colour) { bayer(x, y) } else { 3 };
                batch.groups.push(Group {
                    first,
                    n: 2,
                    kind: Kind::Event { polarity: ev.polarity[k], target, channel },
                });
            }
        }
    }
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
    let probes_ref = &probes;
    let p: &[f32] = params;
    let ecrf = method.ecrf.as_ref();
    let batch_ref = &batch;
    let n_groups = batch.groups.len();
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
                let Kind::Image { view, target, edi, .. } = gr.kind else { continue };
                let (a, m) = (gr.first - r0, gr.n);
                let origin = a + m - 1;
                let blurred = m > 1;
                any_kernel |= blurred;
                let pg = (blurred && is_dsk).then(|| {
                    wk.pgrad_groups.push((g0 + gi) as u32);
                    wk.pgrad.resize(wk.pgrad.len() + pstride, 0.0);
                    wk.pgrad.len() - pstride
                });
                chunk_pg[gi] = pg.unwrap_or(usize::MAX);
                for pass in 0..2 {
                    let (cols, dcol) =
                        if pass == 0 { (wk.renderer.coarse(), &mut wk.dc) } else { (wk.renderer.fine(), &mut wk.df) };
                    let weights = blurred.then(|| &batch_ref.weights[gr.first..gr.first + m]);
                    let mut dw = [0.0f32; MAX_RAYS];
                    let scale = if blurred { blur_scale } else { img_scale };
                    let probe = probes_ref[view as usize].as_ref().filter(|_| blurred && pass == 0);
                    if let (Some(pr), Kind::Image { slot, .. }, Some(weights), Some(pg)) = (probe, gr.kind, weights, pg)
                    {
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
                            inv_gamma,
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
                            inv_gamma,
                            scale,
                            &mut dcol[a..a + m],
                            &mut dw[..m],
                        ) as f64;
                    }
                    if blurred && matches!(blur, Some(Blur::Rigid(_))) {
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
                    if edi_scale > 0.0 && !edi[0].is_nan() {
                        for c in 0..3 {
                            let (gc, dg) = response(cols[origin][c], inv_gamma);
                            let e = gc - edi[c];
                            sums.edi += (e * e) as f64 / (3 * batch_ref.pixels.max(1)) as f64;
                            dcol[origin][c] += 2.0 * e * dg * edi_scale;
                        }
                    }
                }
                // The AWP's colour: its weights over the fine colours of the same rays.
                if let (Some(awp), true) = (awp, blurred && mix > 0.0) {
                    let ps = wk.renderer.last_pass(model);
                    let (s, nf) = (ps.per_ray, ps.width);
                    if !any_awp {
                        wk.dfeat.clear();
                        wk.dfeat.resize(n * s * nf, 0.0);
                        any_awp = true;
                    }
                    let feats = &ps.features[a * s * ps.stride..];
                    let om = &ps.weights[a * s..(a + m) * s];
                    let e0 = blur.and_then(Blur::rigid).expect("the AWP needs the rigid kernel").embeddings
                        + view as usize * emb_dim;
                    let dir = batch_ref.rays[gr.first + m - 1].viewdir;
                    awp.forward(p, &mut wk.awp_ws, feats, ps.stride, s, om, &p[e0..e0 + emb_dim], dir);
                    let (mut d_cols, mut dw) = ([[0.0f32; 3]; MAX_RAYS], [0.0f32; MAX_RAYS]);
                    sums.awp += blur_loss(
                        &wk.renderer.fine()[a..a + m],
                        Some(&wk.awp_ws.weights),
                        target,
                        inv_gamma,
                        mix * img_scale,
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
                    let base = view as usize * kstride + 13 * k_rays + 1;
                    for (k, d) in wk.awp_ws.d_embedding.iter().enumerate() {
                        wk.kgrad[base + k] += *d as f64;
                    }
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
    // The kernel: twists and weights of every view of the batch, summed over workers in order.
    match blur {
        Some(Blur::Rigid(_)) | Some(Blur::Trajectory(_)) if learns_rays => {
            for (v, vk) in kernels.iter().enumerate() {
                let Some(vk) = vk else { continue };
                let base = v * kstride;
                let total = |i: usize| bufs.workers.iter().map(|wk| wk.kgrad[base + i]).sum::<f64>();
                let d_twists: Vec<[f64; 6]> = (0..k_rays)
                    .map(|q| {
                        let d_r: [[f64; 3]; 3] =
                            std::array::from_fn(|i| std::array::from_fn(|j| total(12 * q + 3 * i + j)));
                        let d_t: [f64; 3] = std::array::from_fn(|i| total(12 * q + 9 + i));
                        se3::exp_backward(vk.twists[q], &d_r, &d_t)
                    })
                    .collect();
                match blur {
                    Some(Blur::Rigid(kernel)) => {
                        let d_weights: Vec<f32> = (0..=k_rays).map(|q| total(12 * k_rays + q) as f32).collect();
                        let e0 = kernel.embeddings + v * emb_dim;
                        for k in 0..emb_dim {
                            grads[e0 + k] += total(13 * k_rays + 1 + k) as f32;
                        }
                        let d_twists: Vec<[f32; 6]> = d_twists.iter().map(|t| t.map(|x| x as f32)).collect();
                        let out = vk.rigid.as_ref().expect("rigid kernel output");
                        kernel.backward(params, grads, v, out, &d_twists, &d_weights);
                    }
                    Some(Blur::Trajectory(t)) => t.backward(grads, v, &d_twists),
                    _ => unreachable!("matched above"),
                }
            }
        }
        Some(Blur::Dsk(dsk)) => {
            // Each pixel's gradients from the worker that rendered it, in slot order per view.
            let mut per_group: Vec<Option<&[f64]>> = vec![None; batch.groups.len()];
            for wk in &bufs.workers {
                for (n, &gi) in wk.pgrad_groups.iter().enumerate() {
                    per_group[gi as usize] = Some(&wk.pgrad[pstride * n..pstride * (n + 1)]);
                }
            }
            let mut by_view: Vec<Vec<&[f64]>> = vec![Vec::new(); n_views];
            for (gr, pg) in batch.groups.iter().zip(&per_group) {
                if let (Kind::Image { view, slot, .. }, Some(pg)) = (gr.kind, pg) {
                    debug_assert_eq!(by_view[view as usize].len(), slot as usize);
                    by_view[view as usize].push(pg);
                }
            }
            let dc = &dsk.config;
            let align_scale =
                if step < dc.align_until { (dc.align_weight / batch.pixels.max(1) as f64) as f32 } else { 0.0 };
            for (v, vk) in kernels.iter_mut().enumerate() {
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
                if let Some(pr) = probes[v].as_mut() {
                    pr.d_feats.clone_from(&ws.d_features);
                    pr.d_blur = pix.iter().map(|pg| std::array::from_fn(|c| pg[6 * k_rays + c] as f32)).collect();
                }
            }
            // PDRF's first stage: its rays' backward (replayed with the same samples), then
            // its kernel's.
            if let Some(pass) = &probe_pass {
                let (p, pr): (&[f32], &[Option<Probe>]) = (params, &probes);
                let out = bufs.grads.run(model.layout.len(), probe_pixels.len(), &mut bufs.workers, |range, g, wk| {
                    pass.run(p, pr, range, g, wk, true)
                });
                bufs.grads.sum_into(grads);
                let out = out.concat();
                let mut at = 0;
                for (v, pr) in probes.iter_mut().enumerate() {
                    let Some(pr) = pr.as_mut() else { continue };
                    let n = view_pixels[v].len() * k_rays;
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
