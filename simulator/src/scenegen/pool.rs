//! `pool`: an outdoor hotel pool on a sunny day, in the spirit of Ev-DeblurBlender's `pool`
//! sequence.
//!
//! Depth layers, near to far: a potted shrub and a lounger at the camera's edge (2-4 m), the
//! tiled deck with a "NO DIVING" marking, the pool (blue mosaic walls and floor, rippled glossy
//! water with caustic-like bands, lane ropes of floats, two ladders), loungers with striped
//! cushions and striped umbrellas along the sides, hedges and shrubs, and a three-storey hotel
//! facade (stucco, framed glass windows, balconies with railings, striped awnings, lit ground-
//! floor windows and an emissive "HOTEL EVBLUR" sign). Detail at several scales: mosaic and
//! deck tiles, fine railings and cushion stripes, 5x7 text on signs and a rules board, fBm
//! stucco and foliage. Lit by a bright sky, a sun and the emissive windows and sign. About 1 s of
//! fast motion that travels mostly left to right at changing speed and height, so the blur
//! direction is similar across views (hard for image-only deblurring).

use std::f32::consts::{FRAC_PI_2, PI};

use glam::{Affine3A, Quat, Vec2, Vec3};

use super::camera_path::{keys_toml, Key};
use super::gltf_write::{MaterialDesc, PerspectiveCamera, SceneBuilder};
use super::mesh;
use super::texture::{self, Fbm, Tiles};
use super::GeneratedScene;
use crate::base::sampling::Rng;
use crate::scene::{PunctualLight, WrapMode};

/// Vertical field of view (degrees).
const FOV_Y_DEG: f32 = 45.0;
/// Pool opening: x in [-POOL_X, POOL_X], z in [POOL_Z0, POOL_Z1] (m); water 0.15 m below the deck.
const POOL_X: f32 = 4.0;
/// Far edge of the pool (m).
const POOL_Z0: f32 = -7.0;
/// Near edge of the pool (m).
const POOL_Z1: f32 = -1.0;
/// Pool depth (m).
const POOL_DEPTH: f32 = 1.6;

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

/// A `w` x `h` rectangle outline for [`mesh::extrude`] with its top-left corner at the origin.
fn rect(w: f32, h: f32) -> [Vec2; 4] {
    [Vec2::new(0.0, 0.0), Vec2::new(w, 0.0), Vec2::new(w, -h), Vec2::new(0.0, -h)]
}

