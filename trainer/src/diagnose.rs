//! How well a radiance field explains a dataset's events (`evtrain diagnose events`).
//!
//! The event loss asks the field for the log-luma change between the two times of an event
//! pair (an event and the next event at the same pixel) and compares it with the successor's
//! polarity times its threshold, `p C`. This module draws such pairs (a seeded sample of all
//! pairs with a successor inside the trajectory), predicts the change with any predictor (the
//! trained field through its eCRF, or an analytic oracle in the tests) and scores it the way
//! `evsim dataset-fidelity` scores a simulator's pairs:
//!
//! - `r2 = 1 - sum (pred - target)^2 / sum target^2` (1: exact; 0: no better than predicting no
//!   change at all);
//! - sign agreement: the share of pairs whose predicted change has the polarity's sign;
//!
//! overall and broken down by the time gap between the two events, by the predicted luma (dark,
//! mid, above 1: what a sigmoid colour output cannot reach) and by the distance to the nearest
//! intensity edge in the dataset's sharp view nearest in time (when the dataset has sharp
//! views).

use rayon::prelude::*;

use crate::config::TrainConfig;
use crate::data::dataset::Dataset;
use crate::data::events::Events;
use crate::data::image::RgbImage;
use crate::engine::model::Model;
use crate::engine::renderer::{RayChunk, Renderer};
use crate::engine::rng::Rng;
use crate::events::ecrf::{Ecrf, EcrfWorkspace};
use crate::events::loss::BT601;
use crate::method::rays::{prepare, unzip};

/// One scored event pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoredPair {
    /// The predicted log-luma change from the first event's time to the second's.
    pub predicted: f64,
    /// Its target: the second event's polarity times its threshold.
    pub target: f64,
    /// Time between the two events (us).
    pub gap_us: f64,
    /// The larger of the two predicted lumas (linear).
    pub luma: f64,
    /// Distance (pixels) to the nearest intensity edge of the sharp view nearest in time, when
    /// the dataset has sharp views.
    pub edge_px: Option<f64>,
    /// Whether the pixel is saturated (a channel at 1) in that sharp view: the scene's light
    /// there may exceed what a colour output in [0, 1] represents.
    pub saturated: Option<bool>,
    /// Whether a test view (one training never saw) is involved: for windows between sharp
    /// frames (`None` for event pairs).
    pub test_view: Option<bool>,
}

/// The scores of a set of pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairStats {
    /// Pairs.
    pub n: usize,
    /// `1 - sum (pred - target)^2 / sum target^2` (NaN without pairs).
    pub r2: f64,
    /// Share of pairs with a change (a non-zero target) whose prediction has its sign (NaN
    /// without pairs).
    pub sign: f64,
}

impl PairStats {
    /// The scores of `pairs`.
    pub fn of<'a>(pairs: impl IntoIterator<Item = &'a ScoredPair>) -> PairStats {
        let (mut n, mut err, mut energy, mut signed, mut agree) = (0usize, 0.0f64, 0.0f64, 0usize, 0usize);
        for p in pairs {
            n += 1;
            err += (p.predicted - p.target).powi(2);
            energy += p.target * p.target;
            signed += usize::from(p.target != 0.0);
            agree += usize::from(p.predicted * p.target > 0.0);
        }
        if n == 0 || energy <= 0.0 {
            return PairStats { n, r2: f64::NAN, sign: f64::NAN };
        }
        PairStats { n, r2: 1.0 - err / energy, sign: agree as f64 / signed as f64 }
    }
}

/// The whole report: overall and per bin of each breakdown (label, scores).
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Every pair.
    pub overall: PairStats,
    /// By time between the two events.
    pub by_gap: Vec<(String, PairStats)>,
    /// By the larger predicted luma of the two.
    pub by_luma: Vec<(String, PairStats)>,
    /// By distance to the nearest intensity edge (empty without sharp views).
    pub by_edge: Vec<(String, PairStats)>,
    /// By saturation of the pixel in the nearest sharp view (empty without sharp views).
    pub by_saturation: Vec<(String, PairStats)>,
    /// Windows by whether a test view is involved (empty for event pairs).
    pub by_view: Vec<(String, PairStats)>,
}

