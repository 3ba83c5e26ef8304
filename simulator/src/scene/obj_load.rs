//! Wavefront OBJ + MTL loader (parsed by `tobj`, triangulated, one index per vertex).
//!
//! # Geometry
//! - Polygons are fan-triangulated. Vertices keep the file's winding (counter-clockwise around
//!   the geometric normal). Positions are taken as world space, in metres.
//! - **Normals**: `vn` when the face has them (normalised; a zero or non-finite `vn` is replaced
//!   by the generated normal). Without `vn`, *smooth* per-vertex normals are generated like
//!   Mitsuba does for an OBJ without normals: all vertices at bit-identical positions (anywhere in
//!   the file) are welded, face normals are accumulated area-weighted over the welded vertex and
//!   normalised. (`tobj`'s single-index mode duplicates a position for every distinct `v/vt/vn`
//!   triple; welding undoes that so UV seams do not show as creases. Mitsuba welds by the
//!   position *index* and weights by corner angle, so coincident but separately listed vertices,
//!   or very irregular meshes, can shade slightly differently.)
//! - **UVs**: `vt` with v flipped, `(u, 1 - v)`: OBJ puts v = 0 at the bottom of the image, our
//!   textures put v = 0 at the top row. Vertices without `vt` get (0, 0).
//! - Degenerate (zero-area) triangles are skipped, with one warning per object.
//!
//! # Materials (MTL -> [`Material`])
//!
//! | MTL key          | [`Material`] field                | notes                                        |
//! |------------------|-----------------------------------|----------------------------------------------|
//! | `Kd r g b`       | `base_color`                      | linear, as written; absent -> 0.8            |
//! | `map_Kd file`    | `base_color_texture`              | PNG/JPEG, sRGB-decoded, relative to the .mtl |
//! | `Ke r g b`       | `emission`                        | radiance (W/m^2/sr), one-sided               |
//! | `map_Ke file`    | `emission_texture`                | PNG/JPEG, sRGB-decoded, relative to the .mtl |
//! | `Ks` absent/black| `specular = 0`                    | pure Lambertian                              |
//! | `Ks` non-black   | `specular = 1`, `roughness = sqrt(2 / (Ns + 2))` | Ks's colour is not used (F0 = 0.04) |
//! | `Ns`             | via the roughness formula above   | absent -> 0 (roughness 1)                    |
//! | `Pr x`           | `roughness = x`, `specular = 1`   | PBR extension; overrides `Ns`                |
//! | `Pm x`           | `metallic = x`, `specular = 1`    | PBR extension                                |
//! | `map_Pr`, `map_Pm`, `map_Ks`, `bump`/`map_Bump`/`norm`, `d < 1` | ignored | one warning per material |
//! | (no `usemtl`)    | [`Material::default`] with `specular = 0` | an unknown `usemtl` name is an error |
//!
//! The roughness formula is the Blinn-Phong exponent <-> Beckmann/GGX correspondence
//! `alpha^2 = 2 / (Ns + 2)` with our `alpha = roughness^2`. All OBJ materials are one-sided
//! (`double_sided = false`), as in Mitsuba. Texture options (`map_Kd -s 2 2 1 wood.png`) are
//! ignored with a warning and the last word is taken as the file; `\` in paths is read as `/`.
//!
//! # Errors
//! Every error names the file and the element: an unreadable .obj, a malformed line (tobj's
//! message and the first line at which the file stops parsing), an unreadable or malformed
//! `mtllib`, a missing texture (material and map named), a NaN/infinite position (object and
//! 1-based `v` index), a file with no triangles.

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{is_degenerate, Material, Scene, Texture, TextureRef, TriangleMesh};
use crate::error::SceneError;

/// Options we always load with: triangulated, one index per vertex.
fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() }
}

