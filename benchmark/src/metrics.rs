//! `metrics.json`: a finished cell's scores and where they came from. Written atomically
//! (temporary file + rename) as the cell's last file, so its presence marks the cell done;
//! `evbench table` reads nothing else.
//!
//! Scores are on whole test images in [0, 1] (no cropping or alignment): PSNR (dB) and SSIM as
//! scikit-image (`trainer::metrics`), LPIPS-alex v0.1 (`crate::lpips`) or `null` when no weights
//! were given. The means are over the test views.

use std::path::Path;

use serde::{Deserialize, Serialize};
use trainer::presets::Scale;

use crate::error::BenchError;

/// Format version of `metrics.json` (2: `sessions` added; format 1 files still read).
pub const FORMAT: u32 = 2;
/// File name of a cell's metrics.
pub const FILE: &str = "metrics.json";

/// One test view's scores.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewMetrics {
    /// File name in the dataset's `images_1/` (and the render's in `eval/`).
    pub name: String,
    /// PSNR (dB).
    pub psnr: f64,
    /// SSIM (unitless, at most 1).
    pub ssim: f64,
    /// LPIPS (unitless, lower is better); `None` without weights.
    pub lpips: Option<f64>,
}

/// The machine a cell ran on.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// Host name (`/proc/sys/kernel/hostname`, `$HOSTNAME`, or `unknown`).
    pub hostname: String,
    /// Logical CPUs available to the process.
    pub cpus: usize,
}

impl Machine {
    /// This machine.
    pub fn current() -> Machine {
        let hostname = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty())
            .unwrap_or_else(|| "unknown".into());
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        Machine { hostname, cpus }
    }
}

/// The git commit of the evblur sources this binary was built from, with `-dirty` when they
/// differed from it, or `unknown` (baked in by `build.rs` at build time: a binary that runs
/// after the checkout moved on still names the code it was built from; a build without `.git`
/// takes it from `EVBLUR_GIT_COMMIT`).
pub fn git_commit() -> &'static str {
    env!("EVBLUR_GIT_COMMIT")
}

/// A finished cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellMetrics {
    /// [`FORMAT`].
    pub format: u32,
    /// evbench's version.
    pub tool_version: String,
    /// The cell key (module `matrix::identity`).
    pub key: String,
    /// Method label (the table row).
    pub method: String,
    /// The preset.
    pub preset: String,
    /// The method's own overrides (its ablation switches).
    pub switches: Vec<String>,
    /// Every override applied, the matrix's first.
    pub set: Vec<String>,
    /// The presets' scale.
    pub scale: Scale,
    /// Scene label (the column group).
    pub scene: String,
    /// The dataset identity (64 hex digits).
    pub dataset: String,
    /// Training seed.
    pub seed: u64,
    /// Training iterations done.
    pub steps: u64,
    /// Mean PSNR over the test views (dB).
    pub psnr: f64,
    /// Mean SSIM over the test views.
    pub ssim: f64,
    /// Mean LPIPS over the test views; `None` without weights.
    pub lpips: Option<f64>,
    /// Per test view.
    pub views: Vec<ViewMetrics>,
    /// Training time over every session of the run (s; the trainer's count, evaluations
    /// excluded).
    pub train_seconds: f64,
    /// Time of the final evaluation (s).
    pub eval_seconds: f64,
    /// Wall time over every session of the cell, each from loading the dataset to writing
    /// this file or stopping (s). A resumed cell adds what its interrupted session recorded
    /// (`wall.seconds` in the cell's folder), and at least the training time of its checkpoint
    /// when a session was killed outright; cells scored before 2026-12-07 count only the
    /// session that finished them.
    pub wall_seconds: f64,
    /// Worker threads of that session.
    pub threads: usize,
    /// Where that session ran.
    pub machine: Machine,
    /// Source commit of that session's binary ([`git_commit`]).
    pub git_commit: String,
    /// The sessions that trained the cell, in step order, each with its binary's commit (one
    /// for a cell trained in one go; absent in cells scored before 2026-12-08). Steps that no
    /// session recorded (one killed outright, or run by an older evbench) show as `unknown`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sessions: Vec<Session>,
}

/// The steps one session of a cell trained and the binary that trained them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Session {
    /// First step it trained.
    pub from: u64,
    /// The step it stopped at (exclusive).
    pub to: u64,
    /// [`git_commit`] of its binary, or `unknown`.
    pub git_commit: String,
}

