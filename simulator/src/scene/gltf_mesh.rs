//! Flattening glTF mesh primitives into the one world-space [`TriangleMesh`] of a [`Scene`]
//! (part of the glTF loader; the user manual is the module doc of [`super::gltf_load`]).
//!
//! Per primitive instance: check every accessor against its buffer before reading (so that a
//! corrupt file is an error, not a panic), assemble triangles (strips and fans converted),
//! transform positions by `M` and normals by `M^{-T}`, swap two corners when `det M < 0`, drop
//! degenerate triangles and append.

use std::path::Path;

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};

use super::gltf_load::label;
use super::{is_degenerate, vertex_normals, Material, Scene, TriangleMesh};
use crate::error::SceneError;

/// Appends mesh instances to a scene, adding the default material on first need.
pub(super) struct Flattener<'a, 's> {
    path: &'a Path,
    buffers: &'a [Vec<u8>],
    /// The scene being built (the node walker also adds lights and cameras here).
    pub(super) scene: &'s mut Scene,
    /// Index of [`Material::default`] in `scene.materials`, once appended.
    default_material: Option<u32>,
}

impl<'a, 's> Flattener<'a, 's> {
    /// A flattener reading accessors from `buffers` (the loaded glTF buffers, in order).
    pub(super) fn new(path: &'a Path, buffers: &'a [Vec<u8>], scene: &'s mut Scene) -> Self {
        Flattener { path, buffers, scene, default_material: None }
    }

    /// Append one instance of `mesh` placed by the world transform `world`.
    pub(super) fn mesh(&mut self, mesh: gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        let mesh_el = label("mesh", mesh.index(), mesh.name());
        for prim in mesh.primitives() {
            let el = format!("{mesh_el} primitive {}", prim.index());
            self.primitive(&prim, world, &el)?;
        }
        Ok(())
    }

