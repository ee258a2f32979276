//! The `host-sim diagnose` command line: its arguments, reading a log in
//! any of the accepted formats, and the run that prints the gates, the
//! verdict and the top effect (the diagnosis itself is `super`).

use super::{cranfield, diagnose_against, figures, log, replay, report, residual};
use anyhow::{bail, Context, Result};
use log::Log;
use residual::Nominal;
use std::path::{Path, PathBuf};

/// `host-sim diagnose` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct DiagnoseArgs {
    /// The measured log: schema CSV (`.csv`), defmt telemetry text (other
    /// extensions), or a Cranfield file (`--format cranfield`, or detected).
    #[arg(long)]
    pub log: PathBuf,
    /// A second log used only as the held-out part (a different run or
    /// trajectory). Without it, alternate runs of --log are held out (or the
    /// last 40 % of a single run).
    #[arg(long)]
    pub heldout: Option<PathBuf>,
    /// Rig file (TOML [control] + [plant]) giving the nominal model; default:
    /// the shipped nominal rig.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Healthy reference log: fit a regression nominal on it instead of the
    /// rig's physics (for rigs whose parameters are unknown, e.g. Cranfield).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Input format: auto, csv, defmt or cranfield.
    #[arg(long, default_value = "auto")]
    pub format: String,
    /// Also run the closed-loop replay (nominal plant + control core driven
    /// by the logged reference and load) on the first run of --log.
    #[arg(long)]
    pub replay: bool,
    /// Longest stretch replayed, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub replay_max_s: f64,
    /// Only convert --log to the schema CSV (DIR/log.csv) and validate it.
    #[arg(long)]
    pub convert_only: bool,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// Reads a log in the given format.
pub fn read_log(path: &Path, format: &str) -> Result<Log> {
    let fmt = if format == "auto" {
        let head = std::fs::read_to_string(path)
            .with_context(|| format!("reading {}", path.display()))?
            .lines()
            .next()
            .unwrap_or("")
            .to_string();
        if head.contains("position_error") && head.contains("set_point") {
            "cranfield"
        } else if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
        {
            "csv"
        } else {
            "defmt"
        }
    } else {
        format
    };
    match fmt {
        "csv" => Log::read_csv(path),
        "defmt" => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            log::parse_defmt(&text, &path.display().to_string())
        }
        "cranfield" => Ok(cranfield::convert(path)?.log),
        other => bail!("--format {other}: expected auto, csv, defmt or cranfield"),
    }
}

/// `host-sim diagnose`.
pub fn run_cli(args: &DiagnoseArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let log = read_log(&args.log, &args.format)?;
    for i in &log.issues {
        eprintln!("{}: {i}", log.source);
    }
    if args.convert_only {
        let path = args.out.join("log.csv");
        log.write_csv(&path)?;
        println!(
            "wrote {} ({} rows, {} errors)",
            path.display(),
            log.len(),
            log.errors().count()
        );
        return if log.errors().count() > 0 {
            bail!("the converted log has errors (listed above)")
        } else {
            Ok(())
        };
    }
    let heldout = args
        .heldout
        .as_ref()
        .map(|p| read_log(p, &args.format))
        .transpose()?;
    let rig = crate::config::RigConfig::load_or_nominal(args.rig.as_ref())?;
    let reference = args
        .reference
        .as_ref()
        .map(|p| read_log(p, &args.format))
        .transpose()?;
    let nominal = match &reference {
        Some(r) => Nominal::Regression(residual::fit_regression(r)?),
        None => Nominal::Physics(residual::Physics::from_rig(&rig)),
    };
    let mut d = diagnose_against(
        &log,
        heldout.as_ref(),
        reference.as_ref(),
        nominal,
        rig.plant.load.initial_tilt_deg,
    )?;
    if args.replay {
        match replay::replay(&rig, &log, args.replay_max_s) {
            Ok(r) => d.summary.replay = Some(r),
            Err(e) => eprintln!("replay skipped: {e:#}"),
        }
    }
    report::write(&d, &args.out)?;
    let s = &d.summary;
    for g in &s.gates {
        println!("WARNING [{}]: {}", g.kind, g.message);
    }
    println!("verdict: {}", s.verdict.headline);
    println!(
        "top effect: {} ({} {:.1} %, {} {:.1} %; fit {:.1} → {:.1} % on the {} channel); stack {:?}: {} {:.1} %, {} {:.1} %",
        s.top_effect.as_deref().unwrap_or("none"),
        figures::PRIMARY,
        s.gap_shrink_pct,
        figures::WEIGHTED,
        s.gap_shrink_weighted_pct,
        s.heldout_fit_before,
        s.heldout_fit_after,
        s.primary_channel,
        s.stack,
        figures::PRIMARY,
        s.gap_shrink_stack_pct,
        figures::WEIGHTED,
        s.gap_shrink_stack_weighted_pct
    );
    println!(
        "wrote {}/{{report.md, summary.json, *.png}}",
        args.out.display()
    );
    Ok(())
}
