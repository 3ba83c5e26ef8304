//! Rendering a chunk of rays through a [`Model`]: stratified coarse samples, the coarse field,
//! volume rendering, importance samples from the coarse weights, the fine field over the
//! sorted union, volume rendering again (NeRF's hierarchical sampling); and the whole chain
//! backward from dL/dC of both passes to the parameters.
//!
//! Rays are in NDC (near 0, far 1); `viewdirs` are the unit world-space directions the colour
//! MLP sees. A chunk is rendered with one field call per pass, so the matrix products see
//! `rays x samples` rows. Everything lives in a reusable [`Renderer`]: no allocation per chunk
//! once it has grown to the chunk size.

use super::field::{Field, FieldWorkspace};
use super::model::Model;
use super::real::Real;
use super::rng::Rng;
use super::sampling;
use super::volume::{self, RaySamples, RenderGrad};

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

/// One pass's (coarse or fine) per-sample buffers.
#[derive(Clone, Debug, Default)]
struct Pass<R> {
    /// Samples per ray.
    s: usize,
    t: Vec<R>,
    pos: Vec<[R; 3]>,
    dir: Vec<[R; 3]>,
    sigma: Vec<R>,
    rgb: Vec<[R; 3]>,
    noise: Vec<R>,
    weights: Vec<R>,
    /// Rendered colour per ray.
    out: Vec<[R; 3]>,
    d_sigma: Vec<R>,
    d_rgb: Vec<[R; 3]>,
    /// dL/d position and dL/d view direction per sample (only when ray gradients are asked for).
    d_pos: Vec<[R; 3]>,
    d_dir: Vec<[R; 3]>,
    /// dL/d|d| per ray from volume rendering (the sample spacing scales with |d|).
    d_norm: Vec<R>,
    ws: FieldWorkspace<R>,
}

impl<R: Real> Pass<R> {
    fn resize(&mut self, rays: usize, s: usize) {
        let n = rays * s;
        self.s = s;
        self.t.resize(n, R::zero());
        self.pos.resize(n, [R::zero(); 3]);
        self.dir.resize(n, [R::zero(); 3]);
        self.sigma.resize(n, R::zero());
        self.rgb.resize(n, [R::zero(); 3]);
        self.noise.resize(n, R::zero());
        self.weights.resize(n, R::zero());
        self.out.resize(rays, [R::zero(); 3]);
        self.d_sigma.resize(n, R::zero());
        self.d_rgb.resize(n, [R::zero(); 3]);
        self.d_norm.resize(rays, R::zero());
    }

