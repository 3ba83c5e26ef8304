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
//! Reprojection assumes a static scene (only the camera moves) and view-independent shading at
//! the first hit: glossy highlights are averaged over the window (±32 ms at the dataset default
//! and 1000 FPS), a slight temporal blur. Like the spatial filter, the result is a pure function
//! of its inputs: the same bytes whatever the thread count.

use std::sync::OnceLock;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::film::Image;
use super::integrator::{luminance, Features};
use crate::scene::Camera;

/// One rendered frame of a sequence: its camera, image and first-hit features.
///
/// It also keeps, built on first use and dropped when the features are changed, the packed
/// per-pixel record [`gather`] reads from neighbour frames (one 32-byte record per pixel instead
/// of six separate buffers).
#[derive(Clone, Debug)]
pub struct SequenceFrame {
    camera: Camera,
    image: Image,
    features: Features,
    taps: OnceLock<Vec<Tap>>,
}

/// What the window reads of a neighbour's pixel: demodulated irradiance, its variance over the
/// squared reflectance luminance, the normal and the hit distance, negated when the camera ray
/// sees an emitter (distances are positive).
#[derive(Clone, Copy, Debug)]
struct Tap {
    irradiance: Vec3,
    variance: f32,
    normal: Vec3,
    signed_depth: f32,
}

impl SequenceFrame {
    /// A frame rendered with `camera`: the path tracer's (unfiltered) image and the first-hit
    /// buffers of the same render.
    pub fn new(camera: Camera, image: Image, features: Features) -> SequenceFrame {
        SequenceFrame { camera, image, features, taps: OnceLock::new() }
    }

    /// The camera the frame was rendered with.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The path tracer's (unfiltered) image.
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// The first-hit buffers of the render.
    pub fn features(&self) -> &Features {
        &self.features
    }

    /// The image, to change.
    pub fn image_mut(&mut self) -> &mut Image {
        &mut self.image
    }

    /// The first-hit buffers, to change (the packed records are rebuilt on next use).
    pub fn features_mut(&mut self) -> &mut Features {
        self.taps = OnceLock::new();
        &mut self.features
    }

    /// Keep only what [`gather`] reads of a *neighbour* (the camera and the packed records, built
    /// now if need be) and free the image and feature buffers (about 17 of 24 MB at 600x400):
    /// for a frame that will not be a window's centre again. The image and features keep their
    /// size but hold no pixels; passing the frame as a centre afterwards panics.
    pub fn keep_neighbour_data(&mut self) {
        self.taps();
        let (w, h) = (self.image.width, self.image.height);
        self.image = Image { width: w, height: h, pixels: Vec::new() };
        let f = &self.features;
        self.features = Features {
            width: f.width,
            height: f.height,
            albedo: Vec::new(),
            normal: Vec::new(),
            depth: Vec::new(),
            variance: Vec::new(),
            emission: Vec::new(),
            irradiance: Vec::new(),
        };
    }

