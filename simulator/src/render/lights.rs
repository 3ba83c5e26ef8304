//! Light sampling for next-event estimation.
//!
//! Every light is one entry of a single [`Distribution1D`]. As in pbrt-v4's BVH light sampler,
//! the *infinite* lights (environment, directional lights) and the group of all *bounded* lights
//! share the selection probability equally (`1 / (n_infinite + 1)` each), because an infinite
//! light's power (`pi r^2 ...`) says little about how much of it reaches a given point. Within
//! the bounded group, lights are chosen in proportion to their power `Phi`:
//! emissive triangle: `Phi = pi * A * lum(Le)` (doubled when two-sided), sampled uniformly by
//! area and converted to solid angle (`pdf = p_sel / A * d^2 / |cos theta_l|`).
//!
//! The environment's direction is then importance-sampled by its own map distribution.
//!
//! Punctual and directional lights are delta lights: they are reached only by NEE, never by
//! BSDF sampling, so their contribution needs no MIS weight. They are *not* in the selection
//! distribution: every shading point evaluates all of them ([`Lights::delta_incident`], one
//! shadow ray each), as well as one light sampled from the distribution. Choosing the sun with
//! probability 1/3 and weighting it by 3 would make sunlit pixels the noisiest of all (and, frame
//! to frame, fire false events); evaluating it always costs one shadow ray per delta light.

use crate::base::colour::luminance;
use glam::{Vec2, Vec3};

use crate::base::sampling::{uniform_triangle, Distribution1D};
use crate::scene::{Environment, PunctualLight, Scene};

/// One entry of the light table.
#[derive(Clone, Copy, Debug)]
enum LightRef {
    /// An emissive triangle (mesh index).
    Triangle(u32),
    /// The environment.
    Environment,
}

/// A light sample seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the light point (`f32::INFINITY` for the environment and directional lights).
    pub dist: f32,
    /// Radiance (area lights, environment) or the delta light's contribution `I / d^2` or `E`.
    pub radiance: Vec3,
    /// Solid-angle density including the selection probability; for delta lights, the
    /// selection probability alone.
    pub pdf: f32,
    /// True for point, spot and directional lights.
    pub is_delta: bool,
}

/// The scene's lights, prepared for sampling.
pub struct Lights {
    table: Vec<LightRef>,
    distribution: Distribution1D,
    /// For each mesh triangle: its entry in `table`, or `u32::MAX` when it does not emit.
    tri_entry: Vec<u32>,
    /// Area of each emissive triangle, by table entry (0 for other entries).
    area: Vec<f32>,
    env_entry: Option<u32>,
    /// The emissive triangles alone, chosen by power ([`Lights::sample_bounded`]).
    bounded: Distribution1D,
    /// Centre and radius of the scene's bounding sphere.
    pub bounds: (Vec3, f32),
}

/// Emitted radiance of triangle `prim` at barycentrics `bary`, leaving towards `w`
/// (zero behind a one-sided emitter).
pub fn emitted(scene: &Scene, prim: u32, bary: Vec2, w: Vec3) -> Vec3 {
    emitted_filtered(scene, prim, bary, w, None)
}

/// [`emitted`] with the emission texture filtered over the texture-coordinate footprint `fp`
/// (see [`crate::scene::Texture::sample_footprint`]) when given.
pub fn emitted_filtered(scene: &Scene, prim: u32, bary: Vec2, w: Vec3, fp: Option<(Vec2, Vec2)>) -> Vec3 {
    let mat = &scene.materials[scene.mesh.material[prim as usize] as usize];
    if !mat.is_emissive() {
        return Vec3::ZERO;
    }
    let [a, b, c] = scene.mesh.corners(prim as usize);
    let ng = (b - a).cross(c - a);
    if !mat.double_sided && ng.dot(w) <= 0.0 {
        return Vec3::ZERO;
    }
    let mut le = mat.emission;
    if let Some(t) = mat.emission_texture {
        let [i0, i1, i2] = scene.mesh.indices[prim as usize];
        let uv = scene.mesh.uvs[i0 as usize] * (1.0 - bary.x - bary.y)
            + scene.mesh.uvs[i1 as usize] * bary.x
            + scene.mesh.uvs[i2 as usize] * bary.y;
        let tex = &scene.textures[t.index as usize];
        le *= match fp {
            Some((du, dv)) => tex.sample_footprint(uv, du, dv),
            None => tex.sample(uv),
        }
        .truncate();
    }
    le
}

