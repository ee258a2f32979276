//! The drive: one `step` per PWM period, from a sensor sample to three duties.
//!
//! Order inside a period: input checks, encoder tracking, then — on their
//! decimated periods — the position loop and the speed loop, then the current
//! loop, so new outer references act in the same period they are computed.

use crate::compensation::Compensator;
use crate::foc::{wrap_pi, CurrentLoop, Dq};
use crate::foc::current_loop::RotorState;
use crate::io::{PwmCommand, SensorSample};
use crate::load_estimate::LoadEstimator;
use crate::motion::speed_loop::friction_feedforward_n_m;
use crate::motion::{position_step, EncoderTracker, ScurveMove, SpeedLoop, StopRamp, TrajectorySample};
use crate::params::{ControlParams, ParamError, ValidatedParams};
use crate::foc::transforms::{inverse_clarke, inverse_park, SinCos};
use crate::protection::{clamp_to_stroke, FaultSet, LimitFlags, OpenPhaseMonitor, ThermalModel};
use crate::telemetry::{Mode, Telemetry};
use core::f32::consts::PI;

/// What the host (main task, simulator scenario) may ask of the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Switch the bridge on and hold the present position.
    Enable,
    /// Switch the bridge off.
    Disable,
    /// Plan a jerk-limited move from the present command to `position_m`.
    MoveTo { position_m: f32 },
    /// Declare the present motor-side position to be `position_m` (homing).
    SetHome { position_m: f32 },
    /// Find the electrical offset (bridge must be disabled, no fault).
    Align,
    /// Clear latched faults whose cause is gone.
    ClearFaults,
    /// An external shift added to the trajectory before the position loop,
    /// metres (on top of the observer's, if compensation is on).
    SetPositionShift { shift_m: f32 },
    /// Switch the observer's terminal-error compensation on or off.
    SetCompensation { enabled: bool },
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    /// A move is still in progress (moves are rest-to-rest).
    Busy,
    /// A NaN or infinite argument.
    NotFinite,
    /// An argument beyond its bound (e.g. a shift above
    /// `faults.observer_shift_max_m`).
    OutOfRange,
    /// The bus voltage is below `faults.bus_undervoltage_v`.
    BusLow,
}

/// Conditions evaluated at the speed-loop rate.
const SPEED_RATE_CAUSES: FaultSet =
    FaultSet(FaultSet::MOTOR_OVERTEMP.0 | FaultSet::SPEED_FOLLOWING.0 | FaultSet::OPEN_PHASE.0);
/// Controlled-stop faults after which the drive does not hold on the motor:
/// with a phase open, two phases leave angles with no torque, so once at
/// rest the brake takes the load and the bridge goes off (a stop category 1,
/// where the others hold under control, category 2). Without a brake the
/// drive keeps holding: that beats dropping the load.
const SAFE_STOP_THEN_BRAKE: FaultSet = FaultSet::OPEN_PHASE;

/// Bridge-off faults after which the low-side switches must not be closed:
/// the current can no longer be measured or bounded (overcurrent, a sensor,
/// a NaN sample, the hardware break already acted), or the core's timing is
/// not trusted (overrun, watchdog), or nothing was ever set up (parameters).
const NO_SHORT_CIRCUIT: FaultSet = FaultSet(
    FaultSet::OVERCURRENT.0
        | FaultSet::CURRENT_SENSOR.0
        | FaultSet::NON_FINITE_INPUT.0
        | FaultSet::BRIDGE_BREAK.0
        | FaultSet::ISR_OVERRUN.0
        | FaultSet::WATCHDOG_RESET.0
        | FaultSet::INVALID_PARAMS.0,
);

/// Conditions evaluated at the position-loop rate.
const POSITION_RATE_CAUSES: FaultSet = FaultSet(FaultSet::POSITION_FOLLOWING.0 | FaultSet::STROKE_OVERTRAVEL.0);

/// Period-independent constants, computed once so the 20 kHz path does no
/// divisions it can avoid.
#[derive(Clone, Copy, Debug)]
struct Derived {
    pwm_period_s: f32,
    speed_period_s: f32,
    position_period_s: f32,
    current_limit_a: f32,
    metres_per_count: f32,
    rad_per_count: f32,
    /// `pole_pairs · 2π / counts_per_rev`: counts straight to electrical
    /// radians, one multiply per period.
    electrical_rad_per_count: f32,
    pole_pairs: f32,
    open_phase_window_ticks: u32,
    brake_release_periods: u32,
    brake_engage_periods: u32,
    /// Rotor speed below which an active short circuit's steady current,
    /// `ω_e ψ / sqrt(R² + (ω_e L)²)`, stays inside `limits.current_max_a`.
    short_circuit_speed_max_rad_s: f32,
    speed_ticks_per_position_tick: u32,
}

