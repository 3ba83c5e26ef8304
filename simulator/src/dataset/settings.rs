//! The `[dataset]` table of `scenes/<name>/scene.toml`: what to render, how to expose it and
//! where the views lie. Every field has a default (the paper's settings where it gives them; the
//! sampling defaults are chosen with `evsim dataset-noise`); unknown keys are errors.
//!
//! ```toml
//! [dataset]
//! width = 600              # pixels
//! height = 400             # pixels
//! fps = 1000.0             # rendered frames per second
//! exposure_ms = 40.0       # shutter time of the blurry views (ms)
//! views = 30               # images in images_1/
//! sharp_every = 8          # views 0, 8, 16, ... are sharp test views (llffhold = 8)
//! spp = 2                  # samples per pixel of every 1000 FPS frame
//! spp_max = 0              # adaptive sampling: noisy pixels get up to this many (0 = off)
//! adaptive_variance = 0.1  # with spp_max: the relative variance a pixel's estimate aims at
//! # sharp_spp = 32         # render the sharp images separately at this spp (default: they
//!                          # are the sequence's own frames at the views' mid-times)
//! seed = 0                 # renderer seed
//! denoise = true           # feature-guided denoising of every rendered frame
//! temporal_radius = 32     # with denoise: frames on each side reprojected into each frame
//! temporal_stride = 2      # the window reads every this many frames of them
//! feature_spp = 32         # with denoise: camera rays per pixel for the filters' guides
//! texture_filter = 0.0     # camera rays filter textures over this many pixels (0 = off)
//! radiance_cache = 32      # paths per point of the radiance cache ending paths at the
//!                          # second bounce (0 = off: full paths)
//! cache_vertex = 1         # the path vertex the cache serves: 1 (shadow rays only) or 2
//! shading = "surface_cache" # frames read one converged surface cache (or "path_traced":
//!                          # spp paths per pixel, filtered as denoise says)
//! surface_paths = 64       # with surface_cache: paths per cache point
//! surface_spacing = 0.0    # with surface_cache: cache lattice spacing (0 = diagonal / 512)
//! glossy_paths = 64        # with surface_cache: paths per glossy triangle and pixel block
//! glossy_block = 1         # with surface_cache: pixels on a side of those blocks
//! glossy_stride = 32       # with surface_cache: frames between glossy-grid keyframes
//! glossy_grid_alpha = 0.1  # with surface_cache: GGX alpha from which glossy lobes read them
//! response = { type = "gamma", gamma = 2.2 }
//! ```
//!
//! [`Overrides`] (`evsim --set`, a benchmark matrix's `dataset = {...}` tables) are applied on top
//! before anything is resolved.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::events::config::{Refractory, ThresholdMismatch};
use crate::exposure::CameraResponse;
use crate::render::accel::BvhPreset;
use crate::render::sampler::SamplerKind;
use crate::trajectory::TrajectoryConfig;

/// Where a frame's random numbers come from, frame to frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum NoisePattern {
    /// Every frame reuses the same per-pixel random numbers, so path-tracing noise is a fixed
    /// pattern on the sensor and only changes where the image content changes: far fewer
    /// noise-induced events (see `evsim dataset-noise`).
    #[default]
    Fixed,
    /// Every frame draws new random numbers (noise flickers from frame to frame).
    PerFrame,
}

/// How the frames of a sequence are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shading {
    /// The default. Every frame reads one converged estimate of the light surfaces reflect,
    /// computed once per dataset ([`crate::render::integrator::surface`]): `max(feature_spp,
    /// spp)` camera samples per pixel (sharp renders: `max(feature_spp, sharp_spp)`), delta
    /// lights from shadow grids, rough glossy lobes from the glossy grids of keyframes every
    /// `glossy_stride` frames, sharper ones traced (`glossy_paths`); no image filter. Its
    /// events follow a converged reference far better than the path-traced frames' (factory
    /// at 600x400: event-pair r2 0.944 of the two-reference ceiling; `docs/fidelity.md`).
    #[default]
    SurfaceCache,
    /// Every frame is path traced at `spp` (with the radiance cache, the temporal window and
    /// the spatial filter as `radiance_cache`, `temporal_radius` and `denoise` say): the
    /// pipeline before the surface cache, kept for comparisons.
    PathTraced,
}

