//! The dataset writer: a [`Plan`] in, an Ev-DeblurBlender folder out.
//!
//! Stages, streamed frame by frame (memory: a few images plus the event model's per-pixel
//! state, whatever the sequence length):
//! 1. **Frames.** Frame `k` at `t_k` comes from the frame cache or is rendered (`spp` samples,
//!    the fixed or per-frame noise pattern) and filtered (with `denoise`: the temporal window
//!    and the spatial filter, see [`super::sequence`]), rounded to half floats and cached. Its depth grid
//!    gives the LLFF bounds of row `k` of `all_poses_bounds.npy`. The frame then feeds
//! 2. **events** (the event model over `gain * frame`, into `events.h5`) and
//! 3. **exposure** (the box-filter average of every blurry view whose window it overlaps;
//!    finished views go through the camera response into `images_1/NN.png`).
//! 4. **Sharp images**: the sharp test views of `images_1/` and `images_sharp_1/NN.png` for
//!    every view. By default the sequence frame at the view's mid-time (written in stage 1);
//!    with `sharp_spp` set, a separate render with that many samples (cached as well).
//! 5. **Metadata**: `timestamps.npz`, `poses_bounds.npy` (mid-exposure pose; near/far over the
//!    frames of the exposure), `all_poses_bounds.npy`, `all_timestamps.npy`, `transforms.json`
//!    and, last, the `dataset.toml` manifest that marks the folder complete.
//!
//! What follows each frame in stages 1-4 (caching it, its depth bounds, events, exposure, its
//! sharp views) runs one frame behind, beside the next frame's render in the same thread pool
//! (`super::frame_tail`); the output does not depend on it.
//!
//! Every file is written atomically. An interrupted run resumes from the cached frames (the
//! event and exposure stages are re-run over them, which takes seconds); a complete folder with
//! the same settings hash is left alone. The folder is locked while a run writes it
//! ([`FolderLock`]): a second run into it is refused with the first one's pid, and the
//! temporary files of a killed run are removed by the next.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use super::cache::{round_to_f16, FrameCache};
use super::frame_tail::{Finished, FrameTail};
use super::manifest::DatasetManifest;
use super::plan::{Plan, PIPELINE_VERSION};
use super::sequence::SequenceRenderer;
use super::settings::NoisePattern;
use super::DatasetError;
use crate::base::image::Image;
use crate::events::sinks::NerfH5Sink;
use crate::events::EventSink;
use crate::events::{EventConfig, EventSimulator};
use crate::exposure::{Exposure, ExposureStack, ViewSpec};
use crate::image_io::write_atomic;
use crate::lock::FolderLock;
use crate::npy::{write_npy, write_npz, NpyArray};
use crate::render::film::RenderSettings;
use crate::render::integrator::Renderer;
use crate::render::radiance_cache::FillTimes;
use crate::trajectory::{LlffCamera, Pose};

/// Every `DEPTH_STRIDE`-th pixel (in x and y) is traced for the depth bounds.
pub const DEPTH_STRIDE: u32 = 4;

/// How to run the writer.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// The dataset folder.
    pub out: PathBuf,
    /// Frame cache root; `None` = `<out>/.frames`, removed after a successful run unless
    /// `keep_frames`.
    pub frames_cache: Option<PathBuf>,
    /// Keep the default frame cache after success (for later sweeps).
    pub keep_frames: bool,
    /// Show progress bars on stderr.
    pub progress: bool,
    /// Stop with [`DatasetError::Interrupted`] after rendering this many images (tests).
    pub stop_after_renders: Option<usize>,
}

/// What a run did and how long each stage took.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// The folder was already complete with these settings; nothing was done.
    pub already_complete: bool,
    /// Frames in the sequence.
    pub frames: usize,
    /// Frames rendered in this run (the rest came from the cache).
    pub frames_rendered: usize,
    /// Extra renders of frames the cache already held, made for the temporal window of the
    /// first frames a resumed run filters (`[dataset] temporal_radius` at most).
    pub window_renders: usize,
    /// Sharp views rendered in this run.
    pub sharp_rendered: usize,
    /// ON events written.
    pub events_on: u64,
    /// OFF events written.
    pub events_off: u64,
    /// Wall time spent rendering frames and sharp views (denoising included).
    pub render_time: Duration,
    /// The part of `render_time` spent denoising (`[dataset] denoise`).
    pub denoise_time: Duration,
    /// Wall time spent reading cached frames.
    pub cache_read_time: Duration,
    /// Wall time of writing new renders to the frame cache.
    pub cache_write_time: Duration,
    /// Wall time of the event model and the event file.
    pub events_time: Duration,
    /// Wall time of exposure averaging and PNG encoding.
    pub exposure_time: Duration,
    /// Wall time of depth bounds and metadata files.
    pub metadata_time: Duration,
    /// Peak resident memory (bytes) of the process during the frame stages (render, events,
    /// exposure), the sharp renders and the metadata, when the OS reports it (Linux).
    pub peak_rss: [Option<u64>; 3],
    /// Thread time of the renders' lazily filled caches, by kind
    /// ([`Renderer::fill_times`]).
    pub fill_times: Vec<(&'static str, FillTimes)>,
}

