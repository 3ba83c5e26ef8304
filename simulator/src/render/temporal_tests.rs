use super::*;
use crate::base::sampling::Rng;

const W: u32 = 64;
const H: u32 = 48;

/// Reflectance of the plane z = 0 at world (x, y): a checkerboard of 0.2 / 0.8.
fn texture(p: Vec3) -> Vec3 {
    let c = ((p.x * 4.0).floor() + (p.y * 4.0).floor()).rem_euclid(2.0);
    Vec3::splat(0.2 + 0.6 * c)
}

/// Irradiance on the plane: a gradient plus a bright stripe about 3 pixels wide (a projection
/// off by half a pixel changes it by 10% on its flanks).
fn irradiance(p: Vec3) -> Vec3 {
    let stripe = 1.0 + (-((p.x - 0.3) / 0.15).powi(2)).exp();
    Vec3::new(1.0, 0.9, 0.8) * stripe * (1.0 + 0.1 * p.y)
}

/// Frame `k` of a camera sliding sideways (a lamp strip lies in the plane: its light must not
/// bleed into its surroundings) (0.1 per frame, about a pixel) in front of the
/// plane, with relative noise `noise` (independent per pixel and frame).
fn frame(k: i32, noise: f32, rng: &mut Rng) -> SequenceFrame {
    let (camera, image, features) = frame_parts(k, noise, rng);
    SequenceFrame::new(camera, &image, &features)
}

/// What [`frame`] makes its frame from.
fn frame_parts(k: i32, noise: f32, rng: &mut Rng) -> (Camera, Image, Features) {
    let origin = Vec3::new(0.1 * k as f32, 0.2, 5.0);
    let camera = Camera::look_at(origin, origin - Vec3::Z, Vec3::Y, 0.8);
    let mut image = Image::new(W, H);
    let mut features = Features::new(W, H);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let d = camera.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), W, H);
            let t = -origin.z / d.z;
            let p = origin + d * t;
            let n = 1.0 + noise * (2.0 * rng.next_f32() - 1.0) * 3f32.sqrt();
            image.pixels[i] = texture(p) * irradiance(p) * n;
            features.albedo[i] = texture(p);
            if (p.x + 0.5).abs() < 0.2 {
                // a lamp in the plane: seen directly, reported as emission with albedo 1
                image.pixels[i] = Vec3::splat(20.0);
                features.emission[i] = Vec3::splat(20.0);
                features.albedo[i] = Vec3::ONE;
            }
            features.normal[i] = Vec3::Z;
            features.depth[i] = t;
            features.variance[i] = (luminance(image.pixels[i]) * noise).powi(2);
        }
    }
    features.demodulate(&image);
    (camera, image, features)
}

fn truth(center: &SequenceFrame) -> Vec<Vec3> {
    let mut rng = Rng::new(0, 0);
    let k = (center.camera().origin().x / 0.1).round() as i32;
    frame(k, 0.0, &mut rng).image().pixels.clone()
}

/// RMS relative error against the noise-free frame, over pixels away from the image border.
fn rms_rel(a: &[Vec3], b: &[Vec3]) -> f32 {
    let mut s = 0.0;
    let mut n = 0;
    for y in 6..H - 6 {
        for x in 6..W - 6 {
            let i = (y * W + x) as usize;
            s += ((luminance(a[i]) - luminance(b[i])) / luminance(b[i])).powi(2);
            n += 1;
        }
    }
    (s / n as f32).sqrt()
}

fn refs(frames: &[SequenceFrame]) -> Vec<&SequenceFrame> {
    frames.iter().collect()
}

fn window(noise: f32, seed: u64) -> Vec<SequenceFrame> {
    window_with(noise, seed, |_, _, _| {})
}

/// [`window`] with `change(j, image, features)` applied to frame `j`'s render first.
fn window_with(noise: f32, seed: u64, change: impl Fn(usize, &mut Image, &mut Features)) -> Vec<SequenceFrame> {
    let mut rng = Rng::new(seed, 1);
    (-4..=4)
        .enumerate()
        .map(|(j, k)| {
            let (camera, mut image, mut features) = frame_parts(k, noise, &mut rng);
            change(j, &mut image, &mut features);
            SequenceFrame::new(camera, &image, &features)
        })
        .collect()
}

#[test]
fn noise_free_frames_come_back_unchanged() {
    // exact reprojection: the neighbours see the same lighting, stripe included
    let win = window(0.0, 1);
    let (img, f) = gather(&refs(&win), 4, &TemporalParams::default());
    let err = rms_rel(&img.pixels, &win[4].image().pixels);
    assert!(err < 0.01, "relative RMS change {err}");
    assert_eq!(f.albedo, win[4].features().albedo);
    assert_eq!(f.depth, win[4].features().depth);
}

