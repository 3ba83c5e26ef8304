//! `evsim dataset` end to end on a tiny scene: the reference layout, no-op re-runs, conflicts,
//! resume after an interruption, a camera that sees nothing, and the same bytes whatever the
//! thread count.

use std::path::{Path, PathBuf};

use evblur_tests::{python_with, temp_dir};
use simulator::dataset::check::{check_dataset, CheckOptions, EventsUnit, TestViewPolicy};
use simulator::dataset::{write_dataset, DatasetError, Overrides, Plan, RunOptions, Shading};
use simulator::npy::{read_npy, read_npz};

/// The Cornell box of `scenes/cornell` with a short fast orbit and a tiny dataset table.
fn tiny_scene(dir: &Path) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
    for f in ["scene.obj", "scene.mtl"] {
        std::fs::copy(src.join(f), dir.join(f)).unwrap();
    }
    let toml = dir.join("scene.toml");
    std::fs::write(
        &toml,
        r#"scene = "scene.obj"
[camera]
origin = [0.0, 0.0, 3.9]
target = [0.0, 0.0, 0.0]
fov = 39.3077
fov_axis = "y"
[environment]
type = "constant"
radiance = [0.0, 0.0, 0.0]
[trajectory]
type = "fast_motion"
target = [0.0, 0.0, 0.0]
radius = 3.9
sweep_deg = 20.0
duration = 0.12
[dataset]
width = 48
height = 32
spp = 2
sharp_spp = 4
views = 9
first_view_ms = 12.0
exposure_ms = 8.0
"#,
    )
    .unwrap();
    toml
}

fn plan(toml: &Path) -> Plan {
    Plan::resolve(toml, &Overrides::default()).unwrap()
}

/// Overrides that set the scene file's `[dataset] shading`.
fn shaded(shading: Shading) -> Overrides {
    Overrides::default().with("shading", toml::Value::try_from(shading).unwrap())
}

fn opts(out: &Path, cache: Option<PathBuf>) -> RunOptions {
    RunOptions { out: out.to_path_buf(), frames_cache: cache, ..RunOptions::default() }
}

/// The entries under `dir` outside hidden folders, as paths relative to `dir`, sorted: the
/// files, and the hidden files and folders (not entered).
fn walk(dir: &Path) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let (mut files, mut hidden) = (Vec::new(), Vec::new());
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_path_buf();
            if p.file_name().unwrap().to_string_lossy().starts_with('.') {
                hidden.push(rel);
            } else if p.is_dir() {
                stack.push(p);
            } else {
                files.push(rel);
            }
        }
    }
    files.sort();
    hidden.sort();
    (files, hidden)
}

/// Every file under `dir` (relative path, bytes), sorted, hidden entries skipped.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    walk(dir).0.into_iter().map(|f| (f.display().to_string(), std::fs::read(dir.join(&f)).unwrap())).collect()
}

fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    let names = |f: &[(String, Vec<u8>)]| f.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&fa), names(&fb));
    for ((name, x), (_, y)) in fa.iter().zip(&fb) {
        assert!(x == y, "{name} differs between {} and {}", a.display(), b.display());
    }
}

