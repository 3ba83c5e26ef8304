//! Loader tests on a dataset written by our simulator (`scenes/tiny` at 48x32, 1 spp).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::Vec2;
use simulator::dataset::check::EventsUnit;
use simulator::dataset::{write_dataset, Overrides, Plan, RunOptions};
use simulator::npy::{write_npy, NpyArray};

use super::*;

fn scene_file() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/tiny/scene.toml")
}

fn plan() -> Plan {
    let o = Overrides::default().with("width", 48).with("height", 32).with("spp", 1).with("sharp_spp", 1);
    Plan::resolve(&scene_file(), &o).unwrap()
}

/// The simulated dataset, written once per test run.
fn dataset_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("evblur-loader-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        write_dataset(&plan(), &RunOptions { out: dir.join("tiny"), ..RunOptions::default() }).unwrap();
        dir.join("tiny")
    })
}

fn load() -> Dataset {
    Dataset::load(dataset_dir(), &LoadOptions::default()).unwrap()
}

/// A copy of the dataset in a fresh folder named `name`.
fn copy(name: &str) -> PathBuf {
    let to = dataset_dir().parent().unwrap().join(name);
    let _ = std::fs::remove_dir_all(&to);
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        std::fs::create_dir_all(to.join(&rel)).unwrap();
        for e in std::fs::read_dir(dataset_dir().join(&rel)).unwrap() {
            let e = e.unwrap();
            let r = rel.join(e.file_name());
            if e.file_type().unwrap().is_dir() {
                stack.push(r);
            } else {
                std::fs::copy(e.path(), to.join(&r)).unwrap();
            }
        }
    }
    to
}

#[test]
fn images_split_and_timestamps() {
    let d = load();
    assert_eq!(d.views.len(), 9);
    assert_eq!((d.intrinsics.width, d.intrinsics.height), (48, 32));
    for v in &d.views {
        assert_eq!((v.image.width, v.image.height, v.image.data.len()), (48, 32, 48 * 32 * 3));
        assert!(v.image.data.iter().all(|&x| (0.0..=1.0).contains(&x)));
        // our writer adds the sharp version of every view
        assert_eq!(v.sharp.as_ref().map(|s| (s.width, s.height)), Some((48, 32)));
        assert!(v.t_start_us <= v.t_mid_us && v.t_mid_us <= v.t_end_us);
        assert!(v.near > 0.0 && v.far > v.near);
    }
    assert_eq!(d.split.policy, simulator::dataset::check::TestViewPolicy::Every8);
    assert_eq!(d.split.test, vec![0, 8]);
    assert_eq!(d.split.train, vec![1, 2, 3, 4, 5, 6, 7]);
    for (i, v) in d.views.iter().enumerate() {
        assert_eq!(v.is_sharp(), d.split.test.contains(&i), "view {i}");
    }
    // the sharp test views equal their sharp versions (same render, same encoding)
    assert_eq!(d.views[0].sharp.as_ref().unwrap().data, d.views[0].image.data);
    // scale: the smallest near lands at 1 / 0.75
    let min_near = d.views.iter().map(|v| v.near).fold(f64::INFINITY, f64::min);
    assert!((min_near - 1.0 / 0.75).abs() < 1e-12, "{min_near}");
    assert!(d.ev_map.is_none());
}

#[test]
fn converted_poses_reproduce_the_simulator_camera() {
    let (d, p) = (load(), plan());
    for (view, spec) in d.views.iter().zip(&p.views) {
        let truth = p.trajectory.pose_at(spec.mid_ns).unwrap();
        let back = d.transform.undo(&view.pose);
        assert!((back.position - truth.position).length() < 1e-9, "{} vs {}", back.position, truth.position);
        let cam = truth.camera(p.yfov as f32);
        for (i, j) in [(0, 0), (47, 0), (13, 20), (47, 31)] {
            // loader ray in the recentred, scaled world, rotated back to the file's world
            let r = d.intrinsics.ray(&view.pose, i, j);
            let dir = (d.transform.avg_rotation * r.direction).normalize().as_vec3();
            let want = cam.direction(Vec2::new(i as f32 + 0.5, j as f32 + 0.5), 48, 32);
            assert!((dir - want).length() < 1e-5, "view {} pixel ({i}, {j}): {dir} vs {want}", view.name);
        }
    }
}

