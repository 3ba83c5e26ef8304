//! `.npy` / `.npz` files against numpy itself: our writer's files (an f64 N x 17 pose table, an
//! `.npz` of three f64 arrays as `images_1/timestamps.npz`) are opened with numpy and checked
//! for dtype, shape and values; numpy's `np.save`, `np.savez` and `np.savez_compressed` files
//! of every supported dtype are read back by ours and must match exactly.
//!
//! Without the Mitsuba venv's Python (with numpy) the test prints SKIPPED, or fails when
//! `EVBLUR_REQUIRE_MITSUBA=1`.

use evblur_tests::{python_with, run_python, temp_dir};
use simulator::npy::{read_npy, read_npz, write_npy, write_npz, NpyArray, NpyData};

/// Pose row `i`: distinct, non-round values (the Python side rebuilds them).
fn pose_row(i: usize) -> [f64; 17] {
    std::array::from_fn(|j| (i as f64 + 1.0) * 0.1 + j as f64 * 1e-3 - 1.0 / 3.0)
}

#[test]
fn numpy_reads_our_npy_and_npz() {
    let Some(py) = python_with("numpy", "numpy_reads_our_npy_and_npz") else { return };
    let dir = temp_dir("npy-files", "ours");
    let rows: Vec<[f64; 17]> = (0..7).map(pose_row).collect();
    write_npy(&dir.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).unwrap();
    let mid: Vec<f64> = (0..7).map(|i| 1e6 * i as f64 / 3.0).collect();
    let start: Vec<f64> = mid.iter().map(|t| t - 12_500.25).collect();
    let end: Vec<f64> = mid.iter().map(|t| t + 12_500.25).collect();
    write_npz(
        &dir.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid)),
            ("timestamps_start", NpyArray::vector(start)),
            ("timestamps_end", NpyArray::vector(end)),
        ],
    )
    .unwrap();
    let script = r#"
import sys, numpy as np
d = sys.argv[1]
p = np.load(d + "/poses_bounds.npy")
assert p.dtype == np.float64 and p.shape == (7, 17), (p.dtype, p.shape)
want = np.array([[(i + 1.0) * 0.1 + j * 1e-3 - 1.0 / 3.0 for j in range(17)] for i in range(7)])
assert np.array_equal(p, want), p - want
z = np.load(d + "/images_1/timestamps.npz")
assert sorted(z.files) == ["timestamps", "timestamps_end", "timestamps_start"], z.files
mid = np.array([1e6 * i / 3.0 for i in range(7)])
for k, v in [("timestamps", mid), ("timestamps_start", mid - 12500.25), ("timestamps_end", mid + 12500.25)]:
    assert z[k].dtype == np.float64 and z[k].shape == (7,), (k, z[k].dtype, z[k].shape)
    assert np.array_equal(z[k], v), (k, z[k] - v)
"#;
    run_python(&py, script, [&dir]);
}

#[test]
fn we_read_numpy_save_savez_and_savez_compressed() {
    let Some(py) = python_with("numpy", "we_read_numpy_save_savez_and_savez_compressed") else { return };
    let dir = temp_dir("npy-files", "numpy");
    // Every dtype as a 2 x 3 array of the same six values (bool: odd ones), 1-D and 2-D.
    let script = r#"
import sys, numpy as np
d = sys.argv[1]
vals = [0, 1, 2, 3, 100, 127]
arrays = {}
for code in ["f8", "f4", "i8", "u8", "i4", "u2", "u1", "i1"]:
    arrays[code] = np.array(vals, dtype="<" + code).reshape(2, 3)
arrays["b1"] = (np.array(vals) % 2 == 1).reshape(2, 3)
arrays["pi"] = np.array([np.pi, -np.e, 1e-300, 1.7976931348623157e308])
arrays["big"] = np.arange(100000, dtype=np.float64) / 7.0
for k, v in arrays.items():
    np.save(d + "/" + k + ".npy", v)
np.savez(d + "/plain.npz", **arrays)
np.savez_compressed(d + "/compressed.npz", **arrays)
"#;
    run_python(&py, script, [&dir]);
    let vals = [0u8, 1, 2, 3, 100, 127];
    let two_by_three = |data: NpyData| NpyArray::new(&[2, 3], data).unwrap();
    let mut want: Vec<(String, NpyArray)> = vec![
        ("f8", two_by_three(NpyData::F64(vals.iter().map(|&v| v as f64).collect()))),
        ("f4", two_by_three(NpyData::F32(vals.iter().map(|&v| v as f32).collect()))),
        ("i8", two_by_three(NpyData::I64(vals.iter().map(|&v| v as i64).collect()))),
        ("u8", two_by_three(NpyData::U64(vals.iter().map(|&v| v as u64).collect()))),
        ("i4", two_by_three(NpyData::I32(vals.iter().map(|&v| v as i32).collect()))),
        ("u2", two_by_three(NpyData::U16(vals.iter().map(|&v| v as u16).collect()))),
        ("u1", two_by_three(NpyData::U8(vals.to_vec()))),
        ("i1", two_by_three(NpyData::I8(vals.iter().map(|&v| v as i8).collect()))),
        ("b1", two_by_three(NpyData::Bool(vals.iter().map(|&v| v % 2 == 1).collect()))),
    ]
    .into_iter()
    .map(|(k, a)| (k.to_string(), a))
    .collect();
    want.push(("pi".into(), NpyArray::vector(vec![std::f64::consts::PI, -std::f64::consts::E, 1e-300, f64::MAX])));
    want.push(("big".into(), NpyArray::vector((0..100_000).map(|i| i as f64 / 7.0).collect::<Vec<f64>>())));
    for (name, array) in &want {
        assert_eq!(&read_npy(&dir.join(format!("{name}.npy"))).unwrap(), array, "np.save {name}");
    }
    for archive in ["plain.npz", "compressed.npz"] {
        let got = read_npz(&dir.join(archive)).unwrap();
        assert_eq!(got, want, "{archive}");
    }
}
