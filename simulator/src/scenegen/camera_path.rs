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
    format!("[trajectory]\ntype = \"keys\"\n{}", key_tables(keys, 3))
}

/// Only the `[[trajectory.keys]]` tables of `keys`, each after a blank line, times printed with
/// `t_decimals` digits and positions with 3.
pub fn key_tables(keys: &[Key], t_decimals: usize) -> String {
    let mut s = String::new();
    let v = |p: [f64; 3]| format!("[{:.3}, {:.3}, {:.3}]", p[0], p[1], p[2]);
    for k in keys {
        // writing into a String cannot fail
        let _ = write!(
            s,
            "\n[[trajectory.keys]]\nt = {:.d$}\nposition = {}\nlook_at = {}\n",
            k.t,
            v(k.position),
            v(k.look_at),
            d = t_decimals
        );
    }
    s
}

/// Keys from (time, eye, look-at) triples in single precision.
pub fn keys_from(path: &[(f64, glam::Vec3, glam::Vec3)]) -> Vec<Key> {
    let d = |v: glam::Vec3| [v.x as f64, v.y as f64, v.z as f64];
    path.iter().map(|&(t, p, l)| Key { t, position: d(p), look_at: d(l) }).collect()
}

/// The `[dataset]` and `[events]` tables of the outdoor benchmark scenes (tanabata, trolley).
pub const OUTDOOR_DATASET_AND_EVENTS: &str = "[dataset]
# defaults: the paper's 600x400, 1000 FPS, 40 ms exposure; every 8th view sharp;
# 2 spp, 32 feature rays, temporal radius 32 read every 2nd frame, first-vertex cache (chosen with
# `evsim dataset-noise`)
views = 30
# direct light plus one bounce: outdoors it looks the same as 5 and renders ~30 % faster
max_depth = 3

[events]
c_pos = 0.2
c_neg = 0.2
";

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
