//! Resolving a scene file plus overrides into a [`Plan`]: every setting checked, the frame
//! clock, the views and their times, and the content keys, before any rendering starts.
//!
//! View placement: view `i` has mid-time `t_i = t_start + first + i * spacing`, both rounded to
//! whole frames, with `first = max(50 ms, tau/2 + one frame)` and `spacing` filling the
//! trajectory up to the same margin before its last frame (unless given). Views are sharp when
//! `i % sharp_every == 0`.
//!
//! Keys (SHA-256, hex): the *scene key* hashes the loaded scene's content (geometry, materials,
//! texels, lights, environment); the *render key* adds everything
//! that changes a rendered pixel (resolution, camera FOV, trajectory, renderer settings); the
//! *settings hash* adds everything else (views, exposure, response, events). Frames are cached
//! under the render key, so exposure and event sweeps reuse them; a dataset folder whose
//! manifest has the same settings hash is already complete.

use std::path::{Path, PathBuf};

use serde::Serialize;
use sha2::{Digest, Sha256};

use super::description;
use super::settings::{DatasetConfig, Overrides};
use super::DatasetError;
use crate::events::EventConfig;
use crate::exposure::{duration_ns_from_ms, FrameClock, ViewSpec};
use crate::scene::description::FovAxis;
use crate::scene::{self, Scene};
use crate::trajectory::{frame_times, Trajectory, TrajectoryConfig};

/// Bumped whenever the renderer or the pipeline changes what a frame or file contains, so that
/// stale caches are never reused. 2: the filters leave directly seen light alone
/// (`Features::emission`), which changes every denoised frame. 3: the filters smooth
/// `Features::irradiance` (a per-sample ratio) and remodulate with reflectance from
/// `feature_spp` camera rays. 4: the temporal window weighs its frames equally (was a tent).
/// 5: camera rays' first triangles come from a rasterised visibility buffer (differs from
/// traced rays only within float error of edges). 6: the first-hit-only camera rays are grouped
/// by triangle (distance, normal and emission at each group's mean film point). 7-9: compact
/// sequence frames, grouping taken out. 10: grouping again, emission read per ray.
pub const PIPELINE_VERSION: u32 = 10;

/// Version of the surface-cache frames ([`super::Shading::SurfaceCache`]), in their render key
/// alone (path-traced frames keep theirs): 2 = grids over triangles in their plane, glossy
/// streams the same in every frame; 3 = glossy blocks sized by the lobe's width, glossy grids;
/// 4 = glossy paths trace on from their second vertex, one segment shorter (no extra bounce);
/// 5 = the texture footprint from unnormalised neighbour directions (rounding differs);
/// 6 = a pixel's diffuse samples share the directional lights' BSDF (rounding differs).
pub const SURFACE_VERSION: u32 = 6;

/// The surface-cache part of a render key: surface version, paths per point, spacing bits,
/// camera samples, glossy paths, glossy block, glossy stride, glossy-grid alpha bits.
type SurfaceKey = (u32, u32, u32, u32, u32, u32, u32, u32);

/// Everything a dataset run needs, resolved and checked.
#[derive(Debug)]
pub struct Plan {
    /// The scene description file (`scene.toml`).
    pub scene_file: PathBuf,
    /// The loaded scene.
    pub scene: Scene,
    /// `[dataset]` with the overrides applied.
    pub config: DatasetConfig,
    /// `[events]` with the overrides applied.
    pub events: EventConfig,
    /// `[trajectory]` as written.
    pub trajectory_config: TrajectoryConfig,
    /// The interpolating trajectory.
    pub trajectory: Trajectory,
    /// Full vertical field of view (rad) of the scene's camera.
    pub yfov: f64,
    /// Frame times (ns); frame `k` is at `clock.time_ns(k)`.
    pub clock: FrameClock,
    /// The views of `images_1/`, in order; `views[i].id == i`.
    pub views: Vec<ViewSpec>,
    /// Exposure `tau` (ns).
    pub tau_ns: i64,
    /// Samples per pixel of separate sharp renders (`[dataset] sharp_spp`); `None`: the sharp
    /// images are the sequence's own frames at the views' mid-times.
    pub sharp_spp: Option<u32>,
    /// SHA-256 of the scene folder's files.
    pub scene_key: String,
    /// SHA-256 of what determines the rendered frames.
    pub render_key: String,
    /// SHA-256 of every setting.
    pub settings_hash: String,
    /// Camera position of every frame of the sequence.
    pub camera_path: std::sync::Arc<Vec<glam::Vec3>>,
}