impl Derived {
    fn of(p: &ControlParams) -> Self {
        let cpr = p.encoder.counts_per_rev as f32;
        Self {
            pwm_period_s: p.pwm_period_s(),
            speed_period_s: p.speed_period_s(),
            position_period_s: p.position_period_s(),
            current_limit_a: p.current_limit_a(),
            metres_per_count: p.drive_train.screw_lead_m / cpr,
            rad_per_count: 2.0 * PI / cpr,
            electrical_rad_per_count: p.motor.pole_pairs as f32 * (2.0 * PI / cpr),
            pole_pairs: p.motor.pole_pairs as f32,
            open_phase_window_ticks: periods(p.faults.open_phase_window_s, p.speed_period_s()),
            brake_release_periods: periods(p.brake.release_time_s, p.pwm_period_s()),
            brake_engage_periods: periods(p.brake.engage_time_s, p.pwm_period_s()),
            short_circuit_speed_max_rad_s: short_circuit_speed_max_rad_s(p),
            // Validated: a non-zero multiple of the speed divider.
            speed_ticks_per_position_tick: p.rates.position_loop_divider.checked_div(p.rates.speed_loop_divider).unwrap_or(1),
        }
    }
}

/// Solves `ω_e ψ / sqrt(R² + (ω_e L)²) = I_max` for the mechanical speed;
/// infinite when even the asymptote ψ/L stays below `I_max`.
fn short_circuit_speed_max_rad_s(p: &ControlParams) -> f32 {
    let m = &p.motor;
    let i = p.limits.current_max_a;
    let l = m.inductance_q_h;
    let margin = m.flux_linkage_wb * m.flux_linkage_wb - i * i * l * l;
    if margin <= 0.0 {
        return f32::INFINITY;
    }
    i * m.phase_resistance_ohm / crate::math::sqrt(margin) / m.pole_pairs as f32
}

/// Whole periods of `period_s` in `duration_s`, rounded up, at least 1.
fn periods(duration_s: f32, period_s: f32) -> u32 {
    let n = crate::math::clamp(duration_s / period_s, 1.0, u32::MAX as f32);
    let whole = n as u32;
    if (whole as f32) < n { whole.saturating_add(1) } else { whole }
}

/// The whole drive state. `step` is the only thing the ISR calls.
#[derive(Debug)]
pub struct Controller {
    params: ControlParams,
    derived: Derived,
    mode: Mode,
    faults: FaultSet,
    /// Conditions present at the last step, latched or not: a fault clears
    /// only when its condition has gone.
    present: FaultSet,
    tick: u32,
    /// Periods left to the next speed tick, and speed ticks left to the
    /// next position tick (the position divider is a multiple of the speed
    /// one): a count-down costs less than two divisions every period.
    speed_countdown: u32,
    position_countdown: u32,
    encoder: EncoderTracker,
    current_loop: CurrentLoop,
    speed_loop: SpeedLoop,
    trajectory: ScurveMove,
    move_ticks: u32,
    /// External shift (`SetPositionShift`), the target…
    position_shift_m: f32,
    /// …and what is applied, moving towards it at the compensation's rate
    /// limit so a new shift never arrives as a step.
    external_shift_applied_m: f32,
    compensator: Compensator,
    /// Total shift applied last position period (external + observer).
    applied_shift_m: f32,
    position_command_m: f32,
    position_reference_m: f32,
    speed_reference_rad_s: f32,
    acceleration_reference_rad_s2: f32,
    /// Coulomb friction fed forward to the speed loop, from the position period.
    friction_ff_n_m: f32,
    current_reference: Dq,
    current_dq: Dq,
    voltage_dq: Dq,
    limits: LimitFlags,
    /// A clamped MoveTo is reported until the next telemetry record is cut.
    pending_limits: LimitFlags,
    load: LoadEstimator,
    align_ticks: u32,
    thermal: ThermalModel,
    /// The controlled stop in progress (mode `Stopping`).
    stop: StopRamp,
    /// Consecutive periods with |i_a + i_b + i_c| over its bound.
    current_sum_count: u32,
    /// How long |ω_ref − ω| has been over its threshold.
    speed_error_s: f32,
    /// How long the encoder has shown no count while told to turn.
    no_count_s: f32,
    count_at_last_speed_tick: i32,
    /// The q-current bound the speed loop had last (thermal foldback and
    /// the d-current taken off the current circle).
    q_current_limit_a: f32,
    open_phase: OpenPhaseMonitor,
    /// The open-phase check's last verdict (it keeps it through windows
    /// that cannot judge).
    open_phase_present: bool,
    /// Periods of active short circuit left after a bridge-off fault.
    short_circuit_periods: u32,
    /// PWM periods since the brake was told to open (Running, Stopping) or
    /// to close (Braking, once the stop ramp is at rest).
    brake_periods: u32,
    bus_voltage_v: f32,
    terminal_position_m: Option<f32>,
    telemetry: Telemetry,
}

