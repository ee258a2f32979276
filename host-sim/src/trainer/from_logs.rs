//! From the drive's own logs to the trainer's dataset: telemetry recorded by
//! the host tool (`drive telemetry --csv`), or a CSV from the user's logger
//! with the same columns, turned into runs the trainer reads.
//!
//! What a log needs (by column name; the telemetry CSV has them all):
//! - `time_s`;
//! - `motor_position_m` (or `motor_side_position_m`): the encoder's position
//!   on the rod's scale;
//! - `speed_rad_s` (or `motor_speed_rad_s`): the motor speed;
//! - `terminal_position_m`: the linear scale at the rod (the target comes
//!   from it: terminal error = terminal − motor side);
//! - for the fifth input, the direction of travel: `travel_direction`
//!   (the sign of the last nonzero planned velocity), or
//!   `position_reference_m` (the planned position, in the telemetry) from
//!   which it is taken, the sign of each change held while the plan rests.
//!   Without either the dataset has the paper's four inputs;
//!   `--static-inputs` asks for those alone;
//! - `load_force_n` (a load cell) or `load_force_estimate_n` (the drive's
//!   telemetry: the observer's force input, the load cell or the estimate
//!   as `control.compensation.force_from_estimate` selected). The weights
//!   are tied to that input, so a telemetry log needs to be told which it
//!   was (`--force-source`); a `load_force_n` column is a load cell.
//!
//! Rows with a `mode` column other than Running (4) are left out and
//! counted. The nut's speed and displacement are the motor's through the
//! lead (as `Compensator::inputs` forms them on the drive). Runs are cut
//! automatically: a run starts where the rod starts moving faster than the
//! motion threshold, in one direction, and lasts until the next start (its
//! standstill after the move included), or until a reversal or a gap in
//! the log. Nothing is dropped without being counted in the summary.
//!
//! Refused, naming what is missing: a missing column; a value that is not
//! a finite number (file, line, column); time going backwards; a log that
//! never moves, never reverses, has too few runs of a direction, or whose
//! load force never reaches the range the model must cover.

use super::dataset::{Dataset, Direction, ForceSource, Run, N_INPUTS};
use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How logs are cut and what they must cover.
#[derive(Clone, Debug)]
pub struct LogOptions {
    /// Rod metres per motor radian (lead / 2π).
    pub metres_per_rad: f64,
    /// The load force range the model must see (N): the log must come
    /// within `load_margin` of each end.
    pub load_range_n: (f64, f64),
    /// Share of the range's span a log may fall short of at each end.
    pub load_margin: f64,
    /// Rod speed above which the rod moves (m/s).
    pub motion_threshold_m_s: f64,
    /// A pause in the log longer than this ends the run (s).
    pub gap_s: f64,
    pub min_runs_per_direction: usize,
    pub min_samples_per_run: usize,
    /// Net motor-side travel a run needs (m): the drive's own setpoint
    /// shift (at most `faults.observer_shift_max_m`, 2 mm) ramping in after
    /// an enable moves the rod too, and is not a move.
    pub min_run_travel_m: f64,
    /// The force the drive's observer read while logging (`None`: known
    /// only from a `load_force_n` column).
    pub force_source: Option<ForceSource>,
    /// The paper's four inputs only, even where the logs give the
    /// direction of travel.
    pub static_inputs: bool,
}

impl LogOptions {
    /// Defaults for a rig with this lead; the load range is the one the
    /// compiled model was trained over.
    pub fn new(screw_lead_m: f64) -> Self {
        let m = &servo_core::observer::model::MODEL;
        Self {
            metres_per_rad: screw_lead_m / std::f64::consts::TAU,
            load_range_n: (f64::from(m.input_min[3]), f64::from(m.input_max[3])),
            load_margin: 0.1,
            motion_threshold_m_s: 0.002,
            gap_s: 0.5,
            min_runs_per_direction: 4,
            min_samples_per_run: 20,
            min_run_travel_m: 0.005,
            force_source: None,
            static_inputs: false,
        }
    }
}