    fn taps(&self) -> &[Tap] {
        self.taps.get_or_init(|| {
            let f = &self.features;
            (0..f.depth.len())
                .map(|t| {
                    let la = luminance(f.albedo[t].max(Vec3::splat(MIN_ALBEDO))).max(MIN_ALBEDO);
                    let emissive = f.emission[t] != Vec3::ZERO;
                    Tap {
                        irradiance: f.irradiance[t],
                        variance: f.variance[t] / (la * la),
                        normal: f.normal[t],
                        signed_depth: if emissive { -f.depth[t] } else { f.depth[t] },
                    }
                })
                .collect()
        })
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
pub const MAX_RADIUS: usize = 32;

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
#[inline(never)]
pub fn gather(window: &[&SequenceFrame], center: usize, p: &TemporalParams) -> (Image, Features) {
    let fk = window[center];
    let (w, h) = (fk.image.width, fk.image.height);
    assert!(
        window.iter().all(|f| (f.image.width, f.image.height, f.features.width, f.features.height) == (w, h, w, h)),
        "frames of different sizes"
    );
    let n = (w * h) as usize;
    let neighbours: Vec<&SequenceFrame> = window
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != center && j.abs_diff(center) <= p.radius)
        .map(|(_, &f)| f)
        .collect();
    let mut pixels = vec![Vec3::ZERO; n];
    let mut variance = vec![0.0f32; n];
    let mut irradiance = vec![Vec3::ZERO; n];
    pixels
        .par_chunks_mut(w as usize)
        .zip(variance.par_chunks_mut(w as usize))
        .zip(irradiance.par_chunks_mut(w as usize))
        .enumerate()
        .for_each(|(y, ((row, row_var), row_irr))| gather_row(fk, &neighbours, p, y, row, row_var, row_irr));
    let features = Features { variance, irradiance, ..fk.features.clone() };
    (Image { width: w, height: h, pixels }, features)
}

/// Row `y` of [`gather`]: the centre frame `fk`'s pixels with `neighbours`' taps averaged in.
#[inline(never)]
fn gather_row(
    fk: &SequenceFrame,
    neighbours: &[&SequenceFrame],
    p: &TemporalParams,
    y: usize,
    row: &mut [Vec3],
    row_var: &mut [f32],
    row_irr: &mut [Vec3],
) {
    let (w, h) = (fk.image.width, fk.image.height);
    let wu = w as usize;
    let albedo = |i: usize| fk.features.albedo[i].max(Vec3::splat(MIN_ALBEDO));
    let origin = fk.camera.origin();
    // the row's centre pixels: first-hit point (one plane per coordinate), normal and whether
    // the camera ray sees an emitter; weighted sums of demodulated irradiance and of
    // weight^2 * demodulated variance, and the weight sum
    let row_start = y * wu;
    let mut point = [vec![0.0f32; wu], vec![0.0f32; wu], vec![0.0f32; wu]];
    let mut centre: Vec<(Vec3, bool)> = Vec::with_capacity(wu);
    for x in 0..wu {
        let i = row_start + x;
        let dir = fk.camera.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), w, h);
        let pt = origin + dir * fk.features.depth[i];
        (point[0][x], point[1][x], point[2][x]) = (pt.x, pt.y, pt.z);
        centre.push((fk.features.normal[i], fk.features.emission[i] != Vec3::ZERO));
    }
    let mut sums: Vec<(Vec3, f32, f32)> = (0..wu)
        .map(|x| {
            let i = row_start + x;
            let la = luminance(albedo(i)).max(MIN_ALBEDO);
            (fk.features.irradiance[i], fk.features.variance[i] / (la * la), 1.0)
        })
        .collect();
    // per neighbour: where each centre point lands in its image (pixel-centre coordinates) and
    // how far it is from its camera
    let (mut qx, mut qy, mut dist) = (vec![0.0f32; wu], vec![0.0f32; wu], vec![0.0f32; wu]);
    // one neighbour at a time over the whole row (each pixel still adds its neighbours in window
    // order, so the sums are those of a per-pixel loop): a few memory streams at a time
    for &fj in neighbours {
        let origin_j = fj.camera.origin();
        let projector = fj.camera.projector(w, h);
        let taps_j = fj.taps();
        // the projections, without branches (they vectorise); NaN marks a point behind the camera
        for x in 0..wu {
            let pt = Vec3::new(point[0][x], point[1][x], point[2][x]);
            let q = projector.project_or_nan(pt);
            (qx[x], qy[x]) = (q.x - 0.5, q.y - 0.5);
            dist[x] = (pt - origin_j).length();
        }
        for (x, (&(normal, emissive), (sum, var, wsum))) in centre.iter().zip(sums.iter_mut()).enumerate() {
            let (qx, qy, dist) = (qx[x], qy[x], dist[x]);
            // entirely outside the neighbour's image (NaN included): nothing to read
            if !(qx > -1.0 && qy > -1.0 && qx < w as f32 && qy < h as f32) {
                continue;
            }
            let (x0, y0) = (qx.floor(), qy.floor());
            let (fx, fy) = (qx - x0, qy - y0);
            let taps =
                [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)];
            for (dx, dy, bilinear) in taps {
                let (tx, ty) = (x0 as i64 + dx, y0 as i64 + dy);
                if tx < 0 || ty < 0 || tx >= w as i64 || ty >= h as i64 || bilinear <= 0.0 {
                    continue;
                }
                let tap = &taps_j[(ty as u32 * w + tx as u32) as usize];
                if (tap.signed_depth.abs() - dist).abs() > p.depth_tolerance * dist
                    || tap.normal.dot(normal) < p.min_normal_dot
                    || (tap.signed_depth < 0.0) != emissive
                {
                    continue;
                }
                let wt = bilinear;
                *sum += tap.irradiance * wt;
                *var += tap.variance * wt * wt;
                *wsum += wt;
            }
        }
    }
    for (x, (sum, var, wsum)) in sums.into_iter().enumerate() {
        let i = row_start + x;
        let la = luminance(albedo(i)).max(MIN_ALBEDO);
        row_irr[x] = sum / wsum;
        row[x] = row_irr[x] * fk.features.albedo[i] + fk.features.emission[i];
        row_var[x] = var / (wsum * wsum) * la * la;
    }
}

#[cfg(test)]
#[path = "temporal_tests.rs"]
mod tests;
