//! A new parameter set, applied between two periods.
//!
//! Live parameters (see `params/live.rs`) change with the loops running and
//! their states kept: a proportional gain change moves the integrator by
//! what the output would otherwise jump (`Pi::retune`), an integral gain
//! acts on the error to come only (the integrators hold `∫ki·e`), and a new
//! torque-filter corner starts settled at the present reference. The rest
//! changes with the bridge off only; what it invalidates (commutation,
//! homing) is forgotten.

use super::{expected_load_current_q_a, Controller, Derived};
use crate::foc::Dq;
use crate::lifecycle::Readiness;
use crate::motion::SpeedLoop;
use crate::params::{ControlParams, ValidatedParams};
use crate::protection::FaultSet;
use crate::telemetry::Mode;

/// Why a parameter set was not applied. Nothing of it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ApplyError {
    /// This leaf (index, `params::leaves`; the first such that changed)
    /// changes only with the bridge off (mode `Disabled` or `Fault`, no
    /// short-circuit braking).
    NeedsBridgeOff { leaf: u16 },
    /// The controller did not answer (on the board: the PWM interrupt did
    /// not take the set in time); nothing was applied.
    NoAnswer,
    /// This leaf is beyond what the drive's hardware is rated for (the
    /// board's current, bus or overcurrent-trip rating); nothing applied.
    BeyondHardware { leaf: u16 },
}

impl Controller {
    /// Bridge off: nothing drives the motor and no start-up step runs.
    pub fn bridge_is_off(&self) -> bool {
        matches!(self.mode, Mode::Disabled | Mode::Fault) && self.short_circuit_periods == 0
    }

    /// Applies `new` between two periods (thread context on the host; on
    /// the board, the ISR takes it from the mailbox before its step).
    /// Live parameters change bumplessly with the bridge on; a set that
    /// changes any other is refused then, naming the first such field.
    /// Validated sets only, so the loops never see an unusable one.
    pub fn apply_params(&mut self, new: &ValidatedParams) -> Result<(), ApplyError> {
        let new = *new.get();
        let old = self.params;
        let structural = old.bridge_off_change(&new);
        if let Some(leaf) = structural {
            if !self.bridge_is_off() {
                return Err(ApplyError::NeedsBridgeOff { leaf });
            }
        }
        if old.speed_pi != new.speed_pi || old.torque_filter_hz != new.torque_filter_hz {
            self.speed_loop.retune(&old, &new, self.current_reference.q);
        }
        if old.current_pi.kp != new.current_pi.kp {
            let error = Dq { d: self.current_reference.d - self.current_dq.d, q: self.current_reference.q - self.current_dq.q };
            self.current_loop.retune(old.current_pi.kp, new.current_pi.kp, error);
        }
        self.params = new;
        self.derived = Derived::of(&new);
        if structural.is_some() {
            self.after_structural_change(&old);
        }
        // A controller built from an unusable set (`INVALID_PARAMS`) has a
        // usable one now: the fault clears on `ClearFaults`.
        self.present = self.present.difference(FaultSet::INVALID_PARAMS);
        Ok(())
    }

    /// Bridge off, structure changed: rebuild what depends on it.
    fn after_structural_change(&mut self, old: &ControlParams) {
        let new = self.params;
        self.speed_loop = SpeedLoop::new(&new);
        // (`min`, not `clamp`: no panic path even for a divider of 0.)
        self.speed_countdown = self.speed_countdown.min(new.rates.speed_loop_divider).max(1);
        self.position_countdown = self.position_countdown.min(self.derived.speed_ticks_per_position_tick).max(1);
        let angle_changed = old.motor.pole_pairs != new.motor.pole_pairs
            || old.encoder.counts_per_rev != new.encoder.counts_per_rev
            || old.encoder.direction != new.encoder.direction
            || old.encoder.electrical_offset_rad != new.encoder.electrical_offset_rad;
        let frame_changed = old.encoder.counts_per_rev != new.encoder.counts_per_rev
            || old.encoder.direction != new.encoder.direction
            || old.drive_train.screw_lead_m != new.drive_train.screw_lead_m;
        if angle_changed && !new.startup.commutation_known {
            // The offset found by commutation belongs to the old angle.
            self.readiness.remove(Readiness::COMMUTATED);
            self.readiness.remove(Readiness::HOMED);
        }
        if frame_changed && !new.startup.homed {
            self.readiness.remove(Readiness::HOMED);
        }
        if new.startup.commutation_known {
            self.readiness.insert(Readiness::COMMUTATED);
            self.readiness.insert(Readiness::CURRENTS_CALIBRATED);
        }
        if new.startup.homed {
            self.readiness.insert(Readiness::HOMED);
        }
        if old.startup.expected_load_force_n != new.startup.expected_load_force_n || old.motor != new.motor || frame_changed {
            self.hold_current_q_a = expected_load_current_q_a(&new);
        }
    }
}