/// What a conversion found and left out (summary.json).
#[derive(Clone, Debug, Default, Serialize)]
pub struct LogSummary {
    pub files: Vec<String>,
    pub rows_read: usize,
    /// Rows whose `mode` was not Running.
    pub rows_not_running: usize,
    /// Rows before the first move of each file (no run yet).
    pub rows_before_first_move: usize,
    /// Runs shorter than `min_samples_per_run`, or travelling less than
    /// `min_run_travel_m` with no run right after them, left out: (run,
    /// samples).
    pub short_runs_left_out: Vec<(String, usize)>,
    pub gaps_cutting_runs: usize,
    pub runs_elongation: usize,
    pub runs_contraction: usize,
    pub samples: usize,
    /// Time the rod moved faster than the motion threshold (s).
    pub moving_s: f64,
    /// Time covered by the runs (s).
    pub logged_s: f64,
    pub load_force_min_n: f64,
    pub load_force_max_n: f64,
    pub load_range_needed_n: (f64, f64),
    /// Which column gave the load force.
    pub load_force_column: String,
    pub terminal_error_max_abs_m: f64,
    /// Inputs of the dataset: 5 with the direction of travel, else 4.
    pub inputs: usize,
    /// Where the direction of travel came from, per file
    /// (`travel_direction`, `position_reference_m` or none).
    pub travel_direction_from: Vec<String>,
}

/// The first of `names` the header has.
fn column(header: &csv::StringRecord, names: &[&str], path: &Path, what: &str) -> Result<usize> {
    names.iter().find_map(|n| header.iter().position(|h| h == *n)).ok_or_else(|| {
        anyhow!(
            "{} line 1: missing column '{}' ({what}{}); header is: {}",
            path.display(),
            names[0],
            if names.len() > 1 { format!("; or {}", names[1..].join(", ")) } else { String::new() },
            header.iter().collect::<Vec<_>>().join(",")
        )
    })
}

pub(super) struct Row {
    pub(super) line: u64,
    pub(super) t: f64,
    pub(super) motor_m: f64,
    pub(super) speed_rad_s: f64,
    pub(super) terminal_m: f64,
    pub(super) force_n: f64,
    /// The direction of travel, if the log gives it.
    pub(super) travel: Option<f64>,
}

/// The sign of `d`, or `held` where it is 0.
fn sign_or(d: f64, held: f64) -> f64 {
    if d > 0.0 {
        1.0
    } else if d < 0.0 {
        -1.0
    } else {
        held
    }
}

