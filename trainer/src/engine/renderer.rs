//! Rendering a chunk of rays through a [`Model`]: stratified coarse samples, the coarse field,
//! volume rendering, importance samples from the coarse weights, the fine field over the
//! sorted union, volume rendering again (NeRF's hierarchical sampling); and the whole chain
//! backward from dL/dC of both passes to the parameters.
//!
//! **Skipped samples.** A sample whose density after the noise and the ReLU is zero has
//! alpha = 0 and weight 0 exactly, and its ReLU passes no gradient: it adds nothing to the
//! colour and nothing to any gradient (its colour's gradient is its weight times dL/dC, its
//! position's flows only through the density and the colour). So the field evaluates the
//! density of every sample, and the colour MLP and the whole backward only for the alive ones
//! (the rows are compacted in place, [`Field::forward_colour`]); a skipped sample's features
//! read as zero (a loss on them must weigh them by the render weight, as the AWP's does). And
//! when one field serves both passes (no fine level), the fine pass re-uses the coarse
//! samples' evaluations and evaluates only the importance samples; each coarse sample's
//! gradients from both passes are summed before its one backward. The results are the dense
//! engine's up to rounding, except that a re-used coarse sample keeps its coarse density noise
//! in the fine pass (the dense engine draws it again). `ModelConfig::dense` keeps the dense
//! engine (every sample through the whole field, the union evaluated again) to compare against;
//! [`SampleCounts`] says how many samples each path evaluated.
//!
//! Rays are in NDC (near 0, far 1); `viewdirs` are the unit world-space directions the colour
//! MLP sees. A chunk is rendered with one field call per pass, so the matrix products see
//! `rays x samples` rows. Everything lives in a reusable [`Renderer`]: no allocation per chunk
//! once it has grown to the chunk size.

use super::field::{Field, FieldWorkspace};
use super::model::Model;
use super::occupancy::OccupancyGrid;
use super::real::Real;
use super::rng::Rng;
use super::sampling;
use super::volume::{self, RaySamples, RenderGrad};

mod evals;
use evals::Evals;

/// The rays of a chunk (all three slices have one entry per ray).
#[derive(Clone, Copy, Debug)]
pub struct RayChunk<'a, R = f32> {
    /// NDC origins.
    pub origins: &'a [[R; 3]],
    /// NDC directions (not normalised).
    pub dirs: &'a [[R; 3]],
    /// Unit view directions in world space.
    pub viewdirs: &'a [[R; 3]],
}

/// The raw density a sample in an empty cell of the occupancy grid reads as (not evaluated):
/// far below zero, so that it is dead whatever its density noise.
pub const SKIPPED: f64 = -1e9;

/// A [`Pass`] sample's row code with this bit set is a row of the fine [`Evals`] (else of the
/// coarse ones).
const FINE_ROW: u32 = 1 << 31;

/// One pass's (coarse or fine) rendered samples: each is a row of the coarse or the fine
/// [`Evals`] (`src`), its depth, noise and field outputs gathered from there.
#[derive(Clone, Debug, Default)]
struct Pass<R> {
    /// Samples per ray.
    s: usize,
    src: Vec<u32>,
    t: Vec<R>,
    sigma: Vec<R>,
    rgb: Vec<[R; 3]>,
    noise: Vec<R>,
    weights: Vec<R>,
    /// Per-sample features of the density MLP (zero for a dead sample; filled for the last
    /// pass only).
    feats: Vec<R>,
    /// Rendered colour per ray.
    out: Vec<[R; 3]>,
    d_sigma: Vec<R>,
    d_rgb: Vec<[R; 3]>,
    /// dL/d|d| per ray from volume rendering (the sample spacing scales with |d|).
    d_norm: Vec<R>,
    /// Per ray, where early ray termination ends it (`s`: it does not end early).
    end: Vec<usize>,
}

impl<R: Real> Pass<R> {
    fn resize(&mut self, rays: usize, s: usize) {
        let n = rays * s;
        self.s = s;
        self.src.resize(n, 0);
        self.t.resize(n, R::zero());
        self.sigma.resize(n, R::zero());
        self.rgb.resize(n, [R::zero(); 3]);
        self.noise.resize(n, R::zero());
        self.weights.resize(n, R::zero());
        self.out.resize(rays, [R::zero(); 3]);
        self.d_sigma.resize(n, R::zero());
        self.d_rgb.resize(n, [R::zero(); 3]);
        self.d_norm.resize(rays, R::zero());
        self.end.clear();
        self.end.resize(rays, s);
    }

