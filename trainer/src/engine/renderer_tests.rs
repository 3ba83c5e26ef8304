//! Finite-difference check (f64) of the whole chunk renderer: sample placement, both fields,
//! both volume renderings and the routing of dL/dC back to every parameter, with the sample
//! depths and density noise held fixed (they are not differentiated); also a direct loss on the
//! last pass's per-sample features (the AWP's input).

use super::field::FieldShape;
use super::model::{Model, ModelConfig, VolumeShape};
use super::renderer::{RayChunk, RayGrad, Renderer};
use super::rng::Rng;

fn tiny_config(two_levels: bool) -> ModelConfig {
    let shape = |w: usize, f: usize| FieldShape {
        pe_pos: 2,
        pe_dir: 1,
        density_hidden: vec![w],
        features: f,
        colour_hidden: vec![w],
        bias: true,
    };
    ModelConfig {
        coarse_volume: VolumeShape { res: 6, comps: [2, 2, 1], features: 3 },
        fine_volume: two_levels.then_some(VolumeShape { res: 5, comps: [1, 2, 1], features: 2 }),
        coarse: shape(6, 2),
        fine: two_levels.then(|| shape(5, 3)),
        n_coarse: 7,
        n_fine: if two_levels { 5 } else { 0 },
        density_noise: 0.3,
        tv_plane: 0.0,
        tv_line: 0.0,
        explicit: true,
        bounds: Some(super::model::Aabb { min: [-0.8, -0.7, -1.0], max: [0.9, 0.8, 1.0] }),
    }
}

fn feature_weight(i: usize, c: usize) -> f64 {
    0.05 * ((i * 7 + c * 3) as f64 * 0.9).sin()
}

