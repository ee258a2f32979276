//! `host-sim observer-bench`: the observer on the rigs a second cylinder
//! could be. It builds the rigs from the base rig file itself (`rigs.rs`)
//! and runs one figure group per file, each a row per rig on the same
//! held-out evaluation run (`eval.rs`):
//! - `shipped.rs`: the compiled weights;
//! - `scaled.rs`: the compiled weights scaled by the compliance ratio the
//!   drive identifies (`trainer::stiffness`);
//! - `retrained.rs`: weights retrained from the rig's own logs through the
//!   documented route;
//! - `no_load_cell.rs`: the load cell off, the observer on the drive's
//!   force estimate with the shipped estimate weights.
//!
//! A new figure group is a file with a `run` returning its rows, and one
//! entry in [`groups`]. Writes `summary.json`: the rigs, a table per rig
//! (each group's row), the bars and pass/fail; exits non-zero when a bar
//! is missed.

pub mod anatomy;
pub mod eval;
pub mod no_load_cell;
pub mod retrained;
pub mod rigs;
pub mod scaled;
pub mod shipped;

use crate::config::RigConfig;
use anyhow::{bail, Context, Result};
use eval::Row;
use std::path::PathBuf;
use std::time::Instant;

/// Noise seed of the evaluation run: never a training or logging seed
/// (the held-out seed of the figures in docs/observer-figures.md).
pub const EVAL_SEED: u64 = 6171;

/// `host-sim observer-bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    #[arg(long)]
    pub out: PathBuf,
    /// Base rig file; default: the shipped rig (params/rig.toml).
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Only these rigs (comma-separated names, as in summary.json).
    #[arg(long, value_delimiter = ',')]
    pub rigs: Vec<String>,
    /// Only these figure groups (comma-separated: shipped, scaled, retrained, no_load_cell, anatomy);
    /// default: all but anatomy, a measurement without a bar.
    #[arg(long, value_delimiter = ',')]
    pub groups: Vec<String>,
    /// Stroke cycles logged per payload for retraining.
    #[arg(long, default_value_t = 6)]
    pub cycles: usize,
    /// Weights to evaluate in the "shipped" group instead of the compiled
    /// ones: a trainer's model.json, before it is compiled in.
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Sensor-noise seed of the evaluation run.
    #[arg(long, default_value_t = EVAL_SEED)]
    pub seed: u64,
}

/// A figure group's name and how it runs.
type Group = (&'static str, &'static str, fn(&[rigs::BenchRig], &BenchArgs) -> Result<Vec<Row>>);

/// The figure groups, in column order.
pub fn groups() -> Vec<Group> {
    vec![
        ("shipped", "compiled weights, friction identified into the feedforward", |r, a| {
            let weights = match &a.weights {
                Some(p) => Some(&*Box::leak(Box::new(crate::tool::observer::read_model(p)?))),
                None => None,
            };
            shipped::run(r, weights, a.seed)
        }),
        ("scaled", "compiled weights scaled by the compliance ratio `drive identify stiffness` reads on a simulated drive of the rig (current step above the hold current against the rig file's design), friction identified", |r, a| {
            scaled::run(r, &RigConfig::load_or_nominal(a.params.as_ref())?, a.seed)
        }),
        ("retrained", "weights retrained from the rig's own logs (route: identify friction, log, dataset-from-logs, train --hidden 8, upload, verify)", |r, a| {
            retrained::run(r, a.cycles, a.seed, &a.out)
        }),
        ("no_load_cell", "no load cell: the shipped estimate weights on the drive's current-based force estimate, friction identified", |r, a| {
            no_load_cell::run(r, a.seed)
        }),
        ("anatomy", "where the shipped weights' error comes from (prediction miss, loop lag, static deflection, lead error) and two oracles: the network fitted on the evaluation run itself, and the shipped prediction scaled by the true compliance; no bar", |r, a| {
            anatomy::run(r, a.seed)
        }),
    ]
}

pub fn run(a: &BenchArgs) -> Result<serde_json::Value> {
    let t0 = Instant::now();
    let base = RigConfig::load_or_nominal(a.params.as_ref())?;
    let all = rigs::bench_rigs(&base);
    for n in &a.rigs {
        if !all.iter().any(|r| r.name == n) {
            bail!("--rigs: no rig '{n}' (rigs: {})", all.iter().map(|r| r.name).collect::<Vec<_>>().join(", "));
        }
    }
    let chosen: Vec<_> = all.into_iter().filter(|r| a.rigs.is_empty() || a.rigs.iter().any(|n| n == r.name)).collect();
    let groups = groups();
    for g in &a.groups {
        if !groups.iter().any(|(n, _, _)| n == g) {
            bail!("--groups: no group '{g}' (groups: {})", groups.iter().map(|g| g.0).collect::<Vec<_>>().join(", "));
        }
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut table: Vec<serde_json::Map<String, serde_json::Value>> = chosen
        .iter()
        .map(|r| {
            let mut m = serde_json::Map::new();
            m.insert("rig".into(), r.name.into());
            m.insert("draw".into(), serde_json::to_value(r.draw).unwrap_or_default());
            m
        })
        .collect();
    let mut group_notes = serde_json::Map::new();
    let mut failed = Vec::new();
    for (name, what, f) in groups.iter().filter(|g| if a.groups.is_empty() { g.0 != "anatomy" } else { a.groups.iter().any(|n| n == g.0) }) {
        let t = Instant::now();
        let rows = f(&chosen, a)?;
        group_notes.insert((*name).into(), serde_json::json!({ "what": what, "wall_s": t.elapsed().as_secs_f64() }));
        for row in &rows {
            if row.passed == Some(false) {
                failed.push(format!("{name} on {}: {:.1} % < {:.0} %", row.rig, row.reduction_pct, row.bar_pct.unwrap_or(0.0)));
            }
            // A group may give rows for some rigs only: each goes to its rig's line.
            let m = table.iter_mut().find(|m| m["rig"] == row.rig.as_str()).with_context(|| format!("{name}: a row for an unknown rig {}", row.rig))?;
            m.insert((*name).into(), serde_json::to_value(row)?);
        }
    }
    let mut brief = String::from("| rig |");
    let names: Vec<_> = groups.iter().map(|g| g.0.to_string()).filter(|n| group_notes.contains_key(n)).collect();
    for n in &names {
        brief.push_str(&format!(" {n} (bar) |"));
    }
    for m in &table {
        brief.push_str(&format!("\n| {} |", m["rig"].as_str().unwrap_or("")));
        for n in &names {
            let r = &m[n.as_str()];
            let bar = r["bar_pct"].as_f64().map_or("–".to_string(), |b| format!("{b:.0}"));
            brief.push_str(&format!(" {:.1} % ({bar}) |", r["reduction_pct"].as_f64().unwrap_or(f64::NAN)));
        }
    }
    let summary = serde_json::json!({
        "command": "host-sim observer-bench",
        "evaluation": { "run": "the paper's stroke cycle (0→450→0 mm, tilt swing 30°, the rig's rated payload), observer off and on", "noise_seed": a.seed },
        "figure": "max terminal error reduction, % (1 − max|terminal − reference| on / off)",
        "groups": group_notes,
        "table": table,
        "passed": failed.is_empty(),
        "failed": failed,
        "wall_s": t0.elapsed().as_secs_f64(),
    });
    std::fs::write(a.out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    println!("{brief}");
    println!("wall {:.1} s; wrote {}", t0.elapsed().as_secs_f64(), a.out.join("summary.json").display());
    if !failed.is_empty() {
        bail!("bars missed: {}", failed.join("; "));
    }
    Ok(summary)
}
