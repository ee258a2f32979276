//! The loop cascade: position (1 kHz) → speed (5 kHz) → current (20 kHz),
//! and the telemetry record cut at the position rate.

use super::Controller;
use crate::compensation::Compensator;
use crate::foc::current_loop::RotorState;
use crate::foc::Dq;
use crate::io::{PwmCommand, SensorSample};
use crate::lifecycle::HomingInput;
use crate::motion::speed_loop::friction_feedforward_n_m;
use crate::motion::{position_step, TrajectorySample};
use crate::protection::{clamp_to_stroke, FaultSet, LimitFlags};
use crate::telemetry::{Mode, Telemetry};

/// While the current loop sits on its voltage circle the speed PI may ask
/// for at most this much more q current than flows: it cannot get more, so
/// its integrator must not wind up for it.
const VOLTAGE_LIMITED_Q_MARGIN_A: f32 = 1.0;
/// Hold torque below which the regeneration bound leaves the speed alone
/// (a tenth of the rated load's 1.1 N·m).
const REGEN_HOLD_TORQUE_MIN_N_M: f32 = 0.1;

impl Controller {
    pub(super) fn rotor_state(&self) -> RotorState {
        self.rotor_state_inline()
    }

    /// [`Self::rotor_state`] inlined into the 20 kHz path: the call, its
    /// frame and return cost four instructions a period there.
    #[inline(always)]
    pub(super) fn rotor_state_inline(&self) -> RotorState {
        let k = self.derived.electrical_rad_per_count;
        RotorState {
            // Not wrapped: within offset ± 2π·pole_pairs, which `sincos`
            // reduces as accurately as a wrapped angle.
            electrical_angle_rad: self.encoder.counts_in_turn(&self.params.encoder) * k
                + self.params.encoder.electrical_offset_rad,
            electrical_speed_rad_s: self.encoder.speed_counts_s() * k,
        }
    }

