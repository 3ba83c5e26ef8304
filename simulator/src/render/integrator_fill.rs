//! The radiance cache's side of the renderer: the cache a render asks for, its parameters, and
//! the fills of its lattices (paths from each lattice point, their settings and modes).

use super::*;

impl Renderer<'_> {
    /// The radiance cache `s` asks for (None when `s.radiance_cache` is 0 or paths are too
    /// short to reach a second bounce): the one already filled when its parameters match, else
    /// a new, empty one.
    pub fn radiance_cache(&self, s: &RenderSettings) -> Option<Arc<RadianceCache>> {
        if s.radiance_cache == 0 || s.max_depth < 3 {
            return None;
        }
        let params = self.cache_params(s, s.radiance_cache, s.cache_spacing, 128.0, s.cache_vertex == 1);
        let make = || RadianceCache::new(params, self.scene.mesh.len());
        Some(self.caches.radiance.get_or_make(|c| c.params == params, make))
    }

    /// Time spent so far on the fills of the caches held now, by kind: radiance-cache lattices
    /// (both), surface grids, shadow grids, glossy grids ([`super::radiance_cache::FillClock`]; a surface or glossy
    /// grid's time includes the lattices its paths filled).
    pub fn fill_times(&self) -> [(&'static str, FillTimes); 4] {
        let cache = self.caches.radiance.peek().map(|c| c.clock.times());
        let surface = self.caches.surface.peek().map(|c| c.clocks.each_ref().map(|k| k.times()));
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
    pub(super) fn fill_lattice(&self, cache: &RadianceCache, prim: u32, front: bool) -> Lattice {
        self.fill(cache, prim, front, false)
    }

    /// Compute triangle `prim`'s `front` (or back) side's lattice of `cache`: the second-vertex
    /// lattice, or with `indirect` the first-vertex one ([`RadianceCache::indirect_lattice`]:
    /// its paths are a camera path's, ending at their second vertex in the second-vertex
    /// lattice).
    pub(super) fn fill(&self, cache: &RadianceCache, prim: u32, front: bool, indirect: bool) -> Lattice {
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
    pub(super) fn fill_with(&self, p: &CacheParams, spec: &FillSpec, prim: u32, front: bool) -> Lattice {
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
}

/// The render settings of a lattice's paths (see [`Renderer::fill_point`]): `p`'s path settings,
/// with the first-vertex lattices' paths one segment longer (a camera path's).
pub(super) fn fill_settings(p: &CacheParams, spec: &FillSpec) -> RenderSettings {
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
    pub(super) paths: u32,
    /// Lattice spacing (world units).
    pub(super) spacing: f32,
    /// What the paths compute.
    pub(super) mode: PathMode,
    /// The cache the paths end in at their second vertex.
    pub(super) path_cache: Option<&'c RadianceCache>,
    /// Added to the side's key: keeps the random streams of different lattices apart.
    pub(super) salt: u64,
}

impl PathMode {
    /// The mode of a camera path with `cache`.
    pub(super) fn camera(cache: Option<&RadianceCache>) -> PathMode {
        if cache.is_some_and(|c| c.params.first) {
            PathMode::Camera
        } else {
            PathMode::Full
        }
    }
}

/// Salt of the radiance cache's random streams (keeps them apart from the camera samples').
pub(super) const CACHE_SALT: u64 = 0x7ac4_e5c0_ffee_d00d;