#[test]
fn noise_drops_and_variance_follows() {
    let win = window(0.2, 2);
    let before = rms_rel(&win[4].image().pixels, &truth(&win[4]));
    let (img, f) = gather(&refs(&win), 4, &TemporalParams::default());
    let after = rms_rel(&img.pixels, &truth(&win[4]));
    // nine equal weights: the std of the mean is 1/3, bilinear reads lower
    assert!(after < 0.36 * before, "{before} -> {after}");
    let mean_var = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let ratio = mean_var(&f.variance) / mean_var(&win[4].features().variance);
    assert!(ratio < 0.2 && ratio > 0.02, "variance ratio {ratio}");
    // a radius of 1 averages less
    let (img1, _) = gather(&refs(&win[3..6]), 1, &TemporalParams { radius: 1, ..TemporalParams::default() });
    let after1 = rms_rel(&img1.pixels, &truth(&win[4]));
    assert!(after1 > after && after1 < before, "{before} -> radius 1 {after1} (radius 4 {after})");
}

#[test]
fn other_surfaces_are_not_averaged_in() {
    // an occluder (at half the distance, much brighter) covers the left third of every
    // neighbour: the centre frame must not take its light
    let win = window_with(0.0, 3, |j, image, features| {
        if j == 4 {
            return;
        }
        for y in 0..H {
            for x in 0..W / 3 {
                let i = (y * W + x) as usize;
                features.depth[i] *= 0.5;
                image.pixels[i] = Vec3::splat(50.0);
                features.irradiance[i] = Vec3::splat(50.0);
            }
        }
    });
    let (img, _) = gather(&refs(&win), 4, &TemporalParams::default());
    assert!(rms_rel(&img.pixels, &win[4].image().pixels) < 0.01);
    // the same with a crease: neighbours' normals tilted by 60 degrees
    let win = window_with(0.0, 4, |j, image, features| {
        if j != 4 {
            features.normal.iter_mut().for_each(|n| *n = Vec3::new(0.0, 0.866, 0.5));
            image.pixels.iter_mut().for_each(|p| *p *= 3.0);
            features.irradiance.iter_mut().for_each(|p| *p *= 3.0);
        }
    });
    let (img, _) = gather(&refs(&win), 4, &TemporalParams::default());
    assert!(rms_rel(&img.pixels, &win[4].image().pixels) < 1e-3, "a crease was averaged across");
}

#[test]
fn radius_zero_and_window_ends() {
    let win = window(0.2, 5);
    let (img, f) = gather(&refs(&win), 4, &TemporalParams { radius: 0, ..TemporalParams::default() });
    assert_eq!(img.pixels.len(), win[4].image().pixels.len());
    // reflectance, irradiance and the raw image are kept in half floats (relative error 2^-11
    // each), so radius 0 reproduces the raw render to a few parts in ten thousand
    assert!(rms_rel(&img.pixels, &win[4].image().pixels) < 2e-3);
    for (a, b) in f.variance.iter().zip(&win[4].features().variance) {
        assert!((a - b).abs() <= 1e-5 * b, "{a} vs {b}");
    }
    // one-sided at the start of a sequence
    let before = rms_rel(&win[0].image().pixels, &truth(&win[0]));
    let (img, _) = gather(&refs(&win[..5]), 0, &TemporalParams::default());
    assert!(rms_rel(&img.pixels, &truth(&win[0])) < 0.6 * before);
}

#[test]
fn same_bytes_for_any_thread_count() {
    let win = window(0.2, 6);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| gather(&refs(&win), 4, &TemporalParams::default()))
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn bad_settings_name_the_field() {
    let ok = TemporalParams::default();
    assert!(ok.validate().is_ok());
    let e = TemporalParams { radius: MAX_RADIUS + 1, ..ok }.validate().unwrap_err();
    assert!(e.contains("radius") && e.contains(&MAX_RADIUS.to_string()), "{e}");
    let e = TemporalParams { depth_tolerance: f32::NAN, ..ok }.validate().unwrap_err();
    assert!(e.contains("depth_tolerance"), "{e}");
    let e = TemporalParams { min_normal_dot: 2.0, ..ok }.validate().unwrap_err();
    assert!(e.contains("min_normal_dot"), "{e}");
}

#[test]
fn neighbours_reduced_to_their_records_give_the_same_frame() {
    let win = window(0.1, 5);
    let (img, f) = gather(&refs(&win), 4, &TemporalParams::default());
    let mut reduced = win.clone();
    for (j, fr) in reduced.iter_mut().enumerate() {
        if j != 4 {
            fr.keep_neighbour_data();
            assert!(fr.image().pixels.is_empty());
        }
    }
    let (img2, f2) = gather(&refs(&reduced), 4, &TemporalParams::default());
    assert_eq!(img, img2);
    assert_eq!(f, f2);
}
