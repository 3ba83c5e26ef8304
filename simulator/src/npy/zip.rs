//! The zip container of `.npz`: a stored (uncompressed) writer's headers and CRC-32, and a reader
//! of stored and deflated entries through the central directory.
//!
//! Writer: each entry is a local header (30 bytes + name), the data, and later a central header
//! (46 bytes + name); the end-of-central-directory record (22 bytes) closes the archive. No
//! ZIP64, so an archive is at most [`MAX_ZIP`] bytes. Reader: sizes, CRC and offset come from the
//! central directory (numpy's `savez` writes a ZIP64 extra field with placeholder sizes into the
//! local headers, `force_zip64=True`), the local header only locates the data; ZIP64 extra fields
//! in the central directory are honoured, a ZIP64 end record (archives over 4 GiB) is refused.

use std::io::Read;

/// The largest archive without ZIP64.
pub(crate) const MAX_ZIP: u64 = u32::MAX as u64;

/// Signatures of the zip records.
const LOCAL_SIG: u32 = 0x0403_4b50;
const CENTRAL_SIG: u32 = 0x0201_4b50;
const END_SIG: u32 = 0x0605_4b50;

/// One stored (uncompressed) zip entry.
#[derive(Clone, Copy)]
pub(crate) struct ZipEntry<'a> {
    /// Its name in the archive.
    pub name: &'a str,
    /// Size of the entry's data (stored: compressed = uncompressed).
    pub size: u64,
    /// CRC-32 of the data.
    pub crc: u32,
    /// Offset of its local header in the archive.
    pub offset: u64,
}

impl ZipEntry<'_> {
    /// The fields shared by the local and central headers, from "version needed" to the name
    /// length: version 2.0, no flags, stored, DOS time 00:00 of 1980-01-01.
    fn common(&self) -> Vec<u8> {
        let mut v = Vec::with_capacity(26);
        v.extend_from_slice(&20u16.to_le_bytes()); // version needed
        v.extend_from_slice(&0u16.to_le_bytes()); // flags
        v.extend_from_slice(&0u16.to_le_bytes()); // method: stored
        v.extend_from_slice(&0u16.to_le_bytes()); // time
        v.extend_from_slice(&0x0021u16.to_le_bytes()); // date 1980-01-01
        v.extend_from_slice(&self.crc.to_le_bytes());
        v.extend_from_slice(&(self.size as u32).to_le_bytes()); // compressed
        v.extend_from_slice(&(self.size as u32).to_le_bytes()); // uncompressed
        v.extend_from_slice(&(self.name.len() as u16).to_le_bytes());
        v.extend_from_slice(&0u16.to_le_bytes()); // extra length
        v
    }

    /// The local header (its CRC sits at offset 14).
    pub fn local_header(&self) -> Vec<u8> {
        let mut v = LOCAL_SIG.to_le_bytes().to_vec();
        v.extend_from_slice(&self.common());
        v.extend_from_slice(self.name.as_bytes());
        v
    }

    /// The central directory header.
    pub fn central_header(&self) -> Vec<u8> {
        let mut v = CENTRAL_SIG.to_le_bytes().to_vec();
        v.extend_from_slice(&20u16.to_le_bytes()); // version made by
        v.extend_from_slice(&self.common());
        v.extend_from_slice(&[0; 6]); // comment length, disk start, internal attributes
        v.extend_from_slice(&[0; 4]); // external attributes
        v.extend_from_slice(&(self.offset as u32).to_le_bytes());
        v.extend_from_slice(self.name.as_bytes());
        v
    }

    /// Bytes the entry takes before the central directory: local header + data.
    pub fn stored_len(&self) -> u64 {
        30 + self.name.len() as u64 + self.size
    }
}

/// The end-of-central-directory record for `count` entries whose central directory is
/// `central_len` bytes at `central_offset`.
pub(crate) fn end_record(count: usize, central_len: usize, central_offset: u64) -> Vec<u8> {
    let mut end = Vec::with_capacity(22);
    end.extend_from_slice(&END_SIG.to_le_bytes());
    end.extend_from_slice(&[0; 4]); // this disk, disk of the central directory
    end.extend_from_slice(&(count as u16).to_le_bytes());
    end.extend_from_slice(&(count as u16).to_le_bytes());
    end.extend_from_slice(&(central_len as u32).to_le_bytes());
    end.extend_from_slice(&(central_offset as u32).to_le_bytes());
    end.extend_from_slice(&[0; 2]); // comment length
    end
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), as zip uses it.
pub(crate) struct Crc32(u32);

/// The byte-wise lookup table of [`Crc32`].
const CRC_TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

impl Crc32 {
    /// A fresh checksum.
    pub fn new() -> Crc32 {
        Crc32(!0)
    }
    /// Feed `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = CRC_TABLE[((self.0 ^ b as u32) & 0xff) as usize] ^ (self.0 >> 8);
        }
    }
    /// The checksum of everything fed so far.
    pub fn finish(&self) -> u32 {
        !self.0
    }
}

/// The CRC-32 of `bytes`.
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

