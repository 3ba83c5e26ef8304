//! Finite-difference checks (f64) of the field kernels: every parameter, positions, directions,
//! and the TV regulariser.

use super::field::{Field, FieldShape, FieldWorkspace};
use super::params::Layout;
use super::vm::VmVolume;

/// A tiny deterministic generator for test inputs (not the engine's RNG).
struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-12), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn tiny_field(bias: bool, two_volumes: bool) -> (Field, Layout, Vec<f64>) {
    let mut layout = Layout::default();
    let a = VmVolume::new(&mut layout, "a", [5, 6, 7], [18, 3, 17], 4, ([-1.0; 3], [1.0; 3]));
    let mut volumes = vec![a];
    if two_volumes {
        volumes.push(VmVolume::new(&mut layout, "b", [4, 4, 5], [1, 2, 2], 3, ([-1.2, -0.9, -1.0], [1.1, 1.3, 1.0])));
    }
    let shape =
        FieldShape { pe_pos: 3, pe_dir: 2, density_hidden: vec![8], features: 3, colour_hidden: vec![6, 5], bias };
    let field = Field::new(&mut layout, "f", volumes, shape);
    let mut rng = Lcg(7);
    let mut params = layout.zeros::<f64>();
    for v in &field.volumes {
        // Larger grid values than TensoRF's 0.1 so every path carries a visible gradient.
        v.init(&mut params, &mut || 5.0 * rng.normal(), &mut || 0.5);
        let mut r2 = Lcg(11);
        v.basis.init(&mut params, &mut || r2.uniform());
    }
    let mut r3 = Lcg(13);
    field.init_mlps(&mut params, &mut || r3.uniform());
    (field, layout, params)
}

/// Scalar test loss: fixed random weights on every output (and, with `features`, on the
/// density MLP's features).
fn loss(
    field: &Field,
    params: &[f64],
    pos: &[[f64; 3]],
    dir: &[[f64; 3]],
    ws: &mut FieldWorkspace<f64>,
    features: bool,
) -> f64 {
    let p = pos.len();
    let mut sigma = vec![0.0; p];
    let mut rgb = vec![[0.0; 3]; p];
    field.forward(params, ws, pos, dir, &mut sigma, &mut rgb);
    let (ws_, wr) = weights(p);
    let mut l = sigma.iter().zip(&ws_).map(|(a, b)| a * b).sum::<f64>()
        + rgb.iter().zip(&wr).map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).sum::<f64>();
    if features {
        let wf = feature_weights(p * field.shape.features);
        for i in 0..p {
            let f = field.features(ws, i);
            l += f.iter().zip(&wf[i * f.len()..]).map(|(a, b)| a * b).sum::<f64>();
        }
    }
    l
}

fn feature_weights(n: usize) -> Vec<f64> {
    let mut r = Lcg(123);
    (0..n).map(|_| r.uniform() - 0.5).collect()
}

fn weights(p: usize) -> (Vec<f64>, Vec<[f64; 3]>) {
    let mut r = Lcg(99);
    let ws = (0..p).map(|_| r.uniform() - 0.5).collect();
    let wr = (0..p).map(|_| [r.uniform() - 0.5, r.uniform() - 0.5, r.uniform() - 0.5]).collect();
    (ws, wr)
}

fn inputs(p: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut r = Lcg(3);
    let pos = (0..p).map(|_| [r.uniform() * 1.8 - 0.9, r.uniform() * 1.8 - 0.9, r.uniform() * 1.8 - 0.9]).collect();
    let dir = (0..p)
        .map(|_| {
            let d = [r.normal(), r.normal(), r.normal()];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [d[0] / n, d[1] / n, d[2] / n]
        })
        .collect();
    (pos, dir)
}

/// Rows of a ray share its direction: rows 0-2 and 4-5 here (3 and 6 alone).
fn runs_of_directions(dir: &mut [[f64; 3]]) -> Vec<std::ops::Range<usize>> {
    dir[1] = dir[0];
    dir[2] = dir[0];
    dir[5] = dir[4];
    vec![0..3, 3..4, 4..6, 6..7]
}

fn check_field(bias: bool, two_volumes: bool, features: bool) {
    for all in [false, true] {
        check_field_with(bias, two_volumes, features, all);
    }
}

