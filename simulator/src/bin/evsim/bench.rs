//! `evsim bench render`: the render benchmark. Prints
//! 1. Cornell box 600x400, max depth 5, 64 spp: median wall time and M samples/s of our two
//!    samplers and, in the same run, of Mitsuba 3 (`llvm_ad_rgb`, JIT warm-up excluded) through
//!    the reference-check driver; each image's relMSE against a 1024-spp Mitsuba ground truth
//!    (cached); the efficiency `1 / (time * relMSE)` and its ratio to Mitsuba's, i.e. how much
//!    faster we reach equal error. Times are medians of `--repeats` runs, alternating renderers.
//! 2. A 1 M-triangle scene: BVH build time and closest-hit M rays/s (primary and diffuse rays)
//!    for every obvhs build preset.
//!
//! `evsim bench dataset [SCENE]`: writes the scene's whole dataset (default `scenes/cbox`, the
//! paper's settings) into a fresh temporary folder and cache, and prints per stage the wall
//! time, frames/s and peak memory, and the total (the stages after rendering run beside the
//! renders, so their times overlap), then the thread time the lazily filled caches took (radiance
//! cache lattices, surface, shadow and glossy grids) and the time threads waited for another
//! thread's fill.
//!
//! `evsim bench frames [SCENE]`: the frame stage of a dataset on a short segment: renders the
//! temporal window around `--frames` consecutive frames (at the scene's dataset settings), then
//! prints per frame the medians of rasterising, shading, the temporal window and the spatial
//! filter, and the frame stage of the whole sequence they project to. Quicker than `bench
//! dataset` for comparing two builds or settings side by side.
//!
//! `evsim bench events`: the event model over 1000 frames of 600x400 of a synthetic moving
//! texture (1000 FPS), events into a counting sink, once ideal and once with every
//! non-ideality on. Prints the model time (frame generation excluded), the wall time, M pixel
//! updates/s and M events/s.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use simulator::base::image::Image;
use simulator::base::sampling::{cosine_hemisphere, Frame, Rng};
use simulator::events::{
    CountingSink, EventConfig, EventSimulator, MismatchMode, NoiseConfig, Photoreceptor, Refractory, RefractoryMode,
    ThresholdMismatch,
};
use simulator::export::export_mitsuba;
use simulator::image_io::read_exr;
use simulator::reference::compare::rel_mse;
use simulator::reference::mitsuba;
use simulator::render::accel::{Accel, BvhPreset};
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;
use simulator::render::sampler::SamplerKind;
use simulator::scene::{self, Camera, TriangleMesh};

/// Which benchmark to run.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Cornell box throughput vs Mitsuba, and BVH build/trace on a 1 M-triangle scene.
    Render(RenderBench),
    /// Event-model throughput on a synthetic moving texture (ideal, then all noise on).
    Events(EventsBench),
    /// A whole default-size dataset (1 s at 1000 FPS, 600x400, default spp): time, frames/s and
    /// peak memory per stage.
    Dataset(DatasetBench),
    /// Per-frame cost of a dataset's frames (raster, shading, temporal window, spatial filter)
    /// on a short segment.
    Frames(FramesBench),
    /// `evsim events` against esim_py (ESIM's C++ simulator) on one folder of 8-bit PNG frames.
    Esim(crate::bench_esim::EsimBench),
}

/// Options of `evsim bench frames`.
#[derive(Args, Debug)]
pub struct FramesBench {
    /// The dataset scene.
    #[arg(default_value = "scenes/factory/scene.toml")]
    pub scene: PathBuf,
    /// Frames timed (after the first, which fills the window and is reported apart).
    #[arg(long, default_value_t = 6)]
    pub frames: usize,
    /// First frame of the segment (ms from the trajectory's start; default: its middle).
    #[arg(long)]
    pub start_ms: Option<f64>,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: crate::dataset_cmd::OverrideArgs,
}

/// Options of `evsim bench dataset`.
#[derive(Args, Debug)]
pub struct DatasetBench {
    /// The dataset scene.
    #[arg(default_value = "scenes/cbox/scene.toml")]
    pub scene: PathBuf,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: crate::dataset_cmd::OverrideArgs,
}

