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
//! Output is deterministic: JSON keys are sorted (serde_json's default map), floats are written
//! as the shortest decimal that reads back to the same `f32`, and PNG encoding has no timestamps.
//! Every file is written atomically ([`crate::image_io::write_atomic`]); the `.gltf` goes last,
//! so a reader never sees a `.gltf` whose buffer or images are missing.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::{Mat4, Quat, Vec2, Vec3};
use serde_json::{json, Map, Value};

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
        let (json, bin) = self.encode(name);
        let bin_path = dir.join(format!("{name}.bin"));
        write_atomic(&bin_path, &bin)?;
        let mut textures = Vec::new();
        for (i, t) in self.textures.iter().enumerate() {
            let path = dir.join(texture_uri(i, &t.name));
            write_atomic(&path, &encode_png(&t.pixels).with_context(|| format!("encoding texture {}", t.name))?)?;
            textures.push(path);
        }
        let gltf = dir.join(format!("{name}.gltf"));
        let mut text = serde_json::to_string_pretty(&json)?;
        text.push('\n');
        write_atomic(&gltf, text.as_bytes())?;
        Ok(WrittenScene { gltf, bin: bin_path, textures })
    }

    /// The glTF JSON and the binary buffer (no I/O).
    pub fn encode(&self, name: &str) -> (Value, Vec<u8>) {
        let mut enc = Encoder::default();
        let (mut meshes, mut nodes) = (Vec::new(), Vec::new());
        for m in self.meshes.iter().filter(|m| !m.indices.is_empty()) {
            let pos = enc.vec3(&m.positions, true);
            let nrm = enc.vec3(&m.normals, false);
            let uv = enc.vec2(&m.uvs);
            let idx = enc.indices(&m.indices);
            meshes.push(json!({
                "name": m.name,
                "primitives": [{
                    "attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv},
                    "indices": idx,
                    "material": m.material.0,
                    "mode": 4,
                }],
            }));
            nodes.push(json!({"name": m.name, "mesh": meshes.len() - 1}));
        }
        let mut root = Map::new();
        root.insert("asset".into(), json!({"version": "2.0", "generator": "evblur scenegen"}));
        if let Some(c) = &self.camera {
            let mut persp = json!({"yfov": num(c.yfov), "znear": num(c.znear)});
            if let Some(a) = c.aspect {
                persp["aspectRatio"] = num(a);
            }
            root.insert("cameras".into(), json!([{"name": c.name, "type": "perspective", "perspective": persp}]));
            let matrix: Vec<Value> = c.to_world.to_cols_array().into_iter().map(num).collect();
            nodes.push(json!({"name": c.name, "camera": 0, "matrix": matrix}));
        }
        let (materials, mut used) = self.materials_json();
        if !self.lights.is_empty() {
            let mut lights = Vec::new();
            for (i, l) in self.lights.iter().enumerate() {
                let (json, position, direction) = light_json(l);
                lights.push(json);
                // the node's local -Z is the light direction
                let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, direction.normalize());
                let mut node = json!({
                    "name": format!("light_{i}"),
                    "extensions": {"KHR_lights_punctual": {"light": i}},
                    "rotation": rotation.to_array().map(num),
                });
                if position != Vec3::ZERO {
                    node["translation"] = json!(position.to_array().map(num));
                }
                nodes.push(node);
            }
            root.insert("extensions".into(), json!({"KHR_lights_punctual": {"lights": lights}}));
            used.push("KHR_lights_punctual");
            used.sort();
        }
        if !used.is_empty() {
            root.insert("extensionsUsed".into(), json!(used));
        }
        root.insert("materials".into(), Value::Array(materials));
        if !self.textures.is_empty() {
            let modes = [WrapMode::Repeat, WrapMode::ClampToEdge, WrapMode::MirroredRepeat];
            let samplers: Vec<Value> = modes
                .iter()
                .map(|&w| json!({"magFilter": 9729, "minFilter": 9987, "wrapS": wrap_code(w), "wrapT": wrap_code(w)}))
                .collect();
            let images: Vec<Value> = self
                .textures
                .iter()
                .enumerate()
                .map(|(i, t)| json!({"name": t.name, "uri": texture_uri(i, &t.name)}))
                .collect();
            let textures: Vec<Value> = self
                .textures
                .iter()
                .enumerate()
                .map(|(i, t)| json!({"source": i, "sampler": modes.iter().position(|&w| w == t.wrap).unwrap()}))
                .collect();
            root.insert("samplers".into(), Value::Array(samplers));
            root.insert("images".into(), Value::Array(images));
            root.insert("textures".into(), Value::Array(textures));
        }
        root.insert("meshes".into(), Value::Array(meshes));
        let node_ids: Vec<usize> = (0..nodes.len()).collect();
        root.insert("nodes".into(), Value::Array(nodes));
        root.insert("scene".into(), json!(0));
        root.insert("scenes".into(), json!([{"name": name, "nodes": node_ids}]));
        root.insert("buffers".into(), json!([{"byteLength": enc.bin.len(), "uri": format!("{name}.bin")}]));
        root.insert("bufferViews".into(), Value::Array(enc.views));
        root.insert("accessors".into(), Value::Array(enc.accessors));
        (Value::Object(root), enc.bin)
    }

    /// Material JSON entries and the extensions they use (sorted).
    fn materials_json(&self) -> (Vec<Value>, Vec<&'static str>) {
        let (mut strength_used, mut specular_used) = (false, false);
        let tex = |t: TextureId| json!({"index": t.0});
        let out = self
            .materials
            .iter()
            .map(|m| {
                let [r, g, b] = m.base_color.map(num);
                let mut pbr = json!({
                    "baseColorFactor": [r, g, b, 1.0],
                    "metallicFactor": num(m.metallic),
                    "roughnessFactor": num(m.roughness),
                });
                if let Some(t) = m.base_color_texture {
                    pbr["baseColorTexture"] = tex(t);
                }
                if let Some(t) = m.metallic_roughness_texture {
                    pbr["metallicRoughnessTexture"] = tex(t);
                }
                let mut v = json!({"name": m.name, "pbrMetallicRoughness": pbr, "doubleSided": m.double_sided});
                let mut ext = Map::new();
                // emissive = factor * strength with the factor's largest channel scaled to 1
                let peak = m.emissive.into_iter().fold(0.0f32, f32::max);
                if peak > 0.0 {
                    let factor = m.emissive.map(|c| num(c / peak));
                    v["emissiveFactor"] = json!(factor);
                    let strength = peak * m.emissive_strength;
                    if strength != 1.0 {
                        ext.insert(
                            "KHR_materials_emissive_strength".into(),
                            json!({"emissiveStrength": num(strength)}),
                        );
                        strength_used = true;
                    }
                }
                if let Some(t) = m.emissive_texture {
                    v["emissiveTexture"] = tex(t);
                }
                if let Some(s) = m.specular {
                    ext.insert("KHR_materials_specular".into(), json!({"specularFactor": num(s)}));
                    specular_used = true;
                }
                if !ext.is_empty() {
                    v["extensions"] = Value::Object(ext);
                }
                v
            })
            .collect();
        let mut used = Vec::new();
        if strength_used {
            used.push("KHR_materials_emissive_strength");
        }
        if specular_used {
            used.push("KHR_materials_specular");
        }
        (out, used)
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
fn light_json(l: &PunctualLight) -> (Value, Vec3, Vec3) {
    let entry = |kind: &str, power: Vec3| {
        let peak = power.max_element();
        let color = if peak > 0.0 { power / peak } else { Vec3::ONE };
        json!({"type": kind, "color": color.to_array().map(num), "intensity": num(photometric(peak))})
    };
    match *l {
        PunctualLight::Point { position, intensity } => (entry("point", intensity), position, Vec3::NEG_Z),
        PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
            let mut v = entry("spot", intensity);
            v["spot"] = json!({"innerConeAngle": num(inner_cone), "outerConeAngle": num(outer_cone)});
            (v, position, direction)
        }
        PunctualLight::Directional { direction, irradiance } => {
            (entry("directional", irradiance), Vec3::ZERO, direction)
        }
    }
}