impl Controller {
    /// A controller for `params`. Invalid parameters give a controller that
    /// latches `INVALID_PARAMS` and never enables (the firmware must still
    /// boot and log why); use [`Controller::try_new`] to get the reason.
    pub fn new(params: ControlParams) -> Self {
        match Self::try_new(params) {
            Ok(c) => c,
            Err(_) => {
                let mut c = Self::build(ControlParams::DEFAULT);
                c.faults = FaultSet::INVALID_PARAMS;
                c.present = FaultSet::INVALID_PARAMS;
                c.mode = Mode::Fault;
                c.params = params;
                c
            }
        }
    }

    /// A controller for `params`, or the first parameter that is unusable.
    pub fn try_new(params: ControlParams) -> Result<Self, ParamError> {
        ValidatedParams::new(params).map(Self::from_validated)
    }

    /// A controller for a set already checked (at compile time, in the
    /// firmware).
    pub fn from_validated(params: ValidatedParams) -> Self {
        Self::build(*params.get())
    }

    fn build(params: ControlParams) -> Self {
        Self {
            derived: Derived::of(&params),
            params,
            mode: Mode::Disabled,
            faults: FaultSet::NONE,
            present: FaultSet::NONE,
            tick: 0,
            // The first ticks fall on period `divider`, as `tick % divider == 0` did.
            speed_countdown: params.rates.speed_loop_divider,
            position_countdown: params.rates.position_loop_divider.checked_div(params.rates.speed_loop_divider).unwrap_or(1),
            encoder: EncoderTracker::new(),
            current_loop: CurrentLoop::new(),
            speed_loop: SpeedLoop::new(&params),
            trajectory: ScurveMove::hold(0.0),
            move_ticks: 0,
            position_shift_m: 0.0,
            external_shift_applied_m: 0.0,
            compensator: Compensator::new(params.compensation.enabled_at_start),
            applied_shift_m: 0.0,
            position_command_m: 0.0,
            position_reference_m: 0.0,
            speed_reference_rad_s: 0.0,
            acceleration_reference_rad_s2: 0.0,
            friction_ff_n_m: 0.0,
            current_reference: Dq::default(),
            current_dq: Dq::default(),
            voltage_dq: Dq::default(),
            limits: LimitFlags::NONE,
            pending_limits: LimitFlags::NONE,
            load: LoadEstimator::new(),
            align_ticks: 0,
            thermal: ThermalModel::new(),
            stop: StopRamp::default(),
            current_sum_count: 0,
            speed_error_s: 0.0,
            no_count_s: 0.0,
            count_at_last_speed_tick: 0,
            q_current_limit_a: 0.0,
            open_phase: OpenPhaseMonitor::new(),
            open_phase_present: false,
            brake_periods: 0,
            short_circuit_periods: 0,
            bus_voltage_v: 0.0,
            terminal_position_m: None,
            telemetry: Telemetry::default(),
        }
    }

    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn faults(&self) -> FaultSet {
        self.faults
    }

    /// The last telemetry record (refreshed every position period).
    pub fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    /// Motor-side position `L θ_m / 2π` from the tracked encoder.
    pub fn motor_position_m(&self) -> f32 {
        self.encoder.position_counts() * self.derived.metres_per_count
    }

    pub fn speed_rad_s(&self) -> f32 {
        self.encoder.speed_counts_s() * self.derived.rad_per_count
    }

    /// True while a planned move has time left.
    pub fn move_in_progress(&self) -> bool {
        (self.move_ticks as f32) * self.derived.position_period_s < self.trajectory.duration_s()
    }

    /// Normalised winding temperature of the I²t model (1 = continuous rating).
    pub fn thermal_level(&self) -> f32 {
        self.thermal.level()
    }

    /// The board calls this when a sample arrived before the previous step
    /// finished.
    pub fn report_isr_overrun(&mut self) {
        self.raise(FaultSet::ISR_OVERRUN);
    }

    /// The board calls this when its comparator break switched the outputs
    /// off in hardware (timer break flag seen in the ISR).
    pub fn report_bridge_break(&mut self) {
        self.raise(FaultSet::BRIDGE_BREAK);
    }

    /// True while the brake is (being) held open: a planned move waits for
    /// `brake.release_time_s` after `Enable`.
    fn brake_opening(&self) -> bool {
        self.params.brake.fitted && self.mode == Mode::Running && self.brake_periods < self.derived.brake_release_periods
    }

    /// The board calls this at start-up if the independent watchdog caused
    /// the last reset: the drive then waits for an explicit clear.
    pub fn report_watchdog_reset(&mut self) {
        self.raise(FaultSet::WATCHDOG_RESET);
    }

