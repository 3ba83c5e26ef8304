//! `factory`: a factory hall seen from its open front, in the spirit of Ev-DeblurBlender's
//! `factory` sequence.
//!
//! Depth layers, near to far: a pallet of stencilled crates and a barrel group in the
//! foreground (2-4 m from the camera), a conveyor belt on rollers feeding a painted machine with
//! a control desk and its glowing screen, a steel tank with a valve wheel, pallet racks full of
//! labelled cardboard boxes on the left, and the back wall (bricks below, corrugated sheet above)
//! carrying pipes with flanges, signs, a notice board, a door with a lit EXIT sign and a row of
//! glowing windows, under open roof trusses. Detail at several scales: fine corrugation and belt
//! ridges, 5x7 text on signs, labels and pages, fBm grime, concrete slabs, bricks, wood rings.
//! Lit by a constant sky, a low sun through the open roof and emissive windows, lamps and
//! screens. About 1 s of fast, non-planar hand-held motion (keys every 0.12 s).

use std::f32::consts::{FRAC_PI_2, PI};

use glam::{Affine3A, Quat, Vec2, Vec3};
use image::RgbImage;

use super::camera_path::{keys_toml, Key};
use super::gltf_write::{MaterialDesc, PerspectiveCamera, SceneBuilder};
use super::mesh;
use super::texture::{self, Bricks, Fbm, Tiles, Wood};
use super::GeneratedScene;
use crate::base::sampling::Rng;
use crate::scene::{PunctualLight, WrapMode};

/// Camera of the first view (also written to the glTF file and the `[camera]` table).
const EYE: Vec3 = Vec3::new(-1.56, 1.75, 6.78);
/// Point the first view looks at.
const TARGET: Vec3 = Vec3::new(-0.64, 1.59, -3.0);
/// Vertical field of view (degrees).
const FOV_Y_DEG: f32 = 45.0;

/// Translation-only placement.
fn at(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_translation(Vec3::new(x, y, z))
}

/// Rotation about +Y by `yaw` (rad), then translation.
fn yaw_at(yaw: f32, x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_rotation_translation(Quat::from_rotation_y(yaw), Vec3::new(x, y, z))
}

/// A cylinder axis along +X (from the primitive's +Y), then translation.
fn along_x(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_rotation_translation(Quat::from_rotation_z(FRAC_PI_2), Vec3::new(x, y, z))
}

/// A cylinder axis along +Z (from the primitive's +Y), then translation.
fn along_z(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_rotation_translation(Quat::from_rotation_x(FRAC_PI_2), Vec3::new(x, y, z))
}

/// A `w` x `h` rectangle outline for [`mesh::extrude`] with its top-left corner at the origin.
fn rect(w: f32, h: f32) -> [Vec2; 4] {
    [Vec2::new(0.0, 0.0), Vec2::new(w, 0.0), Vec2::new(w, -h), Vec2::new(0.0, -h)]
}

/// A wood texture with a stencilled label, for crates.
fn crate_texture(seed: u64, label: &str) -> RgbImage {
    let mut img = texture::wood(
        256,
        256,
        &Wood { ring_px: 7.0, distortion: 1.8, stretch: 6.0, light: [206, 164, 112], dark: [128, 84, 44], seed },
    );
    // plank seams every 64 px
    for y in (0..256).step_by(64) {
        for x in 0..256 {
            img.put_pixel(x, y, image::Rgb([70, 45, 25]));
        }
    }
    let w = texture::text_width(label, 3) as i64;
    texture::draw_text(&mut img, label, (256 - w) / 2, 110, 3, [40, 32, 28]);
    texture::draw_text(
        &mut img,
        "THIS SIDE UP",
        (256 - texture::text_width("THIS SIDE UP", 2) as i64) / 2,
        150,
        2,
        [150, 30, 20],
    );
    texture::grime(&mut img, &Fbm { cells: 2, octaves: 5, gain: 0.6, seed: seed + 1 }, 0.35);
    img
}

