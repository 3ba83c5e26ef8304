//! Export to Mitsuba 3, the reference renderer of the path-tracer check.
//!
//! [`export_mitsuba`] writes into a directory:
//! - `mesh_<m>.ply`: the triangles of material `m` as binary little-endian PLY with
//!   `x y z nx ny nz u v` per vertex (Mitsuba's PLY loader keeps `uv` as it is; its `bitmap`
//!   texture, like ours, puts uv (0,0) at the top-left texel, so no flip is needed);
//!   `mesh_<m>_back.ply` is the winding-flipped copy of a double-sided emitter (see below);
//! - `tex_<m>_<slot>.exr`: linear float textures with the material factor baked in (`raw: true`);
//! - `envmap.exr`: the environment map, when there is one;
//! - `scene.json`: `{"format": "evblur-mitsuba-1", "scene": {...}}` where `scene` is the dict for
//!   `mitsuba.load_dict` except for two encodings that `tests/mitsuba/render.py` resolves:
//!   `{"look_at": {"origin", "target", "up"}}` and `{"matrix": [4 rows]}` stand for
//!   `ScalarTransform4f`s, and every `filename` is relative to `scene.json`.
//!
//! The mapping (it reproduces our renderer exactly or refuses with
//! [`ExportError::NotExportable`]):
//! - integrator `path` with `max_depth` (same convention; `u32::MAX` -> -1) and `rr_depth`;
//! - sensor `perspective`: our camera looks down local -Z with +Y up, Mitsuba's down +Z, so we
//!   emit `look_at(origin, origin + forward, up)`; `fov` is our full vertical FOV with
//!   `fov_axis = "y"`; film `hdrfilm` with a `box` filter; sampler `independent`;
//! - `metallic = 0, specular = 0` -> `diffuse`; `metallic = 1` -> `roughconductor` (GGX,
//!   `alpha = roughness^2`, `material = "none"`, `specular_reflectance` = base colour). The latter
//!   equals our Schlick metal only for a white base colour (F = 1 both ways), so reference scenes
//!   use white metals. Everything is wrapped in `twosided`: our surfaces reflect on both sides.
//!   Other metallic/specular mixes and metallic-roughness textures are not exportable.
//! - emission -> `area` emitter radiating along the counter-clockwise normal (Mitsuba, like us,
//!   is one-sided). A double-sided emitter gets a second, winding-flipped copy moved `1e-5` x
//!   the scene diagonal behind the first, so each side's rays hit the copy that faces them.
//! - point -> `point` (`intensity` in W/sr on both sides), directional -> `directional`
//!   (`irradiance`), spot -> `spot` with `cutoff_angle` = outer and `beam_width` = inner cone
//!   (degrees). Mitsuba's spot falloff between the cones is linear in angle, ours is glTF's
//!   smooth curve: spots match only outside the transition band.
//! - constant environment -> `constant`; map -> `envmap` with the same `to_world`. Mitsuba's
//!   envmap lookup uses texel centres along u (as ours) but puts rows 0 and h-1 on the poles
//!   (`y = v (h - 1)`), where ours puts row centres at `(j + 1/2) / h` and clamps at the poles.
//!   The exporter therefore writes a `2h + 1`-row map whose odd rows are ours and whose even
//!   rows (the poles and our row boundaries) are the mean of their neighbours: Mitsuba's
//!   piecewise-linear lookup through those knots is then exactly ours.

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3, Vec4};
use serde_json::{json, Map, Value};

use super::ExportError;
use crate::render::film::RenderSettings;
use crate::scene::{Environment, Material, PunctualLight, Scene, TextureRef, WrapMode};

