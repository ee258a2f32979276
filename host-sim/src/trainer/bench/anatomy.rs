//! Figure group "anatomy": where the error left by the shipped weights
//! comes from on each rig, and what the observer's inputs could do at all.
//! No bar: it is the measurement that says whether the inputs or the
//! training are the limit.
//!
//! With compensation on, the motor is commanded `reference + shift`, so
//! `terminal − reference = (terminal − motor) + shift − (command − motor)`:
//! - `prediction_miss` = `(terminal − motor) + shift`: what the observer
//!   got wrong (the shift is minus its prediction, rate-limited);
//! - `lag` = `command − motor`: what the speed and position loops leave.
//!
//! The terminal error itself, `terminal − motor`, is split into the screw
//! and rod's static axial deflection at the measured axial force and stroke
//! (the plant's own compliance law, `plant::deformation`), the lead error
//! of the rig's screw at that stroke, and the rest (torsion, lost motion,
//! the rod mode ringing).
//!
//! Three oracles, none available to a drive:
//! - `oracle_static_map`: the firmware's network (8 units) fitted on the
//!   evaluation run itself (its off and on legs), then run closed-loop: the
//!   best a static map of the four inputs does on this very trajectory;
//! - `oracle_with_travel_direction`: the same with the fifth input, the
//!   direction of travel: what that input can add at best;
//! - `shipped_times_true_compliance`: the shipped prediction scaled by the
//!   rig's true compliance ratio (1 / stiffness draw): what an exactly
//!   known stiffness, scaling the prediction, would buy.

use super::eval::{evaluate, Row};
use super::rigs::BenchRig;
use crate::config::RigConfig;
use crate::plant::deformation::Compliance;
use crate::scenario::stroke_cycle::run_stroke_cycle_with;
use crate::scenario::{run_stroke_cycle, Direction as Leg, RunTrace, StrokeCycle};
use crate::trainer::dataset::{Dataset, Direction, Run, SplitSpec, N_INPUTS, STATIC_INPUTS};
use crate::trainer::{codegen::to_core_model, train_dataset, DataSource, TrainOptions};
use anyhow::{Context, Result};
use rayon::prelude::*;
use servo_core::compensation::Compensator;
use servo_core::observer::block::{Weights, COMPILED};
use servo_core::observer::model::HIDDEN;
use std::path::PathBuf;

pub fn run(rigs: &[BenchRig], seed: u64) -> Result<Vec<Row>> {
    rigs.par_iter()
        .map(|r| {
            let (tuned, _) = crate::tuning::identify_friction_sim(&r.rig, r.seed).with_context(|| r.name)?;
            let mut row = evaluate(r.name, &tuned, None, seed, None)?;
            let cycle = StrokeCycle::paper(seed);
            let off = run_stroke_cycle(&tuned, &cycle)?;
            let on = run_stroke_cycle_with(&tuned, &StrokeCycle { compensation: true, ..cycle.clone() }, None)?;
            let parts = split_error(&tuned, r.draw.lead_error_m_per_m, &on, cycle.settle_s);
            let open_loop_shipped = open_loop_miss_um(&tuned, &COMPILED, &off, cycle.settle_s);
            let oracle = oracle_weights(&tuned, &off, &on, r.name, STATIC_INPUTS)?;
            let oracle_open = open_loop_miss_um(&tuned, oracle, &off, cycle.settle_s);
            let oracle_row = evaluate(r.name, &tuned, Some(oracle), seed, None)?;
            let oracle5 = oracle_weights(&tuned, &off, &on, r.name, N_INPUTS)?;
            let oracle5_open = open_loop_miss_um(&tuned, oracle5, &off, cycle.settle_s);
            let oracle5_row = evaluate(r.name, &tuned, Some(oracle5), seed, None)?;
            let scaled = scaled_weights(&COMPILED, 1.0 / r.draw.stiffness);
            let scaled_row = evaluate(r.name, &tuned, Some(scaled), seed, None)?;
            row.details = serde_json::json!({
                "worst_with_shipped": parts,
                "open_loop_max_miss_um": { "shipped": open_loop_shipped, "oracle_static_map": oracle_open, "oracle_with_travel_direction": oracle5_open },
                "oracle_static_map": { "reduction_pct": oracle_row.reduction_pct, "terminal_error_max_um_on": oracle_row.terminal_error_max_um_on, "worst_on": oracle_row.worst_on },
                "oracle_with_travel_direction": { "reduction_pct": oracle5_row.reduction_pct, "terminal_error_max_um_on": oracle5_row.terminal_error_max_um_on, "worst_on": oracle5_row.worst_on },
                "shipped_times_true_compliance": { "compliance_ratio": 1.0 / r.draw.stiffness, "reduction_pct": scaled_row.reduction_pct, "terminal_error_max_um_on": scaled_row.terminal_error_max_um_on },
            });
            Ok(row)
        })
        .collect()
}

