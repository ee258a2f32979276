//! `summary.json` and the per-case markdown table of the power-up suite.

use super::run::CaseResult;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;

fn max_of(rows: &[&CaseResult], f: impl Fn(&CaseResult) -> Option<f64>) -> Option<f64> {
    rows.iter().filter_map(|r| f(r)).fold(None, |m, v| Some(m.map_or(v, |m: f64| m.max(v))))
}

/// The suite's figures; successful power-ups and failures apart.
pub fn summarise(rows: &[CaseResult], homing_zeros_m: &[f64], wall_s: f64) -> serde_json::Value {
    let ok: Vec<&CaseResult> = rows.iter().filter(|r| r.failure == super::Failure::None).collect();
    let failures: Vec<&CaseResult> = rows.iter().filter(|r| r.failure != super::Failure::None).collect();
    let spread = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (hi - lo) * 1e6
    };
    serde_json::json!({
        "scenarios": rows.len(),
        "passed": rows.iter().filter(|r| r.passed).count(),
        "power_ups": ok.len(),
        "power_ups_passed": ok.iter().filter(|r| r.passed).count(),
        "failure_cases": failures.len(),
        "failure_cases_passed": failures.iter().filter(|r| r.passed).count(),
        "rod_movement_max_mm": max_of(&ok, |r| Some(r.rod_movement_max_mm)),
        "electrical_offset_error_max_deg": max_of(&ok, |r| r.electrical_offset_error_deg),
        "enable_sag_max_um": max_of(&ok, |r| r.enable_sag_um),
        "hold_error_pp_max_um": max_of(&ok, |r| r.hold_error_pp_um),
        "hold_current_pp_max_a": max_of(&ok, |r| r.hold_current_pp_a),
        "time_to_ready_max_s": max_of(&ok, |r| r.time_to_ready_s),
        "failure_rod_drop_max_mm": max_of(&failures, |r| Some(r.rod_drop_max_mm)),
        "homings": homing_zeros_m.len(),
        "homing_repeatability_um": if homing_zeros_m.is_empty() { None } else { Some(spread(homing_zeros_m)) },
        "homing_zero_positions_m": homing_zeros_m,
        "wall_s": wall_s,
        "cases": rows,
    })
}

/// Writes `summary.json` and `cases.md` into `out`.
pub fn write_report(summary: &serde_json::Value, rows: &[CaseResult], out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(summary)?).with_context(|| format!("writing {}", path.display()))?;
    let mut md = String::from(
        "| case | expected | passed | faults | rod movement mm | rod drop mm | offset error ° | enable sag µm | ready s | bridge off | brake closed | verdict |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let opt = |v: Option<f64>, digits: usize| v.map_or("–".to_string(), |v| format!("{v:.digits$}"));
    for r in rows {
        let expected = r.failure.expected_fault().map_or("ready".to_string(), crate::fault_injection::names);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.4} | {:.4} | {} | {} | {} | {} | {} | {} |",
            r.name,
            expected,
            if r.passed { "yes" } else { "**no**" },
            if r.faults.is_empty() { "none".to_string() } else { r.faults.join("|") },
            r.rod_movement_max_mm,
            r.rod_drop_max_mm,
            opt(r.electrical_offset_error_deg, 2),
            opt(r.enable_sag_um, 2),
            opt(r.time_to_ready_s, 2),
            r.bridge_off_at_end,
            r.brake_closed_at_end,
            r.verdict,
        );
    }
    let path = out.join("cases.md");
    std::fs::write(&path, md).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