/// Reset the peak resident set size (Linux: `5` into `/proc/self/clear_refs`), so that the next
/// [`peak_rss`] covers only what follows. Best effort.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident set size of this process (Linux `VmHWM`), bytes.
pub fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// `images_1/NN.png`-style name of view `i` of `n` (zero-padded to at least 2 digits).
pub fn image_name(i: usize, n: usize) -> String {
    let digits = n.saturating_sub(1).to_string().len().max(2);
    format!("{i:0digits$}.png")
}

/// The default frame cache (`<out>/.frames`) is renamed to this before it is deleted, and a
/// leftover of that name (a run killed while deleting) is removed by the next run.
const FRAMES_BEING_REMOVED: &str = ".frames.removing";

/// The files a complete dataset holds (besides the images).
pub const METADATA_FILES: [&str; 6] = [
    "images_1/timestamps.npz",
    "poses_bounds.npy",
    "all_poses_bounds.npy",
    "all_timestamps.npy",
    "events.h5",
    "transforms.json",
];

/// The manifest's `settings_hash`, if `out/dataset.toml` exists and has one.
fn manifest_hash(out: &Path) -> Option<String> {
    let text = std::fs::read_to_string(out.join("dataset.toml")).ok()?;
    let value: toml::Value = toml::from_str(&text).ok()?;
    value.get("settings_hash")?.as_str().map(str::to_string)
}

fn io_stage(path: &Path) -> impl Fn(anyhow::Error) -> DatasetError + '_ {
    move |e| DatasetError::stage(path.display(), format!("{e:#}"))
}

/// Render one single frame of a dataset (a sharp render at a view's mid-time): with
/// `[dataset] shading = "surface_cache"` from the surface cache with `max(feature_spp, spp)`
/// camera samples per pixel, else the path tracer's image, denoised (spatially) when `denoise`
/// is on. Also returns the time spent denoising.
pub fn render_frame(renderer: &Renderer, settings: &RenderSettings, plan: &Plan) -> (Image, Duration) {
    if plan.config.shading == super::Shading::SurfaceCache {
        let vis = renderer.visibility(settings, settings.feature_spp.max(settings.spp));
        return (renderer.render_surface(settings, &vis), Duration::ZERO);
    }
    if plan.config.denoise {
        let (img, features) = renderer.render_with_features(settings);
        let t = Instant::now();
        let out = crate::render::denoise::denoise(&img, &features, &crate::render::denoise::DenoiseParams::default());
        (out, t.elapsed())
    } else {
        (renderer.render(settings, None), Duration::ZERO)
    }
}

/// The render settings of frame `k` of `plan` (a sharp render when `sharp`).
pub fn render_settings(plan: &Plan, pose: &Pose, k: usize, sharp: bool) -> RenderSettings {
    let c = &plan.config;
    let mut s = RenderSettings::new(pose.camera(plan.yfov as f32));
    s.width = c.width;
    s.height = c.height;
    s.max_depth = c.max_depth;
    s.seed = c.seed;
    s.sampler = c.sampler;
    s.clamp = c.clamp;
    s.light_samples = c.light_samples;
    s.feature_spp = c.feature_spp;
    s.texture_filter = c.texture_filter;
    s.radiance_cache = c.radiance_cache;
    s.cache_vertex = c.cache_vertex;
    s.surface_paths = c.surface_paths;
    s.surface_spacing = c.surface_spacing;
    s.glossy_paths = c.glossy_paths;
    s.glossy_block = c.glossy_block;
    s.glossy_stride = c.glossy_stride;
    s.glossy_grid_alpha = c.glossy_grid_alpha;
    s.camera_path = Some(plan.camera_path.clone());
    if sharp {
        s.spp = plan.sharp_spp.unwrap_or(c.spp);
        // sharp renders draw from their own streams (far from any sequence frame index)
        s.frame = (1 << 40) + k as u64;
    } else {
        s.spp = c.spp;
        s.spp_max = c.spp_max;
        s.adaptive_variance = c.adaptive_variance as f32;
        s.frame = match c.noise_pattern {
            NoisePattern::Fixed => 0,
            NoisePattern::PerFrame => k as u64,
        };
    }
    s
}

