//! `trolley`: a tram street seen from a passing vehicle (a benchmark scene in the spirit of
//! Deblur-NeRF's "trolley").
//!
//! The street runs along X. From the camera (at z = +6, looking towards -Z) the depth layers are:
//! catenary poles and a bus-stop sign on the near kerb (1.4-2 m), the cobbled roadway with two
//! pairs of steel rails, a green-and-cream trolley car with windows, a destination sign and an
//! advertising panel on the far track (7-9 m), its trolley pole reaching the overhead wires,
//! then the far pavement with street lamps and a row of shop facades (brick, plaster, tiles)
//! with text signs, striped awnings, lit shop windows and posters (14-17 m). Lit by a daylight
//! sky (constant environment), the sun and the emissive shop windows and headlight.
//!
//! The camera dollies sideways along the street at about 5 m/s with a small wobble, as if
//! riding past: every view blurs along the same (horizontal) axis, the motion image-only
//! deblurring finds hardest.

use std::f32::consts::FRAC_PI_2;

use glam::{Affine3A, Quat, Vec2, Vec3};
use image::{Rgb, RgbImage};

use super::gltf_write::{MaterialDesc, MaterialId, PerspectiveCamera, SceneBuilder};
use super::mesh;
use super::texture::{self, Bricks, Fbm, Srgb, Tiles};
use super::GeneratedScene;
use crate::base::sampling::Rng;
use crate::scene::{PunctualLight, WrapMode};

/// Camera of the first view (also the `[camera]` table).
const EYE: Vec3 = Vec3::new(-3.0, 1.7, 6.0);
/// Point the first view looks at.
const TARGET: Vec3 = Vec3::new(-2.2, 1.9, -8.0);
/// Vertical field of view (degrees).
const FOV_Y_DEG: f32 = 40.0;
/// Half-length of the modelled street along X (m).
const HALF_LEN: f32 = 18.0;
/// z of the shop facades' front (m).
const FACADE_Z: f32 = -8.0;

/// Translation-only placement.
fn at(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_translation(Vec3::new(x, y, z))
}

/// Uniform in [lo, hi).
fn uniform(rng: &mut Rng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.next_f32()
}

/// Build `trolley`.
pub fn trolley() -> GeneratedScene {
    let mut b = SceneBuilder::new();
    let mut rng = Rng::new(0x7201_1e70, 3);
    let steel = b.add_material(MaterialDesc::metal("rail_steel", [0.75, 0.75, 0.78], 0.25));
    let dark_metal = b.add_material(MaterialDesc::glossy("pole_paint", [0.05, 0.09, 0.07], 0.3));
    road(&mut b, steel);
    facades(&mut b, &mut rng);
    tram(&mut b, steel);
    poles_and_wires(&mut b, dark_metal);
    street_furniture(&mut b, &mut rng, steel, dark_metal);
    b.add_light(PunctualLight::Directional {
        direction: Vec3::new(0.4, -0.7, -0.55).normalize(),
        irradiance: Vec3::new(3.0, 2.8, 2.5),
    });
    b.set_camera(PerspectiveCamera::look_at("view", EYE, TARGET, Vec3::Y, FOV_Y_DEG));
    GeneratedScene { builder: b, toml: toml_text() }
}

