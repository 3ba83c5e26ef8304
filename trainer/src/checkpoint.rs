//! Checkpoints: parameters, Adam moments and the step, in one binary file written atomically
//! (temporary file + rename), so an interrupted write leaves the previous checkpoint intact.
//! Layout (little-endian): magic `EVBLURCK`, format version u32, layout fingerprint u64, step
//! u64, parameter count u64, then params, m and v as f32, then (format 4) the occupancy grid's
//! word count u64 (0: none) and its words as u64, then (formats 3 and 4) a u64 checksum of
//! everything before it, so a flipped or lost byte is refused instead of resuming to NaN or to
//! other numbers (formats 2, without the checksum, and 3, without the grid, still load). Same run, same bytes: the training
//! wall time, which cannot repeat, goes to a text sidecar (`<checkpoint>.seconds`:
//! "step seconds").

use std::path::Path;

use crate::engine::adam::Adam;
use crate::engine::params::Layout;
use crate::error::TrainError;

const MAGIC: &[u8; 8] = b"EVBLURCK";
const VERSION: u32 = 4;
/// The format before the occupancy grid.
const VERSION_NO_GRID: u32 = 3;
/// The format before the checksum.
const VERSION_UNCHECKED: u32 = 2;
const HEADER: usize = 36;
const CHECKSUM: usize = 8;

/// A 64-bit checksum of `bytes` (8-byte words, multiply-xorshift mixed; the tail zero-padded):
/// fast enough for checkpoints of hundreds of MB, and any flipped byte changes it.
pub fn checksum(bytes: &[u8]) -> u64 {
    const K: u64 = 0x9e37_79b9_7f4a_7c15;
    let mix = |h: u64, w: u64| {
        let h = (h ^ w).wrapping_mul(K);
        h ^ (h >> 29)
    };
    let mut chunks = bytes.chunks_exact(8);
    let mut h = mix(0x6576_626c_7572_636b, bytes.len() as u64);
    for c in &mut chunks {
        h = mix(h, u64::from_le_bytes(c.try_into().expect("8 bytes")));
    }
    let mut tail = [0u8; 8];
    tail[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    mix(h, u64::from_le_bytes(tail))
}

/// A training state.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    /// Iterations done.
    pub step: u64,
    /// Training wall time so far (s), excluding evaluation (kept in the sidecar file).
    pub seconds: f64,
    /// Parameters.
    pub params: Vec<f32>,
    /// Optimiser state.
    pub adam: Adam,
    /// The occupancy grid's bits ([`OccupancyGrid`](crate::engine::occupancy::OccupancyGrid)),
    /// if the model has one.
    pub occupancy: Option<Vec<u64>>,
}

