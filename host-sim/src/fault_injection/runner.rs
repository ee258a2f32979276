//! Runs one fault scenario closed-loop (plant + the firmware's control core)
//! and records, every PWM period, what a safety case needs: the true peak
//! phase current, the true motor-side and rod positions, the latched faults,
//! the mode, whether the bridge was on, and any non-finite value anywhere.

use super::injection::{CommandAt, Injection, SensorCorruptor, Timed};
use crate::config::RigConfig;
use crate::plant::{Plant, PlantParams};
use crate::sim::ClosedLoop;
use anyhow::{anyhow, Result};
use servo_core::{
    Command, CommandError, CommandOutcome, ControlParams, Controller, FaultSet, LimitFlags, Mode, PwmCommand,
    Telemetry,
};
use std::f64::consts::TAU;

/// Where and how the drive starts.
#[derive(Clone, Debug)]
pub struct Setup {
    pub control: ControlParams,
    pub plant: PlantParams,
    /// Motor-side start position (the drive is homed there), metres.
    pub position_m: f64,
    /// Tilt from horizontal; 90° = vertical, rod up, gravity opposing extension.
    pub tilt_deg: f64,
    pub seed: u64,
    /// The board's comparator overcurrent break (true phase current,
    /// independent of the core); `None`: not fitted.
    pub hardware_ocp_a: Option<f64>,
    /// Independent watchdog timeout (firmware: `WATCHDOG_TIMEOUT_MS`).
    pub watchdog_timeout_s: f64,
}

impl Setup {
    /// The shipped rig, vertical at rated load, homed mid-stroke, with the
    /// B-G431B-ESC1's 45 A comparator break and the firmware's 100 ms
    /// watchdog.
    pub fn nominal(rig: &RigConfig) -> Self {
        Self {
            control: rig.control,
            plant: rig.plant.clone(),
            position_m: 0.25,
            tilt_deg: 90.0,
            seed: 1,
            hardware_ocp_a: Some(45.0),
            watchdog_timeout_s: 0.100,
        }
    }

    pub fn pwm_period_s(&self) -> f64 {
        1.0 / f64::from(self.control.rates.pwm_frequency_hz)
    }
}

/// What a scenario must show. A test asserts every line of it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Expect {
    /// Fault bits that must be latched at the end of the run (empty with a
    /// reaction: any fault will do).
    pub faults: FaultSet,
    /// The mode right after the first latch: `Fault` (bridge off) or
    /// `Stopping` (controlled stop, bridge on). `None`: the drive must ride
    /// through without any fault.
    pub reaction: Option<Mode>,
    /// The first fault latches at most this many PWM periods after the
    /// first period that carried the fault.
    pub within_periods: u64,
    /// The true phase current may exceed `limits.current_max_a` by this
    /// much, for at most one PWM period in a row.
    pub current_margin_a: f64,
    /// The true motor-side and rod positions stay inside the stroke widened
    /// by this much.
    pub stroke_margin_m: f64,
    /// The rod's speed after the latch stays below this (a controlled stop
    /// must not let the load run); `None`: not judged.
    pub rod_speed_after_latch_max_m_s: Option<f64>,
    /// After the latch the rod is never faster than it struck an obstacle
    /// (`Outcome::impact_speed_m_s`): it rings on the contact, fed by the
    /// impact and decaying; faster means it is driven or falling.
    pub rod_no_faster_than_impact: bool,
}

/// A named fault scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    pub name: &'static str,
    /// One line: what is injected and what the drive should do.
    pub what: &'static str,
    pub setup: Setup,
    pub injections: Vec<Timed>,
    /// Commands given during the run (motion, and command-level faults).
    pub commands: Vec<CommandAt>,
    pub duration_s: f64,
    /// When the fault starts, if it is a command (NaN reference, jump); by
    /// default the earliest injection window.
    pub fault_at_s: Option<f64>,
    pub expect: Expect,
}

impl Scenario {
    /// When the fault starts: `fault_at_s`, else the earliest injection
    /// window. An obstacle counts from the first contact instead, and a
    /// stuck current sensor from the first period its reading is wrong by
    /// more than the current-sum bound (see `run`): until then it reads what
    /// flows, and nothing can tell it from a working one.
    pub fn fault_start_s(&self) -> Option<f64> {
        self.fault_at_s.or_else(|| {
            self.injections
                .iter()
                .filter(|t| !matches!(t.injection, Injection::Obstacle { .. } | Injection::CurrentStuck { .. }))
                .map(|t| t.window.start_s)
                .reduce(f64::min)
        })
    }
}

