//! `evsim bench esim`: `evsim events` against esim_py (ESIM's C++ simulator with Python
//! bindings, uzh-rpg/rpg_vid2e) on one folder of 8-bit PNG frames.
//!
//! The folder is `--frames` (with `--timestamps`), or by default 200 frames of 240x180 of a
//! moving texture written as 8-bit grey PNGs (1 ms apart) into a temporary folder. Both sides
//! use esim_py's settings: C = 0.2 both ways, log eps 1e-3, no refractory period, the 8-bit levels
//! taken as linear intensity (`--linear-input`). Runs alternate, ours first:
//! - ours: the whole `evsim events` process (this executable), start to exit, writing the
//!   default Ev-DeblurNeRF `.h5`;
//! - esim_py: only its `generateFromFolder` call, timed inside Python (`tests/esim/run.py`;
//!   interpreter start and import excluded), which returns the events in memory.
//!
//! Prints the median of each and the ratio, then both event counts and how many pixels' ON and
//! OFF counts agree within 1. esim_py comes from `$EVBLUR_ESIM_PYTHON` or
//! `~/.cache/evblur/esim-venv/bin/python` (made by `tests/esim/setup.sh`); without it only our
//! time is printed.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};
use clap::Args;

use simulator::base::image::Image;
use simulator::events::frames::{list_frames, read_frame, read_timestamps};
use simulator::events::{Event, EventConfig, EventSimulator, EventSink, TimeUnit};

use crate::bench::{bench_frame, bench_texture, median};

/// Options of `evsim bench esim`.
#[derive(Args, Debug)]
pub struct EsimBench {
    /// Folder of frames (only frames: esim_py reads every file in it); default: generated.
    #[arg(long, requires = "timestamps")]
    pub frames: Option<PathBuf>,
    /// Frame times, seconds, one per line (with --frames).
    #[arg(long, requires = "frames")]
    pub timestamps: Option<PathBuf>,
    /// Generated frames.
    #[arg(long, default_value_t = 200)]
    pub count: usize,
    /// Generated frame width.
    #[arg(long, default_value_t = 240)]
    pub width: u32,
    /// Generated frame height.
    #[arg(long, default_value_t = 180)]
    pub height: u32,
    /// Timed runs of each (the median is reported).
    #[arg(long, default_value_t = 7)]
    pub repeats: usize,
}

/// The esim_py venv's Python, if there is one.
fn esim_python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVBLUR_ESIM_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let home = std::env::var_os("HOME")?;
    Some(Path::new(&home).join(".cache/evblur/esim-venv/bin/python")).filter(|p| p.exists())
}

/// `tests/esim/run.py` of this source tree.
fn esim_driver() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/esim/run.py")
}

/// Write `count` grey 8-bit PNG frames of the moving texture and their times (1 ms apart) under
/// `dir`; returns (frames folder, timestamps file).
fn write_frames(dir: &Path, count: usize, width: u32, height: u32) -> Result<(PathBuf, PathBuf)> {
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).with_context(|| format!("{}: cannot create", frames.display()))?;
    let tex = bench_texture(width, height, count);
    let mut img = Image::new(width, height);
    let mut times = String::new();
    for k in 0..count {
        bench_frame(&tex, &mut img, k);
        let grey = image::GrayImage::from_fn(width, height, |x, y| {
            let p = img.pixels[(y * width + x) as usize];
            image::Luma([(p.dot(simulator::events::LUMA_709).clamp(0.0, 1.0) * 255.0).round() as u8])
        });
        let path = frames.join(format!("{k:06}.png"));
        grey.save(&path).with_context(|| format!("{}: cannot write", path.display()))?;
        times.push_str(&format!("{:.6}\n", k as f64 * 1e-3));
    }
    let stamps = dir.join("timestamps.txt");
    std::fs::write(&stamps, times).with_context(|| format!("{}: cannot write", stamps.display()))?;
    Ok((frames, stamps))
}

/// One `evsim events` process over the folder; its wall time, seconds.
fn time_ours(frames: &Path, stamps: &Path, out: &Path) -> Result<f64> {
    let exe = std::env::current_exe().context("cannot find this executable")?;
    let start = Instant::now();
    let run = Command::new(exe)
        .args(["events", "--linear-input", "--frames"])
        .arg(frames)
        .arg("--timestamps")
        .arg(stamps)
        .arg("--out")
        .arg(out)
        .output()
        .context("cannot run evsim events")?;
    let s = start.elapsed().as_secs_f64();
    ensure!(run.status.success(), "evsim events failed: {}", String::from_utf8_lossy(&run.stderr));
    Ok(s)
}

/// What one esim_py run reported (`run.py`'s JSON line).
#[derive(serde::Deserialize)]
struct EsimRun {
    seconds: f64,
    events: u64,
}