/// Export `scene` as seen with `settings` to `out_dir` (created if missing); returns the path
/// of the written `scene.json`. See the module documentation for the file layout and mapping.
pub fn export_mitsuba(scene: &Scene, settings: &RenderSettings, out_dir: &Path) -> Result<PathBuf, ExportError> {
    std::fs::create_dir_all(out_dir).map_err(|e| ExportError::write(out_dir, e))?;
    let mut dict = Map::new();
    dict.insert("type".into(), json!("scene"));
    dict.insert("integrator".into(), integrator(settings));
    dict.insert("sensor".into(), sensor(settings));

    // one shape per material (plus a flipped copy for double-sided emitters)
    let diagonal = bbox_diagonal(&scene.mesh.positions);
    for (m, material) in scene.materials.iter().enumerate() {
        let tris: Vec<[u32; 3]> = scene
            .mesh
            .indices
            .iter()
            .zip(&scene.mesh.material)
            .filter(|(_, &mat)| mat as usize == m)
            .map(|(t, _)| *t)
            .collect();
        if tris.is_empty() {
            continue;
        }
        let element = format!("material {m} \"{}\"", material.name);
        let bsdf = bsdf(scene, material, m, &element, out_dir)?;
        let emitter = emitter(scene, material, m, &element, out_dir)?;
        let file = format!("mesh_{m}.ply");
        write_ply(&out_dir.join(&file), scene, &tris, false, 0.0)?;
        dict.insert(format!("shape_{m}"), shape(&file, &bsdf, emitter.as_ref()));
        if let (Some(emitter), true) = (&emitter, material.double_sided) {
            let file = format!("mesh_{m}_back.ply");
            write_ply(&out_dir.join(&file), scene, &tris, true, 1e-5 * diagonal)?;
            dict.insert(format!("shape_{m}_back"), shape(&file, &bsdf, Some(emitter)));
        }
    }

    for (i, light) in scene.lights.iter().enumerate() {
        dict.insert(format!("light_{i}"), punctual(light));
    }
    if let Some(env) = environment(&scene.environment, out_dir)? {
        dict.insert("environment".into(), env);
    }

    let root = json!({ "format": "evblur-mitsuba-1", "scene": Value::Object(dict) });
    let path = out_dir.join("scene.json");
    std::fs::write(&path, to_text(&root)).map_err(|e| ExportError::write(&path, e))?;
    Ok(path)
}

/// Pretty-printed JSON with a final newline. Non-finite numbers became `null` when the `Value`
/// was built, which Mitsuba rejects loudly.
fn to_text(v: &Value) -> String {
    // serializing a `Value` (string keys only) cannot fail
    let mut text = serde_json::to_string_pretty(v).expect("a serde_json::Value always serializes");
    text.push('\n');
    text
}

/// `path` integrator with our depth convention (which is Mitsuba's).
fn integrator(settings: &RenderSettings) -> Value {
    let max_depth = if settings.max_depth > i32::MAX as u32 { -1 } else { settings.max_depth as i64 };
    json!({
        "type": "path",
        "max_depth": max_depth,
        "rr_depth": settings.rr_depth.min(i32::MAX as u32) as i64,
        "hide_emitters": false,
    })
}

/// `perspective` sensor: our -Z-looking camera expressed as a Mitsuba `look_at`.
fn sensor(settings: &RenderSettings) -> Value {
    let cam = &settings.camera;
    let origin = cam.origin();
    let forward = -cam.to_world.z_axis.truncate().normalize();
    let up = cam.to_world.y_axis.truncate().normalize();
    // fold the frame into the seed as the renderer does (Mitsuba seeds are 32-bit)
    let seed = (settings.seed ^ settings.frame.wrapping_mul(0x9E37_79B9_7F4A_7C15)) as u32;
    json!({
        "type": "perspective",
        "fov": cam.yfov.to_degrees() as f64,
        "fov_axis": "y",
        "near_clip": 1e-4,
        "far_clip": 1e7,
        "to_world": look_at(origin, origin + forward, up),
        "film": {
            "type": "hdrfilm",
            "width": settings.width as i64,
            "height": settings.height as i64,
            "pixel_format": "rgb",
            "component_format": "float32",
            "rfilter": { "type": "box" },
        },
        "sampler": {
            "type": "independent",
            "sample_count": settings.spp as i64,
            "seed": seed as i64,
        },
    })
}

