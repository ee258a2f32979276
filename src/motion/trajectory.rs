//! Jerk-limited (double-S, seven-segment) point-to-point trajectories, from
//! rest to rest, in closed form (Biagiotti & Melchiorri, "Trajectory Planning
//! for Automatic Machines and Robots", §3.4, the v0 = v1 = 0 case).
//!
//! Planning is done once per move; sampling is a handful of multiplies, so the
//! 1 kHz position loop can evaluate it every period.

use crate::params::TrajectoryParams;

/// Position, velocity and acceleration at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TrajectorySample {
    pub position_m: f32,
    pub velocity_m_s: f32,
    pub acceleration_m_s2: f32,
}

/// A planned rest-to-rest move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScurveMove {
    start_m: f32,
    /// +1 or −1: the profile is planned for |distance| and mirrored.
    sign: f32,
    distance_m: f32,
    jerk: f32,
    /// Jerk phase, acceleration phase (including its jerk phases), cruise.
    t_jerk_s: f32,
    t_accel_s: f32,
    t_cruise_s: f32,
    accel_peak: f32,
    velocity_peak: f32,
}

impl ScurveMove {
    /// A move that stays at `position_m`.
    pub const fn hold(position_m: f32) -> Self {
        Self {
            start_m: position_m,
            sign: 1.0,
            distance_m: 0.0,
            jerk: 0.0,
            t_jerk_s: 0.0,
            t_accel_s: 0.0,
            t_cruise_s: 0.0,
            accel_peak: 0.0,
            velocity_peak: 0.0,
        }
    }

    /// Plans `start → end` within the limits. Limits are assumed validated
    /// (positive, finite); a non-finite endpoint gives a hold at `start`.
    pub fn plan(start_m: f32, end_m: f32, limits: &TrajectoryParams) -> Self {
        let d = end_m - start_m;
        if !d.is_finite() || d == 0.0 {
            return Self::hold(start_m);
        }
        let (v, a, j) = (limits.max_velocity_m_s, limits.max_acceleration_m_s2, limits.max_jerk_m_s3);
        let dist = d.abs();
        // Phase lengths if the cruise speed is reached.
        let (mut tj, mut ta) = if v * j >= a * a { (a / j, a / j + v / a) } else {
            let tj = crate::math::sqrt(v / j);
            (tj, 2.0 * tj)
        };
        let mut tv = dist / v - ta;
        if tv < 0.0 {
            // Too short to cruise: the peak speed is set by the distance.
            tv = 0.0;
            if dist >= 2.0 * a * a * a / (j * j) {
                tj = a / j;
                ta = 0.5 * tj + crate::math::sqrt(0.25 * tj * tj + dist / a);
            } else {
                tj = crate::math::cbrt(dist / (2.0 * j));
                ta = 2.0 * tj;
            }
        }
        let accel_peak = j * tj;
        let velocity_peak = (ta - tj) * accel_peak;
        Self {
            start_m,
            sign: if d > 0.0 { 1.0 } else { -1.0 },
            distance_m: dist,
            jerk: j,
            t_jerk_s: tj,
            t_accel_s: ta,
            t_cruise_s: tv,
            accel_peak,
            velocity_peak,
        }
    }

    pub fn duration_s(&self) -> f32 {
        2.0 * self.t_accel_s + self.t_cruise_s
    }

    pub fn end_m(&self) -> f32 {
        self.start_m + self.sign * self.distance_m
    }

    pub fn peak_velocity_m_s(&self) -> f32 {
        self.velocity_peak
    }

    /// The acceleration half of the profile, `t` in [0, Ta], unsigned.
    fn accel_phase(&self, t: f32) -> (f32, f32, f32) {
        let (j, tj, ta, al, vl) = (self.jerk, self.t_jerk_s, self.t_accel_s, self.accel_peak, self.velocity_peak);
        if t < tj {
            (j * t * t * t / 6.0, 0.5 * j * t * t, j * t)
        } else if t < ta - tj {
            (al / 6.0 * (3.0 * t * t - 3.0 * tj * t + tj * tj), al * (t - 0.5 * tj), al)
        } else {
            let tau = ta - t;
            (0.5 * vl * ta - vl * tau + j * tau * tau * tau / 6.0, vl - 0.5 * j * tau * tau, j * tau)
        }
    }

    /// The profile at `t_s` seconds after the move started (clamped to the
    /// move: before it, the start; after it, the end at rest).
    pub fn sample(&self, t_s: f32) -> TrajectorySample {
        let total = self.duration_s();
        if self.distance_m == 0.0 || !(t_s < total) {
            return TrajectorySample { position_m: self.end_m(), velocity_m_s: 0.0, acceleration_m_s2: 0.0 };
        }
        let t = if t_s > 0.0 { t_s } else { 0.0 };
        let (p, v, a) = if t < self.t_accel_s {
            self.accel_phase(t)
        } else if t < self.t_accel_s + self.t_cruise_s {
            (0.5 * self.velocity_peak * self.t_accel_s + self.velocity_peak * (t - self.t_accel_s), self.velocity_peak, 0.0)
        } else {
            // Deceleration mirrors acceleration in time.
            let (p, v, a) = self.accel_phase(total - t);
            (self.distance_m - p, v, -a)
        };
        TrajectorySample {
            position_m: self.start_m + self.sign * p,
            velocity_m_s: self.sign * v,
            acceleration_m_s2: self.sign * a,
        }
    }
}
