//! Streamed setpoints (a platform controller sending position + velocity at
//! 100 Hz–1 kHz), interpolated at the position-loop rate.
//!
//! The reference runs one setpoint interval behind the newest setpoint: a
//! cubic Hermite from where the reference is when a setpoint arrives to the
//! setpoint, over the interval measured between the last two arrivals. A
//! setpoint that arrives early or late never makes the reference jump. When
//! none arrives, the reference carries on along the newest setpoint's
//! velocity for one more interval (a late setpoint still joins smoothly);
//! after that the stream is lost ([`SetpointStream::lost`]) and the caller
//! decelerates from where the reference got to, at that velocity, to rest.

use crate::motion::TrajectorySample;
use crate::params::ControlParams;

/// A lost stream's deceleration rises to the stop deceleration within this,
/// seconds. A step would ring the position loop (59 µm following error
/// and a swing back at 0.1 m/s on the rig); much slower lengthens the stop
/// beyond v²/2a + 1 mm at the top stream speed.
pub const LOSS_STOP_RAMP_IN_S: f32 = 0.008;
/// …and falls back to zero as the speed reaches zero within this: a
/// gentler end, where friction takes over, leaves the rod without a swing
/// back.
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

/// The running disagreement between a stream's position steps and its
/// velocities, metres, after one more point: the step less what the mean
/// of the two points' velocities covers over `interval_s` (the drive's
/// clock between their arrivals), added to what was there, which decays
/// over `window_s`. Over `window_s` it is the mean disagreement in m/s. A
/// point that arrives late by δ adds `−v·δ` and the next, early by as
/// much, takes it back: bunched arrivals cancel; a stream recorded at
/// another rate, or a velocity in other units, builds up.
pub fn step_disagreement_m(previous_m: f32, step_m: f32, mean_velocity_m_s: f32, interval_s: f32, window_s: f32) -> f32 {
    let keep = if window_s > 0.0 { 1.0 - crate::math::clamp(interval_s / window_s, 0.0, 1.0) } else { 0.0 };
    previous_m * keep + (step_m - mean_velocity_m_s * interval_s)
}

/// One streamed point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    pub position_m: f32,
    pub velocity_m_s: f32,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct SetpointStream {
    active: bool,
    from: Setpoint,
    to: Setpoint,
    /// Position periods the interpolation spans (the last measured arrival
    /// interval).
    interval_ticks: u32,
    /// Position periods since `to` arrived.
    since_ticks: u32,
    force_n: f32,
    /// The stream was lost: the reference decelerates (`stop`).
    stopping: bool,
    stop: LossStop,
}

/// A lost stream's deceleration: the deceleration rises to the stop
/// deceleration and falls back to zero as the speed reaches zero, each
/// within a bounded time.
#[derive(Clone, Copy, Debug, Default)]
struct LossStop {
    position_m: f32,
    /// Speed along `direction`, >= 0.
    speed_m_s: f32,
    /// Deceleration, >= 0.
    deceleration_m_s2: f32,
    direction: f32,
}

impl SetpointStream {
    pub fn active(&self) -> bool {
        self.active
    }

    /// Feedforward force of the newest setpoint, newtons (0 if none).
    pub fn force_n(&self) -> f32 {
        self.force_n
    }

    /// Position periods since the newest setpoint arrived.
    pub fn since_ticks(&self) -> u32 {
        self.since_ticks
    }

    /// Position periods the drive expects between setpoints (the last
    /// measured arrival interval).
    pub fn interval_ticks(&self) -> u32 {
        self.interval_ticks
    }

    /// The reference has reached the newest setpoint and carried on along
    /// its velocity for one more expected interval, and still no setpoint
    /// came: the stream is lost.
    pub fn lost(&self) -> bool {
        self.active && self.since_ticks > self.interval_ticks.saturating_mul(2)
    }

    /// Velocity of the newest setpoint (what the reference carries on with
    /// once it has reached it), m/s.
    pub fn velocity_m_s(&self) -> f32 {
        self.to.velocity_m_s
    }

    pub fn stop(&mut self) {
        self.active = false;
        self.stopping = false;
    }

    /// The stream was lost and its deceleration has come to rest.
    pub fn lost_at_rest(&self) -> bool {
        self.active && self.stopping && self.stop.speed_m_s == 0.0
    }

    /// The stream was lost and the reference is decelerating (or at rest).
    pub fn stopping(&self) -> bool {
        self.active && self.stopping
    }

    /// A new setpoint. The first starts from `here` (at rest) over
    /// `max_interval_ticks` (the slowest rate: a gentle start); later ones
    /// from the present reference over the interval since the previous
    /// one, at most `max_interval_ticks`.
    pub fn push(&mut self, sp: Setpoint, force_n: f32, here: Setpoint, max_interval_ticks: u32, dt_s: f32) {
        if self.active {
            // Where the reference is now: on the way to the previous
            // setpoint, or past it along its velocity (a late setpoint).
            let now = self.sample(dt_s);
            self.from = Setpoint { position_m: now.position_m, velocity_m_s: now.velocity_m_s };
            self.interval_ticks = self.since_ticks.clamp(1, max_interval_ticks.max(1));
        } else {
            self.from = here;
            self.interval_ticks = max_interval_ticks.max(1);
            self.active = true;
        }
        self.to = sp;
        self.since_ticks = 0;
        self.force_n = force_n;
    }

