//! A small glTF 2.0 writer: [`SceneBuilder`] collects meshes, materials, textures and a camera,
//! and [`SceneBuilder::write`] saves `name.gltf` + `name.bin` + `textures/*.png`.
//!
//! What is written (and read back by [`crate::scene::gltf_load`]):
//! - one glTF mesh (one TRIANGLES primitive with POSITION, NORMAL, TEXCOORD_0 and u32 indices)
//!   and one node per builder mesh; vertices are already in world space, so nodes carry no
//!   transform. POSITION accessors carry `min`/`max` as the spec requires. Meshes without
//!   triangles are left out.
//! - metallic-roughness materials: `baseColorFactor` (alpha 1) and texture, metallic and
//!   roughness factors and texture, `emissiveFactor` + `KHR_materials_emissive_strength` and
//!   texture, `doubleSided`, and `KHR_materials_specular` `specularFactor`. The emissive colour is
//!   renormalised so the factor's largest channel is 1 and the rest goes into the strength (the
//!   spec keeps `emissiveFactor` in [0, 1]); the product, which is what we render, is kept.
//! - textures as 8-bit PNG files under `textures/`, one sampler per wrap mode (linear filters).
//! - an optional perspective camera on its own node (matrix = camera-to-world).
//! - punctual lights ([`PunctualLight`], `KHR_lights_punctual`), each on a node whose local -Z
//!   is the light's direction; `color * intensity` is photometric (candela, lux: the radiometric
//!   value times [`LUMENS_PER_WATT`]), chosen so that our loader reads back the very same `f32`
//!   radiometric values (the colour is normalised to a largest channel of 1, the rest goes into
//!   the intensity).
//!
//! The loader decodes only textures that a material uses (a texture used in both a colour and a
//! data slot is decoded twice), so unused textures are written but not loaded.
//!
//! The document is built from `gltf-json`'s typed structs (the schema the loader reads too), so
//! it writes the spec's defaults (`alphaMode`, `emissiveFactor`, `texCoord`) and leaves out the
//! primitives' default `mode` (TRIANGLES). Output is deterministic: keys in the structs' order,
//! floats written as the shortest decimal that reads back to the same `f32`, and PNG encoding
//! has no timestamps.
//! Every file is written atomically ([`crate::image_io::write_atomic`]); the `.gltf` goes last,
//! so a reader never sees a `.gltf` whose buffer or images are missing.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::{Mat4, Quat, Vec2, Vec3};
use gltf::json::accessor::{ComponentType, GenericComponentType, Type as AccessorType};
use gltf::json::extensions::scene::khr_lights_punctual::{KhrLightsPunctual, Light, Spot, Type as LightType};
use gltf::json::material::{EmissiveFactor, PbrBaseColorFactor, PbrMetallicRoughness, StrengthFactor};
use gltf::json::mesh::Semantic;
use gltf::json::scene::UnitQuaternion;
use gltf::json::validation::Checked::Valid;
use gltf::json::{
    buffer, camera, extensions, mesh, texture, Accessor, Asset, Buffer, Camera, Image, Index, Material, Mesh, Node,
    Root, Scene,
};
use serde_json::{json, Value};

use crate::image_io::write_atomic;
use crate::scene::{PunctualLight, WrapMode, LUMENS_PER_WATT};

/// Index of a mesh in a [`SceneBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshId(pub u32);

/// Index of a material in a [`SceneBuilder`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

/// Index of a texture in a [`SceneBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TextureId(pub u32);

/// Indexed triangles with one material, in world space (m). Vertex attributes are parallel
/// arrays; the primitives of [`super::mesh`] append to them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Name written to the glTF mesh and node.
    pub name: String,
    /// Vertex positions (m).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates (glTF: (0,0) is the image's top-left).
    pub uvs: Vec<Vec2>,
    /// Triangles, counter-clockwise around the outward normal.
    pub indices: Vec<[u32; 3]>,
    /// The material of every triangle.
    pub material: MaterialId,
}

