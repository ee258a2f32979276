//! defmt telemetry text (as probe-rs or defmt-print print it) read into a
//! diagnosis [`Log`]: each `tlm Telemetry { … }` line is a row.

use super::log::{Issue, Log, Severity};
use anyhow::{bail, Result};
use std::collections::BTreeMap;

/// Telemetry fields of the firmware's `tlm Telemetry { … }` line mapped to
/// schema columns; the others are known and not used.
const TLM_MAP: &[(&str, &str)] = &[
    ("time_s", "time_s"),
    ("position_reference_m", "position_reference_m"),
    ("motor_angle_rad", "motor_angle_rad"),
    ("terminal_position_m", "terminal_position_m"),
    ("current_q_a", "current_q_a"),
    ("current_d_a", "current_d_a"),
    ("voltage_q_v", "voltage_q_v"),
    ("bus_voltage_v", "bus_voltage_v"),
];
const TLM_UNUSED: &[&str] = &[
    "mode",
    "position_command_m",
    "position_shift_m",
    "motor_position_m",
    "speed_reference_rad_s",
    "speed_rad_s",
    "current_q_reference_a",
    "voltage_d_v",
    "load_force_estimate_n",
    "faults",
    "limits",
];

/// Splits `a: x, b: Some(1.0), c: Foo { d: 1 }` at top-level commas.
fn top_level_fields(body: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut cur = String::new();
    for ch in body.chars() {
        match ch {
            '{' | '(' | '[' => depth += 1,
            '}' | ')' | ']' => depth -= 1,
            _ => {}
        }
        if ch == ',' && depth == 0 {
            out.push(std::mem::take(&mut cur));
        } else {
            cur.push(ch);
        }
    }
    out.push(cur);
    out.into_iter()
        .filter_map(|f| {
            let (k, v) = f.split_once(':')?;
            Some((k.trim().to_string(), v.trim().to_string()))
        })
        .collect()
}

/// Parses defmt output (probe-rs / defmt-print): every line containing
/// `tlm Telemetry {` becomes a row; other lines are skipped and counted.
/// `None` fields (no scale) become NaN only if the column exists elsewhere;
/// a column that is `None` on every row is left out.
pub fn parse_defmt(text: &str, source: &str) -> Result<Log> {
    let mut issues = Vec::new();
    let mut rows: Vec<BTreeMap<String, f64>> = Vec::new();
    let mut unknown: BTreeMap<String, usize> = BTreeMap::new();
    let mut skipped = 0usize;
    let mut line_of_row = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let Some(pos) = line.find("tlm Telemetry {") else {
            skipped += 1;
            continue;
        };
        let body = &line[pos + "tlm Telemetry {".len()..];
        let Some(end) = body.rfind('}') else {
            issues.push(Issue {
                row: Some(ln + 1),
                column: None,
                severity: Severity::Error,
                message: "truncated telemetry line".into(),
            });
            continue;
        };
        let mut row = BTreeMap::new();
        for (k, v) in top_level_fields(&body[..end]) {
            if let Some((_, col)) = TLM_MAP.iter().find(|(f, _)| *f == k) {
                let inner = v
                    .strip_prefix("Some(")
                    .and_then(|s| s.strip_suffix(')'))
                    .unwrap_or(&v);
                if inner == "None" {
                    continue;
                }
                match inner.parse::<f64>() {
                    Ok(x) => {
                        row.insert(col.to_string(), x);
                    }
                    Err(_) => issues.push(Issue {
                        row: Some(ln + 1),
                        column: Some(k.clone()),
                        severity: Severity::Error,
                        message: format!("`{v}` is not a number (line {})", ln + 1),
                    }),
                }
            } else if !TLM_UNUSED.contains(&k.as_str()) {
                *unknown.entry(k).or_default() += 1;
            }
        }
        line_of_row.push(ln + 1);
        rows.push(row);
    }
    if rows.is_empty() {
        bail!("{source}: no `tlm Telemetry {{ … }}` lines found ({skipped} other lines)");
    }
    for (k, n) in unknown {
        issues.push(Issue {
            row: None,
            column: Some(k),
            severity: Severity::Note,
            message: format!("unknown telemetry field on {n} lines; ignored"),
        });
    }
    if skipped > 0 {
        issues.push(Issue {
            row: None,
            column: None,
            severity: Severity::Note,
            message: format!("{skipped} non-telemetry lines skipped"),
        });
    }
    let mut names: Vec<String> = rows.iter().flat_map(|r| r.keys().cloned()).collect();
    names.sort();
    names.dedup();
    let columns = names
        .into_iter()
        .map(|n| {
            let v = rows
                .iter()
                .map(|r| r.get(&n).copied().unwrap_or(f64::NAN))
                .collect();
            (n, v)
        })
        .collect();
    let mut log = Log::from_columns(source, columns)?;
    // Row numbers of the validation refer to telemetry rows; name the line too.
    for i in &mut log.issues {
        if let Some(r) = i.row {
            if let Some(l) = line_of_row.get(r - 1) {
                i.message = format!("{} (input line {l})", i.message);
            }
        }
    }
    issues.append(&mut log.issues);
    log.issues = issues;
    Ok(log)
}
