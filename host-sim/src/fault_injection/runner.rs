//! Runs one fault scenario closed-loop (plant + the firmware's control core)
//! and records, every PWM period, what a safety case needs: the true peak
//! phase current, the true motor-side and rod positions, the latched faults,
//! the mode, whether the bridge was on, and any non-finite value anywhere.

use super::injection::{Injection, SensorCorruptor};
use super::scenario::Scenario;
use super::outcome::{PeriodRecord, CommandRecord, Outcome};
use crate::plant::Plant;
use crate::sim::ClosedLoop;
use anyhow::anyhow;
use anyhow::Result;
use std::f64::consts::TAU;
use servo_core::{Command, Controller, FaultSet, LimitFlags, Mode, PwmCommand, Telemetry};

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
