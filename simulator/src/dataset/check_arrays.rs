//! The `.npy` / `.npz` checks: `images_1/timestamps.npz`, `poses_bounds.npy`,
//! `all_poses_bounds.npy` + `all_timestamps.npy` and the optional `ev_map.npz`.
//!
//! An array of the wrong dtype is a problem, but its values are still checked (converted to
//! f64) so that one run reports everything.

use std::path::Path;

use glam::{DMat3, DVec3};

use super::check::{ImageTimes, Lines, TestViewPolicy};
use crate::npy::{read_npy, read_npz, DType, NpyArray};

/// The fix for an unreadable array file.
const REWRITE: &str = "write it again with numpy (np.save / np.savez) or evblur's writer";

/// The numpy name of a dtype.
fn dtype_name(d: DType) -> &'static str {
    match d {
        DType::F64 => "float64",
        DType::F32 => "float32",
        DType::I64 => "int64",
        DType::U64 => "uint64",
        DType::I32 => "int32",
        DType::U16 => "uint16",
        DType::U8 => "uint8",
        DType::I8 => "int8",
        DType::Bool => "bool",
    }
}

/// Check `array` is float64 of shape `want` (`None` entries: any length) and return its values
/// as f64 (also for a wrong dtype); `None` if the shape is wrong.
fn f64_array(lines: &mut Lines, file: &str, field: &str, array: &NpyArray, want: &[Option<usize>]) -> Option<Vec<f64>> {
    let shape_ok =
        array.shape().len() == want.len() && array.shape().iter().zip(want).all(|(&d, w)| w.is_none_or(|w| d == w));
    let show = |s: &[Option<usize>]| {
        let dims: Vec<String> = s.iter().map(|d| d.map_or("any".to_string(), |d| d.to_string())).collect();
        format!("({})", dims.join(", "))
    };
    if array.dtype() != DType::F64 {
        lines.invalid(
            file,
            field,
            format!("dtype {}, expected float64", dtype_name(array.dtype())),
            "save it as float64 (arr.astype(np.float64))",
        );
    }
    if !shape_ok {
        lines.invalid(
            file,
            field,
            format!("shape {:?}, expected {}", array.shape(), show(want)),
            "write one entry per image / trajectory sample, in that shape",
        );
    }
    // A wrong length still leaves the values readable; a wrong rank or row width does not.
    let rows_readable = array.shape().len() == want.len()
        && array.shape().iter().zip(want).skip(1).all(|(&d, w)| w.is_none_or(|w| d == w));
    rows_readable.then(|| array.data().to_f64())
}

/// Up to 5 indices, for messages.
fn first_indices(idx: &[usize]) -> String {
    let shown: Vec<String> = idx.iter().take(5).map(|i| i.to_string()).collect();
    let more = if idx.len() > 5 { format!(" (+{} more)", idx.len() - 5) } else { String::new() };
    format!("[{}]{more}", shown.join(", "))
}

