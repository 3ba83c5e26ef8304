//! The ray-triangle acceleration structure: an obvhs compressed wide BVH (CWBVH, 8-wide) over
//! the scene's world-space triangles, with closest-hit and any-hit (shadow) queries.
//!
//! Build presets trade build time for traversal speed ([`BvhPreset`]); `evsim bench render`
//! prints both for every preset on a 1 M-triangle scene. Measured on 2 cores (two runs, ranges):
//!
//! | preset        | build 1 M tris | primary Mray/s | diffuse Mray/s | Cornell 600x400x64 |
//! |---------------|---------------:|---------------:|---------------:|-------------------:|
//! | FastestBuild  | 0.38-0.40 s    | 5.7-5.9        | 3.9            | 4.36 s             |
//! | FastBuild     | 0.45-0.47 s    | 5.4            | 4.1-4.2        | -                  |
//! | Medium        | 0.50-0.54 s    | 5.8-5.9        | 4.0-4.1        | 3.98-4.16 s        |
//! | SlowBuild     | 0.83-0.87 s    | 5.0            | 3.9-4.1        | 3.78-4.05 s        |
//!
//! The default is `Medium`: the best primary-ray rate on the uniform 1 M-triangle mesh within
//! noise, at 60% of `SlowBuild`'s build time. `SlowBuild`'s spatial pre-splits pay off a few
//! percent on scenes of large, overlapping triangles (the Cornell box) but cost 15% on fine
//! uniform meshes; pick it with `--bvh slow-build` for such scenes. A dataset renders ~1000
//! frames of one static scene, so build time matters less than trace speed there.

use std::time::{Duration, Instant};

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    cwbvh::{builder::build_cwbvh_from_tris, CwBvh},
    ray::{Ray, RayHit},
    rt_triangle::RtTriangle,
    triangle::Triangle,
    BvhBuildParams,
};

use crate::scene::TriangleMesh;

/// obvhs build presets, from quickest to build to quickest to trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BvhPreset {
    /// PLOC with the minimum search radius, no reinsertion: the fastest build, the slowest trace.
    FastestBuild,
    /// PLOC with a low search radius and a little reinsertion.
    FastBuild,
    /// PLOC with a medium search radius and more reinsertion (obvhs' "about Embree build time").
    #[default]
    Medium,
    /// Spatial pre-splits of large triangles plus a wide PLOC search: slowest build, best trace.
    SlowBuild,
}

impl BvhPreset {
    /// The obvhs parameters of this preset.
    pub const fn params(self) -> BvhBuildParams {
        match self {
            BvhPreset::FastestBuild => BvhBuildParams::fastest_build(),
            BvhPreset::FastBuild => BvhBuildParams::fast_build(),
            BvhPreset::Medium => BvhBuildParams::medium_build(),
            BvhPreset::SlowBuild => BvhBuildParams::slow_build(),
        }
    }
    /// Every preset, for benchmarks.
    pub const ALL: [BvhPreset; 4] =
        [BvhPreset::FastestBuild, BvhPreset::FastBuild, BvhPreset::Medium, BvhPreset::SlowBuild];
}

/// A closest hit: distance along the ray, the triangle and the barycentrics of the hit point
/// (`p = (1 - b1 - b2) v0 + b1 v1 + b2 v2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Index of the triangle in the scene's [`TriangleMesh`].
    pub prim: u32,
    /// Barycentric coordinates (b1, b2).
    pub bary: Vec2,
    /// The triangle's edges `v1 - v0` and `v2 - v0` (exactly as computed from the mesh's
    /// corners; the traversal has just read them, so the shading need not fetch the corners).
    pub edges: [Vec3; 2],
}

/// A BVH over a triangle mesh.
pub struct Accel {
    bvh: CwBvh,
    /// Triangles in BVH primitive order, in the layout obvhs intersects fastest.
    tris: Vec<RtTriangle>,
    /// Mesh triangle index of each BVH primitive.
    prim_ids: Vec<u32>,
    /// BVH primitive of each mesh triangle (the first, when pre-splits duplicate it).
    bvh_index: Vec<u32>,
    /// Wall time of the core build.
    pub build_time: Duration,
}