/// One `mtllib` the parser asked for: where it is and what became of it.
struct MtlRecord {
    /// The name as written after `mtllib`.
    name: PathBuf,
    /// Resolved path (relative to the .obj's folder).
    full: PathBuf,
    /// The materials it defines (tobj appends them to its list in call order).
    materials: Vec<tobj::Material>,
    /// Read or parse failure.
    error: Option<String>,
}

/// Load an `.obj` file (and its `.mtl` libraries and textures) into a [`Scene`].
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        SceneError::invalid(path, "file", format!("not UTF-8 text ({e}); re-export the OBJ as UTF-8/ASCII"))
    })?;
    let folder = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let scan = scan_text(path, &text)?;

    // parse; the material loader resolves mtllib names against the .obj's folder and records them
    let mtls: RefCell<Vec<MtlRecord>> = RefCell::new(Vec::new());
    let parsed = tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &load_options(), |name| {
        let full = folder.join(name);
        let mut rec = MtlRecord { name: name.to_path_buf(), full: full.clone(), materials: Vec::new(), error: None };
        let result = match std::fs::read(&full) {
            Err(e) => {
                rec.error = Some(format!("cannot read {} ({e})", full.display()));
                Err(tobj::LoadError::OpenFileFailed)
            }
            Ok(b) => match std::str::from_utf8(&b) {
                Err(e) => {
                    rec.error = Some(format!("{} is not a text MTL file ({e})", full.display()));
                    Err(tobj::LoadError::ReadError)
                }
                Ok(text) if short_colour_line(text).is_some() => {
                    let (n, line) = short_colour_line(text).expect("checked");
                    rec.error = Some(format!(
                        "{} line {n}: `{line}` gives fewer than 3 numbers; write the colour as `key r g b`",
                        full.display()
                    ));
                    Err(tobj::LoadError::MaterialParseError)
                }
                Ok(text) => {
                    let result = tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()));
                    let content = text.lines().any(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
                    if matches!(&result, Ok((m, _)) if m.is_empty()) && content {
                        rec.error = Some(format!("{} defines no material (no `newmtl` line)", full.display()));
                    }
                    result
                }
            },
        };
        match &result {
            Ok((mats, _)) => rec.materials = mats.clone(),
            Err(e) if rec.error.is_none() => rec.error = Some(format!("{e}")),
            Err(_) => {}
        }
        mtls.borrow_mut().push(rec);
        result
    });
    let (models, _) = parsed.map_err(|e| {
        let near = first_bad_line(&text)
            .map(|(n, l)| format!(" (the file stops parsing at line {n}: `{l}`)"))
            .unwrap_or_default();
        SceneError::invalid(path, "OBJ parser", format!("{e}{near}; fix or remove the malformed line"))
    })?;
    let mtls = mtls.into_inner();
    for m in &mtls {
        if let Some(err) = &m.error {
            return Err(SceneError::invalid(
                path,
                format!("mtllib {}", m.name.display()),
                format!("{err}; the path is relative to the .obj's folder"),
            ));
        }
    }

    // materials: rebuild tobj's concatenated list so each knows its .mtl folder
    let mut scene = Scene::default();
    let mut texture_index: HashMap<PathBuf, u32> = HashMap::new();
    let tobj_materials: Vec<(&tobj::Material, &Path)> =
        mtls.iter().flat_map(|m| m.materials.iter().map(|mat| (mat, m.full.as_path()))).collect();
    for (mat, mtl) in &tobj_materials {
        let m = convert_material(mat, mtl, &mut scene, &mut texture_index)?;
        scene.materials.push(m);
    }
    for name in &scan.usemtl {
        if !tobj_materials.iter().any(|(m, _)| &m.name == name) {
            return Err(SceneError::invalid(
                path,
                format!("usemtl {name}"),
                "no such material in the mtllib files; define it there (newmtl) or remove the usemtl line",
            ));
        }
    }

    // geometry
    let mut mesh = TriangleMesh::default();
    let mut has_normal: Vec<bool> = Vec::new();
    let mut default_material: Option<u32> = None;
    let mut degenerate: Vec<(String, usize)> = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let n = m.positions.len() / 3;
        let base = mesh.positions.len() as u32;
        let object = if model.name.is_empty() { "(unnamed)" } else { model.name.as_str() };
        for i in 0..n {
            let p = Vec3::new(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
            if !p.is_finite() {
                // scan_text catches these with the file's own index; this is a safety net
                return Err(SceneError::invalid(
                    path,
                    format!("object \"{object}\" vertex {i}"),
                    format!("non-finite position {p}"),
                ));
            }
            mesh.positions.push(p);
        }
        let file_normals = m.normals.len() == 3 * n;
        for i in 0..n {
            let v = if file_normals {
                Vec3::new(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]).try_normalize()
            } else {
                None
            };
            has_normal.push(v.is_some());
            mesh.normals.push(v.unwrap_or(Vec3::Z));
        }
        let file_uvs = m.texcoords.len() == 2 * n;
        for i in 0..n {
            // flip v: OBJ v = 0 is the bottom row, ours is the top row
            mesh.uvs.push(if file_uvs {
                Vec2::new(m.texcoords[2 * i], 1.0 - m.texcoords[2 * i + 1])
            } else {
                Vec2::ZERO
            });
        }
        let material = match m.material_id {
            Some(id) if id < scene.materials.len() => id as u32,
            _ => *default_material.get_or_insert_with(|| {
                scene.materials.push(Material {
                    name: "default (no usemtl)".into(),
                    specular: 0.0,
                    ..Default::default()
                });
                scene.materials.len() as u32 - 1
            }),
        };
        let mut skipped = 0;
        for t in m.indices.chunks_exact(3) {
            let tri = [t[0] + base, t[1] + base, t[2] + base];
            let corners = tri.map(|i| mesh.positions[i as usize]);
            if is_degenerate(corners) {
                skipped += 1;
                continue;
            }
            mesh.indices.push(tri);
            mesh.material.push(material);
        }
        if skipped > 0 {
            match degenerate.iter_mut().find(|(o, _)| o == object) {
                Some((_, c)) => *c += skipped,
                None => degenerate.push((object.to_string(), skipped)),
            }
        }
    }
    for (object, count) in degenerate {
        scene.warnings.push(format!(
            "{}: object \"{object}\": skipped {count} degenerate (zero-area) triangle(s)",
            path.display()
        ));
    }
    if mesh.is_empty() {
        return Err(SceneError::invalid(
            path,
            "faces",
            "the file contains no (non-degenerate) triangles; an OBJ scene needs `f` lines",
        ));
    }
    if has_normal.iter().any(|h| !h) {
        let welded = welded_normals(&mesh.positions, &mesh.indices);
        for (i, n) in mesh.normals.iter_mut().enumerate() {
            if !has_normal[i] {
                *n = welded[i];
            }
        }
    }
    scene.mesh = mesh;
    scene.source = path.to_path_buf();
    Ok(scene)
}

