//! Loader tests on a dataset in the style of the public real-camera (Ev-DeblurCDAVIS) scenes,
//! written from Rust: float32-rounded poses, the last 5 views sharp, event times in us, float
//! (rectified) coordinates, uint8 polarity {0, 1}, `ev_map.npz`.

use std::path::{Path, PathBuf};

use glam::{DQuat, DVec3};
use simulator::dataset::check::{EventsUnit, TestViewPolicy};
use simulator::npy::{write_npy, write_npz, NpyArray};
use simulator::trajectory::{LlffCamera, Pose};

use super::*;

const W: u32 = 8;
const H: u32 = 6;
const N: usize = 10;
const M: usize = 100;

/// The LLFF row at `s` in [0, 1], rounded to float32 as the public files are.
fn row(s: f64) -> [f64; 17] {
    let pose = Pose {
        rotation: DQuat::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), 0.8 * s - 0.3),
        position: DVec3::new(2.0 * s, 1.0, 5.0 - s),
    };
    LlffCamera::new(pose, W, H, 0.7, 0.5, 20.0).unwrap().to_row().map(|v| v as f32 as f64)
}

/// Raw sensor pixel -> rectified float coordinate.
fn rectify(u: u32, v: u32) -> (f32, f32) {
    (u as f32 + 0.25 + 0.01 * v as f32, v as f32 - 0.125)
}

/// Writes the dataset; returns its folder.
fn write(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evblur-loader-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("images_1")).unwrap();
    for i in 0..N {
        let img =
            ::image::RgbImage::from_fn(W, H, |x, y| ::image::Rgb([(x * 30) as u8, (y * 40) as u8, (i * 20) as u8]));
        img.save(dir.join(format!("images_1/{i:02}.png"))).unwrap();
    }
    // the last 5 views sharp (start == end)
    let mid: Vec<f64> = (0..N).map(|i| 5000.0 + 9000.0 * i as f64).collect();
    let half = |i: usize| if i + 5 >= N { 0.0 } else { 2000.0 };
    let start: Vec<f64> = (0..N).map(|i| mid[i] - half(i)).collect();
    let end: Vec<f64> = (0..N).map(|i| mid[i] + half(i)).collect();
    let rows: Vec<[f64; 17]> = mid.iter().map(|&t| row((t - 1000.0) / 99_000.0)).collect();
    write_npz(
        &dir.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid)),
            ("timestamps_start", NpyArray::vector(start)),
            ("timestamps_end", NpyArray::vector(end)),
        ],
    )
    .unwrap();
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    let all_t: Vec<f64> = (0..M).map(|k| 1000.0 + 1000.0 * k as f64).collect();
    let all_rows: Vec<[f64; 17]> = all_t.iter().map(|&t| row((t - 1000.0) / 99_000.0)).collect();
    write_npy(&dir.join("all_poses_bounds.npy"), &NpyArray::f64_2d(&all_rows)).unwrap();
    write_npy(&dir.join("all_timestamps.npy"), &NpyArray::vector(all_t)).unwrap();
    // events: rectified float coordinates, int64 us times, uint8 polarity
    let n = 300;
    let raw: Vec<(u32, u32)> = (0..n).map(|i| ((i * 3 % W as usize) as u32, (i * 7 % H as usize) as u32)).collect();
    let x: Vec<f32> = raw.iter().map(|&(u, v)| rectify(u, v).0).collect();
    let y: Vec<f32> = raw.iter().map(|&(u, v)| rectify(u, v).1).collect();
    let t: Vec<i64> = (0..n as i64).map(|i| 1000 + 300 * i).collect();
    let p: Vec<u8> = (0..n).map(|i| (i % 3 == 0) as u8).collect();
    let file = rust_hdf5::H5File::create(dir.join("events.h5")).unwrap();
    file.new_dataset::<f32>().shape([n]).create("x").unwrap().write_raw(&x).unwrap();
    file.new_dataset::<f32>().shape([n]).create("y").unwrap().write_raw(&y).unwrap();
    file.new_dataset::<i64>().shape([n]).create("t").unwrap().write_raw(&t).unwrap();
    file.new_dataset::<u8>().shape([n]).create("p").unwrap().write_raw(&p).unwrap();
    file.close().unwrap();
    let map = |f: fn((f32, f32)) -> f32| {
        let v: Vec<f32> = (0..H).flat_map(|v| (0..W).map(move |u| f(rectify(u, v)))).collect();
        NpyArray::new(&[H as usize, W as usize], v).unwrap()
    };
    write_npz(&dir.join("ev_map.npz"), &[("inv_mapx", map(|c| c.0)), ("inv_mapy", map(|c| c.1))]).unwrap();
    dir
}

fn cleanup(dir: &Path) {
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn real_camera_style_dataset_loads() {
    let dir = write("cdavis");
    // the unit is a choice: given as us, and auto-detected as us
    for unit in [EventsUnit::Us, EventsUnit::Auto] {
        let d = Dataset::load(&dir, &LoadOptions { events_unit: unit, ..LoadOptions::default() }).unwrap();
        assert_eq!(d.split.policy, TestViewPolicy::Last5);
        assert_eq!(d.split.test, vec![5, 6, 7, 8, 9]);
        assert!(d.views[3].sharp.is_none());
        let ev = &d.events;
        assert_eq!(ev.file_unit, EventsUnit::Us);
        assert!(ev.float_coordinates);
        assert_eq!((ev.len(), ev.dropped), (300, 0));
        assert_eq!(ev.t_us[1], 1300.0);
        assert_eq!(&ev.polarity[..4], &[1, -1, -1, 1]);
        // raw pixel (u, v) repeats every lcm(8/gcd(3,8), 6/gcd(7,6)) = 24 events
        for i in 0..ev.len() {
            assert_eq!(ev.successor(i), (i + 24 < ev.len()).then_some(i + 24), "event {i}");
        }
        let m = d.ev_map.as_ref().unwrap();
        assert_eq!((m.width, m.height), (W, H));
        let (u, v) = (3, 2);
        assert_eq!((m.inv_mapx[(v * W + u) as usize], m.inv_mapy[(v * W + u) as usize]), rectify(u, v));
        // float32-rounded rotations are accepted and the poses are unit quaternions
        assert!(d.views.iter().all(|v| (v.pose.rotation.length() - 1.0).abs() < 1e-12));
    }
    // the default detects microseconds too (it used to read every file as ns: a us file then
    // trained on events squeezed into the trajectory's first thousandth)
    assert_eq!(LoadOptions::default().events_unit, EventsUnit::Auto);
    assert_eq!(Dataset::load(&dir, &LoadOptions::default()).unwrap().events.file_unit, EventsUnit::Us);
    // an ev_map of the wrong shape is refused by the check, naming the file
    let bad = NpyArray::new(&[W as usize, H as usize], vec![0f32; (W * H) as usize]).unwrap();
    write_npz(&dir.join("ev_map.npz"), &[("inv_mapx", bad.clone()), ("inv_mapy", bad)]).unwrap();
    let e = Dataset::load(&dir, &LoadOptions { events_unit: EventsUnit::Us, ..LoadOptions::default() })
        .unwrap_err()
        .to_string();
    assert!(e.contains("ev_map.npz"), "{e}");
    cleanup(&dir);
}