/// Options of `evsim bench events`.
#[derive(Args, Debug)]
pub struct EventsBench {
    /// Frames per run (at 1000 FPS).
    #[arg(long, default_value_t = 1000)]
    pub frames: usize,
    /// Frame width in pixels.
    #[arg(long, default_value_t = 600)]
    pub width: u32,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 400)]
    pub height: u32,
}

/// Options of `evsim bench render`.
#[derive(Args, Debug)]
pub struct RenderBench {
    /// The Cornell box render description.
    #[arg(long, default_value = "scenes/cornell/scene.toml")]
    pub scene: PathBuf,
    /// Timed repetitions per renderer (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Skip the Mitsuba comparison.
    #[arg(long)]
    pub no_mitsuba: bool,
    /// Only run the BVH part (no Cornell box, no Mitsuba).
    #[arg(long)]
    pub bvh_only: bool,
    /// Triangles in the BVH scene.
    #[arg(long, default_value_t = 1_000_000)]
    pub triangles: usize,
}

/// Run a benchmark.
pub fn run(what: BenchCommand) -> Result<()> {
    match what {
        BenchCommand::Render(b) => render_bench(&b),
        BenchCommand::Events(b) => events_bench(&b),
        BenchCommand::Dataset(b) => dataset_bench(&b),
        BenchCommand::Frames(b) => frames_bench(&b),
        BenchCommand::Esim(b) => crate::bench_esim::esim_bench(&b),
    }
}

fn frames_bench(b: &FramesBench) -> Result<()> {
    use simulator::dataset::sequence::SequenceRenderer;
    use simulator::dataset::Plan;
    let plan = Plan::resolve(&b.scene, &b.overrides.resolve())?;
    let (c, n) = (&plan.config, plan.clock.n_frames);
    anyhow::ensure!(b.frames >= 1, "--frames must be at least 1");
    let start = match b.start_ms {
        Some(ms) => plan.clock.frame_at((ms * 1e6).round() as i64).context("--start-ms is not a frame time")?,
        None => n / 2,
    };
    anyhow::ensure!(start + b.frames < n, "the segment ends after the sequence's {n} frames");
    println!(
        "frames bench: {} frames {}..={} of {} ({}x{}, {} spp{}, {} feature rays, radius {} stride {}, cache {}), {} threads",
        b.scene.display(),
        start,
        start + b.frames,
        n,
        c.width,
        c.height,
        c.spp,
        if c.spp_max > c.spp {
            format!(" (adaptive up to {}, target {})", c.spp_max, c.adaptive_variance)
        } else {
            String::new()
        },
        c.feature_spp,
        if c.denoise { c.temporal_radius } else { 0 },
        c.temporal_stride,
        c.radiance_cache,
        rayon::current_num_threads()
    );
    let t = Instant::now();
    let renderer = Renderer::with_preset(&plan.scene, c.bvh);
    println!("  BVH build {:.2} s", t.elapsed().as_secs_f64());
    let mut seq = SequenceRenderer::new(&plan, &renderer, c.spp);
    let t = Instant::now();
    seq.frame(start)?;
    println!("  first frame (window of {} renders, cache filling): {:.1} s", seq.renders, t.elapsed().as_secs_f64());
    let pose = plan.trajectory.pose_at(plan.clock.time_ns(start))?;
    let settings = simulator::dataset::writer::render_settings(&plan, &pose, start, false);
    let cache = renderer.radiance_cache(&settings);
    let filled_first = cache.as_ref().map(|c| c.filled());
    // per timed frame: raster, shading, window, spatial filter, all (seconds)
    let mut rows: Vec<[f64; 5]> = vec![];
    for k in start + 1..=start + b.frames {
        let before = (seq.raster_time, seq.render_time, seq.gather_time, seq.denoise_time);
        let t = Instant::now();
        seq.frame(k)?;
        let all = t.elapsed().as_secs_f64();
        let raster = (seq.raster_time - before.0).as_secs_f64();
        let render = (seq.render_time - before.1).as_secs_f64();
        let gather = (seq.gather_time - before.2).as_secs_f64();
        let filter = (seq.denoise_time - before.3).as_secs_f64();
        rows.push([raster, render - raster, gather, filter - gather, all]);
    }
    if let (Some(cache), Some((sides0, points0))) = (cache, filled_first) {
        let (sides, points) = cache.filled();
        println!(
            "  radiance cache: {sides} triangle sides filled, {points} lattice points ({} sides, {} points during the timed frames)",
            sides - sides0,
            points - points0
        );
    }
    if c.shading == simulator::dataset::settings::Shading::SurfaceCache {
        let surface = renderer.surface_cache(&settings);
        let ((sides, points), (shadows, shadow_points)) = (surface.filled(), surface.shadows_filled());
        println!("  surface cache: {sides} triangle sides, {points} points; shadow grids: {shadows} sides, {shadow_points} points");
        let (keys, glossy_sides, glossy_points) = surface.glossy_filled();
        if keys > 0 {
            println!("  glossy grids: {keys} keyframes held, {glossy_sides} triangle sides, {glossy_points} points");
        }
        // the last frame again, every grid it reads filled: the shading alone
        let k = start + b.frames;
        let pose = plan.trajectory.pose_at(plan.clock.time_ns(k))?;
        let again = simulator::dataset::writer::render_settings(&plan, &pose, k, false);
        let t = Instant::now();
        simulator::dataset::writer::render_frame(&renderer, &again, &plan);
        println!("  the last frame again (grids filled): {:.3} s", t.elapsed().as_secs_f64());
    }
    print_fill_times(&renderer.fill_times());
    let col = |i: usize| median(&rows.iter().map(|r| r[i]).collect::<Vec<_>>());
    let mean = |i: usize| rows.iter().map(|r| r[i]).sum::<f64>() / rows.len().max(1) as f64;
    println!("  per frame ({} frames):   median     mean", rows.len());
    for (i, name) in ["raster", "shading", "temporal window", "spatial filter", "frame"].iter().enumerate() {
        println!("    {:<16} {:7.3} s {:7.3} s", name, col(i), mean(i));
    }
    if c.spp_max > c.spp {
        let px = (seq.renders * (c.width * c.height) as usize) as f64;
        println!("  adaptive sampling: {:.2} samples per pixel on average", seq.samples as f64 / px);
    }
    println!(
        "  {n} frames at the median rate: {:.1} min; at the mean rate (grids filled on the way included): {:.1} min",
        col(4) * n as f64 / 60.0,
        mean(4) * n as f64 / 60.0
    );
    Ok(())
}

