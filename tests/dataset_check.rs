//! The dataset schema check ([`check_dataset`]) against the tools the public data is made with,
//! and `tests/python/read_dataset.py` (the reference loader's reading, numpy + h5py) against our
//! writers:
//! - a dataset in the public style (h5py `events.h5` with int16/uint16, int64 or uint8/bool
//!   columns, gzip or not; `np.savez` / `np.savez_compressed` timestamps; `np.save` poses, some
//!   float32-rounded; event times in ns or us; a CDAVIS-like one with float coordinates, the
//!   last 5 views sharp and `ev_map.npz`) passes our check, with the unit and the test-view
//!   policy auto-detected, and passes `read_dataset.py`;
//! - a dataset written by our writers (npy/npz, `NerfH5Sink`, PNG) passes `read_dataset.py`, and
//!   a wrong sharp marking fails both.
//!
//! Without the Mitsuba venv's Python (numpy + h5py) the test prints SKIPPED, or fails when
//! `EVBLUR_REQUIRE_MITSUBA=1`. The PNGs are always written from Rust (the venv has no PIL).

use std::path::{Path, PathBuf};
use std::process::Command;

use evblur_tests::{python_with, run_python, temp_dir};
use glam::{DQuat, DVec3};
use simulator::dataset::check::{check_dataset, CheckOptions, EventsUnit, TestViewPolicy};
use simulator::events::sinks::NerfH5Sink;
use simulator::events::{Event, EventSink};
use simulator::npy::{write_npy, write_npz, NpyArray};
use simulator::trajectory::interpolate::Pose;
use simulator::trajectory::llff::LlffCamera;

const W: u32 = 8;
const H: u32 = 6;
const N: usize = 10;

/// The Python verifier.
fn read_dataset_py() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("python/read_dataset.py")
}

/// Run `read_dataset.py dir args...`: (success, stdout + stderr).
fn read_dataset(py: &Path, dir: &Path, args: &[&str]) -> (bool, String) {
    let out = Command::new(py).arg(read_dataset_py()).arg(dir).args(args).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.success(), text)
}

/// `images_1/00.png ..` : N RGB images W x H.
fn write_pngs(dir: &Path) {
    std::fs::create_dir_all(dir.join("images_1")).unwrap();
    for i in 0..N {
        let img = image::RgbImage::from_fn(W, H, |x, y| image::Rgb([(x * 30) as u8, (y * 40) as u8, (i * 20) as u8]));
        img.save(dir.join(format!("images_1/{i:02}.png"))).unwrap();
    }
}

/// Writes the public-style files of a 10-image, 8x6 scene: argv = folder, variant.
const PUBLIC_STYLE: &str = r#"
import sys, numpy as np, h5py
d, variant = sys.argv[1], sys.argv[2]
N, W, H, M = 10, 8, 6, 100
def row(s):
    a = 0.8 * s - 0.3
    c, sn = np.cos(a), np.sin(a)
    R = np.array([[c, 0, sn], [0, 1, 0], [-sn, 0, c]])   # camera-to-world, columns right, up, backward
    m = np.stack([-R[:, 1], R[:, 0], R[:, 2], [2 * s, 1.0, 5 - s], [H, W, 0.5 * H / np.tan(0.35)]], 1)
    return np.concatenate([m.ravel(), [0.5, 20.0]])
mid = 5000.0 + 9000.0 * np.arange(N)
half = np.where(np.arange(N) % 8 == 0, 0.0, 2000.0)
if variant == "cdavis":   # real-camera scenes: the last 5 views are the sharp test views
    half = np.where(np.arange(N) >= N - 5, 0.0, 2000.0)
    np.savez(d + "/ev_map.npz", inv_mapx=np.zeros((H, W), np.float32), inv_mapy=np.ones((H, W), np.float32))
save = np.savez_compressed if variant == "compressed" else np.savez
save(d + "/images_1/timestamps.npz", timestamps=mid, timestamps_start=mid - half, timestamps_end=mid + half)
poses = np.stack([row(t / 1e5) for t in mid])
all_t = 1000.0 * np.arange(1, M + 1)
all_poses = np.stack([row(t / 1e5) for t in all_t])
if variant == "compressed":   # float32-derived rotations
    poses = poses.astype(np.float32).astype(np.float64)
    all_poses = all_poses.astype(np.float32).astype(np.float64)
np.save(d + "/poses_bounds.npy", poses)
np.save(d + "/all_poses_bounds.npy", all_poses)
np.save(d + "/all_timestamps.npy", all_t)
i = np.arange(500)
x, y, t, on = i * 3 % W, i * 5 % H, 1_000_000 + i * 190_000, i % 3 == 0
if variant == "savez":
    cols = x.astype(np.int16), y.astype(np.uint16), t.astype(np.int64), on.astype(np.uint8)
elif variant == "compressed":
    cols = x.astype(np.int64), y.astype(np.int64), t.astype(np.int64), on.astype(bool)
elif variant == "cdavis":   # rectified float coordinates
    cols = (x + 0.37).astype(np.float32), (y - 0.2).astype(np.float32), t.astype(np.int64), on.astype(np.uint8)
