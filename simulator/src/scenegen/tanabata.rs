//! `tanabata`: a Japanese summer-festival street at dusk (a benchmark scene in the spirit of
//! Deblur-NeRF's "tanabata").
//!
//! A paved street runs away from the camera along -Z between two rows of festival stalls
//! (wooden counters, striped awnings, text signs, menu boards, goods on the counters). Bamboo
//! poles stand at several depths, their branches hung with hundreds of colourful paper strips
//! (tanzaku) covered in glyph "writing"; strings of emissive paper lanterns cross the street at
//! four depths and hang from every stall. A vermilion gate and a row of houses close the street.
//! Lit by a dusk sky (constant environment), a low sun and the lanterns.
//!
//! Depth layers: foreground bamboo (2-3 m from the camera), stalls and lantern strings (4-20 m),
//! the gate and houses (25-30 m). The camera shakes in a hand-held, non-planar way: position and
//! look-at wander differently in every 0.1 s segment, so blur direction and length change from
//! view to view.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use glam::{Affine3A, Quat, Vec2, Vec3};
use image::{Rgb, RgbImage};

use super::gltf_write::{MaterialDesc, MaterialId, PerspectiveCamera, SceneBuilder};
use super::mesh;
use super::texture::{self, Fbm, Srgb, Tiles, Wood};
use super::GeneratedScene;
use crate::base::sampling::Rng;
use crate::scene::{PunctualLight, WrapMode};

/// Camera of the first view (also the `[camera]` table).
const EYE: Vec3 = Vec3::new(0.0, 1.6, 8.0);
/// Point the camera looks at, on average.
const TARGET: Vec3 = Vec3::new(0.0, 1.5, -6.0);
/// Vertical field of view (degrees).
const FOV_Y_DEG: f32 = 40.0;
/// Street half-width: stall fronts stand at |x| = this (m).
const STREET: f32 = 3.0;

/// Translation-only placement.
fn at(x: f32, y: f32, z: f32) -> Affine3A {
    Affine3A::from_translation(Vec3::new(x, y, z))
}

/// Uniform in [lo, hi).
fn uniform(rng: &mut Rng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.next_f32()
}

/// Build `tanabata`.
pub fn tanabata() -> GeneratedScene {
    let mut b = SceneBuilder::new();
    let mut rng = Rng::new(0x7a4a_ba7a, 5);
    ground_and_backdrop(&mut b);
    let lamps = lantern_materials(&mut b);
    stalls(&mut b, &mut rng, lamps);
    bamboo(&mut b, &mut rng);
    lantern_strings(&mut b, lamps);
    b.add_light(PunctualLight::Directional {
        direction: Vec3::new(-0.6, -0.45, -0.35).normalize(),
        irradiance: Vec3::new(2.2, 1.6, 1.0),
    });
    b.set_camera(PerspectiveCamera::look_at("view", EYE, TARGET, Vec3::Y, FOV_Y_DEG));
    GeneratedScene { builder: b, toml: toml_text() }
}

