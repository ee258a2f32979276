//! `host-sim`: the command line.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use rayon::prelude::*;
use host_sim::config::RigConfig;
use host_sim::report::{self, csv_out, metrics, plots};
use host_sim::rigs::FamilySpec;
use host_sim::scenario::dataset::{self, DatasetSpec};
use host_sim::scenario::no_load_cell::ForceSource;
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
        /// Run the cycle again with the compiled-in error observer's
        /// compensation on, and report before/after.
        #[arg(long)]
        observer: bool,
        /// Run on every rig of a family (`host-sim rigs`) instead: a row
        /// per rig and the worst case in summary.json, family.md.
        #[arg(long, conflicts_with_all = ["params", "observer"])]
        family: Option<PathBuf>,
        /// With --family: choose each rig's torque filter by its own test
        /// moves first (docs/tuning-family.md, "The torque filter per unit").
        #[arg(long, requires = "family")]
        tune_filter: bool,
    },
    /// Fault injection: every scenario of docs/reliability.md, closed loop.
    /// Writes summary.json, reliability_measured.md and a trace per scenario.
    Faults {
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Every scenario on every rig of a family (`host-sim rigs`).
        #[arg(long, conflicts_with = "params")]
        family: Option<PathBuf>,
    },
    /// Train the IBAS-BPNN error observer (paper §4.1) on a dataset and write
    /// the firmware's model source. Writes summary.json, model.json, model.rs
    /// and test_predictions.csv to --out.
    /// Power-ups under the rated vertical load from random rotor angles and
    /// rod positions, plus the failure cases; writes summary.json, cases.md.
    PowerUp {
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Successful power-ups to run (random rotor angle, rod, encoder zero).
        #[arg(long, default_value_t = 20)]
        power_ups: usize,
        /// Rods are drawn from this range of the stroke, metres.
        #[arg(long, default_value_t = 0.005)]
        rod_min_m: f64,
        #[arg(long, default_value_t = 0.495)]
        rod_max_m: f64,
        /// Homings on one rig for the repeatability figure (0: none).
        #[arg(long, default_value_t = 10)]
        homings: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// The same cases on every rig of a family (`host-sim rigs`); no homings.
        #[arg(long, conflicts_with = "params")]
        family: Option<PathBuf>,
        /// Power up each rig as a commissioned unit: its torque filter
        /// chosen first by its own test moves (docs/tuning-family.md, "The
        /// torque filter per unit"), as the tracking suites do.
        #[arg(long)]
        tune_filter: bool,
    },
    Train(host_sim::trainer::TrainArgs),
    /// Turn the drive's own logs (telemetry CSV, a logger's CSV with the
    /// linear scale) into the trainer's dataset: runs and directions cut
    /// automatically, refused naming what a log lacks.
    DatasetFromLogs(host_sim::trainer::from_logs::FromLogsArgs),
    /// The screw's lead from the drive's logs (strokes at two payloads or
    /// more, a linear scale at the rod), for `drive_train.screw_lead_m`.
    LeadFromLogs(host_sim::trainer::lead::LeadArgs),
    /// The retraining route timed end to end (logs → dataset → train →
    /// upload → verify on the simulated drive): summary.json.
    ObserverRoute(host_sim::trainer::route::RouteArgs),
    /// The observer on the rigs a second cylinder could be (stiffness,
    /// friction, payload, lead, combined), built from the rig file: the
    /// shipped weights and weights retrained from each rig's own logs, on
    /// a held-out run. summary.json; non-zero exit when a bar is missed.
    ObserverBench(host_sim::trainer::bench::BenchArgs),
    /// The observer without a load cell: a model trained on the drive's
    /// current-based force estimate, the paper's run (held out by
    /// trajectory) compensated with it: summary.json.
    ObserverNoLoadCell(host_sim::scenario::no_load_cell::NoLoadCellArgs),
    /// Diagnose the sim-to-real gap of a measured log: where it
    /// lies, which unmodelled effect causes it, how far it shrinks.
    Diagnose(host_sim::diagnose::DiagnoseArgs),
    /// The drive protocol: `drive serve` runs a simulated drive on
    /// a TCP socket; the other subcommands are the host tool, talking to a
    /// board (--port) or a simulated drive (--tcp). docs/host-tool.md.
    Drive(host_sim::tool::DriveArgs),
    /// Tuning from identification: identify inertia,
    /// friction, R and L from captures; propose gains for asked bandwidths
    /// and phase margin; check them on the simulator. docs/tuning.md.
    Tune(host_sim::tuning::cli::TuneArgs),
    /// Observer training data: the paper's cycle at several tilt swings and
    /// payloads, closed loop; one run per leg. Writes DIR/dataset.csv and
    /// DIR/summary.json.
    /// The 6-DOF platform: kinematics along pose trajectories,
    /// leg forces, the Table 4 reproduction. Writes summary.json,
    /// table4.md, geometry.png and per-trajectory plots.
    Platform {
        #[arg(long)]
        out: PathBuf,
        /// Platform geometry (TOML); default: Table 3 (params/platform.toml).
        #[arg(long)]
        geometry: Option<PathBuf>,
        /// Rig file for the six closed-loop legs; default: the shipped rig.
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// A family of rigs a second unit of the cylinder could be, drawn from
    /// a rig file within stated tolerances: DIR/rig_NNN.toml, the five
    /// corners (softer, stiffer, heavier, more friction, combined) and
    /// DIR/family.json. Every suite takes one with --family DIR.
    Rigs(RigsArgs),
    Dataset {
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Tilt swings in degrees (comma-separated).
        #[arg(long, value_delimiter = ',', default_values_t = DatasetSpec::default().tilt_swings_deg)]
        tilt_swings_deg: Vec<f64>,
        /// Payload scales relative to rated (comma-separated).
        #[arg(long, value_delimiter = ',', default_values_t = DatasetSpec::default().payload_scales)]
        payload_scales: Vec<f64>,
        /// Stroke tops in metres (comma-separated), used in turn; never the
        /// paper's 0.45 m with its 30° swing, the held-out evaluation run.
        #[arg(long, value_delimiter = ',', default_values_t = DatasetSpec::default().tops_m)]
        tops_m: Vec<f64>,
        /// Rigs drawn within a second unit's tolerances (stiffness ±15 %,
        /// friction ±30 %, lead within C7) besides the rig file's own.
        #[arg(long, default_value_t = DatasetSpec::default().family_rigs)]
        family_rigs: usize,
        #[arg(long, default_value_t = DatasetSpec::default().seed)]
        seed: u64,
        /// The observer's force input the data is recorded with (sets
        /// control.compensation.force_from_estimate); default: the rig file's.
        #[arg(long, value_enum)]
        force_source: Option<ForceSource>,
    },
}

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
struct RigsArgs {
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Drawn rigs (the corners come on top).
    #[arg(long)]
    count: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Base rig file; default: the shipped nominal rig.
    #[arg(long)]
    params: Option<PathBuf>,
    /// Leave out the five corner rigs.
    #[arg(long)]
    no_corners: bool,
    /// Structure stiffness, ± fraction.
    #[arg(long, default_value_t = FamilySpec::default().stiffness_tol)]
    stiffness_tol: f64,
    /// Coulomb friction, viscous friction and the screw's friction coefficient, each ± fraction.
    #[arg(long, default_value_t = FamilySpec::default().friction_tol)]
    friction_tol: f64,
    /// Payload range, fractions of the base (rated) payload.
    #[arg(long, default_value_t = FamilySpec::default().payload_min)]
    payload_min: f64,
    #[arg(long, default_value_t = FamilySpec::default().payload_max)]
    payload_max: f64,
    /// Rotor, coupling and screw inertia, ± fraction.
    #[arg(long, default_value_t = FamilySpec::default().inertia_tol)]
    inertia_tol: f64,
    /// Winding resistance factor range (cold to hot).
    #[arg(long, default_value_t = FamilySpec::default().resistance_min)]
    resistance_min: f64,
    #[arg(long, default_value_t = FamilySpec::default().resistance_max)]
    resistance_max: f64,
    /// d/q inductance, ± fraction.
    #[arg(long, default_value_t = FamilySpec::default().inductance_tol)]
    inductance_tol: f64,
    /// Magnet flux factor range.
    #[arg(long, default_value_t = FamilySpec::default().flux_min)]
    flux_min: f64,
    #[arg(long, default_value_t = FamilySpec::default().flux_max)]
    flux_max: f64,
    /// Cumulative lead error bound, m/m (default: C7, 52 µm over 300 mm).
    #[arg(long, default_value_t = FamilySpec::default().lead_error_max)]
    lead_error_max: f64,
}

