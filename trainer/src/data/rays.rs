//! Pinhole rays through pixel centres, and the NDC warp for forward-facing scenes.
//!
//! Intrinsics `K = [[f, 0, W/2], [0, f, H/2], [0, 0, 1]]`; pixel `(i, j)` (column, row; row 0 at
//! the top) has its centre at `(i + 0.5, j + 0.5)`. As NeRF's `get_rays`, the camera-space
//! direction is `((u - W/2) / f, -(v - H/2) / f, -1)` (not normalised: its z is -1, which the NDC
//! warp relies on), rotated to world by the camera-to-world rotation; the origin is the camera
//! centre.
//!
//! NDC (NeRF's `ndc_rays`, near plane `n`, here 1): move the origin to the plane `z = -n`,
//! `o <- o + t_n d` with `t_n = -(n + o_z) / d_z`, then
//! `o' = (-f/(W/2) o_x/o_z, -f/(H/2) o_y/o_z, 1 + 2n/o_z)`,
//! `d' = (-f/(W/2) (d_x/d_z - o_x/o_z), -f/(H/2) (d_y/d_z - o_y/o_z), -2n/o_z)`.
//! Points in front of the camera between the near plane and infinity map to NDC depth [-1, 1);
//! the ray `o' + s d'` reaches depth 1 (infinity) at `s = 1`, so samples use near 0, far 1.

use glam::DVec3;
use simulator::trajectory::Pose;

/// A ray: origin and direction (not normalised) in the loader's world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: DVec3,
    /// Direction (for camera rays: z = -1 in camera space).
    pub direction: DVec3,
}

/// Pinhole intrinsics shared by every image: size and focal length (pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
    /// Focal length (pixels), square pixels, principal point at the image centre.
    pub focal: f64,
}