/// The part of the plan that determines rendered pixels (hashed into the render key).
#[derive(Serialize)]
struct RenderIdentity<'a> {
    pipeline_version: u32,
    scene_key: &'a str,
    width: u32,
    height: u32,
    yfov_bits: u64,
    max_depth: u32,
    seed: u64,
    sampler: crate::render::sampler::SamplerKind,
    clamp_bits: u32,
    light_samples: u32,
    /// Adaptive sampling (most samples, target variance bits); only written when on, so that
    /// the keys of frames without it are those of earlier versions.
    #[serde(skip_serializing_if = "Option::is_none")]
    adaptive: Option<(u32, u64)>,
    /// Only written when on, so that the keys of undenoised frames are those of earlier versions.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    denoise: bool,
    /// Only written when it shapes the frames (denoising on, radius > 0).
    #[serde(skip_serializing_if = "is_zero")]
    temporal_radius: u32,
    /// Only written when it shapes the frames (a window reading every `stride`-th frame, 2 or
    /// more), so that the keys of frames reading every frame are those of earlier versions.
    #[serde(skip_serializing_if = "Option::is_none")]
    temporal_stride: Option<u32>,
    /// Only written when it shapes the frames (denoising on, more rays than `spp`).
    #[serde(skip_serializing_if = "is_zero")]
    feature_spp: u32,
    /// Only written when on, so that the keys of frames without it are those of earlier versions.
    #[serde(skip_serializing_if = "is_zero")]
    texture_filter_bits: u32,
    /// Only written when on, as `texture_filter_bits`.
    #[serde(skip_serializing_if = "is_zero")]
    radiance_cache: u32,
    /// Only written when not the default 2 (with the cache on), as `texture_filter_bits`.
    #[serde(skip_serializing_if = "Option::is_none")]
    cache_vertex: Option<u32>,
    /// Only written for surface-cache frames (surface version, paths per point, spacing bits,
    /// camera samples, glossy paths, glossy block, glossy stride, glossy-grid alpha bits), so
    /// that the keys of path-traced frames are those of earlier versions.
    #[serde(skip_serializing_if = "Option::is_none")]
    surface: Option<SurfaceKey>,
    bvh: crate::render::accel::BvhPreset,
    trajectory: &'a TrajectoryConfig,
}

/// Everything (hashed into the settings hash).
#[derive(Serialize)]
struct FullIdentity<'a> {
    render_key: &'a str,
    dataset: &'a DatasetConfig,
    events: &'a EventConfig,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// Feeds f32 values into a hash in blocks (one `update` per 16 K values).
fn hash_f32s(h: &mut Sha256, values: impl Iterator<Item = f32>) {
    let mut buf = Vec::with_capacity(1 << 16);
    for v in values {
        buf.extend_from_slice(&v.to_le_bytes());
        if buf.len() == buf.capacity() {
            h.update(&buf);
            buf.clear();
        }
    }
    h.update(&buf);
}

