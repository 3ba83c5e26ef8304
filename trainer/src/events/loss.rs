//! The event loss: which events a step samples ([`event_candidates`]), where a pair or window
//! ends and what it targets ([`event_window`]), one pair's loss and its gradient
//! ([`EventTerm`], finite-difference checked) and a worker's pairs through the optional eCRF
//! ([`event_losses`]). The training step (`crate::method`) draws the pairs and renders their
//! rays.

use crate::data::dataset::Dataset;
use crate::data::events::Events;
use crate::engine::real::Real;
use crate::events::ecrf::{Ecrf, EcrfWorkspace};
use simulator::events::EventConfig;

/// The reference luma of monochrome events (BT.601), used when the dataset does not say.
pub const BT601: [f64; 3] = [0.299, 0.587, 0.114];

/// Rec.709 luma, what `evsim`'s monochrome sensor sees.
pub const REC709: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Weights of colour events by Bayer channel (R, G, B), as the reference.
pub const COLOUR_WEIGHTS: [f32; 3] = [0.4, 0.2, 0.4];

/// The thresholds `[c_pos, c_neg]` the dataset's events were simulated with (its
/// `dataset.toml`), if it records them.
pub fn dataset_thresholds(data: &Dataset) -> Option<[f64; 2]> {
    event_model(data).map(|m| [m.c_pos as f64, m.c_neg as f64])
}

/// The event model of the dataset's manifest (`dataset.toml`, written by `evsim`), if any.
pub fn event_model(data: &Dataset) -> Option<&EventConfig> {
    data.manifest.as_ref().map(|m| &m.event_model)
}

/// The events the loss samples from: indices of events with a successor (`min_hops`
/// successors, for event windows) inside the trajectory (and, with `inside_exposures`, whose
/// pair lies inside one training view's exposure).
pub fn event_candidates(data: &Dataset, train_views: &[usize], inside_exposures: bool, min_hops: u32) -> Vec<u32> {
    let ev = &data.events;
    let mut windows: Vec<(f64, f64)> =
        train_views.iter().map(|&v| (data.views[v].t_start_us, data.views[v].t_end_us)).collect();
    windows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let inside = |a: f64, b: f64| {
        // the last window starting at or before a
        let i = windows.partition_point(|w| w.0 <= a);
        i > 0 && b <= windows[i - 1].1
    };
    let nth = |i: usize| (0..min_hops.max(1)).try_fold(i, |e, _| ev.successor(e));
    (0..ev.len() as u32)
        .filter(|&i| match nth(i as usize) {
            None => false,
            Some(k) => {
                let (a, b) = (ev.t_us[i as usize], ev.t_us[k]);
                data.trajectory.contains(a) && data.trajectory.contains(b) && (!inside_exposures || inside(a, b))
            }
        })
        .collect()
}

/// The end of an event window: from event `j`, up to `hops` events on at its pixel (fewer
/// where the pixel's events, or those inside the trajectory (`contains`) and at most
/// `max_span_us` after event `j`, end first), and the target log change, the hopped events'
/// polarities times `threshold` (ON, OFF) summed. None when `j` has no successor.
pub fn event_window(
    ev: &Events,
    contains: impl Fn(f64) -> bool,
    j: usize,
    hops: u32,
    max_span_us: f64,
    threshold: [f32; 2],
) -> Option<(usize, f32)> {
    let (mut k, mut counts) = (j, [0u32; 2]);
    let t0 = ev.t_us[j];
    for h in 0..hops {
        // the first successor is the caller's to check (candidates are inside the trajectory)
        match ev.successor(k).filter(|&n| h == 0 || (contains(ev.t_us[n]) && ev.t_us[n] - t0 <= max_span_us)) {
            Some(n) => {
                k = n;
                counts[usize::from(ev.polarity[n] < 0)] += 1;
            }
            None => break,
        }
    }
    // one ON event: 1 * C_on - 0 * C_off, exactly C_on (and -C_off for one OFF event)
    (k != j).then(|| (k, counts[0] as f32 * threshold[0] - counts[1] as f32 * threshold[1]))
}

/// Which event pairs count and how a residual is weighed (`events.saturation`, `events.dark`,
/// `events.huber`; infinities when unset).
#[derive(Clone, Copy, Debug)]
pub struct PairRule {
    /// Drop a pair whose linear luma reaches this at either end.
    pub saturation: f32,
    /// Drop a pair whose linear luma is below this at either end.
    pub dark: f32,
    /// The Huber transition of [`EventTerm`].
    pub huber: f32,
}

/// One event pair's loss on one pass: with L = <luma, y> of the eCRF outputs y at t_j and t_k
/// and the residual `r = log(L_k + eps) - log(L_j + eps) - target`, `weight r^2` (or the Huber
/// loss of `r`), the target `p Theta` for a single event (the sum over the hopped events for a
/// window).
#[derive(Clone, Copy, Debug)]
pub struct EventTerm<R> {
    /// Luma weights (a one-hot channel for colour events).
    pub luma: [R; 3],
    /// Weight of the event (colour events: by channel).
    pub weight: R,
    /// The log change the events say: polarity times threshold, summed over the pair's
    /// events after the first.
    pub target: R,
    /// Offset of the log.
    pub log_eps: R,
    /// Huber transition: `r^2` while `|r| <= huber`, `2 huber |r| - huber^2` beyond (infinite:
    /// the square everywhere).
    pub huber: R,
}