    /// Positions o + t d and view directions of every sample, from `t`.
    fn place(&mut self, chunk: &RayChunk<R>, rays: usize) {
        for r in 0..rays {
            let (o, d) = (chunk.origins[r], chunk.dirs[r]);
            for k in 0..self.s {
                let i = r * self.s + k;
                let t = self.t[i];
                self.pos[i] = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
                self.dir[i] = chunk.viewdirs[r];
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

    /// Volume-renders every ray of the pass.
    fn render(&mut self, chunk: &RayChunk<R>, rays: usize, train: bool) {
        let mut weights = std::mem::take(&mut self.weights);
        for r in 0..rays {
            let out = volume::render(
                &self.samples(r, norm(chunk.dirs[r]), train),
                &mut weights[r * self.s..(r + 1) * self.s],
            );
            self.out[r] = out.rgb;
        }
        self.weights = weights;
    }

    /// Backward through volume rendering: per-sample dL/dsigma_raw and dL/drgb from dL/dC.
    fn render_backward(&mut self, chunk: &RayChunk<R>, rays: usize, d_out: &[[R; 3]], train: bool) {
        let (mut ds, mut dr) = (std::mem::take(&mut self.d_sigma), std::mem::take(&mut self.d_rgb));
        for r in 0..rays {
            let range = r * self.s..(r + 1) * self.s;
            self.d_norm[r] = volume::render_backward(
                &self.samples(r, norm(chunk.dirs[r]), train),
                &RenderGrad::rgb(d_out[r]),
                &mut ds[range.clone()],
                dr[range].as_flattened_mut(),
            );
        }
        self.d_sigma = ds;
        self.d_rgb = dr;
    }

    /// The field's backward; with `with_rays`, also the per-sample position and direction
    /// gradients.
    fn field_backward(
        &mut self,
        field: &Field,
        params: &[R],
        grads: &mut [R],
        with_rays: bool,
        d_features: Option<&[R]>,
    ) {
        if with_rays {
            let n = self.pos.len();
            self.d_pos.resize(n, [R::zero(); 3]);
            self.d_dir.resize(n, [R::zero(); 3]);
            let (dp, dd) = (&mut self.d_pos[..], &mut self.d_dir[..]);
            field.backward(
                params,
                grads,
                &mut self.ws,
                &self.pos,
                &self.d_sigma,
                &self.d_rgb,
                d_features,
                Some(dp),
                Some(dd),
            );
        } else {
            field.backward(params, grads, &mut self.ws, &self.pos, &self.d_sigma, &self.d_rgb, d_features, None, None);
        }
    }

    /// Adds this pass's ray gradients: position x = o + t d gives dL/do = sum dL/dx and
    /// dL/dd = sum t dL/dx, plus the |d| term of the spacing; the view direction's gradient is
    /// the sum over the samples.
    fn add_ray_grads(&self, chunk: &RayChunk<R>, rays: usize, out: &mut [RayGrad<R>]) {
        for (r, g) in out.iter_mut().enumerate().take(rays) {
            let d = chunk.dirs[r];
            let n = norm(d);
            for k in 0..self.s {
                let i = r * self.s + k;
                let (dp, t) = (self.d_pos[i], self.t[i]);
                for a in 0..3 {
                    g.origin[a] += dp[a];
                    g.dir[a] += t * dp[a];
                    g.viewdir[a] += self.d_dir[i][a];
                }
            }
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
    t_imp: Vec<R>,
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
        self.coarse.resize(rays, nc);
        self.fine.resize(rays, nf);
        self.t_imp.resize(cfg.n_fine, R::zero());
        let noise_std = R::of(cfg.density_noise);
        // Coarse pass: stratified t in [0, 1] (NDC), density noise.
        for r in 0..rays {
            let rng = rngs.as_deref_mut().map(|g| &mut g[r]);
            let t = &mut self.coarse.t[r * nc..(r + 1) * nc];
            match rng {
                Some(rng) => {
                    sampling::stratified(R::zero(), R::one(), nc, Some(&mut *rng), t);
                    for n in &mut self.coarse.noise[r * nc..(r + 1) * nc] {
                        *n = noise_std * R::of(rng.normal_f32() as f64);
                    }
                }
                None => sampling::stratified(R::zero(), R::one(), nc, None, t),
            }
        }
        self.coarse.place(chunk, rays);
        let c = &mut self.coarse;
        model.coarse.forward(params, &mut c.ws, &c.pos, &c.dir, &mut c.sigma, &mut c.rgb);
        c.render(chunk, rays, self.train);
        if !self.fine_pass {
            // One pass only: the "fine" colour is the coarse one.
            return;
        }
        // Fine pass: importance samples from the coarse weights, merged with the coarse t.
        let mut det_rng = Rng::new(0, 0);
        for r in 0..rays {
            let (tc, wc) = (&self.coarse.t[r * nc..(r + 1) * nc], &self.coarse.weights[r * nc..(r + 1) * nc]);
            let tf = &mut self.fine.t[r * nf..(r + 1) * nf];
            match rngs.as_deref_mut().map(|g| &mut g[r]) {
                Some(rng) => {
                    sampling::importance(tc, wc, cfg.n_fine, false, rng, &mut self.t_imp);
                    sampling::merge_sorted(tc, &self.t_imp, tf);
                    for n in &mut self.fine.noise[r * nf..(r + 1) * nf] {
                        *n = noise_std * R::of(rng.normal_f32() as f64);
                    }
                }
                None => {
                    sampling::importance(tc, wc, cfg.n_fine, true, &mut det_rng, &mut self.t_imp);
                    sampling::merge_sorted(tc, &self.t_imp, tf);
                }
            }
        }
        self.fine.place(chunk, rays);
        let f = &mut self.fine;
        model.fine_field().forward(params, &mut f.ws, &f.pos, &f.dir, &mut f.sigma, &mut f.rgb);
        f.render(chunk, rays, self.train);
    }

    /// Re-runs the last forward with other `params` or rays but the same sample depths and
    /// noise (sampling is not differentiated; the finite-difference checks hold it fixed).
    pub fn replay(&mut self, model: &Model, params: &[R], chunk: &RayChunk<R>) {
        let rays = self.rays;
        let c = &mut self.coarse;
        c.place(chunk, rays);
        model.coarse.forward(params, &mut c.ws, &c.pos, &c.dir, &mut c.sigma, &mut c.rgb);
        c.render(chunk, rays, self.train);
        if self.fine_pass {
            let f = &mut self.fine;
            f.place(chunk, rays);
            model.fine_field().forward(params, &mut f.ws, &f.pos, &f.dir, &mut f.sigma, &mut f.rgb);
            f.render(chunk, rays, self.train);
        }
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
    /// losses on per-sample features (AWP).
    pub fn last_pass<'a>(&'a self, model: &'a Model) -> PassSamples<'a, R> {
        let (pass, field) =
            if self.fine_pass { (&self.fine, model.fine_field()) } else { (&self.coarse, &model.coarse) };
        let (rows, stride) = field.feature_rows(&pass.ws);
        PassSamples {
            per_ray: pass.s,
            features: rows,
            stride,
            width: field.shape.features,
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
        let with_rays = d_rays.is_some();
        if let Some(out) = d_rays.as_deref_mut() {
            out[..rays].fill(RayGrad::zero());
        }
        if !self.fine_pass {
            // One pass: both losses act on the coarse colour.
            let d: Vec<[R; 3]> =
                d_coarse.iter().zip(d_fine).map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]).collect();
            let c = &mut self.coarse;
            c.render_backward(chunk, rays, &d, self.train);
            c.field_backward(&model.coarse, params, grads, with_rays, d_features);
            if let Some(out) = d_rays {
                c.add_ray_grads(chunk, rays, out);
            }
            return;
        }
        let f = &mut self.fine;
        f.render_backward(chunk, rays, d_fine, self.train);
        f.field_backward(model.fine_field(), params, grads, with_rays, d_features);
        if let Some(out) = d_rays.as_deref_mut() {
            f.add_ray_grads(chunk, rays, out);
        }
        let c = &mut self.coarse;
        c.render_backward(chunk, rays, d_coarse, self.train);
        c.field_backward(&model.coarse, params, grads, with_rays, None);
        if let Some(out) = d_rays {
            c.add_ray_grads(chunk, rays, out);
        }
    }
}
