//! Surface-cache frames: every frame of a sequence reads one converged estimate of the light
//! that surfaces reflect, so that a frame differs from the next only where the projection of
//! the scene differs, as a real camera's would.
//!
//! The scenes are static and only the camera moves, so the view-independent part of the light
//! (what a diffuse surface reflects: the environment, area lights, light via other surfaces) is
//! one field over the surfaces, the same in every frame. It is estimated once per sequence on a
//! [`Grid`] over every triangle side (cells at most [`RenderSettings::surface_spacing`] wide,
//! laid in the triangle's plane along its longest edge, so a long thin triangle costs what its
//! area needs), with [`RenderSettings::surface_paths`] paths per point from random streams
//! keyed by (seed, triangle, side, point): the bytes do not depend on thread count, frame order
//! or resume point.
//!
//! A camera sample ([`RenderSettings::feature_spp`] of them per pixel, from the rasterised
//! visibility buffer, the same film points in every frame) on a mostly diffuse surface
//! ([`super::bsdf::Bsdf::specular_share`] below one half) then takes, with no random number:
//! - the emission at its hit (lamps, screens, the sky where it escapes);
//! - the direct light of every delta light (the sun), with its BSDF and its visibility read
//!   from a *shadow grid* over the triangle side, one shadow ray per point, with cells of half
//!   the smallest pixel footprint the camera path gives the triangle: shadow edges stay sharp to
//!   half a pixel, and its highlights follow the view (when every delta light is directional,
//!   the samples of a pixel on one triangle with one lobe shape share one BSDF evaluation,
//!   affine in their texture's colour: see [`DiffuseRun`]);
//! - its reflectance hint times the surface grid's value at the hit (bilinear).
//!
//! A sample on a glossy or metal surface adds its emission and its delta lights as above. The
//! rest of its reflection follows the view, so it cannot be one field over the surfaces; but
//! the camera path is known in advance. With [`RenderSettings::glossy_stride`] > 0, every
//! `glossy_stride`-th frame of the path is a keyframe ([`GlossyFrame`]), and a *glossy grid*
//! per keyframe and triangle side (the surface grids' layout and spacing) holds the light the
//! point's BSDF reflects towards that keyframe's camera, from `glossy_paths` paths per point
//! whose random streams are keyed by the point alone: neighbouring keyframes differ by the
//! change of view, not by noise. A sample on a lobe of GGX alpha >=
//! [`RenderSettings::glossy_grid_alpha`] blends the two keyframes around its frame (linearly
//! along the path) and takes the result per unit reflectance hint times its own hint.
//!
//! Sharper lobes (and every glossy sample with `glossy_stride` 0) trace
//! [`RenderSettings::glossy_paths`] paths shared by the samples on its triangle in its block
//! of pixels ([`RenderSettings::glossy_block`] on a side for rough lobes, see [`lobe_block`])
//! and spread over their hits. A path, here or in a glossy grid, takes one light sample and
//! one BSDF sample (multiple importance sampling), whose hit adds its emission and the light
//! it reflects within the path's remaining segments (traced on from there). A block's glossy
//! paths take the same random numbers in every frame, so their error drifts with the view
//! instead of flickering. No image filter follows.

use std::sync::{Arc, OnceLock};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{offset_origin, FillSpec, FirstHit, PathMode, Renderer, SurfaceHit, TriangleNumbers};
use crate::base::image::Image;
use crate::base::sampling::power_heuristic;
use crate::render::accel::Hit;
use crate::render::bsdf::Bsdf;
use crate::render::film::RenderSettings;
use crate::render::lights::{emitted_filtered, LightSample};
use crate::render::radiance_cache::{CacheParams, FillClock, RadianceCache};
use crate::render::raster::Visibility;
use crate::render::sampler::{pixel_key, SampleStream};
use crate::scene::PunctualLight;

/// Added to a surface lattice side's key (apart from the radiance cache's lattices).
const SURFACE_SALT: u64 = 2 << 40;

