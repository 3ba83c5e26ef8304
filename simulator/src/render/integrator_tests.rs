//! Known-answer tests of the path tracer (no reference renderer needed).

use glam::{Vec2, Vec3};

use super::*;
use crate::scene::{Camera, Environment, Material, PunctualLight, Scene, TriangleMesh};

/// Add an axis-aligned quad (two triangles) with corners `c`, CCW around `c[1]-c[0] x c[2]-c[0]`.
fn quad(mesh: &mut TriangleMesh, c: [Vec3; 4], material: u32) {
    let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize();
    let base = mesh.positions.len() as u32;
    for p in c {
        mesh.positions.push(p);
        mesh.normals.push(n);
        mesh.uvs.push(Vec2::ZERO);
    }
    mesh.indices.push([base, base + 1, base + 2]);
    mesh.indices.push([base, base + 2, base + 3]);
    mesh.material.extend([material, material]);
}

/// A cube [-1,1]^3 whose faces point inwards (`inward`) or outwards.
fn cube(mesh: &mut TriangleMesh, material: u32, inward: bool) {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let faces = [
        [v(-1., -1., -1.), v(1., -1., -1.), v(1., -1., 1.), v(-1., -1., 1.)], // bottom, normal -y
        [v(-1., 1., -1.), v(-1., 1., 1.), v(1., 1., 1.), v(1., 1., -1.)],     // top, +y
        [v(-1., -1., -1.), v(-1., 1., -1.), v(1., 1., -1.), v(1., -1., -1.)], // back, -z
        [v(-1., -1., 1.), v(1., -1., 1.), v(1., 1., 1.), v(-1., 1., 1.)],     // front, +z
        [v(-1., -1., -1.), v(-1., -1., 1.), v(-1., 1., 1.), v(-1., 1., -1.)], // left, -x
        [v(1., -1., -1.), v(1., 1., -1.), v(1., 1., 1.), v(1., -1., 1.)],     // right, +x
    ];
    for mut f in faces {
        if inward {
            f.reverse();
        }
        quad(mesh, f, material);
    }
}

fn lambert(albedo: f32, emission: f32) -> Material {
    Material {
        name: "m".into(),
        base_color: Vec3::splat(albedo),
        specular: 0.0,
        emission: Vec3::splat(emission),
        ..Material::default()
    }
}

fn settings(spp: u32, max_depth: u32) -> RenderSettings {
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 0.5), Vec3::ZERO, Vec3::Y, 1.2);
    RenderSettings { width: 16, height: 12, spp, max_depth, seed: 3, ..RenderSettings::new(cam) }
}

fn furnace_scene() -> Scene {
    let mut mesh = TriangleMesh::default();
    cube(&mut mesh, 0, true);
    Scene { mesh, materials: vec![lambert(0.5, 1.0)], ..Scene::default() }
}

#[test]
fn furnace_matches_the_geometric_series_at_every_depth() {
    // inner faces emit 1 with albedo 0.5: L = sum_{k < depth} 0.5^k
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    for (depth, want) in [(1, 1.0), (2, 1.5), (3, 1.75), (5, 1.9375), (u32::MAX, 2.0)] {
        let img = r.render(&settings(64, depth), None);
        let m = img.mean();
        assert!((m - Vec3::splat(want)).abs().max_element() < 0.01 * want, "depth {depth}: {m} vs {want}");
    }
}

#[test]
fn diffuse_plane_under_constant_environment_has_its_albedo() {
    // a two-sided quad of albedo 0.6 under a uniform environment of 1 reflects exactly 0.6
    let mut mesh = TriangleMesh::default();
    let s = 50.0;
    quad(&mut mesh, [Vec3::new(-s, 0., -s), Vec3::new(-s, 0., s), Vec3::new(s, 0., s), Vec3::new(s, 0., -s)], 0);
    let mut mat = lambert(0.6, 0.0);
    mat.double_sided = true;
    let scene = Scene { mesh, materials: vec![mat], environment: Environment::Constant(Vec3::ONE), ..Scene::default() };
    let r = Renderer::new(&scene);
    for (eye, target) in
        [(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, -0.2)), (Vec3::new(0.0, -1.0, 0.0), Vec3::new(0.0, 0.0, 0.2))]
    {
        let mut st = settings(256, 3);
        st.camera = Camera::look_at(eye, target, Vec3::Z, 0.3);
        let m = r.render(&st, None).mean();
        assert!((m - Vec3::splat(0.6)).abs().max_element() < 0.01, "{eye}: {m}");
    }
}

