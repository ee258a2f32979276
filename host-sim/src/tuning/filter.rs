//! The torque filter for a unit of the cylinder, chosen by test moves on
//! that unit: a full-stroke move with the rod vertical under its own load,
//! once per candidate corner, keeping the corner whose worst neighbourhood
//! follows best.
//!
//! The filter trades two things. Too low, its lag at the speed loop's
//! crossover (≈ 40 Hz with the shipped gains, beside the rod's axial mode)
//! eats the margin there; too high, it no longer holds down the rotor-to-
//! screw torsional resonance (≈ 340–870 Hz, lowest at full extension where
//! the screw is longest). A stiffer train and a lighter rotor move both, so
//! one corner does not suit every unit (150 Hz rings on the stiffer corner
//! of the family, 250 Hz on the softer one). The design model cannot place
//! the window: with the coupling's damping alone its torsional peak is
//! unstable at every corner, while the plant is stable over 150–300 Hz, so
//! the damping that decides it is not a parameter the tool knows. Hence a
//! measurement, as an auto-tuner does on the bench.

use crate::config::RigConfig;
use crate::report::metrics;
use crate::scenario::{run_stroke_cycle, StrokeCycle};
use anyhow::{bail, Result};

/// The corners tried, Hz.
pub const CANDIDATES_HZ: [f64; 13] = [100.0, 125.0, 150.0, 175.0, 200.0, 225.0, 250.0, 275.0, 300.0, 325.0, 350.0, 375.0, 400.0];

/// A corner is acceptable when its test move follows within this factor
/// of the best corner's RMS: inside the window the RMS is flat (the
/// feedforward does the tracking), at its edges it rises by tens of times.
pub const ACCEPT_RMS_FACTOR: f64 = 1.25;

/// The test move: 0 → 0.5 m (the whole stroke) and back, the rod
/// vertical, rated payload, the drive's own trajectory limits.
pub fn test_move(seed: u64) -> StrokeCycle {
    StrokeCycle { top_m: 0.5, tilt_swing_deg: 0.0, payload_scale: 1.0, settle_s: 0.3, dwell_s: 0.3, seed, compensation: false }
}

/// One corner's test move.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Trial {
    pub torque_filter_hz: f64,
    /// Motor-side following error over the move, µm (reference − motor
    /// position); `None` when the move stopped on a fault.
    pub tracking_rms_um: Option<f64>,
    pub tracking_max_um: Option<f64>,
    pub peak_phase_current_a: Option<f64>,
    /// Within `ACCEPT_RMS_FACTOR` of the best corner's RMS.
    pub acceptable: bool,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct FilterChoice {
    pub torque_filter_hz: f64,
    /// The acceptable window the choice sits in the middle of, Hz.
    pub window_hz: (f64, f64),
    pub torque_filter_before_hz: f64,
    pub trials: Vec<Trial>,
}

/// Runs the test move at every candidate corner on `rig` (sensor noise
/// from `seed`) and returns the choice; the rig's other parameters stay.
pub fn choose_torque_filter(rig: &RigConfig, seed: u64) -> Result<FilterChoice> {
    let cycle = test_move(seed);
    let mut trials: Vec<Trial> = CANDIDATES_HZ
        .iter()
        .map(|&f| {
            let mut r = rig.clone();
            r.control.torque_filter_hz = f as f32;
            let ok = r.control.validate().is_ok();
            let run = if ok { run_stroke_cycle(&r, &cycle).ok().filter(|t| t.aborted.is_none()) } else { None };
            let s = run.map(|t| metrics::paper_summary(&t, seed, cycle.settle_s));
            Trial {
                torque_filter_hz: f,
                tracking_rms_um: s.as_ref().map(|s| s.motor_tracking_rms_um),
                tracking_max_um: s.as_ref().map(|s| s.motor_tracking_max_um),
                peak_phase_current_a: s.as_ref().map(|s| s.peak_phase_current_a),
                acceptable: false,
            }
        })
        .collect();
    let best_rms = trials.iter().filter_map(|t| t.tracking_rms_um).fold(f64::INFINITY, f64::min);
    if !best_rms.is_finite() {
        bail!("no torque filter corner of {CANDIDATES_HZ:?} Hz lets the test move finish on this rig");
    }
    for t in &mut trials {
        t.acceptable = t.tracking_rms_um.is_some_and(|r| r <= ACCEPT_RMS_FACTOR * best_rms);
    }
    // The widest run of acceptable corners, and the corner nearest its
    // geometric middle: as far from both edges as the grid allows.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for (k, t) in trials.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if t.acceptable && r.1 + 1 == k => r.1 = k,
            _ if t.acceptable => runs.push((k, k)),
            _ => {}
        }
    }
    let widest = runs.iter().copied().max_by_key(|r| r.1 - r.0).unwrap_or((0, 0));
    let (lo, hi) = (trials[widest.0].torque_filter_hz, trials[widest.1].torque_filter_hz);
    let middle = (lo * hi).sqrt();
    let pick = trials[widest.0..=widest.1]
        .iter()
        .min_by(|a, b| (a.torque_filter_hz.ln() - middle.ln()).abs().total_cmp(&(b.torque_filter_hz.ln() - middle.ln()).abs()))
        .map_or(lo, |t| t.torque_filter_hz);
    Ok(FilterChoice { torque_filter_hz: pick, window_hz: (lo, hi), torque_filter_before_hz: f64::from(rig.control.torque_filter_hz), trials })
}

/// `rig` with the chosen torque filter in its `[control]`, and the choice.
pub fn retune(rig: &RigConfig, seed: u64) -> Result<(RigConfig, FilterChoice)> {
    let c = choose_torque_filter(rig, seed)?;
    let mut out = rig.clone();
    out.control.torque_filter_hz = c.torque_filter_hz as f32;
    Ok((out, c))
}
