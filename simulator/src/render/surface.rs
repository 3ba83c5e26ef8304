//! Surface-cache frames: every frame of a sequence reads one converged estimate of the light
//! that surfaces reflect, so that a frame differs from the next only where the projection of
//! the scene differs, as a real camera's would.
//!
//! The scenes are static and only the camera moves, so the view-independent part of the light
//! (what a diffuse surface reflects: the environment, area lights, light via other surfaces) is
//! one field over the surfaces, the same in every frame. It is estimated once per sequence on a
//! barycentric lattice over every triangle side ([`super::radiance_cache::Lattice`]), with many
//! paths per point ([`RenderSettings::surface_paths`]) from random streams keyed by (seed,
//! triangle, side, point): the bytes do not depend on thread count, frame order or resume point.
//!
//! A camera sample ([`RenderSettings::feature_spp`] of them per pixel, from the rasterised
//! visibility buffer, the same film points in every frame) on a mostly diffuse surface
//! ([`super::bsdf::Bsdf::specular_share`] below one half) then takes, with no random number:
//! - the emission at its hit (lamps, screens, the sky where it escapes);
//! - the direct light of every delta light (the sun), with its BSDF and its visibility read
//!   from a *shadow lattice* over the triangle side, one shadow ray per point, at half the
//!   smallest pixel footprint the camera path gives the triangle: shadow edges stay sharp to
//!   half a pixel, and its highlights follow the view;
//! - its reflectance hint times the lattice's value at the hit (linear between points).
//!
//! The samples on a glossy or metal surface share, per triangle and pixel,
//! [`RenderSettings::glossy_paths`] paths spread over their hits: each adds the delta lights,
//! one light sample and one BSDF sample (multiple importance sampling), whose hit adds its
//! emission and the light it reflects as a diffuse sample would. Each sample takes that
//! reflected light per unit reflectance hint times its own hint. No image filter follows.

use std::sync::{Arc, OnceLock};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{offset_origin, FillSpec, PathMode, Renderer, SurfaceHit};
use crate::render::accel::Hit;
use crate::render::bsdf::Bsdf;
use crate::render::film::{Image, RenderSettings};
use crate::render::lights::emitted_filtered;
use crate::render::radiance_cache::{lattice_bary, lattice_index};
use crate::render::radiance_cache::{CacheParams, Lattice, RadianceCache};
use crate::render::raster::Visibility;
use crate::render::sampler::{pixel_key, SampleStream};
use crate::render::sampling::power_heuristic;

/// Added to a surface lattice side's key (apart from the radiance cache's lattices).
const SURFACE_SALT: u64 = 2 << 40;

/// Salt of the glossy paths' random streams (apart from the camera samples').
const GLOSSY_SALT: u64 = 0x6c05_5e00_0000_0001;

/// Most lattice steps along a triangle edge of a shadow lattice.
pub const MAX_SHADOW_STEPS: u32 = 2048;

/// A camera sample on a glossy surface, waiting for its triangle's reflection.
struct Sample {
    hit: Hit,
    sh: SurfaceHit,
    bsdf: Bsdf,
    wo: Vec3,
    /// Emission seen directly.
    le: Vec3,
}

/// Distance from `p` to the triangle `a`, `b`, `c` (closest point, Ericson's "Real-Time
/// Collision Detection" 5.1.5).
pub fn distance_to_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    let q = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else {
        let bp = p - b;
        let (d3, d4) = (ab.dot(bp), ac.dot(bp));
        let cp = p - c;
        let (d5, d6) = (ab.dot(cp), ac.dot(cp));
        let (vc, vb, va) = (d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4);
        if d3 >= 0.0 && d4 <= d3 {
            b
        } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            a + ab * (d1 / (d1 - d3))
        } else if d6 >= 0.0 && d5 <= d6 {
            c
        } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            a + ac * (d2 / (d2 - d6))
        } else if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
        } else {
            let denom = 1.0 / (va + vb + vc);
            a + ab * (vb * denom) + ac * (vc * denom)
        }
    };
    let d = (p - q).length();
    if d.is_finite() {
        d
    } else {
        0.0
    }
}

/// What a surface cache's values depend on besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceParams {
    /// Paths per lattice point.
    pub paths: u32,
    /// Lattice spacing (world units).
    pub spacing: f32,
    /// The settings of the paths (depth, roulette, clamping, light samples, seed).
    pub path: CacheParams,
}