#[test]
fn interpolation_reproduces_the_dense_trajectory_and_is_smooth() {
    let (d, p) = (load(), plan());
    let times = d.trajectory.times_us().to_vec();
    assert_eq!(times.len(), p.clock.n_frames);
    for (k, &t) in times.iter().enumerate() {
        let got = d.transform.undo(&d.trajectory.pose_at(t).unwrap());
        let truth = p.trajectory.pose_at(p.clock.time_ns(k)).unwrap();
        assert!((got.position - truth.position).length() < 1e-9, "frame {k}");
        assert!(got.rotation.dot(truth.rotation).abs() > 1.0 - 1e-12, "frame {k}");
    }
    // between frames: close to the simulator's own trajectory (a smooth curve sampled at 1 kHz)
    let (mut max_dist, mut max_angle) = (0.0f64, 0.0f64);
    for k in 0..times.len() - 1 {
        let t = 0.5 * (times[k] + times[k + 1]);
        let got = d.transform.undo(&d.trajectory.pose_at(t).unwrap());
        let truth = p.trajectory.pose_at((t * 1e3).round() as i64).unwrap();
        let angle = got.rotation.angle_between(truth.rotation);
        max_angle = max_angle.max(angle);
        max_dist = max_dist.max((got.position - truth.position).length());
    }
    eprintln!("max between-frame error vs the simulator: {max_dist:e} m, {max_angle:e} rad");
    // the simulator slerps between its (sparser) key poses, so its rotation has kinks at keys that
    // the frame-to-frame slerp rounds off: about 1e-4 rad there (0.01 px at this focal length)
    assert!(max_dist < 1e-5 && max_angle < 5e-4);
    // smooth: second differences at a 0.1 ms step stay small and change little across frames
    let pos = |t: f64| d.trajectory.pose_at(t).unwrap().position;
    let (lo, hi) = d.trajectory.range_us();
    let h = 100.0;
    let (mut prev, mut max_acc, mut max_jump) = (None::<glam::DVec3>, 0.0f64, 0.0f64);
    let mut t = lo + h;
    while t + h <= hi {
        let acc = (pos(t + h) - 2.0 * pos(t) + pos(t - h)) / (h * h);
        if let Some(a) = prev {
            max_jump = max_jump.max((acc - a).length());
        }
        max_acc = max_acc.max(acc.length());
        prev = Some(acc);
        t += h;
    }
    eprintln!("acceleration: max {max_acc:e}, largest change per 0.1 ms {max_jump:e} (scaled units / us^2)");
    assert!(max_acc > 0.0 && max_jump < 0.1 * max_acc);
}

#[test]
fn events_lie_in_the_trajectory_and_successors_are_next_at_the_pixel() {
    let d = load();
    let ev = &d.events;
    assert!(ev.len() > 100, "{} events", ev.len());
    assert_eq!(ev.file_unit, EventsUnit::Ns);
    assert!(!ev.float_coordinates);
    let (lo, hi) = d.trajectory.range_us();
    assert!(ev.t_us.iter().all(|&t| t >= lo && t <= hi));
    assert!(ev.t_us.windows(2).all(|w| w[0] <= w[1]));
    assert!(ev.polarity.iter().all(|&p| p == 1 || p == -1));
    // brute force: per pixel, the events in order
    let mut per_pixel: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for i in 0..ev.len() {
        per_pixel.entry((ev.x[i] as u32, ev.y[i] as u32)).or_default().push(i);
    }
    for list in per_pixel.values() {
        for w in list.windows(2) {
            assert_eq!(ev.successor(w[0]), Some(w[1]));
            assert!(ev.t_us[w[1]] >= ev.t_us[w[0]]);
        }
        assert_eq!(ev.successor(*list.last().unwrap()), None);
    }
    assert_eq!(ev.with_successor().len(), ev.len() - per_pixel.len());
    // every event's ray exists at its time
    assert!(d.ray_at(ev.t_us[0], ev.x[0] as u32, ev.y[0] as u32).is_some());
}

#[test]
fn dropped_events_outside_the_trajectory() {
    // the check refuses such files, so test the reader on its own with a narrower range
    let d = load();
    let (lo, hi) = d.trajectory.range_us();
    let mid = 0.5 * (lo + hi);
    let ev = Events::read(dataset_dir(), EventsUnit::Ns, (lo, mid), (48, 32), 1000).unwrap();
    assert_eq!(ev.len() as u64 + ev.dropped, d.events.len() as u64);
    assert!(ev.dropped > 0 && ev.t_us.iter().all(|&t| t <= mid));
}

