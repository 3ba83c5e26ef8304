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

use std::sync::{Arc, Mutex};

use glam::{Vec2, Vec3};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::accel::{Accel, BvhPreset, Hit};
use super::bsdf::Bsdf;
use super::film::{Image, RenderSettings};
use super::lights::{emitted_filtered, Lights};
use super::radiance_cache::{lattice_bary, lattice_index, steps_for, CacheParams, FillTimes, Lattice, RadianceCache};
use super::raster::{rasterise, FilmOffsets, Visibility};
use super::sampler::{pixel_key, SampleStream, SamplerKind};
use super::sampling::{power_heuristic, Frame};
use crate::scene::{FilmRays, Scene};

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
    /// The radiance cache of the last render that asked for one (kept while its parameters
    /// stay the same, so the frames of a sequence share it).
    cache: Mutex<Option<Arc<RadianceCache>>>,
    /// The film offsets of the last visibility buffer and what they depend on (see
    /// [`Renderer::film_offsets`]).
    film_offsets: Mutex<Option<(FilmKey, Arc<FilmOffsets>)>>,
    /// The surface cache of the last surface-cache render (kept while its parameters stay the
    /// same, see [`surface`]).
    surface: Mutex<Option<Arc<surface::SurfaceCache>>>,
}

/// What a film's camera-sample offsets depend on: width, height, samples per pixel, seed, frame
/// and sampler.
type FilmKey = (u32, u32, u32, u64, u64, SamplerKind);

/// The per-vertex data of one triangle that shading reads, packed (64 bytes).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct ShadingTri {
    normals: [Vec3; 3],
    uvs: [Vec2; 3],
    material: u32,
}

/// What the shading of a hit needs of its triangle alone (see [`Renderer::triangle_numbers`]).
#[derive(Clone, Copy)]
struct TriangleNumbers {
    /// The triangle.
    prim: u32,
    /// Its unit geometric normal.
    ng: Vec3,
    /// Its edges `v1 - v0` and `v2 - v0`.
    edges: [Vec3; 2],
    /// The edges' dot products: e1.e1, e1.e2, e2.e2.
    gram: [f32; 3],
    /// The Gram determinant (zero for a degenerate triangle).
    det: f32,
    /// The texture coordinate's edges `uv1 - uv0` and `uv2 - uv0`.
    uv_edges: [Vec2; 2],
}