impl MeshData {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// A metallic-roughness material (the glTF model, see [`crate::scene::Material`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    /// Name written to the file.
    pub name: String,
    /// Linear base colour factor, each channel in [0, 1].
    pub base_color: [f32; 3],
    /// sRGB base colour texture; multiplies `base_color`.
    pub base_color_texture: Option<TextureId>,
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// Perceptual roughness in [0, 1] (GGX alpha = roughness^2).
    pub roughness: f32,
    /// Linear texture with roughness in G and metallic in B; multiplies the factors.
    pub metallic_roughness_texture: Option<TextureId>,
    /// Linear emissive colour (any non-negative magnitude; see `emissive_strength`).
    pub emissive: [f32; 3],
    /// Multiplier of `emissive` (`KHR_materials_emissive_strength`); emitted radiance
    /// (W/m^2/sr) is `emissive * emissive_strength`.
    pub emissive_strength: f32,
    /// sRGB emissive texture; multiplies the emitted radiance.
    pub emissive_texture: Option<TextureId>,
    /// Reflect and emit on both sides.
    pub double_sided: bool,
    /// `KHR_materials_specular` strength in [0, 1] (None: the extension is not written, which
    /// reads as 1). 0 gives a pure Lambertian diffuse.
    pub specular: Option<f32>,
}

impl Default for MaterialDesc {
    fn default() -> Self {
        MaterialDesc {
            name: "material".into(),
            base_color: [0.8; 3],
            base_color_texture: None,
            metallic: 0.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            emissive: [0.0; 3],
            emissive_strength: 1.0,
            emissive_texture: None,
            double_sided: false,
            specular: None,
        }
    }
}

impl MaterialDesc {
    /// A rough, non-metal material of linear colour `base_color` (roughness 1).
    pub fn diffuse(name: &str, base_color: [f32; 3]) -> MaterialDesc {
        MaterialDesc { name: name.into(), base_color, ..Default::default() }
    }
    /// A dielectric with a specular layer of roughness `roughness` (e.g. 0.1-0.3 for glossy).
    pub fn glossy(name: &str, base_color: [f32; 3], roughness: f32) -> MaterialDesc {
        MaterialDesc { name: name.into(), base_color, roughness, ..Default::default() }
    }
    /// A metal: `base_color` is its F0 colour.
    pub fn metal(name: &str, base_color: [f32; 3], roughness: f32) -> MaterialDesc {
        MaterialDesc { name: name.into(), base_color, metallic: 1.0, roughness, ..Default::default() }
    }
    /// A black, one-sided emitter of radiance `radiance` (W/m^2/sr).
    pub fn emitter(name: &str, radiance: [f32; 3]) -> MaterialDesc {
        MaterialDesc { name: name.into(), base_color: [0.0; 3], emissive: radiance, ..Default::default() }
    }
    /// The same material with a base colour texture, which multiplies `base_color` (use a white
    /// factor to show the texture as it is).
    pub fn with_texture(mut self, texture: TextureId) -> MaterialDesc {
        self.base_color_texture = Some(texture);
        self
    }
}

/// The pixels of a texture (8 bits per channel, sRGB for colour slots, linear for data slots).
#[derive(Clone, Debug, PartialEq)]
pub enum TexturePixels {
    /// Three channels.
    Rgb(image::RgbImage),
    /// Four channels (alpha is written but not used by our renderer).
    Rgba(image::RgbaImage),
}

impl TexturePixels {
    /// (width, height) in pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        match self {
            TexturePixels::Rgb(i) => i.dimensions(),
            TexturePixels::Rgba(i) => i.dimensions(),
        }
    }
}

impl From<image::RgbImage> for TexturePixels {
    fn from(i: image::RgbImage) -> Self {
        TexturePixels::Rgb(i)
    }
}

impl From<image::RgbaImage> for TexturePixels {
    fn from(i: image::RgbaImage) -> Self {
        TexturePixels::Rgba(i)
    }
}

/// A texture: an image written as `textures/<index>_<name>.png` and its wrap mode (both axes).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureDesc {
    /// Name (sanitised into the file name).
    pub name: String,
    /// The pixels.
    pub pixels: TexturePixels,
    /// Wrap mode of u and v.
    pub wrap: WrapMode,
}

/// A perspective camera written to the glTF file.
#[derive(Clone, Debug, PartialEq)]
pub struct PerspectiveCamera {
    /// Name written to the file.
    pub name: String,
    /// Camera-to-world transform (rigid; the camera looks down its local -Z with +Y up).
    pub to_world: Mat4,
    /// Full vertical field of view (rad).
    pub yfov: f32,
    /// Width / height, if known.
    pub aspect: Option<f32>,
    /// Near clip distance (m), > 0.
    pub znear: f32,
}

