//! TODO: the path tracer.

use indicatif::ProgressBar;

use super::film::{Image, RenderSettings};
use crate::scene::Scene;

/// A scene prepared for rendering: BVH built, lights gathered.
pub struct Renderer<'a> {
    /// The scene being rendered.
    pub scene: &'a Scene,
}

impl<'a> Renderer<'a> {
    /// Build the acceleration structure and light tables for `scene`.
    pub fn new(scene: &'a Scene) -> Renderer<'a> {
        Renderer { scene }
    }
    /// Render one image; ticks `progress` once per finished tile when given.
    pub fn render(&self, _settings: &RenderSettings, _progress: Option<&ProgressBar>) -> Image {
        todo!("path tracer")
    }
}
