//! Observer datasets: the paper's elongation/contraction cycle run
//! closed-loop at several tilt swings and payloads; every sample holds what
//! the firmware itself has (encoder speed, nut speed and displacement through
//! the lead, load force from i_q or the load cell) and, as the target, what
//! the test rig's grating scale adds (terminal error and terminal length).
//!
//! Each leg of each cycle is one run: splits are by run, never by sample.

use super::stroke_cycle::{run_stroke_cycle, Direction, StrokeCycle};
use crate::config::RigConfig;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::path::Path;

/// Table 3 of the paper: the leg's length with the rod retracted. Terminal
/// length = this + terminal position, which keeps MAPE on length finite.
pub const LEG_BASE_LENGTH_M: f64 = 0.60;

/// One dataset row; the column names are the trainer's contract.
#[derive(Clone, Debug, Serialize)]
pub struct DatasetRow {
    pub run_id: u32,
    pub direction: Direction,
    pub tilt_swing_deg: f64,
    pub payload_scale: f64,
    pub time_s: f64,
    pub motor_speed_rad_s: f64,
    pub nut_speed_m_s: f64,
    pub nut_displacement_m: f64,
    pub load_force_n: f64,
    pub terminal_length_m: f64,
    pub motor_side_position_m: f64,
    pub terminal_error_m: f64,
}

/// Which cycles make up a dataset.
#[derive(Clone, Debug)]
pub struct DatasetSpec {
    pub tilt_swings_deg: Vec<f64>,
    pub payload_scales: Vec<f64>,
    pub seed: u64,
}

impl Default for DatasetSpec {
    /// 4 tilt swings × 3 payloads = 12 cycles, 24 runs: swings up to 40°
    /// (the paper's 30° inside the range), payloads from half to full rated.
    fn default() -> Self {
        Self { tilt_swings_deg: vec![10.0, 20.0, 30.0, 40.0], payload_scales: vec![0.5, 0.75, 1.0], seed: 11 }
    }
}

/// Runs every cycle of `spec` and returns the rows of the moving legs.
pub fn generate(rig: &RigConfig, spec: &DatasetSpec) -> Result<Vec<DatasetRow>> {
    if !rig.plant.sensors.linear_scale_enabled {
        bail!("the rig has no linear scale ([plant.sensors] linear_scale_enabled = false): no target to learn");
    }
    let lead = f64::from(rig.control.drive_train.screw_lead_m);
    let mut rows = Vec::new();
    let mut run_id = 0u32;
    for (i, &swing) in spec.tilt_swings_deg.iter().enumerate() {
        for (j, &payload) in spec.payload_scales.iter().enumerate() {
            let cycle = StrokeCycle {
                tilt_swing_deg: swing,
                payload_scale: payload,
                seed: spec.seed.wrapping_mul(1000).wrapping_add((i * 100 + j) as u64),
                ..StrokeCycle::paper(0)
            };
            let trace = run_stroke_cycle(rig, &cycle).with_context(|| format!("cycle tilt ±{swing}°, payload ×{payload}"))?;
            if let Some(why) = &trace.aborted {
                bail!("cycle tilt ±{swing}°, payload ×{payload} stopped early: {why}");
            }
            for leg in [Direction::Elongation, Direction::Contraction] {
                for (t, x) in trace.telemetry.iter().zip(&trace.truth).filter(|(_, x)| x.direction == leg) {
                    let Some(scale_m) = t.terminal_position_m else {
                        bail!("telemetry at t = {} s has no linear-scale reading", t.time_s);
                    };
                    let speed = f64::from(t.speed_rad_s);
                    let motor_side = f64::from(t.motor_position_m);
                    let scale = f64::from(scale_m);
                    rows.push(DatasetRow {
                        run_id,
                        direction: leg,
                        tilt_swing_deg: swing,
                        payload_scale: payload,
                        time_s: x.time_s,
                        motor_speed_rad_s: speed,
                        nut_speed_m_s: speed * lead / (2.0 * std::f64::consts::PI),
                        nut_displacement_m: motor_side,
                        load_force_n: f64::from(t.load_force_estimate_n),
                        terminal_length_m: LEG_BASE_LENGTH_M + scale,
                        motor_side_position_m: motor_side,
                        terminal_error_m: scale - motor_side,
                    });
                }
                run_id += 1;
            }
        }
    }
    Ok(rows)
}

/// Writes `rows` as CSV.
pub fn write_csv(rows: &[DatasetRow], path: &Path) -> Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    for r in rows {
        w.serialize(r).with_context(|| format!("writing {}", path.display()))?;
    }
    w.flush()?;
    Ok(())
}