/// The decomposition at the worst sample of `on` and each part's largest
/// magnitude over the run (µm).
fn split_error(rig: &RigConfig, lead_error_m_per_m: f64, on: &RunTrace, settle_s: f64) -> serde_json::Value {
    let c = Compliance::new(&rig.plant);
    let parts = |t: &servo_core::telemetry::Telemetry, x: &crate::sim::TruthRecord| {
        let error = x.terminal_position_m - f64::from(t.position_reference_m);
        let deformation = x.terminal_position_m - x.motor_side_position_m;
        let shift = f64::from(t.position_shift_m);
        let lag = f64::from(t.position_command_m) - x.motor_side_position_m;
        let stroke = x.motor_side_position_m;
        // The drive train compresses under a positive (pushing) force: the
        // rod ends short of the motor side by the deflection.
        let axial = -c.axial_deflection_m(x.axial_force_n, stroke);
        let lead = lead_error_m_per_m * stroke;
        [error, deformation + shift, lag, deformation, axial, lead, deformation - axial - lead]
    };
    let names = ["error", "prediction_miss", "lag", "terminal_error", "static_axial_deflection", "lead_error", "rest"];
    let samples: Vec<_> = on.telemetry.iter().zip(&on.truth).filter(|(_, x)| x.time_s >= settle_s).collect();
    let worst = samples.iter().max_by(|a, b| parts(a.0, a.1)[0].abs().total_cmp(&parts(b.0, b.1)[0].abs()));
    let mut at_worst = serde_json::Map::new();
    if let Some((t, x)) = worst {
        at_worst.insert("time_s".into(), x.time_s.into());
        at_worst.insert("reference_m".into(), f64::from(t.position_reference_m).into());
        at_worst.insert("speed_reference_rad_s".into(), f64::from(t.speed_reference_rad_s).into());
        at_worst.insert("axial_force_n".into(), x.axial_force_n.into());
        for (n, v) in names.iter().zip(parts(t, x)) {
            at_worst.insert(format!("{n}_um"), (v * 1e6).into());
        }
    }
    let mut largest = serde_json::Map::new();
    for (k, n) in names.iter().enumerate() {
        let m = samples.iter().map(|(t, x)| parts(t, x)[k].abs()).fold(0.0, f64::max);
        largest.insert(format!("{n}_um"), (m * 1e6).into());
    }
    serde_json::json!({ "at_worst": at_worst, "largest_over_run": largest })
}

/// The largest |terminal error − prediction| of `w` on the inputs the drive
/// had in `off` (observer off: nothing feeds back), µm.
fn open_loop_miss_um(rig: &RigConfig, w: &Weights, off: &RunTrace, settle_s: f64) -> f64 {
    let travel = travel_directions(off);
    off.telemetry
        .iter()
        .zip(&off.truth)
        .zip(&travel)
        .filter(|((_, x), _)| x.time_s >= settle_s)
        .map(|((t, x), &d)| {
            let inputs = Compensator::inputs(&rig.control, t.speed_rad_s, t.motor_position_m, t.load_force_estimate_n, d as f32);
            let p = f64::from(servo_core::observer::predict(w, inputs));
            ((x.terminal_position_m - x.motor_side_position_m) - p).abs() * 1e6
        })
        .fold(0.0, f64::max)
}