pub(super) fn read_log(path: &Path, summary: &mut LogSummary) -> Result<(Vec<Row>, String)> {
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_path(path).with_context(|| format!("opening {}", path.display()))?;
    let header = rdr.headers().with_context(|| format!("{} line 1: reading the header", path.display()))?.clone();
    let c_t = column(&header, &["time_s"], path, "the time")?;
    let c_x = column(&header, &["motor_position_m", "motor_side_position_m"], path, "the encoder's position on the rod's scale")?;
    let c_w = column(&header, &["speed_rad_s", "motor_speed_rad_s"], path, "the motor speed")?;
    let c_s = column(&header, &["terminal_position_m"], path, "the linear scale at the rod: the target comes from it")?;
    let c_f = column(&header, &["load_force_n", "load_force_estimate_n"], path, "a load cell, or the drive's estimate")?;
    let c_mode = header.iter().position(|h| h == "mode");
    let c_travel = header.iter().position(|h| h == super::dataset::TRAVEL_COLUMN);
    let c_ref = header.iter().position(|h| h == "position_reference_m");
    summary.travel_direction_from.push(match (c_travel, c_ref) {
        (Some(_), _) => super::dataset::TRAVEL_COLUMN.into(),
        (None, Some(_)) => "position_reference_m".into(),
        (None, None) => "none".into(),
    });
    // The held sign of the planned position's changes: 0 until the plan
    // first moves, as on the drive.
    let (mut last_ref, mut held) = (None::<f64>, 0.0);
    let force_name = header.get(c_f).unwrap_or("?").to_string();
    let mut rows = Vec::new();
    let mut rec = csv::StringRecord::new();
    let mut k = 0u64;
    while rdr.read_record(&mut rec).with_context(|| format!("{}: reading data row {}", path.display(), k + 1))? {
        k += 1;
        summary.rows_read += 1;
        let line = rec.position().map(|p| p.line()).unwrap_or(k + 1);
        let num = |c: usize| -> Result<f64> {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s.parse().map_err(|_| {
                anyhow!("{} line {line}: column '{}' = '{s}' is not a number", path.display(), header.get(c).unwrap_or("?"))
            })?;
            if !v.is_finite() {
                let why = if c == c_s { ": the drive had no linear-scale reading (telemetry writes NaN without one)" } else { "" };
                bail!("{} line {line}: column '{}' = '{s}' is not finite{why}", path.display(), header.get(c).unwrap_or("?"));
            }
            Ok(v)
        };
        if let Some(c) = c_mode {
            if num(c)? != f64::from(servo_core::Mode::Running as u8) {
                summary.rows_not_running += 1;
                continue;
            }
        }
        let travel = match (c_travel, c_ref) {
            (Some(c), _) => {
                let d = num(c)?;
                if !(-1.0..=1.0).contains(&d) {
                    bail!("{} line {line}: column 'travel_direction' = {d} is outside [-1, 1] (the sign of the planned velocity)", path.display());
                }
                Some(d)
            }
            (None, Some(c)) => {
                let x = num(c)?;
                held = last_ref.map_or(held, |l| sign_or(x - l, held));
                last_ref = Some(x);
                Some(held)
            }
            (None, None) => None,
        };
        let row = Row { line, t: num(c_t)?, motor_m: num(c_x)?, speed_rad_s: num(c_w)?, terminal_m: num(c_s)?, force_n: num(c_f)?, travel };
        if let Some(prev) = rows.last() {
            let prev: &Row = prev;
            if row.t <= prev.t {
                bail!("{} line {line}: time_s = {} does not increase (line {}: {})", path.display(), row.t, prev.line, prev.t);
            }
        }
        rows.push(row);
    }
    if k == 0 {
        bail!("{}: no data row after the header", path.display());
    }
    Ok((rows, force_name))
}