/// The `[dataset]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DatasetConfig {
    /// Image width (pixels, >= 1).
    pub width: u32,
    /// Image height (pixels, >= 1).
    pub height: u32,
    /// Rendered frames per second (Hz, > 0); the paper renders at 1000.
    pub fps: f64,
    /// Exposure time `tau` of the blurry views (ms, > 0).
    pub exposure_ms: f64,
    /// Number of images in `images_1/` (>= 2).
    pub views: u32,
    /// Every `sharp_every`-th view (index 0, n, 2n, ...) is a sharp test view; only 8 is
    /// accepted, the Ev-DeblurNeRF loader's `llffhold`.
    pub sharp_every: u32,
    /// Time from the trajectory's start to the mid-time of view 0 (ms); default
    /// `max(50, exposure_ms / 2 + one frame)`, so that exposure sweeps up to ~100 ms keep the
    /// same view times.
    pub first_view_ms: Option<f64>,
    /// Time between consecutive view mid-times (ms); default: the views spread evenly from
    /// `first_view_ms` to the same margin before the trajectory's end. Rounded to whole frames.
    pub spacing_ms: Option<f64>,
    /// Samples per pixel of every rendered frame (>= 1; with adaptive sampling, `spp_max`, the
    /// fewest a pixel gets). The default 2, with `feature_spp` 32, `temporal_radius` 32 and
    /// `radiance_cache` 32 at `cache_vertex` 1, keeps noise-induced events below 5% in
    /// `evsim dataset-noise` (factory: 4.26% against the 32-spp reference at `temporal_stride`
    /// 2; at stride 1, 4.08%, and 4.53% against a 96-spp one). With the cache at the second vertex it took 6 (4.70%; 4 spp: 5.26%).
    pub spp: u32,
    /// Adaptive sampling (0 or at most `spp` = off; with `denoise`, the default): every pixel of
    /// a sequence frame first takes `spp` samples; pixels whose estimate is still noisy then take more, up to
    /// `spp_max` in all (see `adaptive_variance`). Dark and mixed pixels (an edge between
    /// differently lit surfaces) need many samples, most pixels few: measured with
    /// `evsim dataset-noise` on `scenes/factory` at 300x200, radius 16, against the same 96 spp
    /// reference, 2..=8 samples (5.2 on average) fire fewer noise-induced events (9.41%) than 6
    /// everywhere (9.76%); at 600x400, radius 32 (`spp = 2`, `spp_max = 8`, 5.07 on average):
    /// 4.62% against 4.70%. Off by default because it saves no time: the pixels that get more
    /// samples are the expensive ones (cluttered, dark, edges), and the extra samples are
    /// shot after the whole frame's first ones, with colder caches, so 5.07 samples on average
    /// cost as much as 6 everywhere (`evsim bench frames`: shading 1.41 / 1.36 s against 1.22 /
    /// 1.33 s). The sharp renders of `sharp_spp` are not adaptive.
    pub spp_max: u32,
    /// With `spp_max`: the relative variance (variance over squared mean) of a pixel's reflected
    /// light that its samples aim at (> 0). A pixel takes `ceil(v / adaptive_variance)` samples
    /// (within `spp..=spp_max`), `v` being the relative variance of one sample's estimate,
    /// measured on the first `spp` samples and averaged over the pixel's 3x3 neighbourhood.
    /// Smaller = more samples.
    pub adaptive_variance: f64,
    /// The sharp images (test views and `images_sharp_1/`). Default (unset): the sequence's own
    /// frames at the views' mid-times, filtered as every frame is: no extra render, and exactly
    /// the frames the blurry views average and the events see. Set: a separate render at each
    /// mid-time with this many samples per pixel (at least `spp`; spatial filter only, since a
    /// single instant has no temporal window).
    pub sharp_spp: Option<u32>,
    /// Maximum path segments (Mitsuba's convention; 2 = direct light only).
    pub max_depth: u32,
    /// Renderer seed (the event seed is in `[events]`).
    pub seed: u64,
    /// The renderer's sample generator.
    pub sampler: SamplerKind,
    /// Fixed or per-frame noise pattern.
    pub noise_pattern: NoisePattern,
    /// BVH build preset.
    pub bvh: BvhPreset,
    /// Camera response applied after exposure averaging (default gamma 2.2).
    pub response: CameraResponse,
    /// Linear gain applied before the response (unitless, > 0): an exposure compensation.
    pub gain: f32,
    /// Sample clamping: the largest channel of one path's contribution, except emitters seen
    /// directly (radiance units; 0 = off). Removes fireflies that flicker between frames and fire
    /// false events, at the cost of darkening rare very bright paths (see `evsim dataset-noise`).
    pub clamp: f32,
    /// Light samples per path vertex (>= 1): splitting the direct-light estimate lowers its noise
    /// (sky visibility, the choice among area lights) at the cost of one shadow ray each.
    pub light_samples: u32,
    /// Filter every rendered frame (sequence frames and sharp renders) with the feature-guided
    /// À-Trous denoiser ([`crate::render::denoise`]) before anything else sees it: far fewer
    /// events fired by path-tracing noise at the same spp (see `evsim dataset-noise`).
    pub denoise: bool,
    /// With `denoise`: frames on each side whose lighting is reprojected into each sequence frame
    /// before the spatial filter ([`crate::render::temporal`]; 0 = spatial filter only, at most
    /// [`crate::render::temporal::MAX_RADIUS`]). Separate sharp renders (`sharp_spp`) are single
    /// instants and get the spatial filter only. Memory at 600x400: the `radius + 1` frames from
    /// the current one on with their buffers (about 11 MB each) and the `radius` before it
    /// reduced to the records the window reads (about 6.7 MB each): about 0.6 GB at radius 32.
    pub temporal_radius: u32,
    /// With `temporal_radius`: the window reads every `temporal_stride`-th frame on each side
    /// (1 = every frame; at least 1; a stride beyond the radius reads the frames `radius` away,
    /// see [`DatasetConfig::window_stride`]). The window still spans `radius` frames, at
    /// `1/stride` of the reads: while the camera moves under a pixel per frame, neighbouring
    /// frames see a surface point through nearly the same pixel and sample pattern, so
    /// skipping them loses little of the averaging. Measured on `scenes/factory` (600x400,
    /// radius 32, `evsim dataset-noise`, 30 frames against the 32-spp reference): noise-induced
    /// events 4.08% at stride 1, 4.26% at 2 (the default), 4.71% at 4; the window's time per
    /// frame halves with each doubling (`evsim bench frames`: 0.27-0.29 s at 1, 0.14-0.17 s at 2).
    pub temporal_stride: u32,
    /// With `denoise`: camera rays per pixel for the filters' guide buffers (reflectance, directly
    /// seen emission, depth, normal); the first `spp` are shaded paths, the others stop at their
    /// first hit (one ray each, no shading). The filtered frame takes its texture and edges from
    /// these, its lighting from the shaded paths: texture and edges stay steady as the camera
    /// moves at a fraction of the cost of more paths. Values up to `spp` mean `spp`.
    pub feature_spp: u32,
    /// Texture filtering at camera-ray hits (pixels, 0..=16; 0 = off, the default): every camera
    /// ray reads its textures averaged over the footprint of this many pixels on the film
    /// (mip-mapped, anisotropic), so texture detail finer than that neither aliases nor flickers
    /// as the camera moves. It blurs textures (1 pixel: visibly) and, measured with
    /// `evsim dataset-noise`-style counts on `scenes/factory` (8 spp, radius 32), pays only at
    /// few `feature_spp` rays: noise-induced events 7.7% -> 6.4% at 8 rays, 5.3% -> 5.1% at 16,
    /// 4.5% -> 4.6% at 32 (footprint 1 pixel); hence off by default.
    pub texture_filter: f32,
    /// Radiance cache (paths per lattice point, 0..=1024; default 32; 0 = off): paths end at
    /// their second surface vertex, which reads the light it reflects from a world-space cache
    /// computed once per sequence ([`crate::render::radiance_cache`]). Faster (a path is a
    /// shadow ray and one bounce ray) and steadier (what lies beyond the second bounce is the
    /// same in every frame: factory at 4 spp, noise-induced events 6.0% -> 5.3%) but
    /// approximate: surfaces beyond the first bounce count as diffuse (factory, 64 spp: mean 1%
    /// darker than full paths).
    pub radiance_cache: u32,
    /// With `radiance_cache`: the camera-path vertex the cache serves, 1 (default) or 2. At 1 a
    /// camera sample on a mostly diffuse surface traces only the shadow rays of its direct light
    /// from delta lights and emissive triangles; the environment and the light arriving via
    /// other surfaces come from a cache of indirect light at the first vertex
    /// ([`crate::render::radiance_cache`]); glossy and metal surfaces keep their bounce ray. At
    /// 2 every camera sample also traces a bounce ray, whose second vertex reads the cache.
    /// Measured on `scenes/factory` (`evsim dataset-noise` at 300x200, radius 16, 10 frames,
    /// against one 96-spp reference each): 6 spp fire 9.76% noise-induced events at 2, and
    /// 3 spp 9.98% at 1; `evsim bench frames`, side by side: shading 1.31 s per frame at 2 and
    /// 6 spp, 0.77 s at 1 and 3 spp, 0.65 s at 1 and 2 spp. The price: the indirect light is
    /// blurred to the lattice's spacing and mostly diffuse surfaces lose their glossy reflections
    /// of other surfaces (factory, 256 spp, against full paths: 33.9 dB PSNR, 36.6 dB at 2).
    pub cache_vertex: u32,
    /// How frames are made: `surface_cache` or `path_traced` (see [`Shading`]).
    pub shading: Shading,
    /// With `shading = "surface_cache"`: paths per point of the surface cache (count, >= 1).
    /// Factory at 150x100 (`evsim dataset-fidelity`): event-pair r2 0.746 at 256, 0.742 at 64,
    /// 0.714 at 16; the cache fills in a quarter of the time at 64.
    pub surface_paths: u32,
    /// With `shading = "surface_cache"`: largest cell side of the surface cache's grids (world
    /// units; 0 = the scene's bounding-box diagonal over 512).
    pub surface_spacing: f32,
    /// With `shading = "surface_cache"`: paths per glossy-grid point (`glossy_stride` > 0,
    /// lobes of GGX alpha >= 0.1), and per triangle and block of pixels (`glossy_block`) on
    /// the glossy surfaces that trace their reflection in every frame (count, >= 1; the same
    /// random numbers at a pixel in every frame). Factory at 300x200, stride 8: pairs 0.955 of
    /// the ceiling at 64, 0.957 at 128.
    pub glossy_paths: u32,
    /// With `shading = "surface_cache"`: pixels on a side of the blocks whose traced glossy
    /// samples share their `glossy_paths` paths (1..=16): the whole block for rough lobes
    /// (alpha >= 0.2), half of it for medium ones, one pixel for sharp ones (alpha < 0.05;
    /// with `glossy_stride` > 0 only lobes below `glossy_grid_alpha` are traced). Factory at
    /// 300x200 with traced
    /// glossy paths (`glossy_stride = 0`): pairs 0.926 of the ceiling at 1, 0.898 at 4.
    pub glossy_block: u32,
    /// With `shading = "surface_cache"`: frames between the keyframes of the camera path whose
    /// glossy grids rough glossy lobes (GGX alpha >= 0.1) read (0 = none: every glossy sample
    /// traces its paths; at most 100000). Per keyframe and visible glossy triangle side, a
    /// grid at the surface cache's spacing holds the light reflected towards that keyframe's
    /// camera from `glossy_paths` paths per point; a frame blends the two keyframes around it.
    /// Factory at 300x200 (`evsim dataset-fidelity`, pairs / 1 ms / 4 ms of the ceiling):
    /// 0.954 / 0.973 / 0.975 at 4, 0.955 / 0.974 / 0.975 at 8, 0.955 / 0.973 / 0.975 at 16,
    /// 0.955 / 0.974 / 0.975 at 32 (the default); 0.926 / 0.954 / 0.975 with traced paths (0). A keyframe costs about what one frame's
    /// traced glossy paths did.
    pub glossy_stride: u32,
    /// With `shading = "surface_cache"` and `glossy_stride` > 0: the GGX alpha from which
    /// glossy lobes read the glossy grids (0..=1, default 0.1); sharper lobes trace
    /// `glossy_paths` paths in every frame, which costs: factory 600x400 (dielectric highlights
    /// at grazing angles, alpha 0.06 to 0.09) takes about 2.1 s a frame at 0.1 and 0.9 s at
    /// 0.05, for the same fidelity (pairs 0.962 vs 0.961 of the ceiling at 300x200), so its
    /// scene sets 0.05. Trolley's metal rails (alpha 0.0625) need 0.1: at 0.05 its 1 ms
    /// windows drop from 0.944 to 0.896 of the ceiling.
    pub glossy_grid_alpha: f32,
}