/// Roadway (cobbles), pavements (tiles), kerbs and two tracks of rails.
fn road(b: &mut SceneBuilder, steel: MaterialId) {
    let repeat = WrapMode::Repeat;
    let mut cobbles = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 10,
            rows: 14,
            grout_px: 2,
            grout: [50, 48, 46],
            colors: vec![[120, 116, 110], [104, 100, 96], [134, 128, 118], [96, 94, 92]],
            random_pick: true,
            jitter: 0.12,
            seed: 401,
        },
    );
    texture::grime(&mut cobbles, &Fbm { cells: 3, octaves: 6, gain: 0.6, seed: 402 }, 0.4);
    let cobble_tex = b.add_texture("cobbles", cobbles, repeat);
    let cobble = b.add_material(MaterialDesc::glossy("cobbles", [1.0; 3], 0.55).with_texture(cobble_tex));
    let m = b.add_mesh("roadway", cobble);
    let road_w = 9.0;
    mesh::plane(b.mesh_mut(m), at(0.0, 0.0, 0.0), Vec2::new(2.0 * HALF_LEN + 20.0, road_w), [56, 12], Vec2::splat(2.0));

    let mut slabs = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 4,
            rows: 4,
            grout_px: 2,
            grout: [90, 88, 84],
            colors: vec![[182, 176, 166], [170, 166, 158]],
            random_pick: true,
            jitter: 0.05,
            seed: 403,
        },
    );
    texture::grime(&mut slabs, &Fbm { cells: 2, octaves: 5, gain: 0.55, seed: 404 }, 0.3);
    let slab_tex = b.add_texture("pavement", slabs, repeat);
    let slab = b.add_material(MaterialDesc::diffuse("pavement", [1.0; 3]).with_texture(slab_tex));
    let m = b.add_mesh("pavements", slab);
    let w = 2.0 * HALF_LEN + 20.0;
    // far pavement up to the facades, near pavement under the camera (raised 0.12 m)
    let far = -road_w / 2.0 - FACADE_Z;
    mesh::cuboid(b.mesh_mut(m), at(0.0, 0.06, FACADE_Z + far / 2.0), Vec3::new(w, 0.12, far), Vec2::splat(2.0));
    mesh::cuboid(b.mesh_mut(m), at(0.0, 0.06, 6.5), Vec3::new(w, 0.12, 4.0), Vec2::splat(2.0));

    // two tracks (gauge 1.435 m) at z = 0 (near) and z = -2.6 (far): rails as thin boxes
    let m = b.add_mesh("rails", steel);
    for zc in [0.0f32, -2.6] {
        for dz in [-0.7175, 0.7175] {
            mesh::cuboid(b.mesh_mut(m), at(0.0, 0.015, zc + dz), Vec3::new(w, 0.03, 0.07), Vec2::ONE);
        }
    }
}