/// Build `pool`.
pub fn pool() -> GeneratedScene {
    let mut b = SceneBuilder::new();
    let repeat = WrapMode::Repeat;
    let clamp = WrapMode::ClampToEdge;
    let mut rng = Rng::new(0x9001, 2);

    // --- deck: stone tiles around the pool opening (four slabs), 256 px per 1.2 m -----------
    let mut deck_px = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 4,
            rows: 4,
            grout_px: 3,
            grout: [150, 140, 128],
            colors: vec![[222, 210, 188], [210, 196, 172], [230, 220, 200]],
            random_pick: true,
            jitter: 0.07,
            seed: 201,
        },
    );
    texture::grime(&mut deck_px, &Fbm { cells: 4, octaves: 6, gain: 0.6, seed: 202 }, 0.3);
    let deck_tex = b.add_texture("deck_tiles", deck_px, repeat);
    let deck = b.add_material(MaterialDesc::glossy("deck_stone", [1.0; 3], 0.55).with_texture(deck_tex));
    let m = b.add_mesh("deck", deck);
    let (x0, x1, z0, z1) = (-16.0f32, 16.0f32, -16.0f32, 12.0f32);
    let slab = |b: &mut SceneBuilder, xa: f32, xb: f32, za: f32, zb: f32| {
        let c = at((xa + xb) / 2.0, 0.0, (za + zb) / 2.0);
        let size = Vec2::new(xb - xa, zb - za);
        let seg = [(size.x / 1.2).ceil() as u32, (size.y / 1.2).ceil() as u32];
        mesh::plane(b.mesh_mut(m), c, size, seg, Vec2::splat(1.2));
    };
    slab(&mut b, x0, x1, POOL_Z1, z1);
    slab(&mut b, x0, x1, z0, POOL_Z0);
    slab(&mut b, x0, -POOL_X, POOL_Z0, POOL_Z1);
    slab(&mut b, POOL_X, x1, POOL_Z0, POOL_Z1);
    // coping stones around the opening
    let coping = b.add_material(MaterialDesc::glossy("coping", [0.85, 0.84, 0.8], 0.35));
    let m = b.add_mesh("coping", coping);
    let (w, l) = (2.0 * POOL_X, POOL_Z1 - POOL_Z0);
    let zc = (POOL_Z0 + POOL_Z1) / 2.0;
    for z in [POOL_Z0 - 0.15, POOL_Z1 + 0.15] {
        mesh::cuboid(b.mesh_mut(m), at(0.0, 0.03, z), Vec3::new(w + 0.6, 0.06, 0.3), Vec2::ONE);
    }
    for x in [-POOL_X - 0.15, POOL_X + 0.15] {
        mesh::cuboid(b.mesh_mut(m), at(x, 0.03, zc), Vec3::new(0.3, 0.06, l), Vec2::ONE);
    }

    // --- pool: blue mosaic shell, rippled water ---------------------------------------------
    let mosaic_px = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 16,
            rows: 16,
            grout_px: 2,
            grout: [200, 215, 220],
            colors: vec![[40, 120, 190], [30, 100, 170], [60, 150, 205], [25, 90, 160]],
            random_pick: true,
            jitter: 0.05,
            seed: 211,
        },
    );
    let mosaic_tex = b.add_texture("pool_mosaic", mosaic_px, repeat);
    let mosaic = b.add_material(MaterialDesc::glossy("pool_mosaic", [1.0; 3], 0.3).with_texture(mosaic_tex));
    let m = b.add_mesh("pool_shell", mosaic);
    mesh::plane(b.mesh_mut(m), at(0.0, -POOL_DEPTH, zc), Vec2::new(w, l), [8, 6], Vec2::splat(0.8));
    let d = POOL_DEPTH;
    // walls facing the pool's inside: far (+Z normal), near (-Z), left (+X), right (-X)
    let walls = [
        (Quat::from_rotation_x(FRAC_PI_2), Vec3::new(0.0, -d / 2.0, POOL_Z0), Vec2::new(w, d)),
        (Quat::from_rotation_x(-FRAC_PI_2), Vec3::new(0.0, -d / 2.0, POOL_Z1), Vec2::new(w, d)),
        (Quat::from_rotation_z(-FRAC_PI_2), Vec3::new(-POOL_X, -d / 2.0, zc), Vec2::new(d, l)),
        (Quat::from_rotation_z(FRAC_PI_2), Vec3::new(POOL_X, -d / 2.0, zc), Vec2::new(d, l)),
    ];
    for (q, p, size) in walls {
        mesh::plane(b.mesh_mut(m), Affine3A::from_rotation_translation(q, p), size, [4, 2], Vec2::splat(0.8));
    }
    let water_px = texture::fbm(
        256,
        256,
        &Fbm { cells: 6, octaves: 4, gain: 0.5, seed: 221 },
        &[
            (0.40, [20, 120, 150]),
            (0.48, [40, 160, 185]),
            (0.5, [150, 225, 235]),
            (0.52, [40, 160, 185]),
            (0.6, [20, 120, 150]),
        ],
    );
    let water_tex = b.add_texture("water_caustics", water_px, repeat);
    let water = b.add_material(MaterialDesc {
        specular: Some(1.0),
        ..MaterialDesc::glossy("water", [0.85, 0.95, 1.0], 0.04).with_texture(water_tex)
    });
    let m = b.add_mesh("water", water);
    mesh::heightfield(b.mesh_mut(m), at(0.0, -0.15, zc), Vec2::new(w, l), [96, 72], Vec2::splat(2.0), |u, v| {
        let (x, z) = (u * w, v * l);
        0.012 * (3.1 * x + 1.3 * z).sin() + 0.008 * (4.7 * z - 2.2 * x).sin() + 0.005 * (9.0 * x + 7.0 * z).sin()
    });

    // lane ropes: chains of red and white floats
    let red = b.add_material(MaterialDesc::glossy("float_red", [0.75, 0.05, 0.04], 0.2));
    let white = b.add_material(MaterialDesc::glossy("float_white", [0.85, 0.85, 0.85], 0.2));
    let (mr, mw) = (b.add_mesh("floats_red", red), b.add_mesh("floats_white", white));
    for x in [-POOL_X / 3.0, POOL_X / 3.0] {
        let n = 40;
        for k in 0..n {
            let z = POOL_Z0 + (k as f32 + 0.5) * l / n as f32;
            let mesh_id = if (k / 4) % 2 == 0 { mr } else { mw };
            mesh::uv_sphere(b.mesh_mut(mesh_id), at(x, -0.14, z), 0.07, 16, 8, Vec2::ONE);
        }
    }

    // ladders: two rails bent over the coping, rungs
    let chrome = b.add_material(MaterialDesc::metal("chrome", [0.9, 0.9, 0.92], 0.12));
    let m = b.add_mesh("ladders", chrome);
    for (x, z) in [(2.6f32, POOL_Z0 + 0.25), (-2.8, POOL_Z0 + 0.25)] {
        for dx in [-0.25f32, 0.25] {
            mesh::cylinder(b.mesh_mut(m), at(x + dx, -0.3, z), 0.025, 1.7, 16, 4, false, Vec2::ONE);
            // the bend over the coping: a torus standing in the rail's YZ plane
            let bend =
                Affine3A::from_rotation_translation(Quat::from_rotation_z(FRAC_PI_2), Vec3::new(x + dx, 0.55, z - 0.2));
            mesh::torus(b.mesh_mut(m), bend, 0.2, 0.025, 32, 8, Vec2::ONE);
            mesh::cylinder(b.mesh_mut(m), at(x + dx, 0.28, z - 0.4), 0.025, 0.55, 16, 2, false, Vec2::ONE);
        }
        for k in 0..4 {
            mesh::cylinder(
                b.mesh_mut(m),
                along_x(x, -1.0 + 0.3 * k as f32, z + 0.02),
                0.02,
                0.5,
                12,
                1,
                false,
                Vec2::ONE,
            );
        }
    }

    // "NO DIVING" and depth markings on the deck
    let mark_px = texture::sign(256, 64, &["NO DIVING   1.6 M"], 2, [170, 20, 20], [228, 220, 204], 0);
    let mark_tex = b.add_texture("deck_marking", mark_px, clamp);
    let mark = b.add_material(MaterialDesc::glossy("deck_marking", [1.0; 3], 0.5).with_texture(mark_tex));
    let m = b.add_mesh("deck_marking", mark);
    mesh::plane(b.mesh_mut(m), at(0.0, 0.003, POOL_Z1 + 0.8), Vec2::new(2.4, 0.6), [1, 1], Vec2::new(2.4, 0.6));
    // plane UVs follow x, z: shift them to one copy of the texture
    let mesh_data = b.mesh_mut(m);
    let (xa, za) = (-1.2, POOL_Z1 + 0.5);
    for (p, uv) in mesh_data.positions.iter().zip(mesh_data.uvs.iter_mut()) {
        *uv = Vec2::new((p.x - xa) / 2.4, (p.z - za) / 0.6);
    }

    // --- loungers with striped cushions ------------------------------------------------------
    let cushion_tex =
        b.add_texture("cushion_stripes", texture::stripes(128, 128, 0.0, 12.0, [250, 250, 245], [20, 60, 130]), repeat);
    let cushion = b.add_material(MaterialDesc::diffuse("cushion", [1.0; 3]).with_texture(cushion_tex));
    let frame = b.add_material(MaterialDesc::glossy("lounger_frame", [0.9, 0.9, 0.88], 0.3));
    let lounger = |b: &mut SceneBuilder, xf: Affine3A| {
        let m = b.add_mesh("lounger_frame", frame);
        for (x, z) in [(-0.3f32, -0.9f32), (0.3, -0.9), (-0.3, 0.9), (0.3, 0.9)] {
            mesh::cuboid(b.mesh_mut(m), xf * at(x, 0.17, z), Vec3::new(0.05, 0.34, 0.05), Vec2::ONE);
        }
        mesh::cuboid(b.mesh_mut(m), xf * at(0.0, 0.34, 0.2), Vec3::new(0.7, 0.05, 1.4), Vec2::ONE);
        let c = b.add_mesh("lounger_cushion", cushion);
        mesh::cuboid(b.mesh_mut(c), xf * at(0.0, 0.41, 0.2), Vec3::new(0.64, 0.08, 1.36), Vec2::splat(0.5));
        let back = xf * Affine3A::from_rotation_translation(Quat::from_rotation_x(-0.9), Vec3::new(0.0, 0.62, -0.78));
        mesh::cuboid(b.mesh_mut(c), back, Vec3::new(0.64, 0.08, 0.75), Vec2::splat(0.5));
    };
    for (x, z, yaw) in [
        (6.0f32, -6.2f32, -0.1f32),
        (6.0, -4.0, 0.05),
        (6.1, -1.8, -0.05),
        (-6.2, -5.0, 0.1),
        (-6.0, -2.6, 0.0),
        (3.4, 2.2, 0.5),
    ] {
        lounger(&mut b, yaw_at(yaw, x, 0.0, z));
    }

    // --- umbrellas: striped canopies on poles with bases -------------------------------------
    let canopy_tex =
        b.add_texture("canopy_stripes", texture::stripes(128, 64, 90.0, 32.0, [235, 235, 230], [210, 60, 40]), repeat);
    let canopy = b.add_material(MaterialDesc {
        double_sided: true,
        ..MaterialDesc::diffuse("canopy", [1.0; 3]).with_texture(canopy_tex)
    });
    let pole = b.add_material(MaterialDesc::glossy("umbrella_pole", [0.5, 0.35, 0.2], 0.4));
    for (x, z) in [(7.2f32, -5.0f32), (7.2, -2.4), (-7.3, -3.8), (-5.0, -9.0)] {
        let m = b.add_mesh("umbrella_canopy", canopy);
        mesh::cone(b.mesh_mut(m), at(x, 2.35, z), 1.4, 0.5, 64, 4, true, Vec2::new(0.55, 1.0));
        let m = b.add_mesh("umbrella_pole", pole);
        mesh::cylinder(b.mesh_mut(m), at(x, 1.2, z), 0.03, 2.4, 16, 2, false, Vec2::ONE);
        mesh::cylinder(b.mesh_mut(m), at(x, 0.05, z), 0.25, 0.1, 32, 1, true, Vec2::ONE);
    }

    // --- plants: hedges, shrubs in pots, a row of tall cypresses ------------------------------
    let leaf_px = texture::fbm(
        256,
        256,
        &Fbm { cells: 16, octaves: 4, gain: 0.6, seed: 231 },
        &[(0.3, [25, 60, 20]), (0.5, [55, 105, 35]), (0.7, [100, 150, 50])],
    );
    let leaf_tex = b.add_texture("leaves", leaf_px, repeat);
    let leaves = b.add_material(MaterialDesc::diffuse("leaves", [1.0; 3]).with_texture(leaf_tex));
    let pot = b.add_material(MaterialDesc::diffuse("terracotta", [0.62, 0.28, 0.15]));
    let bush = |b: &mut SceneBuilder, rng: &mut Rng, c: Vec3, r: f32, blobs: usize| {
        let m = b.add_mesh("shrub", leaves);
        for _ in 0..blobs {
            let o = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() * 0.6, rng.next_f32() - 0.5) * r * 1.2;
            let s = r * (0.45 + 0.35 * rng.next_f32());
            let xf = Affine3A::from_scale_rotation_translation(
                Vec3::new(1.0, 0.8, 1.0) * s,
                Quat::from_rotation_y(rng.next_f32() * PI),
                c + o,
            );
            mesh::uv_sphere(b.mesh_mut(m), xf, 1.0, 24, 12, Vec2::splat(0.4));
        }
    };
    for (x, z) in [(-4.5f32, 2.4f32), (9.0, 0.5), (-9.0, 0.0), (-4.9, -0.3), (5.0, -0.3)] {
        let m = b.add_mesh("pot", pot);
        mesh::cone(
            b.mesh_mut(m),
            Affine3A::from_rotation_translation(Quat::from_rotation_x(PI), Vec3::new(x, 0.3, z)),
            0.4,
            0.9,
            32,
            1,
            true,
            Vec2::ONE,
        );
        bush(&mut b, &mut rng, Vec3::new(x, 0.9, z), 0.45, 7);
    }
    let hedge = b.add_mesh("hedge", leaves);
    for x in [-12.0f32, -8.5, 8.5, 12.0] {
        mesh::cuboid(b.mesh_mut(hedge), at(x, 0.6, -11.0), Vec3::new(3.2, 1.2, 0.8), Vec2::splat(0.8));
    }
    for k in 0..7 {
        let x = -13.0 + 4.33 * k as f32;
        if x.abs() < 3.0 {
            continue;
        }
        let m = b.add_mesh("cypress", leaves);
        let xf = Affine3A::from_scale_rotation_translation(
            Vec3::new(0.7, 2.8, 0.7),
            Quat::IDENTITY,
            Vec3::new(x, 2.8, -12.2),
        );
        mesh::uv_sphere(b.mesh_mut(m), xf, 1.0, 32, 16, Vec2::splat(0.3));
    }

    // --- hotel facade ------------------------------------------------------------------------
    let mut stucco_px = texture::fbm(
        256,
        256,
        &Fbm { cells: 8, octaves: 6, gain: 0.55, seed: 241 },
        &[(0.3, [214, 190, 158]), (0.7, [236, 216, 186])],
    );
    texture::grime(&mut stucco_px, &Fbm { cells: 2, octaves: 5, gain: 0.6, seed: 242 }, 0.3);
    let stucco_tex = b.add_texture("stucco", stucco_px, repeat);
    let stucco = b.add_material(MaterialDesc::diffuse("stucco", [1.0; 3]).with_texture(stucco_tex));
    let (fz, fw, fh) = (-14.0f32, 30.0f32, 11.0f32);
    let m = b.add_mesh("facade", stucco);
    mesh::cuboid(b.mesh_mut(m), at(0.0, fh / 2.0, fz - 0.5), Vec3::new(fw, fh, 1.0), Vec2::splat(2.5));
    // floor bands and a cornice
    for y in [3.6f32, 7.2] {
        mesh::cuboid(b.mesh_mut(m), at(0.0, y, fz + 0.08), Vec3::new(fw, 0.25, 0.16), Vec2::splat(2.5));
    }
    mesh::cuboid(b.mesh_mut(m), at(0.0, fh + 0.2, fz), Vec3::new(fw + 0.4, 0.4, 1.4), Vec2::splat(2.5));
    let glass = b.add_material(MaterialDesc {
        specular: Some(1.0),
        ..MaterialDesc::glossy("window_glass", [0.03, 0.05, 0.07], 0.03)
    });
    let wframe = b.add_material(MaterialDesc::glossy("window_frame", [0.85, 0.85, 0.82], 0.3));
    let interior = b.add_material(MaterialDesc::emitter("lit_window", [2.6, 2.0, 1.3]));
    let (mg, mf, mi) =
        (b.add_mesh("windows", glass), b.add_mesh("window_frames", wframe), b.add_mesh("lit_windows", interior));
    let rail = b.add_material(MaterialDesc::metal("railing", [0.25, 0.25, 0.27], 0.3));
    let mrail = b.add_mesh("balcony_railings", rail);
    let mslab = b.add_mesh("balcony_slabs", wframe);
    let awning_tex =
        b.add_texture("awning_stripes", texture::stripes(128, 64, 90.0, 16.0, [245, 240, 230], [30, 110, 90]), repeat);
    let awning = b.add_material(MaterialDesc {
        double_sided: true,
        ..MaterialDesc::diffuse("awning", [1.0; 3]).with_texture(awning_tex)
    });
    let mawn = b.add_mesh("awnings", awning);
    for col in 0..9 {
        let x = -12.0 + 3.0 * col as f32;
        for floor in 0..3 {
            let y0 = 0.9 + 3.6 * floor as f32;
            let lit = floor == 0 && col % 3 != 1;
            let target = if lit { mi } else { mg };
            mesh::cuboid(b.mesh_mut(target), at(x, y0 + 0.9, fz + 0.02), Vec3::new(1.3, 1.8, 0.04), Vec2::ONE);
            // frame: sides, top, sill, mullion
            for dx in [-0.68f32, 0.68] {
                mesh::cuboid(b.mesh_mut(mf), at(x + dx, y0 + 0.9, fz + 0.06), Vec3::new(0.08, 1.9, 0.1), Vec2::ONE);
            }
            mesh::cuboid(b.mesh_mut(mf), at(x, y0 + 1.84, fz + 0.06), Vec3::new(1.44, 0.08, 0.1), Vec2::ONE);
            mesh::cuboid(b.mesh_mut(mf), at(x, y0 - 0.04, fz + 0.1), Vec3::new(1.5, 0.08, 0.2), Vec2::ONE);
            mesh::cuboid(b.mesh_mut(mf), at(x, y0 + 0.9, fz + 0.06), Vec3::new(0.05, 1.8, 0.06), Vec2::ONE);
            if floor == 0 {
                // an awning over the ground-floor window
                let xf = Affine3A::from_rotation_translation(
                    Quat::from_rotation_x(0.45),
                    Vec3::new(x, y0 + 2.25, fz + 0.45),
                );
                mesh::plane(b.mesh_mut(mawn), xf, Vec2::new(1.6, 0.95), [4, 2], Vec2::new(1.6, 1.0));
            } else {
                // a balcony: slab and railing with fine balusters
                mesh::cuboid(b.mesh_mut(mslab), at(x, y0 - 0.1, fz + 0.55), Vec3::new(2.0, 0.12, 1.1), Vec2::ONE);
                mesh::cylinder(b.mesh_mut(mrail), along_x(x, y0 + 0.9, fz + 1.08), 0.025, 2.0, 12, 1, true, Vec2::ONE);
                for k in 0..17 {
                    mesh::cylinder(
                        b.mesh_mut(mrail),
                        at(x - 0.96 + 0.12 * k as f32, y0 + 0.42, fz + 1.08),
                        0.01,
                        0.95,
                        6,
                        1,
                        false,
                        Vec2::ONE,
                    );
                }
            }
        }
    }
    // emissive hotel sign over the entrance, a rules board by the pool
    let hotel_px = texture::sign(512, 64, &["HOTEL EVBLUR"], 6, [255, 230, 170], [30, 20, 15], 3);
    let hotel_tex = b.add_texture("hotel_sign", hotel_px, clamp);
    let hotel = b.add_material(MaterialDesc {
        emissive_texture: Some(hotel_tex),
        emissive_strength: 5.0,
        ..MaterialDesc::emitter("hotel_sign", [1.0, 1.0, 1.0])
    });
    let m = b.add_mesh("hotel_sign", hotel);
    mesh::extrude(b.mesh_mut(m), at(-2.5, 4.4, fz + 0.2), &rect(5.0, 0.62), 0.06, Vec2::new(5.0, 0.62));

    let mut rules_px = texture::text_page(256, 256, 1, [25, 30, 60], [240, 238, 228], 10, 251);
    for y in 0..30 {
        for x in 0..256 {
            rules_px.put_pixel(x, y, image::Rgb([20, 70, 140]));
        }
    }
    texture::draw_text(
        &mut rules_px,
        "POOL RULES",
        (256 - texture::text_width("POOL RULES", 3) as i64) / 2,
        5,
        3,
        [255, 255, 255],
    );
    let rules_tex = b.add_texture("rules_board", rules_px, clamp);
    let rules = b.add_material(MaterialDesc::glossy("rules_board", [1.0; 3], 0.4).with_texture(rules_tex));
    let m = b.add_mesh("rules_board", rules);
    mesh::extrude(b.mesh_mut(m), yaw_at(0.35, -9.3, 2.0, -7.4), &rect(1.1, 1.1), 0.04, Vec2::new(1.1, 1.1));
    let m = b.add_mesh("rules_posts", pole);
    for dx in [0.15f32, 0.95] {
        mesh::cylinder(
            b.mesh_mut(m),
            at(-9.3 + dx * 0.94, 1.0, -7.4 - dx * 0.34 - 0.05),
            0.03,
            2.0,
            12,
            1,
            false,
            Vec2::ONE,
        );
    }

    b.add_light(PunctualLight::Directional {
        direction: Vec3::new(-0.35, -0.75, -0.55).normalize(),
        irradiance: Vec3::new(3.0, 2.85, 2.55),
    });
    let k = keys();
    let (eye, look) = (k[0].position.map(|v| v as f32), k[0].look_at.map(|v| v as f32));
    b.set_camera(PerspectiveCamera::look_at("view", Vec3::from(eye), Vec3::from(look), Vec3::Y, FOV_Y_DEG));
    GeneratedScene { builder: b, toml: toml_text(&k) }
}