/// Write the dataset of `plan` into `opts.out`. See the [module docs](self).
pub fn write_dataset(plan: &Plan, opts: &RunOptions) -> Result<Summary, DatasetError> {
    let out = &opts.out;
    let n_views = plan.views.len();
    let images = out.join("images_1");
    let sharp_dir = out.join("images_sharp_1");
    let complete = |out: &Path| {
        METADATA_FILES.iter().all(|f| out.join(f).is_file())
            && (0..n_views).all(|i| images.join(image_name(i, n_views)).is_file())
    };
    std::fs::create_dir_all(out).map_err(|e| DatasetError::io(out, "cannot create (choose another --out)", e))?;
    // one writer at a time; what a killed writer left is removed by the next one
    let _lock = FolderLock::acquire(out)?;
    let removing = out.join(FRAMES_BEING_REMOVED);
    if removing.exists() {
        std::fs::remove_dir_all(&removing).map_err(|e| {
            DatasetError::io(&removing, "cannot remove this frame cache of a finished run; delete it", e)
        })?;
    }
    // the folder, images_1/, images_sharp_1/, and the default frame cache's
    // <key>/<frames or sharp>/ folders
    let clean = |dir: &Path, depth| {
        crate::lock::remove_stale_temps(dir, depth).map_err(|e| DatasetError::io(dir, "cannot clean up", e))
    };
    clean(out, 1)?;
    if opts.frames_cache.is_none() {
        clean(&out.join(".frames"), 2)?;
    }
    match manifest_hash(out) {
        Some(h) if h == plan.settings_hash && complete(out) => {
            return Ok(Summary { already_complete: true, frames: plan.clock.n_frames, ..Summary::default() })
        }
        Some(h) if h != plan.settings_hash => {
            return Err(DatasetError::Conflict {
                path: out.join("dataset.toml"),
                message: format!(
                    "this folder holds a dataset made with other settings (hash {} vs {}); delete the folder or \
                     choose another --out",
                    &h[..h.len().min(12)],
                    &plan.settings_hash[..12]
                ),
            });
        }
        _ => {}
    }
    for dir in [&images, &sharp_dir] {
        std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, "cannot create (choose another --out)", e))?;
        remove_stale_images(dir, n_views)?;
    }
    let cache_root = opts.frames_cache.clone().unwrap_or_else(|| out.join(".frames"));
    let cache = FrameCache::open(&cache_root, plan)?;

    let c = &plan.config;
    let (w, h) = (c.width, c.height);
    let n_frames = plan.clock.n_frames;
    let mut summary = Summary { frames: n_frames, ..Summary::default() };
    let pb = if opts.progress { ProgressBar::new(0) } else { ProgressBar::hidden() };
    pb.set_style(
        ProgressStyle::with_template("{msg:24} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta_precise}")
            .expect("valid template"),
    );
    // progress counts samples per pixel rendered or read, so the ETA weighs sharp renders
    pb.set_length(n_frames as u64 * c.spp as u64 + n_views as u64 * plan.sharp_spp.unwrap_or(0) as u64);

    reset_peak_rss();
    let t = Instant::now();
    let renderer = Renderer::with_preset(&plan.scene, c.bvh);
    summary.render_time += t.elapsed();
    let mut renders = 0usize;
    let mut count_render = |summary: &mut Summary| -> Result<(), DatasetError> {
        renders += 1;
        if opts.stop_after_renders.is_some_and(|n| renders >= n) {
            pb.abandon();
            return Err(DatasetError::Interrupted { frames: summary.frames_rendered });
        }
        Ok(())
    };

    // stages 1-3: frames -> events + blurry views
    let blurry: Vec<ViewSpec> = plan.views.iter().copied().filter(|v| !matches!(v.exposure, Exposure::Sharp)).collect();
    let stack = ExposureStack::new(&blurry, plan.clock, w, h)
        .map_err(|e| DatasetError::config(&plan.scene_file, "dataset", e.to_string()))?;
    let event_cfg: EventConfig = plan.events.clone();
    let sim = EventSimulator::new(event_cfg, w, h)
        .map_err(|e| DatasetError::config(&plan.scene_file, "events", e.to_string()))?;
    let events_path = out.join("events.h5");
    let mut sink = NerfH5Sink::create(&events_path).map_err(|e| DatasetError::io(&events_path, "cannot create", e))?;
    let mut tail = FrameTail::new(plan, &renderer.accel, out, sim, stack);
    let mut seq = SequenceRenderer::new(plan, &renderer, c.spp);
    // frame k from the cache or rendered: (frame, wall time, of which denoising)
    let mut next_frame = |k: usize| -> Result<(Finished, Duration, Duration), DatasetError> {
        let pose =
            plan.trajectory.pose_at(plan.clock.time_ns(k)).map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        let t = Instant::now();
        let denoise_time = seq.denoise_time;
        let (frame, store) = seq.frame_or_cached(k, &cache)?;
        Ok((Finished { k, pose, frame, store }, t.elapsed(), seq.denoise_time - denoise_time))
    };
    pb.set_message("frames");
    // frame k renders while frame k - 1 passes the tail (cache, depth bounds, events, views)
    let mut pending: Option<Finished> = None;
    let mut stop = None;
    for k in 0..=n_frames {
        let produce = (k < n_frames && stop.is_none()).then_some(k);
        let (next, passed) = rayon::join(
            || produce.map(&mut next_frame).transpose(),
            || pending.take().map(|f| tail.take(f)).transpose(),
        );
        if passed?.is_some() {
            sink.push(tail.events()).map_err(|e| DatasetError::io(&events_path, "cannot write", e))?;
        }
        if let Some(e) = stop {
            return Err(e); // interrupted, once the last frame rendered is cached
        }
        let Some((f, time, denoise_time)) = next? else { continue };
        if f.store.is_some() {
            summary.render_time += time;
            summary.denoise_time += denoise_time;
            summary.frames_rendered += 1;
            stop = count_render(&mut summary).err();
        } else {
            summary.cache_read_time += time;
        }
        pb.inc(c.spp as u64);
        pending = Some(f);
    }
    let tail = tail.finish()?;
    summary.fill_times = renderer.fill_times().to_vec();
    let t = Instant::now();
    let written = sink.finish().map_err(|e| DatasetError::io(&events_path, "cannot complete", e))?;
    summary.events_time += t.elapsed();
    // every frame this run made was rendered once; what else the window rendered came from the cache
    summary.window_renders = seq.renders.saturating_sub(summary.frames_rendered);
    summary.events_on = tail.events_on;
    summary.events_off = tail.events_off;
    summary.events_time += tail.events_time;
    summary.exposure_time = tail.exposure_time;
    summary.metadata_time = tail.metadata_time;
    summary.cache_write_time = tail.cache_write_time;
    debug_assert_eq!(written, summary.events_on + summary.events_off);
    let (frame_poses, frame_bounds) = (tail.frame_poses, tail.frame_bounds);

    summary.peak_rss[0] = peak_rss();

    // stage 4: sharp renders
    reset_peak_rss();
    pb.set_message("sharp views");
    for view in plan.views.iter().filter(|_| plan.sharp_spp.is_some()) {
        let k = plan.clock.frame_at(view.mid_ns).expect("views lie on frame times");
        let sharp_spp = plan.sharp_spp.unwrap_or(c.spp);
        let path = cache.sharp_path(sharp_spp, view.mid_ns);
        let (img, rendered) =
            cached_or_rendered(&renderer, &path, &render_settings(plan, &frame_poses[k], k, true), plan, &mut summary)?;
        if rendered {
            summary.sharp_rendered += 1;
            count_render(&mut summary)?;
        }
        pb.inc(sharp_spp as u64);
        let t = Instant::now();
        write_sharp(plan, out, view, &img)?;
        summary.exposure_time += t.elapsed();
    }

    summary.peak_rss[1] = peak_rss();

    // stage 5: metadata, manifest last
    reset_peak_rss();
    pb.set_message("metadata");
    let t = Instant::now();
    write_metadata(plan, out, &frame_poses, &frame_bounds, &summary)?;
    summary.metadata_time += t.elapsed();
    pb.finish_and_clear();
    if opts.frames_cache.is_none() && !opts.keep_frames {
        // renamed first, so that a run killed while deleting leaves a name the next run removes
        let removing = out.join(FRAMES_BEING_REMOVED);
        if std::fs::rename(&cache_root, &removing).is_ok() {
            let _ = std::fs::remove_dir_all(&removing); // best effort: the dataset is complete
        }
    }
    summary.peak_rss[2] = peak_rss();
    Ok(summary)
}

