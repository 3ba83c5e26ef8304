//! The camera rays of a pixel that only record their first hit (the filters' guide buffers:
//! the `feature_spp - spp` rays after the shaded ones, see [`RenderSettings::feature_spp`]).
//!
//! These rays come from the visibility buffer with their triangle known, and a pixel's rays
//! mostly share one or two triangles. So the rays are grouped by triangle: each group sets its
//! triangle up once for the camera's origin and the pixel ([`OriginTri`]), after which a ray's
//! barycentrics are a few multiply-adds and a division (the rays' directions are affine in the
//! film point), and reads the material once where it has no texture. Each ray still reads the
//! textures at its own point (the reflectance buffer stays a box-filtered supersample of the
//! pixel), textured emission included; the hit distance and shading normal, which vary
//! smoothly across a pixel, are taken once per group at the mean of its rays' film points and
//! count once per ray.
//!
//! Emission matters: taken at the mean film point, a textured emitter (a screen, a sign) is
//! point-sampled instead of supersampled, its texture aliases and flickers as the camera
//! moves, and since directly seen light bypasses the temporal window, that fires events
//! (factory at 300x200, radius 16, 4 spp: noise-induced events 11.3% -> 16.6%; 11.3% again with
//! emission per ray).
//! Rays the buffer does not settle (nothing covers them, texture filtering on, a triangle seen
//! edge-on, more than [`GROUPS`] triangles in the pixel) take [`Renderer::first_hit`] one by
//! one on a traced or intersected hit.

use glam::{Vec2, Vec3};

use super::{FirstHit, Renderer};
use crate::render::accel::Hit;
use crate::render::film::RenderSettings;
use crate::render::raster::Visibility;
use crate::render::sampler::SampleStream;
use crate::scene::FilmRays;

/// Triangles per pixel whose rays are grouped; rays on further triangles go one by one.
const GROUPS: usize = 4;

/// A triangle set up to intersect rays from one origin `o`: with `n = e1 x e2`, the ray
/// `o + t d` meets its plane at `t = c / (d . n)` and has barycentrics `b_i = k_i + t (d . a_i)`,
/// where `c = (v0 - o) . n`, `a1 = (e2 x n) / |n|^2`, `a2 = (n x e1) / |n|^2` and
/// `k_i = (o - v0) . a_i` (for any length of `d`: `t` is then in units of `|d|`).
struct OriginTri {
    prim: u32,
    edges: [Vec3; 2],
    n: Vec3,
    c: f32,
    a: [Vec3; 2],
    k: [f32; 2],
    /// The reflectance hint and emission, when the same at every point of the triangle (no
    /// texture for them).
    albedo: Option<Vec3>,
    emission: Option<Vec3>,
}

impl OriginTri {
    /// The barycentrics of the ray along `d` (clamped into the triangle as the traced hits'
    /// are) given `d . n`, `d . a1` and `d . a2`, and its distance in units of `|d|`; None when
    /// the ray runs parallel to the plane or meets it behind the origin.
    #[inline]
    fn bary(&self, [dn, da1, da2]: [f32; 3]) -> Option<(f32, Vec2)> {
        let t = self.c / dn;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        let b1 = (self.k[0] + t * da1).clamp(0.0, 1.0);
        let b2 = (self.k[1] + t * da2).clamp(0.0, 1.0 - b1);
        Some((t, Vec2::new(b1, b2)))
    }

    /// `d . n`, `d . a1` and `d . a2`.
    #[inline]
    fn dots(&self, d: Vec3) -> [f32; 3] {
        [d.dot(self.n), d.dot(self.a[0]), d.dot(self.a[1])]
    }
}

/// The rays of one pixel on one triangle.
struct Group {
    tri: OriginTri,
    /// [`OriginTri::dots`] of the pixel corner's direction and their steps per pixel along x and y
    /// (they are affine in the film point).
    dots: [[f32; 3]; 3],
    rays: u32,
    offsets: Vec2,
    albedo: Vec3,
    /// Sum of the rays' emission when the triangle's is textured (else unused).
    emission: Vec3,
}

/// What [`Renderer::first_hit_rays`] adds its rays' first hits to.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct FirstHitSums {
    pub albedo: Vec3,
    pub normal: Vec3,
    pub depth: f32,
    /// Over the `rays` rays only.
    pub emission: Vec3,
    /// Rays in every sum.
    pub rays: u32,
    /// Shaded rays whose sample was dropped (not finite): in the reflectance, normal and
    /// distance sums, not in the emission's.
    pub dropped: u32,
}

