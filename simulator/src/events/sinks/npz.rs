//! NumPy `.npz`: a zip archive of `x.npy` (u16), `y.npy` (u16), `t.npy` (i64, ns) and `p.npy`
//! (i8, +1 ON / -1 OFF), laid out as `numpy.savez` writes it (entries stored, not compressed).
//!
//! The `.npy` header, zip entries and CRC-32 come from [`crate::npy`]. A `.npy` header holds
//! the array length, so each column streams to its own scratch file beside the target
//! (`.name.x.tmp<pid>`, ...) and [`NpzSink::finish`] assembles the archive: for each entry a
//! local header (CRC-32 patched in after the data), the `.npy` header (format 1.0, padded to 64
//! bytes) and the data; then the central directory. No ZIP64: an archive over 4 GiB
//! (about 330 M events) is refused while streaming, with the fix (write `.h5`).

use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use super::{io_err, AtomicTarget, ScratchFile};
use crate::events::{Event, EventSink};
use crate::npy::npy_header;
use crate::npy::zip::{end_record, Crc32, ZipEntry, MAX_ZIP};

/// The columns: zip entry name, numpy dtype, bytes per element.
const COLUMNS: [(&str, &str, u64); 4] =
    [("x.npy", "<u2", 2), ("y.npy", "<u2", 2), ("t.npy", "<i8", 8), ("p.npy", "|i1", 1)];
/// Bytes per event over all columns.
const EVENT_BYTES: u64 = 2 + 2 + 8 + 1;
/// Generous bound on everything but the data: 4 x (local header + name + npy header + central
/// header + name) + end record.
const OVERHEAD: u64 = 4 * (30 + 5 + 128 + 46 + 5) + 22;

/// Streams events into four scratch columns and assembles the `.npz` at finish.
pub struct NpzSink {
    // Field order is drop order: the column writers, their scratch files, the target guard.
    parts: Vec<BufWriter<File>>,
    scratch: Vec<ScratchFile>,
    n: u64,
    target: AtomicTarget,
}

impl NpzSink {
    /// Start writing `path` (scratch columns beside it until [`finish`](Self::finish)).
    pub fn create(path: &Path) -> io::Result<NpzSink> {
        let target = AtomicTarget::new(path)?;
        let mut parts = Vec::new();
        let mut scratch = Vec::new();
        for (name, _, _) in COLUMNS {
            let s = ScratchFile::beside(path, &format!(".{}", &name[..1]));
            let f = File::create(&s.path).map_err(|e| io_err(&s.path, "cannot create a scratch file", e))?;
            scratch.push(s);
            parts.push(BufWriter::with_capacity(1 << 18, f));
        }
        Ok(NpzSink { parts, scratch, n: 0, target })
    }

    /// Assemble the archive and move it into place; returns the number of events written.
    pub fn finish(mut self) -> io::Result<u64> {
        for (w, s) in self.parts.iter_mut().zip(&self.scratch) {
            w.flush().map_err(|e| io_err(&s.path, "cannot write", e))?;
        }
        let tmp = self.target.tmp.clone();
        let err = |e| io_err(&tmp, "cannot write", e);
        let mut out = BufWriter::with_capacity(1 << 20, File::create(&tmp).map_err(err)?);
        let mut central = Vec::new();
        let mut offset = 0u64;
        for ((name, descr, item), s) in COLUMNS.into_iter().zip(&self.scratch) {
            let header = npy_header(descr, &[self.n]);
            let size = header.len() as u64 + self.n * item;
            let entry = ZipEntry { name, size, crc: 0, offset };
            out.write_all(&entry.local_header()).map_err(err)?;
            // Stream the .npy header and the column, taking the CRC-32 on the way.
            let mut crc = Crc32::new();
            crc.update(&header);
            out.write_all(&header).map_err(err)?;
            let mut column = File::open(&s.path).map_err(|e| io_err(&s.path, "cannot read back", e))?;
            let mut buf = vec![0u8; 1 << 20];
            let mut copied = 0u64;
            loop {
                let k = column.read(&mut buf).map_err(|e| io_err(&s.path, "cannot read back", e))?;
                if k == 0 {
                    break;
                }
                crc.update(&buf[..k]);
                out.write_all(&buf[..k]).map_err(err)?;
                copied += k as u64;
            }
            if copied != self.n * item {
                return Err(io_err(
                    &s.path,
                    "scratch column has the wrong length",
                    format!("{copied} bytes, expected {}", self.n * item),
                ));
            }
            // Patch the CRC into the local header (offset 14), then carry on at the end.
            let entry = ZipEntry { crc: crc.finish(), ..entry };
            out.seek(SeekFrom::Start(offset + 14)).map_err(err)?;
            out.write_all(&entry.crc.to_le_bytes()).map_err(err)?;
            out.seek(SeekFrom::End(0)).map_err(err)?;
            central.extend_from_slice(&entry.central_header());
            offset += entry.stored_len();
        }
        let end = end_record(COLUMNS.len(), central.len(), offset);
        out.write_all(&central).map_err(err)?;
        out.write_all(&end).map_err(err)?;
        let file = out.into_inner().map_err(|e| io_err(&tmp, "cannot write", e.error()))?;
        file.sync_all().map_err(err)?;
        drop(file);
        self.target.commit_ref()?;
        Ok(self.n)
    }
}

