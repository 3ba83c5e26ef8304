use super::*;

fn series(label: &str, points: &[(f64, f64)]) -> Series {
    Series { label: label.into(), points: points.to_vec() }
}

/// A contrast-threshold sweep: PSNR of three methods on the left, LPIPS on the right (one missing).
fn sweep() -> Figure {
    let c = [0.1, 0.2, 0.3, 0.5];
    let zip = |ys: [f64; 4]| c.iter().copied().zip(ys).collect::<Vec<_>>();
    Figure {
        title: "Robustness to the contrast threshold".into(),
        x_label: "contrast threshold C".into(),
        left_label: "PSNR (dB)".into(),
        left: vec![
            series("nerf", &zip([24.1, 24.0, 24.2, 24.1])),
            series("ev-deblurnerf", &zip([28.9, 28.1, 27.2, 25.9])),
            series("pdrf", &zip([27.3, 26.8, 26.0, 25.1])),
        ],
        right_label: Some("LPIPS".into()),
        right: vec![
            series("nerf", &zip([0.31, 0.32, 0.31, 0.31])),
            series("ev-deblurnerf", &zip([0.12, 0.14, f64::NAN, 0.21])),
            series("pdrf", &zip([0.16, 0.18, 0.2, 0.24])),
        ],
        x_ticks: c.iter().map(|&x| (x, format!("{x}"))).collect(),
    }
}

/// The figure with only `left` and `right` (one label, so colour PALETTE[0] on either axis).
fn one_line(left: Vec<Series>, right: Vec<Series>) -> Figure {
    Figure { left, right, right_label: Some("LPIPS".into()), x_ticks: Vec::new(), ..sweep() }
}

fn decode(png: &[u8]) -> image::RgbImage {
    image::load_from_memory_with_format(png, image::ImageFormat::Png).unwrap().to_rgb8()
}

/// Pixels of exactly `colour`.
fn count(img: &image::RgbImage, colour: RGBColor) -> usize {
    img.pixels().filter(|p| p.0 == [colour.0, colour.1, colour.2]).count()
}

#[test]
fn png_has_the_figure_size() {
    let img = decode(&render_png(&sweep()).unwrap());
    assert_eq!(img.dimensions(), SIZE);
}

#[test]
fn every_series_is_drawn_in_its_colour() {
    let img = decode(&render_png(&sweep()).unwrap());
    let counts: Vec<usize> = PALETTE[..4].iter().map(|&c| count(&img, c)).collect();
    // Three methods over ~600 px of plot: thousands of pixels each; no fourth colour.
    assert!(counts[..3].iter().all(|&n| n > 2000), "pixels per colour {counts:?}");
    assert_eq!(counts[3], 0, "pixels per colour {counts:?}");
}

#[test]
fn missing_values_are_skipped_and_empty_series_left_out() {
    let nan = f64::NAN;
    let fig = one_line(vec![series("a", &[(1.0, 2.0)]), series("b", &[(1.0, nan)])], vec![series("b", &[(1.0, nan)])]);
    let img = decode(&render_png(&fig).unwrap());
    assert!(count(&img, PALETTE[0]) > 100, "the single point and its legend entry are drawn");
    assert_eq!(count(&img, PALETTE[1]), 0, "series b has no finite point: no line, no legend entry");
}

#[test]
fn a_figure_without_finite_points_is_an_error() {
    let nan = f64::NAN;
    let fig = one_line(vec![series("a", &[(1.0, nan), (2.0, nan)])], vec![series("a", &[(1.0, f64::INFINITY)])]);
    let e = render_png(&fig).unwrap_err();
    assert!(matches!(&e, BenchError::Plot { title, .. } if *title == fig.title), "{e}");
    assert!(e.to_string().contains("no point with a finite metric"), "{e}");
}

#[test]
fn a_non_finite_x_or_right_series_without_label_is_an_error() {
    let fig = one_line(vec![series("a", &[(1.0, 2.0), (f64::NAN, 3.0)])], Vec::new());
    assert!(render_png(&fig).unwrap_err().to_string().contains("finite swept value"));
    let fig = Figure { right_label: None, ..sweep() };
    assert!(render_png(&fig).unwrap_err().to_string().contains("without right_label"));
}

#[test]
fn rendering_is_deterministic() {
    assert_eq!(render_png(&sweep()).unwrap(), render_png(&sweep()).unwrap());
}

#[test]
fn right_axis_lines_are_dashed() {
    let data = series("a", &[(0.1, 0.2), (0.2, 0.25), (0.3, 0.22), (0.5, 0.3)]);
    let solid = count(&decode(&render_png(&one_line(vec![data.clone()], Vec::new())).unwrap()), PALETTE[0]);
    let dashed = count(&decode(&render_png(&one_line(Vec::new(), vec![data])).unwrap()), PALETTE[0]);
    // Dashes of 12 px with 8 px gaps keep 60 % of the line: 65 % of all pixels with the markers and
    // the legend sample; a solid line on the right axis gives 82 % (its triangles are larger).
    assert!(dashed * 4 < solid * 3 && dashed * 10 > solid * 4, "solid {solid} px, dashed {dashed} px");
}

/// Writes the sweep figure to `<temp>/plot-example.png` for a look by eye:
/// `cargo test -p evblur-benchmark plot::tests::write_example -- --ignored`.
#[test]
#[ignore]
fn write_example() {
    let path = std::env::temp_dir().join("plot-example.png");
    write_png(&sweep(), &path).unwrap();
    println!("wrote {}", path.display());
}