/// A Lambertian floor (albedo 0.5, half-size `s`) under a point light of intensity 8 at height
/// 2; with `blocker`, a square of that half-size at height 1 casts a shadow.
fn floor_under_point_light(s: f32, blocker: Option<f32>) -> Scene {
    let mut mesh = TriangleMesh::default();
    quad(&mut mesh, [Vec3::new(-s, 0., -s), Vec3::new(-s, 0., s), Vec3::new(s, 0., s), Vec3::new(s, 0., -s)], 0);
    if let Some(b) = blocker {
        quad(
            &mut mesh,
            [Vec3::new(-b, 1.0, -b), Vec3::new(-b, 1.0, b), Vec3::new(b, 1.0, b), Vec3::new(b, 1.0, -b)],
            0,
        );
    }
    Scene {
        mesh,
        materials: vec![lambert(0.5, 0.0)],
        lights: vec![PunctualLight::Point { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::splat(8.0) }],
        ..Scene::default()
    }
}

#[test]
fn point_light_gives_inverse_square_irradiance() {
    // a Lambertian floor of albedo a under a point light of intensity I at height h:
    // directly below, L = a/pi * I / h^2
    let scene = floor_under_point_light(10.0, None);
    let r = Renderer::new(&scene);
    let mut st = settings(4, 2);
    st.camera = Camera::look_at(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, -1e-3), Vec3::Z, 0.01);
    let m = r.render(&st, None).mean();
    let want = 0.5 / std::f32::consts::PI * 8.0 / 4.0;
    assert!((m.x - want).abs() < 2e-3 * want, "{m} vs {want}");
}

#[test]
fn one_sided_emitter_is_dark_from_behind() {
    let mut mesh = TriangleMesh::default();
    cube(&mut mesh, 0, false); // faces point outwards: the camera inside sees their backs
    let scene = Scene { mesh, materials: vec![lambert(0.0, 1.0)], ..Scene::default() };
    let img = Renderer::new(&scene).render(&settings(4, 5), None);
    assert_eq!(img.mean(), Vec3::ZERO);
}

#[test]
fn image_is_identical_with_one_or_two_threads() {
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    let st = settings(8, 5);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| r.render(&st, None));
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap().install(|| r.render(&st, None));
    assert_eq!(one, two);
    let mut other_frame = st.clone();
    other_frame.frame = 1;
    assert_ne!(r.render(&other_frame, None), one, "frames must use different random streams");
}

#[test]
fn clamping_only_darkens_and_never_touches_directly_seen_emitters() {
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    let base = settings(16, 3);
    let plain = r.render(&base, None);
    // a clamp above every contribution changes nothing
    assert_eq!(r.render(&RenderSettings { clamp: 1e9, ..base.clone() }, None), plain);
    // a low clamp darkens every channel of every pixel (or leaves it), and the mean strictly
    let low = r.render(&RenderSettings { clamp: 0.1, ..base.clone() }, None);
    for (a, b) in low.pixels.iter().zip(&plain.pixels) {
        assert!(a.cmple(*b + Vec3::splat(1e-6)).all(), "{a} > {b}");
    }
    assert!(low.mean().x < plain.mean().x - 0.1, "{} vs {}", low.mean(), plain.mean());
    // emitters seen from the camera are never clamped: depth 1 shows emission 1 exactly
    let direct = RenderSettings { clamp: 0.1, ..settings(4, 1) };
    assert!((r.render(&direct, None).mean() - Vec3::ONE).abs().max_element() < 1e-6);
}

#[test]
fn several_light_samples_per_vertex_keep_the_expectation() {
    // furnace at depth 3: L = 1.75 whatever the number of light samples (MIS with N light
    // samples against one BSDF sample stays unbiased)
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    let one =
        r.render(&RenderSettings { sampler: crate::render::sampler::SamplerKind::Independent, ..settings(4, 3) }, None);
    let four = r.render(
        &RenderSettings {
            light_samples: 4,
            sampler: crate::render::sampler::SamplerKind::Independent,
            ..settings(4, 3)
        },
        None,
    );
    for img in [&one, &four] {
        assert!((img.mean().x - 1.75).abs() < 0.03, "{}", img.mean());
    }
    // a plane under a constant sky with splitting still reflects its albedo
    let mut mesh = TriangleMesh::default();
    let s = 50.0;
    quad(&mut mesh, [Vec3::new(-s, 0., -s), Vec3::new(-s, 0., s), Vec3::new(s, 0., s), Vec3::new(s, 0., -s)], 0);
    let mut mat = lambert(0.6, 0.0);
    mat.double_sided = true;
    let plane = Scene { mesh, materials: vec![mat], environment: Environment::Constant(Vec3::ONE), ..Scene::default() };
    let r = Renderer::new(&plane);
    let cam = Camera::look_at(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, Vec3::Z, 0.5);
    let st = RenderSettings { light_samples: 3, max_depth: 2, ..RenderSettings::new(cam) };
    let img = r.render(&RenderSettings { width: 16, height: 12, spp: 64, ..st }, None);
    assert!((img.mean() - Vec3::splat(0.6)).abs().max_element() < 0.01, "{}", img.mean());
}

