//! The EDI prior: a latent sharp image of each blurry training view, solved from the view and the
//! events of its exposure with the Event-based Double Integral (Pan et al. 2019, "Bringing a
//! blurry frame alive at high frame-rate with an event camera"), as Ev-DeblurNeRF uses it: once,
//! before training, as the target of the origin ray's colour (L_EDI).
//!
//! # The model, per pixel
//! - **Linear light.** The simulator fires events on the log of *linear* intensity
//!   (`ln(eps + I)`, `I` the luma of linear RGB) and averages linear radiance over the exposure,
//!   so the EDI is solved in linear light: the blurry display value `y` is linearised with the
//!   response exponent, `B = y^gamma` (gamma 2.2 for the synthetic scenes), and the answer is
//!   encoded back, `sharp = clamp(S, 0, 1)^(1/gamma)` (display-referred, as [`RgbImage`]).
//! - **Bins.** The exposure `[t_s, t_e]` is split into `n` equal bins (`bins`, 8 in the
//!   reference), boundaries `b_k = t_s + k (t_e - t_s) / n`, `k = 0..=n`; `b_{n/2}` is the
//!   mid-exposure time `t_mid` (taken as `t_mid` exactly when the two agree to 1e-6 us).
//! - **Log increments.** `E_k = log I(b_k) - log I(t_mid)`: the sum of `p Theta_p` over the events
//!   with `t_mid < t <= b_k` (`Theta_on` for `p = +1`, `-Theta_off` for `p = -1`), or minus that
//!   sum over `b_k < t <= t_mid` when `b_k < t_mid`. An event at time `t` has already happened at
//!   `t` (intervals are half-open on the left), so only events in `(t_s, t_e]` count.
//! - **Double integral.** The blur is the mean of the latent image at the `n + 1` boundaries,
//!   `B = 1/(n+1) sum_k I(b_k) = I(t_mid)/(n+1) sum_k exp(E_k)`, hence
//!   `S = I(t_mid) = (n + 1) B / sum_k exp(E_k)`, per channel.
//! - **Monochrome events.** One `E` per pixel, applied to all three channels (a brightness change
//!   scales R, G and B alike; the luma ratio stands in for each channel's).
//! - **Bilinear splat.** An event at float `(x, y)` (rectified real data) adds to the four pixels
//!   around it, pixel `(i, j)` (column, row) with weight `(1 - |x - i|)(1 - |y - j|)`; an integer
//!   coordinate lands on its pixel exactly; weight falling outside the image is dropped.
//!
//! # Cache ([`precompute`])
//! One file per view, `cache_dir/view{index:04}.edi`: a header holding every input that decides the
//! image (bins, thresholds, gamma, size, a hash of the view's image, its exposure times, the
//! number of events in the exposure and the first and last of their times), then the image as
//! little-endian f32, then an FNV-1a checksum of all the preceding bytes. A file whose header
//! differs (stale), whose length is wrong (truncated) or whose checksum fails (corrupt) is
//! recomputed and rewritten atomically.
//!
//! The schedule of the loss weight is [`EdiConfig::weight_at`].

use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::data::{Dataset, Events, RgbImage, View};
use crate::error::TrainError;
use crate::metrics::{psnr, ImageRef};

/// Settings and weight schedule of the EDI prior.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdiConfig {
    /// Equal bins the exposure is split into (>= 1; 8 in the reference): more bins follow faster
    /// motion but sample each bin's events more coarsely.
    pub bins: usize,
    /// Loss weight at step 0 (unitless; 0.01 for synthetic data, 1.0 for real data).
    pub weight: f64,
    /// Loss weight from `decay_steps` on (unitless; 1e-5 for synthetic data); equal to `weight`
    /// for a constant weight (real data).
    pub final_weight: f64,
    /// Steps of the cosine decay from `weight` to `final_weight` (10 000 in the reference).
    pub decay_steps: u64,
}

impl EdiConfig {
    /// The reference settings for synthetic scenes: 8 bins, weight 0.01 cosine-decayed to 1e-5
    /// over 10 k steps.
    pub const fn reference_synthetic() -> EdiConfig {
        EdiConfig { bins: 8, weight: 0.01, final_weight: 1e-5, decay_steps: 10_000 }
    }

    /// The reference settings for real scenes: 8 bins, constant weight 1.0.
    pub const fn reference_real() -> EdiConfig {
        EdiConfig { bins: 8, weight: 1.0, final_weight: 1.0, decay_steps: 10_000 }
    }

