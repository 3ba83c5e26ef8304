//! `evsim events`: run the event model over a folder of frames into an event file.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{ensure, Context, Result};
use clap::Args;

use simulator::events::sinks::{H5Layout, SinkKind, VizConfig};
use simulator::events::{run_on_frames, EventConfig, FramesJob, TimeUnit};

/// Options of `evsim events`.
#[derive(Args, Debug, Clone)]
pub struct EventsArgs {
    /// Folder of frames (.png or .exr), sorted by file name.
    #[arg(long)]
    pub frames: PathBuf,
    /// Text file with one frame time per line.
    #[arg(long)]
    pub timestamps: PathBuf,
    /// Unit of the frame times.
    #[arg(long, value_enum, default_value_t = TimeUnit::S)]
    pub timestamps_unit: TimeUnit,
    /// Output: .h5 (layout from --format), .txt (RPG/ECD `t x y p`) or .npz.
    #[arg(long, default_value = "events.h5")]
    pub out: PathBuf,
    /// Layout of an .h5 output (default nerf: Ev-DeblurNeRF).
    #[arg(long, value_enum)]
    pub format: Option<H5Layout>,
    /// PNG frames hold linear values (default: decode them from sRGB).
    #[arg(long)]
    pub linear_input: bool,
    /// Event model settings (an EventConfig in TOML); the flags below override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// ON threshold C_p (natural-log units).
    #[arg(long)]
    pub c_pos: Option<f32>,
    /// OFF threshold C_m (natural-log units).
    #[arg(long)]
    pub c_neg: Option<f32>,
    /// Seed of the per-pixel random streams (non-idealities only).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Also draw the events into this folder: events_NNNNNN.png per time window (ON red, OFF
    /// blue, white background) and event_rate.csv.
    #[arg(long)]
    pub viz_dir: Option<PathBuf>,
    /// Time window of one visualisation image, ms.
    #[arg(long, default_value_t = 10.0)]
    pub viz_window_ms: f64,
    /// Bin of the event-rate table, ms.
    #[arg(long, default_value_t = 1.0)]
    pub rate_bin_ms: f64,
}

/// Milliseconds from a flag to integer nanoseconds (rounded), at least 1 ns.
fn ms_to_ns(flag: &str, ms: f64) -> Result<i64> {
    let ns = ms * 1e6;
    ensure!(
        ns.is_finite() && ns.round() >= 1.0 && ns < 9e18,
        "--{flag} {ms}: must be a positive number of milliseconds (at least 0.000001)"
    );
    Ok(ns.round() as i64)
}

/// Resolve the flags into a job: the config file, then the flag overrides, then validation.
pub fn resolve(args: &EventsArgs) -> Result<FramesJob> {
    let mut config = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the event config", path.display()))?;
            toml::from_str::<EventConfig>(&text)
                .with_context(|| format!("{}: not a valid event config", path.display()))?
        }
        None => EventConfig::default(),
    };
    if let Some(c) = args.c_pos {
        config.c_pos = c;
    }
    if let Some(c) = args.c_neg {
        config.c_neg = c;
    }
    if let Some(s) = args.seed {
        config.seed = s;
    }
    config.validate()?;
    let viz = match &args.viz_dir {
        Some(dir) => Some(VizConfig {
            window_ns: ms_to_ns("viz-window-ms", args.viz_window_ms)?,
            rate_bin_ns: ms_to_ns("rate-bin-ms", args.rate_bin_ms)?,
            ..VizConfig::new(dir)
        }),
        None => None,
    };
    Ok(FramesJob {
        frames: args.frames.clone(),
        timestamps: args.timestamps.clone(),
        unit: args.timestamps_unit,
        linear_input: args.linear_input,
        out: args.out.clone(),
        kind: SinkKind::from_path(&args.out, args.format)?,
        config,
        viz,
    })
}

