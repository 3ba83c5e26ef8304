//! The `.npy` header: magic `\x93NUMPY`, version, header length, then a Python dict literal
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (3, 17), }` padded with spaces and a
//! newline so that the data starts at a multiple of 64 bytes. Version 1.0 has a u16 length,
//! 2.0 (and 3.0, UTF-8 dict) a u32 length for headers over 65535 bytes.

/// The magic string every `.npy` starts with.
const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// A `.npy` header for an array of `shape` (C order) of numpy dtype `descr`, padded with spaces
/// and a newline to a multiple of 64 bytes, as numpy writes it: version 1.0, or 2.0 if the dict
/// does not fit a u16 length.
pub(crate) fn npy_header(descr: &str, shape: &[u64]) -> Vec<u8> {
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {dims}, }}");
    let (version, preamble) = if 10 + dict.len() + 1 + 63 <= 0xFFFF { (1u8, 10) } else { (2u8, 12) };
    let pad = (64 - (preamble + dict.len() + 1) % 64) % 64;
    let len = dict.len() + pad + 1;
    let mut h = MAGIC.to_vec();
    h.extend_from_slice(&[version, 0]);
    if version == 1 {
        h.extend_from_slice(&(len as u16).to_le_bytes());
    } else {
        h.extend_from_slice(&(len as u32).to_le_bytes());
    }
    h.extend_from_slice(dict.as_bytes());
    h.resize(h.len() + pad, b' ');
    h.push(b'\n');
    h
}

/// What a parsed header says.
#[derive(Debug, PartialEq)]
pub(crate) struct Header {
    /// The dtype string, e.g. `<f8`.
    pub descr: String,
    /// True for Fortran (column-major) order.
    pub fortran_order: bool,
    /// The dimensions.
    pub shape: Vec<usize>,
    /// Where the data starts.
    pub data_offset: usize,
}

/// Parse the header at the start of `bytes`; `Err` is a sentence saying what is wrong.
pub(crate) fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(if bytes.len() < 10 && MAGIC.starts_with(&bytes[..bytes.len().min(6)]) {
            format!("truncated: {} bytes, shorter than the .npy preamble", bytes.len())
        } else {
            "not a .npy file (no \\x93NUMPY magic)".into()
        });
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, 12),
        2 | 3 => return Err("truncated: shorter than the .npy 2.0 preamble".into()),
        v => return Err(format!(".npy format version {v}.{} is not supported (1.0, 2.0, 3.0 are)", bytes[7])),
    };
    let dict = bytes
        .get(start..start + len)
        .ok_or_else(|| format!("truncated: the header says {len} bytes, the file has {}", bytes.len() - start))?;
    let dict = std::str::from_utf8(dict).map_err(|_| "the header is not text".to_string())?;
    let mut p = DictParser { s: dict.trim_end().as_bytes(), i: 0 };
    let (mut descr, mut fortran_order, mut shape) = (None, None, None);
    p.expect(b'{')?;
    loop {
        p.skip_ws();
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.expect(b':')?;
        match key.as_str() {
            "descr" => {
                descr = Some(p.string().map_err(|_| {
                    "'descr' is not a plain dtype string (structured dtypes are not supported)".to_string()
                })?)
            }
            "fortran_order" => fortran_order = Some(p.boolean()?),
            "shape" => shape = Some(p.tuple()?),
            k => return Err(format!("unknown header key '{k}'")),
        }
        p.skip_ws();
        if !p.eat(b',') {
            p.expect(b'}')?;
            break;
        }
    }
    Ok(Header {
        descr: descr.ok_or("the header has no 'descr'")?,
        fortran_order: fortran_order.ok_or("the header has no 'fortran_order'")?,
        shape: shape.ok_or("the header has no 'shape'")?,
        data_offset: start + len,
    })
}

/// A cursor over the header's dict literal (the subset numpy writes).
struct DictParser<'a> {
    s: &'a [u8],
    i: usize,
}

impl DictParser<'_> {
    fn skip_ws(&mut self) {
        while self.s.get(self.i).is_some_and(|c| c.is_ascii_whitespace()) {
            self.i += 1;
        }
    }
    fn eat(&mut self, c: u8) -> bool {
        self.skip_ws();
        let hit = self.s.get(self.i) == Some(&c);
        self.i += hit as usize;
        hit
    }
    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!("malformed header: expected '{}' at character {}", c as char, self.i))
        }
    }
    /// A quoted string ('...' or "...").
    fn string(&mut self) -> Result<String, String> {
        self.skip_ws();
        let q = *self.s.get(self.i).ok_or("malformed header: it ends early")?;
        if q != b'\'' && q != b'"' {
            return Err(format!("malformed header: expected a string at character {}", self.i));
        }
        let end = self.s[self.i + 1..].iter().position(|&c| c == q).ok_or("malformed header: unterminated string")?;
        let out = String::from_utf8_lossy(&self.s[self.i + 1..self.i + 1 + end]).into_owned();
        self.i += end + 2;
        Ok(out)
    }
    fn boolean(&mut self) -> Result<bool, String> {
        self.skip_ws();
        for (word, v) in [(&b"True"[..], true), (&b"False"[..], false)] {
            if self.s[self.i..].starts_with(word) {
                self.i += word.len();
                return Ok(v);
            }
        }
        Err("malformed header: 'fortran_order' is not True or False".into())
    }
    /// A tuple of non-negative integers: `()`, `(3,)`, `(3, 17)`.
    fn tuple(&mut self) -> Result<Vec<usize>, String> {
        self.expect(b'(')?;
        let mut dims = Vec::new();
        loop {
            if self.eat(b')') {
                return Ok(dims);
            }
            let start = self.i;
            while self.s.get(self.i).is_some_and(u8::is_ascii_digit) {
                self.i += 1;
            }
            let n = std::str::from_utf8(&self.s[start..self.i])
                .unwrap()
                .parse()
                .map_err(|_| "malformed header: 'shape' is not a tuple of integers".to_string())?;
            dims.push(n);
            if !self.eat(b',') {
                self.expect(b')')?;
                return Ok(dims);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_padded_to_64_and_parses_back() {
        for shape in [vec![0u64], vec![5], vec![3, 17], vec![123_456_789, 2]] {
            let h = npy_header("<f8", &shape);
            assert_eq!(h.len() % 64, 0, "{shape:?}");
            assert_eq!(&h[6..8], &[1, 0]);
            assert_eq!(*h.last().unwrap(), b'\n');
            let p = parse_header(&h).unwrap();
            assert_eq!(
                p,
                Header {
                    descr: "<f8".into(),
                    fortran_order: false,
                    shape: shape.iter().map(|&d| d as usize).collect(),
                    data_offset: h.len()
                }
            );
        }
    }

    #[test]
    fn numpy_1d_header_is_byte_identical() {
        // np.save of np.zeros(3) writes exactly this header (numpy 1.x and 2.x).
        let mut want = b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }".to_vec();
        want.resize(127, b' ');
        want.push(b'\n');
        assert_eq!(npy_header("<f8", &[3]), want);
    }

    #[test]
    fn odd_spacing_and_double_quotes_parse() {
        let dict = b"{\"descr\":\"|u1\",\"shape\":( 2 , 3 ),\"fortran_order\":True}\n";
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        bytes.extend_from_slice(dict);
        let h = parse_header(&bytes).unwrap();
        assert_eq!((h.descr.as_str(), h.fortran_order, h.shape), ("|u1", true, vec![2, 3]));
    }
}
