//! The surface cache's storage: a [`Grid`] of values over one triangle side, the per-sequence
//! [`SurfaceCache`] of surface, shadow and glossy grids (filled once, on first use), and the
//! geometry they need.

use super::*;

/// Distance from `p` to the triangle `a`, `b`, `c`.
pub fn distance_to_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let d = (p - closest_point_on_triangle(p, a, b, c)).length();
    if d.is_finite() {
        d
    } else {
        0.0
    }
}

/// The point of the triangle `a`, `b`, `c` closest to `p` (Ericson's "Real-Time Collision
/// Detection" 5.1.5).
pub fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
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
    }
}

/// Most grid cells along either axis of a surface grid.
pub const MAX_SURFACE_CELLS: u32 = 1024;

/// A value per point of a grid of rectangular cells laid over one triangle in its plane: x
/// along its longest edge, y across, the cells' sides at most the spacing asked for. Values are
/// read bilinearly at a surface point. Only the points a read inside the triangle can reach
/// (the corners of the cells it overlaps) are computed: a long thin triangle gets about as many
/// points as its area needs, not the square of its longest edge over the spacing, as a
/// barycentric lattice would.
pub struct Grid<T = Vec3> {
    /// The grid's point (0, 0): the first corner of the longest edge.
    pub(super) origin: Vec3,
    /// World to grid units: the x axis over the cell's width.
    pub(super) ax: Vec3,
    /// World to grid units: the y axis over the cell's height.
    pub(super) ay: Vec3,
    /// Cells along x.
    pub(super) nx: u32,
    /// Cells along y.
    pub(super) ny: u32,
    /// Per point, row by row ((nx + 1) * (ny + 1)); zero where not computed.
    pub(super) values: Vec<T>,
    /// Points computed.
    pub(super) points: usize,
}

/// What a [`Grid`] stores per point: a colour, or a compact one (visibilities 0 or 1).
pub trait GridValue: Copy + Default {
    /// The value as a colour.
    fn colour(self) -> Vec3;
}

impl GridValue for Vec3 {
    #[inline]
    fn colour(self) -> Vec3 {
        self
    }
}

impl GridValue for [u8; 3] {
    #[inline]
    fn colour(self) -> Vec3 {
        Vec3::new(self[0] as f32, self[1] as f32, self[2] as f32)
    }
}

impl<T: GridValue> Grid<T> {
    /// Lay a grid over the triangle `corners` with cells at most `spacing` wide (and at most
    /// `max_cells` along an axis: wider where the triangle is longer), and compute each point
    /// the triangle's cells need with `value(k, q)`: `k` the point's index (the key of its
    /// random streams), `q` the triangle's point nearest to it, pulled a hair towards the
    /// centroid (a ray aimed at it hits the triangle).
    pub fn over(corners: [Vec3; 3], spacing: f32, max_cells: u32, mut value: impl FnMut(u64, Vec3) -> T) -> Grid<T> {
        let lens = [0, 1, 2].map(|i| (corners[(i + 1) % 3] - corners[i]).length());
        let e = (0..3).fold(0, |m, i| if lens[i] > lens[m] { i } else { m });
        let (a, b, c) = (corners[e], corners[(e + 1) % 3], corners[(e + 2) % 3]);
        let width = lens[e];
        let x = (b - a) / width;
        let across = (c - a) - x * (c - a).dot(x);
        let height = across.length();
        let y = across / height;
        let usable = width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0 && spacing > 0.0;
        if !usable || !x.is_finite() || !y.is_finite() {
            return Grid {
                origin: a,
                ax: Vec3::ZERO,
                ay: Vec3::ZERO,
                nx: 1,
                ny: 1,
                values: vec![T::default(); 4],
                points: 0,
            };
        }
        let cells = |len: f32| ((len / spacing).ceil().min(max_cells.max(1) as f32) as u32).max(1);
        let (nx, ny) = (cells(width), cells(height));
        let (sx, sy) = (width / nx as f32, height / ny as f32);
        let reach = (sx * sx + sy * sy).sqrt() * 1.001;
        let centroid = (a + b + c) / 3.0;
        let mut values = vec![T::default(); ((nx + 1) * (ny + 1)) as usize];
        let mut points = 0;
        for j in 0..=ny {
            for i in 0..=nx {
                let p = a + x * (i as f32 * sx) + y * (j as f32 * sy);
                let q = closest_point_on_triangle(p, a, b, c);
                if (p - q).length() > reach {
                    continue;
                }
                let k = j * (nx + 1) + i;
                values[k as usize] = value(k as u64, q + (centroid - q) * 1e-3);
                points += 1;
            }
        }
        Grid { origin: a, ax: x / sx, ay: y / sy, nx, ny, values, points }
    }