#[test]
fn broken_datasets_fail_with_the_file_named() {
    // missing file
    let dir = copy("missing-poses");
    std::fs::remove_file(dir.join("poses_bounds.npy")).unwrap();
    let e = Dataset::load(&dir, &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("poses_bounds.npy") && e.contains("missing"), "{e}");
    // wrong shape
    let dir = copy("short-times");
    let t: Vec<f64> = (0..10).map(|k| 1000.0 + k as f64).collect();
    write_npy(&dir.join("all_timestamps.npy"), &NpyArray::vector(t)).unwrap();
    let e = Dataset::load(&dir, &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("all_timestamps.npy"), "{e}");
    // truncated event file
    let dir = copy("truncated-events");
    let bytes = std::fs::read(dir.join("events.h5")).unwrap();
    std::fs::write(dir.join("events.h5"), &bytes[..bytes.len() / 2]).unwrap();
    let e = Dataset::load(&dir, &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("events.h5"), "{e}");
    // a missing image
    let dir = copy("missing-image");
    std::fs::remove_file(dir.join("images_1/03.png")).unwrap();
    let e = Dataset::load(&dir, &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("images_1"), "{e}");
    // wrong event unit: microseconds put the ns events far outside the trajectory
    let e = Dataset::load(dataset_dir(), &LoadOptions { events_unit: EventsUnit::Us, ..LoadOptions::default() })
        .unwrap_err()
        .to_string();
    assert!(e.contains("events.h5") && e.contains("outside the dense trajectory"), "{e}");
    // not a folder
    let e = Dataset::load(&dir.join("nope"), &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("nope"), "{e}");
    for name in ["missing-poses", "short-times", "truncated-events", "missing-image"] {
        let _ = std::fs::remove_dir_all(dataset_dir().parent().unwrap().join(name));
    }
}

#[test]
fn methods_without_events_take_the_datasets_thresholds_for_edi() {
    let dir = copy("thresholds");
    let manifest = dir.join("dataset.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let text = text.replacen("c_pos = 0.20000000298023224", "c_pos = 0.375", 1).replacen(
        "c_neg = 0.20000000298023224",
        "c_neg = 0.3125",
        1,
    );
    std::fs::write(&manifest, text).unwrap();
    let data = Dataset::load(&dir, &LoadOptions::default()).unwrap();
    // (values exact in f32: the manifest stores the simulator's f32 thresholds)
    assert_eq!(crate::events::loss::dataset_thresholds(&data), Some([0.375, 0.3125]));
    let scale = crate::presets::Scale::Cpu;
    let preset = |name: &str| (crate::presets::preset(name).unwrap().build)(scale);
    // edi-nerf has no events section: its EDI images use the dataset's thresholds
    let edi = preset("edi-nerf");
    assert!(edi.events.is_none());
    assert_eq!(crate::method::event_thresholds(&edi, &data), [0.375, 0.3125]);
    // a training threshold (the mismatch study) wins over the dataset's
    let mut ours = preset("ev-deblurnerf");
    ours.events.as_mut().unwrap().threshold = Some([0.25, 0.25]);
    assert_eq!(crate::method::event_thresholds(&ours, &data), [0.25, 0.25]);
    ours.events.as_mut().unwrap().threshold = None;
    assert_eq!(crate::method::event_thresholds(&ours, &data), [0.375, 0.3125]);
}

#[test]
fn a_damaged_or_foreign_manifest_is_refused_not_ignored() {
    let dir = copy("damaged-manifest");
    let manifest = dir.join("dataset.toml");
    let good = std::fs::read_to_string(&manifest).unwrap();
    // one more in the line `key = N` (a count that no longer matches events.h5)
    let bump = |text: &str, key: &str| -> String {
        let line = text.lines().find(|l| l.starts_with(&format!("{key} = "))).unwrap();
        let n: u64 = line.rsplit(' ').next().unwrap().parse().unwrap();
        text.replacen(line, &format!("{key} = {}", n + 1), 1)
    };
    let cases = [
        // a broken line appended: it used to be read as no manifest, and the thresholds as 0.2
        (format!("{good}c_pos = \n"), "not valid TOML"),
        (good.replacen("[event_model]\n", "[event_model]\nthreshold = 0.5\n", 1), "unknown field `threshold`"),
        (bump(&bump(&good, "events"), "events_on"), "events.h5 has"),
        (good.replacen("\nviews = ", "\nviews = 1", 1), "images_1/ has"),
    ];
    for (text, want) in cases {
        std::fs::write(&manifest, &text).unwrap();
        let e = Dataset::load(&dir, &LoadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("dataset.toml") && e.contains(want), "{want}: {e}");
    }
    // without a manifest (a public dataset) the dataset loads
    std::fs::remove_file(&manifest).unwrap();
    assert!(Dataset::load(&dir, &LoadOptions::default()).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}