/// Paving, the gate at the street's end and the houses behind it.
fn ground_and_backdrop(b: &mut SceneBuilder) {
    let repeat = WrapMode::Repeat;
    // stone pavers, 256 px per 2 m, with grime
    let mut paving = texture::tiles(
        256,
        256,
        &Tiles {
            cols: 5,
            rows: 5,
            grout_px: 2,
            grout: [60, 58, 55],
            colors: vec![[150, 146, 138], [128, 124, 118], [162, 155, 140], [138, 136, 132]],
            random_pick: true,
            jitter: 0.1,
            seed: 101,
        },
    );
    texture::grime(&mut paving, &Fbm { cells: 3, octaves: 6, gain: 0.6, seed: 102 }, 0.45);
    let paving_tex = b.add_texture("paving", paving, repeat);
    let ground = b.add_material(MaterialDesc::glossy("paving", [1.0; 3], 0.6).with_texture(paving_tex));
    let m = b.add_mesh("ground", ground);
    mesh::plane(b.mesh_mut(m), at(0.0, 0.0, -10.0), Vec2::new(24.0, 44.0), [24, 44], Vec2::splat(2.0));

    // the vermilion gate (torii) at the street's end
    let vermilion = b.add_material(MaterialDesc::glossy("vermilion", [0.62, 0.08, 0.03], 0.3));
    let black = b.add_material(MaterialDesc::glossy("black_lacquer", [0.02, 0.02, 0.02], 0.2));
    let m = b.add_mesh("gate", vermilion);
    let gz = -24.0;
    for x in [-2.4, 2.4] {
        mesh::cylinder(b.mesh_mut(m), at(x, 2.6, gz), 0.28, 5.2, 32, 1, false, Vec2::ONE);
    }
    mesh::cuboid(b.mesh_mut(m), at(0.0, 4.3, gz), Vec3::new(6.0, 0.28, 0.3), Vec2::ONE);
    let m = b.add_mesh("gate_top", black);
    mesh::cuboid(b.mesh_mut(m), at(0.0, 5.35, gz), Vec3::new(7.4, 0.3, 0.5), Vec2::ONE);
    mesh::cuboid(b.mesh_mut(m), at(0.0, 5.1, gz), Vec3::new(6.8, 0.22, 0.42), Vec2::ONE);
    let gate_sign = texture::sign(128, 192, &["TEN", "MAN", "GU"], 4, [230, 200, 90], [20, 20, 24], 4);
    let gate_sign_tex = b.add_texture("gate_plaque", gate_sign, WrapMode::ClampToEdge);
    let plaque = b.add_material(MaterialDesc::glossy("gate_plaque", [1.0; 3], 0.3).with_texture(gate_sign_tex));
    let m = b.add_mesh("gate_plaque", plaque);
    let outline = [Vec2::new(0.0, 0.0), Vec2::new(0.6, 0.0), Vec2::new(0.6, -0.9), Vec2::new(0.0, -0.9)];
    mesh::extrude(b.mesh_mut(m), at(-0.3, 5.0, gz + 0.2), &outline, 0.08, Vec2::new(0.6, 0.9));

    // houses behind the gate: dark timber facades with lit paper windows
    let timber = texture::wood(
        256,
        256,
        &Wood { ring_px: 6.0, distortion: 2.0, stretch: 8.0, light: [110, 78, 52], dark: [52, 34, 22], seed: 111 },
    );
    let timber_tex = b.add_texture("timber", timber, repeat);
    let timber_mat = b.add_material(MaterialDesc::diffuse("timber", [1.0; 3]).with_texture(timber_tex));
    let m = b.add_mesh("houses", timber_mat);
    let roof_px = texture::stripes(128, 128, 0.0, 8.0, [58, 62, 70], [34, 36, 42]);
    let roof_tex = b.add_texture("roof_tiles", roof_px, repeat);
    let roof_mat = b.add_material(MaterialDesc::glossy("roof_tiles", [1.0; 3], 0.35).with_texture(roof_tex));
    let roofs = b.add_mesh("roofs", roof_mat);
    let shoji = shoji_texture();
    let shoji_tex = b.add_texture("shoji", shoji, repeat);
    let shoji_mat = b.add_material(MaterialDesc {
        emissive_texture: Some(shoji_tex),
        emissive_strength: 1.5,
        ..MaterialDesc::emitter("shoji_window", [1.0, 0.8, 0.55])
    });
    let windows = b.add_mesh("shoji_windows", shoji_mat);
    for (i, x) in [-9.0f32, -4.5, 0.0, 4.5, 9.0].into_iter().enumerate() {
        let h = 4.5 + (i % 2) as f32 * 1.2;
        mesh::cuboid(b.mesh_mut(m), at(x, h / 2.0, -30.0), Vec3::new(4.4, h, 3.0), Vec2::splat(2.0));
        let roof = Affine3A::from_rotation_translation(Quat::from_rotation_x(0.25), Vec3::new(x, h + 0.2, -28.9));
        mesh::cuboid(b.mesh_mut(roofs), roof, Vec3::new(4.8, 0.12, 1.6), Vec2::splat(1.0));
        let outline = [Vec2::new(0.0, 0.0), Vec2::new(1.2, 0.0), Vec2::new(1.2, -1.0), Vec2::new(0.0, -1.0)];
        for wx in [-1.5, 0.3] {
            mesh::extrude(b.mesh_mut(windows), at(x + wx, h - 0.8, -28.48), &outline, 0.04, Vec2::new(1.2, 1.0));
        }
    }
}

