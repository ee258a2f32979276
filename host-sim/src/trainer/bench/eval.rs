//! The evaluation run every figure group uses: the paper's stroke cycle
//! (0 → 450 mm with the tilt 90 → 60 → 90°, back with 90 → 120 → 90°,
//! rated load of the rig) with the observer off and on. No retraining log
//! and no shipped-weights training cycle has this trajectory
//! (docs/observer-figures.md, "Held out by trajectory"), so it is held out by
//! trajectory, and its sensor noise seed is one no training run used.

use crate::config::RigConfig;
use crate::report::metrics;
use crate::scenario::stroke_cycle::run_stroke_cycle_with;
use crate::scenario::{run_stroke_cycle, StrokeCycle};
use anyhow::{bail, Result};
use servo_core::observer::block::Weights;

/// One rig's row of a figure group.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub rig: String,
    /// Largest |terminal − reference| after settling, observer off / on (µm).
    pub terminal_error_max_um_off: f64,
    pub terminal_error_max_um_on: f64,
    pub reduction_pct: f64,
    pub terminal_error_rms_um_on: f64,
    /// Where the worst error with the observer on sits: time (s), reference
    /// position (m), planned speed (m/s), leg, and its share that is
    /// motor-side tracking (reference − motor side, µm).
    pub worst_on: serde_json::Value,
    /// The bar for this rig in this group, if one is asked.
    pub bar_pct: Option<f64>,
    pub passed: Option<bool>,
    /// What the group adds (the route's stages, the friction identified…).
    pub details: serde_json::Value,
}

/// Runs the evaluation cycle on `rig` (its `[control]` as the drive has
/// it) without and with compensation by `weights` (`None`: the compiled
/// model) and fills a row; `bar_pct` decides `passed`.
pub fn evaluate(name: &str, rig: &RigConfig, weights: Option<&'static Weights>, seed: u64, bar_pct: Option<f64>) -> Result<Row> {
    let cycle = StrokeCycle::paper(seed);
    let off = run_stroke_cycle(rig, &cycle)?;
    let on = run_stroke_cycle_with(rig, &StrokeCycle { compensation: true, ..cycle.clone() }, weights)?;
    for (t, what) in [(&off, "observer off"), (&on, "observer on")] {
        if let Some(why) = &t.aborted {
            bail!("{name}: the evaluation run ({what}) stopped early: {why}");
        }
    }
    let f = metrics::observer_figures(&off, &on, cycle.settle_s);
    let worst_on = on
        .telemetry
        .iter()
        .zip(&on.truth)
        .filter(|(_, x)| x.time_s >= cycle.settle_s)
        .map(|(t, x)| (x.terminal_position_m - f64::from(t.position_reference_m), t, x))
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
        .map_or(serde_json::Value::Null, |(e, t, x)| {
            serde_json::json!({
                "error_um": e * 1e6, "time_s": x.time_s, "reference_m": t.position_reference_m,
                "speed_reference_rad_s": t.speed_reference_rad_s, "leg": x.direction,
                "tracking_um": (f64::from(t.position_reference_m) - x.motor_side_position_m) * 1e6,
                "shift_um": f64::from(t.position_shift_m) * 1e6,
            })
        });
    let reduction = f.terminal_error_max_reduction_pct;
    Ok(Row {
        rig: name.to_string(),
        terminal_error_max_um_off: f.terminal_error_max_mm_before * 1e3,
        terminal_error_max_um_on: f.terminal_error_max_mm_after * 1e3,
        reduction_pct: reduction,
        terminal_error_rms_um_on: f.terminal_error_rms_mm_after * 1e3,
        worst_on,
        bar_pct,
        passed: bar_pct.map(|b| reduction >= b),
        details: serde_json::Value::Null,
    })
}
