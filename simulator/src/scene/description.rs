//! The `.toml` render description: a mesh file plus what OBJ cannot express (camera, environment).
//!
//! ```toml
//! scene = "cornell.obj"          # .obj/.gltf/.glb, relative to this file
//!
//! [camera]                       # optional: becomes cameras[0], before the file's own cameras
//! origin = [0.0, 1.0, 3.4]       # m
//! target = [0.0, 1.0, 0.0]       # m
//! up = [0.0, 1.0, 0.0]           # optional, default +Y
//! fov = 39.3                     # full angle in degrees, in (0, 180)
//! fov_axis = "x"                 # "x" (default, like Mitsuba) or "y"
//! aspect = 1.5                   # width / height; required with fov_axis = "x", rejected with "y"
//!
//! [environment]                  # optional: replaces the file's environment
//! type = "constant"
//! radiance = [1.0, 1.0, 1.0]     # W/m^2/sr per RGB channel
//! # or:
//! # type = "map"
//! # file = "sky.exr"             # equirectangular .exr/.hdr, relative to this file
//! # scale = 1.0                  # radiance multiplier (default 1)
//! # rotate_y = 0.0               # degrees about +Y (default 0)
//! ```
//!
//! The dataset tables of the same file (`[trajectory]`, `[dataset]`, `[events]`) are accepted
//! here and read by the dataset writer (`crate::dataset::description`). Unknown keys are
//! errors. Our [`Camera`] stores the vertical FOV, so with `fov_axis = "x"` the horizontal angle
//! is converted with `yfov = 2 atan(tan(xfov / 2) / aspect)` (the formula of
//! [`Camera::yfov_from_xfov`]); render at that aspect ratio to get Mitsuba's framing.

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use serde::Deserialize;

use super::environment::load_map;
use super::{Camera, Environment, Scene};
use crate::error::SceneError;

/// The whole description file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Description {
    /// The mesh file (`.obj`, `.gltf` or `.glb`), relative to the description's folder.
    pub scene: PathBuf,
    /// Camera to put first in [`Scene::cameras`].
    pub camera: Option<CameraDesc>,
    /// Environment replacing the mesh file's.
    pub environment: Option<EnvironmentDesc>,
    /// Camera path of a dataset: accepted here, read by `evsim dataset`
    /// (`crate::dataset::description`); ignored when rendering one image.
    pub trajectory: Option<toml::Table>,
    /// Dataset settings: accepted here, read by `evsim dataset`.
    pub dataset: Option<toml::Table>,
    /// Event-camera settings of a dataset: accepted here, read by `evsim dataset`.
    pub events: Option<toml::Table>,
}

/// Which image axis `fov` spans.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FovAxis {
    /// Horizontal (Mitsuba's default).
    #[default]
    X,
    /// Vertical.
    Y,
}

/// A look-at pinhole camera.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position (m).
    pub origin: [f32; 3],
    /// Point looked at (m).
    pub target: [f32; 3],
    /// Approximate up direction (unitless; default +Y).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Full field of view (degrees) along `fov_axis`, in (0, 180).
    pub fov: f32,
    /// Axis `fov` spans (default `"x"`).
    #[serde(default)]
    pub fov_axis: FovAxis,
    /// Image width / height (unitless) assumed to convert a horizontal FOV; required with
    /// `fov_axis = "x"`.
    pub aspect: Option<f32>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

fn one() -> f32 {
    1.0
}

/// The environment light.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum EnvironmentDesc {
    /// Uniform radiance from every direction.
    Constant {
        /// Radiance (W/m^2/sr) per RGB channel, finite and non-negative.
        radiance: [f32; 3],
    },
    /// Equirectangular map (see [`super::environment`] for the lookup convention).
    Map {
        /// `.exr` or `.hdr` file, relative to the description's folder.
        file: PathBuf,
        /// Radiance multiplier (unitless, default 1), finite and non-negative.
        #[serde(default = "one")]
        scale: f32,
        /// Rotation of the map about +Y (degrees, default 0, counter-clockwise seen from +Y).
        #[serde(default)]
        rotate_y: f32,
    },
}

/// Parse a description from TOML text; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<Description, SceneError> {
    toml::from_str(text).map_err(|e| SceneError::invalid(path, "TOML", e.to_string().trim_end().to_string()))
}

