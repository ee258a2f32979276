//! Observer datasets: CSV loading with validation, and splits by run.
//!
//! One CSV file with a `run_id` column, or a folder of CSV files (each may hold
//! one or more runs). Header names are exact. Required: the run, its
//! direction, the time, the network's inputs and its target:
//!
//! `run_id,direction,time_s,motor_speed_rad_s,nut_speed_m_s,
//! nut_displacement_m,load_force_n,terminal_error_m`
//!
//! The force column's name says which force the drive's observer read
//! while the data were logged, and so which force input the weights may
//! run on: `load_force_n` for the load cell, `load_force_estimate_n` for
//! the drive's current-based estimate (never both; every file alike).
//!
//! Optional: `travel_direction` (the fifth input: the sign of the last
//! nonzero planned velocity, −1 … 1; every file alike: with it the network
//! has five inputs, without it the paper's four), `terminal_length_m` and
//! `motor_side_position_m` (the length
//! model's target; without `terminal_error_m` the error is their
//! difference), `tilt_swing_deg` and `payload_scale` (the simulator's
//! labels, reported only). `host-sim dataset-from-logs` writes such a file
//! from the drive's own logs.
//!
//! Extra columns are ignored; a missing one, an empty or non-finite value, an
//! unknown direction, a run that changes direction or appears in two files, or
//! a run with too few samples is refused with the file, the line and the field.

use anyhow::{anyhow, bail, Context, Result};
pub use servo_core::observer::block::ForceSource;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// ChaCha stream of the split's shuffles (other streams: initialisation).
pub const STREAM_SPLIT: u64 = 1;

/// Input slots of the network (the firmware's): the paper's four state
/// variables and the direction of travel. A dataset, and the network
/// trained on it, uses the first [`STATIC_INPUTS`] or all of them.
pub const N_INPUTS: usize = servo_core::observer::NETWORK_INPUTS;

/// The paper's four inputs: a dataset without the fifth column.
pub const STATIC_INPUTS: usize = servo_core::observer::STATIC_INPUTS;

/// The input columns, in the order the network (and the firmware) takes them.
pub const INPUT_COLUMNS: [&str; N_INPUTS] = servo_core::observer::NETWORK_INPUT_NAMES;

/// The fifth input's column.
pub const TRAVEL_COLUMN: &str = "travel_direction";

/// The columns a dataset file must have (the target, `terminal_error_m`,
/// may instead come from `terminal_length_m − motor_side_position_m`).
pub const REQUIRED_COLUMNS: [&str; 7] =
    ["run_id", "direction", "time_s", "motor_speed_rad_s", "nut_speed_m_s", "nut_displacement_m", "load_force_n"];

/// The force column's name for data logged with the observer on `source`
/// (it stands in for `load_force_n` in [`REQUIRED_COLUMNS`]).
pub fn force_column(source: ForceSource) -> &'static str {
    match source {
        ForceSource::LoadCell => "load_force_n",
        ForceSource::Estimate => "load_force_estimate_n",
    }
}

/// Every column the trainer reads, and writes (NaN where a label is unknown).
pub const ALL_COLUMNS: [&str; 12] = [
    "run_id",
    "direction",
    "tilt_swing_deg",
    "payload_scale",
    "time_s",
    "motor_speed_rad_s",
    "nut_speed_m_s",
    "nut_displacement_m",
    "load_force_n",
    "terminal_length_m",
    "motor_side_position_m",
    "terminal_error_m",
];

/// Direction of motion of a run (paper §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Direction {
    Elongation,
    Contraction,
}

impl Direction {
    pub fn name(self) -> &'static str {
        match self {
            Direction::Elongation => "Elongation",
            Direction::Contraction => "Contraction",
        }
    }
    pub fn opposite(self) -> Direction {
        match self {
            Direction::Elongation => Direction::Contraction,
            Direction::Contraction => Direction::Elongation,
        }
    }
    fn parse(s: &str) -> Option<Direction> {
        if s.eq_ignore_ascii_case("elongation") {
            Some(Direction::Elongation)
        } else if s.eq_ignore_ascii_case("contraction") {
            Some(Direction::Contraction)
        } else {
            None
        }
    }
}

/// What the network is trained to predict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ModelKind {
    /// `terminal_error_m` (the paper's "error model").
    Error,
    /// `terminal_length_m` (the paper's "length model").
    Length,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Error => "error",
            ModelKind::Length => "length",
        }
    }
    pub fn column(self) -> &'static str {
        match self {
            ModelKind::Error => "terminal_error_m",
            ModelKind::Length => "terminal_length_m",
        }
    }
}