    fn primitive(&mut self, prim: &gltf::Primitive, world: Mat4, el: &str) -> Result<(), SceneError> {
        let path = self.path;
        let mode = prim.mode();
        if matches!(mode, Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip) {
            return Err(SceneError::unsupported(
                path,
                el,
                format!(
                    "mode {mode:?} ({}): only TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN can be rendered; \
                     delete the primitive or turn it into faces",
                    mode.as_gl_enum()
                ),
            ));
        }
        let buffers = self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));

        // vertex attributes: POSITION (required), NORMAL and TEXCOORD_0 (optional)
        let pos_el = format!("{el} attribute POSITION");
        let acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| SceneError::invalid(path, &pos_el, "missing; every primitive needs vertex positions"))?;
        self.check(&acc, Dimensions::Vec3, &[DataType::F32], &pos_el)?;
        let positions: Vec<Vec3> = reader.read_positions().map(|it| it.map(Vec3::from).collect()).unwrap_or_default();
        self.check_read(positions.len(), &acc, &pos_el)?;
        check_finite(path, &positions, Vec3::is_finite, &pos_el)?;
        let n = positions.len();

        let normals = match prim.get(&Semantic::Normals) {
            None => None,
            Some(acc) => {
                let nrm_el = format!("{el} attribute NORMAL");
                self.check(&acc, Dimensions::Vec3, &[DataType::F32], &nrm_el)?;
                let normals: Vec<Vec3> =
                    reader.read_normals().map(|it| it.map(Vec3::from).collect()).unwrap_or_default();
                self.check_read(normals.len(), &acc, &nrm_el)?;
                self.check_same_count(normals.len(), n, &nrm_el)?;
                check_finite(path, &normals, Vec3::is_finite, &nrm_el)?;
                Some(normals)
            }
        };

        let uvs = match prim.get(&Semantic::TexCoords(0)) {
            None => vec![Vec2::ZERO; n],
            Some(acc) => {
                let uv_el = format!("{el} attribute TEXCOORD_0");
                self.check(&acc, Dimensions::Vec2, &[DataType::F32, DataType::U8, DataType::U16], &uv_el)?;
                if acc.data_type() != DataType::F32 && !acc.normalized() {
                    return Err(SceneError::invalid(path, uv_el, "integer texture coordinates must be normalized"));
                }
                let uvs: Vec<Vec2> =
                    reader.read_tex_coords(0).map(|t| t.into_f32().map(Vec2::from).collect()).unwrap_or_default();
                self.check_read(uvs.len(), &acc, &uv_el)?;
                self.check_same_count(uvs.len(), n, &uv_el)?;
                check_finite(path, &uvs, Vec2::is_finite, &uv_el)?;
                uvs
            }
        };

        // vertex ids: the index accessor, or 0..n for non-indexed primitives
        let ids: Vec<u32> = match prim.indices() {
            None => (0..n as u32).collect(),
            Some(acc) => {
                let idx_el = format!("{el} indices");
                self.check(&acc, Dimensions::Scalar, &[DataType::U8, DataType::U16, DataType::U32], &idx_el)?;
                let ids: Vec<u32> = reader.read_indices().map(|i| i.into_u32().collect()).unwrap_or_default();
                self.check_read(ids.len(), &acc, &idx_el)?;
                if let Some((k, &v)) = ids.iter().enumerate().find(|(_, &v)| v as usize >= n) {
                    return Err(SceneError::invalid(
                        path,
                        idx_el,
                        format!("index {k} is {v}, out of range: the primitive has {n} vertices"),
                    ));
                }
                ids
            }
        };
        let mut tris = assemble(mode, &ids).map_err(|m| SceneError::invalid(path, el, m))?;

        // to world space: p' = M p, n' = normalize(M^{-T} n); a mirror flips the winding
        let m3 = Mat3::from_mat4(world);
        let normal_matrix = m3.inverse().transpose();
        let world_pos: Vec<Vec3> = positions.iter().map(|&p| world.transform_point3(p)).collect();
        if m3.determinant() < 0.0 {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }
        let total = tris.len();
        tris.retain(|t| !is_degenerate(t.map(|i| world_pos[i as usize])));
        if tris.len() < total {
            self.scene.warnings.push(format!(
                "{}: {el}: skipped {} degenerate (zero-area) triangles of {total}",
                path.display(),
                total - tris.len()
            ));
        }
        if tris.is_empty() {
            return Ok(());
        }
        let generated = vertex_normals(&world_pos, &tris);
        let world_normals = match normals {
            // a normal that vanishes under the transform falls back to the generated one
            Some(ns) => {
                ns.iter().zip(&generated).map(|(&nv, &g)| (normal_matrix * nv).try_normalize().unwrap_or(g)).collect()
            }
            None => generated,
        };

        let material = match prim.material().index() {
            Some(i) => i as u32,
            None => self.default_material(),
        };
        let part = TriangleMesh {
            positions: world_pos,
            normals: world_normals,
            uvs,
            material: vec![material; tris.len()],
            indices: tris,
        };
        self.scene.mesh.append(&part);
        Ok(())
    }

    /// The index of [`Material::default`], appending it on first use.
    fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::default());
            self.scene.materials.len() as u32 - 1
        })
    }

    /// Check an accessor's type and that all the bytes it reads lie inside its buffer, so that
    /// reading it cannot fail half-way (or panic inside the `gltf` crate).
    fn check(&self, acc: &gltf::Accessor, dims: Dimensions, types: &[DataType], el: &str) -> Result<(), SceneError> {
        let bad = |msg: String| SceneError::invalid(self.path, el, format!("accessor {}: {msg}", acc.index()));
        if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
            return Err(bad(format!(
                "has type {:?} of {:?}; expected {dims:?} of one of {types:?}",
                acc.dimensions(),
                acc.data_type()
            )));
        }
        if acc.count() == 0 {
            return Err(bad("count is 0; remove the empty primitive".into()));
        }
        let size = acc.size();
        if let Some(view) = acc.view() {
            self.check_range(&view, acc.offset(), size, acc.count()).map_err(bad)?;
        }
        match acc.sparse() {
            Some(sparse) => {
                if sparse.count() == 0 || sparse.count() > acc.count() {
                    return Err(bad(format!("sparse count {} must be in 1..={}", sparse.count(), acc.count())));
                }
                let indices = sparse.indices();
                let index_size = indices.index_type().size();
                self.check_range(&indices.view(), indices.offset(), index_size, sparse.count()).map_err(&bad)?;
                let values = sparse.values();
                self.check_range(&values.view(), values.offset(), size, sparse.count()).map_err(&bad)?;
            }
            None if acc.view().is_none() => {
                return Err(bad("has neither a bufferView nor sparse data (all zeros); export real data".into()))
            }
            None => {}
        }
        Ok(())
    }

    /// `count` elements of `size` bytes from `offset` in `view` (with its stride) fit the buffer.
    fn check_range(&self, view: &gltf::buffer::View, offset: usize, size: usize, count: usize) -> Result<(), String> {
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(format!(
                "bufferView {} byteStride {stride} is smaller than the element size {size}",
                view.index()
            ));
        }
        let data_len = self.buffers.get(view.buffer().index()).map_or(0, Vec::len);
        let view_end = view.offset().checked_add(view.length());
        let needed =
            stride.checked_mul(count - 1).and_then(|b| b.checked_add(size)).and_then(|b| b.checked_add(offset));
        match (view_end, needed) {
            (Some(end), Some(needed)) if end <= data_len && needed <= view.length() => Ok(()),
            _ => Err(format!(
                "reads past the end of bufferView {} or its buffer ({count} elements of {size} bytes at \
                 offset {offset}, stride {stride}); the file is truncated or inconsistent",
                view.index()
            )),
        }
    }

    /// The reader returned as many elements as the accessor declares.
    fn check_read(&self, got: usize, acc: &gltf::Accessor, el: &str) -> Result<(), SceneError> {
        if got == acc.count() {
            return Ok(());
        }
        Err(SceneError::invalid(
            self.path,
            el,
            format!("accessor {}: read {got} of {} elements; the buffer data is incomplete", acc.index(), acc.count()),
        ))
    }

    /// A vertex attribute has one element per vertex.
    fn check_same_count(&self, got: usize, n: usize, el: &str) -> Result<(), SceneError> {
        if got == n {
            return Ok(());
        }
        Err(SceneError::invalid(self.path, el, format!("has {got} elements but POSITION has {n}; they must match")))
    }
}

