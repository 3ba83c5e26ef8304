//! An occupancy grid over the model's box: which cells may hold density, so that the samples in
//! the others skip the field (empty-space skipping, as Instant-NGP's density grid and TensoRF's
//! alpha mask).
//!
//! **What it holds.** The box (`model.bounds`) is cut into about `res^3` cubic cells
//! ([`Aabb::grid`]). [`OccupancyGrid::build`] evaluates the coarse field's raw density (before
//! noise and the ReLU) at one point per cell, jittered inside it from the run seed and the step,
//! and marks a cell occupied when that density is above `threshold` at its own point or at a
//! neighbour's (a 3 x 3 x 3 dilation, against detail finer than a cell). The presets' threshold
//! is -4: four standard deviations of the density noise below the ReLU's zero, so that a
//! sample in an empty cell would almost never have been alive anyway.
//!
//! **How it is used.** The renderer looks each sample up before the field: a sample in an empty
//! cell is not evaluated and counts as dead (zero density, no colour, no gradient). Samples
//! outside the box are always evaluated. The grid is rebuilt from the current parameters every
//! `every` steps; between rebuilds it is fixed, so a forward and its replay skip the same
//! samples and the gradients are exact for the rendering so skipped. It is part of the training
//! state (checkpoints keep it), so a resumed run skips what the uninterrupted run skipped.

use rayon::prelude::*;

use super::field::FieldWorkspace;
use super::model::{Aabb, Model};
use super::real::Real;
use super::rng::Rng;

/// When and how finely the occupancy grid is built (`model.occupancy`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OccupancyConfig {
    /// Cells per axis, about (the box is cut into about `res^3` cubic cells).
    pub res: usize,
    /// Steps between rebuilds.
    pub every: u64,
    /// Raw density (before noise and the ReLU) above which a cell is occupied.
    pub threshold: f64,
}

/// Which cells of the box may hold density (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyGrid {
    /// Cells per axis.
    pub dims: [usize; 3],
    /// The box.
    pub bounds: Aabb,
    /// One bit per cell, x fastest.
    pub bits: Vec<u64>,
}

/// Points per field call while building (one z-slice of cells is cut into such batches).
const BATCH: usize = 4096;

impl OccupancyGrid {
    /// Words of the bitset for `dims`.
    pub fn words(dims: [usize; 3]) -> usize {
        (dims[0] * dims[1] * dims[2]).div_ceil(64)
    }

    /// Builds the grid of `model`'s coarse field with `params` over `bounds` (see the module
    /// doc): the jitter comes from `seed` and `step`, so the same inputs give the same grid
    /// whatever the thread count.
    pub fn build<R: Real>(
        model: &Model,
        params: &[R],
        bounds: Aabb,
        cfg: &OccupancyConfig,
        seed: u64,
        step: u64,
    ) -> Self {
        let dims = bounds.grid(cfg.res);
        let [nx, ny, nz] = dims;
        let size: [f64; 3] = std::array::from_fn(|a| (bounds.max[a] - bounds.min[a]) / dims[a] as f64);
        let field = &model.coarse;
        let threshold = R::of(cfg.threshold);
        // Above-threshold flags per cell, one z-slice per task (its own jitter stream).
        let slices: Vec<Vec<bool>> = (0..nz)
            .into_par_iter()
            .map_init(FieldWorkspace::<R>::default, |ws, z| {
                let mut rng = Rng::new(seed ^ 0x6f63_6375_7061_6e63, step * nz as u64 + z as u64);
                let pos: Vec<[R; 3]> = (0..nx * ny)
                    .map(|i| {
                        let cell = [i % nx, i / nx, z];
                        std::array::from_fn(|a| {
                            let u = rng.uniform_f32() as f64;
                            R::of(bounds.min[a] + (cell[a] as f64 + u) * size[a])
                        })
                    })
                    .collect();
                let mut sigma = vec![R::zero(); pos.len()];
                for (p, s) in pos.chunks(BATCH).zip(sigma.chunks_mut(BATCH)) {
                    field.forward_density(params, ws, p, s);
                }
                sigma.iter().map(|&s| s > threshold).collect()
            })
            .collect();
        // Dilate by one cell.
        let at = |x: usize, y: usize, z: usize| slices[z][y * nx + x];
        let mut bits = vec![0u64; Self::words(dims)];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let near = |c: usize, n: usize| c.saturating_sub(1)..(c + 2).min(n);
                    let occupied = near(z, nz).any(|zz| near(y, ny).any(|yy| near(x, nx).any(|xx| at(xx, yy, zz))));
                    if occupied {
                        let i = (z * ny + y) * nx + x;
                        bits[i / 64] |= 1 << (i % 64);
                    }
                }
            }
        }
        OccupancyGrid { dims, bounds, bits }
    }

    /// Whether the cell holding `p` may hold density (true outside the box).
    #[inline]
    pub fn occupied(&self, p: [f64; 3]) -> bool {
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let u = (p[a] - self.bounds.min[a]) / (self.bounds.max[a] - self.bounds.min[a]);
            if !(0.0..1.0).contains(&u) {
                return true;
            }
            idx[a] = ((u * self.dims[a] as f64) as usize).min(self.dims[a] - 1);
        }
        let i = (idx[2] * self.dims[1] + idx[1]) * self.dims[0] + idx[0];
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// The fraction of occupied cells.
    pub fn occupied_fraction(&self) -> f64 {
        let cells = self.dims.iter().product::<usize>().max(1);
        self.bits.iter().map(|w| w.count_ones() as usize).sum::<usize>() as f64 / cells as f64
    }
}
