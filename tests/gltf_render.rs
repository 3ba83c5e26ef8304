//! glTF files rendered end to end: loader + camera + emission + transforms + path tracer give
//! exact pixel values where the answer is known.

use std::path::{Path, PathBuf};

use glam::Vec3;
use simulator::render::film::RenderSettings;
use simulator::render::integrator::Renderer;

/// Write `scene.gltf` + `quad.bin` into a fresh folder: one quad in the z = 0 plane spanning
/// [-1,1]^2, CCW around +z, placed by the node transform `quad_node`, with a one-sided emissive
/// material, and a camera at z = 3 looking down -z.
fn write_scene(name: &str, quad_node: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evblur-gltf-render-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut bin = Vec::new();
    for p in [[-1.0f32, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_materials_emissive_strength"],
  "scene": 0,
  "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [
    {quad_node},
    {{"camera": 0, "translation": [0, 0, 3]}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.3, "znear": 0.01}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{
    "pbrMetallicRoughness": {{"baseColorFactor": [0, 0, 0, 1]}},
    "emissiveFactor": [0.5, 0.25, 1.0],
    "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 2.0}}}}
  }}],
  "buffers": [{{"uri": "quad.bin", "byteLength": {len}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
        len = bin.len()
    );
    let path = dir.join("scene.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

fn render_mean(path: &Path) -> Vec3 {
    let scene = simulator::scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let cam = scene.cameras[0].clone();
    let st = RenderSettings { width: 24, height: 16, spp: 4, max_depth: 1, ..RenderSettings::new(cam) };
    Renderer::new(&scene).render(&st, None).mean()
}

#[test]
fn emissive_quad_fills_the_frame_with_its_radiance() {
    // the 0.3 rad camera at distance 3 sees +-0.46 vertically: the quad covers the frame
    let m = render_mean(&write_scene("plain", r#"{"mesh": 0}"#));
    assert!((m - Vec3::new(1.0, 0.5, 2.0)).abs().max_element() < 1e-5, "{m}");
}

#[test]
fn a_quad_turned_away_is_dark_and_a_mirrored_one_is_not() {
    // rotated 180 degrees about y: its emitting side faces away from the camera
    let away = render_mean(&write_scene("away", r#"{"mesh": 0, "rotation": [0, 1, 0, 0]}"#));
    assert_eq!(away, Vec3::ZERO);
    // mirrored in x (negative determinant): the loader flips the winding, so it still faces +z
    let mirrored = render_mean(&write_scene("mirror", r#"{"mesh": 0, "scale": [-1, 1, 1]}"#));
    assert!((mirrored - Vec3::new(1.0, 0.5, 2.0)).abs().max_element() < 1e-5, "{mirrored}");
}
