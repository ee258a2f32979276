//! One power-up, closed loop: the real core against the full plant.

use super::cases::{Failure, PowerUpCase};
use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::ClosedLoop;
use anyhow::{anyhow, Result};
use servo_core::params::HomingMethod;
use servo_core::{Command, Controller, FaultSet, Mode, Readiness};
use std::f64::consts::PI;

/// The drive sits with the bridge off this long before it is asked to
/// start: the load settles onto the brake.
const IDLE_BEFORE_START_S: f64 = 0.2;
/// A start-up that is neither ready nor failed by then is a hang.
const START_UP_BOUND_S: f64 = 90.0;
/// After a failure the run goes on this long: the end state must hold.
const AFTER_FAILURE_S: f64 = 0.3;
/// Ready, then held this long before the `Disable` / `Enable` sag test.
const HOLD_BEFORE_SAG_TEST_S: f64 = 0.3;
/// The brake closes and the bridge goes off within this (engage + margin).
const DISABLED_BEFORE_ENABLE_S: f64 = 0.3;
/// The sag is the largest rod excursion this long after `Enable`.
const SAG_WINDOW_S: f64 = 0.5;
/// Failure cases that home: a travel bound short enough to keep the run
/// short (the user's value; the stroke's 0.53 m works the same, slower).
const FAILURE_HOMING_TRAVEL_M: f32 = 0.1;

/// What one power-up showed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseResult {
    pub name: String,
    pub failure: Failure,
    pub passed: bool,
    /// Why not, in words, when it did not pass.
    pub verdict: String,
    pub faults: Vec<&'static str>,
    /// Largest rod excursion from rest during calibration and commutation
    /// (homing moves the rod on purpose).
    pub rod_movement_max_mm: f64,
    /// Largest fall of the rod below where it was when the fault was
    /// raised (failure cases), or below the start.
    pub rod_drop_max_mm: f64,
    pub electrical_offset_error_deg: Option<f64>,
    pub enable_sag_um: Option<f64>,
    /// Over the hold after ready (before the sag test): the peak-to-peak
    /// of the position error (command − motor side) and of the q current.
    /// A quiet hold moves by the encoder's counts and the current by its
    /// noise; a ringing one by tens of micrometres and amperes.
    pub hold_error_pp_um: Option<f64>,
    pub hold_current_pp_a: Option<f64>,
    pub time_to_ready_s: Option<f64>,
    pub bridge_off_at_end: bool,
    pub brake_closed_at_end: bool,
    /// The commutation's own figures: brake-twist amplitude (counts) and the
    /// check rotation measured / expected.
    pub twist_amplitude_counts: f64,
    pub rotation_ratio: f64,
}

/// The rig of `case`, with the drive off and the load on the closed brake.
fn build(rig: &RigConfig, case: &PowerUpCase) -> Result<ClosedLoop> {
    let mut control = rig.control;
    let mut plant_params = rig.plant.clone();
    match case.failure {
        Failure::BlockedRotor => {
            plant_params.brake.release_time_s = 1e6;
            plant_params.brake.holding_torque_n_m = 50.0;
        }
        Failure::WrongPolePairs => control.motor.pole_pairs = plant_params.motor.pole_pairs + 1,
        Failure::BrakeSlips => {
            // Worn to the load's back-drive torque plus half the test
            // torque: it holds the load alone, not the commutation's test
            // (1.4 N·m on the shipped rig).
            let pl = &plant_params;
            let load = pl.moving_mass_kg() * pl.load.gravity_m_s2 * pl.metres_per_rad() * (2.0 - 1.0 / pl.screw.efficiency);
            let test = 1.5 * f64::from(pl.motor.pole_pairs) * pl.motor.flux_linkage_wb * f64::from(control.commutation.test_current_a);
            plant_params.brake.holding_torque_n_m = load + 0.5 * test;
        }
        Failure::HomeSwitchNeverTriggers => {
            control.homing.method = HomingMethod::Switch;
            control.homing.travel_max_m = FAILURE_HOMING_TRAVEL_M;
        }
        Failure::HardStopNeverMet => {
            plant_params.stroke.retracted_stop_m = -2.0;
            control.homing.travel_max_m = FAILURE_HOMING_TRAVEL_M;
        }
        _ => {}
    }
    let controller = Controller::try_new(control).map_err(|e| anyhow!("{}: control: {e}", case.name))?;
    let mut plant = Plant::try_new(plant_params, case.seed).map_err(|e| anyhow!("{}: plant: {e}", case.name))?;
    plant.set_initial_state(case.rotor_angle_rad, PI / 2.0);
    plant.engage_brake();
    let bench = plant.bench_sensors_mut();
    bench.encoder_zero_rad = case.encoder_zero_rad;
    bench.current_offset_a = case.current_offset_a;
    if case.failure == Failure::HomeSwitchNeverTriggers {
        // Wired, but far below anything the rod reaches.
        bench.home_switch = Some((-1.0, -1));
    }
    let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.set_swap_phases_bc(case.failure == Failure::SwappedPhases);
    cl.override_pending(servo_core::PwmCommand::OFF);
    Ok(cl)
}

