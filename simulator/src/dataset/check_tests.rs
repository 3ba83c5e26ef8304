//! Tests of the schema check: a small valid dataset written with our own writers passes, and
//! each kind of corruption is reported with the file and field it concerns.

use std::path::{Path, PathBuf};

use glam::{DQuat, DVec3};

use super::*;
use crate::events::sinks::NerfH5Sink;
use crate::events::{Event, EventSink};
use crate::npy::{write_npy, write_npz, NpyArray};
use crate::trajectory::interpolate::Pose;
use crate::trajectory::llff::LlffCamera;

const W: u32 = 8;
const H: u32 = 6;
/// Images in the fixture (sharp: 0 and 8).
const N: usize = 10;
/// Dense trajectory: 1000 us .. 100000 us every 1000 us.
const M: usize = 100;

/// A fresh, empty folder for one test.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evblur-check-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The LLFF row of a camera turning about a tilted axis at time `s` in [0, 1].
fn row(s: f64) -> [f64; 17] {
    let pose = Pose {
        rotation: DQuat::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), 0.8 * s - 0.3),
        position: DVec3::new(2.0 * s, 1.0, 5.0 - s),
    };
    LlffCamera::new(pose, W, H, 0.7, 0.5, 20.0).unwrap().to_row()
}

/// Exposure windows (us): mid 5000 + 9000 i, blurry +-2000, sharp every 8th.
fn windows() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mid: Vec<f64> = (0..N).map(|i| 5000.0 + 9000.0 * i as f64).collect();
    let half = |i: usize| if i.is_multiple_of(8) { 0.0 } else { 2000.0 };
    let start = (0..N).map(|i| mid[i] - half(i)).collect();
    let end = (0..N).map(|i| mid[i] + half(i)).collect();
    (mid, start, end)
}

fn write_timestamps(dir: &Path, mid: Vec<f64>, start: Vec<f64>, end: Vec<f64>) {
    write_npz(
        &dir.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid)),
            ("timestamps_start", NpyArray::vector(start)),
            ("timestamps_end", NpyArray::vector(end)),
        ],
    )
    .unwrap();
}

fn write_events(dir: &Path, events: &[Event]) {
    let mut sink = NerfH5Sink::create(&dir.join("events.h5")).unwrap();
    sink.push(events).unwrap();
    sink.finish().unwrap();
}

/// Time-sorted events inside the dense trajectory (ns), both polarities.
fn good_events() -> Vec<Event> {
    (0..500)
        .map(|i| Event {
            x: (i * 3 % W as usize) as u16,
            y: (i * 5 % H as usize) as u16,
            t_ns: 1_000_000 + i as i64 * 190_000,
            p: if i % 3 == 0 { 1 } else { -1 },
        })
        .collect()
}

/// A valid dataset in the Ev-DeblurBlender layout, written with our writers.
fn fixture(name: &str) -> PathBuf {
    let dir = temp_dir(name);
    std::fs::create_dir_all(dir.join("images_1")).unwrap();
    for i in 0..N {
        let img = image::RgbImage::from_fn(W, H, |x, y| image::Rgb([(x * 30) as u8, (y * 40) as u8, (i * 20) as u8]));
        img.save(dir.join(format!("images_1/{i:02}.png"))).unwrap();
    }
    let (mid, start, end) = windows();
    let rows: Vec<[f64; 17]> = mid.iter().map(|t| row(t / 1e5)).collect();
    write_timestamps(&dir, mid, start, end);
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    let dense_t: Vec<f64> = (1..=M).map(|k| 1000.0 * k as f64).collect();
    let dense: Vec<[f64; 17]> = dense_t.iter().map(|t| row(t / 1e5)).collect();
    write_npy(&dir.join("all_poses_bounds.npy"), &NpyArray::f64_2d(&dense)).unwrap();
    write_npy(&dir.join("all_timestamps.npy"), &NpyArray::vector(dense_t)).unwrap();
    write_events(&dir, &good_events());
    dir
}

fn check(dir: &Path) -> CheckReport {
    check_dataset(dir, &CheckOptions::default()).unwrap()
}

/// The problems as strings.
fn problems(r: &CheckReport) -> Vec<String> {
    r.problems().map(|e| e.to_string()).collect()
}

/// Assert the report has a problem containing every one of `parts`.
fn assert_problem(r: &CheckReport, parts: &[&str]) {
    let p = problems(r);
    assert!(p.iter().any(|s| parts.iter().all(|part| s.contains(part))), "no problem with {parts:?} in:\n{r}");
}

