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
        let acc = prim.get(&Semantic::Positions).ok_or_else(|| {
            SceneError::invalid(path, &pos_el, "missing; every primitive needs vertex positions")
        })?;
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
                let normals: Vec<Vec3> = reader.read_normals().map(|it| it.map(Vec3::from).collect()).unwrap_or_default();
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
            return Err(format!("bufferView {} byteStride {stride} is smaller than the element size {size}", view.index()));
        }
        let data_len = self.buffers.get(view.buffer().index()).map_or(0, Vec::len);
        let view_end = view.offset().checked_add(view.length());
        let needed = stride.checked_mul(count - 1).and_then(|b| b.checked_add(size)).and_then(|b| b.checked_add(offset));
        match (view_end, needed) {
            (Some(end), Some(needed)) if end <= data_len && needed <= view.length() => Ok(()),
            _ => Err(format!(
                "reads past the end of bufferView {} or its buffer ({count} elements of {size} bytes at offset {offset}, \
                 stride {stride}); the file is truncated or inconsistent",
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
            if n % 3 != 0 {
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
