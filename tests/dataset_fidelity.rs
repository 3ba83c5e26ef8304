//! `evsim dataset-fidelity` on known answers: a textured plane under a constant sky, lit
//! directly (its reference is exact up to antialiasing), where the dataset's frames must explain
//! the brightness changes almost perfectly; and a deliberately noisy setting (1 spp, no filter,
//! new random numbers every frame) under a small lamp, which must score low.

use std::path::{Path, PathBuf};

use evblur_tests::temp_dir;
use glam::Vec3;
use simulator::base::image::Image;
use simulator::dataset::fidelity::{measure, FidelityOptions};
use simulator::dataset::{Overrides, Plan};

/// A 10 x 10 m textured floor (smooth sinusoidal albedo) and, with `lamp`, a small emitter
/// above it and a box casting a soft shadow; the camera looks down from 2 m and slides sideways
/// at about half a pixel per frame.
fn plane_scene(dir: &Path, lamp: bool, dataset: &str) -> PathBuf {
    let n = 256u32;
    let mut tex = Image::new(n, n);
    for (i, p) in tex.pixels.iter_mut().enumerate() {
        let (u, v) = ((i as u32 % n) as f32 / n as f32, (i as u32 / n) as f32 / n as f32);
        let a = 0.5 + 0.5 * (std::f32::consts::TAU * 28.0 * u).sin() * (std::f32::consts::TAU * 20.0 * v).cos();
        *p = Vec3::new(0.15 + 0.6 * a, 0.2 + 0.5 * a, 0.3 + 0.3 * a);
    }
    simulator::image_io::write_image(&tex, &dir.join("albedo.png")).unwrap();
    let mut obj = String::from(
        "mtllib scene.mtl\nv -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n\
         usemtl floor\nf 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n",
    );
    let mut mtl = String::from("newmtl floor\nKd 1 1 1\nmap_Kd albedo.png\n");
    if lamp {
        // a 0.3 m square lamp facing down at 1.2 m, and a 0.4 m box on the floor below it
        obj += "v -0.15 1.2 -0.15\nv 0.15 1.2 -0.15\nv 0.15 1.2 0.15\nv -0.15 1.2 0.15\nvn 0 -1 0\n\
                usemtl lamp\nf 5//2 6//2 7//2\nf 5//2 7//2 8//2\n";
        let (lo, hi) = (Vec3::new(0.1, 0.0, -0.3), Vec3::new(0.5, 0.4, 0.1));
        let mut k = 9;
        for (axis, sign) in [(0, -1.0f32), (0, 1.0), (1, 1.0), (2, -1.0), (2, 1.0)] {
            let c = |a: f32, b: f32| {
                let mut p = Vec3::ZERO;
                let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
                p[axis] = if sign > 0.0 { hi[axis] } else { lo[axis] };
                p[i] = if a > 0.0 { hi[i] } else { lo[i] };
                p[j] = if b > 0.0 { hi[j] } else { lo[j] };
                p
            };
            for p in [c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)] {
                obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
            }
            obj += &format!("usemtl box\nf {} {} {}\nf {} {} {}\n", k, k + 1, k + 2, k, k + 2, k + 3);
            k += 4;
        }
        mtl += "newmtl lamp\nKd 0 0 0\nKe 40 36 30\nnewmtl box\nKd 0.6 0.6 0.6\n";
    }
    std::fs::write(dir.join("scene.obj"), obj).unwrap();
    std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
    let toml = dir.join("scene.toml");
    std::fs::write(
        &toml,
        format!(
            r#"scene = "scene.obj"
[camera]
origin = [-0.6, 2.0, 0.8]
target = [-0.6, 0.0, 0.0]
fov = 40.0
fov_axis = "y"
[environment]
type = "constant"
radiance = [{sky}]
[trajectory]
type = "keys"
[[trajectory.keys]]
t = 0.0
position = [-0.6, 2.0, 0.8]
look_at = [-0.6, 0.0, 0.0]
[[trajectory.keys]]
t = 0.06
position = [0.7, 2.0, 0.8]
look_at = [0.7, 0.0, 0.0]
[dataset]
width = 48
height = 32
views = 2
exposure_ms = 4.0
first_view_ms = 10.0
spacing_ms = 30.0
{dataset}
"#,
            sky = if lamp { "0.05, 0.05, 0.05" } else { "0.8, 0.8, 0.8" },
        ),
    )
    .unwrap();
    toml
}

fn opts() -> FidelityOptions {
    FidelityOptions { frames: 25, ref_spp: 256, windows_ns: vec![1_000_000, 4_000_000], ..FidelityOptions::default() }
}

#[test]
fn an_exact_reference_is_explained_almost_perfectly() {
    for shading in ["path_traced", "surface_cache"] {
        let dir = temp_dir("fidelity", &format!("exact-{shading}"));
        let settings = format!("max_depth = 2\nshading = \"{shading}\"");
        let plan = Plan::resolve(&plane_scene(&dir, false, &settings), &Overrides::default()).unwrap();
        exact_plane_scores(shading, &plan);
    }
}

fn exact_plane_scores(shading: &str, plan: &Plan) {
    let r = measure(plan, &opts()).unwrap();
    println!("exact plane, {shading}: {r:?}");
    assert!(r.dataset.pairs > 1000, "the sliding texture fires events: {r:?}");
    assert!(r.dataset.pair_r2 >= 0.98, "pair r2 {} on an exact reference", r.dataset.pair_r2);
    assert!(r.dataset.sign_agreement >= 0.99, "{r:?}");
    // the ideal simulator on the reference: pairs exactly, windows up to quantisation
    assert!(r.ideal.pair_r2 > 0.999, "{r:?}");
    let ceiling = r.ceiling.as_ref().unwrap();
    for ((_, d), (_, c)) in r.dataset.windows.iter().zip(&ceiling.windows) {
        assert!(*d >= 0.9 * c, "windows: dataset {d} vs ceiling {c}");
    }
}

#[test]
fn per_frame_noise_scores_low() {
    let dir = temp_dir("fidelity", "noisy");
    let noisy = "max_depth = 3\nshading = \"path_traced\"\nspp = 1\ndenoise = false\nnoise_pattern = \"per_frame\"\nradiance_cache = 0";
    let plan = Plan::resolve(&plane_scene(&dir, true, noisy), &Overrides::default()).unwrap();
    let r = measure(&plan, &opts()).unwrap();
    println!("noisy lamp: {r:?}");
    assert!(r.dataset.pairs > 1000, "{r:?}");
    assert!(r.dataset.pair_r2 < 0.3, "per-frame noise must score low: {r:?}");
    // against the same reference, events from a converged render do well
    let ceiling = r.ceiling.as_ref().unwrap();
    assert!(ceiling.pair_r2 > 0.6 && ceiling.pair_r2 > r.dataset.pair_r2 + 0.3, "{r:?}");
}
