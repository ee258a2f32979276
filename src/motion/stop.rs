//! The controlled stop: from whatever velocity the motor has, decelerate at a
//! fixed rate to rest and hold there. Used when a fault calls for stopping
//! rather than switching off (see `FaultSet::CONTROLLED_STOP`).

use super::trajectory::TrajectorySample;

/// A constant-deceleration ramp to rest.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StopRamp {
    position_m: f32,
    velocity_m_s: f32,
    deceleration_m_s2: f32,
}

impl StopRamp {
    pub fn new(position_m: f32, velocity_m_s: f32, deceleration_m_s2: f32) -> Self {
        let velocity_m_s = if velocity_m_s.is_finite() { velocity_m_s } else { 0.0 };
        Self { position_m, velocity_m_s, deceleration_m_s2 }
    }

    /// Where the ramp comes to rest, from where it is now.
    pub fn rest_position_m(&self) -> f32 {
        let v = self.velocity_m_s;
        self.position_m + v * v.abs() / (2.0 * self.deceleration_m_s2)
    }

    /// The ramp has reached zero velocity.
    pub fn at_rest(&self) -> bool {
        self.velocity_m_s == 0.0
    }

    /// Advances `dt_s` and returns the new reference.
    pub fn advance(&mut self, dt_s: f32) -> TrajectorySample {
        let v0 = self.velocity_m_s;
        let dv = self.deceleration_m_s2 * dt_s;
        let (v1, a) = if v0 > dv {
            (v0 - dv, -self.deceleration_m_s2)
        } else if v0 < -dv {
            (v0 + dv, self.deceleration_m_s2)
        } else {
            (0.0, 0.0)
        };
        self.position_m += 0.5 * (v0 + v1) * dt_s;
        self.velocity_m_s = v1;
        TrajectorySample { position_m: self.position_m, velocity_m_s: v1, acceleration_m_s2: a }
    }
}