/// A row of shop facades with signs, awnings, windows, posters and doors.
fn facades(b: &mut SceneBuilder, rng: &mut Rng) {
    let repeat = WrapMode::Repeat;
    let brick = |b: &mut SceneBuilder, name: &str, c: Srgb, seed: u64| {
        let px = texture::bricks(
            256,
            128,
            &Bricks {
                rows: 16,
                per_row: 8,
                mortar_px: 2,
                brick: c,
                mortar: [200, 195, 185],
                jitter: 0.15,
                grain: 0.35,
                seed,
            },
        );
        let t = b.add_texture(name, px, repeat);
        b.add_material(MaterialDesc { specular: Some(0.3), ..MaterialDesc::diffuse(name, [1.0; 3]).with_texture(t) })
    };
    let walls = [
        brick(b, "brick_red", [150, 68, 48], 501),
        brick(b, "brick_yellow", [190, 160, 100], 502),
        {
            let px = texture::fbm(
                256,
                256,
                &Fbm { cells: 4, octaves: 6, gain: 0.6, seed: 503 },
                &[(0.3, [200, 190, 170]), (0.7, [232, 224, 205])],
            );
            let t = b.add_texture("plaster", px, repeat);
            b.add_material(MaterialDesc::diffuse("plaster", [1.0; 3]).with_texture(t))
        },
        {
            let px = texture::tiles(
                256,
                256,
                &Tiles {
                    cols: 16,
                    rows: 16,
                    grout_px: 1,
                    grout: [230, 230, 225],
                    colors: vec![[40, 110, 100], [50, 120, 110], [36, 100, 92]],
                    random_pick: true,
                    jitter: 0.1,
                    seed: 504,
                },
            );
            let t = b.add_texture("glazed_tiles", px, repeat);
            b.add_material(MaterialDesc::glossy("glazed_tiles", [1.0; 3], 0.15).with_texture(t))
        },
    ];
    let awning_mats: Vec<MaterialId> = [([170, 30, 30], "red"), ([30, 90, 60], "green"), ([40, 60, 150], "blue")]
        .iter()
        .map(|&(c, n)| {
            let t = b.add_texture(
                &format!("awning_{n}"),
                texture::stripes(128, 128, 90.0, 16.0, c, [240, 236, 225]),
                repeat,
            );
            b.add_material(MaterialDesc::diffuse(&format!("awning_{n}"), [1.0; 3]).with_texture(t))
        })
        .collect();
    // lit shop windows: goods shelves (text-like rows) glowing behind the glass
    let shelf_px = texture::text_page(256, 128, 1, [60, 40, 30], [255, 236, 200], 6, 505);
    let shelf_tex = b.add_texture("shop_window", shelf_px, repeat);
    let window = b.add_material(MaterialDesc {
        emissive_texture: Some(shelf_tex),
        emissive_strength: 1.2,
        ..MaterialDesc::emitter("shop_window", [1.0, 0.9, 0.75])
    });
    let upper_px =
        RgbImage::from_fn(64, 64, |x, y| Rgb(if x % 32 < 2 || y % 32 < 2 { [230; 3] } else { [40, 50, 60] }));
    let upper_tex = b.add_texture("upper_windows", upper_px, repeat);
    let upper = b.add_material(MaterialDesc::glossy("upper_windows", [1.0; 3], 0.05).with_texture(upper_tex));
    let poster_px = texture::text_page(128, 192, 2, [240, 240, 240], [30, 40, 110], 6, 506);
    let poster_tex = b.add_texture("poster", poster_px, WrapMode::ClampToEdge);
    let poster = b.add_material(MaterialDesc::diffuse("poster", [1.0; 3]).with_texture(poster_tex));
    let door = b.add_material(MaterialDesc::glossy("door_paint", [0.25, 0.08, 0.05], 0.3));
    let trim = b.add_material(MaterialDesc::glossy("trim", [0.85, 0.84, 0.8], 0.4));

    const SHOPS: [&str; 9] =
        ["BAKERY", "CAFE 24", "BOOKS", "PHARMACY", "FLOWERS", "TAILOR", "HARDWARE", "NEWS", "DELI"];
    const SIGN_COLORS: [(Srgb, Srgb); 4] = [
        ([250, 240, 210], [120, 20, 30]),
        ([20, 20, 20], [240, 200, 60]),
        ([240, 240, 240], [20, 50, 110]),
        ([250, 250, 250], [30, 100, 50]),
    ];
    let wall_meshes: Vec<_> = walls.iter().enumerate().map(|(i, &w)| b.add_mesh(&format!("facades_{i}"), w)).collect();
    let awn_meshes: Vec<_> =
        awning_mats.iter().enumerate().map(|(i, &w)| b.add_mesh(&format!("awnings_{i}"), w)).collect();
    let windows = b.add_mesh("shop_windows", window);
    let uppers = b.add_mesh("upper_windows", upper);
    let posters = b.add_mesh("posters", poster);
    let doors = b.add_mesh("doors", door);
    let trims = b.add_mesh("trim", trim);
    let shop_w = 4.4;
    let n = 10;
    for i in 0..n {
        let x0 = -HALF_LEN - 4.0 + i as f32 * shop_w;
        let xc = x0 + shop_w / 2.0;
        let h = uniform(rng, 7.0, 11.0);
        let depth = 5.0;
        // the building block, its front face at FACADE_Z
        mesh::cuboid(
            b.mesh_mut(wall_meshes[i % walls.len()]),
            at(xc, h / 2.0, FACADE_Z - depth / 2.0),
            Vec3::new(shop_w - 0.05, h, depth),
            Vec2::new(2.0, 1.0),
        );
        // cornice
        mesh::cuboid(
            b.mesh_mut(trims),
            at(xc, h + 0.1, FACADE_Z - depth / 2.0 + 0.1),
            Vec3::new(shop_w + 0.1, 0.2, depth + 0.2),
            Vec2::ONE,
        );
        // upper windows in a grid
        let floors = ((h - 3.6) / 2.6).floor() as i32;
        for f in 0..floors {
            for wx in [-1.3, 0.0, 1.3] {
                let y = 4.6 + f as f32 * 2.6;
                mesh::cuboid(
                    b.mesh_mut(uppers),
                    at(xc + wx, y, FACADE_Z + 0.03),
                    Vec3::new(0.8, 1.3, 0.06),
                    Vec2::new(0.8, 1.3),
                );
                mesh::cuboid(
                    b.mesh_mut(trims),
                    at(xc + wx, y - 0.72, FACADE_Z + 0.08),
                    Vec3::new(1.0, 0.1, 0.16),
                    Vec2::ONE,
                );
            }
        }
        // shop window and door
        mesh::cuboid(
            b.mesh_mut(windows),
            at(xc - 0.5, 1.45, FACADE_Z + 0.03),
            Vec3::new(2.6, 1.9, 0.06),
            Vec2::new(2.6, 1.3),
        );
        mesh::cuboid(b.mesh_mut(doors), at(xc + 1.45, 1.15, FACADE_Z + 0.04), Vec3::new(0.9, 2.3, 0.08), Vec2::ONE);
        // sign board with the shop's name, above the window
        let (fg, bg) = SIGN_COLORS[i % SIGN_COLORS.len()];
        let name = SHOPS[i % SHOPS.len()];
        let t =
            b.add_texture(&format!("sign_{i}"), texture::sign(256, 48, &[name], 3, fg, bg, 3), WrapMode::ClampToEdge);
        let mat = b.add_material(MaterialDesc::glossy(&format!("sign_{i}"), [1.0; 3], 0.35).with_texture(t));
        let m = b.add_mesh(&format!("sign_{i}"), mat);
        let (sw, sh) = (3.6f32, 0.62f32);
        let outline = [Vec2::new(0.0, 0.0), Vec2::new(sw, 0.0), Vec2::new(sw, -sh), Vec2::new(0.0, -sh)];
        mesh::extrude(b.mesh_mut(m), at(xc - sw / 2.0, 3.45, FACADE_Z + 0.06), &outline, 0.08, Vec2::new(sw, sh));
        // striped awning sloping out over the pavement
        let awn =
            Affine3A::from_rotation_translation(Quat::from_rotation_x(0.35), Vec3::new(xc - 0.3, 2.7, FACADE_Z + 0.65));
        mesh::cuboid(b.mesh_mut(awn_meshes[i % awn_meshes.len()]), awn, Vec3::new(3.2, 0.03, 1.4), Vec2::new(1.0, 1.0));
        // a poster beside the door on every other shop
        if i % 2 == 0 {
            mesh::cuboid(
                b.mesh_mut(posters),
                at(xc + 1.45, 2.75, FACADE_Z + 0.05),
                Vec3::new(0.6, 0.9, 0.02),
                Vec2::new(0.6, 0.9),
            );
        }
    }
}

