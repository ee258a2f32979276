//! A lost stream's stop: from the velocity (and acceleration) the reference
//! had when it reached the newest setpoint, a deceleration that rises to
//! the stop deceleration and falls back to zero as the speed reaches zero,
//! each within a bounded time, with the timing corrections the loops need
//! to follow it (see [`StopShaping`]).

use crate::motion::TrajectorySample;
use crate::params::ControlParams;

/// A lost stream's deceleration rises to the stop deceleration within this,
/// seconds. A step would ring the position loop (59 µm following error
/// and a swing back at 0.1 m/s on the rig). Each millisecond of it costs
/// `v/2` ms of travel (0.1 mm per ms at 0.2 m/s) against the rest bound
/// `v²/2a + 1 mm`.
pub const LOSS_STOP_RAMP_IN_S: f32 = 0.008;
/// …and falls back to zero as the speed reaches zero within this: a
/// gentler end, where friction takes over, leaves the rod without a swing
/// back. Near rest it costs almost no travel.
pub const LOSS_STOP_RAMP_OUT_S: f32 = 0.015;

/// How late an acceleration feedforward becomes torque, seconds: the
/// position period's hold (half of it on average), the speed period's, one
/// PWM period of computation, the torque filter's group delay at low
/// frequency (`√2/ω` for its Butterworth low-pass, none when it is off)
/// and the current loop's time constant (`L/kp`). ≈ 2.3 ms with the
/// shipped parameters.
pub fn torque_path_delay_s(p: &ControlParams) -> f32 {
    let speed_rate_hz = p.rates.pwm_frequency_hz / p.rates.speed_loop_divider as f32;
    let f = p.torque_filter_hz;
    // The same test as `Biquad::low_pass`: outside it the filter passes.
    let filter_s = if f > 0.0 && f < 0.45 * speed_rate_hz { core::f32::consts::SQRT_2 / (2.0 * core::f32::consts::PI * f) } else { 0.0 };
    let current_s = if p.current_pi.kp > 0.0 { p.motor.inductance_q_h / p.current_pi.kp } else { 0.0 };
    let delay_s = 0.5 * p.position_period_s() + 0.5 * p.speed_period_s() + p.pwm_period_s() + filter_s + current_s;
    if delay_s.is_finite() {
        delay_s
    } else {
        0.0
    }
}

/// How far the speed the speed loop regulates trails the motor's true
/// speed under a steady acceleration, seconds of it: the encoder tracker's
/// speed is its loop's integrator, which lags a constant acceleration α by
/// `(kp/ki)·α` (0.8 ms with the shipped tracker); the position loop's
/// speed reference is held over a position period while the path's speed
/// moves on, half a period on average the other way. ≈ 0.3 ms net: at the
/// stop's 5 m/s², 1.9 rad/s that the position loop would otherwise have to
/// make up as a steady 24 µm following error.
pub fn speed_lag_s(p: &ControlParams) -> f32 {
    let e = &p.encoder;
    let tracker_s = if e.pll_ki_per_s2 > 0.0 { e.pll_kp_per_s / e.pll_ki_per_s2 } else { 0.0 };
    let lag_s = tracker_s - 0.5 * p.position_period_s();
    if lag_s.is_finite() {
        lag_s
    } else {
        0.0
    }
}

/// What a lost stream's stop needs from the parameters, each period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StopShaping {
    /// `faults.stop_deceleration_m_s2`.
    pub deceleration_m_s2: f32,
    /// [`torque_path_delay_s`]: the stop's acceleration is fed forward that
    /// much ahead.
    pub lead_s: f32,
    /// [`speed_lag_s`]: the velocity handed to the position loop leads by
    /// this much of the path's acceleration (`SetpointStream::advance`).
    pub speed_lag_s: f32,
}

impl StopShaping {
    pub fn of(p: &ControlParams) -> Self {
        Self { deceleration_m_s2: p.faults.stop_deceleration_m_s2, lead_s: torque_path_delay_s(p), speed_lag_s: speed_lag_s(p) }
    }
}

/// A lost stream's deceleration: rises to the stop deceleration and falls
/// back to zero as the speed reaches zero, each within a bounded time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LossStop {
    position_m: f32,
    /// Speed along `direction`, >= 0.
    speed_m_s: f32,
    /// Deceleration; negative while the reference still accelerates along
    /// `direction` (it carries on from the stream's own acceleration).
    deceleration_m_s2: f32,
    direction: f32,
}

impl LossStop {
    /// From the reference last handed out: its position, velocity and
    /// acceleration, so neither the velocity nor the acceleration jumps.
    pub fn from(r: TrajectorySample, deceleration_max_m_s2: f32) -> Self {
        let v = r.velocity_m_s;
        let direction = if v < 0.0 { -1.0 } else { 1.0 };
        let a_max = deceleration_max_m_s2.max(0.0);
        let d = crate::math::clamp(-direction * r.acceleration_m_s2, -a_max, a_max);
        Self { position_m: r.position_m, speed_m_s: v.abs(), deceleration_m_s2: if d.is_finite() { d } else { 0.0 }, direction }
    }

    /// The path's acceleration now (not the one fed forward).
    pub fn acceleration_m_s2(&self) -> f32 {
        -self.direction * self.deceleration_m_s2
    }

    /// The deceleration has brought the reference to rest.
    pub fn at_rest(&self) -> bool {
        self.speed_m_s == 0.0
    }

    /// The next period's reference. The acceleration handed out is the
    /// deceleration `lead_s` ahead (extrapolated along this period's jerk,
    /// not below zero unless it is there already, nor above `a_max`): the loops turn an acceleration feedforward
    /// into torque ≈ 2.3 ms late, and at this stop's jerk (the stop
    /// deceleration within 8 ms, 625 m/s³ at 5 m/s²) that lag would leave
    /// 1.4 m/s² missing at each turn of the ramp.
    pub fn advance(&mut self, dt_s: f32, s: &StopShaping) -> TrajectorySample {
        let a_max = s.deceleration_m_s2.max(0.0);
        let jerk_in = a_max / LOSS_STOP_RAMP_IN_S.max(dt_s);
        let jerk = a_max / LOSS_STOP_RAMP_OUT_S.max(dt_s);
        let u0 = self.speed_m_s;
        let d0 = self.deceleration_m_s2;
        // Ease off once the speed left is what the deceleration sheds while
        // it falls to zero (d²/2j), so both reach zero together.
        let d1 = if d0 > 0.0 && u0 <= d0 * d0 / (2.0 * jerk) + 0.5 * d0 * dt_s {
            (d0 - jerk * dt_s).max(0.0)
        } else {
            (d0 + jerk_in * dt_s).min(a_max)
        };
        let mut u1 = u0 - 0.5 * (d0 + d1) * dt_s;
        let mut d_out = d1;
        if u1 <= 0.0 || (d1 == 0.0 && u0 <= jerk * dt_s * dt_s) {
            u1 = 0.0;
            d_out = 0.0;
        }
        self.position_m += self.direction * 0.5 * (u0 + u1) * dt_s;
        self.speed_m_s = u1;
        self.deceleration_m_s2 = d_out;
        let jerk_now = if dt_s > 0.0 { (d_out - d0) / dt_s } else { 0.0 };
        let d_ff = if u1 == 0.0 { 0.0 } else { crate::math::clamp(d_out + jerk_now * s.lead_s.max(0.0), d_out.min(0.0), a_max) };
        TrajectorySample { position_m: self.position_m, velocity_m_s: self.direction * u1, acceleration_m_s2: -self.direction * d_ff }
    }
}