    /// The row of `coarse` or `fine` sample `i` comes from.
    fn row<'e>(&self, i: usize, coarse: &'e Evals<R>, fine: &'e Evals<R>) -> (&'e Evals<R>, usize) {
        let code = self.src[i];
        if code & FINE_ROW != 0 {
            (fine, (code & !FINE_ROW) as usize)
        } else {
            (coarse, code as usize)
        }
    }

    /// Gathers each sample's depth, noise and raw density from its row; colours are zero until
    /// [`gather_colour`](Self::gather_colour).
    fn gather_density(&mut self, coarse: &Evals<R>, fine: &Evals<R>) {
        for i in 0..self.src.len() {
            let (ev, row) = self.row(i, coarse, fine);
            self.t[i] = ev.t[row];
            self.sigma[i] = ev.sigma[row];
            self.noise[i] = ev.noise[row];
            self.rgb[i] = [R::zero(); 3];
        }
    }

    /// Marks the rows of the samples whose render weight is above `threshold` (every sample's
    /// with `None`) as wanting their colour.
    fn light(&self, threshold: Option<R>, coarse: &mut Evals<R>, fine: &mut Evals<R>) {
        for (i, &code) in self.src.iter().enumerate() {
            if threshold.is_some_and(|thr| self.weights[i] <= thr) {
                continue;
            }
            if code & FINE_ROW != 0 {
                fine.lit[(code & !FINE_ROW) as usize] = true;
            } else {
                coarse.lit[code as usize] = true;
            }
        }
    }

    /// Gathers each sample's colour from its row; with `field`, also its features (from the
    /// field's workspace, zero for a dead row).
    fn gather_colour(&mut self, coarse: &Evals<R>, fine: &Evals<R>, field: Option<&Field>) {
        let width = field.map_or(0, |f| f.shape.features);
        self.feats.clear();
        self.feats.resize(self.src.len() * width, R::zero());
        for i in 0..self.src.len() {
            let (ev, row) = self.row(i, coarse, fine);
            self.rgb[i] = ev.rgb[row];
            if let (Some(f), k) = (field, ev.kidx[row]) {
                if k != u32::MAX {
                    self.feats[i * width..(i + 1) * width].copy_from_slice(f.features(&ev.ws, k as usize));
                }
            }
        }
    }

    fn samples(&self, r: usize, dir_norm: R, train: bool) -> RaySamples<'_, R> {
        let range = r * self.s..(r + 1) * self.s;
        RaySamples {
            t: &self.t[range.clone()],
            dir_norm,
            sigma_raw: &self.sigma[range.clone()],
            rgb: self.rgb[range.clone()].as_flattened(),
            noise: train.then(|| &self.noise[range]),
        }
    }

    /// Ends each ray before its first sample of transmittance below `cutoff` (early ray
    /// termination; `None`: every ray runs to its last sample).
    fn terminate(&mut self, chunk: &RayChunk<R>, rays: usize, train: bool, cutoff: Option<R>) {
        for r in 0..rays {
            self.end[r] = match cutoff {
                Some(c) => volume::termination(&self.samples(r, norm(chunk.dirs[r]), train), c),
                None => self.s,
            };
        }
    }

    /// Samples past the end of their ray.
    fn ended(&self, rays: usize) -> u64 {
        self.end[..rays].iter().map(|&e| (self.s - e) as u64).sum()
    }

    /// Volume-renders every ray of the pass (up to its end).
    fn render(&mut self, chunk: &RayChunk<R>, rays: usize, train: bool) {
        let mut weights = std::mem::take(&mut self.weights);
        for r in 0..rays {
            let out = volume::render_until(
                &self.samples(r, norm(chunk.dirs[r]), train),
                self.end[r],
                &mut weights[r * self.s..(r + 1) * self.s],
            );
            self.out[r] = out.rgb;
        }
        self.weights = weights;
    }

    /// Backward through volume rendering from dL/dC, then each sample's dL/dsigma_raw and
    /// dL/drgb (and `d_features`, samples x width) added to its row.
    #[allow(clippy::too_many_arguments)]
    fn render_backward(
        &mut self,
        chunk: &RayChunk<R>,
        rays: usize,
        d_out: &[[R; 3]],
        train: bool,
        coarse: &mut Evals<R>,
        fine: &mut Evals<R>,
        d_features: Option<(&[R], usize)>,
    ) {
        let (mut ds, mut dr) = (std::mem::take(&mut self.d_sigma), std::mem::take(&mut self.d_rgb));
        for r in 0..rays {
            let range = r * self.s..(r + 1) * self.s;
            self.d_norm[r] = volume::render_backward_until(
                &self.samples(r, norm(chunk.dirs[r]), train),
                self.end[r],
                &RenderGrad::rgb(d_out[r]),
                &mut ds[range.clone()],
                dr[range].as_flattened_mut(),
            );
        }
        for (i, &code) in self.src.iter().enumerate() {
            let (ev, row) = if code & FINE_ROW != 0 {
                (&mut *fine, (code & !FINE_ROW) as usize)
            } else {
                (&mut *coarse, code as usize)
            };
            ev.d_sigma[row] += ds[i];
            for c in 0..3 {
                ev.d_rgb[row][c] += dr[i][c];
            }
            if let Some((df, w)) = d_features {
                for (a, b) in ev.d_feat[row * w..(row + 1) * w].iter_mut().zip(&df[i * w..(i + 1) * w]) {
                    *a += *b;
                }
            }
        }
        self.d_sigma = ds;
        self.d_rgb = dr;
    }

    /// Adds the |d| term of the sample spacing to each ray's direction gradient.
    fn add_norm_grads(&self, chunk: &RayChunk<R>, rays: usize, out: &mut [RayGrad<R>]) {
        for (r, g) in out.iter_mut().enumerate().take(rays) {
            let d = chunk.dirs[r];
            let n = norm(d);
            for a in 0..3 {
                g.dir[a] += self.d_norm[r] * d[a] / n;
            }
        }
    }
}

