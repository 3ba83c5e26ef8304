//! `evsim dataset`: a scene file in, an Ev-DeblurBlender dataset folder out.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use simulator::dataset::noise::{measure, NoiseOptions};
use simulator::dataset::{write_dataset, DatasetConfig, NoisePattern, Overrides, Plan, RunOptions};

/// Options of `evsim dataset`.
#[derive(Args, Debug, Clone)]
pub struct DatasetArgs {
    /// The scene file (`scenes/<name>/scene.toml`, with a [trajectory] table) or its folder.
    pub scene: PathBuf,
    /// The dataset folder to write (created; an interrupted run in it is resumed).
    #[arg(long)]
    pub out: PathBuf,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: OverrideArgs,
    /// Keep linear frames in this folder (shared between runs: exposure and event sweeps reuse
    /// them). Default: <out>/.frames, deleted after success.
    #[arg(long)]
    pub frames_cache: Option<PathBuf>,
    /// Keep the default frame cache (<out>/.frames) after success.
    #[arg(long)]
    pub keep_frames: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Command-line changes to a scene file's settings: `--set KEY=VALUE` for any setting of its
/// `[dataset]`, `[events]` and `[trajectory]` tables, and `--speed`, which is not a key of the
/// file. A new setting of those tables needs nothing here.
#[derive(Args, Debug, Clone, Default)]
pub struct OverrideArgs {
    /// Change a setting of the scene file's [dataset], [events] or [trajectory] table: KEY is a
    /// dotted path, VALUE a TOML value (none removes the key); repeatable, applied in order,
    /// e.g. --set dataset.width=300 --set events.c_pos=0.3 (see --help for the keys)
    #[arg(long = "set", value_name = "KEY=VALUE", long_help = set_long_help())]
    pub set: Vec<String>,
    /// Camera speed factor: the trajectory's clock runs this much faster (2 = the same path in
    /// half the time, twice the blur per exposure).
    #[arg(long)]
    pub speed: Option<f64>,
}

/// The long help of `--set`: the tables, examples, and the `[dataset]` keys read from
/// [`DatasetConfig`] itself (so a new field is listed without touching this file).
fn set_long_help() -> String {
    let keys = simulator::base::settings::field_names::<DatasetConfig>().join(", ");
    format!(
        "Change a setting of the scene file's [dataset], [events] or [trajectory] table before it is \
         read and checked. KEY is a dotted path into the file (table.key or table.subtable.key), \
         VALUE a TOML value (a number, true/false, a quoted or bare string, [a, b], {{k = v}}) or \
         `none`, which removes the key. Repeatable; applied in order, so a later one wins.\n\n\
         Examples:\n  \
         --set dataset.width=300 --set dataset.height=200\n  \
         --set events.c_pos=0.3 --set events.c_neg=0.3\n  \
         --set dataset.shading=path_traced --set dataset.sharp_spp=32\n  \
         --set events.noise.leak_rate_hz=0.1 --set trajectory.radius=5.0\n\n\
         [dataset] keys: {keys}.\n\
         Their meanings and units: the `[dataset]` section of docs/simulator.md and \
         simulator::dataset::DatasetConfig; [events]: simulator::events::EventConfig; \
         [trajectory]: simulator::trajectory (its keys depend on its type)."
    )
}

impl OverrideArgs {
    /// The library's overrides.
    pub fn resolve(&self) -> Overrides {
        Overrides { speed: self.speed, set: self.set.clone(), ..Overrides::default() }
    }
}

/// Run `evsim dataset`.
pub fn run(args: &DatasetArgs) -> Result<()> {
    let start = Instant::now();
    let plan = Plan::resolve(&args.scene, &args.overrides.resolve())?;
    let c = &plan.config;
    let sharp = (0..plan.views.len()).filter(|&i| plan.is_sharp(i)).count();
    eprintln!(
        "{}: {} frames {}x{} at {} FPS ({}); {} views ({} sharp; sharp images from {}), exposure {} ms, threshold {}/{}",
        args.scene.display(),
        plan.clock.n_frames,
        c.width,
        c.height,
        c.fps,
        c.frames_summary(),
        plan.views.len(),
        sharp,
        plan.sharp_source(),
        c.exposure_ms,
        plan.events.c_pos,
        plan.events.c_neg
    );
    let opts = RunOptions {
        out: args.out.clone(),
        frames_cache: args.frames_cache.clone(),
        keep_frames: args.keep_frames,
        progress: !args.quiet,
        stop_after_renders: None,
    };
    let s = write_dataset(&plan, &opts)?;
    if s.already_complete {
        println!("{}: already complete with these settings; nothing to do", args.out.display());
        return Ok(());
    }
    let secs = |d: std::time::Duration| d.as_secs_f64();
    println!(
        "{}: {} images, {} events ({} ON, {} OFF) in {:.1} s",
        args.out.display(),
        plan.views.len(),
        s.events_on + s.events_off,
        s.events_on,
        s.events_off,
        start.elapsed().as_secs_f64()
    );
    println!(
        "  frames: {} rendered, {} from cache{}; sharp renders: {}",
        s.frames_rendered,
        s.frames - s.frames_rendered,
        if s.window_renders > 0 {
            format!(" ({} re-rendered for the temporal window)", s.window_renders)
        } else {
            String::new()
        },
        s.sharp_rendered
    );
    println!(
        "  time: render {:.1} s (of which denoising {:.1} s), cache read {:.1} s; beside them: cache write {:.1} s, events {:.1} s, exposure+png {:.1} s, depth+metadata {:.1} s",
        secs(s.render_time),
        secs(s.denoise_time),
        secs(s.cache_read_time),
        secs(s.cache_write_time),
        secs(s.events_time),
        secs(s.exposure_time),
        secs(s.metadata_time),
    );
    let mb = |b: Option<u64>| b.map(|b| format!("{:.0} MB", b as f64 / 1e6)).unwrap_or_else(|| "n/a".into());
    println!(
        "  peak memory: frames {}, sharp renders {}, metadata {}",
        mb(s.peak_rss[0]),
        mb(s.peak_rss[1]),
        mb(s.peak_rss[2])
    );
    Ok(())
}

/// Options of `evsim dataset-noise`.
#[derive(Args, Debug, Clone)]
pub struct NoiseArgs {
    /// The scene file (as for `evsim dataset`).
    pub scene: PathBuf,
    /// Frames in the measured segment.
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Reference samples per pixel = factor x spp.
    #[arg(long, default_value_t = 16)]
    pub factor: u32,
    /// Start of the segment (ms from the trajectory's start; default: its middle).
    #[arg(long)]
    pub start_ms: Option<f64>,
    /// Width of the comparison windows (ms); default: the whole segment.
    #[arg(long)]
    pub window_ms: Option<f64>,
    /// Pool events over square blocks of this many pixels (1 = per pixel).
    #[arg(long, default_value_t = 1)]
    pub pool: u32,
    /// Also write where the events differ (PNG: the first frame in grey, test events the
    /// reference lacks in red, reference events the test lacks in blue).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: OverrideArgs,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Run `evsim dataset-noise`.
pub fn run_noise(args: &NoiseArgs) -> Result<()> {
    let overrides = args.overrides.resolve();
    let plan = Plan::resolve(&args.scene, &overrides)?;
    if let Some(w) = args.window_ms.filter(|w| !(*w > 0.0 && w.is_finite())) {
        anyhow::bail!("--window-ms {w}: give a positive window in milliseconds");
    }
    let start_frame = match args.start_ms {
        Some(ms) if ms >= 0.0 && ms.is_finite() => Some((ms * 1e6 / plan.clock.dt_ns as f64).round() as usize),
        Some(ms) => anyhow::bail!("--start-ms {ms}: give a time >= 0 in milliseconds"),
        None => None,
    };
    let opts = NoiseOptions {
        start_frame,
        frames: args.frames,
        factor: args.factor,
        window_ns: args.window_ms.map(|w| (w * 1e6).round() as i64),
        pool: args.pool,
        progress: !args.quiet,
    };
    if let Some(m) = args.map.as_ref().filter(|m| !m.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))) {
        anyhow::bail!("--map {}: give a .png file name", m.display());
    }
    let r = measure(&plan, &opts)?;
    if let Some(m) = &args.map {
        simulator::image_io::write_image(&r.pipeline_map.overlay(&r.first_frame), m)?;
    }
    let per = format!(
        "per {} and {}x{} px block",
        args.window_ms.map(|w| format!("{w} ms window")).unwrap_or_else(|| "segment".into()),
        args.pool,
        args.pool
    );
    println!(
        "{}: {} frames {}x{}, {:?} noise pattern, threshold {}, {}: {} spp{} vs a {} spp reference",
        args.scene.display(),
        r.frames,
        r.width,
        r.height,
        plan.config.noise_pattern,
        plan.events.c_pos,
        if !r.denoised {
            "not denoised".to_string()
        } else if plan.config.temporal_radius > 0 {
            format!("denoised (temporal radius {})", plan.config.temporal_radius)
        } else {
            "denoised (spatial only)".to_string()
        },
        r.spp,
        if plan.config.spp_max > r.spp {
            format!(" (adaptive up to {}, target {})", plan.config.spp_max, plan.config.adaptive_variance)
        } else {
            String::new()
        },
        r.ref_spp
    );
    let line = |what: &str, c: &simulator::dataset::noise::Comparison| {
        println!(
            "{what}: {} vs {} events; noise-induced {:.2}% ({} not in the reference {per}), missed {:.2}%",
            c.test_events,
            c.ref_events,
            100.0 * c.noise_fraction(),
            c.excess,
            100.0 * c.missed_fraction()
        )
    };
    line("noise-induced events (the dataset's frames)", &r.pipeline);
    if let Some(c) = &r.vs_unfiltered {
        line("denoised vs an unfiltered reference", c);
    }
    if let Some(c) = &r.unfiltered {
        line("without denoising (same renders)", c);
    }
    println!(
        "render time (filters included): {:.2} s per frame at {} spp, {:.2} s per frame at {} spp{}",
        r.test_time.as_secs_f64() / r.renders as f64,
        if plan.config.spp_max > r.spp { format!("{:.2}", r.mean_spp) } else { r.spp.to_string() },
        r.ref_time.as_secs_f64() / r.renders as f64,
        r.ref_spp,
        if r.renders > r.frames {
            format!(" ({} renders each: the segment and the temporal window's margins)", r.renders)
        } else {
            String::new()
        }
    );
    Ok(())
}

