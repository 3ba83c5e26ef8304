//! Environment light: radiance arriving from infinitely far away.
//!
//! TODO(helper): equirectangular maps, importance sampling.

use glam::{Vec2, Vec3};

/// Light from infinitely far away, as a function of direction.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Vec3),
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Constant(Vec3::ZERO)
    }
}

/// A direction sampled towards the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvSample {
    /// Unit world direction towards the environment.
    pub wi: Vec3,
    /// Radiance arriving along `-wi`.
    pub radiance: Vec3,
    /// Density w.r.t. solid angle.
    pub pdf: f32,
}

impl Environment {
    /// Radiance arriving from direction `d` (unit, pointing away from the scene).
    pub fn radiance(&self, _d: Vec3) -> Vec3 {
        match self {
            Environment::Constant(c) => *c,
        }
    }
    /// True when no light comes from the environment.
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
        }
    }
    /// Sample a direction (importance-sampled for maps, uniform sphere for constants).
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        let wi = crate::render::sampling::uniform_sphere(u);
        Some(EnvSample { wi, radiance: self.radiance(wi), pdf: self.pdf(wi) })
    }
    /// Integral over the sphere of the luminance of the radiance (sr * W/m^2/sr), for light
    /// selection by power.
    pub fn power_integral(&self) -> f32 {
        match self {
            Environment::Constant(c) => 4.0 * std::f32::consts::PI * crate::render::lights::luminance(*c),
        }
    }
    /// Density of [`Environment::sample`] for direction `d`, w.r.t. solid angle.
    pub fn pdf(&self, _d: Vec3) -> f32 {
        crate::render::sampling::UNIFORM_SPHERE_PDF
    }
}
