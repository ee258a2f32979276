//! IBAS-BPNN error-observer trainer (paper §4.1; DESIGN.md §3 "Observer").
//!
//! [`train`] loads a dataset (or makes a synthetic one), splits it by run,
//! and for each candidate hidden size: draws random starts, searches them
//! with IBAS ([`ibas`]), refines the best by back-propagation ([`optim`]),
//! and scores it on the validation runs. The size with the best validation
//! RMSE (the smallest within `select_tolerance` of it) wins and is evaluated
//! on the held-out test runs. [`codegen`] turns the result into the
//! firmware's `src/observer/model.rs`; [`run_cli`] is `host-sim train`.

// NaN-aware `!(a < b)` tests are deliberate; index loops over the four
// inputs read better than zips of four arrays.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

pub mod codegen;
pub mod dataset;
pub mod evaluate;
pub mod ibas;
pub mod network;
pub mod optim;
pub mod physics;
pub mod synthetic;

use anyhow::{bail, Context, Result};
use dataset::{Dataset, DatasetLimits, Direction, ModelKind, Samples, Split, SplitSpec, INPUT_COLUMNS};
use evaluate::Metrics;
use ibas::{IbasOptions, StepDecay};
use indicatif::{ProgressBar, ProgressStyle};
use network::{Batch, Normaliser, Rbf, TrainedModel};
use optim::{Divergence, Method, OptimOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Where the samples come from.
#[derive(Clone, Debug, PartialEq)]
pub enum DataSource {
    /// One CSV file or a folder of CSV files.
    Csv(PathBuf),
    /// [`synthetic::paper_like`] with this many runs.
    Synthetic { runs: usize },
}

/// Everything `train` needs. [`TrainOptions::new`] gives the defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainOptions {
    pub data: DataSource,
    /// Name recorded in the report and the generated model (default: the
    /// file or folder name, or "synthetic").
    pub dataset_name: Option<String>,
    pub kind: ModelKind,
    pub split: SplitSpec,
    /// Share of the training side's runs (per direction) used for validation.
    pub validation_fraction: f64,
    /// Candidate hidden sizes; one value fixes the size.
    pub hidden: Vec<usize>,
    /// Linear skip term `Σ a_j z_j` in the output (not in the paper).
    pub linear_term: bool,
    /// The smallest candidate within this relative margin of the best
    /// validation RMSE is chosen.
    pub select_tolerance: f64,
    /// λ of the L2 term on the output weights (normalised units).
    pub lambda: f64,
    /// Training samples used by back-propagation (spread evenly over the
    /// training runs; 0 = all). Evaluation always uses every sample.
    pub max_train_samples: usize,
    pub seed: u64,
    /// `None`: no IBAS, back-propagation from the random start (baseline).
    pub ibas: Option<IbasOptions>,
    /// `None`: no back-propagation, the IBAS result is the model (baseline).
    pub optimiser: Option<OptimOptions>,
    pub limits: DatasetLimits,
    /// Progress bar on stderr (drawn only on a terminal).
    pub progress: bool,
}

impl TrainOptions {
    pub fn new(data: DataSource) -> TrainOptions {
        TrainOptions {
            data,
            dataset_name: None,
            kind: ModelKind::Error,
            split: SplitSpec::Mixed { test_fraction: 0.25 },
            validation_fraction: 0.2,
            hidden: vec![8, 16, 24, 32],
            linear_term: true,
            select_tolerance: 0.05,
            lambda: 1e-6,
            max_train_samples: 4000,
            seed: 1,
            ibas: Some(IbasOptions::default()),
            optimiser: Some(OptimOptions::default()),
            limits: DatasetLimits::default(),
            progress: false,
        }
    }