/// One PWM period of the record.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct PeriodRecord {
    /// Start of the period.
    pub time_s: f64,
    /// Largest |true phase current| over the period's integration steps.
    pub peak_phase_current_a: f64,
    pub motor_side_position_m: f64,
    pub rod_position_m: f64,
    pub rod_speed_m_s: f64,
    /// Latched after this period's step.
    pub faults: FaultSet,
    pub mode: Mode,
    /// The bridge was driving the motor during this period (the plant's
    /// truth): switching, other than the short circuit below.
    pub bridge_on: bool,
    /// All three low sides on (active short circuit after a bridge-off
    /// fault, while the brake closes): braking, not driving.
    pub short_circuit: bool,
}

/// A command and what the drive answered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandRecord {
    pub at_s: f64,
    pub command: Command,
    pub result: Result<CommandOutcome, CommandError>,
}

/// Everything measured in one run.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub name: &'static str,
    pub pwm_period_s: f64,
    /// Limit the current is judged against (`limits.current_max_a`).
    pub current_limit_a: f64,
    pub stroke_m: (f64, f64),
    /// First period that carried the fault.
    pub fault_period: Option<u64>,
    /// First period after which a fault was latched.
    pub latch_period: Option<u64>,
    /// The bits latched in that period.
    pub first_faults: FaultSet,
    /// Faults latched before the fault was injected (a broken scenario).
    pub faults_before_fault: FaultSet,
    /// Mode right after the first latch.
    pub reaction: Option<Mode>,
    /// First period after the latch in which the bridge was really off.
    pub bridge_off_period: Option<u64>,
    pub final_faults: FaultSet,
    /// Every bit latched at some point of the run (a clear does not remove
    /// it from here).
    pub seen_faults: FaultSet,
    pub final_mode: Mode,
    /// Largest true phase current over the run, and from the fault on.
    pub peak_current_a: f64,
    pub peak_current_after_fault_a: f64,
    /// Longest run of consecutive periods with the true current above
    /// `current_limit_a + margin`, for each margin asked in `runs_over`.
    pub current_trace: Vec<f64>,
    pub motor_side_range_m: (f64, f64),
    pub rod_range_m: (f64, f64),
    /// Motor-side travel from the latch to the end of the run.
    pub travel_after_latch_m: Option<f64>,
    /// Largest rod speed after the latch.
    pub rod_speed_after_latch_max_m_s: Option<f64>,
    /// The rod's speed when it first touched an obstacle.
    pub impact_speed_m_s: Option<f64>,
    pub rod_speed_end_m_s: f64,
    /// First non-finite value found (where, which period).
    pub non_finite: Option<(u64, String)>,
    /// Duties returned by the core outside [0, 1] (or NaN).
    pub duty_out_of_range: u64,
    /// Limit flags seen in any telemetry record.
    pub limits_seen: LimitFlags,
    /// The board's comparator break tripped (period).
    pub hardware_ocp_period: Option<u64>,
    /// A watchdog reset happened (period).
    pub watchdog_reset_period: Option<u64>,
    pub commands: Vec<CommandRecord>,
    pub records: Vec<PeriodRecord>,
}

impl Outcome {
    /// PWM periods from the first period that carried the fault to the step
    /// that latched it (0: the same period's step).
    pub fn detection_periods(&self) -> Option<u64> {
        Some(self.latch_period?.saturating_sub(self.fault_period?))
    }

    pub fn detection_s(&self) -> Option<f64> {
        self.detection_periods().map(|n| n as f64 * self.pwm_period_s)
    }

    /// Periods from the fault to the first period the bridge was off.
    pub fn bridge_off_periods(&self) -> Option<u64> {
        Some(self.bridge_off_period?.saturating_sub(self.fault_period?))
    }

    /// Longest run of consecutive periods with |i| above `limit + margin`.
    pub fn longest_run_over(&self, margin_a: f64) -> u64 {
        let bound = self.current_limit_a + margin_a;
        let mut longest = 0;
        let mut run = 0;
        for i in &self.current_trace {
            if *i > bound {
                run += 1;
                longest = longest.max(run);
            } else {
                run = 0;
            }
        }
        longest
    }