/// Delete the PNGs in `dir` that are not views of this dataset (left by an interrupted run with
/// more views), so that the folder never mixes two datasets.
fn remove_stale_images(dir: &Path, n_views: usize) -> Result<(), DatasetError> {
    let keep: std::collections::HashSet<String> = (0..n_views).map(|i| image_name(i, n_views)).collect();
    let entries = std::fs::read_dir(dir).map_err(|e| DatasetError::io(dir, "cannot list", e))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".png") && !keep.contains(&name) {
            std::fs::remove_file(entry.path())
                .map_err(|e| DatasetError::io(entry.path(), "cannot remove a stale image of an earlier run", e))?;
        }
    }
    Ok(())
}

/// The cached image at `path` (when it has the right size), else a fresh render of `settings`,
/// rounded to halves and cached; `true` when rendered. Adds the time to `summary`.
fn cached_or_rendered(
    renderer: &Renderer,
    path: &Path,
    settings: &RenderSettings,
    plan: &Plan,
    summary: &mut Summary,
) -> Result<(Image, bool), DatasetError> {
    let t = Instant::now();
    if let Some(img) = FrameCache::load(path)?.filter(|i| (i.width, i.height) == (settings.width, settings.height)) {
        summary.cache_read_time += t.elapsed();
        return Ok((img, false));
    }
    let (mut img, denoise_time) = render_frame(renderer, settings, plan);
    summary.denoise_time += denoise_time;
    round_to_f16(&mut img);
    FrameCache::store(path, &img)?;
    summary.render_time += t.elapsed();
    Ok((img, true))
}

