//! Finite-difference checks (f64) of the step's glue: the blur kernel's whole chain (heads ->
//! twists -> rigid warp -> NDC -> renderer -> blurry colour -> response -> loss) back to the
//! kernel's parameters (the event term's checks are in `events/loss_tests.rs`). The pieces are
//! the functions `step` uses.

use glam::{DQuat, DVec3};

use super::rays::NDC_NEAR;
use super::*;
use crate::blur::rigid::KernelOut;
use crate::blur::rigid::RigidConfig;
use crate::blur::se3;
use crate::data::rays::Intrinsics;
use crate::data::rays::Ray;
use crate::engine::field::FieldShape;
use crate::engine::model::{Aabb, ModelConfig, VolumeShape};
use crate::engine::renderer::{PassSamples, RayChunk, RayGrad, Renderer};
use crate::events::loss::bayer;
use simulator::trajectory::Pose;

fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn tiny_model() -> ModelConfig {
    let shape =
        FieldShape { pe_pos: 2, pe_dir: 1, density_hidden: vec![6], features: 2, colour_hidden: vec![6], bias: true };
    ModelConfig {
        coarse_volume: VolumeShape { res: 6, comps: [2, 2, 1], features: 3 },
        fine_volume: None,
        coarse: shape,
        fine: None,
        n_coarse: 7,
        n_fine: 5,
        coarse_step: None,
        density_noise: 0.3,
        tv_plane: 0.0,
        tv_line: 0.0,
        explicit: true,
        dense: false,
        skip_threshold: 0.0,
        occupancy: None,
        bounds: Some(Aabb { min: [-1.2, -1.2, -1.0], max: [1.2, 1.2, 1.0] }),
    }
}

/// The tiny model with parameters from `seed`, its grid values scaled up so that colours vary
/// along the rays.
fn textured_field(seed: u64) -> (Model, Vec<f64>) {
    let model = Model::new(&tiny_model());
    let mut params: Vec<f64> = model.init(seed).iter().map(|&p| p as f64).collect();
    for p in &mut params[model.volumes[0].planes[0]..model.volumes[0].basis.w] {
        *p *= 30.0;
    }
    (model, params)
}

const K: Intrinsics = Intrinsics { width: 40, height: 30, focal: 50.0 };

/// The NDC chunk of world rays.
type Columns = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

fn chunk_of(world: &[Ray]) -> Columns {
    let mut cols = (Vec::new(), Vec::new(), Vec::new());
    for r in world {
        let n = K.ndc(r, NDC_NEAR);
        cols.0.push(n.origin.to_array());
        cols.1.push(n.direction.to_array());
        cols.2.push(r.direction.normalize().to_array());
    }
    cols
}

