//! The drive: one `step` per PWM period, from a sensor sample to three duties.
//!
//! One job per file:
//! - `mode.rs`: the mode machine, the one table of allowed transitions;
//! - `commands.rs`: the commands, which ask the mode machine to move;
//! - `lifecycle.rs`: the start-up steps (calibration, commutation, homing);
//! - `cascade.rs`: the position → speed → current loops;
//! - `checks.rs`: the protection checks that turn a sample into faults;
//! - `reactions.rs`: what a fault or a `Disable` does to the bridge and brake;
//! - `params_apply.rs`: a new parameter set taken live or with the bridge off;
//! - `derived.rs`: the constants a parameter set gives, computed once;
//! - `scope.rs`: the capture and the test signals.
//!
//! `step` reads as one page: ticks → checks → the mode's period → telemetry.

mod cascade;
mod checks;
mod commands;
mod derived;
mod lifecycle;
pub mod mode;
mod params_apply;
mod reactions;
mod scope;
mod stop_assist;

pub use commands::{Command, CommandError, CommandOutcome};
pub use params_apply::ApplyError;
use derived::Derived;

use crate::capture::Capture;
use crate::compensation::Compensator;
use crate::foc::{CurrentLoop, Dq};
use crate::io::{PwmCommand, SensorSample};
use crate::lifecycle::{Commutation, CurrentCalibration, Homing, Readiness};
use crate::load_estimate::LoadEstimator;
use crate::motion::{EncoderTracker, ScurveMove, SetpointStream, SpeedLoop, StopRamp};
use crate::params::{ControlParams, ParamError, ValidatedParams};
use crate::protection::{EmfWatch, FaultSet, LimitFlags, OpenPhaseMonitor, ThermalModel};
use crate::telemetry::{Mode, Telemetry};
use crate::test_signals::TestRun;

/// The whole drive state. `step` is the only thing the ISR calls.
// `repr(C)`: declaration order is layout order. The fields every PWM period
// reads come first, then the derived constants and the parameters, so they
// stay within the reach of the FPU loads' offsets (1020 bytes) from the
// controller's base; what the outer rates and the start-up steps use follows.
#[derive(Debug)]
#[repr(C)]
pub struct Controller {
    mode: Mode,
    /// Non-zero while a capture records ([`HOOK_CAPTURE`]) or a test runs
    /// ([`HOOK_TEST`]): the one byte the period tests for both. It sits in
    /// `mode`'s padding.
    hooks: u8,
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
    current_reference: Dq,
    current_dq: Dq,
    voltage_dq: Dq,
    limits: LimitFlags,
    /// Consecutive periods with |i_a + i_b + i_c| over its bound.
    current_sum_count: u32,
    /// Periods of active short circuit left after a bridge-off fault.
    short_circuit_periods: u32,
    bus_voltage_v: f32,
    terminal_position_m: Option<f32>,
    speed_reference_rad_s: f32,
    acceleration_reference_rad_s2: f32,
    /// Coulomb friction fed forward to the speed loop, from the position period.
    friction_ff_n_m: f32,
    speed_loop: SpeedLoop,
    /// The q-current bound the speed loop had last (thermal and power-stage
    /// foldback, the d-current taken off the current circle), before the
    /// anti-windup and homing narrow it: what the motor could give.
    q_current_limit_a: f32,
    /// PWM periods since the brake was told to open (Running, Stopping) or
    /// to close (Braking, once the stop ramp is at rest).
    brake_periods: u32,
    /// A controlled stop the load was winning, with a brake weaker than the
    /// motor: the brake closes under the loops, which go on holding
    /// (`Braking`) until the load is one the brake holds alone.
    stop_brake_assist: bool,
    /// Under that assist: where the motor side was when the motor's share
    /// of the hold began to ramp down (a slip is measured from here).
    handover_anchor_m: f32,
    /// A controlled stop's speed at its last position period (or at its
    /// start): the runaway check's acceleration.
    speed_prev_rad_s: f32,
    open_phase: OpenPhaseMonitor,
    /// From enable to the first settle: does the torque make the motion?
    torque_watch: crate::protection::TorqueWatch,
    /// The open-phase check's last verdict (it keeps it through windows
    /// that cannot judge).
    open_phase_present: bool,
    thermal: ThermalModel,
    derived: Derived,
    params: ControlParams,
    /// User position of encoder count zero (`SetHome`, homing). Kept apart
    /// from the count, which the electrical angle is taken from.
    home_offset_m: f32,
    trajectory: ScurveMove,
    move_ticks: u32,
    /// How far the move's clock was held back (regeneration bound), s.
    move_lag_s: f32,
    /// Share of real time the move's clock advances next position period
    /// (1, or less while regeneration is bounded).
    move_time_scale: f32,
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
    /// A clamped MoveTo is reported until the next telemetry record is cut.
    pending_limits: LimitFlags,
    load: LoadEstimator,
    /// The controlled stop in progress (mode `Stopping`).
    stop: StopRamp,
    /// How long |ω_ref − ω| has been over its threshold.
    speed_error_s: f32,
    /// How long the encoder has shown no count while told to turn.
    no_count_s: f32,
    /// The back-EMF's direction in the current loop's frame (lost encoder).
    emf_watch: EmfWatch,
    count_at_last_speed_tick: i32,
    /// q current that held the load when the brake last closed, or that the
    /// commutation measured: `Enable` builds it before the brake lets go.
    hold_current_q_a: f32,
    home_switch: Option<bool>,
    power_stage_temperature_c: Option<f32>,
    // ---- start-up steps (`lifecycle.rs`) ----
    readiness: Readiness,
    /// `StartUp`: run the remaining steps one after another.
    start_up_sequence: bool,
    calibration: CurrentCalibration,
    current_offset_a: [f32; 3],
    commutation: Commutation,
    homing: Homing,
    /// Homing found its reference and is backing off to the stroke.
    homing_backing_off: bool,
    telemetry: Telemetry,
    /// Streamed setpoints (`Command::Stream`), when a stream is running.
    stream: SetpointStream,
    /// The planned move's velocity this position period, before any
    /// slowing by the regeneration bound.
    planned_velocity_m_s: f32,
    /// `Command::Stop` is ramping the reference down (`stop`) to rest.
    commanded_stop: bool,
    // ---- scope and test signals (`scope.rs`) ----
    test: TestRun,
    capture: Capture,
    /// Every mode transition taken since creation (`mode::transition_bit`).
    transitions_taken: u128,
    /// Every transition asked for and refused by the mode machine.
    transitions_refused: u128,
}

