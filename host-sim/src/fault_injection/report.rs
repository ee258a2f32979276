//! What `host-sim faults` writes: `summary.json` (one entry per scenario:
//! detection time, reaction, peak current, stroke, NaN check, the rules it
//! broke), `reliability_measured.md` (the measured columns of the table in
//! `docs/reliability.md`) and one CSV trace per scenario.

use super::catalog;
use super::{names, run, Outcome, Scenario};
use crate::config::RigConfig;
use anyhow::{Context, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One scenario in `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct ScenarioSummary {
    pub name: &'static str,
    pub what: &'static str,
    pub expected_faults: String,
    pub expected_reaction: Option<String>,
    pub expected_within_periods: u64,
    /// PWM periods from the first faulty period to the step that latched.
    pub detection_periods: Option<u64>,
    pub detection_ms: Option<f64>,
    /// PWM periods from the first faulty period to the first period with
    /// the bridge really off (the duties act one period later).
    pub bridge_off_periods: Option<u64>,
    pub first_faults: String,
    pub reaction: Option<String>,
    pub final_faults: String,
    pub final_mode: String,
    pub peak_current_a: f64,
    pub peak_current_after_fault_a: f64,
    pub current_limit_a: f64,
    /// Longest run of periods above the limit + the scenario's margin.
    pub longest_run_over_margin_periods: u64,
    pub stroke_excess_mm: f64,
    pub motor_side_range_m: (f64, f64),
    pub rod_range_m: (f64, f64),
    pub travel_after_latch_mm: Option<f64>,
    /// The farthest the motor side got from where it was at the latch.
    pub excursion_after_latch_mm: Option<f64>,
    pub rod_speed_after_latch_max_m_s: Option<f64>,
    /// The rod's speed when it met an obstacle (the stall's bound after the latch).
    pub impact_speed_m_s: Option<f64>,
    pub rod_speed_end_m_s: f64,
    pub hardware_ocp_period: Option<u64>,
    /// Periods from the fault to the comparator trip.
    pub hardware_ocp_after_periods: Option<u64>,
    pub watchdog_reset_period: Option<u64>,
    pub non_finite: Option<String>,
    pub duty_out_of_range: u64,
    pub limit_flags_seen: u8,
    pub commands: Vec<String>,
    pub violations: Vec<String>,
    pub passed: bool,
}

pub fn summarize(sc: &Scenario, o: &Outcome) -> ScenarioSummary {
    let violations = o.violations(&sc.expect);
    ScenarioSummary {
        name: sc.name,
        what: sc.what,
        expected_faults: names(sc.expect.faults),
        expected_reaction: sc.expect.reaction.map(|m| format!("{m:?}")),
        expected_within_periods: sc.expect.within_periods,
        detection_periods: o.detection_periods(),
        detection_ms: o.detection_s().map(|s| s * 1e3),
        bridge_off_periods: o.bridge_off_periods(),
        first_faults: names(o.first_faults),
        reaction: o.reaction.map(|m| format!("{m:?}")),
        final_faults: names(o.final_faults),
        final_mode: format!("{:?}", o.final_mode),
        peak_current_a: o.peak_current_a,
        peak_current_after_fault_a: o.peak_current_after_fault_a,
        current_limit_a: o.current_limit_a,
        longest_run_over_margin_periods: o.longest_run_over(sc.expect.current_margin_a),
        stroke_excess_mm: o.stroke_excess_m() * 1e3,
        motor_side_range_m: o.motor_side_range_m,
        rod_range_m: o.rod_range_m,
        travel_after_latch_mm: o.travel_after_latch_m.map(|x| x * 1e3),
        excursion_after_latch_mm: o.excursion_after_latch_m().map(|x| x * 1e3),
        rod_speed_after_latch_max_m_s: o.rod_speed_after_latch_max_m_s,
        impact_speed_m_s: o.impact_speed_m_s,
        rod_speed_end_m_s: o.rod_speed_end_m_s,
        hardware_ocp_period: o.hardware_ocp_period,
        hardware_ocp_after_periods: o.hardware_ocp_period.zip(o.fault_period).map(|(h, f)| h.saturating_sub(f)),
        watchdog_reset_period: o.watchdog_reset_period,
        non_finite: o.non_finite.as_ref().map(|(n, w)| format!("{w} at period {n}")),
        duty_out_of_range: o.duty_out_of_range,
        limit_flags_seen: o.limits_seen.bits(),
        commands: o.commands.iter().map(|c| format!("t={:.3}s {:?} → {:?}", c.at_s, c.command, c.result)).collect(),
        passed: violations.is_empty(),
        violations,
    }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(|| "—".into(), |x| x.to_string())
}

/// The measured columns, one row per scenario, as a Markdown table.
pub fn markdown_table(rows: &[ScenarioSummary]) -> String {
    let mut s = String::new();
    s.push_str(
        "| scenario | latched first | detection (periods / ms) | bridge off after (periods) | reaction | comparator after (periods) | peak current after fault (A) | stroke excess (mm) | travel after latch (mm) | meets its requirement |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| `{}` | {} | {} / {} | {} | {} | {} | {:.1} | {:.2} | {} | {} |",
            r.name,
            r.first_faults,
            opt(r.detection_periods),
            opt(r.detection_ms.map(|x| format!("{x:.2}"))),
            opt(r.bridge_off_periods),
            r.reaction.clone().unwrap_or_else(|| "none (rides through)".into()),
            opt(r.hardware_ocp_after_periods),
            r.peak_current_after_fault_a,
            r.stroke_excess_mm,
            opt(r.travel_after_latch_mm.map(|x| format!("{x:.1}"))),
            if r.passed { "yes".to_string() } else { format!("**no**: {}", r.violations.join("; ")) },
        );
    }
    s
}

/// Runs every catalog scenario; writes `summary.json`,
/// `reliability_measured.md` and `trace_<name>.csv` (every 4th period) into
/// `out`. Returns the summaries.
pub fn run_catalog(rig: &RigConfig, out: &Path) -> Result<Vec<ScenarioSummary>> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut rows = vec![];
    for sc in catalog::all(rig) {
        let o = run(&sc)?;
        write_trace(&o, &out.join(format!("trace_{}.csv", sc.name)))?;
        rows.push(summarize(&sc, &o));
    }
    let json = serde_json::json!({
        "command": "faults",
        "setup": "vertical, rated load (1.38 kN), homed at 250 mm; faults at 0.5 s, 0.2 s into a move to 350 mm unless stated",
        "pwm_period_s": 1.0 / f64::from(rig.control.rates.pwm_frequency_hz),
        "scenarios": rows,
        "passed": rows.iter().filter(|r| r.passed).count(),
        "failed": rows.iter().filter(|r| !r.passed).map(|r| r.name).collect::<Vec<_>>(),
    });
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?).with_context(|| format!("writing {}", path.display()))?;
    let path = out.join("reliability_measured.md");
    std::fs::write(&path, markdown_table(&rows)).with_context(|| format!("writing {}", path.display()))?;
    Ok(rows)
}

fn write_trace(o: &Outcome, path: &Path) -> Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
    w.write_record([
        "time_s",
        "peak_phase_current_a",
        "motor_side_position_m",
        "rod_position_m",
        "rod_speed_m_s",
        "faults",
        "mode",
        "bridge_on",
        "short_circuit",
    ])?;
    for r in o.records.iter().step_by(4) {
        w.write_record([
            format!("{:.6}", r.time_s),
            format!("{:.4}", r.peak_phase_current_a),
            format!("{:.7}", r.motor_side_position_m),
            format!("{:.7}", r.rod_position_m),
            format!("{:.5}", r.rod_speed_m_s),
            r.faults.bits().to_string(),
            format!("{:?}", r.mode),
            r.bridge_on.to_string(),
            r.short_circuit.to_string(),
        ])?;
    }
    w.flush()?;
    Ok(())
}
