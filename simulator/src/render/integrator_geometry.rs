//! What shading needs of a hit: the triangle's numbers, the surface point, its shading frame
//! and texture coordinates, the texture footprint of a camera ray, and the BSDF there.

use super::*;

impl Renderer<'_> {
    /// Directions of the camera rays through film points `texture_filter` pixels right of and
    /// below `film`: the spread of the camera ray through `film` that textures are filtered
    /// over (None when `texture_filter` is 0, off).
    pub(super) fn camera_spread(&self, s: &RenderSettings, film: Vec2) -> Option<[Vec3; 2]> {
        let k = s.texture_filter;
        (k > 0.0 && k.is_finite())
            .then(|| [Vec2::new(k, 0.0), Vec2::new(0.0, k)].map(|o| s.camera.direction(film + o, s.width, s.height)))
    }

    /// How the texture coordinate changes across the spread of a camera ray (see
    /// [`Renderer::camera_spread`]) at its hit `sh`: the two neighbour rays are cut with the hit
    /// triangle's plane and the offsets expressed in the triangle's texture coordinates (pbrt's
    /// ray differentials). None where a neighbour ray misses the plane.
    pub(super) fn uv_footprint(
        &self,
        hit: &Hit,
        sh: &SurfaceHit,
        origin: Vec3,
        spread: [Vec3; 2],
    ) -> Option<(Vec2, Vec2)> {
        Self::uv_footprint_on(&self.triangle_numbers(hit), sh, origin, spread)
    }

    /// [`Renderer::uv_footprint`] with the hit triangle's numbers `tri` (the directions of
    /// `spread` need not be unit).
    #[inline]
    pub(super) fn uv_footprint_on(
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
    pub(super) fn triangle_numbers(&self, hit: &Hit) -> TriangleNumbers {
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
    pub(super) fn camera_hit(&self, known: Option<Option<u32>>, origin: Vec3, dir: Vec3) -> Option<Hit> {
        known
            .flatten()
            .and_then(|p| self.accel.intersect_triangle(p, origin, dir, 0.0, f32::INFINITY))
            .or_else(|| self.accel.intersect(origin, dir, 0.0, f32::INFINITY))
    }

    /// Record the camera ray `dir`'s first hit `hit` in `first` (as [`Renderer::li_first`]
    /// does, without shading).
    pub(super) fn first_hit(
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
    pub(super) fn surface(&self, hit: &Hit, origin: Vec3, dir: Vec3) -> SurfaceHit {
        self.surface_on(hit, hit.edges[0].cross(hit.edges[1]).normalize(), origin, dir)
    }

    /// [`Renderer::surface`] given the triangle's unit geometric normal `ng`.
    #[inline]
    pub(super) fn surface_on(&self, hit: &Hit, ng: Vec3, origin: Vec3, dir: Vec3) -> SurfaceHit {
        let front = ng.dot(dir) < 0.0;
        let (ns, uv) = self.shading_normal_uv(hit, dir, || ng);
        let p = origin + dir * hit.t;
        SurfaceHit { p, ng, frame: Frame::from_normal(ns), front, uv }
    }

    /// The interpolated shading normal at a hit, facing `-dir` (two-sided shading), and the
    /// texture coordinate; `ng()` is the unit geometric normal, the fallback for a degenerate
    /// interpolated normal.
    #[inline(always)]
    pub(super) fn shading_normal_uv(&self, hit: &Hit, dir: Vec3, ng: impl FnOnce() -> Vec3) -> (Vec3, Vec2) {
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
    pub(super) fn shading_uv(&self, prim: u32, bary: Vec2) -> Vec2 {
        let [t0, t1, t2] = self.shading[prim as usize].uvs;
        let (b1, b2) = (bary.x, bary.y);
        t0 * (1.0 - b1 - b2) + t1 * b1 + t2 * b2
    }

    /// The BSDF of triangle `prim`'s material at texture coordinate `uv`, its textures filtered
    /// over the footprint `fp` (offsets of `uv`, see [`crate::scene::Texture::sample_footprint`])
    /// when given.
    pub(super) fn bsdf(&self, prim: u32, uv: Vec2, fp: Option<(Vec2, Vec2)>) -> Bsdf {
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
}

/// The per-vertex data of one triangle that shading reads, packed (64 bytes).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct ShadingTri {
    pub(super) normals: [Vec3; 3],
    pub(super) uvs: [Vec2; 3],
    pub(super) material: u32,
}

/// What the shading of a hit needs of its triangle alone (see [`Renderer::triangle_numbers`]).
#[derive(Clone, Copy)]
pub(super) struct TriangleNumbers {
    /// The triangle.
    pub(super) prim: u32,
    /// Its unit geometric normal.
    pub(super) ng: Vec3,
    /// Its edges `v1 - v0` and `v2 - v0`.
    pub(super) edges: [Vec3; 2],
    /// The edges' dot products: e1.e1, e1.e2, e2.e2.
    pub(super) gram: [f32; 3],
    /// The Gram determinant (zero for a degenerate triangle).
    pub(super) det: f32,
    /// The texture coordinate's edges `uv1 - uv0` and `uv2 - uv0`.
    pub(super) uv_edges: [Vec2; 2],
}

/// Everything about a surface hit the shading needs.
pub(super) struct SurfaceHit {
    pub(super) p: Vec3,
    /// Unit geometric normal, CCW (not flipped).
    pub(super) ng: Vec3,
    /// Shading frame, its normal flipped to the side of the incoming ray.
    pub(super) frame: Frame,
    /// True when the ray arrived on the side the geometric normal points to.
    pub(super) front: bool,
    pub(super) uv: Vec2,
}

/// Move a ray origin off the surface along the (side-correct) geometric normal, by an amount
/// that scales with the magnitude of the coordinates to stay above float error.
#[inline]
pub(super) fn offset_origin(p: Vec3, n: Vec3) -> Vec3 {
    let eps = 1e-4 * p.abs().max_element().max(1.0);
    p + n * eps
}
