//! Running Mitsuba 3 on a scene exported by [`crate::export::export_mitsuba`].
//!
//! The Python comes from `$EVBLUR_MITSUBA_PYTHON`, else `~/.cache/evblur/mitsuba-venv/bin/python`
//! (made by `tests/mitsuba/setup.sh`). The driver is `tests/mitsuba/render.py` of this
//! repository; it prints one JSON line with the variant and its timings.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};

use crate::base::image::Image;
use crate::image_io::read_exr;

/// The Mitsuba venv's Python, if there is one.
pub fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVBLUR_MITSUBA_PYTHON") {
        return Some(PathBuf::from(p)).filter(|p| p.exists());
    }
    let home = std::env::var_os("HOME")?;
    Some(Path::new(&home).join(".cache/evblur/mitsuba-venv/bin/python")).filter(|p| p.exists())
}

/// The driver script in this repository.
pub fn driver() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/mitsuba/render.py")
}

/// Where ground truths are cached.
pub fn cache_dir() -> PathBuf {
    let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_else(std::env::temp_dir);
    home.join(".cache/evblur/mitsuba-gt")
}

/// What one Mitsuba run reported.
#[derive(Clone, Debug)]
pub struct MitsubaRun {
    /// The variant that ran (the driver falls back to `scalar_rgb` without LLVM).
    pub variant: String,
    /// Seconds of the low-spp warm-up render (JIT compilation for LLVM variants).
    pub warmup_s: f64,
    /// Seconds of the timed render.
    pub render_s: f64,
}

/// Render `scene_json` with Mitsuba at `spp` samples and `seed`, writing `out` (EXR).
pub fn run(python: &Path, scene_json: &Path, spp: u32, seed: u32, variant: &str, out: &Path) -> Result<MitsubaRun> {
    let output = Command::new(python)
        .arg(driver())
        .arg(scene_json)
        .arg("--out")
        .arg(out)
        .args(["--spp", &spp.to_string(), "--seed", &seed.to_string(), "--variant", variant])
        .output()
        .with_context(|| format!("cannot run {}", python.display()))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        bail!("render.py failed on {}:\n{stdout}\n{}", scene_json.display(), String::from_utf8_lossy(&output.stderr));
    }
    let line = stdout.lines().rev().find(|l| l.starts_with('{')).context("render.py printed no JSON line")?;
    let v: serde_json::Value = serde_json::from_str(line).context("render.py JSON line")?;
    Ok(MitsubaRun {
        variant: v["variant"].as_str().unwrap_or("?").to_string(),
        warmup_s: v["warmup_s"].as_f64().unwrap_or(f64::NAN),
        render_s: v["render_s"].as_f64().context("render_s missing")?,
    })
}

/// FNV-1a 64: stable across Rust versions, unlike `DefaultHasher`.
fn fnv1a(state: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(state, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// Hash of every input file of an export folder (sorted by name; our own `mitsuba_*.exr`
/// outputs excluded) plus the render parameters.
fn export_hash(dir: &Path, params: &str) -> Result<u64> {
    let mut names: Vec<_> = std::fs::read_dir(dir)?.map(|e| e.map(|e| e.file_name())).collect::<Result<_, _>>()?;
    names.sort();
    let mut h = fnv1a(0xcbf2_9ce4_8422_2325, params.as_bytes());
    for name in names {
        let n = name.to_string_lossy();
        if n.starts_with("mitsuba_") && n.ends_with(".exr") {
            continue;
        }
        h = fnv1a(h, n.as_bytes());
        h = fnv1a(h, &std::fs::read(dir.join(&name))?);
    }
    Ok(h)
}

/// The ground truth of an exported scene at `spp` samples: read from the cache when this exact
/// export was rendered before, rendered (and cached atomically) otherwise. Returns the image and
/// a note ("cached" or the render time).
pub fn ground_truth(python: &Path, export_dir: &Path, spp: u32, seed: u32, variant: &str) -> Result<(Image, String)> {
    let params = format!("gt spp={spp} seed={seed} {variant} mitsuba=3.9.1");
    let path = cache_dir().join(format!("{:016x}.exr", export_hash(export_dir, &params)?));
    let note = if path.exists() {
        "cached".to_string()
    } else {
        std::fs::create_dir_all(cache_dir())?;
        let tmp = path.with_extension(format!("tmp{}.exr", std::process::id()));
        let r = run(python, &export_dir.join("scene.json"), spp, seed, variant, &tmp)?;
        std::fs::rename(&tmp, &path)?;
        format!("{:.1} s", r.render_s)
    };
    Ok((read_exr(&path)?, note))
}
