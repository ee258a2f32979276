//! I²t winding protection: a first-order thermal model that folds the current
//! limit back before it trips (a servo that must hold a vertical load should
//! lose peak torque gracefully, not drop the load).

use crate::params::ThermalParams;

/// Normalised winding temperature rise θ (1 = steady state at the continuous
/// current).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ThermalModel {
    level: f32,
}

impl ThermalModel {
    pub const fn new() -> Self {
        Self { level: 0.0 }
    }

    pub fn level(&self) -> f32 {
        self.level
    }

    /// Integrates `τ dθ/dt = |i|²/I_c² − θ` over `dt_s` (forward Euler; dt ≪ τ).
    pub fn update(&mut self, p: &ThermalParams, current_magnitude_sq_a2: f32, dt_s: f32) {
        let drive = current_magnitude_sq_a2 / (p.continuous_current_a * p.continuous_current_a);
        if drive.is_finite() {
            self.level += (drive - self.level) * (dt_s / p.time_constant_s);
        }
    }

    /// The current limit after foldback: `peak_a` below `foldback_start`,
    /// falling linearly to the continuous current at θ = 1.
    pub fn current_limit_a(&self, p: &ThermalParams, peak_a: f32) -> f32 {
        if self.level <= p.foldback_start {
            return peak_a;
        }
        let k = crate::math::min((self.level - p.foldback_start) / (1.0 - p.foldback_start), 1.0);
        peak_a + (p.continuous_current_a - peak_a) * k
    }

    pub fn tripped(&self, p: &ThermalParams) -> bool {
        self.level > p.trip_level
    }
}