/// dL/d of a ray's inputs: NDC origin and direction, and the world view direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayGrad<R> {
    /// dL/d origin (NDC).
    pub origin: [R; 3],
    /// dL/d direction (NDC).
    pub dir: [R; 3],
    /// dL/d view direction (as given to the colour MLP).
    pub viewdir: [R; 3],
}

impl<R: Real> RayGrad<R> {
    /// All zero.
    pub fn zero() -> RayGrad<R> {
        RayGrad { origin: [R::zero(); 3], dir: [R::zero(); 3], viewdir: [R::zero(); 3] }
    }
}

fn norm<R: Real>(d: [R; 3]) -> R {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The samples of one pass over a chunk (rows ray-major: ray r's samples are rows
/// `r * per_ray .. (r + 1) * per_ray`).
#[derive(Clone, Copy, Debug)]
pub struct PassSamples<'a, R> {
    /// Samples per ray.
    pub per_ray: usize,
    /// Per-sample features of the density MLP: row i starts at `i * stride`, `width` values.
    pub features: &'a [R],
    /// Row stride of `features`.
    pub stride: usize,
    /// Features per sample.
    pub width: usize,
    /// Render weights of the samples (one per row).
    pub weights: &'a [R],
}

/// Reusable state for rendering chunks of rays (one per thread).
#[derive(Clone, Debug, Default)]
pub struct Renderer<R = f32> {
    rays: usize,
    train: bool,
    fine_pass: bool,
    coarse: Pass<R>,
    fine: Pass<R>,
    coarse_evals: Evals<R>,
    fine_evals: Evals<R>,
    t_imp: Vec<R>,
    counts: SampleCounts,
}

/// How many samples a [`Renderer`] has rendered and how many the field evaluated, since it was
/// made (the sums of every forward).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SampleCounts {
    /// Rays rendered.
    pub rays: u64,
    /// Samples volume-rendered (both passes).
    pub rendered: u64,
    /// Samples whose density was evaluated.
    pub density: u64,
    /// Samples that were alive (positive density after noise): their density's backward.
    pub alive: u64,
    /// Alive samples whose colour a pass wanted: the colour MLP's forward and backward.
    pub coloured: u64,
    /// Samples past the end of their ray (early ray termination), summed over the passes.
    pub ended: u64,
}

impl<R: Real> Renderer<R> {
    /// Renders `chunk`. In training (`rngs`: one generator per ray) the coarse samples are
    /// jittered, importance samples are random and density noise is added; otherwise all three
    /// are deterministic. The colours are then in [`coarse`](Self::coarse) and
    /// [`fine`](Self::fine).
    pub fn forward(&mut self, model: &Model, params: &[R], chunk: &RayChunk<R>, rngs: Option<&mut [Rng]>) {
        self.forward_passes(model, params, chunk, rngs, true);
    }

