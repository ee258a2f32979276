//! The measured log: the documented CSV schema, the firmware's defmt
//! telemetry, and validation that names the row of every problem.
//!
//! Schema (header names, SI units; every column but `time_s` optional, any
//! order, unknown columns reported and ignored): see `SCHEMA` and
//! `docs/diagnosis.md`. `run` splits the log into runs (time restarts per
//! run); without it the log is one run.

use anyhow::{anyhow, bail, Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

pub use super::defmt_log::parse_defmt;

/// One schema column: name, unit, meaning, plausible range (a value outside
/// it is reported as a probable unit mistake).
pub struct Column {
    pub name: &'static str,
    pub unit: &'static str,
    pub meaning: &'static str,
    pub range: (f64, f64),
}

pub const SCHEMA: &[Column] = &[
    Column {
        name: "time_s",
        unit: "s",
        meaning: "sample time, increasing within a run",
        range: (-1.0, 1.0e6),
    },
    Column {
        name: "run",
        unit: "-",
        meaning: "run number (integer); time restarts per run",
        range: (0.0, 1.0e6),
    },
    Column {
        name: "position_reference_m",
        unit: "m",
        meaning: "trajectory position reference",
        range: (-2.0, 2.0),
    },
    Column {
        name: "motor_angle_rad",
        unit: "rad",
        meaning: "multi-turn mechanical motor angle (encoder)",
        range: (-1.0e4, 1.0e4),
    },
    Column {
        name: "terminal_position_m",
        unit: "m",
        meaning: "linear-scale (rod) position",
        range: (-2.0, 2.0),
    },
    Column {
        name: "current_q_a",
        unit: "A",
        meaning: "q-axis current (or the motor current of a non-FOC drive)",
        range: (-500.0, 500.0),
    },
    Column {
        name: "current_d_a",
        unit: "A",
        meaning: "d-axis current",
        range: (-500.0, 500.0),
    },
    Column {
        name: "current_a_a",
        unit: "A",
        meaning: "phase a current (with b, c: Park-transformed to d-q)",
        range: (-500.0, 500.0),
    },
    Column {
        name: "current_b_a",
        unit: "A",
        meaning: "phase b current",
        range: (-500.0, 500.0),
    },
    Column {
        name: "current_c_a",
        unit: "A",
        meaning: "phase c current",
        range: (-500.0, 500.0),
    },
    Column {
        name: "voltage_q_v",
        unit: "V",
        meaning: "q-axis voltage command",
        range: (-1000.0, 1000.0),
    },
    Column {
        name: "bus_voltage_v",
        unit: "V",
        meaning: "DC bus voltage",
        range: (0.0, 1000.0),
    },
    Column {
        name: "load_force_n",
        unit: "N",
        meaning: "external axial force on the rod, + opposes extension (excl. gravity)",
        range: (-1.0e5, 1.0e5),
    },
    Column {
        name: "tilt_deg",
        unit: "deg",
        meaning: "cylinder tilt from horizontal",
        range: (-180.0, 180.0),
    },
    Column {
        name: "motor_temperature_c",
        unit: "°C",
        meaning: "motor (winding or magnet) temperature: a gain drifting with it",
        range: (-50.0, 250.0),
    },
];

/// A problem in the input, with its 1-based data row (the header is row 0).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Issue {
    pub row: Option<usize>,
    pub column: Option<String>,
    pub severity: Severity,
    pub message: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Severity {
    /// The analysis refuses the log.
    Error,
    /// Reported; the analysis goes on (e.g. a gap splits the run).
    Warning,
    /// Reported for information (unknown columns, ruled-out analyses).
    Note,
}

impl std::fmt::Display for Issue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let sev = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
            Severity::Note => "note",
        };
        write!(f, "{sev}")?;
        if let Some(r) = self.row {
            write!(f, " row {r}")?;
        }
        if let Some(c) = &self.column {
            write!(f, " column `{c}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

/// A log in the schema: columns by name, all the same length.
#[derive(Clone, Debug, Default)]
pub struct Log {
    pub source: String,
    pub columns: BTreeMap<String, Vec<f64>>,
    pub issues: Vec<Issue>,
}

impl Log {
    pub fn len(&self) -> usize {
        self.columns.get("time_s").map_or(0, Vec::len)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.columns.get(name).map(Vec::as_slice)
    }
    pub fn has(&self, name: &str) -> bool {
        self.columns.contains_key(name)
    }
    pub fn errors(&self) -> impl Iterator<Item = &Issue> {
        self.issues.iter().filter(|i| i.severity == Severity::Error)
    }

    /// Builds a log from columns (tests, converters); validates it.
    pub fn from_columns(source: &str, columns: BTreeMap<String, Vec<f64>>) -> Result<Log> {
        let n = columns
            .get("time_s")
            .ok_or_else(|| anyhow!("{source}: no `time_s` column"))?
            .len();
        if let Some((k, v)) = columns.iter().find(|(_, v)| v.len() != n) {
            bail!(
                "{source}: column `{k}` has {} values, `time_s` {n}",
                v.len()
            );
        }
        let mut log = Log {
            source: source.to_string(),
            columns,
            issues: Vec::new(),
        };
        log.validate();
        Ok(log)
    }

    /// Reads a CSV in the schema. Empty cells and unparsable numbers become
    /// NaN and are reported by row.
    pub fn read_csv(path: &Path) -> Result<Log> {
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .with_context(|| format!("reading {}", path.display()))?;
        let headers: Vec<String> = rdr.headers()?.iter().map(str::to_string).collect();
        let mut issues = Vec::new();
        let mut keep = Vec::new();
        for (k, h) in headers.iter().enumerate() {
            if SCHEMA.iter().any(|c| c.name == h) {
                keep.push((k, h.clone()));
            } else {
                issues.push(Issue {
                    row: None,
                    column: Some(h.clone()),
                    severity: Severity::Note,
                    message: "not in the schema; ignored".into(),
                });
            }
        }
        let mut columns: BTreeMap<String, Vec<f64>> =
            keep.iter().map(|(_, h)| (h.clone(), Vec::new())).collect();
        for (r, rec) in rdr.records().enumerate() {
            let rec = rec.with_context(|| format!("{}: data row {}", path.display(), r + 1))?;
            for (k, h) in &keep {
                let cell = rec.get(*k).unwrap_or("");
                let v = cell.parse::<f64>().unwrap_or_else(|_| {
                    issues.push(Issue {
                        row: Some(r + 1),
                        column: Some(h.clone()),
                        severity: Severity::Error,
                        message: format!("`{cell}` is not a number"),
                    });
                    f64::NAN
                });
                columns.get_mut(h).expect("kept").push(v);
            }
        }
        let mut log = Log::from_columns(&path.display().to_string(), columns)?;
        issues.append(&mut log.issues);
        log.issues = issues;
        Ok(log)
    }

    /// Writes the log in the schema.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let mut w =
            csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
        let names: Vec<&String> = self.columns.keys().collect();
        w.write_record(names.iter().map(|s| s.as_str()))?;
        for i in 0..self.len() {
            w.write_record(names.iter().map(|n| format!("{}", self.columns[*n][i])))?;
        }
        w.flush()?;
        Ok(())
    }

    /// Checks order, duplicates, gaps, NaN and physical ranges, row by row.
    pub fn validate(&mut self) {
        let n = self.len();
        let mut issues = Vec::new();
        for col in SCHEMA {
            let Some(v) = self.columns.get(col.name) else {
                continue;
            };
            let mut bad = 0;
            for (i, x) in v.iter().enumerate() {
                let msg = if x.is_nan() {
                    Some("NaN or empty".to_string())
                } else if !x.is_finite() || *x < col.range.0 || *x > col.range.1 {
                    let hint = if col.unit == "m" {
                        " (mm given as m?)"
                    } else {
                        ""
                    };
                    Some(format!(
                        "{x} {} outside the plausible range {:?}{hint}",
                        col.unit, col.range
                    ))
                } else {
                    None
                };
                if let Some(message) = msg {
                    bad += 1;
                    if bad <= 20 {
                        issues.push(Issue {
                            row: Some(i + 1),
                            column: Some(col.name.into()),
                            severity: Severity::Error,
                            message,
                        });
                    }
                }
            }
            if bad > 20 {
                issues.push(Issue {
                    row: None,
                    column: Some(col.name.into()),
                    severity: Severity::Error,
                    message: format!("{bad} bad values in all (first 20 listed)"),
                });
            }
        }
        let t = &self.columns["time_s"];
        let run = self.columns.get("run");
        let same_run = |i: usize| run.is_none_or(|r| r[i] == r[i - 1]);
        let mut dts: Vec<f64> = (1..n)
            .filter(|&i| same_run(i))
            .map(|i| t[i] - t[i - 1])
            .filter(|d| *d > 0.0)
            .collect();
        dts.sort_by(f64::total_cmp);
        let median = dts.get(dts.len() / 2).copied().unwrap_or(0.0);
        let mut listed = 0;
        for i in 1..n {
            if !same_run(i) || !t[i].is_finite() || !t[i - 1].is_finite() {
                continue;
            }
            let dt = t[i] - t[i - 1];
            let (severity, message) = if dt == 0.0 {
                (
                    Severity::Error,
                    format!("duplicate timestamp {} s (same as row {i})", t[i]),
                )
            } else if dt < 0.0 {
                (
                    Severity::Error,
                    format!(
                        "time goes back from {} s to {} s (unsorted)",
                        t[i - 1],
                        t[i]
                    ),
                )
            } else if median > 0.0 && dt > 1.5 * median {
                (
                    Severity::Warning,
                    format!("gap of {dt:.4} s (median step {median:.4} s); the run is split here"),
                )
            } else {
                continue;
            };
            listed += 1;
            if listed <= 50 {
                issues.push(Issue {
                    row: Some(i + 1),
                    column: Some("time_s".into()),
                    severity,
                    message,
                });
            }
        }
        if listed > 50 {
            issues.push(Issue {
                row: None,
                column: Some("time_s".into()),
                severity: Severity::Error,
                message: format!("{listed} time-order problems in all (first 50 listed)"),
            });
        }
        self.issues.extend(issues);
    }

    /// Why no stretch of the log can be analysed, with the minimum: the
    /// residual smooths ±10 ms (at least ±2 samples) on both sides of every
    /// sample, so a run or a stretch between gaps needs that window twice
    /// and five samples more (and at least 12).
    pub fn too_short(&self) -> String {
        let t = self.get("time_s").unwrap_or(&[]);
        let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
        d.sort_by(f64::total_cmp);
        let dt = d.get(d.len() / 2).copied().unwrap_or(1e-3);
        let m = super::residual::half_width(dt);
        let longest = self.segments().iter().map(|(a, b)| b - a).max().unwrap_or(0);
        format!(
            "{} rows, the longest run or stretch between gaps {longest} samples; at {:.4} Hz one needs at least {} samples (the ±{m}-sample smoothing window on both sides, plus 5) to give a training and a held-out part",
            self.len(),
            1.0 / dt,
            (2 * m + 5).max(12)
        )
    }

    /// Contiguous segments `[start, end)`: split at run changes and gaps.
    pub fn segments(&self) -> Vec<(usize, usize)> {
        let n = self.len();
        let t = &self.columns["time_s"];
        let run = self.columns.get("run");
        let gap_rows: std::collections::BTreeSet<usize> = self
            .issues
            .iter()
            .filter(|i| i.severity == Severity::Warning && i.column.as_deref() == Some("time_s"))
            .filter_map(|i| i.row.map(|r| r - 1))
            .collect();
        let mut out = Vec::new();
        let mut start = 0;
        for i in 1..=n {
            let split = i == n
                || run.is_some_and(|r| r[i] != r[i - 1])
                || gap_rows.contains(&i)
                || t[i] <= t[i - 1];
            if split {
                if i > start {
                    out.push((start, i));
                }
                start = i;
            }
        }
        out
    }

    /// Which analyses the missing columns rule out.
    pub fn ruled_out(&self) -> Vec<String> {
        let mut out = Vec::new();
        let has_i = self.has("current_q_a") || (self.has("current_a_a") && self.has("current_b_a"));
        if !self.has("motor_angle_rad") {
            out.push("no motor_angle_rad: motor-side kinematics come from the linear scale; cogging, encoder eccentricity, once-per-revolution lead error and the Park transform of phase currents are ruled out".into());
        }
        if !has_i {
            out.push("no current: the torque (inverse-dynamics) residual and every friction, load and current-sensor effect are ruled out".into());
        }
        if !self.has("terminal_position_m") {
            out.push("no terminal_position_m: the position residual and backlash, stiffness, contact, coupling, lead and thermal effects are ruled out".into());
        }
        if !self.has("voltage_q_v") {
            out.push(
                "no voltage_q_v: the voltage residual and inverter dead time are ruled out".into(),
            );
        }
        if !self.has("position_reference_m") {
            out.push(
                "no position_reference_m: residual–input cross-correlation uses the current instead of the reference"
                    .into(),
            );
        }
        if !self.has("load_force_n") {
            out.push(
                "no load_force_n: the external force is taken as zero and the load-band split uses gravity only".into(),
            );
        }
        if !self.has("tilt_deg") {
            out.push("no tilt_deg: the rig's initial tilt is assumed throughout".into());
        }
        if !self.has("bus_voltage_v") {
            out.push("no bus_voltage_v: bus-voltage checks skipped".into());
        }
        out
    }
}

/// Reads a log: `.csv` in the schema, anything else as defmt text.
pub fn read_any(path: &Path) -> Result<Log> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    {
        Log::read_csv(path)
    } else {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        parse_defmt(&text, &path.display().to_string())
    }
}
