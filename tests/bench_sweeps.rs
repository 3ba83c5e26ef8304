//! `evbench sweep` end to end on `scenes/tiny` at 48x32, 1 spp:
//!
//! - A training sweep (exposure x training threshold, `nerf` and `e-nerf`, a few iterations):
//!   one matrix per point, the second exposure renders no frame (the shared frame cache), the
//!   report has a column group per exposure and a row per method and training threshold, the
//!   figure is a PNG, and a second run trains nothing.
//! - A data-only sweep of the event threshold: fewer events at a higher threshold, EDI PSNR
//!   reported, nothing rendered after the first point; the `evbench` binary prints the table.
//! - Bad sweep files: errors naming the file, the axis and the fix.

use std::path::{Path, PathBuf};
use std::process::Command;

use benchmark::run::{self, RunOptions};
use benchmark::sweep::{self, SweepPlan};
use evblur_tests::{temp_dir, workspace_binary};

/// A sweep file on tiny at 48x32 with the given `[sweep]` and methods.
fn sweep_file(dir: &Path, name: &str, methods: &[&str], sweep: &str) -> PathBuf {
    let tiny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml");
    let methods: String = methods.iter().map(|m| format!("[[methods]]\npreset = \"{m}\"\n")).collect();
    let text = format!(
        r#"scale = "cpu"
iterations = 8
seeds = [0]
set = ["model.coarse_volume.res=32", "batch_rays=128", "eval_every=0"]
[dataset]
width = 48
height = 32
spp = 1
sharp_spp = 1
{methods}[[scenes]]
scene = "{}"
{sweep}"#,
        tiny.display()
    );
    let file = dir.join(format!("{name}.toml"));
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn training_sweep_runs_every_point_reuses_frames_and_reports() {
    let dir = temp_dir("sweep", "train");
    let axes = r#"[sweep]
title = "tiny"
[[sweep.axes]]
setting = "dataset.exposure_ms"
values = [10, 20]
label = "exposure (ms)"
[[sweep.axes]]
setting = "train.events.threshold"
values = [[0.2, 0.2], [0.3, 0.3]]
"#;
    // nerf has no events: the second axis cannot apply to it
    let file = sweep_file(&dir, "blur", &["nerf", "e-nerf"], axes);
    let e = SweepPlan::load(&file, None).unwrap_err().to_string();
    assert!(e.contains("blur.toml") && e.contains("events.threshold") && e.contains("nerf"), "{e}");

    let file = sweep_file(&dir, "blur", &["e-nerf", "e2nerf"], axes);
    let results = dir.join("results");
    let plan = SweepPlan::load(&file, Some(&results)).unwrap();
    assert_eq!(plan.points.len(), 4);
    assert_eq!(plan.points.iter().map(|p| p.index.clone()).collect::<Vec<_>>(), [[0, 0], [1, 0], [0, 1], [1, 1]]);
    // two datasets (exposures), shared by the two training thresholds
    let ids: Vec<&str> = plan.points.iter().map(|p| p.plan.scenes[0].identity.as_str()).collect();
    assert!(ids[0] != ids[1] && ids[0] == ids[2] && ids[1] == ids[3], "{ids:?}");
    let keys: std::collections::HashSet<&str> =
        plan.points.iter().flat_map(|p| p.plan.cells.iter().map(|c| c.key.as_str())).collect();
    assert_eq!(keys.len(), 8, "every cell of every point has its own key");

    let opts = RunOptions {
        threads: 2,
        quiet: true,
        frames_cache: Some(results.join(sweep::FRAMES_DIR)),
        ..RunOptions::default()
    };
    let mut simulated = Vec::new();
    for point in &plan.points {
        let s = run::run(&point.plan, &opts).unwrap();
        assert!(s.failed.is_empty(), "{:?}", s.failed);
        assert_eq!(s.trained, 2);
        simulated.push(s.simulated);
    }
    assert_eq!(simulated, [1, 1, 0, 0]);

    let table = sweep::report::scene_table(&plan, 0).unwrap();
    assert_eq!(table.scenes, ["exposure (ms) = 10", "exposure (ms) = 20"]);
    let labels: Vec<&str> = table.rows.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "e-nerf, train.events.threshold = [0.2, 0.2]",
            "e2nerf, train.events.threshold = [0.2, 0.2]",
            "e-nerf, train.events.threshold = [0.3, 0.3]",
            "e2nerf, train.events.threshold = [0.3, 0.3]"
        ]
    );
    assert!(table.rows.iter().all(|r| r.scores.len() == 2 && r.scores.iter().all(|s| s.is_some_and(|s| s.psnr > 5.0))));
    assert_eq!(table.cells.len(), 8);
    let md = benchmark::table::format::markdown(&table);
    assert!(md.contains("exposure (ms) = 20 PSNR↑") && !md.contains("Average"), "{md}");

    let files = sweep::report::write(&plan).unwrap();
    let png = files.iter().find(|f| f.extension().is_some_and(|e| e == "png")).expect("a figure");
    let img = image::open(png).unwrap();
    assert_eq!((img.width(), img.height()), benchmark::plot::SIZE);
    assert!(files.iter().any(|f| f.ends_with("sweep/blur-tiny.csv")), "{files:?}");

    // the second axis's training threshold reached the trainer
    let cfg = &plan.points[3].plan.cells[0].config;
    assert_eq!(cfg.events.as_ref().and_then(|e| e.threshold), Some([0.3, 0.3]));

    // a finished sweep trains nothing
    for point in &plan.points {
        let s = run::run(&point.plan, &opts).unwrap();
        assert_eq!((s.trained, s.skipped, s.simulated), (0, 2, 0));
    }
}