    /// Latches `f`; new faults get their reaction.
    #[inline(never)]
    fn raise(&mut self, f: FaultSet) {
        let new = f.difference(self.faults);
        if new.is_empty() {
            return;
        }
        self.faults.insert(new);
        if !self.faults.only_controlled_stop() {
            let driving = matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Braking)
                && self.speed_rad_s().abs() < self.derived.short_circuit_speed_max_rad_s;
            // Short-circuit braking bridges the brake's engage time, where
            // the fault leaves the power stage and the supply trustworthy.
            self.short_circuit_periods = if driving && self.params.brake.fitted && self.faults.intersection(NO_SHORT_CIRCUIT).is_empty() {
                self.derived.brake_engage_periods
            } else {
                0
            };
            self.mode = Mode::Fault;
            return;
        }
        match self.mode {
            Mode::Running => self.begin_stop(),
            // Already decelerating to rest.
            Mode::Stopping | Mode::Braking => {}
            Mode::Disabled | Mode::Aligning | Mode::Fault => self.mode = Mode::Fault,
        }
    }

    /// Decelerates from the measured motion to rest and holds there.
    #[inline(never)]
    fn begin_stop(&mut self) {
        let v = self.speed_rad_s() * self.params.metres_per_rad();
        self.stop = StopRamp::new(self.motor_position_m(), v, self.params.faults.stop_deceleration_m_s2);
        // The stop's path starts here: following checks before the next
        // position period must not judge it by the command it replaced.
        self.position_command_m = self.motor_position_m();
        self.position_shift_m = 0.0;
        self.external_shift_applied_m = 0.0;
        self.compensator.set_enabled(false);
        self.compensator.reset();
        self.mode = Mode::Stopping;
    }

    /// Handles one command from thread context.
    pub fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
        match cmd {
            Command::Enable => {
                if !self.faults.is_empty() {
                    return Err(CommandError::Faulted(self.faults));
                }
                // Before the first sample there is no reading; the first period
                // then checks it like any other.
                if self.tick > 0 && self.bus_voltage_v < self.params.faults.bus_undervoltage_v {
                    return Err(CommandError::BusLow);
                }
                match self.mode {
                    Mode::Running => return Ok(CommandOutcome::Accepted),
                    // The loops are holding: keep them, open the brake again.
                    Mode::Braking => self.hold_here(),
                    _ => {
                        self.hold_here();
                        self.reset_loops();
                    }
                }
                self.mode = Mode::Running;
                self.brake_periods = 0;
                Ok(CommandOutcome::Accepted)
            }
            Command::Disable => {
                if self.params.brake.fitted && matches!(self.mode, Mode::Running | Mode::Stopping) {
                    // Stop, let the brake close under the loops, then switch off.
                    let v = self.speed_rad_s() * self.params.metres_per_rad();
                    self.stop = StopRamp::new(self.position_command_m, v, self.params.faults.stop_deceleration_m_s2);
                    self.brake_periods = 0;
                    self.mode = Mode::Braking;
                } else if self.mode != Mode::Braking {
                    self.mode = if self.faults.is_empty() { Mode::Disabled } else { Mode::Fault };
                    self.reset_loops();
                }
                Ok(CommandOutcome::Accepted)
            }
            Command::MoveTo { position_m } => {
                if !position_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                if self.mode != Mode::Running {
                    return Err(CommandError::NotRunning);
                }
                if self.move_in_progress() {
                    return Err(CommandError::Busy);
                }
                let l = &self.params.limits;
                let (target, clamped) = clamp_to_stroke(position_m, l.stroke_min_m, l.stroke_max_m);
                self.trajectory = ScurveMove::plan(self.trajectory.end_m(), target, &self.params.trajectory);
                self.move_ticks = 0;
                if clamped {
                    self.pending_limits.insert(LimitFlags::STROKE);
                    Ok(CommandOutcome::ClampedToStroke { position_m: target })
                } else {
                    Ok(CommandOutcome::Accepted)
                }
            }
            Command::SetHome { position_m } => {
                if !position_m.is_finite() {
                    return Err(CommandError::NotFinite);
                }
                if self.mode == Mode::Running || self.mode == Mode::Aligning {
                    return Err(CommandError::NotDisabled);
                }
                let counts = position_m / self.derived.metres_per_count;
                self.encoder.set_count(crate::math::round(counts) as i32);
                self.hold_here();
                Ok(CommandOutcome::Accepted)
            }
            Command::Align => {
                if !self.faults.is_empty() {
                    return Err(CommandError::Faulted(self.faults));
                }
                if self.mode != Mode::Disabled {
                    return Err(CommandError::NotDisabled);
                }
                self.reset_loops();
                self.align_ticks = 0;
                self.mode = Mode::Aligning;
                Ok(CommandOutcome::Accepted)
            }
            Command::ClearFaults => {
                let stuck = self.faults.intersection(self.present);
                if !stuck.is_empty() {
                    return Err(CommandError::CauseStillPresent(stuck));
                }
                self.faults = FaultSet::NONE;
                match self.mode {
                    Mode::Fault => self.mode = Mode::Disabled,
                    Mode::Stopping => {
                        // Resume position control where the stop left it.
                        self.trajectory = ScurveMove::hold(self.position_command_m);
                        self.move_ticks = 0;
                        self.mode = Mode::Running;
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
        }
    }

    /// Makes the present position the trajectory's resting point.
    fn hold_here(&mut self) {
        let here = self.motor_position_m();
        self.trajectory = ScurveMove::hold(here);
        self.move_ticks = 0;
        self.position_reference_m = here;
        self.position_command_m = here;
    }

    fn reset_loops(&mut self) {
        self.current_loop.reset();
        self.speed_loop.reset();
        self.load.reset();
        self.current_reference = Dq::default();
        self.speed_reference_rad_s = 0.0;
        self.acceleration_reference_rad_s2 = 0.0;
        self.friction_ff_n_m = 0.0;
        self.voltage_dq = Dq::default();
    }

    /// Checks one sample; returns the conditions present now.
    fn check_inputs(&mut self, s: &SensorSample) -> FaultSet {
        let f = &self.params.faults;
        let mut present = FaultSet(self.present.0 & (FaultSet::INVALID_PARAMS.0));
        let [a, b, c] = s.phase_current_a;
        // One compare checks every input (a branch each costs more at 20 kHz).
        use crate::math::finite_probe;
        let v = s.bus_voltage_v;
        let mut probe = finite_probe(a) + finite_probe(b) + finite_probe(c) + finite_probe(v);
        if let Some(x) = s.terminal_position_m {
            probe += finite_probe(x);
        }
        if let Some(x) = s.load_cell_force_n {
            probe += finite_probe(x);
        }
        if probe != 0.0 {
            self.current_sum_count = 0;
            present.insert(FaultSet::NON_FINITE_INPUT);
            return present;
        }
        // Only finite readings are kept for telemetry and `Enable`'s bus check.
        self.bus_voltage_v = v;
        self.terminal_position_m = s.terminal_position_m;
        use crate::math::max;
        if max(max(a.abs(), b.abs()), c.abs()) > f.overcurrent_trip_a {
            present.insert(FaultSet::OVERCURRENT);
        }
        // Σi must persist over `current_sum_periods`: noise on three
        // independent channels adds up too.
        if (a + b + c).abs() > f.current_sum_max_a {
            self.current_sum_count = self.current_sum_count.saturating_add(1);
            if self.current_sum_count >= f.current_sum_periods {
                present.insert(FaultSet::CURRENT_SENSOR);
            }
        } else {
            self.current_sum_count = 0;
        }
        // The usual case, a bus inside its window, costs one test of each bound.
        if v >= f.bus_undervoltage_v && v <= f.bus_overvoltage_v {
            return present;
        }
        if v > f.bus_overvoltage_v {
            present.insert(FaultSet::BUS_OVERVOLTAGE);
        }
        // Only while the bridge is on or the fault is latched: a board powered
        // from USB with the bus off must still be configurable, but a latched
        // undervoltage must not clear during the sag.
        let watching = matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Aligning | Mode::Braking)
            || self.faults.contains(FaultSet::BUS_UNDERVOLTAGE);
        if v < f.bus_undervoltage_v && watching {
            present.insert(FaultSet::BUS_UNDERVOLTAGE);
        }
        present
    }

    /// Advances one PWM period. Called from the ADC interrupt; bounded time,
    /// no waiting, no panics.
    pub fn step(&mut self, s: &SensorSample) -> PwmCommand {
        self.tick = self.tick.wrapping_add(1);
        let mut present = self.check_inputs(s);
        let enc = self.encoder.update(
            &self.params.encoder,
            s.encoder_count,
            self.derived.pwm_period_s,
            self.params.faults.encoder_max_step_counts,
            self.params.faults.encoder_max_innovation_counts,
        );
        if enc.implausible_step {
            // A jump is an event, not a standing condition: it can be cleared.
            self.raise(FaultSet::ENCODER_JUMP);
        }
        self.speed_countdown = self.speed_countdown.wrapping_sub(1);
        let speed_tick = self.speed_countdown == 0;
        let mut position_tick = false;
        if speed_tick {
            self.speed_countdown = self.params.rates.speed_loop_divider;
            self.position_countdown = self.position_countdown.wrapping_sub(1);
            position_tick = self.position_countdown == 0;
            if position_tick {
                self.position_countdown = self.derived.speed_ticks_per_position_tick;
            }
        }
        // Causes checked at the outer rates keep their last verdict between
        // their ticks, or a clear between two ticks would find them gone.
        present = present.union(if speed_tick {
            self.check_speed_period(s.phase_current_a)
        } else {
            self.present.intersection(SPEED_RATE_CAUSES)
        });
        present = present.union(if position_tick {
            self.check_motion()
        } else {
            self.present.intersection(POSITION_RATE_CAUSES)
        });
        self.present = present;
        let raised = present.difference(FaultSet::INVALID_PARAMS);
        if !raised.difference(self.faults).is_empty() {
            self.raise(raised);
        }

        // Brake output: open (true) from `current_period` while driving,
        // closed (false) in `PwmCommand::OFF` and the short circuit; only
        // `Braking` decides per period. Without a brake nothing is wired to
        // it, so the same values do no harm.
        let out = match self.mode {
            Mode::Fault if self.short_circuit_periods > 0 => self.short_circuit(s),
            Mode::Disabled | Mode::Fault => self.bridge_off(),
            Mode::Aligning => self.align_period(s),
            Mode::Running | Mode::Stopping => {
                if position_tick {
                    self.brake_tick();
                }
                self.run_period(s, position_tick, speed_tick)
            }
            Mode::Braking => self.braking_period(s, position_tick, speed_tick),
        };
        if position_tick {
            self.cut_telemetry();
        }
        out
    }

    /// Active short circuit (all low-side switches on) while the brake closes
    /// after a bridge-off fault: the motor brakes itself through its winding
    /// resistance, no sensor or loop needed, so a vertical load sinks at a
    /// few mm/s instead of falling. Only entered below the speed whose
    /// short-circuit current stays inside `limits.current_max_a` (≈89 rad/s,
    /// 70 mm/s of rod, for the default motor), and still ended for good if a
    /// phase reads above that limit.
    /// Brake bookkeeping at the position rate while driving: the release
    /// wait after `Enable`, and the hand-over to the brake after an open
    /// phase stop came to rest.
    #[inline(never)]
    fn brake_tick(&mut self) {
        self.brake_periods = self.brake_periods.saturating_add(self.params.rates.position_loop_divider);
        if self.mode == Mode::Stopping
            && self.params.brake.fitted
            && self.stop.at_rest()
            && self.faults.contains(SAFE_STOP_THEN_BRAKE)
        {
            // A degraded motor should not be left holding: once the stop is
            // at rest, hand the load to the brake and switch off.
            self.brake_periods = 0;
            self.mode = Mode::Braking;
        }
    }

    /// `Braking`: the loops hold while the brake closes, then the bridge
    /// goes off.
    #[inline(never)]
    fn braking_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        if self.stop.at_rest() {
            self.brake_periods = self.brake_periods.saturating_add(1);
        }
        if self.brake_periods > self.derived.brake_engage_periods {
            self.mode = if self.faults.is_empty() { Mode::Disabled } else { Mode::Fault };
            return self.bridge_off();
        }
        let mut out = self.run_period(s, position_tick, speed_tick);
        // Closing starts once the stop ramp is at rest.
        out.brake_release = !(self.params.brake.fitted && self.stop.at_rest());
        out
    }

    #[inline(never)]
    fn short_circuit(&mut self, s: &SensorSample) -> PwmCommand {
        self.short_circuit_periods = self.short_circuit_periods.saturating_sub(1);
        let limit = self.params.limits.current_max_a;
        let [a, b, c] = s.phase_current_a;
        // NaN compares false: `!(x <= limit)` ends the short circuit too.
        let bounded = a.abs() <= limit && b.abs() <= limit && c.abs() <= limit;
        let off = self.bridge_off();
        if !bounded {
            self.short_circuit_periods = 0;
            return off;
        }
        PwmCommand { duty: [0.0; 3], enable: true, brake_release: false }
    }

    /// Bridge off: loops reset, the command follows the rod.
    #[inline(never)]
    fn bridge_off(&mut self) -> PwmCommand {
        self.hold_here();
        self.reset_loops();
        // No current flows with the bridge off: the I²t model cools.
        self.current_dq = Dq::default();
        PwmCommand::OFF
    }

    /// Winding temperature, speed following, encoder loss and open phases,
    /// at the speed rate. Returns the standing conditions; raises the events.
    #[inline(never)]
    fn check_speed_period(&mut self, phase_current_a: [f32; 3]) -> FaultSet {
        let mut present = FaultSet::NONE;
        let dt = self.derived.speed_period_s;
        let i2 = self.current_dq.d * self.current_dq.d + self.current_dq.q * self.current_dq.q;
        self.thermal.update(&self.params.thermal, i2, dt);
        // Hysteresis: once tripped, the cause stays until the winding has
        // cooled below the foldback start.
        let th = &self.params.thermal;
        let hot = if self.faults.contains(FaultSet::MOTOR_OVERTEMP) {
            self.thermal.level() > th.foldback_start
        } else {
            self.thermal.tripped(th)
        };
        if hot {
            present.insert(FaultSet::MOTOR_OVERTEMP);
        }
        let count = self.encoder.count();
        let moved = count != self.count_at_last_speed_tick;
        self.count_at_last_speed_tick = count;
        if !matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Braking) {
            self.speed_error_s = 0.0;
            self.no_count_s = 0.0;
            // With the bridge off nothing can be judged; an open phase shows
            // again within a window of the next enable.
            self.open_phase.reset();
            self.open_phase_present = false;
            return present;
        }
        let sc = SinCos::of(self.rotor_state().electrical_angle_rad);
        let reference_a = inverse_clarke(inverse_park(self.current_reference, sc));
        let window = self.derived.open_phase_window_ticks;
        if let Some(open) = self.open_phase.update(&self.params.faults, window, reference_a, phase_current_a) {
            self.open_phase_present = open;
        }
        if self.open_phase_present {
            present.insert(FaultSet::OPEN_PHASE);
        }
        let f = &self.params.faults;
        let w_ref = self.speed_reference_rad_s;
        self.speed_error_s =
            if (w_ref - self.speed_rad_s()).abs() > f.speed_following_error_rad_s { self.speed_error_s + dt } else { 0.0 };
        if self.speed_error_s >= f.speed_following_time_s {
            present.insert(FaultSet::SPEED_FOLLOWING);
        }
        self.no_count_s = if !moved && w_ref.abs() > f.encoder_lost_speed_rad_s { self.no_count_s + dt } else { 0.0 };
        if self.no_count_s >= f.encoder_lost_time_s {
            self.raise(FaultSet::ENCODER_LOST);
        }
        present
    }

    /// Following error, overtravel and the soft limits, at the position rate.
    #[inline(never)]
    fn check_motion(&mut self) -> FaultSet {
        let mut present = FaultSet::NONE;
        let x = self.motor_position_m();
        let l = &self.params.limits;
        let f = &self.params.faults;
        if x < l.stroke_min_m - f.stroke_overtravel_m || x > l.stroke_max_m + f.stroke_overtravel_m {
            present.insert(FaultSet::STROKE_OVERTRAVEL);
        }
        let following = (self.position_command_m - x).abs();
        if matches!(self.mode, Mode::Running | Mode::Stopping) && following > f.position_following_error_m {
            present.insert(FaultSet::POSITION_FOLLOWING);
        }
        let brake_stronger = self.params.brake.fitted
            && self.params.torque_constant_n_m_a() * self.q_current_limit_a < self.params.brake.holding_torque_n_m;
        let stop_failed =
            matches!(self.mode, Mode::Stopping | Mode::Braking) && following > f.stop_following_error_m && brake_stronger;
        if self.mode == Mode::Running {
            // Where would a stop at the stop deceleration end?
            let v = self.speed_rad_s() * self.params.metres_per_rad();
            let rest = x + v * v.abs() / (2.0 * f.stop_deceleration_m_s2);
            if rest > l.stroke_max_m + f.stroke_soft_margin_m || rest < l.stroke_min_m - f.stroke_soft_margin_m {
                self.raise(FaultSet::SOFT_LIMIT);
            }
        }
        // The stop starts from the measured position: straying from it means
        // the load is winning. The brake must take it before the end stop.
        if stop_failed {
            self.raise(FaultSet::STOP_FAILED);
        }
        present
    }

    fn rotor_state(&self) -> RotorState {
        let k = self.derived.electrical_rad_per_count;
        RotorState {
            // Not wrapped: within offset ± 2π·pole_pairs, which `sincos`
            // reduces as accurately as a wrapped angle.
            electrical_angle_rad: self.encoder.counts_in_turn(&self.params.encoder) * k
                + self.params.encoder.electrical_offset_rad,
            electrical_speed_rad_s: self.encoder.speed_counts_s() * k,
        }
    }

    fn run_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        if position_tick {
            self.position_period(s);
        }
        if speed_tick {
            let limit = self.thermal.current_limit_a(&self.params.thermal, self.derived.current_limit_a);
            if limit < self.derived.current_limit_a {
                self.limits.insert(LimitFlags::THERMAL);
            }
            let iq_max2 = limit * limit - self.current_reference.d * self.current_reference.d;
            let iq_max = crate::math::sqrt(crate::math::max(iq_max2, 0.0));
            self.q_current_limit_a = iq_max;
            let out = self.speed_loop.step(
                &self.params,
                self.speed_reference_rad_s,
                self.acceleration_reference_rad_s2,
                self.friction_ff_n_m,
                self.speed_rad_s(),
                iq_max,
            );
            self.current_reference.q = out.current_q_reference_a;
            if out.current_limited {
                self.limits.insert(LimitFlags::CURRENT);
            }
        }
        let rotor = self.rotor_state();
        self.current_period(s, rotor)
    }

    fn current_period(&mut self, s: &SensorSample, rotor: RotorState) -> PwmCommand {
        let out = self.current_loop.step(&self.params, s.phase_current_a, self.current_reference, rotor, s.bus_voltage_v);
        self.current_dq = out.current_dq;
        self.voltage_dq = out.voltage_dq;
        if out.voltage_limited {
            self.limits.insert(LimitFlags::VOLTAGE);
        }
        // `step` decides the brake output for the whole period.
        PwmCommand { duty: out.duty, enable: true, brake_release: true }
    }

    /// The position reference for this period: the planned move, or the
    /// controlled stop.
    fn next_reference(&mut self) -> TrajectorySample {
        if matches!(self.mode, Mode::Stopping | Mode::Braking) {
            return self.stop.advance(self.derived.position_period_s);
        }
        if self.brake_opening() {
            // The move waits for the brake: hold its start.
            return self.trajectory.sample(0.0);
        }
        let t = self.move_ticks as f32 * self.derived.position_period_s;
        self.move_ticks = self.move_ticks.saturating_add(1);
        self.trajectory.sample(t)
    }

    #[inline(never)]
    fn position_period(&mut self, s: &SensorSample) {
        let r = self.next_reference();
        self.position_reference_m = r.position_m;
        let observer_shift = if self.mode == Mode::Running {
            let inputs = Compensator::inputs(&self.params, self.speed_rad_s(), self.motor_position_m(), self.load.force_n());
            let c = self.compensator.update(&self.params, inputs, self.derived.position_period_s);
            if c.limited {
                self.limits.insert(LimitFlags::COMPENSATION);
            }
            if c.input_clamped {
                self.limits.insert(LimitFlags::OBSERVER_INPUT);
            }
            if c.out_of_bounds {
                self.raise(FaultSet::OBSERVER_OUT_OF_BOUNDS);
            }
            c.shift_m
        } else {
            0.0
        };
        let step_max = self.params.compensation.shift_rate_max_m_s * self.derived.position_period_s;
        self.external_shift_applied_m +=
            crate::math::clamp(self.position_shift_m - self.external_shift_applied_m, -step_max, step_max);
        self.applied_shift_m = observer_shift + self.external_shift_applied_m;
        let l = &self.params.limits;
        let (command, clamped) = clamp_to_stroke(r.position_m + self.applied_shift_m, l.stroke_min_m, l.stroke_max_m);
        if clamped {
            self.limits.insert(LimitFlags::STROKE);
        }
        self.position_command_m = command;
        let out = position_step(&self.params, command, r.velocity_m_s, r.acceleration_m_s2, self.motor_position_m());
        self.speed_reference_rad_s = out.speed_reference_rad_s;
        self.acceleration_reference_rad_s2 = out.acceleration_reference_rad_s2;
        if out.speed_limited {
            self.limits.insert(LimitFlags::SPEED);
        }
        self.friction_ff_n_m = friction_feedforward_n_m(&self.params, r.velocity_m_s, self.load.slow_force_n());
        let inertial_n = self.params.drive_train.moving_mass_kg * r.acceleration_m_s2;
        let dt = self.derived.position_period_s;
        match s.load_cell_force_n {
            // The load cell sits beyond the nut and the seal: it feels the
            // payload's inertia but none of the friction.
            Some(f) => {
                self.load.update_measured(&self.params, f, inertial_n, dt);
            }
            None => {
                // The estimate reads friction through the same torque-to-force
                // scaling as the load, so the fed-forward torque goes with it.
                let friction_n = self.friction_ff_n_m * self.params.drive_train.screw_efficiency / self.params.metres_per_rad();
                self.load.update(&self.params, self.current_dq.q, self.acceleration_reference_rad_s2, inertial_n + friction_n, dt);
            }
        }
    }

    #[inline(never)]
    fn align_period(&mut self, s: &SensorSample) -> PwmCommand {
        self.align_ticks = self.align_ticks.saturating_add(1);
        let elapsed_s = self.align_ticks as f32 * self.derived.pwm_period_s;
        if elapsed_s >= self.params.alignment.duration_s {
            // The rotor sits at electrical angle zero: whatever the encoder
            // reads here is minus the offset.
            let theta_m = self.encoder.angle_in_rev_rad(&self.params.encoder);
            self.params.encoder.electrical_offset_rad = wrap_pi(-self.derived.pole_pairs * theta_m);
            self.mode = Mode::Disabled;
            self.reset_loops();
            return PwmCommand::OFF;
        }
        self.current_reference = Dq { d: self.params.alignment.current_a, q: 0.0 };
        self.current_period(s, RotorState { electrical_angle_rad: 0.0, electrical_speed_rad_s: 0.0 })
    }

    #[inline(never)]
    fn cut_telemetry(&mut self) {
        let mut limits = self.limits;
        limits.insert(self.pending_limits);
        self.telemetry = Telemetry {
            time_s: self.tick as f32 * self.derived.pwm_period_s,
            mode: self.mode,
            position_reference_m: self.position_reference_m,
            position_command_m: self.position_command_m,
            position_shift_m: self.applied_shift_m,
            motor_position_m: self.motor_position_m(),
            motor_angle_rad: self.encoder.position_counts() * self.derived.rad_per_count,
            speed_reference_rad_s: self.speed_reference_rad_s,
            speed_rad_s: self.speed_rad_s(),
            current_d_a: self.current_dq.d,
            current_q_a: self.current_dq.q,
            current_q_reference_a: self.current_reference.q,
            voltage_d_v: self.voltage_dq.d,
            voltage_q_v: self.voltage_dq.q,
            bus_voltage_v: self.bus_voltage_v,
            terminal_position_m: self.terminal_position_m,
            load_force_estimate_n: self.load.force_n(),
            faults: self.faults,
            limits,
        };
        self.limits = LimitFlags::NONE;
        self.pending_limits = LimitFlags::NONE;
    }
}
