//! Axial load force estimated from the q-axis current, for telemetry and for
//! the error observer's load input when no load cell is fitted.

use crate::params::ControlParams;

/// First-order low-passed force estimate at the nut.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadEstimator {
    force_n: f32,
}

impl LoadEstimator {
    pub const fn new() -> Self {
        Self { force_n: 0.0 }
    }

    pub fn reset(&mut self) {
        self.force_n = 0.0;
    }

    pub fn force_n(&self) -> f32 {
        self.force_n
    }

    /// Motor torque minus what accelerates the rotating parts, carried to the
    /// nut through the lead with the forward efficiency. Sign: positive when
    /// the cylinder pushes (a compressive load it holds up).
    pub fn update(&mut self, p: &ControlParams, current_q_a: f32, acceleration_rad_s2: f32, dt_s: f32) -> f32 {
        let torque = p.torque_constant_n_m_a() * current_q_a
            - p.drive_train.rotating_inertia_kg_m2 * acceleration_rad_s2;
        let force = torque * p.drive_train.screw_efficiency / p.metres_per_rad();
        let alpha = dt_s * 2.0 * core::f32::consts::PI * p.load_estimate.filter_hz;
        let alpha = if alpha < 1.0 { alpha } else { 1.0 };
        if force.is_finite() {
            self.force_n += alpha * (force - self.force_n);
        }
        self.force_n
    }

    /// A measured force replaces the estimate (load cell fitted).
    pub fn set_measured(&mut self, force_n: f32) {
        self.force_n = force_n;
    }
}
