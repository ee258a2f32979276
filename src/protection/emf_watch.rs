//! Encoder plausibility from the back-EMF, for a rotor the counts say is
//! still (a lost encoder under a hanging load, even at standstill).
//!
//! With a working encoder the current loop's frame turns with the rotor, so
//! the EMF vector `e = u − R i` keeps its direction in that frame (along q).
//! With a frozen count the frame stands still while the rotor turns: `e`
//! rotates in it at the slip's electrical speed. Counting that rotation,
//! rather than `|e|`, is blind to what only makes voltage without motion (an
//! open lead, a current the loop cannot make), which has a fixed direction,
//! and, netted over a window, to dead time's back-and-forth wobble.
//!
//! A window is judged on the motion of its own length, and a rotor that
//! coasts to rest or reverses (a frozen count under a light hanging load:
//! the stationary current vector brakes it, gravity turns it back) lets `e`
//! fall below the threshold EMF and restart the window just when the
//! missing counts are judged. What separates that from a stall is how far
//! the rotor went since the count last moved: a stalled rotor stands at its
//! last count (under one count of twist), so `e` cannot turn a net
//! electrical turn in the frozen frame; a rotor the counter lost can, and
//! did as soon as it ran a quarter of a mechanical turn (at four pole pairs)
//! unseen. That net angle is kept across windows and cleared by a count.

use crate::foc::Dq;
use crate::math::atan2;
use core::f32::consts::FRAC_PI_2;
use crate::params::ControlParams;

#[derive(Clone, Copy, Debug, Default)]
pub struct EmfWatch {
    previous: Dq,
    /// The window being judged: its length and the angle `e` turned in it
    /// (signed: a dead-time or ripple wobble turns back and forth and nets
    /// little; a slipping rotor turns one way).
    window_s: f32,
    turned_rad: f32,
    /// The net angle `e` turned since the count last moved (signed; steps
    /// with too little EMF to judge are left out, not reset).
    turned_since_count_rad: f32,
}

impl EmfWatch {
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The count moved: the rotor is where the encoder says.
    pub fn count_moved(&mut self) {
        self.turned_since_count_rad = 0.0;
    }

    /// True when `e` turned a net electrical turn or more since the count
    /// last moved: the rotor ran on unseen (a standing rotor's `e` keeps its
    /// direction in the standing frame; current steps swing it and bring it
    /// back, they do not wind it round).
    pub fn turned_since_count(&self) -> bool {
        self.turned_since_count_rad.abs() >= core::f32::consts::TAU
    }

    /// True when the window judged so far shows `e` turning, on average,
    /// faster than the mismatch threshold: the rotor turns though the count
    /// may not. False with too little EMF to judge (a rotor at rest, or
    /// turning slower than the threshold) or a fixed `e` (a stalled rotor:
    /// neither it nor the frame turns, whatever resistance error `u − R i`
    /// leaves).
    pub fn sees_rotation(&self, p: &ControlParams) -> bool {
        let threshold_e = p.power_stage.emf_speed_mismatch_rad_s * p.motor.pole_pairs as f32;
        self.window_s > 0.0 && self.turned_rad.abs() > threshold_e * self.window_s
    }

    /// One look, every `dt_s`: true once `e` has turned, on average over
    /// `power_stage.emf_mismatch_time_s`, faster than
    /// `power_stage.emf_speed_mismatch_rad_s` (mechanical).
    pub fn update(&mut self, p: &ControlParams, voltage_dq: Dq, current_dq: Dq, dt_s: f32) -> bool {
        let r = p.motor.phase_resistance_ohm;
        let e = Dq { d: voltage_dq.d - r * current_dq.d, q: voltage_dq.q - r * current_dq.q };
        let prev = self.previous;
        self.previous = e;
        let threshold_e = p.power_stage.emf_speed_mismatch_rad_s * p.motor.pole_pairs as f32;
        // Below the EMF of the threshold speed the direction is noise and
        // inverter dead time.
        let e_min = p.motor.flux_linkage_wb * threshold_e;
        let mag2 = |v: Dq| v.d * v.d + v.q * v.q;
        if !(mag2(e) > e_min * e_min && mag2(prev) > e_min * e_min) {
            self.window_s = 0.0;
            self.turned_rad = 0.0;
            return false;
        }
        let step_rad = atan2(prev.d * e.q - prev.q * e.d, prev.d * e.d + prev.q * e.q);
        if step_rad.abs() <= FRAC_PI_2 {
            self.turned_since_count_rad += step_rad;
        }
        if step_rad.abs() > FRAC_PI_2 {
            // Half a turn or more between two looks is no slip (at the
            // highest legal speed a slipping frame turns `e` by a quarter
            // turn a look at most): the speed changed sign and `e` passed
            // through zero under the `L di/dt` and `ω L i` terms, as in a
            // rotor that bounces back off an obstacle. Judge afresh.
            self.window_s = 0.0;
            self.turned_rad = 0.0;
            return false;
        }
        self.turned_rad += step_rad;
        self.window_s += dt_s;
        if self.window_s < p.power_stage.emf_mismatch_time_s {
            return false;
        }
        let slipping = self.turned_rad.abs() > threshold_e * self.window_s;
        self.window_s = 0.0;
        self.turned_rad = 0.0;
        slipping
    }
}
