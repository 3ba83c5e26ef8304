//! The picture beside a table (`<form>-<scene>.png`): per sharp test view of a scene, a row of
//! panels side by side: the blurry input (the dataset's nearest training view: test views are
//! stored sharp), each table row's render of the test view (its first seed's cell, labelled with
//! that view's PSNR) and the sharp ground truth.
//!
//! The renders are the cells' `eval/NAME.png`, the images come from the dataset folder the cell
//! trained on (its run record, `config.toml`). A scene whose dataset or renders are not on this
//! machine (results copied elsewhere, a cell finished on another host) gets no picture and a
//! note saying why; the table does not depend on it. Small images are enlarged by a whole factor
//! (nearest neighbour) so that the labels fit. Same cells and images -> same bytes.

use std::path::{Path, PathBuf};

use image::RgbImage;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{Form, Table};
use crate::error::BenchError;
use crate::metrics::CellMetrics;

/// Most test views (rows) in one picture.
pub const MAX_VIEWS: usize = 4;
/// Panels narrower than this are enlarged (pixels).
const MIN_PANEL_W: u32 = 240;
/// Height of a panel's label strip, gap between panels, label text height (pixels).
const LABEL_H: u32 = 26;
const GAP: u32 = 6;
const TEXT_PX: f64 = 17.0;

/// One panel: its label and image.
pub struct Panel {
    /// The text above the image.
    pub label: String,
    /// The image (all panels of a picture share one size).
    pub image: RgbImage,
}

/// The cell of `row` on `scene` with the lowest seed, with its folder (relative to the results).
fn first_cell<'a>(table: &'a Table, row: &super::Row, scene: &str) -> Option<&'a (PathBuf, CellMetrics)> {
    table
        .cells
        .iter()
        .filter(|(_, m)| {
            m.scene == scene
                && match table.form {
                    Form::Table1 => m.method == row.label,
                    Form::Ablation => m.preset == row.preset && m.switches == row.switches,
                }
        })
        .min_by_key(|(_, m)| m.seed)
}

/// The dataset folder a cell trained on (its run record's `data`).
fn dataset_of(cell_dir: &Path) -> Result<PathBuf, String> {
    let record = trainer::run::read_record(&cell_dir.join("config.toml")).map_err(|e| e.to_string())?;
    if record.data.is_dir() {
        Ok(record.data)
    } else {
        Err(format!("its dataset {} is not on this machine", record.data.display()))
    }
}

fn read_rgb(path: &Path) -> Result<RgbImage, String> {
    image::open(path).map(|i| i.to_rgb8()).map_err(|e| format!("cannot read {} ({e})", path.display()))
}

/// The index of a view image's name (`07.png` -> 7).
fn view_index(name: &str) -> Option<usize> {
    Path::new(name).file_stem()?.to_str()?.parse().ok()
}

/// The training view nearest to `test` (by index; ties: the lower) among `images_1/`'s views.
fn nearest_training_view(data: &Path, test: usize, tests: &[usize]) -> Result<String, String> {
    let dir = data.join("images_1");
    let entries = std::fs::read_dir(&dir).map_err(|e| format!("cannot list {} ({e})", dir.display()))?;
    let mut names: Vec<String> = entries
        .filter_map(Result::ok)
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    names
        .into_iter()
        .filter_map(|n| view_index(&n).filter(|i| !tests.contains(i)).map(|i| (i.abs_diff(test), i, n)))
        .min()
        .map(|(_, _, n)| n)
        .ok_or_else(|| format!("{} holds no training view", dir.display()))
}