#[test]
fn valid_fixture_passes() {
    let dir = fixture("valid");
    let r = check(&dir);
    assert!(r.is_ok(), "{r}");
    assert_eq!(r.n_images, Some(N));
    assert_eq!(r.image_size, Some((W, H)));
    assert_eq!(r.test_views, Some(TestViewPolicy::Every8));
    let ev = r.events.clone().unwrap();
    assert_eq!((ev.count, ev.on, ev.off, ev.unit), (500, 167, 333, EventsUnit::Ns));
    assert_eq!(ev.t_range, Some((1e6, 1e6 + 499.0 * 190_000.0)));
    let text = r.to_string();
    assert!(text.contains("ok       events.h5: 500 events (167 ON, 333 OFF)"), "{text}");
    assert!(text.contains("unit ns, auto-detected"), "{text}");
    assert!(text.contains("absent   ev_map.npz"), "{text}");
    assert!(text.ends_with("all checks passed"), "{text}");
}

#[test]
fn small_event_chunks_give_the_same_report() {
    let dir = fixture("chunks");
    let r = check_dataset(&dir, &CheckOptions { event_chunk: 7, ..CheckOptions::default() }).unwrap();
    assert_eq!(r, check(&dir));
}

#[test]
fn missing_files_are_each_reported() {
    let dir = fixture("missing");
    std::fs::remove_file(dir.join("events.h5")).unwrap();
    std::fs::remove_file(dir.join("all_timestamps.npy")).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["events.h5: missing"]);
    assert_problem(&r, &["all_timestamps.npy: missing"]);
    assert_eq!(r.problems().count(), 2, "{r}");
    // Without images_1/ (and so its timestamps.npz) the other files are still checked.
    std::fs::remove_dir_all(dir.join("images_1")).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["images_1/: missing; write the blurry/sharp views as images_1/00.png"]);
    assert_problem(&r, &["images_1/timestamps.npz: missing"]);
    assert_eq!(r.problems().count(), 4, "{r}");
    assert!(r.to_string().contains("ok       poses_bounds.npy: 10 rows x 17 float64"), "{r}");
    let e = check_dataset(&dir.join("nope"), &CheckOptions::default()).unwrap_err().to_string();
    assert!(e.contains("nope: cannot open the dataset folder"), "{e}");
}

#[test]
fn truncated_npy_is_unreadable() {
    let dir = fixture("truncated");
    let path = dir.join("poses_bounds.npy");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 40]).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["poses_bounds.npy: cannot be read", "truncated"]);
}

#[test]
fn wrong_dtype_is_reported() {
    let dir = fixture("dtype");
    let t: Vec<f32> = (1..=M).map(|k| 1000.0 * k as f32).collect();
    write_npy(&dir.join("all_timestamps.npy"), &NpyArray::vector(t)).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["all_timestamps.npy: array: dtype float32, expected float64"]);
    assert_eq!(r.problems().count(), 1, "the values are still checked and fine:\n{r}");
}

#[test]
fn non_rotation_is_reported() {
    let dir = fixture("rotation");
    let (mid, ..) = windows();
    let mut rows: Vec<[f64; 17]> = mid.iter().map(|t| row(t / 1e5)).collect();
    for i in 0..3 {
        rows[4][5 * i] *= 1.01; // scale the down axis of row 4
    }
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["poses_bounds.npy: rows [4] (3x3 part): not a pure rotation"]);
    // A float32-rounded rotation is within the default tolerance.
    let rows: Vec<[f64; 17]> = mid.iter().map(|t| row(t / 1e5).map(|v| v as f32 as f64)).collect();
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    assert!(check(&dir).is_ok(), "{}", check(&dir));
}

#[test]
fn mismatched_hwf_is_reported() {
    let dir = fixture("hwf");
    let dense: Vec<[f64; 17]> = (1..=M)
        .map(|k| {
            let mut r = row(k as f64 / 100.0);
            r[9] = 600.0; // width
            r
        })
        .collect();
    write_npy(&dir.join("all_poses_bounds.npy"), &NpyArray::f64_2d(&dense)).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["all_poses_bounds.npy: rows [0, 1, 2, 3, 4] (+95 more) (hwf)", "height, width = 6, 600"]);
}