#[test]
fn tiny_dataset_has_the_reference_layout() {
    let dir = temp_dir("dataset", "layout");
    let toml = tiny_scene(&dir);
    let plan = plan(&toml);
    let out = dir.join("out");
    let s = write_dataset(&plan, &opts(&out, None)).unwrap();
    assert_eq!(s.frames, 120);
    assert_eq!((s.frames_rendered, s.sharp_rendered), (120, 9));
    assert!(s.events_on > 100 && s.events_off > 100, "{s:?}");
    assert!(!out.join(".frames").exists(), "the default frame cache is removed after success");

    // images: 9 views, 00..08, views 0 and 8 sharp
    let names: Vec<String> = (0..9).map(|i| format!("{i:02}.png")).collect();
    for n in &names {
        for folder in ["images_1", "images_sharp_1"] {
            let img = image::open(out.join(folder).join(n)).unwrap();
            assert_eq!((img.width(), img.height()), (48, 32), "{folder}/{n}");
            assert_eq!(img.color(), image::ColorType::Rgb8);
        }
    }
    for sharp in ["00.png", "08.png"] {
        assert_eq!(
            std::fs::read(out.join("images_1").join(sharp)).unwrap(),
            std::fs::read(out.join("images_sharp_1").join(sharp)).unwrap(),
            "a sharp test view is its sharp render"
        );
    }
    assert_ne!(
        std::fs::read(out.join("images_1/04.png")).unwrap(),
        std::fs::read(out.join("images_sharp_1/04.png")).unwrap()
    );

    // timestamps: us, strictly positive, sharp <=> start == end, every 8th sharp
    let ts = read_npz(&out.join("images_1/timestamps.npz")).unwrap();
    let get = |k: &str| ts.iter().find(|(n, _)| n == k).unwrap().1.as_f64().unwrap().to_vec();
    let (mid, start, end) = (get("timestamps"), get("timestamps_start"), get("timestamps_end"));
    assert_eq!(mid.len(), 9);
    for i in 0..9 {
        assert!(start[i] > 0.0 && start[i] <= mid[i] && mid[i] <= end[i]);
        assert_eq!(start[i] == end[i], i % 8 == 0, "view {i}");
        if i % 8 != 0 {
            assert_eq!(end[i] - start[i], 8000.0, "8 ms exposure in us");
        }
    }
    assert_eq!(mid[0], 12_000.0);

    // poses: (9, 17) and (120, 17); pure rotations; hwf; honest bounds (the box is 3-6 m away)
    let poses = read_npy(&out.join("poses_bounds.npy")).unwrap();
    assert_eq!(poses.shape(), &[9, 17]);
    let all = read_npy(&out.join("all_poses_bounds.npy")).unwrap();
    assert_eq!(all.shape(), &[120, 17]);
    for row in poses.as_f64().unwrap().chunks(17).chain(all.as_f64().unwrap().chunks(17)) {
        let cam = simulator::trajectory::LlffCamera::from_row(row.try_into().unwrap()).unwrap();
        assert_eq!((cam.height, cam.width), (32.0, 48.0));
        assert!(cam.near > 2.0 && cam.near < 4.0 && cam.far > 4.5 && cam.far < 7.0, "{cam:?}");
    }
    let all_t = read_npy(&out.join("all_timestamps.npy")).unwrap();
    let all_t = all_t.as_f64().unwrap();
    assert_eq!(all_t.len(), 120);
    assert!(all_t.windows(2).all(|w| w[1] - w[0] == 1000.0));
    // the view's pose is the dense trajectory's pose at its mid-time (view 1 at frame 12 + 12)
    let view_rows = poses.as_f64().unwrap();
    let k = all_t.iter().position(|&t| t == mid[1]).unwrap();
    assert_eq!(&view_rows[17..32], &all.as_f64().unwrap()[17 * k..17 * k + 15]);

    // manifest and transforms
    let manifest: toml::Value = toml::from_str(&std::fs::read_to_string(out.join("dataset.toml")).unwrap()).unwrap();
    assert_eq!(manifest["settings_hash"].as_str().unwrap(), plan.settings_hash);
    assert_eq!(manifest["events"].as_integer().unwrap() as u64, s.events_on + s.events_off);
    let tj: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("transforms.json")).unwrap()).unwrap();
    assert_eq!(tj["frames"].as_array().unwrap().len(), 9);
    assert_eq!(tj["test_filenames"].as_array().unwrap().len(), 2);

    // the schema check (strict: every-8th policy, ns events) passes without warnings
    let opts =
        CheckOptions { test_views: TestViewPolicy::Every8, events_unit: EventsUnit::Ns, ..CheckOptions::default() };
    let report = check_dataset(&out, &opts).unwrap();
    assert!(report.is_ok() && report.warnings().count() == 0, "{report}");
    assert_eq!(report.n_images, Some(9));
    assert_eq!(report.events.as_ref().unwrap().count, s.events_on + s.events_off);

    // and the reference loader's reading (numpy + h5py) accepts it
    if let Some(py) = python_with("h5py, numpy", "dataset_writer: read_dataset.py") {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/read_dataset.py");
        let o = std::process::Command::new(py).arg(script).arg(&out).output().unwrap();
        let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
        let want = format!(
            "read_dataset: ok: 9 images 48x32, 2 sharp, 120 dense poses, {} events",
            s.events_on + s.events_off
        );
        assert!(o.status.success() && text.contains(&want), "{text}");
    }
}

