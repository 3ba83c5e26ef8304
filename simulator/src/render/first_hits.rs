//! The camera rays of a pixel that only record their first hit (the filters' guide buffers:
//! the `feature_spp - spp` rays after the shaded ones, see [`RenderSettings::feature_spp`]).
//!
//! These rays come from the visibility buffer with their triangle known: each is intersected
//! with that one triangle ([`Renderer::camera_hit`]) and records its hit as a shaded camera ray
//! would ([`Renderer::first_hit`]). Grouping a pixel's rays by triangle (barycentrics from
//! affine dot products, distance, normal and emission once per group at the mean film point)
//! was about 0.1 s per 600x400 frame faster but raised the noise-induced events (factory at
//! 300x200, radius 16, 4 spp: 11.3% -> 16.6%), so it was taken out again.

use glam::{Vec2, Vec3};

use super::{FirstHit, Renderer, MISS_DEPTH};
use crate::render::film::RenderSettings;
use crate::render::raster::Visibility;
use crate::render::sampler::SampleStream;
use crate::scene::FilmRays;

/// What [`Renderer::first_hit_rays`] adds its rays' first hits to.
pub(super) struct FirstHitSums {
    pub albedo: Vec3,
    pub normal: Vec3,
    pub depth: f32,
    pub emission: Vec3,
    pub rays: u32,
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
            let film = corner + c;
            let dir = film_rays.direction(film);
            let mut first = FirstHit { albedo: Vec3::ZERO, normal: -dir, depth: MISS_DEPTH, emission: Vec3::ZERO };
            let hit = self.camera_hit(prim, origin, dir);
            self.first_hit(hit, origin, dir, s, &mut first, self.camera_spread(s, film));
            sums.add(&first, 1);
        }
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
