//! The in-memory scene every loader produces and the renderer consumes.
//!
//! - [`Scene`]: world-space triangles with per-vertex normals and UVs, one material per triangle,
//!   textures, punctual lights, the environment and the cameras found in the file.
//! - [`texture`]: decoded textures (sRGB decoded to linear at load time) with wrap modes and
//!   bilinear lookup.
//! - [`environment`]: constant or equirectangular-map environment light.
//! - [`gltf_load`], [`obj_load`]: the file loaders; [`description`]: the `.toml` render
//!   description that names a mesh file plus camera and environment.
//!
//! Conventions: right-handed world, metres, linear Rec.709 RGB radiometric units. Cameras look
//! down their local -Z with +Y up (the glTF convention). Triangles wind counter-clockwise around
//! their geometric normal; emitters radiate towards it unless their material is double-sided.

pub mod camera;
pub mod description;
pub mod environment;
#[cfg(test)]
mod gltf_fixture;
pub mod gltf_load;
mod gltf_material;
mod gltf_mesh;
pub mod obj_load;
pub mod texture;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

pub use camera::{Camera, FilmRays, Projector};
pub use environment::Environment;
pub use texture::{Texture, WrapMode};

use crate::error::SceneError;

/// A loaded scene: flattened world-space geometry plus everything needed to shade it.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// All triangles of all nodes, in world space.
    pub mesh: TriangleMesh,
    /// Materials; `mesh.material[i]` indexes this.
    pub materials: Vec<Material>,
    /// Textures; [`TextureRef::index`] indexes this.
    pub textures: Vec<Texture>,
    /// Point, spot and directional lights.
    pub lights: Vec<PunctualLight>,
    /// Light arriving from infinitely far away.
    pub environment: Environment,
    /// Cameras defined in the file, in file order.
    pub cameras: Vec<Camera>,
    /// Non-fatal problems found while loading (skipped degenerate triangles, ...).
    pub warnings: Vec<String>,
    /// The file the scene came from.
    pub source: PathBuf,
}

/// World-space indexed triangles. Every vertex has a normal and a UV (UV is zero when the file
/// has none; normals are generated, area-weighted, when the file has none).
#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    /// Vertex positions (m).
    pub positions: Vec<Vec3>,
    /// Unit shading normals, one per vertex.
    pub normals: Vec<Vec3>,
    /// Texture coordinates (TEXCOORD_0), one per vertex.
    pub uvs: Vec<Vec2>,
    /// Vertex indices, counter-clockwise around the geometric normal.
    pub indices: Vec<[u32; 3]>,
    /// Material index of each triangle.
    pub material: Vec<u32>,
}

impl TriangleMesh {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }
    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
    /// The three corner positions of triangle `i`.
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }
    /// Append another mesh's triangles, offsetting its indices (materials are kept as they are).
    pub fn append(&mut self, other: &TriangleMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.uvs.extend_from_slice(&other.uvs);
        self.indices.extend(other.indices.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
        self.material.extend_from_slice(&other.material);
    }
}

/// A reference from a material to a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`].
    pub index: u32,
}

/// The glTF metallic-roughness material (OBJ materials are mapped onto it).
///
/// Reflection (glTF spec, appendix B, with `KHR_materials_specular`'s strength `s`):
/// `f = (1 - metallic) (1 - s F_d(v.h)) base/pi + F(v.h) D G / (4 |n.l| |n.v|)` with GGX `D`,
/// separable Smith `G`, `alpha = roughness^2`, Schlick `F` with
/// `F0 = mix(0.04 s, base_color, metallic)` and `F_d` the dielectric Schlick term (F0 = 0.04).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the file, for messages.
    pub name: String,
    /// Linear base colour factor (albedo of the diffuse lobe; F0 of metals).
    pub base_color: Vec3,
    /// Base colour texture (already decoded from sRGB); multiplies `base_color`.
    pub base_color_texture: Option<TextureRef>,
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// Strength of the dielectric specular layer in [0, 1] (`KHR_materials_specular`
    /// `specularFactor`, 1 when the extension is absent): 0 turns a non-metal into a pure
    /// Lambertian diffuse (OBJ materials without `Ks`).
    pub specular: f32,
    /// Perceptual roughness in [0, 1]; GGX alpha = roughness^2.
    pub roughness: f32,
    /// glTF metallic-roughness texture: roughness in G, metallic in B (linear); multiplies factors.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Emitted radiance (W/m^2/sr), factor times `KHR_materials_emissive_strength`.
    pub emission: Vec3,
    /// Emission texture (decoded from sRGB); multiplies `emission`.
    pub emission_texture: Option<TextureRef>,
    /// Emit and reflect on both sides. One-sided emitters radiate only towards the geometric normal.
    pub double_sided: bool,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            base_color: Vec3::splat(0.8),
            base_color_texture: None,
            metallic: 0.0,
            specular: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            emission: Vec3::ZERO,
            emission_texture: None,
            double_sided: false,
        }
    }
}

