//! The `events.h5` check: root datasets `x`, `y`, `t`, `p`, streamed in chunks of
//! [`CheckOptions::event_chunk`] events so that memory does not grow with the file.
//!
//! Any standard integer dtype is read (through `rust-hdf5`'s converting slice reader, as i64),
//! floats as f64 (rectified coordinates, float times), and h5py's `bool` (a one-byte HDF5 enum)
//! as 0/1. The unit of `t` is ns or us; `Auto` picks the one whose mid time lands closest (in log
//! ratio) to the middle of `all_timestamps.npy` (us), ns when there is no trajectory to compare.

use std::path::Path;

use rust_hdf5::{DatatypeMessage, H5Dataset, H5File};

use super::check::{CheckOptions, EventSummary, EventsUnit, Lines};

const FILE: &str = "events.h5";
/// Event times may exceed the trajectory by this much (us) and still count as inside: 1 ns.
const RANGE_SLACK_US: f64 = 1e-3;

/// How a column's values are read.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// A standard-width integer, read as i64.
    Int,
    /// IEEE float, read as f64.
    Float,
    /// A one-byte enum (h5py `bool`), read as its base integer.
    Enum1 { signed: bool },
}

/// One chunk of a column: integers (any standard width, and h5py `bool`) as i64, floats as f64.
#[derive(Clone, Debug, PartialEq)]
pub enum Col {
    /// An integer column.
    Int(Vec<i64>),
    /// A float column (rectified coordinates, float times).
    Float(Vec<f64>),
}

impl Col {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Col::Int(v) => v.len(),
            Col::Float(v) => v.len(),
        }
    }
    /// True if there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Value `i` as f64.
    pub fn get(&self, i: usize) -> f64 {
        match self {
            Col::Int(v) => v[i] as f64,
            Col::Float(v) => v[i],
        }
    }
}

/// The kind of a dataset's dtype, or why it is not a number.
fn kind_of(dt: &DatatypeMessage) -> Result<Kind, String> {
    match dt {
        DatatypeMessage::FixedPoint { .. } => Ok(Kind::Int),
        DatatypeMessage::FloatingPoint { .. } => Ok(Kind::Float),
        DatatypeMessage::Enum { base, .. } => match **base {
            DatatypeMessage::FixedPoint { size: 1, signed, .. } => Ok(Kind::Enum1 { signed }),
            _ => Err(format!("dtype {dt} is an enum wider than one byte")),
        },
        other => Err(format!("dtype {other} is not a number")),
    }
}

/// Read `count` values from `start`.
fn read(ds: &H5Dataset, kind: Kind, start: usize, count: usize) -> rust_hdf5::Result<Col> {
    Ok(match kind {
        Kind::Int => Col::Int(ds.read_numeric_slice_as::<i64>(&[start], &[count])?),
        Kind::Float => Col::Float(ds.read_numeric_slice_as::<f64>(&[start], &[count])?),
        Kind::Enum1 { signed: false } => {
            Col::Int(ds.read_slice::<u8>(&[start], &[count])?.into_iter().map(i64::from).collect())
        }
        Kind::Enum1 { signed: true } => {
            Col::Int(ds.read_slice::<i8>(&[start], &[count])?.into_iter().map(i64::from).collect())
        }
    })
}

/// One 1-D numeric column of `events.h5`, opened for reading in chunks (the reusable part of
/// this check, for the trainer's loader).
pub struct EventColumnReader {
    ds: H5Dataset,
    kind: Kind,
}

impl EventColumnReader {
    /// Open root dataset `name`; errors (as text) when it is missing, not 1-D or not a number.
    pub fn open(file: &H5File, name: &str) -> Result<EventColumnReader, String> {
        let ds = file.dataset(name).map_err(|e| format!("dataset {name} missing ({e})"))?;
        if ds.ndims() != 1 {
            return Err(format!("dataset {name} has shape {:?}, expected 1-D", ds.shape()));
        }
        let dt = ds.datatype().map_err(|e| format!("dataset {name}: {e}"))?;
        let kind = kind_of(&dt).map_err(|e| format!("dataset {name}: {e}"))?;
        Ok(EventColumnReader { ds, kind })
    }
    /// Number of values.
    pub fn len(&self) -> usize {
        self.ds.shape()[0]
    }
    /// True if the column is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// True for a float column (rectified coordinates).
    pub fn is_float(&self) -> bool {
        self.kind == Kind::Float
    }
    /// Read `count` values from `start` (fewer values than asked is an error).
    pub fn read(&self, start: usize, count: usize) -> Result<Col, String> {
        let v = read(&self.ds, self.kind, start, count).map_err(|e| e.to_string())?;
        if v.len() != count {
            return Err(format!("{} values read, {count} asked", v.len()));
        }
        Ok(v)
    }
}

