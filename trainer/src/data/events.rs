//! Events (`events.h5`) on the image clock, each linked to the next event at the same pixel, and
//! the colour-event map (`ev_map.npz`).
//!
//! As the reference loader: times are converted to microseconds (the file's unit is ns for the
//! synthetic scenes, `events_tms_unit = ns`, or us); events outside the dense trajectory's time
//! range `[all_timestamps.min(), all_timestamps.max()]` are dropped (their pose cannot be
//! interpolated); polarity 0 or -1 is OFF (-1), 1 is ON (+1). The event loss pairs each event
//! with its *successor*, the next event in time at the same pixel (same `x`, `y`; for float
//! rectified coordinates the same stored coordinate, i.e. the same raw sensor pixel).
//!
//! Columns are read in chunks through `simulator::dataset::EventColumnReader` (any integer
//! dtype, float, h5py bool).

use std::collections::HashMap;
use std::path::Path;

use rust_hdf5::H5File;
use simulator::dataset::check::EventsUnit;
use simulator::dataset::EventColumnReader;
use simulator::npy::read_npz;

use super::error::LoadError;

const FILE: &str = "events.h5";
const EV_MAP: &str = "ev_map.npz";
/// Marks "no successor" in [`Events::successors`].
pub const NO_SUCCESSOR: u32 = u32::MAX;

/// The events kept by the loader, sorted by time (file order), struct-of-arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Events {
    /// Pixel column (integer-valued for synthetic data, float for rectified real data).
    pub x: Vec<f32>,
    /// Pixel row.
    pub y: Vec<f32>,
    /// Time (us, the clock of `timestamps.npz`).
    pub t_us: Vec<f64>,
    /// Polarity: +1 (ON) or -1 (OFF).
    pub polarity: Vec<i8>,
    /// Index of the next event at the same pixel, or [`NO_SUCCESSOR`].
    pub successors: Vec<u32>,
    /// True if the file stores float (rectified) coordinates.
    pub float_coordinates: bool,
    /// Events of the file dropped for lying outside the dense trajectory's time range.
    pub dropped: u64,
    /// The unit of `t` in the file (never `Auto`).
    pub file_unit: EventsUnit,
}

impl Events {
    /// Number of events kept.
    pub fn len(&self) -> usize {
        self.t_us.len()
    }

    /// True if no event was kept.
    pub fn is_empty(&self) -> bool {
        self.t_us.is_empty()
    }

    /// The successor of event `i` (the next event at the same pixel), if any.
    pub fn successor(&self, i: usize) -> Option<usize> {
        let s = self.successors[i];
        (s != NO_SUCCESSOR).then_some(s as usize)
    }

    /// Indices of the events that have a successor (the event loss samples among these).
    pub fn with_successor(&self) -> Vec<u32> {
        (0..self.len() as u32).filter(|&i| self.successors[i as usize] != NO_SUCCESSOR).collect()
    }

    /// Read `dir/events.h5` in chunks of `chunk` events, `t` in `unit` (not `Auto`), keeping the
    /// events with `range_us.0 <= t <= range_us.1`; `width` x `height` is the image size.
    pub fn read(
        dir: &Path,
        unit: EventsUnit,
        range_us: (f64, f64),
        (width, height): (u32, u32),
        chunk: usize,
    ) -> Result<Events, LoadError> {
        let fix = "write it again with evsim dataset or h5py (root datasets x, y, t, p)";
        let file = H5File::open(dir.join(FILE)).map_err(|e| LoadError::unreadable(FILE, e, fix))?;
        let open = |name| EventColumnReader::open(&file, name).map_err(|e| LoadError::unreadable(FILE, e, fix));
        let cols = [open("x")?, open("y")?, open("t")?, open("p")?];
        let n = cols[0].len();
        if cols.iter().any(|c| c.len() != n) {
            return Err(LoadError::invalid(FILE, "x, y, t, p", "lengths differ", "write columns of equal length"));
        }
        let us_per_unit = unit.us_per_unit();
        let mut ev = Events {
            float_coordinates: cols[0].is_float() || cols[1].is_float(),
            file_unit: unit,
            ..Events::default()
        };
        let chunk = chunk.max(1);
        let mut start = 0;
        let mut last_t = f64::NEG_INFINITY;
        while start < n {
            let count = chunk.min(n - start);
            let read = |c: &EventColumnReader| c.read(start, count).map_err(|e| LoadError::unreadable(FILE, e, fix));
            let (cx, cy, ct, cp) = (read(&cols[0])?, read(&cols[1])?, read(&cols[2])?, read(&cols[3])?);
            for j in 0..count {
                let t_us = ct.get(j) * us_per_unit;
                // the checker refuses these files; a reader called on its own must too, or the
                // successors below (the next event in file order) would pair wrong events
                if t_us.is_nan() || t_us < last_t {
                    return Err(LoadError::invalid(
                        FILE,
                        "t",
                        format!(
                            "event {} at t = {} goes back in time (after {last_t} us) or is not a number",
                            start + j,
                            ct.get(j)
                        ),
                        "sort the events by t (stable sort; ties are allowed)",
                    ));
                }
                last_t = t_us;
                let p = cp.get(j);
                if !(p == 1.0 || p == 0.0 || p == -1.0) {
                    return Err(LoadError::invalid(
                        FILE,
                        "p",
                        format!("event {} has polarity {p}", start + j),
                        "store polarity as 0/1 or -1/+1",
                    ));
                }
                // drop events the trajectory does not cover, as the reference does
                if !(t_us >= range_us.0 && t_us <= range_us.1) {
                    ev.dropped += 1;
                    continue;
                }
                let (x, y) = (cx.get(j), cy.get(j));
                let inside = x >= 0.0 && y >= 0.0 && x < width as f64 && y < height as f64;
                if !ev.float_coordinates && !inside {
                    return Err(LoadError::invalid(
                        FILE,
                        "x, y",
                        format!("event {} at ({x}, {y}) is outside the {width}x{height} image", start + j),
                        "store pixel coordinates of the image size",
                    ));
                }
                ev.x.push(x as f32);
                ev.y.push(y as f32);
                ev.t_us.push(t_us);
                ev.polarity.push(if p > 0.0 { 1 } else { -1 });
            }
            start += count;
        }
        if ev.len() >= NO_SUCCESSOR as usize {
            return Err(LoadError::invalid(
                FILE,
                "x",
                format!("{} events", ev.len()),
                "split the file (< 2^32 events)",
            ));
        }
        ev.successors = successors(&ev.x, &ev.y, (width, height), ev.float_coordinates);
        Ok(ev)
    }
}

