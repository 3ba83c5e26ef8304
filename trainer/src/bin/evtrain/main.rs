//! `evtrain`: train radiance fields on evblur datasets, evaluate them, benchmark the engine.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

use simulator::dataset::check::EventsUnit;
use trainer::bench::BenchSettings;
use trainer::checkpoint::Checkpoint;
use trainer::config::TrainConfig;
use trainer::data::dataset::{Dataset, LoadOptions};
use trainer::engine::model::Model;
use trainer::method::Method;
use trainer::presets::{self, Scale};
use trainer::run::RunPlan;
use trainer::train::{RunPaths, RunRecord, TrainOptions, Trainer};

#[derive(Parser)]
#[command(name = "evtrain", version, about = "Train and evaluate deblurring radiance fields on evblur datasets")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Train a preset on a dataset into a run folder (resumable).
    Train {
        /// Dataset folder (written by `evsim dataset`, or a public Ev-DeblurBlender scene);
        /// with --resume, the run's own (config.toml).
        #[arg(long, required_unless_present = "resume")]
        data: Option<PathBuf>,
        /// Method preset (`evtrain presets` lists them); with --resume, the run's own.
        #[arg(long, required_unless_present = "resume")]
        preset: Option<String>,
        /// `cpu` (sized for 2 cores) or `paper` (the reference hyper-parameters) [default: cpu].
        #[arg(long)]
        scale: Option<String>,
        /// Run folder (config, checkpoints, log, evaluation).
        #[arg(long)]
        out: PathBuf,
        /// A training configuration (TOML, as `evtrain presets --show NAME` prints) replacing
        /// the preset's; the preset name still labels the run.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Continue the run in --out from its checkpoint (with its recorded settings).
        #[arg(long)]
        resume: bool,
        /// Override the preset's iteration count (with --resume: train the run on to this many).
        #[arg(long)]
        iterations: Option<u64>,
        /// Override the seed (a new run only).
        #[arg(long)]
        seed: Option<u64>,
        /// Worker threads (0: all cores); results are reproducible for a given count (a new run
        /// only).
        #[arg(long)]
        threads: Option<usize>,
        /// Override one setting of the preset, KEY=VALUE with KEY a dotted path of its TOML
        /// form (e.g. `events.colour=true`, `ecrf=none`, `events.threshold=[0.3,0.3]`);
        /// repeatable; a new run only.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Unit of the dataset's event times (`auto`: detected from their magnitude against the
        /// trajectory's times, as `evsim check` does); recorded with the run (a new run only).
        #[arg(long, value_enum, default_value_t = EventsUnit::Auto)]
        events_unit: EventsUnit,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Render the test views of a run, score them (PSNR, SSIM) and write metrics.json.
    Eval {
        /// Run folder.
        run: PathBuf,
        /// Worker threads (0: all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
    /// List the presets, or print one's configuration as TOML (to edit and pass to --config).
    Presets {
        /// Print this preset's configuration.
        #[arg(long)]
        show: Option<String>,
        /// Scale of the printed configuration.
        #[arg(long, default_value = "cpu")]
        scale: String,
    },
    /// Diagnose a trained run (`diagnose events RUN`).
    #[command(subcommand)]
    Diagnose(Diagnose),
    /// Time optimisation steps: the reference step and the cpu-scale step on synthetic rays;
    /// with --run, every preset family on a trained field, dense engine against skipping.
    Bench {
        /// Timed steps per shape (after one warm-up).
        #[arg(long, default_value_t = 7)]
        reps: usize,
        /// A trained run (cpu scale) whose dataset and field the preset families are timed on.
        #[arg(long)]
        run: Option<PathBuf>,
        /// With --run: only these presets (repeatable; default: one per family).
        #[arg(long = "preset")]
        presets: Vec<String>,
        /// Worker threads (0: all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// With --run: override a setting on both paths (KEY=VALUE, as `train --set`).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// With --run: override a setting on the dense path only (which always has
        /// `model.dense=true`: the engine before it skipped samples).
        #[arg(long = "dense-set", value_name = "KEY=VALUE")]
        dense_set: Vec<String>,
    },
}

#[derive(Subcommand)]
enum Diagnose {
    /// How well the run's field explains its dataset's events: r2 of the predicted log-luma
    /// change of event pairs against p*C and sign agreement, overall and by time gap, luma and
    /// distance to intensity edges; then, with the dataset's sharp frames, the events summed
    /// between consecutive frames against the frames (the oracle) and against the field.
    Events {
        /// Run folder.
        run: PathBuf,
        /// Event pairs drawn (an event and the next at its pixel).
        #[arg(long, default_value_t = 20000)]
        pairs: usize,
        /// Window pixels drawn (a pixel between two consecutive sharp frames; 0: no windows).
        #[arg(long, default_value_t = 20000)]
        window_pixels: usize,
        /// Rays per side of a pixel, averaged in linear light (the pixel's area); 1: the
        /// pixel-centre ray the event loss casts.
        #[arg(long, default_value_t = 1)]
        supersample: usize,
        /// Read the field's linear colour, not through the run's eCRF.
        #[arg(long)]
        no_ecrf: bool,
        /// Seed of the draw.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Worker threads (0: all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::Train { data, preset, scale, out, config, resume, iterations, seed, threads, set, events_unit, quiet } => {
            if resume && config.is_some() {
                bail!("--config: a resumed run keeps its recorded config.toml; drop --config");
            }
            if resume && !set.is_empty() {
                bail!("--set: a resumed run keeps its recorded config.toml; drop --set");
            }
            if resume && !events_unit.is_auto() {
                bail!("--events-unit: a resumed run keeps its recorded unit (config.toml); drop --events-unit");
            }
            let flags = TrainFlags { iterations, seed, threads, events_unit };
            train(data, preset, scale, &out, config, resume, flags, &set, quiet)
        }
        Cmd::Eval { run, threads } => eval(&run, threads),
        Cmd::Presets { show: None, .. } => {
            for p in presets::PRESETS {
                println!("{:<16} {}", p.name, p.description);
            }
            Ok(())
        }
        Cmd::Presets { show: Some(name), scale } => {
            let Some(p) = presets::preset(&name) else {
                bail!("--show {name}: unknown; choose one of {}", presets::names().join(", "));
            };
            let Some(scale) = Scale::parse(&scale) else { bail!("--scale {scale}: unknown; choose cpu or paper") };
            print!("{}", toml::to_string(&(p.build)(scale))?);
            Ok(())
        }
        Cmd::Diagnose(Diagnose::Events { run, pairs, window_pixels, supersample, no_ecrf, seed, threads }) => {
            let read = FieldReading { supersample, no_ecrf };
            diagnose_events(&run, pairs, window_pixels, read, seed, threads)
        }
        Cmd::Bench { reps, run: None, .. } => bench(reps),
        Cmd::Bench { reps, run: Some(run), presets, threads, set, dense_set } => {
            bench_families(&run, &presets, BenchSettings { set, dense_set, reps, threads })
        }
    }
}

