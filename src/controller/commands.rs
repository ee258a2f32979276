//! The mode machine: what a host may ask, when, and what it changes.
//! Nothing here runs the loops; `step` does, one period at a time.

use super::Controller;
use crate::foc::Dq;
use crate::lifecycle::{Commutation, CurrentCalibration, Homing, Readiness};
use crate::motion::{ScurveMove, Setpoint, StopRamp};
use crate::protection::{clamp_to_stroke, FaultSet, LimitFlags};
use crate::telemetry::Mode;

/// What the host (main task, simulator scenario) may ask of the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Switch the bridge on and hold the present position; with a brake the
    /// hold current builds before it lets go. Needs commutation.
    Enable,
    /// Stop, let the brake close under the loops, switch the bridge off.
    Disable,
    /// Plan a jerk-limited move from the present command to `position_m`.
    /// Needs homing.
    MoveTo { position_m: f32 },
    /// One setpoint of a stream (a platform controller at 100 Hz–1 kHz):
    /// position, velocity and an optional feedforward force (N, positive
    /// opposing extension). Interpolated at the position-loop rate; no
    /// setpoint for `stream.timeout_s` ends in a controlled stop. Needs
    /// homing; the position is bounded by the stroke, the velocity by
    /// `trajectory.max_velocity_m_s`, both reported.
    Stream { position_m: f32, velocity_m_s: f32, force_n: Option<f32> },
    /// Ends a stream: the drive holds where the reference rests.
    StreamEnd,
    /// A controlled stop of whatever moves (a planned move, a jog, a
    /// stream, homing): from the present reference and the measured
    /// velocity down at `faults.stop_deceleration_m_s2` to rest, then
    /// holding there, bridge on, no fault latched. Accepted with nothing
    /// to stop; refused (`Busy`) during calibration and commutation, which
    /// `Disable` ends instead.
    Stop,
    /// Move by `distance_m` at no more than `homing.jog_speed_max_m_s`: the
    /// only motion a drive that is not homed may make.
    Jog { distance_m: f32 },
    /// Declare the present motor-side position to be `position_m`: a user
    /// offset, apart from the count the electrical angle comes from.
    SetHome { position_m: f32 },
    /// Measure the current-sensor offsets (bridge off).
    Calibrate,
    /// Commutation: find the electrical offset with the brake holding the
    /// load, check direction and pole pairs; ends holding, bridge on.
    Align,
    /// Homing (`homing.method`); ends holding at home + back-off.
    Home,
    /// Every start-up step not yet done, in order, ending ready: calibrate,
    /// align, home.
    StartUp,
    /// Clear latched faults whose cause is gone.
    ClearFaults,
    /// An external shift added to the trajectory before the position loop,
    /// metres (on top of the observer's, if compensation is on).
    SetPositionShift { shift_m: f32 },
    /// Switch the observer's terminal-error compensation on or off.
    SetCompensation { enabled: bool },
    /// Run the observer with these weights (checked by
    /// `observer::block::validate`; the compiled model by default). Any
    /// mode: the shift follows at the compensation's rate limit.
    SetObserverWeights { weights: &'static crate::observer::block::Weights },
}

/// A command was taken, possibly after bounding it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandOutcome {
    Accepted,
    /// The target lay outside the stroke; this is the position planned instead.
    ClampedToStroke { position_m: f32 },
}

/// Why a command was refused. Nothing changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// Faults are latched; clear them first.
    Faulted(FaultSet),
    /// These latched faults still have their cause present.
    CauseStillPresent(FaultSet),
    /// The command needs the bridge enabled (Running).
    NotRunning,
    /// The command needs the bridge disabled.
    NotDisabled,
    /// A move or a start-up step is still in progress.
    Busy,
    /// A NaN or infinite argument.
    NotFinite,
    /// An argument beyond its bound (e.g. a shift above
    /// `faults.observer_shift_max_m`).
    OutOfRange,
    /// The bus voltage is below `faults.bus_undervoltage_v`.
    BusLow,
    /// The start-up step still missing: current calibration…
    NotCalibrated,
    /// …commutation (`Align`)…
    NotCommutated,
    /// …or homing (`Home`, or `SetHome` on a rig with a known reference).
    NotHomed,
}

