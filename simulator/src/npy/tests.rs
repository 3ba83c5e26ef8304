//! Round trips of every dtype and rank, and the refusals with their messages.

use super::*;

/// A fresh, empty folder under the system temp dir.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evblur-npy-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Six elements of every dtype, with extremes and (for floats) a NaN-free spread.
fn samples() -> Vec<NpyData> {
    vec![
        NpyData::F64(vec![0.0, -1.5, f64::MAX, f64::MIN_POSITIVE, 1e-300, std::f64::consts::PI]),
        NpyData::F32(vec![0.0, -1.5, f32::MAX, f32::MIN_POSITIVE, f32::INFINITY, 0.1]),
        NpyData::I64(vec![0, -1, i64::MIN, i64::MAX, 42, -7]),
        NpyData::U64(vec![0, 1, u64::MAX, 1 << 40, 42, 7]),
        NpyData::I32(vec![0, -1, i32::MIN, i32::MAX, 42, -7]),
        NpyData::U16(vec![0, 1, u16::MAX, 640, 480, 7]),
        NpyData::U8(vec![0, 1, 255, 128, 2, 3]),
        NpyData::I8(vec![0, -1, -128, 127, 2, -3]),
        NpyData::Bool(vec![true, false, true, true, false, false]),
    ]
}

#[test]
fn every_dtype_round_trips_in_1d_and_2d() {
    let dir = temp_dir("round");
    for data in samples() {
        for shape in [&[6][..], &[2, 3], &[3, 2], &[1, 6]] {
            let a = NpyArray::new(shape, data.clone()).unwrap();
            let path = dir.join(format!("{:?}.npy", a.dtype()));
            write_npy(&path, &a).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let hlen = bytes.len() - data.len() * a.dtype().size();
            assert_eq!(hlen % 64, 0, "header length {hlen} for {:?}", a.dtype());
            assert!(String::from_utf8_lossy(&bytes[..hlen]).contains(a.dtype().descr()));
            assert_eq!(read_npy(&path).unwrap(), a);
        }
        let empty = NpyArray::new(&[0, 17], NpyData::from_le_bytes(data.dtype(), &[])).unwrap();
        assert_eq!(NpyArray::from_npy_bytes(&empty.to_npy_bytes(), "e").unwrap(), empty);
    }
    let names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "no temporary files remain: {names:?}");
}

#[test]
fn npz_round_trips_every_dtype() {
    let dir = temp_dir("npz");
    let arrays: Vec<(String, NpyArray)> = samples()
        .into_iter()
        .map(|d| (format!("{:?}", d.dtype()).to_lowercase(), NpyArray::new(&[3, 2], d).unwrap()))
        .collect();
    let named: Vec<(&str, NpyArray)> = arrays.iter().map(|(n, a)| (n.as_str(), a.clone())).collect();
    let path = dir.join("sub/all.npz");
    write_npz(&path, &named).unwrap();
    assert_eq!(read_npz(&path).unwrap(), arrays);
    write_npz(&path, &[]).unwrap();
    assert!(read_npz(&path).unwrap().is_empty());
}

#[test]
fn constructors_and_accessors() {
    let rows = [[1.0; 17], [2.0; 17]];
    let a = NpyArray::f64_2d(&rows);
    assert_eq!(a.shape(), &[2, 17]);
    assert_eq!(a.as_f64().unwrap()[17], 2.0);
    assert!(a.as_i64().is_none());
    assert_eq!(NpyArray::vector(vec![1i64, 2]).as_i64(), Some(&[1i64, 2][..]));
    assert!(NpyArray::new(&[2, 2], vec![1.0f64; 3]).is_none(), "shape must match the data");
    assert!(NpyArray::new(&[1, 1, 1], vec![1.0f64]).is_none(), "only 1-D and 2-D");
}

/// A `.npy` with a hand-made header dict and `data`.
fn with_dict(dict: &str, data: &[u8]) -> Vec<u8> {
    let mut dict = dict.to_string();
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend_from_slice(data);
    out
}

/// The error message of reading `bytes` as `f.npy`.
fn error_of(bytes: &[u8]) -> String {
    let err = NpyArray::from_npy_bytes(bytes, "dir/f.npy").unwrap_err();
    assert!(matches!(err, NpyError::Format { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.starts_with("dir/f.npy: "), "names the file: {msg}");
    msg
}

#[test]
fn bad_files_are_clear_errors() {
    let good = NpyArray::f64_2d(&[[1.0; 17]; 3]).to_npy_bytes();
    assert!(error_of(&good[..good.len() - 1]).contains("truncated"));
    assert!(error_of(&good[..good.len() - 8 * 17]).contains("truncated"));
    assert!(error_of(&good[..5]).contains("truncated"));
    assert!(error_of(&good[..64]).contains("truncated"));
    assert!(error_of(b"PK\x03\x04 not an npy file").contains("not a .npy"));
    let data = [0u8; 48];
    let fortran = error_of(&with_dict("{'descr': '<f8', 'fortran_order': True, 'shape': (2, 3), }", &data));
    assert!(fortran.contains("Fortran"), "{fortran}");
    let big = error_of(&with_dict("{'descr': '>f8', 'fortran_order': False, 'shape': (6,), }", &data));
    assert!(big.contains("big-endian"), "{big}");
    let unknown = error_of(&with_dict("{'descr': '<c16', 'fortran_order': False, 'shape': (3,), }", &data));
    assert!(unknown.contains("'<c16' is not supported"), "{unknown}");
    let odd = error_of(&with_dict("{'descr': 'é8', 'fortran_order': False, 'shape': (6,), }", &data));
    assert!(odd.contains("is not supported"), "{odd}");
    let structured = error_of(&with_dict("{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (6,), }", &data));
    assert!(structured.contains("structured"), "{structured}");
    let three_d = error_of(&with_dict("{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2, 3), }", &data));
    assert!(three_d.contains("3 dimensions"), "{three_d}");
    // Single-byte dtypes have no byte order: '>u1' and '|u1' are the same.
    assert!(NpyArray::from_npy_bytes(
        &with_dict("{'descr': '>u1', 'fortran_order': False, 'shape': (48,), }", &data),
        "f"
    )
    .is_ok());
}

#[test]
fn bad_npz_and_missing_files_name_the_file() {
    let dir = temp_dir("bad-npz");
    let path = dir.join("t.npz");
    write_npz(&path, &[("timestamps", NpyArray::vector(vec![1.0f64, 2.0]))]).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
    let msg = read_npz(&path).unwrap_err().to_string();
    assert!(msg.contains("t.npz") && msg.contains("zip"), "{msg}");
    let missing = read_npy(&dir.join("nope.npy")).unwrap_err();
    assert!(matches!(missing, NpyError::Io { .. }) && missing.to_string().contains("nope.npy"), "{missing}");
}

#[test]
fn long_header_switches_to_version_2() {
    // 30 000 dims ("1, " each) would not fit a u16 header; only the header code supports it, so test it there.
    let shape: Vec<u64> = vec![1; 30_000];
    let h = npy_header("<f8", &shape);
    assert_eq!(&h[6..8], &[2, 0]);
    assert_eq!(h.len() % 64, 0);
    let parsed = header::parse_header(&h).unwrap();
    assert_eq!(parsed.shape.len(), 30_000);
    assert_eq!(parsed.data_offset, h.len());
}