/// The two-sided BSDF of `material` (see the module docs for the mapping).
fn bsdf(scene: &Scene, material: &Material, m: usize, element: &str, out_dir: &Path) -> Result<Value, ExportError> {
    if material.metallic_roughness_texture.is_some() {
        return Err(ExportError::not_exportable(
            element,
            "metallic-roughness textures have no Mitsuba equivalent here; use constant factors",
        ));
    }
    let reflectance = || -> Result<Value, ExportError> {
        match material.base_color_texture {
            Some(t) => bitmap(scene, t, material.base_color, &format!("tex_{m}_base.exr"), element, out_dir),
            None => Ok(rgb(material.base_color)),
        }
    };
    let inner = if material.metallic == 0.0 && material.specular == 0.0 {
        json!({ "type": "diffuse", "reflectance": reflectance()? })
    } else if material.metallic == 1.0 {
        let alpha = material.roughness * material.roughness;
        let mut d = json!({
            "type": if alpha < 1e-4 { "conductor" } else { "roughconductor" },
            "material": "none",
            "specular_reflectance": reflectance()?,
        });
        if alpha >= 1e-4 {
            d["distribution"] = json!("ggx");
            d["alpha"] = json!(alpha as f64);
        }
        d
    } else {
        return Err(ExportError::not_exportable(
            element,
            format!(
                "metallic = {}, specular = {}: only pure Lambert (metallic 0, specular 0) and pure metals \
                 (metallic 1) map exactly onto Mitsuba BSDFs",
                material.metallic, material.specular
            ),
        ));
    };
    Ok(json!({ "type": "twosided", "bsdf": inner }))
}

/// The `area` emitter of `material`, if it emits.
fn emitter(
    scene: &Scene,
    material: &Material,
    m: usize,
    element: &str,
    out_dir: &Path,
) -> Result<Option<Value>, ExportError> {
    if !material.is_emissive() {
        return Ok(None);
    }
    let radiance = match material.emission_texture {
        Some(t) => bitmap(scene, t, material.emission, &format!("tex_{m}_emission.exr"), element, out_dir)?,
        None => rgb(material.emission),
    };
    Ok(Some(json!({ "type": "area", "radiance": radiance })))
}

/// A `ply` shape dict.
fn shape(file: &str, bsdf: &Value, emitter: Option<&Value>) -> Value {
    let mut d = json!({
        "type": "ply",
        "filename": file,
        "face_normals": false,
        "bsdf": bsdf,
    });
    if let Some(e) = emitter {
        d["emitter"] = e.clone();
    }
    d
}

/// Write texture `t` times `factor` as a linear float EXR and return its `bitmap` dict.
fn bitmap(
    scene: &Scene,
    t: TextureRef,
    factor: Vec3,
    file: &str,
    element: &str,
    out_dir: &Path,
) -> Result<Value, ExportError> {
    let tex = scene
        .textures
        .get(t.index as usize)
        .ok_or_else(|| ExportError::not_exportable(element, format!("texture index {} out of range", t.index)))?;
    if tex.wrap_u != tex.wrap_v {
        return Err(ExportError::not_exportable(
            element,
            format!("texture \"{}\" wraps differently along u and v; Mitsuba has one wrap mode", tex.name),
        ));
    }
    let wrap = match tex.wrap_u {
        WrapMode::Repeat => "repeat",
        WrapMode::ClampToEdge => "clamp",
        WrapMode::MirroredRepeat => "mirror",
    };
    let texels: Vec<Vec3> = tex.texels.iter().map(|&p: &Vec4| p.truncate() * factor).collect();
    write_exr(&out_dir.join(file), tex.width as usize, tex.height as usize, &texels)?;
    Ok(json!({
        "type": "bitmap",
        "filename": file,
        "raw": true,
        "filter_type": "bilinear",
        "wrap_mode": wrap,
    }))
}

