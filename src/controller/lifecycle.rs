//! The start-up steps as the controller runs them: each period of
//! calibration and commutation, the homing hand-overs, and `StartUp`'s
//! chaining of whatever is still missing. The steps' own logic is in
//! `crate::lifecycle`.

use super::Controller;
use crate::io::{PwmCommand, SensorSample};
use crate::lifecycle::{CalibrationResult, CommutationInput, Readiness, SettleVerdict};
use crate::motion::ScurveMove;
use crate::protection::FaultSet;
use crate::telemetry::Mode;

impl Controller {
    /// `StartUp`: starts the first step not yet done; ready when none is.
    pub(super) fn next_start_up_step(&mut self) {
        if !self.start_up_sequence || !self.faults.is_empty() {
            return;
        }
        if !self.readiness.contains(Readiness::CURRENTS_CALIBRATED) {
            if self.mode == Mode::Disabled {
                self.begin_calibration();
            }
        } else if !self.readiness.contains(Readiness::COMMUTATED) {
            if self.mode == Mode::Disabled {
                self.begin_commutation();
            }
        } else if !self.readiness.contains(Readiness::HOMED) {
            if self.mode == Mode::Disabled {
                // Commutated before (an earlier `Align`): enable, then home.
                if self.command(crate::Command::Enable).is_err() {
                    self.start_up_sequence = false;
                    return;
                }
            }
            // Homing moves the rod on purpose: it waits until the loops
            // have held it still once (the torque watch's verdict).
            if matches!(self.mode, Mode::Running | Mode::Preloading) && !self.torque_watch.watching() {
                self.begin_homing();
            }
        } else {
            if self.mode == Mode::Disabled && self.command(crate::Command::Enable).is_err() {
                self.start_up_sequence = false;
                return;
            }
            self.start_up_sequence = false;
        }
    }

    /// One period of current-offset calibration: bridge off, brake closed.
    #[inline(never)]
    pub(super) fn calibration_period(&mut self, s: &SensorSample) -> PwmCommand {
        let off = self.bridge_off();
        match self.calibration.add(&self.params.calibration, s.phase_current_a, s.bus_voltage_v) {
            CalibrationResult::Pending => {}
            CalibrationResult::Done { offset_a } => {
                // The host already subtracts the offsets it was given: what
                // is left is the correction.
                for (total, residual) in self.current_offset_a.iter_mut().zip(offset_a) {
                    *total += residual;
                }
                self.readiness.insert(Readiness::CURRENTS_CALIBRATED);
                self.set_mode(Mode::Disabled);
                self.next_start_up_step();
            }
            CalibrationResult::Failed => self.raise(FaultSet::CALIBRATION_FAILED),
        }
        off
    }

    /// One period of commutation: the step's state machine at the position
    /// rate, its stationary current vector every period.
    #[inline(never)]
    pub(super) fn commutation_period(&mut self, s: &SensorSample, position_tick: bool) -> PwmCommand {
        let mut out = self.commutation.output();
        if position_tick {
            let input = CommutationInput {
                position_counts: self.encoder.position_counts(),
                counts_in_turn: self.encoder.counts_in_turn(&self.params.encoder),
                speed_counts_s: self.encoder.speed_counts_s(),
                load_hint_q_a: self.hold_current_q_a,
            };
            out = self.commutation.update(&self.params, &input, self.derived.position_period_s);
            match out.done {
                None => {}
                Some(Ok(r)) => {
                    self.params.encoder.electrical_offset_rad = r.electrical_offset_rad;
                    self.readiness.insert(Readiness::COMMUTATED);
                    // Bumpless: the vector the rotor hangs on, in its own
                    // frame, is where field-oriented control starts; its q
                    // part is the load, which the speed loop now carries.
                    self.start_holding(r.current_q_a);
                    self.hold_current_q_a = r.current_q_a;
                    self.brake_periods = u32::MAX;
                    self.set_mode(Mode::Running);
                    self.torque_watch.arm();
                    self.next_start_up_step();
                    let rotor = self.rotor_state();
                    return self.current_period(s, rotor);
                }
                Some(Err(fault)) => {
                    self.raise(fault);
                    return self.bridge_off();
                }
            }
        }
        self.vector_period(s, out.current_a, out.angle_rad, out.brake_release)
    }

    /// The found reference: move the user frame, back off from the stop.
    pub(super) fn finish_homing(&mut self, found_m: f32) {
        let h = &self.params.homing;
        self.home_offset_m += h.home_position_m - found_m;
        let target = h.home_position_m - h.direction as f32 * h.backoff_m;
        self.readiness.insert(Readiness::HOMED);
        self.hold_here();
        self.trajectory = ScurveMove::plan(self.motor_position_m(), target, &self.params.trajectory);
        self.restart_move();
        self.homing_backing_off = true;
    }

    /// At the position rate while driving: homing ends once backed off and
    /// the hold has settled (`Homing::settle`); a hold that never settles
    /// is refused, not reported ready.
    pub(super) fn homing_tick(&mut self) {
        if self.mode == Mode::Homing && self.homing_backing_off {
            self.homing_settle_tick();
        }
    }

    /// Out of line: it runs only while homing backs off and settles, and
    /// kept out of the position period's code it costs that period nothing.
    #[cold]
    #[inline(never)]
    fn homing_settle_tick(&mut self) {
        if !self.move_in_progress() {
            let x = self.motor_position_m();
            let band_a = super::friction_band_q_a(&self.params, &self.load);
            let dt = self.derived.position_period_s;
            match self.homing.settle(&self.params, self.position_command_m - x, self.current_reference.q, band_a, dt) {
                SettleVerdict::Settling => {}
                // A reference the hold cannot keep still is no reference:
                // the drive goes back to un-homed, not ready on a ringing hold.
                SettleVerdict::NeverSettled => {
                    self.readiness.remove(Readiness::HOMED);
                    self.raise(FaultSet::LIFECYCLE_TIMEOUT);
                }
                SettleVerdict::Settled => {
                    self.homing_backing_off = false;
                    self.set_mode(Mode::Running);
                    self.next_start_up_step();
                }
            }
        }
    }
}
