//! Homing on an incremental encoder: drive towards the end stop (or the home
//! switch) at a constant speed with a bounded current, and take the contact
//! (or the switch edge) as the reference.
//!
//! The contact is judged when the command has run ahead of the rod by
//! `contact_following_m` and the rotor has been still for `contact_time_s`:
//! by then the speed loop sits on its homing current bound, so the push
//! into the stop — and with it the stop's and the drive train's
//! deflection — is the same every time. That is what makes it repeatable.
//!
//! After the back-off the drive is ready only once the hold is quiet
//! ([`Homing::settle`]): the position error within half the torque watch's
//! travel and the q current within the screw's friction band of where it
//! stood, both for `commutation.settle_s`. A hold whose loop has lost its
//! margin at the retracted end (a unit whose K_t/J runs above the drive's
//! belief, its axial mode near 90 Hz where the structure is stiffest and
//! the torque filter's lag is largest) rings there at tens of micrometres
//! and amperes, and is refused with `lifecycle_timeout` after
//! `commutation.settle_timeout_s` instead of being reported ready.

use crate::params::{ControlParams, HomingMethod};
use crate::protection::FaultSet;

#[derive(Clone, Copy, Debug, Default)]
pub struct HomingInput {
    /// Motor-side position in the controller's present frame.
    pub position_m: f32,
    pub speed_rad_s: f32,
    pub home_switch: Option<bool>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingOutput {
    /// Position command and its velocity for the position loop.
    pub position_m: f32,
    pub velocity_m_s: f32,
    /// `Ok(x)`: the home point lies at `x` in the present frame.
    pub done: Option<Result<f32, FaultSet>>,
}

#[derive(Clone, Copy, Debug)]
pub struct Homing {
    start_m: f32,
    command_m: f32,
    elapsed_s: f32,
    contact_s: f32,
    switch_was: Option<bool>,
    done: Option<Result<f32, FaultSet>>,
    /// The settle after the back-off: how long the hold has been quiet, how
    /// long it has been judged, and the q current the quiet stretch began at.
    quiet_s: f32,
    settling_s: f32,
    anchor_q_a: f32,
}

/// The hold's settle after the back-off, once per position period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SettleVerdict {
    Settling,
    Settled,
    NeverSettled,
}

/// Time to reach the approach speed: a step in velocity would kick the rod
/// mode (≈ 29 Hz); 50 ms is one and a half of its periods.
const APPROACH_RAMP_S: f32 = 0.05;
/// Homing may take this many times the time the whole travel needs at the
/// approach speed: enough for a slow, loaded lift, bounded for a stall.
const HOMING_TIME_FACTOR: f32 = 1.5;
/// How far past `contact_following_m` the command may lead a stalled rod.
const CONTACT_LEAD_FACTOR: f32 = 1.5;

impl Homing {
    pub fn new(start_m: f32) -> Self {
        Self {
            start_m,
            command_m: start_m,
            elapsed_s: 0.0,
            contact_s: 0.0,
            switch_was: None,
            done: None,
            quiet_s: 0.0,
            settling_s: 0.0,
            anchor_q_a: f32::NAN,
        }
    }

    /// One look at the hold after the back-off: `following_error_m`
    /// (command − motor side) and the q current reference.
    ///
    /// Quiet means still and not pushing: the error within half of
    /// `brake.torque_watch_travel_m` (the enable sag bar; a rod kept in a
    /// band of one travel for the settle time moves under travel / settle
    /// time on average, 0.2 mm/s), and the q current within `band_a` of
    /// where the quiet stretch began. The caller gives the screw's friction
    /// band in current: at rest friction takes up any torque inside it, so
    /// a held load's current wanders only within it, while a current
    /// swinging beyond it accelerates the rotor and the rod (a ring of
    /// ±27 A on the light rig that found this, against a band of ≈ 1 A).
    /// NaN compares false: not quiet.
    pub fn settle(&mut self, p: &ControlParams, following_error_m: f32, current_q_a: f32, band_a: f32, dt_s: f32) -> SettleVerdict {
        self.settling_s += dt_s;
        let still = following_error_m.abs() <= 0.5 * p.brake.torque_watch_travel_m;
        if still && (current_q_a - self.anchor_q_a).abs() <= band_a {
            self.quiet_s += dt_s;
        } else {
            self.quiet_s = 0.0;
            self.anchor_q_a = current_q_a;
        }
        if self.quiet_s >= p.commutation.settle_s {
            SettleVerdict::Settled
        } else if self.settling_s > p.commutation.settle_timeout_s {
            SettleVerdict::NeverSettled
        } else {
            SettleVerdict::Settling
        }
    }

    pub fn update(&mut self, p: &ControlParams, s: &HomingInput, dt_s: f32) -> HomingOutput {
        let h = &p.homing;
        let dir = h.direction as f32;
        if self.done.is_some() {
            return HomingOutput { position_m: self.command_m, velocity_m_s: 0.0, done: self.done };
        }
        self.elapsed_s += dt_s;
        let v = h.speed_m_s * crate::math::min(self.elapsed_s / APPROACH_RAMP_S, 1.0);
        let travelled = (s.position_m - self.start_m) * dir;
        match h.method {
            HomingMethod::HardStop => {
                let ahead = (self.command_m - s.position_m) * dir;
                if ahead > h.contact_following_m && s.speed_rad_s.abs() < h.contact_speed_rad_s {
                    self.contact_s += dt_s;
                } else {
                    self.contact_s = 0.0;
                }
                if self.contact_s >= h.contact_time_s {
                    self.done = Some(Ok(s.position_m));
                }
            }
            HomingMethod::Switch => match s.home_switch {
                // No switch wired: the method cannot work; say so at once.
                None => self.done = Some(Err(FaultSet::HOMING_FAILED)),
                Some(closed) => {
                    if closed && self.switch_was == Some(false) {
                        self.done = Some(Ok(s.position_m));
                    } else if closed && self.switch_was.is_none() {
                        // Already on the switch at the start: back off first
                        // would need a second pass; refuse instead of guessing.
                        self.done = Some(Err(FaultSet::HOMING_FAILED));
                    }
                    self.switch_was = Some(closed);
                }
            },
        }
        // Travel bounds a rod that moves; time bounds one that does not (a
        // switch that never closes while the rod rests on the stop).
        let time_max_s = HOMING_TIME_FACTOR * h.travel_max_m / h.speed_m_s + APPROACH_RAMP_S;
        if self.done.is_none() && (travelled.abs() > h.travel_max_m || self.elapsed_s > time_max_s) {
            self.done = Some(Err(FaultSet::HOMING_FAILED));
        }
        if self.done.is_none() {
            // The command never runs more than a little past the contact
            // distance ahead of a rod that does not follow: the push into the
            // stop stays small, and so does the speed reference the position
            // loop makes of the lead (far inside the speed-following trip).
            let lead = (self.command_m - s.position_m) * dir;
            if lead < CONTACT_LEAD_FACTOR * h.contact_following_m {
                self.command_m += dir * v * dt_s;
                return HomingOutput { position_m: self.command_m, velocity_m_s: dir * v, done: None };
            }
            return HomingOutput { position_m: self.command_m, velocity_m_s: 0.0, done: None };
        }
        self.command_m = s.position_m;
        HomingOutput { position_m: self.command_m, velocity_m_s: 0.0, done: self.done }
    }
}