/// Paper sliding-window pattern: a lattice of thin dark bars on warm paper.
fn shoji_texture() -> RgbImage {
    RgbImage::from_fn(128, 128, |x, y| {
        let bar = x % 32 < 3 || y % 24 < 3;
        Rgb(if bar { [40, 28, 18] } else { [255, 236, 200] })
    })
}

/// Two rows of stalls along the street.
fn stalls(b: &mut SceneBuilder, rng: &mut Rng, lantern_mats: [MaterialId; 3]) {
    let repeat = WrapMode::Repeat;
    let wood_px = texture::wood(
        256,
        256,
        &Wood { ring_px: 8.0, distortion: 1.6, stretch: 6.0, light: [206, 162, 112], dark: [118, 76, 42], seed: 201 },
    );
    let wood_tex = b.add_texture("stall_wood", wood_px, repeat);
    let wood = b.add_material(MaterialDesc::glossy("stall_wood", [1.0; 3], 0.45).with_texture(wood_tex));
    // awnings: fine red/white and blue/white stripes (0.3 m per stripe pair)
    let awning_tex = [
        b.add_texture("awning_red", texture::stripes(128, 128, 0.0, 32.0, [200, 30, 30], [245, 240, 230]), repeat),
        b.add_texture("awning_blue", texture::stripes(128, 128, 0.0, 32.0, [30, 60, 160], [245, 240, 230]), repeat),
    ];
    let awnings = awning_tex.map(|t| b.add_material(MaterialDesc::diffuse("awning_cloth", [1.0; 3]).with_texture(t)));
    // valances along the awnings' front edges: the same cloth, stripes vertical
    let valance_tex = [
        b.add_texture("valance_red", texture::stripes(128, 128, 90.0, 32.0, [200, 30, 30], [245, 240, 230]), repeat),
        b.add_texture("valance_blue", texture::stripes(128, 128, 90.0, 32.0, [30, 60, 160], [245, 240, 230]), repeat),
    ];
    let valances =
        valance_tex.map(|t| b.add_material(MaterialDesc::diffuse("valance_cloth", [1.0; 3]).with_texture(t)));
    let menu_px = texture::text_page(256, 256, 3, [240, 230, 200], [60, 36, 22], 10, 202);
    let menu_tex = b.add_texture("menu_boards", menu_px, repeat);
    let menu = b.add_material(MaterialDesc::diffuse("menu_boards", [1.0; 3]).with_texture(menu_tex));
    let pole = b.add_material(MaterialDesc::diffuse("pole_wood", [0.35, 0.24, 0.15]));

    const NAMES: [&str; 10] =
        ["YAKISOBA", "KINGYO", "RAMUNE", "TAKOYAKI", "WATAAME", "YO-YO", "IKAYAKI", "KAKIGORI", "SHATEKI", "OMEN"];
    const SIGN_COLORS: [(Srgb, Srgb); 4] = [
        ([250, 245, 230], [170, 20, 25]),
        ([20, 20, 30], [250, 215, 60]),
        ([250, 250, 250], [25, 60, 140]),
        ([30, 20, 10], [240, 230, 210]),
    ];
    let goods_mats = [
        b.add_material(MaterialDesc::glossy("goods_red", [0.7, 0.05, 0.05], 0.15)),
        b.add_material(MaterialDesc::glossy("goods_yellow", [0.8, 0.6, 0.05], 0.15)),
        b.add_material(MaterialDesc::glossy("goods_cyan", [0.05, 0.5, 0.7], 0.15)),
        b.add_material(MaterialDesc::glossy("goods_pink", [0.8, 0.25, 0.45], 0.15)),
    ];
    let counter = b.add_mesh("stall_counters", wood);
    let posts = b.add_mesh("stall_posts", pole);
    let awning_meshes = [b.add_mesh("awnings_red", awnings[0]), b.add_mesh("awnings_blue", awnings[1])];
    let valance_meshes = [b.add_mesh("valances_red", valances[0]), b.add_mesh("valances_blue", valances[1])];
    let menus = b.add_mesh("menu_boards", menu);
    let goods: Vec<_> = goods_mats.iter().enumerate().map(|(i, &g)| b.add_mesh(&format!("goods_{i}"), g)).collect();
    let lanterns =
        [b.add_mesh("stall_lanterns_red", lantern_mats[0]), b.add_mesh("stall_lanterns_white", lantern_mats[1])];
    let caps = b.add_mesh("lantern_caps", lantern_mats[2]);

    let mut k = 0usize;
    for (side, s) in [(0usize, -1.0f32), (1, 1.0)] {
        for (j, zc) in [4.0f32, 1.0, -2.0, -5.0, -8.0, -11.0, -14.0, -17.0].into_iter().enumerate() {
            let len = 2.7;
            let xf = s * (STREET + 0.9);
            // counter, back wall with menus, four posts
            mesh::cuboid(
                b.mesh_mut(counter),
                at(s * (STREET + 0.3), 0.45, zc),
                Vec3::new(0.6, 0.9, len - 0.2),
                Vec2::ONE,
            );
            mesh::cuboid(
                b.mesh_mut(menus),
                at(s * (STREET + 1.8), 1.3, zc),
                Vec3::new(0.08, 2.6, len),
                Vec2::splat(2.0),
            );
            for (px, pz) in [(STREET, -1.0), (STREET, 1.0), (STREET + 1.8, -1.0), (STREET + 1.8, 1.0)] {
                let y = if px > STREET + 1.0 { 1.4 } else { 1.15 };
                mesh::cylinder(
                    b.mesh_mut(posts),
                    at(s * px, y, zc + pz * len * 0.48),
                    0.04,
                    2.0 * y,
                    10,
                    1,
                    false,
                    Vec2::ONE,
                );
            }
            // awning sloping down towards the street, stripes running down the slope
            let slope = Quat::from_rotation_z(s * 0.22);
            let aw = Affine3A::from_rotation_translation(slope, Vec3::new(xf, 2.55, zc));
            mesh::cuboid(
                b.mesh_mut(awning_meshes[(j + side) % 2]),
                aw,
                Vec3::new(2.2, 0.03, len + 0.1),
                Vec2::new(1.2, 1.2),
            );
            let valance = at(s * (STREET - 0.18), 2.15, zc);
            mesh::cuboid(
                b.mesh_mut(valance_meshes[(j + side) % 2]),
                valance,
                Vec3::new(0.02, 0.34, len + 0.1),
                Vec2::new(1.2, 1.2),
            );
            // shop sign above the front edge, facing the street
            let (fg, bg) = SIGN_COLORS[k % SIGN_COLORS.len()];
            let name = NAMES[k % NAMES.len()];
            let sign_px = texture::sign(256, 64, &[name], 4, fg, bg, 3);
            let sign_tex = b.add_texture(&format!("sign_{name}"), sign_px, WrapMode::ClampToEdge);
            let sign =
                b.add_material(MaterialDesc::glossy(&format!("sign_{name}"), [1.0; 3], 0.4).with_texture(sign_tex));
            let m = b.add_mesh(&format!("sign_{k}"), sign);
            let (w, h) = (2.0f32, 0.5f32);
            let outline = [Vec2::new(0.0, 0.0), Vec2::new(w, 0.0), Vec2::new(w, -h), Vec2::new(0.0, -h)];
            // rotate the +Z cap to face the street (-s X), centred on the stall front
            let face = Quat::from_rotation_y(-s * FRAC_PI_2);
            let corner = Vec3::new(s * (STREET - 0.15), 3.05, zc) + face * Vec3::new(-w / 2.0, 0.0, 0.0);
            mesh::extrude(
                b.mesh_mut(m),
                Affine3A::from_rotation_translation(face, corner),
                &outline,
                0.04,
                Vec2::new(w, h),
            );
            // goods on the counter: balloons and bottles
            for g in 0..6 {
                let gz = zc - 1.0 + g as f32 * 0.4 + uniform(rng, -0.05, 0.05);
                let r = uniform(rng, 0.07, 0.12);
                let gx = s * (STREET + 0.3 + uniform(rng, -0.15, 0.15));
                let gm = goods[(g + k) % goods.len()];
                if g % 3 == 2 {
                    mesh::cylinder(b.mesh_mut(gm), at(gx, 0.9 + 0.12, gz), 0.04, 0.24, 12, 1, true, Vec2::ONE);
                } else {
                    mesh::uv_sphere(b.mesh_mut(gm), at(gx, 0.9 + r, gz), r, 16, 8, Vec2::splat(0.5));
                }
            }
            // two lanterns at the awning's front corners
            for dz in [-1.0, 1.0] {
                let p = Vec3::new(s * (STREET - 0.2), 1.95, zc + dz * 1.1);
                lantern(b, lanterns[(j + side + (dz > 0.0) as usize) % 2], caps, p, 0.16);
            }
            k += 1;
        }
    }
}

