//! The synthetic moving-edge sequence: a vertical step edge moving at constant speed through a
//! 1-row image, whose exposure average has a known box-blurred profile.
//!
//! The edge is at `x(t) = v t / dt` pixels (`v` in px/frame); pixel `i` (centre `c = i + 1/2`) is
//! 1 in frame `k` when `c < x(t_k)`, else 0. Over the window `[t_s, t_e]` the continuous box
//! blur at pixel centre `c` is the fraction of the window with `x(t) > c`:
//! `B(c) = clamp((x(t_e) - c) / (x(t_e) - x(t_s)), 0, 1)`, a linear ramp of width `v tau / dt`
//! pixels. With `v = 1` or `1/3` px/frame each pixel centre is crossed at a frame-interval
//! boundary (`(c / v)` frames is a half-integer), so the midpoint rule is exact and the stack
//! must reproduce `B` to float rounding, partial edge frames included. For other speeds the
//! midpoint rule misplaces each crossing by at most `dt/2`, so `|error| <= dt / (2 tau)`.

use super::*;
use crate::base::image::Image;
use glam::Vec3;

const MS: i64 = 1_000_000;
const N: u32 = 128;

fn edge_frame(k: usize, v: f64) -> Image {
    let x = v * k as f64;
    let mut img = Image::new(N, 1);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        *p = Vec3::splat(if (i as f64 + 0.5) < x { 1.0 } else { 0.0 });
    }
    img
}

/// The analytic box-blurred profile at pixel `i` (a linear ramp between `x(t_s)` and `x(t_e)`).
fn analytic(i: u32, v: f64, mid_ns: i64, tau_ns: i64) -> f64 {
    let x = |t_ns: f64| v * t_ns / MS as f64;
    let (xs, xe) = (x(mid_ns as f64 - tau_ns as f64 / 2.0), x(mid_ns as f64 + tau_ns as f64 / 2.0));
    ((xe - (i as f64 + 0.5)) / (xe - xs)).clamp(0.0, 1.0)
}

/// Stream the edge sequence through a stack and return each view's row.
fn blurred_rows(v: f64, views: &[ViewSpec]) -> Vec<(usize, Image)> {
    let clock = FrameClock::new(0, MS, 400).unwrap();
    let mut stack = ExposureStack::new(views, clock, N, 1).unwrap();
    let mut out = Vec::new();
    for k in 0..clock.n_frames {
        out.extend(stack.push(k, &edge_frame(k, v)).unwrap());
    }
    stack.finish().unwrap();
    assert_eq!(out.len(), views.len());
    out
}

/// Windows with partial edge frames (tau = 2.5, 7.3, 40, 40.5 frames; mid-times on and off the
/// frame grid).
fn edge_views() -> Vec<ViewSpec> {
    vec![
        ViewSpec::blurry(0, 60 * MS, 5 * MS / 2),
        ViewSpec::blurry(1, 63 * MS + 217_000, 7_300_000),
        ViewSpec::blurry(2, 80 * MS, 40 * MS),
        ViewSpec::blurry(3, 90 * MS + 250_001, 40_500_000),
        ViewSpec::blurry(4, 70 * MS + MS / 2, 6 * MS),
    ]
}

#[test]
fn moving_edge_matches_the_analytic_box_blurred_ramp() {
    for v in [1.0, 1.0 / 3.0] {
        let views = edge_views();
        for (id, row) in blurred_rows(v, &views) {
            let view = views[id];
            let Exposure::Box { tau_ns } = view.exposure else { unreachable!() };
            let mut ramp_pixels = 0;
            for i in 0..N {
                let want = analytic(i, v, view.mid_ns, tau_ns);
                let got = row.get(i, 0);
                assert!((got.x as f64 - want).abs() < 1e-4, "v {v} view {id} pixel {i}: {} vs {want}", got.x);
                assert_eq!((got.x, got.x), (got.y, got.z));
                ramp_pixels += (want > 0.0 && want < 1.0) as u32;
            }
            // The ramp really is resolved: about v * tau_frames pixels strictly inside (0, 1).
            let width = v * tau_ns as f64 / MS as f64;
            assert!((ramp_pixels as f64 - width).abs() <= 1.0 + 1e-9, "v {v} view {id}: {ramp_pixels} vs {width}");
        }
    }
}

#[test]
fn moving_edge_at_other_speeds_is_within_half_a_frame() {
    for v in [0.37, 0.5, 2.0] {
        let views = edge_views();
        for (id, row) in blurred_rows(v, &views) {
            let view = views[id];
            let Exposure::Box { tau_ns } = view.exposure else { unreachable!() };
            let bound = 0.5 * MS as f64 / tau_ns as f64 + 1e-6;
            let mut max_err: f64 = 0.0;
            for i in 0..N {
                max_err = max_err.max((row.get(i, 0).x as f64 - analytic(i, v, view.mid_ns, tau_ns)).abs());
            }
            assert!(max_err <= bound, "v {v} view {id}: error {max_err} > {bound}");
        }
    }
}

#[test]
fn moving_edge_through_the_camera_response() {
    // The blur is taken in linear light, then encoded: the pixel in the middle of the ramp is
    // linear 0.5, which encodes to the known 8-bit values (not 0.5 of the encoded values).
    let views = [ViewSpec::blurry(0, 59 * MS + MS / 2, 2 * MS)];
    let (_, row) = blurred_rows(1.0, &views).pop().unwrap();
    // Window [58.5, 60.5] ms: pixel 59 (c = 59.5) is bright for x(t) > 59.5, half the window.
    assert!((row.get(59, 0).x - 0.5).abs() < 1e-7);
    assert_eq!(CameraResponse::Srgb.quantise(row.get(59, 0).x, 1.0), 188);
    assert_eq!(CameraResponse::default().quantise(row.get(59, 0).x, 1.0), 186);
}
