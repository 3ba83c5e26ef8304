//! glTF 2.0 loader (`.gltf` with external or data-URI buffers, and binary `.glb`).
//!
//! # What is read
//! - **Scene graph**: the default scene (or scene 0 when none is marked default). Node TRS and
//!   matrix transforms compose as `world = parent * local`. A mesh used by several nodes is
//!   emitted once per node (instancing is flattened). Everything ends up in one world-space
//!   [`TriangleMesh`](super::TriangleMesh).
//! - **Geometry**: every primitive of mode TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN (strips and
//!   fans are converted to triangles), indexed or not. POSITION must be float VEC3; NORMAL is
//!   used when present, otherwise area-weighted normals are generated
//!   ([`super::vertex_normals`]); TEXCOORD_0 (float, or normalised u8/u16) gives the UVs, zero
//!   when missing. Sparse accessors are supported.
//! - **Transforms**: positions by the world matrix; normals by its inverse transpose,
//!   renormalised. A world matrix with negative determinant (a mirror) swaps two corners of each
//!   triangle so that the counter-clockwise geometric normal still points outwards.
//! - **Materials** (see `gltf_material`): `pbrMetallicRoughness` base colour factor (linear, alpha
//!   dropped) and texture (sRGB, decoded to linear), metallic and roughness factors and the
//!   metallic-roughness texture (linear; G = roughness, B = metallic), `emissiveFactor` and
//!   `emissiveTexture` (sRGB) times `KHR_materials_emissive_strength`, `doubleSided`, and the
//!   `KHR_materials_specular` strength `specularFactor` (in [0, 1], default 1) as `specular`; its
//!   `specularColorFactor` and textures are ignored with a warning (our dielectric F0 is white,
//!   `0.04 specular`). Primitives without a material get [`Material::default`](super::Material).
//!   Images come from a relative URI, a data URI or a bufferView, PNG or JPEG; sampler wrap modes
//!   map to [`WrapMode`](super::WrapMode).
//! - **Lights** (`KHR_lights_punctual`): point, spot and directional, placed by their node's world
//!   transform; lights point down their local -Z. `color * intensity` is photometric (candela
//!   for point and spot, lux for directional) and divided by
//!   [`LUMENS_PER_WATT`](super::LUMENS_PER_WATT) (683 lm/W, Blender's convention) into our
//!   radiometric W/sr and W/m^2 (see [`PunctualLight`]).
//! - **Cameras**: perspective cameras become a [`Camera`] with `yfov` and the
//!   node's world transform with its scale removed (rigid only; a mirror is dropped too).
//!
//! # What is ignored
//! Light `range` (lights fall off with the inverse square law everywhere), orthographic cameras
//! (skipped with a warning), aspect ratio and clip planes, alpha mode and alpha cutoff, normal
//! and occlusion textures, vertex colours, tangents, skins (skinned meshes are placed by their
//! node transform), morph targets (the base shape is used), animations, texture filters, and
//! any extension that is only listed in `extensionsUsed` (a warning names it).
//!
//! # Errors
//! Every error names the file, the element (e.g. `mesh 2 "Chair" primitive 0 attribute
//! POSITION`) and the fix: malformed JSON or GLB, an `extensionsRequired` entry other than
//! `KHR_lights_punctual`, `KHR_materials_emissive_strength` and `KHR_materials_specular` (notably
//! `KHR_texture_transform` and mesh compression), a missing or short buffer, a missing or
//! undecodable image, points and lines primitives, non-finite positions, normals or UVs, indices
//! out of range, a texture that uses a texCoord set other than 0, and a scene without triangles.
//! Degenerate (zero-area) triangles are skipped with one warning per primitive instance.
//!
//! Units: glTF is metres, right-handed, +Y up; we keep its coordinates as they are.

use std::f32::consts::FRAC_PI_2;
use std::path::Path;

use glam::{Mat4, Quat, Vec3};

use super::gltf_material;
use super::gltf_mesh::Flattener;
use super::{Camera, PunctualLight, Scene};
use crate::error::SceneError;