/// The surface cache of one scene (see the [module docs](self)), filled lazily.
pub struct SurfaceCache {
    /// Its parameters.
    pub params: SurfaceParams,
    /// Per triangle, front and back side.
    sides: Vec<[OnceLock<Lattice>; 2]>,
    /// Per triangle side, the visibility of the first three delta lights (see
    /// [`Renderer::fill_shadow`]).
    shadows: Vec<[OnceLock<Lattice>; 2]>,
    /// Camera positions of the sequence (the shadow lattices' density follows the nearest).
    cameras: Vec<Vec3>,
    /// Radians per pixel of the film (vertical field of view over height).
    pixel_angle: f32,
}

impl SurfaceCache {
    /// The lattice of triangle `prim`'s `front` (or back) side, computed by `fill` on first use.
    #[inline]
    pub fn lattice(&self, prim: u32, front: bool, fill: impl FnOnce() -> Lattice) -> &Lattice {
        self.sides[prim as usize][usize::from(!front)].get_or_init(fill)
    }

    /// The shadow lattice of triangle `prim`'s `front` (or back) side, computed by `fill` on
    /// first use.
    #[inline]
    pub fn shadow(&self, prim: u32, front: bool, fill: impl FnOnce() -> Lattice) -> &Lattice {
        self.shadows[prim as usize][usize::from(!front)].get_or_init(fill)
    }

    /// Triangle sides filled so far and their lattice points.
    pub fn filled(&self) -> (usize, usize) {
        let lattices = self.sides.iter().flatten().filter_map(|s| s.get());
        lattices.fold((0, 0), |(n, p), l| (n + 1, p + l.values.len()))
    }
}