impl PerspectiveCamera {
    /// A camera at `origin` looking at `target` with `up` roughly up and vertical FOV `yfov_deg`
    /// (degrees).
    pub fn look_at(name: &str, origin: Vec3, target: Vec3, up: Vec3, yfov_deg: f32) -> PerspectiveCamera {
        let to_world = crate::scene::Camera::look_at(origin, target, up, 1.0).to_world;
        PerspectiveCamera { name: name.into(), to_world, yfov: yfov_deg.to_radians(), aspect: None, znear: 0.01 }
    }
}

/// The files [`SceneBuilder::write`] produced.
#[derive(Clone, Debug, PartialEq)]
pub struct WrittenScene {
    /// The `.gltf` file.
    pub gltf: PathBuf,
    /// The `.bin` buffer.
    pub bin: PathBuf,
    /// The PNG files, in texture order.
    pub textures: Vec<PathBuf>,
}

/// A scene under construction: meshes (one material each), materials, textures and a camera.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneBuilder {
    /// Meshes, in file order.
    pub meshes: Vec<MeshData>,
    /// Materials, in file order (so loaded material `i` is this `i`).
    pub materials: Vec<MaterialDesc>,
    /// Textures, in file order.
    pub textures: Vec<TextureDesc>,
    /// Optional camera.
    pub camera: Option<PerspectiveCamera>,
    /// Point, spot and directional lights (the loader's [`PunctualLight`], world space).
    pub lights: Vec<PunctualLight>,
}

impl SceneBuilder {
    /// An empty scene.
    pub fn new() -> SceneBuilder {
        SceneBuilder::default()
    }

    /// Add a texture (RGB or RGBA image) with a wrap mode.
    pub fn add_texture(&mut self, name: &str, pixels: impl Into<TexturePixels>, wrap: WrapMode) -> TextureId {
        self.textures.push(TextureDesc { name: name.into(), pixels: pixels.into(), wrap });
        TextureId(self.textures.len() as u32 - 1)
    }

    /// Add a material.
    pub fn add_material(&mut self, material: MaterialDesc) -> MaterialId {
        self.materials.push(material);
        MaterialId(self.materials.len() as u32 - 1)
    }

    /// Add an empty mesh with `material`; fill it with [`super::mesh`] primitives through
    /// [`SceneBuilder::mesh_mut`].
    pub fn add_mesh(&mut self, name: &str, material: MaterialId) -> MeshId {
        self.meshes.push(MeshData { name: name.into(), material, ..Default::default() });
        MeshId(self.meshes.len() as u32 - 1)
    }

    /// The mesh `id`, to append geometry to.
    pub fn mesh_mut(&mut self, id: MeshId) -> &mut MeshData {
        &mut self.meshes[id.0 as usize]
    }

    /// Set (or replace) the camera.
    pub fn set_camera(&mut self, camera: PerspectiveCamera) {
        self.camera = Some(camera);
    }

    /// Add a point, spot or directional light.
    pub fn add_light(&mut self, light: PunctualLight) {
        self.lights.push(light);
    }

