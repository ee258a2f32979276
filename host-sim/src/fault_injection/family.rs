//! The fault catalogue over a rig family: every scenario on every rig, a
//! row per rig, the worst case over the family.

use super::report::{run_catalog, ScenarioSummary};
use crate::rigs::family::{write_family_report, RigRow, Worst};
use crate::rigs::FamilyRig;
use anyhow::Result;
use rayon::prelude::*;
use std::path::Path;

/// Runs the catalogue on each rig of `family` (rigs in parallel), each
/// into `out/<rig>/`, and writes the family's report to `out`.
pub fn run_family(family: &[FamilyRig], family_dir: &Path, out: &Path) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let per_rig = family.par_iter().map(|r| run_catalog(&r.rig, &out.join(&r.name))).collect::<Result<Vec<_>>>()?;
    let rows: Vec<RigRow> = family.iter().zip(&per_rig).map(|(r, s)| row(&r.name, s)).collect();
    write_family_report(
        "faults",
        family_dir,
        &rows,
        &[
            ("scenarios_passed", Worst::Min),
            ("stall_rod_speed_after_latch_m_s", Worst::Max),
            ("stall_rod_speed_after_latch_over_impact", Worst::Max),
            ("stall_travel_after_latch_mm", Worst::Max),
            ("load_beyond_rating_travel_after_latch_mm", Worst::Max),
            ("load_beyond_rating_detection_periods", Worst::Max),
            ("stroke_excess_max_mm", Worst::Max),
            ("peak_current_after_fault_max_a", Worst::Max),
        ],
        serde_json::json!({ "scenarios_per_rig": per_rig.first().map_or(0, Vec::len) }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}

fn row(rig: &str, s: &[ScenarioSummary]) -> RigRow {
    let failed: Vec<String> = s.iter().filter(|r| !r.passed).map(|r| format!("{}: {}", r.name, r.violations.join(", "))).collect();
    let stall = s.iter().find(|r| r.name == "stall");
    let beyond = s.iter().find(|r| r.name == "load_beyond_rating");
    let max = |f: &dyn Fn(&ScenarioSummary) -> f64| s.iter().map(f).fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))));
    RigRow {
        rig: rig.to_string(),
        passed: failed.is_empty(),
        verdict: if failed.is_empty() { "ok".into() } else { failed.join("; ") },
        figures: vec![
            ("scenarios".into(), Some(s.len() as f64)),
            ("scenarios_passed".into(), Some(s.iter().filter(|r| r.passed).count() as f64)),
            ("stall_rod_speed_after_latch_m_s".into(), stall.and_then(|r| r.rod_speed_after_latch_max_m_s)),
            (
                "stall_rod_speed_after_latch_over_impact".into(),
                stall.and_then(|r| Some(r.rod_speed_after_latch_max_m_s? / r.impact_speed_m_s?)),
            ),
            ("stall_travel_after_latch_mm".into(), stall.and_then(|r| r.travel_after_latch_mm).map(f64::abs)),
            ("load_beyond_rating_travel_after_latch_mm".into(), beyond.and_then(|r| r.excursion_after_latch_mm)),
            ("load_beyond_rating_detection_periods".into(), beyond.and_then(|r| r.detection_periods).map(|n| n as f64)),
            ("stroke_excess_max_mm".into(), max(&|r| r.stroke_excess_mm)),
            ("peak_current_after_fault_max_a".into(), max(&|r| r.peak_current_after_fault_a)),
        ],
    }
}