    /// One line saying how the model was trained (goes into the metadata).
    pub fn method(&self) -> String {
        let ibas = match &self.ibas {
            None => "no IBAS".to_string(),
            Some(o) => format!(
                "IBAS {} beetle(s) × {} it, d0 {}, step {}→{} {:?}{}{}",
                o.beetles,
                o.iterations,
                o.antenna_d0,
                o.step_start,
                o.step_end,
                o.decay,
                if o.keep_best { ", keep-best" } else { "" },
                if o.adaptive { ", adaptive step" } else { "" }
            ),
        };
        let bp = match &self.optimiser {
            None => "no BP".to_string(),
            Some(o) => match o.method {
                Method::Gd => format!("GD η {} × {} epochs", o.learning_rate, o.epochs),
                Method::Adam => format!("Adam α {} × {} epochs", o.learning_rate, o.epochs),
                Method::Lbfgs => format!("L-BFGS m {} × {} it", o.lbfgs_memory, o.epochs),
            },
        };
        let net = if self.linear_term { "RBF + linear term" } else { "RBF" };
        format!("{net}; {ibas}; {bp}; λ {:e}", self.lambda)
    }
}

/// One hidden size tried.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateReport {
    pub hidden: usize,
    /// Training loss (normalised MSE + λ L2) of the random start (beetle 0's).
    pub init_loss: f64,
    /// Best loss IBAS reached on its fitness samples, and its start's loss there.
    pub ibas_start_loss: Option<f64>,
    pub ibas_loss: Option<f64>,
    pub ibas_evaluations: usize,
    pub bp_train_loss: Option<f64>,
    pub bp_epochs: usize,
    pub stop_reason: String,
    pub diverged: Option<Divergence>,
    pub train_rmse_m: f64,
    pub validation_rmse_m: Option<f64>,
    pub elapsed_s: f64,
}