/// RMS difference of the luminances of two buffers.
fn rms(a: &[Vec3], b: &[Vec3]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (luminance(*x) - luminance(*y)).powi(2) as f64).sum::<f64>() / a.len() as f64).sqrt()
}

#[test]
fn feature_rays_steady_the_reflectance_buffer_and_leave_image_and_lighting_alone() {
    // a floor with a fine checker texture (several checks per pixel) under a point light
    let (scene, st) = checker_floor(80.0);
    let r = Renderer::new(&scene);
    let mut spread = Vec::new();
    for feature_spp in [0, 64] {
        let with = |seed: u64| {
            let st = RenderSettings { seed, feature_spp, ..st.clone() };
            let (img, f) = r.render_with_features(&st);
            assert_eq!(img, r.render(&st, None), "the image is the shaded samples' mean whatever feature_spp is");
            (img, f)
        };
        let ((img1, f1), (_, f2)) = (with(1), with(2));
        if feature_spp == 0 {
            // the 4-sample image itself carries the texture's sampling noise
            assert!(rms(&img1.pixels, &with(3).0.pixels) > 0.01);
        } else {
            // the shaded samples (and so the lighting estimate) do not depend on feature_spp
            let base = RenderSettings { seed: 1, ..st.clone() };
            assert_eq!(f1.irradiance, r.render_with_features(&base).1.irradiance);
        }
        spread.push(rms(&f1.albedo, &f2.albedo));
        // remodulating gives the image back where all rays are shaded
        if feature_spp == 0 {
            for (i, p) in img1.pixels.iter().enumerate() {
                let back = f1.irradiance[i] * f1.albedo[i] + f1.emission[i];
                assert!((back - *p).abs().max_element() < 1e-4 * p.max_element().max(1e-3), "{back} vs {p}");
            }
        }
    }
    // 16x the rays: the reflectance buffer's seed-to-seed spread drops by about 4x
    assert!(spread[1] * 2.5 < spread[0], "albedo spread {:?}", spread);
}

/// A floor at y = 0 with a fine checker texture (`per_unit` checks per world unit) under a
/// point light, and a camera 1 above it looking straight down with a 1 rad field of view.
fn checker_floor(per_unit: f32) -> (Scene, RenderSettings) {
    let mut mesh = TriangleMesh::default();
    let s = 4.0;
    quad(&mut mesh, [Vec3::new(-s, 0., -s), Vec3::new(-s, 0., s), Vec3::new(s, 0., s), Vec3::new(s, 0., -s)], 0);
    for (uv, p) in mesh.uvs.iter_mut().zip(&mesh.positions) {
        *uv = Vec2::new(p.x, p.z) * per_unit / 2.0; // the 2x2 texture holds 2 checks per unit of uv
    }
    let dark = glam::Vec4::new(0.05, 0.05, 0.05, 1.0);
    let light = glam::Vec4::new(0.9, 0.9, 0.9, 1.0);
    let texture = crate::scene::Texture::new("checker", 2, 2, vec![dark, light, light, dark]);
    let mut mat = lambert(1.0, 0.0);
    mat.base_color_texture = Some(crate::scene::TextureRef { index: 0 });
    let scene = Scene {
        mesh,
        materials: vec![mat],
        textures: vec![texture],
        lights: vec![PunctualLight::Point { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::splat(8.0) }],
        ..Scene::default()
    };
    let mut st = settings(4, 2);
    st.camera = Camera::look_at(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, -1e-3), Vec3::Z, 1.0);
    (scene, st)
}

#[test]
fn texture_footprint_of_a_camera_ray_is_its_pixel_step_on_the_surface() {
    // looking straight down from height 1: one pixel step is 2 tan(0.5) / height world units,
    // so the texture coordinate moves by that times the uv scale, along one axis per step
    let (scene, mut st) = checker_floor(80.0);
    st.texture_filter = 1.0;
    let r = Renderer::new(&scene);
    let uv_per_unit = 40.0;
    let step = 2.0 * 0.5f32.tan() / st.height as f32 * uv_per_unit;
    for film in [Vec2::new(8.0, 6.0), Vec2::new(3.3, 9.1)] {
        let dir = st.camera.direction(film, st.width, st.height);
        let origin = st.camera.origin();
        let hit = r.accel.intersect(origin, dir, 0.0, f32::INFINITY).unwrap();
        let sh = r.surface(&hit, origin, dir);
        let spread = r.camera_spread(&st, film).unwrap();
        let (du, dv) = r.uv_footprint(&hit, &sh, origin, spread).unwrap();
        // off-centre rays hit obliquely: a few percent longer steps
        for d in [du, dv] {
            assert!(d.length() > 0.99 * step && d.length() < 1.1 * step, "{film}: {d} vs {step}");
            assert!(d.x.abs().min(d.y.abs()) < 0.05 * step, "{film}: {d} is not along one axis");
        }
        assert!(du.dot(dv).abs() < 0.05 * step * step, "{film}: {du} and {dv} are not perpendicular");
    }
    // off: no spread
    st.texture_filter = 0.0;
    assert!(r.camera_spread(&st, Vec2::new(8.0, 6.0)).is_none());
}