/// Map one MTL material onto ours (see the table in the module doc).
fn convert_material(
    mat: &tobj::Material,
    mtl: &Path,
    scene: &mut Scene,
    textures: &mut HashMap<PathBuf, u32>,
) -> Result<Material, SceneError> {
    let dir = mtl.parent().unwrap_or(Path::new(""));
    let element = |key: &str| format!("material \"{}\" {key}", mat.name);
    let param = |key: &str| -> Result<Option<f32>, SceneError> {
        match mat.unknown_param.get(key) {
            None => Ok(None),
            Some(s) => match s.trim().parse::<f32>() {
                Ok(v) if v.is_finite() => Ok(Some(v.clamp(0.0, 1.0))),
                _ => Err(SceneError::invalid(mtl, element(key), format!("`{s}` is not a number in [0, 1]"))),
            },
        }
    };
    let mut warnings = Vec::new();
    let mut load_tex = |key: &str, spec: &str, scene: &mut Scene| -> Result<TextureRef, SceneError> {
        let words: Vec<&str> = spec.split_whitespace().collect();
        let file = if words.first().is_some_and(|w| w.starts_with('-')) {
            warnings.push(format!("{key} options ignored (`{spec}`)"));
            words.last().copied().unwrap_or_default().to_string()
        } else {
            spec.trim().to_string()
        };
        let full = dir.join(file.replace('\\', "/"));
        if let Some(&index) = textures.get(&full) {
            return Ok(TextureRef { index });
        }
        let tex = Texture::load(&full, true, &element(key))?;
        scene.textures.push(tex);
        let index = scene.textures.len() as u32 - 1;
        textures.insert(full, index);
        Ok(TextureRef { index })
    };

    let mut m = Material { name: mat.name.clone(), double_sided: false, ..Default::default() };
    if let Some(kd) = mat.diffuse {
        m.base_color = Vec3::from(kd);
    }
    if let Some(t) = &mat.diffuse_texture {
        m.base_color_texture = Some(load_tex("map_Kd", t, scene)?);
    }
    if let Some(ke) = mat.emissive {
        m.emission = Vec3::from(ke);
    }
    if let Some(t) = mat.unknown_param.get("map_Ke") {
        m.emission_texture = Some(load_tex("map_Ke", t, scene)?);
        if mat.emissive.is_none() {
            // a map alone means "emit the map": Ke defaults to white (as in Blender's exporter)
            m.emission = Vec3::ONE;
        }
    }
    let colours = [("Kd", mat.diffuse), ("Ke", mat.emissive), ("Ks", mat.specular), ("Ka", mat.ambient)];
    for (key, c) in colours {
        if let Some(c) = c.filter(|c| c.iter().any(|v| !(v.is_finite() && *v >= 0.0))) {
            return Err(SceneError::invalid(
                mtl,
                element(key),
                format!("{c:?}: colours must be finite and non-negative"),
            ));
        }
    }
    // specular layer: Blinn-Phong Ns -> alpha^2 = 2/(Ns+2), roughness = sqrt(alpha)
    let ks_on = mat.specular.is_some_and(|ks| ks.iter().any(|&c| c > 0.0));
    if ks_on {
        let ns = mat.shininess.unwrap_or(0.0).max(0.0);
        m.specular = 1.0;
        m.roughness = (2.0 / (ns + 2.0)).sqrt().sqrt();
    } else {
        m.specular = 0.0;
        m.roughness = 1.0;
    }
    if let Some(pr) = param("Pr")? {
        m.roughness = pr;
        m.specular = 1.0;
    }
    if let Some(pm) = param("Pm")? {
        m.metallic = pm;
        m.specular = 1.0;
    }
    // features we do not model: say so once per material
    let ignored = [
        ("map_Pr", mat.unknown_param.contains_key("map_Pr")),
        ("map_Pm", mat.unknown_param.contains_key("map_Pm")),
        ("map_Ks", mat.specular_texture.is_some()),
        ("bump/map_Bump", mat.normal_texture.is_some()),
        ("norm", mat.unknown_param.contains_key("norm")),
        ("map_d", mat.dissolve_texture.is_some()),
    ];
    for (key, present) in ignored {
        if present {
            warnings.push(format!("{key} is not supported and was ignored"));
        }
    }
    if mat.dissolve.is_some_and(|d| d < 1.0) {
        warnings.push("d < 1 (transparency) is not supported; the surface is opaque".into());
    }
    for w in warnings {
        scene.warnings.push(format!("{}: material \"{}\": {w}", mtl.display(), mat.name));
    }
    Ok(m)
}