impl Material {
    /// True when the material emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// Luminous efficacy (lm/W) between the photometric intensities of `KHR_lights_punctual`
/// (candela for point and spot lights, lux for directional ones) and our radiometric ones: the
/// convention of Blender's glTF exporter and importer (lighting mode "Standard"), so that a
/// scene exported from Blender renders as Cycles renders it: a Blender point light of `P` W
/// becomes `P / (4 pi) * 683` cd in the file and `P / (4 pi)` W/sr here; a sun of `S` W/m^2
/// becomes `683 S` lux and `S` W/m^2.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A light with no area (from `KHR_lights_punctual`), in radiometric units: point and spot
/// lights have a radiant intensity (W/sr), directional lights an irradiance (W/m^2) on a
/// surface facing them, per linear RGB channel. The glTF file holds photometric values
/// (candela, lux), converted at [`LUMENS_PER_WATT`] both ways, as Blender does.
#[derive(Clone, Debug, PartialEq)]
pub enum PunctualLight {
    /// Radiates equally in all directions from `position`.
    Point {
        /// World position (m).
        position: Vec3,
        /// Radiant intensity (W/sr) per RGB channel.
        intensity: Vec3,
    },
    /// A point light restricted to a cone, with glTF's smooth falloff between the angles.
    Spot {
        /// World position (m).
        position: Vec3,
        /// Unit direction the cone points to.
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Vec3,
        /// Inner cone half-angle (rad): full intensity inside.
        inner_cone: f32,
        /// Outer cone half-angle (rad): zero outside.
        outer_cone: f32,
    },
    /// Light from infinitely far away along one direction.
    Directional {
        /// Unit direction the light travels (from the light towards the scene).
        direction: Vec3,
        /// Irradiance (W/m^2) on a surface facing the light.
        irradiance: Vec3,
    },
}

/// Load any supported scene file, chosen by extension: `.gltf`, `.glb`, `.obj`, or a `.toml`
/// render description (see [`description`]).
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let mut scene = match ext.as_deref() {
        Some("gltf") | Some("glb") => gltf_load::load(path)?,
        Some("obj") => obj_load::load(path)?,
        Some("toml") => description::load(path)?,
        _ => {
            return Err(SceneError::unsupported(
                path,
                "file extension",
                "expected a .gltf, .glb, .obj or .toml scene file",
            ))
        }
    };
    scene.source = path.to_path_buf();
    Ok(scene)
}

/// Compute area-weighted vertex normals for triangles that index `positions`.
/// Vertices used by no (non-degenerate) triangle get +Z.
pub fn vertex_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for t in indices {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // cross product length is twice the area: area weighting comes for free
        let fn_ = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += fn_;
        }
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Z)).collect()
}

/// True when the triangle has (numerically) zero area.
pub fn is_degenerate(corners: [Vec3; 3]) -> bool {
    let [a, b, c] = corners;
    let cross = (b - a).cross(c - a);
    let scale = (b - a).length_squared().max((c - a).length_squared());
    !(cross.length_squared() > 1e-14 * scale * scale) || scale == 0.0
}