/// The first non-finite value is an error naming the vertex.
fn check_finite<T: std::fmt::Debug + Copy>(
    path: &Path,
    values: &[T],
    is_finite: impl Fn(T) -> bool,
    el: &str,
) -> Result<(), SceneError> {
    match values.iter().position(|&v| !is_finite(v)) {
        None => Ok(()),
        Some(i) => Err(SceneError::invalid(
            path,
            el,
            format!("vertex {i} is {:?}, not finite (NaN or infinity); fix the exporter or the mesh", values[i]),
        )),
    }
}

/// Triangles from the vertex ids of a primitive (glTF spec 3.7.2.1): TRIANGLES takes ids in
/// threes; strip triangle `i` is `(v_i, v_{i+1}, v_{i+2})`, with the last two swapped for odd
/// `i` to keep the winding; fan triangle `i` is `(v_{i+1}, v_{i+2}, v_0)`.
fn assemble(mode: Mode, ids: &[u32]) -> Result<Vec<[u32; 3]>, String> {
    let n = ids.len();
    Ok(match mode {
        Mode::Triangles => {
            if !n.is_multiple_of(3) {
                return Err(format!("mode TRIANGLES with {n} vertex ids, which is not a multiple of 3"));
            }
            ids.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| if i % 2 == 0 { [ids[i], ids[i + 1], ids[i + 2]] } else { [ids[i], ids[i + 2], ids[i + 1]] })
            .collect(),
        Mode::TriangleFan => (1..n.saturating_sub(1)).map(|i| [ids[i], ids[i + 1], ids[0]]).collect(),
        _ => return Err(format!("mode {mode:?} is not a triangle mode")),
    })
}

#[cfg(test)]
mod tests {
    use super::super::gltf_fixture::{assert_close, temp_dir, Doc};
    use super::super::gltf_load::load;
    use super::*;

    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;