/// The first `Ka`/`Kd`/`Ks`/`Ke` line of an MTL text with fewer than 3 numbers (1-based line
/// number and text): tobj 4 panics on such a line instead of returning an error.
fn short_colour_line(text: &str) -> Option<(usize, &str)> {
    text.lines().enumerate().find_map(|(i, line)| {
        let mut words = line.split_whitespace();
        let colour = matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke"));
        (colour && words.count() < 3).then(|| (i + 1, line.trim()))
    })
}

/// What a plain text pass over the OBJ finds before tobj runs.
struct TextScan {
    /// Material names used by `usemtl`, first use order, unique.
    usemtl: Vec<String>,
}

/// Check `v` lines for non-finite coordinates (naming the object and the 1-based `v` index, as
/// a text editor would count them) and collect `usemtl` names.
fn scan_text(path: &Path, text: &str) -> Result<TextScan, SceneError> {
    let mut object = String::from("(unnamed)");
    let mut v_index = 0usize;
    let mut usemtl: Vec<String> = Vec::new();
    // positive references may point past the line (some exporters write faces first); negative
    // ones count back from it
    let total = |key: &str| text.lines().filter(|l| l.split_whitespace().next() == Some(key)).count();
    let totals = [total("v"), total("vt"), total("vn")];
    let mut seen = [0usize; 3];
    for (line_no, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.clone().next();
        if let Some(k) = ["v", "vt", "vn"].iter().position(|k| Some(*k) == key) {
            seen[k] += 1;
        }
        if key == Some("f") {
            if line.split_whitespace().count() < 4 {
                return Err(SceneError::invalid(
                    path,
                    format!("object \"{object}\" face (line {})", line_no + 1),
                    format!("`{}` has fewer than 3 vertices; a face needs at least 3", line.trim()),
                ));
            }
            check_face_refs(path, &object, line_no + 1, line, totals, seen)?;
        }
        if let Some(k @ ("vt" | "vn")) = key {
            if line.split_whitespace().skip(1).any(|w| w.parse::<f32>().is_ok_and(|x| !x.is_finite())) {
                return Err(SceneError::invalid(
                    path,
                    format!("object \"{object}\" {k} (line {})", line_no + 1),
                    format!("non-finite value `{}`; texture coordinates and normals must be finite", line.trim()),
                ));
            }
        }
        match words.next() {
            Some("o") | Some("g") => object = words.collect::<Vec<_>>().join(" "),
            Some("v") => {
                v_index += 1;
                let bad = words.take(3).any(|w| w.parse::<f32>().is_ok_and(|x| !x.is_finite()));
                if bad {
                    return Err(SceneError::invalid(
                        path,
                        format!("object \"{object}\" vertex v {v_index} (line {})", line_no + 1),
                        format!("non-finite position `{}`; positions must be finite numbers", line.trim()),
                    ));
                }
            }
            Some("usemtl") => {
                let name = line.trim_start()["usemtl".len()..].trim().to_string();
                if !name.is_empty() && !usemtl.contains(&name) {
                    usemtl.push(name);
                }
            }
            _ => {}
        }
    }
    Ok(TextScan { usemtl })
}