/// Write the sharp image of `view`: `images_sharp_1/NN.png` and, for a sharp test view, also
/// `images_1/NN.png`.
pub(super) fn write_sharp(plan: &Plan, out: &Path, view: &ViewSpec, img: &Image) -> Result<(), DatasetError> {
    let name = image_name(view.id, plan.views.len());
    write_png(&out.join("images_sharp_1").join(&name), img, plan)?;
    if matches!(view.exposure, Exposure::Sharp) {
        write_png(&out.join("images_1").join(&name), img, plan)?;
    }
    Ok(())
}

/// Encode a linear view through the camera response (with the gain) and write it atomically.
pub(super) fn write_png(path: &Path, img: &Image, plan: &Plan) -> Result<(), DatasetError> {
    let bytes = plan
        .config
        .response
        .encode_png(img, plan.config.gain)
        .map_err(|e| DatasetError::stage(path.display(), format!("cannot encode PNG: {e}")))?;
    write_atomic(path, &bytes).map_err(io_stage(path))
}

/// Write `timestamps.npz`, the pose files, `transforms.json` and the manifest.
fn write_metadata(
    plan: &Plan,
    out: &Path,
    poses: &[Pose],
    frame_bounds: &[(f64, f64)],
    summary: &Summary,
) -> Result<(), DatasetError> {
    let c = &plan.config;
    let npy_err = |e: crate::npy::NpyError| DatasetError::stage("dataset metadata", e);
    let llff = |pose: Pose, (near, far): (f64, f64), what: String| {
        LlffCamera::new(pose, c.width, c.height, plan.yfov, near, far).map_err(|e| DatasetError::stage(what, e))
    };

    // the dense trajectory: every rendered frame
    let mut all_rows = Vec::with_capacity(poses.len());
    for (k, (&pose, &b)) in poses.iter().zip(frame_bounds).enumerate() {
        all_rows.push(llff(pose, b, format!("frame {k}"))?.to_row());
    }
    let all_t: Vec<f64> = (0..plan.clock.n_frames).map(|k| plan.clock.time_ns(k) as f64 / 1e3).collect();

    // the views: mid-exposure pose, bounds over the frames the exposure covers
    let mut rows = Vec::with_capacity(plan.views.len());
    let (mut mid, mut start, mut end) = (vec![], vec![], vec![]);
    for v in &plan.views {
        let weights = v.weights(&plan.clock).map_err(|e| DatasetError::stage(format!("view {}", v.id), e))?;
        let near = weights.iter().map(|&(k, _)| frame_bounds[k].0).fold(f64::INFINITY, f64::min);
        let far = weights.iter().map(|&(k, _)| frame_bounds[k].1).fold(0.0, f64::max);
        let k = plan.clock.frame_at(v.mid_ns).expect("views lie on frame times");
        rows.push(llff(poses[k], (near, far), format!("view {}", v.id))?.to_row());
        let (s, e) = v.window_us();
        mid.push(v.mid_ns as f64 / 1e3);
        start.push(s);
        end.push(e);
    }
    write_npz(
        &out.join("images_1/timestamps.npz"),
        &[
            ("timestamps", NpyArray::vector(mid)),
            ("timestamps_start", NpyArray::vector(start)),
            ("timestamps_end", NpyArray::vector(end)),
        ],
    )
    .map_err(npy_err)?;
    write_npy(&out.join("poses_bounds.npy"), &NpyArray::f64_2d(&rows)).map_err(npy_err)?;
    write_npy(&out.join("all_poses_bounds.npy"), &NpyArray::f64_2d(&all_rows)).map_err(npy_err)?;
    write_npy(&out.join("all_timestamps.npy"), &NpyArray::vector(all_t)).map_err(npy_err)?;

    let transforms = transforms_json(plan, poses);
    let path = out.join("transforms.json");
    write_atomic(&path, transforms.as_bytes()).map_err(io_stage(&path))?;

    let manifest = DatasetManifest {
        tool: "evsim".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        pipeline_version: PIPELINE_VERSION,
        scene: plan.scene_file.display().to_string(),
        scene_key: plan.scene_key.clone(),
        render_key: plan.render_key.clone(),
        settings_hash: plan.settings_hash.clone(),
        frames: plan.clock.n_frames,
        frame_period_ns: plan.clock.dt_ns,
        first_frame_ns: plan.clock.t0_ns,
        views: plan.views.len(),
        sharp_views: (0..plan.views.len()).filter(|&i| plan.is_sharp(i)).collect(),
        exposure_ns: plan.tau_ns,
        sharp_spp: plan.sharp_spp,
        yfov_deg: plan.yfov.to_degrees(),
        events: summary.events_on + summary.events_off,
        events_on: summary.events_on,
        events_off: summary.events_off,
        dataset: plan.config.clone(),
        event_model: plan.events.clone(),
        trajectory: plan.trajectory_config.clone(),
    };
    let text = manifest.to_toml().map_err(|e| DatasetError::stage("dataset.toml", e))?;
    let path = out.join("dataset.toml");
    write_atomic(&path, text.as_bytes()).map_err(io_stage(&path))
}

