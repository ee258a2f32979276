//! Constants derived from a parameter set once, when it is applied, so the
//! PWM period pays no division or transcendental for them.

use crate::foc::CurrentTiming;
use crate::params::ControlParams;
use core::f32::consts::PI;

/// Period-independent constants, computed once so the 20 kHz path does no
/// divisions it can avoid.
#[derive(Clone, Copy, Debug)]
pub(super) struct Derived {
    /// The PWM period and the current loop's phase lead.
    pub(super) current_timing: CurrentTiming,
    pub(super) speed_period_s: f32,
    pub(super) position_period_s: f32,
    pub(super) current_limit_a: f32,
    pub(super) metres_per_count: f32,
    pub(super) rad_per_count: f32,
    /// `2π / lead`: user position to motor angle.
    pub(super) rad_per_metre: f32,
    /// `pole_pairs · 2π / counts_per_rev`: counts straight to electrical
    /// radians, one multiply per period.
    pub(super) electrical_rad_per_count: f32,
    pub(super) open_phase_window_ticks: u32,
    /// The open-phase model's per-speed-period gain towards the reference.
    pub(super) open_phase_follow_gain: f32,
    pub(super) brake_release_periods: u32,
    pub(super) brake_engage_periods: u32,
    /// `Enable` holds the brake closed this many periods while the hold
    /// current builds.
    pub(super) brake_preload_periods: u32,
    pub(super) calibration_samples: u32,
    /// Rotor speed below which an active short circuit's steady current,
    /// `ω_e ψ / sqrt(R² + (ω_e L)²)`, stays inside `limits.current_max_a`.
    pub(super) short_circuit_speed_max_rad_s: f32,
    pub(super) speed_ticks_per_position_tick: u32,
    /// Streamed setpoints: the longest interpolation interval, in position
    /// periods.
    pub(super) stream_max_ticks: u32,
}

impl Derived {
    pub(super) fn of(p: &ControlParams) -> Self {
        let cpr = p.encoder.counts_per_rev as f32;
        Self {
            current_timing: CurrentTiming::of(p),
            speed_period_s: p.speed_period_s(),
            position_period_s: p.position_period_s(),
            current_limit_a: p.current_limit_a(),
            metres_per_count: p.drive_train.screw_lead_m / cpr,
            rad_per_count: 2.0 * PI / cpr,
            rad_per_metre: 2.0 * PI / p.drive_train.screw_lead_m,
            electrical_rad_per_count: p.motor.pole_pairs as f32 * (2.0 * PI / cpr),
            open_phase_window_ticks: periods(p.faults.open_phase_window_s, p.speed_period_s()),
            open_phase_follow_gain: crate::protection::open_phase::follow_gain(p.current_pi.kp, p.motor.inductance_q_h, p.speed_period_s()),
            brake_release_periods: periods(p.brake.release_time_s, p.pwm_period_s()),
            brake_engage_periods: periods(p.brake.engage_time_s, p.pwm_period_s()),
            brake_preload_periods: if p.brake.fitted { periods(p.brake.preload_time_s, p.pwm_period_s()) } else { 0 },
            calibration_samples: periods(p.calibration.duration_s, p.pwm_period_s()),
            short_circuit_speed_max_rad_s: short_circuit_speed_max_rad_s(p),
            // Validated: a non-zero multiple of the speed divider.
            speed_ticks_per_position_tick: p.rates.position_loop_divider.checked_div(p.rates.speed_loop_divider).unwrap_or(1),
            stream_max_ticks: periods(p.stream.period_max_s, p.position_period_s()),
        }
    }
}

/// Solves `ω_e ψ / sqrt(R² + (ω_e L)²) = I_max` for the mechanical speed;
/// infinite when even the asymptote ψ/L stays below `I_max`.
fn short_circuit_speed_max_rad_s(p: &ControlParams) -> f32 {
    let m = &p.motor;
    let i = p.limits.current_max_a;
    let l = m.inductance_q_h;
    let margin = m.flux_linkage_wb * m.flux_linkage_wb - i * i * l * l;
    if margin <= 0.0 {
        return f32::INFINITY;
    }
    i * m.phase_resistance_ohm / crate::math::sqrt(margin) / m.pole_pairs as f32
}

/// Whole periods of `period_s` in `duration_s`, rounded up, at least 1.
/// Not inlined: `Derived::of` calls it seven times, once, at start-up.
#[inline(never)]
fn periods(duration_s: f32, period_s: f32) -> u32 {
    let n = crate::math::clamp(duration_s / period_s, 1.0, u32::MAX as f32);
    let whole = n as u32;
    if (whole as f32) < n { whole.saturating_add(1) } else { whole }
}