impl DatasetConfig {
    /// How the frames are made, for messages: "surface cache, 32 camera samples, glossy
    /// keyframes every 32 frames" or "path traced, 2 spp, denoise true".
    pub fn frames_summary(&self) -> String {
        match self.shading {
            Shading::SurfaceCache => format!(
                "surface cache, {} camera samples, glossy keyframes every {} frames",
                self.feature_spp.max(self.spp),
                self.glossy_stride
            ),
            Shading::PathTraced => format!("path traced, {} spp, denoise {}", self.spp, self.denoise),
        }
    }

    /// The temporal window's stride as used: `temporal_stride`, at most `temporal_radius` (and
    /// 1 without a window).
    pub fn window_stride(&self) -> u32 {
        self.temporal_stride.clamp(1, self.temporal_radius.max(1))
    }
}

impl Default for DatasetConfig {
    fn default() -> DatasetConfig {
        DatasetConfig {
            width: 600,
            height: 400,
            fps: 1000.0,
            exposure_ms: 40.0,
            views: 30,
            sharp_every: 8,
            first_view_ms: None,
            spacing_ms: None,
            spp: 2,
            spp_max: 0,
            adaptive_variance: 0.1,
            sharp_spp: None,
            max_depth: 5,
            seed: 0,
            sampler: SamplerKind::default(),
            noise_pattern: NoisePattern::default(),
            bvh: BvhPreset::default(),
            response: CameraResponse::default(),
            gain: 1.0,
            clamp: 0.0,
            light_samples: 1,
            denoise: true,
            temporal_radius: 32,
            temporal_stride: 2,
            feature_spp: 32,
            texture_filter: 0.0,
            radiance_cache: 32,
            cache_vertex: 1,
            shading: Shading::default(),
            surface_paths: 64,
            surface_spacing: 0.0,
            glossy_paths: 64,
            glossy_block: 1,
            glossy_stride: 32,
            glossy_grid_alpha: crate::render::integrator::surface::GLOSSY_GRID_ALPHA,
        }
    }
}

