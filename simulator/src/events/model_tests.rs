//! Known-answer and statistical tests of the event model.

use glam::Vec3;

use super::*;
use crate::events::{
    EventConfig, MismatchMode, NoiseConfig, Photoreceptor, Refractory, RefractoryMode, Sensor, ThresholdMismatch,
    VecSink,
};

/// A grey image whose intensity is `f(x, y)`.
fn gray(w: u32, h: u32, mut f: impl FnMut(u32, u32) -> f32) -> Image {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.pixels[(y * w + x) as usize] = Vec3::splat(f(x, y));
        }
    }
    img
}

/// Feed `frames` at `times`; the events of every interval, in order.
fn run(cfg: &EventConfig, frames: &[Image], times: &[i64]) -> Vec<Vec<Event>> {
    let mut sim = EventSimulator::new(cfg.clone(), frames[0].width, frames[0].height).unwrap();
    frames
        .iter()
        .zip(times)
        .map(|(f, &t)| {
            let mut sink = VecSink::default();
            sim.step(f, t, &mut sink).unwrap();
            sink.events
        })
        .collect()
}

/// A smooth pattern moving over time, with random phases.
fn moving_pattern(w: u32, h: u32, frames: usize, seed: u64) -> Vec<Image> {
    let mut rng = noise::pixel_rng(seed, 0);
    let ph: Vec<f32> = (0..4).map(|_| rng.next_f32() * 6.28).collect();
    (0..frames)
        .map(|k| {
            let t = k as f32;
            gray(w, h, |x, y| {
                let (x, y) = (x as f32, y as f32);
                let a = 0.5 + 0.5 * (0.4 * x + 0.3 * y - 0.25 * t + ph[0]).sin();
                let b = 0.6 + 0.4 * (0.2 * x - 0.5 * y + 0.15 * t + ph[1]).cos();
                0.02 + 0.9 * a * b
            })
        })
        .collect()
}

fn ms(k: usize) -> i64 {
    k as i64 * 1_000_000
}

#[test]
fn reconstruction_stays_within_threshold() {
    let (w, h) = (24u32, 16u32);
    let frames = moving_pattern(w, h, 50, 1);
    // irregular but increasing times
    let times: Vec<i64> = (0..50).map(|k| ms(k) + (k as i64 * k as i64 * 37) % 1000).collect();
    let cfg = EventConfig { c_pos: 0.15, c_neg: 0.25, ..EventConfig::default() };
    let log = |img: &Image, i: usize| (cfg.log_eps + img.pixels[i].dot(LUMA_709)).ln();
    let mut l_rec: Vec<f32> = (0..(w * h) as usize).map(|i| log(&frames[0], i)).collect();
    let out = run(&cfg, &frames, &times);
    assert!(out[0].is_empty(), "the first frame emits nothing");
    let mut total = 0;
    for k in 1..frames.len() {
        for e in &out[k] {
            assert!(e.t_ns > times[k - 1] && e.t_ns <= times[k], "event {e:?} outside its interval");
            l_rec[e.y as usize * w as usize + e.x as usize] += if e.p > 0 { cfg.c_pos } else { -cfg.c_neg };
        }
        assert!(out[k].windows(2).all(|p| p[0].order_key() <= p[1].order_key()), "not time-sorted");
        total += out[k].len();
        for (i, &r) in l_rec.iter().enumerate() {
            let err = log(&frames[k], i) - r;
            assert!(err < cfg.c_pos + 1e-4 && err > -cfg.c_neg - 1e-4, "frame {k} pixel {i}: L - L_rec = {err}");
        }
    }
    assert!(total > 1000, "the pattern should fire many events, got {total}");
}

/// A one-pixel ramp from `i0` to `i1` over (t0, t1]: the expected events (count and times).
fn ramp_case(cfg: &EventConfig, i0: f32, i1: f32) {
    let (t0, t1) = (1_000i64, 1_001_000i64);
    let out = run(cfg, &[gray(1, 1, |_, _| i0), gray(1, 1, |_, _| i1)], &[t0, t1]);
    let log = |i: f32| (cfg.log_eps + Vec3::splat(i).dot(LUMA_709)).ln() as f64;
    let (l0, l1) = (log(i0), log(i1));
    let (c, pol) = if l1 > l0 { (cfg.c_pos as f64, 1) } else { (cfg.c_neg as f64, -1) };
    let d = (l1 - l0).abs();
    let n = (d / c).floor() as usize;
    assert!(n >= 3, "test needs several crossings");
    assert_eq!(out[1].len(), n, "floor(D / C) events for D = {d}, C = {c}");
    for (j, e) in out[1].iter().enumerate() {
        let expected = t0 + ((j + 1) as f64 * c / d * (t1 - t0) as f64).round() as i64;
        assert_eq!(e.t_ns, expected, "event {j}");
        assert_eq!(e.p, pol);
        assert!(e.t_ns > t0 && e.t_ns < t1);
    }
    assert!(out[1].windows(2).all(|p| p[0].t_ns < p[1].t_ns), "strictly increasing");
}

