//! Tests of `diagnose.rs`.

use super::*;

fn pair(predicted: f64, target: f64, gap_us: f64, luma: f64) -> ScoredPair {
    ScoredPair { predicted, target, gap_us, luma, edge_px: None, saturated: None, test_view: None }
}

#[test]
fn r2_is_one_for_exact_predictions_zero_for_no_change_and_sign_counts_agreement() {
    let exact = [pair(0.2, 0.2, 500.0, 0.5), pair(-0.2, -0.2, 2e3, 0.5)];
    let s = PairStats::of(&exact);
    assert_eq!((s.n, s.r2, s.sign), (2, 1.0, 1.0));
    let none = [pair(0.0, 0.2, 500.0, 0.5), pair(0.0, -0.2, 2e3, 0.5)];
    let s = PairStats::of(&none);
    assert!(s.r2.abs() < 1e-12 && s.sign == 0.0);
    let wrong = [pair(-0.2, 0.2, 500.0, 0.5), pair(0.1, 0.2, 2e3, 0.5)];
    let s = PairStats::of(&wrong);
    // errors 0.16 and 0.01 over energy 0.08
    assert!((s.r2 - (1.0 - 0.17 / 0.08)).abs() < 1e-12 && s.sign == 0.5);
    assert!(PairStats::of(&[]).r2.is_nan());
}

#[test]
fn pairs_fall_in_their_bins() {
    let pairs = [pair(0.2, 0.2, 500.0, 0.01), pair(0.0, 0.2, 5e3, 0.5), pair(0.2, 0.2, 20e3, 2.0)];
    let r = summarise(&pairs);
    let n = |bins: &[(String, PairStats)]| bins.iter().map(|b| b.1.n).collect::<Vec<_>>();
    assert_eq!(n(&r.by_gap), [1, 0, 1, 1]);
    assert_eq!(n(&r.by_luma), [1, 0, 1, 1]);
    assert!(r.by_edge.is_empty() && r.by_saturation.is_empty());
    assert_eq!(r.by_gap[2].1.r2, 0.0);
    assert_eq!(r.by_luma[3].1.r2, 1.0);
}

#[test]
fn edge_distance_is_zero_on_a_step_and_grows_away_from_it() {
    let (w, h) = (12u32, 3u32);
    let data = (0..w * h).flat_map(|p| if p % w < 6 { [0.0; 3] } else { [1.0; 3] }).collect();
    let d = edge_distance(&RgbImage { width: w, height: h, data });
    // central differences mark the columns either side of the step
    assert_eq!(d[5], 0.0);
    assert_eq!(d[6], 0.0);
    assert_eq!(d[0], 5.0);
    assert_eq!(d[11], 5.0);
    let flat = edge_distance(&RgbImage { width: 4, height: 4, data: vec![0.5; 48] });
    assert!(flat.iter().all(|v| v.is_infinite()));
}

#[test]
fn drawn_pairs_are_a_seeded_sample_of_successor_pairs_inside_the_trajectory() {
    // 4 pixels, 10 events each, 1 ms apart
    let n = 40;
    let events = Events {
        x: (0..n).map(|i| (i % 4) as f32).collect(),
        y: vec![0.0; n],
        t_us: (0..n).map(|i| i as f64 * 1e3).collect(),
        polarity: vec![1; n],
        successors: (0..n).map(|i| if i + 4 < n { (i + 4) as u32 } else { u32::MAX }).collect(),
        ..Events::default()
    };
    let inside = |t: f64| t <= 30e3;
    let all = draw_pairs(&events, inside, 1000, 1);
    assert_eq!(all.len(), 27); // j + 4 <= 30
    assert!(all.iter().all(|&(j, k)| k == j + 4 && inside(events.t_us[k])));
    let a = draw_pairs(&events, inside, 10, 7);
    assert_eq!(a, draw_pairs(&events, inside, 10, 7));
    assert_ne!(a, draw_pairs(&events, inside, 10, 8));
    assert_eq!(a.len(), 10);
    assert!(a.windows(2).all(|p| p[0] < p[1]));
}

