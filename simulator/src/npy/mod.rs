//! NumPy `.npy` and `.npz` files without Python: the dataset's `poses_bounds.npy`,
//! `all_timestamps.npy`, `images_1/timestamps.npz`, ... and the event `.npz` sink.
//!
//! An [`NpyArray`] is a 1-D or 2-D C-order array of one of the [`DType`]s, stored little-endian.
//! [`write_npy`] and [`write_npz`] write atomically (a hidden temporary sibling, then a rename);
//! `.npz` is a zip of `name.npy` entries, stored (uncompressed) like `numpy.savez`, without
//! ZIP64, so at most 4 GiB. [`read_npy`] and [`read_npz`] read what numpy writes (`np.save`,
//! `np.savez`, `np.savez_compressed` i.e. deflate) and refuse anything else with an
//! [`NpyError`] naming the file and the problem: Fortran order, big-endian, other dtypes,
//! truncated data.
//!
//! # What lives where
//! - this file: [`DType`], [`NpyData`], [`NpyArray`], [`NpyError`], the read and write functions.
//! - `header`: the `.npy` header (format 1.0/2.0, padded to 64 bytes) and its parser.
//! - `zip`: stored zip entries, the CRC-32 and the zip reader (stored + deflate).

mod header;
pub(crate) mod zip;

use std::path::{Path, PathBuf};

pub(crate) use header::npy_header;

/// The element types this module reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DType {
    /// `float64`, `<f8`.
    F64,
    /// `float32`, `<f4`.
    F32,
    /// `int64`, `<i8`.
    I64,
    /// `uint64`, `<u8`.
    U64,
    /// `int32`, `<i4`.
    I32,
    /// `uint16`, `<u2`.
    U16,
    /// `uint8`, `|u1`.
    U8,
    /// `int8`, `|i1`.
    I8,
    /// `bool`, `|b1` (one byte, 0 or 1).
    Bool,
}

impl DType {
    /// Every dtype, in declaration order.
    pub const ALL: [DType; 9] =
        [DType::F64, DType::F32, DType::I64, DType::U64, DType::I32, DType::U16, DType::U8, DType::I8, DType::Bool];

    /// The numpy `descr` string numpy writes for it (little-endian).
    pub fn descr(self) -> &'static str {
        match self {
            DType::F64 => "<f8",
            DType::F32 => "<f4",
            DType::I64 => "<i8",
            DType::U64 => "<u8",
            DType::I32 => "<i4",
            DType::U16 => "<u2",
            DType::U8 => "|u1",
            DType::I8 => "|i1",
            DType::Bool => "|b1",
        }
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            DType::F64 | DType::I64 | DType::U64 => 8,
            DType::F32 | DType::I32 => 4,
            DType::U16 => 2,
            DType::U8 | DType::I8 | DType::Bool => 1,
        }
    }

    /// The dtype of a `descr`; `Err` says why not (big-endian, or not one of ours).
    fn from_descr(descr: &str) -> Result<DType, String> {
        let (order, code) = (descr.get(..1).unwrap_or(""), descr.get(1..).unwrap_or(""));
        let dtype = DType::ALL.into_iter().find(|d| &d.descr()[1..] == code);
        match (order, dtype) {
            (">", Some(d)) if d.size() > 1 => Err(format!(
                "big-endian dtype '{descr}' is not supported; save it little-endian (arr.astype('<{code}'))"
            )),
            ("<" | "|" | "=" | ">", Some(d)) if d.size() == 1 => Ok(d),
            ("<", Some(d)) => Ok(d),
            _ => Err(format!("dtype '{descr}' is not supported (use one of f8 f4 i8 u8 i4 u2 u1 i1 b1)")),
        }
    }
}