/// Everything about a surface hit the shading needs.
struct SurfaceHit {
    p: Vec3,
    /// Unit geometric normal, CCW (not flipped).
    ng: Vec3,
    /// Shading frame, its normal flipped to the side of the incoming ray.
    frame: Frame,
    /// True when the ray arrived on the side the geometric normal points to.
    front: bool,
    uv: Vec2,
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
            cache: Mutex::new(None),
            film_offsets: Mutex::new(None),
            surface: Mutex::new(None),
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
        let key = (s.width, s.height, samples, s.seed, s.frame, s.sampler);
        let mut slot = self.film_offsets.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((k, offsets)) = &*slot {
            if *k == key {
                return offsets.clone();
            }
        }
        let offsets = Arc::new(FilmOffsets::new(s.width, s.height, samples, |x, y, out| {
            let key = pixel_key(s.seed, y as u64 * s.width as u64 + x as u64, s.frame);
            for (i, o) in out.iter_mut().enumerate() {
                *o = Vec2::from(SampleStream::new(s.sampler, key, i as u32).next_2d());
            }
        }));
        *slot = Some((key, offsets.clone()));
        offsets
    }

    /// Mean of `spp` box-filtered samples of pixel (x, y) (full paths: no radiance cache).
    pub fn pixel(&self, s: &RenderSettings, x: u32, y: u32) -> Vec3 {
        self.pixel_color(s, x, y, None)
    }

    /// The radiance cache `s` asks for (None when `s.radiance_cache` is 0 or paths are too
    /// short to reach a second bounce): the one already filled when its parameters match, else
    /// a new, empty one.
    pub fn radiance_cache(&self, s: &RenderSettings) -> Option<Arc<RadianceCache>> {
        if s.radiance_cache == 0 || s.max_depth < 3 {
            return None;
        }
        let params = self.cache_params(s, s.radiance_cache, s.cache_spacing, 128.0, s.cache_vertex == 1);
        let mut slot = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        match &*slot {
            Some(c) if c.params == params => Some(c.clone()),
            _ => {
                let c = Arc::new(RadianceCache::new(params, self.scene.mesh.len()));
                *slot = Some(c.clone());
                Some(c)
            }
        }
    }

    /// Time spent so far on the fills of the caches held now, by kind: radiance-cache lattices
    /// (both), surface grids, shadow grids, glossy grids ([`super::radiance_cache::FillClock`]; a surface or glossy
    /// grid's time includes the lattices its paths filled).
    pub fn fill_times(&self) -> [(&'static str, FillTimes); 4] {
        let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map(|c| c.clock.times());
        let surface = self
            .surface
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .map(|c| c.clocks.each_ref().map(|k| k.times()));
        let [grids, shadows, glossy] = surface.unwrap_or_default();
        [
            ("radiance cache", cache.unwrap_or_default()),
            ("surface grids", grids),
            ("shadow grids", shadows),
            ("glossy grids", glossy),
        ]
    }

    /// The parameters of a cache's paths for the render settings `s`: `paths` per point,
    /// `spacing` (0 or not finite: the scene's diagonal over `divisor`), and `s`'s path
    /// settings, the paths starting one segment later than the camera's.
    pub(crate) fn cache_params(
        &self,
        s: &RenderSettings,
        paths: u32,
        spacing: f32,
        divisor: f32,
        first: bool,
    ) -> CacheParams {
        let spacing =
            if spacing > 0.0 && spacing.is_finite() { spacing } else { (self.scene_diagonal() / divisor).max(1e-6) };
        CacheParams {
            paths,
            spacing,
            seed: s.seed,
            sampler: s.sampler,
            max_depth: s.max_depth.saturating_sub(1),
            rr_depth: s.rr_depth.saturating_sub(1).max(1),
            clamp: s.clamp,
            light_samples: s.light_samples,
            first,
        }
    }

    /// Compute the lattice of triangle `prim`'s `front` (or back) side for `cache` (see
    /// [`crate::render::radiance_cache`]).
    fn fill_lattice(&self, cache: &RadianceCache, prim: u32, front: bool) -> Lattice {
        self.fill(cache, prim, front, false)
    }

    /// Compute triangle `prim`'s `front` (or back) side's lattice of `cache`: the second-vertex
    /// lattice, or with `indirect` the first-vertex one ([`RadianceCache::indirect_lattice`]:
    /// its paths are a camera path's, ending at their second vertex in the second-vertex
    /// lattice).
    fn fill(&self, cache: &RadianceCache, prim: u32, front: bool, indirect: bool) -> Lattice {
        let p = cache.params;
        let spec = if indirect {
            FillSpec {
                paths: p.paths,
                spacing: p.spacing,
                mode: PathMode::IndirectFill,
                path_cache: Some(cache),
                salt: 1 << 40,
            }
        } else {
            FillSpec { paths: p.paths, spacing: p.spacing, mode: PathMode::Full, path_cache: None, salt: 0 }
        };
        self.fill_with(&p, &spec, prim, front)
    }

    /// Compute a lattice over triangle `prim`'s `front` (or back) side as `spec` says, with the
    /// path settings of `p`: each point's value is the light its paths reflect (minus the
    /// point's emission) over their reflectance hint, averaged over `spec.paths` paths.
    fn fill_with(&self, p: &CacheParams, spec: &FillSpec, prim: u32, front: bool) -> Lattice {
        let [a, b, c] = self.scene.mesh.corners(prim as usize);
        let (e1, e2) = (b - a, c - a);
        let longest = e1.length().max(e2.length()).max((c - b).length());
        let steps = steps_for(longest, spec.spacing);
        let mut values = vec![Vec3::ZERO; ((steps + 1) * (steps + 2) / 2) as usize];
        let Some(ng) = e1.cross(e2).try_normalize() else {
            return Lattice { steps, values };
        };
        let n = if front { ng } else { -ng };
        let s = fill_settings(p, spec);
        let side = prim as u64 * 2 + u64::from(!front) + spec.salt;
        for j in 0..=steps {
            for i in 0..=steps - j {
                let k = lattice_index(steps, i, j);
                let bary = lattice_bary(steps, i, j);
                let x = a + e1 * bary.x + e2 * bary.y;
                values[k] = self.fill_point(p, spec, &s, prim, n, x, pixel_key(p.seed ^ CACHE_SALT, side, k as u64));
            }
        }
        Lattice { steps, values }
    }

    /// One point of a lattice ([`Renderer::fill_with`]): the light reflected at `x` on
    /// triangle `prim` (side facing `n`) over its reflectance hint, averaged over `spec.paths`
    /// paths of the stream `key`, with the settings `s` ([`fill_settings`]). Zero where the ray
    /// shot at `x` misses the triangle.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn fill_point(
        &self,
        p: &CacheParams,
        spec: &FillSpec,
        s: &RenderSettings,
        prim: u32,
        n: Vec3,
        x: Vec3,
        key: u64,
    ) -> Vec3 {
        let origin = offset_origin(x, n);
        let dir = -n;
        let Some(hit) = self.accel.intersect_triangle(prim, origin, dir, 0.0, f32::INFINITY) else {
            return Vec3::ZERO;
        };
        let (mut refl, mut albedo) = (Vec3::ZERO, Vec3::ZERO);
        for path in 0..spec.paths {
            let mut rng = SampleStream::new(p.sampler, key, path);
            let mut first = FirstHit::new(n);
            let l =
                self.li_first(origin, dir, s, &mut rng, &mut first, None, Some(Some(hit)), spec.path_cache, spec.mode);
            if l.is_finite() {
                refl += (l - first.emission).max(Vec3::ZERO);
                albedo += first.albedo;
            }
        }
        refl / albedo.max(Vec3::splat(MIN_REFLECTANCE))
    }

    /// The colour of pixel (`x`, `y`): the mean of its `spp` traced samples.
    fn pixel_color(&self, s: &RenderSettings, x: u32, y: u32, cache: Option<&RadianceCache>) -> Vec3 {
        let (shade, feats) = self.pixel_sums(s, x, y, 0, None, cache);
        finish_pixel(&shade, &feats).0
    }

    /// The sums a pixel's colour and first-hit features are finished from ([`finish_pixel`]):
    /// its first `spp` camera rays shaded and all `max(spp, feature_spp)` rays' first hits; with
    /// `vis`, the rays' first triangles come from it (see [`Renderer::camera_hit`]).
    fn pixel_sums(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        feature_spp: u32,
        vis: Option<&Visibility>,
        cache: Option<&RadianceCache>,
    ) -> (ShadeSums, FirstHitSums) {
        let key = pixel_key(s.seed, y as u64 * s.width as u64 + x as u64, s.frame);
        let film_rays = s.camera.film_rays(s.width, s.height);
        let mut shade = ShadeSums::default();
        let mut feats = FirstHitSums::default();
        self.shade_samples(s, x, y, 0..s.spp, vis, cache, key, &film_rays, &mut shade, Some(&mut feats));
        // the camera rays that only see the first hit
        self.first_hit_rays(s, x, y, s.spp..s.spp.max(feature_spp), vis, &film_rays, key, &mut feats);
        (shade, feats)
    }

    /// Shade camera samples `samples` of pixel (`x`, `y`) into `shade`, adding their first hits
    /// to `feats` when given (not for samples whose first hits are already in them: adaptive
    /// samples shade rays that were first-hit-only rays).
    #[allow(clippy::too_many_arguments)]
    fn shade_samples(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        samples: std::ops::Range<u32>,
        vis: Option<&Visibility>,
        cache: Option<&RadianceCache>,
        key: u64,
        film_rays: &FilmRays,
        shade: &mut ShadeSums,
        mut feats: Option<&mut FirstHitSums>,
    ) {
        let origin = s.camera.origin();
        for i in samples {
            let mut rng = SampleStream::new(s.sampler, key, i);
            // the film offset: from the visibility buffer when it holds this sample
            let c = match vis.filter(|v| i < v.samples) {
                Some(v) => {
                    rng.skip_4d();
                    v.offset(x, y, i)
                }
                None => {
                    let c = rng.next_4d();
                    Vec2::new(c[0], c[1])
                }
            };
            let film = Vec2::new(x as f32 + c.x, y as f32 + c.y);
            let dir = film_rays.direction(film);
            let mut first = FirstHit::new(-dir);
            let spread = self.camera_spread(s, film);
            let hit = self.camera_hit(vis.filter(|v| i < v.samples).map(|v| v.prim(x, y, i)), origin, dir);
            let l =
                self.li_first(origin, dir, s, &mut rng, &mut first, spread, Some(hit), cache, PathMode::camera(cache));
            shade.attempted += 1;
            if let Some(f) = feats.as_deref_mut() {
                f.albedo += first.albedo;
                f.normal += first.normal;
                f.depth += first.depth;
            }
            // a non-finite sample would poison the pixel: drop it (counts as black)
            if !l.is_finite() {
                if let Some(f) = feats.as_deref_mut() {
                    f.dropped += 1;
                }
                continue;
            }
            shade.add(l, &first);
            if let Some(f) = feats.as_deref_mut() {
                f.emission += first.emission;
                f.rays += 1;
            }
        }
    }

    /// Directions of the camera rays through film points `texture_filter` pixels right of and
    /// below `film`: the spread of the camera ray through `film` that textures are filtered
    /// over (None when `texture_filter` is 0, off).
    fn camera_spread(&self, s: &RenderSettings, film: Vec2) -> Option<[Vec3; 2]> {
        let k = s.texture_filter;
        (k > 0.0 && k.is_finite())
            .then(|| [Vec2::new(k, 0.0), Vec2::new(0.0, k)].map(|o| s.camera.direction(film + o, s.width, s.height)))
    }

    /// How the texture coordinate changes across the spread of a camera ray (see
    /// [`Renderer::camera_spread`]) at its hit `sh`: the two neighbour rays are cut with the hit
    /// triangle's plane and the offsets expressed in the triangle's texture coordinates (pbrt's
    /// ray differentials). None where a neighbour ray misses the plane.
    fn uv_footprint(&self, hit: &Hit, sh: &SurfaceHit, origin: Vec3, spread: [Vec3; 2]) -> Option<(Vec2, Vec2)> {
        Self::uv_footprint_on(&self.triangle_numbers(hit), sh, origin, spread)
    }

    /// [`Renderer::uv_footprint`] with the hit triangle's numbers `tri` (the directions of
    /// `spread` need not be unit).
    #[inline]
    fn uv_footprint_on(
        tri: &TriangleNumbers,
        sh: &SurfaceHit,
        origin: Vec3,
        spread: [Vec3; 2],
    ) -> Option<(Vec2, Vec2)> {
        let TriangleNumbers { edges: [e1, e2], gram: [a11, a12, a22], det, uv_edges: [dt1, dt2], .. } = *tri;
        if !(det > 0.0) {
            return None;
        }
        let plane = sh.ng.dot(sh.p - origin);
        let [du, dv] = spread.map(|d| {
            let cos = sh.ng.dot(d);
            let t = plane / cos;
            // the offset on the plane in barycentric steps along the edges (least squares)
            let dp = origin + d * t - sh.p;
            let (r1, r2) = (e1.dot(dp), e2.dot(dp));
            let (b1, b2) = ((a22 * r1 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det);
            // (the angle test: |cos| > 1e-6 for a unit direction)
            (t > 0.0 && cos * cos > 1e-12 * d.length_squared()).then(|| dt1 * b1 + dt2 * b2)
        });
        let (du, dv) = (du?, dv?);
        (du.is_finite() && dv.is_finite()).then_some((du, dv))
    }

    /// The numbers of `hit`'s triangle that [`Renderer::surface_on`] and
    /// [`Renderer::uv_footprint_on`] take: computed once for the samples of a pixel that hit
    /// the same triangle.
    #[inline]
    fn triangle_numbers(&self, hit: &Hit) -> TriangleNumbers {
        let [e1, e2] = hit.edges;
        let [t0, t1, t2] = self.shading[hit.prim as usize].uvs;
        let (a11, a12, a22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        TriangleNumbers {
            prim: hit.prim,
            ng: e1.cross(e2).normalize(),
            edges: hit.edges,
            gram: [a11, a12, a22],
            det: a11 * a22 - a12 * a12,
            uv_edges: [t1 - t0, t2 - t0],
        }
    }

    /// The first hit of a camera ray. `known` is what a visibility buffer says: `Some(Some(p))`
    /// when triangle `p` covers the ray's film point (the ray is intersected with it alone,
    /// exactly as the BVH would), `Some(None)` when nothing does; rays it cannot settle (no
    /// buffer, nothing covering, a miss of the covering triangle within float error) are traced.
    #[inline]
    fn camera_hit(&self, known: Option<Option<u32>>, origin: Vec3, dir: Vec3) -> Option<Hit> {
        known
            .flatten()
            .and_then(|p| self.accel.intersect_triangle(p, origin, dir, 0.0, f32::INFINITY))
            .or_else(|| self.accel.intersect(origin, dir, 0.0, f32::INFINITY))
    }

    /// Record the camera ray `dir`'s first hit `hit` in `first` (as [`Renderer::li_first`]
    /// does, without shading).
    fn first_hit(
        &self,
        hit: Option<Hit>,
        origin: Vec3,
        dir: Vec3,
        s: &RenderSettings,
        first: &mut FirstHit,
        spread: Option<[Vec3; 2]>,
    ) {
        let Some(hit) = hit else {
            first.emission = self.scene.environment.radiance(dir);
            return;
        };
        let (normal, uv, fp) = match spread {
            None => {
                let (ns, uv) = self.shading_normal_uv(&hit, dir, || hit.edges[0].cross(hit.edges[1]).normalize());
                (ns, uv, None)
            }
            Some(sp) => {
                let sh = self.surface(&hit, origin, dir);
                (sh.frame.n, sh.uv, self.uv_footprint(&hit, &sh, origin, sp))
            }
        };
        first.normal = normal;
        first.depth = hit.t;
        first.emission = emitted_filtered(self.scene, hit.prim, hit.bary, -dir, fp);
        if s.max_depth > 1 {
            first.albedo = self.bsdf(hit.prim, uv, fp).albedo_hint();
        }
    }

    /// Interpolated surface data at a hit, with the shading frame facing `-dir`.
    fn surface(&self, hit: &Hit, origin: Vec3, dir: Vec3) -> SurfaceHit {
        self.surface_on(hit, hit.edges[0].cross(hit.edges[1]).normalize(), origin, dir)
    }

    /// [`Renderer::surface`] given the triangle's unit geometric normal `ng`.
    #[inline]
    fn surface_on(&self, hit: &Hit, ng: Vec3, origin: Vec3, dir: Vec3) -> SurfaceHit {
        let front = ng.dot(dir) < 0.0;
        let (ns, uv) = self.shading_normal_uv(hit, dir, || ng);
        let p = origin + dir * hit.t;
        SurfaceHit { p, ng, frame: Frame::from_normal(ns), front, uv }
    }

    /// The interpolated shading normal at a hit, facing `-dir` (two-sided shading), and the
    /// texture coordinate; `ng()` is the unit geometric normal, the fallback for a degenerate
    /// interpolated normal.
    #[inline(always)]
    fn shading_normal_uv(&self, hit: &Hit, dir: Vec3, ng: impl FnOnce() -> Vec3) -> (Vec3, Vec2) {
        let tri = &self.shading[hit.prim as usize];
        let (b1, b2) = (hit.bary.x, hit.bary.y);
        let b0 = 1.0 - b1 - b2;
        let [n0, n1, n2] = tri.normals;
        let mut ns = (n0 * b0 + n1 * b1 + n2 * b2).try_normalize().unwrap_or_else(ng);
        // make the shading normal face the viewer (two-sided shading)
        if ns.dot(dir) > 0.0 {
            ns = -ns;
        }
        (ns, self.shading_uv(hit.prim, hit.bary))
    }

    /// The texture coordinate of triangle `prim` at barycentrics `bary` (b1, b2).
    #[inline(always)]
    fn shading_uv(&self, prim: u32, bary: Vec2) -> Vec2 {
        let [t0, t1, t2] = self.shading[prim as usize].uvs;
        let (b1, b2) = (bary.x, bary.y);
        t0 * (1.0 - b1 - b2) + t1 * b1 + t2 * b2
    }

    /// The BSDF of triangle `prim`'s material at texture coordinate `uv`, its textures filtered
    /// over the footprint `fp` (offsets of `uv`, see [`crate::scene::Texture::sample_footprint`])
    /// when given.
    fn bsdf(&self, prim: u32, uv: Vec2, fp: Option<(Vec2, Vec2)>) -> Bsdf {
        let mat = &self.scene.materials[self.shading[prim as usize].material as usize];
        let lookup = |t: crate::scene::TextureRef| {
            let tex = &self.scene.textures[t.index as usize];
            match fp {
                Some((du, dv)) => tex.sample_footprint(uv, du, dv),
                None => tex.sample(uv),
            }
        };
        let mut base = mat.base_color;
        if let Some(t) = mat.base_color_texture {
            base *= lookup(t).truncate();
        }
        let (mut metallic, mut roughness) = (mat.metallic, mat.roughness);
        if let Some(t) = mat.metallic_roughness_texture {
            let mr = lookup(t);
            roughness *= mr.y;
            metallic *= mr.z;
        }
        Bsdf::new(base, metallic, mat.specular, roughness)
    }

    /// Radiance arriving at `origin` from direction `dir` (one path sample).
    pub fn li(&self, origin: Vec3, dir: Vec3, s: &RenderSettings, rng: &mut SampleStream) -> Vec3 {
        let mut first = FirstHit::new(-dir);
        self.li_first(origin, dir, s, rng, &mut first, None, None, None, PathMode::Full)
    }

    /// [`Renderer::li`], also recording the camera ray's hit in `first` (left as it is when the
    /// ray escapes); with `spread` (see [`Renderer::camera_spread`]) the first hit's textures are
    /// filtered over the ray's footprint; with `camera_hit`, that is the first hit (else it is
    /// traced); with `cache`, the path ends at its second surface vertex with the cached
    /// reflected light there ([`crate::render::radiance_cache`]), or as `mode` says (see
    /// [`PathMode`]).
    #[allow(clippy::too_many_arguments)]
    fn li_first(
        &self,
        origin: Vec3,
        dir: Vec3,
        s: &RenderSettings,
        rng: &mut SampleStream,
        first: &mut FirstHit,
        spread: Option<[Vec3; 2]>,
        camera_hit: Option<Option<Hit>>,
        cache: Option<&RadianceCache>,
        mode: PathMode,
    ) -> Vec3 {
        let scene = self.scene;
        let mut l = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        let (mut o, mut d) = (origin, dir);
        // density of the BSDF sample that produced `d` (None for the camera ray: no MIS)
        let mut prev_bsdf_pdf: Option<f32> = None;
        let mut prev_p = origin;
        let mut depth = 0u32;
        // light samples per vertex (splitting): MIS weighs N light samples against one BSDF sample
        let n_ls = s.light_samples.max(1) as f32;
        loop {
            let hit = match camera_hit {
                Some(h) if depth == 0 => h,
                _ => self.accel.intersect(o, d, 0.0, f32::INFINITY),
            };
            depth += 1; // this segment
            let Some(hit) = hit else {
                // escaped: add the environment, MIS-weighted against environment sampling
                let le = scene.environment.radiance(d);
                if depth == 1 {
                    first.emission = le;
                }
                if le != Vec3::ZERO {
                    let w = match prev_bsdf_pdf {
                        None => 1.0,
                        Some(pb) => power_heuristic(pb, n_ls * self.lights.pdf_environment(&scene.environment, d)),
                    };
                    l += clamp_after_camera(beta * le * w, depth, s.clamp);
                }
                break;
            };
            let sh = self.surface(&hit, o, d);
            // texture footprint: camera rays only
            let fp = match spread {
                Some(sp) if depth == 1 => self.uv_footprint(&hit, &sh, o, sp),
                _ => None,
            };
            if depth == 1 {
                first.normal = sh.frame.n;
                first.depth = hit.t;
            }

            // add emission at the hit, MIS-weighted against area-light sampling
            let le = emitted_filtered(scene, hit.prim, hit.bary, -d, fp);
            if depth == 1 {
                first.emission = le;
            }
            if le != Vec3::ZERO {
                let w = match prev_bsdf_pdf {
                    None => 1.0,
                    // the first-vertex cache's paths: weighed against the camera samples' light
                    // samples, which pick emissive triangles alone
                    Some(pb) if mode == PathMode::IndirectFill && depth == 2 => {
                        power_heuristic(pb, n_ls * self.lights.pdf_triangle_bounded(hit.prim, prev_p, sh.p, sh.ng))
                    }
                    Some(pb) => power_heuristic(pb, n_ls * self.lights.pdf_triangle(hit.prim, prev_p, sh.p, sh.ng)),
                };
                l += clamp_after_camera(beta * le * w, depth, s.clamp);
            }
            if depth >= s.max_depth {
                break;
            }
            if let Some(cache) = cache.filter(|_| depth == 2) {
                let lattice = cache.lattice(hit.prim, sh.front, || self.fill_lattice(cache, hit.prim, sh.front));
                let albedo = self.bsdf(hit.prim, sh.uv, None).albedo_hint();
                l += clamp_after_camera(beta * albedo * lattice.at(hit.bary), depth + 1, s.clamp);
                break;
            }

            let bsdf = self.bsdf(hit.prim, sh.uv, fp);
            if depth == 1 {
                first.albedo = bsdf.albedo_hint();
            }
            let wo = sh.frame.to_local(-d);
            // side of the geometric normal the path is on; reflection must stay on it
            let ng_side = if sh.front { sh.ng } else { -sh.ng };
            let p_off = offset_origin(sh.p, ng_side);

            // this bounce's numbers: light sample + selection, BSDF sample + lobe + roulette
            let a = rng.next_4d();
            let b = rng.next_4d();
            let (u_light, u_sel) = (Vec2::new(a[0], a[1]), a[2]);
            let (u_dir, u_lobe, u_rr) = (Vec2::new(b[0], b[1]), b[2], b[3]);

            // next-event estimation: every delta light, plus `light_samples` lights sampled by
            // power (the first from `a`, further ones from fresh numbers after `b`, so that one
            // light sample consumes exactly the numbers it always did)
            // (drawn lazily, in order, without a heap allocation per vertex)
            // a first-vertex cache ends the path here where the surface is mostly diffuse:
            // emissive triangles alone are sampled (the environment is in the cache), weighed
            // against the BSDF samples of the cache's paths, which add what these leave out
            // (near an emitter: most of it)
            let end_cache = cache.filter(|_| mode == PathMode::Camera && depth == 1 && bsdf.specular_share(wo) < 0.5);
            // the first-vertex cache's paths: no delta light nor emitter at the first vertex
            let skip_direct = mode == PathMode::IndirectFill && depth == 1;
            // the surface cache's paths: no delta light at the first vertex
            let skip_delta = skip_direct || (mode == PathMode::SurfaceFill && depth == 1);
            let sample_light = |u_sel: f32, u: Vec2| match end_cache {
                Some(_) => self.lights.sample_bounded(scene, sh.p, u_sel, u),
                None => self.lights.sample(scene, sh.p, u_sel, u),
            };
            let first_sample = sample_light(u_sel, u_light);
            let more_samples = (1..s.light_samples.max(1)).map(|_| {
                let c = rng.next_4d();
                sample_light(c[2], Vec2::new(c[0], c[1]))
            });
            let sampled = std::iter::once(first_sample).chain(more_samples).flatten();
            let delta = self.lights.delta_incident(scene, sh.p).filter(|_| !skip_delta);
            for ls in delta.chain(sampled.filter(|ls| !(skip_direct && ls.dist.is_finite()))) {
                let wi_local = sh.frame.to_local(ls.wi);
                if ls.wi.dot(ng_side) > 0.0 {
                    let (f, bsdf_pdf) = bsdf.eval_and_pdf(wo, wi_local);
                    if f != Vec3::ZERO {
                        let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) - 1e-4 } else { f32::INFINITY };
                        if !self.accel.occluded(p_off, ls.wi, 0.0, tmax) {
                            // delta lights: once, no MIS; sampled lights: 1/N each, MIS with N
                            // (where the path ends here, the BSDF samples are the cache's)
                            let w = if ls.is_delta { 1.0 } else { power_heuristic(n_ls * ls.pdf, bsdf_pdf) / n_ls };
                            l += clamp_after_camera(beta * f * ls.radiance * (w / ls.pdf), depth + 1, s.clamp);
                        }
                    }
                }
            }

            if let Some(cache) = end_cache {
                let lattice = cache.indirect_lattice(hit.prim, sh.front, || self.fill(cache, hit.prim, sh.front, true));
                l += clamp_after_camera(beta * bsdf.albedo_hint() * lattice.at(hit.bary), depth + 1, s.clamp);
                break;
            }

            // continue the path along a BSDF sample
            let Some(bs) = bsdf.sample(wo, u_lobe, u_dir) else { break };
            let wi = sh.frame.to_world(bs.wi);
            if wi.dot(ng_side) <= 0.0 {
                break; // the shading normal sent the path through the surface
            }
            beta *= bs.weight;
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }

            // Russian roulette
            if depth >= s.rr_depth {
                let q = beta.max_element().min(0.95);
                if u_rr >= q {
                    break;
                }
                beta /= q;
            }
            prev_bsdf_pdf = Some(bs.pdf);
            prev_p = sh.p;
            o = p_off;
            d = wi;
        }
        l
    }
}