#[test]
fn blur_kernel_chain_matches_finite_differences() {
    let model = Model::new(&tiny_model());
    let mut layout = model.layout.clone();
    let cfg = RigidConfig { k: 3, embedding: 4, hidden: 5, twist_scale: 0.1, init_scale: 1.0 };
    let kernel = RigidKernel::new(&mut layout, &cfg, 2);
    let mut params = layout.zeros::<f64>();
    let field: Vec<f64> = model.init(4).iter().map(|&p| p as f64).collect();
    params[..field.len()].copy_from_slice(&field);
    // Larger grid values than the default init, so colours vary along the rays.
    for p in &mut params[model.volumes[0].planes[0]..model.volumes[0].basis.w] {
        *p *= 30.0;
    }
    kernel.init(&mut params, &mut lcg(5));
    let mut u = lcg(6);
    for p in &mut params[kernel.embeddings..kernel.embeddings + 2 * cfg.embedding] {
        *p = u() - 0.5;
    }
    let pose = Pose { rotation: DQuat::from_rotation_y(0.1), position: DVec3::new(0.05, -0.1, 0.2) };
    let pixel = K.ray(&pose, 14, 11);
    let view = 1;
    let target = [0.4, 0.55, 0.3];
    let inv_gamma = 1.0 / 2.2;
    // Rays of the kernel at `p`: the K warped ones, then the origin ray.
    let rays_at = |p: &[f64]| -> (KernelOut<f64>, Vec<Ray>) {
        let out = kernel.forward(p, view);
        let mut world: Vec<Ray> = out
            .twists
            .iter()
            .map(|&t| {
                let m = se3::exp(t);
                Ray {
                    origin: DVec3::from_array(m.point(pixel.origin.to_array())),
                    direction: DVec3::from_array(m.vector(pixel.direction.to_array())),
                }
            })
            .collect();
        world.push(pixel);
        (out, world)
    };
    let (out, world) = rays_at(&params);
    assert!(out.twists.iter().flatten().any(|x| x.abs() > 1e-3), "twists too small to test: {:?}", out.twists);
    let (o, d, v) = chunk_of(&world);
    let mut renderer = Renderer::<f64>::default();
    let mut rngs: Vec<Rng> = (0..world.len()).map(|r| Rng::new(9, r as u64)).collect();
    renderer.forward(&model, &params, &RayChunk { origins: &o, dirs: &d, viewdirs: &v }, Some(&mut rngs));
    let loss_of = |r: &Renderer<f64>, w: &[f64], dc: &mut [[f64; 3]], df: &mut [[f64; 3]], dw: &mut [f64]| {
        let mut dw2 = vec![0.0; w.len()];
        let a = blur_loss(r.coarse(), Some(w), target, inv_gamma, 1.0, dc, dw);
        let b = blur_loss(r.fine(), Some(w), target, inv_gamma, 1.0, df, &mut dw2);
        for (x, y) in dw.iter_mut().zip(dw2) {
            *x += y;
        }
        a + b
    };
    // Analytic: the step's chain.
    let n = world.len();
    let (mut dc, mut df, mut dw) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![0.0; n]);
    loss_of(&renderer, &out.weights, &mut dc, &mut df, &mut dw);
    let mut grads = layout.zeros::<f64>();
    let mut d_rays = vec![RayGrad::zero(); n];
    renderer.backward(
        &model,
        &params,
        &mut grads,
        &RayChunk { origins: &o, dirs: &d, viewdirs: &v },
        &dc,
        &df,
        Some(&mut d_rays),
        None,
    );
    let d_twists: Vec<[f64; 6]> = (0..cfg.k)
        .map(|q| {
            let (d_r, d_t) = kernel_ray_backward(&K, &pixel, &world[q], &d_rays[q]);
            se3::exp_backward(out.twists[q], &d_r, &d_t)
        })
        .collect();
    kernel.backward(&params, &mut grads, view, &out, &d_twists, &dw);
    // Finite differences over the kernel's parameters, samples held fixed.
    let mut replay = renderer.clone();
    let mut loss_at = |p: &[f64]| {
        let (out, world) = rays_at(p);
        let (o, d, v) = chunk_of(&world);
        replay.replay(&model, p, &RayChunk { origins: &o, dirs: &d, viewdirs: &v });
        let (mut a, mut b, mut c) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![0.0; n]);
        loss_of(&replay, &out.weights, &mut a, &mut b, &mut c)
    };
    let h = 1e-6;
    let mut nonzero = 0;
    for i in kernel.embeddings..layout.len() {
        let (mut p, mut m) = (params.clone(), params.clone());
        p[i] += h;
        m[i] -= h;
        let fd = (loss_at(&p) - loss_at(&m)) / (2.0 * h);
        let name = &layout.tensors.iter().find(|t| t.range.contains(&i)).unwrap().name;
        assert!(
            (fd - grads[i]).abs() <= 2e-6 * (1.0 + fd.abs().max(grads[i].abs())),
            "param {i} ({name}): finite difference {fd}, analytic {}",
            grads[i]
        );
        nonzero += (grads[i].abs() > 1e-8) as usize;
    }
    // The twist heads and the embedding of the view all receive gradient through the rays.
    for t in layout.tensors.iter().filter(|t| t.name.starts_with("rbk.rot") || t.name.starts_with("rbk.trans")) {
        assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-8), "{} receives no gradient", t.name);
    }
    assert!(nonzero > (layout.len() - kernel.embeddings) / 3, "only {nonzero} kernel gradients are non-zero");
}

