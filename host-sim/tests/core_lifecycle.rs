//! The lifecycle's rules in the core alone: what is refused before which
//! step, `SetHome` leaves the commutation alone, nothing moves at power-up.

use servo_core::{Command, CommandError, ControlParams, Controller, Mode, PwmCommand, Readiness, SensorSample};

fn sample(count: u16) -> SensorSample {
    SensorSample { encoder_count: count, ..SensorSample::idle(48.0) }
}

#[test]
fn set_home_moves_the_user_frame_not_the_electrical_angle() {
    // A SetHome that shifted the count the angle is
    // taken from: homing to 0.1234 m turned it by ≈ 259° electrical.
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    for k in 0..100u16 {
        c.step(&sample(1000 + k));
    }
    // Let the tracking observer settle on the last count.
    for _ in 0..4000 {
        c.step(&sample(1099));
    }
    let before = c.electrical_angle_rad();
    for home in [0.1234f32, -0.37, 0.0, 0.499_9] {
        c.command(Command::SetHome { position_m: home }).unwrap();
        c.step(&sample(1099));
        let after = c.electrical_angle_rad();
        assert!((after - before).abs() < 1e-4, "SetHome {home}: angle {before} -> {after}");
        assert!((c.motor_position_m() - home).abs() < 1e-6, "SetHome {home}: position {}", c.motor_position_m());
    }
}

#[test]
fn each_step_is_refused_until_the_one_before_is_done() {
    let mut c = Controller::new(ControlParams::DEFAULT);
    c.step(&sample(0));
    assert_eq!(c.readiness(), Readiness::NONE);
    assert_eq!(c.command(Command::Enable), Err(CommandError::NotCommutated));
    assert_eq!(c.command(Command::Align), Err(CommandError::NotCalibrated));
    assert_eq!(c.command(Command::Home), Err(CommandError::NotCommutated));
    assert_eq!(c.command(Command::MoveTo { position_m: 0.1 }), Err(CommandError::NotCommutated));
    assert_eq!(c.command(Command::Jog { distance_m: 0.001 }), Err(CommandError::NotCommutated));
    // Commutated but not homed: enable and jog, no planned move.
    let mut p = ControlParams::DEFAULT;
    p.startup.commutation_known = true;
    let mut c = Controller::new(p);
    c.step(&sample(0));
    c.command(Command::Enable).unwrap();
    assert_eq!(c.command(Command::MoveTo { position_m: 0.1 }), Err(CommandError::NotHomed));
    assert!(c.command(Command::Jog { distance_m: 0.001 }).is_ok());
}

#[test]
fn nothing_moves_at_power_up_unless_configured() {
    let mut c = Controller::new(ControlParams::DEFAULT);
    c.power_up().unwrap();
    for k in 0..20_000u32 {
        let out = c.step(&sample(0));
        assert_eq!(out, PwmCommand::OFF, "period {k}: the bridge or the brake moved");
    }
    assert_eq!(c.mode(), Mode::Disabled);
    let mut p = ControlParams::DEFAULT;
    p.startup.run_at_power_up = true;
    let mut c = Controller::new(p);
    c.power_up().unwrap();
    c.step(&sample(0));
    assert_eq!(c.mode(), Mode::Calibrating, "run_at_power_up starts with the offsets, bridge off");
}

#[test]
fn an_encoder_fault_forgets_the_commutation_of_an_incremental_encoder() {
    let mut p = ControlParams::DEFAULT;
    p.startup.commutation_known = false;
    let mut c = Controller::new(p);
    // A drive that was commutated and homed earlier in this power cycle.
    c.step(&sample(0));
    assert!(c.command(Command::SetHome { position_m: 0.1 }).is_ok());
    c.step(&sample(0));
    c.step(&sample(30_000)); // a jump no motor makes in 50 µs
    assert!(!c.faults().is_empty());
    assert!(!c.readiness().contains(Readiness::COMMUTATED) && !c.readiness().contains(Readiness::HOMED));
}

/// A rotor resting on an encoder count edge toggles between two counts as
/// the current ripple shakes it by micro-radians: the speed estimate reads
/// one count per position period (above the settle speed), yet the rotor is
/// still. Commutation must settle and start its sweep, not time out; a
/// rotor that really moves (two counts a period) must not settle.
#[test]
fn commutation_settles_on_a_rotor_toggling_between_two_counts() {
    use servo_core::lifecycle::{Commutation, CommutationInput};
    let p = ControlParams::DEFAULT;
    let dt = p.position_period_s();
    let run = |step_counts: f32| {
        let mut c = Commutation::new();
        let ticks = ((p.commutation.ramp_s + p.commutation.settle_timeout_s) / dt) as usize + 10;
        for k in 0..ticks {
            // Before the ramp ends the rotor rests; then it toggles (or walks).
            let (x, v) = match k % 2 {
                0 => (0.0, -step_counts / dt),
                _ => (step_counts, step_counts / dt),
            };
            let x = if step_counts > 1.0 { step_counts * k as f32 } else { x };
            let v = if step_counts > 1.0 { step_counts / dt } else { v };
            let input = CommutationInput { position_counts: x, counts_in_turn: x, speed_counts_s: v, load_hint_q_a: 0.0 };
            let out = c.update(&p, &input, dt);
            if out.angle_rad != 0.0 {
                return Ok(k);
            }
            if let Some(done) = out.done {
                return Err(format!("{done:?} at tick {k}"));
            }
        }
        Err("neither swept nor failed".into())
    };
    let toggling = run(1.0);
    assert!(toggling.is_ok(), "a rotor toggling one count never settled: {toggling:?}");
    let moving = run(2.0);
    assert!(moving.is_err(), "a rotor moving two counts a period settled: {moving:?}");
}