    /// Unit geometric normal of triangle `i` from its counter-clockwise winding.
    fn geometric_normal(m: &TriangleMesh, i: usize) -> Vec3 {
        let [a, b, c] = m.corners(i);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn trs_node_places_triangle() {
        let mut d = Doc::default();
        d.triangle("");
        // p' = T R S p with S = 2, R = +90 deg about Z, T = (1, 2, 3)
        d.node(&format!(r#"{{"mesh":0,"translation":[1,2,3],"rotation":[0,0,{H},{H}],"scale":[2,2,2]}}"#));
        let s = load(&d.write_embedded(&temp_dir("trs"), "trs")).unwrap();
        let m = &s.mesh;
        assert_eq!(m.len(), 1);
        assert_close(m.positions[0], Vec3::new(1.0, 2.0, 3.0));
        assert_close(m.positions[1], Vec3::new(1.0, 4.0, 3.0)); // (1,0,0) -> (2,0,0) -> (0,2,0)
        assert_close(m.positions[2], Vec3::new(-1.0, 2.0, 3.0)); // (0,1,0) -> (0,2,0) -> (-2,0,0)
        for n in &m.normals {
            assert_close(*n, Vec3::Z);
        }
        assert_close(geometric_normal(m, 0), Vec3::Z);
    }

    #[test]
    fn matrix_node_composes_with_parent_and_normals_use_inverse_transpose() {
        let mut d = Doc::default();
        let pos = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let nrm = [H, H, 0.0, H, H, 0.0, H, H, 0.0];
        d.mesh("Slant", &pos, Some(&nrm), None, "");
        // child: column-major matrix scaling x by 3 then translating by (1, 0, 0)
        d.node(r#"{"mesh":0,"matrix":[3,0,0,0, 0,1,0,0, 0,0,1,0, 1,0,0,1]}"#);
        d.node(r#"{"translation":[0,0,5],"children":[0]}"#);
        d.roots = Some(vec![1]);
        let s = load(&d.write_embedded(&temp_dir("matrix"), "matrix")).unwrap();
        let m = &s.mesh;
        assert_close(m.positions[0], Vec3::new(4.0, 0.0, 5.0));
        assert_close(m.positions[1], Vec3::new(1.0, 1.0, 5.0));
        assert_close(m.positions[2], Vec3::new(1.0, 0.0, 6.0));
        // M^{-T} = diag(1/3, 1, 1): (1, 1, 0) -> (1/3, 1, 0)
        let expected = Vec3::new(1.0 / 3.0, 1.0, 0.0).normalize();
        for n in &m.normals {
            assert_close(*n, expected);
        }
    }

    #[test]
    fn negative_scale_flips_winding() {
        let mut d = Doc::default();
        d.triangle("");
        d.node(r#"{"mesh":0,"scale":[-1,1,1]}"#);
        let s = load(&d.write_embedded(&temp_dir("mirror"), "mirror")).unwrap();
        let m = &s.mesh;
        // mirrored corners are (0,0,0), (-1,0,0), (0,1,0); kept in file order they would wind
        // clockwise around +Z; with two corners swapped the geometric normal is +Z again
        assert_close(geometric_normal(m, 0), Vec3::Z);
        assert_eq!(m.indices[0], [0, 2, 1]);
        assert_close(m.positions[1], Vec3::new(-1.0, 0.0, 0.0));
        assert_close(m.normals[0], Vec3::Z);
        assert!(geometric_normal(m, 0).dot(m.normals[0]) > 0.999);
    }

    #[test]
    fn instanced_mesh_emitted_per_node() {
        let mut d = Doc::default();
        d.triangle("");
        d.node(r#"{"mesh":0}"#);
        d.node(r#"{"mesh":0,"translation":[10,0,0]}"#);
        let s = load(&d.write_embedded(&temp_dir("inst"), "inst")).unwrap();
        let m = &s.mesh;
        assert_eq!(m.len(), 2);
        assert_eq!(m.positions.len(), 6);
        let (a, b) = (m.corners(0), m.corners(1));
        for k in 0..3 {
            assert_close(b[k], a[k] + Vec3::new(10.0, 0.0, 0.0));
        }
        assert_eq!(m.indices[1], [3, 4, 5]);
    }

    #[test]
    fn non_indexed_primitive_gets_generated_normals_and_default_material() {
        let mut d = Doc::default();
        // winding (0,0,0) -> (0,0,1) -> (1,0,0) faces +Y
        d.mesh("Floor", &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0], None, None, "");
        d.node(r#"{"mesh":0}"#);
        let s = load(&d.write_embedded(&temp_dir("noidx"), "noidx")).unwrap();
        let m = &s.mesh;
        assert_eq!(m.indices, vec![[0, 1, 2]]);
        for n in &m.normals {
            assert_close(*n, Vec3::Y);
        }
        assert_eq!(m.uvs, vec![Vec2::ZERO; 3]);
        assert_eq!(s.materials, vec![Material::default()]);
        assert_eq!(m.material, vec![0]);
    }

    #[test]
    fn strips_and_fans_become_counter_clockwise_triangles() {
        let mut d = Doc::default();
        // unit square in z = 0; strip order 0 1 2 3 = (0,0) (1,0) (0,1) (1,1)
        let strip = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0];
        d.mesh("Strip", &strip, None, None, r#","mode":5"#);
        // fan around (0,0): (1,0) (1,1) (0,1)
        let fan = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
        d.mesh("Fan", &fan, None, Some(&[0, 1, 2, 3]), r#","mode":6"#);
        d.node(r#"{"mesh":0}"#);
        d.node(r#"{"mesh":1,"translation":[5,0,0]}"#);
        let s = load(&d.write_embedded(&temp_dir("strip"), "strip")).unwrap();
        let m = &s.mesh;
        assert_eq!(m.len(), 4);
        assert_eq!(m.indices[0], [0, 1, 2]);
        assert_eq!(m.indices[1], [1, 3, 2]);
        assert_eq!(m.indices[2], [5, 6, 4]);
        assert_eq!(m.indices[3], [6, 7, 4]);
        for i in 0..4 {
            assert_close(geometric_normal(m, i), Vec3::Z);
        }
        // the two halves of each square cover area 1
        let area: f32 = (0..2)
            .map(|i| {
                let [a, b, c] = m.corners(i);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        assert!((area - 1.0).abs() < 1e-6);
    }

    #[test]
    fn degenerate_triangles_skipped_with_one_warning() {
        let mut d = Doc::default();
        let pos = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0];
        d.mesh("Sliver", &pos, None, Some(&[0, 1, 2, 0, 1, 3, 1, 3, 0]), "");
        d.node(r#"{"mesh":0}"#);
        let s = load(&d.write_embedded(&temp_dir("degen"), "degen")).unwrap();
        assert_eq!(s.mesh.indices, vec![[0, 1, 2]]);
        assert_eq!(s.warnings.len(), 1);
        let w = &s.warnings[0];
        assert!(w.contains("mesh 0 \"Sliver\" primitive 0") && w.contains("skipped 2 degenerate"), "{w}");
    }

    #[test]
    fn points_primitive_is_unsupported() {
        let mut d = Doc::default();
        d.triangle("");
        d.mesh("Dots", &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0], None, None, r#","mode":0"#);
        d.node(r#"{"mesh":0}"#);
        d.node(r#"{"mesh":1}"#);
        let e = load(&d.write_embedded(&temp_dir("points"), "points")).unwrap_err();
        assert!(
            matches!(e, SceneError::Unsupported { ref element, .. } if element == "mesh 1 \"Dots\" primitive 0"),
            "{e}"
        );
        assert!(e.to_string().contains("Points"), "{e}");
    }

    #[test]
    fn nan_position_is_invalid() {
        let mut d = Doc::default();
        d.mesh("Bad", &[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0], None, None, "");
        d.node(r#"{"mesh":0}"#);
        let e = load(&d.write_embedded(&temp_dir("nan"), "nan")).unwrap_err();
        assert!(
            matches!(e, SceneError::Invalid { ref element, .. }
                if element == "mesh 0 \"Bad\" primitive 0 attribute POSITION"),
            "{e}"
        );
        assert!(e.to_string().contains("vertex 1"), "{e}");
    }

    #[test]
    fn index_out_of_range_is_invalid() {
        let mut d = Doc::default();
        d.mesh("Far", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], None, Some(&[0, 1, 7]), "");
        d.node(r#"{"mesh":0}"#);
        let e = load(&d.write_embedded(&temp_dir("oob"), "oob")).unwrap_err();
        assert!(
            matches!(e, SceneError::Invalid { ref element, .. } if element == "mesh 0 \"Far\" primitive 0 indices"),
            "{e}"
        );
        assert!(e.to_string().contains("index 2 is 7"), "{e}");
    }

    #[test]
    fn accessor_past_buffer_end_is_invalid_not_a_panic() {
        let mut d = Doc::default();
        d.triangle("");
        d.node(r#"{"mesh":0}"#);
        // claim 300 positions in a view that holds 3
        let dir = temp_dir("short");
        let json = d.json(Some("short.bin")).replacen(r#""count":3,"type":"VEC3""#, r#""count":300,"type":"VEC3""#, 1);
        super::super::gltf_fixture::write(&dir, "short.bin", &d.bin);
        let path = super::super::gltf_fixture::write(&dir, "short.gltf", json.as_bytes());
        let e = load(&path).unwrap_err();
        assert!(e.to_string().contains("attribute POSITION") && e.to_string().contains("reads past the end"), "{e}");
    }
}