    /// Total number of triangles over all meshes.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(MeshData::triangle_count).sum()
    }

    /// Check ids, attribute lengths, index ranges and value ranges; the error names the element
    /// and the fix.
    pub fn validate(&self) -> Result<()> {
        let tex_ok = |t: Option<TextureId>| t.is_none_or(|t| (t.0 as usize) < self.textures.len());
        for (i, m) in self.materials.iter().enumerate() {
            let el = format!("material {i} \"{}\"", m.name);
            if ![m.base_color_texture, m.metallic_roughness_texture, m.emissive_texture].into_iter().all(tex_ok) {
                bail!("{el}: refers to a texture that was not added to this builder");
            }
            let unit = |v: f32| (0.0..=1.0).contains(&v);
            if !(m.base_color.into_iter().all(unit) && unit(m.metallic) && unit(m.roughness)) {
                bail!("{el}: base_color, metallic and roughness must lie in [0, 1]");
            }
            if m.specular.is_some_and(|s| !unit(s)) {
                bail!("{el}: specular must lie in [0, 1]");
            }
            let nonneg = |v: f32| v.is_finite() && v >= 0.0;
            if !(m.emissive.into_iter().all(nonneg) && nonneg(m.emissive_strength)) {
                bail!("{el}: emissive and emissive_strength must be finite and non-negative");
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            let (w, h) = t.pixels.dimensions();
            if w == 0 || h == 0 {
                bail!("texture {i} \"{}\": the image is empty", t.name);
            }
        }
        for (i, m) in self.meshes.iter().enumerate() {
            let el = format!("mesh {i} \"{}\"", m.name);
            let n = m.positions.len();
            if m.normals.len() != n || m.uvs.len() != n {
                bail!(
                    "{el}: {n} positions but {} normals and {} uvs; append through the mesh primitives",
                    m.normals.len(),
                    m.uvs.len()
                );
            }
            if m.material.0 as usize >= self.materials.len() {
                bail!("{el}: material {} was not added to this builder", m.material.0);
            }
            if let Some(t) = m.indices.iter().find(|t| t.iter().any(|&v| v as usize >= n)) {
                bail!("{el}: triangle {t:?} indexes past the {n} vertices");
            }
            let finite =
                m.positions.iter().chain(&m.normals).all(|v| v.is_finite()) && m.uvs.iter().all(|v| v.is_finite());
            if !finite {
                bail!("{el}: non-finite position, normal or uv; check the transform and parameters");
            }
        }
        for (i, l) in self.lights.iter().enumerate() {
            let (power, dir) = match l {
                PunctualLight::Point { intensity, .. } => (*intensity, Vec3::NEG_Z),
                PunctualLight::Spot { direction, intensity, inner_cone, outer_cone, .. } => {
                    if !(0.0 <= *inner_cone && inner_cone < outer_cone && *outer_cone <= std::f32::consts::FRAC_PI_2) {
                        bail!("light {i}: spot cone angles must satisfy 0 <= inner < outer <= pi/2");
                    }
                    (*intensity, *direction)
                }
                PunctualLight::Directional { direction, irradiance } => (*irradiance, *direction),
            };
            let pos = match l {
                PunctualLight::Point { position, .. } | PunctualLight::Spot { position, .. } => *position,
                PunctualLight::Directional { .. } => Vec3::ZERO,
            };
            if !(power.is_finite() && power.min_element() >= 0.0 && pos.is_finite() && dir.length() > 0.0) {
                bail!("light {i}: power must be finite and non-negative, position finite, direction non-zero");
            }
        }
        if self.triangle_count() == 0 {
            bail!("the scene has no triangles; add meshes and fill them with the mesh primitives");
        }
        if let Some(c) = &self.camera {
            if !(c.yfov > 0.0 && c.yfov < std::f32::consts::PI && c.znear > 0.0 && c.to_world.is_finite()) {
                bail!("camera \"{}\": yfov must be in (0, pi), znear > 0 and the transform finite", c.name);
            }
        }
        Ok(())
    }

    /// Write `dir/name.gltf`, `dir/name.bin` and `dir/textures/<i>_<texture>.png`, atomically
    /// and deterministically (same builder, same bytes).
    pub fn write(&self, dir: &Path, name: &str) -> Result<WrittenScene> {
        self.validate()?;
        let (root, bin) = self.encode(name);
        let bin_path = dir.join(format!("{name}.bin"));
        write_atomic(&bin_path, &bin)?;
        let mut textures = Vec::new();
        for (i, t) in self.textures.iter().enumerate() {
            let path = dir.join(texture_uri(i, &t.name));
            write_atomic(&path, &encode_png(&t.pixels).with_context(|| format!("encoding texture {}", t.name))?)?;
            textures.push(path);
        }
        let gltf = dir.join(format!("{name}.gltf"));
        let mut text = serde_json::to_string_pretty(&root)?;
        text.push('\n');
        write_atomic(&gltf, text.as_bytes())?;
        Ok(WrittenScene { gltf, bin: bin_path, textures })
    }

    /// The glTF document and the binary buffer (no I/O).
    // (gltf-json's extension structs gain fields with its cargo features: `..Default::default()`
    // keeps this building whichever a dependency turns on)
    #[allow(clippy::needless_update)]
    pub fn encode(&self, name: &str) -> (Root, Vec<u8>) {
        let mut enc = Encoder::default();
        let mut root = Root::default();
        for m in self.meshes.iter().filter(|m| !m.indices.is_empty()) {
            let attributes = [
                (Semantic::Positions, enc.vec3(&m.positions, true)),
                (Semantic::Normals, enc.vec3(&m.normals, false)),
                (Semantic::TexCoords(0), enc.vec2(&m.uvs)),
            ];
            let indices = enc.indices(&m.indices);
            let primitive = mesh::Primitive {
                attributes: attributes.into_iter().map(|(s, a)| (Valid(s), a)).collect(),
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(Index::new(m.material.0)),
                mode: Valid(mesh::Mode::Triangles),
                targets: None,
            };
            let mesh = Mesh {
                extensions: None,
                extras: Default::default(),
                name: Some(m.name.clone()),
                primitives: vec![primitive],
                weights: None,
            };
            let index = root.push(mesh);
            root.nodes.push(Node { name: Some(m.name.clone()), mesh: Some(index), ..node() });
        }
        root.asset = Asset { generator: Some("evblur scenegen".into()), ..root.asset };
        if let Some(c) = &self.camera {
            let perspective = camera::Perspective {
                aspect_ratio: c.aspect,
                yfov: c.yfov,
                zfar: None,
                znear: c.znear,
                extensions: None,
                extras: Default::default(),
            };
            let index = root.push(Camera {
                name: Some(c.name.clone()),
                orthographic: None,
                perspective: Some(perspective),
                type_: Valid(camera::Type::Perspective),
                extensions: None,
                extras: Default::default(),
            });
            let matrix = Some(c.to_world.to_cols_array());
            root.nodes.push(Node { name: Some(c.name.clone()), camera: Some(index), matrix, ..node() });
        }
        let mut used = self.materials(&mut root);
        if !self.lights.is_empty() {
            let mut lights = Vec::new();
            for (i, l) in self.lights.iter().enumerate() {
                let (light, position, direction) = light_entry(l);
                lights.push(light);
                // the node's local -Z is the light direction
                let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, direction.normalize());
                let light = Some(KhrLightsPunctual { light: Index::new(i as u32) });
                let ext = extensions::scene::Node { khr_lights_punctual: light, ..Default::default() };
                root.nodes.push(Node {
                    name: Some(format!("light_{i}")),
                    extensions: Some(ext),
                    rotation: Some(UnitQuaternion(rotation.to_array())),
                    translation: (position != Vec3::ZERO).then(|| position.to_array()),
                    ..node()
                });
            }
            let lights = Some(extensions::root::KhrLightsPunctual { lights });
            root.extensions = Some(extensions::root::Root { khr_lights_punctual: lights, ..Default::default() });
            used.push("KHR_lights_punctual");
            used.sort();
        }
        root.extensions_used = used.into_iter().map(String::from).collect();
        if !self.textures.is_empty() {
            let modes = [WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat];
            for &w in &modes {
                root.push(texture::Sampler {
                    mag_filter: Some(Valid(texture::MagFilter::Linear)),
                    min_filter: Some(Valid(texture::MinFilter::LinearMipmapLinear)),
                    name: None,
                    wrap_s: Valid(wrapping(w)),
                    wrap_t: Valid(wrapping(w)),
                    extensions: None,
                    extras: Default::default(),
                });
            }
            for (i, t) in self.textures.iter().enumerate() {
                let source = root.push(Image {
                    buffer_view: None,
                    mime_type: None,
                    name: Some(t.name.clone()),
                    uri: Some(texture_uri(i, &t.name)),
                    extensions: None,
                    extras: Default::default(),
                });
                let sampler = modes.iter().position(|&w| w == t.wrap).expect("every wrap mode has a sampler");
                root.push(texture::Texture {
                    name: None,
                    sampler: Some(Index::new(sampler as u32)),
                    source,
                    extensions: None,
                    extras: Default::default(),
                });
            }
        }
        let nodes = (0..root.nodes.len() as u32).map(Index::new).collect();
        root.scene =
            Some(root.push(Scene { extensions: None, extras: Default::default(), name: Some(name.into()), nodes }));
        root.push(Buffer {
            byte_length: enc.bin.len().into(),
            name: None,
            uri: Some(format!("{name}.bin")),
            extensions: None,
            extras: Default::default(),
        });
        root.buffer_views = enc.views;
        root.accessors = enc.accessors;
        (root, enc.bin)
    }

    /// Pushes the materials onto `root`; returns the extensions they use (sorted).
    // (gltf-json's extension structs gain fields with its cargo features: `..Default::default()`
    // keeps this building whichever a dependency turns on)
    #[allow(clippy::needless_update)]
    fn materials(&self, root: &mut Root) -> Vec<&'static str> {
        let (mut strength_used, mut specular_used) = (false, false);
        let info = |t: TextureId| texture::Info {
            index: Index::new(t.0),
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        };
        for m in &self.materials {
            let [r, g, b] = m.base_color;
            let pbr = PbrMetallicRoughness {
                base_color_factor: PbrBaseColorFactor([r, g, b, 1.0]),
                metallic_factor: StrengthFactor(m.metallic),
                roughness_factor: StrengthFactor(m.roughness),
                base_color_texture: m.base_color_texture.map(info),
                metallic_roughness_texture: m.metallic_roughness_texture.map(info),
                ..Default::default()
            };
            let mut mat = Material {
                name: Some(m.name.clone()),
                pbr_metallic_roughness: pbr,
                double_sided: m.double_sided,
                ..Default::default()
            };
            let mut ext = extensions::material::Material::default();
            // emissive = factor * strength with the factor's largest channel scaled to 1
            let peak = m.emissive.into_iter().fold(0.0f32, f32::max);
            if peak > 0.0 {
                mat.emissive_factor = EmissiveFactor(m.emissive.map(|c| c / peak));
                let strength = peak * m.emissive_strength;
                if strength != 1.0 {
                    let factor = extensions::material::EmissiveStrengthFactor(strength);
                    let e = extensions::material::EmissiveStrength { emissive_strength: factor, ..Default::default() };
                    ext.emissive_strength = Some(e);
                    strength_used = true;
                }
            }
            mat.emissive_texture = m.emissive_texture.map(info);
            if let Some(f) = m.specular {
                let factor = extensions::material::SpecularFactor(f);
                ext.specular = Some(extensions::material::Specular { specular_factor: factor, ..Default::default() });
                specular_used = true;
            }
            if ext.emissive_strength.is_some() || ext.specular.is_some() {
                mat.extensions = Some(ext);
            }
            root.push(mat);
        }
        let mut used = Vec::new();
        if strength_used {
            used.push("KHR_materials_emissive_strength");
        }
        if specular_used {
            used.push("KHR_materials_specular");
        }
        used
    }
}

