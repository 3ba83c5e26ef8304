//! One level of the radiance field (coarse or fine): VM volume features + positional encoding
//! -> density MLP -> (raw density, features); features + encoded view direction -> colour MLP
//! -> sigmoid RGB (linear colour). A fine level may read several volumes (the reference's fine
//! level concatenates the coarse volume's 32 features with its own 32); volumes are shared by
//! parameter offset, so their gradients add up.
//!
//! Kernels run on a chunk of `p` samples with every activation kept in a reusable
//! [`FieldWorkspace`] (rows = samples), so a forward + backward over a chunk allocates nothing.

use super::encoding;
use super::mlp::{backward_stack, forward_stack, Act, Dense, Runs};
use super::params::Layout;
use super::real::Real;
use super::vm::VmVolume;

/// Shape of one field level.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldShape {
    /// Positional-encoding frequencies for positions (reference: 10).
    pub pe_pos: usize,
    /// Positional-encoding frequencies for view directions (reference: 4).
    pub pe_dir: usize,
    /// Hidden widths of the density MLP (reference coarse: [64], fine: [256]).
    pub density_hidden: Vec<usize>,
    /// Features passed from the density MLP to the colour MLP (reference: 15 coarse, 128 fine).
    pub features: usize,
    /// Hidden widths of the colour MLP (reference coarse: [64, 64], fine: [256, 256]).
    pub colour_hidden: Vec<usize>,
    /// Whether the MLP layers have biases (reference: no).
    pub bias: bool,
}

/// A field level: the volumes it reads and its two MLPs.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Volumes whose features are concatenated at the density MLP's input.
    pub volumes: Vec<VmVolume>,
    /// Shape.
    pub shape: FieldShape,
    /// Density MLP layers; the last outputs 1 + features (no activation).
    pub density: Vec<Dense>,
    /// Colour MLP layers; the last outputs 3 with a sigmoid.
    pub colour: Vec<Dense>,
}

/// Reusable buffers for one chunk of samples.
#[derive(Clone, Debug, Default)]
pub struct FieldWorkspace<R> {
    cap: usize,
    /// Rows the activations hold (set by the forward, reduced by a `keep`).
    rows: usize,
    /// Raw VM components per volume (p x n_comps).
    comps: Vec<Vec<R>>,
    /// Density MLP input: volume features then PE(x) (p x d_in).
    x_density: Vec<R>,
    /// Activations of the density MLP layers (the last is p x (1 + features)).
    h_density: Vec<Vec<R>>,
    /// Colour MLP input: features then PE(d).
    x_colour: Vec<R>,
    /// Activations of the colour MLP layers (the last is p x 3, the colour).
    h_colour: Vec<Vec<R>>,
    /// Gradient buffers (same shapes, reused across layers).
    g_a: Vec<R>,
    g_b: Vec<R>,
    g_x: Vec<R>,
    g_comps: Vec<R>,
    /// Runs of rows sharing a view direction (first row of each, then the row count), each
    /// run's PE(d), and scratch for the colour MLP's first layer.
    runs: Vec<u32>,
    pe_runs: Vec<R>,
    run_base: Vec<R>,
    d_pe_runs: Vec<R>,
    /// The rows the colour MLP ran on (increasing indices into the rows).
    coloured: Vec<u32>,
    /// Whether the backward differentiates every input column (see
    /// [`set_all_input_grads`](Self::set_all_input_grads)).
    all_input_grads: bool,
}

impl<R> FieldWorkspace<R> {
    /// With `all`, [`Field::backward`] computes dL/d(input) for the positional encodings' columns
    /// and the volumes' position gradients even when no position or direction gradient is asked
    /// for (work the result never reads), and the colour MLP multiplies every row's PE(d)
    /// (rather than once per run of rows sharing a direction): the engine as it was before it
    /// skipped samples, kept for `model.dense`'s side-by-side timings.
    pub fn set_all_input_grads(&mut self, all: bool) {
        self.all_input_grads = all;
    }
}