/// The trolley car on the far track, with windows, signs and its trolley pole.
fn tram(b: &mut SceneBuilder, steel: MaterialId) {
    let repeat = WrapMode::Repeat;
    let body_px = {
        // cream upper band, green lower body, a thin red pin-stripe between them (1 m per 128 px)
        let noise = texture::fbm_values(128, 128, &Fbm { cells: 4, octaves: 4, gain: 0.5, seed: 601 });
        RgbImage::from_fn(128, 128, |x, y| {
            let n = 0.9 + 0.1 * noise[(y * 128 + x) as usize];
            let c: Srgb = if y < 60 {
                [236, 226, 196]
            } else if y < 64 {
                [160, 30, 30]
            } else {
                [30, 96, 64]
            };
            Rgb(texture::shade(c, n))
        })
    };
    let body_tex = b.add_texture("tram_body", body_px, repeat);
    let body = b.add_material(MaterialDesc::glossy("tram_paint", [1.0; 3], 0.2).with_texture(body_tex));
    let glass = b.add_material(MaterialDesc::glossy("tram_glass", [0.04, 0.05, 0.06], 0.05));
    let roof = b.add_material(MaterialDesc::glossy("tram_roof", [0.3, 0.3, 0.32], 0.5));
    let dest = b.add_texture(
        "tram_destination",
        texture::sign(256, 32, &["12 HARBOUR - CENTRAL"], 2, [255, 200, 60], [15, 12, 8], 2),
        WrapMode::ClampToEdge,
    );
    let dest_mat = b.add_material(MaterialDesc {
        emissive_texture: Some(dest),
        emissive_strength: 3.0,
        ..MaterialDesc::emitter("tram_destination", [1.0, 0.85, 0.5])
    });
    let ad = b.add_texture(
        "tram_advert",
        texture::sign(256, 64, &["RIDE THE 12", "EVERY 6 MIN"], 2, [30, 30, 30], [250, 200, 40], 3),
        WrapMode::ClampToEdge,
    );
    let ad_mat = b.add_material(MaterialDesc::glossy("tram_advert", [1.0; 3], 0.3).with_texture(ad));
    let num = b.add_texture(
        "tram_number",
        texture::sign(64, 64, &["12"], 4, [240, 240, 240], [30, 96, 64], 2),
        WrapMode::ClampToEdge,
    );
    let num_mat = b.add_material(MaterialDesc::glossy("tram_number", [1.0; 3], 0.3).with_texture(num));
    let lamp = b.add_material(MaterialDesc::emitter("tram_headlight", [6.0, 5.6, 4.8]));

    let (len, h, w, zc, x0) = (9.0f32, 2.6f32, 2.3f32, -2.6f32, 4.0f32);
    let floor = 0.45;
    let m = b.add_mesh("tram_body", body);
    mesh::cuboid(b.mesh_mut(m), at(x0, floor + h / 2.0, zc), Vec3::new(len, h, w), Vec2::splat(h));
    let m = b.add_mesh("tram_roof", roof);
    mesh::cuboid(b.mesh_mut(m), at(x0, floor + h + 0.1, zc), Vec3::new(len - 0.2, 0.2, w - 0.1), Vec2::ONE);
    mesh::cuboid(b.mesh_mut(m), at(x0, floor + h + 0.3, zc), Vec3::new(2.0, 0.2, 1.0), Vec2::ONE);
    // windows on the camera side (+Z), as dark glass panes proud of the body
    let mg = b.add_mesh("tram_windows", glass);
    let mf = b.add_mesh("tram_window_frames", steel);
    for k in 0..7 {
        let x = x0 - len / 2.0 + 0.9 + k as f32 * 1.2;
        let side = zc + w / 2.0;
        if k == 1 || k == 5 {
            // a door in place of this window
            mesh::cuboid(b.mesh_mut(mg), at(x, floor + 1.1, side + 0.012), Vec3::new(0.8, 1.9, 0.02), Vec2::ONE);
            mesh::cuboid(b.mesh_mut(mf), at(x, floor + 1.1, side + 0.006), Vec3::new(0.9, 2.0, 0.02), Vec2::ONE);
        } else {
            mesh::cuboid(b.mesh_mut(mg), at(x, floor + 1.75, side + 0.012), Vec3::new(0.95, 0.9, 0.02), Vec2::ONE);
            mesh::cuboid(b.mesh_mut(mf), at(x, floor + 1.75, side + 0.006), Vec3::new(1.03, 0.98, 0.02), Vec2::ONE);
        }
    }
    // destination blind above the windows, an advert panel below, the fleet number
    let md = b.add_mesh("tram_destination", dest_mat);
    mesh::cuboid(
        b.mesh_mut(md),
        at(x0, floor + 2.42, zc + w / 2.0 + 0.015),
        Vec3::new(2.6, 0.3, 0.02),
        Vec2::new(2.6, 0.3),
    );
    let ma = b.add_mesh("tram_advert", ad_mat);
    mesh::cuboid(
        b.mesh_mut(ma),
        at(x0 - 0.2, floor + 0.75, zc + w / 2.0 + 0.015),
        Vec3::new(3.0, 0.7, 0.02),
        Vec2::new(3.0, 0.7),
    );
    let mn = b.add_mesh("tram_number", num_mat);
    mesh::cuboid(
        b.mesh_mut(mn),
        at(x0 + 3.6, floor + 0.8, zc + w / 2.0 + 0.015),
        Vec3::new(0.5, 0.5, 0.02),
        Vec2::new(0.5, 0.5),
    );
    let ml = b.add_mesh("tram_headlight", lamp);
    let front = x0 + len / 2.0 + 0.01;
    let face = Quat::from_rotation_y(FRAC_PI_2);
    mesh::cylinder(
        b.mesh_mut(ml),
        Affine3A::from_rotation_translation(face * Quat::from_rotation_x(FRAC_PI_2), Vec3::new(front, floor + 0.7, zc)),
        0.14,
        0.04,
        20,
        1,
        true,
        Vec2::ONE,
    );
    // bogies, wheels on the rails and the trolley pole up to the contact wire
    let ms = b.add_mesh("tram_running_gear", steel);
    for bx in [x0 - 3.0, x0 + 3.0] {
        mesh::cuboid(b.mesh_mut(ms), at(bx, 0.32, zc), Vec3::new(2.2, 0.3, 1.6), Vec2::ONE);
        for dx in [-0.7, 0.7] {
            for dz in [-0.7175, 0.7175] {
                let xf = Affine3A::from_rotation_translation(
                    Quat::from_rotation_x(FRAC_PI_2),
                    Vec3::new(bx + dx, 0.34, zc + dz),
                );
                mesh::cylinder(b.mesh_mut(ms), xf, 0.34, 0.08, 24, 1, true, Vec2::ONE);
            }
        }
    }
    let pole_len = 3.2;
    let pole_rot = Quat::from_rotation_z(-0.9);
    let base = Vec3::new(x0, floor + h + 0.45, zc);
    mesh::cylinder(
        b.mesh_mut(ms),
        Affine3A::from_rotation_translation(pole_rot, base + pole_rot * Vec3::new(0.0, pole_len / 2.0, 0.0)),
        0.03,
        pole_len,
        8,
        1,
        false,
        Vec2::ONE,
    );
}