#[test]
fn rerun_is_a_noop_and_other_settings_conflict() {
    let dir = temp_dir("dataset", "rerun");
    let toml = tiny_scene(&dir);
    let out = dir.join("out");
    let p = plan(&toml);
    write_dataset(&p, &opts(&out, None)).unwrap();
    let before = files(&out);
    let s = write_dataset(&p, &opts(&out, None)).unwrap();
    assert!(s.already_complete && s.frames_rendered == 0);
    assert_eq!(files(&out), before);

    let other = Plan::resolve(&toml, &Overrides::default().with("exposure_ms", 4.0)).unwrap();
    let e = write_dataset(&other, &opts(&out, None)).unwrap_err();
    assert!(matches!(e, DatasetError::Conflict { .. }), "{e}");
    assert!(e.to_string().contains("dataset.toml") && e.to_string().contains("other settings"), "{e}");
}

#[test]
fn an_interrupted_run_resumes_to_the_same_bytes() {
    for shading in [Shading::SurfaceCache, Shading::PathTraced] {
        resumes_to_the_same_bytes(shading);
    }
}

fn resumes_to_the_same_bytes(shading: Shading) {
    let dir = temp_dir("dataset", &format!("resume-{shading:?}"));
    let toml = tiny_scene(&dir);
    let p = Plan::resolve(&toml, &shaded(shading)).unwrap();
    let (a, b) = (dir.join("a"), dir.join("b"));
    write_dataset(&p, &opts(&a, None)).unwrap();

    // an earlier interrupted run with more views left images 09..11 behind: they must go
    for extra in ["09.png", "10.png", "11.png"] {
        std::fs::create_dir_all(b.join("images_1")).unwrap();
        std::fs::write(b.join("images_1").join(extra), b"stale").unwrap();
    }
    let mut o = opts(&b, None);
    o.stop_after_renders = Some(50);
    let e = write_dataset(&p, &o).unwrap_err();
    assert!(matches!(e, DatasetError::Interrupted { frames: 50 }), "{e}");
    assert!(!b.join("dataset.toml").exists(), "no manifest before the end");
    // what a kill leaves: temporary files of the event file, a view and a cached frame
    let killed = [".events.h5.tmp424242", "images_1/.03.png.tmp424242"];
    for f in killed {
        std::fs::write(b.join(f), b"half").unwrap();
    }
    let cached = std::fs::read_dir(b.join(".frames")).unwrap().next().unwrap().unwrap().path();
    std::fs::write(cached.join(".key.toml.tmp424242"), b"half").unwrap();
    let s = write_dataset(&p, &opts(&b, None)).unwrap();
    assert_eq!(hidden_entries(&b), Vec::<String>::new(), "no temporary file or frame cache survives");
    assert_eq!((s.frames_rendered, s.sharp_rendered), (70, 9), "resumes after the 50 cached frames");
    if shading == Shading::PathTraced {
        // the temporal window of frame 50 needs the `radius` frames before it again (not their
        // filtered results)
        assert_eq!(s.window_renders, p.config.temporal_radius as usize, "{s:?}");
        assert!(s.window_renders > 0);
    } else {
        assert_eq!(s.window_renders, 0, "surface-cache frames have no temporal window: {s:?}");
    }
    assert_same_files(&a, &b);

    // a shared frame cache: an exposure or threshold change re-renders nothing but the sharp
    // views it moves (none here: view times do not depend on the exposure when first_view_ms is set)
    let cache = dir.join("cache");
    write_dataset(&p, &opts(&dir.join("c"), Some(cache.clone()))).unwrap();
    let swept = Overrides { threshold: Some(0.3), ..shaded(shading).with("exposure_ms", 4.0) };
    let p2 = Plan::resolve(&toml, &swept).unwrap();
    let s = write_dataset(&p2, &opts(&dir.join("d"), Some(cache))).unwrap();
    assert_eq!((s.frames_rendered, s.sharp_rendered), (0, 0));
}