#[test]
fn dsk_ray_chain_matches_finite_differences() {
    // Pixel offsets and camera-frame origin shifts of K = 3 kernel points -> world rays -> NDC
    // -> renderer -> blurry colour -> loss, against dsk_ray_backward after the renderer.
    let (model, params) = textured_field(4);
    let pose = Pose {
        rotation: DQuat::from_rotation_y(0.1) * DQuat::from_rotation_x(-0.05),
        position: DVec3::new(0.05, -0.1, 0.2),
    };
    let (i, j) = (14, 11);
    let offsets = [[0.7, -1.2], [-0.4, 0.3], [1.5, 0.9]];
    let origins = [[0.01, -0.02, 0.0], [-0.015, 0.005, 0.0], [0.0, 0.02, 0.0]];
    let weights = [0.5, 0.2, 0.3];
    let target = [0.4, 0.55, 0.3];
    let rays = |off: &[[f64; 2]; 3], org: &[[f64; 3]; 3]| -> Vec<Ray> {
        (0..3).map(|q| dsk_ray(&K, &pose, i, j, off[q], org[q])).collect()
    };
    let loss_of = |r: &Renderer<f64>, dc: &mut [[f64; 3]], df: &mut [[f64; 3]]| {
        let mut dw = [0.0; 3];
        blur_loss(r.coarse(), Some(&weights), target, 1.0 / 2.2, 1.0, dc, &mut dw)
            + blur_loss(r.fine(), Some(&weights), target, 1.0 / 2.2, 1.0, df, &mut dw)
    };
    let world = rays(&offsets, &origins);
    let (o, d, v) = chunk_of(&world);
    let mut renderer = Renderer::<f64>::default();
    let mut rngs: Vec<Rng> = (0..3).map(|r| Rng::new(9, r as u64)).collect();
    renderer.forward(&model, &params, &RayChunk { origins: &o, dirs: &d, viewdirs: &v }, Some(&mut rngs));
    let (mut dc, mut df) = (vec![[0.0; 3]; 3], vec![[0.0; 3]; 3]);
    loss_of(&renderer, &mut dc, &mut df);
    let mut grads = model.layout.zeros::<f64>();
    let mut d_rays = vec![RayGrad::zero(); 3];
    let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &v };
    renderer.backward(&model, &params, &mut grads, &chunk, &dc, &df, Some(&mut d_rays), None);
    let mut replay = renderer.clone();
    let mut loss_at = |off: &[[f64; 2]; 3], org: &[[f64; 3]; 3]| {
        let (o, d, v) = chunk_of(&rays(off, org));
        replay.replay(&model, &params, &RayChunk { origins: &o, dirs: &d, viewdirs: &v });
        let (mut a, mut b) = (vec![[0.0; 3]; 3], vec![[0.0; 3]; 3]);
        loss_of(&replay, &mut a, &mut b)
    };
    let analytic: Vec<_> = (0..3).map(|q| dsk_ray_backward(&K, &pose, &world[q], &d_rays[q])).collect();
    check_kernel_inputs(&offsets, &origins, &analytic, &mut loss_at);
    for (q, (d_off, _)) in analytic.iter().enumerate() {
        assert!(d_off.iter().all(|g| g.abs() > 1e-7), "point {q}: an offset has no gradient");
    }
}

/// A loss as a function of the kernel points' offsets and origin shifts.
type KernelLoss<'a> = dyn FnMut(&[[f64; 2]; 3], &[[f64; 3]; 3]) -> f64 + 'a;

/// Central differences of `loss_at` in every kernel point's offset (2) and origin shift (3)
/// against the analytic `(d_offset, d_origin)` of each point.
fn check_kernel_inputs(
    offsets: &[[f64; 2]; 3],
    origins: &[[f64; 3]; 3],
    analytic: &[([f64; 2], [f64; 3])],
    loss_at: &mut KernelLoss,
) {
    let h = 1e-6;
    for (q, (d_off, d_org)) in analytic.iter().enumerate() {
        for c in 0..5 {
            let mut eval = |delta: f64| {
                let (mut off, mut org) = (*offsets, *origins);
                if c < 2 {
                    off[q][c] += delta;
                } else {
                    org[q][c - 2] += delta;
                }
                loss_at(&off, &org)
            };
            let fd = (eval(h) - eval(-h)) / (2.0 * h);
            let an = if c < 2 { d_off[c] } else { d_org[c - 2] };
            assert!(
                (fd - an).abs() <= 2e-6 * (1.0 + fd.abs().max(an.abs())),
                "point {q} input {c}: finite difference {fd}, analytic {an}"
            );
        }
    }
}

