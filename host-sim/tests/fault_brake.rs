//! The holding brake, closed loop: `Disable` hands a vertical load to the
//! brake before switching off, a move waits for the brake to open, the
//! comparator break latches `BRIDGE_BREAK` and the brake catches the load;
//! and the open-phase check against hand-made phase currents.

use std::f64::consts::{FRAC_PI_2, TAU};

use host_sim::config::RigConfig;
use host_sim::plant::Plant;
use host_sim::sim::ClosedLoop;
use servo_core::params::FaultParams;
use servo_core::protection::OpenPhaseMonitor;
use servo_core::{Command, ControlParams, Controller, FaultSet, Mode};

/// Vertical rated load at 250 mm, drive enabled and settled.
fn holding_at_250_mm(rig: &RigConfig) -> ClosedLoop {
    let mut plant = Plant::new(rig.plant.clone(), 1);
    plant.set_initial_state(0.25 * TAU / rig.plant.screw.lead_m, FRAC_PI_2);
    let mut c = Controller::try_new(rig.control.commissioned()).unwrap();
    c.command(Command::SetHome { position_m: 0.25 }).unwrap();
    let mut cl = ClosedLoop::new(c, plant, 48.0);
    cl.controller.command(Command::Enable).unwrap();
    for _ in 0..10_000 {
        cl.step();
    }
    assert_eq!(cl.controller.mode(), Mode::Running);
    cl
}

fn seconds(cl: &ClosedLoop, s: f64) -> u64 {
    (s / (1.0 / f64::from(cl.controller.params().rates.pwm_frequency_hz))).round() as u64
}

#[test]
fn disable_lets_the_brake_close_under_the_loops_then_switches_off() {
    let rig = RigConfig::nominal().unwrap();
    let mut cl = holding_at_250_mm(&rig);
    let x0 = cl.plant.state().x_rod_m;
    cl.controller.command(Command::Disable).unwrap();
    assert_eq!(cl.controller.mode(), Mode::Braking);
    let engage = f64::from(rig.control.brake.engage_time_s);
    let mut bridge_off_at = None;
    let mut brake_at = None;
    for k in 0..seconds(&cl, 0.5) {
        cl.step();
        if brake_at.is_none() && cl.plant.state().brake_engaged {
            brake_at = Some(k);
        }
        if bridge_off_at.is_none() && !cl.pending_command().enable {
            bridge_off_at = Some(k);
        }
    }
    let (brake_at, off_at) = (brake_at.expect("brake engaged"), bridge_off_at.expect("bridge off"));
    // The plant's brake closes after its own 25 ms; the drive waits its
    // believed 30 ms before switching off, so the brake holds first.
    assert!(brake_at < off_at, "brake at period {brake_at}, bridge off at {off_at}");
    assert!(off_at >= seconds(&cl, engage), "bridge off after {off_at} periods");
    assert_eq!(cl.controller.mode(), Mode::Disabled);
    let drop = x0 - cl.plant.state().x_rod_m;
    // Only the disc's compliance under the load torque (≈5 µm at the motor
    // side) and the rod's relaxation: nothing like a fall.
    assert!(drop.abs() < 50e-6, "rod moved {drop} m");
}

#[test]
fn a_move_waits_for_the_brake_to_open() {
    let rig = RigConfig::nominal().unwrap();
    let mut cl = holding_at_250_mm(&rig);
    cl.controller.command(Command::Disable).unwrap();
    for _ in 0..seconds(&cl, 0.2) {
        cl.step();
    }
    assert!(cl.plant.state().brake_engaged);
    cl.controller.command(Command::Enable).unwrap();
    cl.controller.command(Command::MoveTo { position_m: 0.3 }).unwrap();
    // The hold current builds for the preload time with the brake closed,
    // then the brake needs its release time.
    let release = f64::from(rig.control.brake.preload_time_s + rig.control.brake.release_time_s);
    let mut first_motion = None;
    let mut start = None;
    for k in 0..seconds(&cl, 0.3) {
        let t = cl.step();
        let x0 = *start.get_or_insert(t.position_reference_m);
        if first_motion.is_none() && t.position_reference_m > x0 + 1e-6 {
            first_motion = Some(k);
        }
    }
    let k = first_motion.expect("the move started");
    assert!(k >= seconds(&cl, release), "reference moved after {k} periods, before the brake opened");
    // The S-curve needs (6 µm/j)^(1/3) = 6.2 ms to cover 1 µm at 25 m/s³.
    assert!(k <= seconds(&cl, release + 0.0062) + 40, "reference moved only after {k} periods");
    assert!(!cl.plant.state().brake_engaged);
}

