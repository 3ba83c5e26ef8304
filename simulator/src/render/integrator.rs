//! The unidirectional path tracer (pbrt's `PathIntegrator`, Mitsuba's `path`).
//!
//! For each camera sample: trace a path; at every hit add the emitted radiance (weighted by MIS
//! against light sampling), then next-event estimation to every delta light and to one light
//! sampled by power (weighted by MIS against BSDF sampling, power heuristic), then continue
//! along a BSDF-sampled direction.
//!
//! Depth follows Mitsuba: `max_depth` counts path segments, so 1 shows emitters only and 2 gives
//! direct lighting; Russian roulette starts at `rr_depth` with survival
//! `q = min(max(beta), 0.95)`. Pixels use a box filter: each sample is uniform in its pixel and
//! the pixel value is the plain mean. Every sample's numbers come from a
//! [`SampleStream`] that is a function of (seed, pixel, frame, sample), so the image does not
//! depend on thread count or tile order.
//!
//! What lives where: this file holds the renderer and its frame-level entry points (render,
//! features, visibility, film offsets); `integrator_path.rs` the path (`li`);
//! `integrator_geometry.rs` what shading reads of a hit; `integrator_pixels.rs` the pixel loop,
//! adaptive sampling and the feature buffers; `integrator_fill.rs` the radiance cache's fills;
//! `surface.rs` the surface cache; `first_hits.rs` the first-hit feature sums; what the
//! renderer keeps from frame to frame is held in `frame_caches.rs`.

use crate::base::colour::luminance;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::accel::{Accel, BvhPreset, Hit};
use super::bsdf::Bsdf;
use super::film::RenderSettings;
use super::frame_caches::{FilmKey, FrameCaches};
use super::lights::{emitted_filtered, Lights};
use super::radiance_cache::{lattice_bary, lattice_index, steps_for, CacheParams, FillTimes, Lattice, RadianceCache};
use super::raster::{rasterise, FilmOffsets, Visibility};
use super::sampler::{pixel_key, SampleStream};
use crate::base::image::Image;
use crate::base::sampling::{power_heuristic, Frame};
use crate::scene::{FilmRays, Scene};

use fill::*;
pub(crate) use fill::{FillSpec, PathMode};
use geometry::*;
use pixels::*;
pub use pixels::{Features, MISS_DEPTH};

/// Side of the square tiles rendered in parallel.
pub const TILE: u32 = 16;

/// A scene prepared for rendering: BVH built, lights gathered.
pub struct Renderer<'a> {
    /// The scene being rendered.
    pub scene: &'a Scene,
    /// The BVH over the scene's triangles.
    pub accel: Accel,
    /// The light table.
    pub lights: Lights,
    /// Per triangle, what shading a hit reads (normals, texture coordinates, material) in one
    /// cache line instead of scattered over the mesh's arrays.
    shading: Vec<ShadingTri>,
    /// The radiance cache, surface cache and film offsets kept from frame to frame while
    /// they fit the frame's settings.
    caches: FrameCaches,
}