/// Load a `.toml` description: the referenced mesh file, then its camera and environment.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
    let desc = parse(&text, path)?;
    let folder = path.parent().unwrap_or(Path::new(""));

    let ext = desc.scene.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("obj" | "gltf" | "glb")) {
        return Err(SceneError::invalid(
            path,
            "scene",
            format!("`{}` must be a .obj, .gltf or .glb file", desc.scene.display()),
        ));
    }
    // resolve and check everything before the (slow) mesh load
    let camera = desc.camera.as_ref().map(|c| resolve_camera(c, path)).transpose()?;
    let mut scene = super::load(&folder.join(&desc.scene))?;
    if let Some(cam) = camera {
        scene.cameras.insert(0, cam);
    }
    if let Some(env) = &desc.environment {
        scene.environment = resolve_environment(env, folder, path)?;
    }
    Ok(scene)
}

/// A field check: finite numbers.
fn finite3(v: [f32; 3], path: &Path, field: &str) -> Result<Vec3, SceneError> {
    let v = Vec3::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(SceneError::invalid(path, field, format!("{v} must be finite")))
    }
}

/// Validate a camera description and build the [`Camera`].
fn resolve_camera(c: &CameraDesc, path: &Path) -> Result<Camera, SceneError> {
    let origin = finite3(c.origin, path, "camera.origin")?;
    let target = finite3(c.target, path, "camera.target")?;
    let up = finite3(c.up, path, "camera.up")?;
    let forward = (target - origin)
        .try_normalize()
        .ok_or_else(|| SceneError::invalid(path, "camera.target", "must differ from camera.origin"))?;
    if forward.cross(up).length() < 1e-6 * up.length() || up.length() == 0.0 {
        return Err(SceneError::invalid(path, "camera.up", "must be non-zero and not parallel to the view direction"));
    }
    if !(c.fov > 0.0 && c.fov < 180.0) {
        return Err(SceneError::invalid(path, "camera.fov", format!("{} must be in (0, 180) degrees", c.fov)));
    }
    let fov = c.fov.to_radians();
    let yfov = match (c.fov_axis, c.aspect) {
        (FovAxis::X, Some(aspect)) if aspect.is_finite() && aspect > 0.0 => {
            // Camera::yfov_from_xfov with width / height = aspect
            2.0 * ((fov * 0.5).tan() / aspect).atan()
        }
        (FovAxis::X, Some(aspect)) => {
            return Err(SceneError::invalid(path, "camera.aspect", format!("{aspect} must be a positive width / height")))
        }
        (FovAxis::X, None) => {
            return Err(SceneError::invalid(
                path,
                "camera.aspect",
                "required with fov_axis = \"x\" (our camera stores the vertical FOV); give the render's width / height, or use fov_axis = \"y\"",
            ))
        }
        (FovAxis::Y, None) => fov,
        (FovAxis::Y, Some(_)) => {
            return Err(SceneError::invalid(path, "camera.aspect", "only used with fov_axis = \"x\"; remove it"))
        }
    };
    let mut cam = Camera::look_at(origin, target, up, yfov);
    cam.name = "description camera".into();
    Ok(cam)
}

