//! Finite-difference checks (f64) of the event term, alone (the Huber loss on both sides of its
//! transition) and through the eCRF back to colours and eCRF parameters, and the event window.

use super::*;
use crate::engine::params::Layout;
use crate::engine::rng::Rng;
use crate::events::ecrf::{EcrfConfig, EcrfWorkspace};

#[test]
fn huber_event_term_matches_finite_differences_on_both_sides_of_its_transition() {
    let fd_check = |term: &EventTerm<f64>, yj: [f64; 3], yk: [f64; 3]| {
        let (_, dj, dk) = term.loss(yj, yk, 0.5);
        let h = 1e-7;
        for (e, c) in (0..2).flat_map(|e| (0..3).map(move |c| (e, c))) {
            let (mut a, mut b) = ([yj, yk], [yj, yk]);
            a[e][c] += h;
            b[e][c] -= h;
            let fd = 0.5 * (term.loss(a[0], a[1], 1.0).0 - term.loss(b[0], b[1], 1.0).0) / (2.0 * h);
            let an = if e == 0 { dj[c] } else { dk[c] };
            assert!((fd - an).abs() <= 1e-6 * (1.0 + fd.abs()), "end {e} channel {c}: fd {fd} analytic {an}");
        }
    };
    let yj = [0.3, 0.5, 0.2];
    let luma = [0.299, 0.587, 0.114];
    let l = |y: [f64; 3]| (0..3).map(|c| luma[c] * y[c]).sum::<f64>();
    let square = EventTerm { luma, weight: 0.7, target: 0.2, log_eps: 1e-3, huber: f64::INFINITY };
    let huber = EventTerm { huber: 0.1, ..square };
    // residuals 0.05 (inside the transition) and about 0.5 and -0.6 (outside, both signs)
    for (scale_k, inside) in [((0.25f64).exp(), true), ((0.7f64).exp(), false), ((-0.4f64).exp(), false)] {
        let yk = yj.map(|x| x * scale_k);
        let r = (l(yk) + 1e-3).ln() - (l(yj) + 1e-3).ln() - 0.2;
        assert_eq!(r.abs() <= 0.1, inside, "residual {r}");
        fd_check(&huber, yj, yk);
        fd_check(&square, yj, yk);
        let (lh, ls) = (huber.loss(yj, yk, 1.0).0, square.loss(yj, yk, 1.0).0);
        if inside {
            assert!((lh - ls).abs() < 1e-15, "inside the transition the Huber loss is the square: {lh} vs {ls}");
        } else {
            // linear beyond it: 2 d |r| - d^2, below the square
            assert!((lh - 0.7 * (0.2 * r.abs() - 0.01)).abs() < 1e-12 && lh < ls, "{lh} vs {ls}");
            // the pull is capped at 2 d weight / (L + eps) whatever the residual
            let (_, _, dk) = huber.loss(yj, yk, 1.0);
            let cap = 2.0 * 0.1 * 0.7 / (l(yk) + 1e-3);
            assert!((dk[1] / luma[1]).abs() <= cap * (1.0 + 1e-12), "{dk:?}");
        }
    }
}