/// Salt of the glossy paths' random streams (apart from the camera samples').
const GLOSSY_SALT: u64 = 0x6c05_5e00_0000_0001;

/// Salt of the glossy grids' random streams.
const GLOSSY_GRID_SALT: u64 = 0x6c05_5e00_0000_0002;

/// Default [`RenderSettings::glossy_grid_alpha`]: the GGX alpha from which a glossy sample
/// reads the keyframes' glossy grids (with [`RenderSettings::glossy_stride`] > 0) instead of
/// tracing paths: sharper lobes reflect detail finer than the grids. At 0.05 trolley's rails
/// (alpha 0.0625) read the grids and its windows lose (300x200, of the ceiling: 1 ms 0.896,
/// 24 ms 0.952); at 0.1 they trace (0.944, 0.968).
pub const GLOSSY_GRID_ALPHA: f32 = 0.1;

/// Most cells along either axis of a shadow grid.
pub const MAX_SHADOW_STEPS: u32 = 2048;

/// A camera sample on a glossy surface, waiting for its triangle's reflection.
struct Sample {
    hit: Hit,
    sh: SurfaceHit,
    bsdf: Bsdf,
    wo: Vec3,
    /// Index of its pixel in the band of rows being rendered.
    pixel: usize,
}

/// Cosine between two shading normals above which samples share a [`DiffuseRun`] (0.8 degrees).
const RUN_NORMAL_COS: f32 = 0.9999;

/// Most [`DiffuseRun`]s a pixel keeps open (an edge pixel alternates between its triangles).
const MAX_RUNS: usize = 4;

/// The mostly diffuse camera samples of one pixel on one triangle side whose BSDFs differ only
/// in the base colour (a texture's) and whose shading normals agree within
/// [`RUN_NORMAL_COS`], when every delta light is directional (at most three): the BSDF of the
/// delta lights, affine in the base colour ([`Bsdf::eval_affine`]), is evaluated once for them.
/// Each sample keeps its own texture, emission, shadow-grid visibility and surface-grid value
/// (reading the surface grid once at the samples' mean point cost factory 300x200 0.961 ->
/// 0.946 of the ceiling's pair r2).
struct DiffuseRun {
    /// The triangle.
    prim: u32,
    /// The first sample's surface (the shading frame and side).
    sh: SurfaceHit,
    /// The first sample's BSDF (its base colour is not used).
    bsdf: Bsdf,
    /// The first sample's direction to the camera, in its shading frame.
    wo: Vec3,
    /// Per delta light, the sum of visibility times base colour, and of visibility.
    lit: [(Vec3, f32); 3],
}

/// The settings of the path a glossy path traces on from its second vertex
/// ([`Renderer::second_vertex_light`]): one segment shorter than the camera's.
struct PathRest(RenderSettings);

impl PathRest {
    /// For the frames of `s` (`max_depth` >= 3 where it is used).
    fn new(s: &RenderSettings) -> PathRest {
        PathRest(RenderSettings {
            max_depth: s.max_depth.saturating_sub(1),
            rr_depth: s.rr_depth.saturating_sub(1).max(1),
            camera_path: None,
            ..s.clone()
        })
    }
}

/// Side of the pixel blocks whose glossy samples share paths, for a lobe of GGX `alpha` when
/// [`RenderSettings::glossy_block`] is `block`: the whole block for rough lobes (alpha >= 0.2,
/// whose reflection changes slowly across the surface), half of it for medium ones, one pixel
/// for sharp ones (alpha < 0.05: mirror images keep their detail).
fn lobe_block(block: usize, alpha: f32) -> usize {
    if alpha >= 0.2 {
        block
    } else if alpha >= 0.05 {
        (block / 2).max(1)
    } else {
        1
    }
}