fn rigs(a: RigsArgs) -> Result<()> {
    let spec = FamilySpec {
        stiffness_tol: a.stiffness_tol,
        friction_tol: a.friction_tol,
        payload_min: a.payload_min,
        payload_max: a.payload_max,
        inertia_tol: a.inertia_tol,
        resistance_min: a.resistance_min,
        resistance_max: a.resistance_max,
        inductance_tol: a.inductance_tol,
        flux_min: a.flux_min,
        flux_max: a.flux_max,
        lead_error_max: a.lead_error_max,
    };
    let (text, origin) = match &a.params {
        Some(p) => (std::fs::read_to_string(p).with_context(|| format!("reading rig file {}", p.display()))?, p.display().to_string()),
        None => (host_sim::config::DEFAULT_RIG_TOML.to_string(), "params/rig.toml".to_string()),
    };
    let list = host_sim::rigs::write_family(&text, &origin, &spec, a.count, a.seed, !a.no_corners, &a.out)?;
    println!("wrote {} rig files and family.json to {}", list.len(), a.out.display());
    Ok(())
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Paper { out, family: Some(dir), seed, tune_filter, .. } => {
            let rigs = host_sim::rigs::load_family(&dir)?;
            family_done(host_sim::scenario::family::run_family(&rigs, &dir, seed, tune_filter, &out)?, &out)
        }
        Cmd::Paper { out, params, seed, observer, family: None, .. } => paper(out, params, seed, observer),
        Cmd::Faults { out, family: Some(dir), .. } => {
            let rigs = host_sim::rigs::load_family(&dir)?;
            family_done(host_sim::fault_injection::family::run_family(&rigs, &dir, &out)?, &out)
        }
        Cmd::PowerUp { out, family: Some(dir), power_ups, rod_min_m, rod_max_m, seed, tune_filter, .. } => {
            check_rod_range(rod_min_m, rod_max_m)?;
            let rigs = host_sim::rigs::load_family(&dir)?;
            let s = host_sim::power_up::family::run_family(&rigs, &dir, power_ups, (rod_min_m, rod_max_m), seed, tune_filter, &out)?;
            family_done(s, &out)
        }
        Cmd::Faults { out, params, family: None } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let rows = host_sim::fault_injection::report::run_catalog(&rig, &out)?;
            print!("{}", host_sim::fault_injection::report::markdown_table(&rows));
            println!("{} of {} scenarios meet their requirement", rows.iter().filter(|r| r.passed).count(), rows.len());
            let missed: Vec<String> = rows.iter().filter(|r| !r.passed).map(|r| format!("{}: {}", r.name, r.violations.join(", "))).collect();
            suite_done("faults", &missed, &out)
        }
        Cmd::PowerUp { out, params, power_ups, rod_min_m, rod_max_m, homings, seed, family: None, tune_filter } => {
            power_up(out, params, power_ups, (rod_min_m, rod_max_m), homings, seed, tune_filter)
        }
        Cmd::Train(args) => host_sim::trainer::run_cli(&args).map(|_| ()),
        Cmd::DatasetFromLogs(args) => host_sim::trainer::from_logs::run_cli(&args).map(|_| ()),
        Cmd::LeadFromLogs(args) => host_sim::trainer::lead::run_cli(&args).map(|_| ()),
        Cmd::ObserverRoute(args) => host_sim::trainer::route::run(&args).map(|_| ()),
        Cmd::ObserverBench(args) => host_sim::trainer::bench::run(&args).map(|_| ()),
        Cmd::ObserverNoLoadCell(args) => host_sim::scenario::no_load_cell::run_cli(&args).map(|_| ()),
        Cmd::Diagnose(args) => host_sim::diagnose::run_cli(&args),
        Cmd::Drive(args) => host_sim::tool::run_cli(args),
        Cmd::Tune(args) => host_sim::tuning::cli::run(args),
        Cmd::Platform { out, geometry, params } => {
            let g = match geometry {
                Some(path) => host_sim::platform::Geometry::load(&path)?,
                None => host_sim::platform::Geometry::paper(),
            };
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let summary = host_sim::platform::run::run(g, Some(&rig), &out)?;
            report::write_summary(&summary, &out)?;
            println!("{}", serde_json::to_string_pretty(&summary)?);
            println!("wrote {}/{{summary.json, table4.md, geometry.png, *_pose_*.png, *_leg_*.png}}", out.display());
            Ok(())
        }
        Cmd::Rigs(a) => rigs(a),
        Cmd::Dataset { out, params, tilt_swings_deg, payload_scales, tops_m, family_rigs, seed, force_source } => {
            dataset(out, params, DatasetSpec { tilt_swings_deg, payload_scales, tops_m, family_rigs, identify_friction: true, seed }, force_source)
        }
    }
}

