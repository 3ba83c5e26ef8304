//! Tests of `gltf_write.rs`.

use super::*;
use crate::scenegen::{mesh, texture};
use glam::Affine3A;

/// A fresh, empty folder under the system temp dir.
pub fn temp_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("evblur-scenegen-{tag}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Three materials using every field, two textures (RGB + RGBA, two wrap modes), two
/// meshes, a camera.
fn sample() -> SceneBuilder {
    let mut b = SceneBuilder::new();
    let t0 =
        b.add_texture("stripes 1", texture::stripes(32, 16, 30.0, 6.0, [200, 10, 10], [10, 10, 200]), WrapMode::Repeat);
    let mr = image::RgbaImage::from_fn(8, 4, |x, _| image::Rgba([0, (x * 30) as u8, 255, 255]));
    let t1 = b.add_texture("mr", mr, WrapMode::MirroredRepeat);
    let t2 = b.add_texture("glow", texture::checker(16, 16, 4, [255; 3], [0; 3]), WrapMode::ClampToEdge);
    let m0 = b.add_material(MaterialDesc::glossy("paint", [0.9, 0.5, 0.1], 0.3).with_texture(t0));
    let m1 = b.add_material(MaterialDesc {
        metallic_roughness_texture: Some(t1),
        specular: Some(0.25),
        double_sided: true,
        ..MaterialDesc::metal("metal", [0.8, 0.7, 0.6], 0.45)
    });
    let m2 = b.add_material(MaterialDesc {
        emissive_texture: Some(t2),
        emissive_strength: 2.5,
        ..MaterialDesc::emitter("lamp", [3.0, 1.5, 0.3])
    });
    let a = b.add_mesh("box", m0);
    mesh::cuboid(b.mesh_mut(a), Affine3A::from_translation(Vec3::new(0.0, 0.5, 0.0)), Vec3::ONE, Vec2::ONE);
    let s = b.add_mesh("ball", m1);
    mesh::uv_sphere(b.mesh_mut(s), Affine3A::from_translation(Vec3::new(2.0, 0.5, 0.0)), 0.5, 16, 8, Vec2::ONE);
    let l = b.add_mesh("lamp", m2);
    mesh::plane(b.mesh_mut(l), Affine3A::from_translation(Vec3::new(0.0, 3.0, 0.0)), Vec2::ONE, [2, 2], Vec2::ONE);
    b.add_mesh("empty", m0);
    b.set_camera(PerspectiveCamera::look_at("cam", Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, Vec3::Y, 35.0));
    b.add_light(PunctualLight::Point { position: Vec3::new(1.0, 2.0, 3.0), intensity: Vec3::new(8.0, 4.0, 2.0) });
    b.add_light(PunctualLight::Spot {
        position: Vec3::new(0.0, 4.0, 0.0),
        direction: Vec3::new(0.3, -1.0, 0.1).normalize(),
        intensity: Vec3::splat(5.0),
        inner_cone: 0.2,
        outer_cone: 0.5,
    });
    b.add_light(PunctualLight::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::new(0.0, 1.0, 0.5) });
    b
}

