//! Sweep figures in the style of the Ev-DeblurNeRF robustness figures: a metric against a swept
//! setting (contrast threshold, exposure, ...), one line per method with a marker at each point.
//! The left axis (PSNR) is drawn with solid lines and circles, an optional right twin axis (LPIPS)
//! with dashed lines and triangles; a method has one colour on both axes. The legend (methods,
//! then which line style is which axis) sits right of the plot, never over a line.
//!
//! Points with a non-finite y (a missing metric, e.g. LPIPS `n/a`) are skipped and break the line
//! there, as in matplotlib; a series with no finite point is left out (and the right axis when none
//! of its series has one). Axis ranges span the data
//! and the x ticks with a margin; y tick labels share one number of decimals per axis.
//!
//! Drawn by `plotters` into an RGB buffer and encoded as PNG by `image`. Text uses the embedded
//! DejaVu Sans (`benchmark/assets/`), so no installed font is needed. Same [`Figure`] -> same bytes.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::ranged1d::{BoldPoints, DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::BenchError;

/// One line of a figure: a label (the legend entry; equal labels share a colour across the two
/// axes) and its (x, y) points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend entry, e.g. the method's name.
    pub label: String,
    /// (swept value, metric) points, drawn in the given order.
    pub points: Vec<(f64, f64)>,
}

/// A metric-vs-setting figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title above the plot.
    pub title: String,
    /// X axis label (the swept setting).
    pub x_label: String,
    /// Left axis label, drawn with solid lines.
    pub left_label: String,
    /// Series on the left axis.
    pub left: Vec<Series>,
    /// Right (twin) axis label, drawn with dashed lines; `None` = no right axis.
    pub right_label: Option<String>,
    /// Series on the right axis (needs `right_label`).
    pub right: Vec<Series>,
    /// Draw the x axis at the listed x values only (the swept values), formatted as given.
    /// Empty = at the data's distinct x values.
    pub x_ticks: Vec<(f64, String)>,
}

/// Width and height of the PNG in pixels.
pub const SIZE: (u32, u32) = (960, 600);

/// The embedded font, registered with plotters as its `sans-serif` family.
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Text heights in pixels: title, axis labels, ticks and legend.
const TITLE_PX: f64 = 30.0;
const DESC_PX: f64 = 24.0;
const TEXT_PX: f64 = 20.0;
/// Line width, marker radius, dash and gap lengths in pixels.
const LINE_PX: u32 = 3;
const MARKER_PX: i32 = 6;
const DASH_PX: i32 = 12;
const GAP_PX: i32 = 8;
/// Most labelled ticks on a y axis.
const Y_LABELS: usize = 10;
/// Fraction of a data range added on each side.
const MARGIN: f64 = 0.08;

/// matplotlib's tab10, assigned to labels in order of first appearance (cycled past ten).
const PALETTE: [RGBColor; 10] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0xbc, 0xbd, 0x22),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// Draws `fig` into PNG bytes.
pub fn render_png(fig: &Figure) -> Result<Vec<u8>, BenchError> {
    let err = |message: String| BenchError::plot(&fig.title, message);
    if !font_registered() {
        return Err(err("the embedded font benchmark/assets/DejaVuSans.ttf does not parse; restore it".into()));
    }
    let plan = Plan::new(fig)?;
    let (w, h) = SIZE;
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    draw(fig, &plan, &mut rgb).map_err(|e| err(format!("drawing failed: {e}")))?;
    encode_png(w, h, rgb).map_err(err)
}

/// PNG bytes of a `w` x `h` RGB buffer (3 bytes per pixel, row-major).
pub(crate) fn encode_png(w: u32, h: u32, rgb: Vec<u8>) -> Result<Vec<u8>, String> {
    let img = image::RgbImage::from_raw(w, h, rgb).ok_or("pixel buffer has the wrong size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| format!("encoding PNG: {e}"))?;
    Ok(png)
}

/// Draws `fig` and writes it to `path` atomically (temporary file + rename).
pub fn write_png(fig: &Figure, path: &Path) -> Result<(), BenchError> {
    let png = render_png(fig)?;
    simulator::image_io::write_atomic(path, &png).map_err(|e| BenchError::results(path, format!("{e:#}")))
}

/// Registers the embedded font once; false if it does not parse.
pub(crate) fn font_registered() -> bool {
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| register_font("sans-serif", FontStyle::Normal, FONT).is_ok())
}