/// The render settings of a lattice's paths (see [`Renderer::fill_point`]): `p`'s path settings,
/// with the first-vertex lattices' paths one segment longer (a camera path's).
fn fill_settings(p: &CacheParams, spec: &FillSpec) -> RenderSettings {
    let mut s = RenderSettings::new(crate::scene::Camera::look_at(Vec3::ZERO, -Vec3::Z, Vec3::Y, 1.0));
    let longer = u32::from(spec.mode != PathMode::Full);
    s.max_depth = p.max_depth + longer;
    s.rr_depth = p.rr_depth + longer;
    s.clamp = p.clamp;
    s.light_samples = p.light_samples;
    s
}

/// What a path computes ([`Renderer::li_path`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PathMode {
    /// Everything: a full path, or with a cache, one ending at its second vertex.
    Full,
    /// A camera path with a first-vertex cache ([`CacheParams::first`]): where the first
    /// surface is mostly diffuse, the path ends there with its direct light from delta lights
    /// and emissive triangles plus the cached indirect light times the reflectance hint.
    Camera,
    /// A path of the first-vertex cache: without the direct light of delta lights and emissive
    /// triangles at its first vertex (the camera samples add those).
    IndirectFill,
    /// A path of the surface cache ([`surface`]): without the direct light of delta lights at
    /// its first vertex (the camera samples add that, shadow edges stay sharp).
    SurfaceFill,
}

