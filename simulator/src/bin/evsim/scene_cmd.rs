//! `evsim scene ...`: the procedural scene library ([`simulator::scenegen`]).
//!
//! - `evsim scene generate [--out scenes] [--only NAME]`: build every registered scene (or one)
//!   and write `<out>/<name>/{scene.gltf, scene.bin, textures/*.png, scene.toml}`.

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
    }
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
