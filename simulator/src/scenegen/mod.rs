//! Procedural scenes: build geometry, materials and textures in code and write them as glTF 2.0
//! plus a dataset `scene.toml` (`evsim scene generate`).
//!
//! What lives where:
//! - [`gltf_write`]: [`SceneBuilder`] (meshes with one material each, materials, textures, a
//!   camera) and its deterministic, atomic glTF writer.
//! - [`mesh`]: primitives appended to a builder mesh under a transform (plane, heightfield,
//!   cuboid, cylinder, cone, UV sphere, torus, extruded polygon), UVs in metres.
//! - [`texture`]: seeded procedural textures (stripes, checker, tiles, bricks, fBm, wood, 5x7
//!   bitmap text).
//! - [`demo`]: the `gen_demo` scene, a small example of the whole API.
//! - [`camera_path`]: key-pose `[trajectory]` tables of the benchmark scenes.
//! - [`factory`]: the `factory` benchmark scene (machines, racks, pipes, crates, signs).
//! - [`pool`]: the `pool` benchmark scene (outdoor pool, loungers, umbrellas, plants, a facade).
//! - [`tanabata`]: benchmark scene, a summer-festival street with bamboo, tanzaku and lanterns.
//! - [`trolley`]: benchmark scene, a tram street with shop fronts, seen while riding past.
//!
//! A scene is a [`SceneSpec`] in [`registry`]: a name, a one-line description and a `build`
//! function returning a [`GeneratedScene`] (builder + `scene.toml` text). [`write_scene`] saves
//! it as `<dir>/scene.gltf`, `scene.bin`, `textures/*.png` and `scene.toml`; the CLI and the
//! tests share the registry.
//!
//! Building a scene (see [`demo`] for a complete one):
//!
//! ```no_run
//! use glam::{Affine3A, Vec2, Vec3};
//! use simulator::scene::WrapMode;
//! use simulator::scenegen::{mesh, texture, write_scene, GeneratedScene, MaterialDesc, SceneBuilder};
//!
//! let mut b = SceneBuilder::new();
//! // a 256 px texture per 2 m: 128 px/m on every surface built with tile = (2, 2)
//! let bricks = texture::bricks(256, 256, &texture::Bricks {
//!     rows: 16, per_row: 4, mortar_px: 2, brick: [150, 70, 50], mortar: [190; 3],
//!     jitter: 0.1, grain: 0.3, seed: 1,
//! });
//! let tex = b.add_texture("bricks", bricks, WrapMode::Repeat);
//! let mat = b.add_material(MaterialDesc::diffuse("wall", [1.0; 3]).with_texture(tex));
//! let wall = b.add_mesh("wall", mat);
//! mesh::cuboid(b.mesh_mut(wall), Affine3A::from_translation(Vec3::Y), Vec3::new(4.0, 2.0, 0.2), Vec2::splat(2.0));
//! let toml = "scene = \"scene.gltf\"\n".to_string(); // plus [camera], [trajectory], [dataset]
//! write_scene("scenes/my_scene".as_ref(), &GeneratedScene { builder: b, toml }).unwrap();
//! ```

pub mod camera_path;
pub mod demo;
pub mod factory;
pub mod gltf_write;
pub mod mesh;
pub mod pool;
pub mod tanabata;
pub mod texture;
pub mod trolley;

use std::path::Path;

use anyhow::{Context, Result};

pub use gltf_write::{
    MaterialDesc, MaterialId, MeshData, MeshId, PerspectiveCamera, SceneBuilder, TextureId, TexturePixels, WrittenScene,
};

/// A generated scene: the geometry to write and the `scene.toml` that renders it (it must name
/// `scene = "scene.gltf"`).
#[derive(Clone, Debug)]
pub struct GeneratedScene {
    /// Meshes, materials, textures and camera.
    pub builder: SceneBuilder,
    /// The dataset scene description (`[camera]`, `[environment]`, `[trajectory]`, `[dataset]`).
    pub toml: String,
}

/// One entry of the scene registry.
#[derive(Clone, Copy, Debug)]
pub struct SceneSpec {
    /// Folder name under `scenes/`.
    pub name: &'static str,
    /// One line for `--help`-style listings.
    pub description: &'static str,
    /// Build the scene (deterministic: no clock, no global RNG).
    pub build: fn() -> GeneratedScene,
}

/// Every procedural scene, in listing order.
pub fn registry() -> &'static [SceneSpec] {
    const SCENES: &[SceneSpec] = &[
        SceneSpec {
            name: "gen_demo",
            description: "demonstration: textured ground, boxes, cylinders, spheres, a torus, a sign and an emissive panel (~20k triangles)",
            build: demo::gen_demo,
        },
        SceneSpec {
            name: "factory",
            description: "benchmark: a factory hall with a press, conveyor, tank, racks of boxes, pipes, crates and signs",
            build: factory::factory,
        },
        SceneSpec {
            name: "pool",
            description: "benchmark: an outdoor hotel pool with mosaic tiles, water, ladders, loungers, umbrellas, plants and a facade",
            build: pool::pool,
        },
        SceneSpec {
            name: "tanabata",
            description: "benchmark: a summer-festival street at dusk, bamboo hung with tanzaku, stalls, lanterns; hand-held shake",
            build: tanabata::tanabata,
        },
        SceneSpec {
            name: "trolley",
            description: "benchmark: a tram street with a trolley car, rails, overhead wires and shop fronts; sideways dolly",
            build: trolley::trolley,
        },
    ];
    SCENES
}

