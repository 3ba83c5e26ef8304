//! Evaluation: render the sharp test views at their poses (the origin ray, no blur model),
//! apply the camera response, and score against the ground truth with PSNR and SSIM on whole
//! images in [0, 1] (no cropping, as the reference evaluation). A learned camera trajectory
//! (BAD-NeRF) renders them moved as its training views nearest in time were
//! ([`Method::test_alignment`]); every other method at the dataset's poses.

use std::path::Path;

use rayon::prelude::*;

use crate::config::TrainConfig;
use crate::data::dataset::Dataset;
use crate::engine::renderer::{RayChunk, Renderer};
use crate::error::TrainError;
use crate::method::rays::{prepare, response, unzip, PreparedRay};
use crate::method::{warp, Method};
use crate::metrics::{psnr, ssim, ImageRef};

/// Scores of one test view.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ViewScore {
    /// Index in the dataset's views.
    pub view: usize,
    /// File name in `images_1/`.
    pub name: String,
    /// PSNR (dB).
    pub psnr: f64,
    /// SSIM.
    pub ssim: f64,
}

/// Scores of every test view.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Scores {
    /// Per view, in view order.
    pub views: Vec<ViewScore>,
}

impl Scores {
    /// Mean PSNR over the views (NaN when there are none).
    pub fn mean_psnr(&self) -> f64 {
        self.views.iter().map(|v| v.psnr).sum::<f64>() / self.views.len() as f64
    }

    /// Mean SSIM over the views.
    pub fn mean_ssim(&self) -> f64 {
        self.views.iter().map(|v| v.ssim).sum::<f64>() / self.views.len() as f64
    }
}

/// Renders view `view` at its pose (moved by the method's [`Method::test_alignment`], if any):
/// display-referred RGB, row-major, 3 values per pixel. Rows are rendered in parallel on the
/// current rayon pool; the result does not depend on it.
pub fn render_view(data: &Dataset, method: &Method, params: &[f32], cfg: &TrainConfig, view: usize) -> Vec<f32> {
    let (w, h) = (data.intrinsics.width as usize, data.intrinsics.height as usize);
    let pose = &data.views[view].pose;
    let mid = |v: usize| 0.5 * (data.views[v].t_start_us + data.views[v].t_end_us);
    let train: Vec<(usize, f64)> = data.split.train.iter().map(|&v| (v, mid(v))).collect();
    let (model, align) = (&method.model, method.test_alignment(params, &train, mid(view)));
    let inv_gamma = (1.0 / cfg.response_gamma) as f32;
    let mut out = vec![0.0f32; w * h * 3];
    out.par_chunks_mut(w * 3).enumerate().for_each_init(Renderer::default, |renderer, (j, row)| {
        let rays: Vec<PreparedRay> = (0..w)
            .map(|i| {
                let ray = data.intrinsics.ray(pose, i as u32, j as u32);
                prepare(data, &align.as_ref().map_or(ray, |m| warp(m, &ray)))
            })
            .collect();
        let per_call = (cfg.chunk_rays * 4).max(1);
        for (c, chunk) in rays.chunks(per_call).enumerate() {
            let (o, d, vd) = unzip(chunk);
            renderer.forward(model, params, &RayChunk { origins: &o, dirs: &d, viewdirs: &vd }, None);
            for (k, rgb) in renderer.fine().iter().enumerate() {
                let px = c * per_call + k;
                for ch in 0..3 {
                    row[3 * px + ch] = response(rgb[ch], inv_gamma).0.clamp(0.0, 1.0);
                }
            }
        }
    });
    out
}

/// Renders and scores every test view with `threads` workers (0: all cores); with `out_dir`,
/// also writes each rendering as `NN.png` there.
pub fn evaluate(
    data: &Dataset,
    method: &Method,
    params: &[f32],
    cfg: &TrainConfig,
    threads: usize,
    out_dir: Option<&Path>,
) -> Result<Scores, TrainError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| TrainError::Config(format!("threads = {threads}: cannot start the workers ({e})")))?;
    let (w, h) = (data.intrinsics.width as usize, data.intrinsics.height as usize);
    let mut scores = Scores::default();
    for &v in &data.split.test {
        let img = pool.install(|| render_view(data, method, params, cfg, v));
        let truth = &data.views[v].image;
        let a = ImageRef::new(w, h, 3, &img).map_err(|e| TrainError::Config(format!("render: {e}")))?;
        let b = ImageRef::new(w, h, 3, &truth.data).map_err(|e| TrainError::Config(format!("test view: {e}")))?;
        let (p, s) = (psnr(a, b), ssim(a, b));
        let (p, s) =
            (p.map_err(|e| TrainError::Config(e.to_string()))?, s.map_err(|e| TrainError::Config(e.to_string()))?);
        if let Some(dir) = out_dir {
            write_png(&dir.join(&data.views[v].name), w, h, &img)?;
        }
        scores.views.push(ViewScore { view: v, name: data.views[v].name.clone(), psnr: p, ssim: s });
    }
    Ok(scores)
}

/// Writes display-referred RGB in [0, 1] as an 8-bit PNG, atomically.
pub fn write_png(path: &Path, w: usize, h: usize, rgb: &[f32]) -> Result<(), TrainError> {
    let bytes: Vec<u8> = rgb.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
    let img = image::RgbImage::from_raw(w as u32, h as u32, bytes).expect("w * h * 3 values");
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| TrainError::run(path, format!("cannot encode PNG: {e}"), "report this bug"))?;
    simulator::image_io::write_atomic(path, &png)
        .map_err(|e| TrainError::run(path, format!("{e:#}"), "check the run folder is writable"))
}