/// Loads the dataset, with its events only when the method uses them (evaluation never does).
fn load(data: &Path, cfg: &TrainConfig, events: bool, events_unit: EventsUnit) -> Result<Dataset> {
    let read_events = events && cfg.needs_events();
    let opts = LoadOptions { read_events, read_sharp: true, events_unit, ..LoadOptions::default() };
    Ok(Dataset::load(data, &opts)?)
}

/// `evtrain train`'s overrides of a new run's settings.
struct TrainFlags {
    iterations: Option<u64>,
    seed: Option<u64>,
    threads: Option<usize>,
    events_unit: EventsUnit,
}

#[allow(clippy::too_many_arguments)]
fn train(
    data: Option<PathBuf>,
    preset: Option<String>,
    scale: Option<String>,
    out: &Path,
    config_file: Option<PathBuf>,
    resume: bool,
    flags: TrainFlags,
    set: &[String],
    quiet: bool,
) -> Result<()> {
    let TrainFlags { iterations, seed, threads, events_unit } = flags;
    // The plan holds the folder's lock until the run ends: one process per run folder.
    let (mut plan, dataset) = if resume {
        let plan = RunPlan::resume(out)?;
        let record = &plan.record;
        // A run keeps its settings: flags that would change them are refused, not ignored.
        let c = &record.config;
        let recorded = [
            (
                "--data",
                data.map(|d| std::fs::canonicalize(&d).unwrap_or(d).display().to_string()),
                record.data.display().to_string(),
            ),
            ("--preset", preset, record.preset.clone()),
            ("--scale", scale, scale_name(record.scale).to_string()),
            ("--seed", seed.map(|s| s.to_string()), c.seed.to_string()),
            ("--threads", threads.map(|t| t.to_string()), c.threads.to_string()),
        ];
        for (flag, given, had) in recorded {
            if let Some(given) = given.filter(|g| *g != had) {
                bail!(
                    "{flag} {given}: the run in {} has {flag} {had} (config.toml); drop {flag} to resume it, or choose another --out",
                    out.display()
                );
            }
        }
        let dataset = load(&record.data, &record.config, true, record.events_unit)?;
        (plan, dataset)
    } else {
        let (Some(data), Some(preset)) = (data, preset) else { bail!("--data and --preset are needed for a new run") };
        let Some(p) = presets::preset(&preset) else {
            bail!("--preset {preset}: unknown; choose one of {}", presets::names().join(", "));
        };
        let scale = scale.as_deref().unwrap_or("cpu");
        let Some(scale) = Scale::parse(scale) else { bail!("--scale {scale}: unknown; choose cpu or paper") };
        if RunPaths::new(out).config().exists() {
            bail!("{}: a run is already there; pass --resume to continue it or choose another --out", out.display());
        }
        let mut config = match &config_file {
            None => (p.build)(scale),
            Some(f) => {
                let text =
                    std::fs::read_to_string(f).with_context(|| format!("--config {}: cannot read", f.display()))?;
                toml::from_str(&text).with_context(|| {
                    format!(
                        "--config {}: not a training configuration (see evtrain presets --show {})",
                        f.display(),
                        p.name
                    )
                })?
            }
        };
        config = trainer::config::apply_overrides(&config, set).map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Some(n) = iterations {
            config.iterations = n;
        }
        if let Some(s) = seed {
            config.seed = s;
        }
        if let Some(t) = threads {
            config.threads = t;
        }
        config.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
        let data =
            std::fs::canonicalize(&data).with_context(|| format!("--data {}: no such folder", data.display()))?;
        let dataset = load(&data, &config, true, events_unit)?;
        let record = trainer::run::new_record(&preset, scale, data, config, &dataset, events_unit)?;
        (RunPlan::start(out, record)?, dataset)
    };
    let checkpoint = plan.checkpoint(dataset.views.len())?;
    if let Some(n) = iterations.filter(|n| resume && *n != plan.record.config.iterations) {
        let done = checkpoint.as_ref().map_or(0, |c| c.step);
        if n < done {
            bail!("--iterations {n}: the run in {} is already at step {done}; pass a larger count", out.display());
        }
        plan.record.config.iterations = n;
        plan.save_record()?;
    }
    let (run, record) = (&plan.paths, &plan.record);
    let mut trainer = Trainer::new_in(&dataset, record.config.clone(), checkpoint, Some(&run.dir))?;
    let start = trainer.step;
    if start >= record.config.iterations {
        println!(
            "{}: the run is complete ({start} of {} iterations); pass --iterations N to train it further",
            out.display(),
            record.config.iterations
        );
        return Ok(());
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || {
            if stop.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
            eprintln!("\nstopping after this step (checkpoint follows); Ctrl-C again to quit now");
        })
        .context("cannot install the Ctrl-C / SIGTERM handler")?;
    }
    let rows = trainer.train(run, &TrainOptions { progress: !quiet, stop: Some(&stop), ..TrainOptions::default() })?;
    let last = rows.last();
    println!(
        "{} {} on {}: steps {}..{} in {:.1} s (total {:.1} s), batch PSNR {:.2} dB{}",
        record.preset,
        scale_name(record.scale),
        record.data.display(),
        start,
        trainer.step,
        rows.last().map_or(trainer.seconds, |r| r.seconds) - rows.first().map_or(trainer.seconds, |r| r.seconds),
        trainer.seconds,
        last.map_or(f64::NAN, |r| r.psnr_batch),
        last.and_then(|r| r.psnr_test).map_or(String::new(), |p| format!(", test PSNR {p:.2} dB")),
    );
    if stop.load(Ordering::SeqCst) {
        println!("stopped at step {}; continue with --resume", trainer.step);
    }
    Ok(())
}