/// One drawable series: its runs of consecutive finite points (a missing point breaks the line).
struct Line<'a> {
    label: &'a str,
    colour: RGBColor,
    runs: Vec<Vec<(f64, f64)>>,
}

impl Line<'_> {
    fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.runs.iter().flatten().copied()
    }
}

/// `points` split at the non-finite y values, empty runs dropped.
fn runs(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let runs = points.split(|p| !p.1.is_finite()).filter(|run| !run.is_empty());
    runs.map(<[_]>::to_vec).collect()
}

/// What to draw, checked: the lines, the axis ranges and the x ticks.
struct Plan<'a> {
    left: Vec<Line<'a>>,
    right: Vec<Line<'a>>,
    /// Legend entries (label, colour) of the drawn lines, in colour order.
    legend: Vec<(&'a str, RGBColor)>,
    x: SweptAxis,
    x_labels: Vec<(f64, String)>,
    y_left: Range<f64>,
    y_right: Range<f64>,
}

impl<'a> Plan<'a> {
    fn new(fig: &'a Figure) -> Result<Plan<'a>, BenchError> {
        let err = |message: String| BenchError::plot(&fig.title, message);
        if fig.right_label.is_none() && !fig.right.is_empty() {
            return Err(err("right series given without right_label; set right_label or move them to left".into()));
        }
        let all = || fig.left.iter().chain(&fig.right);
        for s in all() {
            if let Some((x, _)) = s.points.iter().find(|p| !p.0.is_finite()) {
                return Err(err(format!("series \"{}\" has x = {x}; give every point a finite swept value", s.label)));
            }
        }
        if let Some((x, label)) = fig.x_ticks.iter().find(|t| !t.0.is_finite()) {
            return Err(err(format!("x tick \"{label}\" is at x = {x}; give every tick a finite value")));
        }
        // Colours by label order of first appearance.
        let mut labels: Vec<&str> = Vec::new();
        for s in all() {
            if !labels.contains(&s.label.as_str()) {
                labels.push(&s.label);
            }
        }
        let colour = |label: &str| PALETTE[labels.iter().position(|l| *l == label).unwrap_or(0) % PALETTE.len()];
        let lines = |series: &'a [Series]| -> Vec<Line<'a>> {
            let lines =
                series.iter().map(|s| Line { label: &s.label, colour: colour(&s.label), runs: runs(&s.points) });
            lines.filter(|l| !l.runs.is_empty()).collect()
        };
        let (left, right) = (lines(&fig.left), lines(&fig.right));
        if left.is_empty() && right.is_empty() {
            return Err(err(
                "no point with a finite metric to draw; score the cells first or leave this figure out".into()
            ));
        }
        let legend = labels
            .iter()
            .filter(|l| left.iter().chain(&right).any(|line| line.label == **l))
            .map(|l| (*l, colour(l)))
            .collect();
        let x_labels = if fig.x_ticks.is_empty() {
            let mut xs: Vec<f64> = left.iter().chain(&right).flat_map(|l| l.points().map(|p| p.0)).collect();
            xs.sort_by(f64::total_cmp);
            xs.dedup();
            xs.into_iter().map(|x| (x, format!("{x}"))).collect()
        } else {
            fig.x_ticks.clone()
        };
        let ys = |lines: &[Line]| lines.iter().flat_map(|l| l.points().map(|p| p.1)).collect::<Vec<_>>();
        let xs = left.iter().chain(&right).flat_map(|l| l.points().map(|p| p.0));
        let x_range = padded(&xs.chain(x_labels.iter().map(|t| t.0)).collect::<Vec<_>>());
        let (y_left, y_right) = (padded(&ys(&left)), padded(&ys(&right)));
        if ![&x_range, &y_left, &y_right].iter().all(|r| (r.end - r.start).is_finite() && r.end > r.start) {
            return Err(err("values too large to plot (axis range overflows); check the metrics".into()));
        }
        let x = SweptAxis { range: x_range, ticks: x_labels.iter().map(|t| t.0).collect() };
        Ok(Plan { left, right, legend, x, x_labels, y_left, y_right })
    }
}

/// The range of `values` widened by [`MARGIN`] on each side; a single value gets +-10 % (or +-1
/// at zero), no values give 0..1.
fn padded(values: &[f64]) -> Range<f64> {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if values.is_empty() {
        return 0.0..1.0;
    }
    let span = hi - lo;
    let pad = if span > 0.0 {
        span * MARGIN
    } else if lo != 0.0 {
        lo.abs() * 0.1
    } else {
        1.0
    };
    (lo - pad)..(hi + pad)
}

/// Decimals that print every labelled y tick on `range` exactly (at most 6), so that the labels
/// of one axis line up ("0.30", "0.32" rather than "0.3", "0.32").
fn tick_decimals(range: &Range<f64>) -> usize {
    let ticks = RangedCoordf64::from(range.clone()).key_points(BoldPoints(Y_LABELS));
    let exact = |v: f64, d: usize| {
        let scale = 10f64.powi(d as i32);
        ((v * scale).round() / scale - v).abs() <= 1e-9 * v.abs().max(1.0)
    };
    ticks.iter().map(|&v| (0..=6).find(|&d| exact(v, d)).unwrap_or(6)).max().unwrap_or(0)
}

/// A linear x axis whose grid lines and labels are exactly the swept values.
#[derive(Clone)]
struct SweptAxis {
    range: Range<f64>,
    ticks: Vec<f64>,
}

impl Ranged for SweptAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value - self.range.start) / (self.range.end - self.range.start);
        limit.0 + (t * f64::from(limit.1 - limit.0)).round() as i32
    }

    /// The ticks as the bold (labelled) points; no light grid lines.
    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// Draws the figure into `rgb` (SIZE, 3 bytes per pixel).