/// Lantern materials: red paper, white paper (both emissive, ribbed, with glyphs) and black caps.
fn lantern_materials(b: &mut SceneBuilder) -> [MaterialId; 3] {
    let paper = |base: Srgb, ink: Srgb, text: &str| {
        // ribs every 6 px, a band of text around the middle (u wraps around the lantern)
        let mut img =
            RgbImage::from_fn(128, 64, |_, y| Rgb(if y % 6 == 0 { texture::shade(base, 0.55) } else { base }));
        for c in 0..2 {
            texture::draw_text(&mut img, text, 8 + c * 64, 22, 2, ink);
        }
        img
    };
    let red = b.add_texture("lantern_red", paper([255, 90, 50], [60, 10, 5], "MATSU"), WrapMode::Repeat);
    let white = b.add_texture("lantern_white", paper([255, 240, 205], [150, 20, 10], "SAI"), WrapMode::Repeat);
    let red = b.add_material(MaterialDesc {
        emissive_texture: Some(red),
        emissive_strength: 4.0,
        ..MaterialDesc::emitter("lantern_red", [1.0, 0.75, 0.6])
    });
    let white = b.add_material(MaterialDesc {
        emissive_texture: Some(white),
        emissive_strength: 3.0,
        ..MaterialDesc::emitter("lantern_white", [1.0, 0.85, 0.65])
    });
    let caps = b.add_material(MaterialDesc::glossy("lantern_caps", [0.03, 0.03, 0.03], 0.3));
    [red, white, caps]
}

