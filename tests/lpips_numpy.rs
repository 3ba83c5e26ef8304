//! `benchmark::lpips` against `tests/python/lpips_ref.py`, an independent numpy (float64)
//! implementation of LPIPS-alex v0.1, on random weights written by the one Python writer
//! (`benchmark/scripts/lpips_format.py`): He-scaled conv weights (activations stay of order one
//! through the five layers), small biases, non-negative heads with some zeros, seed 7.
//!
//! Image pairs of several sizes (the 31x31 minimum, 64x64, odd 67x45 and its portrait 45x67, a
//! thin 200x31, 300x200) and kinds (smooth + noise at two levels, pure noise, a checkerboard
//! against its one-pixel shift, identical images). The distance and each of its five per-tap
//! terms must agree to [`REL_TOL`] (relative). Properties checked on our side alone: d(a, a) = 0,
//! d(a, b) = d(b, a) bit for bit, and growing perturbations give growing distances. A weights
//! file cut short, with a wrong magic or a wrong shape is an error naming the file. The time of
//! a 600x400 pair is printed (all threads and one).
//!
//! Without the Mitsuba venv's Python (with numpy) the tests print SKIPPED, or fail when
//! `EVBLUR_REQUIRE_MITSUBA=1`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use benchmark::lpips::Lpips;
use evblur_tests::{python_with, rel_err, run_python, temp_dir, write_npy_f32};
use simulator::base::sampling::Rng;

/// Agreement required with numpy, relative to the numpy value.
const REL_TOL: f64 = 1e-4;

/// Writes random LPIPS weights with `lpips_format.write`: argv = scripts dir, output, seed.
const RANDOM_WEIGHTS: &str = r#"
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import lpips_format
rng = np.random.default_rng(int(sys.argv[3]))
tensors = {}
for name, shape in lpips_format.TENSORS:
    if name.startswith("conv") and name.endswith(".weight"):
        # He initialisation: std sqrt(2 / fan_in) keeps the ReLU activations of order one.
        tensors[name] = rng.normal(0.0, np.sqrt(2.0 / np.prod(shape[1:])), shape)
    elif name.endswith(".bias"):
        tensors[name] = rng.normal(0.0, 0.05, shape)
    else:
        head = rng.uniform(0.0, 1.0, shape)
        head[rng.uniform(size=shape) < 0.2] = 0.0
        tensors[name] = head
lpips_format.write(sys.argv[2], tensors)
"#;

/// Random weights (seed 7) in `dir`, written by the Python writer.
fn random_weights(py: &Path, dir: &Path) -> PathBuf {
    let path = dir.join("lpips_random.bin");
    let scripts = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benchmark/scripts");
    run_python(py, RANDOM_WEIGHTS, [scripts.as_os_str(), path.as_os_str(), "7".as_ref()]);
    path
}

/// What an image is made of.
#[derive(Clone, Copy)]
enum Kind {
    /// Gradients, a blob and stripes per channel, plus uniform noise of this amplitude.
    Smooth(f32),
    /// Uniform noise in [0, 1].
    Noise,
    /// 8-pixel checkerboard of two colours, shifted right by this many pixels.
    Checker(usize),
}

