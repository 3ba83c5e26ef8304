//! Punctual lights from Blender: a scene exported by Blender's glTF exporter (lighting mode
//! "Standard": candela and lux at 683 lm/W) renders as Cycles renders the same scene.
//!
//! `tests/blender/lights.py` builds three scenes in Blender (a grey diffuse floor lit by one
//! point, spot or sun light, seen by a camera), renders each with Cycles and exports it to glTF.
//! We load the glTF, render it from its camera and compare the image means: each within
//! `MEAN_TOLERANCE` of Cycles'. Without the 683 lm/W conversion ours came out 683 times too bright.
//!
//! Python: `$EVBLUR_BLENDER_PYTHON`, else `~/.cache/evblur/bpy-venv/bin/python` (made by
//! `tests/blender/setup.sh`). Without one the test prints SKIPPED and passes, unless
//! `EVBLUR_REQUIRE_BLENDER=1` (as `tests/run.sh` sets).
//!
//! Run: `tests/blender/setup.sh && cargo test -p evblur-tests --test blender_reference -- --nocapture`

use std::path::{Path, PathBuf};
use std::process::Command;

use simulator::image_io::read_exr;
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;

/// The cases `lights.py` writes.
const CASES: [&str; 3] = ["point", "spot", "sun"];
/// Largest relative difference of the image means (per channel).
const MEAN_TOLERANCE: f64 = 0.10;
/// Our samples per pixel (Cycles renders 64).
const SPP: u32 = 64;

fn blender_python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVBLUR_BLENDER_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let home = std::env::var_os("HOME")?;
    let p = Path::new(&home).join(".cache/evblur/bpy-venv/bin/python");
    p.is_file().then_some(p)
}

#[test]
fn blender_punctual_lights_render_as_in_cycles() {
    let required = std::env::var("EVBLUR_REQUIRE_BLENDER").is_ok_and(|v| v == "1");
    let Some(python) = blender_python() else {
        assert!(!required, "EVBLUR_REQUIRE_BLENDER=1 but no Blender python: run tests/blender/setup.sh");
        println!("SKIPPED: no Blender python (tests/blender/setup.sh makes one)");
        return;
    };
    let out = std::env::temp_dir().join(format!("evblur-blender-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("blender/lights.py");
    let run = Command::new(&python).arg(&script).arg(&out).output().expect("run the Blender python");
    assert!(
        run.status.success(),
        "{} {} failed:\n{}\n{}",
        python.display(),
        script.display(),
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    let mut worst: f64 = 0.0;
    for case in CASES {
        let cycles = read_exr(&out.join(format!("{case}.exr"))).unwrap_or_else(|e| panic!("{case}: {e:#}"));
        let scene =
            simulator::scene::load(&out.join(case).join("scene.gltf")).unwrap_or_else(|e| panic!("{case}: {e}"));
        assert_eq!(scene.lights.len(), 1, "{case}: the exported light");
        let cam = scene.cameras[0].clone();
        let st = RenderSettings { width: cycles.width, height: cycles.height, spp: SPP, ..RenderSettings::new(cam) };
        let ours = Renderer::new(&scene).render(&st, None);
        let (a, b) = (ours.mean().as_dvec3(), cycles.mean().as_dvec3());
        let rel = ((a - b) / b).abs().max_element();
        println!("{case:6} mean ours {a:.5} Cycles {b:.5}: ratio {:.4}", a.x / b.x);
        assert!(b.min_element() > 1e-3, "{case}: Cycles rendered a black image ({b})");
        worst = worst.max(rel);
        assert!(rel <= MEAN_TOLERANCE, "{case}: ours {a} vs Cycles {b}: {:.1}% apart", 100.0 * rel);
    }
    println!("worst relative difference of the means: {:.2}%", 100.0 * worst);
    let _ = std::fs::remove_dir_all(&out);
}