/// Check `images_1/timestamps.npz`; returns the exposure windows (us) and the matched policy.
pub(super) fn check_timestamps(
    dir: &Path,
    n: Option<usize>,
    policy: TestViewPolicy,
    lines: &mut Lines,
) -> (Option<ImageTimes>, Option<TestViewPolicy>) {
    const FILE: &str = "images_1/timestamps.npz";
    let path = dir.join(FILE);
    if !path.is_file() {
        lines.missing(
            FILE,
            "write timestamps, timestamps_start, timestamps_end (float64 us, one per image) with np.savez",
        );
        return (None, None);
    }
    let arrays = match read_npz(&path) {
        Ok(a) => a,
        Err(e) => {
            lines.unreadable(FILE, e, REWRITE);
            return (None, None);
        }
    };
    let before = lines.problem_count();
    let mut get = |name: &str| -> Option<Vec<f64>> {
        let Some((_, array)) = arrays.iter().find(|(k, _)| k == name) else {
            lines.invalid(FILE, name, "array missing", "add it (float64 us, one per image)");
            return None;
        };
        let v = f64_array(lines, FILE, name, array, &[n])?;
        let bad: Vec<usize> = (0..v.len()).filter(|&i| !(v[i].is_finite() && v[i] > 0.0)).collect();
        if !bad.is_empty() {
            lines.invalid(
                FILE,
                name,
                format!("not strictly positive and finite at {} (e.g. {})", first_indices(&bad), v[bad[0]]),
                "use microseconds on a clock that starts after 0 (the loader asserts timestamps_start > 0)",
            );
        }
        Some(v)
    };
    let (mid, start, end) = (get("timestamps"), get("timestamps_start"), get("timestamps_end"));
    let (Some(mid), Some(start), Some(end)) = (mid, start, end) else { return (None, None) };
    let len = mid.len();
    if start.len() != len || end.len() != len {
        lines.invalid(
            FILE,
            "timestamps_start/timestamps_end",
            format!("lengths {}/{} differ from timestamps ({len})", start.len(), end.len()),
            "write one window per image",
        );
        return (None, None);
    }
    // Exposure windows: start <= mid <= end, mid non-decreasing.
    let outside: Vec<usize> = (0..len).filter(|&i| !(start[i] <= mid[i] && mid[i] <= end[i])).collect();
    if !outside.is_empty() {
        let i = outside[0];
        lines.invalid(
            FILE,
            "timestamps",
            format!(
                "not inside [timestamps_start, timestamps_end] at {} (image {i}: {} not in [{}, {}])",
                first_indices(&outside),
                mid[i],
                start[i],
                end[i]
            ),
            "the mid-exposure time lies inside the window; start < end for blurry views, start == end for sharp ones",
        );
    }
    if let Some(i) = (1..len).find(|&i| mid[i] < mid[i - 1]) {
        lines.invalid(
            FILE,
            "timestamps",
            format!("decreases at image {i} ({} after {})", mid[i], mid[i - 1]),
            "order the images by time",
        );
    }
    // Sharp marking: start == end. The policy says which images must be sharp.
    let sharp: Vec<bool> = (0..len).map(|i| start[i] == end[i]).collect();
    let matches = |p: TestViewPolicy| (0..len).all(|i| sharp[i] == p.is_sharp(i, len));
    let candidates: &[TestViewPolicy] = match policy {
        TestViewPolicy::Auto => &[TestViewPolicy::Every8, TestViewPolicy::Last5],
        TestViewPolicy::Every8 => &[TestViewPolicy::Every8],
        TestViewPolicy::Last5 => &[TestViewPolicy::Last5],
    };
    let matched = candidates.iter().copied().find(|&p| matches(p));
    if matched.is_none() {
        let sharp_idx: Vec<usize> = (0..len).filter(|&i| sharp[i]).collect();
        let want = candidates.iter().map(|p| p.to_string()).collect::<Vec<_>>().join(" or ");
        // Name the wrongly marked images against the closest candidate policy.
        let wrong_for = |p: TestViewPolicy| (0..len).filter(|&i| sharp[i] != p.is_sharp(i, len)).collect::<Vec<_>>();
        let p = candidates.iter().copied().min_by_key(|&p| wrong_for(p).len()).unwrap_or(TestViewPolicy::Every8);
        let wrong = wrong_for(p);
        lines.invalid(
            FILE,
            "timestamps_start == timestamps_end (sharp views)",
            format!(
                "sharp views at {} do not follow {want}; against {p} images {} are marked wrongly",
                first_indices(&sharp_idx),
                first_indices(&wrong)
            ),
            "set start == end exactly for the test views and start < end for every other view",
        );
    }
    if lines.problem_count() == before {
        let n_sharp = sharp.iter().filter(|&&s| s).count();
        let p = matched.map_or("?".to_string(), |p| p.to_string());
        lines.ok(
            FILE,
            format!(
                "{len} windows, {n_sharp} sharp ({p}), {} blurry, mid {:.0}..{:.0} us",
                len - n_sharp,
                mid[0],
                mid[len - 1]
            ),
        );
    }
    (Some(ImageTimes { start, end }), matched)
}

