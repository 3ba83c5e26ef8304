//! The exposure window: which rendered frames a view averages, and with what weights.
//!
//! Frame `k` is rendered at `t_k = t0 + k dt` and stands for the interval `[t_k - dt/2, t_k + dt/2)`
//! (midpoint rule). A view with mid-time `t_i` and exposure `tau` has the window
//! `W = [t_i - tau/2, t_i + tau/2]` and gives frame `k` the weight `w_k = |I_k ∩ W| / tau`.
//! Times are integer nanoseconds; window edges can fall on half nanoseconds (odd `tau` or `dt`), so
//! the overlaps are computed exactly in half-nanosecond units (`i128`) and divided once in `f64`.

use super::ExposureError;

/// The times of the rendered frames: frame `k` is rendered at `t_k = t0_ns + k * dt_ns` for
/// `k = 0 .. n_frames` and stands for `[t_k - dt_ns/2, t_k + dt_ns/2)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameClock {
    /// Time of frame 0, ns.
    pub t0_ns: i64,
    /// Frame period, ns (1 ms = 1_000_000 ns at 1000 FPS).
    pub dt_ns: i64,
    /// Number of rendered frames.
    pub n_frames: usize,
}

impl FrameClock {
    /// A checked clock: `dt_ns > 0`, `n_frames > 0` and every frame time fits in `i64`.
    pub fn new(t0_ns: i64, dt_ns: i64, n_frames: usize) -> Result<FrameClock, ExposureError> {
        if dt_ns <= 0 {
            return Err(ExposureError::Clock {
                message: format!("frame period dt = {dt_ns} ns must be > 0; give a positive frame rate"),
            });
        }
        if n_frames == 0 {
            return Err(ExposureError::Clock { message: "no frames; render at least one frame".into() });
        }
        let last = t0_ns as i128 + (n_frames as i128 - 1) * dt_ns as i128 + dt_ns as i128;
        if last > i64::MAX as i128 {
            return Err(ExposureError::Clock {
                message: format!("{n_frames} frames of {dt_ns} ns from {t0_ns} ns overflow i64 ns; use fewer frames"),
            });
        }
        Ok(FrameClock { t0_ns, dt_ns, n_frames })
    }

    /// Time of frame `k`, ns.
    pub fn time_ns(&self, k: usize) -> i64 {
        self.t0_ns + k as i64 * self.dt_ns
    }

    /// The frame rendered exactly at `t_ns`, if there is one.
    pub fn frame_at(&self, t_ns: i64) -> Option<usize> {
        let d = t_ns as i128 - self.t0_ns as i128;
        let dt = self.dt_ns as i128;
        (d >= 0 && d % dt == 0 && d / dt < self.n_frames as i128).then(|| (d / dt) as usize)
    }

    /// The nearest frame time to `t_ns` (ties to the earlier frame), clamped to the clock.
    pub fn nearest_time_ns(&self, t_ns: i64) -> i64 {
        let d = (t_ns as i128 - self.t0_ns as i128).max(0);
        let dt = self.dt_ns as i128;
        let k = ((d + (dt - 1) / 2) / dt).min(self.n_frames as i128 - 1);
        self.time_ns(k as usize)
    }

    /// The covered time `[t_0 - dt/2, t_last + dt/2]` in half nanoseconds.
    fn covered_half(&self) -> (i128, i128) {
        let (t0, dt) = (self.t0_ns as i128, self.dt_ns as i128);
        (2 * t0 - dt, 2 * (t0 + (self.n_frames as i128 - 1) * dt) + dt)
    }
}

/// How long a view's shutter is open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exposure {
    /// `tau = 0`: the view is the single frame rendered at its time (which must be a frame time).
    Sharp,
    /// A box-filter exposure of `tau_ns` nanoseconds centred on the view's time.
    Box {
        /// Exposure time `tau`, ns (> 0).
        tau_ns: i64,
    },
}

/// One output image: its id, its mid-exposure time and its exposure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ViewSpec {
    /// The caller's id for the view (e.g. the image index); unique within a stack.
    pub id: usize,
    /// Mid-exposure time `t_i`, ns.
    pub mid_ns: i64,
    /// The exposure.
    pub exposure: Exposure,
}

