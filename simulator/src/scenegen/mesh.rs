//! Mesh primitives that append to a [`MeshData`] under a transform.
//!
//! Every primitive is built in its own local frame, centred on the origin (documented per
//! function), then placed by `xf`: positions by `xf`, normals by the inverse transpose of its
//! linear part (renormalised); a mirroring transform (negative determinant) swaps two corners of
//! every triangle so that winding stays counter-clockwise around the outward normal.
//!
//! UVs are in local metres divided by `tile` (metres per texture repeat along u and v), so every
//! surface built with the same `tile` has the same texel density; a `W x H` pixel texture keeps
//! square texels with `tile = (W, H) / pixels_per_metre` (e.g. a 256 x 64 sign over 2 m x 0.5 m). A scaling `xf` stretches the texture with the
//! surface; pass the real size as parameters and keep `xf` rigid to keep the density.
//!
//! Triangle counts (checked by the tests):
//! plane / heightfield `2 nx nz`; cuboid 12; cylinder `2 radial stacks (+ 2 radial caps)`;
//! sphere `2 segments (rings - 1)`; torus `2 major minor`; cone `radial (2 stacks - 1) (+ radial
//! cap)`; extrusion of an n-gon `2 (n - 2) + 2 n`.

use std::f32::consts::{PI, TAU};

use glam::{Affine3A, Mat3, Vec2, Vec3};

use super::gltf_write::MeshData;

/// Local-frame geometry before placement.
#[derive(Default)]
struct Part {
    p: Vec<Vec3>,
    n: Vec<Vec3>,
    uv: Vec<Vec2>,
    tri: Vec<[u32; 3]>,
}

impl Part {
    /// Add a vertex; returns its index.
    fn v(&mut self, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        self.p.push(p);
        self.n.push(n);
        self.uv.push(uv);
        self.p.len() as u32 - 1
    }

    /// A grid of `(nu + 1) x (nv + 1)` vertices from `f(u, v) -> (position, normal, uv)` with
    /// `u, v` in [0, 1]; quads split into two triangles wound counter-clockwise when
    /// `d/du x d/dv` points along the normal.
    fn grid(&mut self, nu: u32, nv: u32, f: impl Fn(f32, f32) -> (Vec3, Vec3, Vec2)) {
        let base = self.p.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                let (p, n, uv) = f(i as f32 / nu as f32, j as f32 / nv as f32);
                self.v(p, n, uv);
            }
        }
        let row = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                let a = base + j * row + i;
                let (b, c, d) = (a + 1, a + row + 1, a + row);
                self.tri.push([a, b, c]);
                self.tri.push([a, c, d]);
            }
        }
    }

    /// Transform into world space and append to `m`.
    fn place(self, m: &mut MeshData, xf: Affine3A) {
        let lin = Mat3::from(xf.matrix3);
        let normal_m = lin.inverse().transpose();
        let mirror = lin.determinant() < 0.0;
        let base = m.positions.len() as u32;
        m.positions.extend(self.p.iter().map(|&p| xf.transform_point3(p)));
        m.normals.extend(self.n.iter().map(|&n| (normal_m * n).try_normalize().unwrap_or(Vec3::Y)));
        m.uvs.extend(self.uv);
        m.indices.extend(self.tri.iter().map(|&[a, b, c]| {
            let t = [a + base, b + base, c + base];
            if mirror {
                [t[0], t[2], t[1]]
            } else {
                t
            }
        }));
    }
}

/// A flat rectangle in the local XZ plane, centred, normal +Y, `size` = (x, z) extent (m), split
/// into `segments` = (nx, nz) cells (each >= 1). UV u along +X, v along +Z.
pub fn plane(m: &mut MeshData, xf: Affine3A, size: Vec2, segments: [u32; 2], tile: Vec2) {
    heightfield(m, xf, size, segments, tile, |_, _| 0.0);
}

