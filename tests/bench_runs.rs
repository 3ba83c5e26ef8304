//! `evbench` end to end on `scenes/tiny` at 48x32, 1 spp (simulated through the matrix's
//! `[dataset]` overrides): two methods x two seeds, 12 iterations each on a 32^3 volume.
//!
//! - An unsharded run, and the same matrix as two shards (one of them stopped after a few
//!   steps, as Ctrl-C would, then resumed from its checkpoint) give the same table, byte for
//!   byte (the CSV holds no timings; a resumed run repeats the uninterrupted one bit for bit
//!   at the same thread count).
//! - Running a finished matrix again trains nothing: every cell is skipped and no file of it
//!   is rewritten (mtimes). Given LPIPS weights (random ones, written here in the documented
//!   format), the finished cells are only scored again: LPIPS appears, checkpoints stay.
//! - The `evbench` binary: `run --dry-run`, `table` (files, Markdown with `n/a` LPIPS), and
//!   errors naming the file, the field and the fix.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::SystemTime;

use benchmark::matrix::{MatrixPlan, Shard};
use benchmark::metrics::{CellMetrics, Session};
use benchmark::run::{self, CellStatus, RunOptions, RunSummary};
use benchmark::table::{self, format, Form};
use evblur_tests::{copy_dir, temp_dir};

/// Iterations per cell.
const ITERATIONS: u64 = 12;

/// Folder of this test binary's files.
fn root() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| temp_dir("bench", "runs"))
}

/// The matrix file: nerf and nerf-sharp on tiny at 48x32, seeds 0 and 1, shrunk for seconds.
fn matrix() -> &'static Path {
    static FILE: OnceLock<PathBuf> = OnceLock::new();
    FILE.get_or_init(|| {
        let tiny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml");
        let text = format!(
            r#"scale = "cpu"
iterations = {ITERATIONS}
seeds = [0, 1]
set = ["model.coarse_volume.res=32", "batch_rays=256", "eval_every=0"]
[dataset]
width = 48
height = 32
spp = 1
sharp_spp = 1
[[methods]]
preset = "nerf"
[[methods]]
preset = "nerf-sharp"
[[scenes]]
scene = "{}"
"#,
            tiny.display()
        );
        let file = root().join("matrix.toml");
        std::fs::write(&file, text).unwrap();
        file
    })
}

/// The matrix with its results in `root()/<name>`.
fn plan(name: &str) -> MatrixPlan {
    MatrixPlan::load(matrix(), Some(&root().join(name))).unwrap()
}

/// Runs `shard` of `plan` quietly on 2 threads, optionally stopping after `stop_after` steps.
fn run(plan: &MatrixPlan, shard: Shard, stop_after: Option<u64>) -> RunSummary {
    let opts = RunOptions { shard, threads: 2, quiet: true, stop_after_steps: stop_after, ..RunOptions::default() };
    let s = run::run(plan, &opts).unwrap();
    assert!(s.failed.is_empty(), "{:?}", s.failed);
    s
}

/// The unsharded results (run once).
fn unsharded() -> &'static MatrixPlan {
    static PLAN: OnceLock<MatrixPlan> = OnceLock::new();
    PLAN.get_or_init(|| {
        let p = plan("unsharded");
        let s = run(&p, Shard::ALL, None);
        assert_eq!((s.cells, s.trained, s.skipped, s.resumed, s.simulated), (4, 4, 0, 0, 1), "{s:?}");
        p
    })
}

/// The table's CSV of a results folder.
fn csv(results: &Path) -> String {
    format::csv(&table::build(results, Form::Table1, None).unwrap())
}

/// Modification times of every file under `dir`.
fn mtimes(dir: &Path) -> Vec<(PathBuf, SystemTime)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(mtimes(&p));
        } else {
            out.push((p.clone(), std::fs::metadata(&p).unwrap().modified().unwrap()));
        }
    }
    out.sort();
    out
}

