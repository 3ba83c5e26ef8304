//! Tests of `surface.rs`.

use super::*;

#[test]
fn a_path_position_is_the_fractional_index_of_the_nearest_point() {
    let path = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 0.0)];
    assert_eq!(path_position(&path, Vec3::ZERO), 0.0);
    assert_eq!(path_position(&path, Vec3::X), 1.0);
    assert_eq!(path_position(&path, Vec3::new(0.25, 0.5, 0.0)), 0.25);
    assert_eq!(path_position(&path, Vec3::new(1.5, 1.0, 0.0)), 1.5);
    // beyond the end (the last segment has no length): its start, the first of the equals
    assert_eq!(path_position(&path, Vec3::new(1.0, 3.0, 0.0)), 2.0);
    assert_eq!(path_position(&path, Vec3::new(-1.0, 0.0, 0.0)), 0.0);
}

#[test]
fn distance_to_a_triangle_is_the_brute_force_minimum() {
    let mut rng = crate::base::sampling::Rng::new(7, 1);
    let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
    for _ in 0..200 {
        let (a, b, c, p) = (v(), v(), v(), v());
        // brute force: the nearest of a fine barycentric grid over the triangle
        let n = 200;
        let mut best = f32::INFINITY;
        for i in 0..=n {
            for j in 0..=n - i {
                let q = a + (b - a) * (i as f32 / n as f32) + (c - a) * (j as f32 / n as f32);
                best = best.min((p - q).length());
            }
        }
        let d = distance_to_triangle(p, a, b, c);
        let step = (b - a).length().max((c - a).length()) / n as f32;
        assert!(d <= best + 1e-4 && d >= best - step - 1e-4, "{d} vs brute force {best}");
    }
}

/// Random triangles, some long and thin.
fn triangles(n: usize) -> Vec<[Vec3; 3]> {
    let mut rng = crate::base::sampling::Rng::new(11, 2);
    let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
    (0..n)
        .map(|k| {
            let (a, b) = (v(), v());
            let c = if k % 2 == 0 { v() } else { a + (v() - a) * 0.02 };
            [a, b, c]
        })
        .collect()
}

#[test]
fn a_grid_reads_a_linear_field_exactly_inside_its_triangle() {
    let f = |p: Vec3| Vec3::new(p.x + 2.0 * p.y - p.z, 3.0 - p.z, 0.5 * p.x);
    let mut rng = crate::base::sampling::Rng::new(5, 3);
    for t in triangles(40) {
        let g = Grid::over(t, 0.3, 64, |_, q| f(q));
        for _ in 0..50 {
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let p = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
            // the corners of p's cell: inside the triangle, exact (but for the hair the
            // computed points are pulled inwards); outside, the value at the triangle's
            // nearest point, off by at most the gradient (< 2.5) times the cell diagonal
            let d = p - g.origin;
            let (gu, gv) = (d.dot(g.ax).floor(), d.dot(g.ay).floor());
            let (cx, cy) = (g.ax / g.ax.length_squared(), g.ay / g.ay.length_squared());
            let inside = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].iter().all(|&(du, dv)| {
                let q = g.origin + cx * (gu + du) + cy * (gv + dv);
                distance_to_triangle(q, t[0], t[1], t[2]) < 1e-4
            });
            let bound = if inside { 0.02 } else { 2.5 * 0.3 * 2f32.sqrt() };
            let err = (g.at(p) - f(p)).abs().max_element();
            assert!(err < bound, "{t:?} at {p}: {} vs {} (cell inside: {inside})", g.at(p), f(p));
        }
    }
}

#[test]
fn a_thin_triangles_grid_has_about_the_points_its_area_needs() {
    // 10 x 0.05, spacing 0.1: a barycentric lattice would take 101 * 102 / 2 = 5151
    let t = [Vec3::ZERO, Vec3::new(10.0, 0.0, 0.0), Vec3::new(3.0, 0.05, 0.0)];
    let g = Grid::over(t, 0.1, 1024, |_, _| Vec3::ONE);
    assert!(g.points() <= 2 * 101 + 2, "{} points", g.points());
    assert!(g.points() >= 101, "{} points", g.points());
    // a capped grid stays bounded and still reads its points
    let g = Grid::over(t, 1e-5, 16, |_, _| Vec3::ONE);
    assert!(g.values.len() <= 17 * 17);
    assert_eq!(g.at(Vec3::new(5.0, 0.01, 0.0)), Vec3::ONE);
}