/// One pixel whose log luma is a known function of time; events where it crosses the
/// threshold (an ideal sensor) and their successors.
fn analytic_events(c: f64) -> (Events, impl Fn(f64) -> f64) {
    let log_l = |t_us: f64| 0.8 * (2.0 * std::f64::consts::PI * t_us / 20e3).sin() + 0.3 * (t_us / 7e3).cos();
    let (mut t_us, mut polarity) = (Vec::new(), Vec::new());
    let mut reference = log_l(0.0);
    let mut t = 0.0;
    while t < 300e3 {
        t += 1.0;
        let v = log_l(t);
        while (v - reference).abs() >= c {
            let p: i8 = if v > reference { 1 } else { -1 };
            reference += p as f64 * c;
            t_us.push(t);
            polarity.push(p);
        }
    }
    let n = t_us.len();
    let events = Events {
        x: vec![0.0; n],
        y: vec![0.0; n],
        t_us,
        polarity,
        successors: (0..n).map(|i| if i + 1 < n { (i + 1) as u32 } else { u32::MAX }).collect(),
        ..Events::default()
    };
    (events, move |t: f64| log_l(t).exp())
}

#[test]
fn an_analytic_oracle_scores_one_and_no_change_or_noise_scores_low() {
    let c = 0.2;
    let (events, luma) = analytic_events(c);
    let reading = EventReading { threshold: [c, c], log_eps: 0.0, luma: [0.2126, 0.7152, 0.0722] };
    let pairs = draw_pairs(&events, |_| true, 500, 3);
    assert!(pairs.len() > 100, "{} pairs", pairs.len());
    let oracle: Vec<[f64; 2]> = pairs.iter().map(|&(j, k)| [luma(events.t_us[j]), luma(events.t_us[k])]).collect();
    let r = summarise(&score_pairs(&events, &[], 1, &pairs, &reading, &oracle));
    // events are stamped to the next microsecond after the crossing: within 1e-3 of C
    assert!(r.overall.r2 > 0.99 && r.overall.sign == 1.0, "{:?}", r.overall);
    let still: Vec<[f64; 2]> = pairs.iter().map(|&(j, _)| [luma(events.t_us[j]); 2]).collect();
    let r = summarise(&score_pairs(&events, &[], 1, &pairs, &reading, &still));
    assert!(r.overall.r2.abs() < 1e-9, "{:?}", r.overall);
    // the luma a few ms off: a wrong time base
    let late: Vec<[f64; 2]> =
        pairs.iter().map(|&(j, k)| [luma(events.t_us[j] + 3e3), luma(events.t_us[k] + 3e3)]).collect();
    let r = summarise(&score_pairs(&events, &[], 1, &pairs, &reading, &late));
    assert!(r.overall.r2 < 0.5, "{:?}", r.overall);
}

/// Ideal-sensor events of `pixels` pixels in a row whose log luma is `log_l(pixel, t)`,
/// stamped at the microsecond after each crossing of threshold `c`, in time order.
fn ideal_events(pixels: usize, c: f64, t_end_us: f64, log_l: impl Fn(usize, f64) -> f64) -> Events {
    let mut ev: Vec<(f64, usize, i8)> = Vec::new();
    for x in 0..pixels {
        let mut reference = log_l(x, 0.0);
        let mut t = 0.0;
        while t < t_end_us {
            t += 1.0;
            let v = log_l(x, t);
            while (v - reference).abs() >= c {
                let p: i8 = if v > reference { 1 } else { -1 };
                reference += p as f64 * c;
                ev.push((t, x, p));
            }
        }
    }
    ev.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let x: Vec<f32> = ev.iter().map(|e| e.1 as f32).collect();
    let y = vec![0.0; ev.len()];
    let successors = crate::data::events::successors(&x, &y, (pixels as u32, 1), false);
    Events {
        t_us: ev.iter().map(|e| e.0).collect(),
        polarity: ev.iter().map(|e| e.2).collect(),
        x,
        y,
        successors,
        ..Events::default()
    }
}