fn draw(fig: &Figure, plan: &Plan, rgb: &mut [u8]) -> DrawResult {
    let root = BitMapBackend::with_buffer_and_format(rgb, SIZE)?.into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(&fig.title, ("sans-serif", TITLE_PX))?;
    let has_right = fig.right_label.is_some() && !plan.right.is_empty();
    let key = |solid: bool, label: &str| (solid, label.to_owned());
    let keys: Vec<(bool, String)> = match &fig.right_label {
        Some(right) if has_right => vec![key(true, &fig.left_label), key(false, right)],
        _ => Vec::new(),
    };
    let text = TextStyle::from(("sans-serif", TEXT_PX).into_font());
    let mut text_w = 0;
    for label in plan.legend.iter().map(|e| e.0).chain(keys.iter().map(|k| k.1.as_str())) {
        text_w = text_w.max(root.estimate_text_size(label, &text)?.0 as i32);
    }
    let legend_w = (text_w + 70).min(SIZE.0 as i32 * 2 / 5);
    let (plot_area, legend_area) = root.split_horizontally(root.dim_in_pixel().0 as i32 - legend_w);

    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(62)
        .y_label_area_size(96)
        .right_y_label_area_size(if has_right { 96 } else { 0 })
        .build_cartesian_2d(plan.x.clone(), plan.y_left.clone())?
        .set_secondary_coord(plan.x.clone(), plan.y_right.clone());
    let x_fmt = |x: &f64| plan.x_labels.iter().find(|t| t.0 == *x).map(|t| t.1.clone()).unwrap_or_default();
    let (left_decimals, right_decimals) = (tick_decimals(&plan.y_left), tick_decimals(&plan.y_right));
    let left_fmt = |y: &f64| format!("{y:.left_decimals$}");
    let right_fmt = |y: &f64| format!("{y:.right_decimals$}");
    chart
        .configure_mesh()
        .x_desc(&fig.x_label)
        .y_desc(&fig.left_label)
        .x_label_formatter(&x_fmt)
        .y_labels(Y_LABELS)
        .y_label_formatter(&left_fmt)
        .label_style(text.clone())
        .axis_desc_style(("sans-serif", DESC_PX))
        .axis_style(BLACK.stroke_width(2))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(WHITE)
        .draw()?;
    if let (Some(right), true) = (&fig.right_label, has_right) {
        chart
            .configure_secondary_axes()
            .y_desc(right)
            .y_labels(Y_LABELS)
            .y_label_formatter(&right_fmt)
            .label_style(text.clone())
            .axis_desc_style(("sans-serif", DESC_PX))
            .axis_style(BLACK.stroke_width(2))
            .draw()?;
    }
    for line in &plan.left {
        for run in &line.runs {
            chart.draw_series(LineSeries::new(run.iter().copied(), line.colour.stroke_width(LINE_PX)))?;
        }
        chart.draw_series(line.points().map(|p| Circle::new(p, MARKER_PX, line.colour.filled())))?;
    }
    for line in &plan.right {
        for run in &line.runs {
            let style = line.colour.stroke_width(LINE_PX);
            chart.draw_secondary_series(DashedLineSeries::new(run.iter().copied(), DASH_PX, GAP_PX, style))?;
        }
        chart.draw_secondary_series(
            line.points().map(|p| TriangleMarker::new(p, MARKER_PX + 1, line.colour.filled())),
        )?;
    }
    draw_legend(&legend_area, plan, &keys, &text)?;
    root.present()?;
    Ok(())
}