/// The runs of one log file.
fn cut_runs(path: &Path, rows: &[Row], o: &LogOptions, summary: &mut LogSummary) -> Vec<Run> {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "log".into());
    let dir_of = |r: &Row| {
        let v = r.speed_rad_s * o.metres_per_rad;
        if v > o.motion_threshold_m_s {
            Some(Direction::Elongation)
        } else if v < -o.motion_threshold_m_s {
            Some(Direction::Contraction)
        } else {
            None
        }
    };
    // Starts of moves, with hysteresis (a start above the threshold, a
    // stop below half of it), so speed ripple near the threshold does not
    // cut a move in pieces. A run lasts until the next start or a gap.
    let mut starts: Vec<(usize, Direction)> = Vec::new();
    let mut ends: Vec<usize> = Vec::new();
    let mut moving: Option<Direction> = None;
    let mut open = false;
    for (i, r) in rows.iter().enumerate() {
        if i > 0 && r.t - rows[i - 1].t > o.gap_s {
            if open {
                summary.gaps_cutting_runs += 1;
                ends.push(i);
                open = false;
            }
            moving = None;
        }
        let v = r.speed_rad_s * o.metres_per_rad;
        let now = dir_of(r);
        match (moving, now) {
            (None, Some(d)) => {
                starts.push((i, d));
                moving = Some(d);
                open = true;
            }
            (Some(m), Some(d)) if m != d => {
                starts.push((i, d));
                moving = Some(d);
                open = true;
            }
            (Some(_), None) if v.abs() < 0.5 * o.motion_threshold_m_s => moving = None,
            _ => {}
        }
    }
    summary.rows_before_first_move += starts.first().map_or(rows.len(), |s| s.0);
    let mut runs = Vec::new();
    // A stretch that travels less than a move (the setpoint shift ramping
    // in) is not a run of its own: its rows go to the run that follows it
    // without a gap, whose direction is the move's.
    let mut carried: Option<usize> = None;
    for (k, &(s, d)) in starts.iter().enumerate() {
        let next_start = starts.get(k + 1).map_or(rows.len(), |n| n.0);
        let e = ends.iter().copied().find(|&e| e > s).unwrap_or(rows.len()).min(next_start);
        let id = format!("{stem}-{k:03}");
        let travel_m = match (rows.get(s), rows.get(e.saturating_sub(1))) {
            (Some(a), Some(b)) if e > s => (b.motor_m - a.motor_m).abs(),
            _ => 0.0,
        };
        let from = carried.take().unwrap_or(s);
        if travel_m < o.min_run_travel_m {
            if e == next_start && e < rows.len() {
                carried = Some(from);
            } else {
                summary.short_runs_left_out.push((id, e - from));
            }
            continue;
        }
        let seg = &rows[from..e];
        if seg.len() < o.min_samples_per_run {
            summary.short_runs_left_out.push((id, seg.len()));
            continue;
        }
        let mut run = Run {
            id,
            direction: d,
            tilt_swing_deg: f64::NAN,
            payload_scale: f64::NAN,
            source: path.to_path_buf(),
            first_line: seg[0].line,
            time_s: Vec::with_capacity(seg.len()),
            inputs: Vec::with_capacity(seg.len()),
            terminal_length_m: Vec::with_capacity(seg.len()),
            motor_side_position_m: Vec::with_capacity(seg.len()),
            terminal_error_m: Vec::with_capacity(seg.len()),
        };
        for (j, r) in seg.iter().enumerate() {
            let x: [f64; N_INPUTS] = [r.speed_rad_s, r.speed_rad_s * o.metres_per_rad, r.motor_m, r.force_n, r.travel.unwrap_or(0.0)];
            if dir_of(r).is_some() {
                summary.moving_s += seg.get(j + 1).map_or(0.0, |n| n.t - r.t);
            }
            run.time_s.push(r.t);
            run.inputs.push(x);
            run.terminal_length_m.push(f64::NAN);
            run.motor_side_position_m.push(r.motor_m);
            run.terminal_error_m.push(r.terminal_m - r.motor_m);
        }
        summary.logged_s += seg[seg.len() - 1].t - seg[0].t;
        runs.push(run);
    }
    runs
}

