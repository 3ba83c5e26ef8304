//! Primary visibility by rasterisation: which triangle each camera sample sees first, found by
//! projecting the mesh onto the film instead of tracing one BVH ray per sample.
//!
//! A dataset frame shoots 32 camera rays per pixel (the filters' guide buffers, see
//! [`super::film::RenderSettings::feature_spp`]); traced, they cost as much as the shaded paths.
//! Rasterised, the cost is a few edge tests per sample and covering triangle. The result is a
//! visibility buffer (one triangle index per camera sample, `None` where nothing covers it);
//! [`super::integrator::Renderer`] turns each entry into the exact ray hit by intersecting the
//! sample's own ray with that one triangle, so a sample's hit is bit for bit what the BVH returns
//! whenever both agree on the triangle.
//!
//! Exactness: the samples are the renderer's own film points (`x + u`, `y + v` in f32), the
//! projected corners are f32, and each edge function is evaluated in f64 from differences of
//! f32 values, whose products are exact: the sign of an edge function is the sign of the exact
//! value, so two triangles sharing an edge never both miss a sample on it (no cracks), and points
//! exactly on an edge count as inside (ties go to the triangle with the lower index). Depth is
//! the interpolated reciprocal of the camera-space distance along the view axis.
//!
//! Triangles are clipped against a near plane [`NEAR`] in front of the eye (geometry closer than
//! that is not seen by the rasteriser; the renderer traces samples nothing covers, so it still
//! appears where nothing else is behind it). Work is split into [`RASTER_TILE`]-pixel square
//! tiles. A tile draws its triangles nearest first (by their nearest point) and skips a pixel
//! for a triangle whose nearest point lies behind all of the pixel's samples' current hits
//! (the factory scene draws 5.6 triangles per covered pixel without this); among equally near
//! hits a sample keeps the lowest triangle index, so the buffer is exactly what drawing in
//! index order gives, whatever the order and the thread count.

use std::sync::Arc;

use glam::{DVec3, Vec2};
use rayon::prelude::*;

use crate::scene::{Camera, TriangleMesh};

/// Camera-space distance (world units, along the view axis) of the near clipping plane.
pub const NEAR: f64 = 1e-3;

/// Side of the square pixel tiles rasterised in parallel.
pub const RASTER_TILE: u32 = 16;

/// Marks a camera sample no triangle covers.
const NONE: u32 = u32::MAX;

/// The first triangle seen by every camera sample of a frame ([`rasterise`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Visibility {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Camera samples per pixel.
    pub samples: u32,
    /// Per pixel (row-major) and sample: the triangle index, or [`NONE`].
    prims: Vec<u32>,
    /// Per pixel and sample: the film offset within the pixel the sample was rasterised at.
    offsets: Arc<FilmOffsets>,
}

/// The film offsets (in [0, 1)^2 within the pixel) of every camera sample of a film: what a
/// renderer's sampler gives its camera rays. Computed once and shared by every frame that draws
/// the same numbers (a fixed noise pattern).
#[derive(Clone, Debug, PartialEq)]
pub struct FilmOffsets {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub samples: u32,
    /// Per pixel (row-major) and sample.
    offsets: Vec<Vec2>,
}

impl FilmOffsets {
    /// The offsets of a `width` x `height` film with `samples` per pixel: `offsets(x, y, out)`
    /// writes pixel (`x`, `y`)'s (`samples` long).
    pub fn new(width: u32, height: u32, samples: u32, offsets: impl Fn(u32, u32, &mut [Vec2]) + Sync) -> FilmOffsets {
        let s = samples.max(1) as usize;
        let mut out = vec![Vec2::ZERO; width as usize * height as usize * s];
        if width > 0 {
            out.par_chunks_mut(width as usize * s).enumerate().for_each(|(y, row)| {
                for (x, px) in row.chunks_exact_mut(s).enumerate() {
                    offsets(x as u32, y as u32, px);
                }
            });
        }
        FilmOffsets { width, height, samples: samples.max(1), offsets: out }
    }

