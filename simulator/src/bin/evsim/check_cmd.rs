//! `evsim check <DIR>`: verify a dataset folder against the Ev-DeblurBlender layout and print
//! one line per check; the exit status is non-zero when a problem was found.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use simulator::dataset::check::{check_dataset, CheckOptions, EventsUnit, TestViewPolicy};

/// Options of `evsim check`.
#[derive(Args, Debug, Clone)]
pub struct CheckArgs {
    /// The dataset folder (holding images_1/, poses_bounds.npy, events.h5, ...).
    pub dir: PathBuf,
    /// Which views must be sharp: every 8th (synthetic), the last 5 (real) or either.
    #[arg(long, value_enum, default_value_t = TestViewPolicy::Auto)]
    pub test_views: TestViewPolicy,
    /// Unit of the event times t in events.h5 (auto: from their magnitude against all_timestamps.npy).
    #[arg(long, value_enum, default_value_t = EventsUnit::Auto)]
    pub events_unit: EventsUnit,
    /// Largest accepted deviation of a pose's 3x3 part from a pure rotation.
    #[arg(long, default_value_t = 1e-4)]
    pub rotation_tolerance: f64,
}

/// Run the check and print the report.
pub fn run(args: &CheckArgs) -> Result<()> {
    if !(args.rotation_tolerance >= 0.0 && args.rotation_tolerance.is_finite()) {
        bail!("--rotation-tolerance must be a finite number >= 0, got {}", args.rotation_tolerance);
    }
    let opts = CheckOptions {
        test_views: args.test_views,
        events_unit: args.events_unit,
        rotation_tolerance: args.rotation_tolerance,
        ..CheckOptions::default()
    };
    let report = check_dataset(&args.dir, &opts)?;
    println!("{report}");
    let n = report.problems().count();
    if n > 0 {
        bail!("{}: {n} problem(s) found (see the PROBLEM lines above)", args.dir.display());
    }
    Ok(())
}
