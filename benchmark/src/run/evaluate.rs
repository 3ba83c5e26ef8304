//! Scoring a trained cell: each sharp test view rendered at its pose (`trainer::eval`, the
//! origin ray through the camera response, clamped to [0, 1]), scored against the ground truth
//! on the whole image with PSNR and SSIM (`trainer::metrics`, scikit-image's definitions) and,
//! with weights, LPIPS; the renders are written to `eval/NN.png`. The PSNR and SSIM equal what
//! `evtrain eval` reports for the same run.

use std::path::Path;

use trainer::config::TrainConfig;
use trainer::data::dataset::Dataset;
use trainer::eval::{render_view, write_png};
use trainer::method::Method;
use trainer::metrics::{psnr, ssim, ImageRef};

use crate::error::BenchError;
use crate::lpips::Lpips;
use crate::metrics::ViewMetrics;

/// Renders and scores every test view of `data` on `pool`, writing the renders into `out_dir`.
pub fn score_views(
    data: &Dataset,
    method: &Method,
    params: &[f32],
    cfg: &TrainConfig,
    lpips: Option<&Lpips>,
    pool: &rayon::ThreadPool,
    out_dir: &Path,
) -> Result<Vec<ViewMetrics>, BenchError> {
    let (w, h) = (data.intrinsics.width as usize, data.intrinsics.height as usize);
    let metric_err = |what: &str, e: trainer::metrics::MetricError| {
        BenchError::results(&data.dir, format!("cannot score the {what}: {e}; check the dataset's images"))
    };
    if data.split.test.is_empty() {
        return Err(BenchError::results(
            &data.dir,
            "has no sharp test views to score; write the dataset with sharp views (evsim dataset, sharp_every)",
        ));
    }
    let mut views = Vec::with_capacity(data.split.test.len());
    for &v in &data.split.test {
        let view = &data.views[v];
        let img = pool.install(|| render_view(data, method, params, cfg, v));
        let (a, b) = (
            ImageRef::new(w, h, 3, &img).map_err(|e| metric_err("render", e))?,
            ImageRef::new(w, h, 3, &view.image.data).map_err(|e| metric_err("test view", e))?,
        );
        let p = psnr(a, b).map_err(|e| metric_err("render", e))?;
        let s = ssim(a, b).map_err(|e| metric_err("render", e))?;
        let l = match lpips {
            None => None,
            Some(net) => Some(pool.install(|| net.distance((w, h, &img), (w, h, &view.image.data)))?),
        };
        write_png(&out_dir.join(&view.name), w, h, &img)?;
        views.push(ViewMetrics { name: view.name.clone(), psnr: p, ssim: s, lpips: l });
    }
    Ok(views)
}

/// The means over views: PSNR, SSIM, and LPIPS when every view has it.
pub fn means(views: &[ViewMetrics]) -> (f64, f64, Option<f64>) {
    let n = views.len() as f64;
    let lpips: Option<Vec<f64>> = views.iter().map(|v| v.lpips).collect();
    (
        views.iter().map(|v| v.psnr).sum::<f64>() / n,
        views.iter().map(|v| v.ssim).sum::<f64>() / n,
        lpips.map(|l| l.iter().sum::<f64>() / n),
    )
}
