//! The paper's run over a rig family: tracking on every rig, a row per
//! rig, the worst case over the family.

use super::{run_stroke_cycle, StrokeCycle};
use crate::report::{self, metrics};
use crate::rigs::family::{write_family_report, RigRow, Worst};
use crate::rigs::FamilyRig;
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::path::Path;

/// Motor-side tracking a rig must hold in the paper's run (RMS, max), µm.
pub const TRACKING_RMS_MAX_UM: f64 = 5.0;
pub const TRACKING_MAX_MAX_UM: f64 = 50.0;

/// What a paper run misses of its requirement (empty: met); the family
/// mode and the single-rig `paper` judge a rig by the same words.
pub fn misses(s: &metrics::PaperSummary) -> Vec<String> {
    let mut why = vec![];
    if let Some(a) = &s.aborted {
        why.push(format!("stopped early: {a}"));
    }
    if !(s.motor_tracking_rms_um <= TRACKING_RMS_MAX_UM) {
        why.push(format!("motor-side RMS {:.2} µm > {TRACKING_RMS_MAX_UM}", s.motor_tracking_rms_um));
    }
    if !(s.motor_tracking_max_um <= TRACKING_MAX_MAX_UM) {
        why.push(format!("motor-side max {:.1} µm > {TRACKING_MAX_MAX_UM}", s.motor_tracking_max_um));
    }
    why
}

/// The paper's run (sensor noise from `seed`) on each rig of `family`,
/// rigs in parallel; each rig's summary in `out/<rig>/`, the family's in `out`.
/// `tune_filter`: each rig's torque filter chosen first by its own test
/// moves (`tuning::filter`), as a bench engineer tunes a unit before use.
pub fn run_family(family: &[FamilyRig], family_dir: &Path, seed: u64, tune_filter: bool, out: &Path) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let cycle = StrokeCycle::paper(seed);
    let rows = family
        .par_iter()
        .map(|r| {
            let dir = out.join(&r.name);
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            let (rig, filter_hz) = tuned(r, seed, tune_filter, &dir)?;
            let trace = run_stroke_cycle(&rig, &cycle).with_context(|| r.name.clone())?;
            let s = metrics::paper_summary(&trace, seed, cycle.settle_s);
            report::write_summary(&s, &dir)?;
            let why = misses(&s);
            Ok(RigRow {
                rig: r.name.clone(),
                passed: why.is_empty(),
                verdict: if why.is_empty() { "ok".into() } else { why.join("; ") },
                figures: vec![
                    ("motor_tracking_rms_um".into(), Some(s.motor_tracking_rms_um)),
                    ("motor_tracking_max_um".into(), Some(s.motor_tracking_max_um)),
                    ("enable_sag_max_um".into(), Some(s.enable_sag_max_um)),
                    ("terminal_error_max_mm".into(), Some(s.terminal_error_max_mm)),
                    ("peak_phase_current_a".into(), Some(s.peak_phase_current_a)),
                    ("torque_filter_hz".into(), Some(filter_hz)),
                ],
            })
        })
        .collect::<Result<Vec<_>>>()?;
    write_family_report(
        "paper",
        family_dir,
        &rows,
        &[
            ("motor_tracking_rms_um", Worst::Max),
            ("motor_tracking_max_um", Worst::Max),
            ("enable_sag_max_um", Worst::Max),
            ("terminal_error_max_mm", Worst::Max),
            ("peak_phase_current_a", Worst::Max),
        ],
        serde_json::json!({ "seed": seed, "tune_filter": tune_filter, "tracking_rms_max_um": TRACKING_RMS_MAX_UM, "tracking_max_max_um": TRACKING_MAX_MAX_UM }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}

/// The rig as a family mode runs it: with its torque filter chosen by its
/// test moves when `tune_filter` (the choice written to
/// `dir/torque_filter.json`), else as its file says; and that filter, Hz.
pub fn tuned(r: &FamilyRig, seed: u64, tune_filter: bool, dir: &Path) -> Result<(crate::config::RigConfig, f64)> {
    if !tune_filter {
        return Ok((r.rig.clone(), f64::from(r.rig.control.torque_filter_hz)));
    }
    let (rig, choice) = crate::tuning::filter::retune(&r.rig, seed).with_context(|| format!("{}: choosing the torque filter", r.name))?;
    let path = dir.join("torque_filter.json");
    std::fs::write(&path, serde_json::to_string_pretty(&choice)?).with_context(|| format!("writing {}", path.display()))?;
    Ok((rig, choice.torque_filter_hz))
}
