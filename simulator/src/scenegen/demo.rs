//! `gen_demo`: a small demonstration of the scene-generation API (about 24k triangles).
//!
//! A tiled ground with grime, a brick back wall, boxes (wood, a text-covered crate, a checker),
//! a striped glossy cylinder, a metal pole, a copper sphere with a noisy roughness map, a noise-
//! coloured glossy sphere, a torus, a striped cone, an extruded sign with text and one emissive
//! LED-text panel, lit by a constant sky. Objects stand at depths from 1.4 m in front of the
//! origin to 3 m behind it, so parallax differs across the camera's fast orbit.

use glam::{Affine3A, Quat, Vec2, Vec3};

use super::gltf_write::{MaterialDesc, PerspectiveCamera, SceneBuilder};
use super::mesh;
use super::texture::{self, Bricks, Fbm, Tiles, Wood};
use super::GeneratedScene;
use crate::scene::WrapMode;

/// Camera of the first view (also written to the glTF file and the `[camera]` table).
const EYE: Vec3 = Vec3::new(0.0, 1.6, 6.0);
/// Point the camera looks at.
const TARGET: Vec3 = Vec3::new(0.0, 0.8, -0.5);
/// Vertical field of view (degrees).
const FOV_Y_DEG: f32 = 40.0;

/// Translation-only placement.
fn at(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_translation(Vec3::new(x, y, z))
}