impl Renderer<'_> {
    /// The surface cache `s` asks for: the one already made when its parameters match, else a
    /// new, empty one.
    pub fn surface_cache(&self, s: &RenderSettings) -> Arc<SurfaceCache> {
        let path = self.cache_params(s, s.radiance_cache, s.surface_spacing, 512.0, false);
        let spacing = path.spacing;
        let params = SurfaceParams { paths: s.surface_paths.max(1), spacing, path };
        let same_path = |c: &SurfaceCache| match &s.camera_path {
            Some(p) if !p.is_empty() => c.cameras[..] == p[..],
            _ => c.cameras == [s.camera.origin()],
        };
        let make = || {
            let n = self.scene.mesh.len();
            let cameras = match &s.camera_path {
                Some(path) if !path.is_empty() => path.to_vec(),
                _ => vec![s.camera.origin()],
            };
            let pixel_angle = s.camera.yfov / s.height.max(1) as f32;
            SurfaceCache {
                params,
                sides: per_side(n),
                shadows: per_side(n),
                cameras,
                pixel_angle,
                glossy: Default::default(),
                clocks: Default::default(),
            }
        };
        self.caches.surface.get_or_make(|c| c.params == params && same_path(c), make)
    }

    /// Render one frame from the surface cache (see the [module docs](self)): `vis` is
    /// [`Renderer::visibility`] of `s`; every pixel is the mean of its `vis.samples` samples.
    pub fn render_surface(&self, s: &RenderSettings, vis: &Visibility) -> Image {
        let (w, h) = (s.width, s.height);
        let surface = self.surface_cache(s);
        let cache = self.radiance_cache(s);
        let cache = cache.as_deref();
        let film_rays = s.camera.film_rays(w, h);
        let block = s.glossy_block.clamp(1, 16);
        let glossy = match s.glossy_stride {
            0 => Vec::new(),
            stride => surface.glossy_frames(s.camera.origin(), stride, s.glossy_paths.max(1)),
        };
        // the delta lights, when all are directional (the same from every point) and have
        // shadow grids: the samples of a pixel then share their BSDF (see `DiffuseRun`)
        let directional = |l: &PunctualLight| matches!(l, PunctualLight::Directional { .. });
        let lights = &self.scene.lights;
        let suns: Option<Vec<LightSample>> = (lights.len() <= 3 && lights.iter().all(directional))
            .then(|| self.lights.delta_incident(self.scene, Vec3::ZERO).collect());
        let suns = suns.as_deref();
        let bands: Vec<Vec<Vec3>> = (0..h.div_ceil(block))
            .into_par_iter()
            .map(|by| {
                let rows = block.min(h - by * block);
                let mut band = vec![Vec3::ZERO; (rows * w) as usize];
                let mut samples = Vec::with_capacity((vis.samples * block * block) as usize);
                let mut runs = Vec::with_capacity(MAX_RUNS);
                for bx in 0..w.div_ceil(block) {
                    let cols = block.min(w - bx * block);
                    samples.clear();
                    for dy in 0..rows {
                        for dx in 0..cols {
                            let (x, y) = (bx * block + dx, by * block + dy);
                            let pixel = (dy * w + x) as usize;
                            band[pixel] = self.surface_pixel(
                                s,
                                x,
                                y,
                                vis,
                                &film_rays,
                                (&surface, &glossy),
                                cache,
                                pixel,
                                &mut samples,
                                (suns, &mut runs),
                            );
                        }
                    }
                    if !samples.is_empty() {
                        let block_index = by as u64 * w.div_ceil(block) as u64 + bx as u64;
                        self.glossy_samples(s, block_index, &samples, &mut band);
                    }
                }
                let n = vis.samples.max(1) as f32;
                band.iter_mut().for_each(|p| *p /= n);
                band
            })
            .collect();
        Image { width: w, height: h, pixels: bands.concat() }
    }

    /// One pixel of [`Renderer::render_surface`]: the sum of its samples on mostly diffuse
    /// surfaces (from the grids) and the direct light and emission of its glossy samples, which
    /// are pushed to `samples` (tagged with `pixel`) for [`Renderer::glossy_samples`].
    #[allow(clippy::too_many_arguments)]
    fn surface_pixel(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        vis: &Visibility,
        film_rays: &crate::scene::FilmRays,
        (surface, glossy): (&SurfaceCache, &[(Arc<GlossyFrame>, f32)]),
        cache: Option<&RadianceCache>,
        pixel: usize,
        samples: &mut Vec<Sample>,
        (suns, runs): (Option<&[LightSample]>, &mut Vec<DiffuseRun>),
    ) -> Vec3 {
        let scene = self.scene;
        runs.clear();
        let origin = s.camera.origin();
        let mut sum = Vec3::ZERO;
        // the camera spread (see `camera_spread`) as offsets of the unnormalised direction,
        // which is affine in the film point; the footprint does not need unit directions
        let k = s.texture_filter;
        let spread_steps = (k > 0.0 && k.is_finite()).then(|| film_rays.steps().map(|d| d * k));
        // the numbers of the triangle the last sample hit (most of a pixel's samples share one)
        let mut last: Option<TriangleNumbers> = None;
        for i in 0..vis.samples {
            let c = vis.offset(x, y, i);
            let film = Vec2::new(x as f32 + c.x, y as f32 + c.y);
            let d = film_rays.unnormalised(film);
            let dir = d.normalize();
            let Some(hit) = self.camera_hit(Some(vis.prim(x, y, i)), origin, dir) else {
                sum += scene.environment.radiance(dir);
                continue;
            };
            let tri = match last {
                Some(t) if t.prim == hit.prim => t,
                _ => *last.insert(self.triangle_numbers(&hit)),
            };
            let sh = self.surface_on(&hit, tri.ng, origin, dir);
            let fp = spread_steps.and_then(|[sx, sy]| Self::uv_footprint_on(&tri, &sh, origin, [d + sx, d + sy]));
            let le = emitted_filtered(scene, hit.prim, hit.bary, -dir, fp);
            if s.max_depth < 2 {
                sum += le;
                continue;
            }
            let bsdf = self.bsdf(hit.prim, sh.uv, fp);
            let wo = sh.frame.to_local(-dir);
            if bsdf.specular_share(wo) >= 0.5 {
                // glossy: the delta lights here; the rest from the keyframes' glossy grids
                // (rough lobes) or traced once for the triangle's samples
                sum += le + self.delta_light(&hit, &sh, &bsdf, wo, surface);
                if !glossy.is_empty() && bsdf.alpha >= s.glossy_grid_alpha {
                    let side = usize::from(!sh.front);
                    let mut g = Vec3::ZERO;
                    for (frame, w) in glossy {
                        let fill = || self.fill_glossy(s, surface, hit.prim, sh.front, frame);
                        g += surface.clocks[2].get_or_fill(&frame.sides[hit.prim as usize][side], fill).at(sh.p) * *w;
                    }
                    sum += bsdf.albedo_hint() * g;
                    continue;
                }
                samples.push(Sample { hit, sh, bsdf, wo, pixel });
                continue;
            }
            sum += le;
            match suns {
                Some(suns) => self.join_run(runs, suns, hit, sh, bsdf, wo, surface, (s, cache), &mut sum),
                None => sum += self.diffuse_light(s, &hit, &sh, &bsdf, wo, surface, cache),
            }
        }
        for run in runs.drain(..) {
            sum += self.run_light(&run, suns.unwrap_or_default());
        }
        sum
    }

    /// Add a mostly diffuse sample's surface-grid light to `sum` and its delta lights' terms to
    /// the pixel's open [`DiffuseRun`] it belongs to, or to a new one (the oldest run's light
    /// added to `sum` first when [`MAX_RUNS`] are open).
    #[allow(clippy::too_many_arguments)]
    fn join_run(
        &self,
        runs: &mut Vec<DiffuseRun>,
        suns: &[LightSample],
        hit: Hit,
        sh: SurfaceHit,
        bsdf: Bsdf,
        wo: Vec3,
        surface: &SurfaceCache,
        (s, cache): (&RenderSettings, Option<&RadianceCache>),
        sum: &mut Vec3,
    ) {
        let same = |r: &DiffuseRun| {
            r.prim == hit.prim
                && r.sh.front == sh.front
                && r.bsdf.metallic == bsdf.metallic
                && r.bsdf.specular == bsdf.specular
                && r.bsdf.alpha == bsdf.alpha
                && r.sh.frame.n.dot(sh.frame.n) >= RUN_NORMAL_COS
        };
        let (prim, front, p, ng) = (hit.prim, sh.front, sh.p, sh.ng);
        let k = match runs.iter().position(same) {
            Some(k) => k,
            None => {
                if runs.len() == MAX_RUNS {
                    let old = runs.remove(0);
                    *sum += self.run_light(&old, suns);
                }
                runs.push(DiffuseRun { prim, sh, bsdf, wo, lit: [(Vec3::ZERO, 0.0); 3] });
                runs.len() - 1
            }
        };
        let run = &mut runs[k];
        let ng_side = if front { ng } else { -ng };
        if suns.iter().any(|l| l.wi.dot(ng_side) > 0.0) {
            let v = surface.shadow(prim, front, || self.fill_shadow(surface, prim, front)).at(p);
            for (lit, v) in run.lit.iter_mut().zip(v.to_array()) {
                lit.0 += bsdf.base_color * v;
                lit.1 += v;
            }
        }
        if s.max_depth >= 2 {
            *sum += self.grid_light(prim, front, p, &bsdf, surface, cache);
        }
    }

    /// The non-delta light a mostly diffuse point `p` of triangle `prim`'s `front` (or back)
    /// side reflects: its reflectance hint times the surface grid there.
    fn grid_light(
        &self,
        prim: u32,
        front: bool,
        p: Vec3,
        bsdf: &Bsdf,
        surface: &SurfaceCache,
        cache: Option<&RadianceCache>,
    ) -> Vec3 {
        let grid = surface.grid(prim, front, || self.fill_surface(surface, cache, prim, front));
        bsdf.albedo_hint() * grid.at(p)
    }

    /// The delta lights `suns` the samples of `run` reflect, summed: through the run's BSDF
    /// (once, affine in each sample's base colour) times each sample's visibility.
    fn run_light(&self, run: &DiffuseRun, suns: &[LightSample]) -> Vec3 {
        let sh = &run.sh;
        let ng_side = if sh.front { sh.ng } else { -sh.ng };
        let mut l = Vec3::ZERO;
        for (ls, &(lit_base, lit)) in suns.iter().zip(&run.lit) {
            if ls.wi.dot(ng_side) <= 0.0 || lit == 0.0 {
                continue;
            }
            let (a, b) = run.bsdf.eval_affine(run.wo, sh.frame.to_local(ls.wi));
            l += (lit_base * a + Vec3::splat(lit * b)) * ls.radiance / ls.pdf;
        }
        l
    }

    /// The light a mostly diffuse surface point reflects towards `wo`: its reflectance hint
    /// times the surface lattice, plus the delta lights with their visibility from the
    /// shadow lattice.
    #[allow(clippy::too_many_arguments)]
    fn diffuse_light(
        &self,
        s: &RenderSettings,
        hit: &Hit,
        sh: &SurfaceHit,
        bsdf: &Bsdf,
        wo: Vec3,
        surface: &SurfaceCache,
        cache: Option<&RadianceCache>,
    ) -> Vec3 {
        let l = self.delta_light(hit, sh, bsdf, wo, surface);
        if s.max_depth < 2 {
            return l;
        }
        l + self.grid_light(hit.prim, sh.front, sh.p, bsdf, surface, cache)
    }

    /// The direct light of the delta lights at a surface point, reflected towards `wo`: each
    /// light's BSDF value times its visibility from the shadow lattice (beyond three delta
    /// lights, a shadow ray each).
    fn delta_light(&self, hit: &Hit, sh: &SurfaceHit, bsdf: &Bsdf, wo: Vec3, surface: &SurfaceCache) -> Vec3 {
        let mut l = Vec3::ZERO;
        let ng_side = if sh.front { sh.ng } else { -sh.ng };
        let mut visibility = None;
        // (k is the light's index in the scene: the shadow grids' slot for the first three)
        for (k, ls) in self.lights.delta_incident_indexed(self.scene, sh.p) {
            if ls.wi.dot(ng_side) <= 0.0 {
                continue;
            }
            let f = bsdf.eval(wo, sh.frame.to_local(ls.wi));
            if f == Vec3::ZERO {
                continue;
            }
            let v = if k < 3 {
                let vis = *visibility.get_or_insert_with(|| {
                    surface.shadow(hit.prim, sh.front, || self.fill_shadow(surface, hit.prim, sh.front)).at(sh.p)
                });
                vis[k]
            } else {
                let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) - 1e-4 } else { f32::INFINITY };
                f32::from(u8::from(!self.accel.occluded(offset_origin(sh.p, ng_side), ls.wi, 0.0, tmax)))
            };
            l += f * ls.radiance * (v / ls.pdf);
        }
        l
    }

    /// The glossy samples of a block of pixels ([`RenderSettings::glossy_block`] on a side):
    /// per triangle, `glossy_paths` paths spread over that triangle's samples (the reflection of
    /// the block's part of the triangle), each going on from its second vertex as
    /// [`Renderer::second_vertex_light`] says; their reflected light (but the delta lights')
    /// per unit reflectance hint, times each sample's own hint, is added to the sample's pixel
    /// in `band`. The random numbers are keyed by the block alone: the same in every frame.
    fn glossy_samples(&self, s: &RenderSettings, block_index: u64, samples: &[Sample], band: &mut [Vec3]) {
        let key = pixel_key(s.seed ^ GLOSSY_SALT, block_index, 0);
        let block = s.glossy_block.clamp(1, 16) as usize;
        let w = s.width as usize;
        // a sample's group: its triangle and its sub-block, whose side follows the lobe's width
        let group_of = |o: &Sample| {
            let side = lobe_block(block, o.bsdf.alpha);
            let (dy, dx) = (o.pixel / w, o.pixel % w % block);
            (o.hit.prim, side, dy / side, dx / side)
        };
        let mut groups = Vec::new();
        for smp in samples {
            let g = group_of(smp);
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        let paths = s.glossy_paths.max(1);
        let rest = PathRest::new(s);
        let mut group: Vec<&Sample> = Vec::new();
        for (g, &id) in groups.iter().enumerate() {
            group.clear();
            group.extend(samples.iter().filter(|o| group_of(o) == id));
            let mut refl = Vec3::ZERO;
            for j in 0..paths {
                let smp = group[j as usize % group.len()];
                let mut rng = SampleStream::new(s.sampler, key, (g as u32) << 16 | j);
                let l = self.glossy_path(s, smp, &rest, &mut rng);
                let hint = smp.bsdf.albedo_hint().max(Vec3::splat(super::MIN_REFLECTANCE));
                if l.is_finite() {
                    refl += l / hint;
                }
            }
            refl /= paths as f32;
            for smp in &group {
                band[smp.pixel] += smp.bsdf.albedo_hint() * refl;
            }
        }
    }

    /// One path of light reflected at the glossy sample `smp`, but its delta lights' (the
    /// caller adds those per sample): one light sample and one BSDF sample (multiple importance
    /// sampling, power heuristic), the BSDF sample's hit adding its emission and, with
    /// `max_depth` 3 or more, what it reflects ([`Renderer::second_vertex_light`]).
    fn glossy_path(&self, s: &RenderSettings, smp: &Sample, rest: &PathRest, rng: &mut SampleStream) -> Vec3 {
        let scene = self.scene;
        let (sh, bsdf, wo) = (&smp.sh, &smp.bsdf, smp.wo);
        let ng_side = if sh.front { sh.ng } else { -sh.ng };
        let p_off = offset_origin(sh.p, ng_side);
        let mut l = Vec3::ZERO;
        let a = rng.next_4d();
        let b = rng.next_4d();
        // a light sample (area lights, the environment), weighed against the BSDF sample
        if let Some(ls) = self.lights.sample(scene, sh.p, a[2], Vec2::new(a[0], a[1])) {
            if ls.wi.dot(ng_side) > 0.0 {
                let (f, bsdf_pdf) = bsdf.eval_and_pdf(wo, sh.frame.to_local(ls.wi));
                let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) - 1e-4 } else { f32::INFINITY };
                if f != Vec3::ZERO && !self.accel.occluded(p_off, ls.wi, 0.0, tmax) {
                    l += f * ls.radiance * (power_heuristic(ls.pdf, bsdf_pdf) / ls.pdf);
                }
            }
        }
        // a BSDF sample: what it reaches adds its emission (MIS) and its reflected light
        let Some(bs) = bsdf.sample(wo, b[2], Vec2::new(b[0], b[1])) else { return l };
        let wi = sh.frame.to_world(bs.wi);
        if wi.dot(ng_side) <= 0.0 {
            return l;
        }
        let Some(hit2) = self.accel.intersect(p_off, wi, 0.0, f32::INFINITY) else {
            let le = scene.environment.radiance(wi);
            let w = power_heuristic(bs.pdf, self.lights.pdf_environment(&scene.environment, wi));
            return l + bs.weight * le * w;
        };
        let sh2 = self.surface(&hit2, p_off, wi);
        let le2 = emitted_filtered(scene, hit2.prim, hit2.bary, -wi, None);
        if le2 != Vec3::ZERO {
            let w = power_heuristic(bs.pdf, self.lights.pdf_triangle(hit2.prim, sh.p, sh2.p, sh2.ng));
            l += bs.weight * le2 * w;
        }
        if s.max_depth >= 3 {
            l += bs.weight * self.second_vertex_light(rest, p_off, wi, &hit2, rng);
        }
        l
    }

    /// The light a camera path's second vertex `hit` (reached from `o` along `d`) reflects
    /// back along the path, within the segments `max_depth` leaves it: a traced path, one
    /// segment shorter than the camera's, with a shadow ray per delta light. (The surface
    /// grids hold a first vertex's light, one bounce more; the radiance cache's lattice blurs
    /// the shadows; the shadow grids would be laid at pixel density over every surface a
    /// reflection shows.)
    fn second_vertex_light(&self, rest: &PathRest, o: Vec3, d: Vec3, hit: &Hit, rng: &mut SampleStream) -> Vec3 {
        // its emission there is the caller's (weighed against its light sample)
        let mut first = FirstHit::new(-d);
        let path = self.li_first(o, d, &rest.0, rng, &mut first, None, Some(Some(*hit)), None, PathMode::Full);
        if path.is_finite() {
            (path - first.emission).max(Vec3::ZERO)
        } else {
            Vec3::ZERO
        }
    }

    /// Compute triangle `prim`'s `front` (or back) side's surface grid: per point, the
    /// non-delta light reflected there per unit reflectance hint ([`Renderer::fill_point`],
    /// `surface_paths` paths ending at their second vertex in the radiance cache `cache`).
    fn fill_surface(&self, surface: &SurfaceCache, cache: Option<&RadianceCache>, prim: u32, front: bool) -> Grid {
        let p = surface.params;
        let spec = FillSpec {
            paths: p.paths,
            spacing: p.spacing,
            mode: PathMode::SurfaceFill,
            path_cache: cache,
            salt: SURFACE_SALT,
        };
        let corners = self.scene.mesh.corners(prim as usize);
        let Some(n) = side_normal(corners, front) else {
            return Grid::over(corners, 0.0, 1, |_, _| Vec3::ZERO);
        };
        let s = super::fill_settings(&p.path, &spec);
        let side = prim as u64 * 2 + u64::from(!front) + spec.salt;
        Grid::over(corners, p.spacing, MAX_SURFACE_CELLS, |k, q| {
            self.fill_point(&p.path, &spec, &s, prim, n, q, pixel_key(p.path.seed ^ super::CACHE_SALT, side, k))
        })
    }

    /// Compute triangle `prim`'s `front` (or back) side's glossy grid for the keyframe `frame`:
    /// per point (the surface grid's spacing), the light but the delta lights' that the
    /// point's BSDF reflects towards the keyframe's camera, per unit reflectance hint, from
    /// `frame.paths` paths ([`Renderer::glossy_path`]) whose random streams are keyed by the
    /// point alone: the same in every keyframe, so the grids of neighbouring keyframes differ
    /// by the change of view, not by noise.
    fn fill_glossy(
        &self,
        s: &RenderSettings,
        surface: &SurfaceCache,
        prim: u32,
        front: bool,
        frame: &GlossyFrame,
    ) -> Grid {
        let corners = self.scene.mesh.corners(prim as usize);
        let Some(n) = side_normal(corners, front) else {
            return Grid::over(corners, 0.0, 1, |_, _| Vec3::ZERO);
        };
        let p = surface.params;
        let side = prim as u64 * 2 + u64::from(!front);
        let rest = PathRest::new(s);
        Grid::over(corners, p.spacing, MAX_SURFACE_CELLS, |k, q| {
            let origin = offset_origin(q, n);
            let Some(hit) = self.accel.intersect_triangle(prim, origin, -n, 0.0, f32::INFINITY) else {
                return Vec3::ZERO;
            };
            let sh = self.surface(&hit, origin, -n);
            let Some(view) = (frame.origin - sh.p).try_normalize() else { return Vec3::ZERO };
            let wo = sh.frame.to_local(view);
            if wo.z <= 0.0 {
                return Vec3::ZERO;
            }
            let bsdf = self.bsdf(prim, sh.uv, None);
            let hint = bsdf.albedo_hint().max(Vec3::splat(super::MIN_REFLECTANCE));
            let smp = Sample { hit, sh, bsdf, wo, pixel: 0 };
            let key = pixel_key(p.path.seed ^ GLOSSY_GRID_SALT, side, k);
            let mut refl = Vec3::ZERO;
            for j in 0..frame.paths {
                let mut rng = SampleStream::new(p.path.sampler, key, j);
                let l = self.glossy_path(s, &smp, &rest, &mut rng);
                if l.is_finite() {
                    refl += l / hint;
                }
            }
            refl / frame.paths as f32
        })
    }

    /// Compute triangle `prim`'s `front` (or back) side's shadow grid: per point, whether
    /// each of the first three delta lights is visible (1) or not (0), with cells of half the
    /// smallest pixel footprint the camera path gives the triangle.
    fn fill_shadow(&self, surface: &SurfaceCache, prim: u32, front: bool) -> Grid<[u8; 3]> {
        let corners = self.scene.mesh.corners(prim as usize);
        let [a, b, c] = corners;
        let near = surface.cameras.iter().map(|&o| distance_to_triangle(o, a, b, c)).fold(f32::INFINITY, f32::min);
        let spacing = 0.5 * near.max(1e-4) * surface.pixel_angle;
        let Some(n) = side_normal(corners, front) else {
            return Grid::over(corners, 0.0, 1, |_, _| [0; 3]);
        };
        Grid::over(corners, spacing, MAX_SHADOW_STEPS, |_, q| {
            let p_off = offset_origin(q, n);
            let mut v = [0u8; 3];
            for (k, ls) in self.lights.delta_incident_indexed(self.scene, q).filter(|(k, _)| *k < 3) {
                let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) - 1e-4 } else { f32::INFINITY };
                v[k] = u8::from(ls.wi.dot(n) > 0.0 && !self.accel.occluded(p_off, ls.wi, 0.0, tmax));
            }
            v
        })
    }

    /// Length of the diagonal of the scene's bounding box.
    pub(crate) fn scene_diagonal(&self) -> f32 {
        let (lo, hi) = self
            .scene
            .mesh
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        (hi - lo).length()
    }
}

#[path = "surface_grid.rs"]
mod grid;
pub use grid::*;

#[cfg(test)]
#[path = "surface_tests.rs"]
mod tests;
