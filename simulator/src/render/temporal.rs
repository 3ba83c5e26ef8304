//! Temporal reuse for a rendered frame sequence: before the spatial filter
//! ([`super::denoise`]), each frame averages in the lighting its neighbours saw at the same
//! surface points (the temporal half of SVGF, Schied et al. 2017, made symmetric because a
//! dataset renders the whole sequence before anything needs a frame).
//!
//! For every pixel of the centre frame, its first-hit point (camera ray times mean hit
//! distance) is projected into each neighbour within `radius` frames with the neighbour's own
//! camera; the neighbour's demodulated irradiance ([`Features::irradiance`]) is read
//! bilinearly from the taps whose hit distance (within `depth_tolerance`, relative) and normal
//! (dot at least `min_normal_dot`) show the same surface (and both or neither see an emitter).
//! Every frame of the window weighs the same (a box: the most noise removed per neighbour read;
//! being symmetric, it does not delay a static scene's lighting).
//! Only reflected light is averaged: what the camera rays see directly (emitters, the sky;
//! [`Features::emission`]) is taken out first and the centre's own added back.
//! The result is remodulated with the centre frame's reflectance, so texture stays sharp; the
//! variance guide of the spatial filter becomes the variance of the weighted mean.
//!
//! Why it matters: path-tracing noise that changes from frame to frame fires false events. A
//! fixed sample pattern keeps most of a pixel's estimate steady, but as the camera moves,
//! secondary and shadow rays cross visibility edges and the estimate jumps; neighbours'
//! reprojected pixels carry independent samples, so averaging them removes such jumps where a
//! single frame's spatial filter cannot tell them from real lighting edges.
//!
//! Reading every neighbour costs a reprojection per neighbour and pixel (about 0.3 s per
//! 600x400 frame at radius 32 on 2 cores; the dataset reads every second one by default,
//! `[dataset] temporal_stride`). Merging runs of 8 frames once into the grid of their
//! first and reading the merged blocks was measured and not adopted: it cut that to 0.13 s but
//! raised the noise-induced events (factory at 300x200, radius 16, 4 spp: 16.6% -> 17.9%, and
//! 19.0% reading only blocks): two bilinear reads blur the lighting and what a block's first
//! frame does not see is lost to it.
//!
//! Reprojection assumes a static scene (only the camera moves) and view-independent shading at
//! the first hit: glossy highlights are averaged over the window (±32 ms at the dataset default
//! and 1000 FPS), a slight temporal blur. Like the spatial filter, the result is a pure function
//! of its inputs: the same bytes whatever the thread count.

use exr::prelude::f16;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::integrator::Features;
use crate::base::colour::luminance;
use crate::base::image::Image;
use crate::scene::Camera;

/// One rendered frame of a sequence, kept compact: its camera, the per-pixel record a window
/// reads of it ([`Tap`]: lighting, variance, normal, distance) and, while it may still be a
/// window's centre, its reflectance, directly seen light and raw render in half floats (the
/// filtered output is rounded to halves anyway). About 46 bytes a pixel (11 MB at 600x400),
/// 28 once reduced to a neighbour ([`SequenceFrame::keep_neighbour_data`]).
#[derive(Clone, Debug)]
pub struct SequenceFrame {
    camera: Camera,
    width: u32,
    height: u32,
    taps: Vec<Tap>,
    albedo: Vec<Half3>,
    emission: Vec<Half3>,
    raw: Vec<Half3>,
}

/// Three half floats.
type Half3 = [f16; 3];

#[inline]
fn to_half3(v: Vec3) -> Half3 {
    [f16::from_f32(v.x), f16::from_f32(v.y), f16::from_f32(v.z)]
}

#[inline]
fn from_half3(h: Half3) -> Vec3 {
    Vec3::new(h[0].to_f32(), h[1].to_f32(), h[2].to_f32())
}