/// Catenary poles on both kerbs, span wires and contact wires, street lamps and a stop sign.
fn poles_and_wires(b: &mut SceneBuilder, paint: MaterialId) {
    let wire = b.add_material(MaterialDesc::diffuse("wire", [0.03, 0.03, 0.03]));
    let poles = b.add_mesh("catenary_poles", paint);
    let wires = b.add_mesh("wires", wire);
    let wire_y = 5.3;
    let along = Quat::from_rotation_z(FRAC_PI_2);
    let across = Quat::from_rotation_x(FRAC_PI_2);
    let (near_z, far_z) = (4.6f32, FACADE_Z + 1.4);
    let mut x = -HALF_LEN;
    while x <= HALF_LEN + 8.0 {
        for z in [near_z, far_z] {
            mesh::cylinder(b.mesh_mut(poles), at(x, 3.1, z), 0.09, 6.2, 16, 1, true, Vec2::ONE);
            mesh::cone(b.mesh_mut(poles), at(x, 6.3, z), 0.1, 0.2, 16, 1, false, Vec2::ONE);
        }
        // span wire across the street
        let mid = (near_z + far_z) / 2.0;
        mesh::cylinder(
            b.mesh_mut(wires),
            Affine3A::from_rotation_translation(across, Vec3::new(x, wire_y + 0.4, mid)),
            0.012,
            near_z - far_z,
            6,
            1,
            false,
            Vec2::ONE,
        );
        x += 8.0;
    }
    // contact wires above each track, and a messenger wire
    let w = 2.0 * HALF_LEN + 20.0;
    for (z, y) in [(0.0, wire_y), (-2.6, wire_y), (0.0, wire_y + 0.4), (-2.6, wire_y + 0.4)] {
        mesh::cylinder(
            b.mesh_mut(wires),
            Affine3A::from_rotation_translation(along, Vec3::new(0.0, y, z)),
            0.012,
            w,
            6,
            1,
            false,
            Vec2::ONE,
        );
    }
    // street lamps on the far pavement: emissive globes on poles
    let globe = b.add_material(MaterialDesc::emitter("lamp_globe", [5.0, 4.6, 3.8]));
    let globes = b.add_mesh("lamp_globes", globe);
    let mut x = -HALF_LEN + 4.0;
    while x <= HALF_LEN + 8.0 {
        mesh::cylinder(b.mesh_mut(poles), at(x, 2.0, FACADE_Z + 2.0), 0.06, 4.0, 12, 1, false, Vec2::ONE);
        mesh::uv_sphere(b.mesh_mut(globes), at(x, 4.2, FACADE_Z + 2.0), 0.22, 24, 12, Vec2::ONE);
        x += 8.0;
    }
    // a tram-stop sign on the near kerb
    let t = b.add_texture(
        "stop_sign",
        texture::sign(128, 128, &["TRAM", "STOP", "12 14"], 3, [250, 250, 250], [20, 110, 60], 4),
        WrapMode::ClampToEdge,
    );
    let mat = b.add_material(MaterialDesc::glossy("stop_sign", [1.0; 3], 0.3).with_texture(t));
    let m = b.add_mesh("stop_sign", mat);
    mesh::cuboid(b.mesh_mut(m), at(1.5, 2.3, near_z + 0.4), Vec3::new(0.6, 0.6, 0.03), Vec2::new(0.6, 0.6));
    mesh::cylinder(b.mesh_mut(poles), at(1.5, 1.2, near_z + 0.37), 0.035, 2.4, 12, 1, false, Vec2::ONE);
}

