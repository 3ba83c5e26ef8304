//! A world-space radiance cache for static scenes: the light a surface reflects, per unit
//! reflectance, stored on a lattice over every triangle and computed once per sequence.
//!
//! With the cache on ([`super::film::RenderSettings::radiance_cache`]), a path ends at its second
//! surface vertex: the vertex's emission is added as always (weighted against the light sample
//! of the first vertex), and its reflected light is its reflectance hint times the cached value
//! interpolated at the hit. So a camera sample costs a shadow ray and one bounce ray instead of a
//! whole path, and what lies beyond the second vertex, the noisiest part of the estimate, is the
//! same in every frame: it cannot flicker as the camera moves (flicker fires false events).
//!
//! Each triangle side gets a barycentric lattice of `r` steps per edge, `r` from its longest
//! edge over the spacing (1..=[`MAX_STEPS`]). A lattice point's value is the ratio of the light
//! reflected towards the surface normal (a path from a ray shot at the point from just in front
//! of it, minus the point's emission) over the reflectance hint there, averaged over
//! `radiance_cache` paths. Values are computed the first time a path reaches the triangle side,
//! from random streams keyed by (seed, triangle, side, point): the same numbers whatever the
//! thread count or the order frames are rendered in, so a resumed run gets the same bytes.
//!
//! The approximation: beyond the second vertex, surfaces are taken as diffuse (the cached light
//! is what they send along their normal, scaled by the reflectance at the hit) and their
//! lighting as varying linearly between lattice points. `evsim dataset-noise` and the cache's
//! test measure what this costs against full paths.
//!
//! **At the first vertex** ([`super::film::RenderSettings::cache_vertex`] 1) a second lattice
//! holds the *indirect* light of every triangle side the camera sees: a camera sample on a
//! mostly diffuse surface (the specular lobe reflecting under half the light,
//! [`super::bsdf::Bsdf::specular_share`]) traces only the shadow rays of its direct light, of
//! the delta lights (the sun: sharp shadows stay exact) and of one emissive triangle picked by
//! power, and adds its reflectance hint times this lattice's value. The lattice's paths are
//! camera paths shot at the point that leave out those two direct terms and end at their second
//! vertex in the first lattice; they keep the environment (sky light through an opening is
//! soft) and, of an emitter reached by BSDF sampling, the share multiple importance sampling
//! gives BSDF samples against the camera samples' light samples (near an emitter, where a
//! light sample's contribution has no bound, nearly all of it). Glossy and metal surfaces keep
//! the bounce ray. The price is more blur in the indirect light (the lattice's spacing) and
//! the glossy reflections of mostly diffuse surfaces; the gain is a camera sample with no bounce
//! ray and indirect light that does not flicker.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use glam::{Vec2, Vec3};

use super::sampler::SamplerKind;

/// Largest number of lattice steps along a triangle edge.
pub const MAX_STEPS: u32 = 128;

/// What a cache's values depend on besides the scene: a cache is reused only for renders with
/// the same parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CacheParams {
    /// Paths per lattice point.
    pub paths: u32,
    /// Lattice spacing (world units).
    pub spacing: f32,
    /// Seed of the cache's random streams.
    pub seed: u64,
    /// Where the numbers come from.
    pub sampler: SamplerKind,
    /// Path segments of the cached paths (counting the ray that reaches the point).
    pub max_depth: u32,
    /// Russian roulette depth of the cached paths.
    pub rr_depth: u32,
    /// Sample clamping of the cached paths.
    pub clamp: f32,
    /// Light samples per vertex of the cached paths.
    pub light_samples: u32,
    /// Also a cache of indirect light for the camera paths' first vertex
    /// ([`super::film::RenderSettings::cache_vertex`] 1, see [`RadianceCache::indirect_lattice`]).
    pub first: bool,
}

/// Thread time spent on lazily filled lattices or grids of one kind: computing them, and
/// waiting for the one another thread is computing (both summed over threads). A fill's time
/// includes the fills it sets off (a surface grid's paths fill radiance-cache lattices).
#[derive(Debug, Default)]
pub struct FillClock {
    fills: AtomicU64,
    fill_ns: AtomicU64,
    wait_ns: AtomicU64,
}

/// What a [`FillClock`] measured so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FillTimes {
    /// Lattices or grids computed.
    pub fills: u64,
    /// Thread time computing them.
    pub fill: Duration,
    /// Thread time waiting for another thread's fill.
    pub wait: Duration,
}