/// How [`Renderer::fill_with`] fills a lattice.
pub(crate) struct FillSpec<'c> {
    /// Paths per lattice point.
    paths: u32,
    /// Lattice spacing (world units).
    spacing: f32,
    /// What the paths compute.
    mode: PathMode,
    /// The cache the paths end in at their second vertex.
    path_cache: Option<&'c RadianceCache>,
    /// Added to the side's key: keeps the random streams of different lattices apart.
    salt: u64,
}

impl PathMode {
    /// The mode of a camera path with `cache`.
    fn camera(cache: Option<&RadianceCache>) -> PathMode {
        if cache.is_some_and(|c| c.params.first) {
            PathMode::Camera
        } else {
            PathMode::Full
        }
    }
}

/// Depth recorded for camera rays that escape (far beyond any scene; world units).
pub const MISS_DEPTH: f32 = 1e6;

/// What a camera ray hit first.
struct FirstHit {
    /// Reflectance hint of the surface ([`Bsdf::albedo_hint`]); 0 for escaped rays (and at
    /// `max_depth` 1, where nothing is reflected).
    albedo: Vec3,
    /// Shading normal facing the camera; `-dir` for escaped rays.
    normal: Vec3,
    /// Distance along the ray ([`MISS_DEPTH`] for escaped rays).
    depth: f32,
    /// Radiance the camera ray sees directly: the hit's emission or, escaped, the environment.
    emission: Vec3,
}

