//! Where along a ray the field is evaluated: NeRF's stratified coarse samples and its importance
//! (inverse-CDF) fine samples. No gradient flows through sampling.
//!
//! **Stratified** (NeRF's `render_rays`, `lindisp = False`): `z_j = near (1 - s_j) + far s_j`
//! with `s = linspace(0, 1, n)`. With jitter (training, NeRF's `perturb`), each sample moves
//! uniformly inside its stratum: `mids_j = (z_j + z_{j+1}) / 2`, `lower = [z_0, mids]`,
//! `upper = [mids, z_{n-1}]`, `t_j = lower_j + (upper_j - lower_j) u_j`; so `t_0` stays in
//! `[near, mid_0]`, `t_{n-1}` in `[mid_{n-2}, far]`, and the output is sorted.
//!
//! **Importance** (NeRF's `sample_pdf`, called with the coarse pass's `t` and weights): with
//! `S` coarse samples, the bins are the `S - 1` midpoints `b_k = (t_k + t_{k+1}) / 2` and the
//! piecewise-constant pdf over them comes from the interior weights,
//! `pdf_k = (w_{k+1} + 1e-5) / sum_{j=1}^{S-2} (w_j + 1e-5)` for `k = 0..S-2`, with
//! `cdf = [0, cumsum(pdf)]` (one value per bin edge). For each `u` (uniform, or
//! `linspace(0, 1, n)` when deterministic): `i = searchsorted(cdf, u, right)`,
//! `below = max(i - 1, 0)`, `above = min(i, S - 2)`, `denom = cdf[above] - cdf[below]` (1 if
//! < 1e-5), and `t = b[below] + (u - cdf[below]) / denom (b[above] - b[below])`.
//!
//! The inverse CDF is monotone in `u`, so [`importance`] sorts its uniforms first and returns
//! sorted samples (the same set NeRF draws, in order; the union with the coarse samples is the
//! same either way), found with one linear walk over the CDF. [`merge_sorted`] then gives the
//! fine pass's `S + n` sorted samples (NeRF's `sort(cat([z_vals, z_samples]))`).
//!
//! Random numbers are drawn as `f32` ([`Rng::uniform_f32`]) in both precisions, so an `f64` run
//! samples the same `t` as an `f32` run up to rounding.

use super::real::Real;
use super::rng::Rng;

/// Fills `out` (length `n`) with `n` samples of t between `near` and `far`, linear in t: the exact
/// linspace without `jitter`, one uniform sample per stratum with it (see the module doc).
/// The output is sorted (for `near <= far`).
pub fn stratified<R: Real>(near: R, far: R, n: usize, jitter: Option<&mut Rng>, out: &mut [R]) {
    assert_eq!(out.len(), n, "stratified: out has {} slots for {n} samples", out.len());
    if n == 0 {
        return;
    }
    // z_j = near (1 - s_j) + far s_j, s = linspace(0, 1, n).
    let step = if n > 1 { R::one() / R::of((n - 1) as f64) } else { R::zero() };
    for (j, z) in out.iter_mut().enumerate() {
        let s = if j + 1 == n && n > 1 { R::one() } else { R::of(j as f64) * step };
        *z = near * (R::one() - s) + far * s;
    }
    let Some(rng) = jitter else { return };
    // Perturb within strata: t_j = lower_j + (upper_j - lower_j) u_j. Walking forward, `lower`
    // (the previous midpoint) is kept before z_j is overwritten.
    let half = R::of(0.5);
    let mut lower = out[0];
    for j in 0..n {
        let upper = if j + 1 < n { half * (out[j] + out[j + 1]) } else { out[j] };
        let u = R::of(rng.uniform_f32() as f64);
        out[j] = lower + (upper - lower) * u;
        lower = upper;
    }
}