/// The hidden files and folders under `dir` (relative paths), sorted.
fn hidden_entries(dir: &Path) -> Vec<String> {
    walk(dir).1.iter().map(|p| p.display().to_string()).collect()
}

#[test]
fn a_second_writer_is_refused_and_a_killed_clean_up_is_finished() {
    let dir = temp_dir("dataset", "lock");
    let toml = tiny_scene(&dir);
    let p = plan(&toml);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    // a writer holds the folder (a lock is per open file, so this process's own lock conflicts
    // as another process's would)
    let held = simulator::lock::FolderLock::acquire(&out).unwrap();
    let e = write_dataset(&p, &opts(&out, None)).unwrap_err();
    assert!(matches!(e, DatasetError::Locked(_)), "{e}");
    let msg = e.to_string();
    assert!(msg.contains(&format!("pid {}", std::process::id())) && msg.contains(&*out.to_string_lossy()), "{msg}");
    assert!(!out.join("events.h5").exists() && !out.join("images_1").exists(), "the second writer wrote nothing");
    drop(held);

    write_dataset(&p, &opts(&out, None)).unwrap();
    assert_eq!(hidden_entries(&out), Vec::<String>::new());
    // a run killed while deleting its frame cache leaves it renamed; the next run (which finds
    // the dataset complete) removes it
    std::fs::create_dir_all(out.join(".frames.removing/abc")).unwrap();
    std::fs::write(out.join(".frames.removing/abc/f000001.exr"), b"x").unwrap();
    let s = write_dataset(&p, &opts(&out, None)).unwrap();
    assert!(s.already_complete);
    assert_eq!(hidden_entries(&out), Vec::<String>::new());
}

#[test]
fn a_camera_that_sees_nothing_is_an_error_naming_the_frame() {
    // the orbit's centre far behind the camera's back: no frame sees the box. The depth bounds
    // are traced one frame behind the renders, and their error must still end the run
    let dir = temp_dir("dataset", "blind");
    let toml = tiny_scene(&dir);
    let text = std::fs::read_to_string(&toml).unwrap();
    let blind = text.replace("target = [0.0, 0.0, 0.0]\nradius", "target = [0.0, 0.0, 100.0]\nradius");
    assert_ne!(blind, text);
    std::fs::write(&toml, blind).unwrap();
    let out = dir.join("out");
    let e = write_dataset(&plan(&toml), &opts(&out, None)).unwrap_err().to_string();
    assert!(e.contains("frame 0 at") && e.contains("sees no surface"), "{e}");
    assert!(!out.join("dataset.toml").exists(), "no manifest for a failed run");
}

#[test]
fn same_bytes_whatever_the_thread_count() {
    let dir = temp_dir("dataset", "threads");
    let toml = tiny_scene(&dir);
    let p = plan(&toml);
    let run = |threads: usize, out: PathBuf| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| write_dataset(&p, &opts(&out, None)).unwrap());
    };
    run(1, dir.join("one"));
    run(3, dir.join("three"));
    assert_same_files(&dir.join("one"), &dir.join("three"));
}