/// Bins of the time gap (us): upper bounds, the last open.
const GAP_BINS_US: [(f64, &str); 4] =
    [(1e3, "< 1 ms"), (4e3, "1-4 ms"), (16e3, "4-16 ms"), (f64::INFINITY, ">= 16 ms")];
/// Bins of the luma: upper bounds.
const LUMA_BINS: [(f64, &str); 4] =
    [(0.02, "< 0.02 (dark)"), (0.2, "0.02-0.2"), (1.0, "0.2-1"), (f64::INFINITY, ">= 1")];
/// Bins of the distance to an edge (pixels): upper bounds.
const EDGE_BINS_PX: [(f64, &str); 3] =
    [(1.5, "on an edge (<= 1 px)"), (4.5, "near (2-4 px)"), (f64::INFINITY, "away (> 4 px)")];
/// Gradient magnitude of display-referred luma (per pixel) that marks an intensity edge.
pub const EDGE_GRADIENT: f32 = 0.1;

/// Scores per bin of `key` over `bins` (upper bounds); pairs whose key is None are left out.
fn binned(
    pairs: &[ScoredPair],
    bins: &[(f64, &str)],
    key: impl Fn(&ScoredPair) -> Option<f64>,
) -> Vec<(String, PairStats)> {
    let bin_of = |v: f64| bins.iter().position(|&(hi, _)| v < hi);
    bins.iter()
        .enumerate()
        .map(|(b, &(_, label))| {
            let stats = PairStats::of(pairs.iter().filter(|p| key(p).and_then(bin_of) == Some(b)));
            (label.to_string(), stats)
        })
        .collect()
}

/// The report of `pairs`.
pub fn summarise(pairs: &[ScoredPair]) -> Report {
    let by_edge = if pairs.iter().any(|p| p.edge_px.is_some()) {
        binned(pairs, &EDGE_BINS_PX, |p| p.edge_px)
    } else {
        Vec::new()
    };
    let by_saturation = if pairs.iter().any(|p| p.saturated.is_some()) {
        let bins = [(0.5, "below 1"), (f64::INFINITY, "saturated (at 1)")];
        binned(pairs, &bins, |p| p.saturated.map(f64::from))
    } else {
        Vec::new()
    };
    let by_view = if pairs.iter().any(|p| p.test_view.is_some()) {
        let bins = [(0.5, "training views"), (f64::INFINITY, "a test view")];
        binned(pairs, &bins, |p| p.test_view.map(f64::from))
    } else {
        Vec::new()
    };
    Report {
        overall: PairStats::of(pairs),
        by_gap: binned(pairs, &GAP_BINS_US, |p| Some(p.gap_us)),
        by_luma: binned(pairs, &LUMA_BINS, |p| Some(p.luma)),
        by_edge,
        by_saturation,
        by_view,
    }
}

/// Up to `n` event pairs `(j, successor of j)`, drawn without replacement with `seed` from the
/// events with a successor whose two times lie inside the dataset's trajectory; in event order.
pub fn draw_pairs(events: &Events, contains: impl Fn(f64) -> bool, n: usize, seed: u64) -> Vec<(usize, usize)> {
    let all: Vec<(usize, usize)> = (0..events.len())
        .filter_map(|j| events.successor(j).map(|k| (j, k)))
        .filter(|&(j, k)| contains(events.t_us[j]) && contains(events.t_us[k]))
        .collect();
    sample_indices(all.len(), n, seed).into_iter().map(|i| all[i]).collect()
}

/// A uniform sample of `n` of the indices `0..total` (all of them when there are no more),
/// drawn without replacement with `seed`, increasing. A partial Fisher-Yates shuffle whose
/// swapped positions live in a map, so the memory is O(n) whatever `total`.
fn sample_indices(total: usize, n: usize, seed: u64) -> Vec<usize> {
    if total <= n {
        return (0..total).collect();
    }
    let mut rng = Rng::new(seed, 0x6469_6167);
    let mut moved = std::collections::HashMap::with_capacity(2 * n);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let r = i + rng.below((total - i) as u64) as usize;
        let at_r = moved.get(&r).copied().unwrap_or(r);
        let at_i = moved.get(&i).copied().unwrap_or(i);
        moved.insert(r, at_i);
        out.push(at_r);
    }
    out.sort_unstable();
    out
}