/// Finite differences against every parameter gradient and the position gradients; the
/// direction gradients summed over each run of rows sharing a direction (the field may put a
/// run's on its first row) against moving the run's direction.
fn check_field_with(bias: bool, two_volumes: bool, features: bool, all: bool) {
    let (field, layout, params) = tiny_field(bias, two_volumes);
    let p = 7;
    let (pos, mut dir) = inputs(p);
    let runs = runs_of_directions(&mut dir);
    let mut ws = FieldWorkspace::default();
    ws.set_all_input_grads(all);
    let mut sigma = vec![0.0; p];
    let mut rgb = vec![[0.0; 3]; p];
    field.forward(&params, &mut ws, &pos, &dir, &mut sigma, &mut rgb);
    let (d_sigma, d_rgb) = weights(p);
    let mut grads = layout.zeros::<f64>();
    let mut d_pos = vec![[0.0; 3]; p];
    let mut d_dir = vec![[0.0; 3]; p];
    let d_feat = features.then(|| feature_weights(p * field.shape.features));
    field.backward(
        &params,
        &mut grads,
        &mut ws,
        &pos,
        &d_sigma,
        &d_rgb,
        d_feat.as_deref(),
        Some(&mut d_pos),
        Some(&mut d_dir),
    );

    let h = 1e-6;
    let close = |fd: f64, an: f64, what: &str| {
        assert!(
            (fd - an).abs() <= 1e-6 * (1.0 + fd.abs().max(an.abs())),
            "{what}: finite difference {fd}, analytic {an}"
        );
    };
    // Every parameter.
    let mut nonzero = 0;
    for i in 0..params.len() {
        let mut pp = params.clone();
        pp[i] += h;
        let lp = loss(&field, &pp, &pos, &dir, &mut ws, features);
        pp[i] -= 2.0 * h;
        let lm = loss(&field, &pp, &pos, &dir, &mut ws, features);
        let fd = (lp - lm) / (2.0 * h);
        let name = &layout.tensors.iter().find(|t| t.range.contains(&i)).unwrap().name;
        close(fd, grads[i], &format!("param {i} ({name})"));
        nonzero += (grads[i].abs() > 1e-8) as usize;
    }
    assert!(nonzero > params.len() / 4, "only {nonzero} of {} gradients are non-zero", params.len());
    // Positions, one row at a time.
    for s in 0..p {
        for a in 0..3 {
            let (mut xp, mut xm) = (pos.clone(), pos.clone());
            xp[s][a] += h;
            xm[s][a] -= h;
            let lp = loss(&field, &params, &xp, &dir, &mut ws, features);
            let lm = loss(&field, &params, &xm, &dir, &mut ws, features);
            close((lp - lm) / (2.0 * h), d_pos[s][a], &format!("dpos[{s}][{a}] (all {all})"));
            assert!(d_pos[s][a].abs() > 1e-9, "dpos[{s}][{a}] is zero");
        }
    }
    // Directions, a run at a time.
    for run in &runs {
        for a in 0..3 {
            let (mut xp, mut xm) = (dir.clone(), dir.clone());
            for s in run.clone() {
                xp[s][a] += h;
                xm[s][a] -= h;
            }
            let lp = loss(&field, &params, &pos, &xp, &mut ws, features);
            let lm = loss(&field, &params, &pos, &xm, &mut ws, features);
            let an: f64 = run.clone().map(|s| d_dir[s][a]).sum();
            close((lp - lm) / (2.0 * h), an, &format!("ddir of rows {run:?} [{a}] (all {all})"));
            assert!(an.abs() > 1e-9, "ddir of rows {run:?} [{a}] is zero");
        }
    }
}

/// A run of rows sharing a direction gives the colours and parameter gradients of
/// multiplying every row's PE(d) (the dense engine's way), up to rounding.
#[test]
fn shared_directions_change_nothing_but_rounding() {
    for bias in [false, true] {
        let (field, layout, params) = tiny_field(bias, true);
        let p = 7;
        let (pos, mut dir) = inputs(p);
        runs_of_directions(&mut dir);
        let (d_sigma, d_rgb) = weights(p);
        let run = |all: bool| {
            let mut ws = FieldWorkspace::default();
            ws.set_all_input_grads(all);
            let (mut sigma, mut rgb) = (vec![0.0; p], vec![[0.0; 3]; p]);
            field.forward(&params, &mut ws, &pos, &dir, &mut sigma, &mut rgb);
            let mut grads = layout.zeros::<f64>();
            field.backward(&params, &mut grads, &mut ws, &pos, &d_sigma, &d_rgb, None, None, None);
            (rgb, grads)
        };
        let ((rgb_runs, g_runs), (rgb_rows, g_rows)) = (run(false), run(true));
        for (a, b) in rgb_runs.iter().flatten().zip(rgb_rows.iter().flatten()) {
            assert!((a - b).abs() <= 1e-14, "colour {a} vs {b}");
        }
        for (i, (a, b)) in g_runs.iter().zip(&g_rows).enumerate() {
            assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "param {i}: {a} with runs vs {b}");
        }
    }
}

#[test]
fn field_gradients_match_finite_differences_without_bias() {
    check_field(false, false, false);
}

#[test]
fn field_gradients_match_finite_differences_with_a_loss_on_the_features() {
    check_field(true, true, true);
}