else:   # "us": times in microseconds, polarity -1/+1
    cols = x.astype(np.uint16), y.astype(np.uint16), (t // 1000).astype(np.int64), np.where(on, 1, -1).astype(np.int8)
kw = dict(compression="gzip", chunks=(64,)) if variant == "compressed" else {}
with h5py.File(d + "/events.h5", "w") as f:
    for k, v in zip("xytp", cols):
        f.create_dataset(k, data=v, **kw)
"#;

#[test]
fn public_style_datasets_pass_the_check() {
    let Some(py) = python_with("h5py, numpy", "public_style_datasets_pass_the_check") else { return };
    let every8 = TestViewPolicy::Every8;
    for (variant, unit, views) in [
        ("savez", EventsUnit::Ns, every8),
        ("compressed", EventsUnit::Ns, every8),
        ("us", EventsUnit::Us, every8),
        ("cdavis", EventsUnit::Ns, TestViewPolicy::Last5),
    ] {
        let dir = temp_dir("dataset-check", &format!("public-{variant}"));
        write_pngs(&dir);
        run_python(&py, PUBLIC_STYLE, [dir.as_os_str(), variant.as_ref()]);
        let report = check_dataset(&dir, &CheckOptions::default()).unwrap();
        assert!(report.is_ok(), "{variant}:\n{report}");
        assert_eq!(report.test_views, Some(views), "{variant}");
        let ev = report.events.clone().unwrap();
        assert_eq!((ev.count, ev.on, ev.off, ev.unit), (500, 167, 333, unit), "{variant}:\n{report}");
        let unit_arg = if unit == EventsUnit::Us { "us" } else { "ns" };
        let views_arg = if views == TestViewPolicy::Last5 { "last5" } else { "every8" };
        let (ok, text) = read_dataset(&py, &dir, &["--events-unit", unit_arg, "--test-views", views_arg]);
        let sharp = if views == TestViewPolicy::Last5 { 5 } else { 2 };
        let want = format!("read_dataset: ok: 10 images 8x6, {sharp} sharp, 100 dense poses, 500 events");
        assert!(ok && text.contains(&want), "{variant}: {text}");
    }
}

/// A dataset written with our writers: the same scene as [`PUBLIC_STYLE`]'s.
fn our_fixture(dir: &Path) {
    write_pngs(dir);
    let row = |s: f64| {
        let pose = Pose {
            rotation: DQuat::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), 0.8 * s - 0.3),
            position: DVec3::new(2.0 * s, 1.0, 5.0 - s),
        };
        LlffCamera::new(pose, W, H, 0.7, 0.5, 20.0).unwrap().to_row()
    };
    let mid: Vec<f64> = (0..N).map(|i| 5000.0 + 9000.0 * i as f64).collect();
    let half = |i: usize| if i.is_multiple_of(8) { 0.0 } else { 2000.0 };
    write_npz(
        &dir.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid.clone())),
            ("timestamps_start", NpyArray::vector((0..N).map(|i| mid[i] - half(i)).collect::<Vec<_>>())),
            ("timestamps_end", NpyArray::vector((0..N).map(|i| mid[i] + half(i)).collect::<Vec<_>>())),
        ],
    )
    .unwrap();
    let rows: Vec<[f64; 17]> = mid.iter().map(|t| row(t / 1e5)).collect();
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    let all_t: Vec<f64> = (1..=100).map(|k| 1000.0 * k as f64).collect();
    let all: Vec<[f64; 17]> = all_t.iter().map(|t| row(t / 1e5)).collect();
    write_npy(&dir.join("all_poses_bounds.npy"), &NpyArray::f64_2d(&all)).unwrap();
    write_npy(&dir.join("all_timestamps.npy"), &NpyArray::vector(all_t)).unwrap();
    let events: Vec<Event> = (0..500)
        .map(|i| Event {
            x: (i * 3 % W as usize) as u16,
            y: (i * 5 % H as usize) as u16,
            t_ns: 1_000_000 + i as i64 * 190_000,
            p: if i % 3 == 0 { 1 } else { -1 },
        })
        .collect();
    let mut sink = NerfH5Sink::create(&dir.join("events.h5")).unwrap();
    sink.push(&events).unwrap();
    sink.finish().unwrap();
}

#[test]
fn reference_style_reader_accepts_our_dataset_and_both_reject_a_wrong_marking() {
    let Some(py) = python_with("h5py, numpy", "reference_style_reader_accepts_our_dataset") else { return };
    let dir = temp_dir("dataset-check", "ours");
    our_fixture(&dir);
    let (ok, text) = read_dataset(&py, &dir, &[]);
    assert!(
        ok && text.contains("read_dataset: ok: 10 images 8x6, 2 sharp, 100 dense poses, 500 events (167 ON)"),
        "{text}"
    );
    let report = check_dataset(&dir, &CheckOptions::default()).unwrap();
    assert!(report.is_ok(), "{report}");

    // Image 3 marked sharp (start == end): both readers refuse it.
    let mid: Vec<f64> = (0..N).map(|i| 5000.0 + 9000.0 * i as f64).collect();
    let half = |i: usize| if i.is_multiple_of(8) || i == 3 { 0.0 } else { 2000.0 };
    write_npz(
        &dir.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid.clone())),
            ("timestamps_start", NpyArray::vector((0..N).map(|i| mid[i] - half(i)).collect::<Vec<_>>())),
            ("timestamps_end", NpyArray::vector((0..N).map(|i| mid[i] + half(i)).collect::<Vec<_>>())),
        ],
    )
    .unwrap();
    let (ok, text) = read_dataset(&py, &dir, &[]);
    assert!(!ok && text.contains("sharp views [0, 3, 8] != test views [0, 8]"), "{text}");
    let report = check_dataset(&dir, &CheckOptions::default()).unwrap();
    let problems: Vec<String> = report.problems().map(|e| e.to_string()).collect();
    assert!(problems.iter().any(|p| p.contains("sharp views at [0, 3, 8]")), "{report}");
}