/// The elements of an array, one vector per [`DType`].
#[derive(Clone, Debug, PartialEq)]
pub enum NpyData {
    /// `float64`.
    F64(Vec<f64>),
    /// `float32`.
    F32(Vec<f32>),
    /// `int64`.
    I64(Vec<i64>),
    /// `uint64`.
    U64(Vec<u64>),
    /// `int32`.
    I32(Vec<i32>),
    /// `uint16`.
    U16(Vec<u16>),
    /// `uint8`.
    U8(Vec<u8>),
    /// `int8`.
    I8(Vec<i8>),
    /// `bool`.
    Bool(Vec<bool>),
}

/// Apply `$body` to the vector inside an [`NpyData`], whatever its type.
macro_rules! each {
    ($data:expr, $v:ident => $body:expr) => {
        match $data {
            NpyData::F64($v) => $body,
            NpyData::F32($v) => $body,
            NpyData::I64($v) => $body,
            NpyData::U64($v) => $body,
            NpyData::I32($v) => $body,
            NpyData::U16($v) => $body,
            NpyData::U8($v) => $body,
            NpyData::I8($v) => $body,
            NpyData::Bool($v) => $body,
        }
    };
}

macro_rules! from_vec {
    ($($t:ty => $variant:ident),*) => {$(
        impl From<Vec<$t>> for NpyData {
            fn from(v: Vec<$t>) -> NpyData {
                NpyData::$variant(v)
            }
        }
    )*};
}
from_vec!(f64 => F64, f32 => F32, i64 => I64, u64 => U64, i32 => I32, u16 => U16, u8 => U8, i8 => I8, bool => Bool);