/// Samples per pixel of the Mitsuba ground truth the errors are measured against.
const GT_SPP: u32 = 1024;

pub(crate) fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn render_bench(b: &RenderBench) -> Result<()> {
    if b.bvh_only {
        return bvh_bench(b.triangles);
    }
    let scene = scene::load(&b.scene)?;
    let camera = scene.cameras.first().cloned().context("the Cornell scene has no camera")?;
    let st = RenderSettings { spp: b.spp, ..RenderSettings::new(camera) };
    let samples = (st.width * st.height * st.spp) as f64;
    let renderer = Renderer::new(&scene);
    renderer.render(&RenderSettings { spp: 1, ..st.clone() }, None); // warm caches
    let python = if b.no_mitsuba { None } else { mitsuba::python() };
    let dir = std::env::temp_dir().join(format!("evblur-bench-{}", std::process::id()));
    let gt = match &python {
        Some(py) => {
            export_mitsuba(&scene, &st, &dir)?;
            eprintln!("ground truth: Mitsuba at {GT_SPP} spp (cached after the first run)...");
            Some(mitsuba::ground_truth(py, &dir, GT_SPP, 1000, "llvm_ad_rgb")?.0)
        }
        None => None,
    };
    // each contender: its name, the time of every repetition and the error of its last image
    let samplers = [SamplerKind::Sobol, SamplerKind::Independent];
    let mut rows: Vec<(String, Vec<f64>, Option<f64>)> =
        samplers.iter().map(|s| (format!("evblur {s:?}").to_lowercase(), vec![], None)).collect();
    if python.is_some() {
        rows.push(("mitsuba".into(), vec![], None));
    }
    for rep in 0..b.repeats {
        for (k, &sampler) in samplers.iter().enumerate() {
            let s = RenderSettings { sampler, seed: rep as u64, ..st.clone() };
            let t = Instant::now();
            let img = renderer.render(&s, None);
            rows[k].1.push(t.elapsed().as_secs_f64());
            rows[k].2 = gt.as_ref().map(|gt| rel_mse(&img, gt));
        }
        if let Some(py) = &python {
            let out = dir.join("mitsuba_bench.exr");
            let run = mitsuba::run(py, &dir.join("scene.json"), st.spp, 1 + rep as u32, "llvm_ad_rgb", &out)?;
            rows[2].0 = format!("mitsuba {}", run.variant);
            rows[2].1.push(run.render_s);
            rows[2].2 = gt.as_ref().map(|gt| read_exr(&out).map(|img| rel_mse(&img, gt))).transpose()?;
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "cornell box {}x{}, max depth {}, {} spp, {} threads, median of {} runs",
        st.width,
        st.height,
        st.max_depth,
        st.spp,
        rayon::current_num_threads(),
        b.repeats
    );
    println!("  {:<22} {:>8} {:>12} {:>11} {:>12}", "renderer", "time s", "M samples/s", "relMSE", "efficiency");
    let effs: Vec<Option<f64>> = rows.iter().map(|(_, t, e)| e.map(|e| 1.0 / (median(t) * e))).collect();
    let sci = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3e}"));
    for ((name, times, err), eff) in rows.iter().zip(&effs) {
        let t = median(times);
        println!("  {:<22} {:>8.3} {:>12.2} {:>11} {:>12}", name, t, samples / t / 1e6, sci(*err), sci(*eff));
    }
    if python.is_some() {
        let t_m = median(&rows[2].1);
        println!(
            "  samples/s vs mitsuba: sobol {:.2}x, independent {:.2}x",
            t_m / median(&rows[0].1),
            t_m / median(&rows[1].1)
        );
        if let (Some(e0), Some(e1), Some(em)) = (effs[0], effs[1], effs[2]) {
            println!(
                "  speed at equal error vs mitsuba (efficiency ratio): sobol {:.2}x, independent {:.2}x",
                e0 / em,
                e1 / em
            );
        }
    } else {
        println!("  mitsuba: not measured (no venv: run ./tests/run.sh once, or set EVBLUR_MITSUBA_PYTHON)");
    }
    bvh_bench(b.triangles)
}