/// One paper lantern (an elongated sphere with black caps) centred at `p`, radius `r`.
fn lantern(b: &mut SceneBuilder, paper: super::MeshId, caps: super::MeshId, p: Vec3, r: f32) {
    let xf = Affine3A::from_scale_rotation_translation(Vec3::new(1.0, 1.3, 1.0), Quat::IDENTITY, p);
    mesh::uv_sphere(b.mesh_mut(paper), xf, r, 24, 12, Vec2::new(TAU * r, PI * r));
    for dy in [-1.0, 1.0] {
        mesh::cylinder(b.mesh_mut(caps), at(p.x, p.y + dy * 1.22 * r, p.z), 0.45 * r, 0.12 * r, 12, 1, true, Vec2::ONE);
    }
}

/// Bamboo poles with branches, leaves and tanzaku (paper strips with writing).
fn bamboo(b: &mut SceneBuilder, rng: &mut Rng) {
    let repeat = WrapMode::Repeat;
    // culm: mottled green with dark nodes every 0.4 m (texture 64 x 128 px over 0.3 x 0.8 m)
    let mottle = texture::fbm_values(64, 128, &Fbm { cells: 2, octaves: 5, gain: 0.6, seed: 301 });
    let culm_px = RgbImage::from_fn(64, 128, |x, y| {
        let base = texture::mix([70, 120, 40], [140, 170, 70], mottle[(y * 64 + x) as usize]);
        Rgb(if y % 64 < 3 { texture::shade(base, 0.45) } else { base })
    });
    let culm_tex = b.add_texture("bamboo_culm", culm_px, repeat);
    let culm = b.add_material(MaterialDesc::glossy("bamboo_culm", [1.0; 3], 0.35).with_texture(culm_tex));
    let leaf =
        b.add_material(MaterialDesc { double_sided: true, ..MaterialDesc::diffuse("bamboo_leaf", [0.12, 0.32, 0.06]) });
    // tanzaku: five paper colours, each with columns of black glyph writing
    const PAPER: [Srgb; 6] =
        [[225, 40, 50], [250, 210, 40], [40, 110, 210], [60, 170, 80], [240, 130, 180], [245, 240, 230]];
    let strips: Vec<_> = PAPER
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let px = texture::text_page(32, 96, 1, [20, 15, 15], c, 3, 310 + i as u64);
            let t = b.add_texture(&format!("tanzaku_{i}"), px, repeat);
            let m = b.add_material(MaterialDesc {
                double_sided: true,
                ..MaterialDesc::diffuse(&format!("tanzaku_{i}"), [1.0; 3]).with_texture(t)
            });
            b.add_mesh(&format!("tanzaku_{i}"), m)
        })
        .collect();
    let culms = b.add_mesh("bamboo_culms", culm);
    let leaves = b.add_mesh("bamboo_leaves", leaf);
    // poles: foreground left and right, then along both stall rows
    let poles = [
        Vec3::new(-2.0, 0.0, 5.6),
        Vec3::new(2.3, 0.0, 4.6),
        Vec3::new(-2.7, 0.0, 0.0),
        Vec3::new(2.7, 0.0, -3.5),
        Vec3::new(-2.7, 0.0, -7.0),
        Vec3::new(2.7, 0.0, -10.5),
        Vec3::new(-2.7, 0.0, -14.0),
        Vec3::new(2.7, 0.0, -18.0),
    ];
    for (pi, &base) in poles.iter().enumerate() {
        let h = uniform(rng, 5.0, 6.0);
        let tilt = Quat::from_rotation_z(uniform(rng, -0.06, 0.06)) * Quat::from_rotation_x(uniform(rng, -0.05, 0.05));
        let culm_xf = Affine3A::from_rotation_translation(tilt, base + tilt * Vec3::new(0.0, h / 2.0, 0.0));
        mesh::cylinder(b.mesh_mut(culms), culm_xf, 0.055, h, 16, 8, false, Vec2::new(0.3, 0.8));
        // branches: thin culms leaning out from the upper two thirds, hung with leaves and strips
        let n_branch = 7;
        for k in 0..n_branch {
            let y0 = h * (0.35 + 0.6 * k as f32 / n_branch as f32);
            let root = base + tilt * Vec3::new(0.0, y0, 0.0);
            let yaw = uniform(rng, 0.0, TAU);
            let lean = uniform(rng, 0.7, 1.2);
            let len = uniform(rng, 0.7, 1.3) * (1.0 - 0.4 * k as f32 / n_branch as f32);
            let rot = Quat::from_rotation_y(yaw) * Quat::from_rotation_z(-lean);
            let dir = rot * Vec3::Y;
            let xf = Affine3A::from_rotation_translation(rot, root + dir * (len / 2.0));
            mesh::cylinder(b.mesh_mut(culms), xf, 0.015, len, 6, 1, false, Vec2::new(0.3, 0.8));
            for _ in 0..8 {
                let p = root + dir * uniform(rng, 0.2, 1.0) * len;
                let r = Quat::from_rotation_y(uniform(rng, 0.0, TAU)) * Quat::from_rotation_z(uniform(rng, -0.8, 0.8));
                let xf = Affine3A::from_rotation_translation(r, p + r * Vec3::new(0.14, 0.0, 0.0));
                mesh::cuboid(b.mesh_mut(leaves), xf, Vec3::new(0.28, 0.004, 0.045), Vec2::ONE);
            }
            let n_strips = if pi < 2 { 12 } else { 7 };
            for _ in 0..n_strips {
                let p = root + dir * uniform(rng, 0.15, 1.0) * len;
                let hang = uniform(rng, 0.02, 0.12);
                let r =
                    Quat::from_rotation_y(uniform(rng, 0.0, TAU)) * Quat::from_rotation_x(uniform(rng, -0.12, 0.12));
                let xf = Affine3A::from_rotation_translation(r, p - Vec3::new(0.0, hang + 0.13, 0.0));
                let m = strips[rng.next_u32() as usize % strips.len()];
                mesh::cuboid(b.mesh_mut(m), xf, Vec3::new(0.09, 0.26, 0.003), Vec2::new(0.09, 0.26));
            }
        }
    }
}