/// For each event, the index of the next event (in file order, i.e. time) at the same pixel.
pub fn successors(x: &[f32], y: &[f32], (width, height): (u32, u32), float_coordinates: bool) -> Vec<u32> {
    let n = x.len();
    let mut out = vec![NO_SUCCESSOR; n];
    // walk backwards, remembering the latest-seen (i.e. next in time) event per pixel
    if float_coordinates {
        let mut next: HashMap<(u32, u32), u32> = HashMap::new();
        for i in (0..n).rev() {
            if let Some(s) = next.insert((x[i].to_bits(), y[i].to_bits()), i as u32) {
                out[i] = s;
            }
        }
    } else {
        // integer coordinates inside the image (checked on reading): one slot per pixel
        let mut next = vec![NO_SUCCESSOR; width as usize * height as usize];
        for i in (0..n).rev() {
            let k = y[i] as usize * width as usize + x[i] as usize;
            out[i] = std::mem::replace(&mut next[k], i as u32);
        }
    }
    out
}

/// The colour-event map of the real Color-DAVIS346 scenes: for each raw sensor pixel, the
/// rectified float coordinate stored in `events.h5`.
#[derive(Clone, Debug, PartialEq)]
pub struct EvMap {
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// `inv_mapx`, row-major (H, W).
    pub inv_mapx: Vec<f32>,
    /// `inv_mapy`, row-major (H, W).
    pub inv_mapy: Vec<f32>,
}

impl EvMap {
    /// Read `dir/ev_map.npz` if present; its arrays must be (height, width).
    pub fn read(dir: &Path, (width, height): (u32, u32)) -> Result<Option<EvMap>, LoadError> {
        let path = dir.join(EV_MAP);
        if !path.is_file() {
            return Ok(None);
        }
        let fix = "write inv_mapx and inv_mapy of shape (H, W) with numpy.savez";
        let arrays = read_npz(&path).map_err(|e| LoadError::unreadable(EV_MAP, e, fix))?;
        let get = |name: &str| -> Result<Vec<f32>, LoadError> {
            let (_, a) = arrays
                .iter()
                .find(|(n, _)| n == name)
                .ok_or_else(|| LoadError::invalid(EV_MAP, name, "missing", fix))?;
            if a.shape() != [height as usize, width as usize] {
                return Err(LoadError::invalid(
                    EV_MAP,
                    name,
                    format!("shape {:?}, expected ({height}, {width})", a.shape()),
                    fix,
                ));
            }
            Ok(a.data().to_f64().into_iter().map(|v| v as f32).collect())
        };
        Ok(Some(EvMap { width, height, inv_mapx: get("inv_mapx")?, inv_mapy: get("inv_mapy")? }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn successors_link_the_next_event_at_the_same_pixel() {
        let x = [1.0, 2.0, 1.0, 1.0, 2.0, 0.0];
        let y = [0.0, 3.0, 0.0, 1.0, 3.0, 0.0];
        let want = [2, 4, NO_SUCCESSOR, NO_SUCCESSOR, NO_SUCCESSOR, NO_SUCCESSOR];
        assert_eq!(successors(&x, &y, (4, 4), false), want);
        assert_eq!(successors(&x, &y, (4, 4), true), want);
    }
}
