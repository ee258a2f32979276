//! Protection checks: a sample in, the conditions present and the latched
//! faults out. The reactions live in `reactions.rs`.

use super::Controller;
use crate::foc::transforms::SinCos;
use crate::io::SensorSample;
use crate::motion::StopRamp;
use crate::protection::{FaultSet, TorqueLook, TorqueWatchVerdict};
use crate::telemetry::Mode;

/// Conditions evaluated at the speed-loop rate.
const SPEED_RATE_CAUSES: FaultSet = FaultSet::MOTOR_OVERTEMP.union(FaultSet::SPEED_FOLLOWING).union(FaultSet::OPEN_PHASE).union(FaultSet::POWER_STAGE_OVERTEMP);

/// Conditions evaluated at the position-loop rate.
const POSITION_RATE_CAUSES: FaultSet = FaultSet::POSITION_FOLLOWING.union(FaultSet::STROKE_OVERTRAVEL);

/// Bridge-off faults after which the low-side switches must not be closed:
/// the current can no longer be measured or bounded (overcurrent, a sensor,
/// a NaN sample, the hardware break already acted), or the core's timing is
/// not trusted (overrun, watchdog), or nothing was ever set up (parameters).
const NO_SHORT_CIRCUIT: FaultSet = FaultSet::OVERCURRENT.union(FaultSet::CURRENT_SENSOR).union(FaultSet::NON_FINITE_INPUT).union(FaultSet::BRIDGE_BREAK).union(FaultSet::ISR_OVERRUN).union(FaultSet::WATCHDOG_RESET).union(FaultSet::INVALID_PARAMS);

impl Controller {
    /// Latches `f`; new faults get their reaction.
    #[inline(never)]
    pub(super) fn raise(&mut self, f: FaultSet) {
        if !self.latch(f) {
            return;
        }
        if !self.faults.only_controlled_stop() {
            self.switch_off();
            return;
        }
        match self.mode {
            Mode::Running | Mode::Homing | Mode::Preloading => self.begin_stop(),
            // Already decelerating to rest.
            Mode::Stopping | Mode::Braking => {}
            Mode::Disabled | Mode::Calibrating | Mode::Aligning | Mode::Fault => self.set_mode(Mode::Fault),
        }
    }

    /// Records `f` without its reaction; false if nothing in it is new.
    #[inline(never)]
    fn latch(&mut self, f: FaultSet) -> bool {
        let new = f.difference(self.faults);
        if new.is_empty() {
            return false;
        }
        self.faults.insert(new);
        // A fault ends a test and triggers a capture armed for it.
        self.finish_test(false);
        self.capture.event(crate::capture::CaptureTrigger::Fault);
        self.refresh_hooks();
        self.forget_position(new);
        // A failed start-up step is not retried by a later `StartUp` step.
        self.start_up_sequence = false;
        true
    }