/// A hash of tensor names and sizes: a checkpoint only loads into the layout it was saved from.
pub fn fingerprint(layout: &Layout) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for t in &layout.tensors {
        for b in t.name.bytes().chain((t.range.len() as u64).to_le_bytes()) {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    h
}

impl Checkpoint {
    /// Writes the checkpoint to `path` atomically.
    pub fn save(&self, layout: &Layout, path: &Path) -> Result<(), TrainError> {
        let n = self.params.len();
        let mut bytes = Vec::with_capacity(HEADER + 12 * n + CHECKSUM);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&VERSION.to_le_bytes());
        bytes.extend_from_slice(&fingerprint(layout).to_le_bytes());
        bytes.extend_from_slice(&self.step.to_le_bytes());
        bytes.extend_from_slice(&(n as u64).to_le_bytes());
        for v in [&self.params, &self.adam.m, &self.adam.v] {
            for x in v.iter() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
        let grid = self.occupancy.as_deref().unwrap_or(&[]);
        bytes.extend_from_slice(&(grid.len() as u64).to_le_bytes());
        for w in grid {
            bytes.extend_from_slice(&w.to_le_bytes());
        }
        let sum = checksum(&bytes);
        bytes.extend_from_slice(&sum.to_le_bytes());
        let write = |p: &Path, b: &[u8]| {
            simulator::image_io::write_atomic(p, b).map_err(|e| {
                TrainError::run(
                    p,
                    format!("cannot write the checkpoint: {e:#}"),
                    "free disk space or choose another --out",
                )
            })
        };
        write(path, &bytes)?;
        write(&seconds_path(path), format!("{} {}\n", self.step, self.seconds).as_bytes())
    }

    /// Reads a checkpoint saved for `layout`.
    pub fn load(layout: &Layout, path: &Path) -> Result<Checkpoint, TrainError> {
        let bytes = std::fs::read(path).map_err(|e| TrainError::io(path, e, "train first (evtrain train)"))?;
        let bad = |what: &str| TrainError::run(path, what.to_string(), "delete the run folder and train again");
        if bytes.len() < HEADER || &bytes[..8] != MAGIC {
            return Err(bad("not an evblur checkpoint (bad header)"));
        }
        let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if !(VERSION_UNCHECKED..=VERSION).contains(&version) {
            return Err(bad(&format!(
                "checkpoint format {version}, this build reads {VERSION_UNCHECKED} to {VERSION}"
            )));
        }
        let tail = if version >= VERSION_NO_GRID { CHECKSUM } else { 0 };
        if u64_at(12) != fingerprint(layout) {
            return Err(bad("saved for a different model shape than config.toml describes"));
        }
        let step = u64_at(20);
        let n = u64_at(28) as usize;
        let truncated = || bad(&format!("truncated: {} bytes for {} parameters", bytes.len(), layout.len()));
        if n != layout.len() {
            return Err(truncated());
        }
        let body = HEADER + 12 * n;
        // Format 4: the grid's word count after the moments.
        let grid_words = if version == VERSION {
            if bytes.len() < body + 8 {
                return Err(truncated());
            }
            u64_at(body)
        } else {
            0
        };
        let grid_bytes = if version == VERSION { 8 + 8 * grid_words as u128 } else { 0 };
        if bytes.len() as u128 != body as u128 + grid_bytes + tail as u128 {
            return Err(truncated());
        }
        if tail > 0 {
            let body = bytes.len() - CHECKSUM;
            if u64::from_le_bytes(bytes[body..].try_into().expect("8 bytes")) != checksum(&bytes[..body]) {
                return Err(bad("corrupted: its checksum does not match its content"));
            }
        }
        let read = |k: usize| -> Vec<f32> {
            bytes[HEADER + 4 * n * k..HEADER + 4 * n * (k + 1)]
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect()
        };
        // The wall time of the same step, when the sidecar has it (0 otherwise).
        let seconds = std::fs::read_to_string(seconds_path(path))
            .ok()
            .and_then(|t| {
                let mut it = t.split_whitespace();
                let s: u64 = it.next()?.parse().ok()?;
                let secs: f64 = it.next()?.parse().ok()?;
                (s == step && secs.is_finite()).then_some(secs)
            })
            .unwrap_or(0.0);
        let occupancy = (grid_words > 0).then(|| {
            let at = body + 8;
            bytes[at..at + 8 * grid_words as usize]
                .chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect()
        });
        Ok(Checkpoint { step, seconds, params: read(0), adam: Adam { m: read(1), v: read(2), t: step }, occupancy })
    }
}

/// The wall-time sidecar of a checkpoint file.
pub fn seconds_path(path: &Path) -> std::path::PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".seconds");
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::params::LrClass;

    #[test]
    fn round_trip_keeps_state_and_wall_time_in_the_sidecar() {
        let mut layout = Layout::default();
        layout.alloc("a", 3, LrClass::Volume);
        let dir = std::env::temp_dir().join(format!("evblur-ck-{}", std::process::id()));
        let path = dir.join("checkpoint.bin");
        let ck = Checkpoint {
            step: 7,
            seconds: 12.5,
            params: vec![1.0, -2.0, 3.5],
            adam: Adam { m: vec![0.1, 0.2, 0.3], v: vec![1e-3, 2e-3, 3e-3], t: 7 },
            occupancy: Some(vec![0x0123_4567_89ab_cdef, 7]),
        };
        ck.save(&layout, &path).unwrap();
        assert_eq!(Checkpoint::load(&layout, &path).unwrap(), ck);
        // The binary file does not depend on the wall time.
        let bytes = std::fs::read(&path).unwrap();
        Checkpoint { seconds: 99.0, ..ck.clone() }.save(&layout, &path).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        // A sidecar of another step is ignored (time unknown: 0).
        std::fs::write(seconds_path(&path), "6 3.0\n").unwrap();
        assert_eq!(Checkpoint::load(&layout, &path).unwrap().seconds, 0.0);
        // Any flipped byte is refused: in a value, in the step, in the checksum itself.
        for at in [HEADER + 5, 20, bytes.len() - 1] {
            let mut bad = bytes.clone();
            bad[at] ^= 0x10;
            std::fs::write(&path, &bad).unwrap();
            let e = Checkpoint::load(&layout, &path).unwrap_err().to_string();
            assert!(e.contains("checksum") && e.contains("checkpoint.bin"), "byte {at}: {e}");
        }
        // A checkpoint without a grid.
        let no_grid = Checkpoint { occupancy: None, ..ck.clone() };
        no_grid.save(&layout, &path).unwrap();
        assert_eq!(Checkpoint::load(&layout, &path).unwrap(), no_grid);
        // The previous formats (3, no grid; 2, no checksum either) still load.
        let body = HEADER + 12 * 3;
        let mut v3 = bytes[..body].to_vec();
        v3[8..12].copy_from_slice(&VERSION_NO_GRID.to_le_bytes());
        let sum = checksum(&v3);
        v3.extend_from_slice(&sum.to_le_bytes());
        std::fs::write(&path, &v3).unwrap();
        assert_eq!(Checkpoint::load(&layout, &path).unwrap(), no_grid);
        let mut old = bytes[..body].to_vec();
        old[8..12].copy_from_slice(&VERSION_UNCHECKED.to_le_bytes());
        std::fs::write(&path, &old).unwrap();
        assert_eq!(Checkpoint::load(&layout, &path).unwrap().params, ck.params);
        // A grid cut short is refused.
        std::fs::write(&path, &bytes[..bytes.len() - 12]).unwrap();
        let e = Checkpoint::load(&layout, &path).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
