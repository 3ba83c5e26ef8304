//! `evsim`: the evblur simulator's command line.
//!
//! - `evsim render <scene> --spp N --out img.exr`: path-trace one image.
//! - `evsim events --frames DIR --timestamps FILE --out events.h5`: the event model over a folder of
//!   frames into an event file (.h5 Ev-DeblurNeRF or DSEC, .txt, .npz).
//! - `evsim dataset scenes/<name>/scene.toml --out DIR`: a whole dataset (frames, events, blurry
//!   and sharp views, poses, manifest), resumable.
//! - `evsim check <DIR> [--test-views every8|last5|auto] [--events-unit ns|us|auto]`: verify a
//!   dataset folder against the Ev-DeblurBlender layout (non-zero exit on problems).
//! - `evsim scene generate [--out scenes] [--only NAME]`: write the procedural scenes (glTF +
//!   `scene.toml`) of `simulator::scenegen::registry()`.
//! - `evsim bench esim`: `evsim events` against esim_py (ESIM's C++ simulator) on one folder.
//! - `evsim bench render`: render throughput (and the Mitsuba ratio when Mitsuba is installed),
//!   BVH build time and ray throughput on a 1 M-triangle scene.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};

use simulator::image_io::write_image;
use simulator::render::accel::BvhPreset;
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;
use simulator::render::sampler::SamplerKind;
use simulator::scene::{self, Camera};

mod bench;
mod bench_esim;
mod check_cmd;
mod dataset_cmd;
mod events_cmd;
mod scene_cmd;

/// evblur simulator: render scenes (and, soon, event-camera datasets).
#[derive(Parser, Debug)]
#[command(name = "evsim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Path-trace one image of a scene (.gltf, .glb, .obj or a .toml render description).
    Render(RenderArgs),
    /// Run the event model over a folder of frames (PNG or EXR) and write an event file.
    Events(events_cmd::EventsArgs),
    /// Simulate an Ev-DeblurBlender dataset (blurry + sharp views, events, poses) from a scene file.
    Dataset(dataset_cmd::DatasetArgs),
    /// Measure the events path-tracing noise fires: a segment at the dataset's spp vs 16x spp.
    DatasetNoise(dataset_cmd::NoiseArgs),
    /// Score a segment's events against a converged reference's brightness changes (event-pair
    /// and window r2, beside an ideal simulator's).
    DatasetFidelity(dataset_cmd::FidelityArgs),
    /// Check a dataset folder against the Ev-DeblurBlender layout (images, timestamps, poses, events).
    Check(check_cmd::CheckArgs),
    /// Procedural scenes: generate the registered scene folders.
    Scene {
        #[command(subcommand)]
        what: scene_cmd::SceneCommand,
    },
    /// Benchmarks that print performance figures.
    Bench {
        #[command(subcommand)]
        what: bench::BenchCommand,
    },
}

/// Options of `evsim render`.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Output image: .exr (linear float) or .png (8-bit sRGB).
    #[arg(long, default_value = "render.exr")]
    pub out: PathBuf,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Image width in pixels.
    #[arg(long, default_value_t = 600)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 400)]
    pub height: u32,
    /// Maximum path segments (1 = emitters only, 2 = direct light; 0 = unlimited).
    #[arg(long, default_value_t = 5)]
    pub max_depth: u32,
    /// Seed of the random streams.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Which of the scene's cameras to use.
    #[arg(long, default_value_t = 0)]
    pub camera: usize,
    /// Camera override: position "x,y,z" (needs --look-at).
    #[arg(long, value_parser = parse_vec3, requires = "look_at", allow_hyphen_values = true)]
    pub look_from: Option<Vec3>,
    /// Camera override: target point "x,y,z".
    #[arg(long, value_parser = parse_vec3, requires = "look_from", allow_hyphen_values = true)]
    pub look_at: Option<Vec3>,
    /// Camera override: up vector "x,y,z".
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0", allow_hyphen_values = true)]
    pub up: Vec3,
    /// Camera override: full vertical field of view in degrees.
    #[arg(long)]
    pub fov: Option<f32>,
    /// Sample generator: stratified Owen-scrambled Sobol, or independent (like Mitsuba's).
    #[arg(long, value_enum, default_value_t = SamplerKind::default())]
    pub sampler: SamplerKind,
    /// BVH build preset.
    #[arg(long, value_enum, default_value_t = BvhPreset::default())]
    pub bvh: BvhPreset,
    /// Sample clamping: largest channel of one path contribution, except emitters seen directly
    /// (0 = off; biased, removes fireflies).
    #[arg(long, default_value_t = 0.0)]
    pub clamp: f32,
    /// Filter the image with the feature-guided spatial denoiser the dataset writer uses
    /// (`[dataset] denoise`; a single image has no temporal window); biased, far less noise
    /// at low spp.
    #[arg(long)]
    pub denoise: bool,
    /// Texture filtering at camera-ray hits: each camera ray reads its textures averaged over
    /// the footprint of this many pixels (mip-mapped, anisotropic; 0 = off, plain bilinear
    /// lookups as Mitsuba's).
    #[arg(long, default_value_t = 0.0)]
    pub texture_filter: f32,
}