/// A node with nothing set.
fn node() -> Node {
    Node {
        camera: None,
        children: None,
        extensions: None,
        extras: Default::default(),
        matrix: None,
        mesh: None,
        name: None,
        rotation: None,
        scale: None,
        translation: None,
        skin: None,
        weights: None,
    }
}

/// An `f32` as the JSON number with the shortest decimal that reads back to the same `f32`
/// (`0.1f32` is written `0.1`, not `0.10000000149011612`).
fn num(x: f32) -> Value {
    let shortest: f64 = format!("{x}").parse().expect("a finite f32 prints as a number");
    json!(shortest)
}

/// The photometric intensity (cd or lux) the loader turns back into `radiometric`: an `f32` `x`
/// with `x / LUMENS_PER_WATT == radiometric` when there is one near the product (as for every
/// committed scene's lights), else the nearest `f32` to the product (read back within an ulp:
/// not every `f32` is such a quotient).
fn photometric(radiometric: f32) -> f32 {
    let x = (f64::from(radiometric) * f64::from(LUMENS_PER_WATT)) as f32;
    let (mut up, mut down) = (x, x);
    for _ in 0..=4 {
        if let Some(c) = [up, down].into_iter().find(|c| c / LUMENS_PER_WATT == radiometric) {
            return c;
        }
        (up, down) = (up.next_up(), down.next_down());
    }
    x
}