impl EventSink for NpzSink {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        let n = self.n + events.len() as u64;
        if n * EVENT_BYTES + OVERHEAD > MAX_ZIP {
            return Err(io_err(
                &self.target.path,
                "too many events for .npz",
                format!("{n} events exceed the 4 GiB zip limit (no ZIP64); write .h5 instead"),
            ));
        }
        let [x, y, t, p] = &mut self.parts[..] else { unreachable!("four columns") };
        let err = |e| io_err(&self.target.path, "cannot write a scratch column", e);
        for e in events {
            x.write_all(&e.x.to_le_bytes()).map_err(err)?;
            y.write_all(&e.y.to_le_bytes()).map_err(err)?;
            t.write_all(&e.t_ns.to_le_bytes()).map_err(err)?;
            p.write_all(&[if e.p > 0 { 1u8 } else { (-1i8) as u8 }]).map_err(err)?;
        }
        self.n = n;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{files, known_events, temp_dir};
    use super::*;

    /// The stored entries of a zip archive, read through its central directory (only what this
    /// writer produces: stored, no ZIP64), checking each CRC and the local headers.
    fn unzip(bytes: &[u8]) -> Vec<(String, Vec<u8>)> {
        let u16_at = |o: usize| u16::from_le_bytes([bytes[o], bytes[o + 1]]) as usize;
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
        let end = bytes.len() - 22;
        assert_eq!(u32_at(end), 0x0605_4b50);
        let (count, mut c) = (u16_at(end + 10), u32_at(end + 16));
        let mut out = Vec::new();
        for _ in 0..count {
            assert_eq!(u32_at(c), 0x0201_4b50);
            let (crc, size, name_len, local) = (u32_at(c + 16), u32_at(c + 20), u16_at(c + 28), u32_at(c + 42));
            let name = String::from_utf8(bytes[c + 46..c + 46 + name_len].to_vec()).unwrap();
            assert_eq!(u32_at(local), 0x0403_4b50);
            assert_eq!(u32_at(local + 14), crc, "local CRC of {name}");
            assert_eq!(u32_at(local + 18), size);
            let data = bytes[local + 30 + name_len..local + 30 + name_len + size].to_vec();
            let mut k = Crc32::new();
            k.update(&data);
            assert_eq!(k.finish() as usize, crc, "CRC of {name}");
            out.push((name, data));
            c += 46 + name_len;
        }
        out
    }

    /// Parse a 1-D `.npy`: its descr, shape and data bytes.
    fn parse_npy(npy: &[u8]) -> (String, usize, &[u8]) {
        assert_eq!(&npy[..8], b"\x93NUMPY\x01\x00");
        let len = u16::from_le_bytes([npy[8], npy[9]]) as usize;
        assert_eq!((10 + len) % 64, 0, "header padded to 64");
        let dict = std::str::from_utf8(&npy[10..10 + len]).unwrap();
        assert!(dict.ends_with('\n') && dict.contains("'fortran_order': False"), "{dict}");
        let descr = dict.split("'descr': '").nth(1).unwrap().split('\'').next().unwrap().to_string();
        let shape = dict.split("'shape': (").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
        (descr, shape, &npy[10 + len..])
    }

    #[test]
    fn crc32_matches_the_check_value() {
        let mut c = Crc32::new();
        c.update(b"123456789");
        assert_eq!(c.finish(), 0xCBF4_3926);
    }

    #[test]
    fn npz_round_trips() {
        let dir = temp_dir("npz");
        let events = known_events(4321, -5_000);
        let path = dir.join("events.npz");
        let mut sink = NpzSink::create(&path).unwrap();
        for batch in events.chunks(1000) {
            sink.push(batch).unwrap();
        }
        assert!(!path.exists());
        assert_eq!(sink.finish().unwrap(), 4321);
        assert_eq!(files(&dir), ["events.npz"], "scratch and temporary files are gone");
        let entries = unzip(&std::fs::read(&path).unwrap());
        let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["x.npy", "y.npy", "t.npy", "p.npy"]);
        let cols: Vec<(String, usize, &[u8])> = entries.iter().map(|(_, d)| parse_npy(d)).collect();
        let descrs: Vec<&str> = cols.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(descrs, ["<u2", "<u2", "<i8", "|i1"]);
        assert!(cols.iter().all(|c| c.1 == events.len()));
        for (i, e) in events.iter().enumerate() {
            assert_eq!(u16::from_le_bytes(cols[0].2[2 * i..2 * i + 2].try_into().unwrap()), e.x);
            assert_eq!(u16::from_le_bytes(cols[1].2[2 * i..2 * i + 2].try_into().unwrap()), e.y);
            assert_eq!(i64::from_le_bytes(cols[2].2[8 * i..8 * i + 8].try_into().unwrap()), e.t_ns);
            assert_eq!(cols[3].2[i] as i8, e.p);
        }
    }

    #[test]
    fn empty_npz_is_valid() {
        let dir = temp_dir("npz-empty");
        let path = dir.join("e.npz");
        assert_eq!(NpzSink::create(&path).unwrap().finish().unwrap(), 0);
        let entries = unzip(&std::fs::read(&path).unwrap());
        assert!(entries.iter().all(|(_, d)| parse_npy(d).1 == 0));
    }

    #[test]
    fn unfinished_npz_leaves_no_file() {
        let dir = temp_dir("npz-drop");
        let mut sink = NpzSink::create(&dir.join("e.npz")).unwrap();
        sink.push(&known_events(100, 0)).unwrap();
        drop(sink);
        assert!(files(&dir).is_empty(), "{:?}", files(&dir));
    }

    #[test]
    fn oversized_npz_is_refused_with_the_fix() {
        let dir = temp_dir("npz-big");
        let mut sink = NpzSink::create(&dir.join("e.npz")).unwrap();
        sink.n = MAX_ZIP / EVENT_BYTES - 10;
        let err = sink.push(&known_events(1000, 0)).unwrap_err();
        assert!(err.to_string().contains(".h5"), "{err}");
    }
}