/// The keys a matrix's or scene's `dataset = {...}` table (and [`Overrides`]) takes besides the
/// scene file's `[dataset]` keys: the shorthands and `set`.
pub const SHORTHANDS: [&str; 7] =
    ["threshold", "threshold_sigma", "leak_rate_hz", "shot_noise_rate_hz", "refractory_ms", "speed", "set"];

/// Changes to a scene file's settings before a dataset is planned: `evsim`'s `--set` and
/// `--speed`, and the `dataset = {...}` tables of benchmark matrices and sweeps.
///
/// A key of such a table is one of three things:
/// - a key of the scene file's `[dataset]` table ([`DatasetConfig`], documented there and in
///   `docs/simulator.md`), held in [`Overrides::dataset`];
/// - `set`: `KEY=VALUE` settings of any of the file's `[dataset]`, `[events]` and
///   `[trajectory]` tables;
/// - a shorthand (the other fields) for a change that is not one key of the file.
///
/// They apply in this order, a later one winning: the `[dataset]` keys (as `dataset.KEY=VALUE`
/// settings, in key order), then `set` in its order (both on the file's TOML, before it is read
/// and checked; [`crate::base::settings::apply_sets`]), then the shorthands on the checked
/// settings.
///
/// ```toml
/// dataset = { width = 300, exposure_ms = 20, threshold = 0.25, set = ["trajectory.radius=5.0"] }
/// ```
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
pub struct Overrides {
    /// Both `[events] c_pos` and `c_neg`: the contrast threshold (log intensity, > 0).
    pub threshold: Option<f32>,
    /// `[events.noise.threshold_mismatch] sigma`: per-pixel threshold spread (log units; 0 =
    /// off), keeping the file's `mode`.
    pub threshold_sigma: Option<f32>,
    /// `[events.noise] leak_rate_hz`: leak events per pixel per second (Hz).
    pub leak_rate_hz: Option<f32>,
    /// `[events.noise] shot_noise_rate_hz`: shot-noise events per pixel per second (Hz).
    pub shot_noise_rate_hz: Option<f32>,
    /// `[events.noise.refractory]` period (ms, >= 0; 0 = off), keeping the file's `mode`.
    pub refractory_ms: Option<f64>,
    /// Camera speed factor (> 0): the trajectory's clock runs this much faster (2 = the same
    /// path in half the time, twice the blur per exposure).
    pub speed: Option<f64>,
    /// Any setting of the scene file's `[dataset]`, `[events]` or `[trajectory]` table,
    /// `KEY=VALUE` with KEY a dotted path (`dataset.glossy_block=2`,
    /// `events.noise.leak_rate_hz=0.1`, `trajectory.radius=5.0`; VALUE a TOML value, `none`
    /// removes the key): applied to the file before it is read and checked, after
    /// [`Overrides::dataset`].
    #[serde(default)]
    pub set: Vec<String>,
    /// Keys of the scene file's `[dataset]` table ([`DatasetConfig`]) and their values: every
    /// other key of a `dataset = {...}` table. Checked by [`Overrides::validate`].
    #[serde(flatten)]
    pub dataset: BTreeMap<String, toml::Value>,
}

