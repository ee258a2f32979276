//! The drive's state machine: faults latch, clear only when their cause has
//! gone, commands are bounded and say so.

use servo_core::{Command, CommandError, CommandOutcome, ControlParams, Controller, FaultSet, LimitFlags, Mode, SensorSample};

fn nominal() -> SensorSample {
    SensorSample::idle(48.0)
}

#[test]
fn default_params_validate() {
    assert_eq!(ControlParams::DEFAULT.validate(), Ok(()));
}

#[test]
fn invalid_params_are_named_and_never_enable() {
    let mut p = ControlParams::DEFAULT;
    p.speed_pi.kp = -1.0;
    let e = Controller::try_new(p).unwrap_err();
    assert_eq!(e.field(), "control.speed_pi.kp");
    let mut c = Controller::new(p.commissioned());
    assert!(c.faults().contains(FaultSet::INVALID_PARAMS));
    assert!(matches!(c.command(Command::Enable), Err(CommandError::Faulted(_))));
    assert!(matches!(c.command(Command::ClearFaults), Err(CommandError::CauseStillPresent(_))));
    assert!(!c.step(&nominal()).enable);
}

#[test]
fn each_bad_field_is_named() {
    let cases: [(&str, fn(&mut ControlParams)); 6] = [
        ("control.motor.phase_resistance_ohm", |p| p.motor.phase_resistance_ohm = 0.0),
        ("control.limits.current_max_a", |p| p.limits.current_max_a = f32::NAN),
        ("control.limits.stroke_max_m", |p| p.limits.stroke_max_m = -0.1),
        ("control.rates.speed_loop_divider", |p| p.rates.speed_loop_divider = 0),
        ("control.faults.overcurrent_trip_a", |p| p.faults.overcurrent_trip_a = 10.0),
        ("control.encoder.direction", |p| p.encoder.direction = 2),
    ];
    for (field, spoil) in cases {
        let mut p = ControlParams::DEFAULT;
        spoil(&mut p);
        assert_eq!(p.validate().unwrap_err().field(), field);
    }
}

#[test]
fn nan_current_latches_and_turns_the_bridge_off_until_cleared() {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    c.command(Command::Enable).unwrap();
    assert!(c.step(&nominal()).enable);
    let mut bad = nominal();
    bad.phase_current_a[1] = f32::NAN;
    let out = c.step(&bad);
    assert!(!out.enable);
    assert!(out.duty.iter().all(|d| d.is_finite()));
    assert!(c.faults().contains(FaultSet::NON_FINITE_INPUT));
    // Still bad: clearing is refused.
    c.step(&bad);
    assert!(matches!(c.command(Command::ClearFaults), Err(CommandError::CauseStillPresent(_))));
    // Cause gone: stays latched until the explicit clear.
    for _ in 0..10 {
        assert!(!c.step(&nominal()).enable);
    }
    assert_eq!(c.mode(), Mode::Fault);
    c.command(Command::ClearFaults).unwrap();
    assert_eq!(c.mode(), Mode::Disabled);
    c.command(Command::Enable).unwrap();
    assert!(c.step(&nominal()).enable);
}

#[test]
fn overcurrent_and_bus_faults_latch() {
    let p = ControlParams::DEFAULT;
    let cases: [(SensorSample, FaultSet); 3] = [
        (SensorSample { phase_current_a: [p.faults.overcurrent_trip_a + 1.0, 0.0, 0.0], ..nominal() }, FaultSet::OVERCURRENT),
        (SensorSample { bus_voltage_v: p.faults.bus_overvoltage_v + 1.0, ..nominal() }, FaultSet::BUS_OVERVOLTAGE),
        (SensorSample { bus_voltage_v: p.faults.bus_undervoltage_v - 1.0, ..nominal() }, FaultSet::BUS_UNDERVOLTAGE),
    ];
    for (sample, fault) in cases {
        let mut c = Controller::new(p.commissioned());
        c.command(Command::Enable).unwrap();
        c.step(&nominal());
        let out = c.step(&sample);
        assert!(c.faults().contains(fault));
        if fault == FaultSet::OVERCURRENT {
            assert!(!out.enable, "{fault:?}: all switches must open");
        } else {
            // The bus faults short the winding (all low sides on) while the
            // brake closes, then open everything.
            assert!(out.enable && out.duty == [0.0; 3], "{fault:?}: {out:?}");
            assert!(!out.brake_release, "{fault:?}: brake not applied");
        }
        let engage_periods = (p.brake.engage_time_s * p.rates.pwm_frequency_hz).ceil() as usize;
        for _ in 0..engage_periods {
            c.step(&sample);
        }
        assert!(!c.step(&sample).enable, "{fault:?}: still switching after the brake closed");
    }
}

#[test]
fn move_outside_the_stroke_is_clamped_and_reported() {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    c.command(Command::Enable).unwrap();
    c.step(&nominal());
    let out = c.command(Command::MoveTo { position_m: 0.8 }).unwrap();
    assert_eq!(out, CommandOutcome::ClampedToStroke { position_m: 0.5 });
    for _ in 0..20 {
        c.step(&nominal());
    }
    assert!(c.telemetry().limits.contains(LimitFlags::STROKE));
    assert!(matches!(c.command(Command::MoveTo { position_m: 0.1 }), Err(CommandError::Busy)));
    assert!(matches!(c.command(Command::MoveTo { position_m: f32::NAN }), Err(CommandError::NotFinite)));
}

#[test]
fn telemetry_is_cut_at_the_position_rate() {
    let p = ControlParams::DEFAULT;
    let mut c = Controller::new(p.commissioned());
    for _ in 0..p.rates.position_loop_divider * 3 {
        c.step(&nominal());
    }
    let t = c.telemetry().time_s;
    assert!((t - 3.0 * p.position_period_s()).abs() < 1e-7, "{t}");
}