/// Bounding sphere (centre, radius) of the scene's vertices; radius at least 1e-3.
fn bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    if scene.mesh.positions.is_empty() {
        return (Vec3::ZERO, 1.0);
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in &scene.mesh.positions {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    ((lo + hi) * 0.5, ((hi - lo) * 0.5).length().max(1e-3))
}

impl Lights {
    /// Gather every light of `scene` and build the power distribution.
    pub fn new(scene: &Scene) -> Lights {
        let bounds = bounding_sphere(scene);
        let mut table = Vec::new();
        let mut power = Vec::new();
        let mut infinite = Vec::new();
        let mut area = Vec::new();
        let mut tri_entry = vec![u32::MAX; scene.mesh.len()];
        for (i, &m) in scene.mesh.material.iter().enumerate() {
            let mat = &scene.materials[m as usize];
            if !mat.is_emissive() {
                continue;
            }
            let [a, b, c] = scene.mesh.corners(i);
            let tri_area = 0.5 * (b - a).cross(c - a).length();
            if !(tri_area > 0.0) {
                continue;
            }
            let mut le = mat.emission;
            if let Some(t) = mat.emission_texture {
                let tex = &scene.textures[t.index as usize];
                le *= tex.texels.iter().map(|t| t.truncate()).sum::<Vec3>() / tex.texels.len().max(1) as f32;
            }
            let sides = if mat.double_sided { 2.0 } else { 1.0 };
            tri_entry[i] = table.len() as u32;
            table.push(LightRef::Triangle(i as u32));
            power.push(sides * std::f32::consts::PI * tri_area * luminance(le));
            infinite.push(false);
            area.push(tri_area);
        }
        let mut env_entry = None;
        if !scene.environment.is_black() {
            env_entry = Some(table.len() as u32);
            table.push(LightRef::Environment);
            power.push(scene.environment.power_integral());
            infinite.push(true);
            area.push(0.0);
        }
        let bounded = Distribution1D::new(
            &power.iter().zip(&infinite).map(|(&p, &inf)| if inf { 0.0 } else { p }).collect::<Vec<_>>(),
        );
        // equal shares for each infinite light and for the bounded group; power within the group
        let bounded_total: f32 =
            power.iter().zip(&infinite).filter(|(p, &inf)| !inf && **p > 0.0).map(|(p, _)| *p).sum();
        let n_infinite = infinite.iter().zip(&power).filter(|(&inf, p)| inf && **p > 0.0).count();
        let shares = n_infinite as f32 + if bounded_total > 0.0 { 1.0 } else { 0.0 };
        let power: Vec<f32> = power
            .iter()
            .zip(&infinite)
            .map(|(&p, &inf)| match (inf, p > 0.0) {
                (_, false) => 0.0,
                (true, true) => 1.0 / shares,
                (false, true) => p / bounded_total / shares,
            })
            .collect();
        let distribution = Distribution1D::new(&power);
        Lights { table, distribution, tri_entry, area, env_entry, bounded, bounds }
    }

    /// True when the scene has no light to *sample* (delta lights are not sampled; see
    /// [`Lights::delta_incident`]).
    pub fn is_empty(&self) -> bool {
        self.table.is_empty() || self.distribution.total <= 0.0
    }

    /// Sample a light as seen from point `p`.
    pub fn sample(&self, scene: &Scene, p: Vec3, u_sel: f32, u: Vec2) -> Option<LightSample> {
        if self.is_empty() {
            return None;
        }
        let (entry, p_sel, _) = self.distribution.sample_discrete(u_sel);
        self.sample_entry(scene, p, entry, p_sel, u)
    }

    /// Sample an emissive triangle as seen from point `p`, chosen by power among the emissive
    /// triangles alone (no environment); None when the scene has none. The radiance cache at
    /// the first vertex ([`crate::render::radiance_cache`]) samples only these.
    pub fn sample_bounded(&self, scene: &Scene, p: Vec3, u_sel: f32, u: Vec2) -> Option<LightSample> {
        if !(self.bounded.total > 0.0) {
            return None;
        }
        let (entry, p_sel, _) = self.bounded.sample_discrete(u_sel);
        self.sample_entry(scene, p, entry, p_sel, u)
    }

    /// Sample light `entry`, chosen with probability `p_sel`, as seen from `p`.
    fn sample_entry(&self, scene: &Scene, p: Vec3, entry: usize, p_sel: f32, u: Vec2) -> Option<LightSample> {
        if p_sel <= 0.0 {
            return None;
        }
        match self.table[entry] {
            LightRef::Triangle(prim) => {
                // uniform point on the triangle, converted from area to solid angle
                let b = uniform_triangle(u);
                let [v0, v1, v2] = scene.mesh.corners(prim as usize);
                let q = v0 * (1.0 - b.x - b.y) + v1 * b.x + v2 * b.y;
                let ng = (v1 - v0).cross(v2 - v0).normalize();
                let to = q - p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    return None;
                }
                let dist = d2.sqrt();
                let wi = to / dist;
                let cos_l = ng.dot(-wi).abs();
                if cos_l <= 1e-7 {
                    return None;
                }
                let radiance = emitted(scene, prim, b, -wi);
                if radiance == Vec3::ZERO {
                    return None;
                }
                let pdf = p_sel / self.area[entry] * d2 / cos_l;
                Some(LightSample { wi, dist, radiance, pdf, is_delta: false })
            }
            LightRef::Environment => {
                let s = scene.environment.sample(u)?;
                if s.pdf <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi: s.wi,
                    dist: f32::INFINITY,
                    radiance: s.radiance,
                    pdf: p_sel * s.pdf,
                    is_delta: false,
                })
            }
        }
    }

    /// Every delta light (point, spot, directional) as seen from `p`, with `pdf = 1`: the
    /// integrator adds all of them at each shading point.
    pub fn delta_incident<'s>(&self, scene: &'s Scene, p: Vec3) -> impl Iterator<Item = LightSample> + 's {
        self.delta_incident_indexed(scene, p).map(|(_, ls)| ls)
    }

    /// [`Lights::delta_incident`] with each light's index in the scene's list (a spot light
    /// that does not reach `p` is skipped, so the position in this sequence is not its index).
    pub fn delta_incident_indexed<'s>(
        &self,
        scene: &'s Scene,
        p: Vec3,
    ) -> impl Iterator<Item = (usize, LightSample)> + 's {
        scene.lights.iter().enumerate().filter_map(move |(k, l)| {
            let (wi, dist, radiance) = punctual_incident(l, p)?;
            Some((k, LightSample { wi, dist, radiance, pdf: 1.0, is_delta: true }))
        })
    }

    /// Solid-angle density with which [`Lights::sample`] picks the point `q` (normal `ng_q`, unit)
    /// on emissive triangle `prim`, seen from `p`.
    pub fn pdf_triangle(&self, prim: u32, p: Vec3, q: Vec3, ng_q: Vec3) -> f32 {
        let entry = self.tri_entry[prim as usize];
        if entry == u32::MAX {
            return 0.0;
        }
        self.triangle_pdf(self.distribution.pmf(entry as usize), entry, p, q, ng_q)
    }

    /// Solid-angle density with which [`Lights::sample_bounded`] picks the point `q` (normal
    /// `ng_q`, unit) on emissive triangle `prim`, seen from `p`.
    pub fn pdf_triangle_bounded(&self, prim: u32, p: Vec3, q: Vec3, ng_q: Vec3) -> f32 {
        let entry = self.tri_entry[prim as usize];
        if entry == u32::MAX || !(self.bounded.total > 0.0) {
            return 0.0;
        }
        self.triangle_pdf(self.bounded.pmf(entry as usize), entry, p, q, ng_q)
    }

    /// Solid-angle density of point `q` on the triangle of `entry`, picked with probability
    /// `p_sel` and then uniformly by area, seen from `p`.
    fn triangle_pdf(&self, p_sel: f32, entry: u32, p: Vec3, q: Vec3, ng_q: Vec3) -> f32 {
        let to = q - p;
        let d2 = to.length_squared();
        let cos_l = ng_q.dot(to).abs() / d2.sqrt();
        if cos_l <= 1e-7 {
            return 0.0;
        }
        p_sel / self.area[entry as usize] * d2 / cos_l
    }

    /// Solid-angle density with which [`Lights::sample`] picks environment direction `d`.
    pub fn pdf_environment(&self, env: &Environment, d: Vec3) -> f32 {
        match self.env_entry {
            Some(e) => self.distribution.pmf(e as usize) * env.pdf(d),
            None => 0.0,
        }
    }
}