#[test]
fn sharp_frames_of_an_analytic_scene_explain_its_windows_and_wrong_frames_do_not() {
    let (pixels, c, gamma) = (6usize, 0.05, 2.2);
    // log luma per pixel: a moving bump over a dark ramp, all below 1
    let log_l = |x: usize, t: f64| -2.5 + 0.2 * x as f64 + 1.5 * (-((x as f64 - t / 40e3) / 1.5).powi(2)).exp();
    let events = ideal_events(pixels, c, 300e3, log_l);
    let frame = |t: f64| RgbImage {
        width: pixels as u32,
        height: 1,
        data: (0..pixels).flat_map(|x| [log_l(x, t).exp().powf(1.0 / gamma) as f32; 3]).collect(),
    };
    let times: Vec<f64> = (0..10).map(|k| k as f64 * 30e3).collect();
    let images: Vec<RgbImage> = times.iter().map(|&t| frame(t)).collect();
    let list: Vec<(f64, &RgbImage, bool)> = times.iter().zip(&images).map(|(&t, i)| (t, i, t == 0.0)).rev().collect();
    let luma = [0.299, 0.587, 0.114];
    // frames come in any order; a time outside the trajectory drops its frame
    let frames = SharpFrames::new(&list, gamma, luma, |t| t < 250e3);
    assert_eq!(frames.t_us, times[..9]);
    assert_eq!(frames.windows(), 8);
    let drawn = draw_window_pixels(&frames, 1000, 1);
    assert_eq!(drawn.len(), 8 * pixels);
    let reading = EventReading { threshold: [c, c], log_eps: 0.0, luma };
    let targets = window_targets(&events, &frames, &drawn, &reading);
    assert!(targets.iter().filter(|t| t.1 > 0).count() > 30, "{targets:?}");
    let score = |l: &[[f64; 2]]| summarise(&score_windows(&frames, &drawn, &targets, &reading, l)).overall;
    // the events sum to the change up to one threshold at each end (f32 frames)
    let oracle = score(&frame_lumas(&frames, &drawn));
    assert!(oracle.r2 > 0.98 && oracle.sign > 0.95, "{oracle:?}");
    let still: Vec<[f64; 2]> = drawn.iter().map(|&(w, p)| [frames.luma[w][p]; 2]).collect();
    assert!(score(&still).r2.abs() < 1e-9);
    let late: Vec<[f64; 2]> =
        drawn.iter().map(|&(w, p)| [log_l(p, times[w] + 15e3).exp(), log_l(p, times[w + 1] + 15e3).exp()]).collect();
    let late = score(&late);
    assert!(late.r2 < oracle.r2 - 0.1, "{late:?} vs {oracle:?}");
}

#[test]
fn window_targets_sum_the_events_after_the_first_frame_up_to_the_second() {
    let events = Events {
        x: vec![0.0, 1.0, 1.0, 1.0, 1.0, 9.0],
        y: vec![0.0; 6],
        t_us: vec![5.0, 10.0, 10.5, 20.0, 25.0, 15.0],
        polarity: vec![1, 1, -1, 1, 1, 1],
        ..Events::default()
    };
    let img = RgbImage { width: 2, height: 1, data: vec![0.5; 6] };
    let list = [(10.0, &img, false), (20.0, &img, false), (30.0, &img, true)];
    let frames = SharpFrames::new(&list, 1.0, [1.0, 0.0, 0.0], |_| true);
    let drawn = draw_window_pixels(&frames, 10, 1);
    assert_eq!(drawn, [(0, 0), (0, 1), (1, 0), (1, 1)]);
    let reading = EventReading { threshold: [0.2, 0.3], log_eps: 0.0, luma: [1.0, 0.0, 0.0] };
    let t = window_targets(&events, &frames, &drawn, &reading);
    // pixel 1: (10, 20] holds -0.3 and +0.2; (20, 30] holds +0.2; the event at 10 and the
    // one before the first frame and off the image count nowhere
    assert_eq!(t, [(0.0, 0), (-0.3 + 0.2, 2), (0.0, 0), (0.2, 1)]);
    let probes = window_probes(&frames, &drawn, &t);
    assert_eq!(probes.iter().map(|p| p.polarity).collect::<Vec<_>>(), [0, -1, 0, 1]);
    assert_eq!((probes[3].x, probes[3].y, probes[3].t_us), (1.5, 0.5, [20.0, 30.0]));
}

#[test]
fn sampled_indices_are_the_partial_shuffle_of_the_whole_list() {
    // the map-based shuffle draws the same sample as shuffling the materialised list
    for (total, n, seed) in [(10usize, 3usize, 1u64), (1000, 50, 2), (1000, 999, 3), (5, 5, 4), (5, 9, 5)] {
        let mut all: Vec<usize> = (0..total).collect();
        if total > n {
            let mut rng = Rng::new(seed, 0x6469_6167);
            for i in 0..n {
                let r = i + rng.below((total - i) as u64) as usize;
                all.swap(i, r);
            }
            all.truncate(n);
            all.sort_unstable();
        }
        let got = sample_indices(total, n, seed);
        assert_eq!(got, all, "{total} {n} {seed}");
        assert!(got.windows(2).all(|w| w[0] < w[1]));
    }
}