/// How far the path swings about its centre: 1 gives blur means of ~12 px at 40 ms, 1.45 about
/// 18 px (mean) and 130 px (max, on the potted shrub passing close to the lens).
const SWING: f64 = 1.45;

/// The camera path: about 1.1 s, keys every 0.12 s, travelling left to right along the near
/// edge while panning right (image motion mostly right to left), at changing speed and height,
/// swung by [`SWING`] about its centre.
fn keys() -> Vec<Key> {
    #[rustfmt::skip]
    const K: [([f64; 3], [f64; 3]); 10] = [
        ([-3.00, 1.70, 4.60], [-2.10, 0.60, -6.0]),
        ([-2.40, 1.85, 4.55], [-1.55, 0.75, -6.0]),
        ([-1.50, 1.95, 4.50], [-0.75, 0.85, -6.0]),
        ([-0.90, 1.80, 4.40], [-0.20, 0.70, -6.0]),
        ([-0.45, 1.60, 4.35], [ 0.25, 0.55, -6.0]),
        ([ 0.30, 1.55, 4.40], [ 0.90, 0.60, -6.0]),
        ([ 1.25, 1.70, 4.50], [ 1.75, 0.80, -6.0]),
        ([ 1.85, 1.90, 4.60], [ 2.30, 0.85, -6.0]),
        ([ 2.30, 1.85, 4.50], [ 2.70, 0.70, -6.0]),
        ([ 3.05, 1.65, 4.40], [ 3.40, 0.60, -6.0]),
    ];
    const CENTRE: [f64; 3] = [0.0, 1.75, 4.5];
    const LOOK_CENTRE: [f64; 3] = [0.6, 0.7, -6.0];
    let swing = |p: [f64; 3], c: [f64; 3]| [0, 1, 2].map(|j| c[j] + SWING * (p[j] - c[j]));
    K.iter()
        .enumerate()
        .map(|(i, &(p, l))| Key { t: 0.12 * i as f64, position: swing(p, CENTRE), look_at: swing(l, LOOK_CENTRE) })
        .collect()
}