/// Options of `evsim dataset-fidelity`.
#[derive(Args, Debug, Clone)]
pub struct FidelityArgs {
    /// The scene file (as for `evsim dataset`).
    pub scene: PathBuf,
    /// Frames in the measured segment (25 at 1000 FPS span 24 ms).
    #[arg(long, default_value_t = 25)]
    pub frames: usize,
    /// Start of the segment (ms from the trajectory's start; default: its middle).
    #[arg(long)]
    pub start_ms: Option<f64>,
    /// Samples per pixel of the reference renders (full paths, no filter).
    #[arg(long, default_value_t = 512)]
    pub ref_spp: u32,
    /// Window lengths (ms) the summed events are scored over.
    #[arg(long, value_delimiter = ',', default_values_t = [1.0, 4.0, 24.0])]
    pub windows_ms: Vec<f64>,
    /// The references' random numbers frame to frame: `fixed` (the same in every frame, so
    /// their remaining noise barely changes between nearby frames) or `per-frame`.
    #[arg(long, value_enum, default_value_t = NoisePattern::Fixed)]
    pub reference_pattern: NoisePattern,
    /// Skip the second reference (and so the two-reference ceiling): half the reference time.
    #[arg(long)]
    pub no_ceiling: bool,
    /// Score every N-th pixel of every N-th row: the reference renders N^2 times faster.
    #[arg(long, default_value_t = 1)]
    pub pixel_stride: u32,
    /// Cache reference frames in this folder (default: ~/.cache/evblur/references).
    #[arg(long)]
    pub reference_cache: Option<PathBuf>,
    /// Render the references again instead of reading or keeping them.
    #[arg(long)]
    pub no_reference_cache: bool,
    /// Settings changes (--set, --speed).
    #[command(flatten)]
    pub overrides: OverrideArgs,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The default reference cache: `$XDG_CACHE_HOME/evblur/references`, else
/// `~/.cache/evblur/references`.
fn default_reference_cache() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("evblur").join("references"))
}

