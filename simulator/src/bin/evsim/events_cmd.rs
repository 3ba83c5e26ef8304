//! `evsim events`: run the event model over a folder of frames into an event file.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use simulator::events::sinks::{H5Layout, SinkKind};
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
}

/// Resolve the flags into a job: the config file, then the flag overrides, then validation.
pub fn resolve(args: &EventsArgs) -> Result<FramesJob> {
    let mut config = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read the event config", path.display()))?;
            toml::from_str::<EventConfig>(&text).with_context(|| format!("{}: not a valid event config", path.display()))?
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
    Ok(FramesJob {
        frames: args.frames.clone(),
        timestamps: args.timestamps.clone(),
        unit: args.timestamps_unit,
        linear_input: args.linear_input,
        out: args.out.clone(),
        kind: SinkKind::from_path(&args.out, args.format)?,
        config,
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