    /// The offsets of pixel (`x`, `y`)'s samples.
    #[inline]
    fn pixel(&self, x: u32, y: u32) -> &[Vec2] {
        let s = self.samples as usize;
        let k = (y as usize * self.width as usize + x as usize) * s;
        &self.offsets[k..k + s]
    }
}

impl Visibility {
    /// The triangle sample `i` of pixel (`x`, `y`) sees first; `None` when no triangle covers it
    /// (the sample sees the environment, or geometry nearer than [`NEAR`]).
    #[inline]
    pub fn prim(&self, x: u32, y: u32, i: u32) -> Option<u32> {
        let k = ((y as usize * self.width as usize + x as usize) * self.samples as usize) + i as usize;
        match self.prims[k] {
            NONE => None,
            p => Some(p),
        }
    }

    /// The film offset (in [0, 1)^2 within the pixel) of sample `i` of pixel (`x`, `y`), as the
    /// `offsets` function given to [`rasterise`] returned it.
    #[inline]
    pub fn offset(&self, x: u32, y: u32, i: u32) -> Vec2 {
        self.offsets.offsets[((y as usize * self.width as usize + x as usize) * self.samples as usize) + i as usize]
    }

    /// Fraction of samples no triangle covers.
    pub fn uncovered_fraction(&self) -> f64 {
        self.prims.iter().filter(|&&p| p == NONE).count() as f64 / self.prims.len().max(1) as f64
    }
}

/// A projected corner: film position (pixels, f32 as the renderer's film points) and the
/// reciprocal of its camera-space depth.
#[derive(Clone, Copy, Debug)]
struct Corner {
    x: f32,
    y: f32,
    inv_z: f64,
}