/// A closed, bumpy sphere of about `n` triangles (lat-long grid, radius modulated).
fn bumpy_sphere(n: usize) -> TriangleMesh {
    let rows = ((n as f64 / 4.0).sqrt() as usize).max(4);
    let cols = 2 * rows;
    let mut m = TriangleMesh::default();
    for i in 0..=rows {
        let theta = std::f32::consts::PI * i as f32 / rows as f32;
        for j in 0..=cols {
            let phi = std::f32::consts::TAU * j as f32 / cols as f32;
            let r = 1.0 + 0.05 * (13.0 * theta).sin() * (17.0 * phi).cos();
            let p = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * r;
            m.positions.push(p);
            m.normals.push(p.normalize());
            m.uvs.push(Vec2::ZERO);
        }
    }
    let w = cols as u32 + 1;
    for i in 0..rows as u32 {
        for j in 0..cols as u32 {
            let (a, b, c, d) = (i * w + j, i * w + j + 1, (i + 1) * w + j, (i + 1) * w + j + 1);
            m.indices.push([a, c, b]);
            m.indices.push([b, c, d]);
            m.material.extend([0, 0]);
        }
    }
    m
}

fn bvh_bench(n: usize) -> Result<()> {
    let mesh = bumpy_sphere(n);
    let cam = Camera::look_at(Vec3::new(0.0, 0.5, 3.0), Vec3::ZERO, Vec3::Y, 0.8);
    let (w, h) = (1024u32, 1024u32);
    println!(
        "BVH: bumpy sphere, {} triangles; rays are closest-hit, {} threads",
        mesh.len(),
        rayon::current_num_threads()
    );
    println!("  {:<14} {:>9} {:>16} {:>16}", "preset", "build s", "primary Mray/s", "diffuse Mray/s");
    for preset in BvhPreset::ALL {
        let accel = Accel::build(&mesh, preset);
        let build = accel.build_time.as_secs_f64();
        // primary rays, then one cosine-distributed bounce from each primary hit
        let origin = cam.origin();
        let t = Instant::now();
        let hits: Vec<Option<(Vec3, Vec3)>> = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let (accel, cam, mesh) = (&accel, &cam, &mesh);
                (0..w).map(move |x| {
                    let d = cam.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), w, h);
                    accel.intersect(origin, d, 0.0, f32::INFINITY).map(|hit| {
                        let [a, b, c] = mesh.corners(hit.prim as usize);
                        let n = (b - a).cross(c - a).normalize();
                        (origin + d * hit.t, if n.dot(d) > 0.0 { -n } else { n })
                    })
                })
            })
            .collect();
        let t_primary = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let bounced: usize = hits
            .par_iter()
            .enumerate()
            .filter_map(|(i, hit)| hit.map(|(p, n)| (i, p, n)))
            .map(|(i, p, n)| {
                let mut rng = Rng::new(i as u64, 9);
                let d = Frame::from_normal(n).to_world(cosine_hemisphere(rng.next_2d()));
                accel.intersect(p + n * 1e-4, d, 0.0, f32::INFINITY).is_some() as usize
            })
            .count();
        let t_diffuse = t.elapsed().as_secs_f64();
        let n_bounce = hits.iter().filter(|h| h.is_some()).count();
        std::hint::black_box(bounced);
        println!(
            "  {:<14} {:>9.3} {:>16.2} {:>16.2}",
            format!("{preset:?}"),
            build,
            (w * h) as f64 / t_primary / 1e6,
            n_bounce as f64 / t_diffuse / 1e6
        );
    }
    Ok(())
}