/// The panels of `scene`'s picture, a row per test view (at most [`MAX_VIEWS`]).
pub fn scene_panels(table: &Table, results: &Path, scene: &str) -> Result<Vec<Vec<Panel>>, String> {
    let cells: Vec<(&super::Row, &(PathBuf, CellMetrics))> =
        table.rows.iter().filter_map(|r| first_cell(table, r, scene).map(|c| (r, c))).collect();
    let Some((_, (dir0, m0))) = cells.first() else {
        return Err("no finished cell".into());
    };
    let data = dataset_of(&results.join(dir0))?;
    let tests: Vec<usize> = m0.views.iter().filter_map(|v| view_index(&v.name)).collect();
    let mut rows = Vec::new();
    for view in m0.views.iter().take(MAX_VIEWS) {
        let test = view_index(&view.name).ok_or_else(|| format!("test view `{}` is not NN.png", view.name))?;
        let input = nearest_training_view(&data, test, &tests)?;
        let mut row = vec![Panel {
            label: format!("blurry input (view {})", view_index(&input).unwrap_or(0)),
            image: read_rgb(&data.join("images_1").join(&input))?,
        }];
        for (r, (dir, m)) in &cells {
            let psnr = m.views.iter().find(|v| v.name == view.name).map(|v| v.psnr);
            let label = match psnr {
                Some(p) => format!("{} {p:.2} dB", r.label),
                None => r.label.clone(),
            };
            row.push(Panel { label, image: read_rgb(&results.join(dir).join("eval").join(&view.name))? });
        }
        row.push(Panel {
            label: format!("sharp ground truth (view {test})"),
            image: read_rgb(&data.join("images_sharp_1").join(&view.name))?,
        });
        rows.push(row);
    }
    let size = rows[0][0].image.dimensions();
    if let Some(p) = rows.iter().flatten().find(|p| p.image.dimensions() != size) {
        return Err(format!("the panel `{}` is {:?}, the input {size:?}", p.label, p.image.dimensions()));
    }
    Ok(rows)
}

/// Draws `rows` of equal-size panels into PNG bytes.
pub fn render_png(rows: &[Vec<Panel>]) -> Result<Vec<u8>, String> {
    let (pw, ph) = rows.first().and_then(|r| r.first()).map(|p| p.image.dimensions()).ok_or("no panel")?;
    if !crate::plot::font_registered() {
        return Err("the embedded font benchmark/assets/DejaVuSans.ttf does not parse; restore it".into());
    }
    let scale = MIN_PANEL_W.div_ceil(pw).max(1);
    let (cw, ch) = (pw * scale, ph * scale + LABEL_H);
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let (w, h) = (GAP + cols * (cw + GAP), GAP + rows.len() as u32 * (ch + GAP));
    let mut canvas = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    for (r, row) in rows.iter().enumerate() {
        for (c, panel) in row.iter().enumerate() {
            let (x0, y0) = (GAP + c as u32 * (cw + GAP), GAP + r as u32 * (ch + GAP) + LABEL_H);
            for (x, y, px) in panel.image.enumerate_pixels() {
                for (dx, dy) in (0..scale).flat_map(|dx| (0..scale).map(move |dy| (dx, dy))) {
                    canvas.put_pixel(x0 + x * scale + dx, y0 + y * scale + dy, *px);
                }
            }
        }
    }
    let mut rgb = canvas.into_raw();
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let style = TextStyle::from(("sans-serif", TEXT_PX).into_font()).pos(Pos::new(HPos::Center, VPos::Center));
        for (r, row) in rows.iter().enumerate() {
            for (c, panel) in row.iter().enumerate() {
                let x = (GAP + c as u32 * (cw + GAP) + cw / 2) as i32;
                let y = (GAP + r as u32 * (ch + GAP) + LABEL_H / 2) as i32;
                root.draw_text(&panel.label, &style, (x, y)).map_err(|e| format!("drawing a label: {e}"))?;
            }
        }
        root.present().map_err(|e| format!("drawing: {e}"))?;
    }
    crate::plot::encode_png(w, h, rgb)
}

/// Writes `<out>/<form>-<scene>.png` for every scene of `table` whose images are here; returns
/// the files written and, per scene without one, why not.
pub fn write_all(table: &Table, results: &Path, out: &Path) -> Result<(Vec<PathBuf>, Vec<String>), BenchError> {
    let (mut written, mut skipped) = (Vec::new(), Vec::new());
    for scene in &table.scenes {
        let png = match scene_panels(table, results, scene).and_then(|rows| render_png(&rows)) {
            Ok(png) => png,
            Err(why) => {
                skipped.push(format!("no picture of {scene}: {why}"));
                continue;
            }
        };
        let path = out.join(format!("{}-{scene}.png", table.form.name()));
        simulator::image_io::write_atomic(&path, &png).map_err(|e| BenchError::results(&path, format!("{e:#}")))?;
        written.push(path);
    }
    Ok((written, skipped))
}