impl FirstHit {
    /// Nothing hit yet; `normal` is the one recorded if the ray escapes.
    fn new(normal: Vec3) -> FirstHit {
        FirstHit { albedo: Vec3::ZERO, normal, depth: MISS_DEPTH, emission: Vec3::ZERO }
    }
}

/// One pixel's features: the means over its samples.
#[derive(Debug)]
struct PixelFeatures {
    albedo: Vec3,
    normal: Vec3,
    depth: f32,
    variance: f32,
    emission: Vec3,
    irradiance: Vec3,
}

/// Running sums over one pixel's shaded samples: radiance, reflected light (radiance minus
/// what the camera ray sees directly), the first-hit reflectance of the same samples, and the
/// moments of their luminances (for the variance of the ratio estimate).
#[derive(Clone, Copy, Debug, Default)]
struct ShadeSums {
    sum: Vec3,
    reflected: Vec3,
    refl_albedo: Vec3,
    r1: f64,
    r2: f64,
    a1: f64,
    a2: f64,
    ra: f64,
    /// Samples with a finite value.
    shaded: u32,
    /// Samples shot (the image is their mean; non-finite ones count as black).
    attempted: u32,
}

impl ShadeSums {
    /// Add a finite sample `l` whose camera ray hit `first`.
    #[inline]
    fn add(&mut self, l: Vec3, first: &FirstHit) {
        self.sum += l;
        let refl = (l - first.emission).max(Vec3::ZERO);
        self.reflected += refl;
        self.refl_albedo += first.albedo;
        let (r, a) = (luminance(refl) as f64, luminance(first.albedo) as f64);
        (self.r1, self.r2, self.a1, self.a2, self.ra) =
            (self.r1 + r, self.r2 + r * r, self.a1 + a, self.a2 + a * a, self.ra + r * a);
        self.shaded += 1;
    }