/// The registry entry called `name`.
pub fn find(name: &str) -> Option<&'static SceneSpec> {
    registry().iter().find(|s| s.name == name)
}

/// Write `scene` into `dir`: `scene.gltf`, `scene.bin`, `textures/*.png`, then `scene.toml`
/// (last, atomically), so a folder with a `scene.toml` is complete. The generator owns
/// `dir/textures/`: PNG files there that this scene no longer writes are removed, so a folder
/// regenerated after a change holds exactly the new scene.
pub fn write_scene(dir: &Path, scene: &GeneratedScene) -> Result<WrittenScene> {
    let written = scene.builder.write(dir, "scene")?;
    let tex_dir = dir.join("textures");
    if let Ok(entries) = std::fs::read_dir(&tex_dir) {
        for entry in entries {
            let path = entry?.path();
            if path.extension().is_some_and(|e| e == "png") && !written.textures.contains(&path) {
                std::fs::remove_file(&path)
                    .with_context(|| format!("{}: cannot remove a stale texture", path.display()))?;
            }
        }
    }
    crate::image_io::write_atomic(&dir.join("scene.toml"), scene.toml.as_bytes())
        .with_context(|| format!("{}: writing scene.toml", dir.display()))?;
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::film::RenderSettings;
    use crate::render::integrator::Renderer;

    #[test]
    fn registry_names_are_unique_folder_names() {
        let names: Vec<&str> = registry().iter().map(|s| s.name).collect();
        for (i, n) in names.iter().enumerate() {
            assert!(!names[..i].contains(n), "{n} registered twice");
            assert!(n.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'), "{n}");
        }
        assert!(find("gen_demo").is_some() && find("nope").is_none());
    }

    /// Every registered scene writes, loads through its scene.toml (with a valid trajectory and
    /// dataset table) and renders a finite, non-black image with the path tracer.
    #[test]
    fn every_registered_scene_generates_loads_and_renders() {
        for spec in registry() {
            let scene = (spec.build)();
            let dir = gltf_write::tests::temp_dir(spec.name);
            write_scene(&dir, &scene).unwrap();
            let toml = dir.join("scene.toml");
            let desc = crate::dataset::description::parse(&scene.toml, &toml).unwrap();
            assert_eq!(desc.scene, Path::new("scene.gltf"));
            desc.trajectory.as_ref().expect("a dataset scene has a [trajectory]").resolve().unwrap();
            assert!(desc.dataset.is_some(), "{}: no [dataset] table", spec.name);
            let loaded = crate::scene::load(&toml).unwrap();
            assert!(loaded.warnings.is_empty(), "{}: {:?}", spec.name, loaded.warnings);
            assert_eq!(loaded.mesh.len(), scene.builder.triangle_count());
            assert_eq!(loaded.materials.len(), scene.builder.materials.len());
            assert!(loaded.materials.iter().any(|m| m.is_emissive()));
            let mut st = RenderSettings::new(loaded.cameras[0].clone());
            (st.width, st.height, st.spp) = (24, 16, 2);
            let img = Renderer::new(&loaded).render(&st, None);
            let mean = img.mean();
            assert!(mean.is_finite() && mean.min_element() > 0.01, "{}: mean {mean}", spec.name);
        }
    }

    /// A scene folder committed under `scenes/` holds exactly what its generator writes now
    /// (same files, same bytes), so it never goes stale.
    #[test]
    fn committed_scene_folders_match_their_generators() {
        let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let files = |d: &Path| -> Vec<(String, Vec<u8>)> {
            let mut out = Vec::new();
            for sub in [d.to_path_buf(), d.join("textures")] {
                let Ok(entries) = std::fs::read_dir(&sub) else { continue };
                for e in entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()) {
                    let rel = e.strip_prefix(d).unwrap().to_string_lossy().into_owned();
                    out.push((rel, std::fs::read(&e).unwrap()));
                }
            }
            out.sort();
            out
        };
        for spec in registry() {
            let committed = scenes.join(spec.name);
            if !committed.join("scene.toml").exists() {
                continue;
            }
            let fresh = gltf_write::tests::temp_dir(&format!("fresh-{}", spec.name));
            write_scene(&fresh, &(spec.build)()).unwrap();
            let (a, b) = (files(&committed), files(&fresh));
            let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
            assert_eq!(
                names(&a),
                names(&b),
                "scenes/{}: regenerate with `evsim scene generate --only {}`",
                spec.name,
                spec.name
            );
            for ((name, x), (_, y)) in a.iter().zip(&b) {
                assert!(
                    x == y,
                    "scenes/{}/{name} is stale: regenerate with `evsim scene generate --only {}`",
                    spec.name,
                    spec.name
                );
            }
        }
    }

    #[test]
    fn stale_textures_are_removed_on_rewrite() {
        let dir = gltf_write::tests::temp_dir("stale");
        std::fs::create_dir_all(dir.join("textures")).unwrap();
        std::fs::write(dir.join("textures/99_old.png"), b"old").unwrap();
        let w = write_scene(&dir, &demo::gen_demo()).unwrap();
        assert!(!dir.join("textures/99_old.png").exists());
        assert!(w.textures.iter().all(|t| t.exists()));
    }

    #[test]
    fn gen_demo_has_about_twenty_thousand_triangles() {
        let n = demo::gen_demo().builder.triangle_count();
        assert!((15_000..40_000).contains(&n), "{n}");
    }
}