/// What the window reads of a neighbour's pixel: demodulated irradiance (half floats), its
/// variance over the squared reflectance luminance, and the normal and hit distance of the
/// surface, the distance negated when the camera ray sees an emitter (distances are positive).
/// 28 bytes.
#[derive(Clone, Copy, Debug)]
struct Tap {
    irradiance: Half3,
    variance: f32,
    normal: Vec3,
    signed_depth: f32,
}

impl Tap {
    #[inline]
    fn irradiance(&self) -> Vec3 {
        from_half3(self.irradiance)
    }
}

/// One input of [`gather_sources`]: a neighbouring frame ([`SequenceFrame::source`]).
#[derive(Clone, Copy)]
pub struct Source<'a> {
    camera: &'a Camera,
    taps: &'a [Tap],
}

impl SequenceFrame {
    /// A frame rendered with `camera`: the path tracer's (unfiltered) image and the first-hit
    /// buffers of the same render. Panics if their sizes differ (a programming error).
    pub fn new(camera: Camera, image: &Image, features: &Features) -> SequenceFrame {
        let (w, h) = (features.width, features.height);
        assert!(image.width == w && image.height == h, "image and features of different renders");
        let f = features;
        let taps = (0..f.depth.len())
            .into_par_iter()
            .map(|t| {
                let la = luminance(f.albedo[t].max(Vec3::splat(MIN_ALBEDO))).max(MIN_ALBEDO);
                let emissive = f.emission[t] != Vec3::ZERO;
                Tap {
                    irradiance: to_half3(f.irradiance[t]),
                    variance: f.variance[t] / (la * la),
                    normal: f.normal[t],
                    signed_depth: if emissive { -f.depth[t] } else { f.depth[t] },
                }
            })
            .collect();
        let halves = |v: &[Vec3]| v.par_iter().map(|&c| to_half3(c)).collect();
        SequenceFrame {
            camera,
            width: w,
            height: h,
            taps,
            albedo: halves(&f.albedo),
            emission: halves(&f.emission),
            raw: halves(&image.pixels),
        }
    }

    /// The camera the frame was rendered with.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The path tracer's (unfiltered) image, as kept (halves; no pixels once reduced to a
    /// neighbour).
    pub fn image(&self) -> Image {
        Image { width: self.width, height: self.height, pixels: self.raw.iter().map(|&h| from_half3(h)).collect() }
    }

    /// The first-hit buffers as kept: reflectance and emission in halves, the demodulated
    /// irradiance in halves, normal, distance and variance as rendered. Panics once the frame is
    /// reduced to a neighbour (a programming error).
    pub fn features(&self) -> Features {
        assert!(self.albedo.len() == self.taps.len(), "a frame reduced to a neighbour has no features");
        let albedo: Vec<Vec3> = self.albedo.iter().map(|&h| from_half3(h)).collect();
        let variance = self
            .taps
            .iter()
            .zip(&albedo)
            .map(|(t, a)| {
                let la = luminance(a.max(Vec3::splat(MIN_ALBEDO))).max(MIN_ALBEDO);
                t.variance * (la * la)
            })
            .collect();
        Features {
            width: self.width,
            height: self.height,
            normal: self.taps.iter().map(|t| t.normal).collect(),
            depth: self.taps.iter().map(|t| t.signed_depth.abs()).collect(),
            irradiance: self.taps.iter().map(|t| t.irradiance()).collect(),
            emission: self.emission.iter().map(|&h| from_half3(h)).collect(),
            variance,
            albedo,
            samples: 0,
        }
    }

    /// Keep only what [`gather`] reads of a *neighbour* (the camera and the packed records) and
    /// free the rest: for a frame that will not be a window's centre again.
    pub fn keep_neighbour_data(&mut self) {
        for v in [&mut self.albedo, &mut self.emission, &mut self.raw] {
            *v = Vec::new();
        }
    }

    /// The frame as an input of [`gather_sources`].
    pub fn source(&self) -> Source<'_> {
        Source { camera: &self.camera, taps: &self.taps }
    }
}