/// Parse "x,y,z" into a vector.
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> =
        s.split(',').map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}': {e}"))).collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers \"x,y,z\", got \"{s}\"")),
    }
}

/// Resolve the camera from the scene and the overrides.
pub fn resolve_camera(args: &RenderArgs, scene: &scene::Scene) -> Result<Camera> {
    let fov = args.fov.map(|f| f.to_radians());
    if let Some(f) = fov {
        if !(f > 0.0 && f < std::f32::consts::PI) {
            bail!("--fov must be in (0, 180) degrees, got {}", args.fov.unwrap());
        }
    }
    if let (Some(from), Some(at)) = (args.look_from, args.look_at) {
        if (at - from).length() == 0.0 || (at - from).normalize().cross(args.up).length() < 1e-6 {
            bail!("--look-from and --look-at must differ and not be parallel to --up");
        }
        return Ok(Camera::look_at(from, at, args.up, fov.unwrap_or(40f32.to_radians())));
    }
    let Some(cam) = scene.cameras.get(args.camera) else {
        bail!(
            "{}: has {} camera(s), so --camera {} does not exist; add a camera to the scene or pass --look-from/--look-at",
            scene.source.display(),
            scene.cameras.len(),
            args.camera
        );
    };
    let mut cam = cam.clone();
    if let Some(f) = fov {
        cam.yfov = f;
    }
    Ok(cam)
}

/// Turn the arguments into render settings (validated).
pub fn settings(args: &RenderArgs, camera: Camera) -> Result<RenderSettings> {
    if args.width == 0 || args.height == 0 || args.spp == 0 {
        bail!("--width, --height and --spp must be positive");
    }
    if !(args.clamp >= 0.0 && args.clamp.is_finite()) {
        bail!("--clamp {}: give a finite value >= 0 (0 turns clamping off)", args.clamp);
    }
    if !(args.texture_filter >= 0.0 && args.texture_filter <= 16.0) {
        bail!("--texture-filter {}: give a footprint of 0..=16 pixels (0 turns filtering off)", args.texture_filter);
    }
    Ok(RenderSettings {
        width: args.width,
        height: args.height,
        spp: args.spp,
        max_depth: if args.max_depth == 0 { u32::MAX } else { args.max_depth },
        rr_depth: 5,
        seed: args.seed,
        frame: 0,
        camera,
        sampler: args.sampler,
        clamp: args.clamp,
        light_samples: 1,
        feature_spp: 0,
        texture_filter: args.texture_filter,
        radiance_cache: 0,
        cache_spacing: 0.0,
        cache_vertex: 2,
        spp_max: 0,
        surface_paths: 64,
        surface_spacing: 0.0,
        glossy_paths: 64,
        glossy_block: 1,
        glossy_stride: 0,
        glossy_grid_alpha: simulator::render::integrator::surface::GLOSSY_GRID_ALPHA,
        camera_path: None,
        adaptive_variance: 0.1,
    })
}

/// A progress bar in the project's style.
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})")
            .expect("static template"),
    );
    pb.set_message(what.to_string());
    pb
}

fn render(args: &RenderArgs) -> Result<()> {
    let t0 = Instant::now();
    let scene = scene::load(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let camera = resolve_camera(args, &scene)?;
    let st = settings(args, camera)?;
    let load_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let renderer = Renderer::with_preset(&scene, args.bvh);
    let build_s = t1.elapsed().as_secs_f64();
    let pb = progress_bar(0, "render");
    let t2 = Instant::now();
    let img = if args.denoise {
        let (img, features) = renderer.render_with_features(&st);
        simulator::render::denoise::denoise(&img, &features, &simulator::render::denoise::DenoiseParams::default())
    } else {
        renderer.render(&st, Some(&pb))
    };
    let render_s = t2.elapsed().as_secs_f64();
    pb.finish_and_clear();
    write_image(&img, &args.out).with_context(|| format!("writing {}", args.out.display()))?;
    let samples = st.width as f64 * st.height as f64 * st.spp as f64;
    println!(
        "{}: {} triangles ({} emissive), {} punctual lights; load {:.2} s, BVH {:.2} s, render {:.2} s ({:.2} M samples/s); wrote {}",
        args.scene.display(),
        scene.mesh.len(),
        scene.mesh.material.iter().filter(|&&m| scene.materials[m as usize].is_emissive()).count(),
        scene.lights.len(),
        load_s,
        build_s,
        render_s,
        samples / render_s / 1e6,
        args.out.display()
    );
    Ok(())
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(args) => render(&args),
        Command::Events(args) => events_cmd::run(&args),
        Command::Dataset(args) => dataset_cmd::run(&args),
        Command::DatasetNoise(args) => dataset_cmd::run_noise(&args),
        Command::DatasetFidelity(args) => dataset_cmd::run_fidelity(&args),
        Command::Check(args) => check_cmd::run(&args),
        Command::Scene { what } => scene_cmd::run(what),
        Command::Bench { what } => bench::run(what),
    }
}
