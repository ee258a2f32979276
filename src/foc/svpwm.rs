//! Space-vector PWM by min-max (midpoint) zero-sequence injection, which gives
//! the same switching pattern as sector-based SVPWM at a fraction of the code.

use super::transforms::{inverse_clarke, AlphaBeta};

/// Largest α-β voltage amplitude the inverter can make without
/// over-modulation: the circle inscribed in the SVPWM hexagon, `V_bus/√3`.
pub fn linear_limit_v(bus_voltage_v: f32) -> f32 {
    bus_voltage_v * 0.577_350_26
}

/// Duties for a stationary-frame voltage command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SvpwmOutput {
    pub duty: [f32; 3],
    /// True if the request lay outside the voltage circle and was scaled back.
    pub limited: bool,
}

/// Turns a voltage vector into three duties in [0, 1].
///
/// A request outside `V_bus/√3` is scaled back onto the circle along its own
/// direction (so the angle, hence the torque direction, is kept) and flagged.
/// A non-positive or non-finite bus voltage gives 50 % on every leg (zero
/// volts) and `limited`.
pub fn svpwm(v: AlphaBeta, bus_voltage_v: f32) -> SvpwmOutput {
    if !(bus_voltage_v > 0.0) || !bus_voltage_v.is_finite() || !v.alpha.is_finite() || !v.beta.is_finite() {
        return SvpwmOutput { duty: [0.5; 3], limited: true };
    }
    let vmax = linear_limit_v(bus_voltage_v);
    let mag2 = v.alpha * v.alpha + v.beta * v.beta;
    let (v, limited) = if mag2 > vmax * vmax {
        let k = vmax / crate::math::sqrt(mag2);
        (AlphaBeta { alpha: v.alpha * k, beta: v.beta * k }, true)
    } else {
        (v, false)
    };
    let [a, b, c] = inverse_clarke(v);
    use crate::math::{max, min};
    let hi = max(max(a, b), c);
    let lo = min(min(a, b), c);
    let mid = 0.5 * (hi + lo);
    let inv_bus = 1.0 / bus_voltage_v;
    // Rounding can put a leg a few ulp past the rails on the circle itself.
    let duty = [a, b, c].map(|x| crate::math::clamp(0.5 + (x - mid) * inv_bus, 0.0, 1.0));
    SvpwmOutput { duty, limited }
}
