//! `host-sim train` on the command line: the arguments, their mapping onto
//! [`TrainOptions`], and the files a run writes (summary, model, firmware
//! source, test predictions). Kept apart from the training itself, which
//! the tests drive without a command line.

use super::comparisons::{baselines, table2, table2_markdown};
use super::dataset::{Dataset, Direction, ModelKind, SplitSpec};
use super::ibas::{IbasOptions, StepDecay};
use super::optim::{Method, OptimOptions};
use super::{codegen, load_data, train_dataset, DataSource, TrainOptions, TrainReport};
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::path::PathBuf;

/// `host-sim train`: train the error observer and write the firmware model.
#[derive(Clone, Debug, clap::Args)]
pub struct TrainArgs {
    /// Dataset: one CSV file (with a run_id column) or a folder of CSV files.
    #[arg(long, conflicts_with = "synthetic", required_unless_present = "synthetic")]
    pub data: Option<PathBuf>,
    /// Train on a built-in synthetic dataset of this many runs instead.
    #[arg(long)]
    pub synthetic: Option<usize>,
    /// Output folder: summary.json, model.json, model.rs, test_predictions.csv.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the generated model here (e.g. ../src/observer/model.rs).
    #[arg(long)]
    pub emit_core: Option<PathBuf>,
    /// Skip the baselines (back-propagation from a random start, IBAS
    /// alone), trained at the chosen size on the same split.
    #[arg(long)]
    pub no_baselines: bool,
    /// Also train the paper's Table 2 grid, {opposite, mixed} × {length,
    /// error}, and write table2.json / table2.md.
    #[arg(long)]
    pub table2: bool,
    /// Dataset name recorded in the model's metadata.
    #[arg(long)]
    pub dataset_name: Option<String>,
    #[arg(long, value_enum, default_value_t = KindArg::Error)]
    pub kind: KindArg,
    #[arg(long, value_enum, default_value_t = SplitArg::Mixed)]
    pub split: SplitArg,
    /// Opposite split: direction trained on (the other one is the test).
    #[arg(long, value_enum, default_value_t = DirectionArg::Elongation)]
    pub train_direction: DirectionArg,
    /// Mixed split: share of each direction's runs held out for the test.
    #[arg(long, default_value_t = 0.25)]
    pub test_fraction: f64,
    #[arg(long, default_value_t = 0.2)]
    pub validation_fraction: f64,
    /// Candidate hidden sizes (comma-separated); one value fixes it.
    #[arg(long, value_delimiter = ',', default_values_t = vec![8, 16, 24, 32])]
    pub hidden: Vec<usize>,
    /// Leave out the linear skip term (the paper's pure RBF network).
    #[arg(long)]
    pub no_linear_term: bool,
    #[arg(long, default_value_t = 1e-6)]
    pub lambda: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, default_value_t = 4000)]
    pub max_train_samples: usize,
    /// IBAS variant: `default` (one beetle, geometric decay, keep-best),
    /// `paper` (as the paper writes it: linear decay, fixed antennae, last
    /// position), `swarm` (4 beetles, adaptive step, keep-best), `none`
    /// (baseline: back-propagation from the random start).
    #[arg(long, value_enum, default_value_t = IbasArg::Default)]
    pub ibas: IbasArg,
    #[arg(long)]
    pub beetles: Option<usize>,
    #[arg(long)]
    pub ibas_iterations: Option<usize>,
    #[arg(long)]
    pub antenna: Option<f64>,
    #[arg(long)]
    pub step_start: Option<f64>,
    #[arg(long)]
    pub step_end: Option<f64>,
    #[arg(long, value_enum)]
    pub decay: Option<DecayArg>,
    /// Back-propagation method (`none`: IBAS alone, a baseline).
    #[arg(long, value_enum, default_value_t = OptimArg::Lbfgs)]
    pub optimiser: OptimArg,
    #[arg(long)]
    pub epochs: Option<usize>,
    #[arg(long)]
    pub learning_rate: Option<f64>,
    #[arg(long)]
    pub no_progress: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum KindArg {
    Error,
    Length,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SplitArg {
    Mixed,
    Opposite,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DirectionArg {
    Elongation,
    Contraction,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IbasArg {
    Default,
    Paper,
    Swarm,
    None,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DecayArg {
    Linear,
    Geometric,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OptimArg {
    Lbfgs,
    Adam,
    Gd,
    None,
}

impl TrainArgs {
    pub fn to_options(&self) -> TrainOptions {
        let data = match (&self.data, self.synthetic) {
            (Some(p), _) => DataSource::Csv(p.clone()),
            (None, Some(n)) => DataSource::Synthetic { runs: n },
            (None, None) => DataSource::Synthetic { runs: 0 },
        };
        let mut o = TrainOptions::new(data);
        o.dataset_name = self.dataset_name.clone();
        o.kind = match self.kind {
            KindArg::Error => ModelKind::Error,
            KindArg::Length => ModelKind::Length,
        };
        o.split = match self.split {
            SplitArg::Mixed => SplitSpec::Mixed { test_fraction: self.test_fraction },
            SplitArg::Opposite => SplitSpec::Opposite {
                train: match self.train_direction {
                    DirectionArg::Elongation => Direction::Elongation,
                    DirectionArg::Contraction => Direction::Contraction,
                },
            },
        };
        o.validation_fraction = self.validation_fraction;
        o.hidden = self.hidden.clone();
        o.linear_term = !self.no_linear_term;
        o.lambda = self.lambda;
        o.seed = self.seed;
        o.max_train_samples = self.max_train_samples;
        o.ibas = if self.ibas == IbasArg::None {
            None
        } else {
            let mut i = match self.ibas {
                IbasArg::Paper => IbasOptions::paper(),
                IbasArg::Swarm => IbasOptions::swarm(),
                _ => IbasOptions::default(),
            };
            if let Some(v) = self.beetles {
                i.beetles = v;
            }
            if let Some(v) = self.ibas_iterations {
                i.iterations = v;
            }
            if let Some(v) = self.antenna {
                i.antenna_d0 = v;
            }
            if let Some(v) = self.step_start {
                i.step_start = v;
            }
            if let Some(v) = self.step_end {
                i.step_end = v;
            }
            if let Some(d) = self.decay {
                i.decay = match d {
                    DecayArg::Linear => StepDecay::Linear,
                    DecayArg::Geometric => StepDecay::Geometric,
                };
            }
            Some(i)
        };
        o.optimiser = match self.optimiser {
            OptimArg::None => None,
            m => {
                let mut oo = OptimOptions::for_method(match m {
                    OptimArg::Adam => Method::Adam,
                    OptimArg::Gd => Method::Gd,
                    _ => Method::Lbfgs,
                });
                if let Some(e) = self.epochs {
                    oo.epochs = e;
                }
                if let Some(lr) = self.learning_rate {
                    oo.learning_rate = lr;
                }
                Some(oo)
            }
        };
        o.progress = !self.no_progress;
        o
    }
}

/// `host-sim train`: trains, writes `summary.json`, `model.json`, `model.rs`
/// and `test_predictions.csv` to `--out` (and the model to `--emit-core`),
/// prints the summary.
pub fn run_cli(args: &TrainArgs) -> Result<TrainReport> {
    let opts = args.to_options();
    if args.data.is_none() && args.synthetic.is_some_and(|n| n < 4) {
        bail!("--synthetic needs at least 4 runs (two per direction)");
    }
    let ds = load_data(&opts)?;
    if let (Some(p), super::dataset::ForceSource::Estimate) = (&args.emit_core, ds.force_source) {
        // The image's model is the load-cell one: a drive runs it on either
        // input, and uploads are checked against the input they were trained
        // on; compiled-in estimate weights would escape that check.
        bail!(
            "--emit-core {}: {} was logged on the drive's force estimate (load_force_estimate_n); the compiled model is the load-cell model: upload these weights instead (docs/observer-retraining.md, \"Without a load cell\")",
            p.display(),
            ds.path.display()
        );
    }
    let report = train_dataset(&ds, &opts)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let argv: Vec<String> = std::env::args().collect();
    let from = argv.iter().position(|a| a == "train").map_or(1, |i| i + 1);
    let command = format!("host-sim train {}", argv.get(from..).unwrap_or_default().join(" "));
    let src = codegen::generate(&report.model, &report.codegen_meta(command.trim()))?;
    let write = |p: PathBuf, s: &str| std::fs::write(&p, s).with_context(|| format!("writing {}", p.display()));
    let baselines = if args.no_baselines { None } else { Some(baselines(&ds, &opts, &report)?) };
    let summary = TrainSummary {
        observer_rmse_um_heldout: report.test.rmse_um,
        mape_before: report.test_uncompensated.mape_pct,
        mape_after: report.test.mape_pct,
        baseline_rmse_um: baselines.clone().unwrap_or_default(),
        report: &report,
    };
    write(args.out.join("summary.json"), &serde_json::to_string_pretty(&summary)?)?;
    if args.table2 {
        let rows = table2(&ds, &opts)?;
        write(args.out.join("table2.json"), &serde_json::to_string_pretty(&rows)?)?;
        write(args.out.join("table2.md"), &table2_markdown(&rows))?;
        print!("{}", table2_markdown(&rows));
    }
    write(args.out.join("model.json"), &serde_json::to_string_pretty(&report.model)?)?;
    write(args.out.join("model.rs"), &src)?;
    write_test_predictions(&ds, &report, &args.out.join("test_predictions.csv"))?;
    if let Some(p) = &args.emit_core {
        write(p.clone(), &src)?;
    }
    println!("{}", serde_json::to_string_pretty(&report)?);
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} model, H = {}: test RMSE {:.3} µm (uncompensated {:.3} µm, physics least squares {}), train {:.3} µm, {:.1} s",
        report.kind.name(),
        report.hidden,
        report.test.rmse_um,
        report.test_uncompensated.rmse_um,
        report.test_physics_baseline.as_ref().map_or("n/a".to_string(), |m| format!("{:.3} µm", m.rmse_um)),
        report.train.rmse_um,
        report.elapsed_s
    );
    if let Some(b) = &baselines {
        println!("baselines (held-out RMSE, µm): {b:?}");
    }
    println!("wrote {}/{{summary.json, model.json, model.rs, test_predictions.csv}}", args.out.display());
    if let Some(p) = &args.emit_core {
        println!("wrote {}", p.display());
    }
    Ok(report)
}

fn write_test_predictions(ds: &Dataset, report: &TrainReport, path: &std::path::Path) -> Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    w.write_record(["run_id", "direction", "time_s", "target_m", "predicted_m", "clamped"])?;
    for r in ds.runs.iter().filter(|r| report.runs.test.contains(&r.id)) {
        let t = r.target(report.kind);
        for i in 0..r.len() {
            let (y, c) = report.model.predict(&r.inputs[i]);
            w.write_record([
                r.id.clone(),
                r.direction.name().to_string(),
                format!("{}", r.time_s[i]),
                format!("{:e}", t[i]),
                format!("{:e}", y),
                format!("{}", u8::from(c)),
            ])?;
        }
    }
    w.flush()?;
    Ok(())
}

/// `summary.json` of `host-sim train`: the report plus the headline figures.
#[derive(Serialize)]
struct TrainSummary<'a> {
    /// Held-out RMSE of the chosen model.
    observer_rmse_um_heldout: f64,
    /// MAPE on terminal length without / with the observer (held-out runs).
    mape_before: Option<f64>,
    mape_after: Option<f64>,
    /// Held-out RMSE of each baseline on the same split, µm.
    baseline_rmse_um: std::collections::BTreeMap<String, f64>,
    #[serde(flatten)]
    report: &'a TrainReport,
}