/// Check the rows of an LLFF file (`poses_bounds.npy` with `n` rows, or the dense trajectory);
/// returns the number of rows when the shape is right.
pub(super) fn check_poses(
    dir: &Path,
    file: &str,
    n: Option<usize>,
    size: Option<(u32, u32)>,
    tolerance: f64,
    lines: &mut Lines,
) -> Option<usize> {
    let path = dir.join(file);
    if !path.is_file() {
        lines
            .missing(file, "write the LLFF rows (float64, 17 per row: 3x5 [down right backward | t | hwf], near, far)");
        return None;
    }
    let array = match read_npy(&path) {
        Ok(a) => a,
        Err(e) => {
            lines.unreadable(file, e, REWRITE);
            return None;
        }
    };
    let before = lines.problem_count();
    let v = f64_array(lines, file, "array", &array, &[n, Some(17)])?;
    let rows = v.len() / 17;
    let (mut not_rot, mut bad_hwf, mut bad_focal, mut bad_bounds, mut non_finite) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut worst = (0.0f64, 1.0f64);
    for (r, row) in v.chunks_exact(17).enumerate() {
        if row.iter().any(|x| !x.is_finite()) {
            non_finite.push(r);
            continue;
        }
        // Rotation: the loader's [c1, -c0, c2] must be orthonormal with det +1.
        let col = |j: usize| DVec3::new(row[j], row[5 + j], row[10 + j]);
        let m = DMat3::from_cols(col(1), -col(0), col(2));
        let e = m.transpose() * m - DMat3::IDENTITY;
        let orth = e.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let det = m.determinant();
        if orth > tolerance || (det - 1.0).abs() > tolerance {
            if not_rot.is_empty() {
                worst = (orth, det);
            }
            not_rot.push(r);
        }
        let (h, w, f) = (row[4], row[9], row[14]);
        if let Some((iw, ih)) = size {
            if (h - ih as f64).abs() > 1e-3 || (w - iw as f64).abs() > 1e-3 {
                bad_hwf.push(r);
            }
        }
        if !(f > 0.0) {
            bad_focal.push(r);
        }
        if !(row[15] > 0.0 && row[16] > row[15]) {
            bad_bounds.push(r);
        }
    }
    let row0 = |idx: &[usize]| &v[17 * idx[0]..17 * idx[0] + 17];
    if !non_finite.is_empty() {
        lines.invalid(file, format!("rows {}", first_indices(&non_finite)), "non-finite values", "write finite poses");
    }
    if !not_rot.is_empty() {
        lines.invalid(
            file,
            format!("rows {} (3x3 part)", first_indices(&not_rot)),
            format!(
                "not a pure rotation (row {}: max |R^T R - I| = {:.2e}, det = {:.6}; tolerance {tolerance:e})",
                not_rot[0], worst.0, worst.1
            ),
            "the columns must be orthonormal down, right, backward axes with det +1",
        );
    }
    if !bad_hwf.is_empty() {
        let r = row0(&bad_hwf);
        let (iw, ih) = size.unwrap_or_default();
        lines.invalid(
            file,
            format!("rows {} (hwf)", first_indices(&bad_hwf)),
            format!("height, width = {}, {} but the images are {ih} x {iw} (h x w)", r[4], r[9]),
            "write hwf = (image height, image width, focal in pixels)",
        );
    }
    if !bad_focal.is_empty() {
        lines.invalid(
            file,
            format!("rows {} (focal)", first_indices(&bad_focal)),
            format!("focal {} is not positive", row0(&bad_focal)[14]),
            "write the focal length in pixels, 0.5 h / tan(yfov / 2)",
        );
    }
    if !bad_bounds.is_empty() {
        let r = row0(&bad_bounds);
        lines.invalid(
            file,
            format!("rows {} (near, far)", first_indices(&bad_bounds)),
            format!("near = {}, far = {}: need 0 < near < far", r[15], r[16]),
            "write the honest depth range of the content seen from that camera",
        );
    }
    if lines.problem_count() == before {
        lines.ok(file, format!("{rows} rows x 17 float64, pure rotations, hwf and 0 < near < far"));
    }
    Some(rows)
}