#[test]
fn data_only_sweep_measures_datasets_without_rendering_twice() {
    let dir = temp_dir("sweep", "data");
    let file = sweep_file(
        &dir,
        "threshold",
        &["nerf"],
        r#"[sweep]
[[sweep.axes]]
setting = "dataset.threshold"
values = [0.2, 0.4]
"#,
    );
    let results = dir.join("results");
    let out = Command::new(workspace_binary("evblur-benchmark", "evbench"))
        .args(["sweep", "--data-only", "--results"])
        .arg(&results)
        .arg(&file)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("| dataset.threshold = 0.4 | tiny |"), "{stdout}");

    let csv = std::fs::read_to_string(results.join("sweep/threshold.data.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.rsplit(',').collect::<Vec<_>>()).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    // fields from the end: edi_psnr, blurry_psnr, blur max, blur mean, events/px, events/s, events
    let events: Vec<u64> = rows.iter().map(|r| r[6].parse().unwrap()).collect();
    assert!(events[1] > 0 && events[1] * 3 / 2 < events[0], "a doubled threshold fires far fewer events: {events:?}");
    for r in &rows {
        let (edi, blurry): (f64, f64) = (r[0].parse().unwrap(), r[1].parse().unwrap());
        assert!(edi > 10.0 && blurry > 10.0, "{r:?}");
    }
    assert!(stdout.contains("0 frames rendered"), "the second point reuses the frames: {stdout}");
    assert!(results.join("sweep/threshold.data.png").is_file());

    // the library's view: the same numbers again, nothing simulated now
    let plan = SweepPlan::load(&file, Some(&results)).unwrap();
    let stats = sweep::data::run(&plan, |_| {}).unwrap();
    assert!(stats.iter().all(|d| d.frames_rendered == 0 && d.simulate_seconds == 0.0));
    assert_eq!(stats.iter().map(|d| d.events).collect::<Vec<_>>(), events);
}

#[test]
fn bad_sweep_files_name_the_axis_and_the_fix() {
    let dir = temp_dir("sweep", "bad");
    let check = |sweep: &str, want: &[&str]| {
        let file = sweep_file(&dir, "bad", &["nerf"], sweep);
        let e = SweepPlan::load(&file, None).unwrap_err().to_string();
        for w in want {
            assert!(e.contains(w), "{e:?} lacks {w:?}");
        }
    };
    let axis =
        |setting: &str, values: &str| format!("[sweep]\n[[sweep.axes]]\nsetting = \"{setting}\"\nvalues = {values}\n");
    check("", &["bad.toml", "sweep", "missing"]);
    check(&axis("dataset.exposure", "[5]"), &["sweep.axes", "exposure", "exposure_ms"]);
    check(&axis("exposure_ms", "[5]"), &["sweep.axes[0]", "dataset.<key>"]);
    check(&axis("dataset.thresold", "[0.2]"), &["sweep.axes", "thresold", "DatasetConfig", "threshold_sigma"]);
    check(&axis("dataset.width", "[[1, 2]]"), &["sweep.axes", "dataset.width", "invalid type"]);
    check(&axis("dataset.exposure_ms", "[]"), &["sweep.axes[0]", "empty"]);
    check(&axis("dataset.exposure_ms", "[5, 5]"), &["appears twice"]);
    check(&axis("dataset.exposure_ms", "[\"long\"]"), &["finite numbers"]);
    check(&axis("dataset.exposure_ms", "[-5]"), &["exposure_ms = -5", "dataset.exposure_ms", "positive"]);
    check(&axis("dataset.speed", "[0]"), &["speed", "positive"]);
    check(&axis("train.bogus.key", "[1]"), &["bogus", "nerf"]);
    check("[sweep]\naxes = []\n", &["sweep.axes", "one or two"]);
    check(&axis("train.seed", "[1, 2]"), &["train.seed", "seeds"]);
    check(&axis("train.iterations", "[0]"), &["iterations", "positive integer"]);
    // a method's own `set` of the swept key wins: every point would repeat one cell
    let file = sweep_file(&dir, "noop", &[], "");
    let text = std::fs::read_to_string(&file).unwrap().replace(
        "[[scenes]]",
        "[[methods]]\npreset = \"nerf\"\nname = \"fixed\"\nset = [\"batch_rays=64\"]\n[[scenes]]",
    ) + &axis("train.batch_rays", "[128, 256]");
    std::fs::write(&file, text).unwrap();
    let e = SweepPlan::load(&file, None).unwrap_err().to_string();
    assert!(e.contains("sweep.axes") && e.contains("fixed") && e.contains("batch_rays = 128"), "{e}");
    check("[sweep]\ncolour = 1\naxes = []\n", &["sweep", "colour"]);
}

#[test]
fn shipped_sweeps_resolve_at_both_scales() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benchmark/configs/sweeps");
    let mut seen = Vec::new();
    for sub in ["", "paper"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        for f in &files {
            let plan = SweepPlan::load(f, Some(Path::new("/nonexistent-results"))).unwrap_or_else(|e| panic!("{e}"));
            let scale = plan.points[0].plan.scale;
            assert_eq!(format!("{scale:?}").to_lowercase(), if sub.is_empty() { "cpu" } else { "paper" }, "{f:?}");
            let cells: usize = plan.points.iter().map(|p| p.plan.cells.len()).sum();
            assert!(cells >= 8, "{f:?}: {cells} cells");
            seen.push((sub, f.file_name().unwrap().to_string_lossy().into_owned(), cells));
        }
    }
    // every study in both versions, with the same cells
    let names = |s: &str| seen.iter().filter(|x| x.0 == s).map(|x| (x.1.clone(), x.2)).collect::<Vec<_>>();
    assert_eq!(names(""), names("paper"));
    let studies: Vec<String> = names("").into_iter().map(|x| x.0).collect();
    for want in ["exposure", "threshold", "mismatch", "noise", "refractory", "speed", "views", "windows"] {
        assert!(studies.contains(&format!("{want}.toml")), "{studies:?}");
    }
}

