//! Converter: Cranfield linear-actuator data (Ruiz-Carcel & Starr 2018, see
//! `../shared/data/cranfield-linear-actuator/README.md`) → the log schema.
//!
//! `set_point` (mm) → `position_reference_m`; `set_point − position_error`
//! (mm) → `terminal_position_m`; `current` (A, Hall sensor, stepper) →
//! `current_q_a`; `load` (kgf) → `load_force_n` (× 9.80665); each (load, run)
//! group → one `run`; `time` restarts at every motion cycle inside a run, so
//! `time_s` is made continuous within the run (cycle restarts are not
//! errors; each is counted in the returned notes).

use super::log::{Issue, Log, Severity};
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// The diagnose-log columns a Cranfield run is converted into.
pub const COLUMNS: [&str; 6] =
    ["time_s", "run", "position_reference_m", "terminal_position_m", "current_q_a", "load_force_n"];

pub const KGF_N: f64 = 9.80665;

/// A converted file, with the (load kgf, run) of every run index.
pub struct Converted {
    pub log: Log,
    pub runs: Vec<(f64, u32)>,
}

pub fn convert(path: &Path) -> Result<Converted> {
    let mut rdr =
        csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
    let h: Vec<String> = rdr.headers()?.iter().map(str::to_string).collect();
    let idx = |name: &str| {
        h.iter()
            .position(|x| x == name)
            .with_context(|| format!("{}: no `{name}` column", path.display()))
    };
    let (i_sp, i_pe, i_cur, i_load, i_run, i_t) = (
        idx("set_point")?,
        idx("position_error")?,
        idx("current")?,
        idx("load")?,
        idx("run")?,
        idx("time")?,
    );
    let mut cols: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for k in COLUMNS {
        cols.insert(k.into(), Vec::new());
    }
    let mut runs: Vec<(f64, u32)> = Vec::new();
    let mut issues = Vec::new();
    let (mut offset, mut last_t, mut last_key) = (0.0, f64::NAN, None::<(f64, u32)>);
    let mut restarts = 0usize;
    for (r, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: data row {}", path.display(), r + 1))?;
        let num = |k: usize| {
            rec.get(k)
                .and_then(|s| s.trim().parse::<f64>().ok())
                .unwrap_or(f64::NAN)
        };
        let (sp, pe, cur, load, run, t) = (
            num(i_sp),
            num(i_pe),
            num(i_cur),
            num(i_load),
            num(i_run),
            num(i_t),
        );
        let key = (load, run as u32);
        if last_key != Some(key) {
            offset = 0.0;
            last_t = f64::NAN;
            last_key = Some(key);
            if !runs.contains(&key) {
                runs.push(key);
            } else {
                issues.push(Issue {
                    row: Some(r + 1),
                    column: Some("run".into()),
                    severity: Severity::Warning,
                    message: format!("run {key:?} resumes after other runs"),
                });
            }
        }
        let run_idx = runs.iter().position(|k| *k == key).unwrap_or(0);
        if t < last_t {
            // A new motion cycle: continue the clock one sample on.
            restarts += 1;
            offset += last_t - t + 0.04;
        }
        last_t = t;
        cols.get_mut("time_s").unwrap().push(t + offset);
        cols.get_mut("run").unwrap().push(run_idx as f64);
        cols.get_mut("position_reference_m")
            .unwrap()
            .push(sp * 1e-3);
        cols.get_mut("terminal_position_m")
            .unwrap()
            .push((sp - pe) * 1e-3);
        cols.get_mut("current_q_a").unwrap().push(cur);
        cols.get_mut("load_force_n").unwrap().push(load * KGF_N);
    }
    let mut log = Log::from_columns(&path.display().to_string(), cols)?;
    issues.push(Issue {
        row: None,
        column: Some("time".into()),
        severity: Severity::Note,
        message: format!("{restarts} motion-cycle time restarts made continuous within their runs"),
    });
    issues.append(&mut log.issues);
    log.issues = issues;
    Ok(Converted { log, runs })
}