#[test]
fn a_comparator_trip_latches_bridge_break_and_the_brake_holds_the_load() {
    let rig = RigConfig::nominal().unwrap();
    let mut cl = holding_at_250_mm(&rig);
    // A comparator set below the holding current: it trips at once.
    cl.set_hardware_break_a(Some(5.0));
    let x0 = cl.plant.state().x_rod_m;
    let mut latched_at = None;
    for k in 0..seconds(&cl, 0.5) {
        cl.step();
        if latched_at.is_none() && cl.controller.faults().contains(FaultSet::BRIDGE_BREAK) {
            latched_at = Some(k);
        }
    }
    let trip = cl.hardware_break_period().expect("the comparator tripped");
    let latched = latched_at.expect("BRIDGE_BREAK latched");
    assert!(latched <= trip + 1, "latched at {latched}, trip at {trip}");
    assert_eq!(cl.controller.mode(), Mode::Fault);
    assert!(!cl.pending_command().brake_release);
    assert!(cl.plant.state().brake_engaged);
    // The rod fell during the brake's 25 ms engage time only (< g t²/2 = 3 mm).
    let drop = x0 - cl.plant.state().x_rod_m;
    assert!(drop > 0.0 && drop < 3.1e-3, "dropped {drop} m");
}

fn faults() -> FaultParams {
    ControlParams::DEFAULT.faults
}

/// Balanced three-phase currents of amplitude `i` at electrical angle `θ`.
fn abc(i: f32, theta: f32) -> [f32; 3] {
    let third = core::f32::consts::TAU / 3.0;
    [i * theta.cos(), i * (theta - third).cos(), i * (theta + third).cos()]
}

#[test]
fn open_phase_monitor_judges_only_windows_with_enough_demand() {
    let f = faults();
    let n = 10;
    // Rotating 10 A vector, measured equals reference: healthy.
    let mut m = OpenPhaseMonitor::new();
    let mut verdict = None;
    for k in 0..n {
        verdict = m.update(&f, n, abc(10.0, 0.3 * k as f32), abc(10.0, 0.3 * k as f32));
        if k < n - 1 {
            assert_eq!(verdict, None, "verdict mid-window");
        }
    }
    assert_eq!(verdict, Some(false));
    // Phase b open: it carries nothing, a and c carry ± the same.
    let mut verdict = None;
    for k in 0..n {
        let r = abc(10.0, 0.3 * k as f32);
        verdict = m.update(&f, n, r, [r[0], 0.0, -r[0]]);
    }
    assert_eq!(verdict, Some(true));
    // At standstill with the vector along b–c, phase a is asked for nothing
    // (cos 90° = 0) and carries nothing: no demand, no verdict on it; b and
    // c carry what they are asked: healthy.
    let theta = core::f32::consts::FRAC_PI_2;
    let mut verdict = None;
    for _ in 0..n {
        verdict = m.update(&f, n, abc(10.0, theta), abc(10.0, theta));
    }
    assert_eq!(verdict, Some(false));
    // Below the demand threshold (0.3 A vector, mean |i| < 1 A): no verdict.
    let mut verdict = Some(true);
    for k in 0..n {
        verdict = m.update(&f, n, abc(0.3, 0.3 * k as f32), [0.0; 3]);
    }
    assert_eq!(verdict, None);
    // Just above the threshold (a light payload's 2 A vector) an empty
    // phase b is seen...
    let mut verdict = None;
    for k in 0..n {
        let r = abc(2.0, 0.3 * k as f32);
        verdict = m.update(&f, n, r, [r[0], 0.0, -r[0]]);
    }
    assert_eq!(verdict, Some(true));
    // ...while a phase that carries a real share of a large demand (a
    // tenth of 10 A: a lagging loop, a slipping frame) is not empty.
    let mut verdict = None;
    for k in 0..n {
        let r = abc(10.0, 0.3 * k as f32);
        verdict = m.update(&f, n, r, [r[0], 0.1 * r[1], r[2]]);
    }
    assert_eq!(verdict, Some(false));
}

/// A bridge-off fault while holding the vertical rated load: until the brake
/// closes (25 ms) the rod is free. Where the power stage is trusted (a bus
/// sag) the drive shorts the winding meanwhile and the load sinks at the
/// short-circuit speed (≈12 mm/s, closed form in fault_power.rs): a few
/// tenths of a millimetre. Where it is not (a NaN current sample: nothing
/// bounds the current) all switches open and the load falls ≈3 mm.
#[test]
fn short_circuit_braking_bridges_the_brake_engage_time() {
    let rig = RigConfig::nominal().unwrap();
    let drop_after = |inject: &dyn Fn(&mut servo_core::SensorSample)| {
        let mut cl = holding_at_250_mm(&rig);
        let x0 = cl.plant.state().x_rod_m;
        let mut min_x = x0;
        for k in 0..seconds(&cl, 0.3) {
            if k < 3 {
                cl.step_with(inject);
            } else {
                cl.step();
            }
            min_x = min_x.min(cl.plant.state().x_rod_m);
        }
        assert_eq!(cl.controller.mode(), Mode::Fault);
        assert!(cl.plant.state().brake_engaged);
        x0 - min_x
    };
    let with_short = drop_after(&|s| s.bus_voltage_v = 30.0);
    let without = drop_after(&|s| s.phase_current_a[0] = f32::NAN);
    println!("drop while the brake closes: {:.3} mm shorted, {:.3} mm open", with_short * 1e3, without * 1e3);
    assert!(with_short < 0.6e-3, "drop with short-circuit braking {with_short} m");
    assert!(without > 2.0e-3, "drop with all switches open {without} m");
}