    /// [`forward`](Self::forward) with the coarse pass only (PDRF's first stage): the
    /// colours, [`last_pass`](Self::last_pass) and [`backward`](Self::backward) are then the
    /// coarse pass's, and each ray draws the same random numbers as the coarse part of a full
    /// forward.
    pub fn forward_coarse(&mut self, model: &Model, params: &[R], chunk: &RayChunk<R>, rngs: Option<&mut [Rng]>) {
        self.forward_passes(model, params, chunk, rngs, false);
    }

    /// The samples counted so far.
    pub fn counts(&self) -> SampleCounts {
        self.counts
    }

    /// The occupancy grid the coarse field's samples skip by (none on the dense path).
    fn grid(model: &Model) -> Option<&OccupancyGrid> {
        model.occupancy.as_ref().filter(|_| !model.config.dense)
    }

    /// The grid of the fine pass's field: the same when one field serves both passes (the grid
    /// holds the coarse field's density), none for a separate fine field.
    fn fine_grid(model: &Model) -> Option<&OccupancyGrid> {
        Self::grid(model).filter(|_| model.fine.is_none())
    }

    /// Whether the fine pass re-uses the coarse pass's evaluations (one field for both
    /// passes, samples skipped) and evaluates only the importance samples.
    fn reuses(model: &Model) -> bool {
        model.fine.is_none() && !model.config.dense
    }

    fn forward_passes(
        &mut self,
        model: &Model,
        params: &[R],
        chunk: &RayChunk<R>,
        mut rngs: Option<&mut [Rng]>,
        fine: bool,
    ) {
        let rays = chunk.origins.len();
        let cfg = &model.config;
        let (nc, nf) = (cfg.n_coarse, model.samples_fine());
        self.rays = rays;
        self.train = rngs.is_some();
        self.fine_pass = fine && cfg.n_fine > 0;
        let reuse = Self::reuses(model);
        self.coarse_evals.resize(rays, nc);
        self.coarse.resize(rays, nc);
        self.t_imp.resize(cfg.n_fine, R::zero());
        let noise_std = R::of(cfg.density_noise);
        // Coarse pass: stratified t in [0, 1] (NDC), density noise.
        let ce = &mut self.coarse_evals;
        for r in 0..rays {
            let rng = rngs.as_deref_mut().map(|g| &mut g[r]);
            let t = &mut ce.t[r * nc..(r + 1) * nc];
            match rng {
                Some(rng) => {
                    sampling::stratified(R::zero(), R::one(), nc, Some(&mut *rng), t);
                    for n in &mut ce.noise[r * nc..(r + 1) * nc] {
                        *n = noise_std * R::of(rng.normal_f32() as f64);
                    }
                }
                None => sampling::stratified(R::zero(), R::one(), nc, None, t),
            }
        }
        ce.place(chunk);
        ce.eval_density(&model.coarse, params, cfg.dense, self.train, Self::grid(model));
        for (i, s) in self.coarse.src.iter_mut().enumerate() {
            *s = i as u32;
        }
        // The weights (from the densities alone) drive the importance samples and say which
        // samples need a colour.
        let cutoff = (!cfg.dense).then(|| R::of(cfg.skip_threshold));
        self.coarse.gather_density(&self.coarse_evals, &self.fine_evals);
        self.coarse.terminate(chunk, rays, self.train, cutoff);
        self.counts.ended += self.coarse.ended(rays);
        self.coarse.render(chunk, rays, self.train);
        self.counts.rays += rays as u64;
        self.counts.rendered += (rays * nc) as u64;
        self.counts.density += self.coarse_evals.cand.len() as u64;
        self.counts.alive += self.coarse_evals.keep.len() as u64;
        if !self.fine_pass {
            // One pass only: the "fine" colour is the coarse one.
            self.colour(model, params, chunk, true);
            return;
        }
        // Fine pass: importance samples from the coarse weights, merged with the coarse t. With
        // one field, the coarse samples' evaluations are re-used and only the importance
        // samples are evaluated; with a fine field, it evaluates the union.
        let per_eval = if reuse { cfg.n_fine } else { nf };
        self.fine_evals.resize(rays, per_eval);
        self.fine.resize(rays, nf);
        let mut det_rng = Rng::new(0, 0);
        let (ce, fe, fp) = (&self.coarse_evals, &mut self.fine_evals, &mut self.fine);
        for r in 0..rays {
            let (tc, wc) = (&ce.t[r * nc..(r + 1) * nc], &self.coarse.weights[r * nc..(r + 1) * nc]);
            let rng = rngs.as_deref_mut().map(|g| &mut g[r]);
            let (det, rng) = match rng {
                Some(rng) => (false, rng),
                None => (true, &mut det_rng),
            };
            sampling::importance(tc, wc, cfg.n_fine, det, rng, &mut self.t_imp);
            let (src, tf) = (&mut fp.src[r * nf..(r + 1) * nf], &mut fp.t[r * nf..(r + 1) * nf]);
            merge_rows(tc, (r * nc) as u32, &self.t_imp, (r * per_eval) as u32 | FINE_ROW, tf, src);
            if reuse {
                fe.t[r * per_eval..(r + 1) * per_eval].copy_from_slice(&self.t_imp);
            } else {
                fe.t[r * nf..(r + 1) * nf].copy_from_slice(tf);
                for (k, s) in src.iter_mut().enumerate() {
                    *s = (r * nf + k) as u32 | FINE_ROW;
                }
            }
            if !det {
                for n in &mut fe.noise[r * per_eval..(r + 1) * per_eval] {
                    *n = noise_std * R::of(rng.normal_f32() as f64);
                }
            }
        }
        fe.place(chunk);
        fe.eval_density(model.fine_field(), params, cfg.dense, self.train, Self::fine_grid(model));
        self.fine.gather_density(&self.coarse_evals, &self.fine_evals);
        self.fine.terminate(chunk, rays, self.train, cutoff);
        self.counts.ended += self.fine.ended(rays);
        self.fine.render(chunk, rays, self.train);
        self.counts.rendered += (rays * nf) as u64;
        self.counts.density += self.fine_evals.cand.len() as u64;
        self.counts.alive += self.fine_evals.keep.len() as u64;
        self.colour(model, params, chunk, true);
    }