impl Renderer<'_> {
    /// Add the first hits of pixel (`x`, `y`)'s camera rays `rays` (their film offsets and
    /// triangles from `vis` when it holds them, else from the pixel's sample streams, `key`) to
    /// `sums`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn first_hit_rays(
        &self,
        s: &RenderSettings,
        x: u32,
        y: u32,
        rays: std::ops::Range<u32>,
        vis: Option<&Visibility>,
        film_rays: &FilmRays,
        key: u64,
        sums: &mut FirstHitSums,
    ) {
        let origin = s.camera.origin();
        let corner = Vec2::new(x as f32, y as f32);
        let (d_corner, [step_x, step_y]) = (film_rays.unnormalised(corner), film_rays.steps());
        let mut groups: [Option<Group>; GROUPS] = [None, None, None, None];
        let grouping = self.camera_spread(s, corner).is_none();
        for i in rays {
            let known = vis.filter(|v| i < v.samples);
            let c = match known {
                Some(v) => v.offset(x, y, i),
                None => {
                    let c = SampleStream::new(s.sampler, key, i).next_4d();
                    Vec2::new(c[0], c[1])
                }
            };
            let prim = known.map(|v| v.prim(x, y, i));
            if let (Some(Some(p)), true) = (prim, grouping) {
                let slot = groups.iter().position(|g| g.as_ref().is_none_or(|g| g.tri.prim == p));
                if let Some(slot) = slot {
                    let g = groups[slot].get_or_insert_with(|| {
                        let tri = self.origin_tri(p, origin);
                        let dots = [tri.dots(d_corner), tri.dots(step_x), tri.dots(step_y)];
                        Group { tri, dots, rays: 0, offsets: Vec2::ZERO, albedo: Vec3::ZERO, emission: Vec3::ZERO }
                    });
                    let [d0, dx, dy] = g.dots;
                    let dots = [0, 1, 2].map(|k| d0[k] + c.x * dx[k] + c.y * dy[k]);
                    if let Some((_, bary)) = g.tri.bary(dots) {
                        if s.max_depth > 1 {
                            g.albedo += g.tri.albedo.unwrap_or_else(|| {
                                let uv = self.shading_uv(p, bary);
                                self.bsdf(p, uv, None).albedo_hint()
                            });
                        }
                        if g.tri.emission.is_none() {
                            // textured emission varies at texel scale: read it per ray, as
                            // the reflectance (the direction only decides the side)
                            let d = d_corner + step_x * c.x + step_y * c.y;
                            g.emission += super::emitted_filtered(self.scene, p, bary, -d, None);
                        }
                        g.rays += 1;
                        g.offsets += c;
                        continue;
                    }
                }
            }
            // one by one
            let film = corner + c;
            let dir = film_rays.direction(film);
            let mut first = FirstHit::new(-dir);
            let hit = self.camera_hit(prim, origin, dir);
            self.first_hit(hit, origin, dir, s, &mut first, self.camera_spread(s, film));
            sums.add(&first, 1);
        }
        // each group: distance, normal and emission at the mean film point
        for g in groups.iter().flatten().filter(|g| g.rays > 0) {
            let film = corner + g.offsets / g.rays as f32;
            let dir = film_rays.direction(film);
            let mut first = FirstHit::new(-dir);
            match g.tri.bary(g.tri.dots(dir)) {
                Some((depth, bary)) => {
                    let hit = Hit { t: depth, prim: g.tri.prim, bary, edges: g.tri.edges };
                    first.normal = self.shading_normal_uv(&hit, dir, || g.tri.n.normalize()).0;
                    first.depth = depth;
                    first.emission = g.tri.emission.unwrap_or(g.emission / g.rays as f32);
                }
                None => {
                    // the mean film point falls off the triangle's plane (seen edge-on): trace it
                    let hit = self.camera_hit(Some(Some(g.tri.prim)), origin, dir);
                    self.first_hit(hit, origin, dir, s, &mut first, None);
                }
            }
            first.albedo = g.albedo / g.rays as f32;
            sums.add(&first, g.rays);
        }
    }

    /// Triangle `prim` set up for rays from `o` (see [`OriginTri`]).
    fn origin_tri(&self, prim: u32, o: Vec3) -> OriginTri {
        let [v0, v1, v2] = self.scene.mesh.corners(prim as usize);
        let (e1, e2) = (v1 - v0, v2 - v0);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        let a = [e2.cross(n) / n2, n.cross(e1) / n2];
        let w0 = o - v0;
        let mat = &self.scene.materials[self.shading[prim as usize].material as usize];
        // untextured: the reflectance hint and the emission (towards `o`: every ray from `o`
        // meets the plane from the same side) are the same at every point
        let albedo = (mat.base_color_texture.is_none() && mat.metallic_roughness_texture.is_none())
            .then(|| self.bsdf(prim, Vec2::ZERO, None).albedo_hint());
        let emission = (!mat.is_emissive() || mat.emission_texture.is_none())
            .then(|| super::emitted_filtered(self.scene, prim, Vec2::splat(1.0 / 3.0), w0, None));
        OriginTri { prim, edges: [e1, e2], n, c: -w0.dot(n), a, k: [w0.dot(a[0]), w0.dot(a[1])], albedo, emission }
    }
}

impl FirstHitSums {
    /// Add `first` as the hit of `rays` rays (its reflectance is their mean).
    #[inline]
    fn add(&mut self, first: &FirstHit, rays: u32) {
        let n = rays as f32;
        self.albedo += first.albedo * n;
        self.normal += first.normal * n;
        self.depth += first.depth * n;
        self.emission += first.emission * n;
        self.rays += rays;
    }
}