/// Trees, a flower stall, parked bicycles and a bench on the far pavement.
fn street_furniture(b: &mut SceneBuilder, rng: &mut Rng, steel: MaterialId, paint: MaterialId) {
    let repeat = WrapMode::Repeat;
    let pave_z = FACADE_Z + 2.0;
    // trees: a trunk and three noisy foliage balls each, between the lamps
    let bark_px = texture::fbm(
        64,
        128,
        &Fbm { cells: 2, octaves: 5, gain: 0.7, seed: 701 },
        &[(0.35, [60, 45, 35]), (0.65, [110, 90, 70])],
    );
    let bark_tex = b.add_texture("bark", bark_px, repeat);
    let bark = b.add_material(MaterialDesc::diffuse("bark", [1.0; 3]).with_texture(bark_tex));
    let leaves_px = texture::fbm(
        256,
        128,
        &Fbm { cells: 8, octaves: 5, gain: 0.65, seed: 702 },
        &[(0.3, [25, 60, 20]), (0.5, [60, 110, 35]), (0.7, [120, 160, 60])],
    );
    let leaves_tex = b.add_texture("foliage", leaves_px, repeat);
    let leaves = b.add_material(MaterialDesc::diffuse("foliage", [1.0; 3]).with_texture(leaves_tex));
    let trunks = b.add_mesh("tree_trunks", bark);
    let crowns = b.add_mesh("tree_crowns", leaves);
    let mut x = -HALF_LEN;
    while x <= HALF_LEN + 8.0 {
        mesh::cylinder(b.mesh_mut(trunks), at(x, 2.2, pave_z - 0.4), 0.14, 4.4, 24, 4, false, Vec2::new(0.5, 1.0));
        for _ in 0..3 {
            let c =
                Vec3::new(x + uniform(rng, -0.8, 0.8), uniform(rng, 4.6, 5.6), pave_z - 0.4 + uniform(rng, -0.5, 0.5));
            let r = uniform(rng, 0.9, 1.3);
            let xf = Affine3A::from_scale_rotation_translation(
                Vec3::new(1.0, 0.8, 1.0),
                Quat::from_rotation_y(uniform(rng, 0.0, std::f32::consts::TAU)),
                c,
            );
            mesh::uv_sphere(b.mesh_mut(crowns), xf, r, 40, 20, Vec2::splat(1.5));
        }
        x += 8.0;
    }

    // a flower stall: crates of small coloured blooms in front of a shop
    let crate_mat = b.add_material(MaterialDesc::diffuse("flower_crates", [0.45, 0.3, 0.18]));
    let crates = b.add_mesh("flower_crates", crate_mat);
    let bloom_colors: [[f32; 3]; 4] = [[0.8, 0.1, 0.15], [0.9, 0.75, 0.1], [0.85, 0.4, 0.6], [0.95, 0.95, 0.9]];
    let blooms: Vec<_> = bloom_colors
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let m = b.add_material(MaterialDesc::glossy(&format!("blooms_{i}"), c, 0.5));
            b.add_mesh(&format!("blooms_{i}"), m)
        })
        .collect();
    for (cx, cy, cz) in
        [(-3.0f32, 0.45f32, FACADE_Z + 0.6), (-1.9, 0.45, FACADE_Z + 0.6), (-2.45, 0.85, FACADE_Z + 0.35)]
    {
        mesh::cuboid(b.mesh_mut(crates), at(cx, cy - 0.2 + 0.06, cz), Vec3::new(1.0, 0.4, 0.5), Vec2::ONE);
        for k in 0..40 {
            let p = Vec3::new(
                cx + uniform(rng, -0.45, 0.45),
                cy + 0.08 + uniform(rng, 0.0, 0.1),
                cz + uniform(rng, -0.2, 0.2),
            );
            mesh::uv_sphere(
                b.mesh_mut(blooms[k % blooms.len()]),
                at(p.x, p.y, p.z),
                uniform(rng, 0.04, 0.07),
                12,
                6,
                Vec2::ONE,
            );
        }
    }

    // parked bicycles: torus wheels, a tube frame
    let tyre = b.add_material(MaterialDesc::glossy("tyres", [0.02, 0.02, 0.02], 0.5));
    let tyres = b.add_mesh("bicycle_tyres", tyre);
    let frames = b.add_mesh("bicycle_frames", paint);
    let spokes = b.add_mesh("bicycle_spokes", steel);
    for bx in [5.5f32, 6.4, 13.0] {
        let z = pave_z + 0.3;
        let face = Quat::from_rotation_x(FRAC_PI_2);
        for dx in [-0.52, 0.52] {
            let c = Vec3::new(bx + dx, 0.47, z);
            mesh::torus(
                b.mesh_mut(tyres),
                Affine3A::from_rotation_translation(face, c),
                0.33,
                0.025,
                48,
                10,
                Vec2::ONE,
            );
            for k in 0..8 {
                let a = k as f32 * std::f32::consts::PI / 8.0;
                let rot = Quat::from_rotation_z(a);
                mesh::cylinder(
                    b.mesh_mut(spokes),
                    Affine3A::from_rotation_translation(rot, c),
                    0.003,
                    0.64,
                    4,
                    1,
                    false,
                    Vec2::ONE,
                );
            }
        }
        for (p, q) in [
            (Vec3::new(bx - 0.52, 0.47, z), Vec3::new(bx, 0.5, z)),
            (Vec3::new(bx, 0.5, z), Vec3::new(bx + 0.35, 0.95, z)),
            (Vec3::new(bx - 0.1, 0.95, z), Vec3::new(bx + 0.35, 0.95, z)),
            (Vec3::new(bx - 0.52, 0.47, z), Vec3::new(bx - 0.1, 0.95, z)),
            (Vec3::new(bx + 0.52, 0.47, z), Vec3::new(bx + 0.4, 1.05, z)),
        ] {
            tube(b, frames, p, q, 0.02);
        }
    }

    // a bench
    let slats = b.add_mesh("bench", paint);
    for k in 0..4 {
        mesh::cuboid(
            b.mesh_mut(slats),
            at(9.0, 0.45, pave_z + 0.1 + k as f32 * 0.12),
            Vec3::new(1.8, 0.04, 0.09),
            Vec2::ONE,
        );
    }
    for dx in [-0.8, 0.8] {
        mesh::cuboid(b.mesh_mut(slats), at(9.0 + dx, 0.22, pave_z + 0.28), Vec3::new(0.06, 0.44, 0.5), Vec2::ONE);
    }
}

