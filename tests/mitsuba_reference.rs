//! Our path tracer against Mitsuba 3 on the reference scenes in `scenes/` (cornell, textured_env, rough_metal).
//!
//! For each scene: load `scene.toml`, export it with `simulator::export::export_mitsuba`, render
//! a ground truth with Mitsuba at `GT_SPP` (cached under `~/.cache/evblur/mitsuba-gt/<hash>.exr`,
//! the hash covering the export and the render parameters), a Mitsuba image at `SPP` with another
//! seed, and ours at `SPP` with each of our samplers (independent, as Mitsuba's, and the default
//! Owen-scrambled Sobol). Pass, for each: `relMSE_ours <= 1.2 relMSE_mitsuba` and no 20x20 tile
//! with `|z| > 5` (see `simulator::reference::compare`).
//!
//! Python: `$EVBLUR_MITSUBA_PYTHON`, else `~/.cache/evblur/mitsuba-venv/bin/python` (made by
//! `tests/mitsuba/setup.sh`). Without one the test prints SKIPPED and passes, unless
//! `EVBLUR_REQUIRE_MITSUBA=1`. `EVBLUR_MITSUBA_VARIANT` picks the variant (default llvm_ad_rgb).
//!
//! Run: `tests/mitsuba/setup.sh && cargo test -p evblur-tests --test mitsuba_reference -- --nocapture`

use std::path::Path;
use std::time::Instant;

use simulator::export::export_mitsuba;
use simulator::image_io::read_exr;
use simulator::reference::compare::{max_abs_z, rel_mse, tile_z};
use simulator::reference::mitsuba::{self, MitsubaRun};
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;
use simulator::render::sampler::SamplerKind;

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

/// One scene's numbers.
struct Row {
    scene: &'static str,
    sampler: SamplerKind,
    rel_ours: f64,
    rel_mitsuba: f64,
    z_ours: f64,
    bad_tiles: usize,
    z_mitsuba: f64,
    t_ours: f64,
    mitsuba: MitsubaRun,
    gt_note: String,
}

/// Check one scene with both of our samplers (one Mitsuba run and one ground truth for both).
fn check_scene(python: &Path, variant: &str, name: &'static str) -> Vec<Row> {
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

    let (gt, gt_note) =
        mitsuba::ground_truth(python, &dir, GT_SPP, GT_SEED, variant).unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let mitsuba_out = dir.join("mitsuba_equal_spp.exr");
    let mitsuba = mitsuba::run(python, &json, SPP, MITSUBA_SEED, variant, &mitsuba_out)
        .unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let theirs = read_exr(&mitsuba_out).unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let renderer = Renderer::new(&scene);
    [SamplerKind::Independent, SamplerKind::Sobol]
        .into_iter()
        .map(|sampler| {
            let st = RenderSettings { sampler, ..settings.clone() };
            let t0 = Instant::now();
            let ours = renderer.render(&st, None);
            let t_ours = t0.elapsed().as_secs_f64();
            assert_eq!((ours.width, ours.height), (gt.width, gt.height), "{name}: image size");
            let zs = tile_z(&ours, &gt, TILE);
            let bad: Vec<_> = zs.iter().filter(|t| t.z.abs() > Z_MAX).collect();
            for t in bad.iter().take(8) {
                eprintln!("{name} {sampler:?}: tile ({}, {}) channel {}: z = {:.1}", t.tx, t.ty, t.channel, t.z);
            }
            Row {
                scene: name,
                sampler,
                rel_ours: rel_mse(&ours, &gt),
                rel_mitsuba: rel_mse(&theirs, &gt),
                z_ours: max_abs_z(&zs),
                bad_tiles: bad.len(),
                z_mitsuba: max_abs_z(&tile_z(&theirs, &gt, TILE)),
                t_ours,
                mitsuba: mitsuba.clone(),
                gt_note: gt_note.clone(),
            }
        })
        .collect()
}

#[test]
fn path_tracer_matches_mitsuba() {
    let Some(python) = evblur_tests::python_with("mitsuba", "mitsuba_reference") else { return };
    let variant = std::env::var("EVBLUR_MITSUBA_VARIANT").unwrap_or_else(|_| "llvm_ad_rgb".into());
    let rows: Vec<Row> = SCENES.iter().flat_map(|s| check_scene(&python, &variant, s)).collect();

    println!("\nMitsuba reference, {WIDTH}x{HEIGHT}, {SPP} spp vs ground truth at {GT_SPP} spp, tiles {TILE}x{TILE}");
    println!(
        "{:<13} {:<11} {:>11} {:>11} {:>6} {:>8} {:>6} {:>8} {:>8} {:>9} {:>9}  GT",
        "scene", "sampler", "relMSE ours", "relMSE mi", "ratio", "max|z|", "bad", "mi|z|", "ours s", "mi s", "mi jit s"
    );
    let mut failures = Vec::new();
    for r in &rows {
        let ratio = r.rel_ours / r.rel_mitsuba;
        println!(
            "{:<13} {:<11} {:>11.3e} {:>11.3e} {:>6.2} {:>8.2} {:>6} {:>8.2} {:>8.2} {:>9.2} {:>9.2}  {} ({})",
            r.scene,
            format!("{:?}", r.sampler),
            r.rel_ours,
            r.rel_mitsuba,
            ratio,
            r.z_ours,
            r.bad_tiles,
            r.z_mitsuba,
            r.t_ours,
            r.mitsuba.render_s,
            r.mitsuba.warmup_s,
            r.gt_note,
            r.mitsuba.variant
        );
        if ratio.is_nan() || ratio > RATIO_MAX {
            failures.push(format!("{} {:?}: relMSE ratio {ratio:.2} > {RATIO_MAX}", r.scene, r.sampler));
        }
        if r.bad_tiles > 0 {
            failures.push(format!(
                "{} {:?}: {} tiles with |z| > {Z_MAX} (max {:.1})",
                r.scene, r.sampler, r.bad_tiles, r.z_ours
            ));
        }
    }
    assert!(failures.is_empty(), "Mitsuba reference check failed:\n{}", failures.join("\n"));
}
