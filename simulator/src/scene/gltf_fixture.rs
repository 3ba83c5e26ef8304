//! Hand-built glTF files for the glTF loader's tests (no extra dependencies: JSON strings, a
//! binary buffer and a tiny base64 encoder).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A glTF document under construction: JSON array entries plus one binary buffer.
#[derive(Default)]
pub struct Doc {
    pub bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
    pub meshes: Vec<String>,
    pub nodes: Vec<String>,
    /// Root nodes of scene 0 (all nodes when empty).
    pub roots: Option<Vec<usize>>,
    /// Extra top-level `"key": value` entries (materials, images, extensions, ...).
    pub extra: Vec<String>,
}

impl Doc {
    /// Append raw bytes as a bufferView (4-byte aligned); returns the view index.
    pub fn view(&mut self, bytes: &[u8]) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(format!(r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}}}"#, bytes.len()));
        self.views.len() - 1
    }

    /// Float accessor of type `ty` ("VEC2", "VEC3") with min/max; returns its index.
    pub fn floats(&mut self, data: &[f32], ty: &str) -> usize {
        let dim = if ty == "VEC2" { 2 } else { 3 };
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let (mut lo, mut hi) = (vec![f32::INFINITY; dim], vec![f32::NEG_INFINITY; dim]);
        for (i, &v) in data.iter().enumerate() {
            lo[i % dim] = lo[i % dim].min(v);
            hi[i % dim] = hi[i % dim].max(v);
        }
        self.accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5126,"count":{},"type":"{ty}","min":{lo:?},"max":{hi:?}}}"#,
            data.len() / dim
        ));
        self.accessors.len() - 1
    }

    /// u16 index accessor; returns its index.
    pub fn indices(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors
            .push(format!(r#"{{"bufferView":{view},"componentType":5123,"count":{},"type":"SCALAR"}}"#, data.len()));
        self.accessors.len() - 1
    }

    /// A mesh with one primitive from positions (+ optional normals, indices, extra JSON).
    pub fn mesh(
        &mut self,
        name: &str,
        pos: &[f32],
        nrm: Option<&[f32]>,
        idx: Option<&[u16]>,
        prim_extra: &str,
    ) -> usize {
        let p = self.floats(pos, "VEC3");
        let mut attrs = format!(r#""POSITION":{p}"#);
        if let Some(n) = nrm {
            attrs += &format!(r#","NORMAL":{}"#, self.floats(n, "VEC3"));
        }
        let indices = idx.map(|i| format!(r#","indices":{}"#, self.indices(i))).unwrap_or_default();
        self.meshes
            .push(format!(r#"{{"name":"{name}","primitives":[{{"attributes":{{{attrs}}}{indices}{prim_extra}}}]}}"#));
        self.meshes.len() - 1
    }

    /// The unit right triangle in z = 0 with +Z normals, indexed.
    pub fn triangle(&mut self, prim_extra: &str) -> usize {
        let pos = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let nrm = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
        self.mesh("Tri", &pos, Some(&nrm), Some(&[0, 1, 2]), prim_extra)
    }

    /// Add a node from its JSON body; returns its index.
    pub fn node(&mut self, json: &str) -> usize {
        self.nodes.push(json.to_string());
        self.nodes.len() - 1
    }

    /// The JSON text, with the buffer at `uri` (None: the GLB blob).
    pub fn json(&self, uri: Option<&str>) -> String {
        let uri = uri.map(|u| format!(r#","uri":"{u}""#)).unwrap_or_default();
        let roots = self.roots.clone().unwrap_or_else(|| (0..self.nodes.len()).collect());
        let mut parts = vec![
            r#""asset":{"version":"2.0"}"#.to_string(),
            r#""scene":0"#.to_string(),
            format!(r#""scenes":[{{"nodes":{roots:?}}}]"#),
            format!(r#""nodes":[{}]"#, self.nodes.join(",")),
        ];
        if !self.meshes.is_empty() {
            parts.push(format!(r#""meshes":[{}]"#, self.meshes.join(",")));
        }
        if !self.bin.is_empty() {
            parts.push(format!(r#""buffers":[{{"byteLength":{}{uri}}}]"#, self.bin.len()));
            parts.push(format!(r#""bufferViews":[{}]"#, self.views.join(",")));
        }
        if !self.accessors.is_empty() {
            parts.push(format!(r#""accessors":[{}]"#, self.accessors.join(",")));
        }
        parts.extend(self.extra.iter().cloned());
        format!("{{{}}}", parts.join(","))
    }

    /// Write `name.gltf` with the buffer as a data URI.
    pub fn write_embedded(&self, dir: &Path, name: &str) -> PathBuf {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        write(dir, &format!("{name}.gltf"), self.json(Some(&uri)).as_bytes())
    }

    /// Write `name.gltf` plus `name.bin`.
    pub fn write_external(&self, dir: &Path, name: &str) -> PathBuf {
        write(dir, &format!("{name}.bin"), &self.bin);
        write(dir, &format!("{name}.gltf"), self.json(Some(&format!("{name}.bin"))).as_bytes())
    }

    /// Write `name.glb` with the buffer in the BIN chunk.
    pub fn write_glb(&self, dir: &Path, name: &str) -> PathBuf {
        let mut json = self.json(None).into_bytes();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let total = 12 + 8 + json.len() + 8 + self.bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
        out.extend_from_slice(&json);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(&self.bin);
        write(dir, &format!("{name}.glb"), &out)
    }
}

/// Write `bytes` to `dir/name`, returning the path.
pub fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A fresh, unique temporary directory.
pub fn temp_dir(tag: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("evblur-gltf-{tag}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A small RGBA8 PNG.
pub fn png(width: u32, height: u32, rgba: &[u8]) -> Vec<u8> {
    let img = image::RgbaImage::from_raw(width, height, rgba.to_vec()).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// Assert two vectors agree to `1e-5`.
pub fn assert_close(a: glam::Vec3, b: glam::Vec3) {
    assert!((a - b).abs().max_element() < 1e-5, "{a} != {b}");
}
