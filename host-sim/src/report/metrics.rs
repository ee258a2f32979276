//! The paper run's figures, computed from a trace.

use crate::scenario::{Direction, RunTrace};
use serde::Serialize;

/// Root mean square and largest magnitude of a series.
pub fn rms_and_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut sum2, mut max, mut n) = (0.0, 0.0_f64, 0usize);
    for v in values {
        sum2 += v * v;
        max = max.max(v.abs());
        n += 1;
    }
    if n == 0 { (0.0, 0.0) } else { ((sum2 / n as f64).sqrt(), max) }
}

/// `summary.json` of `host-sim paper`.
#[derive(Clone, Debug, Serialize)]
pub struct PaperSummary {
    /// Trajectory reference minus true motor-side position (`L θ_m/2π`), from
    /// the first move to the end (the settle period after enabling is
    /// reported apart, as `enable_sag_max_um`).
    pub motor_tracking_rms_um: f64,
    pub motor_tracking_max_um: f64,
    /// Largest motor-side sag while the speed integrator picks up the load
    /// after enabling (the settle period; a real vertical axis holds a brake
    /// until then).
    pub enable_sag_max_um: f64,
    /// Terminal (piston-rod) position minus the trajectory reference, from
    /// the first move on: what the grating scale shows the loop leaves.
    pub terminal_error_rms_mm: f64,
    pub terminal_error_max_mm: f64,
    /// Terminal minus motor-side position (deformation + lost motion).
    pub deformation_max_mm: f64,
    pub terminal_error_max_elongation_mm: f64,
    pub terminal_error_max_contraction_mm: f64,
    pub peak_phase_current_a: f64,
    /// Largest axial force carried by the screw–nut pair.
    pub peak_thrust_n: f64,
    /// Simulated seconds per wall-clock second.
    pub sim_realtime_factor: f64,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub records: usize,
    pub seed: u64,
    /// Set when the run stopped early; the figures then cover only what ran.
    pub aborted: Option<String>,
    /// With `--observer`: the same run again with compensation on.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub observer: Option<ObserverFigures>,
}

/// Closed-loop effect of the compiled-in observer (`paper --observer`).
#[derive(Clone, Debug, Serialize)]
pub struct ObserverFigures {
    /// The compiled model's held-out RMSE, as the trainer measured it (f64).
    pub observer_rmse_um_heldout: f64,
    pub observer_dataset: String,
    pub terminal_error_max_mm_before: f64,
    pub terminal_error_rms_mm_before: f64,
    pub terminal_error_max_mm_after: f64,
    pub terminal_error_rms_mm_after: f64,
    /// `100·(1 − after/before)` on the maximum terminal error.
    pub terminal_error_max_reduction_pct: f64,
    /// Mean |terminal length − reference length| / reference length, in
    /// percent, over the moving legs; length = leg base (0.60 m, Table 3) +
    /// position, as the paper's Table 2 evidently measures it.
    pub mape_before: f64,
    pub mape_after: f64,
    /// Largest shift the compensation applied.
    pub compensation_max_mm: f64,
    pub compensation_aborted: Option<String>,
}

/// MAPE on terminal length over the moving legs, percent.
pub fn length_mape_pct(trace: &RunTrace) -> f64 {
    use crate::scenario::dataset::LEG_BASE_LENGTH_M;
    let (mut sum, mut n) = (0.0, 0usize);
    for (t, x) in trace.telemetry.iter().zip(&trace.truth).filter(|(_, x)| x.direction != Direction::Hold) {
        let reference = LEG_BASE_LENGTH_M + f64::from(t.position_reference_m);
        let measured = LEG_BASE_LENGTH_M + x.terminal_position_m;
        sum += (measured - reference).abs() / reference;
        n += 1;
    }
    if n == 0 { 0.0 } else { 100.0 * sum / n as f64 }
}

/// Compares a run without and one with compensation.
pub fn observer_figures(before: &RunTrace, after: &RunTrace, settle_s: f64) -> ObserverFigures {
    let b = paper_summary(before, 0, settle_s);
    let a = paper_summary(after, 0, settle_s);
    let meta = servo_core::observer::model::META;
    ObserverFigures {
        observer_rmse_um_heldout: f64::from(meta.test_rmse_m) * 1e6,
        observer_dataset: meta.dataset.to_string(),
        terminal_error_max_mm_before: b.terminal_error_max_mm,
        terminal_error_rms_mm_before: b.terminal_error_rms_mm,
        terminal_error_max_mm_after: a.terminal_error_max_mm,
        terminal_error_rms_mm_after: a.terminal_error_rms_mm,
        terminal_error_max_reduction_pct: 100.0 * (1.0 - a.terminal_error_max_mm / b.terminal_error_max_mm),
        mape_before: length_mape_pct(before),
        mape_after: length_mape_pct(after),
        compensation_max_mm: after.telemetry.iter().map(|t| f64::from(t.position_shift_m).abs()).fold(0.0, f64::max) * 1e3,
        compensation_aborted: after.aborted.clone(),
    }
}

pub fn paper_summary(trace: &RunTrace, seed: u64, settle_s: f64) -> PaperSummary {
    let pairs = || trace.telemetry.iter().zip(&trace.truth);
    let tracking = |(t, x): (&servo_core::Telemetry, &crate::sim::TruthRecord)| {
        f64::from(t.position_reference_m) - x.motor_side_position_m
    };
    let (track_rms, track_max) = rms_and_max(pairs().filter(|(_, x)| x.time_s >= settle_s).map(tracking));
    let (_, sag_max) = rms_and_max(pairs().filter(|(_, x)| x.time_s < settle_s).map(tracking));
    let (term_rms, term_max) = rms_and_max(
        pairs().filter(|(_, x)| x.time_s >= settle_s).map(|(t, x)| x.terminal_position_m - f64::from(t.position_reference_m)),
    );
    let (_, deform_max) = rms_and_max(trace.truth.iter().map(|x| x.deformation_m));
    let leg_max = |d: Direction| {
        rms_and_max(
            pairs()
                .zip(&trace.direction)
                .filter(|(_, dir)| **dir == d)
                .map(|((t, x), _)| x.terminal_position_m - f64::from(t.position_reference_m)),
        )
        .1
    };
    PaperSummary {
        motor_tracking_rms_um: track_rms * 1e6,
        motor_tracking_max_um: track_max * 1e6,
        enable_sag_max_um: sag_max * 1e6,
        terminal_error_rms_mm: term_rms * 1e3,
        terminal_error_max_mm: term_max * 1e3,
        deformation_max_mm: deform_max * 1e3,
        terminal_error_max_elongation_mm: leg_max(Direction::Elongation) * 1e3,
        terminal_error_max_contraction_mm: leg_max(Direction::Contraction) * 1e3,
        peak_phase_current_a: trace.truth.iter().fold(0.0, |m, x| m.max(x.phase_current_peak_a)),
        peak_thrust_n: trace.truth.iter().fold(0.0, |m, x| m.max(x.axial_force_n.abs())),
        sim_realtime_factor: if trace.wall_s > 0.0 { trace.simulated_s / trace.wall_s } else { f64::INFINITY },
        simulated_s: trace.simulated_s,
        wall_s: trace.wall_s,
        records: trace.telemetry.len(),
        seed,
        aborted: trace.aborted.clone(),
        observer: None,
    }
}
