//! `evbench sweep --data-only`: simulate each point's datasets (sharing one frame cache, so
//! exposure and event settings re-use the rendered frames) and report what the data looks like,
//! without training:
//!
//! - events per second and per pixel (from the manifest's counts, the frame clock and the size);
//! - the mean and largest blur displacement of the blurry views (pixels; the simulator's
//!   [`blur_stats`], every 4th pixel);
//! - the PSNR of the blurry training views and of their EDI reconstructions (the trainer's
//!   event double integral, 8 bins, the dataset's thresholds and response) against the sharp
//!   frames.
//!
//! Written to `<results>/sweep/<stem>.data.{md,csv,png}` (a `.`: a scene may be named `data`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use simulator::dataset::blur::blur_stats;
use simulator::dataset::manifest::DatasetManifest;
use simulator::exposure::CameraResponse;
use simulator::render::accel::Accel;
use trainer::data::{Dataset, LoadOptions};

use super::plan::SweepPlan;
use super::SWEEP_DIR;
use crate::error::BenchError;
use crate::matrix::{SceneSource, Shard};
use crate::plot::{self, Figure, Series};
use crate::run::dataset;

/// EDI bins (the `edi-nerf` preset's).
pub const EDI_BINS: usize = 8;

/// Statistics of one point's dataset of one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct DataStats {
    /// The point's values, printed (`exposure_ms = 5`).
    pub point: String,
    /// The value of the first axis (the plot's x).
    pub x: f64,
    /// The point's value index per axis.
    pub index: Vec<usize>,
    /// The scene.
    pub scene: String,
    /// The dataset folder.
    pub dir: PathBuf,
    /// Events (ON + OFF).
    pub events: u64,
    /// Events per second of the whole sequence (Hz).
    pub events_per_second: f64,
    /// Events per pixel of the whole sequence.
    pub events_per_pixel: f64,
    /// Mean blur displacement of the blurry views (px).
    pub blur_mean_px: f64,
    /// Largest blur displacement (px).
    pub blur_max_px: f64,
    /// Mean PSNR of the blurry training views against their sharp frames (dB).
    pub blurry_psnr: Option<f64>,
    /// Mean PSNR of their EDI reconstructions (dB).
    pub edi_psnr: Option<f64>,
    /// Frames rendered for this dataset now (0: all from the frame cache, or it existed).
    pub frames_rendered: usize,
    /// Seconds to simulate it now (0 if it existed).
    pub simulate_seconds: f64,
    /// Seconds for the statistics (blur, EDI).
    pub stats_seconds: f64,
}

/// Simulates every point's datasets (as needed) and measures them, in point order; `on_point`
/// sees each result as it comes.
pub fn run(plan: &SweepPlan, mut on_point: impl FnMut(&DataStats)) -> Result<Vec<DataStats>, BenchError> {
    if !plan.axes.iter().any(|a| matches!(a.setting, super::plan::Setting::Dataset(_))) {
        return Err(BenchError::config(
            &plan.file,
            "sweep.axes",
            "no axis is a dataset.* setting, so every point has the same dataset; --data-only measures \
             datasets (run the sweep without it to train)",
        ));
    }
    let frames = plan.results.join(super::FRAMES_DIR);
    let mut out = Vec::new();
    for (p, point) in plan.points.iter().enumerate() {
        let text = plan.point_text(p);
        for scene in &point.plan.scenes {
            let SceneSource::Simulate(sim) = &scene.source else {
                return Err(BenchError::config(
                    &plan.file,
                    format!("scenes: {}", scene.name),
                    "a data-only sweep simulates its datasets; give the scene as `scene = \"…/scene.toml\"`",
                ));
            };
            let start = Instant::now();
            let (dir, summary) = dataset::ensure(scene, &plan.results, Shard::ALL, Some(&frames))?;
            let simulate_seconds = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let mut stats = measure(sim, &dir, &plan.results)?;
            stats.point = text.clone();
            stats.x = plan.axes[0].values[point.index[0]].x;
            stats.index = point.index.clone();
            stats.scene = scene.name.clone();
            stats.frames_rendered = summary.as_ref().map_or(0, |s| s.frames_rendered + s.sharp_rendered);
            stats.simulate_seconds = if summary.is_some() { simulate_seconds } else { 0.0 };
            stats.stats_seconds = start.elapsed().as_secs_f64();
            on_point(&stats);
            out.push(stats);
        }
    }
    Ok(out)
}

