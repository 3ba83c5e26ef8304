//! The samples one field call evaluates ([`Evals`]): the coarse and the fine evaluations a
//! [`Renderer`] keeps, which its passes gather from and route gradients to.

use super::*;

/// The samples one field call evaluates (ray-major, `per_ray` per ray): where they are, their
/// density noise, which of them are alive and the field's outputs; and, in the backward, the
/// gradients the passes route to them.
#[derive(Clone, Debug, Default)]
pub(super) struct Evals<R> {
    pub(super) per_ray: usize,
    pub(super) t: Vec<R>,
    pub(super) pos: Vec<[R; 3]>,
    pub(super) dir: Vec<[R; 3]>,
    pub(super) noise: Vec<R>,
    /// Raw density of every row.
    pub(super) sigma: Vec<R>,
    /// Colour of every row (zero for a dead row).
    pub(super) rgb: Vec<[R; 3]>,
    /// The alive rows, increasing; `kidx[row]` is a row's place in `keep` (`u32::MAX`: dead).
    pub(super) keep: Vec<u32>,
    pub(super) kidx: Vec<u32>,
    /// Per row: whether a pass wants its colour (its render weight is above the threshold).
    pub(super) lit: Vec<bool>,
    /// The coloured rows (alive and lit), as places in `keep`.
    pub(super) kcol: Vec<u32>,
    /// Whether the last evaluation was on the dense path (no row is dropped).
    pub(super) dense: bool,
    /// The rows the field evaluated (not in an empty cell of the occupancy grid), their
    /// positions and densities, and the alive ones' places among them.
    pub(super) cand: Vec<u32>,
    pub(super) cpos: Vec<[R; 3]>,
    pub(super) csigma: Vec<R>,
    pub(super) places: Vec<u32>,
    pub(super) kpos: Vec<[R; 3]>,
    pub(super) kdir: Vec<[R; 3]>,
    pub(super) kray: Vec<u32>,
    pub(super) krgb: Vec<[R; 3]>,
    /// dL/d raw density, dL/d colour and dL/d features of every row, summed over the passes
    /// that render it.
    pub(super) d_sigma: Vec<R>,
    pub(super) d_rgb: Vec<[R; 3]>,
    pub(super) d_feat: Vec<R>,
    /// The same of the alive rows, and what the field's backward gives them.
    pub(super) kd_sigma: Vec<R>,
    pub(super) kd_rgb: Vec<[R; 3]>,
    pub(super) kd_feat: Vec<R>,
    pub(super) kd_pos: Vec<[R; 3]>,
    pub(super) kd_dir: Vec<[R; 3]>,
    pub(super) ws: FieldWorkspace<R>,
}

impl<R: Real> Evals<R> {
    pub(super) fn resize(&mut self, rays: usize, per_ray: usize) {
        let n = rays * per_ray;
        self.per_ray = per_ray;
        self.t.resize(n, R::zero());
        self.pos.resize(n, [R::zero(); 3]);
        self.dir.resize(n, [R::zero(); 3]);
        self.noise.resize(n, R::zero());
        self.sigma.resize(n, R::zero());
        self.rgb.resize(n, [R::zero(); 3]);
        self.kidx.resize(n, 0);
        self.lit.clear();
        self.lit.resize(n, false);
    }

    pub(super) fn rows(&self) -> usize {
        self.t.len()
    }

    /// Positions o + t d and view directions of every row, from `t`.
    pub(super) fn place(&mut self, chunk: &RayChunk<R>) {
        for (i, t) in self.t.iter().enumerate() {
            let r = i / self.per_ray;
            let (o, d) = (chunk.origins[r], chunk.dirs[r]);
            self.pos[i] = [o[0] + *t * d[0], o[1] + *t * d[1], o[2] + *t * d[2]];
            self.dir[i] = chunk.viewdirs[r];
        }
    }

    /// Runs `field`'s density on every row and keeps the alive ones: rows whose density after
    /// noise is positive, or every row when `dense` (whose backward then also differentiates
    /// the unused input columns, as the engine did before it skipped anything). Colours are
    /// zero until [`eval_colour`](Self::eval_colour).
    /// With `grid`, the rows in its empty cells are not evaluated: their raw density reads as
    /// [`SKIPPED`] and they are dead.
    pub(super) fn eval_density(
        &mut self,
        field: &Field,
        params: &[R],
        dense: bool,
        train: bool,
        grid: Option<&OccupancyGrid>,
    ) {
        self.ws.set_all_input_grads(dense);
        self.dense = dense;
        // The evaluated rows (all of them without a grid).
        self.cand.clear();
        match grid {
            Some(g) => {
                self.cpos.clear();
                for (i, p) in self.pos.iter().enumerate() {
                    let f = |a: usize| p[a].to_f64().expect("a finite position");
                    if g.occupied([f(0), f(1), f(2)]) {
                        self.cand.push(i as u32);
                        self.cpos.push(*p);
                    } else {
                        self.sigma[i] = R::of(SKIPPED);
                    }
                }
                self.csigma.resize(self.cand.len(), R::zero());
                field.forward_density(params, &mut self.ws, &self.cpos, &mut self.csigma);
                for (&i, &s) in self.cand.iter().zip(&self.csigma) {
                    self.sigma[i as usize] = s;
                }
            }
            None => {
                self.cand.extend(0..self.rows() as u32);
                field.forward_density(params, &mut self.ws, &self.pos, &mut self.sigma);
            }
        }
        self.keep.clear();
        self.places.clear();
        self.kidx.fill(u32::MAX);
        for (c, &i) in self.cand.iter().enumerate() {
            let i = i as usize;
            let x = if train { self.sigma[i] + self.noise[i] } else { self.sigma[i] };
            if dense || x > R::zero() {
                self.kidx[i] = self.keep.len() as u32;
                self.keep.push(i as u32);
                self.places.push(c as u32);
            }
        }
        field.keep_rows(&mut self.ws, &self.places);
        self.rgb.fill([R::zero(); 3]);
    }

