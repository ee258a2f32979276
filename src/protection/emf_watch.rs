//! Encoder plausibility from the back-EMF, for a rotor the counts say is
//! still (a lost encoder under a hanging load, even at standstill).
//!
//! With a working encoder the current loop's frame turns with the rotor, so
//! the EMF vector `e = u − R i` keeps its direction in that frame (along q).
//! With a frozen count the frame stands still while the rotor turns: `e`
//! rotates in it at the slip's electrical speed. Counting that rotation,
//! rather than `|e|`, is blind to what only makes voltage without motion (an
//! open lead, a current the loop cannot make), which has a fixed direction.

use crate::foc::Dq;
use crate::math::atan2;
use crate::params::ControlParams;

#[derive(Clone, Copy, Debug, Default)]
pub struct EmfWatch {
    previous: Dq,
    rotating_s: f32,
}

impl EmfWatch {
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// One look, every `dt_s`: true once `e` has turned faster than
    /// `power_stage.emf_speed_mismatch_rad_s` (mechanical) for
    /// `power_stage.emf_mismatch_time_s`.
    pub fn update(&mut self, p: &ControlParams, voltage_dq: Dq, current_dq: Dq, dt_s: f32) -> bool {
        let r = p.motor.phase_resistance_ohm;
        let e = Dq { d: voltage_dq.d - r * current_dq.d, q: voltage_dq.q - r * current_dq.q };
        let prev = self.previous;
        self.previous = e;
        let pole_pairs = p.motor.pole_pairs as f32;
        let threshold_e = p.power_stage.emf_speed_mismatch_rad_s * pole_pairs;
        // Below half the EMF of the threshold speed the direction is noise.
        let e_min = 0.5 * p.motor.flux_linkage_wb * threshold_e;
        let mag2 = |v: Dq| v.d * v.d + v.q * v.q;
        if !(mag2(e) > e_min * e_min && mag2(prev) > e_min * e_min) {
            self.rotating_s = 0.0;
            return false;
        }
        let turned = atan2(prev.d * e.q - prev.q * e.d, prev.d * e.d + prev.q * e.q);
        if turned.abs() > threshold_e * dt_s {
            self.rotating_s += dt_s;
        } else {
            self.rotating_s = 0.0;
        }
        self.rotating_s >= p.power_stage.emf_mismatch_time_s
    }
}