fn dataset(out: PathBuf, params: Option<PathBuf>, spec: DatasetSpec, force_source: Option<ForceSource>) -> Result<()> {
    for (name, values) in [("--tilt-swings-deg", &spec.tilt_swings_deg), ("--payload-scales", &spec.payload_scales)] {
        if values.is_empty() || values.iter().any(|v| !v.is_finite() || *v < 0.0) {
            anyhow::bail!("{name}: expected a comma-separated list of finite, non-negative numbers, got {values:?}");
        }
    }
    if let Some(p) = spec.payload_scales.iter().find(|p| **p > 1.25) {
        anyhow::bail!("--payload-scales: {p} is above 1.25 × rated, beyond the drive's rating");
    }
    if spec.tops_m.is_empty() || spec.tops_m.iter().any(|t| !(t.is_finite() && (0.05..=0.49).contains(t))) {
        anyhow::bail!("--tops-m: expected stroke tops within 0.05–0.49 m, got {:?}", spec.tops_m);
    }
    if let Some(s) = spec.tilt_swings_deg.iter().find(|s| **s > 90.0) {
        anyhow::bail!("--tilt-swings-deg: {s}° would tilt past horizontal");
    }
    let mut rig = RigConfig::load_or_nominal(params.as_ref())?;
    if let Some(source) = force_source {
        source.apply(&mut rig);
    }
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let t0 = std::time::Instant::now();
    let rows = dataset::generate(&rig, &spec)?;
    let path = out.join("dataset.csv");
    dataset::write_csv(&rows, &path, servo_core::observer::block::ForceSource::selected(rig.control.compensation.force_from_estimate))?;
    let runs = rows.last().map_or(0, |r| r.run_id + 1);
    let summary = serde_json::json!({
        "dataset": path.display().to_string(),
        "runs": runs,
        "samples": rows.len(),
        "tilt_swings_deg": spec.tilt_swings_deg,
        "payload_scales": spec.payload_scales,
        "tops_m": spec.tops_m,
        "rigs": dataset::family_draws(&spec).into_iter().map(|(name, _)| name).collect::<Vec<_>>(),
        "seed": spec.seed,
        "force_from_estimate": rig.control.compensation.force_from_estimate,
        "terminal_error_min_m": rows.iter().map(|r| r.terminal_error_m).fold(f64::INFINITY, f64::min),
        "terminal_error_max_m": rows.iter().map(|r| r.terminal_error_m).fold(f64::NEG_INFINITY, f64::max),
        "wall_s": t0.elapsed().as_secs_f64(),
    });
    report::write_summary(&summary, &out)?;
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}