    /// How far the true motor-side or rod position went beyond the stroke
    /// (0 if never).
    pub fn stroke_excess_m(&self) -> f64 {
        let (lo, hi) = self.stroke_m;
        let worst_lo = self.motor_side_range_m.0.min(self.rod_range_m.0);
        let worst_hi = self.motor_side_range_m.1.max(self.rod_range_m.1);
        (lo - worst_lo).max(worst_hi - hi).max(0.0)
    }

    /// The rules of `expect` this run broke, in words (empty: all kept).
    pub fn violations(&self, e: &Expect) -> Vec<String> {
        let mut v = vec![];
        if !self.faults_before_fault.is_empty() {
            v.push(format!("faults {} latched before the fault was injected", names(self.faults_before_fault)));
        }
        if e.reaction.is_none() {
            if !self.final_faults.is_empty() || self.latch_period.is_some() {
                v.push(format!("expected to ride through, but {} latched", names(self.first_faults.union(self.final_faults))));
            }
        } else {
            if !self.seen_faults.contains(e.faults) {
                v.push(format!("expected {} latched, got {}", names(e.faults), names(self.seen_faults)));
            }
            match self.detection_periods() {
                Some(n) if n <= e.within_periods => {}
                Some(n) => v.push(format!("latched after {n} periods, bound {}", e.within_periods)),
                None => v.push("no fault latched".into()),
            }
            if self.reaction != e.reaction {
                v.push(format!("reaction {:?}, expected {:?}", self.reaction, e.reaction));
            }
        }
        let run = self.longest_run_over(e.current_margin_a);
        if run > 1 {
            v.push(format!(
                "true phase current above {:.1} A for {run} consecutive periods (peak {:.1} A)",
                self.current_limit_a + e.current_margin_a,
                self.peak_current_a
            ));
        }
        let excess = self.stroke_excess_m();
        if excess > e.stroke_margin_m {
            v.push(format!(
                "stroke exceeded by {:.2} mm (motor side {:.4}..{:.4} m, rod {:.4}..{:.4} m), allowed {:.2} mm",
                excess * 1e3,
                self.motor_side_range_m.0,
                self.motor_side_range_m.1,
                self.rod_range_m.0,
                self.rod_range_m.1,
                e.stroke_margin_m * 1e3
            ));
        }
        if let (Some(bound), Some(v_max)) = (e.rod_speed_after_latch_max_m_s, self.rod_speed_after_latch_max_m_s) {
            if v_max > bound {
                v.push(format!("rod reached {v_max:.3} m/s after the latch, bound {bound} m/s"));
            }
        }
        if e.rod_no_faster_than_impact {
            match (self.impact_speed_m_s, self.rod_speed_after_latch_max_m_s) {
                (Some(impact), Some(v_max)) if v_max > impact => {
                    v.push(format!("rod reached {v_max:.3} m/s after the latch, faster than its {impact:.3} m/s impact"))
                }
                (None, _) => v.push("the rod never touched the obstacle".into()),
                _ => {}
            }
        }
        if let Some((period, what)) = &self.non_finite {
            v.push(format!("non-finite {what} at period {period}"));
        }
        if self.duty_out_of_range > 0 {
            v.push(format!("{} duties outside [0, 1]", self.duty_out_of_range));
        }
        v
    }

    /// Panics with every broken rule (for tests).
    pub fn assert_meets(&self, e: &Expect) {
        let v = self.violations(e);
        assert!(v.is_empty(), "scenario `{}`:\n  {}\n{}", self.name, v.join("\n  "), self.brief());
    }

    /// A short human-readable account.
    pub fn brief(&self) -> String {
        format!(
            "{}: detection {:?} periods, bridge off after {:?} periods, first {} → {:?}, final {} / {:?}, peak {:.1} A \
             (after fault {:.1} A), motor side {:.4}..{:.4} m, rod {:.4}..{:.4} m, travel after latch {:?} m, \
             rod speed end {:.4} m/s, hw OCP {:?}, non-finite {:?}",
            self.name,
            self.detection_periods(),
            self.bridge_off_periods(),
            names(self.first_faults),
            self.reaction,
            names(self.final_faults),
            self.final_mode,
            self.peak_current_a,
            self.peak_current_after_fault_a,
            self.motor_side_range_m.0,
            self.motor_side_range_m.1,
            self.rod_range_m.0,
            self.rod_range_m.1,
            self.travel_after_latch_m,
            self.rod_speed_end_m_s,
            self.hardware_ocp_period,
            self.non_finite,
        )
    }