impl NpyData {
    /// Every element as f64 (bool: 0 or 1).
    pub fn to_f64(&self) -> Vec<f64> {
        match self {
            NpyData::F64(v) => v.clone(),
            NpyData::F32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I64(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::U64(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::U16(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::U8(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I8(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::Bool(v) => v.iter().map(|&x| x as u8 as f64).collect(),
        }
    }

    /// Its dtype.
    pub fn dtype(&self) -> DType {
        match self {
            NpyData::F64(_) => DType::F64,
            NpyData::F32(_) => DType::F32,
            NpyData::I64(_) => DType::I64,
            NpyData::U64(_) => DType::U64,
            NpyData::I32(_) => DType::I32,
            NpyData::U16(_) => DType::U16,
            NpyData::U8(_) => DType::U8,
            NpyData::I8(_) => DType::I8,
            NpyData::Bool(_) => DType::Bool,
        }
    }

    /// The number of elements.
    pub fn len(&self) -> usize {
        each!(self, v => v.len())
    }

    /// True if there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The elements as little-endian bytes.
    fn to_le_bytes(&self) -> Vec<u8> {
        fn le<T: Copy, const N: usize>(v: &[T], f: fn(T) -> [u8; N]) -> Vec<u8> {
            v.iter().flat_map(|&x| f(x)).collect()
        }
        match self {
            NpyData::F64(v) => le(v, f64::to_le_bytes),
            NpyData::F32(v) => le(v, f32::to_le_bytes),
            NpyData::I64(v) => le(v, i64::to_le_bytes),
            NpyData::U64(v) => le(v, u64::to_le_bytes),
            NpyData::I32(v) => le(v, i32::to_le_bytes),
            NpyData::U16(v) => le(v, u16::to_le_bytes),
            NpyData::U8(v) => v.clone(),
            NpyData::I8(v) => le(v, i8::to_le_bytes),
            NpyData::Bool(v) => v.iter().map(|&b| b as u8).collect(),
        }
    }

    /// Decode `bytes` (exactly `dtype.size()` per element) as `dtype`.
    fn from_le_bytes(dtype: DType, bytes: &[u8]) -> NpyData {
        macro_rules! decode {
            ($t:ty, $variant:ident) => {
                NpyData::$variant(
                    bytes
                        .chunks_exact(std::mem::size_of::<$t>())
                        .map(|c| <$t>::from_le_bytes(c.try_into().unwrap()))
                        .collect(),
                )
            };
        }
        match dtype {
            DType::F64 => decode!(f64, F64),
            DType::F32 => decode!(f32, F32),
            DType::I64 => decode!(i64, I64),
            DType::U64 => decode!(u64, U64),
            DType::I32 => decode!(i32, I32),
            DType::U16 => decode!(u16, U16),
            DType::U8 => NpyData::U8(bytes.to_vec()),
            DType::I8 => NpyData::I8(bytes.iter().map(|&b| b as i8).collect()),
            DType::Bool => NpyData::Bool(bytes.iter().map(|&b| b != 0).collect()),
        }
    }
}

/// A 1-D or 2-D array in C (row-major) order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    shape: Vec<usize>,
    data: NpyData,
}

impl NpyArray {
    /// An array of `shape` (1 or 2 dimensions, C order) holding `data`; `None` if the shape has
    /// another rank or does not match the number of elements.
    pub fn new(shape: &[usize], data: impl Into<NpyData>) -> Option<NpyArray> {
        let data = data.into();
        let ok =
            matches!(shape.len(), 1 | 2) && shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)) == Some(data.len());
        ok.then(|| NpyArray { shape: shape.to_vec(), data })
    }

    /// A 1-D array of `data`.
    pub fn vector(data: impl Into<NpyData>) -> NpyArray {
        let data = data.into();
        NpyArray { shape: vec![data.len()], data }
    }

    /// A 2-D `float64` array with one row per entry of `rows` (e.g. LLFF pose rows, N x 17).
    pub fn f64_2d<const C: usize>(rows: &[[f64; C]]) -> NpyArray {
        NpyArray { shape: vec![rows.len(), C], data: NpyData::F64(rows.iter().flatten().copied().collect()) }
    }

    /// The dimensions (1 or 2 of them).
    pub fn shape(&self) -> &[usize] {
        &self.shape
    }

    /// The element type.
    pub fn dtype(&self) -> DType {
        self.data.dtype()
    }

    /// The elements, in C order.
    pub fn data(&self) -> &NpyData {
        &self.data
    }

    /// The elements if the dtype is `float64`.
    pub fn as_f64(&self) -> Option<&[f64]> {
        match &self.data {
            NpyData::F64(v) => Some(v),
            _ => None,
        }
    }

    /// The elements if the dtype is `int64`.
    pub fn as_i64(&self) -> Option<&[i64]> {
        match &self.data {
            NpyData::I64(v) => Some(v),
            _ => None,
        }
    }

    /// The whole `.npy` file: header then data.
    pub fn to_npy_bytes(&self) -> Vec<u8> {
        let shape: Vec<u64> = self.shape.iter().map(|&d| d as u64).collect();
        let mut out = npy_header(self.dtype().descr(), &shape);
        out.extend_from_slice(&self.data.to_le_bytes());
        out
    }

    /// Parse a whole `.npy` file; `file` names it in errors.
    pub fn from_npy_bytes(bytes: &[u8], file: &str) -> Result<NpyArray, NpyError> {
        let bad = |problem: String| NpyError::Format { file: file.to_string(), problem };
        let h = header::parse_header(bytes).map_err(bad)?;
        let dtype = DType::from_descr(&h.descr).map_err(bad)?;
        if h.fortran_order && h.shape.iter().filter(|&&d| d > 1).count() > 1 {
            return Err(bad(
                "Fortran (column-major) order is not supported; save a C-order array (np.ascontiguousarray)".into(),
            ));
        }
        if !matches!(h.shape.len(), 1 | 2) {
            return Err(bad(format!(
                "shape {:?} has {} dimensions; only 1-D and 2-D arrays are supported",
                h.shape,
                h.shape.len()
            )));
        }
        let n = h
            .shape
            .iter()
            .try_fold(1usize, |a, &d| a.checked_mul(d))
            .ok_or_else(|| bad(format!("shape {:?} overflows", h.shape)))?;
        let want = n.checked_mul(dtype.size()).ok_or_else(|| bad(format!("shape {:?} overflows", h.shape)))?;
        let got = bytes.len() - h.data_offset;
        if got < want {
            return Err(bad(format!(
                "truncated: shape {:?} of {} needs {want} data bytes, the file has {got}",
                h.shape, h.descr
            )));
        }
        if got > want {
            return Err(bad(format!("{} bytes after the data of shape {:?} (corrupt file?)", got - want, h.shape)));
        }
        Ok(NpyArray { shape: h.shape, data: NpyData::from_le_bytes(dtype, &bytes[h.data_offset..]) })
    }
}

/// Why a `.npy` / `.npz` file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    /// The file system refused.
    #[error("{}: {what}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// The cause.
        source: std::io::Error,
    },
    /// The bytes are not an array this module reads.
    #[error("{file}: {problem}")]
    Format {
        /// The file (for an `.npz` entry: `archive.npz, entry x.npy`).
        file: String,
        /// What is wrong, and the fix where there is one.
        problem: String,
    },
    /// The `.npz` would exceed the zip limit.
    #[error("{}: {size} bytes exceed the 4 GiB zip limit (no ZIP64); write smaller arrays or another format", path.display())]
    TooLarge {
        /// The target.
        path: PathBuf,
        /// The size the archive would have.
        size: u64,
    },
}