impl<R: Real> EventTerm<R> {
    /// (loss, dL/dy_j, dL/dy_k), the gradients times `scale`.
    pub fn loss(&self, yj: [R; 3], yk: [R; 3], scale: R) -> (R, [R; 3], [R; 3]) {
        let l = |y: [R; 3]| (0..3).map(|c| self.luma[c] * y[c]).sum::<R>();
        let (lj, lk) = (l(yj), l(yk));
        let r = (lk + self.log_eps).ln() - (lj + self.log_eps).ln() - self.target;
        let d = self.huber;
        let (loss, slope) = if r.abs() <= d {
            (r * r, r)
        } else {
            (R::of(2.0) * d * r.abs() - d * d, if r > R::zero() { d } else { -d })
        };
        let dr = R::of(2.0) * self.weight * slope * scale;
        let (dlk, dlj) = (dr / (lk + self.log_eps), -dr / (lj + self.log_eps));
        (self.weight * loss, self.luma.map(|w| w * dlj), self.luma.map(|w| w * dlk))
    }
}

/// The Bayer channel (RGGB) of a pixel: (even x, even y) R, (odd, odd) B, else G.
pub fn bayer(x: f64, y: f64) -> u8 {
    let (xi, yi) = (x.round() as i64, y.round() as i64);
    match (xi.rem_euclid(2), yi.rem_euclid(2)) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// One event pair of a worker's chunk: its two rays' index in the chunk (t_j at `first`, t_k
/// at `first + 1`), the last event's polarity (the eCRF's input), the target log change and
/// the channel (3: luma, else the Bayer channel of a colour event).
#[derive(Clone, Copy, Debug)]
pub struct EventPair {
    /// Index of the pair's first ray in the chunk.
    pub first: usize,
    /// Polarity of the pair's last event.
    pub polarity: i8,
    /// Target log change.
    pub target: f32,
    /// 0-2: a colour event's Bayer channel; 3: luma.
    pub channel: u8,
}

/// Per-thread buffers of [`event_losses`], reused across chunks.
#[derive(Clone, Debug, Default)]
pub struct EventWorkspace {
    ecrf: [EcrfWorkspace<f32>; 3],
    x: [Vec<f32>; 3],
    y: [Vec<f32>; 3],
    dy: [Vec<f32>; 3],
    dx: Vec<f32>,
    pol: Vec<i8>,
}

/// The event loss of `pairs` on both passes (`colours`: the chunk's coarse and fine colours):
/// adds dL/dC (scaled by `scale` = weight / events) to `d_colours` and the eCRF's gradient to
/// `g`; returns the unweighted loss summed over its pairs and passes. A pair whose linear luma
/// reaches `rule.saturation` or falls below `rule.dark` at either end adds nothing.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
pub fn event_losses(
    ws: &mut EventWorkspace,
    ecrf: Option<&Ecrf>,
    p: &[f32],
    g: &mut [f32],
    pairs: &[EventPair],
    colours: [&[[f32; 3]]; 2],
    d_colours: [&mut [[f32; 3]]; 2],
    luma: [f32; 3],
    log_eps: f32,
    rule: PairRule,
    scale: f32,
) -> f64 {
    if pairs.is_empty() || scale == 0.0 {
        return 0.0;
    }
    let m = 2 * pairs.len();
    let mut total = 0.0f64;
    for (cols, dcol) in colours.into_iter().zip(d_colours) {
        ws.pol.clear();
        for c in 0..3 {
            ws.x[c].clear();
            for e in pairs {
                ws.x[c].extend([cols[e.first][c], cols[e.first + 1][c]]);
                if c == 0 {
                    ws.pol.extend([e.polarity, e.polarity]);
                }
            }
            ws.y[c].resize(m, 0.0);
            match ecrf {
                Some(e) => e.forward(p, c, &ws.x[c], &ws.pol, &mut ws.y[c], &mut ws.ecrf[c]),
                None => ws.y[c].copy_from_slice(&ws.x[c]),
            }
            ws.dy[c].clear();
            ws.dy[c].resize(m, 0.0);
        }
        for (e, pair) in pairs.iter().enumerate() {
            let (weight, lum): (f32, [f32; 3]) = if pair.channel < 3 {
                let mut l = [0.0; 3];
                l[pair.channel as usize] = 1.0;
                (COLOUR_WEIGHTS[pair.channel as usize], l)
            } else {
                (1.0, luma)
            };
            let linear = |i: usize| (0..3).map(|c| lum[c] * ws.x[c][i]).sum::<f32>();
            let (lj, lk) = (linear(2 * e), linear(2 * e + 1));
            if lj >= rule.saturation || lk >= rule.saturation || lj < rule.dark || lk < rule.dark {
                continue;
            }
            let y = |i: usize| [ws.y[0][i], ws.y[1][i], ws.y[2][i]];
            let t = EventTerm { luma: lum, weight, target: pair.target, log_eps, huber: rule.huber };
            let (loss, dj, dk) = t.loss(y(2 * e), y(2 * e + 1), scale);
            total += loss as f64;
            for c in 0..3 {
                ws.dy[c][2 * e] = dj[c];
                ws.dy[c][2 * e + 1] = dk[c];
            }
        }
        for c in 0..3 {
            ws.dx.resize(m, 0.0);
            match ecrf {
                Some(e) => e.backward(p, g, c, &ws.dy[c], &mut ws.dx, &mut ws.ecrf[c]),
                None => ws.dx.copy_from_slice(&ws.dy[c]),
            }
            for (e, pair) in pairs.iter().enumerate() {
                dcol[pair.first][c] += ws.dx[2 * e];
                dcol[pair.first + 1][c] += ws.dx[2 * e + 1];
            }
        }
    }
    total
}

#[cfg(test)]
#[path = "loss_tests.rs"]
mod tests;