#[test]
fn ramp_emits_floor_d_over_c_events_at_interpolated_times() {
    let cfg = EventConfig { c_pos: 0.3, c_neg: 0.45, ..EventConfig::default() };
    ramp_case(&cfg, 0.1, 0.9); // up: C_p = 0.3, D = 2.19 -> 7 events
    ramp_case(&cfg, 0.9, 0.1); // down: C_m = 0.45 -> 4 events
    let swapped = EventConfig { c_pos: 0.45, c_neg: 0.3, ..cfg };
    ramp_case(&swapped, 0.1, 0.9);
    ramp_case(&swapped, 0.9, 0.1);
}

#[test]
fn static_scene_emits_nothing() {
    let mut rng = noise::pixel_rng(9, 9);
    let img = gray(17, 11, |_, _| rng.next_f32());
    let mut sim = EventSimulator::new(EventConfig::default(), 17, 11).unwrap();
    for k in 0..20 {
        let mut sink = VecSink::default();
        let st = sim.step(&img, ms(k), &mut sink).unwrap();
        assert!(sink.events.is_empty());
        assert_eq!(st, FrameStats::default());
    }
}

/// Every non-ideality on.
fn noisy(refractory: RefractoryMode, mismatch: MismatchMode) -> EventConfig {
    EventConfig {
        seed: 42,
        noise: NoiseConfig {
            threshold_mismatch: Some(ThresholdMismatch { sigma: 0.03, mode: mismatch }),
            refractory: Some(Refractory { period_ns: 300_000, mode: refractory }),
            photoreceptor: Some(Photoreceptor { cutoff_hz: 300.0 }),
            leak_rate_hz: 5.0,
            shot_noise_rate_hz: 20.0,
        },
        ..EventConfig::default()
    }
}

#[test]
fn output_is_identical_for_one_and_two_threads() {
    let frames = moving_pattern(40, 21, 30, 5);
    let times: Vec<i64> = (0..30).map(ms).collect();
    for cfg in [
        EventConfig::default(),
        noisy(RefractoryMode::Consume, MismatchMode::PerInterval),
        noisy(RefractoryMode::FireLater, MismatchMode::Fixed),
    ] {
        let with = |n: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| run(&cfg, &frames, &times))
        };
        let (a, b) = (with(1), with(2));
        assert!(a.iter().map(Vec::len).sum::<usize>() > 100);
        assert_eq!(a, b);
    }
}

#[test]
fn pure_red_change_fires_only_red_pixels() {
    let cfg = EventConfig { sensor: Sensor::Rggb, ..EventConfig::default() };
    let f0 = Image { pixels: vec![Vec3::splat(0.3); 6 * 4], ..Image::new(6, 4) };
    let f1 = Image { pixels: vec![Vec3::new(0.6, 0.3, 0.3); 6 * 4], ..Image::new(6, 4) };
    let out = run(&cfg, &[f0, f1], &[0, ms(1)]);
    let n = (((cfg.log_eps + 0.6) / (cfg.log_eps + 0.3)).ln() / cfg.c_pos).floor() as usize;
    assert_eq!(out[1].len(), n * 3 * 2, "{n} events at each of the 6 red pixels");
    assert!(out[1].iter().all(|e| e.x % 2 == 0 && e.y % 2 == 0 && e.p == 1), "{:?}", out[1]);
}