/// Check that every `v/vt/vn` reference of the face on `line` names an element of the file:
/// 1-based up to the file's count, or negative back from the `seen` elements before the line.
fn check_face_refs(
    path: &Path,
    object: &str,
    line_no: usize,
    line: &str,
    totals: [usize; 3],
    seen: [usize; 3],
) -> Result<(), SceneError> {
    const KIND: [&str; 3] = ["v", "vt", "vn"];
    for vertex in line.split_whitespace().skip(1) {
        for (k, part) in vertex.split('/').enumerate().take(3) {
            if part.is_empty() {
                continue; // `v//vn`, or no reference (tobj reports the malformed ones)
            }
            let Ok(i) = part.parse::<i64>() else { continue };
            let ok = match i {
                0 => false,
                i if i > 0 => i as usize <= totals[k],
                i => i.unsigned_abs() as usize <= seen[k],
            };
            if !ok {
                let have = if i < 0 { seen[k] } else { totals[k] };
                return Err(SceneError::invalid(
                    path,
                    format!("object \"{object}\" face (line {line_no})"),
                    format!(
                        "`{vertex}` refers to {} {i}, but the file has {have} {} lines{}; fix the face or re-export the OBJ",
                        KIND[k],
                        KIND[k],
                        if i < 0 { " before it" } else { "" }
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Bisect for the first line at which the file no longer parses (tobj reports no line numbers).
fn first_bad_line(text: &str) -> Option<(usize, String)> {
    let lines: Vec<&str> = text.lines().collect();
    let parses = |k: usize| {
        let prefix = lines[..k].join("\n");
        tobj::load_obj_buf(&mut Cursor::new(prefix.as_bytes()), &load_options(), |_| {
            Ok((Vec::new(), Default::default()))
        })
        .is_ok()
    };
    if parses(lines.len()) {
        return None;
    }
    // invariant: prefix of lo lines parses, prefix of hi lines does not
    let (mut lo, mut hi) = (0usize, lines.len());
    if !parses(0) {
        return None;
    }
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if parses(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((hi, lines[hi - 1].trim().to_string()))
}

/// Smooth normals over position-welded vertices: every vertex gets the normalised sum of the
/// (area-weighted) face normals of all triangles touching any vertex at the same position.
fn welded_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    // weld key: the exact bits (with -0.0 folded into 0.0)
    let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut slot: HashMap<[u32; 3], usize> = HashMap::new();
    let vertex_slot: Vec<usize> = positions
        .iter()
        .map(|&p| {
            let n = slot.len();
            *slot.entry(key(p)).or_insert(n)
        })
        .collect();
    let mut acc = vec![Vec3::ZERO; slot.len()];
    for t in indices {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // |cross| = twice the area: area weighting for free
        let face = (b - a).cross(c - a);
        for &i in t {
            acc[vertex_slot[i as usize]] += face;
        }
    }
    vertex_slot.iter().map(|&s| acc[s].try_normalize().unwrap_or(Vec3::Z)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh temp folder for one test.
    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("evblur-obj-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    const QUAD_MTL: &str = "\
newmtl matte
Kd 0.5 0.25 0.125
newmtl glossy
Kd 0.1 0.2 0.3
Ks 0.04 0.04 0.04
Ns 98
newmtl light
Kd 0 0 0
Ke 10 9 8
newmtl pbr
Kd 1 1 1
Pr 0.3
Pm 1
map_Pr rough.png
";

    #[test]
    fn materials_follow_the_mapping_table() {
        let dir = temp_dir("materials");
        write(&dir, "m.mtl", QUAD_MTL);
        let obj = write(
            &dir,
            "a.obj",
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
             usemtl matte\nf 1 2 3\nusemtl glossy\nf 1 3 4\nusemtl light\nf 1 2 4\nusemtl pbr\nf 2 3 4\n",
        );
        let s = load(&obj).unwrap();
        assert_eq!(s.mesh.len(), 4);
        let by_name = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap();
        let matte = by_name("matte");
        assert_eq!(matte.base_color, Vec3::new(0.5, 0.25, 0.125));
        assert_eq!(matte.specular, 0.0);
        assert!(!matte.double_sided);
        let glossy = by_name("glossy");
        assert_eq!(glossy.specular, 1.0);
        // Ns = 98: alpha^2 = 0.02, roughness = 0.02^(1/4)
        assert!((glossy.roughness - 0.02f32.powf(0.25)).abs() < 1e-6);
        let light = by_name("light");
        assert_eq!(light.emission, Vec3::new(10.0, 9.0, 8.0));
        let pbr = by_name("pbr");
        assert_eq!((pbr.roughness, pbr.metallic, pbr.specular), (0.3, 1.0, 1.0));
        assert!(s.warnings.iter().any(|w| w.contains("map_Pr")), "{:?}", s.warnings);
        // triangle -> material assignment follows usemtl
        let names: Vec<&str> = s.mesh.material.iter().map(|&m| s.materials[m as usize].name.as_str()).collect();
        assert_eq!(names, ["matte", "glossy", "light", "pbr"]);
    }

    #[test]
    fn no_material_gives_lambertian_default_and_smooth_welded_normals() {
        let dir = temp_dir("smooth");
        // a tent: two triangles meeting at the ridge x = 0, no vn; vt splits the ridge vertices
        let obj = write(
            &dir,
            "t.obj",
            "v -1 0 0\nv 0 1 0\nv 0 1 1\nv -1 0 1\nv 1 0 0\nv 1 0 1\n\
             vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n\
             f 1/1 3/2 2/3\nf 1/1 4/4 3/2\nf 2/5 3/5 5/1\nf 3/5 6/2 5/1\n",
        );
        let s = load(&obj).unwrap();
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.materials[0].specular, 0.0);
        assert!(s.mesh.material.iter().all(|&m| m == 0));
        // ridge vertices (y = 1) are welded across the vt seam: normal straight up
        let mut ridge = 0;
        for (p, n) in s.mesh.positions.iter().zip(&s.mesh.normals) {
            if p.y == 1.0 {
                ridge += 1;
                assert!((*n - Vec3::Y).length() < 1e-5, "{n}");
            } else {
                assert!((n.length() - 1.0).abs() < 1e-5 && n.y > 0.5);
            }
        }
        assert!(ridge >= 4, "tobj duplicates the ridge per vt: {ridge}");
        // v flipped: vt (1, 1) -> uv (1, 0)
        assert!(s.mesh.uvs.contains(&Vec2::new(1.0, 0.0)));
    }

    #[test]
    fn file_normals_are_normalised_and_degenerates_skipped() {
        let dir = temp_dir("normals");
        let obj = write(
            &dir,
            "n.obj",
            "o Thing\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nvn 0 0 2\nf 1//1 2//1 3//1\nf 1//1 2//1 4//1\n",
        );
        let s = load(&obj).unwrap();
        assert_eq!(s.mesh.len(), 1);
        assert!(s.mesh.normals.iter().all(|n| *n == Vec3::Z));
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("Thing") && s.warnings[0].contains("1 degenerate"));
    }

    #[test]
    fn textures_resolve_relative_to_the_mtl() {
        let dir = temp_dir("tex");
        std::fs::create_dir_all(dir.join("mat/tex")).unwrap();
        // a 1x1 sRGB 128 grey PNG
        let img = image::RgbImage::from_pixel(1, 1, image::Rgb([128, 128, 128]));
        img.save(dir.join("mat/tex/grey.png")).unwrap();
        write(&dir, "mat/m.mtl", "newmtl t\nKd 1 1 1\nmap_Kd tex/grey.png\nmap_Ke -s 1 1 1 tex/grey.png\n");
        let obj = write(&dir, "a.obj", "mtllib mat/m.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let s = load(&obj).unwrap();
        let m = &s.materials[0];
        assert_eq!(s.textures.len(), 1, "same file shared");
        assert_eq!(m.base_color_texture, Some(TextureRef { index: 0 }));
        assert_eq!(m.emission_texture, Some(TextureRef { index: 0 }));
        assert_eq!(m.emission, Vec3::ONE);
        assert!((s.textures[0].texels[0].x - 0.2158605).abs() < 1e-4, "sRGB decoded");
        assert!(s.warnings.iter().any(|w| w.contains("options ignored")));
    }

    #[test]
    fn errors_name_the_file_and_element() {
        let dir = temp_dir("errors");
        let msg = |r: Result<Scene, SceneError>| r.unwrap_err().to_string();

        let e = msg(load(&dir.join("missing.obj")));
        assert!(e.contains("missing.obj"), "{e}");

        let obj = write(&dir, "mtl.obj", "mtllib nope.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let e = msg(load(&obj));
        assert!(e.contains("mtllib nope.mtl") && e.contains("mtl.obj"), "{e}");

        write(&dir, "t.mtl", "newmtl wood\nmap_Kd wood.png\n");
        let obj = write(&dir, "tex.obj", "mtllib t.mtl\nusemtl wood\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let e = msg(load(&obj));
        assert!(e.contains("material \"wood\" map_Kd") && e.contains("wood.png"), "{e}");

        let obj = write(&dir, "nan.obj", "o Bad\nv 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
        let e = msg(load(&obj));
        assert!(e.contains("object \"Bad\" vertex v 2"), "{e}");

        let obj = write(&dir, "parse.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 x 0\nf 1 2 3\n");
        let e = msg(load(&obj));
        assert!(e.contains("parse.obj") && e.contains("line 4"), "{e}");

        let obj = write(&dir, "empty.obj", "v 0 0 0\nv 1 0 0\n");
        let e = msg(load(&obj));
        assert!(e.contains("no (non-degenerate) triangles"), "{e}");

        let obj = write(&dir, "oob.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
        let e = msg(load(&obj));
        assert!(e.contains("face (line 4)") && e.contains("refers to v 9") && e.contains("3 v lines"), "{e}");
        let obj = write(&dir, "vt.obj", "o Tri\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/99 2/99 3/99\n");
        let e = msg(load(&obj));
        assert!(e.contains("object \"Tri\" face (line 5)") && e.contains("`1/99` refers to vt 99"), "{e}");
        let obj = write(&dir, "vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//-2\n");
        let e = msg(load(&obj));
        assert!(e.contains("refers to vn -2") && e.contains("1 vn lines before it"), "{e}");
        // relative references and a face before its vertices are fine
        let obj = write(&dir, "rel.obj", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/-1 -2/-1 -1/-1\n");
        assert_eq!(load(&obj).unwrap().mesh.indices.len(), 2);

        // an MTL that is not one (binary, or text without a material) is an error, not a scene
        // without its materials and lights
        std::fs::write(dir.join("bin.mtl"), [0xffu8, 0xfe, 0x00, 0x9c, 0x80]).unwrap();
        std::fs::write(dir.join("junk.mtl"), "this is not a material library\n").unwrap();
        for mtl in ["bin.mtl", "junk.mtl"] {
            let obj = write(&dir, "m.obj", &format!("mtllib {mtl}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
            let e = msg(load(&obj));
            assert!(
                e.contains(&format!("mtllib {mtl}")) && (e.contains("not a text MTL") || e.contains("no `newmtl`")),
                "{e}"
            );
        }
    }

    #[test]
    fn unknown_usemtl_is_an_error_naming_it() {
        let dir = temp_dir("unknown");
        write(&dir, "m.mtl", "newmtl a\nKd 1 0 0\n");
        let obj = write(&dir, "u.obj", "mtllib m.mtl\nusemtl zzz\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let e = load(&obj).unwrap_err().to_string();
        assert!(e.contains("u.obj") && e.contains("usemtl zzz") && e.contains("no such material"), "{e}");
    }

    #[test]
    fn short_colours_short_faces_and_non_finite_values_are_errors_not_panics() {
        let dir = temp_dir("short");
        let cases = [
            ("newmtl a\nKd 0.5 0.5\n", "usemtl a\nf 1 2 3\n", "fewer than 3 numbers"),
            ("newmtl a\nKe nan 1 1\n", "usemtl a\nf 1 2 3\n", "finite and non-negative"),
            ("newmtl a\nKd -1 0 0\n", "usemtl a\nf 1 2 3\n", "finite and non-negative"),
            ("newmtl a\n", "usemtl a\nf 1 2\n", "fewer than 3 vertices"),
            ("newmtl a\n", "vt nan 0\nusemtl a\nf 1 2 3\n", "non-finite value"),
            ("newmtl a\n", "vn 0 inf 1\nusemtl a\nf 1 2 3\n", "non-finite value"),
        ];
        for (i, (mtl, tail, want)) in cases.iter().enumerate() {
            write(&dir, &format!("m{i}.mtl"), mtl);
            let text = format!("mtllib m{i}.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n{tail}");
            let e = load(&write(&dir, &format!("o{i}.obj"), &text)).unwrap_err().to_string();
            assert!(e.contains(want), "case {i}: {e}");
        }
    }
}