#[test]
fn texture_filtering_steadies_the_reflectance_and_keeps_its_mean() {
    // 80 checks per unit: about 7 across a pixel. Four rays per pixel alias badly unfiltered;
    // with the texture filtered over a pixel each ray reads nearly the pixel's mean
    let (scene, st) = checker_floor(80.0);
    let r = Renderer::new(&scene);
    let mean = |a: &[Vec3]| a.iter().map(|x| luminance(*x) as f64).sum::<f64>() / a.len() as f64;
    let mut spread = Vec::new();
    for texture_filter in [0.0, 1.0] {
        let albedo =
            |seed: u64| r.render_with_features(&RenderSettings { seed, texture_filter, ..st.clone() }).1.albedo;
        let (a1, a2) = (albedo(1), albedo(2));
        spread.push(rms(&a1, &a2));
        // the checker's mean reflectance is (0.05 + 0.9) / 2 (unfiltered: 768 rays of 0.05 or
        // 0.9, a standard error of 0.015)
        let tol = if texture_filter > 0.0 { 0.005 } else { 0.045 };
        assert!((mean(&a1) - 0.475).abs() < tol, "texture_filter {texture_filter}: mean {}", mean(&a1));
    }
    assert!(spread[1] * 4.0 < spread[0], "albedo spread {spread:?}");
}

/// A closed diffuse room (inward cube, albedo 0.6) lit by a square ceiling lamp, with a smaller
/// outward cube (albedo 0.3) standing in it, seen from inside: edges, shadows and interreflection.
fn lit_room() -> (Scene, RenderSettings) {
    let mut mesh = TriangleMesh::default();
    cube(&mut mesh, 0, true);
    // facing down, a little below the ceiling
    let lamp = 0.98;
    quad(
        &mut mesh,
        [
            Vec3::new(-0.3, lamp, -0.3),
            Vec3::new(0.3, lamp, -0.3),
            Vec3::new(0.3, lamp, 0.3),
            Vec3::new(-0.3, lamp, 0.3),
        ],
        1,
    );
    let mut inner = TriangleMesh::default();
    cube(&mut inner, 2, false);
    for p in &mut inner.positions {
        *p = *p * 0.35 + Vec3::new(0.2, -0.65, -0.3);
    }
    mesh.append(&inner);
    let materials = vec![lambert(0.6, 0.0), lambert(0.0, 12.0), lambert(0.3, 0.0)];
    let cam = Camera::look_at(Vec3::new(-0.6, 0.3, 0.9), Vec3::new(0.2, -0.5, -0.3), Vec3::Y, 1.3);
    let st = RenderSettings { width: 40, height: 30, spp: 8, max_depth: 5, seed: 5, ..RenderSettings::new(cam) };
    (Scene { mesh, materials, ..Scene::default() }, st)
}

#[test]
fn rasterised_camera_rays_give_the_traced_image_but_for_edge_samples() {
    let (scene, st) = lit_room();
    let r = Renderer::new(&scene);
    let st = RenderSettings { feature_spp: 16, ..st };
    let (img, f) = r.render_with_features(&st);
    let traced = r.render(&st, None);
    let same = img.pixels.iter().zip(&traced.pixels).filter(|(a, b)| a == b).count();
    assert!(same * 1000 >= img.pixels.len() * 995, "{same} of {} pixels identical", img.pixels.len());
    // nothing is left uncovered inside a closed room, and the depth buffer is the room's
    assert_eq!(r.visibility(&st, 16).uncovered_fraction(), 0.0);
    assert!(f.depth.iter().all(|&d| d > 0.0 && d < 4.0));
}

#[test]
fn radiance_cache_is_exact_in_the_furnace() {
    // every surface emits 1 and reflects half (Lambert: the cache's diffuse assumption holds):
    // the expectation is the full paths' sum_{k < depth} 0.5^k
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    for (depth, want) in [(3, 1.75), (5, 1.9375)] {
        let st = RenderSettings { radiance_cache: 32, cache_spacing: 0.7, ..settings(32, depth) };
        let m = r.render_with_features(&st).0.mean();
        assert!((m - Vec3::splat(want)).abs().max_element() < 0.01 * want, "depth {depth}: {m} vs {want}");
    }
    // depth 2 (direct light only) never reaches a second bounce: no cache
    assert!(r.radiance_cache(&settings(4, 2)).is_none());
}

