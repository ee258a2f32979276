//! Space-vector PWM by min-max (midpoint) zero-sequence injection, which gives
//! the same switching pattern as sector-based SVPWM at a fraction of the code.

use super::transforms::{inverse_clarke, AlphaBeta};

/// Largest α-β voltage amplitude the inverter can make without
/// over-modulation: the circle inscribed in the SVPWM hexagon, `V_bus/√3`.
#[inline(always)]
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

/// Bus voltages the fast path takes, as `f32` bit patterns: [2⁻⁶⁰, 2⁶⁰) V.
/// Inside it `(V_bus/√3)²` and `1/V_bus` are normal and finite, so a request
/// that passes the circle test is finite too, and nothing needs re-checking.
const FAST_BUS_BITS_LO: u32 = (127 - 60) << 23;
const FAST_BUS_BITS_SPAN: u32 = 120 << 23;

/// The fast path takes requests up to `(1 − 2⁻¹²)` of the circle's |v|²
/// (|v| within 1.2e-4 of it). There the injected legs lie at most
/// `0.5·(1 − 2⁻¹³)·V_bus` from the midpoint before rounding, and the few
/// ulps of rounding in between cannot reach the rails: the duties are in
/// [0, 1] without clamping. The current loop bounds its request to
/// `max_modulation` of the circle (0.95 by default), inside this range for
/// any `max_modulation` up to 0.9998; above that, and for any other request,
/// the checked path gives the same duties, only slower.
const FAST_CIRCLE_FRACTION: f32 = 1.0 - 1.0 / 4096.0;

/// Turns a voltage vector into three duties in [0, 1].
///
/// A request outside `V_bus/√3` is scaled back onto the circle along its own
/// direction (so the angle, hence the torque direction, is kept) and flagged.
/// A non-positive or non-finite bus voltage gives 50 % on every leg (zero
/// volts) and `limited`.
#[inline(always)]
pub fn svpwm(v: AlphaBeta, bus_voltage_v: f32) -> SvpwmOutput {
    let vmax = linear_limit_v(bus_voltage_v);
    let mag2 = v.alpha * v.alpha + v.beta * v.beta;
    let bus_ok = bus_voltage_v.to_bits().wrapping_sub(FAST_BUS_BITS_LO) < FAST_BUS_BITS_SPAN;
    if bus_ok && mag2 <= vmax * vmax * FAST_CIRCLE_FRACTION {
        return SvpwmOutput { duty: duties(v, bus_voltage_v), limited: false };
    }
    svpwm_edge(v, bus_voltage_v)
}

/// Min-max injection, centred on 50 %.
#[inline(always)]
fn duties(v: AlphaBeta, bus_voltage_v: f32) -> [f32; 3] {
    use crate::math::{max, min};
    let [a, b, c] = inverse_clarke(v);
    let mid = 0.5 * (max(max(a, b), c) + min(min(a, b), c));
    let inv_bus = 1.0 / bus_voltage_v;
    [0.5 + (a - mid) * inv_bus, 0.5 + (b - mid) * inv_bus, 0.5 + (c - mid) * inv_bus]
}

/// On or outside the circle, a bus outside the fast range, or a non-finite
/// input: every check, and the duties clamped.
#[inline(always)]
fn svpwm_edge(v: AlphaBeta, bus_voltage_v: f32) -> SvpwmOutput {
    use crate::math::finite_probe;
    let finite = finite_probe(bus_voltage_v) + finite_probe(v.alpha) + finite_probe(v.beta) == 0.0;
    if !(finite && bus_voltage_v > 0.0) {
        return SvpwmOutput { duty: [0.5; 3], limited: true };
    }
    let vmax = linear_limit_v(bus_voltage_v);
    let mag2 = v.alpha * v.alpha + v.beta * v.beta;
    let limited = mag2 > vmax * vmax;
    let k = if limited { vmax / crate::math::sqrt(mag2) } else { 1.0 };
    let mut duty = duties(AlphaBeta { alpha: v.alpha * k, beta: v.beta * k }, bus_voltage_v);
    // Rounding can put a leg a few ulp past the rails on the circle itself.
    for d in &mut duty {
        *d = crate::math::clamp(*d, 0.0, 1.0);
    }
    SvpwmOutput { duty, limited }
}