impl ViewSpec {
    /// A sharp view at `t_ns` (must be a frame time).
    pub fn sharp(id: usize, t_ns: i64) -> ViewSpec {
        ViewSpec { id, mid_ns: t_ns, exposure: Exposure::Sharp }
    }

    /// A blurry view averaging `[mid_ns - tau_ns/2, mid_ns + tau_ns/2]`.
    pub fn blurry(id: usize, mid_ns: i64, tau_ns: i64) -> ViewSpec {
        ViewSpec { id, mid_ns, exposure: Exposure::Box { tau_ns } }
    }

    /// The exposure window `(start, end)` in microseconds as `timestamps_start`/`timestamps_end`
    /// of `timestamps.npz` want them (equal for a sharp view).
    pub fn window_us(&self) -> (f64, f64) {
        let tau = match self.exposure {
            Exposure::Sharp => 0.0,
            Exposure::Box { tau_ns } => tau_ns as f64,
        };
        ((self.mid_ns as f64 - tau / 2.0) / 1e3, (self.mid_ns as f64 + tau / 2.0) / 1e3)
    }

    /// The frames this view averages and their weights (summing to 1), in frame order.
    ///
    /// Errors: `tau <= 0`, a window outside the rendered frames, a sharp view off the frame times.
    pub fn weights(&self, clock: &FrameClock) -> Result<Vec<(usize, f64)>, ExposureError> {
        let view = format!("view {}", self.id);
        match self.exposure {
            Exposure::Sharp => match clock.frame_at(self.mid_ns) {
                Some(k) => Ok(vec![(k, 1.0)]),
                None => Err(ExposureError::SharpOffFrame {
                    view,
                    t_ns: self.mid_ns,
                    t0_ns: clock.t0_ns,
                    dt_ns: clock.dt_ns,
                    nearest_ns: clock.nearest_time_ns(self.mid_ns),
                }),
            },
            Exposure::Box { tau_ns } => {
                if tau_ns <= 0 {
                    return Err(ExposureError::BadExposure { view, tau: format!("{tau_ns} ns") });
                }
                let (m, tau) = (self.mid_ns as i128, tau_ns as i128);
                weights_half(&view, 2 * m - tau, 2 * m + tau, clock)
            }
        }
    }
}

/// The frames overlapping the window `[window_start_ns, window_end_ns]` and their weights
/// `w_k = |I_k ∩ W| / (end - start)`, in frame order; frames with zero overlap are left out.
///
/// Errors: `end <= start` (`tau <= 0`) and a window reaching outside the rendered frames.
pub fn frame_weights(
    window_start_ns: i64,
    window_end_ns: i64,
    clock: &FrameClock,
) -> Result<Vec<(usize, f64)>, ExposureError> {
    weights_half("window", 2 * window_start_ns as i128, 2 * window_end_ns as i128, clock)
}

/// Convert a duration in milliseconds (as config files give exposures) to whole nanoseconds,
/// rounded to nearest. `what` names the field in the error. NaN, infinities, negatives and
/// overflow are rejected.
pub fn duration_ns_from_ms(what: &str, ms: f64) -> Result<i64, ExposureError> {
    let ns = ms * 1e6;
    if !(ns >= 0.0) || !ns.is_finite() || ns.round() > i64::MAX as f64 / 2.0 {
        return Err(ExposureError::BadExposure { view: what.to_string(), tau: format!("{ms} ms") });
    }
    Ok(ns.round() as i64)
}

