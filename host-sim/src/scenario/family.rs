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

/// The paper's run (sensor noise from `seed`) on each rig of `family`,
/// rigs in parallel; each rig's summary in `out/<rig>/`, the family's in `out`.
pub fn run_family(family: &[FamilyRig], family_dir: &Path, seed: u64, out: &Path) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let cycle = StrokeCycle::paper(seed);
    let rows = family
        .par_iter()
        .map(|r| {
            let trace = run_stroke_cycle(&r.rig, &cycle).with_context(|| r.name.clone())?;
            let s = metrics::paper_summary(&trace, seed, cycle.settle_s);
            let dir = out.join(&r.name);
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            report::write_summary(&s, &dir)?;
            let mut why = vec![];
            if let Some(a) = &s.aborted {
                why.push(format!("stopped early: {a}"));
            }
            if s.motor_tracking_rms_um > TRACKING_RMS_MAX_UM {
                why.push(format!("motor-side RMS {:.2} µm > {TRACKING_RMS_MAX_UM}", s.motor_tracking_rms_um));
            }
            if s.motor_tracking_max_um > TRACKING_MAX_MAX_UM {
                why.push(format!("motor-side max {:.1} µm > {TRACKING_MAX_MAX_UM}", s.motor_tracking_max_um));
            }
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
        serde_json::json!({ "seed": seed, "tracking_rms_max_um": TRACKING_RMS_MAX_UM, "tracking_max_max_um": TRACKING_MAX_MAX_UM }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}