/// Build `factory`.
pub fn factory() -> GeneratedScene {
    let mut b = SceneBuilder::new();
    let repeat = WrapMode::Repeat;
    let clamp = WrapMode::ClampToEdge;
    let mut rng = Rng::new(0xfac7, 1);

    // --- floor: concrete slabs (1.5 m) with grime, 256 px per 3 m; hazard lanes ------------
    let mut floor_px = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 2,
            rows: 2,
            grout_px: 2,
            grout: [60, 60, 58],
            colors: vec![[150, 148, 142], [138, 136, 132], [160, 156, 150]],
            random_pick: true,
            jitter: 0.06,
            seed: 101,
        },
    );
    texture::grime(&mut floor_px, &Fbm { cells: 3, octaves: 7, gain: 0.65, seed: 102 }, 0.6);
    let floor_tex = b.add_texture("concrete", floor_px, repeat);
    let floor = b.add_material(MaterialDesc::glossy("concrete", [1.0; 3], 0.6).with_texture(floor_tex));
    let m = b.add_mesh("floor", floor);
    mesh::plane(b.mesh_mut(m), at(0.0, 0.0, 0.0), Vec2::new(30.0, 26.0), [30, 26], Vec2::splat(3.0));

    let hazard_tex = b.add_texture(
        "hazard",
        texture::stripes(64, 64, 45.0, 16.0 * 2f32.sqrt() / 2.0, [235, 190, 20], [25, 25, 25]),
        repeat,
    );
    let hazard = b.add_material(MaterialDesc::glossy("hazard_paint", [1.0; 3], 0.4).with_texture(hazard_tex));
    let m = b.add_mesh("hazard_lanes", hazard);
    for x in [-2.4f32, 4.6] {
        mesh::plane(b.mesh_mut(m), at(x, 0.004, 0.0), Vec2::new(0.2, 16.0), [1, 16], Vec2::splat(0.4));
    }
    mesh::plane(b.mesh_mut(m), at(1.1, 0.004, 1.6), Vec2::new(7.2, 0.2), [8, 1], Vec2::splat(0.4));

    // --- back wall: bricks below, corrugated sheet above; a side wall on the left ---------
    let bricks = texture::bricks(
        256,
        128,
        &Bricks {
            rows: 16,
            per_row: 8,
            mortar_px: 2,
            brick: [140, 62, 44],
            mortar: [175, 170, 160],
            jitter: 0.18,
            grain: 0.4,
            seed: 111,
        },
    );
    let brick_tex = b.add_texture("bricks", bricks, repeat);
    let brick = b.add_material(MaterialDesc::diffuse("bricks", [1.0; 3]).with_texture(brick_tex));
    let m = b.add_mesh("brick_walls", brick);
    mesh::cuboid(b.mesh_mut(m), at(0.0, 1.25, -6.15), Vec3::new(26.0, 2.5, 0.3), Vec2::new(4.0, 2.0));
    mesh::cuboid(b.mesh_mut(m), at(-9.15, 1.25, 0.0), Vec3::new(0.3, 2.5, 12.6), Vec2::new(4.0, 2.0));

    let mut sheet_px = texture::stripes(256, 256, 90.0, 8.0, [150, 160, 168], [104, 114, 124]);
    texture::grime(&mut sheet_px, &Fbm { cells: 2, octaves: 6, gain: 0.6, seed: 121 }, 0.55);
    let sheet_tex = b.add_texture("corrugated", sheet_px, repeat);
    let sheet = b.add_material(MaterialDesc {
        specular: Some(0.6),
        ..MaterialDesc::glossy("corrugated_sheet", [1.0; 3], 0.35).with_texture(sheet_tex)
    });
    let m = b.add_mesh("sheet_walls", sheet);
    mesh::cuboid(b.mesh_mut(m), at(0.0, 5.0, -6.2), Vec3::new(26.0, 5.0, 0.2), Vec2::splat(2.0));
    mesh::cuboid(b.mesh_mut(m), at(-9.2, 5.0, 0.0), Vec3::new(0.2, 5.0, 12.6), Vec2::splat(2.0));

    // glowing windows high on the back wall (area lights)
    let window = b.add_material(MaterialDesc::emitter("window_glow", [3.2, 3.4, 3.8]));
    let m = b.add_mesh("windows", window);
    for i in 0..5 {
        let x = -8.0 + 3.6 * i as f32;
        mesh::extrude(b.mesh_mut(m), at(x, 6.6, -6.05), &rect(2.2, 1.1), 0.04, Vec2::new(2.2, 1.1));
    }
    let frame = b.add_material(MaterialDesc::glossy("dark_steel", [0.06, 0.065, 0.07], 0.3));
    let m = b.add_mesh("window_mullions", frame);
    for i in 0..5 {
        let x = -8.0 + 3.6 * i as f32;
        for k in 1..4 {
            mesh::cuboid(b.mesh_mut(m), at(x + 0.55 * k as f32, 6.05, -6.0), Vec3::new(0.05, 1.1, 0.06), Vec2::ONE);
        }
        mesh::cuboid(b.mesh_mut(m), at(x + 1.1, 6.05, -6.0), Vec3::new(2.2, 0.05, 0.06), Vec2::ONE);
    }

    // --- roof trusses (open roof: the sun comes through) -----------------------------------
    let truss_mat = b.add_material(MaterialDesc::glossy("truss_paint", [0.5, 0.52, 0.55], 0.45));
    let m = b.add_mesh("roof_trusses", truss_mat);
    for k in 0..5 {
        let z = -5.5 + 2.8 * k as f32;
        mesh::cuboid(b.mesh_mut(m), at(0.0, 7.6, z), Vec3::new(26.0, 0.35, 0.18), Vec2::ONE);
        for i in 0..13 {
            let x = -12.0 + 2.0 * i as f32;
            let xf = Affine3A::from_rotation_translation(Quat::from_rotation_z(0.6), Vec3::new(x, 7.2, z));
            mesh::cuboid(b.mesh_mut(m), xf, Vec3::new(0.9, 0.07, 0.07), Vec2::ONE);
        }
        mesh::cuboid(b.mesh_mut(m), at(0.0, 6.85, z), Vec3::new(26.0, 0.12, 0.12), Vec2::ONE);
    }

    // --- pipes along the back wall, flanges, a valve wheel --------------------------------
    let rough = texture::fbm_values(128, 128, &Fbm { cells: 4, octaves: 5, gain: 0.6, seed: 131 });
    let pipe_mr =
        b.add_texture("pipe_roughness", texture::roughness_metallic(128, 128, &rough, 0.15, 0.55, 1.0), repeat);
    let steel = b.add_material(MaterialDesc {
        metallic_roughness_texture: Some(pipe_mr),
        ..MaterialDesc::metal("brushed_steel", [0.82, 0.82, 0.84], 1.0)
    });
    let red_pipe = b.add_material(MaterialDesc::glossy("red_pipe", [0.55, 0.06, 0.04], 0.25));
    let m = b.add_mesh("steel_pipes", steel);
    for (y, r) in [(5.3f32, 0.16f32), (4.75, 0.1)] {
        mesh::cylinder(b.mesh_mut(m), along_x(0.0, y, -5.75), r, 26.0, 48, 26, false, Vec2::ONE);
        for i in 0..12 {
            let x = -11.0 + 2.0 * i as f32;
            mesh::cylinder(b.mesh_mut(m), along_x(x, y, -5.75), r + 0.04, 0.08, 32, 1, true, Vec2::ONE);
        }
    }
    // drops from the upper pipe into the tank and the machine
    for (x, z, y0) in [(5.4f32, -5.75f32, 3.4f32), (2.2, -5.75, 2.0)] {
        let h = 5.3 - y0;
        mesh::cylinder(b.mesh_mut(m), at(x, y0 + h / 2.0, z), 0.12, h, 32, 8, false, Vec2::ONE);
        mesh::uv_sphere(b.mesh_mut(m), at(x, 5.3, z), 0.19, 32, 16, Vec2::ONE);
    }
    let m = b.add_mesh("red_pipes", red_pipe);
    mesh::cylinder(b.mesh_mut(m), along_x(-3.0, 4.2, -5.8), 0.08, 12.0, 32, 12, false, Vec2::ONE);
    mesh::cylinder(b.mesh_mut(m), at(3.0, 2.1, -5.8), 0.08, 4.2, 32, 4, false, Vec2::ONE);
    mesh::uv_sphere(b.mesh_mut(m), at(3.0, 4.2, -5.8), 0.11, 24, 12, Vec2::ONE);
    mesh::torus(b.mesh_mut(m), along_z(3.0, 1.6, -5.55), 0.22, 0.03, 48, 12, Vec2::ONE);
    for a in 0..3 {
        let xf =
            Affine3A::from_rotation_translation(Quat::from_rotation_z(a as f32 * PI / 3.0), Vec3::new(3.0, 1.6, -5.55));
        mesh::cuboid(b.mesh_mut(m), xf, Vec3::new(0.44, 0.025, 0.025), Vec2::ONE);
    }

    // --- signs, notice board, door with an EXIT sign -----------------------------------------
    let sign_px = texture::sign(512, 96, &["EVBLUR WORKS", "HALL 7 LINE B"], 4, [245, 245, 240], [28, 60, 120], 4);
    let sign_tex = b.add_texture("hall_sign", sign_px, clamp);
    let sign = b.add_material(MaterialDesc::glossy("hall_sign", [1.0; 3], 0.3).with_texture(sign_tex));
    let m = b.add_mesh("hall_sign", sign);
    mesh::extrude(b.mesh_mut(m), at(-3.6, 3.9, -5.95), &rect(4.0, 0.75), 0.05, Vec2::new(4.0, 0.75));

    let danger_px =
        texture::sign(256, 128, &["DANGER", "HIGH VOLTAGE", "KEEP CLEAR"], 3, [20, 20, 20], [240, 196, 20], 6);
    let danger_tex = b.add_texture("danger_sign", danger_px, clamp);
    let danger = b.add_material(MaterialDesc::glossy("danger_sign", [1.0; 3], 0.35).with_texture(danger_tex));
    let m = b.add_mesh("danger_signs", danger);
    mesh::extrude(b.mesh_mut(m), at(0.6, 2.2, -5.95), &rect(1.2, 0.6), 0.03, Vec2::new(1.2, 0.6));
    mesh::extrude(b.mesh_mut(m), yaw_at(FRAC_PI_2, -8.95, 2.0, -1.0), &rect(1.0, 0.5), 0.03, Vec2::new(1.0, 0.5));

    let notice_px = texture::text_page(256, 256, 1, [25, 25, 35], [236, 232, 220], 6, 141);
    let notice_tex = b.add_texture("notice_board", notice_px, clamp);
    let notice = b.add_material(MaterialDesc {
        specular: Some(0.1),
        ..MaterialDesc::diffuse("notice", [1.0; 3]).with_texture(notice_tex)
    });
    let m = b.add_mesh("notice_board", notice);
    mesh::extrude(b.mesh_mut(m), at(-1.4, 2.1, -5.96), &rect(1.3, 1.3), 0.03, Vec2::new(1.3, 1.3));

    let door = b.add_material(MaterialDesc::glossy("door_paint", [0.12, 0.2, 0.3], 0.4));
    let m = b.add_mesh("door", door);
    mesh::cuboid(b.mesh_mut(m), at(7.2, 1.2, -5.97), Vec3::new(1.8, 2.4, 0.06), Vec2::ONE);
    let exit_tex =
        b.add_texture("exit_sign", texture::sign(128, 48, &["EXIT"], 5, [240, 255, 240], [10, 130, 50], 3), clamp);
    let exit = b.add_material(MaterialDesc {
        emissive_texture: Some(exit_tex),
        emissive_strength: 4.0,
        ..MaterialDesc::emitter("exit_sign", [1.0, 1.0, 1.0])
    });
    let m = b.add_mesh("exit_sign", exit);
    mesh::extrude(b.mesh_mut(m), at(6.8, 2.85, -5.95), &rect(0.8, 0.3), 0.04, Vec2::new(0.8, 0.3));

    // --- the press: painted body, housing, hopper, control desk with a glowing screen -------
    let mut paint_px = texture::fbm(
        256,
        256,
        &Fbm { cells: 4, octaves: 6, gain: 0.55, seed: 151 },
        &[(0.2, [58, 110, 84]), (0.6, [74, 132, 100]), (0.9, [96, 140, 110])],
    );
    texture::grime(&mut paint_px, &Fbm { cells: 2, octaves: 6, gain: 0.7, seed: 152 }, 0.5);
    let paint_tex = b.add_texture("machine_paint", paint_px, repeat);
    let paint = b.add_material(MaterialDesc::glossy("machine_paint", [1.0; 3], 0.22).with_texture(paint_tex));
    let m = b.add_mesh("press_body", paint);
    mesh::cuboid(b.mesh_mut(m), at(2.4, 0.9, -3.2), Vec3::new(3.0, 1.8, 2.0), Vec2::splat(2.0));
    mesh::cuboid(b.mesh_mut(m), at(2.4, 2.6, -3.4), Vec3::new(2.0, 1.6, 1.4), Vec2::splat(2.0));
    mesh::cuboid(b.mesh_mut(m), at(0.9, 0.65, -1.55), Vec3::new(0.9, 1.3, 0.5), Vec2::splat(2.0));
    let hopper = b.add_material(MaterialDesc::metal("galvanised", [0.7, 0.72, 0.74], 0.4));
    let m = b.add_mesh("hopper", hopper);
    let flip = Affine3A::from_rotation_translation(Quat::from_rotation_x(PI), Vec3::new(2.4, 3.95, -3.4));
    mesh::cone(b.mesh_mut(m), flip, 0.8, 1.1, 64, 8, true, Vec2::ONE);
    mesh::cylinder(b.mesh_mut(m), at(2.4, 4.75, -3.4), 0.8, 0.5, 64, 2, true, Vec2::ONE);
    // hydraulic rams on the body's front
    for x in [1.4f32, 3.4] {
        mesh::cylinder(b.mesh_mut(m), at(x, 2.35, -2.1), 0.12, 1.1, 32, 4, true, Vec2::ONE);
    }

    let screen_px = texture::text_page(128, 96, 1, [120, 255, 150], [5, 25, 10], 4, 161);
    let screen_tex = b.add_texture("control_screen", screen_px, clamp);
    let screen = b.add_material(MaterialDesc {
        emissive_texture: Some(screen_tex),
        emissive_strength: 3.0,
        ..MaterialDesc::emitter("control_screen", [1.0, 1.0, 1.0])
    });
    let m = b.add_mesh("control_screen", screen);
    let tilt = Affine3A::from_rotation_translation(Quat::from_rotation_x(-0.5), Vec3::new(0.6, 1.36, -1.28));
    mesh::extrude(b.mesh_mut(m), tilt, &rect(0.6, 0.4), 0.02, Vec2::new(0.6, 0.4));
    let red_btn = b.add_material(MaterialDesc::glossy("red_button", [0.8, 0.04, 0.03], 0.15));
    let green_btn = b.add_material(MaterialDesc::glossy("green_button", [0.05, 0.6, 0.1], 0.15));
    for (mat, x) in [(red_btn, 0.65f32), (green_btn, 0.9), (red_btn, 1.15)] {
        let m = b.add_mesh("button", mat);
        mesh::cylinder(b.mesh_mut(m), along_z(x, 0.95, -1.28), 0.06, 0.06, 24, 1, true, Vec2::ONE);
    }

    // --- steel tank with a ladder -----------------------------------------------------------
    let m = b.add_mesh("tank", steel);
    mesh::cylinder(b.mesh_mut(m), at(5.4, 1.7, -4.2), 0.9, 3.4, 96, 24, true, Vec2::ONE);
    mesh::uv_sphere(b.mesh_mut(m), at(5.4, 3.4, -4.2), 0.9, 96, 24, Vec2::ONE);
    for k in 0..4 {
        mesh::cylinder(b.mesh_mut(m), at(5.4, 0.4 + 0.9 * k as f32, -4.2), 0.93, 0.06, 96, 1, true, Vec2::ONE);
    }
    let tank_label = texture::sign(256, 64, &["TANK 2  HYDRAULIC OIL"], 2, [20, 20, 20], [236, 236, 228], 2);
    let label_tex = b.add_texture("tank_label", tank_label, clamp);
    let label = b.add_material(MaterialDesc::diffuse("tank_label", [1.0; 3]).with_texture(label_tex));
    let m = b.add_mesh("tank_label", label);
    mesh::extrude(b.mesh_mut(m), yaw_at(-0.3, 4.6, 2.2, -3.2), &rect(1.2, 0.3), 0.02, Vec2::new(1.2, 0.3));

    // --- conveyor: belt with fine ridges on rollers, legs -----------------------------------
    let belt_tex =
        b.add_texture("belt_ridges", texture::stripes(64, 64, 90.0, 4.0, [40, 40, 42], [70, 70, 74]), repeat);
    let belt = b.add_material(MaterialDesc::glossy("belt_rubber", [1.0; 3], 0.5).with_texture(belt_tex));
    let m = b.add_mesh("conveyor_belt", belt);
    mesh::cuboid(b.mesh_mut(m), at(-1.0, 0.92, -2.4), Vec3::new(4.6, 0.05, 0.8), Vec2::splat(0.25));
    let yellow = b.add_material(MaterialDesc::glossy("yellow_paint", [0.75, 0.52, 0.03], 0.3));
    let m = b.add_mesh("conveyor_frame", yellow);
    for z in [-2.85f32, -1.95] {
        mesh::cuboid(b.mesh_mut(m), at(-1.0, 0.86, z), Vec3::new(4.6, 0.16, 0.06), Vec2::ONE);
        for i in 0..4 {
            mesh::cuboid(b.mesh_mut(m), at(-3.0 + 1.33 * i as f32, 0.4, z), Vec3::new(0.08, 0.8, 0.08), Vec2::ONE);
        }
    }
    let m = b.add_mesh("rollers", steel);
    for i in 0..18 {
        mesh::cylinder(b.mesh_mut(m), along_z(-3.2 + 0.26 * i as f32, 0.84, -2.4), 0.045, 0.84, 24, 1, true, Vec2::ONE);
    }
    // parts riding on the belt
    let m = b.add_mesh("parts", hopper);
    for i in 0..5 {
        mesh::cylinder(b.mesh_mut(m), at(-2.8 + 0.9 * i as f32, 1.03, -2.4), 0.16, 0.16, 40, 1, true, Vec2::ONE);
        mesh::torus(b.mesh_mut(m), at(-2.8 + 0.9 * i as f32, 1.12, -2.4), 0.12, 0.03, 32, 10, Vec2::ONE);
    }

    // --- pallet racks with cardboard boxes (left) -------------------------------------------
    let blue = b.add_material(MaterialDesc::glossy("rack_blue", [0.05, 0.16, 0.5], 0.35));
    let orange = b.add_material(MaterialDesc::glossy("rack_orange", [0.8, 0.25, 0.02], 0.35));
    let mut card_px = texture::fbm(
        256,
        256,
        &Fbm { cells: 8, octaves: 5, gain: 0.5, seed: 171 },
        &[(0.3, [160, 120, 78]), (0.7, [190, 150, 100])],
    );
    for (i, word) in ["PART 4471", "LOT 0392", "BOLTS M8", "FRAGILE", "SPARES", "FILTERS"].iter().enumerate() {
        let (x, y) = ((i % 2) as i64 * 128 + 10, (i / 2) as i64 * 85 + 20);
        texture::draw_text(&mut card_px, word, x, y, 2, [30, 25, 20]);
        texture::draw_text(&mut card_px, "0 4 1 8 9 2 7", x, y + 24, 1, [30, 25, 20]);
        for k in 0..20 {
            // a barcode
            if (i * 7 + k * 3) % 5 < 3 {
                for yy in 0..14 {
                    card_px.put_pixel((x + 2 * k as i64) as u32, (y + 40 + yy) as u32, image::Rgb([20, 20, 20]));
                }
            }
        }
    }
    let card_tex = b.add_texture("cardboard", card_px, repeat);
    let card = b.add_material(MaterialDesc::diffuse("cardboard", [1.0; 3]).with_texture(card_tex));
    let rack = |b: &mut SceneBuilder, rng: &mut Rng, origin: Vec3, yaw: f32, bays: usize| {
        let xf = |x: f32, y: f32, z: f32| Affine3A::from_translation(origin) * yaw_at(yaw, 0.0, 0.0, 0.0) * at(x, y, z);
        let (bay, depth, height) = (1.8f32, 1.0f32, 4.2f32);
        let len = bay * bays as f32;
        let m = b.add_mesh("rack_uprights", blue);
        for i in 0..=bays {
            for z in [0.0, -depth] {
                mesh::cuboid(
                    b.mesh_mut(m),
                    xf(bay * i as f32, height / 2.0, z),
                    Vec3::new(0.09, height, 0.09),
                    Vec2::ONE,
                );
            }
            for k in 0..6 {
                let r = Affine3A::from_rotation_x(if k % 2 == 0 { 0.9 } else { -0.9 });
                mesh::cuboid(
                    b.mesh_mut(m),
                    xf(bay * i as f32, 0.35 + 0.7 * k as f32, -depth / 2.0) * r,
                    Vec3::new(0.03, 0.03, 1.25),
                    Vec2::ONE,
                );
            }
        }
        let m = b.add_mesh("rack_beams", orange);
        let deck = b.add_mesh("rack_boxes", card);
        for level in 0..3 {
            let y = 0.15 + 1.4 * level as f32;
            for z in [0.0, -depth] {
                mesh::cuboid(b.mesh_mut(m), xf(len / 2.0, y, z), Vec3::new(len, 0.12, 0.06), Vec2::ONE);
            }
            // boxes on the level
            for i in 0..bays {
                let mut x = bay * i as f32 + 0.1;
                while x < bay * (i + 1) as f32 - 0.5 {
                    let w = 0.35 + 0.35 * rng.next_f32();
                    let h = 0.3 + 0.7 * rng.next_f32();
                    let d = 0.5 + 0.4 * rng.next_f32();
                    if x + w > bay * (i + 1) as f32 - 0.08 {
                        break;
                    }
                    let tilt = (rng.next_f32() - 0.5) * 0.2;
                    let place = xf(x + w / 2.0, y + 0.06 + h / 2.0, -depth / 2.0) * Affine3A::from_rotation_y(tilt);
                    mesh::cuboid(b.mesh_mut(deck), place, Vec3::new(w, h, d), Vec2::splat(0.9 + 0.3 * rng.next_f32()));
                    x += w + 0.05 + 0.1 * rng.next_f32();
                }
            }
        }
    };
    rack(&mut b, &mut rng, Vec3::new(-8.2, 0.0, -4.3), 0.0, 3);
    rack(&mut b, &mut rng, Vec3::new(-7.8, 0.0, 2.6), FRAC_PI_2, 3);

    // --- foreground: pallets of crates, barrels, gas bottles --------------------------------
    let crate_a = b.add_texture("crate_a", crate_texture(181, "EVB 07"), repeat);
    let crate_b = b.add_texture("crate_b", crate_texture(183, "PRESS DIE"), repeat);
    let crate_ma = b.add_material(MaterialDesc::glossy("crate_a", [1.0; 3], 0.55).with_texture(crate_a));
    let crate_mb = b.add_material(MaterialDesc::glossy("crate_b", [1.0; 3], 0.55).with_texture(crate_b));
    let pallet = b.add_material(MaterialDesc::diffuse("pallet_wood", [0.45, 0.33, 0.2]));
    let pallet_at = |b: &mut SceneBuilder, xf: Affine3A| {
        let m = b.add_mesh("pallet", pallet);
        for k in 0..7 {
            mesh::cuboid(
                b.mesh_mut(m),
                xf * at(-0.54 + 0.18 * k as f32, 0.13, 0.0),
                Vec3::new(0.1, 0.025, 1.2),
                Vec2::ONE,
            );
        }
        for z in [-0.5f32, 0.0, 0.5] {
            mesh::cuboid(b.mesh_mut(m), xf * at(0.0, 0.06, z), Vec3::new(1.2, 0.11, 0.12), Vec2::ONE);
        }
    };
    let p1 = yaw_at(0.25, -2.0, 0.0, 2.4);
    pallet_at(&mut b, p1);
    let m = b.add_mesh("crates_a", crate_ma);
    mesh::cuboid(b.mesh_mut(m), p1 * at(0.0, 0.59, 0.0), Vec3::new(1.1, 0.9, 1.1), Vec2::splat(1.1));
    mesh::cuboid(b.mesh_mut(m), p1 * yaw_at(0.2, 0.05, 1.36, 0.05), Vec3::new(0.8, 0.64, 0.8), Vec2::splat(0.8));
    let p2 = yaw_at(-0.4, 3.2, 0.0, 2.9);
    pallet_at(&mut b, p2);
    let m = b.add_mesh("crates_b", crate_mb);
    mesh::cuboid(b.mesh_mut(m), p2 * at(0.0, 0.49, 0.0), Vec3::new(1.15, 0.7, 1.15), Vec2::splat(1.15));
    let m = b.add_mesh("crates_c", crate_ma);
    mesh::cuboid(b.mesh_mut(m), yaw_at(0.1, 0.6, 0.35, 0.4), Vec3::new(0.7, 0.7, 0.7), Vec2::splat(0.7));

    let barrel_tex =
        b.add_texture("barrel_bands", texture::stripes(64, 128, 0.0, 42.0, [20, 70, 150], [16, 54, 120]), repeat);
    let barrel = b.add_material(MaterialDesc::glossy("barrel_paint", [1.0; 3], 0.25).with_texture(barrel_tex));
    let m = b.add_mesh("barrels", barrel);
    for (x, z) in [(4.4f32, 0.6f32), (5.1, 0.9), (4.7, 1.5), (5.6, 0.2)] {
        mesh::cylinder(b.mesh_mut(m), at(x, 0.45, z), 0.3, 0.9, 64, 6, true, Vec2::splat(0.9));
    }
    let gas = b.add_material(MaterialDesc::glossy("gas_bottle", [0.1, 0.45, 0.15], 0.2));
    let m = b.add_mesh("gas_bottles", gas);
    for (x, z) in [(-4.0f32, -5.6f32), (-3.7, -5.65), (-3.4, -5.6)] {
        mesh::cylinder(b.mesh_mut(m), at(x, 0.75, z), 0.12, 1.5, 32, 4, false, Vec2::ONE);
        mesh::uv_sphere(b.mesh_mut(m), at(x, 1.5, z), 0.12, 32, 12, Vec2::ONE);
    }

    // --- hanging lamps over the machine (area lights) ---------------------------------------
    let lamp = b.add_material(MaterialDesc::emitter("lamp_panel", [9.0, 8.2, 6.8]));
    let m = b.add_mesh("lamp_panels", lamp);
    for (x, z) in [(-2.0f32, -2.5f32), (2.4, -1.2), (-5.5, -0.5)] {
        mesh::cuboid(b.mesh_mut(m), at(x, 4.6, z), Vec3::new(1.4, 0.04, 0.35), Vec2::ONE);
    }
    let m = b.add_mesh("lamp_cables", frame);
    for (x, z) in [(-2.0f32, -2.5f32), (2.4, -1.2), (-5.5, -0.5)] {
        for dx in [-0.6f32, 0.6] {
            mesh::cylinder(b.mesh_mut(m), at(x + dx, 6.1, z), 0.01, 2.9, 6, 1, false, Vec2::ONE);
        }
        mesh::cuboid(b.mesh_mut(m), at(x, 4.66, z), Vec3::new(1.5, 0.08, 0.42), Vec2::ONE);
    }

    b.add_light(PunctualLight::Directional {
        direction: Vec3::new(0.45, -0.8, -0.4).normalize(),
        irradiance: Vec3::new(2.4, 2.2, 1.9),
    });
    b.set_camera(PerspectiveCamera::look_at("view", EYE, TARGET, Vec3::Y, FOV_Y_DEG));
    GeneratedScene { builder: b, toml: toml_text() }
}