/// A light's `KHR_lights_punctual` entry, its node position and direction.
fn light_entry(l: &PunctualLight) -> (Light, Vec3, Vec3) {
    let entry = |kind: LightType, power: Vec3, spot: Option<Spot>| {
        let peak = power.max_element();
        let color = if peak > 0.0 { power / peak } else { Vec3::ONE };
        Light {
            color: color.to_array(),
            extensions: None,
            extras: Default::default(),
            intensity: photometric(peak),
            name: None,
            range: None,
            spot,
            type_: Valid(kind),
        }
    };
    match *l {
        PunctualLight::Point { position, intensity } => {
            (entry(LightType::Point, intensity, None), position, Vec3::NEG_Z)
        }
        PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
            let spot = Spot { inner_cone_angle: inner_cone, outer_cone_angle: outer_cone };
            (entry(LightType::Spot, intensity, Some(spot)), position, direction)
        }
        PunctualLight::Directional { direction, irradiance } => {
            (entry(LightType::Directional, irradiance, None), Vec3::ZERO, direction)
        }
    }
}

/// glTF sampler wrapping mode.
fn wrapping(w: WrapMode) -> texture::WrappingMode {
    match w {
        WrapMode::Repeat => texture::WrappingMode::Repeat,
        WrapMode::ClampToEdge => texture::WrappingMode::ClampToEdge,
        WrapMode::MirroredRepeat => texture::WrappingMode::MirroredRepeat,
    }
}