#[test]
fn radiance_cache_stays_close_to_full_paths_and_shortens_them() {
    let (scene, st) = lit_room();
    let r = Renderer::new(&scene);
    let full = r.render(&RenderSettings { spp: 512, ..st.clone() }, None);
    let st_cached = RenderSettings { spp: 512, radiance_cache: 64, cache_spacing: 0.25, ..st.clone() };
    let cached = r.render_with_features(&st_cached).0;
    let (mf, mc) = (luminance(full.mean()), luminance(cached.mean()));
    assert!((mc - mf).abs() < 0.01 * mf, "mean {mc} vs full paths {mf}");
    let rel = rms(&cached.pixels, &full.pixels) / mf as f64;
    assert!(rel < 0.02, "relative rms difference {rel}");
    // it filled lattices for the sides paths reached: the room's inner sides, not the outsides
    let cache = r.radiance_cache(&st_cached).expect("same parameters: the same cache");
    let (sides, points) = cache.filled();
    assert!(sides > 0 && sides <= scene.mesh.len() && points >= 3 * sides, "{sides} sides, {points} points");
}

#[test]
fn first_vertex_cache_is_exact_in_the_furnace() {
    // the camera samples' light samples and the cache paths' BSDF samples of the emitters
    // share the direct light by MIS weights that sum to one: no light counted twice or lost
    let scene = furnace_scene();
    let r = Renderer::new(&scene);
    for (depth, want) in [(3, 1.75), (5, 1.9375)] {
        let st = RenderSettings { radiance_cache: 32, cache_spacing: 0.7, cache_vertex: 1, ..settings(32, depth) };
        let m = r.render_with_features(&st).0.mean();
        assert!((m - Vec3::splat(want)).abs().max_element() < 0.01 * want, "depth {depth}: {m} vs {want}");
    }
}

#[test]
fn first_vertex_cache_stays_close_to_full_paths_with_steadier_pixels() {
    let (scene, st) = lit_room();
    let r = Renderer::new(&scene);
    let full = r.render(&RenderSettings { spp: 512, ..st.clone() }, None);
    let (mf, n) = (luminance(full.mean()), full.pixels.len());
    let cached = |vertex: u32, spp: u32| {
        let st = RenderSettings { spp, radiance_cache: 64, cache_spacing: 0.1, cache_vertex: vertex, ..st.clone() };
        r.render_with_features(&st).0
    };
    let first = cached(1, 512);
    let mc = luminance(first.mean());
    // (measured: 0.1% and 1.0%)
    assert!((mc - mf).abs() < 0.01 * mf, "mean {mc} vs full paths {mf}");
    let rel = rms(&first.pixels, &full.pixels) / mf as f64;
    assert!(rel < 0.025, "relative rms difference {rel}");
    // at few samples, the pixels stray less from the converged image than the second-vertex
    // cache's do (no bounce ray: the indirect light is the same in every sample)
    let (second_4, first_4) = (cached(2, 4), cached(1, 4));
    let (e2, e1) = (rms(&second_4.pixels, &cached(2, 512).pixels), rms(&first_4.pixels, &first.pixels));
    // (measured: 0.0144 against 0.0243)
    assert!(e1 * 1.3 < e2, "rms error at 4 spp: first-vertex cache {e1}, second-vertex {e2} ({n} pixels)");
}

#[test]
fn radiance_cache_gives_the_same_bytes_whatever_the_threads_or_frame_order() {
    for vertex in [2, 1] {
        radiance_cache_bytes_do_not_depend_on_threads_or_frame_order(vertex);
    }
}

fn radiance_cache_bytes_do_not_depend_on_threads_or_frame_order(cache_vertex: u32) {
    let (scene, st) = lit_room();
    let st = RenderSettings { radiance_cache: 8, cache_spacing: 0.3, cache_vertex, ..st };
    let frame1 = RenderSettings {
        frame: 1,
        camera: Camera::look_at(Vec3::new(-0.5, 0.2, 0.9), Vec3::ZERO, Vec3::Y, 1.3),
        ..st.clone()
    };
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    // a fresh renderer (empty cache) rendering frame 1 alone, on one thread
    let alone = {
        let r = Renderer::new(&scene);
        pool(1).install(|| r.render_with_features(&frame1))
    };
    // another renders frame 0 first (filling lattices in another order), on two threads
    let r = Renderer::new(&scene);
    pool(2).install(|| r.render_with_features(&st));
    let after = pool(2).install(|| r.render_with_features(&frame1));
    assert_eq!(alone, after);
}