fn scale_name(scale: Scale) -> &'static str {
    match scale {
        Scale::Cpu => "cpu",
        Scale::Paper => "paper",
    }
}

fn eval(dir: &Path, threads: usize) -> Result<()> {
    let plan = RunPlan::resume(dir)?; // locked: it writes eval/ and metrics.json
    let (run, record) = (&plan.paths, &plan.record);
    let dataset = load(&record.data, &record.config, false, record.events_unit)?;
    let mut method = Method::new(&record.config, dataset.views.len());
    let ck = Checkpoint::load(method.layout(), &run.checkpoint())?;
    method.restore_occupancy(&ck)?;
    let scores = trainer::eval::evaluate(&dataset, &method, &ck.params, &record.config, threads, Some(&run.eval()))?;
    let json = serde_json::json!({
        "preset": record.preset,
        "scale": record.scale,
        "data": record.data,
        "step": ck.step,
        "train_seconds": ck.seconds,
        "psnr": scores.mean_psnr(),
        "ssim": scores.mean_ssim(),
        "views": scores.views,
    });
    simulator::image_io::write_atomic(&run.dir.join("metrics.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    for v in &scores.views {
        println!("{:<10} PSNR {:6.2} dB  SSIM {:.4}", v.name, v.psnr, v.ssim);
    }
    println!(
        "mean       PSNR {:6.2} dB  SSIM {:.4}  ({} test views, step {})",
        scores.mean_psnr(),
        scores.mean_ssim(),
        scores.views.len(),
        ck.step
    );
    Ok(())
}

/// A run folder's paths and its recorded settings (`config.toml`), checked as a new run's are.
fn read_record(dir: &Path) -> Result<(RunPaths, RunRecord)> {
    let run = RunPaths::new(dir);
    if !run.config().is_file() {
        bail!("{}: not a run folder (no config.toml); train first", dir.display());
    }
    let record = trainer::run::read_record(&run.config())?;
    Ok((run, record))
}

/// A run folder's paths and record, and its dataset with events and sharp views.
fn open_run(dir: &Path) -> Result<(RunPaths, RunRecord, Dataset)> {
    let (run, record) = read_record(dir)?;
    let opts =
        LoadOptions { read_events: true, read_sharp: true, events_unit: record.events_unit, ..LoadOptions::default() };
    let dataset = Dataset::load(&record.data, &opts)?;
    Ok((run, record, dataset))
}

/// How `diagnose events` reads the field.
struct FieldReading {
    supersample: usize,
    no_ecrf: bool,
}

fn diagnose_events(
    dir: &Path,
    pairs: usize,
    window_pixels: usize,
    read: FieldReading,
    seed: u64,
    threads: usize,
) -> Result<()> {
    use trainer::diagnose;
    if pairs == 0 {
        bail!("--pairs 0: draw at least one pair");
    }
    if read.supersample == 0 {
        bail!("--supersample 0: at least 1 ray per pixel side");
    }
    let (run, record, dataset) = open_run(dir)?;
    if dataset.events.is_empty() {
        bail!("{}: the dataset has no events to diagnose (events.h5 is empty)", record.data.display());
    }
    let mut method = Method::new(&record.config, dataset.views.len());
    let ck = Checkpoint::load(method.layout(), &run.checkpoint())?;
    method.restore_occupancy(&ck)?;
    let reading = diagnose::EventReading::of(&record.config, &dataset);
    let drawn = diagnose::draw_pairs(&dataset.events, |t| dataset.trajectory.contains(t), pairs, seed);
    if drawn.is_empty() {
        bail!("{}: no event has a successor at its pixel inside the trajectory", record.data.display());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .with_context(|| format!("--threads {threads}: cannot start the workers"))?;
    let ecrf = method.ecrf.as_ref().filter(|_| !read.no_ecrf);
    let field = diagnose::FieldReader {
        model: &method.model,
        params: &ck.params,
        cfg: &record.config,
        ecrf,
        supersample: read.supersample,
        luma: reading.luma,
    };
    let lumas =
        pool.install(|| diagnose::field_lumas(&dataset, &field, &diagnose::pair_probes(&dataset.events, &drawn)));
    let sharp = diagnose::sharp_views(&dataset);
    let scored = diagnose::score_pairs(&dataset.events, &sharp, dataset.intrinsics.width, &drawn, &reading, &lumas);
    let title = format!(
        "{} ({}, step {}) on {}: {} event pairs of {} events, threshold {:.3}/{:.3}, log_eps {:e}; field read {}, {}",
        record.preset,
        scale_name(record.scale),
        ck.step,
        record.data.display(),
        drawn.len(),
        dataset.events.len(),
        reading.threshold[0],
        reading.threshold[1],
        reading.log_eps as f32,
        match read.supersample {
            1 => "at the pixel centre".to_string(),
            n => format!("as the mean of {n}x{n} rays over the pixel"),
        },
        match (method.ecrf.is_some(), ecrf.is_some()) {
            (true, true) => "through the eCRF",
            (true, false) => "linear (its eCRF left out)",
            _ => "linear (no eCRF)",
        }
    );
    print!("{}", diagnose::format_report(&title, &diagnose::summarise(&scored)));
    if window_pixels == 0 {
        return Ok(());
    }
    let frames = diagnose::SharpFrames::new(&sharp, record.config.response_gamma, reading.luma, |t| {
        dataset.trajectory.contains(t)
    });
    if frames.windows() == 0 {
        println!("no windows: the dataset has fewer than two sharp frames inside the trajectory (images_sharp_1/)");
        return Ok(());
    }
    let scores =
        pool.install(|| diagnose::score_sharp_windows(&dataset, &frames, &field, &reading, window_pixels, seed));
    let gaps: Vec<f64> = frames.t_us.windows(2).map(|t| t[1] - t[0]).collect();
    let title = format!(
        "windows between consecutive sharp frames ({} windows of {:.1}-{:.1} ms): {} pixels drawn, {} with events; \
         frames linearised with gamma {}",
        frames.windows(),
        gaps.iter().copied().fold(f64::INFINITY, f64::min) / 1e3,
        gaps.iter().copied().fold(0.0, f64::max) / 1e3,
        scores.drawn,
        scores.with_events,
        record.config.response_gamma
    );
    print!("{}", diagnose::format_windows(&title, &scores.oracle, &scores.field));
    Ok(())
}

fn bench(reps: usize) -> Result<()> {
    let threads = rayon::current_num_threads();
    let shapes = [
        (
            "reference step (1024 rays x 128 samples, VM 256^3 [64,16,16], 64-wide MLP)",
            trainer::bench::reference_config(),
        ),
        ("cpu-scale step (nerf --scale cpu)", presets::nerf(Scale::Cpu)),
        (
            "paper-scale step (nerf --scale paper: 64 + 128 samples, fine VM 512^3, 256-wide MLP)",
            presets::nerf(Scale::Paper),
        ),
    ];
    println!("{threads} threads, {reps} timed steps each after one warm-up, dense engine (every sample evaluated)");
    for (name, cfg) in shapes {
        let t = trainer::bench::time_steps(name, &cfg, reps, threads);
        println!(
            "{name}: median {:.1} ms/step, {:.1} GFLOP/s  (min {:.1}, max {:.1} ms)",
            t.median_ms,
            t.gflops,
            t.times_ms.iter().cloned().fold(f64::INFINITY, f64::min),
            t.times_ms.iter().cloned().fold(0.0, f64::max)
        );
    }
    let paper = Model::new(&presets::paper_model());
    println!(
        "paper model: {:.1} M parameters; peak memory of this process {:.2} GB (parameters, Adam moments, gradients)",
        paper.layout.len() as f64 / 1e6,
        peak_rss_bytes().unwrap_or(0) as f64 / 1e9
    );
    Ok(())
}

/// `evtrain bench --run`: each preset family's step on the run's trained field, dense against
/// skipping, side by side.
fn bench_families(dir: &Path, only: &[String], settings: BenchSettings) -> Result<()> {
    let reps = settings.reps;
    if reps == 0 {
        bail!("--reps 0: time at least one step");
    }
    let (run, record, dataset) = open_run(dir)?;
    let method = Method::new(&record.config, dataset.views.len());
    let ck = Checkpoint::load(method.layout(), &run.checkpoint())?;
    let families: Vec<(String, String)> = if only.is_empty() {
        trainer::bench::FAMILIES.iter().map(|(f, p)| (f.to_string(), p.to_string())).collect()
    } else {
        only.iter().map(|p| (p.clone(), p.clone())).collect()
    };
    println!(
        "{} (step {}) on {}: {} timed steps per path after one warm-up, dense and skipping alternating",
        record.preset,
        ck.step,
        record.data.display(),
        reps
    );
    let plus = |s: &[String]| s.iter().map(|x| format!(" + {x}")).collect::<String>();
    let both = plus(&settings.set);
    let dense = plus(&settings.dense_set);
    println!("dense path: preset{both}{dense} + model.dense=true; skipping path: preset{both}");
    println!(
        "{:<20} {:<16} {:>9} {:>9} {:>7}   samples per ray: rendered dense | rendered / ended / density / alive / coloured skipping",
        "family", "preset", "dense ms", "skip ms", "ratio"
    );
    let mut grids = Vec::new();
    for (family, preset) in families {
        let t = trainer::bench::time_family(
            &family,
            &preset,
            &dataset,
            (method.layout(), &ck.params),
            record.config.model.bounds,
            &settings,
        )?;
        println!(
            "{:<20} {:<16} {:>9.1} {:>9.1} {:>6.2}x   {:.0} | {:.0} / {:.1} / {:.1} / {:.1} / {:.1}{}",
            t.family,
            t.preset,
            t.dense.per_step_ms(),
            t.skipping.per_step_ms(),
            t.dense.per_step_ms() / t.skipping.per_step_ms(),
            t.dense.rendered_per_ray,
            t.skipping.rendered_per_ray,
            t.skipping.ended_per_ray,
            t.skipping.density_per_ray,
            t.skipping.alive_per_ray,
            t.skipping.coloured_per_ray,
            if t.from_run < t.tensors {
                format!("  ({} of {} tensors from the run)", t.from_run, t.tensors)
            } else {
                String::new()
            }
        );
        if t.skipping.occupancy_every > 0 {
            grids.push(format!(
                "{}: {:.1} ms median step + {:.1} ms grid rebuild / {} steps",
                t.preset, t.skipping.median_ms, t.skipping.occupancy_ms, t.skipping.occupancy_every
            ));
        }
    }
    if !grids.is_empty() {
        println!("skip ms = median step + the occupancy grid's rebuild spread over its steps:");
        for g in grids {
            println!("  {g}");
        }
    }
    Ok(())
}

/// Peak resident memory of this process (Linux `VmHWM`).
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}