impl CellMetrics {
    /// Writes `dir/metrics.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<(), BenchError> {
        let path = dir.join(FILE);
        // JSON has no NaN or infinity (serde_json would write null): refuse rather than mislabel.
        let views =
            self.views.iter().flat_map(|v| [("psnr", v.psnr), ("ssim", v.ssim), ("lpips", v.lpips.unwrap_or(0.0))]);
        let scores = [("psnr", self.psnr), ("ssim", self.ssim), ("lpips", self.lpips.unwrap_or(0.0))];
        if let Some((name, v)) = scores.into_iter().chain(views).find(|(_, v)| !v.is_finite()) {
            return Err(BenchError::results(
                &path,
                format!("{name} = {v}: a score is not finite (a render or test view holds NaN, or they are identical); check the run"),
            ));
        }
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| BenchError::results(&path, format!("cannot encode ({e})")))?;
        simulator::image_io::write_atomic(&path, format!("{text}\n").as_bytes())
            .map_err(|e| BenchError::results(&path, format!("{e:#}")))
    }

    /// Reads `path` (a `metrics.json`).
    pub fn read(path: &Path) -> Result<CellMetrics, BenchError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| BenchError::results(path, format!("cannot read ({e}); check permissions")))?;
        // A newer evbench's file may hold fields this one does not know: say so before parsing.
        let format = serde_json::from_str::<serde_json::Value>(&text).ok().and_then(|v| v["format"].as_u64());
        if let Some(f) = format.filter(|&f| f > u64::from(FORMAT)) {
            return Err(BenchError::results(
                path,
                format!("metrics format {f}, written by a newer evbench (this one reads up to {FORMAT}); the cell is finished: read it with that evbench, or update this one"),
            ));
        }
        let m: CellMetrics = serde_json::from_str(&text).map_err(|e| {
            BenchError::results(
                path,
                format!("not an evbench metrics file ({e}); delete it to evaluate the cell again"),
            )
        })?;
        if !(1..=FORMAT).contains(&m.format) {
            return Err(BenchError::results(
                path,
                format!(
                    "metrics format {}, this build reads 1 to {FORMAT}; delete it to evaluate the cell again",
                    m.format
                ),
            ));
        }
        Ok(m)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A synthetic finished cell (one view holding the means).
    pub(crate) fn cell(method: &str, scene: &str, seed: u64, scores: (f64, Option<f64>, f64)) -> CellMetrics {
        let (psnr, lpips, ssim) = scores;
        let preset = trainer::presets::preset(method).map_or("nerf", |p| p.name).to_string();
        CellMetrics {
            format: FORMAT,
            tool_version: "test".into(),
            key: crate::matrix::identity::sha256_hex(format!("{method}/{scene}/{seed}").as_bytes())[..16].into(),
            method: method.into(),
            preset,
            switches: vec![],
            set: vec![],
            scale: Scale::Cpu,
            scene: scene.into(),
            dataset: "d".repeat(64),
            seed,
            steps: 10,
            psnr,
            ssim,
            lpips,
            views: vec![ViewMetrics { name: "00.png".into(), psnr, ssim, lpips }],
            train_seconds: 1.0,
            eval_seconds: 0.5,
            wall_seconds: 2.0,
            threads: 2,
            machine: Machine { hostname: "test".into(), cpus: 2 },
            git_commit: "unknown".into(),
            sessions: vec![],
        }
    }

    #[test]
    fn the_commit_is_the_one_the_binary_was_built_from() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let head = std::process::Command::new("git").arg("-C").arg(root).args(["rev-parse", "HEAD"]).output();
        match head {
            // Named by the builder (`EVBLUR_GIT_COMMIT=... cargo build`): taken as given.
            _ if env!("EVBLUR_GIT_COMMIT_GIVEN") == "1" => assert!(!git_commit().is_empty()),
            Ok(o) if o.status.success() => {
                // Cargo built this test after the last commit (build.rs reruns when the refs move).
                let head = String::from_utf8(o.stdout).unwrap().trim().to_string();
                assert!([head.clone(), format!("{head}-dirty")].contains(&git_commit().to_string()), "{head}");
            }
            _ => assert_eq!(git_commit(), "unknown"),
        }
    }

    #[test]
    fn writes_atomically_and_reads_back() {
        let dir = std::env::temp_dir().join(format!("evbench-metrics-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let sessions = vec![Session { from: 0, to: 10, git_commit: "abc".into() }];
        let m = CellMetrics { sessions, ..cell("nerf", "tiny", 0, (20.5, None, 0.5)) };
        m.write(&dir).unwrap();
        assert_eq!(CellMetrics::read(&dir.join(FILE)).unwrap(), m);
        // Only metrics.json is left: the temporary file was renamed into place.
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, [FILE]);
        let text = std::fs::read_to_string(dir.join(FILE)).unwrap();
        assert!(text.contains("\"lpips\": null"), "{text}");

        // A non-finite score is refused, and the previous file stays whole.
        let bad = CellMetrics { psnr: f64::NAN, ..m.clone() };
        let err = bad.write(&dir).unwrap_err().to_string();
        assert!(err.contains("metrics.json") && err.contains("not finite"), "{err}");
        assert_eq!(CellMetrics::read(&dir.join(FILE)).unwrap(), m);

        // Format 1 (before `sessions`) still reads; a newer evbench's file is not called damaged.
        let v1 = text.replace("\"format\": 2", "\"format\": 1");
        std::fs::write(dir.join(FILE), &v1).unwrap();
        assert_eq!(CellMetrics::read(&dir.join(FILE)).unwrap(), CellMetrics { format: 1, ..m.clone() });
        let v3 = text.replace("\"format\": 2", "\"format\": 3").replace("\"key\"", "\"new_field\": 0, \"key\"");
        std::fs::write(dir.join(FILE), v3).unwrap();
        let err = CellMetrics::read(&dir.join(FILE)).unwrap_err().to_string();
        assert!(err.contains("newer evbench") && !err.contains("delete"), "{err}");

        // A damaged file names itself and the fix.
        std::fs::write(dir.join(FILE), "{\"format\": 1").unwrap();
        let err = CellMetrics::read(&dir.join(FILE)).unwrap_err().to_string();
        assert!(err.contains("metrics.json") && err.contains("delete it"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