#[test]
fn first_hit_rays_from_the_buffer_agree_with_traced_ones() {
    // untextured walls with an emitter in view, a finely textured floor seen at an angle, and
    // the same floor glowing with the texture (textured emission, as screens and signs have)
    let (floor, mut floor_st) = checker_floor(7.0);
    floor_st.camera = Camera::look_at(Vec3::new(0.3, 1.0, 2.0), Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 1.0);
    let mut glowing = floor.clone();
    glowing.materials[0].emission = Vec3::splat(2.0);
    glowing.materials[0].emission_texture = glowing.materials[0].base_color_texture;
    let glowing_st = floor_st.clone();
    let (room, mut room_st) = lit_room();
    // pixels of 0.008 rad (0.002 in a dataset frame)
    for st in [&mut floor_st, &mut room_st] {
        (st.width, st.height) = (160, 120);
    }
    let glowing_st = RenderSettings { width: 160, height: 120, ..glowing_st };
    for (scene, st) in [(room, room_st), (floor, floor_st), (glowing, glowing_st)] {
        let r = Renderer::new(&scene);
        let rays = 16;
        let vis = r.visibility(&st, rays);
        let film_rays = st.camera.film_rays(st.width, st.height);
        let (mut close, mut n) = (0, 0);
        for y in 0..st.height {
            for x in 0..st.width {
                let key = pixel_key(st.seed, (y * st.width + x) as u64, st.frame);
                let zero = first_hits::FirstHitSums::default;
                let (mut fast, mut traced) = (zero(), zero());
                r.first_hit_rays(&st, x, y, 0..rays, Some(&vis), &film_rays, key, &mut fast);
                // the same rays, each traced through the BVH
                for i in 0..rays {
                    let c = vis.offset(x, y, i);
                    let dir = film_rays.direction(Vec2::new(x as f32 + c.x, y as f32 + c.y));
                    let mut first = FirstHit::new(-dir);
                    r.first_hit(
                        r.camera_hit(None, st.camera.origin(), dir),
                        st.camera.origin(),
                        dir,
                        &st,
                        &mut first,
                        None,
                    );
                    traced.albedo += first.albedo;
                    traced.normal += first.normal;
                    traced.depth += first.depth;
                    traced.emission += first.emission;
                    traced.rays += 1;
                }
                assert_eq!(fast.rays, rays);
                let near =
                    |a: Vec3, b: Vec3, tol: f32| (a - b).abs().max_element() <= tol * (1.0 + b.abs().max_element());
                n += 1;
                // reflectance and emission per ray; distance and normal at the mean film point
                // (off by the second order of the pixel's angle)
                if near(fast.albedo, traced.albedo, 1e-4)
                    && near(fast.emission, traced.emission, 1e-4)
                    && fast.normal.normalize().dot(traced.normal.normalize()) > 1.0 - 1e-5
                    && (fast.depth - traced.depth).abs() <= 1e-3 * traced.depth
                {
                    close += 1;
                }
            }
        }
        // only pixels with a ray within float error of an edge may differ
        assert!(close * 1000 >= n * 990, "{close} of {n} pixels agree");
    }
}

#[test]
fn adaptive_sampling_adds_samples_where_the_estimate_is_noisy() {
    let (scene, st) = lit_room();
    let r = Renderer::new(&scene);
    let base = RenderSettings { spp: 2, feature_spp: 16, ..st };
    let adaptive = RenderSettings { spp_max: 12, adaptive_variance: 0.05, ..base.clone() };
    let (img, f) = r.render_with_features(&adaptive);
    // the first-hit buffers do not change: the extra samples shade rays that were first-hit rays
    let (_, f_base) = r.render_with_features(&base);
    assert_eq!(
        (&f.albedo, &f.normal, &f.depth, &f.emission),
        (&f_base.albedo, &f_base.normal, &f_base.depth, &f_base.emission)
    );
    // every pixel is what `n` samples everywhere give it, for its own n in 2..=12
    let uniform: Vec<Image> =
        (2..=12).map(|spp| r.render_with_features(&RenderSettings { spp, ..base.clone() }).0).collect();
    let counts: Vec<u32> = (0..img.pixels.len())
        .map(|i| {
            let n = uniform.iter().position(|u| u.pixels[i] == img.pixels[i]);
            n.unwrap_or_else(|| panic!("pixel {i} matches no uniform sample count")) as u32 + 2
        })
        .collect();
    assert!(counts.contains(&2) && counts.iter().any(|&n| n > 6), "counts {counts:?}");
    // the pixels given more samples are those whose first 2 were further from the converged
    // image (in log luminance, what events see)
    let reference = r.render_with_features(&RenderSettings { spp: 1024, ..base.clone() }).0;
    let log_err = |i: usize| {
        let l = |c: Vec3| (luminance(c) as f64 + 1e-3).ln();
        (l(uniform[0].pixels[i]) - l(reference.pixels[i])).abs()
    };
    let mean_err = |boosted: bool| {
        let e: Vec<f64> = (0..counts.len()).filter(|&i| (counts[i] > 2) == boosted).map(log_err).collect();
        e.iter().sum::<f64>() / e.len() as f64
    };
    let (err_boosted, err_rest) = (mean_err(true), mean_err(false));
    assert!(err_boosted > 1.2 * err_rest, "2-sample log error {err_boosted} (boosted pixels) vs {err_rest} (the rest)");
    // the same bytes whatever the thread count
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    assert_eq!(pool(1).install(|| r.render_with_features(&adaptive)), (img, f));
}