/// Run ids of each side.
#[derive(Clone, Debug, Serialize)]
pub struct RunLists {
    pub train: Vec<String>,
    pub validation: Vec<String>,
    pub test: Vec<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct SampleCounts {
    pub train_total: usize,
    pub train_used: usize,
    pub ibas_used: usize,
    pub validation: usize,
    pub test: usize,
}

/// What `train` did and how well the chosen model does.
#[derive(Clone, Debug, Serialize)]
pub struct TrainReport {
    pub dataset: String,
    pub dataset_path: String,
    pub kind: ModelKind,
    pub split: String,
    pub seed: u64,
    pub method: String,
    pub runs: RunLists,
    pub samples: SampleCounts,
    pub input_columns: [&'static str; 4],
    pub hidden: usize,
    pub candidates: Vec<CandidateReport>,
    pub train: Metrics,
    pub validation: Option<Metrics>,
    /// Held-out runs, with the model ("after compensation")…
    pub test: Metrics,
    /// …and without it ("before compensation": the whole terminal error).
    pub test_uncompensated: Metrics,
    /// Baseline: least squares on the textbook deformation/friction terms
    /// ([`physics`]), fitted on the same training samples.
    pub test_physics_baseline: Option<Metrics>,
    pub physics_fit: Option<physics::PhysicsFit>,
    /// Set when back-propagation of the chosen size blew up (its last good
    /// weights were kept).
    pub diverged: Option<Divergence>,
    pub warnings: Vec<String>,
    pub elapsed_s: f64,
    #[serde(skip)]
    pub model: TrainedModel,
}

impl TrainReport {
    /// Metadata for [`codegen::generate`].
    pub fn codegen_meta(&self, command: &str) -> codegen::CodegenMeta {
        codegen::CodegenMeta {
            dataset: self.dataset.clone(),
            split: self.split.clone(),
            seed: self.seed,
            test_rmse_m: self.test.rmse_m,
            test_mse_m2: self.test.mse_m2,
            test_mape_pct: self.test.mape_pct,
            train_rmse_m: self.train.rmse_m,
            method: self.method.clone(),
            command: command.to_string(),
        }
    }
}

/// Loads `opts.data` and trains on it.
pub fn train(opts: &TrainOptions) -> Result<TrainReport> {
    train_dataset(&load_data(opts)?, opts)
}

/// The dataset `opts.data` names, validated.
pub fn load_data(opts: &TrainOptions) -> Result<Dataset> {
    Ok(match &opts.data {
        DataSource::Csv(p) => Dataset::load(p, &opts.limits)?,
        DataSource::Synthetic { runs } => {
            synthetic::paper_like(opts.dataset_name.as_deref().unwrap_or("synthetic"), *runs)
        }
    })
}

/// Trains on a loaded dataset.
pub fn train_dataset(ds: &Dataset, opts: &TrainOptions) -> Result<TrainReport> {
    let t0 = Instant::now();
    if opts.hidden.is_empty() || opts.hidden.contains(&0) {
        bail!("hidden sizes must be positive (got {:?})", opts.hidden);
    }
    if opts.ibas.is_none() && opts.optimiser.is_none() {
        bail!("neither IBAS nor back-propagation is enabled: nothing would be trained");
    }
    if !(opts.lambda >= 0.0) {
        bail!("λ must be ≥ 0 (got {})", opts.lambda);
    }
    let mut warnings = Vec::new();
    let split: Split = dataset::split(ds, &opts.split, opts.validation_fraction, opts.seed)?;
    if split.train.is_empty() {
        bail!("{}: no training run left after the split", ds.path.display());
    }
    if split.validation.is_empty() {
        warnings.push("no validation run (the training side has one run per direction): hidden size and kept epoch chosen on training loss".into());
    }
    let kind = opts.kind;
    let train_all = Samples::gather(ds, &split.train, kind, 1);
    let train_used = Samples::gather_at_most(ds, &split.train, kind, opts.max_train_samples);
    let val_all = Samples::gather(ds, &split.validation, kind, 1);
    let val_used = Samples::gather_at_most(ds, &split.validation, kind, opts.max_train_samples / 2);
    let test_all = Samples::gather(ds, &split.test, kind, 1);
    let ibas_max = opts.ibas.as_ref().map_or(0, |o| o.max_samples);
    let ibas_used = Samples::gather_at_most(ds, &split.train, kind, ibas_max);

    let norm = Normaliser::fit(&train_all.inputs, &train_all.target);
    let train_batch = Batch::new(&norm, &train_used.inputs, &train_used.target);
    let val_batch = Batch::new(&norm, &val_used.inputs, &val_used.target);
    let ibas_batch = Batch::new(&norm, &ibas_used.inputs, &ibas_used.target);

    let per_candidate = opts.ibas.as_ref().map_or(0, |o| o.beetles.max(1) * o.iterations)
        + opts.optimiser.as_ref().map_or(0, |o| o.epochs);
    let pb = if opts.progress {
        let pb = ProgressBar::new((per_candidate * opts.hidden.len()) as u64);
        if let Ok(style) = ProgressStyle::with_template("{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} {msg}") {
            pb.set_style(style);
        }
        pb.set_prefix("train");
        pb
    } else {
        ProgressBar::hidden()
    };

    let mut candidates = Vec::new();
    let mut models = Vec::new();
    for &h in &opts.hidden {
        pb.set_message(format!("H = {h}"));
        let (model, rep) = train_one(h, opts, &norm, &train_batch, &val_batch, &ibas_batch, &train_all, &val_all, &pb);
        candidates.push(rep);
        models.push(model);
    }
    pb.finish_and_clear();

    let score = |c: &CandidateReport| c.validation_rmse_m.unwrap_or(c.train_rmse_m);
    let best = candidates.iter().map(score).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        bail!("every candidate ended with a non-finite error: training failed (see the stop reasons: {:?})", candidates.iter().map(|c| &c.stop_reason).collect::<Vec<_>>());
    }
    let mut chosen = 0;
    let mut chosen_h = usize::MAX;
    for (i, c) in candidates.iter().enumerate() {
        if score(c) <= best * (1.0 + opts.select_tolerance) && c.hidden < chosen_h {
            chosen = i;
            chosen_h = c.hidden;
        }
    }
    let model = models.swap_remove(chosen);
    let diverged = candidates[chosen].diverged.clone();
    if let Some(d) = &diverged {
        warnings.push(format!("back-propagation diverged at epoch {} ({}); the last good weights were kept", d.epoch, d.reason));
    }
    let train_m = evaluate::evaluate(&model, &train_all);
    let val_m = (!val_all.is_empty()).then(|| evaluate::evaluate(&model, &val_all));
    let test_m = evaluate::evaluate(&model, &test_all);
    if test_m.out_of_range_samples > 0 {
        warnings.push(format!(
            "{} of {} test samples ({:.1} %) have inputs outside the trained range (clamped, as in the firmware): below {:?}, above {:?} per input {:?}",
            test_m.out_of_range_samples,
            test_m.samples,
            100.0 * test_m.out_of_range_fraction,
            test_m.below_range_per_input,
            test_m.above_range_per_input,
            INPUT_COLUMNS
        ));
    }
    let physics_fit = match physics::PhysicsFit::fit(&train_used) {
        Ok(f) => Some(f),
        Err(e) => {
            warnings.push(format!("{e:#}"));
            None
        }
    };
    let test_physics_baseline = physics_fit.as_ref().map(|f| evaluate::from_residuals(&f.residuals(&test_all), &test_all.length_m));
    let ids = |v: &[usize]| v.iter().map(|&i| ds.runs[i].id.clone()).collect::<Vec<_>>();
    Ok(TrainReport {
        dataset: opts.dataset_name.clone().unwrap_or_else(|| ds.name.clone()),
        dataset_path: ds.path.display().to_string(),
        kind,
        split: opts.split.describe(),
        seed: opts.seed,
        method: opts.method(),
        runs: RunLists { train: ids(&split.train), validation: ids(&split.validation), test: ids(&split.test) },
        samples: SampleCounts {
            train_total: train_all.len(),
            train_used: train_used.len(),
            ibas_used: if opts.ibas.is_some() { ibas_used.len() } else { 0 },
            validation: val_all.len(),
            test: test_all.len(),
        },
        input_columns: INPUT_COLUMNS,
        hidden: model.hidden(),
        candidates,
        train: train_m,
        validation: val_m,
        test_uncompensated: evaluate::uncompensated(&test_all),
        test_physics_baseline,
        physics_fit,
        test: test_m,
        diverged,
        warnings,
        elapsed_s: t0.elapsed().as_secs_f64(),
        model,
    })
}

#[allow(clippy::too_many_arguments)]
fn train_one(
    h: usize,
    opts: &TrainOptions,
    norm: &Normaliser,
    train: &Batch,
    val: &Batch,
    ibas_batch: &Batch,
    train_all: &Samples,
    val_all: &Samples,
    pb: &ProgressBar,
) -> (TrainedModel, CandidateReport) {
    let t0 = Instant::now();
    let rbf = Rbf::with_linear(h, opts.linear_term);
    // Each size has its own stream: results do not depend on which other sizes are tried.
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    rng.set_stream(1000 + h as u64);
    let n_starts = opts.ibas.as_ref().map_or(1, |o| o.beetles.max(1));
    let starts: Vec<Vec<f64>> = (0..n_starts).map(|_| rbf.init_random(&mut rng)).collect();
    let init_loss = rbf.loss(&starts[0], train, opts.lambda);
    let (mut p, mut ibas_start_loss, mut ibas_loss, mut ibas_evals) = (starts[0].clone(), None, None, 0);
    if let Some(io) = &opts.ibas {
        let out = ibas::search(starts, |x| rbf.loss(x, ibas_batch, opts.lambda), io, &mut rng, pb);
        p = out.x;
        ibas_start_loss = Some(out.start_f);
        ibas_loss = Some(out.f);
        ibas_evals = out.evaluations;
    }
    let (mut bp_loss, mut epochs, mut stop, mut diverged) = (None, 0, "no back-propagation".to_string(), None);
    if let Some(oo) = &opts.optimiser {
        let mut val_fn = |q: &[f64]| rbf.loss(q, val, 0.0);
        let val_opt: Option<optim::Validation<'_>> = if val.is_empty() { None } else { Some(&mut val_fn) };
        let out = optim::minimise(p, |q, g| rbf.loss_grad(q, train, opts.lambda, g), val_opt, oo, pb);
        p = out.params;
        bp_loss = Some(out.train_loss);
        epochs = out.epochs;
        stop = out.stop_reason;
        diverged = out.diverged;
    }
    let model = TrainedModel { kind: opts.kind, rbf, params: p, norm: norm.clone() };
    let train_rmse_m = evaluate::evaluate(&model, train_all).rmse_m;
    let validation_rmse_m = (!val_all.is_empty()).then(|| evaluate::evaluate(&model, val_all).rmse_m);
    let rep = CandidateReport {
        hidden: h,
        init_loss,
        ibas_start_loss,
        ibas_loss,
        ibas_evaluations: ibas_evals,
        bp_train_loss: bp_loss,
        bp_epochs: epochs,
        stop_reason: stop,
        diverged,
        train_rmse_m,
        validation_rmse_m,
        elapsed_s: t0.elapsed().as_secs_f64(),
    };
    (model, rep)
}

// ───────────────────────────── command line ─────────────────────────────

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

/// The baselines of issue 3 on the chosen model's split and size.
fn baselines(ds: &Dataset, opts: &TrainOptions, chosen: &TrainReport) -> Result<std::collections::BTreeMap<String, f64>> {
    let mut out = std::collections::BTreeMap::new();
    let mut base = opts.clone();
    base.hidden = vec![chosen.hidden];
    base.progress = false;
    let mut bp_random = base.clone();
    bp_random.ibas = None;
    if bp_random.optimiser.is_some() {
        out.insert("bp_random_init".to_string(), train_dataset(ds, &bp_random)?.test.rmse_um);
    }
    let mut ibas_only = base.clone();
    ibas_only.optimiser = None;
    if ibas_only.ibas.is_some() {
        out.insert("ibas_only".to_string(), train_dataset(ds, &ibas_only)?.test.rmse_um);
    }
    if let Some(m) = &chosen.test_physics_baseline {
        out.insert("physics_least_squares".to_string(), m.rmse_um);
    }
    Ok(out)
}

/// One row of the paper's Table 2 as this dataset gives it.
#[derive(Clone, Debug, Serialize)]
pub struct Table2Row {
    pub dataset_and_model: String,
    /// Held-out, before compensation (the whole error) and after (residual).
    pub mse_mm2_before: f64,
    pub rmse_mm_before: f64,
    pub mape_before: f64,
    pub mse_mm2_after: f64,
    pub rmse_mm_after: f64,
    pub mape_after: f64,
}

/// {opposite (both ways), mixed} × {length, error}. Opposite rows average
/// the two directions (train on elongation → test contraction, and back).
fn table2(ds: &Dataset, opts: &TrainOptions) -> Result<Vec<Table2Row>> {
    let mut rows = Vec::new();
    for kind in [ModelKind::Length, ModelKind::Error] {
        for split_name in ["opposite", "mixed"] {
            let splits: Vec<SplitSpec> = match split_name {
                "opposite" => vec![
                    SplitSpec::Opposite { train: Direction::Elongation },
                    SplitSpec::Opposite { train: Direction::Contraction },
                ],
                _ => vec![opts.split.clone()],
            };
            let mut acc = [0.0f64; 6];
            for split in &splits {
                let mut o = opts.clone();
                o.kind = kind;
                o.split = split.clone();
                o.progress = false;
                let r = train_dataset(ds, &o)?;
                let (b, a) = (&r.test_uncompensated, &r.test);
                for (slot, v) in acc.iter_mut().zip([
                    b.mse_m2 * 1e6,
                    b.rmse_m * 1e3,
                    b.mape_pct.unwrap_or(f64::NAN),
                    a.mse_m2 * 1e6,
                    a.rmse_m * 1e3,
                    a.mape_pct.unwrap_or(f64::NAN),
                ]) {
                    *slot += v / splits.len() as f64;
                }
            }
            rows.push(Table2Row {
                dataset_and_model: format!("{split_name} data, {} model", kind.name()),
                mse_mm2_before: acc[0],
                rmse_mm_before: acc[1],
                mape_before: acc[2],
                mse_mm2_after: acc[3],
                rmse_mm_after: acc[4],
                mape_after: acc[5],
            });
        }
    }
    Ok(rows)
}

fn table2_markdown(rows: &[Table2Row]) -> String {
    let mut s = String::from(
        "| dataset and observation model | MSE before (mm²) | RMSE before (mm) | MAPE before (%) | MSE after (mm²) | RMSE after (mm) | MAPE after (%) |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.4e} | {:.5} | {:.5} | {:.4e} | {:.5} | {:.5} |\n",
            r.dataset_and_model, r.mse_mm2_before, r.rmse_mm_before, r.mape_before, r.mse_mm2_after, r.rmse_mm_after, r.mape_after
        );
    }
    s
}