#[test]
fn bad_settings_name_the_field() {
    let dir = temp_dir("dataset", "bad");
    let toml = tiny_scene(&dir);
    let text = std::fs::read_to_string(&toml).unwrap();
    let check = |edit: &dyn Fn(&str) -> String, want: &[&str]| {
        std::fs::write(&toml, edit(&text)).unwrap();
        let e = Plan::resolve(&toml, &Overrides::default()).unwrap_err().to_string();
        for w in want {
            assert!(e.contains(w), "{e:?} lacks {w:?}");
        }
    };
    check(&|t| t.replace("exposure_ms = 8.0", "exposure_ms = -8.0"), &["scene.toml", "dataset.exposure_ms"]);
    check(&|t| t.replace("exposure_ms = 8.0", "exposure_ms = nan"), &["dataset.exposure_ms"]);
    check(&|t| t.replace("spp = 2", "spp = 0"), &["dataset.spp"]);
    check(&|t| t.replace("views = 9", "views = 200"), &["dataset.views", "do not fit"]);
    check(&|t| t.replace("first_view_ms = 12.0", "first_view_ms = 2.0"), &["dataset.first_view_ms"]);
    check(&|t| t.replace("spp = 2\n", "spp = 2\nspeed = 3\n"), &["speed"]);
    check(
        &|t| t.replace("spp = 2\n", "spp = 2\nadaptive_variance = 0.0\n"),
        &["dataset.adaptive_variance", "positive"],
    );
    check(&|t| t.replace("spp = 2\n", "spp = 2\nspp_max = 5000\n"), &["dataset.spp_max"]);
    check(&|t| t.replace("spp = 2\n", "spp = 2\nspp_max = 1\n"), &["dataset.spp_max", "below spp = 2"]);
    check(&|t| t.split("[trajectory]").next().unwrap().to_string(), &["trajectory", "missing"]);
    check(&|t| t.replace("sharp_spp = 4", "sharp_spp = 1"), &["dataset.sharp_spp"]);
    check(&|t| t.replace("spp = 2\n", "spp = 2\ntemporal_stride = 0\n"), &["dataset.temporal_stride", "1..=64"]);
    check(&|t| t.replace("spp = 2\n", "spp = 2\nglossy_grid_alpha = 1.5\n"), &["dataset.glossy_grid_alpha", "0..=1"]);
    check(&|t| t.replace("spp = 2\n", "spp = 2\nglossy_grid_alpha = nan\n"), &["dataset.glossy_grid_alpha"]);
    // no sharp test views (0) or another marking than every 8th: a dataset the loader rejects
    for every in ["0", "4"] {
        check(
            &|t| t.replace("spp = 2\n", &format!("spp = 2\nsharp_every = {every}\n")),
            &["dataset.sharp_every", "set 8"],
        );
    }
    std::fs::write(&toml, &text).unwrap();
    let e = Plan::resolve(&toml, &Overrides { threshold: Some(-0.1), ..Overrides::default() }).unwrap_err();
    assert!(e.to_string().contains("events") && e.to_string().contains("c_pos"), "{e}");

    // unwritable output: a file where the folder should be
    let blocker = dir.join("blocker");
    std::fs::write(&blocker, b"x").unwrap();
    let e = write_dataset(&plan(&toml), &opts(&blocker.join("out"), None)).unwrap_err().to_string();
    assert!(e.contains("blocker"), "{e}");
}