/// One run: consecutive samples of one stroke in one direction.
#[derive(Clone, Debug)]
pub struct Run {
    pub id: String,
    pub direction: Direction,
    /// NaN when the file does not say (labels of simulated runs).
    pub tilt_swing_deg: f64,
    pub payload_scale: f64,
    /// File the run came from and the line of its first sample (1-based,
    /// the header being line 1).
    pub source: PathBuf,
    pub first_line: u64,
    pub time_s: Vec<f64>,
    /// Inputs in [`INPUT_COLUMNS`] order (an unused slot holds 0).
    pub inputs: Vec<[f64; N_INPUTS]>,
    /// NaN when the file has neither the length nor the motor side.
    pub terminal_length_m: Vec<f64>,
    pub motor_side_position_m: Vec<f64>,
    pub terminal_error_m: Vec<f64>,
}

impl Run {
    pub fn len(&self) -> usize {
        self.inputs.len()
    }
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }
    /// The training target of `kind`.
    pub fn target(&self, kind: ModelKind) -> &[f64] {
        match kind {
            ModelKind::Error => &self.terminal_error_m,
            ModelKind::Length => &self.terminal_length_m,
        }
    }
}

/// A loaded, validated dataset.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// File or folder name (goes into the generated model's metadata).
    pub name: String,
    pub path: PathBuf,
    /// Runs sorted by id.
    pub runs: Vec<Run>,
    /// The force the observer read while the data were logged.
    pub force_source: ForceSource,
    /// Inputs the data carry: 4, or 5 with the direction of travel.
    pub inputs: usize,
}

/// Limits a dataset must meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DatasetLimits {
    /// A run with fewer samples is refused.
    pub min_samples_per_run: usize,
}

impl Default for DatasetLimits {
    fn default() -> Self {
        DatasetLimits { min_samples_per_run: 20 }
    }
}

impl Dataset {
    /// Loads one CSV file or every `*.csv` file of a folder (in name order).
    pub fn load(path: &Path, limits: &DatasetLimits) -> Result<Dataset> {
        let files: Vec<PathBuf> = if path.is_dir() {
            let mut v: Vec<PathBuf> = std::fs::read_dir(path)
                .with_context(|| format!("reading dataset folder {}", path.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file() && p.extension().is_some_and(|x| x.eq_ignore_ascii_case("csv")))
                .collect();
            v.sort();
            if v.is_empty() {
                bail!("dataset folder {} holds no .csv file", path.display());
            }
            v
        } else if path.is_file() {
            vec![path.to_path_buf()]
        } else {
            bail!("dataset {} does not exist", path.display());
        };
        let mut runs: BTreeMap<String, Run> = BTreeMap::new();
        let mut force: Option<(ForceSource, &PathBuf)> = None;
        let mut inputs: Option<(usize, &PathBuf)> = None;
        for f in &files {
            let (source, n) = read_file(f, &mut runs)?;
            match inputs {
                Some((m, first)) if m != n => bail!(
                    "{} line 1: {} '{TRAVEL_COLUMN}' column, but {} {}: every file of a dataset has the same inputs",
                    f.display(),
                    if n == N_INPUTS { "a" } else { "no" },
                    first.display(),
                    if m == N_INPUTS { "has one" } else { "has none" }
                ),
                Some(_) => {}
                None => inputs = Some((n, f)),
            }
            match force {
                Some((s, first)) if s != source => bail!(
                    "{} line 1: force column '{}', but {} has '{}': data logged on the load cell and on the estimate train different weights",
                    f.display(),
                    force_column(source),
                    first.display(),
                    force_column(s)
                ),
                Some(_) => {}
                None => force = Some((source, f)),
            }
        }
        let force_source = force.map_or(ForceSource::LoadCell, |(s, _)| s);
        let runs: Vec<Run> = runs.into_values().collect();
        if runs.is_empty() {
            bail!("dataset {} holds no sample", path.display());
        }
        for r in &runs {
            if r.len() < limits.min_samples_per_run {
                bail!(
                    "{} line {}: run '{}' has {} samples; at least {} are needed",
                    r.source.display(),
                    r.first_line,
                    r.id,
                    r.len(),
                    limits.min_samples_per_run
                );
            }
        }
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string());
        let inputs = inputs.map_or(STATIC_INPUTS, |(n, _)| n);
        Ok(Dataset { name, path: path.to_path_buf(), runs, force_source, inputs })
    }