/// Validate an environment description and build the [`Environment`].
fn resolve_environment(env: &EnvironmentDesc, folder: &Path, path: &Path) -> Result<Environment, SceneError> {
    match env {
        EnvironmentDesc::Constant { radiance } => {
            let r = finite3(*radiance, path, "environment.radiance")?;
            if r.min_element() < 0.0 {
                return Err(SceneError::invalid(path, "environment.radiance", format!("{r} must be non-negative")));
            }
            Ok(Environment::Constant(r))
        }
        EnvironmentDesc::Map { file, scale, rotate_y } => {
            if !(scale.is_finite() && *scale >= 0.0) {
                return Err(SceneError::invalid(
                    path,
                    "environment.scale",
                    format!("{scale} must be finite and non-negative"),
                ));
            }
            if !rotate_y.is_finite() {
                return Err(SceneError::invalid(path, "environment.rotate_y", "must be a finite angle in degrees"));
            }
            load_map(&folder.join(file), *scale, Mat3::from_rotation_y(rotate_y.to_radians()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("evblur-desc-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

    #[test]
    fn loads_mesh_camera_and_environment() {
        let dir = temp_dir("ok");
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(dir.join("meshes/tri.obj"), TRI).unwrap();
        let toml = dir.join("scene.toml");
        std::fs::write(
            &toml,
            r#"scene = "meshes/tri.obj"
[camera]
origin = [0.0, 1.0, 3.4]
target = [0.0, 1.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 39.3
fov_axis = "x"
aspect = 1.5
[environment]
type = "constant"
radiance = [1.0, 0.5, 0.25]
"#,
        )
        .unwrap();
        let s = super::super::load(&toml).unwrap();
        assert_eq!(s.mesh.len(), 1);
        assert_eq!(s.source, toml);
        let cam = &s.cameras[0];
        assert!((cam.origin() - Vec3::new(0.0, 1.0, 3.4)).length() < 1e-6);
        // looks down -Z towards the target
        assert!((cam.to_world.transform_vector3(-Vec3::Z) - -Vec3::Z).length() < 1e-6);
        let expected = Camera::yfov_from_xfov(39.3f32.to_radians(), 600, 400);
        assert!((cam.yfov - expected).abs() < 1e-6, "{} vs {expected}", cam.yfov);
        assert_eq!(s.environment, Environment::Constant(Vec3::new(1.0, 0.5, 0.25)));
    }

    #[test]
    fn map_environment_with_rotation() {
        let dir = temp_dir("map");
        std::fs::write(dir.join("tri.obj"), TRI).unwrap();
        exr::prelude::write_rgb_file(dir.join("sky.exr"), 8, 4, |x, _| (x as f32, 1.0f32, 1.0f32)).unwrap();
        let toml = dir.join("s.toml");
        std::fs::write(
            &toml,
            "scene = \"tri.obj\"\n[environment]\ntype = \"map\"\nfile = \"sky.exr\"\nscale = 2.0\nrotate_y = 90.0\n",
        )
        .unwrap();
        let s = load(&toml).unwrap();
        let Environment::Map(m) = &s.environment else { panic!("{:?}", s.environment) };
        assert_eq!(m.scale, 2.0);
        // rotating +Z (the image centre) by 90 degrees about +Y gives +X
        assert!((m.to_world * Vec3::Z - Vec3::X).length() < 1e-6);
        assert!((m.uv(Vec3::X) - glam::Vec2::new(0.5, 0.5)).length() < 1e-5);
        assert!(s.cameras.is_empty());
    }

    #[test]
    fn rejects_unknown_keys_and_bad_values() {
        let dir = temp_dir("bad");
        std::fs::write(dir.join("tri.obj"), TRI).unwrap();
        let run = |name: &str, text: &str| {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            load(&p).unwrap_err().to_string()
        };
        let cam = |extra: &str| {
            format!("scene = \"tri.obj\"\n[camera]\norigin = [0.0, 0.0, 1.0]\ntarget = [0.0, 0.0, 0.0]\n{extra}\n")
        };

        let e = run("unknown.toml", &cam("fov = 40.0\naspect = 1.0\nfocal = 3.0"));
        assert!(e.contains("unknown.toml") && e.contains("focal"), "{e}");
        let e = run(
            "unknown_env.toml",
            "scene = \"tri.obj\"\n[environment]\ntype = \"constant\"\nradiance = [1.0, 1.0, 1.0]\nfile = \"x\"\n",
        );
        assert!(e.contains("file"), "{e}");
        let e = run("fov.toml", &cam("fov = 180.0\naspect = 1.0"));
        assert!(e.contains("camera.fov"), "{e}");
        let e = run("fov0.toml", &cam("fov = 0.0\nfov_axis = \"y\""));
        assert!(e.contains("camera.fov"), "{e}");
        let e = run("aspect.toml", &cam("fov = 40.0"));
        assert!(e.contains("camera.aspect"), "{e}");
        let e =
            run("neg.toml", "scene = \"tri.obj\"\n[environment]\ntype = \"constant\"\nradiance = [1.0, -1.0, 1.0]\n");
        assert!(e.contains("environment.radiance"), "{e}");
        let e =
            run("nan.toml", "scene = \"tri.obj\"\n[environment]\ntype = \"constant\"\nradiance = [nan, 1.0, 1.0]\n");
        assert!(e.contains("environment.radiance"), "{e}");
        let e = run("syntax.toml", "scene = \"tri.obj\n");
        assert!(e.contains("syntax.toml") && e.contains("line 1"), "{e}");
        let e = run("self.toml", "scene = \"self.toml\"\n");
        assert!(e.contains("scene"), "{e}");
        let e = run("type.toml", "scene = \"tri.obj\"\n[environment]\ntype = \"sky\"\n");
        assert!(e.contains("sky"), "{e}");
    }
}