/// Relative path of texture `i`: `textures/<i>_<name>.png`, the name reduced to `[A-Za-z0-9_-]`.
fn texture_uri(i: usize, name: &str) -> String {
    let clean: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    format!("textures/{i:02}_{clean}.png")
}

/// PNG bytes of a texture (fixed compression settings, so deterministic).
fn encode_png(p: &TexturePixels) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new(&mut out);
    match p {
        TexturePixels::Rgb(i) => enc.write_image(i.as_raw(), i.width(), i.height(), image::ExtendedColorType::Rgb8)?,
        TexturePixels::Rgba(i) => {
            enc.write_image(i.as_raw(), i.width(), i.height(), image::ExtendedColorType::Rgba8)?
        }
    }
    Ok(out)
}

/// Builds the binary buffer with its buffer views and accessors.
#[derive(Default)]
struct Encoder {
    bin: Vec<u8>,
    views: Vec<buffer::View>,
    accessors: Vec<Accessor>,
}

impl Encoder {
    /// Append `bytes` as a buffer view (4-byte aligned) with `target`; returns the view index.
    fn view(&mut self, bytes: &[u8], target: buffer::Target) -> Index<buffer::View> {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(buffer::View {
            buffer: Index::new(0),
            byte_length: bytes.len().into(),
            byte_offset: Some(offset.into()),
            byte_stride: None,
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: Default::default(),
        });
        Index::new(self.views.len() as u32 - 1)
    }

    /// An accessor of `count` elements of `ty` in `view`.
    fn accessor(
        &mut self,
        view: Index<buffer::View>,
        component: ComponentType,
        count: usize,
        ty: AccessorType,
    ) -> Accessor {
        Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: count.into(),
            component_type: Valid(GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(ty),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        }
    }

    /// A float accessor; `bounds` adds per-component min/max.
    fn floats(&mut self, data: &[f32], dim: usize, ty: AccessorType, bounds: bool) -> Index<Accessor> {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes, buffer::Target::ArrayBuffer);
        let mut acc = self.accessor(view, ComponentType::F32, data.len() / dim, ty);
        if bounds {
            let (mut lo, mut hi) = (vec![f32::INFINITY; dim], vec![f32::NEG_INFINITY; dim]);
            for (i, &v) in data.iter().enumerate() {
                lo[i % dim] = lo[i % dim].min(v);
                hi[i % dim] = hi[i % dim].max(v);
            }
            acc.min = Some(Value::Array(lo.into_iter().map(num).collect()));
            acc.max = Some(Value::Array(hi.into_iter().map(num).collect()));
        }
        self.accessors.push(acc);
        Index::new(self.accessors.len() as u32 - 1)
    }

    fn vec3(&mut self, v: &[Vec3], bounds: bool) -> Index<Accessor> {
        let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
        self.floats(&flat, 3, AccessorType::Vec3, bounds)
    }

    fn vec2(&mut self, v: &[Vec2]) -> Index<Accessor> {
        let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
        self.floats(&flat, 2, AccessorType::Vec2, false)
    }

    fn indices(&mut self, tris: &[[u32; 3]]) -> Index<Accessor> {
        let bytes: Vec<u8> = tris.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, buffer::Target::ElementArrayBuffer);
        let acc = self.accessor(view, ComponentType::U32, tris.len() * 3, AccessorType::Scalar);
        self.accessors.push(acc);
        Index::new(self.accessors.len() as u32 - 1)
    }
}

#[cfg(test)]
#[path = "gltf_write_tests.rs"]
pub(crate) mod tests;
