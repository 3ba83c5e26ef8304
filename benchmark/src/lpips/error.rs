//! Why LPIPS weights could not be loaded or a distance not computed. Weights errors name the
//! file and say how to make a good one; image errors give the sizes involved.

use std::path::PathBuf;

/// The fix for every malformed weights file.
const REEXPORT: &str = super::INSTALL_HINT;

/// An LPIPS failure: an unreadable or malformed weights file, or images it cannot score.
#[derive(Debug, thiserror::Error)]
pub enum LpipsError {
    /// The weights file could not be read.
    #[error("cannot read LPIPS weights {}: {source}; pass an existing file ({REEXPORT})", path.display())]
    Io {
        /// The weights file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file does not start with the magic bytes `EVBLPIPS`.
    #[error("{}: not an LPIPS weights file (starts with {found:?}, expected \"EVBLPIPS\"); {REEXPORT}", path.display())]
    BadMagic {
        /// The weights file.
        path: PathBuf,
        /// Its first bytes (up to 8), lossily as text.
        found: String,
    },
    /// The format version is not the one this build reads.
    #[error("{}: LPIPS weights format version {found}, this build reads version {expected}; {REEXPORT}", path.display())]
    Version {
        /// The weights file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        expected: u32,
    },
    /// The file ends before `what` (at byte `offset`) is complete.
    #[error("{}: truncated at byte {offset}: {what} is missing or incomplete (file has {len} bytes); {REEXPORT}", path.display())]
    Truncated {
        /// The weights file.
        path: PathBuf,
        /// Byte offset of the incomplete item.
        offset: usize,
        /// The item, e.g. "data of conv2.weight".
        what: String,
        /// File length (bytes).
        len: usize,
    },
    /// The file holds another number of tensors than the 15 of LPIPS-alex.
    #[error("{}: {found} tensors, expected {expected} (5 conv weights + 5 biases + 5 heads); {REEXPORT}", path.display())]
    TensorCount {
        /// The weights file.
        path: PathBuf,
        /// Count in the file.
        found: u32,
        /// Count expected.
        expected: u32,
    },
    /// Tensor `index` has another name than the one expected at that position.
    #[error("{}: tensor {index} is named {found:?}, expected {expected:?} (tensors come in a fixed order); {REEXPORT}", path.display())]
    WrongName {
        /// The weights file.
        path: PathBuf,
        /// Position in the file (0-based).
        index: usize,
        /// Name in the file.
        found: String,
        /// Name expected.
        expected: &'static str,
    },
    /// A tensor has another shape than AlexNet / the LPIPS heads need.
    #[error("{}: tensor {name} has shape {found}, expected {expected:?}; {REEXPORT}", path.display())]
    WrongShape {
        /// The weights file.
        path: PathBuf,
        /// Tensor name.
        name: &'static str,
        /// Shape in the file, e.g. "[64, 3, 11, 11]" or "rank 9".
        found: String,
        /// Shape expected.
        expected: Vec<usize>,
    },
    /// A weight is NaN or infinite, or a head weight is negative (LPIPS v0.1 clamps them to >= 0).
    #[error("{}: {name}[{index}] = {value} is invalid ({reason}); {REEXPORT}", path.display())]
    BadValue {
        /// The weights file.
        path: PathBuf,
        /// Tensor name.
        name: &'static str,
        /// Flat index of the value.
        index: usize,
        /// The value.
        value: f32,
        /// "not finite" or "negative head weight".
        reason: &'static str,
    },
    /// Bytes follow the last tensor.
    #[error("{}: {extra} unexpected bytes after the last tensor; {REEXPORT}", path.display())]
    TrailingBytes {
        /// The weights file.
        path: PathBuf,
        /// Number of extra bytes.
        extra: usize,
    },
    /// The data slice does not hold `width * height * 3` values.
    #[error(
        "image data holds {actual} values but {width}x{height} RGB needs {expected}; \
         pass the interleaved row-major RGB buffer of exactly that image"
    )]
    DataLength {
        /// Width (pixels).
        width: usize,
        /// Height (pixels).
        height: usize,
        /// `width * height * 3`.
        expected: u128,
        /// Length of the slice given.
        actual: usize,
    },
    /// The two images differ in width or height.
    #[error("images differ in size: {}x{} vs {}x{} (width x height); compare images of one size", a[0], a[1], b[0], b[1])]
    SizeMismatch {
        /// First image: width, height.
        a: [usize; 2],
        /// Second image: width, height.
        b: [usize; 2],
    },
    /// AlexNet's conv1 and two max pools leave no pixel.
    #[error(
        "LPIPS (AlexNet) needs images of at least {min}x{min} pixels, got {width}x{height}; \
         compare larger images"
    )]
    TooSmall {
        /// Width (pixels).
        width: usize,
        /// Height (pixels).
        height: usize,
        /// Smallest side that works.
        min: usize,
    },
}