/// Strings of lanterns across the street at four depths.
fn lantern_strings(b: &mut SceneBuilder, mats: [MaterialId; 3]) {
    let rope = b.add_material(MaterialDesc::diffuse("rope", [0.1, 0.08, 0.06]));
    let ropes = b.add_mesh("lantern_ropes", rope);
    let red = b.add_mesh("string_lanterns_red", mats[0]);
    let white = b.add_mesh("string_lanterns_white", mats[1]);
    let caps = b.add_mesh("string_lantern_caps", mats[2]);
    let across = Quat::from_rotation_z(FRAC_PI_2);
    for (i, z) in [2.5f32, -3.0, -9.0, -15.0].into_iter().enumerate() {
        let y = 3.6 + 0.1 * i as f32;
        let xf = Affine3A::from_rotation_translation(across, Vec3::new(0.0, y, z));
        mesh::cylinder(b.mesh_mut(ropes), xf, 0.01, 2.0 * STREET + 1.0, 6, 1, false, Vec2::ONE);
        let n = 7;
        for k in 0..n {
            let x = -STREET + 0.45 + k as f32 * (2.0 * STREET - 0.9) / (n - 1) as f32;
            // the rope sags: lanterns near the middle hang lower
            let sag = 0.35 * (1.0 - (x / STREET).powi(2));
            let m = if (k + i) % 2 == 0 { red } else { white };
            lantern(b, m, caps, Vec3::new(x, y - 0.3 - sag, z), 0.2);
        }
    }
}

