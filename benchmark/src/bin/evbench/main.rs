//! `evbench`: run a benchmark matrix (simulate -> train -> score, resumable, shardable) and
//! merge its finished cells into the paper's tables.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use benchmark::matrix::{MatrixPlan, SceneSource, Shard};
use benchmark::run::{self, CellStatus, RunOptions};
use benchmark::sweep::{self, SweepPlan};
use benchmark::table::{self, Form, Selection};

#[derive(Parser)]
#[command(name = "evbench", version, about = "Run benchmark matrices of evblur methods and make the paper's tables")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run the cells of a matrix (methods x scenes x seeds) that are not finished: simulate
    /// missing datasets, train (resuming from checkpoints), score; Ctrl-C stops after the
    /// current step with a checkpoint.
    Run {
        /// The run-matrix file (TOML; fields in benchmark/src/matrix/config.rs).
        config: PathBuf,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Run a sweep: a matrix plus one or two swept settings (sweep files in
    /// benchmark/configs/sweeps/); every point's cells run like a matrix's (resumable,
    /// shardable), then a table and a figure per scene go to RESULTS/sweep/.
    Sweep {
        /// The sweep file (a run matrix with a [sweep] table; see benchmark/src/sweep/config.rs).
        config: PathBuf,
        /// Simulate and measure the datasets (events, blur, EDI PSNR) without training.
        #[arg(long)]
        data_only: bool,
        /// Only write the tables and figures of the finished cells.
        #[arg(long, conflicts_with = "data_only")]
        report: bool,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Merge the finished cells under RESULTS (any shards, any machines) into a table as
    /// Markdown, CSV and LaTeX, with a manifest.
    Table {
        /// The results folder of `evbench run`.
        results: PathBuf,
        /// Folder for FORM.md, FORM.csv, FORM.tex and FORM.manifest.json (default: RESULTS).
        #[arg(long)]
        out: Option<PathBuf>,
        /// table1 (rows = methods) or ablation (rows = switch combinations).
        #[arg(long, default_value = "table1")]
        form: Form,
        /// Keep only this matrix's cells, scenes in its order (default: every finished cell).
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// The LPIPS distance (AlexNet, v0.1; lower is more alike) between two images of one size
    /// (PNG, JPEG, ...; RGB in [0, 1], alpha dropped), with its five per-layer terms.
    Lpips {
        /// The first image.
        a: PathBuf,
        /// The second image.
        b: PathBuf,
        /// LPIPS weights (default: $EVBLUR_LPIPS_WEIGHTS, else ~/.cache/evblur/lpips/alex-v0.1.bin).
        #[arg(long)]
        lpips_weights: Option<PathBuf>,
    },
}

/// The options `run` and `sweep` share.
#[derive(Args)]
struct RunArgs {
    /// Run part i of n (1-based; of every point, for a sweep): the cells at positions p with
    /// p % n == i - 1 in key order, the same split on every machine.
    #[arg(long, value_name = "i/n")]
    shard: Option<Shard>,
    /// Results folder (default: the file's `results`, else runs/bench).
    #[arg(long)]
    results: Option<PathBuf>,
    /// LPIPS weights (default: $EVBLUR_LPIPS_WEIGHTS, else ~/.cache/evblur/lpips/alex-v0.1.bin
    /// once benchmark/scripts/install_lpips.sh has run); without them LPIPS is n/a.
    #[arg(long)]
    lpips_weights: Option<PathBuf>,
    /// Worker threads for training and scoring (0: all cores). A cell resumes bit for bit
    /// only with the thread count it started with.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// List the cells and their status, run nothing.
    #[arg(long)]
    dry_run: bool,
    /// No progress bars or per-cell lines (the final summary is still printed).
    #[arg(long)]
    quiet: bool,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::Run { config, run } => {
            let plan = MatrixPlan::load(&config, run.results.as_deref())?;
            let shard = run.shard.unwrap_or_default();
            if run.dry_run {
                return list(&plan, shard, 0);
            }
            let stop = ctrl_c()?;
            let opts = run_options(&run, &stop, None);
            let code = run_matrix(&plan, &opts)?;
            // The table of this matrix's finished cells (all shards' so far). After a failure
            // there may be none: the failures above are the news, not the missing table.
            if let Err(e) = write_table(&plan.results, Form::Table1, Some(&Selection::of(&plan)), None) {
                if code == 0 {
                    return Err(e);
                }
                eprintln!("no table: {e:#}");
            }
            std::process::exit(code);
        }
        Cmd::Sweep { config, data_only, report, run } => {
            let plan = SweepPlan::load(&config, run.results.as_deref())?;
            let shard = run.shard.unwrap_or_default();
            if run.dry_run {
                let mut first = 0;
                for (p, point) in plan.points.iter().enumerate() {
                    println!("point {}: {}", p + 1, plan.point_text(p));
                    list(&point.plan, shard, first)?;
                    first += point.plan.cells.len();
                }
                return Ok(());
            }
            if data_only {
                return data_sweep(&plan);
            }
            let mut code = 0;
            if !report {
                let stop = ctrl_c()?;
                let frames = plan.results.join(sweep::FRAMES_DIR);
                let mut opts = run_options(&run, &stop, Some(frames));
                for (p, point) in plan.points.iter().enumerate() {
                    if !run.quiet {
                        println!("point {} of {}: {}", p + 1, plan.points.len(), plan.point_text(p));
                    }
                    code = code.max(run_matrix(&point.plan, &opts)?);
                    opts.first_position += point.plan.cells.len();
                    if code == 130 {
                        break;
                    }
                }
            }
            for s in 0..plan.points[0].plan.scenes.len() {
                print!("{}", table::format::markdown(&sweep::report::scene_table(&plan, s)?));
            }
            let files = sweep::report::write(&plan)?;
            let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
            println!("wrote {}", names.join(", "));
            std::process::exit(code);
        }
        Cmd::Table { results, out, form, config } => {
            let selection = match &config {
                Some(c) => Some(Selection::of(&MatrixPlan::load(c, Some(&results))?)),
                None => None,
            };
            write_table(&results, form, selection.as_ref(), out.as_deref())
        }
        Cmd::Lpips { a, b, lpips_weights } => lpips_pair(&a, &b, lpips_weights.as_deref()),
    }
}

/// `lpips A B`: prints the distance and its per-layer terms.
fn lpips_pair(a: &Path, b: &Path, weights: Option<&Path>) -> Result<()> {
    use benchmark::lpips::{weights_path, Lpips, INSTALL_HINT, WEIGHTS_ENV};
    let weights = weights_path(weights)
        .with_context(|| format!("no LPIPS weights (--lpips-weights or ${WEIGHTS_ENV}): {INSTALL_HINT}"))?;
    let net = Lpips::load(&weights)?;
    let read = |path: &Path| -> Result<(usize, usize, Vec<f32>)> {
        let img = image::open(path)
            .with_context(|| format!("cannot read the image {}; give a PNG or JPEG file", path.display()))?
            .to_rgb32f();
        let (w, h) = img.dimensions();
        Ok((w as usize, h as usize, img.into_raw()))
    };
    let ((wa, ha, da), (wb, hb, db)) = (read(a)?, read(b)?);
    let layers = net
        .layer_distances((wa, ha, &da), (wb, hb, &db))
        .with_context(|| format!("cannot compare {} with {}", a.display(), b.display()))?;
    let terms: Vec<String> = layers.iter().map(|t| format!("{t:.6}")).collect();
    println!("LPIPS {:.6} (layers {})", layers.iter().sum::<f64>(), terms.join(" "));
    Ok(())
}

/// Builds the table of the finished cells under `results`, prints it as Markdown and writes
/// the Markdown, CSV, LaTeX and manifest files and the per-scene pictures into `out` (default
/// `results`).
fn write_table(results: &Path, form: Form, selection: Option<&Selection>, out: Option<&Path>) -> Result<()> {
    let t = table::build(results, form, selection)?;
    print!("{}", table::format::markdown(&t));
    let out = out.unwrap_or(results);
    let mut files = table::manifest::write_all(&t, results, out)?;
    let (pictures, skipped) = table::figure::write_all(&t, results, out)?;
    files.extend(pictures);
    for why in skipped {
        println!("{why}");
    }
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    println!("{} cells; wrote {}", t.cells.len(), names.join(", "));
    Ok(())
}

/// `run --dry-run`: the shard's cells with their status (the first cell at position `first`).
fn list(plan: &MatrixPlan, shard: Shard, first: usize) -> Result<()> {
    let cells = run::shard_cells(plan, shard, first);
    println!(
        "{}: {} cells, {} in shard {shard}; results in {}",
        plan.file.display(),
        plan.cells.len(),
        cells.len(),
        plan.results.display()
    );
    for scene in &plan.scenes {
        let dir = scene.dataset_dir(&plan.results);
        let state = if run::dataset::is_complete(&dir) { "present" } else { "missing" };
        let from = match &scene.source {
            SceneSource::Simulate(p) => format!("simulated from {}", p.scene_file.display()),
            SceneSource::Folder(_) => "a dataset folder".to_string(),
        };
        println!("scene {}: {from} -> {} ({state})", scene.name, dir.display());
    }
    println!("{:<16}  {:<12} {:<20} {:>6} {:>10}  status", "key", "scene", "method", "seed", "iterations");
    for c in cells {
        let status = match run::status(plan, c)? {
            CellStatus::Done { lpips: true } => "done".to_string(),
            CellStatus::Done { lpips: false } => "done (no LPIPS)".to_string(),
            CellStatus::Partial { step } => format!("partial (step {step})"),
            CellStatus::Todo => "to do".to_string(),
        };
        println!(
            "{:<16}  {:<12} {:<20} {:>6} {:>10}  {status}",
            c.key, plan.scenes[c.scene].name, plan.methods[c.method].name, c.seed, c.config.iterations
        );
    }
    Ok(())
}

/// `sweep --data-only`: simulate and measure every point's datasets, print and write the table.
fn data_sweep(plan: &SweepPlan) -> Result<()> {
    let start = Instant::now();
    let stats = sweep::data::run(plan, |d| println!("{d}"))?;
    print!("{}", sweep::data::markdown(&stats));
    let files = sweep::data::write(plan, &stats)?;
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    println!("{} datasets in {:.1} s; wrote {}", stats.len(), start.elapsed().as_secs_f64(), names.join(", "));
    Ok(())
}

/// Installs the handler of Ctrl-C and of SIGTERM / SIGHUP (what `scancel`, a preemption or a
/// Kubernetes eviction sends first): the first signal sets the flag, the second quits.
fn ctrl_c() -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!(
            "\nstopping after this training step with a checkpoint (or once the dataset being simulated is \
             written); Ctrl-C again to quit now (rendered frames are kept)"
        );
    })
    .context("cannot install the Ctrl-C / SIGTERM handler")?;
    Ok(stop)
}