impl Overrides {
    /// True when nothing is overridden.
    pub fn is_empty(&self) -> bool {
        *self == Overrides::default()
    }

    /// These overrides with the scene file's `[dataset] key = value` (replacing an earlier value
    /// of `key`), e.g. `Overrides::default().with("width", 48).with("height", 32)`.
    pub fn with(mut self, key: &str, value: impl Into<toml::Value>) -> Overrides {
        self.dataset.insert(key.to_string(), value.into());
        self
    }

    /// These overrides, with `over`'s taking precedence: its shorthands and `[dataset]` keys
    /// key by key; its `set` list after this one's (so its settings win, also over this one's
    /// `[dataset]` keys).
    pub fn merged(&self, over: &Overrides) -> Overrides {
        let mut dataset = self.dataset.clone();
        dataset.extend(over.dataset.iter().map(|(k, v)| (k.clone(), v.clone())));
        Overrides {
            threshold: over.threshold.or(self.threshold),
            threshold_sigma: over.threshold_sigma.or(self.threshold_sigma),
            leak_rate_hz: over.leak_rate_hz.or(self.leak_rate_hz),
            shot_noise_rate_hz: over.shot_noise_rate_hz.or(self.shot_noise_rate_hz),
            refractory_ms: over.refractory_ms.or(self.refractory_ms),
            speed: over.speed.or(self.speed),
            set: self.set.iter().chain(&over.set).cloned().collect(),
            dataset,
        }
    }