    /// The value at the surface point `p` (bilinear in its cell; outside the grid, at the
    /// nearest edge).
    #[inline(always)]
    pub fn at(&self, p: Vec3) -> Vec3 {
        let d = p - self.origin;
        let (u, v) = (d.dot(self.ax), d.dot(self.ay));
        let u = if u.is_finite() { u.clamp(0.0, self.nx as f32) } else { 0.0 };
        let v = if v.is_finite() { v.clamp(0.0, self.ny as f32) } else { 0.0 };
        let (i, j) = ((u as u32).min(self.nx - 1), (v as u32).min(self.ny - 1));
        let (fu, fv) = (u - i as f32, v - j as f32);
        let row = self.nx as usize + 1;
        let k = j as usize * row + i as usize;
        let v = |k: usize| self.values[k].colour();
        let (p00, p10, p01, p11) = (v(k), v(k + 1), v(k + row), v(k + row + 1));
        (p00 * (1.0 - fu) + p10 * fu) * (1.0 - fv) + (p01 * (1.0 - fu) + p11 * fu) * fv
    }

    /// Points computed.
    pub fn points(&self) -> usize {
        self.points
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
    pub(super) sides: Vec<[OnceLock<Grid>; 2]>,
    /// Per triangle side, the visibility of the first three delta lights (see
    /// [`Renderer::fill_shadow`]).
    pub(super) shadows: Vec<[OnceLock<Grid<[u8; 3]>>; 2]>,
    /// Camera positions of the sequence (the shadow lattices' density follows the nearest).
    pub(super) cameras: Vec<Vec3>,
    /// Radians per pixel of the film (vertical field of view over height).
    pub(super) pixel_angle: f32,
    /// The glossy grids of the keyframes in use (see [`GlossyFrame`]).
    pub(super) glossy: std::sync::Mutex<Vec<Arc<GlossyFrame>>>,
    /// Time spent on the surface, shadow and glossy grids' fills.
    pub clocks: [FillClock; 3],
}

/// The glossy grids of one keyframe of the camera path: per triangle side, the light its
/// rough glossy lobe reflects towards the keyframe's camera, per unit reflectance hint
/// ([`Renderer::fill_glossy`]). A frame between two keyframes reads both and blends them.
pub struct GlossyFrame {
    /// Index of the keyframe in the camera path.
    pub(super) frame: usize,
    /// Its camera position.
    pub(super) origin: Vec3,
    /// Paths per point.
    pub(super) paths: u32,
    /// Per triangle, front and back side.
    pub(super) sides: Vec<[OnceLock<Grid>; 2]>,
}

impl GlossyFrame {
    /// Triangle sides filled so far and their points computed.
    pub(super) fn filled(&self) -> (usize, usize) {
        filled(&self.sides)
    }
}

impl SurfaceCache {
    /// The grid of triangle `prim`'s `front` (or back) side, computed by `fill` on first use.
    #[inline]
    pub fn grid(&self, prim: u32, front: bool, fill: impl FnOnce() -> Grid) -> &Grid {
        self.clocks[0].get_or_fill(&self.sides[prim as usize][usize::from(!front)], fill)
    }

    /// The shadow lattice of triangle `prim`'s `front` (or back) side, computed by `fill` on
    /// first use.
    #[inline]
    pub fn shadow(&self, prim: u32, front: bool, fill: impl FnOnce() -> Grid<[u8; 3]>) -> &Grid<[u8; 3]> {
        self.clocks[1].get_or_fill(&self.shadows[prim as usize][usize::from(!front)], fill)
    }

    /// Triangle sides filled so far and their points computed.
    pub fn filled(&self) -> (usize, usize) {
        filled(&self.sides)
    }

    /// Shadow grids filled so far and their points computed.
    pub fn shadows_filled(&self) -> (usize, usize) {
        filled(&self.shadows)
    }