/// The run options of `run` and `sweep`.
fn run_options<'a>(run: &RunArgs, stop: &'a AtomicBool, frames_cache: Option<PathBuf>) -> RunOptions<'a> {
    let lpips_weights = benchmark::lpips::weights_path(run.lpips_weights.as_deref());
    if lpips_weights.is_none() && !run.quiet {
        println!(
            "no LPIPS weights (--lpips-weights or ${}): LPIPS will be n/a; {}",
            benchmark::lpips::WEIGHTS_ENV,
            benchmark::lpips::INSTALL_HINT
        );
    }
    RunOptions {
        shard: run.shard.unwrap_or_default(),
        lpips_weights,
        threads: run.threads,
        bars: std::io::stderr().is_terminal(),
        quiet: run.quiet,
        stop: Some(stop),
        stop_after_steps: None,
        frames_cache,
        first_position: 0,
    }
}

/// `run`: the exit code (0 done, 1 a cell failed, 130 stopped by Ctrl-C).
fn run_matrix(plan: &MatrixPlan, opts: &RunOptions) -> Result<i32> {
    let start = Instant::now();
    let shard = opts.shard;
    let s = run::run(plan, opts)?;
    println!(
        "shard {shard}: {} cells: {} already done, {} trained, {} resumed, {} scored only, {} failed; {} datasets simulated; {:.1} s",
        s.cells,
        s.skipped,
        s.trained,
        s.resumed,
        s.scored,
        s.failed.len(),
        s.simulated,
        start.elapsed().as_secs_f64()
    );
    for (dir, e) in &s.failed {
        eprintln!("failed: {}: {e}", dir.display());
    }
    Ok(if s.interrupted {
        println!("stopped; run the same command again to resume");
        130
    } else if !s.failed.is_empty() {
        1
    } else {
        0
    })
}
