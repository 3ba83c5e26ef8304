//! `evsim bench render`: the render benchmark. Prints
//! 1. Cornell box 600x400, max depth 5, 64 spp: our median wall time and M samples/s, and in the
//!    same run Mitsuba 3's (`llvm_ad_rgb`, JIT warm-up excluded) through the reference-check
//!    driver, with the ratio. Times are medians of `--repeats` runs, alternating the renderers.
//! 2. A 1 M-triangle scene: BVH build time and closest-hit M rays/s (primary and diffuse rays)
//!    for every obvhs build preset.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use simulator::render::accel::{Accel, BvhPreset};
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;
use simulator::render::sampling::{cosine_hemisphere, Frame, Rng};
use simulator::scene::{self, Camera, TriangleMesh};

/// Which benchmark to run.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Cornell box throughput vs Mitsuba, and BVH build/trace on a 1 M-triangle scene.
    Render(RenderBench),
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
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// The Python of the Mitsuba venv, if installed.
pub fn mitsuba_python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVBLUR_MITSUBA_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let home = std::env::var_os("HOME")?;
    let p = Path::new(&home).join(".cache/evblur/mitsuba-venv/bin/python");
    p.exists().then_some(p)
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
    let mitsuba = if b.no_mitsuba { None } else { mitsuba_python() };
    let export_dir = std::env::temp_dir().join(format!("evblur-bench-{}", std::process::id()));
    if mitsuba.is_some() {
        simulator::export::mitsuba::export_mitsuba(&scene, &st, &export_dir)?;
    }
    let (mut ours, mut theirs, mut variant) = (vec![], vec![], String::new());
    for _ in 0..b.repeats {
        let t = Instant::now();
        std::hint::black_box(renderer.render(&st, None));
        ours.push(t.elapsed().as_secs_f64());
        if let Some(py) = &mitsuba {
            let (t, v) = mitsuba_time(py, &export_dir, st.spp)?;
            theirs.push(t);
            variant = v;
        }
    }
    let t_ours = median(ours.clone());
    println!("cornell box {}x{}, max depth {}, {} spp, {} threads", st.width, st.height, st.max_depth, st.spp, rayon::current_num_threads());
    println!("  evblur : median {:.3} s  {:.2} M samples/s  (runs {:?})", t_ours, samples / t_ours / 1e6, round3(&ours));
    if !theirs.is_empty() {
        let t_m = median(theirs.clone());
        println!("  mitsuba {variant}: median {:.3} s  {:.2} M samples/s  (runs {:?})", t_m, samples / t_m / 1e6, round3(&theirs));
        println!("  ratio evblur/mitsuba samples/s: {:.2}x", t_m / t_ours);
    } else {
        println!("  mitsuba: not measured (no venv; run the test command once, or set EVBLUR_MITSUBA_PYTHON)");
    }
    let _ = std::fs::remove_dir_all(&export_dir);
    bvh_bench(b.triangles)
}

fn round3(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1000.0).round() / 1000.0).collect()
}

/// Time one Mitsuba render of the exported scene (JIT warm-up excluded by the driver); returns
/// the seconds and the variant that ran.
fn mitsuba_time(py: &Path, dir: &Path, spp: u32) -> Result<(f64, String)> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/mitsuba/render.py");
    let out = dir.join("bench.exr");
    let o = Command::new(py)
        .arg(&script)
        .arg(dir.join("scene.json"))
        .args(["--spp", &spp.to_string(), "--seed", "1", "--out"])
        .arg(&out)
        .output()
        .with_context(|| format!("running {}", py.display()))?;
    if !o.status.success() {
        bail!("mitsuba driver failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    let line = stdout.lines().rev().find(|l| l.contains("render_s")).context("driver printed no timing")?;
    let v: serde_json::Value = serde_json::from_str(line)?;
    let variant = v["variant"].as_str().unwrap_or("?").to_string();
    Ok((v["render_s"].as_f64().context("render_s missing")?, variant))
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
    println!("BVH: bumpy sphere, {} triangles; rays are closest-hit, {} threads", mesh.len(), rayon::current_num_threads());
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