#[test]
fn surface_cache_frames_match_full_paths_in_the_lit_room_and_ignore_thread_count() {
    // the room of `lit_room` at max depth 3 (the lamp, its direct light and one bounce): the
    // surface-cache frame against a converged path-traced render of the same view
    let (scene, st) = lit_room();
    let r = Renderer::new(&scene);
    let st = RenderSettings { max_depth: 3, feature_spp: 16, radiance_cache: 32, surface_paths: 128, ..st };
    let vis = r.visibility(&st, 16);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| {
        let r = Renderer::new(&scene);
        r.render_surface(&st, &r.visibility(&st, 16))
    });
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap().install(|| r.render_surface(&st, &vis));
    assert_eq!(one, two, "the bytes must not depend on thread count or fill order");
    let truth = r.render(&RenderSettings { spp: 1024, ..st.clone() }, None);
    let (m, t) = (two.mean(), truth.mean());
    assert!((m - t).abs().max_element() < 0.03 * t.max_element(), "mean {m} vs full paths {t}");
    // per pixel: the lattice's interpolation and the cached bounce stay within a few percent
    let rel = rms(&two.pixels, &truth.pixels) / (t.x as f64);
    assert!(rel < 0.08, "relative RMS {rel}");
}

#[test]
fn surface_cache_glossy_blocks_ignore_thread_count_and_keep_the_mean() {
    // the lit room with a metal box: its reflection traced by glossy paths shared over 1x1 and
    // 3x3 blocks of pixels (the edge blocks cut short), against full paths
    let (mut scene, st) = lit_room();
    scene.materials[2] = Material { metallic: 1.0, roughness: 0.3, ..lambert(0.8, 0.0) };
    let r = Renderer::new(&scene);
    let st = RenderSettings { max_depth: 3, feature_spp: 16, radiance_cache: 16, surface_paths: 32, ..st };
    assert!(!st.width.is_multiple_of(3) || !st.height.is_multiple_of(3), "the test wants edge blocks");
    let vis = r.visibility(&st, 16);
    let truth = r.render(&RenderSettings { spp: 512, ..st.clone() }, None);
    let t = truth.mean();
    for block in [1, 3] {
        let sb = RenderSettings { glossy_block: block, ..st.clone() };
        let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        let one = pool(1).install(|| r.render_surface(&sb, &vis));
        let two = pool(2).install(|| r.render_surface(&sb, &vis));
        assert_eq!(one, two, "block {block}: the bytes must not depend on thread count");
        let m = two.mean();
        assert!((m - t).abs().max_element() < 0.04 * t.max_element(), "block {block}: mean {m} vs full paths {t}");
    }
}