/// [`frame_weights`] on half-nanosecond window edges `[start2, end2]`.
fn weights_half(view: &str, start2: i128, end2: i128, clock: &FrameClock) -> Result<Vec<(usize, f64)>, ExposureError> {
    if end2 <= start2 {
        return Err(ExposureError::BadExposure {
            view: view.to_string(),
            tau: format!("{} ns", (end2 - start2) as f64 / 2.0),
        });
    }
    let (c0, c1) = clock.covered_half();
    if start2 < c0 || end2 > c1 {
        return Err(ExposureError::WindowOutsideFrames {
            view: view.to_string(),
            start_ns: start2 as f64 / 2.0,
            end_ns: end2 as f64 / 2.0,
            covered_start_ns: c0 as f64 / 2.0,
            covered_end_ns: c1 as f64 / 2.0,
        });
    }
    // Frame k covers [c0 + 2k dt, c0 + 2(k+1) dt) in half-ns: the first frame contains the window
    // start, the last is the last one starting before the window end.
    let step = 2 * clock.dt_ns as i128;
    let first = ((start2 - c0) / step) as usize;
    let last = (((end2 - c0 + step - 1) / step - 1) as usize).min(clock.n_frames - 1);
    let tau2 = (end2 - start2) as f64;
    let mut out = Vec::with_capacity(last + 1 - first);
    for k in first..=last {
        let lo = c0 + k as i128 * step;
        // Overlap |I_k ∩ W| (exact, half-ns), then w_k = overlap / tau.
        let overlap = (end2.min(lo + step) - start2.max(lo)).max(0);
        if overlap > 0 {
            out.push((k, overlap as f64 / tau2));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn clock(n: usize) -> FrameClock {
        FrameClock::new(0, MS, n).unwrap()
    }

    fn sum(w: &[(usize, f64)]) -> f64 {
        w.iter().map(|&(_, x)| x).sum()
    }

    #[test]
    fn tau_2_5_frames_centred_on_a_frame_gives_three_quarter_edges() {
        // W = [10 - 1.25, 10 + 1.25] ms; frame 9 covers [8.5, 9.5): 0.75 ms, frame 10: 1 ms,
        // frame 11: 0.75 ms; divided by 2.5 ms: 0.3, 0.4, 0.3.
        let w = ViewSpec::blurry(0, 10 * MS, 5 * MS / 2).weights(&clock(20)).unwrap();
        let ks: Vec<usize> = w.iter().map(|p| p.0).collect();
        assert_eq!(ks, vec![9, 10, 11]);
        for (&(_, got), want) in w.iter().zip([0.3, 0.4, 0.3]) {
            assert!((got - want).abs() < 1e-15, "{w:?}");
        }
        assert!((sum(&w) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn tau_2_5_frames_centred_between_frames() {
        // W = [10.5 - 1.25, 10.5 + 1.25] = [9.25, 11.75] ms: frame 9 [8.5, 9.5) 0.25, frame 10 1,
        // frame 11 1, frame 12 [11.5, 12.5) 0.25; / 2.5 -> 0.1, 0.4, 0.4, 0.1.
        let w = ViewSpec::blurry(0, 10 * MS + MS / 2, 5 * MS / 2).weights(&clock(20)).unwrap();
        let want = [(9, 0.1), (10, 0.4), (11, 0.4), (12, 0.1)];
        assert_eq!(w.len(), 4);
        for (&(k, got), (wk, want)) in w.iter().zip(want) {
            assert_eq!(k, wk);
            assert!((got - want).abs() < 1e-15, "{w:?}");
        }
    }

    #[test]
    fn odd_frame_count_centred_on_a_frame_uses_whole_frames() {
        // 5 frames centred on frame 7: exactly frames 5..=9, each 1/5.
        let w = ViewSpec::blurry(0, 7 * MS, 5 * MS).weights(&clock(20)).unwrap();
        assert_eq!(w.iter().map(|p| p.0).collect::<Vec<_>>(), vec![5, 6, 7, 8, 9]);
        assert!(w.iter().all(|&(_, x)| x == 0.2));
        // 40 ms (the default) centred on a frame: 39 whole frames and two halves.
        let w = ViewSpec::blurry(0, 50 * MS, 40 * MS).weights(&clock(100)).unwrap();
        assert_eq!(w.len(), 41);
        assert_eq!((w[0].1, w[40].1), (0.5 / 40.0, 0.5 / 40.0));
        assert!(w[1..40].iter().all(|&(_, x)| x == 1.0 / 40.0));
    }

    #[test]
    fn weights_sum_to_one_for_many_windows() {
        let c = FrameClock::new(3, 997, 400).unwrap(); // odd period: half-ns edges
        let mut n = 0;
        for mid in (20_000..300_000).step_by(7_919) {
            for tau in [1, 2, 3, 500, 997, 1994, 2500, 10_001, 39_999] {
                let w = ViewSpec::blurry(0, mid, tau).weights(&c).unwrap();
                assert!((sum(&w) - 1.0).abs() < 1e-12, "mid {mid} tau {tau}: {}", sum(&w));
                assert!(w.iter().all(|&(_, x)| x > 0.0));
                assert!(w.windows(2).all(|p| p[1].0 == p[0].0 + 1), "contiguous frames");
                n += 1;
            }
        }
        assert!(n > 300);
    }

    #[test]
    fn frame_weights_matches_view_weights() {
        let a = frame_weights(8 * MS, 12 * MS, &clock(20)).unwrap();
        let b = ViewSpec::blurry(0, 10 * MS, 4 * MS).weights(&clock(20)).unwrap();
        assert_eq!(a, b);
        // A window touching a frame boundary does not include the frame behind it.
        let w = frame_weights(MS / 2, 3 * MS / 2, &clock(20)).unwrap();
        assert_eq!(w, vec![(1, 1.0)]);
    }

    #[test]
    fn window_may_use_the_whole_rendered_range() {
        // 10 frames cover [-0.5, 9.5] ms.
        let w = frame_weights(-MS / 2, 9 * MS + MS / 2, &clock(10)).unwrap();
        assert_eq!(w.len(), 10);
        assert!(w.iter().all(|&(_, x)| (x - 0.1).abs() < 1e-15));
    }

    #[test]
    fn bad_tau_is_an_error_naming_the_view() {
        for tau in [0, -5] {
            let e = ViewSpec::blurry(4, 5 * MS, tau).weights(&clock(10)).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, ExposureError::BadExposure { .. }));
            assert!(msg.contains("view 4") && msg.contains("must be > 0"), "{msg}");
        }
        let e = frame_weights(5, 5, &clock(10)).unwrap_err();
        assert!(matches!(e, ExposureError::BadExposure { .. }));
        for ms in [f64::NAN, f64::INFINITY, -1.0, 1e300] {
            let e = duration_ns_from_ms("exposure_ms", ms).unwrap_err();
            assert!(e.to_string().contains("exposure_ms"), "{e}");
        }
        assert_eq!(duration_ns_from_ms("exposure_ms", 40.0).unwrap(), 40 * MS);
        assert_eq!(duration_ns_from_ms("exposure_ms", 0.0000015).unwrap(), 2);
    }

    #[test]
    fn window_outside_frames_is_an_error_with_the_fix() {
        // 10 frames cover [-0.5, 9.5] ms; a 40 ms window at 5 ms does not fit.
        let e = ViewSpec::blurry(2, 5 * MS, 40 * MS).weights(&clock(10)).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, ExposureError::WindowOutsideFrames { .. }));
        assert!(
            msg.contains("view 2") && msg.contains("render more frames") && msg.contains("shorter exposure"),
            "{msg}"
        );
        // Just past either end.
        assert!(frame_weights(-MS / 2 - 1, MS, &clock(10)).is_err());
        assert!(frame_weights(0, 9 * MS + MS / 2 + 1, &clock(10)).is_err());
    }

    #[test]
    fn sharp_views_take_their_frame_or_fail_off_the_grid() {
        assert_eq!(ViewSpec::sharp(0, 7 * MS).weights(&clock(10)).unwrap(), vec![(7, 1.0)]);
        let e = ViewSpec::sharp(8, 7 * MS + 400_000).weights(&clock(10)).unwrap_err();
        assert_eq!(
            e,
            ExposureError::SharpOffFrame {
                view: "view 8".into(),
                t_ns: 7_400_000,
                t0_ns: 0,
                dt_ns: MS,
                nearest_ns: 7 * MS
            }
        );
        assert!(e.to_string().contains("put sharp views on frame times"));
        assert!(ViewSpec::sharp(1, 10 * MS).weights(&clock(10)).is_err(), "past the last frame");
        assert!(ViewSpec::sharp(1, -MS).weights(&clock(10)).is_err(), "before frame 0");
    }

    #[test]
    fn clock_rejects_bad_periods_and_window_us_is_in_microseconds() {
        assert!(FrameClock::new(0, 0, 10).is_err());
        assert!(FrameClock::new(0, -1, 10).is_err());
        assert!(FrameClock::new(0, MS, 0).is_err());
        assert!(FrameClock::new(i64::MAX - 10, MS, 2).is_err());
        assert_eq!(ViewSpec::blurry(0, 100 * MS, 40 * MS).window_us(), (80_000.0, 120_000.0));
        assert_eq!(ViewSpec::sharp(0, 100 * MS).window_us(), (100_000.0, 100_000.0));
    }
}
