//! `trainer::metrics` ([`psnr`], [`ssim`]) against scikit-image's `peak_signal_noise_ratio` and
//! `structural_similarity` (`tests/python/metrics_ref.py`, data range 1, float64) on image pairs
//! of several sizes (odd ones, the 7x7 minimum, a 600x400 frame), 1 and 3 channels: noisy copies
//! of a smooth image, two noise levels, pure noise, identical images. Both must agree to 1e-4
//! (absolute); the largest differences and the time of one 600x400 RGB SSIM are printed.
//!
//! Without the Mitsuba venv's Python (with numpy and scikit-image) the test prints SKIPPED, or
//! fails when `EVBLUR_REQUIRE_MITSUBA=1`.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use evblur_tests::{python_with, temp_dir, write_npy_f32};
use simulator::base::sampling::Rng;
use trainer::metrics::{psnr, ssim, ImageRef};

/// Agreement required with skimage (absolute, PSNR in dB and SSIM).
const TOL: f64 = 1e-4;

/// A smooth image (gradients, a blob, stripes per channel) plus uniform noise of amplitude
/// `noise`, clamped to [0, 1]; `noise = 1` with `smooth = false` is pure noise.
fn image(w: usize, h: usize, nc: usize, smooth: bool, noise: f32, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed, 11);
    let mut data = Vec::with_capacity(w * h * nc);
    for j in 0..h {
        for i in 0..w {
            for c in 0..nc {
                let (u, v) = (i as f32 / w as f32, j as f32 / h as f32);
                let blob = (-((u - 0.6).powi(2) + (v - 0.4).powi(2)) * 10.0).exp();
                let stripes = 0.1 * (12.0 * u + 3.0 * c as f32).sin();
                let base = if smooth { 0.15 + 0.4 * u + 0.2 * v + 0.25 * blob + stripes } else { 0.5 };
                data.push((base + noise * (rng.next_f32() - 0.5)).clamp(0.0, 1.0));
            }
        }
    }
    data
}

/// One image pair to score.
struct Case {
    name: &'static str,
    w: usize,
    h: usize,
    nc: usize,
    a: Vec<f32>,
    b: Vec<f32>,
}

fn cases() -> Vec<Case> {
    let case = |name, w, h, nc, a, b| Case { name, w, h, nc, a, b };
    let pair = |name, w, h, nc, (na, nb): (f32, f32), seed| {
        case(name, w, h, nc, image(w, h, nc, true, na, seed), image(w, h, nc, true, nb, seed + 1))
    };
    let same = image(25, 19, 3, true, 0.2, 40);
    vec![
        pair("minimum 7x7 gray", 7, 7, 1, (0.0, 0.2), 1),
        pair("8x7 rgb", 8, 7, 3, (0.05, 0.3), 3),
        pair("16x9 gray", 16, 9, 1, (0.0, 0.1), 5),
        pair("33x17 rgb, odd", 33, 17, 3, (0.0, 0.05), 7),
        pair("64x48 rgb, two noise levels", 64, 48, 3, (0.02, 0.2), 9),
        pair("101x63 gray, odd", 101, 63, 1, (0.1, 0.5), 11),
        case("45x31 rgb, pure noise", 45, 31, 3, image(45, 31, 3, false, 1.0, 13), image(45, 31, 3, false, 1.0, 14)),
        case("25x19 rgb, identical", 25, 19, 3, same.clone(), same),
        pair("600x400 rgb", 600, 400, 3, (0.0, 0.1), 15),
    ]
}

#[test]
fn psnr_and_ssim_match_skimage() {
    let Some(py) = python_with("numpy, skimage.metrics", "psnr_and_ssim_match_skimage") else { return };
    let dir = temp_dir("metrics", "skimage");
    let cases = cases();
    let mut args = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        for (tag, data) in [("a", &c.a), ("b", &c.b)] {
            let path = dir.join(format!("{k}{tag}.npy"));
            let shape = if c.nc == 1 { vec![c.h, c.w] } else { vec![c.h, c.w, c.nc] };
            write_npy_f32(&path, &shape, data);
            args.push(path);
        }
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/metrics_ref.py");
    let out = Command::new(&py).arg(script).args(&args).output().unwrap();
    assert!(out.status.success(), "metrics_ref.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let reference: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let reference = reference.as_array().unwrap();
    assert_eq!(reference.len(), cases.len());

    let (mut worst_psnr, mut worst_ssim) = (0.0f64, 0.0f64);
    for (c, r) in cases.iter().zip(reference) {
        let a = ImageRef::new(c.w, c.h, c.nc, &c.a).unwrap();
        let b = ImageRef::new(c.w, c.h, c.nc, &c.b).unwrap();
        let (p, s) = (psnr(a, b).unwrap(), ssim(a, b).unwrap());
        let want_p = match &r["psnr"] {
            serde_json::Value::String(v) if v == "inf" => f64::INFINITY,
            v => v.as_f64().unwrap(),
        };
        let want_s = r["ssim"].as_f64().unwrap();
        println!("{:32} PSNR {p:10.6} (skimage {want_p:10.6})  SSIM {s:.8} (skimage {want_s:.8})", c.name);
        if want_p.is_infinite() {
            assert_eq!(p, want_p, "{}: PSNR", c.name);
        } else {
            worst_psnr = worst_psnr.max((p - want_p).abs());
            assert!((p - want_p).abs() < TOL, "{}: PSNR {p} vs skimage {want_p}", c.name);
        }
        worst_ssim = worst_ssim.max((s - want_s).abs());
        assert!((s - want_s).abs() < TOL, "{}: SSIM {s} vs skimage {want_s}", c.name);
    }
    println!("max |ours - skimage|: PSNR {worst_psnr:.3e} dB, SSIM {worst_ssim:.3e}");

    // Time of one SSIM on the 600x400 RGB pair (best of 5).
    let big = cases.last().unwrap();
    let (a, b) = (ImageRef::new(600, 400, 3, &big.a).unwrap(), ImageRef::new(600, 400, 3, &big.b).unwrap());
    let best = (0..5)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(ssim(a, b).unwrap());
            t.elapsed()
        })
        .min()
        .unwrap();
    println!("ssim 600x400 RGB: {:.2} ms", best.as_secs_f64() * 1e3);
}