impl<'a> Renderer<'a> {
    /// Build the acceleration structure (default preset) and light tables for `scene`.
    pub fn new(scene: &'a Scene) -> Renderer<'a> {
        Self::with_preset(scene, BvhPreset::default())
    }

    /// As [`Renderer::new`] with a chosen BVH build preset.
    pub fn with_preset(scene: &'a Scene, preset: BvhPreset) -> Renderer<'a> {
        let mesh = &scene.mesh;
        let shading = mesh
            .indices
            .iter()
            .zip(&mesh.material)
            .map(|(&[i0, i1, i2], &material)| ShadingTri {
                normals: [i0, i1, i2].map(|i| mesh.normals[i as usize]),
                uvs: [i0, i1, i2].map(|i| mesh.uvs[i as usize]),
                material,
            })
            .collect();
        Renderer {
            scene,
            accel: Accel::build(&scene.mesh, preset),
            lights: Lights::new(scene),
            shading,
            caches: FrameCaches::default(),
        }
    }

    /// Render one image; ticks `progress` once per finished tile when given. Camera rays are
    /// traced; with `settings.radiance_cache`, paths end at their second bounce
    /// ([`crate::render::radiance_cache`]).
    pub fn render(&self, settings: &RenderSettings, progress: Option<&ProgressBar>) -> Image {
        let (w, h) = (settings.width, settings.height);
        let cache = self.radiance_cache(settings);
        let cache = cache.as_deref();
        let tiles_x = w.div_ceil(TILE);
        let tiles: Vec<(u32, u32)> =
            (0..h.div_ceil(TILE)).flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty))).collect();
        if let Some(pb) = progress {
            pb.set_length(tiles.len() as u64);
        }
        let done: Vec<Vec<Vec3>> = tiles
            .par_iter()
            .map(|&(tx, ty)| {
                let mut out = Vec::with_capacity((TILE * TILE) as usize);
                for y in ty * TILE..((ty + 1) * TILE).min(h) {
                    for x in tx * TILE..((tx + 1) * TILE).min(w) {
                        out.push(self.pixel_color(settings, x, y, cache));
                    }
                }
                if let Some(pb) = progress {
                    pb.inc(1);
                }
                out
            })
            .collect();
        let mut img = Image::new(w, h);
        for (&(tx, ty), px) in tiles.iter().zip(done) {
            let mut it = px.into_iter();
            for y in ty * TILE..((ty + 1) * TILE).min(h) {
                for x in tx * TILE..((tx + 1) * TILE).min(w) {
                    img.pixels[(y * w + x) as usize] = it.next().unwrap_or_default();
                }
            }
        }
        img
    }

    /// Render one image and the first-hit feature buffers a denoiser is guided by
    /// ([`crate::render::denoise`]). The buffers average `max(spp, feature_spp)` camera rays per
    /// pixel (see [`Features`]). The camera rays' first hits come from a rasterised visibility
    /// buffer ([`crate::render::raster`]): the image equals [`Renderer::render`]'s except for
    /// samples within float error of a triangle edge (or seeing geometry nearer than
    /// [`crate::render::raster::NEAR`]). Paths use the radiance cache as in
    /// [`Renderer::render`].
    pub fn render_with_features(&self, settings: &RenderSettings) -> (Image, Features) {
        let vis = self.visibility(settings, settings.feature_spp.max(settings.spp));
        self.shade_with_features(settings, &vis)
    }

    /// The shading half of [`Renderer::render_with_features`]: `vis` is
    /// [`Renderer::visibility`] of the same settings with `max(spp, feature_spp)` samples.
    pub fn shade_with_features(&self, settings: &RenderSettings, vis: &Visibility) -> (Image, Features) {
        let (w, h) = (settings.width, settings.height);
        let feature_spp = settings.feature_spp.max(settings.spp);
        let cache = self.radiance_cache(settings);
        let cache = cache.as_deref();
        let rows: Vec<Vec<(ShadeSums, FirstHitSums)>> = (0..h)
            .into_par_iter()
            .map(|y| (0..w).map(|x| self.pixel_sums(settings, x, y, feature_spp, Some(vis), cache)).collect())
            .collect();
        let mut sums: Vec<(ShadeSums, FirstHitSums)> = rows.concat();
        let s = settings;
        if s.spp_max > s.spp {
            let target = adaptive_spp(&sums, w, h, s);
            let film_rays = s.camera.film_rays(w, h);
            sums.par_chunks_mut(w as usize).zip(target.par_chunks(w as usize)).enumerate().for_each(
                |(y, (row, target))| {
                    for (x, ((shade, _), &n)) in row.iter_mut().zip(target).enumerate() {
                        if n > s.spp {
                            let (x, y) = (x as u32, y as u32);
                            let key = pixel_key(s.seed, y as u64 * w as u64 + x as u64, s.frame);
                            self.shade_samples(s, x, y, s.spp..n, Some(vis), cache, key, &film_rays, shade, None);
                        }
                    }
                },
            );
        }
        let mut img = Image::new(w, h);
        let mut f = Features::new(w, h);
        f.samples = sums.iter().map(|(shade, _)| shade.attempted as u64).sum();
        for (i, (shade, feats)) in sums.iter().enumerate() {
            let (c, pf) = finish_pixel(shade, feats);
            img.pixels[i] = c;
            f.albedo[i] = pf.albedo;
            f.normal[i] = pf.normal;
            f.depth[i] = pf.depth;
            f.variance[i] = pf.variance;
            f.emission[i] = pf.emission;
            f.irradiance[i] = pf.irradiance;
        }
        (img, f)
    }

    /// The first triangle each of the first `samples` camera rays of every pixel sees
    /// (rasterised, with the film points the renderer's samplers give those rays).
    pub fn visibility(&self, s: &RenderSettings, samples: u32) -> Visibility {
        rasterise(&self.scene.mesh, &s.camera, self.film_offsets(s, samples))
    }

    /// The film offsets the samplers give the first `samples` camera rays of every pixel of
    /// `s`'s film: computed once and reused while the film, seed, sampler and frame stay the
    /// same (every frame of a sequence with a fixed noise pattern).
    pub fn film_offsets(&self, s: &RenderSettings, samples: u32) -> Arc<FilmOffsets> {
        let key: FilmKey = (s.width, s.height, samples, s.seed, s.frame, s.sampler);
        let make = || {
            let offsets = FilmOffsets::new(s.width, s.height, samples, |x, y, out| {
                let key = pixel_key(s.seed, y as u64 * s.width as u64 + x as u64, s.frame);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = Vec2::from(SampleStream::new(s.sampler, key, i as u32).next_2d());
                }
            });
            (key, Arc::new(offsets))
        };
        self.caches.film_offsets.get_or_make(|(k, _)| *k == key, make).1.clone()
    }

    /// Mean of `spp` box-filtered samples of pixel (x, y) (full paths: no radiance cache).
    pub fn pixel(&self, s: &RenderSettings, x: u32, y: u32) -> Vec3 {
        self.pixel_color(s, x, y, None)
    }
}

/// Smallest reflectance a pixel's reflected light is divided by.
const MIN_REFLECTANCE: f32 = 1e-3;

#[path = "integrator_fill.rs"]
mod fill;
#[path = "first_hits.rs"]
mod first_hits;
#[path = "integrator_geometry.rs"]
mod geometry;
#[path = "integrator_path.rs"]
mod path;
#[path = "integrator_pixels.rs"]
mod pixels;
#[path = "surface.rs"]
pub mod surface;
use first_hits::FirstHitSums;

#[cfg(test)]
#[path = "integrator_tests.rs"]
mod tests;