/// Direction, distance and incident contribution (`I / d^2`, or `E`) of a delta light at `p`.
fn punctual_incident(light: &PunctualLight, p: Vec3) -> Option<(Vec3, f32, Vec3)> {
    match *light {
        PunctualLight::Point { position, intensity } => {
            let to = position - p;
            let d2 = to.length_squared();
            (d2 > 0.0).then(|| (to / d2.sqrt(), d2.sqrt(), intensity / d2))
        }
        PunctualLight::Spot { position, direction, intensity, inner_cone, outer_cone } => {
            let to = position - p;
            let d2 = to.length_squared();
            if !(d2 > 0.0) {
                return None;
            }
            let wi = to / d2.sqrt();
            // glTF's recommended smooth angular falloff between the cone angles
            let scale = 1.0 / (inner_cone.cos() - outer_cone.cos()).max(1e-3);
            let offset = -outer_cone.cos() * scale;
            let att = (direction.dot(-wi) * scale + offset).clamp(0.0, 1.0);
            let att = att * att;
            (att > 0.0).then(|| (wi, d2.sqrt(), intensity * att / d2))
        }
        PunctualLight::Directional { direction, irradiance } => Some((-direction, f32::INFINITY, irradiance)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::accel::{Accel, BvhPreset};
    use crate::render::chi2::{chi2_test, Chi2Config, Chi2Result};
    use crate::scene::{Material, TriangleMesh};

    /// Three emissive triangles of different power and sidedness around the origin, plus a
    /// constant environment when `env`.
    fn scene(env: bool) -> Scene {
        let mut mesh = TriangleMesh::default();
        let tris = [
            ([Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.0, -1.0), Vec3::new(0.0, 2.0, 1.0)], 0u32), // ceiling, faces up
            ([Vec3::new(2.0, -1.0, 0.5), Vec3::new(2.0, 1.0, 0.5), Vec3::new(2.0, 0.0, -1.5)], 1), // +x wall, two-sided
            ([Vec3::new(-0.5, -3.0, 0.0), Vec3::new(0.0, -3.0, 0.5), Vec3::new(0.5, -3.0, 0.0)], 2), // small, below
        ];
        for (i, (c, m)) in tris.iter().enumerate() {
            for p in c {
                mesh.positions.push(*p);
                mesh.normals.push(Vec3::Y);
                mesh.uvs.push(Vec2::ZERO);
            }
            let b = 3 * i as u32;
            mesh.indices.push([b, b + 1, b + 2]);
            mesh.material.push(*m);
        }
        let emitter = |e: f32, two: bool| Material {
            emission: Vec3::splat(e),
            double_sided: two,
            specular: 0.0,
            ..Material::default()
        };
        Scene {
            mesh,
            materials: vec![emitter(3.0, true), emitter(1.0, true), emitter(20.0, true)],
            environment: if env { Environment::Constant(Vec3::splat(0.5)) } else { Environment::default() },
            ..Scene::default()
        }
    }

    /// A delta light's index is its place in the scene's list even where a spot light before
    /// it does not reach the point (the shadow grids keep one slot per index).
    #[test]
    fn delta_lights_keep_their_scene_index() {
        let mut s = scene(false);
        let spot = PunctualLight::Spot {
            position: Vec3::new(0.0, 5.0, 0.0),
            direction: Vec3::Y,
            intensity: Vec3::ONE,
            inner_cone: 0.1,
            outer_cone: 0.2,
        };
        let sun = PunctualLight::Directional { direction: -Vec3::Y, irradiance: Vec3::ONE };
        s.lights = vec![spot, sun];
        let lights = Lights::new(&s);
        // the spot points up, away from the origin: only the sun reaches it, as light 1
        let seen: Vec<usize> = lights.delta_incident_indexed(&s, Vec3::ZERO).map(|(k, _)| k).collect();
        assert_eq!(seen, vec![1]);
        // above the spot, inside its cone, both
        let seen: Vec<usize> = lights.delta_incident_indexed(&s, Vec3::new(0.0, 9.0, 0.0)).map(|(k, _)| k).collect();
        assert_eq!(seen, vec![0, 1]);
        assert_eq!(lights.delta_incident(&s, Vec3::ZERO).count(), 1);
    }

    /// The density of `Lights::sample` for direction `d` from `p`: every emissive triangle the
    /// line crosses (sampling ignores occlusion) plus the environment.
    fn pdf_brute(lights: &Lights, scene: &Scene, accel: &Accel, p: Vec3, d: Vec3) -> f32 {
        lights.pdf_environment(&scene.environment, d)
            + pdf_crossed(scene, accel, p, d, |prim, q, n| lights.pdf_triangle(prim, p, q, n))
    }

    /// The sum of `pdf(prim, q, ng)` over every triangle the line from `p` along `d` crosses
    /// (at `q`, unit geometric normal `ng`).
    fn pdf_crossed(scene: &Scene, accel: &Accel, p: Vec3, d: Vec3, pdf: impl Fn(u32, Vec3, Vec3) -> f32) -> f32 {
        let (mut sum, mut tmin) = (0.0, 0.0);
        while let Some(h) = accel.intersect(p, d, tmin, f32::INFINITY) {
            let [a, b, c] = scene.mesh.corners(h.prim as usize);
            sum += pdf(h.prim, p + d * h.t, (b - a).cross(c - a).normalize());
            tmin = h.t * (1.0 + 1e-5) + 1e-6;
        }
        sum
    }

    /// Chi-square test, on `scene(env)` from a fixed point `p`, of the directions of
    /// `Lights::sample` (or with `bounded`, `Lights::sample_bounded`) against the density of
    /// every light the line crosses; returns the result with the scene and its lights.
    fn chi2_of_sampler(env: bool, bounded: bool) -> (Chi2Result, Scene, Lights) {
        let scene = scene(env);
        let lights = Lights::new(&scene);
        let accel = Accel::build(&scene.mesh, BvhPreset::Medium);
        let p = Vec3::new(0.1, 0.2, 0.0);
        let r = chi2_test(
            Chi2Config { alpha: 1e-3 / 2.0, substeps: 32, ..Chi2Config::default() },
            |u_sel, u| {
                match bounded {
                    true => lights.sample_bounded(&scene, p, u_sel, u),
                    false => lights.sample(&scene, p, u_sel, u),
                }
                .map(|s| s.wi)
            },
            |d| match bounded {
                // every emitter the line crosses, by the emitters-alone density
                true => pdf_crossed(&scene, &accel, p, d, |prim, q, n| lights.pdf_triangle_bounded(prim, p, q, n)),
                false => pdf_brute(&lights, &scene, &accel, p, d),
            },
        );
        (r, scene, lights)
    }

    #[test]
    fn light_sampling_matches_its_pdf() {
        for env in [false, true] {
            let (r, ..) = chi2_of_sampler(env, false);
            assert!(r.passed, "env {env}: {r:?}");
            assert!((r.pdf_integral - r.accepted).abs() < 5e-3, "env {env}: {r:?}");
        }
    }

    #[test]
    fn sampling_emitters_alone_matches_its_pdf_and_never_picks_the_environment() {
        for env in [false, true] {
            let (r, scene, lights) = chi2_of_sampler(env, true);
            assert!(r.passed, "env {env}: {r:?}");
            // all of the density lies on the emitters (none on the environment)
            assert!((r.pdf_integral - r.accepted).abs() < 5e-3 && r.accepted > 0.99, "env {env}: {r:?}");
            let p = Vec3::new(0.1, 0.2, 0.0);
            let picks =
                (0..64).filter_map(|i| lights.sample_bounded(&scene, p, (i as f32 + 0.5) / 64.0, Vec2::splat(0.3)));
            assert!(picks.into_iter().all(|s| s.dist.is_finite() && !s.is_delta));
        }
        // no emitter: nothing to pick
        let dark = Scene { environment: Environment::Constant(Vec3::ONE), ..Scene::default() };
        assert!(Lights::new(&dark).sample_bounded(&dark, Vec3::ZERO, 0.5, Vec2::splat(0.5)).is_none());
    }

    #[test]
    fn selection_follows_power_and_gives_infinite_lights_an_equal_share() {
        let scene = scene(true);
        let lights = Lights::new(&scene);
        // two-sided triangles: Phi = 2 pi A lum(Le); the environment takes half
        let area = |i: usize| {
            let [a, b, c] = scene.mesh.corners(i);
            0.5 * (b - a).cross(c - a).length()
        };
        let power: Vec<f32> =
            (0..3).map(|i| 2.0 * std::f32::consts::PI * area(i) * luminance(scene.materials[i].emission)).collect();
        let total: f32 = power.iter().sum();
        for (i, p) in power.iter().enumerate() {
            let want = 0.5 * p / total;
            assert!((lights.distribution.pmf(i) - want).abs() < 1e-6, "light {i}");
        }
        assert!((lights.distribution.pmf(3) - 0.5).abs() < 1e-6, "environment share");
    }

    #[test]
    fn one_sided_emitters_are_dark_from_behind_in_sampling() {
        let mut scene = scene(false);
        scene.materials[0].double_sided = false;
        let [a, b, c] = scene.mesh.corners(0);
        let n = (b - a).cross(c - a).normalize();
        let lights = Lights::new(&scene);
        // from the side the normal points away from, the ceiling's samples carry no radiance
        let behind = Vec3::new(0.0, 2.0, 0.0) - n * 1.5;
        let mut r = crate::base::sampling::Rng::new(3, 4);
        for _ in 0..2000 {
            let u_sel = lights.distribution.cdf[0] + r.next_f32() * lights.distribution.pmf(0) * 0.999;
            if let Some(s) = lights.sample(&scene, behind, u_sel, r.next_2d()) {
                panic!("a one-sided emitter was sampled from behind: {s:?}");
            }
        }
    }
}