#[test]
fn a_sweeps_shards_split_all_its_points_and_iterations_can_be_swept() {
    let dir = temp_dir("sweep", "shards");
    let file = sweep_file(
        &dir,
        "its",
        &["nerf"],
        "[sweep]\n[[sweep.axes]]\nsetting = \"train.iterations\"\nvalues = [4, 6, 8]\n",
    );
    let plan = SweepPlan::load(&file, Some(&dir.join("results"))).unwrap();
    let its: Vec<u64> = plan.points.iter().map(|p| p.plan.cells[0].config.iterations).collect();
    assert_eq!(its, [4, 6, 8], "the axis wins over the matrix's iterations");
    // one cell per point: numbered across the sweep, two shards take 2 and 1 of the 3
    let count = |index| {
        let shard = benchmark::matrix::Shard { index, count: 2 };
        let mut first = 0;
        let mut n = 0;
        for p in &plan.points {
            n += run::shard_cells(&p.plan, shard, first).len();
            first += p.plan.cells.len();
        }
        n
    };
    assert_eq!((count(1), count(2)), (2, 1));

    // a data-only sweep needs a dataset axis
    let e = sweep::data::run(&plan, |_| {}).unwrap_err().to_string();
    assert!(e.contains("its.toml") && e.contains("dataset.*"), "{e}");
}
