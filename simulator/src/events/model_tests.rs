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
    let ph: Vec<f32> = (0..4).map(|_| rng.next_f32() * std::f32::consts::TAU).collect();
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
    assert_eq!(
        field(nz(NoiseConfig { shot_noise_rate_hz: f32::NAN, ..Default::default() })),
        "noise.shot_noise_rate_hz"
    );
    let tm = Some(ThresholdMismatch { sigma: -0.01, mode: MismatchMode::Fixed });
    assert_eq!(
        field(nz(NoiseConfig { threshold_mismatch: tm, ..Default::default() })),
        "noise.threshold_mismatch.sigma"
    );
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

/// Events of a static grey scene over `frames` intervals of `dt_ns`.
fn static_run(cfg: &EventConfig, w: u32, h: u32, frames: usize, dt_ns: i64) -> Vec<Event> {
    let img = gray(w, h, |_, _| 0.4);
    let mut sim = EventSimulator::new(cfg.clone(), w, h).unwrap();
    let mut sink = VecSink::default();
    for k in 0..=frames {
        sim.step(&img, k as i64 * dt_ns, &mut sink).unwrap();
    }
    sink.events
}

#[test]
fn leak_rate_matches_config() {
    let rate = 20.0;
    let cfg = EventConfig { noise: NoiseConfig { leak_rate_hz: rate, ..Default::default() }, ..EventConfig::default() };
    let (w, h, seconds) = (32u32, 32u32, 2.0);
    let ev = static_run(&cfg, w, h, 1000, 2_000_000);
    let measured = ev.len() as f64 / (w * h) as f64 / seconds;
    assert!((measured / rate as f64 - 1.0).abs() < 0.2, "leak rate {measured} Hz, configured {rate}");
    assert!(ev.iter().all(|e| e.p == 1), "leak events are ON");
    // the random phase spreads them out: not all pixels fire in the same nanosecond
    let first_t: std::collections::HashSet<i64> = ev.iter().take(100).map(|e| e.t_ns).collect();
    assert!(first_t.len() > 50);
}

#[test]
fn shot_noise_rate_matches_config() {
    let rate = 30.0;
    let cfg =
        EventConfig { noise: NoiseConfig { shot_noise_rate_hz: rate, ..Default::default() }, ..EventConfig::default() };
    let (w, h, seconds) = (32u32, 32u32, 2.0);
    let ev = static_run(&cfg, w, h, 1000, 2_000_000);
    let measured = ev.len() as f64 / (w * h) as f64 / seconds;
    assert!((measured / rate as f64 - 1.0).abs() < 0.2, "shot rate {measured} Hz, configured {rate}");
    let on = ev.iter().filter(|e| e.p == 1).count() as f64 / ev.len() as f64;
    assert!((on - 0.5).abs() < 0.03, "ON fraction {on}");
    assert!(ev.windows(2).all(|p| p[0].t_ns <= p[1].t_ns), "sorted across intervals");
}