/// Write `bytes` to `path` atomically: a hidden temporary sibling, then a rename.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), NpyError> {
    let io = |what, source| NpyError::Io { path: path.to_path_buf(), what, source };
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| io("cannot create the folder", e))?;
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    let result = std::fs::write(&tmp, bytes)
        .map_err(|e| io("cannot write", e))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| io("cannot move into place", e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Write `array` to `path` as a `.npy` file, atomically.
pub fn write_npy(path: &Path, array: &NpyArray) -> Result<(), NpyError> {
    write_atomic(path, &array.to_npy_bytes())
}

/// Write `arrays` to `path` as an `.npz` (entries `name.npy`, stored, as `numpy.savez`),
/// atomically; refused over 4 GiB.
pub fn write_npz(path: &Path, arrays: &[(&str, NpyArray)]) -> Result<(), NpyError> {
    let (mut out, mut central) = (Vec::new(), Vec::new());
    for (name, array) in arrays {
        let name = format!("{name}.npy");
        let npy = array.to_npy_bytes();
        let entry =
            zip::ZipEntry { name: &name, size: npy.len() as u64, crc: zip::crc32(&npy), offset: out.len() as u64 };
        // Everything so far, this entry, its central header and the end record must fit in u32.
        let size = out.len() as u64 + entry.stored_len() + central.len() as u64 + 46 + name.len() as u64 + 22;
        if size > zip::MAX_ZIP {
            return Err(NpyError::TooLarge { path: path.to_path_buf(), size });
        }
        out.extend_from_slice(&entry.local_header());
        out.extend_from_slice(&npy);
        central.extend_from_slice(&entry.central_header());
    }
    let offset = out.len() as u64;
    out.extend_from_slice(&central);
    out.extend_from_slice(&zip::end_record(arrays.len(), central.len(), offset));
    write_atomic(path, &out)
}

/// Read a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray, NpyError> {
    let bytes =
        std::fs::read(path).map_err(|source| NpyError::Io { path: path.to_path_buf(), what: "cannot read", source })?;
    NpyArray::from_npy_bytes(&bytes, &path.display().to_string())
}

/// Read an `.npz` file (stored or deflated entries): `(name, array)` in archive order, the
/// name without its `.npy` suffix (as `np.load(...)[name]`).
pub fn read_npz(path: &Path) -> Result<Vec<(String, NpyArray)>, NpyError> {
    let bytes =
        std::fs::read(path).map_err(|source| NpyError::Io { path: path.to_path_buf(), what: "cannot read", source })?;
    let entries =
        zip::unzip(&bytes).map_err(|problem| NpyError::Format { file: path.display().to_string(), problem })?;
    entries
        .into_iter()
        .map(|(name, data)| {
            let array = NpyArray::from_npy_bytes(&data, &format!("{}, entry {name}", path.display()))?;
            Ok((name.strip_suffix(".npy").unwrap_or(&name).to_string(), array))
        })
        .collect()
}

#[cfg(test)]
mod tests;
