//! Streamed setpoints (a platform controller sending position + velocity at
//! 100 Hz–1 kHz), interpolated at the position-loop rate.
//!
//! The reference runs one setpoint interval behind the newest setpoint: a
//! cubic Hermite from where the reference is when a setpoint arrives to the
//! setpoint, over the interval measured between the last two arrivals. A
//! setpoint that arrives early or late never makes the reference jump; one
//! that does not arrive leaves the reference resting on the last one, and
//! the caller ends the stream after its timeout.

use crate::motion::TrajectorySample;

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

    pub fn stop(&mut self) {
        self.active = false;
    }

    /// A new setpoint. The first starts from `here` (at rest) over
    /// `max_interval_ticks` (the slowest rate: a gentle start); later ones
    /// from the present reference over the interval since the previous
    /// one, at most `max_interval_ticks`.
    pub fn push(&mut self, sp: Setpoint, force_n: f32, here: Setpoint, max_interval_ticks: u32, dt_s: f32) {
        if self.active {
            // Where the reference is now; at the end of the interval that is
            // the previous setpoint itself, moving at its velocity (resting
            // there is only for a stream that has stopped arriving).
            self.from = if self.since_ticks >= self.interval_ticks {
                self.to
            } else {
                let now = self.sample(dt_s);
                Setpoint { position_m: now.position_m, velocity_m_s: now.velocity_m_s }
            };
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
    pub fn advance(&mut self, dt_s: f32) -> TrajectorySample {
        let r = self.sample(dt_s);
        self.since_ticks = self.since_ticks.saturating_add(1);
        r
    }

    /// Cubic Hermite between `from` and `to` at the present tick; resting
    /// on `to` once the interval has run out.
    fn sample(&self, dt_s: f32) -> TrajectorySample {
        let n = self.interval_ticks.max(1) as f32;
        let u = self.since_ticks as f32 / n;
        if u >= 1.0 {
            return TrajectorySample { position_m: self.to.position_m, velocity_m_s: 0.0, acceleration_m_s2: 0.0 };
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