impl FillClock {
    /// `cell`'s value, computed by `fill` on first use (timed, as is a wait for another
    /// thread's fill of it).
    #[inline]
    pub fn get_or_fill<'a, T>(&self, cell: &'a OnceLock<T>, fill: impl FnOnce() -> T) -> &'a T {
        match cell.get() {
            Some(v) => v,
            None => self.timed(cell, fill),
        }
    }

    #[cold]
    fn timed<'a, T>(&self, cell: &'a OnceLock<T>, fill: impl FnOnce() -> T) -> &'a T {
        let t = Instant::now();
        let mut filled = false;
        let v = cell.get_or_init(|| {
            filled = true;
            fill()
        });
        let ns = t.elapsed().as_nanos() as u64;
        if filled {
            self.fills.fetch_add(1, Ordering::Relaxed);
            self.fill_ns.fetch_add(ns, Ordering::Relaxed);
        } else {
            self.wait_ns.fetch_add(ns, Ordering::Relaxed);
        }
        v
    }

    /// What it measured so far.
    pub fn times(&self) -> FillTimes {
        FillTimes {
            fills: self.fills.load(Ordering::Relaxed),
            fill: Duration::from_nanos(self.fill_ns.load(Ordering::Relaxed)),
            wait: Duration::from_nanos(self.wait_ns.load(Ordering::Relaxed)),
        }
    }
}

/// The cache of one scene (see the [module docs](self)); filled lazily.
pub struct RadianceCache {
    /// Its parameters.
    pub params: CacheParams,
    /// Per triangle, front and back side: the lattice steps and the values of the lattice points.
    sides: Vec<[OnceLock<Lattice>; 2]>,
    /// The same for the indirect light at the first vertex (empty unless `params.first`).
    indirect: Vec<[OnceLock<Lattice>; 2]>,
    /// Time spent on both lattices' fills.
    pub clock: FillClock,
}

/// One triangle side's lattice.
#[derive(Clone, Debug)]
pub struct Lattice {
    /// Steps per edge.
    pub steps: u32,
    /// Values of the `(steps + 1)(steps + 2) / 2` points, in [`lattice_index`] order.
    pub values: Vec<Vec3>,
}

impl RadianceCache {
    /// An empty cache for `triangles` triangles.
    pub fn new(params: CacheParams, triangles: usize) -> RadianceCache {
        let sides = |n: usize| (0..n).map(|_| [OnceLock::new(), OnceLock::new()]).collect();
        let indirect = sides(if params.first { triangles } else { 0 });
        RadianceCache { params, sides: sides(triangles), indirect, clock: FillClock::default() }
    }

    /// The first-vertex lattice of triangle `prim`'s `front` (or back) side, computed by `fill`
    /// on first use: light reflected as the second-vertex lattice's is, but leaving out the
    /// direct light of delta lights and emissive triangles at the point (the camera samples
    /// trace those) and, of the light of emitters that the cache's paths reach by BSDF
    /// sampling, the share the camera samples' light samples take (MIS). Only with
    /// `params.first`.
    #[inline]
    pub fn indirect_lattice(&self, prim: u32, front: bool, fill: impl FnOnce() -> Lattice) -> &Lattice {
        self.clock.get_or_fill(&self.indirect[prim as usize][usize::from(!front)], fill)
    }

    /// The lattice of triangle `prim`'s `front` (or back) side, computed by `fill` on first use.
    #[inline]
    pub fn lattice(&self, prim: u32, front: bool, fill: impl FnOnce() -> Lattice) -> &Lattice {
        self.clock.get_or_fill(&self.sides[prim as usize][usize::from(!front)], fill)
    }

    /// Triangle sides filled so far and their lattice points (both lattices).
    pub fn filled(&self) -> (usize, usize) {
        let mut sides = 0;
        let mut points = 0;
        for l in self.sides.iter().chain(&self.indirect).flatten().filter_map(|s| s.get()) {
            sides += 1;
            points += l.values.len();
        }
        (sides, points)
    }
}

/// Index of lattice point (`i`, `j`) (barycentrics `(i / steps, j / steps)` for corners 1 and 2,
/// `i + j <= steps`) in a lattice of `steps` steps.
#[inline]
pub fn lattice_index(steps: u32, i: u32, j: u32) -> usize {
    // rows of constant j hold steps + 1 - j points
    (j * (steps + 1) - j * j.saturating_sub(1) / 2 + i) as usize
}

/// Lattice steps of a triangle whose longest edge is `longest` at `spacing`.
pub fn steps_for(longest: f32, spacing: f32) -> u32 {
    if !(spacing > 0.0) || !longest.is_finite() {
        return 1;
    }
    ((longest / spacing).ceil() as u32).clamp(1, MAX_STEPS)
}

/// Barycentrics (b1, b2) of lattice point (`i`, `j`), pulled towards the centroid by a hair so
/// that a ray aimed at a corner or edge point still hits the triangle.
pub fn lattice_bary(steps: u32, i: u32, j: u32) -> Vec2 {
    let b = Vec2::new(i as f32, j as f32) / steps as f32;
    let c = Vec2::splat(1.0 / 3.0);
    c + (b - c) * (1.0 - 1e-3)
}

