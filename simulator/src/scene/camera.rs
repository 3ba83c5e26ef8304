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
        let tan_half = (self.yfov * 0.5).tan();
        let aspect = width as f32 / height as f32;
        let x = (2.0 * p.x / width as f32 - 1.0) * tan_half * aspect;
        let y = (1.0 - 2.0 * p.y / height as f32) * tan_half;
        self.to_world.transform_vector3(Vec3::new(x, y, -1.0)).normalize()
    }
}