/// Sample mean and standard deviation.
fn moments(v: &[f32]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

#[test]
fn threshold_mismatch_has_the_configured_statistics() {
    let (c_pos, c_neg, sigma) = (0.2f32, 0.3f32, 0.03f32);
    for mode in [MismatchMode::Fixed, MismatchMode::PerInterval] {
        let noise = NoiseConfig { threshold_mismatch: Some(ThresholdMismatch { sigma, mode }), ..Default::default() };
        let cfg = EventConfig { c_pos, c_neg, noise, ..EventConfig::default() };
        let mut sim = EventSimulator::new(cfg, 100, 100).unwrap();
        let img = gray(100, 100, |_, _| 0.5);
        sim.step(&img, 0, &mut VecSink::default()).unwrap();
        let first: Vec<Pixel> = sim.pixels.clone();
        sim.step(&img, 1_000_000, &mut VecSink::default()).unwrap();
        for (name, c, get) in
            [("c_pos", c_pos, (|p: &Pixel| p.c_pos) as fn(&Pixel) -> f32), ("c_neg", c_neg, |p| p.c_neg)]
        {
            let v: Vec<f32> = sim.pixels.iter().map(get).collect();
            let (mean, sd) = moments(&v);
            // 10^4 samples: standard errors 3e-4 (mean) and 0.7 % (sigma)
            assert!((mean - c as f64).abs() < 0.0015, "{mode:?} {name}: mean {mean}");
            assert!((sd / sigma as f64 - 1.0).abs() < 0.05, "{mode:?} {name}: sigma {sd}");
            let same = first.iter().zip(&sim.pixels).filter(|(a, b)| get(a) == get(b)).count();
            match mode {
                MismatchMode::Fixed => assert_eq!(same, v.len(), "fixed thresholds must not change"),
                MismatchMode::PerInterval => assert!(same < 10, "{same} thresholds not redrawn"),
            }
        }
    }
}

#[test]
fn refractory_consumes_or_delays_crossings() {
    // one pixel ramps by D = 10.5 C over 1 ms: crossings at T_n = n / 10.5 ms, ~95 us apart;
    // then it stays still for 2 ms
    let c = 0.2f32;
    let eps = 1e-3f32;
    let (i0, i1) = (0.01f32, (eps + 0.01) * (10.5 * c).exp() - eps);
    let luma = |i: f32| i / Vec3::ONE.dot(LUMA_709); // so that the luma is exactly i (to f32 precision)
    let frames = [
        gray(1, 1, |_, _| luma(i0)),
        gray(1, 1, |_, _| luma(i1)),
        gray(1, 1, |_, _| luma(i1)),
        gray(1, 1, |_, _| luma(i1)),
    ];
    let times = [0, ms(1), ms(2), ms(3)];
    let period = 250_000i64;
    let log = |i: f32| (eps + Vec3::splat(luma(i)).dot(LUMA_709)).ln() as f64;
    let d = log(i1) - log(i0);
    assert_eq!((d / c as f64).floor(), 10.0);
    let t_cross = |n: usize| (n as f64 * c as f64 / d * 1e6).round() as i64;
    let cfg = |mode| EventConfig {
        c_pos: c,
        c_neg: c,
        log_eps: eps,
        noise: NoiseConfig { refractory: Some(Refractory { period_ns: period, mode }), ..Default::default() },
        ..EventConfig::default()
    };
    let times_of = |out: &Vec<Vec<Event>>| out.iter().flatten().map(|e| e.t_ns).collect::<Vec<_>>();

    // ESIM: crossings 2, 3, 5, 6, 8, 9 fall inside the period of the last event and are lost
    let out = run(&cfg(RefractoryMode::Consume), &frames, &times);
    assert_eq!(times_of(&out), vec![t_cross(1), t_cross(4), t_cross(7), t_cross(10)]);
    assert!(out[2].is_empty() && out[3].is_empty(), "consumed crossings never come back");

    // v2e: every crossing fires, one period after the previous event; 4 in the ramp interval,
    // the 6 still pending at 1 ms in the following still intervals
    let out = run(&cfg(RefractoryMode::FireLater), &frames, &times);
    let expected: Vec<i64> = (0..10).map(|k| t_cross(1) + k * period).collect();
    assert_eq!(times_of(&out), expected);
    assert_eq!(out.iter().map(Vec::len).collect::<Vec<_>>(), vec![0, 4, 4, 2]);
    assert!(out.iter().flatten().all(|e| e.p == 1));
}

#[test]
fn photoreceptor_low_pass_delays_events_more_in_the_dark() {
    // an intensity step x2 at frame 1: the filtered log follows
    // lp_k = L_b - (L_b - L_a) (1 - a)^k with a = ((255 I + 20) / 275) dt 2 pi f, so the
    // cumulative event count after frame k is floor((lp_k - L_a) / C)
    let cutoff_hz = 20.0f32;
    let cfg = EventConfig {
        c_pos: 0.1,
        noise: NoiseConfig { photoreceptor: Some(Photoreceptor { cutoff_hz }), ..Default::default() },
        ..EventConfig::default()
    };
    let counts = |lo: f32| {
        let frames: Vec<Image> = (0..60).map(|k| gray(1, 1, |_, _| if k == 0 { lo } else { 2.0 * lo })).collect();
        let out = run(&cfg, &frames, &(0..60).map(ms).collect::<Vec<_>>());
        out.iter()
            .scan(0usize, |n, o| {
                *n += o.len();
                Some(*n)
            })
            .collect::<Vec<usize>>()
    };
    let expected = |lo: f32| {
        let i_b = Vec3::splat(2.0 * lo).dot(LUMA_709);
        let (l_a, l_b) = ((cfg.log_eps + Vec3::splat(lo).dot(LUMA_709)).ln(), (cfg.log_eps + i_b).ln());
        let a = ((255.0 * i_b + 20.0) / 275.0 * 1e-3 * std::f32::consts::TAU * cutoff_hz) as f64;
        (0..60)
            .map(|k| (((l_b - l_a) as f64 * (1.0 - (1.0 - a).powi(k)) + 1e-9) / cfg.c_pos as f64).floor() as usize)
            .collect::<Vec<_>>()
    };
    let (bright, dim) = (counts(0.4), counts(0.01));
    for (k, (&got, want)) in bright.iter().zip(expected(0.4)).enumerate() {
        assert_eq!(got, want, "bright, frame {k}: {got} events, expected {want}");
    }
    for (k, (&got, want)) in dim.iter().zip(expected(0.01)).enumerate() {
        assert_eq!(got, want, "dim, frame {k}: {got} events, expected {want}");
    }
    assert!(bright[3] < 6 && bright[59] == 6, "filtered, but all 6 crossings arrive: {bright:?}");
    assert!(dim[59] < bright[59], "the dim pixel lags: {dim:?}");
}

#[test]
fn radiance_above_one_reaches_the_model_unclamped() {
    // a pixel brightening from 2 to 8 (both beyond the frame camera's white): ln(4) / 0.2 = 6.9
    // crossings, so 6 ON events; a clamp at 1 would give none
    let cfg = EventConfig { c_pos: 0.2, c_neg: 0.2, ..EventConfig::default() };
    let frames = [gray(1, 1, |_, _| 2.0), gray(1, 1, |_, _| 8.0), gray(1, 1, |_, _| 0.5)];
    let ev = run(&cfg, &frames, &[ms(0), ms(1), ms(2)]);
    assert_eq!(ev[1].len(), 6, "{:?}", ev[1]);
    assert!(ev[1].iter().all(|e| e.p > 0));
    // and down to 0.5, from the last ON level ln(2) + 6 * 0.2: (ln(0.25) - 1.2) / 0.2 = -12.9
    assert_eq!(ev[2].len(), 12, "{:?}", ev[2]);
    assert!(ev[2].iter().all(|e| e.p < 0));
}

/// [`run`] through [`LogFrame`]s in batches of `batch` frames.
fn run_batched(cfg: &EventConfig, frames: &[Image], times: &[i64], batch: usize) -> (Vec<Event>, Vec<FrameStats>) {
    let mut sim = EventSimulator::new(cfg.clone(), frames[0].width, frames[0].height).unwrap();
    let log: Vec<LogFrame> = frames.iter().map(|f| LogFrame::from_image(f, cfg).unwrap()).collect();
    let mut sink = VecSink::default();
    let mut stats = Vec::new();
    for (f, t) in log.chunks(batch).zip(times.chunks(batch)) {
        stats.extend(sim.step_log_batch(f, t, &mut sink).unwrap());
    }
    (sink.events, stats)
}

#[test]
fn log_frames_in_batches_give_the_events_and_stats_of_single_steps() {
    let (w, h) = (37u32, 23u32); // rows not a multiple of the chunk height
    let frames = moving_pattern(w, h, 30, 9);
    let times: Vec<i64> = (0..frames.len()).map(|k| ms(k) + (k as i64 * 7919) % 1000).collect();
    let configs = [
        EventConfig::default(),
        EventConfig { sensor: Sensor::Rggb, c_pos: 0.15, c_neg: 0.25, ..EventConfig::default() },
        noisy(RefractoryMode::FireLater, MismatchMode::Fixed),
        noisy(RefractoryMode::Consume, MismatchMode::PerInterval),
    ];
    for cfg in configs {
        // single steps on images: the reference
        let mut sim = EventSimulator::new(cfg.clone(), w, h).unwrap();
        let mut sink = VecSink::default();
        let stats: Vec<FrameStats> =
            frames.iter().zip(&times).map(|(f, &t)| sim.step(f, t, &mut sink).unwrap()).collect();
        assert!(sink.events.len() > 100, "the pattern must fire: {}", sink.events.len());
        for batch in [1, 4, 29, 64] {
            let (events, batch_stats) = run_batched(&cfg, &frames, &times, batch);
            assert_eq!(events, sink.events, "batch {batch}, {cfg:?}");
            assert_eq!(batch_stats, stats, "batch {batch}, {cfg:?}");
        }
    }
}

#[test]
fn the_ideal_pixel_loop_matches_the_general_one() {
    // chunk_ideal is what step runs without non-idealities; chunk is the general loop
    let (w, h) = (40u32, 8u32);
    let frames = moving_pattern(w, h, 25, 4);
    let cfg = EventConfig { c_pos: 0.11, c_neg: 0.13, ..EventConfig::default() };
    let (mut a, mut b) =
        (EventSimulator::new(cfg.clone(), w, h).unwrap(), EventSimulator::new(cfg.clone(), w, h).unwrap());
    a.step(&frames[0], 0, &mut VecSink::default()).unwrap();
    b.step(&frames[0], 0, &mut VecSink::default()).unwrap();
    let n = w as usize * h as usize;
    let mut fired = 0;
    for (k, f) in frames.iter().enumerate().skip(1) {
        let levels = ImageLevels { image: f, sensor: cfg.sensor, log_eps: cfg.log_eps };
        let iv = Interval { cfg: &cfg, width: w as usize, t0: ms(k - 1), t1: ms(k), dt: 1e6, dt_s: 1e-3 };
        let (mut ea, mut eb) = (Vec::new(), Vec::new());
        let sa = iv.chunk_ideal(0, &mut a.pixels[..n], &mut a.noise[..n], &levels, &mut ea);
        let sb = iv.chunk(0, &mut b.pixels[..n], &mut b.noise[..n], &levels, &mut eb);
        assert_eq!(ea, eb, "frame {k}");
        assert_eq!((sa.on, sa.off), (sb.on, sb.off));
        assert_eq!(sa.max_change_c.to_bits(), sb.max_change_c.to_bits(), "frame {k}");
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            assert_eq!((p.ref_l.to_bits(), p.l.to_bits()), (q.ref_l.to_bits(), q.l.to_bits()));
        }
        fired += ea.len();
    }
    assert!(fired > 100, "{fired}");
}