/// Hand-held shake: 0.1 s keys whose position and look-at wander on a seeded random walk in
/// all three axes, with a slow push forward down the street. `SHAKE` scales the motion (tuned so
/// that `evsim scene info` reports blur in the benchmark's range).
fn keys() -> Vec<(f64, Vec3, Vec3)> {
    const SHAKE: f32 = 1.0;
    let mut rng = Rng::new(0x7a4a_ba7a_0001, 9);
    (0..=10)
        .map(|k| {
            let t = k as f64 * 0.1;
            let mut jitter =
                |a: f32| Vec3::new(uniform(&mut rng, -a, a), uniform(&mut rng, -a, a) * 0.6, uniform(&mut rng, -a, a));
            let eye = EYE + Vec3::new(0.0, 0.0, -2.5 * t as f32) + jitter(0.6 * SHAKE);
            let look = TARGET + jitter(1.1 * SHAKE);
            (t, eye, look)
        })
        .collect()
}

/// The dataset description of `tanabata`.
fn toml_text() -> String {
    let keys_text = super::camera_path::key_tables(&super::camera_path::keys_from(&keys()), 2);
    format!(
        r#"# tanabata: a summer-festival street at dusk, written by `evsim scene generate --only tanabata`
# (simulator/src/scenegen/tanabata.rs); regenerate rather than edit the glTF.
scene = "scene.gltf"

{camera_and_sky}
# 1 s of hand-held shake while walking into the street: direction and speed change every 0.1 s
[trajectory]
type = "keys"
{keys_text}
{tail}"#,
        tail = super::camera_path::OUTDOOR_DATASET_AND_EVENTS,
        camera_and_sky = super::camera_path::camera_and_sky(EYE, TARGET, FOV_Y_DEG, 1, [0.32, 0.36, 0.5]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rich enough for a benchmark: tens of thousands of triangles, several emissive materials.
    #[test]
    fn tanabata_is_rich() {
        let s = tanabata();
        assert!(s.builder.triangle_count() >= 50_000, "{}", s.builder.triangle_count());
        assert!(s.builder.materials.iter().filter(|m| m.emissive != [0.0; 3]).count() >= 3);
    }
}