/// A punctual light as a Mitsuba emitter dict.
fn punctual(light: &PunctualLight) -> Value {
    match light {
        PunctualLight::Point { position, intensity } => json!({
            "type": "point",
            "position": vec3(*position),
            "intensity": rgb(*intensity),
        }),
        PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
            // any up vector not parallel to the axis will do: the cone is symmetric
            let up = if direction.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
            json!({
                "type": "spot",
                "to_world": look_at(*position, *position + *direction, up),
                "intensity": rgb(*intensity),
                "cutoff_angle": outer_cone.to_degrees() as f64,
                "beam_width": inner_cone.to_degrees() as f64,
            })
        }
        PunctualLight::Directional { direction, irradiance } => json!({
            "type": "directional",
            "direction": vec3(*direction),
            "irradiance": rgb(*irradiance),
        }),
    }
}

/// The environment emitter, or `None` for a black environment.
fn environment(env: &Environment, out_dir: &Path) -> Result<Option<Value>, ExportError> {
    #[allow(unreachable_patterns)]
    match env {
        Environment::Constant(c) if c.max_element() <= 0.0 => Ok(None),
        Environment::Constant(c) => Ok(Some(json!({ "type": "constant", "radiance": rgb(*c) }))),
        Environment::Map(map) => {
            envmap_emitter(map.width, map.height, &map.texels, map.scale, map.to_world, out_dir).map(Some)
        }
    }
}

/// Write an equirectangular environment map (row-major RGB, row 0 = +Y) as `envmap.exr` and
/// return its `envmap` dict; `to_world` maps map-local directions to world directions.
pub(crate) fn envmap_emitter(
    width: u32,
    height: u32,
    texels: &[Vec3],
    scale: f32,
    to_world: Mat3,
    out_dir: &Path,
) -> Result<Value, ExportError> {
    if texels.len() != (width * height) as usize || width < 2 || height < 3 {
        return Err(ExportError::not_exportable(
            "environment map",
            format!("{width}x{height} map with {} texels: Mitsuba needs at least 2x3 and a full image", texels.len()),
        ));
    }
    // resample to Mitsuba's pole-to-pole rows (see the module doc): row k sits at v = k / (2h)
    let (w, h) = (width as usize, height as usize);
    let mut rows = Vec::with_capacity(w * (2 * h + 1));
    for k in 0..=2 * h {
        for x in 0..w {
            let ours = |j: usize| texels[j.min(h - 1) * w + x];
            rows.push(if k % 2 == 1 { ours(k / 2) } else { 0.5 * (ours((k / 2).saturating_sub(1)) + ours(k / 2)) });
        }
    }
    write_exr(&out_dir.join("envmap.exr"), w, 2 * h + 1, &rows)?;
    let m = glam::Mat4::from_mat3(to_world);
    let rows: Vec<Vec<f64>> = (0..4).map(|r| m.row(r).to_array().iter().map(|&v| v as f64).collect()).collect();
    Ok(json!({
        "type": "envmap",
        "filename": "envmap.exr",
        "scale": scale as f64,
        "to_world": { "matrix": rows },
    }))
}