    /// The loss weight at `step`: `final + (weight - final) (1 + cos(pi step / decay_steps)) / 2`
    /// before `decay_steps`, `final_weight` from then on.
    pub fn weight_at(&self, step: u64) -> f64 {
        if step >= self.decay_steps {
            return self.final_weight;
        }
        let s = step as f64 / self.decay_steps as f64;
        self.final_weight + (self.weight - self.final_weight) * 0.5 * (1.0 + (std::f64::consts::PI * s).cos())
    }

    /// Checks the settings; the message names the field and the fix.
    pub fn validate(&self) -> Result<(), String> {
        if self.bins == 0 {
            return Err("edi.bins is 0; use at least 1 (8 in the reference)".into());
        }
        for (name, v) in [("edi.weight", self.weight), ("edi.final_weight", self.final_weight)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} = {v} is out of range; it must be a finite number >= 0"));
            }
        }
        Ok(())
    }
}

/// Checks the solver's inputs: `bins >= 1`, positive finite thresholds and gamma.
fn check_settings(bins: usize, (theta_on, theta_off): (f64, f64), gamma: f64) -> Result<(), TrainError> {
    if bins == 0 {
        return Err(TrainError::Config("edi: bins is 0; use at least 1 (8 in the reference)".into()));
    }
    for (name, v) in [("threshold (ON)", theta_on), ("threshold (OFF)", theta_off), ("response gamma", gamma)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(TrainError::Config(format!("edi: {name} = {v}; it must be a positive number")));
        }
    }
    Ok(())
}

/// Indices of the events with `t_start < t <= t_end` (binary search on the sorted times).
fn exposure_range(events: &Events, t_start: f64, t_end: f64) -> Range<usize> {
    let lo = events.t_us.partition_point(|&t| t <= t_start);
    let hi = events.t_us.partition_point(|&t| t <= t_end).max(lo);
    lo..hi
}

/// The bin boundaries `b_0..=b_n` of `view`'s exposure (`b_0 = t_s`, `b_n = t_e` exactly, and
/// `b_{n/2} = t_mid` when they agree to 1e-6 us).
fn boundaries(view: &View, bins: usize) -> Vec<f64> {
    let (t_s, t_e) = (view.t_start_us, view.t_end_us);
    let mut b: Vec<f64> = (0..=bins).map(|k| t_s + (t_e - t_s) * k as f64 / bins as f64).collect();
    b[bins] = t_e;
    if bins.is_multiple_of(2) && (b[bins / 2] - view.t_mid_us).abs() <= 1e-6 {
        b[bins / 2] = view.t_mid_us;
    }
    b
}