#[test]
fn bad_config_names_the_field() {
    let field = |cfg: EventConfig| match EventSimulator::new(cfg, 4, 4) {
        Err(EventError::Config { field, .. }) => field,
        other => panic!("expected a config error, got {:?}", other.map(|_| ())),
    };
    let d = EventConfig::default;
    assert_eq!(field(EventConfig { c_pos: 0.0, ..d() }), "c_pos");
    assert_eq!(field(EventConfig { c_neg: f32::NAN, ..d() }), "c_neg");
    assert_eq!(field(EventConfig { c_neg: -0.1, ..d() }), "c_neg");
    assert_eq!(field(EventConfig { log_eps: 0.0, ..d() }), "log_eps");
    let nz = |noise: NoiseConfig| EventConfig { noise, ..d() };
    assert_eq!(field(nz(NoiseConfig { leak_rate_hz: -1.0, ..Default::default() })), "noise.leak_rate_hz");
    assert_eq!(field(nz(NoiseConfig { shot_noise_rate_hz: f32::NAN, ..Default::default() })), "noise.shot_noise_rate_hz");
    let tm = Some(ThresholdMismatch { sigma: -0.01, mode: MismatchMode::Fixed });
    assert_eq!(field(nz(NoiseConfig { threshold_mismatch: tm, ..Default::default() })), "noise.threshold_mismatch.sigma");
    let pr = Some(Photoreceptor { cutoff_hz: 0.0 });
    assert_eq!(field(nz(NoiseConfig { photoreceptor: pr, ..Default::default() })), "noise.photoreceptor.cutoff_hz");
    // config files reject unknown keys, also nested ones
    assert!(toml::from_str::<EventConfig>("c_pos = 0.3\nc_neg = 0.3").is_ok());
    assert!(toml::from_str::<EventConfig>("c_pos = 0.3\nthreshold = 1").is_err());
    assert!(toml::from_str::<EventConfig>("[noise]\nleak_rate = 1").is_err());
    let parsed: EventConfig = toml::from_str("[noise.refractory]\nperiod_ns = 1000\nmode = \"fire_later\"").unwrap();
    assert_eq!(parsed.noise.refractory, Some(Refractory { period_ns: 1000, mode: RefractoryMode::FireLater }));
}

#[test]
fn bad_frames_are_rejected_without_side_effects() {
    let frames = moving_pattern(8, 6, 6, 3);
    let times: Vec<i64> = (0..6).map(ms).collect();
    let clean = run(&EventConfig::default(), &frames, &times);
    let mut sim = EventSimulator::new(EventConfig::default(), 8, 6).unwrap();
    let mut nan = frames[2].clone();
    nan.pixels[2 * 8 + 3].y = f32::NAN;
    let mut neg = frames[2].clone();
    neg.pixels[8].z = -1e-3;
    for (k, (f, &t)) in frames.iter().zip(&times).enumerate() {
        let mut sink = VecSink::default();
        if k >= 1 {
            let e = sim.step(&gray(8, 5, |_, _| 0.5), t, &mut sink).unwrap_err();
            assert!(matches!(e, EventError::FrameSize { width: 8, height: 6, got_width: 8, got_height: 5 }), "{e}");
            let e = sim.step(f, times[k - 1], &mut sink).unwrap_err();
            assert!(matches!(e, EventError::NonIncreasingTime { .. }), "{e}");
            let e = sim.step(f, times[k - 1] - 5, &mut sink).unwrap_err();
            assert!(matches!(e, EventError::NonIncreasingTime { .. }), "{e}");
            let e = sim.step(&nan, t, &mut sink).unwrap_err();
            assert!(matches!(e, EventError::BadIntensity { x: 3, y: 2, .. }), "{e}");
            assert!(e.to_string().contains("(x 3, y 2)"), "{e}");
            let e = sim.step(&neg, t, &mut sink).unwrap_err();
            assert!(matches!(e, EventError::BadIntensity { x: 0, y: 1, .. }), "{e}");
            assert!(sink.events.is_empty(), "a rejected frame emits nothing");
        }
        sim.step(f, t, &mut sink).unwrap();
        assert_eq!(sink.events, clean[k], "frame {k}: the rejected frames changed the state");
    }
}

#[test]
fn frame_stats_report_the_change_in_thresholds() {
    let cfg = EventConfig { c_pos: 0.2, c_neg: 0.4, ..EventConfig::default() };
    let mut sim = EventSimulator::new(cfg.clone(), 2, 1).unwrap();
    let mut sink = VecSink::default();
    let l = |i: f32| (cfg.log_eps + i).ln();
    sim.step(&gray(2, 1, |_, _| 0.5), 0, &mut sink).unwrap();
    // pixel 0 brightens by 0.1 C_p... pixel 1 darkens by 1.5 C_m
    let i1 = [(l(0.5) + 0.1 * 0.2).exp() - cfg.log_eps, (l(0.5) - 1.5 * 0.4).exp() - cfg.log_eps];
    let st = sim.step(&gray(2, 1, |x, _| i1[x as usize]), 1_000_000, &mut sink).unwrap();
    assert!((st.max_change_c - 1.5).abs() < 1e-4, "{st:?}");
    assert!(st.undersampled());
    assert_eq!((st.on, st.off), (0, 1));
    assert_eq!(st.suggested_interval_ns(1_000_000, 0.5), Some(333_333));
    let st = sim.step(&gray(2, 1, |x, _| i1[x as usize]), 2_000_000, &mut sink).unwrap();
    assert!(!st.undersampled() && st.suggested_interval_ns(1_000_000, 0.5).is_none());
}