/// Run `evsim events`.
pub fn run(args: &EventsArgs) -> Result<()> {
    let job = resolve(args)?;
    let t0 = Instant::now();
    let pb = crate::progress_bar(0, "events");
    let result = run_on_frames(&job, Some(&pb));
    pb.finish_and_clear();
    let s = result?;
    println!(
        "{} frames {}x{}: {} events ({} ON, {} OFF) in {:.2} s; max |dL|/C = {:.3}; wrote {} ({:?})",
        s.frames,
        s.width,
        s.height,
        s.on + s.off,
        s.on,
        s.off,
        t0.elapsed().as_secs_f64(),
        s.max_change_c,
        job.out.display(),
        job.kind
    );
    if let (Some(v), Some(cfg)) = (&s.viz, &job.viz) {
        println!(
            "viz: {} window images of {} ms from t = {:.6} s into {}; {} ON, {} OFF; event rate peak {:.0} Hz at t = {:.6} s, mean {:.0} Hz ({} ms bins in {})",
            v.windows,
            cfg.window_ns as f64 * 1e-6,
            v.t_first_window_ns.unwrap_or(0) as f64 * 1e-9,
            cfg.dir.display(),
            v.on,
            v.off,
            v.peak_rate_hz,
            v.peak_t_ns as f64 * 1e-9,
            v.mean_rate_hz,
            cfg.rate_bin_ns as f64 * 1e-6,
            cfg.dir.join(simulator::events::sinks::viz::RATE_CSV).display()
        );
    }
    if s.max_change_c > 1.0 {
        eprintln!(
            "warning: max |dL|/C = {:.2} > 1 in {} of {} frame intervals: the frame rate is too low for the threshold, \
             so crossings between frames are timed by linear interpolation and may be misplaced; render about {:.0}x more frames",
            s.max_change_c,
            s.undersampled_intervals,
            s.frames - 1,
            s.max_change_c.ceil()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use simulator::events::{NoiseConfig, Refractory, RefractoryMode};

    /// Parse an `evsim events ...` command line through the real CLI.
    fn parse(args: &[&str]) -> Result<EventsArgs, clap::Error> {
        let argv = ["evsim", "events", "--frames", "f", "--timestamps", "t.txt"].iter().chain(args);
        match crate::Cli::try_parse_from(argv)?.command {
            crate::Command::Events(a) => Ok(a),
            other => panic!("parsed as {other:?}"),
        }
    }

    fn toml_file(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("evblur-events-cmd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn toml_config_then_flag_overrides() {
        let cfg = toml_file(
            "ok.toml",
            "c_pos = 0.3\nc_neg = 0.25\nseed = 7\n[noise.refractory]\nperiod_ns = 1000\nmode = \"consume\"\n",
        );
        let cfg = cfg.to_str().unwrap();
        let job = resolve(&parse(&["--config", cfg, "--c-pos", "0.5"]).unwrap()).unwrap();
        let expected = EventConfig {
            c_pos: 0.5,
            c_neg: 0.25,
            seed: 7,
            noise: NoiseConfig {
                refractory: Some(Refractory { period_ns: 1000, mode: RefractoryMode::Consume }),
                ..NoiseConfig::default()
            },
            ..EventConfig::default()
        };
        assert_eq!(job.config, expected, "the file's values, c_pos from the flag");
        assert_eq!(job.kind, SinkKind::NerfH5);
        assert!(job.viz.is_none());

        // Without --config: the defaults, then the flags.
        let job = resolve(&parse(&["--c-neg", "0.4", "--seed", "3"]).unwrap()).unwrap();
        assert_eq!(job.config, EventConfig { c_neg: 0.4, seed: 3, ..EventConfig::default() });
    }

    #[test]
    fn unknown_toml_key_is_named() {
        let cfg = toml_file("typo.toml", "c_pos = 0.3\nc_poss = 0.4\n");
        let e = format!("{:#}", resolve(&parse(&["--config", cfg.to_str().unwrap()]).unwrap()).unwrap_err());
        assert!(e.contains("typo.toml") && e.contains("c_poss"), "{e}");
    }

    #[test]
    fn dsec_format_needs_an_h5_output() {
        let e = format!("{:#}", resolve(&parse(&["--out", "e.txt", "--format", "dsec"]).unwrap()).unwrap_err());
        assert!(e.contains("e.txt") && e.contains("--format dsec applies only to .h5"), "{e}");
        let job = resolve(&parse(&["--out", "e.h5", "--format", "dsec"]).unwrap()).unwrap();
        assert_eq!(job.kind, SinkKind::DsecH5);
        assert!(parse(&["--format", "hdf"]).is_err(), "an unknown layout is a parse error");
    }

    #[test]
    fn viz_flags_become_a_viz_config() {
        let job = resolve(&parse(&["--viz-dir", "v"]).unwrap()).unwrap();
        assert_eq!(job.viz, Some(VizConfig::new("v")));
        let job =
            resolve(&parse(&["--viz-dir", "v", "--viz-window-ms", "2.5", "--rate-bin-ms", "0.1"]).unwrap()).unwrap();
        let viz = job.viz.unwrap();
        assert_eq!((viz.window_ns, viz.rate_bin_ns), (2_500_000, 100_000));
        let e = format!("{:#}", resolve(&parse(&["--viz-dir", "v", "--viz-window-ms", "0"]).unwrap()).unwrap_err());
        assert!(e.contains("--viz-window-ms 0") && e.contains("positive"), "{e}");
        let e = format!("{:#}", resolve(&parse(&["--viz-dir", "v", "--rate-bin-ms", "nan"]).unwrap()).unwrap_err());
        assert!(e.contains("--rate-bin-ms"), "{e}");
    }
}