#[test]
fn unsorted_events_are_reported() {
    let dir = fixture("unsorted");
    let mut events = good_events();
    events.swap(10, 11);
    write_events(&dir, &events);
    let r = check(&dir);
    assert_problem(&r, &["events.h5: t: 1 event(s) go back in time, the first at index 11"]);
    assert!(r.to_string().contains("info     events.h5: 500 events (167 ON, 333 OFF)"), "{r}");
    assert_eq!(r.events.map(|e| e.count), Some(500));
}

#[test]
fn event_outside_the_trajectory_and_image_is_reported() {
    let dir = fixture("outside");
    let mut events = good_events();
    events.push(Event { x: W as u16, y: 0, t_ns: 100_000_001, p: 1 }); // 1 ns past the end: inside the slack
    events.push(Event { x: 0, y: 0, t_ns: 100_002_000, p: 1 });
    write_events(&dir, &events);
    let r = check(&dir);
    assert_problem(&r, &["events.h5: t: 1 event(s) lie outside the dense trajectory [1000, 100000] us", "index 501"]);
    assert_problem(&r, &["events.h5: x: 1 event(s) are not in 0 <= x < 8, the first at index 500"]);
    // Told the times are us, every event is far outside.
    let r = check_dataset(&dir, &CheckOptions { events_unit: EventsUnit::Us, ..CheckOptions::default() }).unwrap();
    assert_problem(&r, &["events.h5: t: 502 event(s) lie outside", "(unit us)"]);
}

#[test]
fn wrong_sharp_marking_is_reported() {
    let dir = fixture("sharp");
    let (mid, mut start, end) = windows();
    start[3] = end[3]; // image 3 looks sharp
    write_timestamps(&dir, mid, start, end);
    let r = check(&dir);
    assert_problem(
        &r,
        &[
            "images_1/timestamps.npz: timestamps_start == timestamps_end (sharp views)",
            "sharp views at [0, 3, 8]",
            "images [3] are marked wrongly",
        ],
    );
    // The last-5 policy is recognised when asked and in auto mode.
    let (mid, ..) = windows();
    let start: Vec<f64> = (0..N).map(|i| mid[i] - if i >= N - 5 { 0.0 } else { 1000.0 }).collect();
    let end: Vec<f64> = (0..N).map(|i| mid[i] + if i >= N - 5 { 0.0 } else { 1000.0 }).collect();
    write_timestamps(&dir, mid, start, end);
    assert_eq!(check(&dir).test_views, Some(TestViewPolicy::Last5));
    let strict = CheckOptions { test_views: TestViewPolicy::Every8, ..CheckOptions::default() };
    let r = check_dataset(&dir, &strict).unwrap();
    assert_problem(&r, &["do not follow every8 (llffhold = 8)"]);
}

#[test]
fn negative_timestamp_is_reported() {
    let dir = fixture("negative");
    let (mid, mut start, end) = windows();
    start[1] = -5.0;
    write_timestamps(&dir, mid, start, end);
    let r = check(&dir);
    assert_problem(
        &r,
        &["images_1/timestamps.npz: timestamps_start: not strictly positive and finite at [1] (e.g. -5)"],
    );
    assert_problem(&r, &["images_1/timestamps.npz: timestamps_start: images [1] outside the dense trajectory"]);
}

#[test]
fn image_problems_are_reported() {
    let dir = fixture("images");
    image::RgbImage::new(W + 1, H).save(dir.join("images_1/05.png")).unwrap();
    image::GrayImage::new(W, H).save(dir.join("images_1/06.png")).unwrap();
    image::RgbaImage::new(W, H).save(dir.join("images_1/07.png")).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["images_1/05.png: size: 9x6, but 00.png is 8x6"]);
    assert_problem(&r, &["images_1/06.png: colour type: L8, not 8-bit RGB"]);
    assert!(r.warnings().any(|w| w.contains("1 of 10 images are RGBA (e.g. 07.png)")), "{r}");
    // Not zero-padded: 10.png sorts before 2.png.
    let dir = fixture("padding");
    std::fs::rename(dir.join("images_1/02.png"), dir.join("images_1/2.png")).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["images_1/: 2.png: sorts after 09.png by name but its number is not larger"]);
}