    /// Glossy grids of the keyframes held now: keyframes, triangle sides and points computed.
    pub fn glossy_filled(&self) -> (usize, usize, usize) {
        let frames = self.glossy.lock().unwrap_or_else(|e| e.into_inner());
        frames.iter().map(|f| f.filled()).fold((frames.len(), 0, 0), |(k, n, p), (a, b)| (k, n + a, p + b))
    }

    /// The keyframes a frame whose camera is at `origin` reads, with their weights: with a
    /// camera path and `stride` > 0, the two keyframes (every `stride` frames of the path, and
    /// its last frame) around the point of the path nearest `origin`, weighted linearly; else
    /// `origin`'s own. Keyframes far from these are dropped.
    pub(super) fn glossy_frames(&self, origin: Vec3, stride: u32, paths: u32) -> Vec<(Arc<GlossyFrame>, f32)> {
        let path = &self.cameras;
        let n = path.len();
        let stride = stride.max(1) as usize;
        let wanted: Vec<(usize, Vec3, f32)> = if n < 2 {
            vec![(0, origin, 1.0)]
        } else {
            let t = path_position(path, origin);
            let k0 = ((t / stride as f32).floor() as usize * stride).min(n - 1);
            let k1 = (k0 + stride).min(n - 1);
            let f = if k1 > k0 { ((t - k0 as f32) / (k1 - k0) as f32).clamp(0.0, 1.0) } else { 0.0 };
            vec![(k0, path[k0], 1.0 - f), (k1, path[k1], f)]
        };
        let mut frames = self.glossy.lock().unwrap_or_else(|e| e.into_inner());
        // keep the keyframes within a stride of these (frames come in order, mostly)
        let (lo, hi) = (wanted[0].0.saturating_sub(stride), wanted[wanted.len() - 1].0 + stride);
        // (a lone camera's keyframe is its own position)
        frames.retain(|f| f.paths == paths && (lo..=hi).contains(&f.frame) && (n >= 2 || f.origin == origin));
        wanted
            .into_iter()
            .filter(|w| w.2 > 0.0)
            .map(|(k, o, w)| {
                let frame = match frames.iter().find(|f| f.frame == k && f.origin == o) {
                    Some(f) => f.clone(),
                    None => {
                        let sides = per_side(self.sides.len());
                        let f = Arc::new(GlossyFrame { frame: k, origin: o, paths, sides });
                        frames.push(f.clone());
                        f
                    }
                };
                (frame, w)
            })
            .collect()
    }
}

/// Sides filled so far in `sides` and their points computed.
pub(super) fn filled<T: GridValue>(sides: &[[OnceLock<Grid<T>>; 2]]) -> (usize, usize) {
    let grids = sides.iter().flatten().filter_map(|s| s.get());
    grids.fold((0, 0), |(n, p), g| (n + 1, p + g.points))
}

/// Where along the polyline `path` (>= 2 points) the point nearest `origin` lies, as a
/// fractional index: exactly `i` when `origin` is point `i` (the first such), else the first
/// of equally near points.
pub(super) fn path_position(path: &[Vec3], origin: Vec3) -> f32 {
    // a frame of the path itself: exactly its index
    if let Some(i) = path.iter().position(|&p| p == origin) {
        return i as f32;
    }
    let mut best = (f32::INFINITY, 0.0);
    for (i, seg) in path.windows(2).enumerate() {
        let (a, b) = (seg[0], seg[1]);
        let ab = b - a;
        let len2 = ab.length_squared();
        let u = if len2 > 0.0 { ((origin - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let d = (a + ab * u - origin).length_squared();
        if d < best.0 {
            best = (d, i as f32 + u);
        }
    }
    best.1
}

/// One empty slot per side of `n` triangles.
pub(super) fn per_side<T>(n: usize) -> Vec<[OnceLock<T>; 2]> {
    (0..n).map(|_| [OnceLock::new(), OnceLock::new()]).collect()
}

/// The unit normal of the side `front` (or back) of the triangle `corners`; None if degenerate.
pub(super) fn side_normal(corners: [Vec3; 3], front: bool) -> Option<Vec3> {
    let [a, b, c] = corners;
    let ng = (b - a).cross(c - a).try_normalize()?;
    Some(if front { ng } else { -ng })
}
