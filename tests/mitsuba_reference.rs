//! Our path tracer against Mitsuba 3 on the reference scenes in `scenes/` (cornell, textured_env, rough_metal).
//!
//! For each scene: load `scene.toml`, export it with `simulator::export::export_mitsuba`, render
//! a ground truth with Mitsuba at `GT_SPP` (cached under `~/.cache/evblur/mitsuba-gt/<hash>.exr`,
//! the hash covering the export and the render parameters), a Mitsuba image at `SPP` with another
//! seed, and ours at `SPP`. Pass: `relMSE_ours <= 1.2 relMSE_mitsuba` and no 20x20 tile with
//! `|z| > 5` (see `evblur_tests::compare`).
//!
//! Python: `$EVBLUR_MITSUBA_PYTHON`, else `~/.cache/evblur/mitsuba-venv/bin/python` (made by
//! `tests/mitsuba/setup.sh`). Without one the test prints SKIPPED and passes, unless
//! `EVBLUR_REQUIRE_MITSUBA=1`. `EVBLUR_MITSUBA_VARIANT` picks the variant (default llvm_ad_rgb).
//!
//! Run: `tests/mitsuba/setup.sh && cargo test -p evblur-tests --test mitsuba_reference -- --nocapture`

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use evblur_tests::compare::{max_abs_z, rel_mse, tile_z};
use glam::Vec3;
use simulator::export::export_mitsuba;
use simulator::render::film::{Image, RenderSettings};
use simulator::render::integrator::Renderer;

const SCENES: [&str; 3] = ["cornell", "textured_env", "rough_metal"];
const WIDTH: u32 = 240;
const HEIGHT: u32 = 160;
/// Samples per pixel of our render and of the equal-effort Mitsuba render.
const SPP: u32 = 64;
/// Samples per pixel of the ground truth.
const GT_SPP: u32 = 2048;
const GT_SEED: u32 = 1000;
const MITSUBA_SEED: u32 = 2;
const TILE: u32 = 20;
const Z_MAX: f64 = 5.0;
const RATIO_MAX: f64 = 1.2;

fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVBLUR_MITSUBA_PYTHON") {
        return Some(PathBuf::from(p)).filter(|p| p.exists());
    }
    let home = std::env::var_os("HOME")?;
    Some(Path::new(&home).join(".cache/evblur/mitsuba-venv/bin/python")).filter(|p| p.exists())
}

fn cache_dir() -> PathBuf {
    let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_else(std::env::temp_dir);
    home.join(".cache/evblur/mitsuba-gt")
}

