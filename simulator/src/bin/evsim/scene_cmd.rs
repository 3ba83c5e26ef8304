//! `evsim scene ...`: the procedural scene library ([`simulator::scenegen`]).
//!
//! - `evsim scene generate [--out scenes] [--only NAME]`: build every registered scene (or one)
//!   and write `<out>/<name>/{scene.gltf, scene.bin, textures/*.png, scene.toml}`.
//! - `evsim scene info <scene.toml>`: content, trajectory and the blur statistics of the
//!   configured exposure (mean / max pixel displacement, blur-axis consistency).
//! - `evsim scene preview <scene.toml> --out sheet.png`: sharp | blurry | events of one view.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Result};
use clap::{Args, Subcommand};

use simulator::scenegen::{self, write_scene};

/// The `evsim scene` subcommands.
#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Write the registered procedural scenes as glTF + scene.toml folders.
    Generate(GenerateArgs),
    /// Print a dataset scene's content, trajectory and blur statistics.
    Info(InfoArgs),
    /// Write a contact sheet (sharp view, blurry view, event frame of its exposure).
    Preview(PreviewArgs),
}

/// Options of `evsim scene info`.
#[derive(Args, Debug, Clone)]
pub struct InfoArgs {
    /// The scene file (`scenes/<name>/scene.toml`).
    pub scene: PathBuf,
    /// Trace every this-many-th pixel for the blur statistics.
    #[arg(long, default_value_t = 4)]
    pub stride: u32,
    /// Print every view's blur.
    #[arg(long)]
    pub per_view: bool,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: crate::dataset_cmd::OverrideArgs,
}

/// Options of `evsim scene preview`.
#[derive(Args, Debug, Clone)]
pub struct PreviewArgs {
    /// The scene file (`scenes/<name>/scene.toml`).
    pub scene: PathBuf,
    /// Output PNG.
    #[arg(long, default_value = "preview.png")]
    pub out: PathBuf,
    /// Which blurry view (default: the one nearest the middle).
    #[arg(long)]
    pub view: Option<usize>,
    /// Settings changes (e.g. --set dataset.width=300 --set dataset.height=200 for a quick sheet).
    #[command(flatten)]
    pub overrides: crate::dataset_cmd::OverrideArgs,
}

/// Options of `evsim scene generate`.
#[derive(Args, Debug, Clone)]
pub struct GenerateArgs {
    /// Folder that receives one sub-folder per scene.
    #[arg(long, default_value = "scenes")]
    pub out: PathBuf,
    /// Generate only this scene (an unknown name lists the registered ones).
    #[arg(long)]
    pub only: Option<String>,
}

/// Run one `evsim scene` subcommand.
pub fn run(cmd: SceneCommand) -> Result<()> {
    match cmd {
        SceneCommand::Generate(args) => generate(&args),
        SceneCommand::Info(args) => info(&args),
        SceneCommand::Preview(args) => preview(&args),
    }
}