/// Settings of the temporal window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemporalParams {
    /// Frames on each side averaged into a frame (0 = none).
    pub radius: usize,
    /// Largest relative difference of hit distances for a neighbour's tap to count as the same
    /// surface.
    pub depth_tolerance: f32,
    /// Smallest dot product of the normals for a neighbour's tap to count as the same surface.
    pub min_normal_dot: f32,
}

impl Default for TemporalParams {
    fn default() -> TemporalParams {
        TemporalParams { radius: 4, depth_tolerance: 0.03, min_normal_dot: 0.9 }
    }
}

/// Largest supported radius (a window of 65 frames held in memory).
pub const MAX_RADIUS: usize = 64;

impl TemporalParams {
    /// Check the settings; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<(), String> {
        if self.radius > MAX_RADIUS {
            return Err(format!("radius = {} must be at most {MAX_RADIUS} frames", self.radius));
        }
        if !(self.depth_tolerance > 0.0 && self.depth_tolerance < 1.0) {
            return Err(format!("depth_tolerance = {} must be in (0, 1)", self.depth_tolerance));
        }
        if !(self.min_normal_dot > -1.0 && self.min_normal_dot <= 1.0) {
            return Err(format!("min_normal_dot = {} must be in (-1, 1]", self.min_normal_dot));
        }
        Ok(())
    }
}

/// Smallest reflectance divided out (as in the spatial filter).
const MIN_ALBEDO: f32 = 1e-3;

/// The centre frame `window[center]` with its neighbours' lighting averaged in (see the
/// [module docs](self)); `window` holds consecutive frames, at most `radius` on each side of the
/// centre (fewer at the ends of a sequence). Returns the image and the features to give the
/// spatial filter (the centre's, with the variance of the weighted mean). Panics if the frames'
/// sizes differ (a programming error).
pub fn gather(window: &[&SequenceFrame], center: usize, p: &TemporalParams) -> (Image, Features) {
    let sources: Vec<Source> = window
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != center && j.abs_diff(center) <= p.radius)
        .map(|(_, f)| f.source())
        .collect();
    gather_sources(window[center], &sources, p)
}

/// [`gather`] from any list of neighbours: `centre`'s lighting with that of `sources` averaged
/// in, each weighing as much as the centre. Panics if the sizes differ (a
/// programming error).
pub fn gather_sources(centre: &SequenceFrame, sources: &[Source], p: &TemporalParams) -> (Image, Features) {
    let (w, h) = (centre.width, centre.height);
    let n = (w * h) as usize;
    assert!(sources.iter().all(|s| s.taps.len() == n), "frames of different sizes");
    let own = centre.source();
    let mut pixels = vec![Vec3::ZERO; n];
    let mut variance = vec![0.0f32; n];
    let mut irradiance = vec![Vec3::ZERO; n];
    let fk = centre.features();
    let band = BAND_ROWS * w as usize;
    pixels
        .par_chunks_mut(band)
        .zip(variance.par_chunks_mut(band))
        .zip(irradiance.par_chunks_mut(band))
        .enumerate()
        .for_each(|(b, ((px, px_var), px_irr))| {
            let start = b * band;
            let sums = accumulate_band(&own, sources, p, w, h, start / w as usize, px.len() / w as usize);
            for (k, (sum, var, wsum)) in sums.into_iter().enumerate() {
                let i = start + k;
                let la = luminance(fk.albedo[i].max(Vec3::splat(MIN_ALBEDO))).max(MIN_ALBEDO);
                px_irr[k] = sum / wsum;
                px[k] = px_irr[k] * fk.albedo[i] + fk.emission[i];
                px_var[k] = var / (wsum * wsum) * la * la;
            }
        });
    let features = Features { variance, irradiance, ..fk };
    (Image { width: w, height: h, pixels }, features)
}

/// Rows gathered together: a source's image rows that neighbouring rows of the centre read
/// (a bilinear read spans two) are then still in the cache.
const BAND_ROWS: usize = 8;