    /// The answer to the command given at `at_s` (first match).
    pub fn command_result(&self, at_s: f64) -> Option<Result<CommandOutcome, CommandError>> {
        self.commands.iter().find(|c| (c.at_s - at_s).abs() < 1e-9).map(|c| c.result)
    }
}

/// Fault names joined by `|`, "none" if empty.
pub fn names(f: FaultSet) -> String {
    if f.is_empty() {
        return "none".into();
    }
    f.names().collect::<Vec<_>>().join("|")
}

fn first_non_finite_telemetry(t: &Telemetry) -> Option<&'static str> {
    let fields = [
        ("telemetry.time_s", t.time_s),
        ("telemetry.position_reference_m", t.position_reference_m),
        ("telemetry.position_command_m", t.position_command_m),
        ("telemetry.motor_position_m", t.motor_position_m),
        ("telemetry.motor_angle_rad", t.motor_angle_rad),
        ("telemetry.speed_reference_rad_s", t.speed_reference_rad_s),
        ("telemetry.speed_rad_s", t.speed_rad_s),
        ("telemetry.current_d_a", t.current_d_a),
        ("telemetry.current_q_a", t.current_q_a),
        ("telemetry.current_q_reference_a", t.current_q_reference_a),
        ("telemetry.voltage_d_v", t.voltage_d_v),
        ("telemetry.voltage_q_v", t.voltage_q_v),
        ("telemetry.bus_voltage_v", t.bus_voltage_v),
        ("telemetry.load_force_estimate_n", t.load_force_estimate_n),
        ("telemetry.terminal_position_m", t.terminal_position_m.unwrap_or(0.0)),
    ];
    fields.iter().find(|(_, v)| !v.is_finite()).map(|(n, _)| *n)
}

/// Where a non-finite value sits in the core's outputs and state or the
/// plant's state, if anywhere.
fn first_non_finite(cl: &ClosedLoop) -> Option<&'static str> {
    let cmd = cl.pending_command();
    if cmd.duty.iter().any(|d| !d.is_finite()) {
        return Some("duty");
    }
    if let Some(n) = first_non_finite_telemetry(&cl.controller.telemetry()) {
        return Some(n);
    }
    let c = &cl.controller;
    let core = [
        ("controller.motor_position_m", c.motor_position_m()),
        ("controller.speed_rad_s", c.speed_rad_s()),
        ("controller.thermal_level", c.thermal_level()),
    ];
    if let Some((n, _)) = core.iter().find(|(_, v)| !v.is_finite()) {
        return Some(n);
    }
    const STATE: [&str; 8] = [
        "plant.i_d",
        "plant.i_q",
        "plant.theta_m",
        "plant.omega_m",
        "plant.theta_s",
        "plant.omega_s",
        "plant.x_rod",
        "plant.v_rod",
    ];
    cl.plant.state_vector().iter().zip(STATE).find(|(v, _)| !v.is_finite()).map(|(_, n)| n)
}