/// `transforms.json` (nerfstudio / instant-ngp): the sharp renders of every view
/// (`images_sharp_1/`), camera-to-world in the OpenGL convention (x right, y up, z backward,
/// as ours), pinhole intrinsics, and which views are test views.
fn transforms_json(plan: &Plan, poses: &[Pose]) -> String {
    let c = &plan.config;
    let (w, h) = (c.width as f64, c.height as f64);
    let focal = crate::trajectory::llff::focal_from_yfov(h, plan.yfov);
    let n = plan.views.len();
    let mut frames = Vec::new();
    let (mut train, mut test) = (vec![], vec![]);
    for v in &plan.views {
        let k = plan.clock.frame_at(v.mid_ns).expect("views lie on frame times");
        let m = glam::DMat4::from_rotation_translation(poses[k].rotation, poses[k].position);
        let rows: Vec<Vec<f64>> = (0..4).map(|r| (0..4).map(|col| m.col(col)[r]).collect()).collect();
        let file = format!("images_sharp_1/{}", image_name(v.id, n));
        if plan.is_sharp(v.id) { &mut test } else { &mut train }.push(serde_json::Value::from(file.clone()));
        frames.push(serde_json::json!({
            "file_path": file,
            "transform_matrix": rows,
            "time": v.mid_ns as f64 / 1e9,
        }));
    }
    let json = serde_json::json!({
        "camera_model": "OPENCV",
        "w": c.width,
        "h": c.height,
        "fl_x": focal,
        "fl_y": focal,
        "cx": w / 2.0,
        "cy": h / 2.0,
        "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
        "camera_angle_x": 2.0 * (w / (2.0 * focal)).atan(),
        "camera_angle_y": plan.yfov,
        "train_filenames": train,
        "test_filenames": test,
        "frames": frames,
    });
    serde_json::to_string_pretty(&json).expect("plain JSON") + "\n"
}
