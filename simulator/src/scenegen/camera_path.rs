//! Key-pose camera paths of the benchmark scenes, written as the `[trajectory]` table of their
//! `scene.toml` (`type = "keys"`, see [`crate::trajectory::keys`]).
//!
//! A benchmark path is about 1 s of fast, non-planar motion with keys every 0.1-0.15 s whose
//! speed and direction change from key to key, so the blur differs between exposures.

use std::fmt::Write;

/// One key pose: time (s), camera centre (m) and the point it looks at (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Key {
    /// Time of the key (s).
    pub t: f64,
    /// Camera centre (m).
    pub position: [f64; 3],
    /// World-space point looked at (m).
    pub look_at: [f64; 3],
}

/// The `[trajectory]` table (with its `[[trajectory.keys]]`) for `keys`, in order.
pub fn keys_toml(keys: &[Key]) -> String {
    let mut s = String::from("[trajectory]\ntype = \"keys\"\n");
    let v = |p: [f64; 3]| format!("[{:.3}, {:.3}, {:.3}]", p[0], p[1], p[2]);
    for k in keys {
        // writing into a String cannot fail
        let _ = write!(
            s,
            "\n[[trajectory.keys]]\nt = {:.3}\nposition = {}\nlook_at = {}\n",
            k.t,
            v(k.position),
            v(k.look_at)
        );
    }
    s
}

/// The `[camera]` and constant `[environment]` tables shared by the generated scene files:
/// camera at `eye` looking at `target` (printed with `decimals` digits), vertical FOV
/// `fov_y_deg`, and a constant sky of radiance `sky`. Ends with a newline.
pub fn camera_and_sky(eye: glam::Vec3, target: glam::Vec3, fov_y_deg: f32, decimals: usize, sky: [f32; 3]) -> String {
    let v = |p: glam::Vec3| format!("[{:.d$}, {:.d$}, {:.d$}]", p.x, p.y, p.z, d = decimals);
    format!(
        "[camera]\norigin = {}\ntarget = {}\nfov = {fov_y_deg:.1}\nfov_axis = \"y\"\n\n[environment]\ntype = \"constant\"\nradiance = [{}, {}, {}]\n",
        v(eye),
        v(target),
        sky[0],
        sky[1],
        sky[2]
    )
}