    /// The reflected light per unit reflectance (luminance) and the variance of one sample's
    /// estimate of it: the ratio estimate's residual variance over the squared mean reflectance
    /// (delta method); None below 2 samples.
    fn ratio_and_sample_variance(&self) -> Option<(f64, f64)> {
        let m = self.shaded as f64;
        if self.shaded < 2 {
            return None;
        }
        let e = self.r1 / self.a1.max(MIN_REFLECTANCE as f64 * m);
        let resid2 = (self.r2 - 2.0 * e * self.ra + e * e * self.a2).max(0.0);
        let a_mean = (self.a1 / m).max(MIN_REFLECTANCE as f64);
        Some((e, resid2 / (m - 1.0) / (a_mean * a_mean)))
    }
}

/// Adaptive sampling: the shaded samples each pixel gets in all (`spp..=spp_max`), from the
/// first `spp`: enough for the relative variance of its reflected light's estimate to reach
/// `adaptive_target`, judged by the per-sample relative variance averaged over the pixel's
/// 3x3 neighbourhood (a few samples per pixel are too few to judge one pixel by).
fn adaptive_spp(sums: &[(ShadeSums, FirstHitSums)], w: u32, h: u32, s: &RenderSettings) -> Vec<u32> {
    let rel: Vec<f32> = sums
        .par_iter()
        .map(|(shade, _)| match shade.ratio_and_sample_variance() {
            Some((e, v)) if e > 0.0 => (v / (e * e)) as f32,
            _ => 0.0,
        })
        .collect();
    let (w, h) = (w as usize, h as usize);
    let t = s.adaptive_variance;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (mut sum, mut n) = (0.0f32, 0u32);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    sum += rel[yy * w + xx];
                    n += 1;
                }
            }
            let want = (sum / n as f32 / t).ceil();
            if want.is_finite() {
                (want as u32).clamp(s.spp, s.spp_max)
            } else {
                s.spp_max
            }
        })
        .collect()
}