#[test]
fn written_gltf_loads_back_with_the_same_content() {
    let b = sample();
    let dir = temp_dir("roundtrip");
    let w = b.write(&dir, "sample").unwrap();
    assert_eq!(w.textures.len(), 3);
    let s = crate::scene::load(&w.gltf).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.mesh.len(), b.triangle_count());
    assert_eq!(s.mesh.len(), 12 + 2 * 16 * 7 + 8);
    assert_eq!(s.materials.len(), 3);
    assert_eq!(s.textures.len(), 3);
    // geometry in node order: positions and normals exactly as built
    assert_eq!(&s.mesh.positions[..24], &b.meshes[0].positions[..]);
    assert_eq!(&s.mesh.normals[..24], &b.meshes[0].normals[..]);
    assert_eq!(&s.mesh.uvs[..24], &b.meshes[0].uvs[..]);
    for (loaded, desc) in s.materials.iter().zip(&b.materials) {
        assert_eq!(loaded.name, desc.name);
        assert_eq!(loaded.base_color, Vec3::from(desc.base_color));
        assert_eq!(loaded.metallic, desc.metallic);
        assert_eq!(loaded.roughness, desc.roughness);
        assert_eq!(loaded.specular, desc.specular.unwrap_or(1.0));
        assert_eq!(loaded.double_sided, desc.double_sided);
        let e = Vec3::from(desc.emissive) * desc.emissive_strength;
        assert!((loaded.emission - e).abs().max_element() <= 1e-6 * e.max_element(), "{} vs {e}", loaded.emission);
        assert_eq!(loaded.base_color_texture.is_some(), desc.base_color_texture.is_some());
        assert_eq!(loaded.metallic_roughness_texture.is_some(), desc.metallic_roughness_texture.is_some());
        assert_eq!(loaded.emission_texture.is_some(), desc.emissive_texture.is_some());
    }
    // textures decode at their size with their wrap mode (each is used in one slot, in order)
    for (t, d) in s.textures.iter().zip(&b.textures) {
        assert_eq!((t.width, t.height), d.pixels.dimensions());
        assert_eq!((t.wrap_u, t.wrap_v), (d.wrap, d.wrap));
    }
    // the metallic-roughness texture is linear: G of texel (1, 0) is 30/255
    let mr = &s.textures[s.materials[1].metallic_roughness_texture.unwrap().index as usize];
    assert!((mr.texels[1].y - 30.0 / 255.0).abs() < 1e-6);
    assert_eq!(s.lights.len(), 3);
    for (got, want) in s.lights.iter().zip(&b.lights) {
        use PunctualLight::*;
        let close = |a: Vec3, b: Vec3| a.abs_diff_eq(b, 1e-5);
        match (got, want) {
            (Point { position: p, intensity: i }, Point { position: q, intensity: j }) => {
                assert!(close(*p, *q) && close(*i, *j), "{got:?} vs {want:?}")
            }
            (
                Spot { position: p, direction: d, intensity: i, inner_cone: a, outer_cone: o },
                Spot { position: q, direction: e, intensity: j, inner_cone: b, outer_cone: c },
            ) => {
                assert!(close(*p, *q) && close(*d, *e) && close(*i, *j) && a == b && o == c, "{got:?} vs {want:?}")
            }
            (Directional { direction: d, irradiance: i }, Directional { direction: e, irradiance: j }) => {
                assert!(close(*d, *e) && close(*i, *j), "{got:?} vs {want:?}")
            }
            _ => panic!("{got:?} vs {want:?}"),
        }
    }
    let cam = &s.cameras[0];
    assert!((cam.yfov - 35f32.to_radians()).abs() < 1e-6);
    assert!(cam.origin().abs_diff_eq(Vec3::new(0.0, 1.0, 5.0), 1e-5));
}

#[test]
fn output_is_deterministic_and_has_position_bounds() {
    let (d1, d2) = (temp_dir("det1"), temp_dir("det2"));
    let (w1, w2) = (sample().write(&d1, "s").unwrap(), sample().write(&d2, "s").unwrap());
    let files = |w: &WrittenScene| [vec![w.gltf.clone(), w.bin.clone()], w.textures.clone()].concat();
    for (a, b) in files(&w1).iter().zip(files(&w2).iter()) {
        assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap(), "{}", a.display());
    }
    let json: Value = serde_json::from_slice(&std::fs::read(&w1.gltf).unwrap()).unwrap();
    let acc = &json["accessors"][0];
    assert_eq!(acc["min"], json!([-0.5, 0.0, -0.5]));
    assert_eq!(acc["max"], json!([0.5, 1.0, 0.5]));
    // the emissive factor stays in [0, 1]; the rest went to the strength
    let lamp = &json["materials"][2];
    assert_eq!(lamp["emissiveFactor"], json!([1.0, 0.5, 0.1]));
    assert_eq!(lamp["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"], json!(7.5));
}

#[test]
fn invalid_input_is_an_error_naming_the_element() {
    let mut b = sample();
    b.materials[1].roughness = 1.5;
    let e = b.write(&temp_dir("bad"), "bad").unwrap_err().to_string();
    assert!(e.contains("material 1 \"metal\""), "{e}");
    let mut b = sample();
    b.meshes[0].indices.push([0, 1, 999]);
    let e = b.validate().unwrap_err().to_string();
    assert!(e.contains("mesh 0 \"box\""), "{e}");
    let e = SceneBuilder::new().validate().unwrap_err().to_string();
    assert!(e.contains("no triangles"), "{e}");
}

#[test]
fn photometric_intensities_read_back_to_the_same_radiometric_bits() {
    // the committed scenes' lights come back bit for bit (so their dataset keys stay)
    for v in [2.4f32, 3.0, 2.2, 1.0, 8.0, 0.5] {
        assert_eq!(photometric(v) / LUMENS_PER_WATT, v, "{v}");
    }
    // any power within an ulp: small, large, awkward mantissas
    let (mut x, mut n, mut exact) = (1.0e-3f32, 0, 0);
    while x < 1.0e5 {
        for v in [x, x * 1.1, x * std::f32::consts::PI, x.next_up()] {
            let p = photometric(v);
            let back = p / LUMENS_PER_WATT;
            assert!(back == v || back == v.next_up() || back == v.next_down(), "{v} -> {p} -> {back}");
            exact += usize::from(back == v);
            // through the JSON number the loader parses
            let json: f32 = serde_json::from_value(num(p)).unwrap();
            assert_eq!(json, p, "{p} does not survive JSON");
            n += 1;
        }
        x *= 1.37;
    }
    assert!(n > 100 && exact * 10 > n * 8, "{exact} of {n} exact");
}
