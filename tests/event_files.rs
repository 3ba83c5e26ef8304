//! Event files as the tools people use read them: every writer (Ev-DeblurNeRF and DSEC `.h5`,
//! RPG text, `.npz`) writes a known event list, and the Mitsuba venv's Python opens each file
//! with h5py / numpy and checks dtypes, shapes, values and DSEC's `ms_to_idx` against
//! `searchsorted`. Then `evsim events` (its library function, [`run_on_frames`]) runs on five
//! small PNG frames, and its input errors are checked to leave no output.
//!
//! Without a Python that imports h5py (`tests/mitsuba/setup.sh` installs it) the Python checks
//! print SKIPPED, or fail when `EVBLUR_REQUIRE_MITSUBA=1`.

use std::path::{Path, PathBuf};

use evblur_tests::{python_with, run_python, temp_dir};
use glam::Vec3;
use simulator::base::image::Image;
use simulator::events::sinks::{EventWriter, H5Layout, SinkKind, VizConfig};
use simulator::events::{run_on_frames, Event, EventConfig, EventSink, FramesJob, TimeUnit};
use simulator::image_io::write_image;

/// `n` time-sorted events with ties, both polarities and ~29 ms of span from `t0` ns; the Python
/// check rebuilds the same list.
fn known_events(n: usize, t0: i64) -> Vec<Event> {
    (0..n)
        .map(|i| Event {
            x: (i * 7 % 640) as u16,
            y: (i * 13 % 480) as u16,
            t_ns: t0 + (i as i64 / 3) * 17_333,
            p: if i % 5 < 2 { 1 } else { -1 },
        })
        .collect()
}