    /// The reference for this position period; then the clock advances.
    /// Once the stream is lost ([`Self::lost`]) the reference decelerates
    /// from where it got to, at `stop_deceleration_m_s2`, the deceleration
    /// reaching it within [`LOSS_STOP_RAMP_IN_S`] and leaving it within
    /// [`LOSS_STOP_RAMP_OUT_S`].
    /// `lead_s` ([`torque_path_delay_s`]): the stop's acceleration is fed
    /// forward that much ahead of its position and velocity.
    pub fn advance(&mut self, dt_s: f32, stop_deceleration_m_s2: f32, lead_s: f32) -> TrajectorySample {
        if self.lost() && !self.stopping {
            // From the reference last handed out, at its velocity.
            let r = self.sample_at(self.since_ticks.saturating_sub(1), dt_s);
            let v = r.velocity_m_s;
            self.stop = LossStop { position_m: r.position_m, speed_m_s: v.abs(), deceleration_m_s2: 0.0, direction: if v < 0.0 { -1.0 } else { 1.0 } };
            self.stopping = true;
        }
        if self.stopping {
            return self.stop.advance(dt_s, stop_deceleration_m_s2, lead_s);
        }
        let r = self.sample(dt_s);
        self.since_ticks = self.since_ticks.saturating_add(1);
        r
    }

    /// Cubic Hermite between `from` and `to` at the present tick; past the
    /// interval, `to` carried on along its velocity (the caller ends that
    /// after one more interval, [`Self::lost`]).
    fn sample(&self, dt_s: f32) -> TrajectorySample {
        self.sample_at(self.since_ticks, dt_s)
    }

    fn sample_at(&self, since_ticks: u32, dt_s: f32) -> TrajectorySample {
        let n = self.interval_ticks.max(1) as f32;
        let u = since_ticks as f32 / n;
        if u >= 1.0 {
            let beyond_s = since_ticks.saturating_sub(self.interval_ticks) as f32 * dt_s;
            let v = self.to.velocity_m_s;
            return TrajectorySample { position_m: self.to.position_m + v * beyond_s, velocity_m_s: v, acceleration_m_s2: 0.0 };
        }
        let t = n * dt_s;
        let (p0, p1) = (self.from.position_m, self.to.position_m);
        let (m0, m1) = (self.from.velocity_m_s * t, self.to.velocity_m_s * t);
        let (u2, u3) = (u * u, u * u * u);
        let position_m = (2.0 * u3 - 3.0 * u2 + 1.0) * p0 + (u3 - 2.0 * u2 + u) * m0 + (-2.0 * u3 + 3.0 * u2) * p1 + (u3 - u2) * m1;
        let dp_du = (6.0 * u2 - 6.0 * u) * p0 + (3.0 * u2 - 4.0 * u + 1.0) * m0 + (-6.0 * u2 + 6.0 * u) * p1 + (3.0 * u2 - 2.0 * u) * m1;
        let d2p_du2 = (12.0 * u - 6.0) * p0 + (6.0 * u - 4.0) * m0 + (-12.0 * u + 6.0) * p1 + (6.0 * u - 2.0) * m1;
        TrajectorySample { position_m, velocity_m_s: dp_du / t, acceleration_m_s2: d2p_du2 / (t * t) }
    }
}

impl LossStop {
    /// The acceleration handed out is the deceleration `lead_s` ahead
    /// (extrapolated along this period's jerk, within `[0, a_max]`): the
    /// loops turn an acceleration feedforward into torque ≈ 2.3 ms late, and
    /// at this stop's jerk (the stop deceleration within 8 ms, 625 m/s³ at
    /// 5 m/s²) that lag leaves 1.4 m/s² missing at each turn of the ramp,
    /// which the position loop catches only as a following error (44 µm at
    /// 0.2 m/s, 55 µm at 0.1 m/s on a rigid rod). A planned move's jerk
    /// (25 m/s³) leaves 0.06 m/s²: its feedforward needs no lead.
    fn advance(&mut self, dt_s: f32, deceleration_max_m_s2: f32, lead_s: f32) -> TrajectorySample {
        let a_max = deceleration_max_m_s2.max(0.0);
        let jerk_in = a_max / LOSS_STOP_RAMP_IN_S.max(dt_s);
        let jerk = a_max / LOSS_STOP_RAMP_OUT_S.max(dt_s);
        let u0 = self.speed_m_s;
        let d0 = self.deceleration_m_s2;
        // Ease off once the speed left is what the deceleration sheds while
        // it falls to zero (d²/2j), so both reach zero together.
        let d1 = if u0 <= d0 * d0 / (2.0 * jerk) + 0.5 * d0 * dt_s {
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
        let d_ff = if u1 == 0.0 { 0.0 } else { crate::math::clamp(d_out + jerk_now * lead_s.max(0.0), 0.0, a_max) };
        TrajectorySample {
            position_m: self.position_m,
            velocity_m_s: self.direction * u1,
            acceleration_m_s2: -self.direction * d_ff,
        }
    }
}