/// glTF sampler wrap code.
fn wrap_code(w: WrapMode) -> u32 {
    match w {
        WrapMode::Repeat => 10497,
        WrapMode::ClampToEdge => 33071,
        WrapMode::MirroredRepeat => 33648,
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
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Encoder {
    /// Append `bytes` as a buffer view (4-byte aligned) with `target`; returns the view index.
    fn view(&mut self, bytes: &[u8], target: u32) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len(), "target": target}));
        self.views.len() - 1
    }

    /// A float accessor; `bounds` adds per-component min/max.
    fn floats(&mut self, data: &[f32], dim: usize, ty: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes, 34962);
        let mut acc = json!({"bufferView": view, "componentType": 5126, "count": data.len() / dim, "type": ty});
        if bounds {
            let (mut lo, mut hi) = (vec![f32::INFINITY; dim], vec![f32::NEG_INFINITY; dim]);
            for (i, &v) in data.iter().enumerate() {
                lo[i % dim] = lo[i % dim].min(v);
                hi[i % dim] = hi[i % dim].max(v);
            }
            acc["min"] = Value::Array(lo.into_iter().map(num).collect());
            acc["max"] = Value::Array(hi.into_iter().map(num).collect());
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    fn vec3(&mut self, v: &[Vec3], bounds: bool) -> usize {
        let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
        self.floats(&flat, 3, "VEC3", bounds)
    }

    fn vec2(&mut self, v: &[Vec2]) -> usize {
        let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
        self.floats(&flat, 2, "VEC2", false)
    }

    fn indices(&mut self, tris: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = tris.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, 34963);
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5125, "count": tris.len() * 3, "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

#[cfg(test)]
#[path = "gltf_write_tests.rs"]
pub(crate) mod tests;