#[test]
fn pdrf_first_stage_chain_matches_finite_differences() {
    // PDRF's first stage: K = 3 kernel points -> world rays -> NDC -> coarse pass only ->
    // (blurry colour -> loss) and (features integrated with the render weights -> a linear
    // term standing for the second-stage kernel's use of them), against the renderer's
    // backward with d_features from ray_features_backward, then dsk_ray_backward. The render
    // weights of the integration are held fixed on both sides (as in the method).
    let (model, params) = textured_field(6);
    let pose = Pose {
        rotation: DQuat::from_rotation_y(-0.08) * DQuat::from_rotation_x(0.04),
        position: DVec3::new(-0.05, 0.1, 0.15),
    };
    let (i, j) = (17, 12);
    let offsets = [[0.0, 0.0], [-0.6, 0.8], [1.1, -0.7]];
    let origins = [[0.0, 0.0, 0.0], [0.012, -0.01, 0.0], [-0.02, 0.015, 0.0]];
    let weights = [0.3, 0.45, 0.25];
    let target = [0.5, 0.35, 0.6];
    let nf = model.coarse.shape.features;
    let coef: Vec<f64> = (0..3 * nf).map(|x| (x as f64 * 0.83).sin()).collect();
    let rays = |off: &[[f64; 2]; 3], org: &[[f64; 3]; 3]| -> Vec<Ray> {
        (0..3).map(|q| dsk_ray(&K, &pose, i, j, off[q], org[q])).collect()
    };
    // The loss of a rendered stage; `fixed`: the render weights of the integration.
    let loss_of = |r: &Renderer<f64>, fixed: &[f64], dc: &mut [[f64; 3]]| {
        let mut dw = [0.0; 3];
        let mut l = blur_loss(r.coarse(), Some(&weights), target, 1.0 / 2.2, 1.0, dc, &mut dw);
        let ps = PassSamples { weights: fixed, ..r.last_pass(&model) };
        let mut f = vec![0.0; nf];
        for q in 0..3 {
            ray_features(&ps, q, &mut f);
            l += f.iter().zip(&coef[q * nf..(q + 1) * nf]).map(|(a, b)| a * b).sum::<f64>();
        }
        l
    };
    let world = rays(&offsets, &origins);
    let (o, d, v) = chunk_of(&world);
    let chunk = RayChunk { origins: &o, dirs: &d, viewdirs: &v };
    let mut renderer = Renderer::<f64>::default();
    let mut rngs: Vec<Rng> = (0..3).map(|r| Rng::new(11, r as u64)).collect();
    renderer.forward_coarse(&model, &params, &chunk, Some(&mut rngs));
    let fixed = renderer.last_pass(&model).weights.to_vec();
    let spr = renderer.last_pass(&model).per_ray;
    let mut dc = vec![[0.0; 3]; 3];
    loss_of(&renderer, &fixed, &mut dc);
    let mut dfeat = vec![0.0; 3 * spr * nf];
    for q in 0..3 {
        let ps = renderer.last_pass(&model);
        ray_features_backward(&ps, q, &coef[q * nf..(q + 1) * nf], &mut dfeat[q * spr * nf..(q + 1) * spr * nf]);
    }
    let mut grads = model.layout.zeros::<f64>();
    let mut d_rays = vec![RayGrad::zero(); 3];
    renderer.backward(&model, &params, &mut grads, &chunk, &dc, &[[0.0; 3]; 3], Some(&mut d_rays), Some(&dfeat));
    let mut replay = renderer.clone();
    let mut loss_at = |p: &[f64], off: &[[f64; 2]; 3], org: &[[f64; 3]; 3]| {
        let (o, d, v) = chunk_of(&rays(off, org));
        replay.replay(&model, p, &RayChunk { origins: &o, dirs: &d, viewdirs: &v });
        loss_of(&replay, &fixed, &mut [[0.0; 3]; 3])
    };
    let analytic: Vec<_> = (0..3).map(|q| dsk_ray_backward(&K, &pose, &world[q], &d_rays[q])).collect();
    check_kernel_inputs(&offsets, &origins, &analytic, &mut |off, org| loss_at(&params, off, org));
    for (q, (d_off, _)) in analytic.iter().enumerate() {
        assert!(d_off[0].abs() + d_off[1].abs() > 1e-7, "point {q}: no offset gradient");
    }
    let h = 1e-6;
    let close = |fd: f64, an: f64| (fd - an).abs() <= 2e-6 * (1.0 + fd.abs().max(an.abs()));
    // The field's parameters (colour and feature paths both reach them).
    let mut reached = 0;
    for x in 0..params.len() {
        let (mut pp, mut pm) = (params.clone(), params.clone());
        pp[x] += h;
        pm[x] -= h;
        let fd = (loss_at(&pp, &offsets, &origins) - loss_at(&pm, &offsets, &origins)) / (2.0 * h);
        assert!(close(fd, grads[x]), "parameter {x}: finite difference {fd}, analytic {}", grads[x]);
        reached += usize::from(grads[x].abs() > 1e-9);
    }
    assert!(reached > params.len() / 2, "only {reached} of {} parameters reached", params.len());
}