#[test]
fn optional_files_are_checked_when_present() {
    let dir = fixture("optional");
    std::fs::write(dir.join("dataset.toml"), "# manifest\n").unwrap();
    std::fs::create_dir_all(dir.join("images_sharp_1")).unwrap();
    for i in 0..N - 1 {
        image::RgbImage::new(W, H).save(dir.join(format!("images_sharp_1/{i:02}.png"))).unwrap();
    }
    let map = NpyArray::new(&[H as usize, W as usize], vec![0.5f32; (W * H) as usize]).unwrap();
    let bad_map = NpyArray::new(&[W as usize, H as usize], vec![0.5f32; (W * H) as usize]).unwrap();
    write_npz(&dir.join("ev_map.npz"), &[("inv_mapx", map), ("inv_mapy", bad_map)]).unwrap();
    let r = check(&dir);
    // a manifest is read strictly: a comment alone lacks every field
    assert_problem(&r, &["dataset.toml: manifest: [event_model] has no c_pos"]);
    assert_problem(&r, &["images_sharp_1/: file names: differ from images_1/: missing [\"09.png\"]"]);
    assert_problem(&r, &["ev_map.npz: inv_mapy: shape [8, 6], expected (H, W) = Some([6, 8])"]);
    assert_eq!(r.problems().count(), 3, "{r}");
}

/// Write `events.h5` column by column (any dtypes), as other tools would.
fn write_columns(dir: &Path, write: impl FnOnce(&rust_hdf5::H5File)) {
    let path = dir.join("events.h5");
    let _ = std::fs::remove_file(&path);
    let file = rust_hdf5::H5File::create(&path).unwrap();
    write(&file);
    file.close().unwrap();
}

fn column<T: rust_hdf5::H5Type>(file: &rust_hdf5::H5File, name: &str, data: &[T]) {
    file.new_dataset::<T>().shape([data.len()]).create(name).unwrap().write_raw(data).unwrap();
}

#[test]
fn bad_event_columns_are_reported() {
    let dir = fixture("columns");
    let n = 20usize;
    let t: Vec<i64> = (0..n as i64).map(|i| 2_000_000 + 1000 * i).collect();
    // Other dtypes than ours are fine: int32 x, uint8 y, uint8 p in {0, 1}, float64 t.
    write_columns(&dir, |f| {
        column(f, "x", &vec![1i32; n]);
        column(f, "y", &vec![2u8; n]);
        column(f, "t", &t.iter().map(|&t| t as f64).collect::<Vec<_>>());
        column(f, "p", &(0..n).map(|i| (i % 2) as u8).collect::<Vec<_>>());
    });
    let r = check(&dir);
    assert!(r.is_ok(), "{r}");
    assert_eq!(r.events.as_ref().map(|e| (e.on, e.off, e.unit)), Some((10, 10, EventsUnit::Ns)));
    // p = 2, OFF as both 0 and -1, y = H, x of the wrong length.
    write_columns(&dir, |f| {
        column(f, "x", &vec![1i64; n + 1]);
        column(f, "y", &vec![H as u16; n]);
        column(f, "t", &t);
        column(f, "p", &(0..n).map(|i| [0i8, -1, 1, 2][i % 4]).collect::<Vec<_>>());
    });
    let r = check(&dir);
    assert_problem(&r, &["events.h5: x, y, t, p: lengths differ (x 21, y 20, t 20, p 20)"]);
    write_columns(&dir, |f| {
        column(f, "x", &vec![1i64; n]);
        column(f, "y", &vec![H as u16; n]);
        column(f, "t", &t);
        column(f, "p", &(0..n).map(|i| [0i8, -1, 1, 2][i % 4]).collect::<Vec<_>>());
    });
    let r = check(&dir);
    assert_problem(&r, &["events.h5: p: 5 event(s) are neither 0/1 nor -1/+1, the first at index 3 (p = 2)"]);
    assert_problem(&r, &["events.h5: p: mixes 0 and -1 for OFF"]);
    assert_problem(&r, &["events.h5: y: 20 event(s) are not in 0 <= y < 6, the first at index 0 (6)"]);
    // A missing column.
    write_columns(&dir, |f| {
        column(f, "x", &vec![1u16; n]);
        column(f, "y", &vec![1u16; n]);
        column(f, "t", &t);
    });
    assert_problem(&check(&dir), &["events.h5: p: dataset missing"]);
}

#[test]
fn a_truncated_png_is_a_problem_not_a_pass() {
    let dir = fixture("truncated-png");
    let path = dir.join("images_1/03.png");
    let bytes = std::fs::read(&path).unwrap();
    // the header (IHDR) survives, the image data stream is cut
    std::fs::write(&path, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let r = check(&dir);
    assert_problem(&r, &["images_1/03.png", "cannot be decoded"]);
    let _ = std::fs::remove_dir_all(&dir);
}
