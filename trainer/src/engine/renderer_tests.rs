//! Finite-difference check (f64) of the whole chunk renderer: sample placement, both fields,
//! both volume renderings and the routing of dL/dC back to every parameter, with the sample
//! depths and density noise held fixed (they are not differentiated); also a direct loss on the
//! last pass's per-sample features (the AWP's input).

use super::field::FieldShape;
use super::model::{Model, ModelConfig, VolumeShape};
use super::occupancy::{OccupancyConfig, OccupancyGrid};
use super::renderer::{RayChunk, RayGrad, Renderer};
use super::rng::Rng;

fn tiny_config(two_levels: bool) -> ModelConfig {
    tiny_config_with(two_levels, if two_levels { 5 } else { 0 })
}

/// The tiny model with `n_fine` importance samples (one level and `n_fine > 0`: one field for
/// both passes, the fine pass re-using the coarse evaluations).
fn tiny_config_with(two_levels: bool, n_fine: usize) -> ModelConfig {
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
        n_fine,
        coarse_step: None,
        density_noise: 0.3,
        tv_plane: 0.0,
        tv_line: 0.0,
        explicit: true,
        dense: false,
        skip_threshold: 0.0,
        occupancy: None,
        bounds: Some(super::model::Aabb { min: [-0.8, -0.7, -1.0], max: [0.9, 0.8, 1.0] }),
    }
}

fn feature_weight(i: usize, c: usize) -> f64 {
    0.05 * ((i * 7 + c * 3) as f64 * 0.9).sin()
}

fn check(cfg: ModelConfig) {
    check_with(cfg, 0.0, None)
}

/// [`check`] with `bias` added to every raw density (a denser field ends rays sooner).
fn check_with_density(cfg: ModelConfig, bias: f64) {
    check_with(cfg, bias, None)
}

/// [`check`] with `bias` added to every raw density and, with `grid`, an occupancy grid of that
/// threshold built from the parameters checked.
fn check_with(cfg: ModelConfig, bias: f64, grid: Option<f64>) {
    let mut model = Model::new(&cfg);
    // Larger grid values than the default init, so densities and colours vary along the rays.
    let mut params: Vec<f64> = model.init(3).iter().map(|&p| p as f64).collect();
    for v in &model.volumes {
        for t in model.layout.tensors.iter().filter(|t| t.range.start >= v.planes[0] && t.range.end <= v.basis.w) {
            for p in &mut params[t.range.clone()] {
                *p *= 30.0;
            }
        }
    }
    // The density MLP's output layer (one hidden layer in the tiny shapes): raw density first.
    for t in model.layout.tensors.iter().filter(|t| t.name.ends_with(".density.1.b")) {
        params[t.range.start] += bias;
    }
    if let Some(threshold) = grid {
        let cfg = OccupancyConfig { res: 12, every: 1, threshold };
        let g = OccupancyGrid::build(&model, &params, model.bounds(), &cfg, 3, 0);
        let f = g.occupied_fraction();
        assert!(f > 0.05 && f < 0.95, "the grid must have empty and occupied cells: {f}");
        model.occupancy = Some(g);
    }
    let origins = [[0.1, -0.2, -1.0], [-0.4, 0.3, -1.0], [0.25, 0.05, -1.0]];
    let dirs = [[0.05, 0.02, 2.0], [-0.1, 0.04, 2.0], [0.0, -0.08, 2.0]];
    let viewdirs = [[0.3f64, -0.1, -0.95], [0.0, 0.2, -0.98], [-0.2, 0.0, -0.98]];
    let chunk = RayChunk { origins: &origins, dirs: &dirs, viewdirs: &viewdirs };
    let mut rngs: Vec<Rng> = (0..3).map(|r| Rng::new(11, r)).collect();
    let mut renderer = Renderer::<f64>::default();
    renderer.forward(&model, &params, &chunk, Some(&mut rngs));
    // The check must see skipped samples (or, dense, none).
    let counts = renderer.counts();
    if model.config.dense {
        assert_eq!((counts.alive, counts.density), (counts.rendered, counts.rendered), "{counts:?}");
    } else if bias == 0.0 {
        assert!(counts.alive < counts.density && counts.alive > counts.density / 4, "{counts:?}");
    }
    // With a grid, some samples are not evaluated.
    let without = {
        let bare = Model { occupancy: None, ..model.clone() };
        let mut r = Renderer::<f64>::default();
        r.forward(&bare, &params, &chunk, Some(&mut (0..3).map(|r| Rng::new(11, r)).collect::<Vec<_>>()));
        r.counts()
    };
    assert_eq!(counts.density < without.density, grid.is_some() && !model.config.dense, "{counts:?} {without:?}");
    // With a skip threshold, some rays end early and some alive samples get no colour.
    if model.config.skip_threshold > 0.0 {
        assert!(counts.ended > 0 && counts.coloured < counts.alive, "{counts:?}");
    } else {
        assert_eq!(counts.ended, 0, "{counts:?}");
    }
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
    check(tiny_config(true));
}

#[test]
fn renderer_gradients_match_finite_differences_with_one_field_for_both_passes() {
    check(tiny_config_with(false, 6));
}

#[test]
fn renderer_gradients_match_finite_differences_on_the_dense_path() {
    check(ModelConfig { dense: true, ..tiny_config_with(false, 6) });
    check(ModelConfig { dense: true, ..tiny_config(true) });
}