    /// Runs `field`'s colour MLP on the alive rows that are [`lit`](Self::lit); the others'
    /// colour stays zero.
    pub(super) fn eval_colour(&mut self, field: &Field, params: &[R]) {
        self.kcol.clear();
        self.kdir.clear();
        self.kray.clear();
        for (j, &k) in self.keep.iter().enumerate() {
            let k = k as usize;
            if self.lit[k] {
                self.kcol.push(j as u32);
                self.kdir.push(self.dir[k]);
                self.kray.push((k / self.per_ray) as u32);
            }
        }
        self.krgb.resize(self.kcol.len(), [R::zero(); 3]);
        field.forward_colour(params, &mut self.ws, Some(&self.kcol), Some(&self.kray), &self.kdir, &mut self.krgb);
        for (&j, c) in self.kcol.iter().zip(&self.krgb) {
            self.rgb[self.keep[j as usize] as usize] = *c;
        }
    }

    /// Drops the alive rows that pass no gradient from the workspace before a backward: rows
    /// that are not coloured and whose density and feature gradients (`width` features per
    /// row, 0 if none) are zero, e.g. samples past the end of every ray that renders them.
    /// They would add exactly nothing; the density's backward skips them.
    pub(super) fn drop_silent_rows(&mut self, field: &Field, width: usize) {
        // In place: the kept rows and their coloured places move down (w <= j, wc <= ci), and
        // `places` (free after the forward) collects the kept rows' old places.
        self.places.clear();
        let (mut ci, mut wc) = (0, 0);
        for j in 0..self.keep.len() {
            let ku = self.keep[j] as usize;
            let coloured = ci < self.kcol.len() && self.kcol[ci] as usize == j;
            ci += coloured as usize;
            let feat = width > 0 && self.d_feat[ku * width..(ku + 1) * width].iter().any(|&x| x != R::zero());
            if coloured || feat || self.d_sigma[ku] != R::zero() {
                let w = self.places.len();
                if coloured {
                    self.kcol[wc] = w as u32;
                    wc += 1;
                }
                self.kidx[ku] = w as u32;
                self.keep[w] = ku as u32;
                self.places.push(j as u32);
            } else {
                self.kidx[ku] = u32::MAX;
            }
        }
        let kept = self.places.len();
        if kept < self.keep.len() {
            field.keep_rows(&mut self.ws, &self.places);
            self.keep.truncate(kept);
        }
        self.kcol.truncate(wc);
    }

    /// Clears the routed gradients before a backward (`width`: features per row, 0 if none).
    pub(super) fn zero_grads(&mut self, width: usize) {
        let n = self.rows();
        self.d_sigma.clear();
        self.d_sigma.resize(n, R::zero());
        self.d_rgb.clear();
        self.d_rgb.resize(n, [R::zero(); 3]);
        self.d_feat.clear();
        self.d_feat.resize(n * width, R::zero());
    }

    /// The field's backward over the alive rows, from the routed gradients (with `with_feat`,
    /// the features' too); with `rays_out`, adds each alive row's position and direction
    /// gradient to its ray.
    pub(super) fn backward(
        &mut self,
        field: &Field,
        params: &[R],
        grads: &mut [R],
        with_feat: bool,
        rays_out: Option<&mut [RayGrad<R>]>,
    ) {
        if self.keep.is_empty() {
            return;
        }
        let nf = field.shape.features;
        if !self.dense {
            self.drop_silent_rows(field, if with_feat { nf } else { 0 });
        }
        self.kpos.clear();
        self.kd_sigma.clear();
        self.kd_rgb.clear();
        self.kd_feat.clear();
        for &k in &self.keep {
            let k = k as usize;
            self.kpos.push(self.pos[k]);
            self.kd_sigma.push(self.d_sigma[k]);
            if with_feat {
                self.kd_feat.extend_from_slice(&self.d_feat[k * nf..(k + 1) * nf]);
            }
        }
        for &j in &self.kcol {
            self.kd_rgb.push(self.d_rgb[self.keep[j as usize] as usize]);
        }
        let d_features = with_feat.then_some(&self.kd_feat[..]);
        // The positions' and directions' gradients only when the rays want theirs.
        let (d_pos, d_dir) = if rays_out.is_some() {
            self.kd_pos.resize(self.keep.len(), [R::zero(); 3]);
            self.kd_dir.resize(self.kcol.len(), [R::zero(); 3]);
            (Some(&mut self.kd_pos[..]), Some(&mut self.kd_dir[..]))
        } else {
            (None, None)
        };
        field.backward(params, grads, &mut self.ws, &self.kpos, &self.kd_sigma, &self.kd_rgb, d_features, d_pos, d_dir);
        let Some(out) = rays_out else { return };
        // x = o + t d: dL/do = sum dL/dx, dL/dd = sum t dL/dx; the view direction's gradient is
        // the sum over the coloured samples.
        for (j, &k) in self.keep.iter().enumerate() {
            let k = k as usize;
            let (dp, t, g) = (self.kd_pos[j], self.t[k], &mut out[k / self.per_ray]);
            for a in 0..3 {
                g.origin[a] += dp[a];
                g.dir[a] += t * dp[a];
            }
        }
        for (&j, dd) in self.kcol.iter().zip(&self.kd_dir) {
            let g = &mut out[self.keep[j as usize] as usize / self.per_ray];
            for a in 0..3 {
                g.viewdir[a] += dd[a];
            }
        }
    }
}