impl Renderer<'_> {
    /// The surface cache `s` asks for: the one already made when its parameters match, else a
    /// new, empty one.
    pub fn surface_cache(&self, s: &RenderSettings) -> Arc<SurfaceCache> {
        let spacing = if s.surface_spacing > 0.0 && s.surface_spacing.is_finite() {
            s.surface_spacing
        } else {
            (self.scene_diagonal() / 512.0).max(1e-6)
        };
        let path = CacheParams {
            paths: s.radiance_cache,
            spacing,
            seed: s.seed,
            sampler: s.sampler,
            max_depth: s.max_depth.saturating_sub(1),
            rr_depth: s.rr_depth.saturating_sub(1).max(1),
            clamp: s.clamp,
            light_samples: s.light_samples,
            first: false,
        };
        let params = SurfaceParams { paths: s.surface_paths.max(1), spacing, path };
        let mut slot = self.surface.lock().unwrap_or_else(|e| e.into_inner());
        let same_path = |c: &SurfaceCache| match &s.camera_path {
            Some(p) if !p.is_empty() => c.cameras[..] == p[..],
            _ => c.cameras == [s.camera.origin()],
        };
        match &*slot {
            Some(c) if c.params == params && same_path(c) => c.clone(),
            _ => {
                let sides = || (0..self.scene.mesh.len()).map(|_| [OnceLock::new(), OnceLock::new()]).collect();
                let cameras = match &s.camera_path {
                    Some(path) if !path.is_empty() => path.to_vec(),
                    _ => vec![s.camera.origin()],
                };
                let pixel_angle = s.camera.yfov / s.height.max(1) as f32;
                let c = Arc::new(SurfaceCache { params, sides: sides(), shadows: sides(), cameras, pixel_angle });
                *slot = Some(c.clone());
                c
            }
        }
    }

    /// Render one frame from the surface cache (see the [module docs](self)): `vis` is
    /// [`Renderer::visibility`] of `s`; every pixel is the mean of its `vis.samples` samples.
    pub fn render_surface(&self, s: &RenderSettings, vis: &Visibility) -> Image {
        let (w, h) = (s.width, s.height);
        let surface = self.surface_cache(s);
        let cache = self.radiance_cache(s);
        let cache = cache.as_deref();
        let film_rays = s.camera.film_rays(w, h);
        let rows: Vec<Vec<Vec3>> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut samples = Vec::with_capacity(vis.samples as usize);
                (0..w).map(|x| self.surface_pixel(s, x, y, vis, &film_rays, &surface, cache, &mut samples)).collect()
            })
            .collect();
        Image { width: w, height: h, pixels: rows.concat() }
    }

    /// One pixel of [`Renderer::render_surface`]: its samples shaded one by one from the
    /// lattices, and the glossy reflection of each triangle it sees traced once for all of
    /// that triangle's samples (`samples` is scratch space).
    #[allow(clippy::too_many_arguments)]
    fn surface_pixel(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        vis: &Visibility,
        film_rays: &crate::scene::FilmRays,
        surface: &SurfaceCache,
        cache: Option<&RadianceCache>,
        samples: &mut Vec<Sample>,
    ) -> Vec3 {
        let scene = self.scene;
        let origin = s.camera.origin();
        let n = vis.samples.max(1);
        samples.clear();
        let mut sum = Vec3::ZERO;
        for i in 0..vis.samples {
            let c = vis.offset(x, y, i);
            let film = Vec2::new(x as f32 + c.x, y as f32 + c.y);
            let dir = film_rays.direction(film);
            let Some(hit) = self.camera_hit(Some(vis.prim(x, y, i)), origin, dir) else {
                sum += scene.environment.radiance(dir);
                continue;
            };
            let sh = self.surface(&hit, origin, dir);
            let spread = self.camera_spread(s, film);
            let fp = spread.and_then(|sp| self.uv_footprint(&hit, &sh, origin, sp));
            let le = emitted_filtered(scene, hit.prim, hit.bary, -dir, fp);
            if s.max_depth < 2 {
                sum += le;
                continue;
            }
            let bsdf = self.bsdf(hit.prim, sh.uv, fp);
            let wo = sh.frame.to_local(-dir);
            if bsdf.specular_share(wo) >= 0.5 {
                // glossy: its reflection is traced below, once for the triangle's samples
                samples.push(Sample { hit, sh, bsdf, wo, le });
                continue;
            }
            sum += le + self.diffuse_light(s, &hit, &sh, &bsdf, wo, surface, cache);
        }
        if !samples.is_empty() {
            sum += self.glossy_samples(s, x, y, samples, surface, cache);
        }
        sum / n as f32
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
        let lattice = surface.lattice(hit.prim, sh.front, || {
            let p = surface.params;
            let spec = FillSpec {
                paths: p.paths,
                spacing: p.spacing,
                mode: PathMode::SurfaceFill,
                path_cache: cache,
                salt: SURFACE_SALT,
            };
            self.fill_with(&p.path, &spec, hit.prim, sh.front)
        });
        l + bsdf.albedo_hint() * lattice.at(hit.bary)
    }

    /// The direct light of the delta lights at a surface point, reflected towards `wo`: each
    /// light's BSDF value times its visibility from the shadow lattice (beyond three delta
    /// lights, a shadow ray each).
    fn delta_light(&self, hit: &Hit, sh: &SurfaceHit, bsdf: &Bsdf, wo: Vec3, surface: &SurfaceCache) -> Vec3 {
        let mut l = Vec3::ZERO;
        let ng_side = if sh.front { sh.ng } else { -sh.ng };
        let mut visibility = None;
        for (k, ls) in self.lights.delta_incident(self.scene, sh.p).enumerate() {
            if ls.wi.dot(ng_side) <= 0.0 {
                continue;
            }
            let f = bsdf.eval(wo, sh.frame.to_local(ls.wi));
            if f == Vec3::ZERO {
                continue;
            }
            let v = if k < 3 {
                let vis = *visibility.get_or_insert_with(|| {
                    surface.shadow(hit.prim, sh.front, || self.fill_shadow(surface, hit.prim, sh.front)).at(hit.bary)
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

    /// The glossy samples of a pixel: per triangle, `glossy_paths` paths spread over that
    /// triangle's samples (the reflection of the pixel's part of the triangle), each ending at
    /// its second vertex in the lattices; their reflected light per unit reflectance hint,
    /// times each sample's own hint, plus each sample's emission. Returns the sum.
    fn glossy_samples(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        samples: &[Sample],
        surface: &SurfaceCache,
        cache: Option<&RadianceCache>,
    ) -> Vec3 {
        let key = pixel_key(s.seed ^ GLOSSY_SALT, y as u64 * s.width as u64 + x as u64, s.frame);
        let mut prims: Vec<u32> = Vec::new();
        for smp in samples {
            if !prims.contains(&smp.hit.prim) {
                prims.push(smp.hit.prim);
            }
        }
        let paths = s.glossy_paths.max(1);
        let mut sum = Vec3::ZERO;
        for (g, &prim) in prims.iter().enumerate() {
            let group: Vec<&Sample> = samples.iter().filter(|o| o.hit.prim == prim).collect();
            let mut refl = Vec3::ZERO;
            for j in 0..paths {
                let smp = group[j as usize % group.len()];
                let mut rng = SampleStream::new(s.sampler, key, (g as u32) << 16 | j);
                let l = self.glossy_path(s, smp, surface, cache, &mut rng);
                let hint = smp.bsdf.albedo_hint().max(Vec3::splat(super::MIN_REFLECTANCE));
                if l.is_finite() {
                    refl += l / hint;
                }
            }
            refl /= paths as f32;
            for smp in group {
                sum += smp.le + smp.bsdf.albedo_hint() * refl;
            }
        }
        sum
    }

    /// One path of light reflected at the glossy sample `smp`: the delta lights (visibility
    /// from the shadow lattice), one light sample and one BSDF sample (multiple importance
    /// sampling, power heuristic), the BSDF sample's hit adding its emission and, with
    /// `max_depth` 3 or more, what it reflects from the lattices.
    fn glossy_path(
        &self,
        s: &RenderSettings,
        smp: &Sample,
        surface: &SurfaceCache,
        cache: Option<&RadianceCache>,
        rng: &mut SampleStream,
    ) -> Vec3 {
        let scene = self.scene;
        let (sh, bsdf, wo) = (&smp.sh, &smp.bsdf, smp.wo);
        let ng_side = if sh.front { sh.ng } else { -sh.ng };
        let p_off = offset_origin(sh.p, ng_side);
        // the delta lights, as on a diffuse surface but with the glossy BSDF
        let mut l = self.delta_light(&smp.hit, sh, bsdf, wo, surface);
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
            let bsdf2 = self.bsdf(hit2.prim, sh2.uv, None);
            let wo2 = sh2.frame.to_local(-wi);
            l += bs.weight * self.diffuse_light(s, &hit2, &sh2, &bsdf2, wo2, surface, cache);
        }
        l
    }

    /// Compute triangle `prim`'s `front` (or back) side's shadow lattice: per point, whether
    /// each of the first three delta lights is visible (1) or not (0), at a spacing of half
    /// the smallest pixel footprint the camera path gives the triangle.
    fn fill_shadow(&self, surface: &SurfaceCache, prim: u32, front: bool) -> Lattice {
        let [a, b, c] = self.scene.mesh.corners(prim as usize);
        let (e1, e2) = (b - a, c - a);
        let longest = e1.length().max(e2.length()).max((c - b).length());
        let near = surface.cameras.iter().map(|&o| distance_to_triangle(o, a, b, c)).fold(f32::INFINITY, f32::min);
        let spacing = 0.5 * near.max(1e-4) * surface.pixel_angle;
        let steps = if spacing > 0.0 && longest.is_finite() {
            ((longest / spacing).ceil() as u32).clamp(1, MAX_SHADOW_STEPS)
        } else {
            1
        };
        let mut values = vec![Vec3::ZERO; ((steps + 1) * (steps + 2) / 2) as usize];
        let Some(ng) = e1.cross(e2).try_normalize() else {
            return Lattice { steps, values };
        };
        let n = if front { ng } else { -ng };
        for j in 0..=steps {
            for i in 0..=steps - j {
                let bary = lattice_bary(steps, i, j);
                let p = a + e1 * bary.x + e2 * bary.y;
                let p_off = offset_origin(p, n);
                let mut v = [0.0f32; 3];
                for (k, ls) in self.lights.delta_incident(self.scene, p).take(3).enumerate() {
                    let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) - 1e-4 } else { f32::INFINITY };
                    v[k] = f32::from(u8::from(ls.wi.dot(n) > 0.0 && !self.accel.occluded(p_off, ls.wi, 0.0, tmax)));
                }
                values[lattice_index(steps, i, j)] = Vec3::from(v);
            }
        }
        Lattice { steps, values }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_triangle_is_the_brute_force_minimum() {
        let mut rng = crate::render::sampling::Rng::new(7, 1);
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
        for _ in 0..200 {
            let (a, b, c, p) = (v(), v(), v(), v());
            // brute force: the nearest of a fine barycentric grid over the triangle
            let n = 200;
            let mut best = f32::INFINITY;
            for i in 0..=n {
                for j in 0..=n - i {
                    let q = a + (b - a) * (i as f32 / n as f32) + (c - a) * (j as f32 / n as f32);
                    best = best.min((p - q).length());
                }
            }
            let d = distance_to_triangle(p, a, b, c);
            let step = (b - a).length().max((c - a).length()) / n as f32;
            assert!(d <= best + 1e-4 && d >= best - step - 1e-4, "{d} vs brute force {best}");
        }
    }
}