/// Run `evsim dataset-fidelity`.
pub fn run_fidelity(args: &FidelityArgs) -> Result<()> {
    use simulator::dataset::fidelity::{self, FidelityOptions, Scores};
    let overrides = args.overrides.resolve();
    let plan = Plan::resolve(&args.scene, &overrides)?;
    let start_frame = match args.start_ms {
        Some(ms) if ms >= 0.0 && ms.is_finite() => Some((ms * 1e6 / plan.clock.dt_ns as f64).round() as usize),
        Some(ms) => anyhow::bail!("--start-ms {ms}: give a time >= 0 in milliseconds"),
        None => None,
    };
    if let Some(w) = args.windows_ms.iter().find(|w| !(**w > 0.0 && w.is_finite())) {
        anyhow::bail!("--windows-ms {w}: give positive window lengths in milliseconds, e.g. 1,4,24");
    }
    let opts = FidelityOptions {
        start_frame,
        frames: args.frames,
        ref_spp: args.ref_spp,
        windows_ns: args.windows_ms.iter().map(|w| (w * 1e6).round() as i64).collect(),
        ceiling: !args.no_ceiling,
        pixel_stride: args.pixel_stride,
        reference_pattern: args.reference_pattern,
        reference_cache: if args.no_reference_cache {
            None
        } else {
            args.reference_cache.clone().or_else(default_reference_cache)
        },
        progress: !args.quiet,
    };
    let r = fidelity::measure(&plan, &opts)?;
    let c = &plan.config;
    println!(
        "{}: frames {}..{} ({} frames) {}x{}{}, threshold {}/{}, against a {} spp reference (full paths, no filter, {:?} noise pattern)",
        args.scene.display(),
        r.start_frame,
        r.start_frame + r.frames - 1,
        r.frames,
        r.width,
        r.height,
        if r.pixel_stride > 1 { format!(" (one pixel in {} per row and column scored)", r.pixel_stride) } else { String::new() },
        plan.events.c_pos,
        plan.events.c_neg,
        r.ref_spp,
        args.reference_pattern
    );
    let head: String =
        r.dataset.windows.iter().map(|(w, _)| format!("  {:>7}", format!("{} ms", *w as f64 / 1e6))).collect();
    println!("{:<28} {:>9} {:>8} {:>6}{head}", "r2 (1 = exact)", "events", "pairs", "sign");
    let row = |name: &str, s: &Scores| {
        let w: String = s.windows.iter().map(|(_, r2)| format!("  {r2:>7.3}")).collect();
        println!("{name:<28} {:>9} {:>8.3} {:>6.3}{w}", s.events, s.pair_r2, s.sign_agreement);
    };
    row("dataset frames", &r.dataset);
    row("ideal (ESIM on reference)", &r.ideal);
    if let Some(cl) = &r.ceiling {
        row("ceiling (ESIM on 2nd ref.)", cl);
    }
    if let Some((pairs, w)) = r.ratios() {
        let w: String = w.iter().map(|(_, q)| format!("  {q:>7.3}")).collect();
        println!("{:<28} {:>9} {pairs:>8.3} {:>6}{w}", "dataset / ceiling", "", "");
    }
    println!(
        "counts per pixel over the segment vs the ideal simulator: {} vs {} events, excess {:.2}%, missed {:.2}%",
        r.counts.test_events,
        r.counts.ref_events,
        100.0 * r.counts.noise_fraction(),
        100.0 * r.counts.missed_fraction()
    );
    println!(
        "time: dataset frames {:.2} s per frame ({}), references {:.1} s ({} of {} frames from the cache)",
        r.dataset_time.as_secs_f64() / r.frames as f64,
        c.frames_summary(),
        r.reference_time.as_secs_f64(),
        r.reference_cached,
        r.frames * if r.ceiling.is_some() { 2 } else { 1 }
    );
    Ok(())
}