fn seconds(cl: &ClosedLoop, s: f64) -> u64 {
    (s / f64::from(cl.controller.params().pwm_period_s())).ceil() as u64
}

/// Runs `case` and judges it.
pub fn run_case(rig: &RigConfig, case: &PowerUpCase) -> Result<CaseResult> {
    let mut cl = build(rig, case)?;
    let frozen_count = std::cell::Cell::new(None::<u16>);
    let unplugged = case.failure == Failure::EncoderUnplugged;
    let mut step = |cl: &mut ClosedLoop| {
        cl.step_with(|s| {
            if unplugged {
                // The counter keeps the value it had when the cable came off.
                s.encoder_count = *frozen_count.get().get_or_insert(s.encoder_count);
                frozen_count.set(Some(s.encoder_count));
            }
        });
    };
    cl.controller.power_up().map_err(|e| anyhow!("{}: power_up: {e:?}", case.name))?;
    for _ in 0..seconds(&cl, IDLE_BEFORE_START_S) {
        step(&mut cl);
    }
    let mut stored_offset_rad = None;
    if let Some(error_rad) = case.failure.offset_error_rad() {
        stored_offset_rad = Some(store_wrong_offset(&mut cl, f64::from(rig.plant.motor.pole_pairs), error_rad).map_err(|e| anyhow!("{}: {e}", case.name))?);
    }
    let nominal_bus = rig.plant.inverter.nominal_bus_voltage_v;
    let x0 = cl.plant.state().x_rod_m;
    let t_start = cl.time_s();
    cl.controller.command(Command::StartUp).map_err(|e| anyhow!("{}: StartUp refused: {e:?}", case.name))?;
    let mut movement = 0.0f64;
    let mut homing_seen = false;
    let mut offset_error_deg = None;
    let mut ready_at = None;
    let mut fault_at: Option<(f64, f64)> = None;
    let mut drop = 0.0f64;
    let bound = seconds(&cl, START_UP_BOUND_S);
    let pole_pairs = f64::from(rig.plant.motor.pole_pairs);
    for _ in 0..bound {
        if case.failure == Failure::SupplySagDuringCalibration {
            // 5 V down over the first 50 ms of the average, still above the
            // undervoltage trip: only the calibration can see it.
            let t = cl.time_s() - t_start;
            cl.set_bus_voltage_v(nominal_bus - 5.0 * (t / 0.05).clamp(0.0, 1.0));
        }
        step(&mut cl);
        let c = &cl.controller;
        let x = cl.plant.state().x_rod_m;
        homing_seen |= c.mode() == Mode::Homing;
        if !homing_seen {
            movement = movement.max((x - x0).abs());
        }
        if offset_error_deg.is_none() && c.readiness().contains(Readiness::COMMUTATED) {
            // The angle the drive now uses against the rotor's true one, at
            // the same sampling instant (the counter's zero is arbitrary, so
            // the offset itself has no truth to compare with).
            let truth = pole_pairs * cl.sampled_state().theta_m_rad;
            let e = (f64::from(c.electrical_angle_rad()) - truth).rem_euclid(2.0 * PI);
            offset_error_deg = Some(e.min(2.0 * PI - e).to_degrees());
        }
        if fault_at.is_none() && !c.faults().is_empty() {
            fault_at = Some((cl.time_s(), x));
        }
        // A fall: before homing (which moves the rod down on purpose), or
        // after a fault; for a commutation error no check saw, from the
        // start (the fall before the verdict counts).
        match fault_at {
            _ if case.failure.offset_error_rad().is_some() => drop = drop.max(x0 - x),
            Some((_, xf)) => drop = drop.max(xf - x),
            None if !homing_seen => drop = drop.max(x0 - x),
            None => {}
        }
        if c.faults().is_empty() && c.mode() == Mode::Running && c.readiness() == Readiness::ALL {
            ready_at = Some(cl.time_s() - t_start);
            break;
        }
        if let Some((t, _)) = fault_at {
            if cl.time_s() - t > AFTER_FAILURE_S && matches!(c.mode(), Mode::Fault | Mode::Disabled) {
                break;
            }
        }
    }
    let mut enable_sag_um = None;
    let mut hold = None;
    if ready_at.is_some() {
        hold = Some(hold_spread(&mut cl, &mut step));
        enable_sag_um = Some(enable_sag(&mut cl, &mut step)?);
    }
    let c = &cl.controller;
    let bridge_off = !cl.pending_command().enable;
    let brake_closed = cl.plant.state().brake_engaged;
    let mut result = CaseResult {
        name: case.name.clone(),
        failure: case.failure,
        passed: false,
        verdict: String::new(),
        faults: c.faults().names().collect(),
        rod_movement_max_mm: movement * 1e3,
        rod_drop_max_mm: drop * 1e3,
        electrical_offset_error_deg: offset_error_deg,
        enable_sag_um,
        hold_error_pp_um: hold.map(|h| h.0),
        hold_current_pp_a: hold.map(|h| h.1),
        time_to_ready_s: ready_at,
        bridge_off_at_end: bridge_off,
        brake_closed_at_end: brake_closed,
        twist_amplitude_counts: f64::from(c.commutation_report().twist_amplitude_counts),
        rotation_ratio: f64::from(c.commutation_report().rotation_ratio),
    };
    result.verdict = judge(&result, case.failure.expected_fault(), c.faults());
    // The drive may hold on a corrected angle while the brake closes; the
    // user's stored offset must come back unchanged.
    if let Some(stored) = stored_offset_rad {
        let now = c.params().encoder.electrical_offset_rad;
        if result.verdict == "ok" && now != stored {
            result.verdict = format!("stored offset {stored} rad changed to {now} rad");
        }
    }
    result.passed = result.verdict == "ok";
    Ok(result)
}