/// Write the triangles `tris` of the scene mesh as a binary little-endian PLY with positions,
/// normals and uvs. With `flip`, the winding and normals are reversed and every vertex moves
/// `offset` along its new normal.
fn write_ply(path: &Path, scene: &Scene, tris: &[[u32; 3]], flip: bool, offset: f32) -> Result<(), ExportError> {
    let mesh = &scene.mesh;
    // compact the vertices this group uses
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    let mut used = Vec::new();
    for t in tris {
        for &i in t {
            if remap[i as usize] == u32::MAX {
                remap[i as usize] = used.len() as u32;
                used.push(i as usize);
            }
        }
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment evblur export\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float u\nproperty float v\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        used.len(),
        tris.len()
    );
    let mut bytes = header.into_bytes();
    bytes.reserve(used.len() * 32 + tris.len() * 13);
    let sign = if flip { -1.0 } else { 1.0 };
    for &i in &used {
        let n = mesh.normals.get(i).copied().unwrap_or(Vec3::Z) * sign;
        let p = mesh.positions[i] + n * offset;
        let uv = mesh.uvs.get(i).copied().unwrap_or_default();
        for v in [p.x, p.y, p.z, n.x, n.y, n.z, uv.x, uv.y] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in tris {
        let [a, b, c] = t.map(|i| remap[i as usize]);
        let t = if flip { [a, c, b] } else { [a, b, c] };
        bytes.push(3);
        for i in t {
            bytes.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    std::fs::write(path, bytes).map_err(|e| ExportError::write(path, e))
}

/// Write a linear float RGB EXR, row 0 at the top.
fn write_exr(path: &Path, width: usize, height: usize, texels: &[Vec3]) -> Result<(), ExportError> {
    exr::prelude::write_rgb_file(path, width, height, |x, y| {
        let p = texels[y * width + x];
        (p.x, p.y, p.z)
    })
    .map_err(|e| ExportError::write(path, e))
}

/// Length of the bounding-box diagonal of `points` (1 for an empty set).
fn bbox_diagonal(points: &[Vec3]) -> f32 {
    if points.is_empty() {
        return 1.0;
    }
    let (lo, hi) = points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    (hi - lo).length().max(1e-6)
}

fn vec3(v: Vec3) -> Value {
    json!([v.x as f64, v.y as f64, v.z as f64])
}

fn rgb(c: Vec3) -> Value {
    json!({ "type": "rgb", "value": vec3(c) })
}

/// The `{"look_at": ...}` encoding of a `ScalarTransform4f` (resolved by `tests/mitsuba/render.py`).
fn look_at(origin: Vec3, target: Vec3, up: Vec3) -> Value {
    json!({ "look_at": { "origin": vec3(origin), "target": vec3(target), "up": vec3(up) } })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Camera, TriangleMesh};
    use glam::Vec2;

    /// A quad `a b c d` (counter-clockwise seen from where its normal points) as two triangles.
    fn quad(mesh: &mut TriangleMesh, p: [Vec3; 4], material: u32) {
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        let base = mesh.positions.len() as u32;
        let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
        for k in 0..4 {
            mesh.positions.push(p[k]);
            mesh.normals.push(n);
            mesh.uvs.push(uv[k]);
        }
        mesh.indices.push([base, base + 1, base + 2]);
        mesh.indices.push([base, base + 2, base + 3]);
        mesh.material.extend([material, material]);
    }

    fn lambert(name: &str, c: Vec3) -> Material {
        Material { name: name.into(), base_color: c, specular: 0.0, ..Material::default() }
    }

    /// A Cornell-like box spanning [-1, 1]^3, open towards +Z, with a light under the ceiling.
    pub(crate) fn cornell() -> (Scene, RenderSettings) {
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let mut mesh = TriangleMesh::default();
        quad(&mut mesh, [v(-1., -1., 1.), v(1., -1., 1.), v(1., -1., -1.), v(-1., -1., -1.)], 0); // floor, +Y
        quad(&mut mesh, [v(-1., 1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(-1., 1., 1.)], 0); // ceiling, -Y
        quad(&mut mesh, [v(-1., -1., -1.), v(1., -1., -1.), v(1., 1., -1.), v(-1., 1., -1.)], 0); // back, +Z
        quad(&mut mesh, [v(-1., -1., 1.), v(-1., -1., -1.), v(-1., 1., -1.), v(-1., 1., 1.)], 1); // left, +X
        quad(&mut mesh, [v(1., -1., -1.), v(1., -1., 1.), v(1., 1., 1.), v(1., 1., -1.)], 2); // right, -X
        let s = 0.25;
        quad(&mut mesh, [v(-s, 0.99, -s), v(s, 0.99, -s), v(s, 0.99, s), v(-s, 0.99, s)], 3); // light, -Y
        let materials = vec![
            lambert("white", Vec3::splat(0.7)),
            lambert("red", Vec3::new(0.57, 0.04, 0.04)),
            lambert("green", Vec3::new(0.1, 0.38, 0.08)),
            Material { emission: Vec3::new(17.0, 12.0, 4.0), ..lambert("light", Vec3::ZERO) },
        ];
        let scene = Scene { mesh, materials, ..Scene::default() };
        let camera = Camera::look_at(v(0.0, 0.0, 3.9), Vec3::ZERO, Vec3::Y, 39.3077f32.to_radians());
        let mut settings = RenderSettings::new(camera);
        settings.width = 120;
        settings.height = 80;
        settings.spp = 16;
        (scene, settings)
    }

    #[test]
    fn writes_json_ply_and_maps_materials() {
        let (scene, settings) = cornell();
        let dir = std::env::temp_dir().join(format!("evblur-export-test-{}", std::process::id()));
        let json = export_mitsuba(&scene, &settings, &dir).unwrap();
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(doc["format"], "evblur-mitsuba-1");
        let s = &doc["scene"];
        assert_eq!(s["type"], "scene");
        assert_eq!(s["shape_0"]["bsdf"]["bsdf"]["type"], "diffuse");
        assert_eq!(s["shape_3"]["emitter"]["type"], "area");
        assert_eq!(s["shape_3"]["filename"], "mesh_3.ply");
        // integers stay integers, other numbers are floats (Mitsuba's properties are typed)
        assert_eq!(s["integrator"]["max_depth"].as_i64(), Some(5));
        assert_eq!(s["sensor"]["fov_axis"], "y");
        assert!(s["sensor"]["fov"].is_f64());
        // forward is -Z of the camera: the target lies towards the box
        let target: Vec<f64> = s["sensor"]["to_world"]["look_at"]["target"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(&target[..2], &[0.0, 0.0]);
        assert!((target[2] - 2.9).abs() < 1e-5, "{target:?}");
        let ply = std::fs::read(dir.join("mesh_1.ply")).unwrap();
        let header_end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        assert_eq!(ply.len(), header_end + 4 * 32 + 2 * 13);
        // out-of-family materials are refused
        let mut bad = scene.clone();
        bad.materials[0].metallic = 0.5;
        let err = export_mitsuba(&bad, &settings, &dir).unwrap_err();
        assert!(err.to_string().contains("not exportable"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
        // for a manual look with tests/mitsuba/render.py
        if let Some(keep) = std::env::var_os("EVBLUR_EXPORT_DIR") {
            export_mitsuba(&scene, &settings, Path::new(&keep)).unwrap();
        }
    }

    #[test]
    fn unlimited_depth_is_minus_one_and_json_escapes() {
        let (_, mut settings) = cornell();
        settings.max_depth = u32::MAX;
        let parsed: Value = serde_json::from_str(&to_text(&integrator(&settings))).unwrap();
        assert_eq!(parsed["max_depth"].as_i64(), Some(-1));
        // strings survive the round trip through the written text
        let tricky = "a\"b\\c\n";
        let parsed: Value = serde_json::from_str(&to_text(&json!({ "k": tricky }))).unwrap();
        assert_eq!(parsed["k"], tricky);
    }

    #[test]
    fn envmap_dict_has_matrix_and_file() {
        let dir = std::env::temp_dir().join(format!("evblur-export-env-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let texels = vec![Vec3::ONE; 8 * 4];
        let j = envmap_emitter(8, 4, &texels, 2.0, Mat3::IDENTITY, &dir).unwrap();
        let j: Value = serde_json::from_str(&to_text(&j)).unwrap();
        assert_eq!(j["type"], "envmap");
        assert_eq!(j["filename"], "envmap.exr");
        assert_eq!(j["scale"].as_f64(), Some(2.0));
        let matrix = j["to_world"]["matrix"].as_array().unwrap();
        assert_eq!(matrix.len(), 4);
        assert_eq!(matrix[1], json!([0.0, 1.0, 0.0, 0.0]));
        assert!(dir.join("envmap.exr").exists());
        std::fs::remove_dir_all(&dir).ok();
    }
}