/// Largest user position `SetHome` takes: far beyond any stroke, small
/// enough that positions and angles stay exact to a count in `f32`.
const HOME_POSITION_MAX_M: f32 = 100.0;

/// Faults after which the electrical offset and the reference are not
/// trusted any more (the counter may have lost or gained counts).
const LOSES_POSITION: FaultSet = FaultSet::ENCODER_JUMP.union(FaultSet::ENCODER_LOST).union(FaultSet::WATCHDOG_RESET).union(FaultSet::WRONG_DIRECTION);

impl Controller {
    /// Handles one command from thread context.
    pub fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
        if self.test.active()
            && !matches!(
                cmd,
                Command::Disable | Command::Enable | Command::ClearFaults | Command::StreamEnd | Command::SetCompensation { .. } | Command::SetPositionShift { .. }
            )
        {
            // A test owns the references until it ends (or `Disable`).
            return Err(CommandError::Busy);
        }
        match cmd {
            Command::Enable => self.enable(),
            Command::Disable => {
                self.finish_test(false);
                self.start_up_sequence = false;
                self.stream.stop();
                if self.params.brake.fitted && matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Homing | Mode::Preloading) {
                    // Stop, let the brake close under the loops, then switch off.
                    let v = self.speed_rad_s() * self.params.metres_per_rad();
                    self.stop = StopRamp::new(self.position_command_m, v, self.params.faults.stop_deceleration_m_s2);
                    self.brake_periods = 0;
                    self.set_mode(Mode::Braking);
                } else if self.mode == Mode::Aligning {
                    // The commutation holds its vector while the brake closes.
                    return Err(CommandError::Busy);
                } else if self.mode != Mode::Braking {
                    self.set_mode(if self.faults.is_empty() { Mode::Disabled } else { Mode::Fault });
                    self.reset_loops();
                }
                Ok(CommandOutcome::Accepted)
            }
            Command::MoveTo { position_m } => {
                if !position_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                self.check_can_move()?;
                if !self.readiness.contains(Readiness::HOMED) {
                    return Err(CommandError::NotHomed);
                }
                let l = &self.params.limits;
                let (target, clamped) = clamp_to_stroke(position_m, l.stroke_min_m, l.stroke_max_m);
                self.trajectory = ScurveMove::plan(self.trajectory.end_m(), target, &self.params.trajectory);
                self.restart_move();
                if clamped {
                    self.pending_limits.insert(LimitFlags::STROKE);
                    Ok(CommandOutcome::ClampedToStroke { position_m: target })
                } else {
                    Ok(CommandOutcome::Accepted)
                }
            }
            Command::Stream { position_m, velocity_m_s, force_n } => self.stream_setpoint(position_m, velocity_m_s, force_n),
            Command::StreamEnd => {
                if self.stream.active() {
                    let here = self.position_reference_m;
                    self.stream.stop();
                    self.trajectory = ScurveMove::hold(here);
                    self.restart_move();
                }
                Ok(CommandOutcome::Accepted)
            }
            Command::Stop => self.stop_motion(),
            Command::Jog { distance_m } => {
                if !distance_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                self.check_can_move()?;
                let mut limits = self.params.trajectory;
                limits.max_velocity_m_s = crate::math::min(limits.max_velocity_m_s, self.params.homing.jog_speed_max_m_s);
                let mut target = self.trajectory.end_m() + distance_m;
                let mut outcome = CommandOutcome::Accepted;
                if self.readiness.contains(Readiness::HOMED) {
                    let l = &self.params.limits;
                    let (t, clamped) = clamp_to_stroke(target, l.stroke_min_m, l.stroke_max_m);
                    if clamped {
                        self.pending_limits.insert(LimitFlags::STROKE);
                        outcome = CommandOutcome::ClampedToStroke { position_m: t };
                    }
                    target = t;
                }
                self.trajectory = ScurveMove::plan(self.trajectory.end_m(), target, &limits);
                self.restart_move();
                Ok(outcome)
            }
            Command::SetHome { position_m } => {
                if !position_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                if position_m.abs() > HOME_POSITION_MAX_M {
                    return Err(CommandError::OutOfRange);
                }
                if matches!(self.mode, Mode::Calibrating | Mode::Aligning | Mode::Homing) || self.move_in_progress() {
                    return Err(CommandError::Busy);
                }
                let (l, overtravel_m) = (&self.params.limits, self.params.faults.stroke_overtravel_m);
                let outside = position_m < l.stroke_min_m - overtravel_m || position_m > l.stroke_max_m + overtravel_m;
                if outside && !matches!(self.mode, Mode::Disabled | Mode::Fault) {
                    // With the bridge on, the rod would be declared beyond
                    // the stroke and the overtravel trip would drop the load
                    // at once (a mistyped sign does that).
                    return Err(CommandError::OutOfRange);
                }
                // Only the user frame moves: the count, and with it the
                // electrical angle, stays where it is.
                self.home_offset_m += position_m - self.motor_position_m();
                self.readiness.insert(Readiness::HOMED);
                self.hold_here();
                Ok(CommandOutcome::Accepted)
            }
            Command::Calibrate => {
                self.check_idle()?;
                self.begin_calibration();
                Ok(CommandOutcome::Accepted)
            }
            Command::Align => {
                self.check_idle()?;
                if !self.readiness.contains(Readiness::CURRENTS_CALIBRATED) {
                    return Err(CommandError::NotCalibrated);
                }
                self.begin_commutation();
                Ok(CommandOutcome::Accepted)
            }
            Command::Home => {
                if !self.faults.is_empty() {
                    return Err(CommandError::Faulted(self.faults));
                }
                if !self.readiness.contains(Readiness::COMMUTATED) {
                    return Err(CommandError::NotCommutated);
                }
                match self.mode {
                    Mode::Disabled => {
                        self.enable()?;
                        self.begin_homing();
                    }
                    Mode::Running | Mode::Preloading if !self.move_in_progress() => self.begin_homing(),
                    _ => return Err(CommandError::Busy),
                }
                Ok(CommandOutcome::Accepted)
            }
            Command::StartUp => {
                if !self.faults.is_empty() {
                    return Err(CommandError::Faulted(self.faults));
                }
                if !matches!(self.mode, Mode::Disabled | Mode::Running) || self.move_in_progress() {
                    return Err(CommandError::Busy);
                }
                // A stored offset is checked, not trusted: the commutation
                // step runs and must find it (a light load hides an offset
                // that makes no torque until homing drops the rod).
                if self.mode == Mode::Disabled && self.params.startup.commutation_known && self.params.brake.fitted {
                    self.readiness.remove(Readiness::COMMUTATED);
                }
                self.start_up_sequence = true;
                self.next_start_up_step();
                Ok(CommandOutcome::Accepted)
            }
            Command::ClearFaults => {
                let stuck = self.faults.intersection(self.present);
                if !stuck.is_empty() {
                    return Err(CommandError::CauseStillPresent(stuck));
                }
                self.faults = FaultSet::NONE;
                match self.mode {
                    Mode::Fault => self.set_mode(Mode::Disabled),
                    Mode::Stopping => {
                        // Resume position control where the stop left it.
                        self.trajectory = ScurveMove::hold(self.position_command_m);
                        self.restart_move();
                        self.set_mode(Mode::Running);
                    }
                    _ => {}
                }
                Ok(CommandOutcome::Accepted)
            }
            Command::SetPositionShift { shift_m } => {
                if !shift_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                if shift_m.abs() > self.params.faults.observer_shift_max_m {
                    return Err(CommandError::OutOfRange);
                }
                self.position_shift_m = shift_m;
                Ok(CommandOutcome::Accepted)
            }
            Command::SetCompensation { enabled } => {
                self.compensator.set_enabled(enabled);
                Ok(CommandOutcome::Accepted)
            }
            Command::SetObserverWeights { weights } => {
                self.compensator.set_model(weights);
                Ok(CommandOutcome::Accepted)
            }
        }
    }

    /// `Enable`: the bridge on, holding here; with a brake, the hold current
    /// builds for `brake.preload_time_s` before the brake is told to open.
    fn enable(&mut self) -> Result<CommandOutcome, CommandError> {
        if !self.faults.is_empty() {
            return Err(CommandError::Faulted(self.faults));
        }
        if !self.readiness.contains(Readiness::COMMUTATED) {
            return Err(CommandError::NotCommutated);
        }
        // Before the first sample there is no reading; the first period
        // then checks it like any other.
        if self.tick > 0 && self.bus_voltage_v < self.params.faults.bus_undervoltage_v {
            return Err(CommandError::BusLow);
        }
        match self.mode {
            Mode::Running | Mode::Homing | Mode::Preloading => return Ok(CommandOutcome::Accepted),
            // The loops are holding: keep them, open the brake again.
            Mode::Braking => {
                self.hold_here();
                self.brake_periods = self.derived.brake_preload_periods;
                self.set_mode(Mode::Running);
                return Ok(CommandOutcome::Accepted);
            }
            Mode::Disabled => {
                // Without a brake nothing holds the load before the loops
                // do: no preload to build, nothing to wait for.
                let preload = if self.params.brake.fitted { self.hold_current_q_a } else { 0.0 };
                self.start_holding(preload);
                self.brake_periods = 0;
                self.torque_watch.arm();
            }
            _ => return Err(CommandError::Busy),
        }
        self.set_mode(if self.params.brake.fitted { Mode::Preloading } else { Mode::Running });
        Ok(CommandOutcome::Accepted)
    }

    /// `Stream`: bounded, reported, handed to the interpolator.
    fn stream_setpoint(&mut self, position_m: f32, velocity_m_s: f32, force_n: Option<f32>) -> Result<CommandOutcome, CommandError> {
        let force_n = force_n.unwrap_or(0.0);
        if !(position_m.is_finite() && velocity_m_s.is_finite() && force_n.is_finite()) {
            return Err(CommandError::NotFinite);
        }
        if force_n.abs() > self.params.thrust_peak_n() {
            return Err(CommandError::OutOfRange);
        }
        if !self.readiness.contains(Readiness::COMMUTATED) {
            return Err(CommandError::NotCommutated);
        }
        if !self.readiness.contains(Readiness::HOMED) {
            return Err(CommandError::NotHomed);
        }
        if !self.faults.is_empty() {
            // Named before the mode: a latched fault is why the drive is not
            // running, and clearing it is the next step.
            return Err(CommandError::Faulted(self.faults));
        }
        if self.mode != Mode::Running {
            return Err(CommandError::NotRunning);
        }
        if self.stream.stopping() {
            // The stream was lost and the rod is stopping: a late point
            // does not restart it; the stop ends in `stream_timeout`.
            return Err(CommandError::Faulted(FaultSet::STREAM_TIMEOUT));
        }
        if !self.stream.active() && self.move_in_progress() {
            return Err(CommandError::Busy);
        }
        let l = &self.params.limits;
        let (position_m, clamped) = clamp_to_stroke(position_m, l.stroke_min_m, l.stroke_max_m);
        let v_max = self.params.trajectory.max_velocity_m_s;
        let velocity = crate::math::clamp(velocity_m_s, -v_max, v_max);
        if velocity != velocity_m_s {
            self.pending_limits.insert(LimitFlags::SPEED);
        }
        let here = Setpoint { position_m: self.position_reference_m, velocity_m_s: 0.0 };
        let max = self.derived.stream_max_ticks;
        self.stream.push(Setpoint { position_m, velocity_m_s: velocity }, force_n, here, max, self.derived.position_period_s);
        if clamped {
            self.pending_limits.insert(LimitFlags::STROKE);
            return Ok(CommandOutcome::ClampedToStroke { position_m });
        }
        Ok(CommandOutcome::Accepted)
    }

    /// `Stop`: a stop ramp from the reference, ended in `stop_reference`.
    fn stop_motion(&mut self) -> Result<CommandOutcome, CommandError> {
        match self.mode {
            Mode::Running | Mode::Preloading | Mode::Homing => {}
            // Not moving, or already on the way to rest.
            Mode::Disabled | Mode::Fault | Mode::Stopping | Mode::Braking => return Ok(CommandOutcome::Accepted),
            Mode::Calibrating | Mode::Aligning => return Err(CommandError::Busy),
        }
        self.start_up_sequence = false;
        if self.mode != Mode::Homing && !self.move_in_progress() {
            return Ok(CommandOutcome::Accepted);
        }
        self.stream.stop();
        self.homing_backing_off = false;
        if self.mode == Mode::Preloading || self.brake_opening() {
            // The move has not started: hold where it would have begun.
            self.hold_here();
        } else {
            let v = self.speed_rad_s() * self.params.metres_per_rad();
            self.stop = StopRamp::new(self.position_reference_m, v, self.params.faults.stop_deceleration_m_s2);
            self.commanded_stop = true;
        }
        if self.mode == Mode::Homing {
            self.set_mode(Mode::Running);
        }
        Ok(CommandOutcome::Accepted)
    }

    /// One position period of a commanded stop; at rest the drive holds.
    pub(super) fn stop_reference(&mut self) -> crate::motion::TrajectorySample {
        let r = self.stop.advance(self.derived.position_period_s);
        if self.stop.at_rest() {
            self.commanded_stop = false;
            self.trajectory = ScurveMove::hold(r.position_m);
            self.restart_move();
        }
        r
    }

    /// Refused unless the drive is off with nothing latched.
    fn check_idle(&self) -> Result<(), CommandError> {
        if !self.faults.is_empty() {
            return Err(CommandError::Faulted(self.faults));
        }
        if self.mode != Mode::Disabled {
            return Err(CommandError::NotDisabled);
        }
        Ok(())
    }

    /// Moves need the bridge on, no move under way and the offset known.
    fn check_can_move(&self) -> Result<(), CommandError> {
        if !self.readiness.contains(Readiness::COMMUTATED) {
            return Err(CommandError::NotCommutated);
        }
        if !matches!(self.mode, Mode::Running | Mode::Preloading) {
            return Err(CommandError::NotRunning);
        }
        if self.move_in_progress() {
            return Err(CommandError::Busy);
        }
        Ok(())
    }

    /// Loops reset, holding here, the speed loop already delivering
    /// `current_q_a` (the load's hold current; 0 for none).
    pub(super) fn start_holding(&mut self, current_q_a: f32) {
        self.hold_here();
        self.reset_loops();
        self.speed_loop.preload(current_q_a);
        self.current_reference = Dq { d: 0.0, q: current_q_a };
    }

    pub(super) fn begin_calibration(&mut self) {
        self.calibration = CurrentCalibration::new(self.derived.calibration_samples);
        self.set_mode(Mode::Calibrating);
    }

    pub(super) fn begin_commutation(&mut self) {
        self.reset_loops();
        self.commutation = Commutation::new();
        self.set_mode(Mode::Aligning);
    }

    pub(super) fn begin_homing(&mut self) {
        self.hold_here();
        self.stream.stop();
        self.homing = Homing::new(self.motor_position_m());
        self.homing_backing_off = false;
        self.set_mode(Mode::Homing);
    }

    /// Forgets what a fault made untrustworthy.
    pub(super) fn forget_position(&mut self, new: FaultSet) {
        if new.intersects(LOSES_POSITION) && !self.params.startup.commutation_known {
            self.readiness.remove(Readiness::COMMUTATED);
            self.readiness.remove(Readiness::HOMED);
        }
    }

    /// Makes the present position the trajectory's resting point.
    // Out of line: seven callers, none on the 20 kHz path (≈ 60 bytes of
    // `ScurveMove::hold` each when inlined).
    #[inline(never)]
    pub(super) fn hold_here(&mut self) {
        self.commanded_stop = false;
        let here = self.motor_position_m();
        self.trajectory = ScurveMove::hold(here);
        self.restart_move();
        self.position_reference_m = here;
        self.position_command_m = here;
    }

    pub(super) fn reset_loops(&mut self) {
        self.current_loop.reset();
        self.speed_loop.reset();
        self.load.reset();
        self.current_reference = Dq::default();
        self.speed_reference_rad_s = 0.0;
        self.acceleration_reference_rad_s2 = 0.0;
        self.friction_ff_n_m = 0.0;
        self.voltage_dq = Dq::default();
    }
}
