//! TEMPORARY Lambert-only stand-in with the final API; replaced by the GGX model.

use glam::{Vec2, Vec3};

use super::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};

/// BSDF at a shading point (local frame, +Z = normal).
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    /// Base colour.
    pub base_color: Vec3,
    /// Metalness.
    pub metallic: f32,
    /// Dielectric specular strength.
    pub specular: f32,
    /// GGX alpha.
    pub alpha: f32,
}

/// A sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Direction.
    pub wi: Vec3,
    /// eval / pdf.
    pub weight: Vec3,
    /// Solid-angle density.
    pub pdf: f32,
}

impl Bsdf {
    /// New BSDF.
    pub fn new(base_color: Vec3, metallic: f32, specular: f32, roughness: f32) -> Bsdf {
        Bsdf { base_color, metallic, specular, alpha: (roughness * roughness).max(1e-3) }
    }
    /// f cos.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.base_color * wi.z * std::f32::consts::FRAC_1_PI
    }
    /// pdf.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi.z)
    }
    /// sample.
    pub fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (pdf > 0.0).then(|| BsdfSample { wi, weight: self.base_color, pdf })
    }
    /// albedo.
    pub fn albedo_hint(&self) -> Vec3 {
        self.base_color
    }
}