/// An interleaved RGB image in [0, 1].
fn image(w: usize, h: usize, kind: Kind, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed, 23);
    let mut data = Vec::with_capacity(w * h * 3);
    for j in 0..h {
        for i in 0..w {
            for c in 0..3 {
                let (u, v) = (i as f32 / w as f32, j as f32 / h as f32);
                let value = match kind {
                    Kind::Smooth(noise) => {
                        let blob = (-((u - 0.6).powi(2) + (v - 0.4).powi(2)) * 10.0).exp();
                        let stripes = 0.1 * (40.0 * u + 3.0 * c as f32).sin();
                        0.15 + 0.4 * u + 0.2 * v + 0.25 * blob + stripes + noise * (rng.next_f32() - 0.5)
                    }
                    Kind::Noise => rng.next_f32(),
                    Kind::Checker(shift) => [0.1 + 0.1 * c as f32, 0.9 - 0.2 * c as f32][((i + shift) / 8 + j / 8) % 2],
                };
                data.push(value.clamp(0.0, 1.0));
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
    a: Vec<f32>,
    b: Vec<f32>,
}

fn cases() -> Vec<Case> {
    let case = |name, w, h, (ka, kb): (Kind, Kind), seed| Case {
        name,
        w,
        h,
        a: image(w, h, ka, seed),
        b: image(w, h, kb, seed + 1),
    };
    let (clean, light, heavy) = (Kind::Smooth(0.0), Kind::Smooth(0.05), Kind::Smooth(0.3));
    let same = image(64, 48, light, 50);
    vec![
        case("31x31 minimum", 31, 31, (clean, light), 1),
        case("64x64 clean vs noisy", 64, 64, (clean, heavy), 3),
        case("67x45 odd, two noise levels", 67, 45, (light, heavy), 5),
        case("45x67 portrait", 45, 67, (light, heavy), 7),
        case("200x31 thin", 200, 31, (clean, light), 9),
        case("50x40 pure noise", 50, 40, (Kind::Noise, Kind::Noise), 11),
        case("96x64 checker vs 1px shift", 96, 64, (Kind::Checker(0), Kind::Checker(1)), 13),
        case("300x200 clean vs noisy", 300, 200, (clean, light), 15),
        Case { name: "64x48 identical", w: 64, h: 48, a: same.clone(), b: same },
    ]
}

/// `lpips_ref.py` on every case: (distance, five per-tap terms) per pair.
fn numpy_reference(py: &Path, weights: &Path, dir: &Path, cases: &[Case]) -> Vec<(f64, Vec<f64>)> {
    let mut args = vec![weights.to_owned()];
    for (k, c) in cases.iter().enumerate() {
        for (tag, data) in [("a", &c.a), ("b", &c.b)] {
            let path = dir.join(format!("{k}{tag}.npy"));
            write_npy_f32(&path, &[c.h, c.w, 3], data);
            args.push(path);
        }
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/lpips_ref.py");
    // One BLAS thread: the reference is small, and the machine may be busy.
    let out =
        Command::new(py).arg(script).args(&args).env("OPENBLAS_NUM_THREADS", "1").env("OMP_NUM_THREADS", "1").output();
    let out = out.unwrap();
    assert!(out.status.success(), "lpips_ref.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let reference: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let reference = reference.as_array().unwrap();
    assert_eq!(reference.len(), cases.len());
    reference
        .iter()
        .map(|r| {
            let layers = r["layers"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            (r["distance"].as_f64().unwrap(), layers)
        })
        .collect()
}

#[test]
fn lpips_matches_numpy() {
    let Some(py) = python_with("numpy", "lpips_matches_numpy") else { return };
    let dir = temp_dir("lpips", "numpy");
    let weights = random_weights(&py, &dir);
    let net = Lpips::load(&weights).unwrap();
    let cases = cases();
    let reference = numpy_reference(&py, &weights, &dir, &cases);

    let (mut worst, mut worst_layer) = (0.0f64, 0.0f64);
    for (c, (want, want_layers)) in cases.iter().zip(&reference) {
        let (a, b) = ((c.w, c.h, c.a.as_slice()), (c.w, c.h, c.b.as_slice()));
        let d = net.distance(a, b).unwrap();
        let layers = net.layer_distances(a, b).unwrap();
        println!("{:30} LPIPS {d:.8} (numpy {want:.8})  rel. diff {:.2e}", c.name, rel_err(d, *want));
        worst = worst.max(rel_err(d, *want));
        assert!(rel_err(d, *want) < REL_TOL, "{}: LPIPS {d} vs numpy {want}", c.name);
        for (l, (&ours, &want)) in layers.iter().zip(want_layers).enumerate() {
            worst_layer = worst_layer.max(rel_err(ours, want));
            assert!(rel_err(ours, want) < REL_TOL, "{}: tap {} term {ours} vs numpy {want}", c.name, l + 1);
        }
        if c.name.ends_with("identical") {
            assert_eq!((d, *want), (0.0, 0.0), "{}", c.name);
        } else {
            assert!(d > 0.0, "{}: distance {d}", c.name);
        }
        // Identity and symmetry (bit for bit: both images go through the same arithmetic).
        assert_eq!(net.distance(a, a).unwrap(), 0.0, "{}: d(a, a)", c.name);
        assert_eq!(net.distance(b, a).unwrap(), d, "{}: d(b, a) != d(a, b)", c.name);
    }
    println!("max relative |ours - numpy|: distance {worst:.3e}, per-tap terms {worst_layer:.3e}");
}

#[test]
fn larger_perturbations_give_larger_distances() {
    let Some(py) = python_with("numpy", "larger_perturbations_give_larger_distances") else { return };
    let dir = temp_dir("lpips", "monotone");
    let net = Lpips::load(random_weights(&py, &dir)).unwrap();
    let (w, h) = (128, 96);
    let a = image(w, h, Kind::Smooth(0.0), 30);
    let mut rng = Rng::new(31, 5);
    let noise: Vec<f32> = (0..a.len()).map(|_| rng.next_f32() - 0.5).collect();
    let mut last = 0.0;
    for s in [0.01, 0.03, 0.1, 0.3] {
        let b: Vec<f32> = a.iter().zip(&noise).map(|(v, n)| (v + s * n).clamp(0.0, 1.0)).collect();
        let d = net.distance((w, h, &a), (w, h, &b)).unwrap();
        println!("noise amplitude {s:4}: LPIPS {d:.6}");
        assert!(d > last, "noise {s}: distance {d} not above {last}");
        last = d;
    }
}

#[test]
fn malformed_weights_files_are_errors_naming_the_file() {
    let Some(py) = python_with("numpy", "malformed_weights_files_are_errors_naming_the_file") else { return };
    let dir = temp_dir("lpips", "malformed");
    let good = std::fs::read(random_weights(&py, &dir)).unwrap();
    let expect_error = |name: &str, bytes: &[u8], says: &str| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let msg = Lpips::load(&path).err().unwrap_or_else(|| panic!("{name} accepted")).to_string();
        println!("{name}: {msg}");
        assert!(msg.contains(path.to_str().unwrap()) && msg.contains("install_lpips.sh"), "{msg}");
        assert!(msg.contains(says), "{name}: {msg:?} does not say {says:?}");
    };
    expect_error("half.bin", &good[..good.len() / 2], "truncated");
    expect_error("one_short.bin", &good[..good.len() - 1], "truncated");
    expect_error("empty.bin", b"", "not an LPIPS weights file");
    let mut magic = good.clone();
    magic[..8].copy_from_slice(b"\x80\x02}q\x00(X\x05"); // a pickle, e.g. a .pth given by mistake
    expect_error("magic.bin", &magic, "not an LPIPS weights file");
    let mut shape = good.clone();
    shape[36..40].copy_from_slice(&32u32.to_le_bytes()); // conv1.weight (32, 3, 11, 11)
    expect_error("shape.bin", &shape, "[32, 3, 11, 11]");
    let missing = dir.join("missing.bin");
    let msg = Lpips::load(&missing).err().unwrap().to_string();
    assert!(msg.contains(missing.to_str().unwrap()), "{msg}");
}

#[test]
fn time_of_a_600x400_pair() {
    let Some(py) = python_with("numpy", "time_of_a_600x400_pair") else { return };
    let dir = temp_dir("lpips", "timing");
    let net = Lpips::load(random_weights(&py, &dir)).unwrap();
    let (a, b) = (image(600, 400, Kind::Smooth(0.0), 40), image(600, 400, Kind::Smooth(0.1), 41));
    let best = |threads: usize| -> Duration {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            (0..3)
                .map(|_| {
                    let t = Instant::now();
                    std::hint::black_box(net.distance((600, 400, &a), (600, 400, &b)).unwrap());
                    t.elapsed()
                })
                .min()
                .unwrap()
        })
    };
    let all = rayon::current_num_threads();
    println!("LPIPS 600x400 pair: {:.0} ms on {all} threads", best(all).as_secs_f64() * 1e3);
    println!("LPIPS 600x400 pair: {:.0} ms on 1 thread", best(1).as_secs_f64() * 1e3);
}