    /// After the densities and the weights of every pass: runs the colour MLPs on the samples
    /// the passes want and renders the passes' colours. With `light`, a pass wants the
    /// samples whose weight is above `model.skip_threshold` (every sample on the dense
    /// path); without, the samples the last forward wanted (a replay).
    fn colour(&mut self, model: &Model, params: &[R], chunk: &RayChunk<R>, light: bool) {
        let (rays, train) = (self.rays, self.train);
        let (ce, fe) = (&mut self.coarse_evals, &mut self.fine_evals);
        if light {
            let cfg = &model.config;
            let threshold = (!cfg.dense).then(|| R::of(cfg.skip_threshold));
            self.coarse.light(threshold, ce, fe);
            if self.fine_pass {
                self.fine.light(threshold, ce, fe);
            }
        }
        ce.eval_colour(&model.coarse, params);
        let feats = (!self.fine_pass).then_some(&model.coarse);
        self.coarse.gather_colour(ce, fe, feats);
        self.coarse.render(chunk, rays, train);
        if light {
            self.counts.coloured += ce.kcol.len() as u64;
        }
        if self.fine_pass {
            fe.eval_colour(model.fine_field(), params);
            self.fine.gather_colour(ce, fe, Some(model.fine_field()));
            self.fine.render(chunk, rays, train);
            if light {
                self.counts.coloured += fe.kcol.len() as u64;
            }
        }
    }

    /// Re-runs the last forward with other `params` or rays but the same sample depths, noise
    /// and coloured samples (sampling is not differentiated; the finite-difference checks hold
    /// it fixed).
    pub fn replay(&mut self, model: &Model, params: &[R], chunk: &RayChunk<R>) {
        let dense = model.config.dense;
        self.coarse_evals.place(chunk);
        self.coarse_evals.eval_density(&model.coarse, params, dense, self.train, Self::grid(model));
        self.coarse.gather_density(&self.coarse_evals, &self.fine_evals);
        if self.fine_pass {
            self.fine_evals.place(chunk);
            self.fine_evals.eval_density(model.fine_field(), params, dense, self.train, Self::fine_grid(model));
            self.fine.gather_density(&self.coarse_evals, &self.fine_evals);
        }
        self.colour(model, params, chunk, false);
    }

    /// Coarse colours of the last forward (linear RGB, one per ray).
    pub fn coarse(&self) -> &[[R; 3]] {
        &self.coarse.out[..self.rays]
    }

    /// Fine colours of the last forward (the coarse ones when the model has no importance
    /// samples).
    pub fn fine(&self) -> &[[R; 3]] {
        if self.fine_pass {
            &self.fine.out[..self.rays]
        } else {
            &self.coarse.out[..self.rays]
        }
    }

