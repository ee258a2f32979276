//! `host-sim`: the command line.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use host_sim::config::RigConfig;
use host_sim::report::{self, csv_out, metrics, plots};
use host_sim::scenario::{run_stroke_cycle, StrokeCycle};
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "host-sim", version, about = "Host simulator of the direct-driven servo electric cylinder")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// The paper's experiment (§5.2): elongation 0→450 mm with tilt 90→60→90°,
    /// contraction 450→0 mm with 90→120→90°, rated load, closed loop through
    /// the firmware's control core. Writes summary.json, CSV traces and plots.
    Paper {
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Rig file (TOML with [control] and [plant]); default: the shipped nominal rig.
        #[arg(long)]
        params: Option<PathBuf>,
        /// Seed of the sensor noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Paper { out, params, seed } => paper(out, params, seed),
    }
}

fn paper(out: PathBuf, params: Option<PathBuf>, seed: u64) -> Result<()> {
    let rig = RigConfig::load_or_nominal(params.as_ref())?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let cycle = StrokeCycle::paper(seed);
    let trace = run_stroke_cycle(&rig, &cycle)?;
    let summary = metrics::paper_summary(&trace, seed, cycle.settle_s);
    csv_out::write_trace(&trace, &out)?;
    plots::paper_plots(&trace, &out)?;
    report::write_summary(&summary, &out)?;
    println!("{}", serde_json::to_string_pretty(&summary)?);
    println!("wrote {}/{{summary.json, telemetry.csv, plant.csv, *.png}}", out.display());
    match trace.aborted {
        Some(why) => anyhow::bail!("the paper run stopped early: {why} (the trace up to there is in {})", out.display()),
        None => Ok(()),
    }
}
