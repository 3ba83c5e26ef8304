//! A [`Table`] as Markdown, CSV and LaTeX (booktabs).
//!
//! Printed precision: PSNR 2 decimals, LPIPS and SSIM 3; the CSV keeps more (4 and 5) for
//! further processing and holds no timings, so equal results give equal bytes. A missing cell
//! is `-` (empty in the CSV), a missing LPIPS `n/a`. The best value of each column (as printed)
//! is bold when two rows or more have one.

use super::{Form, Scores, Table};

/// The three metrics of a column group, in the paper's order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Metric {
    Psnr,
    Lpips,
    Ssim,
}

const METRICS: [Metric; 3] = [Metric::Psnr, Metric::Lpips, Metric::Ssim];

impl Metric {
    fn value(self, s: &Scores) -> Option<f64> {
        match self {
            Metric::Psnr => Some(s.psnr),
            Metric::Lpips => s.lpips,
            Metric::Ssim => Some(s.ssim),
        }
    }

    /// Printed decimals (tables) and CSV decimals.
    fn decimals(self, csv: bool) -> usize {
        match (self, csv) {
            (Metric::Psnr, false) => 2,
            (Metric::Psnr, true) => 4,
            (_, false) => 3,
            (_, true) => 5,
        }
    }

    fn higher_is_better(self) -> bool {
        self != Metric::Lpips
    }

    fn header(self) -> (&'static str, &'static str, &'static str) {
        // (Markdown, LaTeX, CSV)
        match self {
            Metric::Psnr => ("PSNR↑", "PSNR$\\uparrow$", "psnr"),
            Metric::Lpips => ("LPIPS↓", "LPIPS$\\downarrow$", "lpips"),
            Metric::Ssim => ("SSIM↑", "SSIM$\\uparrow$", "ssim"),
        }
    }
}

/// A printed cell: its text and whether it is the column's best.
struct Printed {
    text: String,
    best: bool,
}

/// Every row's printed cells: per column group (scenes, then the average), per metric.
fn printed(table: &Table) -> Vec<Vec<Printed>> {
    let groups = group_titles(table).len();
    let mut out: Vec<Vec<Printed>> = table.rows.iter().map(|_| Vec::with_capacity(groups * 3)).collect();
    for g in 0..groups {
        for metric in METRICS {
            let text = |s: &Option<Scores>| match s {
                None => "-".to_string(),
                Some(s) => metric.value(s).map_or("n/a".into(), |v| format!("{v:.*}", metric.decimals(false))),
            };
            let texts: Vec<String> = table.rows.iter().map(|r| text(&r.scores[g])).collect();
            // The best as printed (ties all bold), among rows with a value.
            let values: Vec<Option<f64>> = texts.iter().map(|t| t.parse::<f64>().ok()).collect();
            let present: Vec<f64> = values.iter().flatten().copied().collect();
            let best = if present.len() < 2 {
                None
            } else if metric.higher_is_better() {
                present.iter().copied().reduce(f64::max)
            } else {
                present.iter().copied().reduce(f64::min)
            };
            for ((row, text), v) in out.iter_mut().zip(texts).zip(values) {
                row.push(Printed { best: best.is_some() && v == best, text });
            }
        }
    }
    out
}

/// The column groups' titles: the scenes, then `Average` (if the table has it).
fn group_titles(table: &Table) -> Vec<String> {
    let average = table.average.then(|| "Average".to_string());
    table.scenes.iter().cloned().chain(average).collect()
}

/// The title of the row column.
fn row_title(form: Form) -> &'static str {
    match form {
        Form::Table1 => "Method",
        Form::Ablation => "Switches",
    }
}

/// The table as Markdown (one header row: `<scene> PSNR↑` ...).
pub fn markdown(table: &Table) -> String {
    let mut header = vec![row_title(table.form).to_string()];
    for g in group_titles(table) {
        header.extend(METRICS.iter().map(|m| format!("{g} {}", m.header().0)));
    }
    let mut s = format!("| {} |\n", header.join(" | "));
    s.push_str(&format!("|---|{}\n", "---:|".repeat(header.len() - 1)));
    for (row, cells) in table.rows.iter().zip(printed(table)) {
        let cells: Vec<String> =
            cells.into_iter().map(|c| if c.best { format!("**{}**", c.text) } else { c.text }).collect();
        s.push_str(&format!("| {} | {} |\n", row.label.replace('|', "\\|"), cells.join(" | ")));
    }
    s
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The table as CSV: `method` (Table 1) or `preset,switches` (ablation), then
/// `<scene>_psnr,<scene>_lpips,<scene>_ssim` per scene and `average_*`.
pub fn csv(table: &Table) -> String {
    let mut header: Vec<String> = match table.form {
        Form::Table1 => vec!["method".into()],
        Form::Ablation => vec!["preset".into(), "switches".into()],
    };
    let average = table.average.then(|| "average".to_string());
    let groups: Vec<String> = table.scenes.iter().cloned().chain(average).collect();
    for g in &groups {
        header.extend(METRICS.iter().map(|m| csv_field(&format!("{g}_{}", m.header().2))));
    }
    let mut s = header.join(",") + "\n";
    for row in &table.rows {
        let mut fields: Vec<String> = match table.form {
            Form::Table1 => vec![csv_field(&row.label)],
            Form::Ablation => vec![csv_field(&row.preset), csv_field(&row.switches.join("; "))],
        };
        for scores in &row.scores {
            for m in METRICS {
                fields.push(match scores {
                    None => String::new(),
                    Some(sc) => m.value(sc).map_or("n/a".into(), |v| format!("{v:.*}", m.decimals(true))),
                });
            }
        }
        s.push_str(&(fields.join(",") + "\n"));
    }
    s
}

/// Escapes LaTeX's special characters (and `--`, which would print as a dash).
pub fn latex_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut prev = '\0';
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\textbackslash{}"),
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            '-' if prev == '-' => out.push_str("{}-"),
            _ => out.push(c),
        }
        prev = c;
    }
    out
}

/// The table as a LaTeX `tabular` (needs `\usepackage{booktabs}`).
pub fn latex(table: &Table) -> String {
    let groups = group_titles(table);
    let mut s = format!("\\begin{{tabular}}{{l{}}}\n\\toprule\n", "ccc".repeat(groups.len()));
    let titles: Vec<String> =
        groups.iter().map(|g| format!("\\multicolumn{{3}}{{c}}{{{}}}", latex_escape(g))).collect();
    s.push_str(&format!(" & {} \\\\\n", titles.join(" & ")));
    let rules: Vec<String> =
        (0..groups.len()).map(|g| format!("\\cmidrule(lr){{{}-{}}}", 2 + 3 * g, 4 + 3 * g)).collect();
    s.push_str(&(rules.join(" ") + "\n"));
    let mut header = vec![row_title(table.form).to_string()];
    for _ in &groups {
        header.extend(METRICS.iter().map(|m| m.header().1.to_string()));
    }
    s.push_str(&format!("{} \\\\\n\\midrule\n", header.join(" & ")));
    for (row, cells) in table.rows.iter().zip(printed(table)) {
        let cells: Vec<String> =
            cells.into_iter().map(|c| if c.best { format!("\\textbf{{{}}}", c.text) } else { c.text }).collect();
        s.push_str(&format!("{} & {} \\\\\n", latex_escape(&row.label), cells.join(" & ")));
    }
    s.push_str("\\bottomrule\n\\end{tabular}\n");
    s
}