fn paper(out: PathBuf, params: Option<PathBuf>, seed: u64, observer: bool) -> Result<()> {
    let rig = RigConfig::load_or_nominal(params.as_ref())?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let cycle = StrokeCycle::paper(seed);
    let trace = run_stroke_cycle(&rig, &cycle)?;
    let mut summary = metrics::paper_summary(&trace, seed, cycle.settle_s);
    csv_out::write_trace(&trace, &out)?;
    plots::paper_plots(&trace, &out)?;
    if observer {
        let compensated = run_stroke_cycle(&rig, &StrokeCycle { compensation: true, ..cycle })?;
        summary.observer = Some(metrics::observer_figures(&trace, &compensated, cycle.settle_s));
        let dir = out.join("compensated");
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        csv_out::write_trace(&compensated, &dir)?;
        plots::paper_plots(&compensated, &dir)?;
        plots::compensation_plot(&trace, &compensated, &out)?;
    }
    report::write_summary(&summary, &out)?;
    println!("{}", serde_json::to_string_pretty(&summary)?);
    println!("wrote {}/{{summary.json, telemetry.csv, plant.csv, *.png}}", out.display());
    if let Some(why) = &trace.aborted {
        anyhow::bail!("the paper run stopped early: {why} (the trace up to there is in {})", out.display());
    }
    suite_done("paper", &host_sim::scenario::family::misses(&summary), &out)
}

