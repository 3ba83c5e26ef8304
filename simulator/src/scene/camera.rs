//! Pinhole perspective camera.
//!
//! The camera looks down its local -Z with +Y up and +X to the right (glTF). Image row 0 is the
//! top of the picture and world-right appears on the image's right (as in Mitsuba).

use glam::{Mat4, Vec2, Vec3};

/// A perspective pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Name from the file, for messages.
    pub name: String,
    /// Camera-to-world rigid transform (no scale).
    pub to_world: Mat4,
    /// Full vertical field of view (rad).
    pub yfov: f32,
}

impl Camera {
    /// A camera at `origin` looking at `target`, with `up` roughly up and full vertical FOV `yfov`.
    pub fn look_at(origin: Vec3, target: Vec3, up: Vec3, yfov: f32) -> Camera {
        // columns: camera +X = right, +Y = true up, +Z = backwards (the camera looks down -Z)
        let forward = (target - origin).normalize();
        let right = forward.cross(up).normalize();
        let true_up = right.cross(forward);
        let to_world =
            Mat4::from_cols(right.extend(0.0), true_up.extend(0.0), (-forward).extend(0.0), origin.extend(1.0));
        Camera { name: "look_at".into(), to_world, yfov }
    }

    /// Convert a full horizontal FOV to the full vertical FOV for an image of `width` x `height`.
    pub fn yfov_from_xfov(xfov: f32, width: u32, height: u32) -> f32 {
        2.0 * ((xfov * 0.5).tan() * height as f32 / width as f32).atan()
    }

    /// Camera position in world space.
    pub fn origin(&self) -> Vec3 {
        self.to_world.w_axis.truncate()
    }

    /// World-space unit direction through film point `p` (pixels, (0,0) = top-left corner of the
    /// image) for an image of `width` x `height` pixels.
    pub fn direction(&self, p: Vec2, width: u32, height: u32) -> Vec3 {
        self.film_rays(width, height).direction(p)
    }

    /// [`Camera::direction`] for many film points: the per-camera numbers (a `tan`) computed
    /// once.
    pub fn film_rays(&self, width: u32, height: u32) -> FilmRays {
        FilmRays {
            to_world: self.to_world,
            tan_half: (self.yfov * 0.5).tan(),
            aspect: width as f32 / height as f32,
            width: width as f32,
            height: height as f32,
        }
    }

    /// Film point (pixels, as [`Camera::direction`] takes them) where world point `x` appears in
    /// an image of `width` x `height`, or `None` when `x` is not in front of the camera. The
    /// point may lie outside the image.
    pub fn project(&self, x: Vec3, width: u32, height: u32) -> Option<Vec2> {
        self.projector(width, height).project(x)
    }

    /// [`Camera::project`] for many points: the per-camera numbers computed once.
    pub fn projector(&self, width: u32, height: u32) -> Projector {
        Projector {
            origin: self.origin(),
            axes: [self.to_world.x_axis, self.to_world.y_axis, self.to_world.z_axis].map(|a| a.truncate()),
            tan_half: (self.yfov * 0.5).tan(),
            aspect: width as f32 / height as f32,
            width: width as f32,
            height: height as f32,
        }
    }
}

/// A camera's rays through the film of an image of a given size ([`Camera::film_rays`]).
#[derive(Clone, Copy, Debug)]
pub struct FilmRays {
    to_world: Mat4,
    tan_half: f32,
    aspect: f32,
    width: f32,
    height: f32,
}

impl FilmRays {
    /// World-space unit direction through film point `p` (as [`Camera::direction`]).
    #[inline]
    pub fn direction(&self, p: Vec2) -> Vec3 {
        self.unnormalised(p).normalize()
    }

    /// [`FilmRays::direction`] before normalisation: the world-space direction to the point of
    /// the image plane at distance 1, affine in `p`.
    #[inline]
    pub fn unnormalised(&self, p: Vec2) -> Vec3 {
        let x = (2.0 * p.x / self.width - 1.0) * self.tan_half * self.aspect;
        let y = (1.0 - 2.0 * p.y / self.height) * self.tan_half;
        self.to_world.transform_vector3(Vec3::new(x, y, -1.0))
    }

    /// How [`FilmRays::unnormalised`] changes per pixel along x and along y.
    #[inline]
    pub fn steps(&self) -> [Vec3; 2] {
        [
            self.to_world.transform_vector3(Vec3::new(2.0 / self.width * self.tan_half * self.aspect, 0.0, 0.0)),
            self.to_world.transform_vector3(Vec3::new(0.0, -2.0 / self.height * self.tan_half, 0.0)),
        ]
    }
}

/// A camera's projection onto an image of a given size ([`Camera::projector`]).
#[derive(Clone, Copy, Debug)]
pub struct Projector {
    origin: Vec3,
    axes: [Vec3; 3],
    tan_half: f32,
    aspect: f32,
    width: f32,
    height: f32,
}

impl Projector {
    /// As [`Camera::project`].
    pub fn project(&self, x: Vec3) -> Option<Vec2> {
        // rigid transform: the inverse rotation is the transpose
        let d = x - self.origin;
        let local = Vec3::new(d.dot(self.axes[0]), d.dot(self.axes[1]), d.dot(self.axes[2]));
        if !(local.z < 0.0) {
            return None;
        }
        Some(self.film(local))
    }

    /// As [`Projector::project`], with NaN coordinates for a point not in front of the camera
    /// (no branch, so that loops of it vectorise).
    #[inline(always)]
    pub fn project_or_nan(&self, x: Vec3) -> Vec2 {
        let d = x - self.origin;
        let local = Vec3::new(d.dot(self.axes[0]), d.dot(self.axes[1]), d.dot(self.axes[2]));
        let q = self.film(local);
        if local.z < 0.0 {
            q
        } else {
            Vec2::NAN
        }
    }

    /// Film coordinates of the camera-space point `local`.
    #[inline(always)]
    fn film(&self, local: Vec3) -> Vec2 {
        let (sx, sy) = (local.x / -local.z / (self.tan_half * self.aspect), local.y / -local.z / self.tan_half);
        Vec2::new((sx + 1.0) * 0.5 * self.width, (1.0 - sy) * 0.5 * self.height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_direction() {
        let cam = Camera::look_at(Vec3::new(0.3, 1.2, 5.0), Vec3::new(-0.5, 0.8, 0.0), Vec3::Y, 0.8);
        let (w, h) = (600, 400);
        for p in [Vec2::new(0.5, 0.5), Vec2::new(300.0, 200.0), Vec2::new(599.2, 17.3), Vec2::new(12.0, 398.0)] {
            for dist in [0.1f32, 3.0, 250.0] {
                let x = cam.origin() + cam.direction(p, w, h) * dist;
                let q = cam.project(x, w, h).expect("in front");
                assert!((q - p).length() < 1e-3 * dist.max(1.0), "{p} at {dist}: {q}");
            }
        }
        // behind the camera and at the eye: nothing
        let behind = cam.origin() - cam.direction(Vec2::new(300.0, 200.0), w, h);
        assert_eq!(cam.project(behind, w, h), None);
        assert_eq!(cam.project(cam.origin(), w, h), None);
    }
}