impl Field {
    /// Builds a level reading `volumes`, allocating its MLPs in `layout` under `name`.
    pub fn new(layout: &mut Layout, name: &str, volumes: Vec<VmVolume>, shape: FieldShape) -> Field {
        let vol_features: usize = volumes.iter().map(|v| v.n_features()).sum();
        let mut n_in = vol_features + encoding::width(shape.pe_pos);
        let mut density = Vec::new();
        for (i, &w) in shape.density_hidden.iter().enumerate() {
            density.push(Dense::new(layout, &format!("{name}.density.{i}"), n_in, w, shape.bias, Act::Relu));
            n_in = w;
        }
        let i = shape.density_hidden.len();
        density.push(Dense::new(
            layout,
            &format!("{name}.density.{i}"),
            n_in,
            1 + shape.features,
            shape.bias,
            Act::None,
        ));
        let mut n_in = shape.features + encoding::width(shape.pe_dir);
        let mut colour = Vec::new();
        for (i, &w) in shape.colour_hidden.iter().enumerate() {
            colour.push(Dense::new(layout, &format!("{name}.colour.{i}"), n_in, w, shape.bias, Act::Relu));
            n_in = w;
        }
        let i = shape.colour_hidden.len();
        colour.push(Dense::new(layout, &format!("{name}.colour.{i}"), n_in, 3, shape.bias, Act::Sigmoid));
        Field { volumes, shape, density, colour }
    }

    /// Initialises the MLPs (not the volumes, which the model initialises once each).
    pub fn init_mlps<R: Real>(&self, params: &mut [R], uniform: &mut impl FnMut() -> f64) {
        for l in self.density.iter().chain(&self.colour) {
            l.init(params, uniform);
        }
    }

    fn d_density_in(&self) -> usize {
        self.density[0].n_in
    }

    fn d_colour_in(&self) -> usize {
        self.colour[0].n_in
    }

    /// Multiply-adds per sample of the forward pass (for GFLOP/s figures; backward is ~2x).
    pub fn macs_per_sample(&self) -> usize {
        let mlp: usize = self.density.iter().chain(&self.colour).map(|l| l.n_in * l.n_out).sum();
        let vm: usize = self.volumes.iter().map(|v| v.n_comps() * (v.n_features() + 7)).sum();
        mlp + vm
    }

    /// Makes `ws` big enough for chunks of `p` samples.
    pub fn reserve<R: Real>(&self, ws: &mut FieldWorkspace<R>, p: usize) {
        if ws.cap >= p && ws.comps.len() == self.volumes.len() && ws.h_density.len() == self.density.len() {
            return;
        }
        let z = |n: usize| vec![R::zero(); p * n];
        ws.cap = p;
        ws.comps = self.volumes.iter().map(|v| z(v.n_comps())).collect();
        ws.x_density = z(self.d_density_in());
        ws.h_density = self.density.iter().map(|l| z(l.n_out)).collect();
        ws.x_colour = z(self.d_colour_in());
        ws.h_colour = self.colour.iter().map(|l| z(l.n_out)).collect();
        let widest = self.density.iter().chain(&self.colour).map(|l| l.n_out.max(l.n_in)).max().unwrap_or(0);
        ws.g_a = z(widest);
        ws.g_b = z(widest);
        ws.g_x = z(widest);
        ws.g_comps = z(self.volumes.iter().map(|v| v.n_comps()).max().unwrap_or(0));
    }

    /// Forward over `p` samples at positions `pos` (p x 3) with unit view directions `dir`
    /// (p x 3): writes the raw density into `sigma` (p) and the colour into `rgb` (p x 3).
    pub fn forward<R: Real>(
        &self,
        params: &[R],
        ws: &mut FieldWorkspace<R>,
        pos: &[[R; 3]],
        dir: &[[R; 3]],
        sigma: &mut [R],
        rgb: &mut [[R; 3]],
    ) {
        self.forward_density(params, ws, pos, sigma);
        self.forward_colour(params, ws, None, None, dir, rgb);
    }