/// Per pixel, the distance (pixels, 8-connected chamfer) to the nearest pixel whose luma
/// gradient (central differences of display-referred Rec.709 luma) is at least
/// [`EDGE_GRADIENT`]; infinity when the image has no edge.
pub fn edge_distance(img: &RgbImage) -> Vec<f32> {
    let (w, h) = (img.width as usize, img.height as usize);
    let luma: Vec<f32> = img.data.chunks_exact(3).map(|c| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]).collect();
    let at = |i: usize, j: usize| luma[j * w + i];
    let mut d = vec![f32::INFINITY; w * h];
    for j in 0..h {
        for i in 0..w {
            let gx = (at((i + 1).min(w - 1), j) - at(i.saturating_sub(1), j)) * 0.5;
            let gy = (at(i, (j + 1).min(h - 1)) - at(i, j.saturating_sub(1))) * 0.5;
            if (gx * gx + gy * gy).sqrt() >= EDGE_GRADIENT {
                d[j * w + i] = 0.0;
            }
        }
    }
    // two passes of the 3x3 chamfer (1, sqrt 2)
    let diag = std::f32::consts::SQRT_2;
    for j in 0..h {
        for i in 0..w {
            let mut v = d[j * w + i];
            if i > 0 {
                v = v.min(d[j * w + i - 1] + 1.0);
            }
            if j > 0 {
                v = v.min(d[(j - 1) * w + i] + 1.0);
                if i > 0 {
                    v = v.min(d[(j - 1) * w + i - 1] + diag);
                }
                if i + 1 < w {
                    v = v.min(d[(j - 1) * w + i + 1] + diag);
                }
            }
            d[j * w + i] = v;
        }
    }
    for j in (0..h).rev() {
        for i in (0..w).rev() {
            let mut v = d[j * w + i];
            if i + 1 < w {
                v = v.min(d[j * w + i + 1] + 1.0);
            }
            if j + 1 < h {
                v = v.min(d[(j + 1) * w + i] + 1.0);
                if i + 1 < w {
                    v = v.min(d[(j + 1) * w + i + 1] + diag);
                }
                if i > 0 {
                    v = v.min(d[(j + 1) * w + i - 1] + diag);
                }
            }
            d[j * w + i] = v;
        }
    }
    d
}

/// The thresholds, log offset and luma weights the diagnosis reads events with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EventReading {
    /// `[C_on, C_off]`.
    pub threshold: [f64; 2],
    /// Offset of the log.
    pub log_eps: f64,
    /// Luma weights of the linear colour.
    pub luma: [f64; 3],
}

impl EventReading {
    /// What run configuration `cfg` trains with (its events table, resolved from the dataset),
    /// else the dataset's event model.
    pub fn of(cfg: &TrainConfig, data: &Dataset) -> EventReading {
        let mut c = cfg.clone();
        if c.events.is_none() {
            c.events = Some(crate::config::EventLossConfig::reference());
        }
        crate::method::resolve(&mut c, data);
        let e = c.events.expect("set above");
        EventReading {
            threshold: e.threshold.unwrap_or([0.2, 0.2]),
            log_eps: e.log_eps.unwrap_or(1e-5),
            luma: e.luma.unwrap_or(BT601),
        }
    }
}