/// Extensions whose content we read; any other required extension is an error.
const SUPPORTED_EXTENSIONS: &[&str] =
    &["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_specular"];

/// Load a `.gltf` or `.glb` file into a flattened world-space [`Scene`].
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    check_glb_length(path, &bytes)?;
    // parse without validation first so that an unsupported required extension gets our own
    // message rather than the crate's generic validation error
    let gltf = gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| parse_error(path, e))?;
    let mut warnings = Vec::new();
    check_version(path, gltf.document.as_json())?;
    check_extensions(path, gltf.document.as_json(), &mut warnings)?;
    check_position_accessors(path, gltf.document.as_json())?;
    check_images(path, gltf.document.as_json())?;
    let blob = gltf.blob;
    let mut json = gltf.document.into_json();
    // every required extension is one of ours now; the crate's validator would still reject
    // KHR_materials_specular, which gltf-json 1.4 reads but leaves out of its ENABLED_EXTENSIONS
    json.extensions_required.clear();
    let doc = gltf::Document::from_json(json).map_err(|e| parse_error(path, e))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = load_buffers(path, base, &doc, blob)?;

    let mut scene = Scene { warnings, source: path.to_path_buf(), ..Default::default() };
    scene.materials =
        gltf_material::load_materials(path, base, &doc, &buffers, &mut scene.textures, &mut scene.warnings)?;
    let root = doc.default_scene().or_else(|| doc.scenes().next()).ok_or_else(|| {
        SceneError::invalid(path, "scenes", "the file defines no scene; add a scene that lists the root nodes")
    })?;
    let mut walker =
        Walker { path, on_path: vec![false; doc.nodes().len()], flat: Flattener::new(path, &buffers, &mut scene) };
    for node in root.nodes() {
        walker.visit(node, Mat4::IDENTITY)?;
    }
    if scene.mesh.is_empty() {
        return Err(SceneError::invalid(
            path,
            label("scene", root.index(), root.name()),
            "the scene contains no (non-degenerate) triangles; check that its nodes reference meshes",
        ));
    }
    Ok(scene)
}

/// `kind index "name"`, the way every message names a glTF element.
pub(super) fn label(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {index} \"{n}\""),
        None => format!("{kind} {index}"),
    }
}

/// Map a parser or validator error to [`SceneError::Invalid`].
fn parse_error(path: &Path, e: gltf::Error) -> SceneError {
    match e {
        gltf::Error::Deserialize(e) => {
            SceneError::invalid(path, "JSON", format!("malformed glTF JSON: {e}; fix the file or re-export it"))
        }
        gltf::Error::Binary(e) => {
            SceneError::invalid(path, "GLB container", format!("malformed binary glTF: {e}; re-export the file"))
        }
        gltf::Error::Validation(errors) => {
            let list: Vec<String> = errors.iter().map(|(p, e)| format!("{p}: {e}")).collect();
            SceneError::invalid(path, "glTF validation", format!("{}; fix these elements", list.join("; ")))
        }
        e => SceneError::invalid(path, "glTF", e.to_string()),
    }
}

/// Reject files of another major glTF version than 2 (`asset.version`, and `asset.minVersion`
/// when given): glTF 1.0 files parse as JSON but mean other things.
fn check_version(path: &Path, root: &gltf::json::Root) -> Result<(), SceneError> {
    let asset = &root.asset;
    let major = |v: &str| v.split('.').next().and_then(|m| m.parse::<u32>().ok());
    for (field, v) in
        [("asset.version", Some(asset.version.as_str())), ("asset.minVersion", asset.min_version.as_deref())]
    {
        let Some(v) = v else { continue };
        if major(v) != Some(2) {
            return Err(SceneError::unsupported(
                path,
                field,
                format!("\"{v}\": only glTF 2.x files are read; re-export the scene as glTF 2.0"),
            ));
        }
    }
    Ok(())
}