/// A grid in the local XZ plane displaced along +Y by `height(u, v)` (m), `u, v` in [0, 1]
/// across `size` = (x, z) (m) from the -X, -Z corner. Normals come from central differences of
/// `height` at one cell's spacing (so `height` is also called up to one cell outside [0, 1]).
/// UVs are the undisplaced XZ position / `tile`.
pub fn heightfield(
    m: &mut MeshData,
    xf: Affine3A,
    size: Vec2,
    segments: [u32; 2],
    tile: Vec2,
    height: impl Fn(f32, f32) -> f32,
) {
    let [nx, nz] = segments.map(|s| s.max(1));
    let (du, dv) = (1.0 / nx as f32, 1.0 / nz as f32);
    let mut part = Part::default();
    part.grid(nx, nz, |u, v| {
        let p = Vec3::new((u - 0.5) * size.x, height(u, v), (v - 0.5) * size.y);
        // dp/du = (size.x, dh/du, 0), dp/dv = (0, dh/dv, size.y); n = dp/dv x dp/du
        let dhdu = (height(u + du, v) - height(u - du, v)) / (2.0 * du);
        let dhdv = (height(u, v + dv) - height(u, v - dv)) / (2.0 * dv);
        let n = Vec3::new(-dhdu * size.y, size.x * size.y, -dhdv * size.x).normalize();
        (p, n, Vec2::new(p.x, p.z) / tile)
    });
    // grid winds around (d/du x d/dv) = -Y here; flip to wind around +Y
    for t in &mut part.tri {
        t.swap(1, 2);
    }
    part.place(m, xf);
}

/// An axis-aligned box centred on the origin with edge lengths `size` (m); 24 vertices (flat
/// normals), 12 triangles, each face's UVs from its own two axes / `tile`.
pub fn cuboid(m: &mut MeshData, xf: Affine3A, size: Vec3, tile: Vec2) {
    let h = size * 0.5;
    let mut part = Part::default();
    // (normal, u axis, v axis): u x v = normal for every face, so the quad winds outwards
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (n, u, v) in faces {
        let (eu, ev, en) = (u.abs().dot(h), v.abs().dot(h), n.abs().dot(h));
        let base = part.p.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let p = n * en + u * (su * eu) + v * (sv * ev);
            // v of the image grows downwards: flip so text reads upright on +v-up faces
            part.v(p, n, Vec2::new((su + 1.0) * eu, (1.0 - sv) * ev) / tile);
        }
        part.tri.push([base, base + 1, base + 2]);
        part.tri.push([base, base + 2, base + 3]);
    }
    part.place(m, xf);
}

/// A cylinder along local +Y from `y = -height/2` to `height/2`, `radial` (>= 3) segments around
/// and `stacks` (>= 1) along; optional flat caps. Side UVs: arc length and height / `tile`.
#[allow(clippy::too_many_arguments)] // positional like the other primitives: size, segments, caps, tile
pub fn cylinder(
    m: &mut MeshData,
    xf: Affine3A,
    radius: f32,
    height: f32,
    radial: u32,
    stacks: u32,
    caps: bool,
    tile: Vec2,
) {
    frustum(m, xf, radius, radius, height, radial, stacks, caps, caps, tile);
}

/// A cone along local +Y: base disc of `radius` at `y = -height/2`, apex at `height/2`;
/// `radial` (>= 3) segments, `stacks` (>= 1) rings along, optional base cap.
#[allow(clippy::too_many_arguments)]
pub fn cone(m: &mut MeshData, xf: Affine3A, radius: f32, height: f32, radial: u32, stacks: u32, cap: bool, tile: Vec2) {
    frustum(m, xf, radius, 0.0, height, radial, stacks, cap, false, tile);
}