/// Texture drift per frame in pixels (x, y).
const DRIFT: (f32, f32) = (0.3, 0.1);

/// A smooth colour texture with some sharp edges, large enough for the drift of `frames`.
pub(crate) fn bench_texture(w: u32, h: u32, frames: usize) -> Image {
    let tw = w + (DRIFT.0 * frames as f32) as u32 + 2;
    let th = h + (DRIFT.1 * frames as f32) as u32 + 2;
    let mut tex = Image::new(tw, th);
    tex.pixels.par_chunks_mut(tw as usize).enumerate().for_each(|(y, row)| {
        let y = y as f32;
        for (x, p) in row.iter_mut().enumerate() {
            let x = x as f32;
            let smooth = 0.5 + 0.25 * (0.05 * x + 0.03 * y).sin() + 0.2 * (0.011 * x - 0.07 * y).cos();
            let checks = if ((x / 37.0) as i32 + (y / 29.0) as i32) % 2 == 0 { 1.0 } else { 0.35 };
            let v = (smooth * checks).clamp(0.01, 1.0);
            *p = Vec3::new(v, v * (0.8 + 0.2 * (0.02 * x).sin()), v * 0.9);
        }
    });
    tex
}

/// Frame `k`: the texture shifted by `k * DRIFT`, bilinearly interpolated.
pub(crate) fn bench_frame(tex: &Image, out: &mut Image, k: usize) {
    let (ox, oy) = (DRIFT.0 * k as f32, DRIFT.1 * k as f32);
    let (ix, iy) = (ox.floor() as usize, oy.floor() as usize);
    let (fx, fy) = (ox - ox.floor(), oy - oy.floor());
    let (w, tw) = (out.width as usize, tex.width as usize);
    out.pixels.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let r0 = &tex.pixels[(y + iy) * tw + ix..];
        let r1 = &tex.pixels[(y + iy + 1) * tw + ix..];
        for (x, p) in row.iter_mut().enumerate() {
            let a = r0[x].lerp(r0[x + 1], fx);
            let b = r1[x].lerp(r1[x + 1], fx);
            *p = a.lerp(b, fy);
        }
    });
}

fn events_bench(b: &EventsBench) -> Result<()> {
    let noisy = EventConfig {
        seed: 1,
        noise: NoiseConfig {
            threshold_mismatch: Some(ThresholdMismatch { sigma: 0.03, mode: MismatchMode::Fixed }),
            refractory: Some(Refractory { period_ns: 100_000, mode: RefractoryMode::FireLater }),
            photoreceptor: Some(Photoreceptor { cutoff_hz: 300.0 }),
            leak_rate_hz: 0.1,
            shot_noise_rate_hz: 1.0,
        },
        ..EventConfig::default()
    };
    let tex = bench_texture(b.width, b.height, b.frames);
    let mut frame = Image::new(b.width, b.height);
    println!(
        "events: {}x{}, {} frames at 1000 FPS, moving texture, counting sink, {} threads",
        b.width,
        b.height,
        b.frames,
        rayon::current_num_threads()
    );
    println!(
        "  {:<8} {:>8} {:>8} {:>16} {:>10} {:>11} {:>14}",
        "config", "model s", "wall s", "M px-updates/s", "M events/s", "events", "max |dL|/C"
    );
    for (name, cfg) in [("ideal", EventConfig::default()), ("noisy", noisy)] {
        let mut sim = EventSimulator::new(cfg, b.width, b.height)?;
        let mut sink = CountingSink::default();
        let (mut model_s, mut max_change) = (0.0f64, 0.0f32);
        let wall = Instant::now();
        for k in 0..b.frames {
            bench_frame(&tex, &mut frame, k);
            let t = Instant::now();
            let st = sim.step(&frame, k as i64 * 1_000_000, &mut sink)?;
            model_s += t.elapsed().as_secs_f64();
            max_change = max_change.max(st.max_change_c);
        }
        let wall_s = wall.elapsed().as_secs_f64();
        let updates = b.width as f64 * b.height as f64 * b.frames as f64;
        let events = sink.on + sink.off;
        println!(
            "  {:<8} {:>8.3} {:>8.3} {:>16.1} {:>10.2} {:>11} {:>14.3}",
            name,
            model_s,
            wall_s,
            updates / model_s / 1e6,
            events as f64 / model_s / 1e6,
            events,
            max_change
        );
    }
    Ok(())
}