#[test]
fn blur_loss_without_a_kernel_is_the_plain_loss_and_bayer_follows_rggb() {
    let cols = [[0.2f64, 0.3, 0.4]];
    let (mut dc, mut dw) = ([[0.0; 3]], [0.0]);
    let l = blur_loss(&cols, None, [0.5, 0.5, 0.5], 1.0, 1.0, &mut dc, &mut dw);
    assert!((l - (0.09 + 0.04 + 0.01)).abs() < 1e-12);
    assert!((dc[0][0] - 2.0 * -0.3).abs() < 1e-12);
    assert_eq!([bayer(0.0, 0.0), bayer(1.0, 0.0), bayer(0.0, 1.0), bayer(1.0, 1.0), bayer(2.0, 4.0)], [0, 1, 1, 2, 0]);
}

#[test]
fn a_learned_trajectory_moves_a_test_view_as_its_training_views_nearest_in_time() {
    let build = |name: &str| (crate::presets::preset(name).unwrap().build)(crate::presets::Scale::Cpu);
    let method = Method::new(&build("bad-nerf"), 5);
    let Some(Blur::Trajectory(tr)) = &method.blur else { panic!("bad-nerf has no trajectory") };
    let o = tr.offset;
    let mut params = vec![0.0f32; method.layout().len()];
    // Views 1, 2 and 4 train (mid-exposure times 10, 20, 40); 0 and 3 are test views, whose
    // twists never learn and must not count.
    let train = [(1, 10.0), (2, 20.0), (4, 40.0)];
    assert_eq!(method.test_alignment(&params, &train, 30.0), Some(se3::exp([0.0; 6])), "zero twists: no motion");
    for (i, p) in params[o..o + 60].iter_mut().enumerate() {
        *p = (i as f32 * 0.37).sin() * 0.02;
    }
    let mid = |v: usize, c: usize| 0.5 * (params[o + 12 * v + c] as f64 + params[o + 12 * v + 6 + c] as f64);
    let close = |got: se3::Rigid, want: se3::Rigid, what: &str| {
        for a in 0..3 {
            assert!((got.t[a] - want.t[a]).abs() < 1e-12, "{what}: translation {:?} against {:?}", got.t, want.t);
            for b in 0..3 {
                assert!(
                    (got.r[a][b] - want.r[a][b]).abs() < 1e-12,
                    "{what}: rotation {:?} against {:?}",
                    got.r,
                    want.r
                );
            }
        }
    };
    // Between views 2 and 4, a quarter of the way: the twists interpolated, then exp.
    let want = se3::exp(std::array::from_fn(|c| 0.75 * mid(2, c) + 0.25 * mid(4, c)));
    close(method.test_alignment(&params, &train, 25.0).unwrap(), want, "between");
    assert!(want.t.iter().any(|t| t.abs() > 1e-3), "the test's twists move the camera");
    // Before the first training view and after the last: the nearest one's; on one: its own.
    close(method.test_alignment(&params, &train, 0.0).unwrap(), se3::exp(std::array::from_fn(|c| mid(1, c))), "before");
    close(method.test_alignment(&params, &train, 50.0).unwrap(), se3::exp(std::array::from_fn(|c| mid(4, c))), "after");
    close(method.test_alignment(&params, &train, 20.0).unwrap(), se3::exp(std::array::from_fn(|c| mid(2, c))), "on");
    // Every other method renders the test views at the dataset's poses.
    for name in ["nerf", "dp-nerf", "deblur-nerf", "pdrf", "e2nerf", "ev-deblurnerf"] {
        let m = Method::new(&build(name), 5);
        assert_eq!(m.test_alignment(&vec![0.1; m.layout().len()], &train, 25.0), None, "{name}");
    }
}