/// `Controller::hooks` bits.
const HOOK_CAPTURE: u8 = 1;
const HOOK_TEST: u8 = 2;

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
                c.set_mode(Mode::Fault);
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
        let mut readiness = Readiness::NONE;
        if params.startup.commutation_known {
            // An absolute encoder: offset and currents come commissioned.
            readiness.insert(Readiness::COMMUTATED);
            readiness.insert(Readiness::CURRENTS_CALIBRATED);
        }
        if params.startup.homed {
            readiness.insert(Readiness::HOMED);
        }
        let derived = Derived::of(&params);
        Self {
            derived,
            mode: Mode::Disabled,
            hooks: 0,
            faults: FaultSet::NONE,
            present: FaultSet::NONE,
            tick: 0,
            // The first ticks fall on period `divider`, as `tick % divider == 0` did.
            speed_countdown: params.rates.speed_loop_divider,
            position_countdown: derived.speed_ticks_per_position_tick,
            encoder: EncoderTracker::new(),
            home_offset_m: 0.0,
            current_loop: CurrentLoop::new(),
            speed_loop: SpeedLoop::new(&params),
            trajectory: ScurveMove::hold(0.0),
            move_ticks: 0,
            move_lag_s: 0.0,
            move_time_scale: 1.0,
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
            thermal: ThermalModel::new(),
            stop: StopRamp::default(),
            current_sum_count: 0,
            speed_error_s: 0.0,
            no_count_s: 0.0,
            emf_watch: EmfWatch::default(),
            count_at_last_speed_tick: 0,
            q_current_limit_a: 0.0,
            open_phase: OpenPhaseMonitor::new(),
            torque_watch: crate::protection::TorqueWatch::new(),
            open_phase_present: false,
            brake_periods: 0,
            stop_brake_assist: false,
            handover_anchor_m: 0.0,
            speed_prev_rad_s: 0.0,
            hold_current_q_a: expected_load_current_q_a(&params),
            short_circuit_periods: 0,
            bus_voltage_v: 0.0,
            terminal_position_m: None,
            home_switch: None,
            power_stage_temperature_c: None,
            readiness,
            start_up_sequence: false,
            calibration: CurrentCalibration::new(derived.calibration_samples),
            current_offset_a: [0.0; 3],
            commutation: Commutation::new(),
            homing: Homing::new(0.0),
            homing_backing_off: false,
            telemetry: Telemetry::default(),
            stream: SetpointStream::default(),
            planned_velocity_m_s: 0.0,
            commanded_stop: false,
            test: TestRun::new(),
            capture: Capture::new(),
            transitions_taken: 0,
            transitions_refused: 0,
            params,
        }
    }

    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    /// The weights the observer runs (compiled, or an uploaded block).
    pub fn observer_weights(&self) -> &'static crate::observer::block::Weights {
        self.compensator.model()
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn faults(&self) -> FaultSet {
        self.faults
    }

    /// Start-up steps done.
    pub fn readiness(&self) -> Readiness {
        self.readiness
    }

    /// What the last commutation measured (fit, twist, check rotation).
    pub fn commutation_report(&self) -> crate::lifecycle::CommutationReport {
        self.commutation.report()
    }

    /// Phase-current offsets the calibration measured, amperes: the host
    /// subtracts them from the currents it reports (zero until calibrated).
    pub fn current_offsets_a(&self) -> [f32; 3] {
        self.current_offset_a
    }

    /// The last telemetry record (refreshed every position period).
    pub fn telemetry(&self) -> Telemetry {
        self.telemetry
    }

    /// Motor-side position `L θ_m / 2π` in the user's frame (home offset
    /// applied).
    // Out of line: ≈ 13 callers (commands, stops, the position period),
    // none in `current_period`.
    #[inline(never)]
    pub fn motor_position_m(&self) -> f32 {
        self.motor_position_m_inline()
    }

    /// [`Self::motor_position_m`] inlined, for the capture's slots.
    #[inline(always)]
    pub(super) fn motor_position_m_inline(&self) -> f32 {
        self.encoder.position_counts() * self.derived.metres_per_count + self.home_offset_m
    }

    pub fn speed_rad_s(&self) -> f32 {
        self.encoder.speed_counts_s() * self.derived.rad_per_count
    }

    /// Electrical angle the current loop uses now (offset applied).
    pub fn electrical_angle_rad(&self) -> f32 {
        self.electrical_angle_rad_inline()
    }

    /// [`Self::electrical_angle_rad`] inlined, for the capture's slots:
    /// with no call in the frame, its hot path needs no saved registers.
    #[inline(always)]
    pub(super) fn electrical_angle_rad_inline(&self) -> f32 {
        crate::foc::wrap_pi(self.rotor_state_inline().electrical_angle_rad)
    }

    /// True while a planned move has time left or a stream runs.
    // Out of line: five callers (commands, the brake, the board's snapshot
    // every 20th period), none in `current_period`.
    #[inline(never)]
    pub fn move_in_progress(&self) -> bool {
        self.stream.active() || self.commanded_stop || self.move_time_s() < self.trajectory.duration_s()
    }

    /// Time into the present move (its clock, held back while regeneration
    /// is bounded).
    fn move_time_s(&self) -> f32 {
        self.move_ticks as f32 * self.derived.position_period_s - self.move_lag_s
    }

    fn restart_move(&mut self) {
        self.move_ticks = 0;
        self.move_lag_s = 0.0;
    }

    /// The power stage's last measured temperature, °C.
    pub fn power_stage_temperature_c(&self) -> Option<f32> {
        self.power_stage_temperature_c
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

    /// The board calls this at start-up if the independent watchdog caused
    /// the last reset: the drive then waits for an explicit clear.
    pub fn report_watchdog_reset(&mut self) {
        self.raise(FaultSet::WATCHDOG_RESET);
    }

    /// The board reports a standing condition of its own (one of
    /// [`FaultSet::BOARD_CONDITIONS`]: no hardware break, unsafe boot option
    /// bytes, brake feedback disagreeing), or that it is gone. Latched as a
    /// fault at once; while it stands, `ClearFaults` answers
    /// `CauseStillPresent` and `Enable` is refused.
    pub fn report_board_condition(&mut self, condition: FaultSet, present: bool) {
        let condition = condition.intersection(FaultSet::BOARD_CONDITIONS);
        if present {
            self.present.insert(condition);
            self.raise(condition);
        } else {
            self.present.remove(condition);
        }
    }

    /// Whether the next [`Controller::step`] runs the current loop only (no
    /// speed or position tick): the board serves bulk requests (parameter
    /// sets, capture and test-signal requests) in such a period, so that
    /// their copies never add to the longest one.
    #[inline(always)]
    pub fn next_period_is_current_only(&self) -> bool {
        self.speed_countdown != 1
    }

    /// Whether the board may serve a bulk request before the next
    /// [`Controller::step`]: a period that runs the current loop only and
    /// in which no capture encodes a batch (its record's end or a full
    /// staging). The longest period is then a parameter set plus a plain
    /// current-loop period, not that plus the capture's end. A request
    /// held back waits at most two periods (a speed tick, then a capture's
    /// end); thread mode allows four.
    #[inline(always)]
    pub fn next_period_serves_bulk(&self) -> bool {
        self.next_period_is_current_only() && !self.capture.flushes_next_period()
    }

    /// The host calls this once the board is up. Nothing moves unless the
    /// configuration asks for it (`startup.run_at_power_up`).
    pub fn power_up(&mut self) -> Result<CommandOutcome, CommandError> {
        if self.params.startup.run_at_power_up {
            self.command(Command::StartUp)
        } else {
            Ok(CommandOutcome::Accepted)
        }
    }

    /// [`Controller::step`] as a function of its own, for a caller built
    /// for size: the firmware image (firmware/Cargo.toml, opt-level "z")
    /// calls this from the PWM interrupt, so the period's code is compiled
    /// with the core's settings ("s", for speed) instead of being inlined
    /// into the interrupt and compiled for size there. Costs a call.
    #[inline(never)]
    pub fn step_out_of_line(&mut self, s: &SensorSample) -> PwmCommand {
        self.step(s)
    }

    /// Advances one PWM period. Called from the ADC interrupt; bounded time,
    /// no waiting, no panics.
    pub fn step(&mut self, s: &SensorSample) -> PwmCommand {
        self.tick = self.tick.wrapping_add(1);
        let present = self.check_inputs(s);
        let enc = self.encoder.update(
            &self.params.encoder,
            s.encoder_count,
            self.derived.current_timing.period_s,
            self.params.faults.encoder_max_step_counts,
            self.params.faults.encoder_max_innovation_counts,
        );
        if enc.implausible_step {
            // A jump is an event, not a standing condition: it can be cleared.
            self.raise(FaultSet::ENCODER_JUMP);
        }
        let (speed_tick, position_tick) = self.next_ticks();
        self.latch_conditions(present, s, speed_tick, position_tick);

        // Brake output: open (true) from `current_period` while driving,
        // closed (false) in `PwmCommand::OFF` and the short circuit; only
        // `Braking`, `Enable`'s preload and the start-up steps decide per
        // period. Without a brake nothing is wired to it.
        // Driving first: it is the 20 kHz case the cycle budget is for.
        let out = match self.mode {
            Mode::Running | Mode::Stopping | Mode::Homing => {
                if position_tick {
                    self.brake_tick();
                }
                self.run_period_inline(s, position_tick, speed_tick)
            }
            Mode::Fault if self.short_circuit_periods > 0 => self.short_circuit(s),
            Mode::Disabled | Mode::Fault => self.bridge_off(),
            Mode::Calibrating => self.calibration_period(s),
            Mode::Aligning => self.commutation_period(s, position_tick),
            Mode::Braking => self.braking_period(s, position_tick, speed_tick),
            Mode::Preloading => self.preload_period(s, position_tick, speed_tick),
        };
        if self.hooks != 0 {
            self.hooks_period(s, speed_tick);
        }
        if position_tick {
            self.cut_telemetry();
        }
        out
    }

    /// Counts the period down to the speed and position ticks.
    #[inline]
    fn next_ticks(&mut self) -> (bool, bool) {
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
        (speed_tick, position_tick)
    }
}

/// q current that holds `startup.expected_load_force_n` at the screw, in
/// the direction the encoder counts up (positive rotation extends the rod,
/// a positive load opposes extension).
pub(super) fn expected_load_current_q_a(p: &ControlParams) -> f32 {
    load_current_q_a(p, p.startup.expected_load_force_n)
}

/// The q current whose torque balances `force_n` at the nut (the screw's
/// ideal lead; friction is the caller's band).
/// The screw's Coulomb friction under the slow load estimate, as q current:
/// at rest friction takes up any torque inside this band, so a held load's
/// current may wander within it without moving the rod.
pub(super) fn friction_band_q_a(p: &ControlParams, load: &LoadEstimator) -> f32 {
    crate::motion::speed_loop::coulomb_friction_n_m(p, load.slow_force_n()) / p.torque_constant_n_m_a()
}
pub(super) fn load_current_q_a(p: &ControlParams, force_n: f32) -> f32 {
    let torque = force_n * p.metres_per_rad();
    torque / p.torque_constant_n_m_a()
}