/// Reject required extensions we do not implement; warn about used ones we ignore.
fn check_extensions(path: &Path, root: &gltf::json::Root, warnings: &mut Vec<String>) -> Result<(), SceneError> {
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            let fix = match ext.as_str() {
                "KHR_texture_transform" => "texture transforms are not supported; bake them into the UVs and re-export",
                "KHR_draco_mesh_compression" | "EXT_meshopt_compression" | "KHR_mesh_quantization" => {
                    "compressed or quantized meshes are not supported; re-export without mesh compression"
                }
                _ => "re-export the file without this extension",
            };
            return Err(SceneError::unsupported(
                path,
                format!("extensionsRequired \"{ext}\""),
                format!(
                    "extension {ext} is required by the file but not implemented (supported: {}); {fix}",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    for ext in &root.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(format!("{}: extension {ext} is used but not supported; it is ignored", path.display()));
        }
    }
    Ok(())
}

/// Check every primitive's POSITION accessor index before the crate's validator runs: it reads
/// that accessor's bounds without checking the index (gltf-json 1.4 panics on one out of range).
fn check_position_accessors(path: &Path, root: &gltf::json::Root) -> Result<(), SceneError> {
    use gltf::json::mesh::Semantic;
    use gltf::json::validation::Checked;
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(a) = prim.attributes.get(&Checked::Valid(Semantic::Positions)).filter(|a| a.value() >= n) {
                return Err(SceneError::invalid(
                    path,
                    format!("{} primitive {p} attribute POSITION", label("mesh", m, mesh.name.as_deref())),
                    format!(
                        "accessor {} is out of range: the file has {n} accessors; point POSITION at the primitive's \
                         vertex positions or re-export the file",
                        a.value()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// A GLB's declared total length must cover its header and fit in the file (gltf 1.4 subtracts
/// the header size from it unchecked, which panics with overflow checks on).
fn check_glb_length(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let declared = bytes.get(8..12).map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")) as usize);
    match declared {
        Some(n) if (20..=bytes.len()).contains(&n) => Ok(()),
        _ => Err(SceneError::invalid(
            path,
            "GLB container",
            format!(
                "the header declares {} bytes, the file has {}; the file is truncated or damaged, re-export it",
                declared.map_or("no length".into(), |n| n.to_string()),
                bytes.len()
            ),
        )),
    }
}

/// Every image needs a source, a `uri` or a `bufferView` (gltf 1.4 panics on one with neither).
fn check_images(path: &Path, root: &gltf::json::Root) -> Result<(), SceneError> {
    for (i, image) in root.images.iter().enumerate() {
        if image.uri.is_none() && image.buffer_view.is_none() {
            return Err(SceneError::invalid(
                path,
                label("image", i, image.name.as_deref()),
                "has neither a uri nor a bufferView; point it at the texture file or re-export the file",
            ));
        }
    }
    Ok(())
}

/// Read every buffer: the GLB blob, a data URI or a file relative to the scene file.
fn load_buffers(
    path: &Path,
    base: &Path,
    doc: &gltf::Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let el = label("buffer", buffer.index(), buffer.name());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                SceneError::invalid(
                    path,
                    &el,
                    "refers to the GLB binary chunk, but the file has none (or it is used twice)",
                )
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(path, base, uri, &el)?,
        };
        if buffer.length() == 0 {
            return Err(SceneError::invalid(
                path,
                format!("{el} byteLength"),
                "is missing or 0 (glTF requires the buffer's size, at least 1); re-export the file",
            ));
        }
        if data.len() < buffer.length() {
            return Err(SceneError::invalid(
                path,
                &el,
                format!(
                    "holds {} bytes but byteLength is {}; the buffer file is truncated or stale",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Read the bytes a URI points at: a base64 data URI, or a file path (percent-encoded) relative
/// to `base`, the scene file's folder. `el` names the referring element for messages.
pub(super) fn read_uri(path: &Path, base: &Path, uri: &str, el: &str) -> Result<Vec<u8>, SceneError> {
    if uri.starts_with("data:") {
        return gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), None).map(|d| d.0).map_err(|e| {
            SceneError::invalid(path, el, format!("data URI cannot be decoded ({e}); it must be base64"))
        });
    }
    if uri.contains("://") {
        return Err(SceneError::unsupported(
            path,
            el,
            format!("URI \"{uri}\": only relative paths and data URIs are read; download the file next to the scene"),
        ));
    }
    let file = base.join(percent_decode(uri));
    std::fs::read(&file).map_err(|e| {
        SceneError::invalid(
            path,
            el,
            format!(
                "file {} (uri \"{uri}\") cannot be read: {e}; put it next to the scene file or fix the uri",
                file.display()
            ),
        )
    })
}

/// Decode `%XX` escapes of a URI path (invalid escapes are kept as they are).
pub(super) fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Depth-first walk of the node hierarchy, composing world transforms.
struct Walker<'a, 's> {
    path: &'a Path,
    /// Nodes on the current root-to-node path, to reject cycles.
    on_path: Vec<bool>,
    flat: Flattener<'a, 's>,
}

impl Walker<'_, '_> {
    fn visit(&mut self, node: gltf::Node, parent: Mat4) -> Result<(), SceneError> {
        let el = label("node", node.index(), node.name());
        if self.on_path[node.index()] {
            return Err(SceneError::invalid(
                self.path,
                el,
                "the node hierarchy has a cycle (the node is its own ancestor)",
            ));
        }
        let local = match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => Mat4::from_cols_array_2d(&matrix),
            gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
                Mat4::from_scale_rotation_translation(
                    Vec3::from(scale),
                    Quat::from_array(rotation).normalize(),
                    Vec3::from(translation),
                )
            }
        };
        let world = parent * local;
        if !world.is_finite() {
            return Err(SceneError::invalid(
                self.path,
                el,
                "world transform is not finite (zero rotation quaternion or huge values); fix the node transform",
            ));
        }
        if let Some(mesh) = node.mesh() {
            self.flat.mesh(mesh, world)?;
        }
        if let Some(light) = node.light() {
            let l = punctual_light(self.path, &light, world)?;
            self.flat.scene.lights.push(l);
        }
        if let Some(camera) = node.camera() {
            self.camera(&camera, &el, world)?;
        }
        self.on_path[node.index()] = true;
        for child in node.children() {
            self.visit(child, world)?;
        }
        self.on_path[node.index()] = false;
        Ok(())
    }

    /// A perspective camera with the rigid part of the node transform; orthographic is skipped.
    fn camera(&mut self, camera: &gltf::Camera, node_el: &str, world: Mat4) -> Result<(), SceneError> {
        let el = label("camera", camera.index(), camera.name());
        match camera.projection() {
            gltf::camera::Projection::Perspective(p) => {
                if !(p.yfov() > 0.0 && p.yfov() < std::f32::consts::PI) {
                    return Err(SceneError::invalid(
                        self.path,
                        format!("{el} perspective.yfov"),
                        format!("{} is not a field of view; give the vertical angle in radians, in (0, pi)", p.yfov()),
                    ));
                }
                // we render with the image's own aspect and no clipping planes, but values the
                // glTF specification forbids mean a broken export
                let near_far_ok = p.znear() > 0.0 && p.zfar().is_none_or(|f| f > p.znear());
                if !near_far_ok || p.aspect_ratio().is_some_and(|a| !(a > 0.0 && a.is_finite())) {
                    return Err(SceneError::invalid(
                        self.path,
                        format!("{el} perspective"),
                        format!(
                            "znear {}, zfar {:?}, aspectRatio {:?}: glTF requires znear > 0, zfar > znear and \
                             aspectRatio > 0; fix the camera or re-export the file",
                            p.znear(),
                            p.zfar(),
                            p.aspect_ratio()
                        ),
                    ));
                }
                // strip scale (and shear): keep rotation and translation only
                let (_, rotation, translation) = world.to_scale_rotation_translation();
                let name = camera.name().map(str::to_string).unwrap_or_else(|| el.clone());
                let to_world = Mat4::from_rotation_translation(rotation.normalize(), translation);
                self.flat.scene.cameras.push(Camera { name, to_world, yfov: p.yfov() });
            }
            gltf::camera::Projection::Orthographic(_) => self.flat.scene.warnings.push(format!(
                "{}: {el} on {node_el}: orthographic cameras are not supported; skipped",
                self.path.display()
            )),
        }
        Ok(())
    }
}

/// A `KHR_lights_punctual` light placed by its node's world transform (lights look down -Z).
fn punctual_light(
    path: &Path,
    light: &gltf::khr_lights_punctual::Light,
    world: Mat4,
) -> Result<PunctualLight, SceneError> {
    use gltf::khr_lights_punctual::Kind;
    let el = label("light", light.index(), light.name());
    // photometric in the file, radiometric here
    let power = Vec3::from(light.color()) * (light.intensity() / super::LUMENS_PER_WATT);
    if !power.is_finite() || power.min_element() < 0.0 {
        return Err(SceneError::invalid(path, el, "color and intensity must be finite and non-negative"));
    }
    if let Some(range) = light.range().filter(|r| !(*r > 0.0)) {
        return Err(SceneError::invalid(
            path,
            format!("{el} range"),
            format!("{range} must be > 0 (or absent: no limit)"),
        ));
    }
    let position = world.transform_point3(Vec3::ZERO);
    let direction = world.transform_vector3(Vec3::NEG_Z).try_normalize().ok_or_else(|| {
        SceneError::invalid(path, &el, "the node transform has zero scale, so the light has no direction")
    });
    Ok(match light.kind() {
        Kind::Point => PunctualLight::Point { position, intensity: power },
        Kind::Directional => PunctualLight::Directional { direction: direction?, irradiance: power },
        Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            if !(0.0 <= inner_cone_angle && inner_cone_angle < outer_cone_angle && outer_cone_angle <= FRAC_PI_2) {
                return Err(SceneError::invalid(
                    path,
                    el,
                    format!(
                        "spot cone angles {inner_cone_angle} (inner) and {outer_cone_angle} (outer) \
                         must satisfy 0 <= inner < outer <= pi/2"
                    ),
                ));
            }
            PunctualLight::Spot {
                position,
                direction: direction?,
                intensity: power,
                inner_cone: inner_cone_angle,
                outer_cone: outer_cone_angle,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::super::gltf_fixture::{self as fixture, assert_close, temp_dir, Doc};
    use super::*;

    /// sin 45 deg and cos 45 deg, for quarter-turn quaternions.
    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;

    fn doc_with_triangle() -> Doc {
        let mut d = Doc::default();
        d.triangle("");
        d.node(r#"{"mesh":0}"#);
        d
    }

    #[test]
    fn external_bin_buffer_loads() {
        let dir = temp_dir("extbin");
        let s = load(&doc_with_triangle().write_external(&dir, "tri")).unwrap();
        assert_eq!(s.mesh.len(), 1);
        assert_eq!(s.mesh.positions[1], Vec3::X);
        assert_eq!(s.mesh.normals[2], Vec3::Z);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn punctual_lights_follow_their_nodes() {
        let mut d = doc_with_triangle();
        d.extra.push(r#""extensionsUsed":["KHR_lights_punctual"]"#.into());
        d.extra.push(
            r#""extensions":{"KHR_lights_punctual":{"lights":[
            {"type":"point","color":[1,0.5,0.25],"intensity":8,"range":3},
            {"type":"spot","intensity":2,"spot":{"innerConeAngle":0.2,"outerConeAngle":0.5}},
            {"type":"directional","color":[0,1,0],"intensity":3}]}}"#
                .into(),
        );
        d.node(r#"{"translation":[1,2,3],"extensions":{"KHR_lights_punctual":{"light":0}}}"#);
        // +90 deg about X turns local -Z into +Y
        d.node(&format!(
            r#"{{"translation":[0,0,4],"rotation":[{H},0,0,{H}],"extensions":{{"KHR_lights_punctual":{{"light":1}}}}}}"#
        ));
        // directional under a parent with a half turn about Y: -Z becomes +Z
        d.node(r#"{"extensions":{"KHR_lights_punctual":{"light":2}}}"#);
        d.node(r#"{"rotation":[0,1,0,0],"translation":[9,9,9],"children":[3]}"#);
        d.roots = Some(vec![0, 1, 2, 4]);
        let s = load(&d.write_embedded(&temp_dir("lights"), "lights")).unwrap();
        assert_eq!(s.lights.len(), 3);
        match &s.lights[0] {
            PunctualLight::Point { position, intensity } => {
                assert_close(*position, Vec3::new(1.0, 2.0, 3.0));
                assert_close(*intensity * 683.0, Vec3::new(8.0, 4.0, 2.0));
            }
            l => panic!("expected a point light, got {l:?}"),
        }
        match &s.lights[1] {
            PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
                assert_close(*position, Vec3::new(0.0, 0.0, 4.0));
                assert_close(*direction, Vec3::Y);
                assert_close(*intensity * 683.0, Vec3::splat(2.0));
                assert_eq!((*inner_cone, *outer_cone), (0.2, 0.5));
            }
            l => panic!("expected a spot light, got {l:?}"),
        }
        match &s.lights[2] {
            PunctualLight::Directional { direction, irradiance } => {
                assert_close(*direction, Vec3::Z);
                assert_close(*irradiance * 683.0, Vec3::new(0.0, 3.0, 0.0));
            }
            l => panic!("expected a directional light, got {l:?}"),
        }
    }

    #[test]
    fn perspective_camera_pose_without_scale_and_ortho_skipped() {
        let mut d = doc_with_triangle();
        d.extra.push(
            r#""cameras":[{"name":"Main","type":"perspective","perspective":{"yfov":0.8,"znear":0.1}},
            {"type":"orthographic","orthographic":{"xmag":1,"ymag":1,"znear":0.1,"zfar":10}}]"#
                .into(),
        );
        // quarter turn about Y, scaled by 2: the camera then looks down world -X
        d.node(&format!(r#"{{"camera":0,"translation":[0,1,5],"rotation":[0,{H},0,{H}],"scale":[2,2,2]}}"#));
        d.node(r#"{"camera":1}"#);
        let s = load(&d.write_embedded(&temp_dir("camera"), "camera")).unwrap();
        assert_eq!(s.cameras.len(), 1);
        let c = &s.cameras[0];
        assert_eq!(c.name, "Main");
        assert_eq!(c.yfov, 0.8);
        assert_close(c.origin(), Vec3::new(0.0, 1.0, 5.0));
        let forward = c.to_world.transform_vector3(Vec3::NEG_Z);
        assert_close(forward, Vec3::NEG_X);
        assert_close(c.to_world.transform_vector3(Vec3::Y), Vec3::Y);
        assert_eq!(s.warnings.len(), 1);
        assert!(s.warnings[0].contains("orthographic") && s.warnings[0].contains("camera 1"), "{:?}", s.warnings);
    }

    #[test]
    fn a_camera_without_a_field_of_view_is_invalid() {
        let dir = temp_dir("yfov");
        for yfov in ["0", "-0.5", "3.5"] {
            let mut d = doc_with_triangle();
            d.extra
                .push(format!(r#""cameras":[{{"type":"perspective","perspective":{{"yfov":{yfov},"znear":0.1}}}}]"#));
            d.node(r#"{"camera":0}"#);
            let e = load(&d.write_embedded(&dir, "cam")).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, SceneError::Invalid { .. }), "{msg}");
            assert!(msg.contains("camera 0 perspective.yfov") && msg.contains("radians"), "{msg}");
        }
    }

    #[test]
    fn a_gltf_1_file_is_unsupported() {
        let dir = temp_dir("v1");
        let d = doc_with_triangle();
        let text = d.json(None);
        assert!(text.contains(r#""version":"2.0""#));
        for (from, to) in [
            (r#""version":"2.0""#, r#""version":"1.0""#),
            (r#""version":"2.0""#, r#""version":"2.0","minVersion":"3.0""#),
        ] {
            let path = fixture::write(&dir, "old.gltf", text.replace(from, to).as_bytes());
            let e = load(&path).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, SceneError::Unsupported { .. }) && msg.contains("glTF 2.0"), "{msg}");
        }
    }

    #[test]
    fn required_unsupported_extension_is_an_error_used_only_warns() {
        let dir = temp_dir("ext");
        let mut d = doc_with_triangle();
        d.extra.push(r#""extensionsUsed":["KHR_texture_transform"]"#.into());
        let s = load(&d.write_embedded(&dir, "used")).unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("KHR_texture_transform")), "{:?}", s.warnings);

        d.extra.push(r#""extensionsRequired":["KHR_texture_transform"]"#.into());
        let e = load(&d.write_embedded(&dir, "required")).unwrap_err();
        assert!(matches!(e, SceneError::Unsupported { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("extensionsRequired \"KHR_texture_transform\"") && msg.contains("UVs"), "{msg}");
    }

    #[test]
    fn required_materials_specular_loads() {
        let mut d = Doc::default();
        d.triangle(r#","material":0"#);
        d.node(r#"{"mesh":0}"#);
        d.extra.push(
            r#""extensionsUsed":["KHR_materials_specular"],"extensionsRequired":["KHR_materials_specular"],
            "materials":[{"extensions":{"KHR_materials_specular":{"specularFactor":0.5}}}]"#
                .into(),
        );
        let s = load(&d.write_embedded(&temp_dir("spec"), "required")).unwrap();
        assert_eq!(s.materials[0].specular, 0.5);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn missing_bin_file_names_buffer_and_file() {
        let dir = temp_dir("nobin");
        let path = doc_with_triangle().write_external(&dir, "tri");
        std::fs::remove_file(dir.join("tri.bin")).unwrap();
        let e = load(&path).unwrap_err();
        assert!(matches!(e, SceneError::Invalid { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("buffer 0") && msg.contains("tri.bin") && msg.contains("tri.gltf"), "{msg}");
    }

    #[test]
    fn malformed_json_and_empty_scene_are_invalid() {
        let dir = temp_dir("bad");
        let path = fixture::write(&dir, "bad.gltf", br#"{"asset":{"version":"2.0"},"nodes":[{]}"#);
        let e = load(&path).unwrap_err();
        assert!(matches!(e, SceneError::Invalid { ref element, .. } if element == "JSON"), "{e}");
        assert!(e.to_string().contains("line 1"), "{e}");

        let mut d = Doc::default();
        d.node(r#"{"name":"Empty"}"#);
        let e = load(&d.write_embedded(&dir, "empty")).unwrap_err();
        assert!(
            matches!(e, SceneError::Invalid { .. }) && e.to_string().contains("no (non-degenerate) triangles"),
            "{e}"
        );

        let e = load(&dir.join("absent.gltf")).unwrap_err();
        assert!(matches!(e, SceneError::Io { .. }), "{e}");
    }

    #[test]
    fn position_accessor_out_of_range_is_invalid_not_a_panic() {
        let dir = temp_dir("posrange");
        let mut d = Doc::default();
        d.mesh("Bad", &[0.0; 9], None, None, "");
        d.meshes[0] = d.meshes[0].replace(r#""POSITION":0"#, r#""POSITION":99"#);
        d.node(r#"{"mesh":0}"#);
        let e = load(&d.write_embedded(&dir, "bad")).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, SceneError::Invalid { .. }), "{msg}");
        assert!(
            msg.contains("bad.gltf")
                && msg.contains("mesh 0 \"Bad\" primitive 0 attribute POSITION")
                && msg.contains("accessor 99 is out of range: the file has 1 accessors"),
            "{msg}"
        );
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("my%20mesh.bin"), "my mesh.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("a%zzb"), "a%zzb");
    }
}