/// `evsim scene info`.
fn info(args: &InfoArgs) -> Result<()> {
    use simulator::dataset::blur::blur_stats;
    use simulator::dataset::Plan;
    use simulator::render::integrator::Renderer;
    let plan = Plan::resolve(&args.scene, &args.overrides.resolve())?;
    let s = &plan.scene;
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::INFINITY), glam::Vec3::splat(f32::NEG_INFINITY));
    for p in &s.mesh.positions {
        (lo, hi) = (lo.min(*p), hi.max(*p));
    }
    let texels: usize = s.textures.iter().map(|t| (t.width * t.height) as usize).sum();
    let emissive = s.materials.iter().filter(|m| m.is_emissive()).count();
    let env = match &s.environment {
        simulator::scene::Environment::Constant(c) => format!("constant {c}"),
        simulator::scene::Environment::Map(m) => format!("map {}x{} (scale {})", m.width, m.height, m.scale),
    };
    println!("{}", args.scene.display());
    println!("  triangles   {}", s.mesh.len());
    println!("  materials   {} ({} emissive)", s.materials.len(), emissive);
    println!("  textures    {} ({:.1} M texels)", s.textures.len(), texels as f64 / 1e6);
    println!("  lights      {} punctual; environment {env}", s.lights.len());
    println!("  bounds      {lo} .. {hi} m");
    // the camera path
    let c = &plan.config;
    let n = plan.clock.n_frames;
    let mut path = 0.0;
    let mut prev: Option<glam::DVec3> = None;
    for k in 0..n {
        let p = plan.trajectory.pose_at(plan.clock.time_ns(k))?.position;
        if let Some(q) = prev {
            path += (p - q).length();
        }
        prev = Some(p);
    }
    let secs = n as f64 * plan.clock.dt_ns as f64 / 1e9;
    println!(
        "  trajectory  {:.3} s, {n} frames at {} FPS, camera path {:.2} m ({:.2} m/s)",
        secs,
        c.fps,
        path,
        path / secs
    );
    let sharp = (0..plan.views.len()).filter(|&i| plan.is_sharp(i)).count();
    println!(
        "  dataset     {}x{}, {} views ({} sharp), exposure {} ms, {} spp (sharp images from {}), threshold {}/{}",
        c.width,
        c.height,
        plan.views.len(),
        sharp,
        c.exposure_ms,
        c.spp,
        plan.sharp_source(),
        plan.events.c_pos,
        plan.events.c_neg
    );
    let renderer = Renderer::with_preset(&plan.scene, c.bvh);
    let b = blur_stats(&plan, &renderer.accel, args.stride)?;
    if args.per_view {
        for v in &b.views {
            println!(
                "    view {:>3}: mean {:6.1} px, max {:6.1} px, direction {:+6.1} deg",
                v.view,
                v.mean,
                v.max,
                v.mean_vector[1].atan2(v.mean_vector[0]).to_degrees()
            );
        }
    }
    println!(
        "  blur        mean {:.1} px, max {:.1} px over {} blurry views at {} ms; blur-axis consistency {:.2}",
        b.mean,
        b.max,
        b.views.len(),
        c.exposure_ms,
        b.direction_consistency
    );
    Ok(())
}

/// `evsim scene preview`.
fn preview(args: &PreviewArgs) -> Result<()> {
    use simulator::dataset::preview::contact_sheet;
    use simulator::dataset::Plan;
    use simulator::render::integrator::Renderer;
    let t0 = Instant::now();
    let plan = Plan::resolve(&args.scene, &args.overrides.resolve())?;
    let renderer = Renderer::with_preset(&plan.scene, plan.config.bvh);
    let sheet = contact_sheet(&plan, &renderer, args.view)?;
    let mut bytes = Vec::new();
    sheet.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
    simulator::image_io::write_atomic(&args.out, &bytes)?;
    println!(
        "{}: wrote {} ({}x{}) in {:.1} s",
        args.scene.display(),
        args.out.display(),
        sheet.width(),
        sheet.height(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `evsim scene generate`.
fn generate(args: &GenerateArgs) -> Result<()> {
    let specs: Vec<&scenegen::SceneSpec> = match &args.only {
        Some(name) => match scenegen::find(name) {
            Some(s) => vec![s],
            None => {
                let list: Vec<String> =
                    scenegen::registry().iter().map(|s| format!("  {:<12} {}", s.name, s.description)).collect();
                bail!("--only {name}: no such procedural scene; the registered scenes are:\n{}", list.join("\n"));
            }
        },
        None => scenegen::registry().iter().collect(),
    };
    for spec in specs {
        let t0 = Instant::now();
        let scene = (spec.build)();
        let dir = args.out.join(spec.name);
        let written = write_scene(&dir, &scene)?;
        println!(
            "{}: {} triangles, {} meshes, {} materials, {} textures in {:.2} s -> {}",
            spec.name,
            scene.builder.triangle_count(),
            scene.builder.meshes.len(),
            scene.builder.materials.len(),
            written.textures.len(),
            t0.elapsed().as_secs_f64(),
            dir.join("scene.toml").display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generate_writes_one_folder_and_lists_scenes_for_an_unknown_name() {
        let out = std::env::temp_dir().join(format!("evsim-scene-generate-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        generate(&GenerateArgs { out: out.clone(), only: Some("gen_demo".into()) }).unwrap();
        for f in ["scene.gltf", "scene.bin", "scene.toml"] {
            assert!(out.join("gen_demo").join(f).is_file(), "{f}");
        }
        let e = generate(&GenerateArgs { out, only: Some("nope".into()) }).unwrap_err().to_string();
        assert!(e.contains("--only nope") && e.contains("gen_demo"), "{e}");
    }
}