/// Shared body of [`cylinder`] and [`cone`]: radius `r0` at the bottom, `r1` at the top.
#[allow(clippy::too_many_arguments)]
fn frustum(
    m: &mut MeshData,
    xf: Affine3A,
    r0: f32,
    r1: f32,
    height: f32,
    radial: u32,
    stacks: u32,
    cap0: bool,
    cap1: bool,
    tile: Vec2,
) {
    let (radial, stacks) = (radial.max(3), stacks.max(1));
    let mut part = Part::default();
    // side normal: perpendicular to the slant line, (cos, (r0 - r1) / h, sin) normalised
    let slope = (r0 - r1) / height;
    let circ = TAU * r0.max(r1);
    let side = |u: f32, v: f32| {
        let (s, c) = (u * TAU).sin_cos();
        let r = r0 + (r1 - r0) * v;
        // at the apex of a cone use the normal half a segment on (the vertex is per segment below)
        let p = Vec3::new(r * c, (v - 0.5) * height, -r * s);
        let n = Vec3::new(c, slope, -s).normalize();
        (p, n, Vec2::new(u * circ, (1.0 - v) * height) / tile)
    };
    if r1 > 0.0 {
        part.grid(radial, stacks, side);
    } else {
        // a cone: a grid up to the last ring, then one triangle per segment to a per-segment apex
        let top = (stacks - 1) as f32 / stacks as f32;
        if stacks > 1 {
            part.grid(radial, stacks - 1, |u, v| side(u, v * top));
        }
        let ring = part.p.len() as u32;
        for i in 0..=radial {
            let (p, n, uv) = side(i as f32 / radial as f32, top);
            part.v(p, n, uv);
        }
        for i in 0..radial {
            let um = (i as f32 + 0.5) / radial as f32;
            let (p, n, uv) = side(um, 1.0);
            let apex = part.v(p, n, uv);
            part.tri.push([ring + i, ring + i + 1, apex]);
        }
    }
    // caps: fans of `radial` triangles around a centre vertex; UVs planar in XZ
    for (cap, y, r, n) in [(cap0, -0.5 * height, r0, Vec3::NEG_Y), (cap1, 0.5 * height, r1, Vec3::Y)] {
        if !cap || r <= 0.0 {
            continue;
        }
        let centre = part.v(Vec3::new(0.0, y, 0.0), n, Vec2::ZERO);
        for i in 0..radial {
            let (s, c) = (i as f32 / radial as f32 * TAU).sin_cos();
            let p = Vec3::new(r * c, y, -r * s);
            part.v(p, n, Vec2::new(p.x, p.z) / tile);
        }
        for i in 0..radial {
            let (a, b) = (centre + 1 + i, centre + 1 + (i + 1) % radial);
            // the ring runs counter-clockwise seen from +Y
            part.tri.push(if n.y > 0.0 { [centre, a, b] } else { [centre, b, a] });
        }
    }
    part.place(m, xf);
}

/// A UV sphere of `radius` centred on the origin, poles on local Y; `segments` (>= 3) around,
/// `rings` (>= 2) pole to pole. UVs: arc length around the equator and from the north pole.
pub fn uv_sphere(m: &mut MeshData, xf: Affine3A, radius: f32, segments: u32, rings: u32, tile: Vec2) {
    let (segments, rings) = (segments.max(3), rings.max(2));
    let mut part = Part::default();
    let row = segments + 1;
    for j in 0..=rings {
        let theta = j as f32 / rings as f32 * PI;
        for i in 0..=segments {
            let phi = i as f32 / segments as f32 * TAU;
            let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin());
            part.v(n * radius, n, Vec2::new(phi * radius, theta * radius) / tile);
        }
    }
    for j in 0..rings {
        for i in 0..segments {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row + 1, a + row);
            // going down (+theta) and around (+phi): (d - a) x (b - a) points outwards
            if j > 0 {
                part.tri.push([a, d, b]);
            }
            if j + 1 < rings {
                part.tri.push([b, d, c]);
            }
        }
    }
    part.place(m, xf);
}

/// A torus around local +Y: tube of radius `minor` around a circle of radius `major` in XZ;
/// `major_segments` (>= 3) around the ring, `minor_segments` (>= 3) around the tube.
pub fn torus(
    m: &mut MeshData,
    xf: Affine3A,
    major: f32,
    minor: f32,
    major_segments: u32,
    minor_segments: u32,
    tile: Vec2,
) {
    let (nu, nv) = (major_segments.max(3), minor_segments.max(3));
    let mut part = Part::default();
    part.grid(nu, nv, |u, v| {
        let (su, cu) = (u * TAU).sin_cos();
        let (sv, cv) = (v * TAU).sin_cos();
        let n = Vec3::new(cv * cu, sv, -cv * su);
        let p = Vec3::new(major * cu, 0.0, -major * su) + n * minor;
        (p, n, Vec2::new(u * TAU * major, v * TAU * minor) / tile)
    });
    part.place(m, xf);
}

