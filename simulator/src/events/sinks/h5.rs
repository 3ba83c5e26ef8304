//! HDF5 event files, written with the pure-Rust `rust-hdf5` crate (no libhdf5 needed).
//!
//! - [`NerfH5Sink`] (Ev-DeblurNeRF, `docs/dataset-format.md`): root datasets `x` u16, `y` u16,
//!   `t` i64 (ns, the frame clock), `p` i8 (+1 ON, -1 OFF; the loader accepts {-1, +1} or {0, 1}).
//! - [`DsecH5Sink`] (DSEC): `/events/x` u16, `/events/y` u16, `/events/t` u32 (us since
//!   `t_offset`), `/events/p` u8 (1 ON, 0 OFF); `/t_offset` i64 scalar (us, the first event's time
//!   floored to the microsecond, 0 when there are no events) so that the frame-clock time in us
//!   is `t + t_offset`; `/ms_to_idx` u64 where `ms_to_idx[m]` is the index of the first event with
//!   `t >= 1000 m`, for `m = 0 ..= t_last / 1000` (as DSEC: `searchsorted(t, 1000 m)`).
//!
//! All 1-D datasets are chunked (65536 elements), resizable, shuffled and deflate-compressed, and
//! grow by appending each batch; `rust-hdf5` buffers the last partial chunk until the file is
//! closed, so memory stays at one batch plus one chunk per dataset.

use std::io;
use std::path::Path;

use rayon::prelude::*;
use rust_hdf5::{H5Dataset, H5File, H5Type};

use super::{io_err, AtomicTarget};
use crate::events::{Event, EventSink};

/// Elements per HDF5 chunk.
const CHUNK: usize = 1 << 16;
/// Deflate level (1 fast .. 9 small).
const DEFLATE: u32 = 4;

/// An empty, growable, compressed 1-D dataset named `name` in `group` ("" for the root).
fn growable<T: H5Type>(file: &H5File, group: Option<&rust_hdf5::H5Group>, name: &str) -> rust_hdf5::Result<H5Dataset> {
    let builder = match group {
        Some(g) => g.new_dataset::<T>(),
        None => file.new_dataset::<T>(),
    };
    builder.shape([0usize]).chunk(&[CHUNK]).max_shape(&[None]).shuffle_deflate(DEFLATE).create(name)
}

/// The columns of one batch, reused between batches.
#[derive(Default)]
struct Columns<T, P> {
    x: Vec<u16>,
    y: Vec<u16>,
    t: Vec<T>,
    p: Vec<P>,
}

impl<T, P> Columns<T, P> {
    fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.t.clear();
        self.p.clear();
    }
}

/// Full chunks a [`NerfH5Sink`] gathers before compressing them together.
const FLUSH_CHUNKS: usize = 1;

/// One chunk's bytes as stored (little-endian, as `append` stores them on this platform).
trait Le: Copy + Default + Send + Sync {
    fn put(v: &[Self], out: &mut Vec<u8>);
}