#[test]
fn log_frames_are_checked() {
    let e = LogFrame::new(2, 2, vec![0.5; 3], vec![0.0; 4]).unwrap_err();
    assert!(matches!(e, EventError::FrameLength { intensity: 3, log: 4, .. }), "{e}");
    let e = LogFrame::new(2, 2, vec![0.5, 0.5, -1.0, 0.5], vec![0.0; 4]).unwrap_err();
    assert!(matches!(e, EventError::BadIntensity { x: 0, y: 1, .. }), "{e}");
    let e = LogFrame::new(2, 1, vec![0.5, 0.5], vec![0.0, f32::NAN]).unwrap_err();
    assert!(matches!(e, EventError::BadIntensity { x: 1, y: 0, .. }), "{e}");
    let mut img = gray(3, 1, |_, _| 0.5);
    img.pixels[2] = Vec3::new(0.5, f32::INFINITY, 0.5);
    let e = LogFrame::from_image(&img, &EventConfig::default()).unwrap_err();
    assert!(matches!(e, EventError::BadIntensity { x: 2, y: 0, .. }), "{e}");
    // another size or a time not after the last is refused, and nothing changes
    let mut sim = EventSimulator::new(EventConfig::default(), 3, 1).unwrap();
    let ok = LogFrame::from_image(&gray(3, 1, |_, _| 0.5), &EventConfig::default()).unwrap();
    sim.step_log(&ok, 10, &mut VecSink::default()).unwrap();
    let other = LogFrame::from_image(&gray(2, 1, |_, _| 0.5), &EventConfig::default()).unwrap();
    assert!(matches!(sim.step_log(&other, 20, &mut VecSink::default()), Err(EventError::FrameSize { .. })));
    let e = sim.step_log_batch(&[ok.clone(), ok.clone()], &[20, 20], &mut VecSink::default()).unwrap_err();
    assert!(matches!(e, EventError::NonIncreasingTime { prev_ns: 20, t_ns: 20 }), "{e}");
    assert_eq!(sim.last_time_ns(), Some(10));
}