/// The CSV files of `logs`: files as given, folders' `.csv` files sorted.
pub(super) fn log_files(logs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if logs.is_empty() {
        bail!("no log given");
    }
    let mut files = Vec::new();
    for p in logs {
        if p.is_dir() {
            let mut v: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("reading folder {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|x| x == "csv"))
                .collect();
            v.sort();
            if v.is_empty() {
                bail!("log folder {} holds no .csv file", p.display());
            }
            files.extend(v);
        } else if p.exists() {
            files.push(p.clone());
        } else {
            bail!("log {} does not exist", p.display());
        }
    }
    Ok(files)
}

/// The dataset of `logs`, checked for what the model needs.
pub fn convert(logs: &[PathBuf], o: &LogOptions) -> Result<(Dataset, LogSummary)> {
    let files = log_files(logs)?;
    let mut s = LogSummary { load_range_needed_n: o.load_range_n, load_force_min_n: f64::INFINITY, load_force_max_n: f64::NEG_INFINITY, ..LogSummary::default() };
    let mut runs = Vec::new();
    let mut force_cols = Vec::new();
    for f in &files {
        s.files.push(f.display().to_string());
        let (rows, force) = read_log(f, &mut s)?;
        force_cols.push(force);
        runs.extend(cut_runs(f, &rows, o, &mut s));
    }
    force_cols.dedup();
    s.load_force_column = force_cols.join(",");
    let force_source = force_source_of(&force_cols, o.force_source, &files)?;
    let logs_named = files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", ");
    if runs.is_empty() {
        bail!(
            "{logs_named}: no move: the rod never moves faster than {} mm/s for {} samples (or the drive never ran); log moves in both directions (docs/observer-retraining.md, \"What to log\")",
            o.motion_threshold_m_s * 1e3,
            o.min_samples_per_run
        );
    }
    for r in &runs {
        for (x, e) in r.inputs.iter().zip(&r.terminal_error_m) {
            s.load_force_min_n = s.load_force_min_n.min(x[3]);
            s.load_force_max_n = s.load_force_max_n.max(x[3]);
            s.terminal_error_max_abs_m = s.terminal_error_max_abs_m.max(e.abs());
        }
    }
    s.runs_elongation = runs.iter().filter(|r| r.direction == Direction::Elongation).count();
    s.runs_contraction = runs.len() - s.runs_elongation;
    s.samples = runs.iter().map(Run::len).sum();
    let count = |d: Direction| if d == Direction::Elongation { s.runs_elongation } else { s.runs_contraction };
    for d in [Direction::Elongation, Direction::Contraction] {
        if count(d) == 0 {
            bail!(
                "{logs_named}: never reverses: {} {} runs and no {} run; the model needs moves in both directions",
                count(d.opposite()),
                d.opposite().name(),
                d.name()
            );
        }
    }
    for d in [Direction::Elongation, Direction::Contraction] {
        if count(d) < o.min_runs_per_direction {
            bail!(
                "{logs_named}: too short: {} {} runs; at least {} per direction are needed (training, validation and a held-out test run); log more moves",
                count(d),
                d.name(),
                o.min_runs_per_direction
            );
        }
    }
    let (lo, hi) = o.load_range_n;
    let slack = o.load_margin * (hi - lo).abs();
    let mut missing = Vec::new();
    if s.load_force_max_n < hi - slack {
        missing.push(format!("loads up to {hi:.0} N (the log reaches {:.0} N: log moves with the heavier payload)", s.load_force_max_n));
    }
    if s.load_force_min_n > lo + slack {
        missing.push(format!("loads down to {lo:.0} N (the log's least is {:.0} N: log moves with the lighter payload or unloaded)", s.load_force_min_n));
    }
    if !missing.is_empty() {
        bail!(
            "{logs_named}: never reaches the loads the model needs ({}, within {:.0} %; --load-range-n LO,HI sets the range): missing {}",
            s.load_force_column,
            o.load_margin * 100.0,
            missing.join(" and ")
        );
    }
    let name = files.first().and_then(|f| f.parent()).and_then(|p| p.file_name()).map_or("logs".into(), |n| n.to_string_lossy().into_owned());
    // Five inputs only when every log gives the direction of travel: a
    // dataset's inputs are the same in every run.
    let travel = !o.static_inputs && s.travel_direction_from.iter().all(|f| f != "none");
    if !travel {
        for r in &mut runs {
            for x in &mut r.inputs {
                x[4] = 0.0;
            }
        }
    }
    s.inputs = if travel { N_INPUTS } else { super::dataset::STATIC_INPUTS };
    let ds = Dataset::from_runs(&format!("logs:{name}"), runs).with_force_source(force_source).with_inputs(s.inputs);
    Ok((ds, s))
}

/// The force the observer read in the logs: a load cell's own column says
/// so; the telemetry's `load_force_estimate_n` is whatever the drive had
/// selected, which only the user can say.
fn force_source_of(columns: &[String], given: Option<ForceSource>, files: &[PathBuf]) -> Result<ForceSource> {
    let named = files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", ");
    let load_cell = columns.iter().any(|c| c == "load_force_n");
    let telemetry = columns.iter().any(|c| c == "load_force_estimate_n");
    match (load_cell, telemetry, given) {
        (true, true, _) => bail!("{named}: some logs give 'load_force_n' (a load cell), others 'load_force_estimate_n': log every file with the same force input"),
        (true, false, Some(ForceSource::Estimate)) => {
            bail!("{named}: --force-source estimate, but the logs' force column is 'load_force_n', a load cell's")
        }
        (true, false, _) => Ok(ForceSource::LoadCell),
        (false, _, Some(g)) => Ok(g),
        (false, _, None) => bail!(
            "{named}: the force column 'load_force_estimate_n' is the observer's force input as the drive had it selected: \
             say which with --force-source load-cell (control.compensation.force_from_estimate = false, load cell fitted) \
             or --force-source estimate (force_from_estimate = true); the weights run only on that input"
        ),
    }
}