#[test]
fn field_gradients_match_finite_differences_with_bias_and_two_volumes() {
    check_field(true, true, false);
}

/// Without position and direction gradients the backward skips the positional encodings'
/// input columns and the volumes' position terms: the parameter gradients must not change,
/// whether or not the workspace asks for every input column (the dense engine's setting).
#[test]
fn parameter_gradients_do_not_depend_on_asking_for_input_gradients() {
    for (bias, two_volumes, features) in [(false, false, false), (true, true, true)] {
        let (field, layout, params) = tiny_field(bias, two_volumes);
        let p = 7;
        let (pos, dir) = inputs(p);
        let (d_sigma, d_rgb) = weights(p);
        let d_feat = features.then(|| feature_weights(p * field.shape.features));
        let run = |all: bool, inputs_too: bool| {
            let mut ws = FieldWorkspace::default();
            ws.set_all_input_grads(all);
            let (mut sigma, mut rgb) = (vec![0.0; p], vec![[0.0; 3]; p]);
            field.forward(&params, &mut ws, &pos, &dir, &mut sigma, &mut rgb);
            let mut grads = layout.zeros::<f64>();
            let (mut d_pos, mut d_dir) = (vec![[0.0; 3]; p], vec![[0.0; 3]; p]);
            let (dp, dd) = if inputs_too { (Some(&mut d_pos[..]), Some(&mut d_dir[..])) } else { (None, None) };
            field.backward(&params, &mut grads, &mut ws, &pos, &d_sigma, &d_rgb, d_feat.as_deref(), dp, dd);
            grads
        };
        let full = run(false, true);
        assert!(full.iter().filter(|g| g.abs() > 1e-8).count() > full.len() / 4, "gradients are mostly zero");
        for (all, inputs_too) in [(false, false), (true, false), (true, true)] {
            let g = run(all, inputs_too);
            for (i, (a, b)) in g.iter().zip(&full).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "param {i}: {a} (all {all}, inputs {inputs_too}) vs {b} with input gradients"
                );
            }
        }
    }
}

#[test]
fn tv_gradient_matches_finite_differences() {
    let (field, layout, params) = tiny_field(false, false);
    let v = &field.volumes[0];
    let mut grads = layout.zeros::<f64>();
    let l0 = v.tv(&params, &mut grads, 0.7, 0.3);
    assert!(l0 > 0.0);
    // Training's gradient-only form: the same values, bit for bit.
    let mut g_only = layout.zeros::<f64>();
    v.tv_grad(&params, &mut g_only, 0.7, 0.3);
    assert!(g_only.iter().zip(&grads).all(|(a, b)| a.to_bits() == b.to_bits()));
    let h = 1e-6;
    for i in 0..v.basis.w {
        let mut pp = params.clone();
        let mut scratch = layout.zeros::<f64>();
        pp[i] += h;
        let lp = v.tv(&pp, &mut scratch, 0.7, 0.3);
        pp[i] -= 2.0 * h;
        let lm = v.tv(&pp, &mut scratch, 0.7, 0.3);
        let fd = (lp - lm) / (2.0 * h);
        assert!((fd - grads[i]).abs() <= 1e-6 * (1.0 + fd.abs()), "tv param {i}: fd {fd} analytic {}", grads[i]);
        assert!(grads[i] != 0.0);
    }
}

#[test]
fn tv_of_a_constant_grid_is_zero() {
    let (field, layout, mut params) = tiny_field(false, false);
    params.iter_mut().for_each(|p| *p = 0.25);
    let mut grads = layout.zeros::<f64>();
    assert_eq!(field.volumes[0].tv(&params, &mut grads, 1.0, 1.0), 0.0);
    assert!(grads.iter().all(|&g| g == 0.0));
}

#[test]
fn vm_components_interpolate_grid_values_at_nodes() {
    let (field, _, params) = tiny_field(false, false);
    let v = &field.volumes[0];
    // At grid node (1, 2, 3) of a 5x6x7 grid over [-1, 1]^3 each component is plane * line.
    let node = |i: usize, n: usize| -1.0 + 2.0 * i as f64 / (n - 1) as f64;
    let pos = [node(1, 5), node(2, 6), node(3, 7)];
    let mut out = vec![0.0; v.n_comps()];
    v.components(&params, pos, &mut out);
    let idx = [1usize, 2, 3];
    let mut o = 0;
    for m in 0..3 {
        let [a, b] = super::vm::MAT[m];
        let n = v.comps[m];
        for k in 0..n {
            let plane = params[v.planes[m] + (idx[b] * v.res[a] + idx[a]) * n + k];
            let line = params[v.lines[m] + idx[super::vm::VEC[m]] * n + k];
            assert!((out[o + k] - plane * line).abs() < 1e-12);
        }
        o += n;
    }
}