/// Score `pairs` of `events` given each pair's two linear lumas `lumas` (at the first event's
/// time, at the second's); the edge distance comes from the sharp image nearest in time among
/// `sharp` (mid-time in us, image of `width` pixels a row, whether a test view's).
pub fn score_pairs(
    events: &Events,
    sharp: &[(f64, &RgbImage, bool)],
    width: u32,
    pairs: &[(usize, usize)],
    reading: &EventReading,
    lumas: &[[f64; 2]],
) -> Vec<ScoredPair> {
    let ev = events;
    let mut edges: Vec<Option<Vec<f32>>> = vec![None; sharp.len()];
    let w = width as usize;
    pairs
        .iter()
        .zip(lumas)
        .map(|(&(j, k), &[lj, lk])| {
            let theta = if ev.polarity[k] > 0 { reading.threshold[0] } else { reading.threshold[1] };
            let predicted = (lk + reading.log_eps).ln() - (lj + reading.log_eps).ln();
            let t_mid = 0.5 * (ev.t_us[j] + ev.t_us[k]);
            let nearest =
                (0..sharp.len()).min_by(|&a, &b| (sharp[a].0 - t_mid).abs().total_cmp(&(sharp[b].0 - t_mid).abs()));
            let (x, y) = (ev.x[j].round() as usize, ev.y[j].round() as usize);
            let edge_px = nearest.map(|s| {
                let d = edges[s].get_or_insert_with(|| edge_distance(sharp[s].1));
                d.get(y * w + x).copied().unwrap_or(f32::INFINITY) as f64
            });
            let saturated = nearest
                .and_then(|s| sharp[s].1.data.get(3 * (y * w + x)..3 * (y * w + x) + 3))
                .map(|c| c.iter().any(|&v| v >= 1.0));
            ScoredPair {
                predicted,
                target: ev.polarity[k] as f64 * theta,
                gap_us: ev.t_us[k] - ev.t_us[j],
                luma: lj.max(lk),
                edge_px,
                saturated,
                test_view: None,
            }
        })
        .collect()
}

/// A pixel read at two times: the rays through `(x, y)` (pixel units, continuous) at the
/// trajectory's poses at `t_us`, colours read through the eCRF with `polarity`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// Column (pixel units; `i + 0.5` is the centre of column `i`).
    pub x: f64,
    /// Row (pixel units).
    pub y: f64,
    /// The two times (us), inside the trajectory.
    pub t_us: [f64; 2],
    /// The polarity the eCRF reads both colours with (0: neither).
    pub polarity: i8,
}

/// The probes of event pairs: the first event's pixel centre at the two events' times, read
/// with the successor's polarity (as the event loss reads a pair).
pub fn pair_probes(events: &Events, pairs: &[(usize, usize)]) -> Vec<Probe> {
    pairs
        .iter()
        .map(|&(j, k)| Probe {
            x: events.x[j] as f64 + 0.5,
            y: events.y[j] as f64 + 0.5,
            t_us: [events.t_us[j], events.t_us[k]],
            polarity: events.polarity[k],
        })
        .collect()
}

/// A trained field and how to read it.
#[derive(Clone, Copy)]
pub struct FieldReader<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its parameters.
    pub params: &'a [f32],
    /// The run's configuration (ray chunk size).
    pub cfg: &'a TrainConfig,
    /// The eCRF the colours go through (`None`: the linear colour).
    pub ecrf: Option<&'a Ecrf>,
    /// Rays per side of a pixel: 1 reads the pixel-centre ray (as the event loss casts it), n > 1
    /// the mean linear colour of n x n rays at the centres of a grid over the pixel (its area, as
    /// a sensor integrates it).
    pub supersample: usize,
    /// Luma weights of the linear colour.
    pub luma: [f64; 3],
}