/// FNV-1a 64: stable across Rust versions, unlike `DefaultHasher`.
fn fnv1a(state: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(state, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// Hash of every file of the export (sorted by name) plus the ground-truth parameters.
fn export_hash(dir: &Path, variant: &str) -> u64 {
    let mut names: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    names.sort();
    let mut h = fnv1a(0xcbf2_9ce4_8422_2325, format!("gt spp={GT_SPP} seed={GT_SEED} {variant} mitsuba=3.9.1").as_bytes());
    for name in names {
        if name.to_string_lossy().ends_with(".exr") && name.to_string_lossy().starts_with("mitsuba_") {
            continue; // our own outputs
        }
        h = fnv1a(h, name.to_string_lossy().as_bytes());
        h = fnv1a(h, &std::fs::read(dir.join(&name)).unwrap());
    }
    h
}

/// Timings printed by render.py.
struct MitsubaRun {
    variant: String,
    warmup_s: f64,
    render_s: f64,
}

/// Run `tests/mitsuba/render.py` on `scene_json`.
fn run_mitsuba(python: &Path, scene_json: &Path, spp: u32, seed: u32, variant: &str, out: &Path) -> MitsubaRun {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("mitsuba/render.py");
    let output = Command::new(python)
        .arg(&script)
        .arg(scene_json)
        .args(["--out", out.to_str().unwrap(), "--spp", &spp.to_string(), "--seed", &seed.to_string()])
        .args(["--variant", variant])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "render.py failed on {}:\n{stdout}\n{}",
        scene_json.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    let line = stdout.lines().rev().find(|l| l.starts_with('{')).expect("render.py printed no JSON line");
    let v: serde_json::Value = serde_json::from_str(line).expect("render.py JSON line");
    MitsubaRun {
        variant: v["variant"].as_str().unwrap_or("?").to_string(),
        warmup_s: v["warmup_s"].as_f64().unwrap_or(f64::NAN),
        render_s: v["render_s"].as_f64().unwrap_or(f64::NAN),
    }
}

fn read_exr(path: &Path) -> Image {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.width() as u32, res.height() as u32),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    img.layer_data.channel_data.pixels
}

/// One scene's numbers.
struct Row {
    scene: &'static str,
    rel_ours: f64,
    rel_mitsuba: f64,
    z_ours: f64,
    bad_tiles: usize,
    z_mitsuba: f64,
    t_ours: f64,
    mitsuba: MitsubaRun,
    gt_note: String,
}

fn check_scene(python: &Path, variant: &str, name: &'static str) -> Row {
    let toml = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name).join("scene.toml");
    let scene = simulator::scene::load(&toml).unwrap_or_else(|e| panic!("{e}"));
    let camera = scene.cameras.first().cloned().unwrap_or_else(|| panic!("{}: no camera", toml.display()));
    let mut settings = RenderSettings::new(camera);
    settings.width = WIDTH;
    settings.height = HEIGHT;
    settings.spp = SPP;
    settings.max_depth = 5;
    settings.rr_depth = 5;
    settings.seed = 1;

    let dir = std::env::temp_dir().join(format!("evblur-mitsuba-{}", std::process::id())).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    let json = export_mitsuba(&scene, &settings, &dir).unwrap_or_else(|e| panic!("{name}: {e}"));

    // ground truth, cached by content hash
    let gt_path = cache_dir().join(format!("{:016x}.exr", export_hash(&dir, variant)));
    let gt_note = if gt_path.exists() {
        "cached".to_string()
    } else {
        std::fs::create_dir_all(cache_dir()).unwrap();
        let tmp = gt_path.with_extension(format!("tmp{}.exr", std::process::id()));
        let run = run_mitsuba(python, &json, GT_SPP, GT_SEED, variant, &tmp);
        std::fs::rename(&tmp, &gt_path).unwrap();
        format!("{:.1} s", run.render_s)
    };
    let gt = read_exr(&gt_path);

    let mitsuba_out = dir.join("mitsuba_equal_spp.exr");
    let mitsuba = run_mitsuba(python, &json, SPP, MITSUBA_SEED, variant, &mitsuba_out);
    let theirs = read_exr(&mitsuba_out);

    let t0 = Instant::now();
    let ours = Renderer::new(&scene).render(&settings, None);
    let t_ours = t0.elapsed().as_secs_f64();
    assert_eq!((ours.width, ours.height), (gt.width, gt.height), "{name}: image size");

    let zs = tile_z(&ours, &gt, TILE);
    let bad: Vec<_> = zs.iter().filter(|t| t.z.abs() > Z_MAX).collect();
    for t in bad.iter().take(8) {
        eprintln!("{name}: tile ({}, {}) channel {}: z = {:.1}", t.tx, t.ty, t.channel, t.z);
    }
    Row {
        scene: name,
        rel_ours: rel_mse(&ours, &gt),
        rel_mitsuba: rel_mse(&theirs, &gt),
        z_ours: max_abs_z(&zs),
        bad_tiles: bad.len(),
        z_mitsuba: max_abs_z(&tile_z(&theirs, &gt, TILE)),
        t_ours,
        mitsuba,
        gt_note,
    }
}

#[test]
fn path_tracer_matches_mitsuba() {
    let Some(python) = python() else {
        let msg = "no Mitsuba python: set EVBLUR_MITSUBA_PYTHON or run tests/mitsuba/setup.sh";
        if std::env::var("EVBLUR_REQUIRE_MITSUBA").as_deref() == Ok("1") {
            panic!("EVBLUR_REQUIRE_MITSUBA=1 but {msg}");
        }
        eprintln!("\n*** SKIPPED mitsuba_reference: {msg} ***\n");
        return;
    };
    let variant = std::env::var("EVBLUR_MITSUBA_VARIANT").unwrap_or_else(|_| "llvm_ad_rgb".into());
    let rows: Vec<Row> = SCENES.iter().map(|s| check_scene(&python, &variant, s)).collect();

    println!(
        "\nMitsuba reference, {WIDTH}x{HEIGHT}, {SPP} spp vs ground truth at {GT_SPP} spp, tiles {TILE}x{TILE}"
    );
    println!(
        "{:<13} {:>11} {:>11} {:>6} {:>8} {:>6} {:>8} {:>8} {:>9} {:>9}  {}",
        "scene", "relMSE ours", "relMSE mi", "ratio", "max|z|", "bad", "mi|z|", "ours s", "mi s", "mi jit s", "GT"
    );
    let mut failures = Vec::new();
    for r in &rows {
        let ratio = r.rel_ours / r.rel_mitsuba;
        println!(
            "{:<13} {:>11.3e} {:>11.3e} {:>6.2} {:>8.2} {:>6} {:>8.2} {:>8.2} {:>9.2} {:>9.2}  {} ({})",
            r.scene, r.rel_ours, r.rel_mitsuba, ratio, r.z_ours, r.bad_tiles, r.z_mitsuba, r.t_ours,
            r.mitsuba.render_s, r.mitsuba.warmup_s, r.gt_note, r.mitsuba.variant
        );
        if !(ratio <= RATIO_MAX) {
            failures.push(format!("{}: relMSE ratio {ratio:.2} > {RATIO_MAX}", r.scene));
        }
        if r.bad_tiles > 0 {
            failures.push(format!("{}: {} tiles with |z| > {Z_MAX} (max {:.1})", r.scene, r.bad_tiles, r.z_ours));
        }
    }
    assert!(failures.is_empty(), "Mitsuba reference check failed:\n{}", failures.join("\n"));
}