/// A pixel's colour and features from its sums (see [`Renderer::pixel_sums`]).
fn finish_pixel(shade: &ShadeSums, feats: &FirstHitSums) -> (Vec3, PixelFeatures) {
    let n = shade.attempted.max(1) as f32;
    let rays = (feats.rays + feats.dropped).max(1) as f32;
    let albedo = feats.albedo / rays;
    // reflected light per unit reflectance: a ratio over the same samples, so that texture
    // detail inside the pixel (which samples happened to land on) cancels out
    let irradiance = shade.reflected / shade.refl_albedo.max(Vec3::splat(MIN_REFLECTANCE));
    // variance of the pixel's reflected light `albedo * irradiance`: the ratio estimate's
    // (delta method) variance, scaled by the reflectance luminance
    let m = shade.shaded.max(1) as f64;
    let e = luminance(irradiance) as f64;
    let resid2 = (shade.r2 - 2.0 * e * shade.ra + e * e * shade.a2).max(0.0);
    let a_mean = (shade.a1 / m).max(MIN_REFLECTANCE as f64);
    let la = luminance(albedo) as f64;
    let variance = if shade.shaded > 1 { (resid2 / (m - 1.0) / m / (a_mean * a_mean) * la * la) as f32 } else { 0.0 };
    let features = PixelFeatures {
        albedo,
        normal: feats.normal.try_normalize().unwrap_or(Vec3::Z),
        depth: feats.depth / rays,
        variance,
        emission: feats.emission / feats.rays.max(1) as f32,
        irradiance,
    };
    (shade.sum / n, features)
}