/// The dataset description of `pool`; `keys[0]` is also the `[camera]`.
fn toml_text(keys: &[Key]) -> String {
    let v = |p: [f64; 3]| format!("[{:.3}, {:.3}, {:.3}]", p[0], p[1], p[2]);
    format!(
        r#"# pool: a benchmark scene written by `evsim scene generate --only pool`
# (simulator/src/scenegen/pool.rs); regenerate rather than edit.
scene = "scene.gltf"

[camera]
origin = {eye}
target = {look}
fov = {FOV_Y_DEG:.1}
fov_axis = "y"

[environment]
type = "constant"
radiance = [0.55, 0.68, 0.9]

# fast motion, about 1 s, mostly left to right
{traj}
# defaults: the paper's 600x400, 1000 FPS, 40 ms exposure and threshold 0.2 ([events]);
# 2 spp, 32 feature rays, temporal radius 32 read every 2nd frame, first-vertex cache (chosen with
# `evsim dataset-noise`)
# max_depth 3 (direct light plus one bounce) keeps 1000 frames affordable
[dataset]
views = 30
sharp_every = 8
max_depth = 3
"#,
        eye = v(keys[0].position),
        look = v(keys[0].look_at),
        traj = keys_toml(keys),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pool_is_rich() {
        let s = pool();
        assert!(s.builder.triangle_count() >= 20_000, "{}", s.builder.triangle_count());
        assert!(s.builder.materials.iter().filter(|m| m.emissive != [0.0; 3]).count() >= 2);
    }
}