/// The direction of travel at each telemetry sample, as the drive forms it
/// (the sign of the planned position's change, held at rest).
fn travel_directions(trace: &RunTrace) -> Vec<f64> {
    let mut held = 0.0;
    let mut last: Option<f32> = None;
    trace
        .telemetry
        .iter()
        .map(|t| {
            if let Some(l) = last {
                let d = t.position_reference_m - l;
                held = if d > 0.0 { 1.0 } else if d < 0.0 { -1.0 } else { held };
            }
            last = Some(t.position_reference_m);
            held
        })
        .collect()
}

/// The evaluation run's moving samples as trainer runs (one per leg).
fn legs(rig: &RigConfig, trace: &RunTrace, tag: &str) -> Vec<Run> {
    let travel = travel_directions(trace);
    let lead = f64::from(rig.control.drive_train.screw_lead_m);
    [(Leg::Elongation, Direction::Elongation), (Leg::Contraction, Direction::Contraction)]
        .into_iter()
        .map(|(leg, direction)| {
            let mut run = Run {
                id: format!("{tag}-{}", direction.name()),
                direction,
                tilt_swing_deg: f64::NAN,
                payload_scale: f64::NAN,
                source: PathBuf::from("evaluation run"),
                first_line: 0,
                time_s: vec![],
                inputs: vec![],
                terminal_length_m: vec![],
                motor_side_position_m: vec![],
                terminal_error_m: vec![],
            };
            for ((t, x), &d) in trace.telemetry.iter().zip(&trace.truth).zip(&travel).filter(|((_, x), _)| x.direction == leg) {
                let Some(scale) = t.terminal_position_m else { continue };
                let w = f64::from(t.speed_rad_s);
                let motor = f64::from(t.motor_position_m);
                let input: [f64; N_INPUTS] = [w, w * lead / std::f64::consts::TAU, motor, f64::from(t.load_force_estimate_n), d];
                run.time_s.push(x.time_s);
                run.inputs.push(input);
                run.terminal_length_m.push(f64::NAN);
                run.motor_side_position_m.push(motor);
                run.terminal_error_m.push(f64::from(scale) - motor);
            }
            run
        })
        .collect()
}

/// The firmware's network fitted on the evaluation run itself. Each leg is
/// given twice, so the split's held-out test leg still leaves every leg in
/// training: an oracle, not a model. `inputs`: 4, or 5 with the direction
/// of travel.
fn oracle_weights(rig: &RigConfig, off: &RunTrace, on: &RunTrace, name: &str, inputs: usize) -> Result<&'static Weights> {
    let mut runs = legs(rig, off, "off");
    runs.extend(legs(rig, on, "on"));
    runs.extend(legs(rig, off, "off-copy"));
    runs.extend(legs(rig, on, "on-copy"));
    let ds = Dataset::from_runs(&format!("{name} evaluation run (oracle)"), runs).with_inputs(inputs);
    let mut o = TrainOptions::new(DataSource::Synthetic { runs: 0 });
    o.hidden = vec![HIDDEN];
    o.validation_fraction = 0.0;
    o.split = SplitSpec::Mixed { test_fraction: 0.25 };
    o.max_train_samples = 8000;
    let report = train_dataset(&ds, &o).with_context(|| format!("{name}: oracle fit"))?;
    Ok(Box::leak(Box::new(to_core_model::<HIDDEN>(&report.model)?)))
}

/// `w` with its prediction scaled by `k` (output scale and offset).
pub fn scaled_weights(w: &Weights, k: f64) -> &'static Weights {
    let mut s = *w;
    s.output_scale = (f64::from(s.output_scale) * k) as f32;
    s.output_offset = (f64::from(s.output_offset) * k) as f32;
    Box::leak(Box::new(s))
}