/// Build `gen_demo`.
pub fn gen_demo() -> GeneratedScene {
    let mut b = SceneBuilder::new();
    let repeat = WrapMode::Repeat;

    // ground: 14 m square of 0.5 m tiles with grout and grime, 256 px per 2 m
    let mut ground_px = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 4,
            rows: 4,
            grout_px: 3,
            grout: [70, 68, 64],
            colors: vec![[196, 190, 178], [168, 160, 150], [182, 176, 170]],
            random_pick: true,
            jitter: 0.08,
            seed: 11,
        },
    );
    texture::grime(&mut ground_px, &Fbm { cells: 2, octaves: 6, gain: 0.6, seed: 12 }, 0.5);
    let ground_tex = b.add_texture("ground_tiles", ground_px, repeat);
    let ground = b.add_material(MaterialDesc::glossy("ground", [1.0; 3], 0.55).with_texture(ground_tex));
    let m = b.add_mesh("ground", ground);
    mesh::plane(b.mesh_mut(m), Affine3A::IDENTITY, Vec2::splat(14.0), [48, 48], Vec2::splat(2.0));

    // back wall: bricks, 4 m x 2 m per repeat
    let bricks = texture::bricks(
        256,
        128,
        &Bricks {
            rows: 16,
            per_row: 8,
            mortar_px: 2,
            brick: [150, 70, 50],
            mortar: [190, 185, 175],
            jitter: 0.15,
            grain: 0.35,
            seed: 21,
        },
    );
    let wall_tex = b.add_texture("wall_bricks", bricks, repeat);
    let wall = b.add_material(MaterialDesc {
        specular: Some(0.3),
        ..MaterialDesc::diffuse("wall", [1.0; 3]).with_texture(wall_tex)
    });
    let m = b.add_mesh("wall", wall);
    let upright = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let wall_xf = Affine3A::from_rotation_translation(upright, Vec3::new(0.0, 2.0, -4.0));
    mesh::plane(b.mesh_mut(m), wall_xf, Vec2::new(14.0, 4.0), [28, 8], Vec2::new(4.0, 2.0));

    // boxes: wood, a crate papered with text, a checker cube
    let wood_px = texture::wood(
        256,
        256,
        &Wood { ring_px: 9.0, distortion: 1.5, stretch: 5.0, light: [214, 170, 118], dark: [120, 74, 38], seed: 31 },
    );
    let wood_tex = b.add_texture("wood", wood_px, repeat);
    let wood = b.add_material(MaterialDesc::glossy("wood", [1.0; 3], 0.35).with_texture(wood_tex));
    let m = b.add_mesh("wood_box", wood);
    let xf = Affine3A::from_rotation_translation(Quat::from_rotation_y(0.4), Vec3::new(-1.6, 0.4, 0.5));
    mesh::cuboid(b.mesh_mut(m), xf, Vec3::new(1.0, 0.8, 1.0), Vec2::splat(1.0));

    let page = texture::text_page(256, 256, 2, [30, 30, 40], [235, 230, 215], 8, 41);
    let page_tex = b.add_texture("text_page", page, repeat);
    let paper = b.add_material(MaterialDesc {
        specular: Some(0.0),
        ..MaterialDesc::diffuse("paper", [1.0; 3]).with_texture(page_tex)
    });
    let m = b.add_mesh("poster_crate", paper);
    let xf = Affine3A::from_rotation_translation(Quat::from_rotation_y(-0.3), Vec3::new(1.8, 0.8, -1.5));
    mesh::cuboid(b.mesh_mut(m), xf, Vec3::new(0.8, 1.6, 0.8), Vec2::splat(0.8));

    let checker_tex = b.add_texture("checker", texture::checker(64, 64, 8, [20, 20, 20], [230, 230, 230]), repeat);
    let checker = b.add_material(MaterialDesc::glossy("checker", [1.0; 3], 0.2).with_texture(checker_tex));
    let m = b.add_mesh("checker_cube", checker);
    let xf = Affine3A::from_rotation_translation(Quat::from_rotation_y(0.8), Vec3::new(-0.6, 0.35, -2.5));
    mesh::cuboid(b.mesh_mut(m), xf, Vec3::splat(0.7), Vec2::splat(0.35));

    // cylinders: fine glossy stripes, a metal pole
    let stripes = texture::stripes(128, 128, 30.0, 16.0, [230, 200, 40], [30, 30, 30]);
    let stripes_tex = b.add_texture("stripes", stripes, repeat);
    let striped = b.add_material(MaterialDesc::glossy("striped", [1.0; 3], 0.15).with_texture(stripes_tex));
    let m = b.add_mesh("striped_cylinder", striped);
    mesh::cylinder(b.mesh_mut(m), at(0.6, 0.7, 0.8), 0.35, 1.4, 96, 12, true, Vec2::splat(0.5));
    let steel = b.add_material(MaterialDesc::metal("steel", [0.9, 0.9, 0.92], 0.25));
    let m = b.add_mesh("pole", steel);
    mesh::cylinder(b.mesh_mut(m), at(-2.8, 1.1, -2.0), 0.2, 2.2, 64, 8, true, Vec2::ONE);

    // spheres: copper with a noisy roughness map, and a noise-coloured glossy ball
    let rough = texture::fbm_values(128, 64, &Fbm { cells: 4, octaves: 5, gain: 0.6, seed: 51 });
    let mr_tex = b.add_texture("copper_mr", texture::roughness_metallic(128, 64, &rough, 0.1, 0.6, 1.0), repeat);
    let copper = b.add_material(MaterialDesc {
        metallic_roughness_texture: Some(mr_tex),
        ..MaterialDesc::metal("copper", [0.95, 0.64, 0.54], 1.0)
    });
    let m = b.add_mesh("copper_sphere", copper);
    mesh::uv_sphere(
        b.mesh_mut(m),
        at(-0.2, 0.5, -0.8),
        0.5,
        96,
        48,
        Vec2::new(std::f32::consts::TAU * 0.5, std::f32::consts::PI * 0.5),
    );
    let marble_px = texture::fbm(
        256,
        128,
        &Fbm { cells: 3, octaves: 6, gain: 0.55, seed: 61 },
        &[(0.3, [20, 40, 90]), (0.5, [220, 220, 235]), (0.7, [150, 30, 40])],
    );
    let marble_tex = b.add_texture("marble", marble_px, repeat);
    let marble = b.add_material(MaterialDesc::glossy("marble", [1.0; 3], 0.3).with_texture(marble_tex));
    let m = b.add_mesh("marble_sphere", marble);
    mesh::uv_sphere(
        b.mesh_mut(m),
        at(2.4, 0.35, 1.0),
        0.35,
        64,
        32,
        Vec2::new(std::f32::consts::TAU * 0.35, std::f32::consts::PI * 0.35),
    );

    // a red torus lying on the crate, a striped cone
    let red = b.add_material(MaterialDesc::glossy("red_plastic", [0.7, 0.05, 0.04], 0.1));
    let m = b.add_mesh("torus", red);
    mesh::torus(b.mesh_mut(m), at(1.8, 1.68, -1.5), 0.28, 0.08, 48, 16, Vec2::splat(0.25));
    let cone_tex = b.add_texture(
        "cone_stripes",
        texture::stripes(64, 64, 45.0, 8.0 * std::f32::consts::SQRT_2, [240, 110, 20], [245, 245, 245]),
        repeat,
    );
    let cone_mat = b.add_material(MaterialDesc::diffuse("cone", [1.0; 3]).with_texture(cone_tex));
    let m = b.add_mesh("cone", cone_mat);
    mesh::cone(b.mesh_mut(m), at(-2.2, 0.4, 1.4), 0.35, 0.8, 48, 4, true, Vec2::splat(0.3));

    // an extruded sign with chamfered corners; its front cap shows the text exactly once
    let (w, h, c) = (2.0f32, 0.5f32, 0.06f32);
    let outline = [
        Vec2::new(c, 0.0),
        Vec2::new(w - c, 0.0),
        Vec2::new(w, -c),
        Vec2::new(w, c - h),
        Vec2::new(w - c, -h),
        Vec2::new(c, -h),
        Vec2::new(0.0, c - h),
        Vec2::new(0.0, -c),
    ];
    let sign_px = texture::sign(256, 64, &["EVBLUR DEMO", "EVENTS 1000 FPS"], 3, [250, 250, 250], [20, 70, 140], 3);
    let sign_tex = b.add_texture("sign", sign_px, WrapMode::ClampToEdge);
    let sign = b.add_material(MaterialDesc::glossy("sign", [1.0; 3], 0.4).with_texture(sign_tex));
    let m = b.add_mesh("sign", sign);
    mesh::extrude(b.mesh_mut(m), at(-1.0, 2.9, -3.0), &outline, 0.05, Vec2::new(w, h));
    let m = b.add_mesh("sign_posts", steel);
    for x in [-0.8, 0.8] {
        mesh::cylinder(b.mesh_mut(m), at(x, 1.2, -3.06), 0.03, 2.4, 16, 1, false, Vec2::ONE);
    }

    // the emissive LED board, facing the camera
    let led = texture::text_page(128, 64, 1, [255, 220, 150], [25, 12, 5], 4, 71);
    let led_tex = b.add_texture("led_board", led, WrapMode::ClampToEdge);
    let panel = b.add_material(MaterialDesc {
        emissive_texture: Some(led_tex),
        emissive_strength: 6.0,
        ..MaterialDesc::emitter("led_panel", [1.0, 0.85, 0.6])
    });
    let m = b.add_mesh("led_panel", panel);
    let board = [Vec2::new(0.0, 0.0), Vec2::new(1.6, 0.0), Vec2::new(1.6, -0.8), Vec2::new(0.0, -0.8)];
    let xf = Affine3A::from_rotation_translation(Quat::from_rotation_y(-0.35), Vec3::new(1.9, 2.4, -3.2));
    mesh::extrude(b.mesh_mut(m), xf, &board, 0.02, Vec2::new(1.6, 0.8));

    b.set_camera(PerspectiveCamera::look_at("view", EYE, TARGET, Vec3::Y, FOV_Y_DEG));
    GeneratedScene { builder: b, toml: toml_text() }
}

/// The dataset description of `gen_demo`.
fn toml_text() -> String {
    format!(
        r#"# gen_demo: a procedural demonstration scene written by `evsim scene generate --only gen_demo`
# (simulator/src/scenegen/demo.rs); regenerate rather than edit the glTF.
scene = "scene.gltf"

{camera_and_sky}
# a fast 0.25 s orbit in front of the objects
[trajectory]
type = "fast_motion"
target = [{tx:.1}, {ty:.1}, {tz:.1}]
radius = {radius:.1}
height = {height:.1}
start_azimuth_deg = -10.0
sweep_deg = 20.0
bob = 0.2
duration = 0.25

[dataset]
width = 96
height = 64
spp = 4
views = 9
first_view_ms = 25.0
exposure_ms = 20.0
"#,
        camera_and_sky = super::camera_path::camera_and_sky(EYE, TARGET, FOV_Y_DEG, 1, [0.5, 0.55, 0.6]),
        tx = TARGET.x,
        ty = TARGET.y,
        tz = TARGET.z,
        radius = EYE.z - TARGET.z,
        height = EYE.y - TARGET.y,
    )
}