    /// Builds a dataset from runs made in memory (synthetic data, tests),
    /// their force read from the load cell (see [`Dataset::with_force_source`])
    /// and the paper's four inputs (see [`Dataset::with_inputs`]).
    pub fn from_runs(name: &str, mut runs: Vec<Run>) -> Dataset {
        runs.sort_by(|a, b| a.id.cmp(&b.id));
        Dataset { name: name.to_string(), path: PathBuf::from(name), runs, force_source: ForceSource::LoadCell, inputs: STATIC_INPUTS }
    }

    /// The same runs, with their first `inputs` input slots used (4 or 5).
    pub fn with_inputs(self, inputs: usize) -> Dataset {
        Dataset { inputs: inputs.clamp(STATIC_INPUTS, N_INPUTS), ..self }
    }

    /// The same runs, logged with the observer reading `source`.
    pub fn with_force_source(self, source: ForceSource) -> Dataset {
        Dataset { force_source: source, ..self }
    }

    /// Writes the dataset as one CSV file in the format [`Dataset::load`] reads.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        // Unknown optional values are left empty.
        let label = |v: f64| if v.is_nan() { String::new() } else { format!("{v:e}") };
        let mut w = csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
        let mut header: Vec<&str> = ALL_COLUMNS.map(|c| if c == "load_force_n" { force_column(self.force_source) } else { c }).to_vec();
        let travel = self.inputs == N_INPUTS;
        if travel {
            header.push(TRAVEL_COLUMN);
        }
        w.write_record(&header)?;
        for r in &self.runs {
            for i in 0..r.len() {
                let x = r.inputs[i];
                let mut row = vec![
                    r.id.clone(),
                    r.direction.name().to_string(),
                    label(r.tilt_swing_deg),
                    label(r.payload_scale),
                    format!("{}", r.time_s[i]),
                    format!("{:e}", x[0]),
                    format!("{:e}", x[1]),
                    format!("{:e}", x[2]),
                    format!("{:e}", x[3]),
                    label(r.terminal_length_m[i]),
                    label(r.motor_side_position_m[i]),
                    format!("{:e}", r.terminal_error_m[i]),
                ];
                if travel {
                    row.push(format!("{}", x[4]));
                }
                w.write_record(&row)?;
            }
        }
        w.flush().with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }

    pub fn n_samples(&self) -> usize {
        self.runs.iter().map(Run::len).sum()
    }
}