#[test]
fn surface_cache_glossy_grids_keep_the_mean_ignore_thread_count_and_blend_keyframes() {
    // the lit room with a rough metal box (GGX alpha 0.16: it reads the glossy grids), seen
    // from a short camera path with keyframes every 2 frames: frames on a keyframe (max depth 3)
    // and between two (max depth 6), against full paths from the same camera
    let (mut scene, st) = lit_room();
    scene.materials[2] = Material { metallic: 1.0, roughness: 0.4, ..lambert(0.8, 0.0) };
    let r = Renderer::new(&scene);
    let eye = |k: usize| Vec3::new(-0.6 + 0.02 * k as f32, 0.3, 0.9);
    let path = std::sync::Arc::new((0..5).map(eye).collect::<Vec<_>>());
    let at = |k: usize| Camera::look_at(eye(k), Vec3::new(0.2, -0.5, -0.3), Vec3::Y, 1.3);
    let st = RenderSettings {
        max_depth: 6,
        feature_spp: 16,
        radiance_cache: 16,
        surface_paths: 32,
        glossy_stride: 2,
        camera_path: Some(path),
        ..st
    };
    let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    for (k, max_depth) in [(2, 3), (1, 6)] {
        let sk = RenderSettings { camera: at(k), max_depth, ..st.clone() };
        let vis = r.visibility(&sk, 16);
        let one = pool(1).install(|| {
            let fresh = Renderer::new(&scene);
            fresh.render_surface(&sk, &fresh.visibility(&sk, 16))
        });
        let two = pool(2).install(|| r.render_surface(&sk, &vis));
        assert_eq!(one, two, "frame {k}: the bytes must not depend on thread count or fill order");
        let truth = r.render(&RenderSettings { spp: 512, camera_path: None, ..sk.clone() }, None);
        let (m, t) = (two.mean(), truth.mean());
        assert!((m - t).abs().max_element() < 0.04 * t.max_element(), "frame {k}: mean {m} vs full paths {t}");
        // the pixels that see only the metal box (the last 12 triangles), whose light is all
        // glossy: their mean against full paths and against traced glossy paths
        let first_box = scene.mesh.len() as u32 - 12;
        let on_box = |i: usize| {
            let (x, y) = ((i % sk.width as usize) as u32, (i / sk.width as usize) as u32);
            (0..16).all(|j| vis.prim(x, y, j).is_some_and(|p| p >= first_box))
        };
        let box_mean = |img: &crate::base::image::Image| {
            let px: Vec<Vec3> = (0..img.pixels.len()).filter(|&i| on_box(i)).map(|i| img.pixels[i]).collect();
            (px.iter().copied().sum::<Vec3>() / px.len() as f32, px.len())
        };
        let traced = r.render_surface(&RenderSettings { glossy_stride: 0, ..sk.clone() }, &vis);
        let ((g, n), (b, _), (tr, _)) = (box_mean(&two), box_mean(&truth), box_mean(&traced));
        assert!(n >= 20, "frame {k}: {n} pixels on the box");
        // the grids hold what the traced glossy paths estimate, with the bounces max_depth
        // allows: both within 0.5% of full paths at max depth 3 and 6 (reading a first
        // vertex's surface grid at the second vertex, as before SURFACE_VERSION 4, put the box
        // 41% above full paths at max depth 3, 8% at 6)
        for (name, other, tol) in [("traced glossy paths", tr, 0.03), ("full paths", b, 0.03)] {
            let rel = (g - other).abs().max_element() / other.max_element();
            assert!(rel < tol, "frame {k}: the box's mean {g} vs {name} {other} ({n} pixels; full {b}, traced {tr})");
        }
    }
    // keyframes 0 and 2 are held; a frame on keyframe 2 reads it alone, so rendering frame 2
    // with a stride of 2 and of 1 (keyframes 2 and 3, weight 0 on 3) gives the same bytes
    let s2 = RenderSettings { camera: at(2), ..st.clone() };
    let vis = r.visibility(&s2, 16);
    let a = r.render_surface(&s2, &vis);
    let b = r.render_surface(&RenderSettings { glossy_stride: 1, ..s2.clone() }, &vis);
    assert_eq!(a, b, "a frame on a keyframe reads that keyframe alone");
}

#[test]
fn surface_cache_shadow_lattice_keeps_a_point_lights_shadow_edge_sharp() {
    // a floor under a point light with a square blocker: the surface-cache frame's shadow edge
    // matches the traced render's pixel for pixel, but for the pixels the edge crosses
    let scene = floor_under_point_light(4.0, Some(0.3));
    let r = Renderer::new(&scene);
    let cam = Camera::look_at(Vec3::new(0.0, 3.5, 0.01), Vec3::ZERO, Vec3::Y, 0.9);
    let st = RenderSettings { width: 32, height: 32, max_depth: 2, feature_spp: 16, ..RenderSettings::new(cam) };
    let surf = r.render_surface(&st, &r.visibility(&st, 16));
    let truth = r.render(&RenderSettings { spp: 256, ..st.clone() }, None);
    let close = surf.pixels.iter().zip(&truth.pixels).filter(|(a, b)| (**a - **b).abs().max_element() < 0.01).count();
    assert!(close * 100 >= surf.pixels.len() * 85, "{close} of {} pixels agree", surf.pixels.len());
    // fully shadowed pixels: within a quarter (16 fixed samples per pixel against 256 random
    // ones decide the pixels the edge crosses)
    let dark = surf.pixels.iter().filter(|p| p.x < 1e-4).count();
    let dark_truth = truth.pixels.iter().filter(|p| p.x < 1e-4).count();
    let row = |img: &crate::base::image::Image| {
        (0..32).map(|x| format!("{:.3}", img.get(x, 16).x)).collect::<Vec<_>>().join(" ")
    };
    assert!(
        dark > 20 && dark.abs_diff(dark_truth) * 4 <= dark_truth,
        "shadow {dark} vs {dark_truth} pixels\n{}\n{}",
        row(&surf),
        row(&truth)
    );
}