/// `evsim bench dataset`.
fn dataset_bench(b: &DatasetBench) -> Result<()> {
    use simulator::dataset::{write_dataset, Plan, RunOptions};
    let plan = Plan::resolve(&b.scene, &b.overrides.resolve())?;
    let out = std::env::temp_dir().join(format!("evsim-bench-dataset-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let c = &plan.config;
    let n = plan.clock.n_frames;
    println!(
        "dataset bench: {} ({} frames {}x{} at {} FPS, {}; {} views, sharp images from {}), {} threads",
        b.scene.display(),
        n,
        c.width,
        c.height,
        c.fps,
        c.frames_summary(),
        plan.views.len(),
        plan.sharp_source(),
        rayon::current_num_threads()
    );
    let start = Instant::now();
    let s = write_dataset(&plan, &RunOptions { out: out.clone(), progress: true, ..RunOptions::default() })?;
    let total = start.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&out);
    let mb = |b: Option<u64>| b.map(|b| format!("{:.0} MB", b as f64 / 1e6)).unwrap_or_else(|| "n/a".into());
    let fps = |d: std::time::Duration| n as f64 / d.as_secs_f64().max(1e-9);
    println!("stage                          time      frames/s   peak memory");
    println!(
        "render frames + sharp views  {:8.1} s  {:9.2}   {} (frames stage), {} (sharp stage)",
        s.render_time.as_secs_f64(),
        fps(s.render_time),
        mb(s.peak_rss[0]),
        mb(s.peak_rss[1])
    );
    if !s.denoise_time.is_zero() {
        println!("  of which denoising          {:8.1} s  {:9.2}", s.denoise_time.as_secs_f64(), fps(s.denoise_time));
    }
    println!("beside the renders (their times overlap the renders'):");
    println!(
        "frame cache writes           {:8.1} s  {:9.1}",
        s.cache_write_time.as_secs_f64(),
        fps(s.cache_write_time)
    );
    println!("events                       {:8.1} s  {:9.1}", s.events_time.as_secs_f64(), fps(s.events_time));
    println!("exposure + PNG               {:8.1} s  {:9.1}", s.exposure_time.as_secs_f64(), fps(s.exposure_time));
    println!(
        "depth bounds + metadata      {:8.1} s  {:9.1}   {} (metadata stage)",
        s.metadata_time.as_secs_f64(),
        fps(s.metadata_time),
        mb(s.peak_rss[2])
    );
    println!(
        "total                        {:8.1} s  {:9.2}   ({:.1} min; {} events)",
        total,
        n as f64 / total,
        total / 60.0,
        s.events_on + s.events_off
    );
    print_fill_times(&s.fill_times);
    Ok(())
}

/// Print the thread time of the caches' fills and of waits for another thread's fill.
fn print_fill_times(times: &[(&str, simulator::render::radiance_cache::FillTimes)]) {
    println!("cache fills (thread time, summed over threads; a grid's time includes the lattices it filled):");
    for (name, t) in times.iter().filter(|(_, t)| t.fills > 0) {
        println!(
            "  {:<16} {:7} filled {:8.1} s   waiting for another thread's fill {:7.1} s",
            name,
            t.fills,
            t.fill.as_secs_f64(),
            t.wait.as_secs_f64()
        );
    }
}