/// Reads one file's runs into `runs`; the force source its force column
/// names, and the inputs it carries (5 with a `travel_direction` column).
fn read_file(path: &Path, runs: &mut BTreeMap<String, Run>) -> Result<(ForceSource, usize)> {
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("opening {}", path.display()))?;
    let header = rdr.headers().with_context(|| format!("{} line 1: reading the header", path.display()))?.clone();
    let find = |name: &str| header.iter().position(|h| h == name);
    let missing = |name: &str| {
        anyhow!("{} line 1: missing column '{}' (header is: {})", path.display(), name, header.iter().collect::<Vec<_>>().join(","))
    };
    let source = match (find(force_column(ForceSource::LoadCell)), find(force_column(ForceSource::Estimate))) {
        (Some(_), Some(_)) => bail!(
            "{} line 1: both 'load_force_n' (load cell) and 'load_force_estimate_n' (the drive's estimate): keep the one the observer read while logging",
            path.display()
        ),
        (None, Some(_)) => ForceSource::Estimate,
        _ => ForceSource::LoadCell,
    };
    let mut col = [0usize; REQUIRED_COLUMNS.len()];
    for (slot, name) in col.iter_mut().zip(REQUIRED_COLUMNS) {
        let name = if name == "load_force_n" { force_column(source) } else { name };
        *slot = find(name).ok_or_else(|| missing(name))?;
    }
    let [c_run, c_dir, c_time, c_w, c_v, c_x, c_f] = col;
    let (c_tilt, c_pay) = (find("tilt_swing_deg"), find("payload_scale"));
    let c_travel = find(TRAVEL_COLUMN);
    let (c_len, c_motor, c_err) = (find("terminal_length_m"), find("motor_side_position_m"), find("terminal_error_m"));
    if c_err.is_none() && (c_len.is_none() || c_motor.is_none()) {
        return Err(missing("terminal_error_m")
            .context("the target: terminal_error_m, or terminal_length_m and motor_side_position_m to take it from"));
    }
    let mut rec = csv::StringRecord::new();
    let mut data_row = 0u64;
    loop {
        let more = rdr.read_record(&mut rec).with_context(|| format!("{}: reading data row {}", path.display(), data_row + 1))?;
        if !more {
            break;
        }
        data_row += 1;
        let line = rec.position().map(|p| p.line()).unwrap_or(data_row + 1);
        let at = || format!("{} line {} (data row {})", path.display(), line, data_row);
        let field = |c: usize| -> Result<&str> {
            let s = rec.get(c).unwrap_or("");
            if s.is_empty() {
                bail!("{}: field '{}' is empty", at(), header.get(c).unwrap_or("?"));
            }
            Ok(s)
        };
        let num = |c: usize| -> Result<f64> {
            let s = field(c)?;
            let v: f64 = s.parse().map_err(|_| anyhow!("{}: field '{}' = '{}' is not a number", at(), header.get(c).unwrap_or("?"), s))?;
            if !v.is_finite() {
                bail!("{}: field '{}' = '{}' is not finite", at(), header.get(c).unwrap_or("?"), s);
            }
            Ok(v)
        };
        // An optional column may leave a row's value empty (unknown).
        let opt = |c: Option<usize>| -> Result<f64> {
            match c {
                Some(c) if !rec.get(c).unwrap_or("").is_empty() => num(c),
                _ => Ok(f64::NAN),
            }
        };
        let id = field(c_run)?.to_string();
        let dir_s = field(c_dir)?;
        let direction = Direction::parse(dir_s)
            .ok_or_else(|| anyhow!("{}: direction '{}' is neither Elongation nor Contraction", at(), dir_s))?;
        let (tilt, pay, t) = (opt(c_tilt)?, opt(c_pay)?, num(c_time)?);
        let travel = match c_travel {
            Some(c) => {
                let d = num(c)?;
                if !(-1.0..=1.0).contains(&d) {
                    bail!("{}: field '{TRAVEL_COLUMN}' = {d} is outside [-1, 1] (the sign of the planned velocity)", at());
                }
                d
            }
            None => 0.0,
        };
        let x = [num(c_w)?, num(c_v)?, num(c_x)?, num(c_f)?, travel];
        let (len, motor) = (opt(c_len)?, opt(c_motor)?);
        let err = match c_err {
            Some(c) => num(c)?,
            None if len.is_nan() || motor.is_nan() => {
                bail!("{}: terminal_length_m or motor_side_position_m is empty and there is no terminal_error_m", at())
            }
            None => len - motor,
        };
        let len = if len.is_nan() { motor + err } else { len };
        let run = runs.entry(id.clone()).or_insert_with(|| Run {
            id: id.clone(),
            direction,
            tilt_swing_deg: tilt,
            payload_scale: pay,
            source: path.to_path_buf(),
            first_line: line,
            time_s: Vec::new(),
            inputs: Vec::new(),
            terminal_length_m: Vec::new(),
            motor_side_position_m: Vec::new(),
            terminal_error_m: Vec::new(),
        });
        if run.source != path {
            bail!("{}: run '{}' already appeared in {} (a run must be in one file)", at(), id, run.source.display());
        }
        if run.direction != direction {
            bail!("{}: run '{}' changes direction from {} to {}", at(), id, run.direction.name(), direction.name());
        }
        run.time_s.push(t);
        run.inputs.push(x);
        run.terminal_length_m.push(len);
        run.motor_side_position_m.push(motor);
        run.terminal_error_m.push(err);
    }
    if data_row == 0 {
        bail!("{}: no data row after the header", path.display());
    }
    Ok((source, if c_travel.is_some() { N_INPUTS } else { STATIC_INPUTS }))
}

/// How runs are split into training, validation and held-out test runs.
/// Never by sample: every run goes whole to one side.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum SplitSpec {
    /// Paper's "opposite" data: train (and validate) on runs of `train`,
    /// test on every run of the other direction.
    Opposite { train: Direction },
    /// Paper's "mixed" data: both directions; `test_fraction` of each
    /// direction's runs (at least one) are held out for the test.
    Mixed { test_fraction: f64 },
}

impl SplitSpec {
    pub fn describe(&self) -> String {
        match self {
            SplitSpec::Opposite { train } => format!("opposite: train {}, test {}", train.name(), train.opposite().name()),
            SplitSpec::Mixed { test_fraction } => format!("mixed: {:.0} % of each direction's runs held out", test_fraction * 100.0),
        }
    }
}

