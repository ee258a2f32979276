//! The pieces of a period, one opaque call each (`#[inline(never)]`): what
//! the table's "pieces" rows measure.

use super::*;

// ---- wrappers: one opaque call each ---------------------------------------

#[inline(never)]
pub(crate) fn step(c: &mut Controller, s: &SensorSample) -> PwmCommand {
    c.step(s)
}

#[inline(never)]
pub(crate) fn sincos(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

#[inline(never)]
pub(crate) fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

#[inline(never)]
pub(crate) fn expf(x: f32) -> f32 {
    libm::expf(x)
}

#[inline(never)]
pub(crate) fn wrap(x: f32) -> f32 {
    wrap_pi(x)
}

#[inline(never)]
pub(crate) fn clarke_park(abc: [f32; 3], sc: SinCos) -> Dq {
    park(clarke(abc), sc)
}

#[inline(never)]
pub(crate) fn pi_update(pi: &mut Pi, p: &ControlParams, e: f32) -> f32 {
    pi.update(&p.current_pi, e, 0.1, -20.0, 20.0, 50e-6).value
}

#[inline(never)]
pub(crate) fn svpwm_call(v: AlphaBeta, bus: f32) -> [f32; 3] {
    svpwm(v, bus).duty
}

#[inline(never)]
pub(crate) fn inverse_park_call(v: Dq, sc: SinCos) -> AlphaBeta {
    inverse_park(v, sc)
}

#[inline(never)]
pub(crate) fn current_loop(
    cl: &mut CurrentLoop,
    p: &ControlParams,
    abc: [f32; 3],
    r: Dq,
    rotor: RotorState,
    bus: f32,
) -> [f32; 3] {
    cl.step(p, CurrentTiming::of(p), abc, r, rotor, bus).duty
}

#[inline(never)]
pub(crate) fn encoder(e: &mut EncoderTracker, p: &ControlParams, raw: u16) -> bool {
    e.update(&p.encoder, raw, 50e-6, 2000, 100.0).implausible_step
}

#[inline(never)]
pub(crate) fn speed_loop(sl: &mut SpeedLoop, p: &ControlParams, w_ref: f32, w: f32) -> f32 {
    sl.step(p, w_ref, 100.0, 0.1, w, (-30.0, 30.0)).current_q_reference_a
}

#[inline(never)]
pub(crate) fn trajectory(m: &ScurveMove, t: f32) -> f32 {
    m.sample(t).position_m
}

#[inline(never)]
pub(crate) fn position(p: &ControlParams, cmd: f32, meas: f32) -> f32 {
    position_step(p, cmd, 0.1, 1.0, meas).speed_reference_rad_s
}

#[inline(never)]
pub(crate) fn observe(x: [f32; 4]) -> f32 {
    observer::evaluate(&observer::model::MODEL, x).value_m
}

/// The forward pass the drive runs: the five-slot network, here with the
/// compiled model (its fifth slot unused), behind a call like the above.
#[inline(never)]
pub(crate) fn observe_network(x: [f32; observer::NETWORK_INPUTS]) -> f32 {
    observer::evaluate(&observer::block::COMPILED, x).value_m
}

/// The same network with a five-input model: every slot in use.
#[inline(never)]
pub(crate) fn observe_five_input(x: [f32; observer::NETWORK_INPUTS]) -> f32 {
    observer::evaluate(&golden::FIVE_INPUT_MODEL, x).value_m
}

/// The core's square root (`vsqrt.f32` on this target), behind a call so it
/// is counted like the libm one next to it.
#[inline(never)]
pub(crate) fn vsqrt(x: f32) -> f32 {
    servo_core::math::sqrt(x)
}

/// The core's single-precision sin/cos (`servo_core::math::sincos`), behind a
/// call, next to libm's `sincosf` it replaced.
#[inline(never)]
pub(crate) fn sincos_poly(x: f32) -> (f32, f32) {
    servo_core::math::sincos(x)
}

/// micromath's sin and cos (the design card's crate), behind a call.
#[inline(never)]
pub(crate) fn sincos_micromath(x: f32) -> (f32, f32) {
    use micromath::F32Ext;
    (x.sin(), x.cos())
}