/// One (clipped) triangle ready to rasterise.
#[derive(Clone, Copy, Debug)]
struct RasterTri {
    prim: u32,
    /// Corners as f64 (exact copies of the f32 film positions), counter-clockwise in the edge
    /// functions' sense.
    v: [[f64; 2]; 3],
    /// The reciprocal depth as a plane over the film: `inv_z = dz[0] x + dz[1] y + dz[2]`.
    dz: [f64; 3],
    /// An upper bound of that plane over the triangle (its nearest point), rounding included.
    near: f64,
    /// Pixel bounding box, inclusive, clamped to the film.
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

/// The edge function of the directed edge `a -> b` at `p` (twice the signed area of `a, b, p`).
#[inline(always)]
fn edge(a: [f64; 2], b: [f64; 2], px: f64, py: f64) -> f64 {
    (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
}

/// Rasterise `mesh` as seen by `camera` onto the film of `offsets` (its size and camera samples
/// per pixel, at its film offsets). Film points are `x + u`, `y + v` in f32, as
/// [`crate::scene::FilmRays::direction`] takes them.
pub fn rasterise(mesh: &TriangleMesh, camera: &Camera, offsets: Arc<FilmOffsets>) -> Visibility {
    let (width, height, samples) = (offsets.width, offsets.height, offsets.samples);
    if width == 0 || height == 0 {
        return Visibility { width, height, samples, prims: Vec::new(), offsets };
    }
    let tris = setup(mesh, camera, width, height);
    let (tiles_x, tiles_y) = (width.div_ceil(RASTER_TILE), height.div_ceil(RASTER_TILE));
    // bin the triangles to the tiles their bounding boxes touch, in index order
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    for (k, t) in tris.iter().enumerate() {
        for ty in t.y0 / RASTER_TILE..=t.y1 / RASTER_TILE {
            for tx in t.x0 / RASTER_TILE..=t.x1 / RASTER_TILE {
                bins[(ty * tiles_x + tx) as usize].push(k as u32);
            }
        }
    }
    let done: Vec<Vec<u32>> = bins
        .par_iter()
        .enumerate()
        .map(|(b, bin)| {
            let (tx, ty) = (b as u32 % tiles_x, b as u32 / tiles_x);
            raster_tile(&tris, bin, tx * RASTER_TILE, ty * RASTER_TILE, &offsets)
        })
        .collect();
    let s = samples as usize;
    let mut prims = vec![NONE; width as usize * height as usize * s];
    for (b, tile) in done.iter().enumerate() {
        let (x0, y0) = ((b as u32 % tiles_x) * RASTER_TILE, (b as u32 / tiles_x) * RASTER_TILE);
        let tw = (width - x0).min(RASTER_TILE) as usize;
        for (row, chunk) in tile.chunks_exact(tw * s).enumerate() {
            let start = ((y0 as usize + row) * width as usize + x0 as usize) * s;
            prims[start..start + tw * s].copy_from_slice(chunk);
        }
    }
    Visibility { width, height, samples, prims, offsets }
}

/// Rasterise the triangles `bin` (indices into `tris`) over the tile at (`x0`, `y0`); returns the
/// tile's samples' triangles row by row (tile width clipped to the film).
fn raster_tile(tris: &[RasterTri], bin: &[u32], x0: u32, y0: u32, offsets: &FilmOffsets) -> Vec<u32> {
    let (x1, y1) = ((x0 + RASTER_TILE).min(offsets.width), (y0 + RASTER_TILE).min(offsets.height));
    let (tw, th, s) = ((x1 - x0) as usize, (y1 - y0) as usize, offsets.samples as usize);
    let mut prim = vec![NONE; tw * th * s];
    if bin.is_empty() {
        return prim;
    }
    let mut depth = vec![0.0f64; tw * th * s];
    // per pixel: the farthest of its samples' depths (0 while one is uncovered); a triangle
    // whose nearest point is farther cannot win any of them
    let mut farthest = vec![0.0f64; tw * th];
    // nearest triangles first, so that those behind them are mostly skipped
    let mut bin = bin.to_vec();
    bin.sort_unstable_by(|&i, &j| tris[j as usize].near.total_cmp(&tris[i as usize].near).then(i.cmp(&j)));
    // the samples' film points, as the renderer computes them, one plane per coordinate (so
    // that a pixel's samples are tested in vector lanes)
    let (mut film_x, mut film_y) = (vec![0.0f64; tw * th * s], vec![0.0f64; tw * th * s]);
    for y in y0..y1 {
        for x in x0..x1 {
            let base = ((y - y0) as usize * tw + (x - x0) as usize) * s;
            let points = film_x[base..base + s].iter_mut().zip(&mut film_y[base..base + s]);
            for ((fx, fy), o) in points.zip(offsets.pixel(x, y)) {
                (*fx, *fy) = ((x as f32 + o.x) as f64, (y as f32 + o.y) as f64);
            }
        }
    }
    for &k in &bin {
        let t = &tris[k as usize];
        let [a, b, c] = t.v;
        for y in t.y0.max(y0)..=t.y1.min(y1 - 1) {
            for x in t.x0.max(x0)..=t.x1.min(x1 - 1) {
                let pixel = (y - y0) as usize * tw + (x - x0) as usize;
                if t.near < farthest[pixel] {
                    continue;
                }
                // skip the pixel when its square (with a margin for f32 rounding) lies outside
                // an edge
                let (lx, ly, hx, hy) = (x as f64 - 0.01, y as f64 - 0.01, x as f64 + 1.01, y as f64 + 1.01);
                let outside = |p: [f64; 2], q: [f64; 2]| {
                    edge(p, q, lx, ly) < 0.0
                        && edge(p, q, hx, ly) < 0.0
                        && edge(p, q, lx, hy) < 0.0
                        && edge(p, q, hx, hy) < 0.0
                };
                if outside(b, c) || outside(c, a) || outside(a, b) {
                    continue;
                }
                let inside = |p: [f64; 2], q: [f64; 2]| {
                    edge(p, q, lx, ly) >= 0.0
                        && edge(p, q, hx, ly) >= 0.0
                        && edge(p, q, lx, hy) >= 0.0
                        && edge(p, q, hx, hy) >= 0.0
                };
                let covered = inside(b, c) && inside(c, a) && inside(a, b);
                let base = pixel * s;
                let (px, py) = (&film_x[base..base + s], &film_y[base..base + s]);
                let (depth, prim) = (&mut depth[base..base + s], &mut prim[base..base + s]);
                // without branches (non-short-circuit `&`, selects): the loops vectorise. A
                // sample keeps the nearest hit and, among equally near ones, the lowest
                // triangle index: what drawing in index order with a strict depth test gives
                for j in 0..s {
                    let (px, py) = (px[j], py[j]);
                    let hit = covered
                        | ((edge(b, c, px, py) >= 0.0) & (edge(c, a, px, py) >= 0.0) & (edge(a, b, px, py) >= 0.0));
                    let iz = t.dz[0] * px + t.dz[1] * py + t.dz[2];
                    let tie = (iz == depth[j]) & (prim[j] != NONE) & (t.prim < prim[j]);
                    let closer = hit & ((iz > depth[j]) | tie);
                    depth[j] = if closer { iz } else { depth[j] };
                    prim[j] = if closer { t.prim } else { prim[j] };
                }
                farthest[pixel] = min_of(depth);
            }
        }
    }
    prim
}

/// The smallest of `v`, infinity when empty: what a fold of `f64::min` from infinity gives (NaNs
/// skipped; a zero's sign may differ, which no comparison sees), in four lanes so that it
/// vectorises instead of waiting on one long chain of `min`s.
#[inline(always)]
fn min_of(v: &[f64]) -> f64 {
    let mut m = [f64::INFINITY; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            m[l] = m[l].min(c[l]);
        }
    }
    rest.iter().fold(m[0].min(m[1]).min(m[2].min(m[3])), |r, &d| r.min(d))
}

/// Project, clip and set up every triangle of `mesh` that may cover part of the film.
fn setup(mesh: &TriangleMesh, camera: &Camera, width: u32, height: u32) -> Vec<RasterTri> {
    let origin = camera.origin().as_dvec3();
    let axes =
        [camera.to_world.x_axis, camera.to_world.y_axis, camera.to_world.z_axis].map(|a| a.truncate().as_dvec3());
    let tan_half = (camera.yfov as f64 * 0.5).tan();
    let aspect = width as f64 / height as f64;
    let (w, h) = (width as f64, height as f64);
    // camera space: x right, y up, z = distance in front of the eye along the view axis
    let to_cam = |p: glam::Vec3| {
        let d = p.as_dvec3() - origin;
        DVec3::new(d.dot(axes[0]), d.dot(axes[1]), -d.dot(axes[2]))
    };
    let project = |c: DVec3| Corner {
        x: ((c.x / c.z / (tan_half * aspect) + 1.0) * 0.5 * w) as f32,
        y: ((1.0 - c.y / c.z / tan_half) * 0.5 * h) as f32,
        inv_z: 1.0 / c.z,
    };
    let cam: Vec<DVec3> = mesh.positions.iter().map(|&p| to_cam(p)).collect();
    let corners: Vec<Option<Corner>> = cam.iter().map(|&c| (c.z >= NEAR).then(|| project(c))).collect();
    let mut out = Vec::new();
    for (prim, &idx) in mesh.indices.iter().enumerate() {
        let prim = prim as u32;
        let pc = idx.map(|i| corners[i as usize]);
        if let [Some(a), Some(b), Some(c)] = pc {
            push_tri(&mut out, prim, [a, b, c], width, height);
            continue;
        }
        if idx.iter().all(|&i| cam[i as usize].z < NEAR) {
            continue;
        }
        // clip the polygon against the near plane (Sutherland-Hodgman, one plane); the point on
        // an edge is computed from its endpoints in index order, so neighbours agree on it
        let mut poly: Vec<Corner> = Vec::with_capacity(4);
        for e in 0..3 {
            let (i, j) = (idx[e], idx[(e + 1) % 3]);
            let (ci, cj) = (cam[i as usize], cam[j as usize]);
            if let Some(c) = pc[e] {
                poly.push(c);
            }
            if (ci.z >= NEAR) != (cj.z >= NEAR) {
                let (p, q) = if i < j { (ci, cj) } else { (cj, ci) };
                let s = (NEAR - p.z) / (q.z - p.z);
                let mut x = p + (q - p) * s;
                x.z = NEAR;
                poly.push(project(x));
            }
        }
        for k in 1..poly.len().saturating_sub(1) {
            push_tri(&mut out, prim, [poly[0], poly[k], poly[k + 1]], width, height);
        }
    }
    out
}

/// Set up the projected triangle `c` of triangle `prim` and append it unless it is degenerate or
/// off the film.
fn push_tri(out: &mut Vec<RasterTri>, prim: u32, c: [Corner; 3], width: u32, height: u32) {
    if c.iter().any(|c| !(c.x.is_finite() && c.y.is_finite())) {
        return;
    }
    let mut v = c.map(|c| [c.x as f64, c.y as f64]);
    let mut inv_z = c.map(|c| c.inv_z);
    let area = edge(v[0], v[1], v[2][0], v[2][1]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    if area < 0.0 {
        v.swap(1, 2);
        inv_z.swap(1, 2);
    }
    let (min_x, max_x) = (
        v.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min),
        v.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max),
    );
    let (min_y, max_y) = (
        v.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min),
        v.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max),
    );
    // film points lie in [0, width) x [0, height); a pixel x holds points in [x, x + 1]
    if max_x < 0.0 || max_y < 0.0 || min_x > width as f64 || min_y > height as f64 {
        return;
    }
    let clamp = |v: f64, hi: u32| (v.floor().max(0.0) as u32).min(hi - 1);
    // a sample on the right edge of pixel x - 1 (x exactly) belongs to pixel x - 1 too
    let (x0, x1) = (clamp(min_x - 1.0, width), clamp(max_x, width));
    let (y0, y1) = (clamp(min_y - 1.0, height), clamp(max_y, height));
    // the barycentric weight of corner i is edge(v[i + 1], v[i + 2], p) / area, linear in p
    let inv_area = 1.0 / area.abs();
    let mut dz = [0.0; 3];
    for i in 0..3 {
        let (p, q) = (v[(i + 1) % 3], v[(i + 2) % 3]);
        dz[0] -= (q[1] - p[1]) * inv_z[i] * inv_area;
        dz[1] += (q[0] - p[0]) * inv_z[i] * inv_area;
        dz[2] += edge(p, q, 0.0, 0.0) * inv_z[i] * inv_area;
    }
    // the plane is largest at a corner; evaluated at a point inside, its rounding error is far
    // below 1e-12 of the terms' magnitudes
    let plane = |p: [f64; 2]| dz[0] * p[0] + dz[1] * p[1] + dz[2];
    let scale = |p: [f64; 2]| (dz[0] * p[0]).abs() + (dz[1] * p[1]).abs() + dz[2].abs();
    let near = v.iter().map(|&p| plane(p) + 1e-12 * scale(p)).fold(f64::NEG_INFINITY, f64::max);
    out.push(RasterTri { prim, v, dz, near, x0, y0, x1, y1 });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::sampling::Rng;
    use crate::render::accel::{Accel, BvhPreset};
    use glam::Vec3;

    /// Random offsets from a hash of the pixel, as a renderer's sampler would give them.
    fn offsets_fn(seed: u64) -> impl Fn(u32, u32, &mut [Vec2]) + Sync {
        move |x, y, out: &mut [Vec2]| {
            let mut rng = Rng::new(seed ^ ((y as u64) << 32 | x as u64), 7);
            for o in out.iter_mut() {
                *o = rng.next_2d();
            }
        }
    }

    /// The table of [`offsets_fn`] for a `w` x `h` film with `s` samples per pixel.
    fn offsets(seed: u64, w: u32, h: u32, s: u32) -> Arc<FilmOffsets> {
        Arc::new(FilmOffsets::new(w, h, s, offsets_fn(seed)))
    }

    /// Boxes and slanted quads around a camera, some crossing the near plane.
    fn scene() -> TriangleMesh {
        let mut m = TriangleMesh::default();
        let mut rng = Rng::new(5, 9);
        let quad = |m: &mut TriangleMesh, c: Vec3, u: Vec3, v: Vec3| {
            let b = m.positions.len() as u32;
            for p in [c - u - v, c + u - v, c + u + v, c - u + v] {
                m.positions.push(p);
                m.normals.push(u.cross(v).normalize());
                m.uvs.push(Vec2::ZERO);
            }
            m.indices.push([b, b + 1, b + 2]);
            m.indices.push([b, b + 2, b + 3]);
            m.material.extend([0, 0]);
        };
        // a big floor reaching behind the camera, a back wall, and random quads in between
        quad(&mut m, Vec3::new(0.0, -1.0, 0.0), Vec3::X * 20.0, Vec3::Z * 20.0);
        quad(&mut m, Vec3::new(0.0, 0.0, -8.0), Vec3::X * 6.0, Vec3::Y * 3.0);
        for _ in 0..60 {
            let c = Vec3::new(rng.next_f32() * 8.0 - 4.0, rng.next_f32() * 3.0 - 1.0, -rng.next_f32() * 7.0);
            let u = (rng.next_2d().extend(rng.next_f32()) - 0.5) * 1.5;
            let v = (rng.next_2d().extend(rng.next_f32()) - 0.5) * 1.5;
            quad(&mut m, c, u, v);
        }
        m
    }

    #[test]
    fn visibility_matches_traced_camera_rays() {
        let mesh = scene();
        let accel = Accel::build(&mesh, BvhPreset::Medium);
        let cam = Camera::look_at(Vec3::new(0.3, 0.2, 2.0), Vec3::new(-0.2, -0.1, -3.0), Vec3::Y, 0.9);
        let (w, h, s) = (90, 60, 8);
        let off = offsets_fn(3);
        let vis = rasterise(&mesh, &cam, offsets(3, w, h, s));
        let rays = cam.film_rays(w, h);
        let (mut agree, mut differ, mut covered) = (0, 0, 0);
        let mut o = vec![Vec2::ZERO; s as usize];
        for y in 0..h {
            for x in 0..w {
                off(x, y, &mut o);
                for (i, u) in o.iter().enumerate() {
                    let dir = rays.direction(Vec2::new(x as f32 + u.x, y as f32 + u.y));
                    let traced = accel.intersect(cam.origin(), dir, 0.0, f32::INFINITY).map(|h| h.prim);
                    let got = vis.prim(x, y, i as u32);
                    covered += got.is_some() as u32;
                    if got == traced {
                        agree += 1;
                    } else {
                        differ += 1;
                    }
                }
            }
        }
        let n = w * h * s;
        assert!(covered > n / 2, "the scene should cover most samples: {covered} of {n}");
        // disagreements only where a sample lies within float error of an edge
        assert!(differ * 2000 < n, "{differ} of {n} samples disagree ({agree} agree)");
    }

    #[test]
    fn min_of_equals_a_fold_of_min() {
        let mut rng = Rng::new(3, 0);
        for n in 0..40 {
            for _ in 0..50 {
                let v: Vec<f64> = (0..n)
                    .map(|_| match rng.next_f32() {
                        u if u < 0.1 => f64::NAN,
                        u if u < 0.2 => 0.0,
                        u => (u as f64 - 0.5) * 1e3,
                    })
                    .collect();
                let fold = v.iter().fold(f64::INFINITY, |m, &d| m.min(d));
                assert_eq!(min_of(&v), fold, "{v:?}");
            }
        }
    }

    #[test]
    fn culled_front_to_back_drawing_equals_drawing_in_index_order() {
        // the scene plus exact duplicates of some quads (same corners, later indices: equal
        // depths, where the lower index must win)
        let mut mesh = scene();
        for k in (4..40).step_by(6) {
            let idx = mesh.indices[k];
            mesh.indices.push(idx);
            mesh.material.push(0);
        }
        let cam = Camera::look_at(Vec3::new(0.3, 0.2, 2.0), Vec3::new(-0.2, -0.1, -3.0), Vec3::Y, 0.9);
        let (w, h, s) = (90, 60, 8);
        let off = offsets(3, w, h, s);
        let vis = rasterise(&mesh, &cam, off.clone());
        // every triangle over every sample of its box, in index order, strict depth test
        let tris = setup(&mesh, &cam, w, h);
        let mut depth = vec![0.0f64; (w * h * s) as usize];
        let mut prim = vec![NONE; depth.len()];
        for t in &tris {
            let [a, b, c] = t.v;
            for y in t.y0..=t.y1 {
                for x in t.x0..=t.x1 {
                    for (i, o) in off.pixel(x, y).iter().enumerate() {
                        let (px, py) = ((x as f32 + o.x) as f64, (y as f32 + o.y) as f64);
                        let k = ((y * w + x) * s) as usize + i;
                        let inside =
                            edge(b, c, px, py) >= 0.0 && edge(c, a, px, py) >= 0.0 && edge(a, b, px, py) >= 0.0;
                        let iz = t.dz[0] * px + t.dz[1] * py + t.dz[2];
                        if inside && iz > depth[k] {
                            (depth[k], prim[k]) = (iz, t.prim);
                        }
                    }
                }
            }
        }
        assert_eq!(vis.prims, prim);
        let dups = (0..vis.prims.len())
            .filter(|&k| (mesh.indices.len() - 6..mesh.indices.len()).contains(&(prim[k] as usize)));
        assert_eq!(dups.count(), 0, "a duplicate (higher index) won a tie");
        assert!(prim.iter().filter(|&&p| p != NONE).count() > prim.len() / 2);
    }

    #[test]
    fn shared_edges_leave_no_cracks() {
        // a fan of thin triangles around a centre, over an empty background: every sample inside
        // the fan's hull is covered
        let mut m = TriangleMesh::default();
        let n = 97;
        m.positions.push(Vec3::new(0.01, -0.02, -2.0));
        m.normals.push(Vec3::Z);
        m.uvs.push(Vec2::ZERO);
        for k in 0..n {
            let a = k as f32 / n as f32 * std::f32::consts::TAU;
            m.positions.push(Vec3::new(a.cos() * 3.0, a.sin() * 3.0, -2.0 - 0.3 * a.sin()));
            m.normals.push(Vec3::Z);
            m.uvs.push(Vec2::ZERO);
            m.indices.push([0, 1 + k as u32, 1 + ((k + 1) % n) as u32]);
            m.material.push(0);
        }
        let cam = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 0.8);
        let vis = rasterise(&m, &cam, offsets(11, 64, 48, 16));
        // the fan fills the whole film
        assert_eq!(vis.uncovered_fraction(), 0.0);
    }

    #[test]
    fn buffer_does_not_depend_on_thread_count() {
        let mesh = scene();
        let cam = Camera::look_at(Vec3::new(0.0, 0.5, 1.5), Vec3::new(0.0, 0.0, -3.0), Vec3::Y, 1.0);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| rasterise(&mesh, &cam, offsets(2, 70, 50, 4)))
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn geometry_behind_the_camera_is_not_drawn() {
        let mut m = TriangleMesh::default();
        for p in [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0)] {
            m.positions.push(p);
            m.normals.push(Vec3::Z);
            m.uvs.push(Vec2::ZERO);
        }
        m.indices.push([0, 1, 2]);
        m.material.push(0);
        let cam = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 0.8);
        assert_eq!(rasterise(&m, &cam, offsets(1, 20, 10, 2)).uncovered_fraction(), 1.0);
    }
}