fn check(two_levels: bool) {
    let model = Model::new(&tiny_config(two_levels));
    // Larger grid values than the default init, so densities and colours vary along the rays.
    let mut params: Vec<f64> = model.init(3).iter().map(|&p| p as f64).collect();
    for v in &model.volumes {
        for t in model.layout.tensors.iter().filter(|t| t.range.start >= v.planes[0] && t.range.end <= v.basis.w) {
            for p in &mut params[t.range.clone()] {
                *p *= 30.0;
            }
        }
    }
    let origins = [[0.1, -0.2, -1.0], [-0.4, 0.3, -1.0], [0.25, 0.05, -1.0]];
    let dirs = [[0.05, 0.02, 2.0], [-0.1, 0.04, 2.0], [0.0, -0.08, 2.0]];
    let viewdirs = [[0.3f64, -0.1, -0.95], [0.0, 0.2, -0.98], [-0.2, 0.0, -0.98]];
    let chunk = RayChunk { origins: &origins, dirs: &dirs, viewdirs: &viewdirs };
    let mut rngs: Vec<Rng> = (0..3).map(|r| Rng::new(11, r)).collect();
    let mut renderer = Renderer::<f64>::default();
    renderer.forward(&model, &params, &chunk, Some(&mut rngs));
    let wc = [[0.3, -0.2, 0.5], [0.1, 0.4, -0.3], [-0.6, 0.2, 0.1]];
    let wf = [[-0.2, 0.5, 0.3], [0.4, -0.1, 0.2], [0.3, 0.3, -0.5]];
    let loss = |r: &Renderer<f64>| -> f64 {
        let dot = |a: &[[f64; 3]], w: &[[f64; 3]; 3]| -> f64 {
            a.iter().zip(w).map(|(x, y)| x[0] * y[0] + x[1] * y[1] + x[2] * y[2]).sum()
        };
        // A direct loss on the last pass's per-sample features (what the AWP reads).
        let ps = r.last_pass(&model);
        let feat: f64 = (0..ps.weights.len())
            .flat_map(|i| (0..ps.width).map(move |c| (i, c)))
            .map(|(i, c)| feature_weight(i, c) * ps.features[i * ps.stride + c])
            .sum();
        dot(r.coarse(), &wc) + dot(r.fine(), &wf) + feat
    };
    let ps = renderer.last_pass(&model);
    let d_features: Vec<f64> =
        (0..ps.weights.len()).flat_map(|i| (0..ps.width).map(move |c| feature_weight(i, c))).collect();
    let mut grads = model.layout.zeros::<f64>();
    let mut d_rays = vec![RayGrad::zero(); 3];
    renderer.backward(&model, &params, &mut grads, &chunk, &wc, &wf, Some(&mut d_rays), Some(&d_features));
    let h = 1e-6;
    let mut replay = renderer.clone();
    let mut checked = 0;
    for i in 0..params.len() {
        let mut p = params.clone();
        p[i] += h;
        replay.replay(&model, &p, &chunk);
        let lp = loss(&replay);
        p[i] -= 2.0 * h;
        replay.replay(&model, &p, &chunk);
        let lm = loss(&replay);
        let fd = (lp - lm) / (2.0 * h);
        let name = &model.layout.tensors.iter().find(|t| t.range.contains(&i)).unwrap().name;
        assert!(
            (fd - grads[i]).abs() <= 1e-6 * (1.0 + fd.abs().max(grads[i].abs())),
            "param {i} ({name}): finite difference {fd}, analytic {}",
            grads[i]
        );
        checked += (grads[i].abs() > 1e-7) as usize;
    }
    assert!(checked > params.len() / 5, "only {checked} of {} gradients are non-zero", params.len());
    // Every tensor of the layout is reached by the loss.
    for t in &model.layout.tensors {
        assert!(grads[t.range.clone()].iter().any(|g| g.abs() > 1e-9), "{} receives no gradient", t.name);
    }
    // The rays' inputs (what a blur kernel moves), samples held at the same t.
    let mut replay = renderer.clone();
    for r in 0..3 {
        for (which, a) in (0..3).flat_map(|w| (0..3).map(move |a| (w, a))) {
            let eval = |delta: f64, replay: &mut Renderer<f64>| {
                let (mut o, mut d, mut v) = (origins, dirs, viewdirs);
                [&mut o, &mut d, &mut v][which][r][a] += delta;
                replay.replay(&model, &params, &RayChunk { origins: &o, dirs: &d, viewdirs: &v });
                loss(replay)
            };
            let fd = (eval(h, &mut replay) - eval(-h, &mut replay)) / (2.0 * h);
            let g = &d_rays[r];
            let an = [g.origin, g.dir, g.viewdir][which][a];
            let name = ["origin", "dir", "viewdir"][which];
            assert!(
                (fd - an).abs() <= 1e-6 * (1.0 + fd.abs().max(an.abs())),
                "ray {r} {name}[{a}]: finite difference {fd}, analytic {an}"
            );
            assert!(an.abs() > 1e-8, "ray {r} {name}[{a}] has no gradient");
        }
    }
}

#[test]
fn renderer_gradients_match_finite_differences_with_two_levels() {
    check(true);
}

#[test]
fn renderer_gradients_match_finite_differences_with_one_pass() {
    check(false);
}

#[test]
fn evaluation_forward_is_deterministic_and_matches_replay() {
    let model = Model::new(&tiny_config(true));
    let params: Vec<f64> = model.init(5).iter().map(|&p| p as f64).collect();
    let origins = [[0.1, -0.2, -1.0]];
    let dirs = [[0.05, 0.02, 2.0]];
    let viewdirs = [[0.0, 0.0, -1.0]];
    let chunk = RayChunk { origins: &origins, dirs: &dirs, viewdirs: &viewdirs };
    let mut a = Renderer::<f64>::default();
    a.forward(&model, &params, &chunk, None);
    let first = (a.coarse()[0], a.fine()[0]);
    a.replay(&model, &params, &chunk);
    assert_eq!(first, (a.coarse()[0], a.fine()[0]));
    let mut b = Renderer::<f64>::default();
    b.forward(&model, &params, &chunk, None);
    assert_eq!(first, (b.coarse()[0], b.fine()[0]));
    assert!(first.1.iter().all(|c| c.is_finite() && *c >= 0.0));
}