/// A prism: the simple polygon `outline` (local XY, m, either winding, no repeated closing
/// point) extruded along local Z from `-depth/2` to `depth/2`. Caps are ear-clipped (concave
/// outlines work); sides have flat normals. Cap UVs: `(x, -y) / tile`, so an outline spanning
/// `x in [0, W]`, `y in [-H, 0]` (top-left corner at the origin) shows exactly one upright copy
/// of the texture on the +Z cap with `tile = (W, H)`; side UVs: perimeter length and depth /
/// `tile`.
pub fn extrude(m: &mut MeshData, xf: Affine3A, outline: &[Vec2], depth: f32, tile: Vec2) {
    let n = outline.len();
    if n < 3 {
        return;
    }
    // make the outline counter-clockwise seen from +Z
    let area2: f32 = (0..n).map(|i| outline[i].perp_dot(outline[(i + 1) % n])).sum();
    let pts: Vec<Vec2> = if area2 < 0.0 { outline.iter().rev().copied().collect() } else { outline.to_vec() };
    let ears = ear_clip(&pts);
    let mut part = Part::default();
    let h = depth * 0.5;
    for (z, nz) in [(h, Vec3::Z), (-h, Vec3::NEG_Z)] {
        let base = part.p.len() as u32;
        for p in &pts {
            // image v grows downwards: v = -y keeps text upright on the front cap
            part.v(p.extend(z), nz, Vec2::new(p.x, -p.y) / tile);
        }
        for &[a, b, c] in &ears {
            part.tri.push(if z > 0.0 { [base + a, base + b, base + c] } else { [base + a, base + c, base + b] });
        }
    }
    let mut s = 0.0;
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        let len = (b - a).length();
        // outward normal of a counter-clockwise edge is its direction turned clockwise
        let nrm = Vec2::new(b.y - a.y, a.x - b.x).normalize_or_zero().extend(0.0);
        let base = part.p.len() as u32;
        part.v(a.extend(-h), nrm, Vec2::new(s, depth) / tile);
        part.v(b.extend(-h), nrm, Vec2::new(s + len, depth) / tile);
        part.v(b.extend(h), nrm, Vec2::new(s + len, 0.0) / tile);
        part.v(a.extend(h), nrm, Vec2::new(s, 0.0) / tile);
        part.tri.push([base, base + 1, base + 2]);
        part.tri.push([base, base + 2, base + 3]);
        s += len;
    }
    part.place(m, xf);
}

/// Triangulate a simple counter-clockwise polygon by ear clipping (O(n^2)); returns `n - 2`
/// counter-clockwise triangles of vertex indices.
fn ear_clip(pts: &[Vec2]) -> Vec<[u32; 3]> {
    let mut idx: Vec<u32> = (0..pts.len() as u32).collect();
    let mut out = Vec::new();
    let p = |i: u32| pts[i as usize];
    while idx.len() > 3 {
        let k = idx.len();
        let ear = (0..k).find(|&i| {
            let (a, b, c) = (idx[(i + k - 1) % k], idx[i], idx[(i + 1) % k]);
            let convex = (p(b) - p(a)).perp_dot(p(c) - p(b)) > 0.0;
            convex && idx.iter().filter(|&&j| j != a && j != b && j != c).all(|&j| !in_triangle(p(j), p(a), p(b), p(c)))
        });
        // a degenerate or self-intersecting outline has no ear: clip any vertex to terminate
        let i = ear.unwrap_or(0);
        out.push([idx[(i + k - 1) % k], idx[i], idx[(i + 1) % k]]);
        idx.remove(i);
    }
    out.push([idx[0], idx[1], idx[2]]);
    out
}