/// Check the dense trajectory (`all_poses_bounds.npy`, `all_timestamps.npy`) and that every
/// exposure window lies inside it; returns its time range in us.
pub(super) fn check_dense(
    dir: &Path,
    size: Option<(u32, u32)>,
    times: Option<&ImageTimes>,
    tolerance: f64,
    lines: &mut Lines,
) -> Option<(f64, f64)> {
    const FILE: &str = "all_timestamps.npy";
    let rows = check_poses(dir, "all_poses_bounds.npy", None, size, tolerance, lines);
    let path = dir.join(FILE);
    if !path.is_file() {
        lines.missing(FILE, "write one float64 time (us) per row of all_poses_bounds.npy");
        return None;
    }
    let array = match read_npy(&path) {
        Ok(a) => a,
        Err(e) => {
            lines.unreadable(FILE, e, REWRITE);
            return None;
        }
    };
    let before = lines.problem_count();
    let t = f64_array(lines, FILE, "array", &array, &[rows])?;
    if t.is_empty() {
        lines.invalid(FILE, "array", "empty", "write the dense trajectory's times");
        return None;
    }
    if let Some(i) = t.iter().position(|x| !x.is_finite()) {
        lines.invalid(FILE, format!("entry {i}"), format!("{} is not finite", t[i]), "write finite times (us)");
        return None;
    }
    if let Some(i) = (1..t.len()).find(|&i| t[i] <= t[i - 1]) {
        lines.invalid(
            FILE,
            format!("entry {i}"),
            format!("{} does not increase strictly after {}", t[i], t[i - 1]),
            "write one strictly increasing time per dense pose",
        );
    }
    let (lo, hi) = t.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    if let Some(times) = times {
        let out = |v: &[f64]| (0..v.len()).filter(|&i| !(v[i] >= lo && v[i] <= hi)).collect::<Vec<_>>();
        for (name, v) in [("timestamps_start", &times.start), ("timestamps_end", &times.end)] {
            let bad = out(v);
            if !bad.is_empty() {
                lines.invalid(
                    "images_1/timestamps.npz",
                    name,
                    format!(
                        "images {} outside the dense trajectory [{lo}, {hi}] us of all_timestamps.npy (e.g. {})",
                        first_indices(&bad),
                        v[bad[0]]
                    ),
                    "render the dense trajectory over every exposure window",
                );
            }
        }
    }
    if lines.problem_count() == before {
        lines.ok(FILE, format!("{} strictly increasing times {lo:.0}..{hi:.0} us, covering every exposure", t.len()));
    }
    Some((lo, hi))
}

/// Check the optional `ev_map.npz`: `inv_mapx`, `inv_mapy` of shape (H, W).
pub(super) fn check_ev_map(dir: &Path, size: Option<(u32, u32)>, lines: &mut Lines) {
    const FILE: &str = "ev_map.npz";
    let path = dir.join(FILE);
    if !path.is_file() {
        lines.0.push(super::check::CheckLine::Absent {
            file: FILE.into(),
            detail: "only for colour events with rectified float coordinates (CDAVIS)".into(),
        });
        return;
    }
    let arrays = match read_npz(&path) {
        Ok(a) => a,
        Err(e) => return lines.unreadable(FILE, e, REWRITE),
    };
    let before = lines.problem_count();
    for name in ["inv_mapx", "inv_mapy"] {
        let Some((_, a)) = arrays.iter().find(|(k, _)| k == name) else {
            lines.invalid(FILE, name, "array missing", "write inv_mapx and inv_mapy (H x W)");
            continue;
        };
        let want = size.map(|(w, h)| vec![h as usize, w as usize]);
        if a.shape().len() != 2 || want.as_ref().is_some_and(|w| a.shape() != w.as_slice()) {
            lines.invalid(
                FILE,
                name,
                format!("shape {:?}, expected (H, W) = {:?}", a.shape(), want),
                "one entry per raw sensor pixel",
            );
        }
    }
    if lines.problem_count() == before {
        lines.ok(FILE, "inv_mapx, inv_mapy of shape (H, W)");
    }
}