    /// The first half of [`forward`](Self::forward): volume features, positional encoding and
    /// the density MLP over `p` samples; writes the raw density into `sigma` (p) and keeps the
    /// activations in `ws` for [`forward_colour`](Self::forward_colour).
    pub fn forward_density<R: Real>(&self, params: &[R], ws: &mut FieldWorkspace<R>, pos: &[[R; 3]], sigma: &mut [R]) {
        let p = pos.len();
        self.reserve(ws, p);
        ws.rows = p;
        ws.coloured.clear();
        let dd = self.d_density_in();
        // Volume features, then PE(x), side by side in the density input.
        let mut col = 0;
        for (v, comps) in self.volumes.iter().zip(&mut ws.comps) {
            let nc = v.n_comps();
            for (i, x) in pos.iter().enumerate() {
                v.components(params, *x, &mut comps[i * nc..(i + 1) * nc]);
            }
            v.basis.forward(params, p, comps, nc, &mut ws.x_density[col..], dd);
            col += v.n_features();
        }
        let pw = encoding::width(self.shape.pe_pos);
        for (i, x) in pos.iter().enumerate() {
            encoding::encode(*x, self.shape.pe_pos, &mut ws.x_density[i * dd + col..i * dd + col + pw]);
        }
        forward_stack(&self.density, params, p, &ws.x_density, self.d_density_in(), &mut ws.h_density);
        let nf = self.shape.features;
        let out = ws.h_density.last().expect("density MLP has an output layer");
        for i in 0..p {
            sigma[i] = out[i * (1 + nf)];
        }
    }

    /// Drops every row of `ws` but `keep` (increasing row indices; rows `keep[j]` move to `j`),
    /// after [`forward_density`](Self::forward_density): the colour MLP and the
    /// [`backward`](Self::backward) then see only the kept samples. After a
    /// [`forward_colour`](Self::forward_colour), `keep` must hold every coloured row (their
    /// colour activations stay).
    pub fn keep_rows<R: Real>(&self, ws: &mut FieldWorkspace<R>, keep: &[u32]) {
        debug_assert!(keep.windows(2).all(|w| w[0] < w[1]), "keep_rows: keep is not increasing");
        debug_assert!(keep.last().is_none_or(|&k| (k as usize) < ws.rows), "keep_rows: a row past the end");
        if keep.len() == ws.rows {
            return;
        }
        // The coloured rows' new places.
        let mut at = 0;
        for c in ws.coloured.iter_mut() {
            while at < keep.len() && keep[at] < *c {
                at += 1;
            }
            assert!(at < keep.len() && keep[at] == *c, "keep_rows: coloured row {c} is dropped");
            *c = at as u32;
        }
        // In place: keep[j] >= j, so walking up never overwrites a row still to move.
        let compact = |buf: &mut [R], width: usize| {
            for (j, &k) in keep.iter().enumerate() {
                let k = k as usize;
                if k != j {
                    buf.copy_within(k * width..(k + 1) * width, j * width);
                }
            }
        };
        for (v, comps) in self.volumes.iter().zip(&mut ws.comps) {
            compact(comps, v.n_comps());
        }
        compact(&mut ws.x_density, self.d_density_in());
        for (l, h) in self.density.iter().zip(&mut ws.h_density) {
            compact(h, l.n_out);
        }
        ws.rows = keep.len();
    }

