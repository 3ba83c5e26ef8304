//! The film: the settings of one render (the image it makes is [`crate::base::image::Image`]).

use super::sampler::SamplerKind;
use crate::scene::Camera;

/// Everything that determines one rendered image besides the scene.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Maximum number of path segments (Mitsuba's convention): 1 = emitters seen directly,
    /// 2 = direct lighting, ...; `u32::MAX` = unlimited (Russian roulette ends paths).
    pub max_depth: u32,
    /// Depth (in segments) from which Russian roulette may end paths.
    pub rr_depth: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Frame index, folded into the random streams so that frames of a sequence differ.
    pub frame: u64,
    /// The camera to render from.
    pub camera: Camera,
    /// Where the random numbers come from.
    pub sampler: SamplerKind,
    /// Largest channel of any one path contribution except directly visible emitters (sample
    /// clamping against fireflies; biased); 0 = off (the default).
    pub clamp: f32,
    /// Light samples per path vertex (>= 1; splitting: less direct-light noise per primary ray).
    pub light_samples: u32,
    /// Camera rays per pixel for the first-hit buffers of
    /// [`super::integrator::Renderer::render_with_features`] (reflectance, emission, depth,
    /// normal); the first `spp` of them are the shaded paths, the rest stop at their first hit.
    /// Values below `spp` mean `spp`. Cheap (one ray each) and what keeps texture and edge
    /// detail of filtered frames steady while the camera moves.
    pub feature_spp: u32,
    /// Texture filtering at camera-ray hits: each camera ray looks its textures up averaged over
    /// the footprint of a `texture_filter`-pixel step on the film (mip-mapped, anisotropic; see
    /// [`crate::scene::Texture::sample_footprint`]), so that texture detail finer than that does
    /// not flicker from frame to frame. 0 = off (plain bilinear lookups, as Mitsuba does).
    pub texture_filter: f32,
    /// Paths per lattice point of the radiance cache ([`super::radiance_cache`]) that ends
    /// paths at their second surface vertex; 0 = off (full paths, the default).
    pub radiance_cache: u32,
    /// Lattice spacing of the radiance cache (world units; 0 = the scene's bounding-box
    /// diagonal over 128).
    pub cache_spacing: f32,
    /// The camera-path vertex the radiance cache serves: 2 (the default) ends paths at their
    /// second surface vertex with the cached light there; 1 ends them at the first: a camera
    /// sample then traces only the shadow rays of its direct light from delta lights and
    /// emissive triangles, and the rest (the environment, light via other surfaces) comes from
    /// a cache of indirect light (see [`super::radiance_cache`]).
    pub cache_vertex: u32,
    /// Adaptive sampling in [`super::integrator::Renderer::shade_with_features`]: pixels whose
    /// first `spp` samples show a noisy estimate get up to this many in all; at most `spp`
    /// (the default 0) = off.
    pub spp_max: u32,
    /// Paths per grid point of the surface cache that [`super::integrator::Renderer::render_surface`]
    /// reads ([`super::integrator::surface`]).
    pub surface_paths: u32,
    /// Largest cell side of the surface cache's grids (world units; 0 = the scene's bounding-box diagonal
    /// over 512).
    pub surface_spacing: f32,
    /// Paths per triangle and pixel on glossy surfaces in a surface-cache render (>= 1).
    pub glossy_paths: u32,
    /// Side of the blocks of pixels whose glossy samples share their paths in a surface-cache
    /// render (pixels, >= 1).
    pub glossy_block: u32,
    /// Frames between the keyframes whose glossy grids a surface-cache render reads on rough
    /// glossy lobes (0 = none: every glossy sample traces paths).
    pub glossy_stride: u32,
    /// GGX alpha from which a glossy lobe reads the glossy grids (with `glossy_stride` > 0);
    /// sharper lobes trace paths in every frame (default
    /// [`crate::render::integrator::surface::GLOSSY_GRID_ALPHA`]).
    pub glossy_grid_alpha: f32,
    /// Camera positions of the sequence a surface-cache render belongs to: its shadow
    /// grids are as fine as the nearest of them needs (`None`: this frame's camera alone).
    pub camera_path: Option<std::sync::Arc<Vec<glam::Vec3>>>,
    /// With `spp_max`: the relative variance of a pixel's estimate adaptive sampling aims at
    /// (see [`crate::dataset::DatasetConfig::adaptive_variance`]).
    pub adaptive_variance: f32,
}

impl RenderSettings {
    /// Defaults: 600x400, 64 spp, max depth 5, roulette from depth 5, seed 0, frame 0, Sobol, no
    /// clamping.
    pub fn new(camera: Camera) -> RenderSettings {
        RenderSettings {
            width: 600,
            height: 400,
            spp: 64,
            max_depth: 5,
            rr_depth: 5,
            seed: 0,
            frame: 0,
            camera,
            sampler: SamplerKind::default(),
            clamp: 0.0,
            light_samples: 1,
            feature_spp: 0,
            texture_filter: 0.0,
            radiance_cache: 0,
            cache_spacing: 0.0,
            cache_vertex: 2,
            spp_max: 0,
            surface_paths: 64,
            surface_spacing: 0.0,
            glossy_paths: 64,
            glossy_block: 1,
            glossy_stride: 0,
            glossy_grid_alpha: crate::render::integrator::surface::GLOSSY_GRID_ALPHA,
            camera_path: None,
            adaptive_variance: 0.1,
        }
    }
}