/// Early ray termination and samples without colour: the gradients are those of the rendering
/// so truncated (the replay holds the ends and the coloured samples fixed, as sampling).
#[test]
fn renderer_gradients_match_finite_differences_with_a_skip_threshold() {
    check_with_density(ModelConfig { skip_threshold: 0.05, ..tiny_config_with(false, 6) }, 2.0);
    check_with_density(ModelConfig { skip_threshold: 0.05, ..tiny_config(true) }, 2.0);
    check_with_density(ModelConfig { skip_threshold: 0.05, ..tiny_config(false) }, 2.0);
}

/// Empty-space skipping: the samples in empty cells are dead; the rest are differentiated as
/// without the grid.
#[test]
fn renderer_gradients_match_finite_differences_with_an_occupancy_grid() {
    check_with(tiny_config_with(false, 6), 0.0, Some(0.2));
    check_with(tiny_config(true), 0.0, Some(0.2));
    check_with(tiny_config(false), 0.0, Some(0.2));
}

#[test]
fn renderer_gradients_match_finite_differences_with_one_pass() {
    check(tiny_config(false));
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

/// Skipping samples whose density is zero and re-using the coarse evaluations changes nothing
/// but rounding: without density noise (the one draw the two paths make differently), the
/// colours, the last pass's weights and features, and every gradient agree with the dense path.
#[test]
fn skipping_samples_matches_the_dense_path() {
    for cfg in [tiny_config(true), tiny_config(false), tiny_config_with(false, 6)] {
        let cfg = ModelConfig { density_noise: 0.0, ..cfg };
        let dense_cfg = ModelConfig { dense: true, ..cfg.clone() };
        let (model, dense_model) = (Model::new(&cfg), Model::new(&dense_cfg));
        let mut params: Vec<f64> = model.init(7).iter().map(|&p| p as f64).collect();
        for p in &mut params[model.volumes[0].planes[0]..model.volumes[0].basis.w] {
            *p *= 30.0;
        }
        let rays = 5;
        let origins: Vec<[f64; 3]> = (0..rays).map(|r| [0.15 * r as f64 - 0.3, 0.1 - 0.05 * r as f64, -1.0]).collect();
        let dirs: Vec<[f64; 3]> = (0..rays).map(|r| [0.02 * r as f64 - 0.04, 0.03, 2.0]).collect();
        let viewdirs = vec![[0.1, -0.1, -0.99]; rays];
        let chunk = RayChunk { origins: &origins, dirs: &dirs, viewdirs: &viewdirs };
        let d_c: Vec<[f64; 3]> = (0..rays).map(|r| [0.3, -0.2 * r as f64, 0.1]).collect();
        let d_f: Vec<[f64; 3]> = (0..rays).map(|r| [-0.1 * r as f64, 0.4, 0.2]).collect();
        let run = |model: &Model| {
            let mut rngs: Vec<Rng> = (0..rays).map(|r| Rng::new(5, r as u64)).collect();
            let mut renderer = Renderer::<f64>::default();
            renderer.forward(model, &params, &chunk, Some(&mut rngs));
            let ps = renderer.last_pass(model);
            // As the AWP's: a feature's gradient carries its sample's render weight.
            let d_feat: Vec<f64> = (0..ps.features.len())
                .map(|i| ps.weights[i / ps.width] * feature_weight(i / ps.width, i % ps.width))
                .collect();
            let (feats, weights) = (ps.features.to_vec(), ps.weights.to_vec());
            let mut grads = model.layout.zeros::<f64>();
            let mut d_rays = vec![RayGrad::zero(); rays];
            renderer.backward(model, &params, &mut grads, &chunk, &d_c, &d_f, Some(&mut d_rays), Some(&d_feat));
            let cols = [renderer.coarse().to_vec(), renderer.fine().to_vec()];
            (cols, feats, weights, grads, d_rays, renderer.counts())
        };
        let (a, b) = (run(&model), run(&dense_model));
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-10 * (1.0 + x.abs().max(y.abs()));
        for (ca, cb) in a.0.iter().zip(&b.0) {
            assert!(ca.iter().flatten().zip(cb.iter().flatten()).all(|(x, y)| close(*x, *y)), "{ca:?} vs {cb:?}");
        }
        assert!(a.2.iter().zip(&b.2).all(|(x, y)| close(*x, *y)), "weights differ");
        // Features agree wherever they count: a skipped sample has zero weight (and zeros).
        let width = a.1.len() / a.2.len();
        for (i, w) in a.2.iter().enumerate() {
            let (fa, fb) = (&a.1[i * width..], &b.1[i * width..]);
            for c in 0..width {
                assert!(if *w == 0.0 { fa[c] == 0.0 } else { close(fa[c], fb[c]) }, "sample {i} feature {c}");
            }
        }
        for (i, (x, y)) in a.3.iter().zip(&b.3).enumerate() {
            assert!(close(*x, *y), "parameter {i}: {x} skipping, {y} dense");
        }
        for (ra, rb) in a.4.iter().zip(&b.4) {
            for (x, y) in
                [ra.origin, ra.dir, ra.viewdir].iter().flatten().zip([rb.origin, rb.dir, rb.viewdir].iter().flatten())
            {
                assert!(close(*x, *y), "ray gradient {x} vs {y}");
            }
        }
        // And it did skip: fewer samples reached the colour MLP (and, with one field, fewer
        // densities were evaluated) than the dense path's.
        let (ca, cb) = (a.5, b.5);
        assert_eq!((ca.rays, ca.rendered), (cb.rays, cb.rendered));
        assert!(ca.alive < cb.alive, "{ca:?} vs dense {cb:?}");
        let one_field = cfg.fine.is_none() && cfg.n_fine > 0;
        assert_eq!(ca.density < cb.density, one_field, "{ca:?} vs dense {cb:?}");
    }
}