/// The drive is told its commutation is known, with an offset `error_rad`
/// (electrical) off the true one: the offset the drive would need is found
/// from the rotor's true angle against the angle the drive computes now.
fn store_wrong_offset(cl: &mut ClosedLoop, pole_pairs: f64, error_rad: f64) -> Result<f32> {
    let truth = pole_pairs * cl.sampled_state().theta_m_rad;
    let believed = f64::from(cl.controller.electrical_angle_rad());
    let mut p = *cl.controller.params();
    let right = f64::from(p.encoder.electrical_offset_rad) + truth - believed;
    p.encoder.electrical_offset_rad = (right + error_rad + PI).rem_euclid(2.0 * PI) as f32 - PI as f32;
    p.startup.commutation_known = true;
    let stored = p.encoder.electrical_offset_rad;
    let p = servo_core::params::ValidatedParams::new(p).map_err(|e| anyhow!("wrong offset refused: {e:?}"))?;
    cl.controller.apply_params(&p).map_err(|e| anyhow!("wrong offset not applied: {e:?}"))?;
    Ok(stored)
}

/// Holds for `HOLD_BEFORE_SAG_TEST_S` after ready: the peak-to-peak of the
/// position error (µm) and of the q current (A) over it.
fn hold_spread(cl: &mut ClosedLoop, step: &mut impl FnMut(&mut ClosedLoop)) -> (f64, f64) {
    let (mut e_lo, mut e_hi, mut i_lo, mut i_hi) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for _ in 0..seconds(cl, HOLD_BEFORE_SAG_TEST_S) {
        step(cl);
        let t = cl.controller.telemetry();
        let e = f64::from(t.position_command_m - t.motor_position_m);
        let i = cl.plant.state().i_q_a;
        (e_lo, e_hi, i_lo, i_hi) = (e_lo.min(e), e_hi.max(e), i_lo.min(i), i_hi.max(i));
    }
    ((e_hi - e_lo) * 1e6, i_hi - i_lo)
}