/// The statistics of the complete dataset `dir` simulated from `sim` (EDI images cached under
/// `<results>/sweep/edi/`).
fn measure(sim: &simulator::dataset::Plan, dir: &Path, results: &Path) -> Result<DataStats, BenchError> {
    let manifest = dir.join("dataset.toml");
    let m = DatasetManifest::read(dir)
        .map_err(|e| BenchError::results(&manifest, format!("{e}; delete the dataset folder to re-simulate it")))?
        .ok_or_else(|| BenchError::results(&manifest, "missing; delete the dataset folder to re-simulate it"))?;
    let (events, frames, period) = (m.events, m.frames, m.frame_period_ns);
    // the settings the dataset was simulated with (its plan)
    let thresholds = (sim.events.c_pos as f64, sim.events.c_neg as f64);
    let gamma = match sim.config.response {
        CameraResponse::Gamma { gamma } => Some(gamma as f64),
        CameraResponse::Linear => Some(1.0),
        // the EDI inverts a power law; an sRGB dataset gets no EDI score rather than a wrong one
        CameraResponse::Srgb => None,
    };
    let pixels = (sim.config.width as f64) * (sim.config.height as f64);
    let seconds = frames as f64 * period as f64 * 1e-9;

    let accel = Accel::build(&sim.scene.mesh, sim.config.bvh);
    let blur = blur_stats(sim, &accel, 4)?;

    let data = Dataset::load(dir, &LoadOptions::default())?;
    let train = data.split.train.clone();
    let hash = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let cache = results.join(SWEEP_DIR).join("edi").join(hash);
    let score = match gamma {
        Some(gamma) => {
            let edi = trainer::events::edi::precompute(&data, &train, EDI_BINS, thresholds, gamma, &cache)?;
            trainer::events::edi::psnr_vs_sharp(&data, &train, &edi)
        }
        None => None,
    };
    Ok(DataStats {
        point: String::new(),
        x: 0.0,
        index: Vec::new(),
        scene: String::new(),
        dir: dir.to_owned(),
        events,
        events_per_second: events as f64 / seconds,
        events_per_pixel: events as f64 / pixels,
        blur_mean_px: blur.mean,
        blur_max_px: blur.max,
        blurry_psnr: score.map(|s| s.blurry_psnr),
        edi_psnr: score.map(|s| s.edi_psnr),
        frames_rendered: 0,
        simulate_seconds: 0.0,
        stats_seconds: 0.0,
    })
}

impl std::fmt::Display for DataStats {
    /// One line: the point, the scene and every statistic, with the simulation's cost.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} {}: {:.3e} events/s, {:.1} events/px, blur {:.2} px (max {:.2}), blurry {} dB, EDI {} dB; \
             {} frames rendered, simulated in {:.1} s, measured in {:.1} s",
            self.point,
            self.scene,
            self.events_per_second,
            self.events_per_pixel,
            self.blur_mean_px,
            self.blur_max_px,
            opt(self.blurry_psnr),
            opt(self.edi_psnr),
            self.frames_rendered,
            self.simulate_seconds,
            self.stats_seconds
        )
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |v| format!("{v:.2}"))
}