/// How far the hand-held path swings about its centre: 1 gives blur means of ~12 px at 40 ms,
/// 1.6 about 20 px (mean) and 70 px (max).
const SWING: f64 = 1.6;

/// The hand-held camera path: about 1.1 s, keys every 0.12 s, weaving sideways and up and down
/// while panning, at changing speed (up to ~8 m/s at 6-12 m depth), swung by [`SWING`] about
/// its centre.
fn keys() -> Vec<Key> {
    #[rustfmt::skip]
    const K: [([f64; 3], [f64; 3]); 10] = [
        ([-0.90, 1.75, 6.60], [-0.40, 1.50, -3.0]),
        ([-0.45, 1.95, 6.45], [ 0.20, 1.35, -3.0]),
        ([ 0.15, 1.85, 6.20], [ 0.90, 1.10, -3.0]),
        ([ 0.50, 1.55, 6.05], [ 0.80, 1.30, -3.0]),
        ([ 1.10, 1.50, 6.30], [ 0.20, 1.70, -3.0]),
        ([ 1.35, 1.80, 6.55], [-0.50, 1.50, -3.0]),
        ([ 0.95, 2.05, 6.40], [-1.20, 1.15, -3.0]),
        ([ 0.30, 1.85, 6.10], [-0.90, 1.00, -3.0]),
        ([-0.20, 1.55, 6.20], [ 0.00, 1.35, -3.0]),
        ([-0.70, 1.70, 6.50], [ 0.60, 1.60, -3.0]),
    ];
    const CENTRE: [f64; 3] = [0.2, 1.75, 6.3];
    const LOOK_CENTRE: [f64; 3] = [0.0, 1.35, -3.0];
    let swing = |p: [f64; 3], c: [f64; 3]| [0, 1, 2].map(|j| c[j] + SWING * (p[j] - c[j]));
    K.iter()
        .enumerate()
        .map(|(i, &(p, l))| Key { t: 0.12 * i as f64, position: swing(p, CENTRE), look_at: swing(l, LOOK_CENTRE) })
        .collect()
}

