//! Position loop: proportional on the motor-side position with velocity
//! feedforward from the trajectory, producing the speed reference.

use crate::params::ControlParams;

/// One position-loop update, in motor-shaft units for the speed loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionLoopOutput {
    pub speed_reference_rad_s: f32,
    pub acceleration_reference_rad_s2: f32,
    /// |ω_ref| hit the Eq. 19 speed bound.
    pub speed_limited: bool,
}

/// Stateless: a P controller needs no memory, and the integral action lives
/// in the speed loop where the load torque appears.
pub fn position_step(
    p: &ControlParams,
    command_m: f32,
    velocity_ff_m_s: f32,
    acceleration_ff_m_s2: f32,
    measured_m: f32,
) -> PositionLoopOutput {
    let rad_per_m = 1.0 / p.metres_per_rad();
    let v = velocity_ff_m_s + p.position_kp_per_s * (command_m - measured_m);
    let w = v * rad_per_m;
    let w_max = p.limits.speed_max_rad_s;
    let speed_limited = !(w.abs() <= w_max);
    PositionLoopOutput {
        speed_reference_rad_s: if w.is_nan() { 0.0 } else { crate::math::clamp(w, -w_max, w_max) },
        acceleration_reference_rad_s2: acceleration_ff_m_s2 * rad_per_m,
        speed_limited,
    }
}