/// Every entry of a zip archive in central-directory order, decompressed (stored or deflate)
/// and CRC-checked; `Err` is a sentence saying what is wrong.
pub(crate) fn unzip(bytes: &[u8]) -> Result<Vec<(String, Vec<u8>)>, String> {
    let u16_at = |o: usize| -> Result<u64, String> {
        bytes
            .get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]) as u64)
            .ok_or_else(|| format!("truncated zip (a record at byte {o} runs past the end)"))
    };
    let u32_at = |o: usize| -> Result<u64, String> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64)
            .ok_or_else(|| format!("truncated zip (a record at byte {o} runs past the end)"))
    };
    let u64_at = |o: usize| -> Result<u64, String> {
        bytes
            .get(o..o + 8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
            .ok_or_else(|| format!("truncated zip (a record at byte {o} runs past the end)"))
    };
    // The end record: the last END_SIG at least 22 bytes before the end (a comment may follow).
    let end = (0..=bytes.len().saturating_sub(22))
        .rev()
        .take(22 + 65_535 + 1)
        .find(|&o| bytes.len() >= 22 && u32_at(o) == Ok(END_SIG as u64))
        .ok_or("not a zip archive (no end-of-central-directory record; truncated?)")?;
    let (count, central_offset) = (u16_at(end + 10)?, u32_at(end + 16)?);
    if count == 0xFFFF || central_offset == 0xFFFF_FFFF {
        return Err("ZIP64 archive (over 4 GiB or 65535 entries) is not supported".into());
    }
    let mut c = central_offset as usize;
    let mut out = Vec::with_capacity(count as usize);
    for i in 0..count {
        if u32_at(c)? != CENTRAL_SIG as u64 {
            return Err(format!(
                "central directory entry {i} at byte {c} has a bad signature (corrupt or truncated zip)"
            ));
        }
        let (flags, method, crc) = (u16_at(c + 8)?, u16_at(c + 10)?, u32_at(c + 16)?);
        let (mut csize, mut usize_, name_len, extra_len, comment_len) = (
            u32_at(c + 20)?,
            u32_at(c + 24)?,
            u16_at(c + 28)? as usize,
            u16_at(c + 30)? as usize,
            u16_at(c + 32)? as usize,
        );
        let mut local = u32_at(c + 42)?;
        let name_bytes = bytes.get(c + 46..c + 46 + name_len).ok_or("truncated zip (central directory)")?;
        let name = String::from_utf8_lossy(name_bytes).into_owned();
        // ZIP64 extra field (id 1): the 64-bit values of the fields set to 0xFFFFFFFF, in order.
        let mut e = c + 46 + name_len;
        let extra_end = e + extra_len;
        while e + 4 <= extra_end {
            let (id, len) = (u16_at(e)?, u16_at(e + 2)? as usize);
            if id == 1 {
                let mut f = e + 4;
                for field in [&mut usize_, &mut csize, &mut local] {
                    if *field == 0xFFFF_FFFF {
                        *field = u64_at(f)?;
                        f += 8;
                    }
                }
            }
            e += 4 + len;
        }
        if flags & 1 != 0 {
            return Err(format!("entry {name} is encrypted"));
        }
        let local = local as usize;
        if u32_at(local)? != LOCAL_SIG as u64 {
            return Err(format!("entry {name}: bad local header at byte {local} (corrupt zip)"));
        }
        let start = local + 30 + u16_at(local + 26)? as usize + u16_at(local + 28)? as usize;
        let raw = bytes.get(start..start.saturating_add(csize as usize)).ok_or_else(|| {
            format!("entry {name} is truncated ({csize} bytes expected at byte {start}, the file has {})", bytes.len())
        })?;
        let data = match method {
            0 => raw.to_vec(),
            8 => {
                // Deflate expands at most ~1032x: do not trust a huge declared size up front.
                let mut d = Vec::with_capacity((usize_ as usize).min(raw.len().saturating_mul(1032)));
                flate2::read::DeflateDecoder::new(raw)
                    .read_to_end(&mut d)
                    .map_err(|e| format!("entry {name}: bad deflate stream: {e}"))?;
                d
            }
            m => {
                return Err(format!(
                    "entry {name} uses zip compression method {m}; only stored (0) and deflate (8) are supported"
                ))
            }
        };
        if data.len() as u64 != usize_ {
            return Err(format!("entry {name} has {} bytes, its header says {usize_}", data.len()));
        }
        if crc32(&data) as u64 != crc {
            return Err(format!("entry {name} fails its CRC-32 check (corrupt file)"));
        }
        out.push((name, data));
        c += 46 + name_len + extra_len + comment_len;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn stored_archive_round_trips() {
        let files: [(&str, &[u8]); 2] = [("a.npy", b"hello"), ("bb.npy", b"")];
        let (mut out, mut central, mut offset) = (Vec::new(), Vec::new(), 0u64);
        for (name, data) in files {
            let e = ZipEntry { name, size: data.len() as u64, crc: crc32(data), offset };
            out.extend_from_slice(&e.local_header());
            out.extend_from_slice(data);
            central.extend_from_slice(&e.central_header());
            offset += e.stored_len();
        }
        out.extend_from_slice(&central);
        out.extend_from_slice(&end_record(2, central.len(), offset));
        let back = unzip(&out).unwrap();
        assert_eq!(back, vec![("a.npy".to_string(), b"hello".to_vec()), ("bb.npy".to_string(), vec![])]);
        // A flipped data byte fails the CRC; a cut archive is reported, not a panic.
        let mut bad = out.clone();
        bad[30 + 5] ^= 1;
        assert!(unzip(&bad).unwrap_err().contains("CRC"));
        assert!(unzip(&out[..out.len() - 30]).is_err());
        assert!(unzip(b"").is_err());
    }
}