/// Salt of the radiance cache's random streams (keeps them apart from the camera samples').
const CACHE_SALT: u64 = 0x7ac4_e5c0_ffee_d00d;

/// Smallest reflectance a pixel's reflected light is divided by.
const MIN_REFLECTANCE: f32 = 1e-3;

/// Per-pixel first-hit buffers of one render (row-major like [`Image`]), the guides of
/// [`crate::render::denoise`].
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Mean reflectance hint of the first hits (0 where rays escaped).
    pub albedo: Vec<Vec3>,
    /// Normalised mean shading normal of the first hits.
    pub normal: Vec<Vec3>,
    /// Mean first-hit distance ([`MISS_DEPTH`] for escaped rays).
    pub depth: Vec<f32>,
    /// Variance of the luminance of the pixel's reflected light `albedo * irradiance` (its
    /// sampling error over the `spp` shaded samples).
    pub variance: Vec<f32>,
    /// Mean radiance the camera rays see directly (emitters, the environment): not reflected
    /// light, so the filters leave it alone (a lamp's pixels must not bleed into the ceiling).
    pub emission: Vec<Vec3>,
    /// Reflected light per unit reflectance (demodulated): the shaded samples' radiance minus
    /// their directly seen emission, summed, over the sum of their reflectances. The filters
    /// smooth this and multiply it back by `albedo`; texture detail within a pixel does not
    /// enter it.
    pub irradiance: Vec<Vec3>,
    /// Shaded samples of the render, all pixels together (with adaptive sampling, more than
    /// `spp` per pixel; 0 where unknown).
    pub samples: u64,
}

impl Features {
    /// Empty buffers (albedo 1, normal +z, depth 0, variance 0, no emission, irradiance 0).
    pub fn new(width: u32, height: u32) -> Features {
        let n = (width * height) as usize;
        Features {
            width,
            height,
            albedo: vec![Vec3::ONE; n],
            normal: vec![Vec3::Z; n],
            depth: vec![0.0; n],
            variance: vec![0.0; n],
            emission: vec![Vec3::ZERO; n],
            irradiance: vec![Vec3::ZERO; n],
            samples: 0,
        }
    }

    /// Set `irradiance` from an image as `(pixel - emission) / albedo` per pixel (for images
    /// made without the renderer's per-sample buffers, such as test images).
    pub fn demodulate(&mut self, img: &Image) {
        for (i, c) in img.pixels.iter().enumerate() {
            self.irradiance[i] =
                (*c - self.emission[i]).max(Vec3::ZERO) / self.albedo[i].max(Vec3::splat(MIN_REFLECTANCE));
        }
    }
}

/// Rec.709 luminance of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Sample clamping (Cycles' "clamp"): a contribution of a path with `segments` segments is
/// scaled so that its largest channel is at most `clamp`, except light reaching the camera
/// directly (`segments == 1`). `clamp <= 0` or infinite turns it off. Biased (it darkens rare,
/// very bright paths such as caustics and highlights of small lights) but removes the fireflies
/// that flicker from frame to frame and fire false events.
#[inline]
fn clamp_after_camera(c: Vec3, segments: u32, clamp: f32) -> Vec3 {
    let m = c.max_element();
    if segments <= 1 || !(clamp > 0.0) || !clamp.is_finite() || m <= clamp {
        c
    } else {
        c * (clamp / m)
    }
}

/// Move a ray origin off the surface along the (side-correct) geometric normal, by an amount
/// that scales with the magnitude of the coordinates to stay above float error.
#[inline]
fn offset_origin(p: Vec3, n: Vec3) -> Vec3 {
    let eps = 1e-4 * p.abs().max_element().max(1.0);
    p + n * eps
}

#[path = "first_hits.rs"]
mod first_hits;
#[path = "surface.rs"]
pub mod surface;
use first_hits::FirstHitSums;

#[cfg(test)]
#[path = "integrator_tests.rs"]
mod tests;