#[test]
fn event_term_through_the_ecrf_matches_finite_differences() {
    let mut layout = Layout::default();
    for polarity_input in [true, false] {
        let cfg = EcrfConfig { polarity: polarity_input, ..EcrfConfig::reference() };
        let ecrf = Ecrf::new(&mut layout, &cfg);
        let mut p32 = layout.zeros::<f32>();
        ecrf.init(&mut p32, 3);
        let mut rng = Rng::new(11, 0);
        let mut u = || rng.uniform_f64();
        // Move off the identity so the MLP matters.
        let params: Vec<f64> = p32.iter().map(|&x| x as f64 + 0.2 * (u() - 0.5)).collect();
        for (colour, pol) in [(false, 1i8), (false, -1), (true, 1)] {
            let cols = [[0.3, 0.5, 0.2], [0.35, 0.42, 0.25]];
            let term = EventTerm {
                luma: if colour { [0.0, 1.0, 0.0] } else { [0.299, 0.587, 0.114] },
                weight: if colour { 0.2 } else { 1.0 },
                target: pol as f64 * 0.2,
                log_eps: 1e-5,
                huber: if colour { 0.05 } else { f64::INFINITY },
            };
            let pols = [pol, pol];
            let forward = |p: &[f64], cols: &[[f64; 3]; 2], ws: &mut [EcrfWorkspace<f64>; 3]| -> ([[f64; 3]; 2], f64) {
                let mut y = [[0.0; 3]; 2];
                for c in 0..3 {
                    let mut out = [0.0; 2];
                    ecrf.forward(p, c, &[cols[0][c], cols[1][c]], &pols, &mut out, &mut ws[c]);
                    y[0][c] = out[0];
                    y[1][c] = out[1];
                }
                (y, term.loss(y[0], y[1], 1.0).0)
            };
            let mut ws: [EcrfWorkspace<f64>; 3] = Default::default();
            let (y, _) = forward(&params, &cols, &mut ws);
            let (_, dj, dk) = term.loss(y[0], y[1], 1.0);
            let mut grads = layout.zeros::<f64>();
            let mut d_cols = [[0.0; 3]; 2];
            for c in 0..3 {
                let mut dx = [0.0; 2];
                ecrf.backward(&params, &mut grads, c, &[dj[c], dk[c]], &mut dx, &mut ws[c]);
                d_cols[0][c] = dx[0];
                d_cols[1][c] = dx[1];
            }
            let h = 1e-6;
            let mut ws2: [EcrfWorkspace<f64>; 3] = Default::default();
            for r in ecrf.ranges() {
                for i in r {
                    let (mut a, mut b) = (params.clone(), params.clone());
                    a[i] += h;
                    b[i] -= h;
                    let fd = (forward(&a, &cols, &mut ws2).1 - forward(&b, &cols, &mut ws2).1) / (2.0 * h);
                    assert!(
                        (fd - grads[i]).abs() <= 1e-6 * (1.0 + fd.abs()),
                        "eCRF param {i}: fd {fd} analytic {}",
                        grads[i]
                    );
                }
            }
            for (e, c) in (0..2).flat_map(|e| (0..3).map(move |c| (e, c))) {
                let (mut a, mut b) = (cols, cols);
                a[e][c] += h;
                b[e][c] -= h;
                let fd = (forward(&params, &a, &mut ws2).1 - forward(&params, &b, &mut ws2).1) / (2.0 * h);
                let an = d_cols[e][c];
                assert!(
                    (fd - an).abs() <= 1e-6 * (1.0 + fd.abs()),
                    "colour {e}.{c} ({colour}, {pol}): fd {fd} analytic {an}"
                );
                if term.luma[c] != 0.0 {
                    assert!(an.abs() > 1e-6, "colour {e}.{c} gets no gradient");
                }
            }
        }
    }
}

#[test]
fn an_event_window_hops_up_to_its_count_and_sums_polarities_times_thresholds() {
    // one pixel: + + - + at 0..4 ms, then one more at 10 ms
    let pol = [1i8, 1, -1, 1, 1];
    let n = pol.len();
    let ev = crate::data::events::Events {
        x: vec![0.0; n],
        y: vec![0.0; n],
        t_us: vec![0.0, 1e3, 2e3, 3e3, 10e3],
        polarity: pol.to_vec(),
        successors: (0..n).map(|i| if i + 1 < n { (i + 1) as u32 } else { u32::MAX }).collect(),
        ..Default::default()
    };
    let th = [0.25f32, 0.2];
    let all = |_: f64| true;
    // one hop: the successor's polarity times its threshold, exactly
    assert_eq!(event_window(&ev, all, 0, 1, f64::INFINITY, th), Some((1, 0.25)));
    assert_eq!(event_window(&ev, all, 1, 1, f64::INFINITY, th), Some((2, -0.2)));
    // three hops from event 0: + - + = 2 * 0.25 - 0.2
    let (k, target) = event_window(&ev, all, 0, 3, f64::INFINITY, th).unwrap();
    assert_eq!(k, 3);
    assert!((target - 0.3).abs() < 1e-6, "{target}");
    // the pixel's events end first: four hops at most from event 0
    assert_eq!(event_window(&ev, all, 0, 9, f64::INFINITY, th).map(|w| w.0), Some(4));
    // the trajectory ends first (at 5 ms): the window stops at event 3
    assert_eq!(event_window(&ev, |t| t <= 5e3, 0, 9, f64::INFINITY, th).map(|w| w.0), Some(3));
    // at most 2.5 ms after event 0: events 1 and 2 (1 and 2 ms), not 3 (3 ms)
    assert_eq!(event_window(&ev, all, 0, 9, 2.5e3, th).map(|w| w.0), Some(2));
    // the first hop is always taken, however far: event 3 (3 ms) to 4 (10 ms)
    assert_eq!(event_window(&ev, all, 3, 9, 1.0, th), Some((4, 0.25)));
    // no successor, no window
    assert_eq!(event_window(&ev, all, 4, 2, f64::INFINITY, th), None);
}
