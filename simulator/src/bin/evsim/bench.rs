//! `evsim bench ...`: benchmark programs that print their figures.

use anyhow::Result;
use clap::Subcommand;

/// Which benchmark to run.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Cornell box throughput vs Mitsuba, and BVH build/trace on a 1 M-triangle scene.
    Render,
}

/// Run a benchmark.
pub fn run(what: BenchCommand) -> Result<()> {
    match what {
        BenchCommand::Render => anyhow::bail!("not yet"),
    }
}