/// The linear lumas a trained field (fine pass, read as `field` says) gives each probe at its
/// two times. Probes are rendered in parallel on the current rayon pool; the result does not
/// depend on it.
pub fn field_lumas(data: &Dataset, field: &FieldReader, probes: &[Probe]) -> Vec<[f64; 2]> {
    let FieldReader { model, params, cfg, ecrf, supersample, luma } = *field;
    let n = supersample.max(1);
    let per_call = ((cfg.chunk_rays * 4).max(2) / (2 * n * n)).max(1);
    probes
        .par_chunks(per_call)
        .map_init(Renderer::default, |renderer, chunk| {
            let mut rays = Vec::with_capacity(2 * n * n * chunk.len());
            let mut pol = Vec::with_capacity(2 * chunk.len());
            for p in chunk {
                for t in p.t_us {
                    // callers keep probes inside the trajectory
                    let pose = data.trajectory.pose_at(t).expect("probe inside the trajectory");
                    for k in 0..n * n {
                        let (du, dv) =
                            (((k % n) as f64 + 0.5) / n as f64 - 0.5, ((k / n) as f64 + 0.5) / n as f64 - 0.5);
                        rays.push(prepare(data, &data.intrinsics.ray_through(&pose, p.x + du, p.y + dv)));
                    }
                }
                pol.extend([p.polarity, p.polarity]);
            }
            let (o, d, vd) = unzip(&rays);
            renderer.forward(model, params, &RayChunk { origins: &o, dirs: &d, viewdirs: &vd }, None);
            // the pixel's light: the mean linear colour of its rays
            let cols: Vec<[f32; 3]> = renderer
                .fine()
                .chunks_exact(n * n)
                .map(|g| {
                    let mut m = [0.0f32; 3];
                    for col in g {
                        for c in 0..3 {
                            m[c] += col[c] / (n * n) as f32;
                        }
                    }
                    m
                })
                .collect();
            let mut y = [vec![0.0f32; cols.len()], vec![0.0f32; cols.len()], vec![0.0f32; cols.len()]];
            for (c, yc) in y.iter_mut().enumerate() {
                let x: Vec<f32> = cols.iter().map(|col| col[c]).collect();
                match ecrf {
                    Some(e) => e.forward(params, c, &x, &pol, yc, &mut EcrfWorkspace::default()),
                    None => yc.copy_from_slice(&x),
                }
            }
            let l = |i: usize| (0..3).map(|c| luma[c] * y[c][i] as f64).sum::<f64>();
            (0..chunk.len()).map(|p| [l(2 * p), l(2 * p + 1)]).collect::<Vec<_>>()
        })
        .flatten()
        .collect()
}

/// The sharp images of `data`'s views with their mid-times (us) and whether each is a test
/// view, for [`score_pairs`] and [`SharpFrames::new`].
pub fn sharp_views(data: &Dataset) -> Vec<(f64, &RgbImage, bool)> {
    data.views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.sharp.as_ref().map(|s| (v.t_mid_us, s, data.split.test.contains(&i))))
        .collect()
}

/// The sharp frames of the windows report: times (us, increasing) and the images, linear.
///
/// An event camera's events between two times sum, per pixel, to the change of its log
/// brightness up to one threshold at each end: `sum p C = log L(t_b) - log L(t_a) + e` with
/// `|e| < C` for an ideal sensor. With sharp frames at `t_a` and `t_b` that is a check of the
/// events against ground truth (the oracle), and the same window read from a field checks the
/// field on the scale the frames supervise.
#[derive(Clone, Debug, PartialEq)]
pub struct SharpFrames {
    /// Frame times (us), strictly increasing.
    pub t_us: Vec<f64>,
    /// Linear lumas, `width * height` per frame.
    pub luma: Vec<Vec<f64>>,
    /// Whether a pixel has a channel at 1 (display-referred): its light may be above what the
    /// frame records.
    pub saturated: Vec<Vec<bool>>,
    /// Distance to the nearest intensity edge (pixels), per frame ([`edge_distance`]).
    pub edge_px: Vec<Vec<f32>>,
    /// Whether a frame is a test view's.
    pub test: Vec<bool>,
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
}

impl SharpFrames {
    /// Linearises display-referred `frames` (time in us, image, whether a test view's; any
    /// order) through the response exponent `gamma` (`linear = display^gamma`) and takes their
    /// luma with `luma`; frames at times `contains` refuses are left out.
    pub fn new(
        frames: &[(f64, &RgbImage, bool)],
        gamma: f64,
        luma: [f64; 3],
        contains: impl Fn(f64) -> bool,
    ) -> SharpFrames {
        let mut kept: Vec<&(f64, &RgbImage, bool)> = frames.iter().filter(|f| contains(f.0)).collect();
        kept.sort_by(|a, b| a.0.total_cmp(&b.0));
        kept.dedup_by(|a, b| a.0 == b.0);
        let (width, height) = kept.first().map_or((0, 0), |f| (f.1.width, f.1.height));
        let lin = |v: f32| (v.max(0.0) as f64).powf(gamma);
        SharpFrames {
            t_us: kept.iter().map(|f| f.0).collect(),
            luma: kept
                .iter()
                .map(|f| f.1.data.chunks_exact(3).map(|c| (0..3).map(|k| luma[k] * lin(c[k])).sum()).collect())
                .collect(),
            saturated: kept
                .iter()
                .map(|f| f.1.data.chunks_exact(3).map(|c| c.iter().any(|&v| v >= 1.0)).collect())
                .collect(),
            edge_px: kept.iter().map(|f| edge_distance(f.1)).collect(),
            test: kept.iter().map(|f| f.2).collect(),
            width,
            height,
        }
    }