/// A thin cylinder from `p` to `q` (radius `r`).
fn tube(b: &mut SceneBuilder, m: super::MeshId, p: Vec3, q: Vec3, r: f32) {
    let d = q - p;
    let rot = Quat::from_rotation_arc(Vec3::Y, d.normalize());
    mesh::cylinder(
        b.mesh_mut(m),
        Affine3A::from_rotation_translation(rot, (p + q) / 2.0),
        r,
        d.length(),
        10,
        1,
        false,
        Vec2::ONE,
    );
}

/// The sideways dolly: 0.1 s keys along +X at about `SPEED` m/s, with a small seeded wobble of
/// the position and look-at (tuned so that `evsim scene info` reports blur in the benchmark's
/// range while every view blurs along the same axis).
fn keys() -> Vec<(f64, Vec3, Vec3)> {
    const SPEED: f32 = 5.0;
    let mut rng = Rng::new(0x7201_1e70_0001, 7);
    (0..=10)
        .map(|k| {
            let t = k as f32 * 0.1;
            // speed varies by +-15 % over the second (a gentle acceleration)
            let x = SPEED * (t + 0.15 * t * t - 0.1 * t * t * t);
            let wobble = Vec3::new(0.0, uniform(&mut rng, -0.04, 0.04), uniform(&mut rng, -0.04, 0.04));
            let look_wobble = Vec3::new(uniform(&mut rng, -0.2, 0.2), uniform(&mut rng, -0.15, 0.15), 0.0);
            (k as f64 * 0.1, EYE + Vec3::new(x, 0.0, 0.0) + wobble, TARGET + Vec3::new(x, 0.0, 0.0) + look_wobble)
        })
        .collect()
}