/// Runs a scenario to its end (a latched fault does not end it: the
/// reaction is part of what is measured).
pub fn run(sc: &Scenario) -> Result<Outcome> {
    let setup = &sc.setup;
    let dt = setup.pwm_period_s();
    let control = setup.control;
    let mut plant = Plant::try_new(setup.plant.clone(), setup.seed).map_err(|e| anyhow!("{}: plant: {e}", sc.name))?;
    let lead = setup.plant.screw.lead_m;
    let theta = (setup.position_m - setup.plant.stroke.initial_position_m) * TAU / lead;
    plant.set_initial_state(theta, setup.tilt_deg.to_radians());
    let mut controller = Controller::try_new(crate::sim::commissioned_control(control, &plant)).map_err(|e| anyhow!("{}: control: {e}", sc.name))?;
    controller
        .command(Command::SetHome { position_m: setup.position_m as f32 })
        .map_err(|e| anyhow!("{}: homing refused: {e:?}", sc.name))?;
    controller.command(Command::Enable).map_err(|e| anyhow!("{}: enable refused: {e:?}", sc.name))?;
    let nominal_bus = setup.plant.inverter.nominal_bus_voltage_v;
    let mut cl = ClosedLoop::new(controller, plant, nominal_bus);
    // Sub-period resolution for the current record, with or without a break.
    cl.set_hardware_break_a(Some(setup.hardware_ocp_a.unwrap_or(f64::INFINITY)));

    let periods = (sc.duration_s / dt).round() as u64;
    let fault_start = sc.fault_start_s();
    let mut corruptor = SensorCorruptor::new(&sc.injections, setup.seed);
    let mut overrun_done = vec![false; sc.injections.len()];
    let mut commands_done = vec![false; sc.commands.len()];
    let hang = sc.injections.iter().find(|t| t.injection == Injection::CoreHang).map(|t| t.window);
    let mut watchdog_reset_period = None;
    let mut open_phase = None;
    let mut out = Outcome {
        name: sc.name,
        pwm_period_s: dt,
        current_limit_a: f64::from(control.limits.current_max_a),
        stroke_m: (f64::from(control.limits.stroke_min_m), f64::from(control.limits.stroke_max_m)),
        fault_period: None,
        latch_period: None,
        first_faults: FaultSet::NONE,
        faults_before_fault: FaultSet::NONE,
        reaction: None,
        bridge_off_period: None,
        final_faults: FaultSet::NONE,
        seen_faults: FaultSet::NONE,
        final_mode: Mode::Disabled,
        peak_current_a: 0.0,
        peak_current_after_fault_a: 0.0,
        current_trace: Vec::with_capacity(periods as usize),
        motor_side_range_m: (f64::INFINITY, f64::NEG_INFINITY),
        rod_range_m: (f64::INFINITY, f64::NEG_INFINITY),
        travel_after_latch_m: None,
        rod_speed_after_latch_max_m_s: None,
        impact_speed_m_s: None,
        rod_speed_end_m_s: 0.0,
        non_finite: None,
        duty_out_of_range: 0,
        limits_seen: LimitFlags::NONE,
        hardware_ocp_period: None,
        watchdog_reset_period: None,
        commands: vec![],
        records: Vec::with_capacity(periods as usize),
    };
    let mut latch_position = None;

    for n in 0..periods {
        let t = n as f64 * dt;
        if fault_start.is_some_and(|s| t + 0.5 * dt >= s) && out.fault_period.is_none() {
            out.fault_period = Some(n);
        }

        // Plant-level injections.
        let mut bus = nominal_bus;
        let mut force = 0.0;
        let mut open = None;
        for (k, timed) in sc.injections.iter().enumerate() {
            if !timed.window.contains(t, dt) {
                continue;
            }
            match timed.injection {
                Injection::BusVoltage { volts } => bus = volts,
                Injection::ExternalForce { newtons } => force += newtons,
                Injection::Obstacle { position_m, stiffness_n_m } => {
                    let penetration = cl.plant.state().x_rod_m - position_m;
                    if penetration > 0.0 {
                        force += stiffness_n_m * penetration;
                        if out.fault_period.is_none() {
                            out.fault_period = Some(n);
                        }
                        if out.impact_speed_m_s.is_none() {
                            out.impact_speed_m_s = Some(cl.plant.state().v_rod_m_s.abs());
                        }
                    }
                }
                Injection::OpenPhase { phase } => open = Some(phase),
                Injection::IsrOverrun if !overrun_done[k] => {
                    overrun_done[k] = true;
                    cl.controller.report_isr_overrun();
                }
                _ => {}
            }
        }
        // A sensor stuck at a value is a fault once the phase's true
        // current leaves that value by more than the noise bound of the
        // three-phase sum (`faults.current_sum_max_a`): the sum is the
        // only witness, and it is the stuck phase's error.
        if out.fault_period.is_none() && sc.fault_at_s.is_none() {
            let truth = cl.plant.state().phase_current_a;
            let bound = f64::from(control.faults.current_sum_max_a);
            let wrong = sc.injections.iter().any(|timed| match timed.injection {
                Injection::CurrentStuck { phase, value_a } => {
                    timed.window.contains(t, dt) && (truth[phase] - f64::from(value_a)).abs() > bound
                }
                _ => false,
            });
            if wrong {
                out.fault_period = Some(n);
            }
        }
        let faulty_now = out.fault_period.is_some();
        cl.set_bus_voltage_v(bus);
        cl.plant.set_external_force_n(force);
        if open != open_phase {
            cl.plant.set_open_phase(open);
            open_phase = open;
        }

        // Commands due in this period (thread context, before the step).
        for (k, c) in sc.commands.iter().enumerate() {
            if !commands_done[k] && c.at_s < t + 0.5 * dt {
                commands_done[k] = true;
                let result = cl.controller.command(c.command);
                out.commands.push(CommandRecord { at_s: c.at_s, command: c.command, result });
            }
        }

        // The core runs, or the board hangs until the watchdog bites.
        let hung = hang.is_some_and(|w| w.contains(t, dt)) && watchdog_reset_period.is_none();
        if hung {
            let started = hang.map_or(t, |w| w.start_s);
            if t + 0.5 * dt >= started + setup.watchdog_timeout_s {
                // Reset: outputs disabled at once, a fresh controller that
                // knows why it restarted.
                let mut fresh = Controller::new(crate::sim::commissioned_control(control, &cl.plant));
                fresh.report_watchdog_reset();
                cl.controller = fresh;
                cl.override_pending(PwmCommand::OFF);
                watchdog_reset_period = Some(n);
                cl.step();
            } else {
                cl.step_without_core();
            }
        } else {
            let injections = &sc.injections;
            cl.step_with(|s| corruptor.apply(injections, t, dt, s));
        }
        let cmd = *cl.pending_command();
        if cmd.duty.iter().any(|d| !(0.0..=1.0).contains(d)) {
            out.duty_out_of_range += 1;
        }

        let state = cl.plant.state().clone();
        let peak = cl.period_peak_current_a();

        let faults = cl.controller.faults();
        out.seen_faults.insert(faults);
        let mode = cl.controller.mode();
        if !faults.is_empty() && out.latch_period.is_none() {
            if out.fault_period.is_none() {
                out.faults_before_fault = faults;
            }
            out.latch_period = Some(n);
            out.first_faults = faults;
            out.reaction = Some(mode);
            latch_position = Some(state.motor_side_position_m);
        }
        let short_circuit = matches!(cl.plant.drive(), crate::plant::Drive::Pwm(d) if d == [0.0; 3]);
        let bridge_on = state.inverter_enabled && !short_circuit;
        if out.latch_period.is_some() && out.bridge_off_period.is_none() && !bridge_on {
            out.bridge_off_period = Some(n);
        }
        out.peak_current_a = out.peak_current_a.max(peak);
        if faulty_now {
            out.peak_current_after_fault_a = out.peak_current_after_fault_a.max(peak);
        }
        out.current_trace.push(peak);
        let xm = state.motor_side_position_m;
        let xr = state.x_rod_m;
        out.motor_side_range_m = (out.motor_side_range_m.0.min(xm), out.motor_side_range_m.1.max(xm));
        out.rod_range_m = (out.rod_range_m.0.min(xr), out.rod_range_m.1.max(xr));
        if out.latch_period.is_some() {
            let v = state.v_rod_m_s.abs();
            out.rod_speed_after_latch_max_m_s = Some(out.rod_speed_after_latch_max_m_s.map_or(v, |m| m.max(v)));
        }
        out.limits_seen.insert(cl.controller.telemetry().limits);
        if out.non_finite.is_none() {
            if let Some(what) = first_non_finite(&cl) {
                out.non_finite = Some((n, what.to_string()));
            }
        }
        out.records.push(PeriodRecord {
            time_s: t,
            peak_phase_current_a: peak,
            motor_side_position_m: xm,
            rod_position_m: xr,
            rod_speed_m_s: state.v_rod_m_s,
            faults,
            mode,
            bridge_on,
            short_circuit,
        });
    }
    let state = cl.plant.state();
    out.final_faults = cl.controller.faults();
    out.final_mode = cl.controller.mode();
    out.rod_speed_end_m_s = state.v_rod_m_s;
    out.travel_after_latch_m = latch_position.map(|x0| state.motor_side_position_m - x0);
    out.hardware_ocp_period = cl.hardware_break_period();
    out.watchdog_reset_period = watchdog_reset_period;
    Ok(out)
}