impl Lattice {
    /// The value at barycentrics `bary` (b1, b2): linear within the lattice cell holding it.
    pub fn at(&self, bary: Vec2) -> Vec3 {
        let r = self.steps;
        let rf = r as f32;
        let (u, v) = ((bary.x.clamp(0.0, 1.0)) * rf, (bary.y.clamp(0.0, 1.0)) * rf);
        let (i, j) = ((u.floor() as u32).min(r), (v.floor() as u32).min(r));
        let (fu, fv) = (u - i as f32, v - j as f32);
        let p = |i: u32, j: u32| {
            let (i, j) = (i.min(r), j.min(r));
            let i = i.min(r - j);
            self.values[lattice_index(r, i, j)]
        };
        if i + j >= r {
            // on or past the far edge (float error): the nearest lattice point
            return p(i, j);
        }
        if fu + fv <= 1.0 {
            p(i, j) * (1.0 - fu - fv) + p(i + 1, j) * fu + p(i, j + 1) * fv
        } else {
            // the upper cell (i + 1, j + 1), (i, j + 1), (i + 1, j)
            let (gu, gv) = (1.0 - fu, 1.0 - fv);
            p(i + 1, j + 1) * (1.0 - gu - gv) + p(i, j + 1) * gu + p(i + 1, j) * gv
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_indices_enumerate_the_points_once() {
        for r in 1..9 {
            let mut seen = vec![false; ((r + 1) * (r + 2) / 2) as usize];
            for j in 0..=r {
                for i in 0..=r - j {
                    let k = lattice_index(r, i, j);
                    assert!(!seen[k], "r {r}: ({i}, {j}) -> {k} twice");
                    seen[k] = true;
                }
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    #[test]
    fn interpolation_is_exact_for_linear_functions() {
        // values of a linear function of the barycentrics come back exactly (up to rounding)
        let f = |b: Vec2| Vec3::new(1.0 + 2.0 * b.x - b.y, 0.5 * b.y, 3.0 - b.x);
        for r in [1u32, 2, 5, 16] {
            let mut values = vec![Vec3::ZERO; ((r + 1) * (r + 2) / 2) as usize];
            for j in 0..=r {
                for i in 0..=r - j {
                    values[lattice_index(r, i, j)] = f(Vec2::new(i as f32, j as f32) / r as f32);
                }
            }
            let l = Lattice { steps: r, values };
            let mut rng = crate::base::sampling::Rng::new(r as u64, 1);
            for _ in 0..500 {
                let mut b = rng.next_2d();
                if b.x + b.y > 1.0 {
                    b = Vec2::ONE - b;
                }
                assert!((l.at(b) - f(b)).abs().max_element() < 1e-4, "r {r} at {b}: {} vs {}", l.at(b), f(b));
            }
        }
    }

    #[test]
    fn fill_clock_counts_each_fill_once_and_times_a_wait() {
        let clock = FillClock::default();
        let cell = OnceLock::new();
        let calls = AtomicU64::new(0);
        let fill = || {
            calls.fetch_add(1, Ordering::Relaxed);
            7u32
        };
        assert_eq!(*clock.get_or_fill(&cell, fill), 7);
        assert_eq!(*clock.get_or_fill(&cell, || unreachable!("the cell is filled")), 7);
        let t = clock.times();
        assert_eq!((t.fills, calls.load(Ordering::Relaxed), t.wait), (1, 1, Duration::ZERO));
        // a second thread that needs the cell while the first fills it waits, and is timed
        let (clock, cell) = (FillClock::default(), OnceLock::new());
        let (started, go) = std::sync::mpsc::channel();
        std::thread::scope(|scope| {
            scope.spawn(|| {
                clock.get_or_fill(&cell, || {
                    started.send(()).unwrap();
                    std::thread::sleep(Duration::from_millis(30));
                    1u8
                })
            });
            go.recv().unwrap();
            assert_eq!(*clock.get_or_fill(&cell, || 2u8), 1, "the first fill's value");
        });
        let t = clock.times();
        assert_eq!(t.fills, 1);
        assert!(t.fill >= Duration::from_millis(30) && t.wait > Duration::ZERO, "{t:?}");
    }

    #[test]
    fn steps_follow_the_spacing_within_bounds() {
        assert_eq!(steps_for(1.0, 0.25), 4);
        assert_eq!(steps_for(0.01, 0.25), 1);
        assert_eq!(steps_for(1e6, 0.25), MAX_STEPS);
        assert_eq!(steps_for(1.0, 0.0), 1);
        assert_eq!(steps_for(f32::NAN, 0.1), 1);
    }
}