/// SHA-256 of the loaded scene's content: triangles, normals, UVs, materials, texture texels,
/// punctual lights and the environment (cameras excluded: the trajectory places the camera).
/// Hashing what was loaded, rather than files, catches every referenced file (meshes,
/// textures, maps) and ignores unrelated ones.
pub fn scene_key(scene: &Scene) -> String {
    let mut h = Sha256::new();
    let m = &scene.mesh;
    h.update((m.positions.len() as u64).to_le_bytes());
    hash_f32s(&mut h, m.positions.iter().chain(&m.normals).flat_map(|v| v.to_array()));
    hash_f32s(&mut h, m.uvs.iter().flat_map(|v| v.to_array()));
    h.update((m.indices.len() as u64).to_le_bytes());
    let ints: Vec<u8> = m.indices.iter().flatten().chain(&m.material).flat_map(|i| i.to_le_bytes()).collect();
    h.update(&ints);
    // small parts: their Debug text (f32 Debug output is exact)
    h.update(format!("{:?}{:?}", scene.materials, scene.lights).as_bytes());
    for t in &scene.textures {
        h.update(format!("{}x{} {:?} {:?}", t.width, t.height, t.wrap_u, t.wrap_v).as_bytes());
        hash_f32s(&mut h, t.texels.iter().flat_map(|v| v.to_array()));
    }
    match &scene.environment {
        crate::scene::Environment::Map(map) => {
            h.update(format!("map {}x{} {:?} {:?}", map.width, map.height, map.scale, map.to_world).as_bytes());
            hash_f32s(&mut h, map.texels.iter().flat_map(|v| v.to_array()));
        }
        other => h.update(format!("{other:?}").as_bytes()),
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

impl Plan {
    /// Read `scene_file` (a `.toml` scene description with `[trajectory]` and optional
    /// `[dataset]` / `[events]` tables), apply `overrides`, check everything and load the scene.
    /// A folder stands for its `scene.toml` (`evsim dataset scenes/cbox`).
    pub fn resolve(scene_file: &Path, overrides: &Overrides) -> Result<Plan, DatasetError> {
        let folder_file;
        let scene_file = if scene_file.is_dir() {
            folder_file = scene_file.join("scene.toml");
            folder_file.as_path()
        } else {
            scene_file
        };
        let text = std::fs::read_to_string(scene_file)
            .map_err(|e| DatasetError::io(scene_file, "cannot read the scene file", e))?;
        let bad = |field: &str, message: String| DatasetError::config(scene_file, field, message);
        overrides.validate().map_err(|(field, message)| bad(&field, message))?;
        // the [dataset] keys and `set` on the file's TOML; the shorthands below, once it is read
        let sets = overrides.sets();
        let desc = if sets.is_empty() {
            description::parse(&text, scene_file)?
        } else {
            description::parse_with_sets(&text, scene_file, &sets)?
        };
        let trajectory_config = desc.trajectory.as_ref().map(|t| overrides.apply_speed(t)).ok_or_else(|| {
            bad(
                "trajectory",
                "missing: a dataset needs a camera path; add a [trajectory] table, e.g. type = \"fast_motion\", \
                 target = [0.0, 0.0, 0.0], radius = 4.0 (see simulator::trajectory)"
                    .into(),
            )
        })?;
        let config = desc.dataset.clone().unwrap_or_default();
        let mut events = desc.events.clone().unwrap_or_default();
        overrides.apply_events(&mut events);
        validate(&config, &events, scene_file)?;

        let trajectory = trajectory_config.resolve().map_err(|e| bad("trajectory", e.to_string()))?;
        if trajectory.start_ns() < 0 {
            return Err(bad(
                "trajectory",
                "starts before t = 0 s; the dataset's timestamps must be positive, so shift the keys' times".into(),
            ));
        }
        let times = frame_times(config.fps, trajectory.start_ns(), trajectory.end_ns())
            .map_err(|e| bad("dataset.fps", e.to_string()))?;
        let n_frames = times.times_ns.len();
        let dt_ns = (1e9 / config.fps).round() as i64;
        if times.times_ns.windows(2).any(|w| w[1] - w[0] != dt_ns) {
            return Err(bad(
                "dataset.fps",
                format!(
                    "{} FPS does not give a whole number of nanoseconds per frame; use e.g. 1000 or 500",
                    config.fps
                ),
            ));
        }
        let clock =
            FrameClock::new(times.times_ns[0], dt_ns, n_frames).map_err(|e| bad("dataset.fps", e.to_string()))?;
        let tau_ns = duration_ns_from_ms("dataset.exposure_ms", config.exposure_ms)
            .map_err(|e| bad("dataset.exposure_ms", e.to_string()))?;
        let views = place_views(&config, &clock, tau_ns).map_err(|(field, m)| bad(field, m))?;

        // the camera: the description's [camera] (or the mesh file's first camera) gives the FOV
        if let Some(cam) = &desc.camera {
            if let (FovAxis::X, Some(aspect)) = (cam.fov_axis, cam.aspect) {
                let want = config.width as f32 / config.height as f32;
                if (aspect - want).abs() > 1e-3 * want {
                    return Err(bad(
                        "camera.aspect",
                        format!(
                            "{aspect} differs from the dataset's width / height = {want}; set aspect = {want} \
                             (or give the FOV with fov_axis = \"y\")"
                        ),
                    ));
                }
            }
        }
        let scene = scene::load(scene_file)?;
        let yfov = scene.cameras.first().map(|c| c.yfov as f64).ok_or_else(|| {
            bad("camera", "missing: the field of view comes from the camera; add a [camera] table with fov".into())
        })?;

        let scene_key = scene_key(&scene);
        let render_key = sha256_hex(
            toml::to_string(&RenderIdentity {
                pipeline_version: PIPELINE_VERSION,
                scene_key: &scene_key,
                width: config.width,
                height: config.height,
                yfov_bits: yfov.to_bits(),
                max_depth: config.max_depth,
                seed: config.seed,
                sampler: config.sampler,
                clamp_bits: config.clamp.to_bits(),
                light_samples: config.light_samples,
                adaptive: (config.denoise && config.spp_max > config.spp)
                    .then(|| (config.spp_max, config.adaptive_variance.to_bits())),
                denoise: config.denoise,
                temporal_radius: if config.denoise { config.temporal_radius } else { 0 },
                temporal_stride: (config.denoise && config.window_stride() > 1).then_some(config.window_stride()),
                feature_spp: if config.denoise && config.feature_spp > config.spp { config.feature_spp } else { 0 },
                texture_filter_bits: config.texture_filter.to_bits(),
                radiance_cache: config.radiance_cache,
                cache_vertex: (config.radiance_cache > 0 && config.cache_vertex != 2).then_some(config.cache_vertex),
                surface: (config.shading == super::Shading::SurfaceCache).then_some((
                    SURFACE_VERSION,
                    config.surface_paths,
                    config.surface_spacing.to_bits(),
                    config.feature_spp,
                    config.glossy_paths,
                    config.glossy_block,
                    config.glossy_stride,
                    config.glossy_grid_alpha.to_bits(),
                )),
                bvh: config.bvh,
                trajectory: &trajectory_config,
            })
            .expect("plain data serialises")
            .as_bytes(),
        );
        let settings_hash = sha256_hex(
            toml::to_string(&FullIdentity { render_key: &render_key, dataset: &config, events: &events })
                .expect("plain data serialises")
                .as_bytes(),
        );
        let sharp_spp = config.sharp_spp;
        let camera_path = (0..clock.n_frames)
            .map(|k| trajectory.pose_at(clock.time_ns(k)).map(|p| p.camera(yfov as f32).origin()))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| DatasetError::stage("trajectory", e))?;
        Ok(Plan {
            scene_file: scene_file.to_path_buf(),
            scene,
            config,
            events,
            trajectory_config,
            trajectory,
            yfov,
            clock,
            views,
            tau_ns,
            sharp_spp,
            scene_key,
            render_key,
            settings_hash,
            camera_path: std::sync::Arc::new(camera_path),
        })
    }

    /// Where the sharp images come from, for messages: "the sequence frames" or "N spp renders".
    pub fn sharp_source(&self) -> String {
        match self.sharp_spp {
            None => "the sequence frames".into(),
            Some(spp) => format!("{spp} spp renders"),
        }
    }

    /// Whether view `i` is a sharp test view.
    pub fn is_sharp(&self, i: usize) -> bool {
        matches!(self.views[i].exposure, crate::exposure::Exposure::Sharp)
    }
}

/// Range checks with the field's name.
fn validate(d: &DatasetConfig, ev: &EventConfig, file: &Path) -> Result<(), DatasetError> {
    let bad = |field: &str, message: String| Err(DatasetError::config(file, field, message));
    if d.width == 0 || d.height == 0 || d.width > 16384 || d.height > 16384 {
        return bad("dataset.width/height", format!("{}x{} must be 1..=16384 pixels each", d.width, d.height));
    }
    if !(d.fps > 0.0 && d.fps.is_finite()) {
        return bad("dataset.fps", format!("{} must be a positive frame rate (frames per second)", d.fps));
    }
    if !(d.exposure_ms > 0.0 && d.exposure_ms.is_finite()) {
        return bad("dataset.exposure_ms", format!("{} must be a positive time in milliseconds", d.exposure_ms));
    }
    if d.views < 2 {
        return bad("dataset.views", format!("{} must be at least 2", d.views));
    }
    if d.sharp_every != 8 {
        return bad(
            "dataset.sharp_every",
            format!(
                "{} writes a marking the Ev-DeblurNeRF loader cannot read: it takes every 8th view (0, 8, 16, ...) \
                 as a sharp test view (llffhold = 8), and evsim check and evtrain follow it; set 8",
                d.sharp_every
            ),
        );
    }
    for (field, v) in [("dataset.first_view_ms", d.first_view_ms), ("dataset.spacing_ms", d.spacing_ms)] {
        if let Some(v) = v {
            if !(v > 0.0 && v.is_finite()) {
                return bad(field, format!("{v} must be a positive time in milliseconds"));
            }
        }
    }
    if d.spp == 0 {
        return bad("dataset.spp", "0 must be at least 1 sample per pixel".into());
    }
    if let Some(s) = d.sharp_spp {
        if s < d.spp {
            return bad("dataset.sharp_spp", format!("{s} must be at least spp = {}", d.spp));
        }
    }
    if d.max_depth == 0 {
        return bad("dataset.max_depth", "0 must be at least 1 path segment".into());
    }
    if d.temporal_radius as usize > crate::render::temporal::MAX_RADIUS {
        return bad(
            "dataset.temporal_radius",
            format!("{} must be at most {} frames", d.temporal_radius, crate::render::temporal::MAX_RADIUS),
        );
    }
    if !(1..=crate::render::temporal::MAX_RADIUS as u32).contains(&d.temporal_stride) {
        return bad(
            "dataset.temporal_stride",
            format!(
                "{} must be 1..={} (the temporal window reads every stride-th frame; 1 = all)",
                d.temporal_stride,
                crate::render::temporal::MAX_RADIUS
            ),
        );
    }
    if d.feature_spp > 4096 {
        return bad("dataset.feature_spp", format!("{} must be at most 4096 camera rays per pixel", d.feature_spp));
    }
    if !(d.texture_filter >= 0.0 && d.texture_filter <= 16.0) {
        return bad(
            "dataset.texture_filter",
            format!("{} must be a footprint of 0..=16 pixels (0 turns texture filtering off)", d.texture_filter),
        );
    }
    if d.radiance_cache > 1024 {
        return bad(
            "dataset.radiance_cache",
            format!("{} must be at most 1024 paths per cache point (0 turns the cache off)", d.radiance_cache),
        );
    }
    if d.surface_paths == 0 {
        return bad("dataset.surface_paths", "0 must be at least 1 (paths per surface-cache point)".into());
    }
    if !(1..=16).contains(&d.glossy_block) {
        return bad(
            "dataset.glossy_block",
            format!("{} must be 1..=16 (pixels on a side of the blocks sharing glossy paths)", d.glossy_block),
        );
    }
    if d.glossy_stride > 100_000 {
        return bad(
            "dataset.glossy_stride",
            format!("{} must be at most 100000 (frames between glossy keyframes; 0 = none)", d.glossy_stride),
        );
    }
    if !(0.0..=1.0).contains(&d.glossy_grid_alpha) {
        return bad(
            "dataset.glossy_grid_alpha",
            format!(
                "{} must be a GGX alpha in 0..=1 (glossy lobes from it read the glossy grids; default 0.1)",
                d.glossy_grid_alpha
            ),
        );
    }
    if d.glossy_paths == 0 {
        return bad("dataset.glossy_paths", "0 must be at least 1 (paths per camera sample on glossy surfaces)".into());
    }
    if !(d.surface_spacing >= 0.0 && d.surface_spacing.is_finite()) {
        return bad(
            "dataset.surface_spacing",
            format!("{} must be a length >= 0 in world units (0 = the scene's diagonal over 512)", d.surface_spacing),
        );
    }
    if !(1..=2).contains(&d.cache_vertex) {
        return bad(
            "dataset.cache_vertex",
            format!("{} must be 1 or 2 (the camera-path vertex the radiance cache serves)", d.cache_vertex),
        );
    }
    if d.spp_max > 4096 {
        return bad("dataset.spp_max", format!("{} must be at most 4096 samples per pixel (0 = off)", d.spp_max));
    }
    if d.spp_max != 0 && d.spp_max < d.spp {
        return bad(
            "dataset.spp_max",
            format!("{} is below spp = {}; the adaptive budget must be at least spp (or 0 = off)", d.spp_max, d.spp),
        );
    }
    if !(d.adaptive_variance > 0.0 && d.adaptive_variance.is_finite()) {
        return bad(
            "dataset.adaptive_variance",
            format!("{} must be a positive relative variance (smaller = more samples)", d.adaptive_variance),
        );
    }
    if d.light_samples == 0 || d.light_samples > 64 {
        return bad("dataset.light_samples", format!("{} must be 1..=64", d.light_samples));
    }
    if !(d.clamp >= 0.0 && d.clamp.is_finite()) {
        return bad("dataset.clamp", format!("{} must be >= 0 (0 turns clamping off)", d.clamp));
    }
    if !(d.gain > 0.0 && d.gain.is_finite()) {
        return bad("dataset.gain", format!("{} must be a positive finite factor", d.gain));
    }
    d.response.validate().map_err(|e| DatasetError::config(file, "dataset.response", e.to_string()))?;
    ev.validate().map_err(|e| DatasetError::config(file, "events", e.to_string()))?;
    Ok(())
}

/// View mid-times on frame times (see the module doc); errors name the field to change.
fn place_views(d: &DatasetConfig, clock: &FrameClock, tau_ns: i64) -> Result<Vec<ViewSpec>, (&'static str, String)> {
    let dt = clock.dt_ns;
    let n_frames = clock.n_frames as i64;
    let frames_of = |ms: f64| (ms * 1e6 / dt as f64).round() as i64;
    // half the exposure in frames, rounded up, plus one frame of margin
    let half = (tau_ns + 2 * dt - 1) / (2 * dt) + 1;
    let first = match d.first_view_ms {
        Some(ms) => frames_of(ms),
        None => frames_of(50.0).max(half),
    };
    if first < half {
        return Err((
            "dataset.first_view_ms",
            format!(
                "view 0's exposure would start before the trajectory (or at time 0); use at least {} ms",
                half as f64 * dt as f64 / 1e6
            ),
        ));
    }
    let n = d.views as i64;
    let last_allowed = n_frames - 1 - first.max(half); // same margin at the end
    let spacing = match d.spacing_ms {
        Some(ms) => frames_of(ms),
        None => (last_allowed - first) / (n - 1),
    };
    if spacing < 1 || first + (n - 1) * spacing > n_frames - 1 - half {
        let span_ms = n_frames as f64 * dt as f64 / 1e6;
        return Err((
            "dataset.views",
            format!(
                "{n} views{} with {} ms exposures do not fit in the {span_ms} ms trajectory; use fewer views, a \
                 shorter exposure or spacing, or a longer trajectory",
                d.spacing_ms.map(|s| format!(" {s} ms apart")).unwrap_or_default(),
                d.exposure_ms
            ),
        ));
    }
    let views = (0..n as usize)
        .map(|i| {
            let t = clock.time_ns((first + i as i64 * spacing) as usize);
            if d.sharp_every > 0 && i % d.sharp_every as usize == 0 {
                ViewSpec::sharp(i, t)
            } else {
                ViewSpec::blurry(i, t, tau_ns)
            }
        })
        .collect();
    Ok(views)
}