macro_rules! le {
    ($($t:ty),*) => {$(
        impl Le for $t {
            fn put(v: &[$t], out: &mut Vec<u8>) {
                out.reserve(v.len() * std::mem::size_of::<$t>());
                for x in v {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
    )*};
}
le!(u16, i64, i8);

/// `CHUNK` elements of a column, filtered (shuffle + deflate) exactly as the writer filters them.
fn filtered_chunk<T: Le>(chunk: &[T]) -> rust_hdf5::Result<Vec<u8>> {
    let mut raw = Vec::new();
    T::put(chunk, &mut raw);
    let pipeline = rust_hdf5::FilterPipeline::shuffle_deflate(std::mem::size_of::<T>() as u32, DEFLATE);
    Ok(rust_hdf5::format::messages::filter::apply_filters(&pipeline, &raw)?)
}

/// Writes the Ev-DeblurNeRF layout (root `x`, `y`, `t` ns, `p` +1/-1).
///
/// Full chunks are compressed on all cores (rayon) and stored with direct chunk writes, in the
/// order `append` would store them (per batch, column by column), and the last, partial chunks
/// (zero-filled) as the close would store them. The file has the bytes of one written by appending each batch.
pub struct NerfH5Sink {
    // Field order is drop order: datasets, then the file, then the temporary-file guard.
    sets: Option<[H5Dataset; 4]>,
    file: Option<H5File>,
    /// Events pushed and not yet in a written chunk (from element `chunks * CHUNK`).
    cols: Columns<i64, i8>,
    /// Full chunks written per column.
    chunks: usize,
    /// For each batch since the last flush that completed chunks: how many.
    groups: Vec<usize>,
    n: u64,
    target: AtomicTarget,
}

impl NerfH5Sink {
    /// Start writing `path` (through a temporary sibling).
    pub fn create(path: &Path) -> io::Result<NerfH5Sink> {
        let target = AtomicTarget::new(path)?;
        let h5 = |e| io_err(&target.tmp, "cannot create the HDF5 file", e);
        let file = H5File::create(&target.tmp).map_err(h5)?;
        let sets = [
            growable::<u16>(&file, None, "x").map_err(h5)?,
            growable::<u16>(&file, None, "y").map_err(h5)?,
            growable::<i64>(&file, None, "t").map_err(h5)?,
            growable::<i8>(&file, None, "p").map_err(h5)?,
        ];
        Ok(NerfH5Sink {
            sets: Some(sets),
            file: Some(file),
            cols: Columns::default(),
            chunks: 0,
            groups: Vec::new(),
            n: 0,
            target,
        })
    }

    /// Compress the full chunks gathered (in parallel) and store them in `append`'s order; with
    /// `tail`, also the last, partial chunk of each column, zero-filled as the close would
    /// fill it, after them (where the close would store it).
    fn flush_chunks(&mut self, tail: bool) -> rust_hdf5::Result<()> {
        let full: usize = self.groups.iter().sum();
        let c = &self.cols;
        let rest = c.x.len() - full * CHUNK;
        let last = usize::from(tail && rest > 0);
        if full + last == 0 {
            return Ok(());
        }
        // chunk j of column col: elements j * CHUNK.. of the pending columns, the tail padded
        let chunk_of = |col: usize, j: usize| -> rust_hdf5::Result<Vec<u8>> {
            let r = j * CHUNK..((j + 1) * CHUNK).min(c.x.len());
            fn padded<T: Le + Default>(v: &[T]) -> rust_hdf5::Result<Vec<u8>> {
                if v.len() == CHUNK {
                    return filtered_chunk(v);
                }
                let mut whole = v.to_vec();
                whole.resize(CHUNK, T::default());
                filtered_chunk(&whole)
            }
            match col {
                0 => padded(&c.x[r]),
                1 => padded(&c.y[r]),
                2 => padded(&c.t[r]),
                _ => padded(&c.p[r]),
            }
        };
        let per_col = full + last;
        let jobs: Vec<(usize, usize)> = (0..4).flat_map(|col| (0..per_col).map(move |j| (col, j))).collect();
        let filtered: Vec<Vec<u8>> =
            jobs.par_iter().map(|&(col, j)| chunk_of(col, j)).collect::<rust_hdf5::Result<_>>()?;
        let sets = self.sets.as_ref().expect("open until finish");
        let mut first = 0;
        for &m in self.groups.iter().chain(std::iter::repeat_n(&1, last)) {
            for (col, set) in sets.iter().enumerate() {
                for j in first..first + m {
                    set.write_chunk_raw(self.chunks + j, &filtered[col * per_col + j], 0)?;
                }
            }
            first += m;
        }
        self.chunks += full;
        self.groups.clear();
        let done = (full * CHUNK + last * rest).min(c.x.len());
        let c = &mut self.cols;
        c.x.drain(..done);
        c.y.drain(..done);
        c.t.drain(..done);
        c.p.drain(..done);
        for set in sets {
            set.extend(&[self.n as usize - c.x.len()])?;
        }
        Ok(())
    }

    /// Close the file and move it into place; returns the number of events written.
    pub fn finish(mut self) -> io::Result<u64> {
        let tmp = self.target.tmp.clone();
        let h5 = |e| io_err(&tmp, "cannot complete the HDF5 file", e);
        self.flush_chunks(true).map_err(h5)?;
        self.sets = None;
        let file = self.file.take().expect("open until finish");
        file.close().map_err(h5)?;
        let n = self.n;
        self.target.commit_ref()?;
        Ok(n)
    }
}

impl EventSink for NerfH5Sink {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        if events.is_empty() {
            return Ok(());
        }
        let before = self.n as usize;
        let c = &mut self.cols;
        for e in events {
            c.x.push(e.x);
            c.y.push(e.y);
            c.t.push(e.t_ns);
            c.p.push(if e.p > 0 { 1 } else { -1 });
        }
        self.n += events.len() as u64;
        let completed = self.n as usize / CHUNK - before / CHUNK;
        if completed > 0 {
            self.groups.push(completed);
        }
        if self.groups.iter().sum::<usize>() >= FLUSH_CHUNKS {
            self.flush_chunks(false).map_err(|e| io_err(&self.target.tmp, "cannot append events", e))?;
        }
        Ok(())
    }
}

/// Writes the DSEC layout (`/events/{x, y, t us, p 0/1}`, `/t_offset`, `/ms_to_idx`).
pub struct DsecH5Sink {
    // Field order is drop order: datasets, then the file, then the temporary-file guard.
    sets: Option<([H5Dataset; 4], H5Dataset)>,
    file: Option<H5File>,
    cols: Columns<u32, u8>,
    ms_to_idx: Vec<u64>,
    /// `t_offset` in us, fixed by the first event.
    t_offset_us: Option<i64>,
    /// Entries of `ms_to_idx` written so far (= the next millisecond boundary to place).
    next_ms: u64,
    n: u64,
    target: AtomicTarget,
}

impl DsecH5Sink {
    /// Start writing `path` (through a temporary sibling).
    pub fn create(path: &Path) -> io::Result<DsecH5Sink> {
        let target = AtomicTarget::new(path)?;
        let h5 = |e| io_err(&target.tmp, "cannot create the HDF5 file", e);
        let file = H5File::create(&target.tmp).map_err(h5)?;
        let g = file.create_group("events").map_err(h5)?;
        let sets = [
            growable::<u16>(&file, Some(&g), "x").map_err(h5)?,
            growable::<u16>(&file, Some(&g), "y").map_err(h5)?,
            growable::<u32>(&file, Some(&g), "t").map_err(h5)?,
            growable::<u8>(&file, Some(&g), "p").map_err(h5)?,
        ];
        let ms = growable::<u64>(&file, None, "ms_to_idx").map_err(h5)?;
        Ok(DsecH5Sink {
            sets: Some((sets, ms)),
            file: Some(file),
            cols: Columns::default(),
            ms_to_idx: Vec::new(),
            t_offset_us: None,
            next_ms: 0,
            n: 0,
            target,
        })
    }

    /// Write `/t_offset`, close the file and move it into place; returns the number of events.
    pub fn finish(mut self) -> io::Result<u64> {
        self.sets = None;
        let file = self.file.take().expect("open until finish");
        let h5 = |e| io_err(&self.target.tmp, "cannot complete the HDF5 file", e);
        let t_offset = self.t_offset_us.unwrap_or(0);
        file.new_dataset::<i64>().scalar().create("t_offset").map_err(h5)?.write_raw(&[t_offset]).map_err(h5)?;
        file.close().map_err(h5)?;
        let n = self.n;
        self.target.commit_ref()?;
        Ok(n)
    }
}

impl EventSink for DsecH5Sink {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        let Some(first) = events.first() else { return Ok(()) };
        let t_offset = *self.t_offset_us.get_or_insert(first.t_ns.div_euclid(1000));
        let c = &mut self.cols;
        c.clear();
        self.ms_to_idx.clear();
        for (i, e) in events.iter().enumerate() {
            // Microseconds since t_offset (floored: ties and order are kept).
            let t_us = e.t_ns.div_euclid(1000) - t_offset;
            let Ok(t) = u32::try_from(t_us) else {
                return Err(io_err(
                    &self.target.path,
                    "DSEC time overflow",
                    format!("an event {t_us} us after t_offset does not fit u32 (71.6 min); split the sequence or use the nerf layout"),
                ));
            };
            // ms_to_idx[m] = index of the first event with t >= 1000 m: every boundary up to
            // this event's time that is not yet placed starts at this event.
            while self.next_ms * 1000 <= t as u64 {
                self.ms_to_idx.push(self.n + i as u64);
                self.next_ms += 1;
            }
            c.x.push(e.x);
            c.y.push(e.y);
            c.t.push(t);
            c.p.push(u8::from(e.p > 0));
        }
        let ([x, y, t, p], ms) = self.sets.as_ref().expect("open until finish");
        let h5 = |e| io_err(&self.target.tmp, "cannot append events", e);
        x.append(&c.x).map_err(h5)?;
        y.append(&c.y).map_err(h5)?;
        t.append(&c.t).map_err(h5)?;
        p.append(&c.p).map_err(h5)?;
        if !self.ms_to_idx.is_empty() {
            ms.append(&self.ms_to_idx).map_err(h5)?;
        }
        self.n += events.len() as u64;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{files, known_events, temp_dir};
    use super::*;

    fn write_in_batches(sink: &mut dyn EventSink, events: &[Event]) {
        for batch in events.chunks(977) {
            sink.push(batch).unwrap();
            sink.push(&[]).unwrap();
        }
    }

    #[test]
    fn nerf_h5_is_written_atomically() {
        let dir = temp_dir("nerf-h5");
        let events = known_events(5000, 1_000_000);
        let path = dir.join("events.h5");
        let mut sink = NerfH5Sink::create(&path).unwrap();
        write_in_batches(&mut sink, &events);
        assert!(!path.exists(), "the target appears only at finish");
        assert_eq!(sink.finish().unwrap(), 5000);
        assert!(std::fs::metadata(&path).unwrap().len() > 0);
        assert_eq!(files(&dir), ["events.h5"], "no temporary file remains");
    }

    /// The plain writer the chunked one must equal: `append` per batch.
    fn appended(path: &Path, batches: &[&[Event]]) {
        let file = H5File::create(path).unwrap();
        let sets = [
            growable::<u16>(&file, None, "x").unwrap(),
            growable::<u16>(&file, None, "y").unwrap(),
            growable::<i64>(&file, None, "t").unwrap(),
            growable::<i8>(&file, None, "p").unwrap(),
        ];
        for b in batches.iter().filter(|b| !b.is_empty()) {
            sets[0].append(&b.iter().map(|e| e.x).collect::<Vec<_>>()).unwrap();
            sets[1].append(&b.iter().map(|e| e.y).collect::<Vec<_>>()).unwrap();
            sets[2].append(&b.iter().map(|e| e.t_ns).collect::<Vec<_>>()).unwrap();
            sets[3].append(&b.iter().map(|e| if e.p > 0 { 1i8 } else { -1 }).collect::<Vec<_>>()).unwrap();
        }
        drop(sets);
        file.close().unwrap();
    }

    #[test]
    fn nerf_h5_has_the_bytes_of_appending_every_batch() {
        let dir = temp_dir("nerf-h5-bytes");
        // sizes around chunk boundaries, batches smaller and larger than a chunk
        for (n, batch) in [
            (0, 977),
            (1, 977),
            (CHUNK - 1, 977),
            (CHUNK, 977),
            (CHUNK + 1, 5000),
            (5 * CHUNK + 17, 977),
            (5 * CHUNK + 17, 3 * CHUNK / 2),
            (9 * CHUNK, CHUNK),
        ] {
            let events = known_events(n, 1_000_000);
            let batches: Vec<&[Event]> = events.chunks(batch).collect();
            let (a, b) = (dir.join("appended.h5"), dir.join("chunked.h5"));
            appended(&a, &batches);
            let mut sink = NerfH5Sink::create(&b).unwrap();
            for batch in &batches {
                sink.push(batch).unwrap();
            }
            assert_eq!(sink.finish().unwrap(), n as u64);
            assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(), "{n} events in batches of {batch}");
        }
    }

    #[test]
    fn dsec_h5_is_written_atomically() {
        let dir = temp_dir("dsec-h5");
        let events = known_events(5000, 1_000_000);
        let path = dir.join("events.h5");
        let mut sink = DsecH5Sink::create(&path).unwrap();
        write_in_batches(&mut sink, &events);
        assert_eq!(sink.finish().unwrap(), 5000);
        assert!(std::fs::metadata(&path).unwrap().len() > 0);
        assert_eq!(files(&dir), ["events.h5"], "no temporary file remains");
    }

    #[test]
    fn dsec_ms_to_idx_is_searchsorted_of_the_ms_boundaries() {
        let dir = temp_dir("dsec-ms");
        let events = known_events(4000, 123_456_789);
        let mut sink = DsecH5Sink::create(&dir.join("e.h5")).unwrap();
        let mut ms = Vec::new();
        for batch in events.chunks(333) {
            sink.push(batch).unwrap();
            ms.extend_from_slice(&sink.ms_to_idx);
        }
        let t_offset = sink.t_offset_us.unwrap();
        assert_eq!(t_offset, 123_456);
        let t: Vec<i64> = events.iter().map(|e| e.t_ns.div_euclid(1000) - t_offset).collect();
        let last_ms = (*t.last().unwrap() / 1000) as usize;
        assert_eq!(ms.len(), last_ms + 1);
        for (m, &idx) in ms.iter().enumerate() {
            assert_eq!(idx as usize, t.partition_point(|&t| t < 1000 * m as i64), "ms {m}");
        }
        sink.finish().unwrap();
    }

    #[test]
    fn unfinished_h5_sinks_leave_no_file() {
        let dir = temp_dir("h5-drop");
        let events = known_events(3000, 0);
        let mut a = NerfH5Sink::create(&dir.join("a.h5")).unwrap();
        let mut b = DsecH5Sink::create(&dir.join("b.h5")).unwrap();
        write_in_batches(&mut a, &events);
        write_in_batches(&mut b, &events);
        drop((a, b));
        assert!(files(&dir).is_empty(), "{:?}", files(&dir));
    }
}