    /// [`Self::run_period_inline`] for the braking and preload periods.
    pub(super) fn run_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        self.run_period_inline(s, position_tick, speed_tick)
    }

    /// The cascade's period: inlined into `step`'s driving case, where the
    /// call, its frame and its return cost eight instructions a period.
    #[inline(always)]
    pub(super) fn run_period_inline(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        if position_tick {
            self.position_period(s);
        }
        if speed_tick {
            self.speed_period();
        }
        let rotor = self.rotor_state_inline();
        self.current_period(s, rotor)
    }

    /// [`Self::run_period`] with the q reference bounded by `q_cap_a` after
    /// the speed loop: a hold handing its load to the brake lowers the
    /// motor's share without touching the speed loop's state, so a slip
    /// gets the whole of it back at once.
    pub(super) fn run_period_capped(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool, q_cap_a: f32) -> PwmCommand {
        if position_tick {
            self.position_period(s);
        }
        if speed_tick {
            self.speed_period();
        }
        self.current_reference.q = crate::math::clamp(self.current_reference.q, -q_cap_a, q_cap_a);
        let rotor = self.rotor_state_inline();
        self.current_period(s, rotor)
    }

    /// The speed PI inside the q-current bounds of this instant.
    #[inline(never)]
    fn speed_period(&mut self) {
        let mut limit = self.thermal.current_limit_a(&self.params.thermal, self.derived.current_limit_a);
        if let Some(t) = self.power_stage_temperature_c {
            let ps = &self.params.power_stage;
            let share = crate::math::clamp((ps.temperature_trip_c - t) / (ps.temperature_trip_c - ps.temperature_foldback_c), 0.0, 1.0);
            limit = crate::math::min(limit, share * self.derived.current_limit_a);
        }
        if limit < self.derived.current_limit_a {
            self.limits.insert(LimitFlags::THERMAL);
        }
        let iq_max2 = limit * limit - self.current_reference.d * self.current_reference.d;
        let iq_max = crate::math::sqrt(crate::math::max(iq_max2, 0.0));
        self.q_current_limit_a = iq_max;
        let (mut lo, mut hi) = (-iq_max, iq_max);
        // At standstill under a closed brake a voltage-limited period is the
        // current loop slewing to the preloaded hold current (kp times the
        // step exceeds the circle above about 11.8 A), not the back-EMF
        // circle: narrowing there would clamp the speed integrator's preset
        // to the current flowing in that first period and throw the hold away.
        // The same holds for the hold on the half-turned angle after a torque
        // verdict: the current reverses from the wrong angle's push.
        if self.limits.contains(LimitFlags::VOLTAGE) && self.mode != Mode::Preloading && !self.torque_watch.turned() {
            let reachable = self.current_dq.q.abs() + VOLTAGE_LIMITED_Q_MARGIN_A;
            lo = crate::math::max(lo, -reachable);
            hi = crate::math::min(hi, reachable);
        }
        if self.test.suspends_speed() {
            // A current step holds the q reference, inside today's bound.
            self.current_reference.q = crate::math::clamp(self.current_reference.q, lo, hi);
            return;
        }
        if self.mode == Mode::Homing && !self.homing_backing_off {
            // Around the hold current: lifts the load, pushes into the stop
            // with a bounded force.
            let push = self.params.homing.current_max_a;
            lo = crate::math::max(lo, self.hold_current_q_a - push);
            hi = crate::math::min(hi, self.hold_current_q_a + push);
        }
        let out = self.speed_loop.step(
            &self.params,
            self.speed_reference_rad_s,
            self.acceleration_reference_rad_s2,
            self.friction_ff_n_m,
            self.speed_rad_s(),
            (lo, hi),
        );
        // A current chirp rides on the loop's output (0 without a test).
        self.current_reference.q = out.current_q_reference_a + self.test.current_offset_a;
        if out.current_limited {
            self.limits.insert(LimitFlags::CURRENT);
        }
    }

    pub(super) fn current_period(&mut self, s: &SensorSample, rotor: RotorState) -> PwmCommand {
        let out = self.current_loop.step(&self.params, self.derived.current_timing, s.phase_current_a, self.current_reference, rotor, s.bus_voltage_v);
        self.current_dq = out.current_dq;
        self.voltage_dq = out.voltage_dq;
        if out.voltage_limited {
            self.limits.insert(LimitFlags::VOLTAGE);
        }
        // `step` decides the brake output for the whole period.
        PwmCommand { duty: out.duty, enable: true, brake_release: true }
    }

    /// The position reference for this period: the planned move, homing,
    /// or the controlled stop.
    fn next_reference(&mut self) -> TrajectorySample {
        self.planned_velocity_m_s = 0.0;
        if matches!(self.mode, Mode::Stopping | Mode::Braking) {
            return self.stop.advance(self.derived.position_period_s);
        }
        if self.brake_opening() {
            // The move (or homing) waits for the brake: hold its start.
            return self.trajectory.sample(0.0);
        }
        if self.mode == Mode::Homing && !self.homing_backing_off {
            return self.homing_reference();
        }
        if self.commanded_stop {
            return self.stop_reference();
        }
        if self.stream.active() {
            return self.stream_reference();
        }
        let t = self.move_time_s();
        self.move_ticks = self.move_ticks.saturating_add(1);
        let scale = self.move_time_scale;
        let mut r = self.trajectory.sample(t);
        self.planned_velocity_m_s = r.velocity_m_s;
        if scale < 1.0 {
            // The move runs slower: its clock falls behind, its velocity and
            // acceleration shrink with it.
            self.move_lag_s += (1.0 - scale) * self.derived.position_period_s;
            r.velocity_m_s *= scale;
            r.acceleration_m_s2 *= scale * scale;
        }
        r
    }

    /// One streamed period: the interpolated setpoints, or, once they
    /// stopped arriving, a deceleration from where the reference got to (at
    /// the newest setpoint's velocity) to rest, `stream_timeout` latched
    /// only then. The reference never stops dead: a rod at speed would
    /// overshoot and ring.
    #[inline(never)]
    fn stream_reference(&mut self) -> TrajectorySample {
        let shaping = crate::motion::stream_stop::StopShaping::of(&self.params);
        let mut r = self.stream.advance(self.derived.position_period_s, &shaping);
        if self.stream.lost_at_rest() {
            self.raise(FaultSet::STREAM_TIMEOUT);
            if self.mode == Mode::Stopping {
                // The stream's own stop has come to rest: the controlled
                // stop holds there, not where the motor happens to be while
                // the payload still swings on the rod (a step of tens of µm).
                self.stop = crate::motion::StopRamp::new(r.position_m, 0.0, self.params.faults.stop_deceleration_m_s2);
            }
            return r;
        }
        if self.stream.decelerating() {
            return r;
        }
        let a_max = self.params.trajectory.max_acceleration_m_s2;
        if r.acceleration_m_s2.abs() > a_max {
            // Setpoints closer in time than their velocities allow: the
            // feedforward is bounded (the position loop takes the rest).
            r.acceleration_m_s2 = a_max.copysign(r.acceleration_m_s2);
            self.limits.insert(LimitFlags::SPEED);
        }
        r
    }

    /// One homing period; on contact the frame moves and the back-off starts.
    fn homing_reference(&mut self) -> TrajectorySample {
        let input = HomingInput { position_m: self.motor_position_m(), speed_rad_s: self.speed_rad_s(), home_switch: self.home_switch };
        let out = self.homing.update(&self.params, &input, self.derived.position_period_s);
        match out.done {
            None => TrajectorySample { position_m: out.position_m, velocity_m_s: out.velocity_m_s, acceleration_m_s2: 0.0 },
            Some(Ok(found_m)) => {
                self.finish_homing(found_m);
                self.trajectory.sample(0.0)
            }
            Some(Err(fault)) => {
                self.raise(fault);
                let here = self.motor_position_m();
                TrajectorySample { position_m: here, velocity_m_s: 0.0, acceleration_m_s2: 0.0 }
            }
        }
    }

    #[inline(never)]
    fn position_period(&mut self, s: &SensorSample) {
        if self.test.suspends_position() {
            self.test_track_position();
            return;
        }
        let r = self.next_reference();
        self.position_reference_m = r.position_m;
        // The observer's shift ramps in only once the brake has let go: a
        // shift while it opens would push the rotor against the brake,
        // which the start-up torque watch rightly reads as a rotor that
        // does not follow its torque.
        let (observer_shift, observer_rate_m_s) = if self.mode == Mode::Running && !self.brake_opening() {
            let travel = self.compensator.travel_direction(r.velocity_m_s);
            let inputs = Compensator::inputs(&self.params, self.speed_rad_s(), self.motor_position_m(), self.load.force_n(), travel);
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
            (c.shift_m, c.rate_m_s)
        } else {
            (0.0, 0.0)
        };
        let step_max = self.params.compensation.shift_rate_max_m_s * self.derived.position_period_s;
        self.external_shift_applied_m +=
            crate::math::clamp(self.position_shift_m - self.external_shift_applied_m, -step_max, step_max);
        self.applied_shift_m = observer_shift + self.external_shift_applied_m;
        // A position chirp rides on the command (0 without a test).
        let mut command = r.position_m + self.applied_shift_m + self.test.position_offset_m;
        if self.stroke_limits_active() {
            let l = &self.params.limits;
            let (clamped_command, clamped) = clamp_to_stroke(command, l.stroke_min_m, l.stroke_max_m);
            if clamped {
                self.limits.insert(LimitFlags::STROKE);
            }
            command = clamped_command;
        }
        self.position_command_m = command;
        // The command is the reference plus the shift, so during a planned
        // move its velocity is the plan's plus the shift's: fed forward, the
        // shift's growth at a move's start (the load's force rising with the
        // acceleration) is not left to the P loop as a lag of rate / kp. At
        // rest the P loop holds the shift alone, as the start-up torque
        // watch expects while it judges the rotor against its torque.
        // Only with the load cell as the force input: the estimate is read
        // from the current this feedforward commands, so fed forward the
        // shift's rate would close a loop through the speed loop's current
        // (estimate → shift → velocity → current → estimate), whereas the
        // load cell is outside it.
        let shift_ff_m_s =
            if self.planned_velocity_m_s != 0.0 && self.force_from_load_cell(s) { observer_rate_m_s } else { 0.0 };
        let out = position_step(&self.params, command, r.velocity_m_s + shift_ff_m_s, r.acceleration_m_s2, self.motor_position_m());
        self.speed_reference_rad_s = out.speed_reference_rad_s + self.test.speed_offset_rad_s;
        self.acceleration_reference_rad_s2 = out.acceleration_reference_rad_s2;
        if out.speed_limited {
            self.limits.insert(LimitFlags::SPEED);
        }
        self.bound_regeneration();
        // A speed chirp's friction is fed forward from its reference, as a
        // move's is from the plan (and a speed step's, `test_track_position`):
        // the test then measures the loop the drive runs, not Coulomb
        // friction switching at every reversal of the sweep.
        let planned_m_s = if self.test.speed_offset_rad_s != 0.0 {
            r.velocity_m_s + self.test.speed_offset_rad_s * self.params.metres_per_rad()
        } else {
            r.velocity_m_s
        };
        let nut_force_n = if self.stream.active() {
            // The nut carries the payload's inertial force too: a stream's
            // stop (5 m/s² against the rated mass, half the weight) changes
            // the screw's load-proportional friction by a tenth of that.
            self.load.slow_force_n() + self.params.drive_train.moving_mass_kg * r.acceleration_m_s2
        } else {
            self.load.slow_force_n()
        };
        self.friction_ff_n_m = friction_feedforward_n_m(&self.params, planned_m_s, nut_force_n);
        if self.stream.active() {
            // A streamed force feedforward: the load the platform expects,
            // as torque at the screw.
            self.friction_ff_n_m += self.stream.force_n() * self.params.metres_per_rad();
        }
        let inertial_n = self.params.drive_train.moving_mass_kg * r.acceleration_m_s2;
        let dt = self.derived.position_period_s;
        match s.load_cell_force_n {
            // The load cell sits beyond the nut and the seal: it feels the
            // payload's inertia but none of the friction.
            Some(f) if self.force_from_load_cell(s) => {
                self.load.update_measured(&self.params, f, inertial_n, dt);
            }
            _ => {
                self.load.update(&self.params, self.current_dq.q, self.acceleration_reference_rad_s2, planned_m_s, inertial_n, dt);
            }
        }
    }

    /// Whether the load force (the observer's force input) comes from the
    /// load cell this period, rather than from the current-based estimate.
    fn force_from_load_cell(&self, s: &SensorSample) -> bool {
        s.load_cell_force_n.is_some() && !self.params.compensation.force_from_estimate
    }

    /// Regeneration: while the bus is above `regen_bus_start_v`, a hanging
    /// load may be lowered at most as fast as the power left between that
    /// and `regen_bus_max_v` allows, `P / T_hold`. Refusing the current
    /// would drop the load; bounding the lowering speed bounds the power.
    /// The bound follows the slow load estimate (the weight, not the
    /// instantaneous torque, whose sign flips with every correction), and
    /// slows the move's own clock so the reference does not run away.
    fn bound_regeneration(&mut self) {
        self.move_time_scale = 1.0;
        let ps = &self.params.power_stage;
        if self.bus_voltage_v <= ps.regen_bus_start_v {
            return;
        }
        let mpr = self.params.metres_per_rad();
        let hold_torque_n_m = self.load.slow_force_n() * mpr;
        // Below this no load hangs on the motor: braking the rotor's own
        // inertia returns little, and the trip guards it.
        if hold_torque_n_m.abs() < REGEN_HOLD_TORQUE_MIN_N_M {
            return;
        }
        // A load that opposes extension drives the motor when lowered.
        let lowering = -hold_torque_n_m.signum();
        let share = crate::math::clamp((ps.regen_bus_max_v - self.bus_voltage_v) / (ps.regen_bus_max_v - ps.regen_bus_start_v), 0.0, 1.0);
        let speed_max = share * ps.regen_power_max_w / hold_torque_n_m.abs();
        // The planned speed, before any slowing: the clock's scale must not
        // feed back on itself.
        let planned = (self.planned_velocity_m_s / mpr) * lowering;
        if planned > speed_max {
            self.move_time_scale = speed_max / planned;
        }
        if self.speed_reference_rad_s * lowering > speed_max {
            self.speed_reference_rad_s = speed_max * lowering;
            self.limits.insert(LimitFlags::REGEN);
        }
    }

    #[inline(never)]
    pub(super) fn cut_telemetry(&mut self) {
        let mut limits = self.limits;
        limits.insert(self.pending_limits);
        self.telemetry = Telemetry {
            time_s: self.tick as f32 * self.derived.current_timing.period_s,
            mode: self.mode,
            position_reference_m: self.position_reference_m,
            position_command_m: self.position_command_m,
            position_shift_m: self.applied_shift_m,
            motor_position_m: self.motor_position_m(),
            // In the user's frame, like the position: the angle the rod's
            // position corresponds to (per-revolution effects are phased by it).
            motor_angle_rad: self.motor_position_m() * self.derived.rad_per_metre,
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
            readiness: self.readiness,
        };
        self.limits = LimitFlags::NONE;
        self.pending_limits = LimitFlags::NONE;
    }

    /// Stationary current vector (commutation): magnitude at an electrical
    /// angle, held by the current loop with the rotor angle fixed there.
    pub(super) fn vector_period(&mut self, s: &SensorSample, current_a: f32, angle_rad: f32, brake_release: bool) -> PwmCommand {
        self.current_reference = Dq { d: current_a, q: 0.0 };
        let mut out = self.current_period(s, RotorState { electrical_angle_rad: angle_rad, electrical_speed_rad_s: 0.0 });
        out.brake_release = brake_release;
        out
    }
}