impl Intrinsics {
    /// Camera-space direction through the centre of pixel (`i`, `j`) = (column, row).
    pub fn camera_direction(&self, i: u32, j: u32) -> DVec3 {
        self.camera_direction_at(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// Camera-space direction through the image point (`u`, `v`) (continuous pixel
    /// coordinates: pixel (i, j) covers [i, i + 1) x [j, j + 1), its centre is (i + 0.5, j + 0.5)).
    pub fn camera_direction_at(&self, u: f64, v: f64) -> DVec3 {
        DVec3::new((u - 0.5 * self.width as f64) / self.focal, -(v - 0.5 * self.height as f64) / self.focal, -1.0)
    }

    /// The world ray through the image point (`u`, `v`) (continuous coordinates, see
    /// [`Intrinsics::camera_direction_at`]) for a camera at `pose`.
    pub fn ray_through(&self, pose: &Pose, u: f64, v: f64) -> Ray {
        Ray { origin: pose.position, direction: pose.rotation * self.camera_direction_at(u, v) }
    }

    /// The world ray of pixel (`i`, `j`) for a camera at `pose` (camera-to-world).
    pub fn ray(&self, pose: &Pose, i: u32, j: u32) -> Ray {
        Ray { origin: pose.position, direction: pose.rotation * self.camera_direction(i, j) }
    }

    /// The ray in NDC (see the module doc) with near plane `near` (the reference uses 1).
    pub fn ndc(&self, ray: &Ray, near: f64) -> Ray {
        ndc_ray(self.width, self.height, self.focal, near, ray)
    }
}

/// NeRF's `ndc_rays` for a `width` x `height` image of focal `focal` (pixels), near plane `near`
/// (formula in the module doc). The ray must not be parallel to the image plane.
pub fn ndc_ray(width: u32, height: u32, focal: f64, near: f64, ray: &Ray) -> Ray {
    let (o, d) = (ray.origin, ray.direction);
    // shift the origin to the near plane z = -near
    let t = -(near + o.z) / d.z;
    let o = o + t * d;
    // project
    let ax = -focal / (0.5 * width as f64);
    let ay = -focal / (0.5 * height as f64);
    let origin = DVec3::new(ax * o.x / o.z, ay * o.y / o.z, 1.0 + 2.0 * near / o.z);
    let direction = DVec3::new(ax * (d.x / d.z - o.x / o.z), ay * (d.y / d.z - o.y / o.z), -2.0 * near / o.z);
    Ray { origin, direction }
}

/// Backward of [`ndc_ray`]: dL/d(world origin) and dL/d(world direction) from dL/d(NDC
/// origin) and dL/d(NDC direction). With `s = o + t d` on the near plane (`s_z = -near`), the
/// NDC ray is `(-a_x s_x / n, -a_y s_y / n, -1)`, `(a_x (d_x/d_z + s_x/n), a_y (d_y/d_z + s_y/n), 2)`,
/// so its z components carry no gradient.
pub fn ndc_ray_backward(
    width: u32,
    height: u32,
    focal: f64,
    near: f64,
    ray: &Ray,
    d_origin: DVec3,
    d_direction: DVec3,
) -> (DVec3, DVec3) {
    let (o, d) = (ray.origin, ray.direction);
    let t = -(near + o.z) / d.z;
    let ax = -focal / (0.5 * width as f64);
    let ay = -focal / (0.5 * height as f64);
    // dL/ds for the near-plane point s.
    let g_sx = ax / near * (d_direction.x - d_origin.x);
    let g_sy = ay / near * (d_direction.y - d_origin.y);
    let (rx, ry) = (d.x / d.z, d.y / d.z);
    // s = o + t d with t = -(near + o_z) / d_z: ds/do_z = -d / d_z, ds/dd_z = -t d / d_z.
    let d_o = DVec3::new(g_sx, g_sy, -(g_sx * rx + g_sy * ry));
    let d_d = DVec3::new(
        g_sx * t + ax * d_direction.x / d.z,
        g_sy * t + ay * d_direction.y / d.z,
        -t * (g_sx * rx + g_sy * ry) - (ax * d_direction.x * rx + ay * d_direction.y * ry) / d.z,
    );
    (d_o, d_d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn ndc_backward_matches_finite_differences() {
        let ray = Ray { origin: DVec3::new(0.3, -0.2, 0.4), direction: DVec3::new(0.2, 0.15, -1.1) };
        let (go, gd) = (DVec3::new(0.7, -0.4, 0.9), DVec3::new(-0.3, 0.8, 0.5));
        let loss = |r: &Ray| {
            let n = ndc_ray(K.width, K.height, K.focal, 1.0, r);
            n.origin.dot(go) + n.direction.dot(gd)
        };
        let (d_o, d_d) = ndc_ray_backward(K.width, K.height, K.focal, 1.0, &ray, go, gd);
        let h = 1e-6;
        for a in 0..3 {
            for (which, an) in [("origin", d_o[a]), ("direction", d_d[a])] {
                let (mut p, mut m) = (ray, ray);
                let e = DVec3::from_array(std::array::from_fn(|i| if i == a { h } else { 0.0 }));
                if which == "origin" {
                    p.origin += e;
                    m.origin -= e;
                } else {
                    p.direction += e;
                    m.direction -= e;
                }
                let fd = (loss(&p) - loss(&m)) / (2.0 * h);
                assert!((fd - an).abs() < 1e-6 * (1.0 + fd.abs()), "{which}[{a}]: fd {fd} analytic {an}");
                assert!(an.abs() > 1e-6, "{which}[{a}] is zero");
            }
        }
    }

    const K: Intrinsics = Intrinsics { width: 40, height: 30, focal: 50.0 };

    /// NDC of a camera-space point (x, y, z), z < 0: the projective map the rays follow.
    fn ndc_point(p: DVec3, near: f64) -> DVec3 {
        let ax = -K.focal / (0.5 * K.width as f64);
        let ay = -K.focal / (0.5 * K.height as f64);
        DVec3::new(ax * p.x / p.z, ay * p.y / p.z, 1.0 + 2.0 * near / p.z)
    }

    #[test]
    fn pixel_centre_ray_hits_the_pixel() {
        // a point on the ray of pixel (3, 7) at depth 2 projects back to (3.5, 7.5) with K
        let r = K.ray(&Pose { rotation: DQuat::IDENTITY, position: DVec3::ZERO }, 3, 7);
        let p = r.origin + 2.0 * r.direction;
        let u = K.focal * p.x / -p.z + 20.0;
        let v = -K.focal * p.y / -p.z + 15.0;
        assert!((u - 3.5).abs() < 1e-12 && (v - 7.5).abs() < 1e-12, "{u} {v}");
    }

    #[test]
    fn ndc_maps_known_points() {
        let cam = Pose { rotation: DQuat::IDENTITY, position: DVec3::ZERO };
        let r = K.ray(&cam, 5, 21);
        let n = ndc_ray(K.width, K.height, K.focal, 1.0, &r);
        // the origin is the near-plane point: NDC depth -1
        assert!((n.origin.z + 1.0).abs() < 1e-12, "{}", n.origin);
        // a point at depth 4 on the ray is o' + s d' with s = 1 - near / depth = 0.75
        let p = r.origin + 4.0 * r.direction;
        let want = ndc_point(p, 1.0);
        let got = n.origin + 0.75 * n.direction;
        assert!((got - want).length() < 1e-12, "{got} vs {want}");
        // the explicit formula for the centre pixel-ish ray through (0.2, -0.1, -1) at depth 2:
        // x' = -f/(W/2) * 0.4/-2 = 2.5 * 0.2 = 0.5, y' = -50/15 * -0.2/-2 = -1/3, z' = 1 - 2/2 = 0
        let q = ndc_point(DVec3::new(0.4, -0.2, -2.0), 1.0);
        assert!((q - DVec3::new(0.5, -1.0 / 3.0, 0.0)).length() < 1e-12, "{q}");
        // infinity: s = 1 reaches depth 1
        assert!(((n.origin + n.direction).z - 1.0).abs() < 1e-12);
    }
}