/// The legend panel: a row per method (colour sample with marker, label), then a row per line
/// style (solid with circles = left axis, dashed with triangles = right axis) when there is a
/// right axis.
fn draw_legend(
    area: &DrawingArea<BitMapBackend, Shift>,
    plan: &Plan,
    keys: &[(bool, String)],
    text: &TextStyle,
) -> DrawResult {
    const ROW: i32 = 32;
    const SAMPLE: i32 = 40;
    let text = text.pos(Pos::new(HPos::Left, VPos::Center));
    let room = area.dim_in_pixel().0 as i32 - SAMPLE - 18;
    let mut y = 30;
    for (label, colour) in &plan.legend {
        area.draw(&PathElement::new([(4, y), (4 + SAMPLE, y)], colour.stroke_width(LINE_PX)))?;
        area.draw(&Circle::new((4 + SAMPLE / 2, y), MARKER_PX, colour.filled()))?;
        area.draw_text(&fit(area, label, &text, room)?, &text, (SAMPLE + 14, y))?;
        y += ROW;
    }
    y += ROW / 2;
    for (solid, label) in keys {
        let style = BLACK.stroke_width(LINE_PX);
        let middle = (4 + SAMPLE / 2, y);
        if *solid {
            area.draw(&PathElement::new([(4, y), (4 + SAMPLE, y)], style))?;
            area.draw(&Circle::new(middle, MARKER_PX, BLACK.filled()))?;
        } else {
            area.draw(&PathElement::new([(4, y), (4 + DASH_PX, y)], style))?;
            area.draw(&PathElement::new([(4 + SAMPLE - DASH_PX, y), (4 + SAMPLE, y)], style))?;
            area.draw(&TriangleMarker::new(middle, MARKER_PX + 1, BLACK.filled()))?;
        }
        area.draw_text(&fit(area, label, &text, room)?, &text, (SAMPLE + 14, y))?;
        y += ROW;
    }
    Ok(())
}

/// `label`, shortened with a trailing ellipsis until it is at most `room` pixels wide.
fn fit(
    area: &DrawingArea<BitMapBackend, Shift>,
    label: &str,
    text: &TextStyle,
    room: i32,
) -> Result<String, Box<dyn std::error::Error>> {
    let mut out = label.to_string();
    let mut chars: Vec<char> = label.chars().collect();
    while area.estimate_text_size(&out, text)?.0 as i32 > room && !chars.is_empty() {
        chars.pop();
        out = chars.iter().collect::<String>() + "…";
    }
    Ok(out)
}

#[cfg(test)]
#[path = "plot_tests.rs"]
mod tests;
