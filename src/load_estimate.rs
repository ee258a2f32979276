//! Axial load force estimated from the q-axis current, for telemetry and for
//! the error observer's load input when no load cell is fitted or
//! `compensation.force_from_estimate` selects it.

use crate::motion::speed_loop::{coulomb_friction_n_m, friction_direction};
use crate::params::ControlParams;

/// First-order low-passed force estimate at the nut.
#[derive(Clone, Copy, Debug)]
pub struct LoadEstimator {
    /// Low-passed force without the fed-forward part.
    slow_n: f32,
    force_n: f32,
    /// Time the estimate has run since the last reset.
    since_reset_s: f32,
}

impl Default for LoadEstimator {
    fn default() -> Self {
        Self::new()
    }
}

impl LoadEstimator {
    pub const fn new() -> Self {
        Self { slow_n: 0.0, force_n: 0.0, since_reset_s: 0.0 }
    }

    pub fn reset(&mut self) {
        self.slow_n = 0.0;
        self.force_n = 0.0;
        self.since_reset_s = 0.0;
    }

    pub fn force_n(&self) -> f32 {
        self.force_n
    }

    /// The low-passed part alone: weight, tilt and payload, without what the
    /// trajectory's own acceleration and the fed-forward friction add.
    pub fn slow_force_n(&self) -> f32 {
        self.slow_n
    }

    /// The axial force at the nut from the motor torque: what is left of
    /// `K_t i_q` after the rotating parts' inertia `J α`, the viscous drag
    /// `B ω` and the Coulomb friction `T_f`, carried through the lead,
    /// `F = (K_t i_q − J α − B ω − T_f)/(L/2π)`. The screw's efficiency is
    /// in `T_f` (its load share `(L/2π)·μ·|F|` changes sign with the motion),
    /// not a factor on the torque: raising a load takes `F·L/2π/η`, lowering
    /// it only `F·L/2π·(2 − 1/η)`, and a fixed factor would read the same
    /// load ≈ 25 % apart on the two legs. Sign: positive when the cylinder
    /// pushes (a compressive load it holds up). What is left is the load a
    /// load cell at the nut would read: weight, tilt, payload and its
    /// inertia, and any external force.
    ///
    /// Speed and friction follow the planned velocity, never the measured
    /// one, so the estimate does not feed measured motion back into the
    /// observer. At standstill the friction can be anything within its size
    /// `|T_f|`: the torque then only bounds the load to
    /// `F ∈ [(τ − |T_f|)/r, (τ + |T_f|)/r]`, and the estimate stays where it
    /// is while it lies in that band. Reading the stuck nut's torque as the
    /// load instead closes a loop through the observer: its shift moves the
    /// rod a little, the friction flips, the "load" jumps by 2|T_f|/r
    /// (≈ 440 N at the rated load) and so does the next shift.
    ///
    /// `inertial_n` (moving mass × reference acceleration) bypasses the
    /// low-pass: the filter then only smooths the slow part (weight, tilt,
    /// payload) and the estimate keeps up with move starts.
    pub fn update(
        &mut self,
        p: &ControlParams,
        current_q_a: f32,
        acceleration_rad_s2: f32,
        planned_velocity_m_s: f32,
        inertial_n: f32,
        dt_s: f32,
    ) -> f32 {
        let d = &p.drive_train;
        let r = p.metres_per_rad();
        let direction = friction_direction(p, planned_velocity_m_s);
        let friction_n_m = coulomb_friction_n_m(p, self.slow_n);
        let torque = p.torque_constant_n_m_a() * current_q_a
            - d.rotating_inertia_kg_m2 * acceleration_rad_s2
            - d.viscous_friction_n_m_s_rad * planned_velocity_m_s / r
            - direction * friction_n_m;
        let measured = torque / r - inertial_n;
        let band = (1.0 - direction.abs()) * friction_n_m / r;
        // After a reset there is nothing to hold yet: for three time
        // constants of the low-pass the estimate settles on the middle of
        // the band, then it holds.
        let settle_s = 3.0 / (2.0 * core::f32::consts::PI * p.load_estimate.filter_hz);
        let slow = if self.since_reset_s < settle_s {
            self.since_reset_s += dt_s;
            measured
        } else {
            crate::math::clamp(self.slow_n, measured - band, measured + band)
        };
        self.filter(p, slow + inertial_n, inertial_n, dt_s)
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