/// True when `q` lies inside or on the counter-clockwise triangle `a b c`.
fn in_triangle(q: Vec2, a: Vec2, b: Vec2, c: Vec2) -> bool {
    (b - a).perp_dot(q - a) >= 0.0 && (c - b).perp_dot(q - b) >= 0.0 && (a - c).perp_dot(q - c) >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn mesh() -> MeshData {
        MeshData::default()
    }

    /// Signed volume (divergence theorem): positive for a closed mesh wound outwards.
    fn volume(m: &MeshData) -> f32 {
        m.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Every face normal agrees with its vertex normals, and (for convex shapes) points away from
    /// `centre`; every vertex normal is unit length.
    fn check_normals(m: &MeshData, centre: Option<Vec3>) {
        for n in &m.normals {
            assert!((n.length() - 1.0).abs() < 1e-4);
        }
        for t in &m.indices {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let fnrm = (b - a).cross(c - a);
            assert!(fnrm.length() > 0.0, "degenerate triangle {t:?}");
            let avg: Vec3 = t.iter().map(|&i| m.normals[i as usize]).sum();
            assert!(fnrm.dot(avg) > 0.0, "winding disagrees with the normals at {t:?}");
            if let Some(o) = centre {
                assert!(fnrm.dot((a + b + c) / 3.0 - o) > 0.0, "face {t:?} points inwards");
            }
        }
    }

    fn xf() -> Affine3A {
        Affine3A::from_rotation_translation(
            Quat::from_rotation_x(0.3) * Quat::from_rotation_y(1.1),
            Vec3::new(1.0, 2.0, -3.0),
        )
    }

    #[test]
    fn cuboid_is_closed_outward_with_12_triangles() {
        let mut m = mesh();
        cuboid(&mut m, xf(), Vec3::new(1.0, 2.0, 3.0), Vec2::splat(1.0));
        assert_eq!(m.indices.len(), 12);
        assert!((volume(&m) - 6.0).abs() < 1e-4, "{}", volume(&m));
        check_normals(&m, Some(xf().translation.into()));
    }

    #[test]
    fn mirrored_transform_keeps_outward_winding() {
        let mut m = mesh();
        cuboid(&mut m, Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0)), Vec3::ONE, Vec2::splat(1.0));
        assert!((volume(&m) - 1.0).abs() < 1e-5);
        check_normals(&m, Some(Vec3::ZERO));
    }

    #[test]
    fn cylinder_and_cone_counts_and_volume() {
        let mut m = mesh();
        cylinder(&mut m, xf(), 0.5, 2.0, 32, 3, true, Vec2::splat(1.0));
        assert_eq!(m.indices.len(), 2 * 32 * 3 + 2 * 32);
        // inscribed polygon area: n/2 r^2 sin(2 pi / n)
        let exact = 16.0 * 0.25 * (TAU / 32.0).sin() * 2.0;
        assert!((volume(&m) - exact).abs() < 1e-3, "{} vs {exact}", volume(&m));
        check_normals(&m, Some(xf().translation.into()));

        let mut c = mesh();
        cone(&mut c, Affine3A::IDENTITY, 1.0, 3.0, 24, 4, true, Vec2::splat(1.0));
        assert_eq!(c.indices.len(), 24 * (2 * 4 - 1) + 24);
        let exact = 12.0 * (TAU / 24.0).sin() * 3.0 / 3.0;
        assert!((volume(&c) - exact).abs() < 1e-3, "{} vs {exact}", volume(&c));
        check_normals(&c, Some(Vec3::ZERO));
    }

    #[test]
    fn sphere_and_torus_counts_and_volume() {
        let mut s = mesh();
        uv_sphere(&mut s, xf(), 1.0, 48, 24, Vec2::splat(1.0));
        assert_eq!(s.indices.len(), 2 * 48 * 23);
        assert!((volume(&s) - 4.0 / 3.0 * PI).abs() < 0.05, "{}", volume(&s));
        check_normals(&s, Some(xf().translation.into()));

        let mut t = mesh();
        torus(&mut t, Affine3A::IDENTITY, 1.0, 0.25, 64, 16, Vec2::splat(1.0));
        assert_eq!(t.indices.len(), 2 * 64 * 16);
        // Pappus with inscribed polygons: tube section 16/2 r^2 sin(2 pi/16), path sin(x)/x shrink
        let section = 8.0 * 0.25 * 0.25 * (TAU / 16.0).sin();
        let path = TAU * 1.0 * (TAU / 64.0).sin() / (TAU / 64.0);
        let exact = section * path;
        assert!((volume(&t) - exact).abs() < 0.005 * exact, "{} vs {exact}", volume(&t));
        check_normals(&t, None);
        // every face points away from the tube's core circle
        for tri in &t.indices {
            let [a, b, c] = tri.map(|i| t.positions[i as usize]);
            let mid = (a + b + c) / 3.0;
            let core = Vec3::new(mid.x, 0.0, mid.z).normalize();
            assert!((b - a).cross(c - a).dot(mid - core) > 0.0);
        }
    }

    #[test]
    fn plane_and_heightfield_face_up() {
        let mut p = mesh();
        plane(&mut p, Affine3A::IDENTITY, Vec2::new(4.0, 2.0), [8, 4], Vec2::splat(0.5));
        assert_eq!(p.indices.len(), 2 * 8 * 4);
        check_normals(&p, None);
        assert!(p.normals.iter().all(|n| n.abs_diff_eq(Vec3::Y, 1e-6)));
        // UVs in metres / tile: the 4 m side spans 8 repeats
        let umax = p.uvs.iter().map(|u| u.x).fold(f32::MIN, f32::max);
        let umin = p.uvs.iter().map(|u| u.x).fold(f32::MAX, f32::min);
        assert!((umax - umin - 8.0).abs() < 1e-5);

        let mut h = mesh();
        heightfield(&mut h, Affine3A::IDENTITY, Vec2::splat(2.0), [32, 32], Vec2::ONE, |u, v| {
            0.2 * (u * 6.0).sin() * (v * 5.0).cos()
        });
        assert_eq!(h.indices.len(), 2 * 32 * 32);
        check_normals(&h, None);
        // the analytic normal agrees with the faces
        for t in &h.indices {
            let [a, b, c] = t.map(|i| h.positions[i as usize]);
            assert!((b - a).cross(c - a).normalize().dot(h.normals[t[0] as usize]) > 0.9);
        }
    }

    /// UV extent of the vertices `range` of `m`: (min, max).
    fn uv_box(m: &MeshData, range: std::ops::Range<usize>) -> (Vec2, Vec2) {
        let uv = &m.uvs[range];
        (uv.iter().fold(Vec2::MAX, |a, &b| a.min(b)), uv.iter().fold(Vec2::MIN, |a, &b| a.max(b)))
    }

    #[test]
    fn uvs_are_metres_over_tile() {
        // cuboid: each face's 4 vertices span its two edges / tile
        let mut m = mesh();
        cuboid(&mut m, Affine3A::IDENTITY, Vec3::new(1.0, 2.0, 3.0), Vec2::new(0.5, 0.25));
        let spans: Vec<Vec2> = (0..6).map(|f| uv_box(&m, 4 * f..4 * f + 4)).map(|(lo, hi)| hi - lo).collect();
        // +X face: u along Z (3 m), v along Y (2 m); +Y face: u along X (1 m), v along Z (3 m)
        assert!(spans[0].abs_diff_eq(Vec2::new(6.0, 8.0), 1e-5), "{:?}", spans[0]);
        assert!(spans[2].abs_diff_eq(Vec2::new(2.0, 12.0), 1e-5), "{:?}", spans[2]);
        // the upper edge of a side face is at image top (v = 0)
        let top = (0..4).filter(|&i| m.positions[i].y > 0.0).map(|i| m.uvs[i].y);
        assert!(top.into_iter().all(|v| v == 0.0));
        // extrusion: an outline over [0, W] x [-H, 0] with tile (W, H) maps the front cap to [0, 1]^2
        let (w, h) = (2.0, 0.5);
        let rect = [Vec2::ZERO, Vec2::new(w, 0.0), Vec2::new(w, -h), Vec2::new(0.0, -h)];
        let mut e = mesh();
        extrude(&mut e, Affine3A::IDENTITY, &rect, 0.1, Vec2::new(w, h));
        let (lo, hi) = uv_box(&e, 0..4);
        assert!(lo.abs_diff_eq(Vec2::ZERO, 1e-6) && hi.abs_diff_eq(Vec2::ONE, 1e-6), "{lo} {hi}");
        // the top-left corner (0, 0) is the image's top-left
        let corner = (0..4).find(|&i| e.positions[i].truncate() == Vec2::ZERO).unwrap();
        assert_eq!(e.uvs[corner], Vec2::ZERO);
        // sphere: u spans the equator's length / tile
        let mut s = mesh();
        uv_sphere(&mut s, Affine3A::IDENTITY, 0.5, 16, 8, Vec2::ONE);
        let (lo, hi) = uv_box(&s, 0..s.uvs.len());
        assert!((hi - lo).abs_diff_eq(Vec2::new(TAU * 0.5, PI * 0.5), 1e-5));
    }

    #[test]
    fn extrusion_of_concave_outline_is_closed_and_outward() {
        // an L shape, given clockwise to exercise the reordering
        let l = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.0, 2.0),
            Vec2::new(1.0, 2.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(2.0, 0.0),
        ];
        let mut m = mesh();
        extrude(&mut m, xf(), &l, 0.5, Vec2::splat(1.0));
        assert_eq!(m.indices.len(), 2 * 4 + 2 * 6);
        assert!((volume(&m) - 3.0 * 0.5).abs() < 1e-4, "{}", volume(&m));
        check_normals(&m, None);
    }
}
