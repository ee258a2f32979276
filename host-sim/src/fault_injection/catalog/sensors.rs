//! Sensor faults: current and bus samples, and the encoder.

use super::*;

/// The encoder stops while the drive holds the rated vertical load at rest,
/// and the load then grows a little (the platform moves): the frozen angle
/// makes the held q current a stationary vector already at its torque peak,
/// so the rotor slips. No count moves; the back-EMF does.
pub fn encoder_dropout_at_standstill(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "encoder_dropout_at_standstill",
        what: "encoder frozen while holding the rated load at rest, then +300 N",
        setup: base(rig),
        injections: vec![
            at(FAULT_AT_S, Injection::EncoderFrozen),
            at(FAULT_AT_S + 0.01, Injection::ExternalForce { newtons: 300.0 }),
        ],
        commands: vec![],
        duration_s: 1.0,
        fault_at_s: Some(FAULT_AT_S),
        expect: expect(FaultSet::ENCODER_LOST, Mode::Fault, 2000),
    }
}

/// σ = 1 A on every current reading for 20 ms (30× the ADC noise): the
/// drive rides through.
pub fn noise_burst(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "noise_burst",
        what: "σ = 1 A noise on all current readings for 20 ms while moving",
        setup: base(rig),
        injections: vec![during(FAULT_AT_S, FAULT_AT_S + 0.02, Injection::CurrentNoise { sigma_a: 1.0 })],
        commands: moving(),
        duration_s: 1.1,
        fault_at_s: None,
        expect: ride_through(),
    }
}

/// One reading of +60 A on phase a (an EMI spike): above the 45 A trip.
pub fn noise_spike(rig: &RigConfig) -> Scenario {
    let setup = base(rig);
    let inj = one_period(&setup, FAULT_AT_S, Injection::CurrentOffset { phase: 0, offset_a: 60.0 });
    Scenario {
        name: "noise_spike",
        what: "one +60 A spike on the phase-a current reading while moving",
        setup,
        injections: vec![inj],
        commands: moving(),
        duration_s: 0.7,
        fault_at_s: None,
        expect: expect(FaultSet::OVERCURRENT, Mode::Fault, 0),
    }
}

/// Phase a reads full scale (a shorted amplifier input).
pub fn current_sensor_stuck_high(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "current_sensor_stuck_high",
        what: "phase-a current reading stuck at +50 A (ADC full scale) while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::CurrentStuck { phase: 0, value_a: 50.0 })],
        commands: moving(),
        duration_s: 0.6,
        fault_at_s: None,
        expect: expect(FaultSet::OVERCURRENT, Mode::Fault, 0),
    }
}

/// Phase a reads 0 A (an open amplifier input).
pub fn current_sensor_stuck_zero(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "current_sensor_stuck_zero",
        what: "phase-a current reading stuck at 0 A while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::CurrentStuck { phase: 0, value_a: 0.0 })],
        commands: moving(),
        duration_s: 0.8,
        fault_at_s: None,
        expect: expect(FaultSet::NONE, Mode::Fault, 20),
    }
}

/// +5 A offset on phase b (amplifier offset drift).
pub fn current_sensor_offset(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "current_sensor_offset",
        what: "+5 A offset on the phase-b current reading while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::CurrentOffset { phase: 1, offset_a: 5.0 })],
        commands: moving(),
        duration_s: 0.8,
        fault_at_s: None,
        expect: expect(FaultSet::NONE, Mode::Fault, 20),
    }
}

pub fn nan_current_sample(rig: &RigConfig) -> Scenario {
    one_nan_sample(rig, "nan_current_sample", "one NaN phase-c current reading while moving", Injection::CurrentNan { phase: 2 })
}

pub fn nan_bus_sample(rig: &RigConfig) -> Scenario {
    one_nan_sample(rig, "nan_bus_sample", "one NaN bus-voltage reading while moving", Injection::BusReadingNan)
}

/// One non-finite reading for one period while moving: the drive refuses
/// it as `non_finite_input` at once, whichever sensor it came from.
fn one_nan_sample(rig: &RigConfig, name: &'static str, what: &'static str, nan: Injection) -> Scenario {
    let setup = base(rig);
    let inj = one_period(&setup, FAULT_AT_S, nan);
    Scenario {
        name,
        what,
        setup,
        injections: vec![inj],
        commands: moving(),
        duration_s: 0.7,
        fault_at_s: None,
        expect: expect(FaultSet::NON_FINITE_INPUT, Mode::Fault, 0),
    }
}

/// A one-period burst of 5000 spurious counts (half a revolution).
pub fn encoder_glitch(rig: &RigConfig) -> Scenario {
    let setup = base(rig);
    let inj = one_period(&setup, FAULT_AT_S, Injection::EncoderOffset { counts: 5000 });
    Scenario {
        name: "encoder_glitch",
        what: "encoder reads +5000 counts off for one period while moving",
        setup,
        injections: vec![inj],
        commands: moving(),
        duration_s: 0.7,
        fault_at_s: None,
        expect: expect(FaultSet::ENCODER_JUMP, Mode::Fault, 0),
    }
}

/// A lasting miscount of 1000 counts (144° electrical) in one period: twice
/// what the motor can turn in a period at top speed, half the jump bound.
pub fn encoder_miscount(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "encoder_miscount",
        what: "encoder count jumps by +1000 counts and stays off while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::EncoderOffset { counts: 1000 })],
        commands: moving(),
        duration_s: 0.8,
        fault_at_s: None,
        expect: expect(FaultSet::ENCODER_JUMP, Mode::Fault, 0),
    }
}

/// The count freezes (cable off) while the rotor turns at 251 rad/s.
pub fn encoder_dropout(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "encoder_dropout",
        what: "encoder count frozen while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::EncoderFrozen)],
        commands: moving(),
        duration_s: 0.8,
        fault_at_s: None,
        expect: expect(FaultSet::ENCODER_LOST, Mode::Fault, 420),
    }
}