#[test]
fn fixed_noise_pattern_fires_fewer_noise_events_than_per_frame_noise() {
    use simulator::dataset::noise::{measure, NoiseOptions};
    use simulator::dataset::NoisePattern;
    let dir = temp_dir("dataset", "noise");
    let toml = tiny_scene(&dir);
    let opts = NoiseOptions { frames: 12, factor: 4, ..NoiseOptions::default() };
    let run_radius = |pattern: NoisePattern, denoise: bool, radius: u32| {
        let o = shaded(Shading::PathTraced)
            .with("noise_pattern", toml::Value::try_from(pattern).unwrap())
            .with("denoise", denoise)
            .with("temporal_radius", radius);
        measure(&Plan::resolve(&toml, &o).unwrap(), &opts).unwrap()
    };
    let run = |pattern, denoise| run_radius(pattern, denoise, 4);
    let (fixed, flicker) = (run(NoisePattern::Fixed, false), run(NoisePattern::PerFrame, false));
    assert_eq!((fixed.frames, fixed.spp, fixed.ref_spp, fixed.denoised), (12, 2, 8, false));
    assert_eq!(fixed.mean_spp, 2.0, "uniform sampling: spp in every pixel of every render");
    assert!(fixed.unfiltered.is_none() && fixed.vs_unfiltered.is_none());
    // the map holds the same differences, per pixel, and the overlay shows them
    for r in [&fixed, &flicker] {
        let m = &r.pipeline_map;
        assert_eq!((m.pool, m.width, m.height), (1, r.width, r.height));
        let sum = |v: &[u32]| v.iter().map(|&n| n as u64).sum::<u64>();
        assert_eq!((sum(&m.excess), sum(&m.missing)), (r.pipeline.excess, r.pipeline.missing));
        let img = m.overlay(&r.first_frame);
        let reddish = img.pixels.iter().filter(|p| p.x > p.y && p.x > p.z).count();
        let excess_only = m.excess.iter().zip(&m.missing).filter(|&(&e, &mi)| e.min(2) > mi.min(2)).count();
        assert_eq!(reddish, excess_only, "red marks the blocks with more excess than missing events (up to 2)");
    }
    let (fixed, flicker) = (fixed.pipeline, flicker.pipeline);
    assert!(fixed.test_events > 0 && fixed.ref_events > 0);
    // per-frame noise at 2 spp fires more than twice the events of the (less noisy) 8 spp reference
    assert!(flicker.test_events > 2 * flicker.ref_events, "{flicker:?}");
    assert!(flicker.noise_fraction() > 0.5, "{flicker:?}");
    // a fixed pattern fires an order of magnitude fewer events the reference lacks (the fractions
    // are not comparable: the per-frame reference flickers too)
    assert!(10 * fixed.excess < flicker.excess, "{fixed:?} vs {flicker:?}");

    // denoising: the same renders measured both ways, at least 30% fewer noise events with the
    // filter (about 46% fewer here: 2 spp flickering per frame in a 48x32 box)
    let denoised = run(NoisePattern::PerFrame, true);
    let unfiltered = denoised.unfiltered.clone().expect("denoised runs report the unfiltered measure");
    assert_eq!(unfiltered, flicker, "the unfiltered measure is the one without denoising");
    assert!(denoised.vs_unfiltered.is_some());
    assert!(
        10 * denoised.pipeline.excess < 7 * unfiltered.excess,
        "denoised {:?} vs unfiltered {unfiltered:?}",
        denoised.pipeline
    );
    // the temporal window removes noise events the spatial filter alone leaves
    let spatial = run_radius(NoisePattern::PerFrame, true, 0).pipeline;
    assert!(
        10 * denoised.pipeline.excess < 8 * spatial.excess,
        "temporal + spatial {:?} vs spatial {spatial:?}",
        denoised.pipeline
    );
    let bad = measure(&plan(&toml), &NoiseOptions { factor: 1, ..NoiseOptions::default() }).unwrap_err();
    assert!(bad.to_string().contains("factor"), "{bad}");
}

#[test]
fn noise_measure_of_surface_cache_frames_has_no_unfiltered_sequence() {
    // Surface-cache frames (the default) have no image filter and no raw renders to compare;
    // `evsim dataset-noise` used to panic on them.
    use simulator::dataset::noise::{measure, NoiseOptions};
    let dir = temp_dir("dataset", "noise-surface");
    let p = plan(&tiny_scene(&dir));
    assert!(p.config.denoise && p.config.shading == Shading::SurfaceCache, "the defaults this test is about");
    let r = measure(&p, &NoiseOptions { frames: 3, factor: 2, ..NoiseOptions::default() }).unwrap();
    assert!(!r.denoised && r.unfiltered.is_none() && r.vs_unfiltered.is_none(), "{:?}", r.pipeline);
    assert_eq!((r.frames, r.spp), (3, 2));
}