/// An opened column: dataset, kind and dtype name.
struct Column {
    name: &'static str,
    ds: H5Dataset,
    kind: Kind,
    dtype: String,
}

/// Open the four columns, reporting every missing, non-1-D or non-numeric one.
fn open_columns(file: &H5File, lines: &mut Lines) -> Option<[Column; 4]> {
    let mut out = Vec::new();
    for name in ["x", "y", "t", "p"] {
        let ds = match file.dataset(name) {
            Ok(ds) => ds,
            Err(e) => {
                lines.invalid(FILE, name, format!("dataset missing ({e})"), "write root datasets x, y, t, p");
                continue;
            }
        };
        if ds.ndims() != 1 {
            lines.invalid(FILE, name, format!("shape {:?}, expected 1-D", ds.shape()), "write one value per event");
            continue;
        }
        let dt = match ds.datatype() {
            Ok(dt) => dt,
            Err(e) => {
                lines.unreadable(FILE, format!("dataset {name}: {e}"), "write it again with h5py or evblur");
                continue;
            }
        };
        match kind_of(&dt) {
            Ok(kind) => {
                let dtype = if matches!(kind, Kind::Enum1 { .. }) { format!("bool ({dt})") } else { dt.to_string() };
                out.push(Column { name, ds, kind, dtype })
            }
            Err(e) => lines.invalid(FILE, name, e, "store integers (or floats for rectified coordinates)"),
        }
    }
    out.try_into().ok()
}

/// The unit of `t` to use, and whether it was detected.
fn resolve_unit(opt: EventsUnit, t_first: f64, t_last: f64, dense: Option<(f64, f64)>) -> EventsUnit {
    if opt != EventsUnit::Auto {
        return opt;
    }
    let Some((lo, hi)) = dense else { return EventsUnit::Ns };
    let (mid_t, mid_dense) = (0.5 * (t_first + t_last), 0.5 * (lo + hi));
    if !(mid_t > 0.0 && mid_dense > 0.0) {
        return EventsUnit::Ns;
    }
    let score = |u: EventsUnit| (mid_t * u.us_per_unit() / mid_dense).ln().abs();
    if score(EventsUnit::Us) < score(EventsUnit::Ns) {
        EventsUnit::Us
    } else {
        EventsUnit::Ns
    }
}

/// First offender and count of one kind of bad event.
#[derive(Default)]
struct Bad {
    count: u64,
    first: Option<(u64, String)>,
}

impl Bad {
    fn hit(&mut self, i: u64, what: impl FnOnce() -> String) {
        self.count += 1;
        if self.first.is_none() {
            self.first = Some((i, what()));
        }
    }
    fn report(&self, lines: &mut Lines, field: &str, problem: &str, fix: &str) {
        if let Some((i, what)) = &self.first {
            lines.invalid(
                FILE,
                field,
                format!("{} event(s) {problem}, the first at index {i} ({what})", self.count),
                fix,
            );
        }
    }
}