    /// The `KEY=VALUE` settings applied to the scene file's TOML, in order: the `[dataset]`
    /// keys as `dataset.KEY=VALUE` (VALUE in TOML syntax), then `set`.
    pub fn sets(&self) -> Vec<String> {
        let keys = self.dataset.iter().map(|(k, v)| format!("dataset.{k}={v}"));
        keys.chain(self.set.iter().cloned()).collect()
    }

    /// Reject what cannot be applied, naming the field: a `[dataset]` key that is not one of
    /// [`DatasetConfig`]'s or a value of the wrong type for it, and NaN, negative or zero
    /// shorthands that are not range-checked later. The rest is range-checked with the scene's
    /// own settings once applied.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (key, value) in &self.dataset {
            let one: toml::Table = [(key.clone(), value.clone())].into_iter().collect();
            if let Err(e) = toml::Value::Table(one).try_into::<DatasetConfig>() {
                return Err((
                    format!("dataset.{key}"),
                    format!(
                        "{key} = {value}: {}; a `dataset` table takes the keys of a scene file's [dataset] \
                         table (simulator::dataset::DatasetConfig: listed under --set in `evsim dataset --help`, \
                         explained in docs/simulator.md) or one of: {}",
                        e.message().trim_end(),
                        SHORTHANDS.join(", ")
                    ),
                ));
            }
        }
        if let Some(ms) = self.refractory_ms {
            if !(ms >= 0.0 && ms.is_finite()) {
                return Err((
                    "refractory_ms".into(),
                    format!("{ms} must be a time >= 0 in milliseconds (0 turns it off)"),
                ));
            }
        }
        if let Some(s) = self.speed {
            if !(s > 0.0 && s.is_finite()) {
                return Err(("speed".into(), format!("{s} must be a positive factor (1 = the scene's own speed)")));
            }
        }
        Ok(())
    }

    /// The trajectory with its clock scaled by `speed` (unchanged without it).
    pub fn apply_speed(&self, t: &TrajectoryConfig) -> TrajectoryConfig {
        match self.speed {
            Some(s) if s != 1.0 => t.time_scaled(s),
            _ => t.clone(),
        }
    }

    /// Apply the event shorthands (`threshold`, `threshold_sigma`, `leak_rate_hz`,
    /// `shot_noise_rate_hz`, `refractory_ms`) to the file's `[events]` settings.
    pub fn apply_events(&self, ev: &mut crate::events::EventConfig) {
        if let Some(c) = self.threshold {
            ev.c_pos = c;
            ev.c_neg = c;
        }
        let noise = &mut ev.noise;
        if let Some(sigma) = self.threshold_sigma {
            let mode = noise.threshold_mismatch.map(|m| m.mode).unwrap_or_default();
            noise.threshold_mismatch = (sigma != 0.0).then_some(ThresholdMismatch { sigma, mode });
        }
        noise.leak_rate_hz = self.leak_rate_hz.unwrap_or(noise.leak_rate_hz);
        noise.shot_noise_rate_hz = self.shot_noise_rate_hz.unwrap_or(noise.shot_noise_rate_hz);
        if let Some(ms) = self.refractory_ms {
            let mode = noise.refractory.map(|r| r.mode).unwrap_or_default();
            let period_ns = (ms * 1e6).round() as i64;
            noise.refractory = (period_ns > 0).then_some(Refractory { period_ns, mode });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Overrides {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn a_dataset_table_splits_into_shorthands_set_and_dataset_keys() {
        let o = read(
            "width = 300\nexposure_ms = 20\nshading = \"path_traced\"\nresponse = { type = \"gamma\", gamma = 2.2 }\n\
             threshold = 0.25\nspeed = 2\nset = [\"trajectory.radius=5.0\"]\n",
        );
        assert_eq!((o.threshold, o.speed), (Some(0.25), Some(2.0)));
        assert_eq!(o.set, ["trajectory.radius=5.0"]);
        assert_eq!(o.dataset.keys().collect::<Vec<_>>(), ["exposure_ms", "response", "shading", "width"]);
        assert_eq!(
            o,
            Overrides { threshold: Some(0.25), speed: Some(2.0), ..Overrides::default() }
                .with("width", 300)
                .with("exposure_ms", 20)
                .with("shading", "path_traced")
                .with("response", read("type = \"gamma\"\ngamma = 2.2").dataset.into_iter().collect::<toml::Table>())
                .merged(&Overrides { set: vec!["trajectory.radius=5.0".into()], ..Overrides::default() })
        );
        // every shorthand is a field, not a [dataset] key
        for key in SHORTHANDS {
            let value = if key == "set" { "[]" } else { "1" };
            assert!(read(&format!("{key} = {value}")).dataset.is_empty(), "{key}");
        }
        assert!(o.validate().is_ok());
    }

    #[test]
    fn dataset_keys_become_sets_that_give_back_their_values() {
        let o = Overrides::default()
            .with("exposure_ms", 0.1)
            .with("texture_filter", 1e-7)
            .with("glossy_grid_alpha", 0.05f32)
            .with("views", 12)
            .with("denoise", false)
            .with("noise_pattern", "per_frame")
            .merged(&Overrides { set: vec!["dataset.views=14".into()], ..Overrides::default() });
        let sets = o.sets();
        assert_eq!(sets.last().map(String::as_str), Some("dataset.views=14"), "set comes last: {sets:?}");
        let mut doc = toml::Table::new();
        let w = crate::base::settings::SetWording { flag: "--set", example: "", missing: "", create_tables: true };
        crate::base::settings::apply_sets(&mut doc, &sets, w).unwrap();
        let d: DatasetConfig = doc["dataset"].clone().try_into().unwrap();
        assert_eq!((d.exposure_ms, d.texture_filter, d.glossy_grid_alpha), (0.1, 1e-7, 0.05));
        assert_eq!((d.views, d.denoise, d.noise_pattern), (14, false, NoisePattern::PerFrame));
    }

    #[test]
    fn merged_takes_the_scenes_keys_over_the_matrixs_key_by_key() {
        let matrix = read("width = 300\nheight = 200\nthreshold = 0.2\nset = [\"dataset.spp=4\"]");
        let scene = read("height = 100\nspeed = 2\nset = [\"dataset.spp=8\"]");
        let m = matrix.merged(&scene);
        assert_eq!((m.dataset["width"].as_integer(), m.dataset["height"].as_integer()), (Some(300), Some(100)));
        assert_eq!((m.threshold, m.speed), (Some(0.2), Some(2.0)));
        assert_eq!(m.set, ["dataset.spp=4", "dataset.spp=8"]);
        assert!(Overrides::default().is_empty() && !m.is_empty());
    }

    #[test]
    fn validate_names_an_unknown_key_or_a_wrong_value_and_where_the_keys_are() {
        let (field, e) = read("widht = 3").validate().unwrap_err();
        assert_eq!(field, "dataset.widht");
        for says in ["unknown field `widht`", "`width`", "DatasetConfig", "evsim dataset --help", "docs/simulator.md"] {
            assert!(e.contains(says), "{says}: {e}");
        }
        assert!(e.contains("threshold_sigma") && e.contains("set"), "{e}");
        let (field, e) = read("width = \"wide\"").validate().unwrap_err();
        assert!(field == "dataset.width" && e.contains("invalid type"), "{field}: {e}");
        assert_eq!(read("speed = 0").validate().unwrap_err().0, "speed");
        assert_eq!(read("refractory_ms = -1").validate().unwrap_err().0, "refractory_ms");
    }
}