/// NeRF's `sample_pdf` (see the module doc): fills `out` (length `n_fine`) with samples of t drawn
/// from the piecewise-constant pdf of the coarse pass, given the coarse sample positions `bins_t`
/// (sorted, length `S >= 3`) and their render `weights` (length `S`; the first and last are not
/// used, as in NeRF). `det` uses `u = linspace(0, 1, n_fine)` (evaluation) and leaves `rng`
/// untouched; otherwise `u` is uniform. The output is sorted ascending.
pub fn importance<R: Real>(bins_t: &[R], weights: &[R], n_fine: usize, det: bool, rng: &mut Rng, out: &mut [R]) {
    let s = bins_t.len();
    assert!(s >= 3, "importance: {s} coarse samples, need at least 3 (the pdf uses weights[1..S-1])");
    assert_eq!(weights.len(), s, "importance: {} weights for {s} coarse samples", weights.len());
    assert_eq!(out.len(), n_fine, "importance: out has {} slots for {n_fine} samples", out.len());
    if n_fine == 0 {
        return;
    }
    // Uniforms, sorted (the inverse CDF is monotone, so the samples come out sorted).
    if det {
        let step = if n_fine > 1 { R::one() / R::of((n_fine - 1) as f64) } else { R::zero() };
        for (j, u) in out.iter_mut().enumerate() {
            *u = if j + 1 == n_fine && n_fine > 1 { R::one() } else { R::of(j as f64) * step };
        }
    } else {
        for u in out.iter_mut() {
            *u = R::of(rng.uniform_f32() as f64);
        }
        out.sort_unstable_by(|a, b| a.partial_cmp(b).expect("uniforms are finite"));
    }
    // pdf_k = (w_{k+1} + 1e-5) / sum, k = 0..m-1 (m = S - 2 intervals between S - 1 bin edges).
    let eps = R::of(1e-5);
    let interior = &weights[1..s - 1];
    let total: R = interior.iter().map(|&w| w + eps).sum();
    let pdf = |k: usize| (interior[k] + eps) / total;
    let bin = |k: usize| R::of(0.5) * (bins_t[k] + bins_t[k + 1]);
    let n_edges = s - 1;
    // Walk the CDF once: `i` = searchsorted(cdf, u, right) = the number of edges with cdf <= u;
    // `c_prev` = cdf[i - 1], `c_cur` = cdf[i] (when i < n_edges). cdf[0] = 0 <= u, so i >= 1.
    let (mut i, mut c_prev, mut c_cur) = (0usize, R::zero(), R::zero());
    for x in out.iter_mut() {
        let u = *x;
        while i < n_edges && c_cur <= u {
            c_prev = c_cur;
            i += 1;
            if i < n_edges {
                c_cur += pdf(i - 1);
            }
        }
        // below = i - 1, above = min(i, S - 2); cdf and bins gathered at both.
        let below = i - 1;
        let (above, c_above) = if i < n_edges { (i, c_cur) } else { (n_edges - 1, c_prev) };
        let mut denom = c_above - c_prev;
        if denom < eps {
            denom = R::one();
        }
        let frac = (u - c_prev) / denom;
        *x = bin(below) + frac * (bin(above) - bin(below));
    }
}

/// The sorted union of two sorted slices (`out.len() == coarse.len() + fine.len()`), e.g. the
/// coarse and importance samples the fine pass evaluates.
pub fn merge_sorted<R: Real>(coarse: &[R], fine: &[R], out: &mut [R]) {
    assert_eq!(out.len(), coarse.len() + fine.len(), "merge_sorted: out has the wrong length");
    merge_walk(coarse, fine, |k, t, _| out[k] = t);
}