/// `E_k = log I(b_k) - log I(t_mid)` for every pixel, pixel-major (`(j * width + i) * (bins + 1)
/// + k`), from the events `range` (those of the exposure, sorted by time).
fn log_increments(
    view: &View,
    events: &Events,
    range: Range<usize>,
    (width, height): (u32, u32),
    bins: usize,
    (theta_on, theta_off): (f64, f64),
) -> Vec<f64> {
    let stride = bins + 1;
    let (w, h) = (width as i64, height as i64);
    let b = boundaries(view, bins);
    // per pixel: slots 0..bins hold each bin's increment D_j (events in (b_j, b_{j+1}]), slot
    // `bins` holds M, the increment up to the reference time (events in (t_s, t_mid])
    let mut acc = vec![0.0f64; width as usize * height as usize * stride];
    let mut j = 0;
    for e in range {
        let t = events.t_us[e];
        // events are time-sorted, so the bin only moves forward
        while j + 1 < bins && t > b[j + 1] {
            j += 1;
        }
        let (x, y) = (events.x[e] as f64, events.y[e] as f64);
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        let v = if events.polarity[e] > 0 { theta_on } else { -theta_off };
        let before_mid = t <= view.t_mid_us;
        // bilinear splat onto the four neighbouring pixels
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        for (dx, dy, wt) in
            [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
        {
            let (px, py) = (x0 + dx, y0 + dy);
            if wt == 0.0 || px < 0 || py < 0 || px >= w || py >= h {
                continue;
            }
            let p = (py * w + px) as usize * stride;
            acc[p + j] += wt * v;
            if before_mid {
                acc[p + bins] += wt * v;
            }
        }
    }
    // E_k = C_k - M with C_k = sum_{j < k} D_j the increment from t_s to b_k (in place)
    for px in acc.chunks_exact_mut(stride) {
        let m = px[bins];
        let mut c = 0.0;
        for slot in px.iter_mut() {
            // slot k < bins holds D_k (read before it becomes E_k); the last one held M
            let d = *slot;
            *slot = c - m;
            c += d;
        }
    }
    acc
}

/// The EDI image from the events `range` of `view`'s exposure (sizes and settings checked).
fn solve(
    view: &View,
    events: &Events,
    range: Range<usize>,
    size: (u32, u32),
    bins: usize,
    thresholds: (f64, f64),
    gamma: f64,
) -> RgbImage {
    let e = log_increments(view, events, range, size, bins, thresholds);
    let mut data = Vec::with_capacity(view.image.data.len());
    for (rgb, e_px) in view.image.data.chunks_exact(3).zip(e.chunks_exact(bins + 1)) {
        // S = (n + 1) B / sum_k exp(E_k), in linear light
        let scale = (bins + 1) as f64 / e_px.iter().map(|&e_k| e_k.exp()).sum::<f64>();
        for &y in rgb {
            let blurry_lin = (y.max(0.0) as f64).powf(gamma);
            let sharp_lin = if blurry_lin > 0.0 { blurry_lin * scale } else { 0.0 };
            let sharp_lin = if sharp_lin.is_nan() { 0.0 } else { sharp_lin.clamp(0.0, 1.0) };
            data.push(sharp_lin.powf(1.0 / gamma) as f32);
        }
    }
    RgbImage { width: size.0, height: size.1, data }
}

/// The EDI image of one view from the events of its exposure (display-referred RGB in [0, 1],
/// row-major, `width * height * 3` f32, the layout of [`RgbImage`]). `thresholds` are
/// `(Theta_on, Theta_off)` (log intensity per event), `gamma` the response exponent (2.2 for the
/// synthetic scenes). A sharp view (empty exposure) gets its own image back.
///
/// # Panics
/// If `bins` is 0 or the view's image is not `width x height` ([`precompute`] checks both).
pub fn edi_image(
    view: &View,
    events: &Events,
    width: u32,
    height: u32,
    bins: usize,
    thresholds: (f64, f64),
    gamma: f64,
) -> RgbImage {
    assert!(bins > 0, "edi_image: bins must be at least 1");
    assert_eq!(
        (view.image.width, view.image.height, view.image.data.len()),
        (width, height, 3 * width as usize * height as usize),
        "edi_image: view {} is not {width}x{height}",
        view.name
    );
    let range = exposure_range(events, view.t_start_us, view.t_end_us);
    solve(view, events, range, (width, height), bins, thresholds, gamma)
}

/// FNV-1a (64-bit) offset basis.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a (64-bit) of `bytes`, continuing from `h`.
fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// First bytes of a cache file (format version 1).
const MAGIC: &[u8; 8] = b"EVEDI\x00\x00\x01";

/// The header of a view's cache file: every input that decides its EDI image.
fn cache_header(
    view: &View,
    events: &Events,
    range: &Range<usize>,
    bins: usize,
    (theta_on, theta_off): (f64, f64),
    gamma: f64,
) -> Vec<u8> {
    let image_hash = view.image.data.iter().fold(FNV_OFFSET, |h, v| fnv1a(h, &v.to_bits().to_le_bytes()));
    let (first, last) =
        if range.is_empty() { (0.0, 0.0) } else { (events.t_us[range.start], events.t_us[range.end - 1]) };
    let mut h = MAGIC.to_vec();
    h.extend_from_slice(&(bins as u64).to_le_bytes());
    for v in [theta_on, theta_off, gamma] {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h.extend_from_slice(&view.image.width.to_le_bytes());
    h.extend_from_slice(&view.image.height.to_le_bytes());
    h.extend_from_slice(&image_hash.to_le_bytes());
    for v in [view.t_start_us, view.t_mid_us, view.t_end_us] {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h.extend_from_slice(&(range.len() as u64).to_le_bytes());
    for v in [first, last] {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h
}

/// The image of a cache file with this `header` and `len` values, or `None` if the file is
/// missing, stale, truncated or corrupt.
fn read_cache(path: &Path, header: &[u8], len: usize) -> Option<Vec<f32>> {
    let bytes = std::fs::read(path).ok()?;
    if bytes.len() != header.len() + 4 * len + 8 || !bytes.starts_with(header) {
        return None;
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a(FNV_OFFSET, body).to_le_bytes() != sum {
        return None;
    }
    Some(body[header.len()..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))).collect())
}

/// Writes a cache file: header, values, checksum.
fn write_cache(path: &Path, header: &[u8], data: &[f32]) -> Result<(), TrainError> {
    let mut bytes = Vec::with_capacity(header.len() + 4 * data.len() + 8);
    bytes.extend_from_slice(header);
    for v in data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let sum = fnv1a(FNV_OFFSET, &bytes);
    bytes.extend_from_slice(&sum.to_le_bytes());
    simulator::image_io::write_atomic(path, &bytes).map_err(|e| {
        TrainError::run(
            path,
            format!("cannot write the EDI cache: {e:#}"),
            "free disk space or choose another cache folder",
        )
    })
}

/// The cache file of view `index`.
fn cache_path(cache_dir: &Path, index: usize) -> PathBuf {
    cache_dir.join(format!("view{index:04}.edi"))
}

/// [`precompute`], also returning how many images were computed (not read from the cache).
fn precompute_counted(
    data: &Dataset,
    views: &[usize],
    bins: usize,
    thresholds: (f64, f64),
    gamma: f64,
    cache_dir: &Path,
) -> Result<(Vec<RgbImage>, usize), TrainError> {
    check_settings(bins, thresholds, gamma)?;
    let size = (data.intrinsics.width, data.intrinsics.height);
    for &i in views {
        let view = data.views.get(i).ok_or_else(|| {
            TrainError::Config(format!("edi: view index {i} is out of range ({} views)", data.views.len()))
        })?;
        let img = &view.image;
        if (img.width, img.height) != size || img.data.len() != 3 * size.0 as usize * size.1 as usize {
            return Err(TrainError::Config(format!(
                "edi: view {} is {}x{} ({} values), the dataset {}x{}; write every image at the dataset's size",
                view.name,
                img.width,
                img.height,
                img.data.len(),
                size.0,
                size.1
            )));
        }
    }
    std::fs::create_dir_all(cache_dir)
        .map_err(|e| TrainError::io(cache_dir, e, "create the EDI cache folder or choose another one"))?;
    let done: Vec<(RgbImage, bool)> = views
        .par_iter()
        .map(|&i| {
            let view = &data.views[i];
            let range = exposure_range(&data.events, view.t_start_us, view.t_end_us);
            let header = cache_header(view, &data.events, &range, bins, thresholds, gamma);
            let path = cache_path(cache_dir, i);
            if let Some(cached) = read_cache(&path, &header, view.image.data.len()) {
                return Ok((RgbImage { width: size.0, height: size.1, data: cached }, false));
            }
            let img = solve(view, &data.events, range, size, bins, thresholds, gamma);
            write_cache(&path, &header, &img.data)?;
            Ok((img, true))
        })
        .collect::<Result<_, TrainError>>()?;
    let computed = done.iter().filter(|(_, c)| *c).count();
    Ok((done.into_iter().map(|(img, _)| img).collect(), computed))
}

/// EDI images of `views` (indices into `data.views`), in that order, computed in parallel (the
/// result does not depend on the thread count) and cached in `cache_dir` (created if missing;
/// one file per view, see the module doc): a cached image is reused only if every input matches,
/// otherwise it is recomputed and rewritten atomically. `thresholds` are `(Theta_on, Theta_off)`,
/// `gamma` the response exponent. Errors on bad settings, an index out of range, an image of
/// another size, or a cache folder that cannot be created or written.
pub fn precompute(
    data: &Dataset,
    views: &[usize],
    bins: usize,
    thresholds: (f64, f64),
    gamma: f64,
    cache_dir: &Path,
) -> Result<Vec<RgbImage>, TrainError> {
    precompute_counted(data, views, bins, thresholds, gamma, cache_dir).map(|(images, _)| images)
}

/// Mean PSNRs against the sharp images (for reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdiScore {
    /// Views scored.
    pub views: usize,
    /// Mean PSNR (dB) of the blurry views against their sharp images.
    pub blurry_psnr: f64,
    /// Mean PSNR (dB) of the EDI images against the sharp images.
    pub edi_psnr: f64,
}

/// Scores the EDI images `edi` of `views` (as [`precompute`] returns them) and the blurry views
/// against the views' sharp images; `None` if a view has no sharp image, the lengths differ, a
/// size differs or `views` is empty.
pub fn psnr_vs_sharp(data: &Dataset, views: &[usize], edi: &[RgbImage]) -> Option<EdiScore> {
    if views.is_empty() || views.len() != edi.len() {
        return None;
    }
    let (mut blurry_sum, mut edi_sum) = (0.0, 0.0);
    for (&i, img) in views.iter().zip(edi) {
        let view = data.views.get(i)?;
        let sharp = ImageRef::try_from(view.sharp.as_ref()?).ok()?;
        blurry_sum += psnr(sharp, ImageRef::try_from(&view.image).ok()?).ok()?;
        edi_sum += psnr(sharp, ImageRef::try_from(img).ok()?).ok()?;
    }
    let n = views.len() as f64;
    Some(EdiScore { views: views.len(), blurry_psnr: blurry_sum / n, edi_psnr: edi_sum / n })
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;
    use std::time::Instant;

    use glam::{DMat3, DQuat, DVec3};
    use simulator::dataset::check::TestViewPolicy;
    use simulator::trajectory::Pose;

    use super::*;
    use crate::data::events::NO_SUCCESSOR;
    use crate::data::world::WorldTransform;
    use crate::data::{DenseTrajectory, Intrinsics, LoadOptions, Split};

    const GAMMA: f64 = 2.2;

    fn pose() -> Pose {
        Pose { rotation: DQuat::IDENTITY, position: DVec3::ZERO }
    }

    /// A view of `image` exposed over `[t_start, t_end]` (us), mid-time at the centre.
    fn view(image: RgbImage, t_start: f64, t_end: f64) -> View {
        View {
            name: "v.png".into(),
            image,
            sharp: None,
            pose: pose(),
            near: 1.0,
            far: 10.0,
            t_mid_us: 0.5 * (t_start + t_end),
            t_start_us: t_start,
            t_end_us: t_end,
        }
    }

    /// Events from `(x, y, t_us, polarity)`, in the given (time) order.
    fn events(list: &[(f32, f32, f64, i8)]) -> Events {
        Events {
            x: list.iter().map(|e| e.0).collect(),
            y: list.iter().map(|e| e.1).collect(),
            t_us: list.iter().map(|e| e.2).collect(),
            polarity: list.iter().map(|e| e.3).collect(),
            successors: vec![NO_SUCCESSOR; list.len()],
            ..Events::default()
        }
    }

    /// A dataset of `views` and `events` (`width x height`); nothing else is used by the EDI.
    fn dataset(views: Vec<View>, events: Events, width: u32, height: u32) -> Dataset {
        let train = (0..views.len()).collect();
        Dataset {
            dir: PathBuf::from("edi-test"),
            intrinsics: Intrinsics { width, height, focal: 10.0 },
            views,
            split: Split { policy: TestViewPolicy::Every8, train, test: vec![] },
            trajectory: DenseTrajectory::new(vec![0.0, 1e7], &[pose(), pose()]).unwrap(),
            events,
            ev_map: None,
            transform: WorldTransform { scale: 1.0, avg_rotation: DMat3::IDENTITY, avg_center: DVec3::ZERO },
            warnings: vec![],
            manifest: None,
        }
    }

    /// A fresh temporary folder.
    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("evblur-edi-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    // The analytic scene: a 2x1 image exposed over [1000, 1800] us, 8 bins (boundaries every
    // 100 us, t_mid = 1400). Pixel 0 changes by the events below (on boundaries, at t_mid, at
    // t_s and t_e, two at one time); pixel 1 has none.
    const T_S: f64 = 1000.0;
    const T_E: f64 = 1800.0;
    const THETA: (f64, f64) = (0.3, 0.2);
    const PIXEL0: [(f64, i8); 11] = [
        (1000.0, 1),
        (1050.0, 1),
        (1100.0, -1),
        (1230.0, 1),
        (1400.0, 1),
        (1401.0, -1),
        (1555.0, 1),
        (1555.0, 1),
        (1700.0, -1),
        (1799.0, 1),
        (1800.0, -1),
    ];
    /// Linear mid-exposure intensity of pixel 0 and its colour.
    const I_MID: f64 = 0.37;
    const COLOUR: [f64; 3] = [1.0, 0.5, 0.25];
    /// Display value of pixel 1 (no events).
    const STILL: f32 = 0.6;

    /// Pixel 0's log intensity at `t`, up to a constant: the sum of `p Theta` over the events
    /// at or before `t` (independent of the solver's bookkeeping).
    fn log_i(t: f64) -> f64 {
        PIXEL0.iter().filter(|e| e.0 <= t).map(|e| if e.1 > 0 { THETA.0 } else { -THETA.1 }).sum()
    }

    /// The analytic scene's view: blurry = mean of the latent intensity at the 9 boundaries.
    fn analytic_view() -> View {
        let t_mid = 0.5 * (T_S + T_E);
        let lin: f64 = (0..=8).map(|k| I_MID * (log_i(T_S + 100.0 * k as f64) - log_i(t_mid)).exp()).sum::<f64>() / 9.0;
        let mut data: Vec<f32> = COLOUR.iter().map(|c| (c * lin).powf(1.0 / GAMMA) as f32).collect();
        data.extend([STILL; 3]);
        view(RgbImage { width: 2, height: 1, data }, T_S, T_E)
    }

    fn analytic_events() -> Events {
        events(&PIXEL0.map(|(t, p)| (0.0, 0.0, t, p)))
    }

    #[test]
    fn recovers_the_mid_exposure_intensity_of_an_analytic_scene() {
        let img = edi_image(&analytic_view(), &analytic_events(), 2, 1, 8, THETA, GAMMA);
        for (c, colour) in COLOUR.iter().enumerate() {
            let want = (colour * I_MID).powf(1.0 / GAMMA);
            assert!((img.data[c] as f64 - want).abs() < 1e-5, "channel {c}: {} vs {want}", img.data[c]);
            assert!((img.data[3 + c] - STILL).abs() < 1e-6, "a still pixel keeps its value");
        }
        // the blurry pixel differs from the answer by far more than the tolerance
        assert!((analytic_view().image.data[0] as f64 - I_MID.powf(1.0 / GAMMA)).abs() > 1e-2);
    }

    #[test]
    fn events_outside_the_exposure_are_ignored() {
        let inside = analytic_events();
        let mut list = vec![(0.0, 0.0, 500.0, 1), (1.0, 0.0, 999.5, -1), (1.0, 0.0, T_S, 1)];
        list.extend(PIXEL0.map(|(t, p)| (0.0f32, 0.0f32, t, p)));
        list.extend([(0.0, 0.0, T_E + 1e-3, 1), (1.0, 0.0, 2500.0, -1)]);
        let all = events(&list);
        let v = analytic_view();
        assert_eq!(edi_image(&v, &inside, 2, 1, 8, THETA, GAMMA), edi_image(&v, &all, 2, 1, 8, THETA, GAMMA));
        // a sharp view (empty exposure) keeps its image
        let sharp = view(v.image.clone(), T_S, T_S);
        let img = edi_image(&sharp, &all, 2, 1, 8, THETA, GAMMA);
        for (a, b) in img.data.iter().zip(&v.image.data) {
            assert!((a - b).abs() < 1e-6);
        }
    }

    #[test]
    fn float_events_splat_bilinearly() {
        let (w, h) = (4u32, 3u32);
        let v = view(RgbImage { width: w, height: h, data: vec![0.5; 36] }, 0.0, 200.0);
        let ev = events(&[
            (3.0, 2.0, 50.0, -1),  // integer, before t_mid: E_0 = +0.2 at (3, 2)
            (1.25, 0.5, 150.0, 1), // interior float: four pixels, E_2
            (3.5, 2.5, 160.0, 1),  // corner: only (3, 2) is inside, weight 1/4
            (-0.5, 0.0, 170.0, 1), // left border: only (0, 0), weight 1/2
        ]);
        let range = exposure_range(&ev, 0.0, 200.0);
        let e = log_increments(&v, &ev, range, (w, h), 2, (0.4, 0.2));
        let mut want = vec![0.0; 12 * 3];
        let mut set = |i: usize, j: usize, k: usize, value: f64| want[(j * 4 + i) * 3 + k] += value;
        set(3, 2, 0, 0.2);
        for (i, j, wt) in [(1, 0, 0.375), (2, 0, 0.125), (1, 1, 0.375), (2, 1, 0.125)] {
            set(i, j, 2, wt * 0.4);
        }
        set(3, 2, 2, 0.25 * 0.4);
        set(0, 0, 2, 0.5 * 0.4);
        for (k, (a, b)) in e.iter().zip(&want).enumerate() {
            assert!((a - b).abs() < 1e-12, "pixel {}, boundary {}: {a} vs {b}", k / 3, k % 3);
        }
    }

    /// Three 8x6 views, 40 000 events, integer and float coordinates.
    fn cache_dataset() -> Dataset {
        let (w, h) = (8u32, 6u32);
        let image = |s: f32| RgbImage {
            width: w,
            height: h,
            data: (0..w * h * 3).map(|k| 0.1 + 0.8 * ((k as f32 * 0.37 + s).sin() * 0.5 + 0.5)).collect(),
        };
        let views =
            vec![view(image(0.0), 0.0, 400.0), view(image(1.0), 500.0, 900.0), view(image(2.0), 1000.0, 1400.0)];
        let mut state = 12345u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) as f32 / (1u64 << 31) as f32
        };
        let list: Vec<_> = (0..40_000)
            .map(|i| {
                let (x, y) = ((next() * 8.0).floor(), (next() * 6.0).floor());
                let (x, y) = if i % 3 == 0 { (x + next(), y + next() - 0.5) } else { (x, y) };
                (x, y, i as f64 * 0.04, if next() < 0.5 { 1 } else { -1 })
            })
            .collect();
        dataset(views, events(&list), w, h)
    }

    #[test]
    fn precompute_caches_and_recomputes_stale_or_damaged_files() {
        let mut data = cache_dataset();
        let dir = temp("cache");
        let all = [0, 1, 2];
        let run = |data: &Dataset, theta| precompute_counted(data, &all, 8, theta, GAMMA, &dir).unwrap();
        let (first, n) = run(&data, (0.2, 0.2));
        assert_eq!(n, 3);
        for (&i, img) in all.iter().zip(&first) {
            assert_eq!(img, &edi_image(&data.views[i], &data.events, 8, 6, 8, (0.2, 0.2), GAMMA));
        }
        // the second call reads every file
        assert_eq!(run(&data, (0.2, 0.2)), (first.clone(), 0));
        // other thresholds: recomputed, different images; back again: recomputed
        let (other, n) = run(&data, (0.25, 0.2));
        assert_eq!(n, 3);
        assert_ne!(other, first);
        assert_eq!(run(&data, (0.2, 0.2)), (first.clone(), 3));
        // a truncated file, a flipped byte, a garbage file: each recomputed, never a panic
        let file = |i| cache_path(&dir, i);
        let bytes = std::fs::read(file(1)).unwrap();
        std::fs::write(file(1), &bytes[..bytes.len() / 2]).unwrap();
        assert_eq!(run(&data, (0.2, 0.2)), (first.clone(), 1));
        let mut bytes = std::fs::read(file(2)).unwrap();
        let k = bytes.len() - 100;
        bytes[k] ^= 0x10;
        std::fs::write(file(2), &bytes).unwrap();
        assert_eq!(run(&data, (0.2, 0.2)), (first.clone(), 1));
        std::fs::write(file(0), b"EVEDI").unwrap();
        assert_eq!(run(&data, (0.2, 0.2)), (first.clone(), 1));
        // stale inputs: an image, an exposure, the events of one exposure
        data.views[1].image.data[5] += 0.01;
        assert_eq!(run(&data, (0.2, 0.2)).1, 1);
        data.views[2].t_end_us += 1.0;
        assert_eq!(run(&data, (0.2, 0.2)).1, 1);
        let drop = data.events.t_us.partition_point(|&t| t <= 200.0);
        for col in [&mut data.events.x, &mut data.events.y] {
            col.remove(drop);
        }
        data.events.t_us.remove(drop);
        data.events.polarity.remove(drop);
        assert_eq!(run(&data, (0.2, 0.2)).1, 1);
        assert_eq!(run(&data, (0.2, 0.2)).1, 0);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn precompute_is_independent_of_the_thread_count() {
        let data = cache_dataset();
        let with = |threads: usize| {
            let dir = temp(&format!("threads{threads}"));
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let out = pool.install(|| precompute(&data, &[2, 0, 1], 8, (0.2, 0.3), GAMMA, &dir).unwrap());
            let _ = std::fs::remove_dir_all(&dir);
            out
        };
        let one = with(1);
        assert_eq!(one, with(3));
        assert_eq!(one[0], edi_image(&data.views[2], &data.events, 8, 6, 8, (0.2, 0.3), GAMMA));
    }

    #[test]
    fn precompute_refuses_bad_settings() {
        let data = cache_dataset();
        let dir = temp("refuse");
        let err = |views: &[usize], bins, theta, gamma, dir: &Path| {
            precompute(&data, views, bins, theta, gamma, dir).unwrap_err().to_string()
        };
        assert!(err(&[0], 0, (0.2, 0.2), GAMMA, &dir).contains("bins"));
        assert!(err(&[0], 8, (0.0, 0.2), GAMMA, &dir).contains("threshold"));
        assert!(err(&[0], 8, (0.2, 0.2), f64::NAN, &dir).contains("gamma"));
        assert!(err(&[3], 8, (0.2, 0.2), GAMMA, &dir).contains("out of range"));
        // a cache "folder" that is a file
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("file");
        std::fs::write(&file, b"x").unwrap();
        assert!(err(&[0], 8, (0.2, 0.2), GAMMA, &file).contains("cache"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn weight_schedule_decays_by_a_half_cosine() {
        let c = EdiConfig::reference_synthetic();
        assert_eq!(c.weight_at(0), 0.01);
        assert!((c.weight_at(5_000) - 0.5 * (0.01 + 1e-5)).abs() < 1e-15);
        assert!(c.weight_at(2_500) > c.weight_at(2_501));
        assert_eq!(c.weight_at(10_000), 1e-5);
        assert_eq!(c.weight_at(30_000), 1e-5);
        let r = EdiConfig::reference_real();
        assert!([0, 1, 5_000, 10_000, 30_000].iter().all(|&s| r.weight_at(s) == 1.0));
        assert!(c.validate().is_ok() && r.validate().is_ok());
        assert!(EdiConfig { bins: 0, ..c.clone() }.validate().unwrap_err().contains("bins"));
        assert!(EdiConfig { weight: -1.0, ..c.clone() }.validate().unwrap_err().contains("edi.weight"));
        let toml = "bins = 8\nweight = 0.01\nfinal_weight = 1e-5\ndecay_steps = 10000\n";
        assert_eq!(toml::from_str::<EdiConfig>(toml).unwrap(), c);
        assert!(toml::from_str::<EdiConfig>(&format!("{toml}extra = 1\n")).is_err());
    }

    /// EDI vs blurry PSNR against the sharp images on our factory scene (300x200, threshold
    /// 0.2, gamma 2.2); the folder is `$EVBLUR_FACTORY300` or `/work/data/factory300`.
    #[test]
    #[ignore = "needs /work/data/factory300 (26 M events): cargo test --release edi -- --ignored --nocapture"]
    fn factory300_edi_psnr() {
        let dir = std::env::var_os("EVBLUR_FACTORY300")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("/work/data/factory300"));
        if !dir.is_dir() {
            eprintln!("{}: no dataset, skipped", dir.display());
            return;
        }
        let t = Instant::now();
        let data = Dataset::load(&dir, &LoadOptions::default()).unwrap();
        println!(
            "loaded {} views, {} events in {:.1} s",
            data.views.len(),
            data.events.len(),
            t.elapsed().as_secs_f64()
        );
        let train = data.split.train.clone();
        let cache = temp("factory300");
        for (bins, gamma) in [(8, 2.2), (8, 1.0), (16, 2.2)] {
            let t = Instant::now();
            let (imgs, n) = precompute_counted(&data, &train, bins, (0.2, 0.2), gamma, &cache).unwrap();
            let computed = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let (_, cached) = precompute_counted(&data, &train, bins, (0.2, 0.2), gamma, &cache).unwrap();
            let read = t.elapsed().as_secs_f64();
            assert_eq!((n, cached), (train.len(), 0));
            let s = psnr_vs_sharp(&data, &train, &imgs).unwrap();
            println!(
                "bins {bins:2}, gamma {gamma}: {} training views, blurry {:.2} dB, EDI {:.2} dB \
                 (computed in {computed:.2} s, read from the cache in {read:.2} s)",
                s.views, s.blurry_psnr, s.edi_psnr
            );
            if gamma == GAMMA {
                assert!(s.edi_psnr > s.blurry_psnr + 3.0, "the EDI images should be much sharper than the views");
            }
        }
        let _ = std::fs::remove_dir_all(&cache);
    }
}
