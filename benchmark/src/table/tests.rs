//! Tables from synthetic `metrics.json` files: order, means, the average column, bold best,
//! `n/a` LPIPS, missing cells, the ablation form, conflicting results and the output files.

use std::path::{Path, PathBuf};

use super::format::{csv, latex, latex_escape, markdown};
use super::*;
use crate::metrics::tests::cell;

/// A fresh results folder holding `cells` at `<scene>/<method>/<key>/metrics.json`.
fn results(name: &str, cells: &[CellMetrics]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("evbench-table-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for m in cells {
        m.write(&dir.join(&m.scene).join(&m.method).join(&m.key)).unwrap();
    }
    dir
}

/// Two scenes; ev-deblurnerf has LPIPS everywhere, nerf on one scene only, nerf-sharp lacks
/// pool. Registry order: nerf, nerf-sharp, ev-deblurnerf.
fn sample() -> Vec<CellMetrics> {
    vec![
        cell("ev-deblurnerf", "factory", 0, (27.0, Some(0.10), 0.85)),
        cell("ev-deblurnerf", "factory", 1, (27.6, Some(0.12), 0.87)),
        cell("ev-deblurnerf", "pool", 0, (25.1, Some(0.20), 0.80)),
        cell("nerf", "factory", 0, (21.8, Some(0.30), 0.70)),
        cell("nerf", "pool", 0, (20.0, None, 0.60)),
        cell("nerf-sharp", "factory", 0, (28.0, Some(0.05), 0.90)),
    ]
}