impl Accel {
    /// Build the BVH over `mesh` with `preset`.
    pub fn build(mesh: &TriangleMesh, preset: BvhPreset) -> Accel {
        let start = Instant::now();
        let tris: Vec<Triangle> = (0..mesh.len())
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                Triangle { v0: a.into(), v1: b.into(), v2: c.into() }
            })
            .collect();
        if tris.is_empty() {
            return Accel {
                bvh: CwBvh::default(),
                tris: vec![],
                prim_ids: vec![],
                bvh_index: vec![],
                build_time: start.elapsed(),
            };
        }
        let mut core = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&tris, preset.params(), &mut core);
        // reorder the triangles so the leaves read them contiguously
        let prim_ids = bvh.primitive_indices.clone();
        let mut bvh_index = vec![u32::MAX; tris.len()];
        for (j, &i) in prim_ids.iter().enumerate().rev() {
            bvh_index[i as usize] = j as u32;
        }
        let tris = prim_ids.iter().map(|&i| RtTriangle::from(&tris[i as usize])).collect();
        Accel { bvh, tris, prim_ids, bvh_index, build_time: start.elapsed() }
    }

    /// Closest intersection with `t` in (`tmin`, `tmax`), if any.
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        if self.tris.is_empty() {
            return None;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let mut hit = RayHit::none();
        let tris = &self.tris;
        if !self.bvh.ray_traverse(ray, &mut hit, |r, id| tris[id].intersect(r)) {
            return None;
        }
        Some(self.hit(hit.primitive_id, hit.t, origin, dir))
    }

    /// The intersection of the ray with mesh triangle `prim` alone, with `t` in (`tmin`,
    /// `tmax`): the same numbers [`Accel::intersect`] returns when that triangle is the closest
    /// hit. For rays whose first triangle is known (rasterised camera rays).
    #[inline]
    pub fn intersect_triangle(&self, prim: u32, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let j = *self.bvh_index.get(prim as usize)?;
        let tri = self.tris.get(j as usize)?;
        let t = tri.intersect(&Ray::new(origin.into(), dir.into(), tmin, tmax));
        (t >= tmin && t <= tmax && t.is_finite()).then(|| self.hit(j, t, origin, dir))
    }

    /// The [`Hit`] of the ray with BVH primitive `j` at distance `t`.
    #[inline]
    fn hit(&self, j: u32, t: f32, origin: Vec3, dir: Vec3) -> Hit {
        let tri = &self.tris[j as usize];
        let bary = barycentrics(tri, origin.into(), dir.into());
        // obvhs stores e1 = v0 - v1: its negation is v1 - v0 bit for bit
        let edges = [Vec3::from(-tri.e1), Vec3::from(tri.e2)];
        Hit { t, prim: self.prim_ids[j as usize], bary, edges }
    }

    /// True when anything blocks the segment from `origin` along `dir` for t in (`tmin`, `tmax`).
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let tris = &self.tris;
        !self.bvh.ray_traverse_miss(ray, |r, id| tris[id].intersect(r))
    }
}

/// Barycentrics (b1, b2) of the hit of a ray with an obvhs `RtTriangle`
/// (v0 = base, v1 = v0 - e1, v2 = v0 + e2), by the Moller-Trumbore formulas.
#[inline]
fn barycentrics(tri: &RtTriangle, o: Vec3A, d: Vec3A) -> Vec2 {
    let v0 = tri.v0;
    let edge1 = -tri.e1; // v1 - v0
    let edge2 = tri.e2; // v2 - v0
    let pvec = d.cross(edge2);
    let det = edge1.dot(pvec);
    if det == 0.0 {
        return Vec2::ZERO;
    }
    let inv = 1.0 / det;
    let tvec = o - v0;
    let b1 = tvec.dot(pvec) * inv;
    let qvec = tvec.cross(edge1);
    let b2 = d.dot(qvec) * inv;
    Vec2::new(b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0 - b1.clamp(0.0, 1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::sampling::{uniform_sphere, Rng};

    /// Brute-force closest hit by testing every triangle.
    fn brute(mesh: &TriangleMesh, o: Vec3, d: Vec3, tmax: f32) -> Option<(f32, u32)> {
        let ray = Ray::new(o.into(), d.into(), 0.0, tmax);
        let mut best: Option<(f32, u32)> = None;
        for i in 0..mesh.len() {
            let [a, b, c] = mesh.corners(i);
            let t = RtTriangle::new(a.into(), b.into(), c.into()).intersect(&ray);
            if t < tmax && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i as u32));
            }
        }
        best
    }

    fn random_soup(n: usize, rng: &mut Rng) -> TriangleMesh {
        let mut m = TriangleMesh::default();
        for i in 0..n {
            let c = (rng.next_2d().extend(rng.next_f32()) - 0.5) * 4.0;
            for _ in 0..3 {
                m.positions.push(c + (rng.next_2d().extend(rng.next_f32()) - 0.5) * 0.6);
                m.normals.push(Vec3::Z);
                m.uvs.push(Vec2::ZERO);
            }
            let b = 3 * i as u32;
            m.indices.push([b, b + 1, b + 2]);
            m.material.push(0);
        }
        m
    }

    #[test]
    fn closest_and_shadow_hits_match_brute_force_for_every_preset() {
        let mut rng = Rng::new(11, 3);
        let mesh = random_soup(500, &mut rng);
        for preset in BvhPreset::ALL {
            let accel = Accel::build(&mesh, preset);
            let mut hits = 0;
            for _ in 0..3000 {
                let o = (rng.next_2d().extend(rng.next_f32()) - 0.5) * 6.0;
                let d = uniform_sphere(rng.next_2d());
                let tmax = if rng.next_f32() < 0.5 { f32::INFINITY } else { 2.0 };
                let got = accel.intersect(o, d, 0.0, tmax);
                let want = brute(&mesh, o, d, tmax);
                match (got, want) {
                    (None, None) => {}
                    (Some(h), Some((t, _))) => {
                        hits += 1;
                        assert!((h.t - t).abs() <= 1e-5 * t.max(1.0), "{preset:?}: t {} vs {}", h.t, t);
                        // the hit point reconstructed from barycentrics lies on the ray
                        let [a, b, c] = mesh.corners(h.prim as usize);
                        let p = a * (1.0 - h.bary.x - h.bary.y) + b * h.bary.x + c * h.bary.y;
                        assert!((p - (o + d * h.t)).length() < 1e-3, "{preset:?}: {p} vs {}", o + d * h.t);
                    }
                    (g, w) => panic!("{preset:?}: bvh {g:?} vs brute {w:?}"),
                }
                assert_eq!(accel.occluded(o, d, 0.0, tmax), want.is_some());
            }
            assert!(hits > 300, "too few hits to mean anything: {hits}");
        }
    }

    #[test]
    fn empty_mesh_hits_nothing() {
        let accel = Accel::build(&TriangleMesh::default(), BvhPreset::Medium);
        assert!(accel.intersect(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY).is_none());
        assert!(!accel.occluded(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY));
    }
}