#[test]
fn sweep_overrides_reach_the_plan_and_a_shared_frame_cache_skips_rendering() {
    let dir = temp_dir("dataset", "sweep");
    let toml = tiny_scene(&dir);
    let base = plan(&toml);
    let over = |o: Overrides| Plan::resolve(&toml, &o);

    // event and exposure settings keep the render key: the frames can be shared
    let noisy = over(
        Overrides {
            threshold_sigma: Some(0.03),
            leak_rate_hz: Some(0.5),
            shot_noise_rate_hz: Some(2.0),
            refractory_ms: Some(0.25),
            ..Overrides::default()
        }
        .with("exposure_ms", 4.0),
    )
    .unwrap();
    assert_eq!(noisy.render_key, base.render_key);
    assert_ne!(noisy.settings_hash, base.settings_hash);
    let n = &noisy.events.noise;
    assert_eq!(n.threshold_mismatch.map(|m| m.sigma), Some(0.03));
    assert_eq!((n.leak_rate_hz, n.shot_noise_rate_hz), (0.5, 2.0));
    assert_eq!(n.refractory.map(|r| r.period_ns), Some(250_000));
    let off = over(Overrides { threshold_sigma: Some(0.0), refractory_ms: Some(0.0), ..Overrides::default() }).unwrap();
    assert!(off.events.noise.threshold_mismatch.is_none() && off.events.noise.refractory.is_none());

    // the temporal window's stride shapes the frames (as used: at most the radius)
    let stride = |s: u32, r: u32| {
        over(shaded(Shading::PathTraced).with("temporal_stride", s).with("temporal_radius", r)).unwrap().render_key
    };
    assert_ne!(stride(1, 4), stride(2, 4));
    assert_eq!(stride(4, 4), stride(9, 4));
    assert_eq!(stride(1, 0), stride(3, 0), "no window, no stride");

    // speed re-times the path: half the frames at twice the speed, another render key
    let fast = over(Overrides { speed: Some(2.0), ..Overrides::default() }).unwrap();
    assert_ne!(fast.render_key, base.render_key);
    let span = |p: &Plan| p.trajectory.end_ns() - p.trajectory.start_ns();
    assert_eq!(span(&fast) * 2, span(&base));
    let end = |p: &Plan| p.trajectory.pose_at(p.trajectory.end_ns()).unwrap().position;
    assert!((end(&fast) - end(&base)).length() < 1e-9);

    // a second dataset that differs only in exposure and event noise renders nothing
    let cache = dir.join("frames");
    let first = write_dataset(&base, &opts(&dir.join("a"), Some(cache.clone()))).unwrap();
    assert!(first.frames_rendered > 0 && first.sharp_rendered > 0);
    let second = write_dataset(&noisy, &opts(&dir.join("b"), Some(cache))).unwrap();
    assert_eq!((second.frames_rendered, second.sharp_rendered), (0, 0), "{second:?}");
    assert!(second.frames > 0 && second.events_on + second.events_off > 0);

    for (o, field) in [
        (Overrides { speed: Some(0.0), ..Overrides::default() }, "speed"),
        (Overrides { speed: Some(f64::NAN), ..Overrides::default() }, "speed"),
        (Overrides { refractory_ms: Some(-1.0), ..Overrides::default() }, "refractory_ms"),
        (Overrides { leak_rate_hz: Some(f32::NAN), ..Overrides::default() }, "leak_rate_hz"),
        (Overrides { threshold_sigma: Some(-0.1), ..Overrides::default() }, "sigma"),
    ] {
        let e = over(o).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains("scene.toml"), "{e}");
    }
}

#[test]
fn sharp_images_default_to_the_sequence_frames() {
    // without sharp_spp nothing is rendered for the sharp images: each is the (filtered,
    // cached) sequence frame at its view's mid-time, through the camera response
    let dir = temp_dir("dataset", "sharp-frames");
    let toml = tiny_scene(&dir);
    let text = std::fs::read_to_string(&toml).unwrap().replace("sharp_spp = 4\n", "");
    std::fs::write(&toml, text).unwrap();
    let p = plan(&toml);
    assert_eq!(p.sharp_spp, None);
    let (out, cache_root) = (dir.join("out"), dir.join("cache"));
    let s = write_dataset(&p, &opts(&out, Some(cache_root.clone()))).unwrap();
    assert_eq!((s.frames_rendered, s.sharp_rendered), (120, 0));
    let cache = simulator::dataset::cache::FrameCache::open(&cache_root, &p).unwrap();
    for v in &p.views {
        let k = p.clock.frame_at(v.mid_ns).unwrap();
        let path = cache.frame_path(p.config.fps, p.config.spp, p.config.noise_pattern, k);
        let frame = simulator::dataset::cache::FrameCache::load(&path).unwrap().unwrap();
        let want = p.config.response.encode_png(&frame, p.config.gain).unwrap();
        let name = format!("{:02}.png", v.id);
        assert_eq!(std::fs::read(out.join("images_sharp_1").join(&name)).unwrap(), want, "view {}", v.id);
        if p.is_sharp(v.id) {
            assert_eq!(std::fs::read(out.join("images_1").join(&name)).unwrap(), want, "view {}", v.id);
        }
    }
    let o = CheckOptions { test_views: TestViewPolicy::Every8, events_unit: EventsUnit::Ns, ..CheckOptions::default() };
    let report = check_dataset(&out, &o).unwrap();
    assert!(report.is_ok() && report.warnings().count() == 0, "{report}");
    let manifest = std::fs::read_to_string(out.join("dataset.toml")).unwrap();
    assert!(!manifest.contains("sharp_spp"), "no sharp spp recorded when nothing was rendered");
}