    /// The samples of the last pass (the fine one, or the only one) of the last forward, for
    /// losses on per-sample features (AWP). A skipped sample (zero density) has zero features
    /// and zero weight.
    pub fn last_pass<'a>(&'a self, model: &'a Model) -> PassSamples<'a, R> {
        let (pass, field) =
            if self.fine_pass { (&self.fine, model.fine_field()) } else { (&self.coarse, &model.coarse) };
        let width = field.shape.features;
        PassSamples {
            per_ray: pass.s,
            features: &pass.feats[..self.rays * pass.s * width],
            stride: width,
            width,
            weights: &pass.weights[..self.rays * pass.s],
        }
    }

    /// Backward of the last [`forward`](Self::forward): accumulates the parameter gradients of
    /// a loss with dL/dC `d_coarse` and `d_fine` (one per ray) into `grads`. With `d_rays`,
    /// also writes each ray's input gradients (for blur models that move rays); sample depths
    /// are held fixed (sampling is not differentiated). `d_features` (rays x samples x
    /// features, contiguous) is a loss's direct gradient on the last pass's features
    /// ([`last_pass`](Self::last_pass)).
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &mut self,
        model: &Model,
        params: &[R],
        grads: &mut [R],
        chunk: &RayChunk<R>,
        d_coarse: &[[R; 3]],
        d_fine: &[[R; 3]],
        mut d_rays: Option<&mut [RayGrad<R>]>,
        d_features: Option<&[R]>,
    ) {
        let rays = self.rays;
        if let Some(out) = d_rays.as_deref_mut() {
            out[..rays].fill(RayGrad::zero());
        }
        let (train, with_feat) = (self.train, d_features.is_some());
        let (ce, fe) = (&mut self.coarse_evals, &mut self.fine_evals);
        if !self.fine_pass {
            // One pass: both losses act on the coarse colour.
            let width = model.coarse.shape.features;
            ce.zero_grads(if with_feat { width } else { 0 });
            let d: Vec<[R; 3]> =
                d_coarse.iter().zip(d_fine).map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]).collect();
            self.coarse.render_backward(chunk, rays, &d, train, ce, fe, d_features.map(|d| (d, width)));
            ce.backward(&model.coarse, params, grads, with_feat, d_rays.as_deref_mut());
            if let Some(out) = d_rays {
                self.coarse.add_norm_grads(chunk, rays, out);
            }
            return;
        }
        let fine_field = model.fine_field();
        let width = fine_field.shape.features;
        let reuse = Self::reuses(model);
        // The last pass's features live in the coarse rows too when they are re-used.
        ce.zero_grads(if with_feat && reuse { width } else { 0 });
        fe.zero_grads(if with_feat { width } else { 0 });
        self.fine.render_backward(chunk, rays, d_fine, train, ce, fe, d_features.map(|d| (d, width)));
        if reuse {
            // The coarse rows collect both passes' gradients before their one backward.
            self.coarse.render_backward(chunk, rays, d_coarse, train, ce, fe, None);
            fe.backward(fine_field, params, grads, with_feat, d_rays.as_deref_mut());
            ce.backward(&model.coarse, params, grads, with_feat, d_rays.as_deref_mut());
            if let Some(out) = d_rays {
                self.fine.add_norm_grads(chunk, rays, out);
                self.coarse.add_norm_grads(chunk, rays, out);
            }
            return;
        }
        fe.backward(fine_field, params, grads, with_feat, d_rays.as_deref_mut());
        if let Some(out) = d_rays.as_deref_mut() {
            self.fine.add_norm_grads(chunk, rays, out);
        }
        self.coarse.render_backward(chunk, rays, d_coarse, train, ce, fe, None);
        ce.backward(&model.coarse, params, grads, false, d_rays.as_deref_mut());
        if let Some(out) = d_rays {
            self.coarse.add_norm_grads(chunk, rays, out);
        }
    }
}

/// The sorted union of one ray's coarse depths `a` (rows `a0..`) and importance depths `b`
/// (rows `b0..`): depths into `t`, each one's row code into `src` (ties: the coarse first, as
/// [`sampling::merge_sorted`]).
fn merge_rows<R: Real>(a: &[R], a0: u32, b: &[R], b0: u32, t: &mut [R], src: &mut [u32]) {
    sampling::merge_walk(a, b, |k, x, origin| {
        t[k] = x;
        src[k] = match origin {
            Ok(i) => a0 + i as u32,
            Err(j) => b0 + j as u32,
        };
    });
}
