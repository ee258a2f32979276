//! Axial load force estimated from the q-axis current, for telemetry and for
//! the error observer's load input when no load cell is fitted.

use crate::params::ControlParams;

/// First-order low-passed force estimate at the nut.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadEstimator {
    /// Low-passed force without the fed-forward part.
    slow_n: f32,
    force_n: f32,
}

impl LoadEstimator {
    pub const fn new() -> Self {
        Self { slow_n: 0.0, force_n: 0.0 }
    }

    pub fn reset(&mut self) {
        self.slow_n = 0.0;
        self.force_n = 0.0;
    }

    pub fn force_n(&self) -> f32 {
        self.force_n
    }

    /// The low-passed part alone: weight, tilt and payload, without what the
    /// trajectory's own acceleration and the fed-forward friction add.
    pub fn slow_force_n(&self) -> f32 {
        self.slow_n
    }

    /// Motor torque minus what accelerates the rotating parts, carried to the
    /// nut through the lead with the forward efficiency. Sign: positive when
    /// the cylinder pushes (a compressive load it holds up).
    ///
    /// `feedforward_n` is what the drive itself commands on top of the load:
    /// the trajectory's inertial force (moving mass × reference acceleration)
    /// and the fed-forward Coulomb friction, as a force at the nut. It
    /// bypasses the low-pass: the filter then only smooths the slow part
    /// (weight, tilt, payload) and the estimate keeps up with move starts and
    /// friction reversals without feeding measured motion back into the
    /// observer.
    pub fn update(&mut self, p: &ControlParams, current_q_a: f32, acceleration_rad_s2: f32, feedforward_n: f32, dt_s: f32) -> f32 {
        let torque = p.torque_constant_n_m_a() * current_q_a
            - p.drive_train.rotating_inertia_kg_m2 * acceleration_rad_s2;
        let force = torque * p.drive_train.screw_efficiency / p.metres_per_rad();
        self.filter(p, force, feedforward_n, dt_s)
    }

    /// A load-cell reading replaces the estimate, through the same low-pass:
    /// the observer fed from it closes a loop through the rod's ≈29 Hz mode
    /// (shift → motion → inertial force → predicted deformation → shift), and
    /// the filter keeps that loop's gain below one.
    pub fn update_measured(&mut self, p: &ControlParams, force_n: f32, feedforward_n: f32, dt_s: f32) -> f32 {
        self.filter(p, force_n, feedforward_n, dt_s)
    }

    /// Complementary split: low-pass on `force − feedforward`, `feedforward` added
    /// back unfiltered.
    fn filter(&mut self, p: &ControlParams, force_n: f32, feedforward_n: f32, dt_s: f32) -> f32 {
        let alpha = dt_s * 2.0 * core::f32::consts::PI * p.load_estimate.filter_hz;
        let alpha = if alpha < 1.0 { alpha } else { 1.0 };
        let slow = force_n - feedforward_n;
        if slow.is_finite() {
            self.slow_n += alpha * (slow - self.slow_n);
        }
        if feedforward_n.is_finite() {
            self.force_n = self.slow_n + feedforward_n;
        }
        self.force_n
    }
}
