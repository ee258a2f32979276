//! `drive bench-stream --family DIR`: the paper run's reference streamed
//! at 1 kHz to a simulated drive of every rig of a family, a row per rig,
//! the worst case over the family.

use super::bench::stream_and_capture;
use crate::rigs::family::{write_family_report, RigRow, Worst};
use crate::rigs::FamilyRig;
use crate::scenario::family::{tuned, TRACKING_MAX_MAX_UM, TRACKING_RMS_MAX_UM};
use anyhow::{Context, Result};
use std::path::Path;

/// What a streamed run (`stream_and_capture`'s summary) misses of its
/// requirement (empty: met); the family mode and the single-rig
/// `drive bench-stream` judge a rig by the same words.
pub fn misses(s: &serde_json::Value) -> Vec<String> {
    let (rms, max) = (s["motor_tracking_rms_um"].as_f64(), s["motor_tracking_max_um"].as_f64());
    let refusals = s["refusals"].as_u64().unwrap_or(0);
    let faults: Vec<String> = s["faults"].as_array().into_iter().flatten().filter_map(|f| f.as_str().map(String::from)).collect();
    let mut why = vec![];
    if refusals > 0 {
        why.push(format!("{refusals} setpoints refused"));
    }
    if !faults.is_empty() {
        why.push(format!("faults {}", faults.join(", ")));
    }
    match rms {
        Some(v) if v <= TRACKING_RMS_MAX_UM => {}
        v => why.push(format!("motor-side RMS {:.2} µm > {TRACKING_RMS_MAX_UM}", v.unwrap_or(f64::NAN))),
    }
    match max {
        Some(v) if v <= TRACKING_MAX_MAX_UM => {}
        v => why.push(format!("motor-side max {:.1} µm > {TRACKING_MAX_MAX_UM}", v.unwrap_or(f64::NAN))),
    }
    why
}

/// The stream on each rig in turn (each serves its own simulated drive on a
/// local port); each rig's summary in `out/<rig>/`. `tune_filter`: each
/// rig's torque filter chosen first by its own test moves.
pub fn run_family(family: &[FamilyRig], family_dir: &Path, tune_filter: bool, out: &Path) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let mut rows = Vec::new();
    for r in family {
        let dir = out.join(&r.name);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let (rig, filter_hz) = tuned(r, 1, tune_filter, &dir)?;
        let s = stream_and_capture(&rig, &dir).with_context(|| r.name.clone())?;
        std::fs::write(dir.join("summary.json"), serde_json::to_string_pretty(&s)?)?;
        let (rms, max) = (s["motor_tracking_rms_um"].as_f64(), s["motor_tracking_max_um"].as_f64());
        let refusals = s["refusals"].as_u64().unwrap_or(0);
        let why = misses(&s);
        rows.push(RigRow {
            rig: r.name.clone(),
            passed: why.is_empty(),
            verdict: if why.is_empty() { "ok".into() } else { why.join("; ") },
            figures: vec![
                ("motor_tracking_rms_um".into(), rms),
                ("motor_tracking_max_um".into(), max),
                ("refusals".into(), Some(refusals as f64)),
                ("torque_filter_hz".into(), Some(filter_hz)),
            ],
        });
    }
    write_family_report(
        "drive bench-stream",
        family_dir,
        &rows,
        &[("motor_tracking_rms_um", Worst::Max), ("motor_tracking_max_um", Worst::Max), ("refusals", Worst::Max)],
        serde_json::json!({ "tune_filter": tune_filter, "stream_rate_hz": 1000.0, "tracking_rms_max_um": TRACKING_RMS_MAX_UM, "tracking_max_max_um": TRACKING_MAX_MAX_UM }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}