    /// Windows between consecutive frames.
    pub fn windows(&self) -> usize {
        self.t_us.len().saturating_sub(1)
    }

    /// Pixels per frame.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// A drawn window pixel: window `w` (from frame `w` to frame `w + 1`), pixel index `p`.
pub type WindowPixel = (usize, usize);

/// Up to `n` window pixels of `frames`, drawn without replacement with `seed`; in order.
pub fn draw_window_pixels(frames: &SharpFrames, n: usize, seed: u64) -> Vec<WindowPixel> {
    let pixels = frames.pixels();
    sample_indices(frames.windows() * pixels, n, seed).into_iter().map(|i| (i / pixels, i % pixels)).collect()
}

/// Per drawn window pixel, the events' summed polarity times threshold inside the window (the
/// first frame's time excluded, the second's included) and how many events that is.
pub fn window_targets(
    events: &Events,
    frames: &SharpFrames,
    drawn: &[WindowPixel],
    reading: &EventReading,
) -> Vec<(f64, u32)> {
    let pixels = frames.pixels();
    let mut slot = std::collections::HashMap::with_capacity(drawn.len());
    for (i, &(w, p)) in drawn.iter().enumerate() {
        slot.insert(w * pixels + p, i);
    }
    let mut out = vec![(0.0f64, 0u32); drawn.len()];
    let (w, h) = (frames.width as i64, frames.height as i64);
    for j in 0..events.len() {
        let t = events.t_us[j];
        // windows are (t_w, t_w+1]: the first frame time at or after t closes the event's window
        let end = frames.t_us.partition_point(|&f| f < t);
        if end == 0 || end >= frames.t_us.len() {
            continue;
        }
        let (x, y) = (events.x[j].round() as i64, events.y[j].round() as i64);
        if x < 0 || y < 0 || x >= w || y >= h {
            continue;
        }
        if let Some(&i) = slot.get(&((end - 1) * pixels + (y * w + x) as usize)) {
            let p = events.polarity[j];
            out[i].0 += p as f64 * if p > 0 { reading.threshold[0] } else { reading.threshold[1] };
            out[i].1 += 1;
        }
    }
    out
}

/// The probes of drawn window pixels: the pixel centre at the window's two frame times, read
/// with the sign of the window's target (0 when its events cancel or it has none).
pub fn window_probes(frames: &SharpFrames, drawn: &[WindowPixel], targets: &[(f64, u32)]) -> Vec<Probe> {
    let w = frames.width as usize;
    drawn
        .iter()
        .zip(targets)
        .map(|(&(win, p), &(target, _))| Probe {
            x: (p % w) as f64 + 0.5,
            y: (p / w) as f64 + 0.5,
            t_us: [frames.t_us[win], frames.t_us[win + 1]],
            polarity: if target > 0.0 {
                1
            } else if target < 0.0 {
                -1
            } else {
                0
            },
        })
        .collect()
}

/// The frames' own lumas at each drawn window pixel's two times: the oracle's prediction.
pub fn frame_lumas(frames: &SharpFrames, drawn: &[WindowPixel]) -> Vec<[f64; 2]> {
    drawn.iter().map(|&(w, p)| [frames.luma[w][p], frames.luma[w + 1][p]]).collect()
}

/// Score window pixels given a prediction's two lumas each. Every predictor is binned by the
/// frames (luma: the larger of the two frames'; edge distance and saturation: either frame),
/// so the oracle's rows and a field's cover the same pixels.
pub fn score_windows(
    frames: &SharpFrames,
    drawn: &[WindowPixel],
    targets: &[(f64, u32)],
    reading: &EventReading,
    lumas: &[[f64; 2]],
) -> Vec<ScoredPair> {
    drawn
        .iter()
        .zip(targets)
        .zip(lumas)
        .map(|((&(w, p), &(target, _)), &[la, lb])| ScoredPair {
            predicted: (lb + reading.log_eps).ln() - (la + reading.log_eps).ln(),
            target,
            gap_us: frames.t_us[w + 1] - frames.t_us[w],
            luma: frames.luma[w][p].max(frames.luma[w + 1][p]),
            edge_px: Some(frames.edge_px[w][p].min(frames.edge_px[w + 1][p]) as f64),
            saturated: Some(frames.saturated[w][p] || frames.saturated[w + 1][p]),
            test_view: Some(frames.test[w] || frames.test[w + 1]),
        })
        .collect()
}

/// The oracle's and a field's scores on seeded window pixels: what `evtrain diagnose events`
/// prints under its windows heading.
pub struct WindowScores {
    /// The frames' own prediction (the oracle).
    pub oracle: Report,
    /// The field's prediction at the same pixels and times.
    pub field: Report,
    /// Window pixels drawn.
    pub drawn: usize,
    /// Drawn window pixels with at least one event.
    pub with_events: usize,
}

/// Draw up to `n` window pixels of `frames` with `seed`, sum their events, and score the
/// frames' and the field's log-luma change against those sums.
pub fn score_sharp_windows(
    data: &Dataset,
    frames: &SharpFrames,
    field: &FieldReader,
    reading: &EventReading,
    n: usize,
    seed: u64,
) -> WindowScores {
    let drawn = draw_window_pixels(frames, n, seed);
    let targets = window_targets(&data.events, frames, &drawn, reading);
    let predicted = field_lumas(data, field, &window_probes(frames, &drawn, &targets));
    let score = |lumas: &[[f64; 2]]| summarise(&score_windows(frames, &drawn, &targets, reading, lumas));
    WindowScores {
        oracle: score(&frame_lumas(frames, &drawn)),
        field: score(&predicted),
        drawn: drawn.len(),
        with_events: targets.iter().filter(|t| t.1 > 0).count(),
    }
}

/// The windows report as text: the oracle's and the field's r2 and sign agreement side by
/// side, overall and by the frames' luma, edge distance and saturation.
pub fn format_windows(title: &str, oracle: &Report, field: &Report) -> String {
    let mut out = format!(
        "{title}\n{:<24} {:>8} {:>8} {:>8} {:>8} {:>8}\n",
        "window pixels", "n", "oracle", "sign", "field", "sign"
    );
    let row = |label: &str, o: &PairStats, f: &PairStats| {
        format!("{label:<24} {:>8} {:>8.3} {:>8.3} {:>8.3} {:>8.3}\n", o.n, o.r2, o.sign, f.r2, f.sign)
    };
    out += &row("all", &oracle.overall, &field.overall);
    let breakdowns = [
        ("luma in the frames (linear)", &oracle.by_luma, &field.by_luma),
        ("distance to an edge in the frames", &oracle.by_edge, &field.by_edge),
        ("the pixel in the frames", &oracle.by_saturation, &field.by_saturation),
        ("the window's views", &oracle.by_view, &field.by_view),
    ];
    for (name, o, f) in breakdowns {
        out += &format!("by {name}\n");
        for ((label, so), (_, sf)) in o.iter().zip(f) {
            out += &row(&format!("  {label}"), so, sf);
        }
    }
    out
}

/// The report as text: one line per row, r2 and sign agreement per bin.
pub fn format_report(title: &str, r: &Report) -> String {
    let mut out = format!("{title}\n{:<24} {:>8} {:>8} {:>8}\n", "pairs", "n", "r2", "sign");
    let row = |label: &str, s: &PairStats| format!("{label:<24} {:>8} {:>8.3} {:>8.3}\n", s.n, s.r2, s.sign);
    out += &row("all", &r.overall);
    let breakdowns = [
        ("time gap", &r.by_gap),
        ("predicted luma (linear)", &r.by_luma),
        ("distance to an edge of the nearest sharp view", &r.by_edge),
        ("the pixel in the nearest sharp view", &r.by_saturation),
    ];
    for (name, bins) in breakdowns {
        if bins.is_empty() {
            continue;
        }
        out += &format!("by {name}\n");
        for (label, s) in bins {
            out += &row(&format!("  {label}"), s);
        }
    }
    out
}

#[cfg(test)]
#[path = "diagnose_tests.rs"]
mod tests;