/// One esim_py call over the folder (per-pixel counts to `counts`, if given).
fn time_esim(py: &Path, frames: &Path, stamps: &Path, size: (u32, u32), counts: Option<&Path>) -> Result<EsimRun> {
    let cfg = EventConfig::default();
    let run = Command::new(py)
        .arg(esim_driver())
        .arg(frames)
        .arg(stamps)
        .args([cfg.c_pos.to_string(), cfg.c_neg.to_string(), cfg.log_eps.to_string()])
        .args([size.0.to_string(), size.1.to_string()])
        .arg(counts.map_or_else(|| PathBuf::from("-"), Path::to_path_buf))
        .output()
        .with_context(|| format!("cannot run {}", py.display()))?;
    ensure!(run.status.success(), "esim_py failed: {}", String::from_utf8_lossy(&run.stderr));
    let line = String::from_utf8_lossy(&run.stdout);
    serde_json::from_str(line.trim()).with_context(|| format!("esim_py printed no seconds/events line: {line}"))
}

/// Per-pixel ON and OFF counts, in the layout of `run.py`'s (ON plane, then OFF plane).
struct PixelCounts {
    width: usize,
    plane: usize,
    counts: Vec<u32>,
}

impl EventSink for PixelCounts {
    fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
        for e in events {
            let off = usize::from(e.p < 0) * self.plane;
            self.counts[off + e.y as usize * self.width + e.x as usize] += 1;
        }
        Ok(())
    }
}

/// Our per-pixel counts, from an in-process run of the model over the same frames and settings.
fn our_counts(frames: &Path, stamps: &Path) -> Result<(PixelCounts, (u32, u32))> {
    let paths = list_frames(frames)?;
    let times = read_timestamps(stamps, TimeUnit::S)?;
    ensure!(times.len() == paths.len(), "{}: one time per frame needed", stamps.display());
    let first = read_frame(&paths[0], true)?;
    let (w, h) = (first.width, first.height);
    let mut sim = EventSimulator::new(EventConfig::default(), w, h)?;
    let plane = w as usize * h as usize;
    let mut sink = PixelCounts { width: w as usize, plane, counts: vec![0; 2 * plane] };
    sim.step(&first, times[0], &mut sink)?;
    for (path, &t) in paths.iter().zip(&times).skip(1) {
        sim.step(&read_frame(path, true)?, t, &mut sink)?;
    }
    Ok((sink, (w, h)))
}

/// `evsim bench esim`.
pub fn esim_bench(b: &EsimBench) -> Result<()> {
    ensure!(b.repeats >= 1, "--repeats must be at least 1");
    let dir = std::env::temp_dir().join(format!("evsim-bench-esim-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let result = run_bench(b, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn run_bench(b: &EsimBench, dir: &Path) -> Result<()> {
    let (frames, stamps) = match (&b.frames, &b.timestamps) {
        (Some(f), Some(t)) => (f.clone(), t.clone()),
        _ => write_frames(dir, b.count, b.width, b.height)?,
    };
    let n = list_frames(&frames)?.len();
    let (ours_counts, size) = our_counts(&frames, &stamps)?;
    let counts = &ours_counts.counts;
    let our_events: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    println!(
        "esim bench: {n} frames {}x{} from {}, C 0.2, log eps 1e-3, no refractory period, {} repeats, {} threads",
        size.0,
        size.1,
        frames.display(),
        b.repeats,
        rayon::current_num_threads()
    );
    let py = esim_python();
    if py.is_none() {
        println!("  esim_py not installed (tests/esim/setup.sh PATH/TO/rpg_vid2e/esim_py): our time only");
    }
    let out = dir.join("events.h5");
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    let mut esim_events = 0;
    for _ in 0..b.repeats {
        ours.push(time_ours(&frames, &stamps, &out)?);
        if let Some(py) = &py {
            let run = time_esim(py, &frames, &stamps, size, None)?;
            esim_events = run.events;
            theirs.push(run.seconds);
        }
    }
    let per_frame = |s: f64| s * 1e3 / n as f64;
    let ours_s = median(&ours);
    println!("  {:<34} {:>8} {:>10}", "", "median s", "ms/frame");
    println!("  {:<34} {:>8.3} {:>10.3}", "evsim events (process, writes .h5)", ours_s, per_frame(ours_s));
    let Some(py) = py else { return Ok(()) };
    let theirs_s = median(&theirs);
    println!("  {:<34} {:>8.3} {:>10.3}", "esim_py generateFromFolder (call)", theirs_s, per_frame(theirs_s));
    println!("  speed-up: {:.2}x esim_py's speed", theirs_s / ours_s);
    // per-pixel agreement
    let esim_counts_path = dir.join("esim-counts.bin");
    time_esim(&py, &frames, &stamps, size, Some(&esim_counts_path))?;
    let bytes =
        std::fs::read(&esim_counts_path).with_context(|| format!("{}: cannot read", esim_counts_path.display()))?;
    if bytes.len() != counts.len() * 4 {
        bail!("esim_py's counts have {} bytes, expected {}", bytes.len(), counts.len() * 4);
    }
    let esim_counts: Vec<u32> = bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let px = counts.len() / 2;
    let within = (0..px)
        .filter(|&i| counts[i].abs_diff(esim_counts[i]) <= 1 && counts[px + i].abs_diff(esim_counts[px + i]) <= 1)
        .count();
    println!(
        "  events: ours {our_events}, esim_py {esim_events} ({:+.3}%); pixels whose ON and OFF counts agree within 1: {:.2}%",
        (our_events as f64 / esim_events.max(1) as f64 - 1.0) * 100.0,
        within as f64 * 100.0 / px as f64
    );
    Ok(())
}