/// A camera at (x0, 0, 0) looking down -z has NDC rays of direction (a_x x0 / n, 0, 2) for
/// every pixel (n the near plane, a_x = -f / (W / 2)): the farther it sits to the side, the
/// more voxels its rays cross, and `coarse_step` raises the counts to match.
#[test]
fn sample_counts_follow_the_longest_ray_in_voxels() {
    let at = |x0: f64| Pose { rotation: DQuat::IDENTITY, position: DVec3::new(x0, 0.0, 0.0) };
    let bounds = Aabb { min: [-4.0, -1.0, -1.0], max: [4.0, 1.0, 1.0] };
    let coarse_volume = VolumeShape { res: 40, comps: [2, 2, 1], features: 3 };
    let model = ModelConfig { coarse_step: Some(2.0), n_coarse: 7, n_fine: 5, coarse_volume, ..tiny_model() };
    let g = bounds.grid(model.coarse_volume.res);
    let voxel: Vec<f64> = (0..3).map(|a| (bounds.max[a] - bounds.min[a]) / (g[a] - 1) as f64).collect();
    let ax = -K.focal / (0.5 * K.width as f64);
    let expect = |x0: f64| {
        let len = ((ax * x0 / NDC_NEAR / voxel[0]).powi(2) + (2.0 / voxel[2]).powi(2)).sqrt();
        (len / 2.0).ceil() as usize
    };
    // the widest camera decides; the count and the importance samples grow in proportion
    let rays = rays::border_rays(&K, &[at(0.3), at(-1.5), at(0.0)]);
    let n = expect(1.5);
    assert!(n > 7, "the test needs a count above the configured one, got {n}");
    assert_eq!(rays::samples_for(&rays, &model, &bounds), (n, (5.0 * n as f64 / 7.0).round() as usize));
    // a count the rays do not need is kept; without coarse_step the counts are as given
    let near = rays::border_rays(&K, &[at(0.0)]);
    assert!(expect(0.0) > 7 && expect(0.0) < n, "the centred camera needs fewer samples than the widest");
    assert_eq!(rays::samples_for(&near, &model, &bounds).0, expect(0.0));
    let wide = ModelConfig { n_coarse: 40, n_fine: 9, ..model.clone() };
    assert!(expect(0.0) < 40);
    assert_eq!(rays::samples_for(&near, &wide, &bounds), (40, 9));
    assert_eq!(rays::samples_for(&rays, &ModelConfig { coarse_step: None, ..model.clone() }, &bounds), (7, 5));
    // resolving twice changes nothing: the raised counts already sample finely enough
    let raised = ModelConfig { n_coarse: n, n_fine: (5.0 * n as f64 / 7.0).round() as usize, ..model };
    assert_eq!(rays::samples_for(&rays, &raised, &bounds), (raised.n_coarse, raised.n_fine));
    // a step that is not a number, or so fine it would ask for thousands of samples, is refused
    for bad in [f64::NAN, -1.0, 0.1] {
        let mut cfg = crate::presets::nerf(crate::presets::Scale::Cpu);
        cfg.model.coarse_step = Some(bad);
        assert!(cfg.validate().unwrap_err().contains("model.coarse_step"), "{bad}");
    }
}