/// `Disable` (the brake closes under the loops), then `Enable`: the largest
/// rod excursion after `Enable`, micrometres.
fn enable_sag(cl: &mut ClosedLoop, step: &mut impl FnMut(&mut ClosedLoop)) -> Result<f64> {
    cl.controller.command(Command::Disable).map_err(|e| anyhow!("Disable refused: {e:?}"))?;
    for _ in 0..seconds(cl, DISABLED_BEFORE_ENABLE_S) {
        step(cl);
    }
    if cl.controller.mode() != Mode::Disabled {
        anyhow::bail!("Disable ended in {:?}", cl.controller.mode());
    }
    let before = cl.plant.state().x_rod_m;
    cl.controller.command(Command::Enable).map_err(|e| anyhow!("Enable refused: {e:?}"))?;
    let mut sag = 0.0f64;
    for _ in 0..seconds(cl, SAG_WINDOW_S) {
        step(cl);
        sag = sag.max((cl.plant.state().x_rod_m - before).abs());
    }
    Ok(sag * 1e6)
}

/// The bars for one case; "ok" or the first that is missed.
fn judge(r: &CaseResult, expected: Option<FaultSet>, faults: FaultSet) -> String {
    match expected {
        None => {
            if r.time_to_ready_s.is_none() {
                return format!("never ready; faults {:?}", r.faults);
            }
            if r.rod_movement_max_mm > 0.1 {
                return format!("rod moved {:.3} mm during power-up (> 0.1)", r.rod_movement_max_mm);
            }
            if r.electrical_offset_error_deg.is_none_or(|e| e > 5.0) {
                return format!("offset error {:?}° (> 5)", r.electrical_offset_error_deg);
            }
            if r.enable_sag_um.is_none_or(|s| s > 10.0) {
                return format!("enable sag {:?} µm (> 10)", r.enable_sag_um);
            }
            // A good Disable / Enable must not be taken for a fault.
            if !faults.is_empty() || r.bridge_off_at_end {
                return format!("after Disable / Enable: faults {:?}, bridge off {}", r.faults, r.bridge_off_at_end);
            }
            "ok".into()
        }
        Some(f) => {
            if r.time_to_ready_s.is_some() {
                return "became ready despite the fault".into();
            }
            if !faults.contains(f) {
                return format!("expected {}, latched {:?}", crate::fault_injection::names(f), r.faults);
            }
            if !r.bridge_off_at_end || !r.brake_closed_at_end {
                return format!("end state: bridge off {}, brake closed {}", r.bridge_off_at_end, r.brake_closed_at_end);
            }
            if r.rod_drop_max_mm > 0.5 {
                return format!("rod dropped {:.3} mm (> 0.5)", r.rod_drop_max_mm);
            }
            "ok".into()
        }
    }
}

/// Homes `homings` times on one rig (started up from `case`) and returns
/// the physical position of user zero after each, metres.
pub fn homing_repeatability(rig: &RigConfig, case: &PowerUpCase, homings: usize) -> Result<Vec<f64>> {
    let mut cl = build(rig, case)?;
    cl.controller.command(Command::StartUp).map_err(|e| anyhow!("StartUp refused: {e:?}"))?;
    let ready = |cl: &ClosedLoop| {
        cl.controller.mode() == Mode::Running && cl.controller.readiness() == Readiness::ALL && !cl.controller.move_in_progress()
    };
    let mut zeros = Vec::with_capacity(homings);
    for k in 0..=homings {
        if k > 0 {
            cl.controller.command(Command::Home).map_err(|e| anyhow!("homing {k}: Home refused: {e:?}"))?;
            // Homing starts this period; `ready` is false until it ends.
            cl.step();
        }
        let mut steps = 0u64;
        while !ready(&cl) {
            cl.step();
            steps += 1;
            if steps > seconds(&cl, START_UP_BOUND_S) || !cl.controller.faults().is_empty() {
                anyhow::bail!("homing {k}: not ready; faults {}", crate::fault_injection::names(cl.controller.faults()));
            }
        }
        for _ in 0..seconds(&cl, 0.2) {
            cl.step();
        }
        if k > 0 {
            // Where user zero lies on the motor side: truth minus belief.
            let truth = cl.sampled_state().motor_side_position_m;
            zeros.push(truth - f64::from(cl.controller.motor_position_m()));
        }
    }
    Ok(zeros)
}