/// The dataset description of `trolley`.
fn toml_text() -> String {
    let keys_text = super::camera_path::key_tables(&super::camera_path::keys_from(&keys()), 2);
    format!(
        r#"# trolley: a tram street seen while riding past, written by `evsim scene generate --only trolley`
# (simulator/src/scenegen/trolley.rs); regenerate rather than edit the glTF.
scene = "scene.gltf"

{camera_and_sky}
# 1 s sideways dolly along the street with a small wobble: a consistent horizontal blur axis
[trajectory]
type = "keys"
{keys_text}
{tail}"#,
        tail = super::camera_path::OUTDOOR_DATASET_AND_EVENTS,
        camera_and_sky = super::camera_path::camera_and_sky(EYE, TARGET, FOV_Y_DEG, 1, [0.55, 0.62, 0.75]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::blur::blur_stats;
    use crate::dataset::settings::Overrides;
    use crate::dataset::Plan;
    use crate::render::accel::Accel;
    use crate::scenegen::{gltf_write, write_scene};

    /// Tens of thousands of triangles, and the sideways dolly blurs every view along the same
    /// axis (the property this scene exists for), checked at a small resolution.
    #[test]
    fn trolley_is_rich_and_blurs_along_one_axis() {
        let scene = trolley();
        assert!(scene.builder.triangle_count() >= 40_000, "{}", scene.builder.triangle_count());
        let dir = gltf_write::tests::temp_dir("trolley-blur");
        write_scene(&dir, &scene).unwrap();
        let overrides = Overrides::default().with("width", 60).with("height", 40);
        let plan = Plan::resolve(&dir.join("scene.toml"), &overrides).unwrap();
        let accel = Accel::build(&plan.scene.mesh, plan.config.bvh);
        let b = blur_stats(&plan, &accel, 2).unwrap();
        assert!(b.direction_consistency >= 0.9, "{b:?}");
    }
}