/// Check `events.h5` (required); `size` is the image (width, height), `dense` the trajectory's
/// time range in us.
pub(super) fn check_events(
    dir: &Path,
    size: Option<(u32, u32)>,
    dense: Option<(f64, f64)>,
    opts: &CheckOptions,
    lines: &mut Lines,
) -> Option<EventSummary> {
    let path = dir.join(FILE);
    if !path.is_file() {
        lines.missing(FILE, "write the events (root datasets x, y, t ns, p) with evsim events or h5py");
        return None;
    }
    let file = match H5File::open(&path) {
        Ok(f) => f,
        Err(e) => {
            lines.unreadable(FILE, e, "write it again with h5py or evblur (a plain HDF5 file)");
            return None;
        }
    };
    let before = lines.problem_count();
    let cols = open_columns(&file, lines)?;
    let n = cols[0].ds.shape()[0];
    if cols.iter().any(|c| c.ds.shape()[0] != n) {
        let lens: Vec<String> = cols.iter().map(|c| format!("{} {}", c.name, c.ds.shape()[0])).collect();
        lines.invalid(
            FILE,
            "x, y, t, p",
            format!("lengths differ ({})", lens.join(", ")),
            "write x, y, t, p of equal length",
        );
        return None;
    }
    let [x, y, t, p] = &cols;
    let h5 = |lines: &mut Lines, c: &Column, e: rust_hdf5::Hdf5Error| {
        lines.unreadable(FILE, format!("dataset {}: {e}", c.name), "write it again with h5py or evblur");
    };

    // The unit of t, from its first and last values (the file is meant to be sorted).
    let ends = if n == 0 {
        None
    } else {
        match (read(&t.ds, t.kind, 0, 1), read(&t.ds, t.kind, n - 1, 1)) {
            (Ok(a), Ok(b)) => Some((a.get(0), b.get(0))),
            (Err(e), _) | (_, Err(e)) => {
                h5(lines, t, e);
                return None;
            }
        }
    };
    let unit = ends.map_or(EventsUnit::Ns, |(a, b)| resolve_unit(opts.events_unit, a, b, dense));
    let k = unit.us_per_unit();

    // Stream the columns chunk by chunk.
    let (mut unsorted, mut out_of_time, mut bad_x, mut bad_y, mut bad_p, mut bad_t) =
        (Bad::default(), Bad::default(), Bad::default(), Bad::default(), Bad::default(), Bad::default());
    let (mut on, mut off, mut seen_zero, mut seen_minus) = (0u64, 0u64, false, false);
    let (mut t_min, mut t_max, mut prev) = (f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    let chunk = opts.event_chunk.max(1);
    let mut start = 0;
    while start < n {
        let count = chunk.min(n - start);
        let mut chunk_cols = Vec::with_capacity(4);
        for c in &cols {
            match read(&c.ds, c.kind, start, count) {
                Ok(v) if v.len() == count => chunk_cols.push(v),
                Ok(v) => {
                    lines.unreadable(
                        FILE,
                        format!("dataset {}: {} values read, {count} asked", c.name, v.len()),
                        "write it again with h5py or evblur",
                    );
                    return None;
                }
                Err(e) => {
                    h5(lines, c, e);
                    return None;
                }
            }
        }
        let [cx, cy, ct, cp] = &chunk_cols[..] else { unreachable!("four columns") };
        for j in 0..count {
            let i = (start + j) as u64;
            let tv = ct.get(j);
            if !tv.is_finite() {
                bad_t.hit(i, || format!("t = {tv}"));
                continue;
            }
            if tv < prev {
                unsorted.hit(i, || format!("t = {tv} after {prev}"));
            }
            prev = tv;
            t_min = t_min.min(tv);
            t_max = t_max.max(tv);
            if let Some((lo, hi)) = dense {
                let us = tv * k;
                if !(us >= lo - RANGE_SLACK_US && us <= hi + RANGE_SLACK_US) {
                    out_of_time.hit(i, || format!("t = {tv} {unit} = {us} us"));
                }
            }
            for (col, bad, limit) in [(cx, &mut bad_x, size.map(|s| s.0)), (cy, &mut bad_y, size.map(|s| s.1))] {
                let v = col.get(j);
                let ok = match col {
                    Col::Int(_) => v >= 0.0 && limit.is_none_or(|l| v < l as f64),
                    Col::Float(_) => v.is_finite(),
                };
                if !ok {
                    bad.hit(i, || format!("{v}"));
                }
            }
            let pv = cp.get(j);
            if pv == 1.0 {
                on += 1;
            } else if pv == 0.0 || pv == -1.0 {
                off += 1;
                seen_zero |= pv == 0.0;
                seen_minus |= pv == -1.0;
            } else {
                bad_p.hit(i, || format!("p = {pv}"));
            }
        }
        start += count;
    }

    let (w, h) = size.map_or(("W".to_string(), "H".to_string()), |(w, h)| (w.to_string(), h.to_string()));
    bad_t.report(lines, "t", "are not finite", "write finite times");
    unsorted.report(lines, "t", "go back in time", "sort the events by t (stable sort; ties are allowed)");
    if let Some((lo, hi)) = dense {
        out_of_time.report(
            lines,
            "t",
            &format!("lie outside the dense trajectory [{lo}, {hi}] us of all_timestamps.npy (unit {unit})"),
            "extend all_poses_bounds.npy / all_timestamps.npy over every event, or check the unit of t (ns)",
        );
    }
    bad_x.report(lines, "x", &format!("are not in 0 <= x < {w}"), "store pixel columns of the image size");
    bad_y.report(lines, "y", &format!("are not in 0 <= y < {h}"), "store pixel rows of the image size");
    bad_p.report(lines, "p", "are neither 0/1 nor -1/+1", "store polarity as {0, 1} or {-1, +1}");
    if seen_zero && seen_minus {
        lines.invalid(FILE, "p", "mixes 0 and -1 for OFF", "use either {0, 1} or {-1, +1}");
    }
    let t_range = (n > 0 && t_min <= t_max).then_some((t_min, t_max));
    let detected = if opts.events_unit == EventsUnit::Auto { "auto-detected" } else { "given" };
    let range = t_range.map_or("no events".to_string(), |(a, b)| format!("t {a}..{b} {unit}"));
    let detail = format!(
        "{n} events ({on} ON, {off} OFF), {range} (unit {unit}, {detected}); dtypes x {}, y {}, t {}, p {}",
        x.dtype, y.dtype, t.dtype, p.dtype
    );
    if lines.problem_count() == before {
        lines.ok(FILE, detail);
    } else {
        lines.info(FILE, detail);
    }
    Some(EventSummary { count: n as u64, t_range, unit, on, off })
}