    /// The bridge-off reaction: short-circuit braking through the brake's
    /// engage time where the power stage is still trusted, then off.
    #[inline(never)]
    fn switch_off(&mut self) {
        let driving = matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Braking | Mode::Homing | Mode::Preloading)
            && self.speed_rad_s().abs() < self.derived.short_circuit_speed_max_rad_s;
        // Short-circuit braking bridges the brake's engage time, where
        // the fault leaves the power stage and the supply trustworthy.
        self.short_circuit_periods = if driving && self.params.brake.fitted && self.faults.intersection(NO_SHORT_CIRCUIT).is_empty() {
            self.derived.brake_engage_periods
        } else {
            0
        };
        self.set_mode(Mode::Fault);
    }

    /// Decelerates from the measured motion to rest and holds there.
    #[inline(never)]
    pub(super) fn begin_stop(&mut self) {
        let v = self.speed_rad_s() * self.params.metres_per_rad();
        self.stop = StopRamp::new(self.motor_position_m(), v, self.params.faults.stop_deceleration_m_s2);
        self.commanded_stop = false;
        // The stop's path starts here: following checks before the next
        // position period must not judge it by the command it replaced.
        self.position_command_m = self.motor_position_m();
        self.position_shift_m = 0.0;
        self.external_shift_applied_m = 0.0;
        self.compensator.set_enabled(false);
        self.compensator.reset();
        self.homing_backing_off = false;
        self.stream.stop();
        self.speed_prev_rad_s = self.speed_rad_s();
        self.set_mode(Mode::Stopping);
    }

    /// The outer-rate checks, then every new condition latched.
    #[inline]
    pub(super) fn latch_conditions(&mut self, mut present: FaultSet, s: &SensorSample, speed_tick: bool, position_tick: bool) {
        // Causes checked at the outer rates keep their last verdict between
        // their ticks, or a clear between two ticks would find them gone.
        present = present.union(if speed_tick {
            self.check_speed_period(s.phase_current_a)
        } else {
            self.present.intersection(SPEED_RATE_CAUSES)
        });
        present = present.union(if position_tick {
            // The slow inputs are read at the rate they are used.
            self.home_switch = s.home_switch;
            self.power_stage_temperature_c = s.power_stage_temperature_c;
            self.check_motion()
        } else {
            self.present.intersection(POSITION_RATE_CAUSES)
        });
        self.present = present;
        let raised = present.difference(FaultSet::INVALID_PARAMS);
        if !raised.difference(self.faults).is_empty() {
            self.raise(raised);
        }
    }

    /// Checks one sample; returns the conditions present now.
    pub(super) fn check_inputs(&mut self, s: &SensorSample) -> FaultSet {
        let f = &self.params.faults;
        let mut present = self.present.intersection(FaultSet::INVALID_PARAMS.union(FaultSet::BOARD_CONDITIONS));
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
        // Only while the bridge is on (or about to be) or the fault is
        // latched: a board powered from USB with the bus off must still be
        // configurable, but a latched undervoltage must not clear during the
        // sag.
        let watching = !matches!(self.mode, Mode::Disabled | Mode::Fault) || self.faults.contains(FaultSet::BUS_UNDERVOLTAGE);
        if v < f.bus_undervoltage_v && watching {
            present.insert(FaultSet::BUS_UNDERVOLTAGE);
        }
        present
    }

    /// Winding and power-stage temperature, speed following, encoder loss
    /// (no counts while turning, or back-EMF without counts at standstill)
    /// and open phases, at the speed rate. Returns the standing conditions;
    /// raises the events.
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
        if let Some(t) = self.power_stage_temperature_c {
            let ps = &self.params.power_stage;
            let limit = if self.faults.contains(FaultSet::POWER_STAGE_OVERTEMP) { ps.temperature_foldback_c } else { ps.temperature_trip_c };
            if !(t < limit) {
                present.insert(FaultSet::POWER_STAGE_OVERTEMP);
            }
        }
        let count = self.encoder.count();
        let moved = count != self.count_at_last_speed_tick;
        self.count_at_last_speed_tick = count;
        if moved {
            self.emf_watch.count_moved();
        }
        if !matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Braking | Mode::Homing | Mode::Preloading) {
            self.speed_error_s = 0.0;
            self.no_count_s = 0.0;
            self.emf_watch.reset();
            // With the bridge off nothing can be judged; an open phase shows
            // again within a window of the next enable.
            self.open_phase.reset();
            self.open_phase_present = false;
            return present;
        }
        let sc = SinCos::of(self.rotor_state().electrical_angle_rad);
        let reference_a = self.open_phase.expected_phase_current_a(self.derived.open_phase_follow_gain, self.current_reference, sc);
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
        // Homing stalls against the stop on purpose, told to turn: there the
        // back-EMF check below judges the encoder instead.
        let told_to_turn = w_ref.abs() > f.encoder_lost_speed_rad_s && self.mode != Mode::Homing;
        self.no_count_s = if !moved && told_to_turn { self.no_count_s + dt } else { 0.0 };
        if self.no_count_s >= f.encoder_lost_time_s {
            // No count while told to turn: a lost encoder if the back-EMF
            // says the rotor turns, or turned a net electrical turn since
            // the last count (it may be reversing right now), else a stall
            // (the rotor stands at its last count, the position cannot
            // follow: a controlled stop, not a fall).
            if self.emf_watch.sees_rotation(&self.params) || self.emf_watch.turned_since_count() {
                self.raise(FaultSet::ENCODER_LOST);
            } else {
                present.insert(FaultSet::POSITION_FOLLOWING);
            }
        }
        present
    }

    /// From enable until the loops first hold the rod still: the motor side
    /// must not leave its command against the torque asked of it.
    #[inline(never)]
    fn watch_torque(&mut self, x: f32) {
        let holding_turned = self.mode == Mode::Braking && self.torque_watch.turned();
        if !(matches!(self.mode, Mode::Running | Mode::Preloading) || holding_turned) {
            self.torque_watch.disarm();
            return;
        }
        let look = TorqueLook {
            following_error_m: self.position_command_m - x,
            position_m: x,
            q_current_reference_a: self.current_reference.q,
            preload_current_a: self.hold_current_q_a,
            stated_load_current_a: super::expected_load_current_q_a(&self.params),
            speed_m_s: self.speed_rad_s() * self.params.metres_per_rad(),
            brake_closed: self.mode == Mode::Preloading,
            may_settle: self.mode == Mode::Running && !self.brake_opening(),
            moving: self.move_in_progress(),
            dt_s: self.derived.position_period_s,
        };
        match self.torque_watch.update(&self.params, look) {
            TorqueWatchVerdict::Watching => {}
            TorqueWatchVerdict::Inconsistent => self.torque_inconsistent(false),
            TorqueWatchVerdict::Reversed => self.torque_inconsistent(true),
            // Only a start-up waits on the settle; a user's own enable goes on.
            TorqueWatchVerdict::NeverSettled if self.start_up_sequence => self.raise(FaultSet::LIFECYCLE_TIMEOUT),
            TorqueWatchVerdict::NeverSettled => {}
            // A start-up waiting to home goes on.
            TorqueWatchVerdict::Settled => self.next_start_up_step(),
        }
    }

    /// The torque does not make the motion. With the brake open the load is
    /// on the motor alone, and short-circuit braking only holds it at a sink
    /// speed: its torque `1.5 p² ψ² ω / R` grows with the speed, so a load
    /// `T` sinks at `ω = T R / (1.5 p² ψ²)` (≈ 12 mm/s at rated load on the
    /// nominal motor, more on a hot winding or a weak magnet) through the
    /// brake's engage time, most of the half-millimetre budget. The watch's
    /// verdict is an angle error, reversed or missing torque, that a turned
    /// angle undoes ([`crate::protection::TorqueWatch::turn`]): the loops
    /// hold on it while the brake closes (`Braking`, the fault latched, the
    /// brake's engage time running from the first verdict), watched as
    /// before. When the turns are spent the bridge goes off with the short
    /// circuit, as it does at once for a verdict on the closed brake. The
    /// user's stored offset is put back when the bridge goes off.
    #[inline(never)]
    fn torque_inconsistent(&mut self, reversed: bool) {
        let first = !self.torque_watch.turned();
        if first && !(self.mode == Mode::Running && self.params.brake.fitted) {
            self.raise(FaultSet::WRONG_DIRECTION);
            return;
        }
        let emf_d_v = self.voltage_dq.d - self.params.motor.phase_resistance_ohm * self.current_dq.d;
        let turned = self.torque_watch.turn(reversed, self.params.encoder.electrical_offset_rad, emf_d_v, self.speed_rad_s());
        let Some(o) = turned else {
            // The turned angles did no better: the fault is latched already.
            self.switch_off();
            return;
        };
        self.latch(FaultSet::WRONG_DIRECTION);
        self.params.encoder.electrical_offset_rad = o;
        // The first verdict comes at a few mm/s: the stop ramps from there.
        // A later one finds the brake already closing; the rod is held
        // where it is, the brake left closing.
        let v = if first { self.speed_rad_s() * self.params.metres_per_rad() } else { 0.0 };
        self.start_holding(self.hold_current_q_a);
        self.stop = StopRamp::new(self.position_command_m, v, self.params.faults.stop_deceleration_m_s2);
        if first {
            self.brake_periods = 0;
        }
        self.set_mode(Mode::Braking);
    }

    /// The stroke means something once homed; homing itself runs to the
    /// stop and backs off from it, beyond the stroke, so the limits act from
    /// the end of homing on.
    pub(super) fn stroke_limits_active(&self) -> bool {
        self.readiness.contains(crate::lifecycle::Readiness::HOMED) && self.mode != Mode::Homing
    }

    /// The brake holds more than the motor at its present current limit.
    #[inline(always)]
    fn brake_stronger(&self) -> bool {
        self.params.brake.fitted
            && self.params.torque_constant_n_m_a() * self.q_current_limit_a < self.params.brake.holding_torque_n_m
    }

    /// Following error, overtravel and the soft limits, at the position rate.
    /// Stroke and soft limits mean something only once homed.
    #[inline(never)]
    fn check_motion(&mut self) -> FaultSet {
        let mut present = FaultSet::NONE;
        let x = self.motor_position_m();
        let l = &self.params.limits;
        let f = &self.params.faults;
        let homed = self.stroke_limits_active();
        if homed && (x < l.stroke_min_m - f.stroke_overtravel_m || x > l.stroke_max_m + f.stroke_overtravel_m) {
            present.insert(FaultSet::STROKE_OVERTRAVEL);
        }
        let following = (self.position_command_m - x).abs();
        if matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Preloading) && following > f.position_following_error_m {
            present.insert(FaultSet::POSITION_FOLLOWING);
        }
        let brake_stronger = self.brake_stronger();
        let stop_failed =
            matches!(self.mode, Mode::Stopping | Mode::Braking) && following > f.stop_following_error_m && brake_stronger;
        if matches!(self.mode, Mode::Running | Mode::Preloading) && homed {
            // Where would a stop at the stop deceleration end?
            let v = self.speed_rad_s() * self.params.metres_per_rad();
            let rest = x + v * v.abs() / (2.0 * f.stop_deceleration_m_s2);
            if rest > l.stroke_max_m + f.stroke_soft_margin_m || rest < l.stroke_min_m - f.stroke_soft_margin_m {
                self.raise(FaultSet::SOFT_LIMIT);
            }
        }
        // A current chirp makes voltage without motion on purpose: `L di/dt`
        // of a kHz sweep, sampled here at the position rate, aliases into a
        // turning `e` and reads as a slipping rotor. The watch sits out the
        // chirp (bounded by its duration, which the test's bounds limit)
        // and starts a fresh window after it. A current step keeps it: with
        // both outer loops suspended it is the only encoder guard left.
        if self.test.sweeps_current() {
            self.emf_watch.reset();
        } else if matches!(self.mode, Mode::Running | Mode::Stopping | Mode::Braking | Mode::Homing | Mode::Preloading)
            && self.emf_watch.update(&self.params, self.voltage_dq, self.current_dq, self.derived.position_period_s)
        {
            self.raise(FaultSet::ENCODER_LOST);
        }
        if self.torque_watch.watching() {
            self.watch_torque(x);
        }
        // The stop starts from the measured position: straying from it means
        // the load is winning. The brake must take it before the end stop.
        if stop_failed {
            self.raise(FaultSet::STOP_FAILED);
        }
        // The load is winning the stop and the motor is the stronger of the
        // two: handing the load to the brake alone would let it slide, so
        // the brake closes now and the loops push with it. It is already
        // lost, before it strays that far, when the rod would outrun the
        // bus while the brake engages (`stop_outruns_bus`).
        let stop_losing = self.mode == Mode::Stopping
            && self.params.brake.fitted
            && !self.brake_stronger()
            && ((self.position_command_m - x).abs() > self.params.faults.stop_following_error_m || self.stop_outruns_bus(x));
        if stop_losing {
            self.assist_stop_with_brake();
        } else if self.stop_brake_assist {
            self.anchor_assisted_stop();
        }
        present
    }
}
