//! Streamed setpoints (a platform controller sending position + velocity at
//! 100 Hz–1 kHz), interpolated at the position-loop rate.
//!
//! The reference runs one setpoint interval behind the newest setpoint: a
//! cubic Hermite from where the reference is when a setpoint arrives to the
//! setpoint, over the interval measured between the last two arrivals. A
//! setpoint that arrives early or late never makes the reference jump. When
//! the reference reaches the newest setpoint and no newer one has come, it
//! starts to decelerate from the velocity and acceleration it has there
//! (`stream_stop`); a setpoint that arrives within one more expected
//! interval still joins smoothly from the decelerating reference. After
//! that the stream is lost ([`SetpointStream::lost`]): the deceleration
//! goes on to rest and later setpoints are refused.

use crate::motion::TrajectorySample;
use crate::motion::stream_stop::{LossStop, StopShaping};

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
    /// The reference passed the newest setpoint with no newer one: it
    /// decelerates (`stop`).
    decelerating: bool,
    stop: LossStop,
    /// The stop's shaping of the last period (a late setpoint joins from
    /// where the stop would have gone next).
    shaping: StopShaping,
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

    /// The reference reached the newest setpoint one expected interval ago
    /// (and has been decelerating since), and still no setpoint came: the
    /// stream is lost.
    pub fn lost(&self) -> bool {
        self.active && self.since_ticks > self.interval_ticks.saturating_mul(2)
    }

    /// Velocity of the newest setpoint (what the reference has when it
    /// reaches it), m/s.
    pub fn velocity_m_s(&self) -> f32 {
        self.to.velocity_m_s
    }

    pub fn stop(&mut self) {
        self.active = false;
        self.decelerating = false;
    }

    /// The stream was lost and its deceleration has come to rest.
    pub fn lost_at_rest(&self) -> bool {
        self.lost() && self.decelerating && self.stop.at_rest()
    }

    /// The reference is on the stop's deceleration (or at rest after it):
    /// its acceleration is the stop's, not the stream's.
    pub fn decelerating(&self) -> bool {
        self.active && self.decelerating
    }

    /// The stream was lost and the reference is decelerating (or at rest):
    /// a setpoint no longer joins.
    pub fn stopping(&self) -> bool {
        self.lost() && self.decelerating
    }

    /// A new setpoint. The first starts from `here` (at rest) over
    /// `max_interval_ticks` (the slowest rate: a gentle start); later ones
    /// from the present reference over the interval since the previous
    /// one, at most `max_interval_ticks`.
    pub fn push(&mut self, sp: Setpoint, force_n: f32, here: Setpoint, max_interval_ticks: u32, dt_s: f32) {
        if self.active {
            // Where the reference is now: on the way to the previous
            // setpoint, or decelerating past it (a late setpoint).
            let now = if self.decelerating {
                let mut next = self.stop;
                next.advance(dt_s, &self.shaping)
            } else {
                self.sample(dt_s)
            };
            self.decelerating = false;
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
    /// Once the reference has reached the newest setpoint and none newer
    /// came, it decelerates (`LossStop`, shaped by `shaping`) from where it
    /// got to. The velocity handed out leads by `shaping.speed_lag_s` of
    /// the acceleration (what the speed loop's measured speed trails by).
    pub fn advance(&mut self, dt_s: f32, shaping: &StopShaping) -> TrajectorySample {
        self.shaping = *shaping;
        if self.active && !self.decelerating && self.since_ticks > self.interval_ticks {
            // From the reference last handed out: the newest setpoint.
            let r = self.sample_at(self.since_ticks.saturating_sub(1), dt_s);
            self.stop = LossStop::from(r, shaping.deceleration_m_s2);
            self.decelerating = true;
        }
        let (mut r, path_acceleration_m_s2) = if self.decelerating {
            let r = self.stop.advance(dt_s, shaping);
            (r, self.stop.acceleration_m_s2())
        } else {
            let r = self.sample(dt_s);
            (r, r.acceleration_m_s2)
        };
        self.since_ticks = self.since_ticks.saturating_add(1);
        if r.velocity_m_s != 0.0 {
            r.velocity_m_s -= path_acceleration_m_s2 * shaping.speed_lag_s;
        }
        r
    }

    /// Cubic Hermite between `from` and `to` at the present tick (at its
    /// end, `to` with the Hermite's own acceleration there); past the
    /// interval, `to` carried on along its velocity (`advance` decelerates
    /// from the end instead).
    fn sample(&self, dt_s: f32) -> TrajectorySample {
        self.sample_at(self.since_ticks, dt_s)
    }

    fn sample_at(&self, since_ticks: u32, dt_s: f32) -> TrajectorySample {
        let n = self.interval_ticks.max(1) as f32;
        let u = since_ticks as f32 / n;
        if u > 1.0 {
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