#[test]
fn set_changes_any_setting_of_the_scene_file_and_names_each_mistake() {
    let dir = temp_dir("dataset", "set");
    let toml = tiny_scene(&dir);
    let with = |sets: &[&str], o: Overrides| {
        Plan::resolve(&toml, &Overrides { set: sets.iter().map(|s| s.to_string()).collect(), ..o })
    };
    // A set value is the same dataset as a matrix's `dataset = { exposure_ms = 4.0 }` key, and
    // as the file with that value written in it (same settings hash).
    let keyed = Plan::resolve(&toml, &Overrides::default().with("exposure_ms", 4.0)).unwrap();
    let set = with(&["dataset.exposure_ms=4.0"], Overrides::default()).unwrap();
    assert_eq!(set.settings_hash, keyed.settings_hash);
    assert_ne!(set.settings_hash, plan(&toml).settings_hash);
    let written = dir.join("written.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(text.contains("exposure_ms = "), "the tiny scene sets its exposure");
    let text: String = text
        .lines()
        .map(|l| if l.starts_with("exposure_ms = ") { "exposure_ms = 4.0\n".into() } else { format!("{l}\n") })
        .collect();
    std::fs::write(&written, text).unwrap();
    assert_eq!(Plan::resolve(&written, &Overrides::default()).unwrap().settings_hash, set.settings_hash);
    // Settings no flag names: a nested event-noise table (created: the file has no [events.noise]),
    // a [dataset] field, the trajectory.
    let p = with(
        &["events.noise.leak_rate_hz=0.25", "dataset.glossy_block=3", "trajectory.radius=5.0"],
        Overrides::default(),
    )
    .unwrap();
    assert_eq!((p.events.noise.leak_rate_hz, p.config.glossy_block), (0.25, 3));
    assert_ne!(p.render_key, plan(&toml).render_key, "the trajectory is part of the render key");
    // The order: the [dataset] keys, then the sets, then the shorthands.
    let keyed = Overrides { threshold: Some(0.4), ..Overrides::default().with("exposure_ms", 6.0) };
    let p = with(&["dataset.exposure_ms=4.0", "events.c_pos=0.2"], keyed).unwrap();
    assert_eq!((p.config.exposure_ms, p.events.c_pos, p.events.c_neg), (4.0, 0.4, 0.4));
    // A key that is not one of [dataset]'s is named, with where the keys are.
    let e = Plan::resolve(&toml, &Overrides::default().with("exposur_ms", 4.0)).unwrap_err().to_string();
    assert!(e.contains("dataset.exposur_ms") && e.contains("DatasetConfig") && e.contains("scene.toml"), "{e}");
    for (sets, says) in [
        (&["dataset.exposure_ms"][..], "expected KEY=VALUE"),
        (&["dataset.exposur_ms=4"][..], "exposur_ms"),
        (&["dataset.exposure_ms=fast"][..], "exposure_ms"),
        (&["camera.fov=30"][..], "only settings of [dataset], [events] and [trajectory]"),
        (&["scene=other.obj"][..], "only settings of [dataset], [events] and [trajectory]"),
        (&["dataset.fps=nan"][..], "dataset.fps"),
    ] {
        let e = with(sets, Overrides::default()).unwrap_err().to_string();
        assert!(e.contains(says) && e.contains("scene.toml"), "{sets:?}: {e}");
    }
}