#[test]
fn table1_orders_rows_averages_seeds_and_scenes() {
    let dir = results("t1", &sample());
    let t = build(&dir, Form::Table1, None).unwrap();
    assert_eq!(t.scenes, ["factory", "pool"]);
    let labels: Vec<&str> = t.rows.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(labels, ["nerf", "nerf-sharp", "ev-deblurnerf"]);
    // ev-deblurnerf: the mean of two seeds on factory, then the average of the scenes.
    let evd = &t.rows[2].scores;
    let f = evd[0].unwrap();
    assert!((f.psnr - 27.3).abs() < 1e-12 && (f.lpips.unwrap() - 0.11).abs() < 1e-12 && (f.ssim - 0.86).abs() < 1e-12);
    let avg = evd[2].unwrap();
    assert!((avg.psnr - 26.2).abs() < 1e-12 && (avg.lpips.unwrap() - 0.155).abs() < 1e-12);
    assert!((avg.ssim - 0.83).abs() < 1e-12);
    // nerf: LPIPS missing on pool, so its average has none; nerf-sharp has no average at all.
    assert_eq!(t.rows[0].scores[1].unwrap().lpips, None);
    assert!(t.rows[0].scores[2].unwrap().lpips.is_none() && t.rows[0].scores[2].is_some());
    assert_eq!(t.rows[1].scores[1], None);
    assert_eq!(t.rows[1].scores[2], None);
    assert_eq!(t.cells.len(), 6);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn formats_mark_the_best_per_column_and_missing_values() {
    let dir = results("fmt", &sample());
    let t = build(&dir, Form::Table1, None).unwrap();
    let md = markdown(&t);
    let lines: Vec<&str> = md.lines().collect();
    assert_eq!(
        lines[0],
        "| Method | factory PSNR↑ | factory LPIPS↓ | factory SSIM↑ | pool PSNR↑ | pool LPIPS↓ | pool SSIM↑ | Average PSNR↑ | Average LPIPS↓ | Average SSIM↑ |"
    );
    assert_eq!(lines[1], "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    // Best: nerf-sharp on factory; ev-deblurnerf on pool and the average, except LPIPS: only
    // ev-deblurnerf has one there (nerf's is n/a), and a lone value is not bold.
    assert_eq!(lines[2], "| nerf | 21.80 | 0.300 | 0.700 | 20.00 | n/a | 0.600 | 20.90 | n/a | 0.650 |");
    assert_eq!(lines[3], "| nerf-sharp | **28.00** | **0.050** | **0.900** | - | - | - | - | - | - |");
    assert_eq!(
        lines[4],
        "| ev-deblurnerf | 27.30 | 0.110 | 0.860 | **25.10** | 0.200 | **0.800** | **26.20** | 0.155 | **0.830** |"
    );

    let c = csv(&t);
    let lines: Vec<&str> = c.lines().collect();
    assert_eq!(
        lines[0],
        "method,factory_psnr,factory_lpips,factory_ssim,pool_psnr,pool_lpips,pool_ssim,average_psnr,average_lpips,average_ssim"
    );
    assert_eq!(lines[1], "nerf,21.8000,0.30000,0.70000,20.0000,n/a,0.60000,20.9000,n/a,0.65000");
    assert_eq!(lines[2], "nerf-sharp,28.0000,0.05000,0.90000,,,,,,");

    let tex = latex(&t);
    assert!(
        tex.contains("\\multicolumn{3}{c}{factory} & \\multicolumn{3}{c}{pool} & \\multicolumn{3}{c}{Average}"),
        "{tex}"
    );
    assert!(tex.contains("\\cmidrule(lr){2-4} \\cmidrule(lr){5-7} \\cmidrule(lr){8-10}"), "{tex}");
    assert!(tex.contains("nerf-sharp & \\textbf{28.00} & \\textbf{0.050} & \\textbf{0.900} & - &"), "{tex}");
    assert!(tex.contains("Method & PSNR$\\uparrow$ & LPIPS$\\downarrow$ & SSIM$\\uparrow$"), "{tex}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ties_as_printed_are_all_bold_and_a_single_value_is_not() {
    let dir = results(
        "ties",
        &[cell("nerf", "tiny", 0, (20.001, None, 0.5)), cell("nerf-sharp", "tiny", 0, (20.004, None, 0.4))],
    );
    let md = markdown(&build(&dir, Form::Table1, None).unwrap());
    assert!(md.contains("| nerf | **20.00** | n/a | **0.500** |"), "{md}");
    assert!(md.contains("| nerf-sharp | **20.00** | n/a | 0.400 |"), "{md}");
    std::fs::remove_dir_all(&dir).unwrap();

    let dir = results("single", &[cell("nerf", "tiny", 0, (20.0, Some(0.2), 0.5))]);
    let md = markdown(&build(&dir, Form::Table1, None).unwrap());
    assert!(md.contains("| nerf | 20.00 | 0.200 | 0.500 | 20.00 | 0.200 | 0.500 |"), "{md}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ablation_rows_are_switch_combinations() {
    let with = |name: &str, switches: &[&str], psnr: f64| {
        let mut m = cell(name, "factory", 0, (psnr, None, 0.8));
        m.preset = "ev-deblurnerf".into();
        m.switches = switches.iter().map(|s| s.to_string()).collect();
        m.set = m.switches.clone();
        m
    };
    let dir = results(
        "ablation",
        &[
            with("no-edi-no-ecrf", &["edi=none", "ecrf=none"], 25.0),
            with("full", &[], 27.0),
            with("no-edi", &["edi=none"], 26.0),
        ],
    );
    let t = build(&dir, Form::Ablation, None).unwrap();
    let labels: Vec<&str> = t.rows.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(labels, ["(preset)", "edi=none", "edi=none, ecrf=none"]);
    let c = csv(&t);
    assert!(c.starts_with("preset,switches,factory_psnr,"), "{c}");
    assert!(c.contains("\nev-deblurnerf,edi=none; ecrf=none,25.0000,n/a,"), "{c}");
    assert!(markdown(&t).starts_with("| Switches |"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn conflicting_results_are_errors_and_keys_select_cells() {
    let a = cell("nerf", "tiny", 0, (20.0, None, 0.5));
    let mut stale = cell("nerf", "tiny", 0, (19.0, None, 0.4));
    stale.key = "0123456789abcdef".into();
    stale.steps = 5;
    let dir = results("conflict", &[a.clone(), stale.clone()]);
    let e = build(&dir, Form::Table1, None).unwrap_err().to_string();
    assert!(e.contains("two results for nerf on tiny with seed 0") && e.contains("--config"), "{e}");
    let sel = Selection { keys: [a.key.clone()].into(), scenes: vec!["tiny".into()] };
    let t = build(&dir, Form::Table1, Some(&sel)).unwrap();
    assert_eq!(t.cells.len(), 1);

    // One name, two meanings (another seed, other steps).
    let mut other = cell("nerf", "tiny", 1, (19.0, None, 0.4));
    other.steps = 5;
    let dir2 = results("meaning", &[a, other]);
    let e = build(&dir2, Form::Table1, None).unwrap_err().to_string();
    assert!(e.contains("method nerf means two things"), "{e}");
    for d in [dir, dir2] {
        std::fs::remove_dir_all(d).unwrap();
    }
    let e = build(Path::new("/nonexistent/results"), Form::Table1, None).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/results") && e.contains("evbench run"), "{e}");
}

#[test]
fn datasets_and_hidden_folders_are_not_scanned_and_files_are_written() {
    let dir = results("scan", &[cell("nerf", "tiny", 0, (20.0, None, 0.5))]);
    // A metrics.json under datasets/ or a hidden folder is not a cell; a half-written temporary
    // file beside a cell's metrics is ignored.
    cell("nerf", "x", 0, (1.0, None, 0.1)).write(&dir.join("datasets/abc")).unwrap();
    cell("nerf", "y", 0, (1.0, None, 0.1)).write(&dir.join(".trash/abc")).unwrap();
    std::fs::write(dir.join("tiny/.metrics.json.tmp123"), "{").unwrap();
    let t = build(&dir, Form::Table1, None).unwrap();
    assert_eq!(t.scenes, ["tiny"]);
    let out = dir.join("tables");
    let files = manifest::write_all(&t, &dir, &out).unwrap();
    let names: Vec<String> = files.iter().map(|f| f.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["table1.md", "table1.csv", "table1.tex", "table1.manifest.json"]);
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&files[3]).unwrap()).unwrap();
    assert_eq!(m["tool"], "evbench");
    assert_eq!(m["seeds"], serde_json::json!([0]));
    assert_eq!(m["cells"][0]["wall_seconds"], 2.0);
    assert_eq!(m["cells"][0]["machine"]["hostname"], "test");
    assert!(m["cells"][0]["folder"].as_str().unwrap().starts_with("tiny/nerf/"));
    assert!(m["git_commit"].is_string() && m["machine"]["cpus"].as_u64().unwrap() >= 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn latex_escapes_names() {
    assert_eq!(latex_escape("ev-deblurnerf--"), "ev-deblurnerf-{}-");
    assert_eq!(latex_escape("a_b & 50%"), "a\\_b \\& 50\\%");
    assert_eq!(latex_escape("x=[0.3,0.3]"), "x=[0.3,0.3]");
}

/// A dataset folder with views 00-03 (test views 00 and 03), each image a flat colour of its
/// index, sharp images a flat grey.
fn picture_dataset(dir: &Path) {
    for (sub, sharp) in [("images_1", false), ("images_sharp_1", true)] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        for i in 0..4u8 {
            let px = if sharp { [128, 128, 128] } else { [40 * i, 0, 0] };
            image::RgbImage::from_pixel(30, 20, image::Rgb(px)).save(dir.join(sub).join(format!("0{i}.png"))).unwrap();
        }
    }
}

#[test]
fn the_picture_shows_input_renders_and_ground_truth_per_test_view_or_says_why_not() {
    let mut cells = vec![
        cell("nerf", "factory", 0, (21.8, None, 0.70)),
        cell("nerf", "factory", 1, (22.8, None, 0.70)),
        cell("ev-deblurnerf", "factory", 0, (27.0, None, 0.85)),
    ];
    for m in &mut cells {
        m.views = ["00.png", "03.png"]
            .map(|n| metrics::ViewMetrics { name: n.into(), psnr: m.psnr + 1.0, ssim: 0.5, lpips: None })
            .into();
    }
    let dir = results("picture", &cells);
    let data = dir.join("datasets").join("d");
    picture_dataset(&data);
    for m in &cells {
        let cell_dir = dir.join(&m.scene).join(&m.method).join(&m.key);
        let preset = trainer::presets::preset(&m.preset).unwrap();
        let record = trainer::train::RunRecord {
            preset: m.preset.clone(),
            scale: m.scale,
            data: data.clone(),
            config: (preset.build)(m.scale),
            events_unit: Default::default(),
        };
        trainer::run::write_record(&cell_dir.join("config.toml"), &record).unwrap();
        std::fs::create_dir_all(cell_dir.join("eval")).unwrap();
        for v in ["00.png", "03.png"] {
            let shade = (m.psnr * 5.0) as u8 + m.seed as u8;
            image::RgbImage::from_pixel(30, 20, image::Rgb([0, shade, 0])).save(cell_dir.join("eval").join(v)).unwrap();
        }
    }
    let t = build(&dir, Form::Table1, None).unwrap();
    let rows = figure::scene_panels(&t, &dir, "factory").unwrap();
    let labels: Vec<Vec<&str>> = rows.iter().map(|r| r.iter().map(|p| p.label.as_str()).collect()).collect();
    // the nearest training view of 00 is 01, of 03 it is 02; nerf's first seed (0) is shown
    assert_eq!(
        labels[0],
        ["blurry input (view 1)", "nerf 22.80 dB", "ev-deblurnerf 28.00 dB", "sharp ground truth (view 0)"]
    );
    assert_eq!(labels[1][0], "blurry input (view 2)");
    assert_eq!(labels[1][3], "sharp ground truth (view 3)");
    assert_eq!(rows[0][0].image.get_pixel(0, 0).0, [40, 0, 0]);
    assert_eq!(rows[1][0].image.get_pixel(0, 0).0, [80, 0, 0]);
    assert_eq!(rows[0][1].image.get_pixel(0, 0).0, [0, 109, 0], "nerf's seed-0 render");
    assert_eq!(rows[0][3].image.get_pixel(0, 0).0, [128, 128, 128]);
    let (written, skipped) = figure::write_all(&t, &dir, &dir).unwrap();
    assert!(skipped.is_empty(), "{skipped:?}");
    assert_eq!(written, [dir.join("table1-factory.png")]);
    let png = image::open(&written[0]).unwrap().to_rgb8();
    // 30-pixel panels enlarged 8x to 240, four columns and two rows with their label strips
    assert_eq!(png.dimensions(), (6 + 4 * (240 + 6), 6 + 2 * (160 + 26 + 6)));
    assert_eq!(png.get_pixel(6 + 10, 6 + 26 + 10).0, [40, 0, 0], "the input, enlarged, below its label");
    assert!(
        png.pixels().any(|p| p.0 != [255, 255, 255] && p.0[0] == p.0[1] && p.0[1] == p.0[2] && p.0[0] < 128),
        "no label text"
    );
    // the same cells draw the same bytes
    let again = figure::render_png(&figure::scene_panels(&t, &dir, "factory").unwrap()).unwrap();
    assert_eq!(again, std::fs::read(&written[0]).unwrap());

    // a dataset that is gone: no picture, and the note names the folder
    std::fs::remove_dir_all(&data).unwrap();
    std::fs::remove_file(&written[0]).unwrap();
    let (written, skipped) = figure::write_all(&t, &dir, &dir).unwrap();
    assert!(written.is_empty());
    assert!(
        skipped[0].contains("no picture of factory") && skipped[0].contains(&data.display().to_string()),
        "{skipped:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