/// The dataset description of `factory`.
fn toml_text() -> String {
    format!(
        r#"# factory: a benchmark scene written by `evsim scene generate --only factory`
# (simulator/src/scenegen/factory.rs); regenerate rather than edit.
scene = "scene.gltf"

{camera_and_sky}
# fast hand-held motion, about 1 s
{traj}
# defaults: the paper's 600x400, 1000 FPS, 40 ms exposure and threshold 0.2 ([events]);
# surface-cache frames, 32 camera samples
# max_depth 3 (direct light plus one bounce) keeps 1000 frames affordable in this open hall;
# glossy_grid_alpha 0.05: the paints' highlights at grazing angles (alpha 0.06 to 0.09) read the
# glossy grids, for half the frame time at the same fidelity (`evsim dataset-fidelity`);
# glossy keyframes every 128 frames: the rough lobes' light changes slowly along this path
# (the same fidelity as every 32, 4% less time: benchmark/results/2026-12-05-dataset-time.md)
[dataset]
views = 30
sharp_every = 8
max_depth = 3
glossy_grid_alpha = 0.05
glossy_stride = 128
"#,
        camera_and_sky = super::camera_path::camera_and_sky(EYE, TARGET, FOV_Y_DEG, 2, [0.42, 0.47, 0.55]),
        traj = keys_toml(&keys()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factory_is_rich() {
        let s = factory();
        assert!(s.builder.triangle_count() >= 20_000, "{}", s.builder.triangle_count());
        assert!(s.builder.materials.iter().filter(|m| m.emissive != [0.0; 3]).count() >= 2);
    }
}