/// A single-rig suite's end, as the family modes end: after its
/// summary.json is written, a missed requirement fails the command
/// (exit 1), naming each scenario that missed and why.
fn suite_done(command: &str, missed: &[String], out: &std::path::Path) -> Result<()> {
    if missed.is_empty() {
        return Ok(());
    }
    anyhow::bail!("{command}: {} missed its requirement: {} (summary: {})", missed.len(), missed.join("; "), out.join("summary.json").display())
}

fn power_up(out: PathBuf, params: Option<PathBuf>, power_ups: usize, rod_m: (f64, f64), homings: usize, seed: u64, tune_filter: bool) -> Result<()> {
    use host_sim::power_up;
    let (lo, hi) = rod_m;
    check_rod_range(lo, hi)?;
    let mut rig = RigConfig::load_or_nominal(params.as_ref())?;
    if tune_filter {
        let (tuned, choice) = host_sim::tuning::filter::retune(&rig, seed).context("choosing the torque filter")?;
        std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
        std::fs::write(out.join("torque_filter.json"), serde_json::to_string_pretty(&choice)?)?;
        rig = tuned;
    }
    let t0 = std::time::Instant::now();
    let cases = power_up::suite(power_ups, lo, hi, rig.plant.screw.lead_m, seed);
    // Independent runs, each with its own plant and controller.
    let rows = cases.par_iter().map(|c| power_up::run_case(&rig, c)).collect::<Result<Vec<_>>>()?;
    // A rig that never gets ready (a hold that rings) still gets its
    // table: the homings' failure is one more missed requirement.
    let (zeros, homings_missed) = match homings {
        0 => (vec![], None),
        _ => match power_up::homing_repeatability(&rig, &cases[0], homings) {
            Ok(z) => (z, None),
            Err(e) => (vec![], Some(format!("homing repeatability: {e}"))),
        },
    };
    let summary = power_up::summarise(&rows, &zeros, t0.elapsed().as_secs_f64());
    power_up::write_report(&summary, &rows, &out)?;
    let mut brief = summary.clone();
    if let Some(m) = brief.as_object_mut() {
        m.remove("cases");
    }
    println!("{}", serde_json::to_string_pretty(&brief)?);
    print!("{}", std::fs::read_to_string(out.join("cases.md"))?);
    let mut missed: Vec<String> = rows.iter().filter(|r| !r.passed).map(|r| format!("{}: {}", r.name, r.verdict)).collect();
    missed.extend(homings_missed);
    suite_done("power-up", &missed, &out)
}

fn check_rod_range(lo: f64, hi: f64) -> Result<()> {
    if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= 0.5) {
        anyhow::bail!("--rod-min-m / --rod-max-m: need 0 <= min < max <= 0.5 (the stroke), got {lo} / {hi}");
    }
    Ok(())
}

/// Prints a family mode's per-rig table and worst cases; fails when a rig did.
fn family_done(summary: serde_json::Value, out: &std::path::Path) -> Result<()> {
    print!("{}", std::fs::read_to_string(out.join("family.md"))?);
    println!("worst: {}", serde_json::to_string_pretty(&summary["worst"])?);
    let failed = summary["rigs_failed"].as_array().map_or(0, Vec::len);
    println!("{} of {} rigs pass; wrote {}/{{summary.json, family.md}} and a folder per rig", summary["rigs_passed"], summary["rigs"], out.display());
    if failed > 0 {
        anyhow::bail!("{failed} rig(s) failed: {}", summary["rigs_failed"]);
    }
    Ok(())
}
