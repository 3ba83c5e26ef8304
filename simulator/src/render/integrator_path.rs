//! The path: radiance along a camera ray (next-event estimation, MIS, Russian roulette,
//! the caches where paths end).

use super::*;

impl Renderer<'_> {
    /// [`Renderer::li`], also recording the camera ray's hit in `first` (left as it is when the
    /// ray escapes); with `spread` (see [`Renderer::camera_spread`]) the first hit's textures are
    /// filtered over the ray's footprint; with `camera_hit`, that is the first hit (else it is
    /// traced); with `cache`, the path ends at its second surface vertex with the cached
    /// reflected light there ([`crate::render::radiance_cache`]), or as `mode` says (see
    /// [`PathMode`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn li_first(
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

/// Sample clamping (Cycles' "clamp"): a contribution of a path with `segments` segments is
/// scaled so that its largest channel is at most `clamp`, except light reaching the camera
/// directly (`segments == 1`). `clamp <= 0` or infinite turns it off. Biased (it darkens rare,
/// very bright paths such as caustics and highlights of small lights) but removes the fireflies
/// that flicker from frame to frame and fire false events.
#[inline]
pub(super) fn clamp_after_camera(c: Vec3, segments: u32, clamp: f32) -> Vec3 {
    let m = c.max_element();
    if segments <= 1 || !(clamp > 0.0) || !clamp.is_finite() || m <= clamp {
        c
    } else {
        c * (clamp / m)
    }
}