#[test]
fn shards_merge_into_the_unsharded_table_and_a_stopped_cell_resumes() {
    let a = unsharded();
    let b = plan("sharded");
    // Shard 2/2, stopped after 5 steps of its first cell (a checkpoint is written).
    let s = run(&b, Shard { index: 2, count: 2 }, Some(5));
    assert!(s.interrupted && s.trained == 0 && s.simulated == 1, "{s:?}");
    let second: Vec<_> = run::shard_cells(&b, Shard { index: 2, count: 2 }, 0);
    let partial: Vec<_> =
        second.iter().filter(|c| run::status(&b, c).unwrap() == CellStatus::Partial { step: 5 }).collect();
    assert_eq!(partial.len(), 1);
    // The stopped session's wall time waits beside the checkpoint for the session that resumes.
    let stopped_dir = b.cell_dir(partial[0]);
    let wall_file = stopped_dir.join(run::cell::WALL_FILE);
    let first: f64 = std::fs::read_to_string(&wall_file).unwrap().trim().parse().unwrap();
    assert!(first > 0.0, "{first}");
    // (Made long, so that only adding it up can reach the figure below.)
    std::fs::write(&wall_file, format!("{}\n", first + 1000.0)).unwrap();
    // So is the commit of the binary that trained the first 5 steps (here claimed to be another).
    let sessions_file = stopped_dir.join(run::cell::SESSIONS_FILE);
    let recorded: Vec<Session> = serde_json::from_str(&std::fs::read_to_string(&sessions_file).unwrap()).unwrap();
    let commit = benchmark::metrics::git_commit();
    assert_eq!(recorded, [Session { from: 0, to: 5, git_commit: commit.into() }]);
    std::fs::write(&sessions_file, r#"[{"from": 0, "to": 5, "git_commit": "0123abc"}]"#).unwrap();
    // Again: the stopped cell resumes at step 5, the other trains; then shard 1/2 (the dataset
    // is reused).
    let s = run(&b, Shard { index: 2, count: 2 }, None);
    assert_eq!((s.cells, s.resumed, s.trained, s.simulated), (2, 1, 1, 0), "{s:?}");
    // Its wall time covers both sessions: the first's record, and at least the training.
    let m = CellMetrics::read(&stopped_dir.join("metrics.json")).unwrap();
    assert!(m.wall_seconds > first + 1000.0 && m.wall_seconds >= m.train_seconds, "{first} then {m:?}");
    assert!(m.wall_seconds < first + 1000.0 + 600.0, "{m:?}");
    // Each session's steps and binary: the first's record, then this one's.
    let both = [
        Session { from: 0, to: 5, git_commit: "0123abc".into() },
        Session { from: 5, to: ITERATIONS, git_commit: commit.into() },
    ];
    assert_eq!((m.git_commit.as_str(), &m.sessions[..]), (commit, &both[..]));
    let s = run(&b, Shard { index: 1, count: 2 }, None);
    assert_eq!((s.cells, s.trained, s.simulated), (2, 2, 0), "{s:?}");

    let (ta, tb) = (csv(&a.results), csv(&b.results));
    assert_eq!(ta, tb, "sharded and unsharded tables differ");
    assert_eq!(ta.lines().count(), 3, "{ta}");
    assert!(ta.starts_with("method,tiny_psnr,tiny_lpips,tiny_ssim,average_psnr"), "{ta}");
    assert!(ta.contains("\nnerf,") && ta.contains("\nnerf-sharp,") && ta.contains(",n/a,"), "{ta}");

    // Each cell's folder: the trainer's run, the renders, the metrics.
    for cell in &a.cells {
        let dir = a.cell_dir(cell);
        for f in ["config.toml", "checkpoint.bin", "log.csv", "eval/00.png", "eval/08.png", "metrics.json"] {
            assert!(dir.join(f).is_file(), "{}/{f} is missing", dir.display());
        }
        let m = CellMetrics::read(&dir.join("metrics.json")).unwrap();
        assert_eq!((m.key.as_str(), m.seed, m.steps, m.views.len()), (cell.key.as_str(), cell.seed, ITERATIONS, 2));
        assert!(m.lpips.is_none() && m.views.iter().all(|v| v.lpips.is_none()));
        assert!(m.psnr.is_finite() && m.ssim > -1.0 && m.ssim <= 1.0 && m.wall_seconds > 0.0, "{m:?}");
        assert_eq!(m.threads, 2);
        assert_eq!(m.sessions, [Session { from: 0, to: ITERATIONS, git_commit: m.git_commit.clone() }]);
    }
    // One dataset folder, complete, no shard's partial copy left behind.
    let datasets: Vec<String> = std::fs::read_dir(b.results.join("datasets"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(datasets, [&b.scenes[0].identity[..16]]);
    assert!(b.scenes[0].dataset_dir(&b.results).join("dataset.toml").is_file());
}

#[test]
fn a_finished_matrix_is_skipped_without_rewriting_anything() {
    let a = unsharded();
    let before = mtimes(&a.results);
    let s = run(a, Shard::ALL, None);
    assert_eq!((s.cells, s.skipped, s.trained, s.resumed, s.scored, s.simulated), (4, 4, 0, 0, 0, 0), "{s:?}");
    assert_eq!(mtimes(&a.results), before);
}

/// LPIPS weights with smooth pseudo-random values in the format of `benchmark::lpips::weights`
/// (He-scaled convolutions, small biases, non-negative heads).
fn random_lpips_weights(path: &Path) {
    let convs = [(64, 3, 11), (192, 64, 5), (384, 192, 3), (256, 384, 3), (256, 256, 3)];
    let mut tensors: Vec<(String, Vec<u32>, Vec<f32>)> = Vec::new();
    let value = |t: usize, i: usize| (((t * 7919 + i * 104729) % 1999) as f32 / 1999.0) - 0.5;
    for (l, &(c_out, c_in, k)) in convs.iter().enumerate() {
        let n = c_out * c_in * k * k;
        let he = (24.0 / (c_in * k * k) as f32).sqrt();
        tensors.push((
            format!("conv{}.weight", l + 1),
            vec![c_out as u32, c_in as u32, k as u32, k as u32],
            (0..n).map(|i| he * value(2 * l, i)).collect(),
        ));
        tensors.push((
            format!("conv{}.bias", l + 1),
            vec![c_out as u32],
            (0..c_out).map(|i| 0.01 * value(2 * l + 1, i)).collect(),
        ));
    }
    for (l, &(c_out, _, _)) in convs.iter().enumerate() {
        tensors.push((
            format!("lin{l}.weight"),
            vec![c_out as u32],
            (0..c_out).map(|i| value(10 + l, i) + 0.5).collect(),
        ));
    }
    let mut bytes = b"EVBLPIPS".to_vec();
    bytes.extend(1u32.to_le_bytes());
    bytes.extend((tensors.len() as u32).to_le_bytes());
    for (name, shape, data) in tensors {
        bytes.extend((name.len() as u32).to_le_bytes());
        bytes.extend(name.as_bytes());
        bytes.extend((shape.len() as u32).to_le_bytes());
        shape.iter().for_each(|d| bytes.extend(d.to_le_bytes()));
        data.iter().for_each(|v| bytes.extend(v.to_le_bytes()));
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn lpips_weights_score_finished_cells_again_without_training() {
    let a = unsharded();
    let c = plan("with-lpips");
    copy_dir(&a.results, &c.results);
    let weights = root().join("lpips_random.bin");
    random_lpips_weights(&weights);
    let modified = |f: PathBuf| std::fs::metadata(f).unwrap().modified().unwrap();
    let checkpoints =
        |p: &MatrixPlan| p.cells.iter().map(|c| modified(p.cell_dir(c).join("checkpoint.bin"))).collect::<Vec<_>>();
    let before = checkpoints(&c);
    let opts = RunOptions { threads: 2, quiet: true, lpips_weights: Some(weights), ..RunOptions::default() };
    let s = run::run(&c, &opts).unwrap();
    assert!(s.failed.is_empty(), "{:?}", s.failed);
    assert_eq!((s.cells, s.scored, s.trained, s.resumed, s.skipped), (4, 4, 0, 0, 0), "{s:?}");
    assert_eq!(checkpoints(&c), before);
    for cell in &c.cells {
        let m = CellMetrics::read(&c.cell_dir(cell).join("metrics.json")).unwrap();
        let l = m.lpips.unwrap();
        assert!(l.is_finite() && l > 0.0 && m.views.iter().all(|v| v.lpips.is_some()), "{m:?}");
        assert_eq!(m.steps, ITERATIONS);
        // Scoring again keeps the record of the session that trained it.
        let trained = CellMetrics::read(&a.cell_dir(cell).join("metrics.json")).unwrap();
        assert_eq!(m.sessions, trained.sessions);
        assert_eq!(m.sessions.len(), 1, "{:?}", m.sessions);
    }
    // PSNR and SSIM are unchanged; LPIPS is no longer n/a.
    let (ta, tc) = (csv(&a.results), csv(&c.results));
    assert!(ta.contains("n/a") && !tc.contains("n/a"), "{ta}\n{tc}");
    let strip = |t: &str| {
        t.lines()
            .map(|l| l.split(',').enumerate().filter(|(i, _)| i % 3 != 2).map(|(_, f)| f).collect::<Vec<_>>().join(","))
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(&ta), strip(&tc));
    // Again with the weights: nothing left to do.
    let s = run::run(&c, &opts).unwrap();
    assert_eq!((s.skipped, s.scored), (4, 0), "{s:?}");
}

/// The `evbench` binary beside this test's target folder, built (or brought up to date) by
/// cargo first: binaries of another package are not built for this crate's tests.
fn evbench() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| evblur_tests::workspace_binary("evblur-benchmark", "evbench"))
}

fn evbench_run(args: &[&str]) -> Output {
    // No LPIPS weights: neither the variable nor an installed file under HOME.
    Command::new(evbench())
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .env_remove("EVBLUR_LPIPS_WEIGHTS")
        .env("HOME", root())
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = evbench_run(args);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "evbench {args:?} failed:\n{stdout}\n{stderr}");
    stdout.into_owned()
}

fn fails(args: &[&str]) -> String {
    let out = evbench_run(args);
    assert!(!out.status.success(), "evbench {args:?} succeeded:\n{}", String::from_utf8_lossy(&out.stdout));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn the_evbench_binary_lists_runs_tabulates_and_explains_mistakes() {
    let a = unsharded();
    let (m, results) = (matrix().to_str().unwrap(), a.results.to_str().unwrap());
    let listing = ok(&["run", m, "--results", results, "--dry-run", "--shard", "1/2"]);
    assert!(listing.contains("4 cells, 2 in shard 1/2"), "{listing}");
    assert_eq!(listing.matches("done (no LPIPS)").count(), 2, "{listing}");
    assert!(listing.contains("scene tiny: simulated from") && listing.contains("(present)"), "{listing}");

    // A finished matrix: the run trains nothing and says so.
    let out = ok(&["run", m, "--results", results, "--quiet"]);
    assert!(out.contains("4 cells: 4 already done, 0 trained"), "{out}");

    let out_dir = root().join("tables");
    let md = ok(&["table", results, "--out", out_dir.to_str().unwrap(), "--config", m]);
    assert!(md.starts_with("| Method | tiny PSNR↑ | tiny LPIPS↓ | tiny SSIM↑ | Average PSNR↑"), "{md}");
    assert!(md.contains("| nerf | ") && md.contains(" n/a ") && md.contains("**"), "{md}");
    for ext in ["md", "csv", "tex", "manifest.json"] {
        assert!(out_dir.join(format!("table1.{ext}")).is_file(), "table1.{ext}");
    }
    assert_eq!(std::fs::read_to_string(out_dir.join("table1.csv")).unwrap(), csv(&a.results));
    // the picture: per test view, the input, both methods' renders and the ground truth
    let picture = image::open(out_dir.join("table1-tiny.png")).expect("table1-tiny.png").to_rgb8();
    // (panels enlarged to at least 240 pixels wide, 6-pixel gaps: input, nerf, ev-deblurnerf, truth)
    let w = picture.width() - 6;
    assert!(w.is_multiple_of(4) && w / 4 >= 246, "four panels side by side: {:?}", picture.dimensions());
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("table1.manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["cells"].as_array().unwrap().len(), 4);
    assert_eq!(manifest["seeds"], serde_json::json!([0, 1]));
    ok(&["table", results, "--form", "ablation", "--out", out_dir.to_str().unwrap()]);
    assert!(out_dir.join("ablation.csv").is_file());

    let bad = root().join("bad.toml");
    std::fs::write(&bad, "scale = \"cpu\"\n[[methods]]\npreset = \"nerff\"\n[[scenes]]\ndata = \".\"\n").unwrap();
    let e = fails(&["run", bad.to_str().unwrap(), "--dry-run"]);
    assert!(e.contains("bad.toml: methods[0].preset: `nerff` is not a preset; choose one of nerf,"), "{e}");
    let e = fails(&["run", m, "--shard", "3/2"]);
    assert!(e.contains("3/2") && e.contains("1 <= i <= n"), "{e}");
    let e = fails(&["table", results, "--form", "table2"]);
    assert!(e.contains("choose table1 or ablation"), "{e}");
    let e = fails(&["run", m, "--results", results, "--lpips-weights", "/nonexistent/lpips.bin"]);
    assert!(e.contains("/nonexistent/lpips.bin") && e.contains("install_lpips.sh"), "{e}");
    // Cells that fail (a results folder that cannot be created) end with their errors, not
    // with a complaint about the table they could not make.
    let blocker = root().join("blocker");
    std::fs::write(&blocker, b"a file").unwrap();
    let nowhere = blocker.join("results");
    let e = fails(&["run", m, "--results", nowhere.to_str().unwrap(), "--quiet"]);
    let last = e.lines().last().unwrap_or_default();
    assert!(e.contains("failed: ") && e.contains("blocker"), "{e}");
    assert!(last.starts_with("no table: "), "the failures come first, then this note: {e}");
}