    /// The second half of [`forward`](Self::forward), after
    /// [`forward_density`](Self::forward_density) (and [`keep_rows`](Self::keep_rows)): the
    /// colour of the rows `coloured` (increasing indices into the workspace's rows; `None`:
    /// every row). The other rows get no colour: their colour reads as zero and the
    /// [`backward`](Self::backward) passes only their density's gradient. `dir` and `rgb` have
    /// one entry per coloured row, as `ray` (each row's ray, if given): consecutive coloured
    /// rows of one ray (without `ray`: any consecutive rows) with equal directions form a run
    /// that shares one PE(d) product and one direction gradient.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_colour<R: Real>(
        &self,
        params: &[R],
        ws: &mut FieldWorkspace<R>,
        coloured: Option<&[u32]>,
        ray: Option<&[u32]>,
        dir: &[[R; 3]],
        rgb: &mut [[R; 3]],
    ) {
        ws.coloured.clear();
        match coloured {
            Some(rows) => {
                debug_assert!(rows.windows(2).all(|w| w[0] < w[1]), "forward_colour: rows are not increasing");
                debug_assert!(
                    rows.last().is_none_or(|&k| (k as usize) < ws.rows),
                    "forward_colour: a row past the end"
                );
                ws.coloured.extend_from_slice(rows);
            }
            None => ws.coloured.extend(0..ws.rows as u32),
        }
        let p = ws.coloured.len();
        assert_eq!(dir.len(), p, "forward_colour: {} directions for {p} coloured rows", dir.len());
        assert!(ray.is_none_or(|r| r.len() == p), "forward_colour: rays for {p} coloured rows");
        if p == 0 {
            return;
        }
        // Features (after the raw density) and PE(d) form the colour input.
        let nf = self.shape.features;
        let dc = self.d_colour_in();
        let out = ws.h_density.last().expect("density MLP has an output layer");
        let dw = encoding::width(self.shape.pe_dir);
        for (i, &k) in ws.coloured.iter().enumerate() {
            let k = k as usize;
            ws.x_colour[i * dc..i * dc + nf].copy_from_slice(&out[k * (1 + nf) + 1..(k + 1) * (1 + nf)]);
        }
        if ws.all_input_grads {
            for i in 0..p {
                encoding::encode(dir[i], self.shape.pe_dir, &mut ws.x_colour[i * dc + nf..i * dc + nf + dw]);
            }
            forward_stack(&self.colour, params, p, &ws.x_colour, dc, &mut ws.h_colour);
        } else {
            // A ray's samples share its direction: PE(d) and its product with the first
            // layer's weights once per run of equal directions.
            ws.runs.clear();
            ws.pe_runs.clear();
            for i in 0..p {
                if i == 0 || dir[i] != dir[i - 1] || ray.is_some_and(|r| r[i] != r[i - 1]) {
                    ws.runs.push(i as u32);
                    let at = ws.pe_runs.len();
                    ws.pe_runs.resize(at + dw, R::zero());
                    encoding::encode(dir[i], self.shape.pe_dir, &mut ws.pe_runs[at..]);
                }
            }
            ws.runs.push(p as u32);
            let (first, rest) = self.colour.split_first().expect("colour MLP has an output layer");
            let (h0, h_rest) = ws.h_colour.split_first_mut().expect("colour MLP has an output layer");
            let runs = Runs { starts: &ws.runs, x: &ws.pe_runs };
            first.forward_runs(params, (&ws.x_colour, dc), nf, runs, h0, first.n_out, &mut ws.run_base);
            forward_stack(rest, params, p, h0, first.n_out, h_rest);
        }
        let c = ws.h_colour.last().expect("colour MLP has an output layer");
        for i in 0..p {
            rgb[i] = [c[3 * i], c[3 * i + 1], c[3 * i + 2]];
        }
    }

    /// The features the density MLP gave sample `i` in the last forward on `ws` (what the
    /// colour MLP reads; DP-NeRF's AWP integrates them along the ray); after
    /// [`keep_rows`](Self::keep_rows), `i` counts the kept rows.
    pub fn features<'a, R: Real>(&self, ws: &'a FieldWorkspace<R>, i: usize) -> &'a [R] {
        let nf = self.shape.features;
        let out = ws.h_density.last().expect("density MLP has an output layer");
        &out[i * (1 + nf) + 1..(i + 1) * (1 + nf)]
    }

    /// Backward of the last [`forward`](Self::forward) on `ws`: accumulates parameter gradients
    /// into `grads`. `pos`, `d_sigma`, `d_features` (p x features, optional: a loss's direct
    /// gradient on the [`features`](Self::features)) and `d_pos` have one entry per row of the
    /// workspace, `d_rgb` and `d_dir` one per coloured row of the last
    /// [`forward_colour`](Self::forward_colour). When `d_pos` / `d_dir` are given, writes dL/dpos
    /// and dL/ddir into them (consecutive coloured rows with equal directions share one PE(d)
    /// product, so such a run's summed direction gradient is written to its first row and zero
    /// to the others, unless the workspace [asks for every input gradient](FieldWorkspace::set_all_input_grads)).
    #[allow(clippy::too_many_arguments)]
    pub fn backward<R: Real>(
        &self,
        params: &[R],
        grads: &mut [R],
        ws: &mut FieldWorkspace<R>,
        pos: &[[R; 3]],
        d_sigma: &[R],
        d_rgb: &[[R; 3]],
        d_features: Option<&[R]>,
        d_pos: Option<&mut [[R; 3]]>,
        d_dir: Option<&mut [[R; 3]]>,
    ) {
        let p = pos.len();
        assert_eq!(p, ws.rows, "Field::backward: {p} positions for the {} rows of the last forward", ws.rows);
        let nf = self.shape.features;
        let dc = self.d_colour_in();
        let dd = self.d_density_in();
        // Colour MLP, down to its input (features | PE(d)); the PE(d) part per run of rows and
        // only when d_dir is wanted, as the PE(x) columns of the density input only when d_pos
        // is (all of it per row with `all`, the dense engine).
        let all = ws.all_input_grads;
        let vol_cols: usize = self.volumes.iter().map(|v| v.n_features()).sum();
        let density_cols = if all || d_pos.is_some() { dd } else { vol_cols };
        let pc = ws.coloured.len();
        assert_eq!(d_rgb.len(), pc, "Field::backward: {} colour gradients for {pc} coloured rows", d_rgb.len());
        for i in 0..pc {
            ws.g_a[3 * i..3 * i + 3].copy_from_slice(&d_rgb[i]);
        }
        let dw = encoding::width(self.shape.pe_dir);
        if pc == 0 {
            // No colour: only the densities (and direct feature gradients) pass gradients.
        } else if all {
            backward_stack(
                &self.colour,
                params,
                grads,
                pc,
                (&ws.x_colour, dc),
                &ws.h_colour,
                &mut ws.g_a,
                &mut ws.g_b,
                &mut ws.g_x,
                dc,
            );
            // ws.g_x now holds dL/d x_colour (p x dc).
            if let Some(d_dir) = d_dir {
                for i in 0..pc {
                    let enc = &ws.x_colour[i * dc + nf..i * dc + nf + dw];
                    d_dir[i] = encoding::backward(enc, &ws.g_x[i * dc + nf..i * dc + nf + dw], self.shape.pe_dir);
                }
            }
        } else {
            // The layers above the first, then the first over the runs of the forward.
            let (first, rest) = self.colour.split_first().expect("colour MLP has an output layer");
            let (h0, h_rest) = ws.h_colour.split_first().expect("colour MLP has an output layer");
            let n0 = first.n_out;
            let runs = Runs { starts: &ws.runs, x: &ws.pe_runs };
            let x = (&ws.x_colour[..], dc);
            // dz of the first layer ends in g_a (no layers above) or g_x; dL/d features into
            // g_x (p x dc, first nf columns) either way.
            if rest.is_empty() {
                first.backward_runs(grads, x, nf, runs, h0, &mut ws.g_a, n0, &mut ws.run_base);
                first.input_grad_cols(params, pc, &ws.g_a, n0, (&mut ws.g_x[..], dc, R::zero()), 0..nf);
            } else {
                backward_stack(rest, params, grads, pc, (h0, n0), h_rest, &mut ws.g_a, &mut ws.g_b, &mut ws.g_x, n0);
                first.backward_runs(grads, x, nf, runs, h0, &mut ws.g_x, n0, &mut ws.run_base);
                first.input_grad_cols(params, pc, &ws.g_x, n0, (&mut ws.g_b[..], dc, R::zero()), 0..nf);
                std::mem::swap(&mut ws.g_x, &mut ws.g_b);
            }
            if let Some(d_dir) = d_dir {
                // Each run's direction gradient (from its summed dz), on its first row; the
                // run's other rows get zero.
                let nr = ws.runs.len() - 1;
                let d_pe = &mut ws.d_pe_runs;
                d_pe.resize(nr * dw, R::zero());
                first.input_grad_cols(params, nr, &ws.run_base, n0, (&mut d_pe[..], dw, R::zero()), nf..dc);
                for r in 0..nr {
                    let rows = ws.runs[r] as usize..ws.runs[r + 1] as usize;
                    let enc = &ws.pe_runs[r * dw..(r + 1) * dw];
                    d_dir[rows.start] = encoding::backward(enc, &d_pe[r * dw..(r + 1) * dw], self.shape.pe_dir);
                    d_dir[rows.start + 1..rows.end].fill([R::zero(); 3]);
                }
            }
        }
        // Density MLP output gradient: (d sigma, d features).
        // The features' gradient from the colour MLP reaches the coloured rows only.
        for i in 0..p {
            ws.g_a[i * (1 + nf)..(i + 1) * (1 + nf)].fill(R::zero());
        }
        if pc > 0 {
            for (j, &i) in ws.coloured.iter().enumerate() {
                let (src, dst) = (&ws.g_x[j * dc..j * dc + nf], i as usize * (1 + nf) + 1);
                ws.g_a[dst..dst + nf].copy_from_slice(src);
            }
        }
        for i in 0..p {
            ws.g_a[i * (1 + nf)] = d_sigma[i];
            let dst = i * (1 + nf) + 1;
            if let Some(df) = d_features {
                for (g, d) in ws.g_a[dst..dst + nf].iter_mut().zip(&df[i * nf..(i + 1) * nf]) {
                    *g += *d;
                }
            }
        }
        backward_stack(
            &self.density,
            params,
            grads,
            p,
            (&ws.x_density, dd),
            &ws.h_density,
            &mut ws.g_a,
            &mut ws.g_b,
            &mut ws.g_x,
            density_cols,
        );
        // ws.g_x holds dL/d x_density (p x dd) in its first density_cols columns: per volume
        // through its basis, then the grid.
        let mut d_pos = d_pos;
        if let Some(d) = d_pos.as_deref_mut() {
            let pw = encoding::width(self.shape.pe_pos);
            let col = vol_cols;
            for i in 0..p {
                let enc = &ws.x_density[i * dd + col..i * dd + col + pw];
                d[i] = encoding::backward(enc, &ws.g_x[i * dd + col..i * dd + col + pw], self.shape.pe_pos);
            }
        }
        let want_dpos = all || d_pos.is_some();
        let mut col = 0;
        for (v, comps) in self.volumes.iter().zip(&ws.comps) {
            let nc = v.n_comps();
            // d comps = dA B^T, dB += comps^T dA (the basis has no activation).
            let mut g_feat = std::mem::take(&mut ws.g_x);
            v.basis.backward(
                params,
                grads,
                p,
                comps,
                nc,
                &[], // y is unused without an activation
                &mut g_feat[col..],
                dd,
                Some((&mut ws.g_comps[..], nc, R::zero())),
            );
            ws.g_x = g_feat;
            for (i, x) in pos.iter().enumerate() {
                let dp = v.components_backward(params, grads, *x, &ws.g_comps[i * nc..(i + 1) * nc], want_dpos);
                if let Some(d) = d_pos.as_deref_mut() {
                    for a in 0..3 {
                        d[i][a] += dp[a];
                    }
                }
            }
            col += v.n_features();
        }
    }
}