/// `host-sim dataset-from-logs`.
#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct FromLogsArgs {
    /// Log files (CSV) or folders of them: `drive telemetry --csv` records,
    /// or a logger's CSV with the same columns (docs/observer-retraining.md).
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Output folder: dataset.csv (the trainer's format) and summary.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Rig file, for the screw lead; default: the shipped rig.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Load force range (N) the model must cover; default: the range the
    /// compiled model was trained over.
    #[arg(long, value_delimiter = ',', num_args = 2)]
    pub load_range_n: Option<Vec<f64>>,
    /// Rod speed (m/s) above which a move starts.
    #[arg(long, default_value_t = 0.002)]
    pub motion_threshold_m_s: f64,
    /// Runs each direction needs at least.
    #[arg(long, default_value_t = 4)]
    pub min_runs_per_direction: usize,
    /// The force the drive's observer read while logging: `load-cell`
    /// (`control.compensation.force_from_estimate = false`, a load cell
    /// fitted) or `estimate`. Needed for the telemetry's
    /// `load_force_estimate_n`; the weights are tied to it.
    #[arg(long, value_enum)]
    pub force_source: Option<crate::scenario::no_load_cell::ForceSource>,
    /// The paper's four inputs only: leave the direction of travel out
    /// even where the logs give it (weights for firmware without the fifth
    /// input slot).
    #[arg(long)]
    pub static_inputs: bool,
}

/// Converts, writes `dataset.csv` and `summary.json`, prints what it found.
pub fn run_cli(a: &FromLogsArgs) -> Result<LogSummary> {
    let rig = crate::config::RigConfig::load_or_nominal(a.params.as_ref())?;
    let mut o = LogOptions::new(f64::from(rig.control.drive_train.screw_lead_m));
    if let Some(r) = &a.load_range_n {
        let (lo, hi) = (r[0], r[1]);
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            bail!("--load-range-n: expected LO,HI with LO < HI, got {lo},{hi}");
        }
        o.load_range_n = (lo, hi);
    }
    if !(a.motion_threshold_m_s.is_finite() && a.motion_threshold_m_s > 0.0) {
        bail!("--motion-threshold-m-s: must be > 0, got {}", a.motion_threshold_m_s);
    }
    o.motion_threshold_m_s = a.motion_threshold_m_s;
    o.min_runs_per_direction = a.min_runs_per_direction.max(1);
    o.force_source = a.force_source.map(|f| f.core());
    o.static_inputs = a.static_inputs;
    let (ds, s) = convert(&a.logs, &o)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let path = a.out.join("dataset.csv");
    ds.write_csv(&path)?;
    let summary = serde_json::json!({ "command": "host-sim dataset-from-logs", "dataset": path.display().to_string(), "force_source": ds.force_source.name(), "logs": s });
    std::fs::write(a.out.join("summary.json"), serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("writing {}", a.out.join("summary.json").display()))?;
    println!(
        "{} runs ({} elongation, {} contraction), {} samples, {:.1} s moving of {:.1} s in runs; load force {:.0}..{:.0} N ({}); max |terminal error| {:.1} µm; {} inputs",
        s.runs_elongation + s.runs_contraction,
        s.runs_elongation,
        s.runs_contraction,
        s.samples,
        s.moving_s,
        s.logged_s,
        s.load_force_min_n,
        s.load_force_max_n,
        s.load_force_column,
        s.terminal_error_max_abs_m * 1e6,
        s.inputs
    );
    println!(
        "left out: {} rows not Running, {} rows before the first move, {} runs under {} samples, {} gaps cutting runs",
        s.rows_not_running,
        s.rows_before_first_move,
        s.short_runs_left_out.len(),
        o.min_samples_per_run,
        s.gaps_cutting_runs
    );
    println!("wrote {} and {}/summary.json", path.display(), a.out.display());
    Ok(s)
}
