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
pub mod from_logs;
pub mod lead;
pub mod log_moves;
pub mod route;
pub mod stiffness;
pub mod bench;
pub mod ibas;
pub mod network;
pub mod optim;
pub mod physics;
pub mod synthetic;

mod cli;
mod comparisons;

pub use cli::*;
pub use comparisons::Table2Row;

use anyhow::{bail, Result};
use dataset::{Dataset, DatasetLimits, ModelKind, Samples, Split, SplitSpec, INPUT_COLUMNS};
use evaluate::Metrics;
use ibas::IbasOptions;
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
    pub input_columns: Vec<&'static str>,
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
    if let Some(r) = ds.runs.iter().find(|r| r.target(opts.kind).iter().any(|v| v.is_nan())) {
        bail!(
            "{} line {}: run '{}' has no {} (the {} model's target): give that column, or train the error model",
            r.source.display(),
            r.first_line,
            r.id,
            opts.kind.column(),
            opts.kind.name()
        );
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
        let (model, rep) = train_one(h, ds.inputs, opts, &norm, &train_batch, &val_batch, &ibas_batch, &train_all, &val_all, &pb);
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
            &INPUT_COLUMNS[..ds.inputs]
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
    let model = TrainedModel { force_source: Some(ds.force_source), ..model };
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
        input_columns: INPUT_COLUMNS[..ds.inputs].to_vec(),
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
    inputs: usize,
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
    let rbf = Rbf::with_linear(h, opts.linear_term).with_inputs(inputs);
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
    let model = TrainedModel { kind: opts.kind, rbf, params: p, norm: norm.clone(), force_source: None };
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