/// Rows `y0..y0 + rows` of the window: per pixel of `centre` (a `w` x `h` frame), its own
/// weighted sums plus those `sources` hold at the same surface point: (irradiance, variance
/// with the weights squared, weight).
fn accumulate_band(
    centre: &Source,
    sources: &[Source],
    p: &TemporalParams,
    w: u32,
    h: u32,
    y0: usize,
    rows: usize,
) -> Vec<(Vec3, f32, f32)> {
    let wu = w as usize;
    let n = wu * rows;
    let origin = centre.camera.origin();
    let taps = &centre.taps[y0 * wu..y0 * wu + n];
    // the band's first-hit points, one plane per coordinate (so the projections vectorise)
    let mut point = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    for (k, tap) in taps.iter().enumerate() {
        let (x, y) = (k % wu, y0 + k / wu);
        let dir = centre.camera.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), w, h);
        let pt = origin + dir * tap.signed_depth.abs();
        (point[0][k], point[1][k], point[2][k]) = (pt.x, pt.y, pt.z);
    }
    let mut sums: Vec<(Vec3, f32, f32)> = taps.iter().map(|t| (t.irradiance(), t.variance, 1.0)).collect();
    // per source: where each point lands in its image (pixel-centre coordinates) and how far
    // it is from its camera
    let (mut qx, mut qy, mut dist) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    let (wf, hf) = (w as f32, h as f32);
    // one source at a time over the whole band (each pixel still adds its sources in order, so
    // the sums are those of a per-pixel loop): a few memory streams at a time
    for src in sources {
        let origin_j = src.camera.origin();
        let projector = src.camera.projector(w, h);
        // the projections, without branches; NaN marks a point behind the camera
        for (k, ((qx, qy), dist)) in qx.iter_mut().zip(qy.iter_mut()).zip(dist.iter_mut()).enumerate() {
            let pt = Vec3::new(point[0][k], point[1][k], point[2][k]);
            let q = projector.project_or_nan(pt);
            (*qx, *qy) = (q.x - 0.5, q.y - 0.5);
            *dist = (pt - origin_j).length();
        }
        for (k, (sum, var, wsum)) in sums.iter_mut().enumerate() {
            let (qx, qy, dist) = (qx[k], qy[k], dist[k]);
            // entirely outside the source's image (NaN included): nothing to read
            if !(qx > -1.0 && qy > -1.0 && qx < wf && qy < hf) {
                continue;
            }
            let (normal, emissive) = (taps[k].normal, taps[k].signed_depth < 0.0);
            let tolerance = p.depth_tolerance * dist;
            let (x0, y0) = (qx.floor(), qy.floor());
            let (fx, fy) = (qx - x0, qy - y0);
            let bilinear = [(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy];
            let (x0, y0) = (x0 as i64, y0 as i64);
            // the four taps' indices (None: off the image)
            let index = |dx: i64, dy: i64| {
                let (tx, ty) = (x0 + dx, y0 + dy);
                (tx >= 0 && ty >= 0 && tx < w as i64 && ty < h as i64).then(|| (ty as u32 * w + tx as u32) as usize)
            };
            let indices = if x0 >= 0 && y0 >= 0 && x0 + 1 < w as i64 && y0 + 1 < h as i64 {
                let i = (y0 as u32 * w + x0 as u32) as usize;
                [Some(i), Some(i + 1), Some(i + wu), Some(i + wu + 1)]
            } else {
                [index(0, 0), index(1, 0), index(0, 1), index(1, 1)]
            };
            for (i, bilinear) in indices.into_iter().zip(bilinear) {
                let Some(i) = i else { continue };
                if bilinear <= 0.0 {
                    continue;
                }
                let tap = &src.taps[i];
                if (tap.signed_depth.abs() - dist).abs() > tolerance
                    || tap.normal.dot(normal) < p.min_normal_dot
                    || (tap.signed_depth < 0.0) != emissive
                {
                    continue;
                }
                *sum += tap.irradiance() * bilinear;
                *var += tap.variance * bilinear * bilinear;
                *wsum += bilinear;
            }
        }
    }
    sums
}

#[cfg(test)]
#[path = "temporal_tests.rs"]
mod tests;