/// The statistics as a Markdown table.
pub fn markdown(stats: &[DataStats]) -> String {
    let mut s = String::from(
        "| point | scene | events/s | events/px | blur mean (px) | blur max (px) | blurry PSNR (dB) | EDI PSNR (dB) | frames rendered | simulate (s) |\n\
         |---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for d in stats {
        s.push_str(&format!(
            "| {} | {} | {:.3e} | {:.1} | {:.2} | {:.2} | {} | {} | {} | {:.1} |\n",
            d.point,
            d.scene,
            d.events_per_second,
            d.events_per_pixel,
            d.blur_mean_px,
            d.blur_max_px,
            opt(d.blurry_psnr),
            opt(d.edi_psnr),
            d.frames_rendered,
            d.simulate_seconds
        ));
    }
    s
}

/// The statistics as CSV (no timings, so equal data give equal bytes).
pub fn csv(stats: &[DataStats]) -> String {
    let mut s = String::from(
        "point,scene,events,events_per_second,events_per_pixel,blur_mean_px,blur_max_px,blurry_psnr,edi_psnr\n",
    );
    let field = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for d in stats {
        s.push_str(&format!(
            "\"{}\",{},{},{:.1},{:.3},{:.4},{:.4},{},{}\n",
            d.point.replace('"', "\"\""),
            d.scene,
            d.events,
            d.events_per_second,
            d.events_per_pixel,
            d.blur_mean_px,
            d.blur_max_px,
            field(d.blurry_psnr),
            field(d.edi_psnr)
        ));
    }
    s
}

/// EDI and blurry PSNR (solid) and events per pixel (dashed) vs the first axis, per scene (and
/// value of the second axis).
pub fn figure(plan: &SweepPlan, stats: &[DataStats]) -> Figure {
    let second = |d: &DataStats| match (plan.axes.get(1), d.index.get(1)) {
        (Some(a), Some(&j)) => format!(" ({})", a.values[j].text),
        _ => String::new(),
    };
    let mut left: Vec<Series> = Vec::new();
    let mut right: Vec<Series> = Vec::new();
    let push = |set: &mut Vec<Series>, label: String, p: (f64, f64)| match set.iter_mut().find(|s| s.label == label) {
        Some(s) => s.points.push(p),
        None => set.push(Series { label, points: vec![p] }),
    };
    for d in stats {
        let key = format!("{}{}", d.scene, second(d));
        push(&mut left, format!("{key}: EDI"), (d.x, d.edi_psnr.unwrap_or(f64::NAN)));
        push(&mut left, format!("{key}: blurry"), (d.x, d.blurry_psnr.unwrap_or(f64::NAN)));
        push(&mut right, format!("{key}: events"), (d.x, d.events_per_pixel));
    }
    let axis0 = &plan.axes[0];
    Figure {
        title: match plan.axes.get(1) {
            Some(a) => format!("{}: data; (value) = {}", plan.title, a.label),
            None => format!("{}: data", plan.title),
        },
        x_label: axis0.label.clone(),
        left_label: "PSNR vs sharp (dB, solid)".into(),
        left,
        right_label: Some("events per pixel (dashed)".into()),
        right,
        x_ticks: axis0.values.iter().map(|v| (v.x, v.text.clone())).collect(),
    }
}

/// Writes `<results>/sweep/<stem>.data.{md,csv,png}`; returns the files.
pub fn write(plan: &SweepPlan, stats: &[DataStats]) -> Result<Vec<PathBuf>, BenchError> {
    let out = plan.results.join(SWEEP_DIR);
    std::fs::create_dir_all(&out)
        .map_err(|e| BenchError::results(&out, format!("cannot create ({e}); check the results folder")))?;
    let stem = plan.file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "sweep".into());
    let mut written = Vec::new();
    for (ext, text) in [("md", markdown(stats)), ("csv", csv(stats))] {
        let path = out.join(format!("{stem}.data.{ext}"));
        simulator::image_io::write_atomic(&path, text.as_bytes())
            .map_err(|e| BenchError::results(&path, format!("{e:#}")))?;
        written.push(path);
    }
    let png = out.join(format!("{stem}.data.png"));
    plot::write_png(&figure(plan, stats), &png)?;
    written.push(png);
    Ok(written)
}