/// Run indices (into [`Dataset::runs`]) of each side of a split.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Split {
    pub train: Vec<usize>,
    /// Used to choose the hidden size and the epoch to keep; empty when the
    /// training side has a single run.
    pub validation: Vec<usize>,
    pub test: Vec<usize>,
}

/// Splits `ds` by run. `validation_fraction` of the training side's runs of
/// each direction (at least one when that direction has two or more) go to
/// validation. Deterministic for `seed`.
pub fn split(ds: &Dataset, spec: &SplitSpec, validation_fraction: f64, seed: u64) -> Result<Split> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(STREAM_SPLIT);
    let of = |d: Direction| -> Vec<usize> { (0..ds.runs.len()).filter(|&i| ds.runs[i].direction == d).collect() };
    let mut out = Split::default();
    let mut train_pool: Vec<Vec<usize>> = Vec::new();
    match *spec {
        SplitSpec::Opposite { train } => {
            let (tr, te) = (of(train), of(train.opposite()));
            if tr.is_empty() || te.is_empty() {
                bail!(
                    "{}: the opposite split needs runs of both directions; it has {} {} and {} {} runs",
                    ds.path.display(),
                    tr.len(),
                    train.name(),
                    te.len(),
                    train.opposite().name()
                );
            }
            out.test = te;
            train_pool.push(tr);
        }
        SplitSpec::Mixed { test_fraction } => {
            if !(0.0..1.0).contains(&test_fraction) {
                bail!("mixed split: test fraction {test_fraction} is not in [0, 1)");
            }
            for d in [Direction::Elongation, Direction::Contraction] {
                let mut runs = of(d);
                if runs.is_empty() {
                    continue;
                }
                if runs.len() < 2 {
                    bail!(
                        "{}: the mixed split holds out whole runs of each direction; {} has only one run ('{}')",
                        ds.path.display(),
                        d.name(),
                        ds.runs[runs[0]].id
                    );
                }
                runs.shuffle(&mut rng);
                let n_test = ((test_fraction * runs.len() as f64).round() as usize).clamp(1, runs.len() - 1);
                out.test.extend(runs.drain(..n_test));
                train_pool.push(runs);
            }
            if out.test.is_empty() {
                bail!("{}: no run to split", ds.path.display());
            }
        }
    }
    for mut runs in train_pool {
        runs.shuffle(&mut rng);
        let n_val = if runs.len() >= 2 {
            ((validation_fraction * runs.len() as f64).round() as usize).clamp(usize::from(validation_fraction > 0.0), runs.len() - 1)
        } else {
            0
        };
        out.validation.extend(runs.drain(..n_val));
        out.train.extend(runs);
    }
    out.train.sort_unstable();
    out.validation.sort_unstable();
    out.test.sort_unstable();
    Ok(out)
}

/// Samples of a set of runs, flattened: inputs and targets (metres).
#[derive(Clone, Debug, Default)]
pub struct Samples {
    pub inputs: Vec<[f64; N_INPUTS]>,
    pub target: Vec<f64>,
    /// True terminal length of each sample (for MAPE).
    pub length_m: Vec<f64>,
    /// The error column (for the "before compensation" figures).
    pub error_m: Vec<f64>,
}

impl Samples {
    /// Every sample of `runs` (`stride` 1) or every `stride`-th one.
    pub fn gather(ds: &Dataset, runs: &[usize], kind: ModelKind, stride: usize) -> Samples {
        let stride = stride.max(1);
        let mut s = Samples::default();
        for &ri in runs {
            let r = &ds.runs[ri];
            let t = r.target(kind);
            for i in (0..r.len()).step_by(stride) {
                // Slots the dataset does not use carry nothing.
                let mut x = r.inputs[i];
                for v in x.iter_mut().skip(ds.inputs) {
                    *v = 0.0;
                }
                s.inputs.push(x);
                s.target.push(t[i]);
                s.length_m.push(r.terminal_length_m[i]);
                s.error_m.push(r.terminal_error_m[i]);
            }
        }
        s
    }

    /// At most `max` samples spread evenly over the runs (a common stride).
    pub fn gather_at_most(ds: &Dataset, runs: &[usize], kind: ModelKind, max: usize) -> Samples {
        let total: usize = runs.iter().map(|&i| ds.runs[i].len()).sum();
        let stride = if max == 0 { 1 } else { total.div_ceil(max) };
        Samples::gather(ds, runs, kind, stride)
    }

    pub fn len(&self) -> usize {
        self.inputs.len()
    }
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }
}