/// Walks the sorted union of two sorted slices in order (ties: `coarse` first), calling
/// `emit(k, value, origin)` for the k-th value, `origin` `Ok(i)` for `coarse[i]` and `Err(j)`
/// for `fine[j]`.
pub fn merge_walk<R: Real>(coarse: &[R], fine: &[R], mut emit: impl FnMut(usize, R, Result<usize, usize>)) {
    debug_assert!(coarse.windows(2).all(|w| w[0] <= w[1]), "merge_sorted: coarse is not sorted");
    debug_assert!(fine.windows(2).all(|w| w[0] <= w[1]), "merge_sorted: fine is not sorted");
    let (mut a, mut b) = (0, 0);
    for k in 0..coarse.len() + fine.len() {
        if b == fine.len() || (a < coarse.len() && coarse[a] <= fine[b]) {
            emit(k, coarse[a], Ok(a));
            a += 1;
        } else {
            emit(k, fine[b], Err(b));
            b += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// NeRF's `sample_pdf` transcribed literally (allocating, binary search, unsorted `u`).
    fn sample_pdf_reference(bins_t: &[f32], weights: &[f32], u: &[f32]) -> Vec<f32> {
        let bins: Vec<f32> = bins_t.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        let w: Vec<f32> = weights[1..weights.len() - 1].iter().map(|&w| w + 1e-5).collect();
        let total: f32 = w.iter().sum();
        let mut cdf = vec![0.0f32];
        let mut acc = 0.0f32;
        for &wk in &w {
            acc += wk / total;
            cdf.push(acc);
        }
        u.iter()
            .map(|&u| {
                let inds = cdf.partition_point(|&c| c <= u); // searchsorted(right = True)
                let below = inds.saturating_sub(1);
                let above = inds.min(cdf.len() - 1);
                let mut denom = cdf[above] - cdf[below];
                if denom < 1e-5 {
                    denom = 1.0;
                }
                let t = (u - cdf[below]) / denom;
                bins[below] + t * (bins[above] - bins[below])
            })
            .collect()
    }

    fn coarse_ray(s: usize, rng: &mut Rng) -> (Vec<f32>, Vec<f32>) {
        let mut t = vec![0.0; s];
        stratified(0.0, 1.0, s, Some(rng), &mut t);
        let w: Vec<f32> = (0..s).map(|k| (k as f32 * 0.7).sin().max(0.0) * rng.uniform_f32()).collect();
        (t, w)
    }

    #[test]
    fn stratified_without_jitter_is_the_linspace() {
        let mut t = [0.0f64; 5];
        stratified(2.0, 6.0, 5, None, &mut t);
        assert_eq!(t, [2.0, 3.0, 4.0, 5.0, 6.0]);
        let mut one = [0.0f32; 1];
        stratified(0.5, 1.0, 1, None, &mut one);
        assert_eq!(one, [0.5]);
    }

    #[test]
    fn stratified_jitter_stays_in_its_stratum_and_fills_it_uniformly() {
        let (near, far, n) = (0.0f32, 1.0f32, 8);
        let mut lin = vec![0.0f32; n];
        stratified(near, far, n, None, &mut lin);
        let mut t = vec![0.0f32; n];
        let mut rng = Rng::new(1, 0);
        // Per stratum j, a 10-bin histogram of the position inside [lower_j, upper_j].
        let mut hist = vec![[0u64; 10]; n];
        let draws = 20_000;
        for _ in 0..draws {
            stratified(near, far, n, Some(&mut rng), &mut t);
            assert!(t.windows(2).all(|w| w[0] <= w[1]));
            for j in 0..n {
                let lower = if j == 0 { lin[0] } else { 0.5 * (lin[j - 1] + lin[j]) };
                let upper = if j + 1 == n { lin[j] } else { 0.5 * (lin[j] + lin[j + 1]) };
                assert!(t[j] >= lower && t[j] <= upper, "sample {j}: {} outside [{lower}, {upper}]", t[j]);
                let f = ((t[j] - lower) / (upper - lower) * 10.0).min(9.0) as usize;
                hist[j][f] += 1;
            }
        }
        for h in &hist {
            let e = draws as f64 / 10.0;
            let chi2: f64 = h.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
            assert!(chi2 < 27.9, "chi2 {chi2} (9 dof, 99.9% quantile 27.9)");
        }
    }

    #[test]
    fn importance_matches_the_literal_sample_pdf() {
        let mut rng = Rng::new(5, 0);
        for trial in 0..50 {
            let s = 3 + trial % 20;
            let (t, w) = coarse_ray(s, &mut rng);
            let n = 1 + trial % 33;
            for det in [true, false] {
                let mut ours = vec![0.0f32; n];
                let mut rng_a = Rng::new(77, trial as u64);
                importance(&t, &w, n, det, &mut rng_a, &mut ours);
                // The same uniforms, unsorted, through the literal transcription.
                let u: Vec<f32> = if det {
                    (0..n).map(|j| if n > 1 { j as f32 / (n - 1) as f32 } else { 0.0 }).collect()
                } else {
                    let mut rng_b = Rng::new(77, trial as u64);
                    (0..n).map(|_| rng_b.uniform_f32()).collect()
                };
                let mut reference = sample_pdf_reference(&t, &w, &u);
                reference.sort_by(f32::total_cmp);
                for (a, b) in ours.iter().zip(&reference) {
                    assert!((a - b).abs() <= 1e-6, "trial {trial} det {det}: {a} vs {b}");
                }
                assert!(ours.windows(2).all(|p| p[0] <= p[1]), "not sorted");
            }
        }
    }

    #[test]
    fn a_delta_weight_puts_every_sample_in_its_bin() {
        let s = 16;
        let mut t = vec![0.0f64; s];
        stratified(0.0, 1.0, s, None, &mut t);
        let mut w = vec![0.0; s];
        w[6] = 1.0;
        // Weight 6 is interval 5 of the pdf, between bin edges 5 and 6: the midpoints of
        // t_5, t_6 and of t_6, t_7.
        let (lo, hi) = (0.5 * (t[5] + t[6]), 0.5 * (t[6] + t[7]));
        let mut rng = Rng::new(2, 0);
        let mut out = vec![0.0; 1000];
        importance(&t, &w, 1000, false, &mut rng, &mut out);
        // The other 13 intervals carry 1e-5 each: about 13e-5 of the mass, so at most a few samples.
        let inside = out.iter().filter(|&&x| x >= lo && x <= hi).count();
        assert!(inside >= 995, "{inside} of 1000 samples in the weighted bin");
        // Inside the bin the pdf is flat: the mean is near the bin's centre.
        let mean = out.iter().filter(|&&x| x >= lo && x <= hi).sum::<f64>() / inside as f64;
        assert!((mean - t[6]).abs() < 0.05 * (hi - lo), "mean {mean}, centre {}", t[6]);
    }

    #[test]
    fn importance_samples_follow_the_pdf() {
        // Chi-square of the samples' interval counts against the piecewise-constant pdf.
        let s = 12;
        let mut t = vec![0.0f64; s];
        stratified(1.0, 3.0, s, None, &mut t);
        let w: Vec<f64> = (0..s).map(|k| 0.05 + (k as f64 * 0.9).cos().abs()).collect();
        let interior: Vec<f64> = w[1..s - 1].iter().map(|&x| x + 1e-5).collect();
        let total: f64 = interior.iter().sum();
        let edges: Vec<f64> = t.windows(2).map(|p| 0.5 * (p[0] + p[1])).collect();
        let mut counts = vec![0u64; s - 2];
        let mut rng = Rng::new(4, 0);
        let (draws, per) = (500, 64);
        let mut out = vec![0.0; per];
        for _ in 0..draws {
            importance(&t, &w, per, false, &mut rng, &mut out);
            for &x in &out {
                let k = edges.partition_point(|&e| e <= x).clamp(1, s - 2) - 1;
                counts[k] += 1;
            }
        }
        let n = (draws * per) as f64;
        let chi2: f64 = counts
            .iter()
            .zip(&interior)
            .map(|(&c, &p)| {
                let e = n * p / total;
                (c as f64 - e).powi(2) / e
            })
            .sum();
        assert!(chi2 < 27.9, "chi2 {chi2} (9 dof, 99.9% quantile 27.9)");
    }

    #[test]
    fn deterministic_samples_are_monotone_and_span_the_bins() {
        let mut rng = Rng::new(8, 0);
        let (t, w) = coarse_ray(64, &mut rng);
        let mut out = vec![0.0f32; 64];
        let before = rng.clone().next_u64();
        importance(&t, &w, 64, true, &mut rng, &mut out);
        assert_eq!(rng.next_u64(), before, "det must not draw random numbers");
        assert!(out.windows(2).all(|p| p[0] <= p[1]));
        // u = 0 and u = 1 map to the first and last bin edges.
        assert_eq!(out[0], 0.5 * (t[0] + t[1]));
        assert!((out[63] - 0.5 * (t[62] + t[63])).abs() < 1e-6);
    }

    #[test]
    fn merge_gives_the_sorted_union() {
        let mut rng = Rng::new(3, 3);
        let (t, w) = coarse_ray(64, &mut rng);
        let mut fine = vec![0.0f32; 64];
        importance(&t, &w, 64, false, &mut rng, &mut fine);
        let mut merged = vec![0.0f32; 128];
        merge_sorted(&t, &fine, &mut merged);
        let mut brute: Vec<f32> = t.iter().chain(&fine).copied().collect();
        brute.sort_by(f32::total_cmp);
        assert_eq!(merged, brute);
        let mut only_coarse = vec![0.0f32; 64];
        merge_sorted(&t, &[], &mut only_coarse);
        assert_eq!(only_coarse, t);
    }
}
