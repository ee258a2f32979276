//! The power-up suite over a rig family: the same cases on every rig, a
//! row per rig, the worst case over the family.

use super::{run_case, suite, CaseResult, Failure};
use crate::rigs::family::{write_family_report, RigRow, Worst};
use crate::rigs::FamilyRig;
use anyhow::Result;
use rayon::prelude::*;
use std::path::Path;

/// Runs `power_ups` successful power-ups and every failure case on each
/// rig of `family` (cases drawn once from `seed`, rods in `rod_m`), writes
/// each rig's own report to `out/<rig>/` and the family's to `out`.
pub fn run_family(
    family: &[FamilyRig],
    family_dir: &Path,
    power_ups: usize,
    rod_m: (f64, f64),
    seed: u64,
    tune_filter: bool,
    out: &Path,
) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let mut rows = vec![];
    for r in family {
        let dir = out.join(&r.name);
        std::fs::create_dir_all(&dir)?;
        let (rig, _) = crate::scenario::family::tuned(r, seed, tune_filter, &dir)?;
        let cases = suite(power_ups, rod_m.0, rod_m.1, rig.plant.screw.lead_m, seed);
        let results = cases.par_iter().map(|c| run_case(&rig, c)).collect::<Result<Vec<_>>>()?;
        let summary = super::summarise(&results, &[], 0.0);
        super::write_report(&summary, &results, &out.join(&r.name))?;
        rows.push(row(&r.name, &results));
    }
    write_family_report(
        "power-up",
        family_dir,
        &rows,
        &[
            ("cases_passed", Worst::Min),
            ("false_refusals", Worst::Max),
            ("failures_missed", Worst::Max),
            ("rotation_ratio_right_min", Worst::Min),
            ("rotation_ratio_right_max", Worst::Max),
            ("rotation_ratio_wrong_poles", Worst::Min),
            ("failure_rod_drop_max_mm", Worst::Max),
            ("rod_movement_max_mm", Worst::Max),
            ("electrical_offset_error_max_deg", Worst::Max),
            ("enable_sag_max_um", Worst::Max),
            ("hold_error_pp_max_um", Worst::Max),
            ("hold_current_pp_max_a", Worst::Max),
            ("time_to_ready_max_s", Worst::Max),
        ],
        serde_json::json!({ "power_ups_per_rig": power_ups, "failure_cases_per_rig": Failure::ALL.len(), "seed": seed, "tune_filter": tune_filter }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}

fn row(rig: &str, results: &[CaseResult]) -> RigRow {
    let ok: Vec<&CaseResult> = results.iter().filter(|r| r.failure == Failure::None).collect();
    let bad: Vec<&CaseResult> = results.iter().filter(|r| r.failure != Failure::None).collect();
    let max = |v: &mut dyn Iterator<Item = f64>| v.fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))));
    let min = |v: &mut dyn Iterator<Item = f64>| v.fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.min(x))));
    let ratios = || ok.iter().filter(|r| r.rotation_ratio != 0.0).map(|r| r.rotation_ratio);
    let failed: Vec<String> = results.iter().filter(|r| !r.passed).map(|r| format!("{}: {}", r.name, r.verdict)).collect();
    RigRow {
        rig: rig.to_string(),
        passed: failed.is_empty(),
        verdict: if failed.is_empty() { "ok".into() } else { failed.join("; ") },
        figures: vec![
            ("cases".into(), Some(results.len() as f64)),
            ("cases_passed".into(), Some(results.iter().filter(|r| r.passed).count() as f64)),
            ("false_refusals".into(), Some(ok.iter().filter(|r| r.time_to_ready_s.is_none()).count() as f64)),
            ("failures_missed".into(), Some(bad.iter().filter(|r| !r.passed).count() as f64)),
            ("rotation_ratio_right_min".into(), min(&mut ratios())),
            ("rotation_ratio_right_max".into(), max(&mut ratios())),
            (
                "rotation_ratio_wrong_poles".into(),
                bad.iter().find(|r| r.failure == Failure::WrongPolePairs).map(|r| r.rotation_ratio),
            ),
            ("failure_rod_drop_max_mm".into(), max(&mut bad.iter().map(|r| r.rod_drop_max_mm))),
            ("rod_movement_max_mm".into(), max(&mut ok.iter().map(|r| r.rod_movement_max_mm))),
            ("electrical_offset_error_max_deg".into(), max(&mut ok.iter().filter_map(|r| r.electrical_offset_error_deg))),
            ("enable_sag_max_um".into(), max(&mut ok.iter().filter_map(|r| r.enable_sag_um))),
            ("hold_error_pp_max_um".into(), max(&mut ok.iter().filter_map(|r| r.hold_error_pp_um))),
            ("hold_current_pp_max_a".into(), max(&mut ok.iter().filter_map(|r| r.hold_current_pp_a))),
            ("time_to_ready_max_s".into(), max(&mut ok.iter().filter_map(|r| r.time_to_ready_s))),
        ],
    }
}