const CHECK_FILES: &str = r#"
import sys, h5py, numpy as np
d, n, t0 = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
i = np.arange(n)
x = (i * 7 % 640).astype(np.uint16)
y = (i * 13 % 480).astype(np.uint16)
t = (t0 + (i // 3) * 17333).astype(np.int64)
p = np.where(i % 5 < 2, 1, -1).astype(np.int8)
on = (p > 0).astype(np.uint8)

def same(a, b, dtype, what):
    a = np.asarray(a)
    assert a.dtype == np.dtype(dtype), (what, a.dtype, dtype)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    assert np.array_equal(a, b), (what, a[:5], b[:5])

with h5py.File(d + "/nerf.h5", "r") as f:
    assert sorted(f.keys()) == ["p", "t", "x", "y"], list(f.keys())
    for k, v, dt in [("x", x, "u2"), ("y", y, "u2"), ("t", t, "i8"), ("p", p, "i1")]:
        assert f[k].compression == "gzip" and f[k].chunks is not None, k
        same(f[k][:], v, dt, "nerf " + k)

with h5py.File(d + "/dsec.h5", "r") as f:
    assert sorted(f.keys()) == ["events", "ms_to_idx", "t_offset"], list(f.keys())
    assert f["t_offset"].shape == () and f["t_offset"].dtype == np.int64
    off = int(f["t_offset"][()])
    t_us = t // 1000
    assert off == t_us[0], (off, t_us[0])
    e = f["events"]
    rel = (t_us - off).astype(np.uint32)
    for k, v, dt in [("x", x, "u2"), ("y", y, "u2"), ("t", rel, "u4"), ("p", on, "u1")]:
        assert e[k].compression == "gzip", k
        same(e[k][:], v, dt, "dsec " + k)
    tr = e["t"][:].astype(np.int64)
    want = np.searchsorted(tr, np.arange(tr[-1] // 1000 + 1) * 1000, side="left").astype(np.uint64)
    assert len(want) > 20
    same(f["ms_to_idx"][:], want, "u8", "ms_to_idx")
    # DSEC's use: the events of ms [a, b) are t[ms_to_idx[a]:ms_to_idx[b]].
    a, b = 3, 7
    sl = tr[want[a]:want[b]]
    assert sl.min() >= 1000 * a and sl.max() < 1000 * b

z = np.load(d + "/events.npz")
assert sorted(z.files) == ["p", "t", "x", "y"], z.files
for k, v, dt in [("x", x, "u2"), ("y", y, "u2"), ("t", t, "i8"), ("p", p, "i1")]:
    same(z[k], v, dt, "npz " + k)

rows = [l.split(" ") for l in open(d + "/events.txt").read().splitlines()]
assert len(rows) == n and all(len(r) == 4 for r in rows)
assert all(len(r[0].split(".")[1]) == 9 for r in rows)
ts = np.array([int(r[0].split(".")[0]) * 10**9 + int(r[0].split(".")[1]) for r in rows], dtype=np.int64)
same(ts, t, "i8", "txt t")
same(np.array([int(r[1]) for r in rows], dtype=np.uint16), x, "u2", "txt x")
same(np.array([int(r[2]) for r in rows], dtype=np.uint16), y, "u2", "txt y")
same(np.array([int(r[3]) for r in rows], dtype=np.uint8), on, "u1", "txt p")
assert np.allclose(np.loadtxt(d + "/events.txt")[:, 0], t / 1e9, rtol=0, atol=1e-9)
print("ok")
"#;

#[test]
fn event_files_read_back_in_python() {
    let dir = temp_dir("event-files", "formats");
    let (n, t0) = (5000, 1_234_567_890);
    let events = known_events(n, t0);
    for (name, layout) in [
        ("nerf.h5", Some(H5Layout::Nerf)),
        ("dsec.h5", Some(H5Layout::Dsec)),
        ("events.npz", None),
        ("events.txt", None),
    ] {
        let path = dir.join(name);
        let mut sink = EventWriter::create(&path, SinkKind::from_path(&path, layout).unwrap()).unwrap();
        for batch in events.chunks(700) {
            sink.push(batch).unwrap();
        }
        assert_eq!(sink.finish().unwrap(), n as u64, "{name}");
    }
    let mut names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["dsec.h5", "events.npz", "events.txt", "nerf.h5"], "no temporary files remain");
    let Some(py) = python_with("h5py, numpy", "event_files_read_back_in_python") else { return };
    run_python(&py, CHECK_FILES, &[dir.display().to_string(), n.to_string(), t0.to_string()]);
}

/// Five 40x24 sRGB PNG frames of a sine grating moving 2 px per frame, and their times (1 ms
/// apart, in seconds) in `timestamps.txt`.
fn write_frames(dir: &Path) -> (PathBuf, PathBuf) {
    let frames = dir.join("frames");
    for k in 0..5 {
        let mut img = Image::new(40, 24);
        for (i, px) in img.pixels.iter_mut().enumerate() {
            let x = (i % 40) as f32;
            *px = Vec3::splat(0.5 + 0.4 * (std::f32::consts::TAU * (x - 2.0 * k as f32) / 16.0).sin());
        }
        write_image(&img, &frames.join(format!("frame_{k:03}.png"))).unwrap();
    }
    let ts = dir.join("timestamps.txt");
    std::fs::write(&ts, "0.010\n0.011\n0.012\n0.013\n0.014\n").unwrap();
    (frames, ts)
}

fn job(frames: &Path, timestamps: &Path, out: &Path, kind: SinkKind) -> FramesJob {
    FramesJob {
        frames: frames.to_path_buf(),
        timestamps: timestamps.to_path_buf(),
        unit: TimeUnit::S,
        linear_input: false,
        out: out.to_path_buf(),
        kind,
        config: EventConfig::default(),
        viz: None,
    }
}

const CHECK_CLI: &str = r#"
import sys, h5py, numpy as np
path, n = sys.argv[1], int(sys.argv[2])
with h5py.File(path, "r") as f:
    t, x, y, p = (f[k][:] for k in "txyp")
assert len(t) == n and len(x) == n and len(y) == n and len(p) == n
assert np.all(np.diff(t) >= 0), "sorted by time"
assert t[0] > 10_000_000 and t[-1] <= 14_000_000, (t[0], t[-1])
assert x.max() < 40 and y.max() < 24 and set(np.unique(p)) <= {-1, 1}
print("ok")
"#;

#[test]
fn evsim_events_runs_on_png_frames() {
    let dir = temp_dir("event-files", "cli");
    let (frames, ts) = write_frames(&dir);
    let out = dir.join("out/events.h5");
    let s = run_on_frames(&job(&frames, &ts, &out, SinkKind::NerfH5), None).unwrap();
    assert_eq!((s.frames, s.width, s.height), (5, 40, 24));
    assert!(s.on > 0 && s.off > 0, "{s:?}");
    assert!(s.max_change_c > 0.0);
    assert!(std::fs::metadata(&out).unwrap().len() > 0);

    // The other formats agree on the count.
    for name in ["e.npz", "e.txt"] {
        let p = dir.join(name);
        let s2 = run_on_frames(&job(&frames, &ts, &p, SinkKind::from_path(&p, None).unwrap()), None).unwrap();
        assert_eq!(s2.on + s2.off, s.on + s.off, "{name}");
    }
    let lines = std::fs::read_to_string(dir.join("e.txt")).unwrap().lines().count() as u64;
    assert_eq!(lines, s.on + s.off);

    if let Some(py) = python_with("h5py, numpy", "evsim_events_runs_on_png_frames") {
        run_python(&py, CHECK_CLI, &[out.display().to_string(), (s.on + s.off).to_string()]);
    }
}

#[test]
fn evsim_events_with_viz_writes_the_event_file_and_the_pictures() {
    let dir = temp_dir("event-files", "cli-viz");
    let (frames, ts) = write_frames(&dir);
    let out = dir.join("e.txt");
    let viz_dir = dir.join("viz");
    let viz = VizConfig { window_ns: 1_000_000, rate_bin_ns: 500_000, ..VizConfig::new(&viz_dir) };
    let s = run_on_frames(&FramesJob { viz: Some(viz), ..job(&frames, &ts, &out, SinkKind::Text) }, None).unwrap();
    let v = s.viz.expect("a viz summary");

    // The tee gave both sinks every event.
    assert_eq!((v.on, v.off), (s.on, s.off));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count() as u64, s.on + s.off);
    // Events lie in (10, 14] ms: 4 or 5 windows of 1 ms from the 10 ms one, images 40x24.
    assert_eq!(v.t_first_window_ns, Some(10_000_000));
    assert!((4..=5).contains(&v.windows), "{v:?}");
    for i in 0..v.windows {
        let img = simulator::events::frames::read_frame(&viz_dir.join(format!("events_{i:06}.png")), true).unwrap();
        assert_eq!((img.width, img.height), (40, 24));
    }
    let csv = std::fs::read_to_string(viz_dir.join("event_rate.csv")).unwrap();
    let total: u64 = csv.lines().skip(1).map(|l| l.split(',').nth(3).unwrap().parse::<u64>().unwrap()).sum();
    assert_eq!(total, s.on + s.off);
    assert!(v.peak_rate_hz >= v.mean_rate_hz && v.mean_rate_hz > 0.0, "{v:?}");
}

#[test]
fn evsim_events_input_errors_name_the_file_and_leave_no_output() {
    let dir = temp_dir("event-files", "cli-errors");
    let (frames, ts) = write_frames(&dir);
    let out = dir.join("events.h5");
    let err = |j: &FramesJob| format!("{:#}", run_on_frames(j, None).unwrap_err());

    // Wrong number of timestamps.
    let short = dir.join("short.txt");
    std::fs::write(&short, "0.010\n0.011\n").unwrap();
    let e = err(&job(&frames, &short, &out, SinkKind::NerfH5));
    assert!(e.contains("short.txt") && e.contains("2 timestamps") && e.contains("5 frames"), "{e}");

    // Non-increasing timestamps.
    let back = dir.join("back.txt");
    std::fs::write(&back, "0.010\n0.011\n0.011\n0.013\n0.014\n").unwrap();
    let e = err(&job(&frames, &back, &out, SinkKind::NerfH5));
    assert!(e.contains("back.txt: line 3") && e.contains("strictly increase"), "{e}");

    // A frame of another size, found mid-run: the partial output is removed.
    write_image(&Image::new(8, 8), &frames.join("frame_003.png")).unwrap();
    let e = err(&job(&frames, &ts, &out, SinkKind::DsecH5));
    assert!(e.contains("frame_003.png") && e.contains("same size"), "{e}");

    // A 16-bit frame among 8-bit ones (the same size): another quantisation, refused by name.
    let (w, h) = image::image_dimensions(frames.join("frame_000.png")).unwrap();
    image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(w, h, image::Rgb([30000, 30000, 30000]))
        .save(frames.join("frame_003.png"))
        .unwrap();
    let e = err(&job(&frames, &ts, &out, SinkKind::NerfH5));
    assert!(e.contains("frame_003.png: is a 16-bit PNG") && e.contains("is a 8-bit PNG"), "{e}");

    // An unreadable frame.
    std::fs::write(frames.join("frame_003.png"), b"not a png").unwrap();
    let e = err(&job(&frames, &ts, &out, SinkKind::Npz));
    assert!(e.contains("frame_003.png") && e.contains("cannot read"), "{e}");

    let left: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    assert!(!left.iter().any(|n| n.contains("events") || n.contains("tmp")), "{left:?}");
}
