//! The whole drive (`Controller::step`) on the target: the ISR's code path.
#![no_std]
#![no_main]

use core::f32::consts::PI;
use firmware_tests::{check, check_close, test_main, Outcome};
// The same rigid PMSM plant the golden vectors replay through.
use golden::plant::RigidPlant;
use servo_core::{
    Command, CommandError, ControlParams, Controller, FaultSet, Mode, PwmCommand, SensorSample,
};

const BUS_V: f32 = 48.0;

fn duties_ok(out: &PwmCommand) -> bool {
    out.duty
        .iter()
        .all(|d| d.is_finite() && (0.0..=1.0).contains(d))
}

/// A fixed, deterministic sensor sequence around standstill: a small balanced
/// current ripple, ±1 count of encoder jitter, a little bus ripple.
fn synthetic_sample(k: u32) -> SensorSample {
    let phase = 2.0 * PI * 50.0 * k as f32 / 20_000.0;
    let ripple = 0.2f32;
    let jitter = [0i32, 1, 0, -1][(k / 7 % 4) as usize];
    SensorSample {
        phase_current_a: [
            ripple * libm::sinf(phase),
            ripple * libm::sinf(phase - 2.0 * PI / 3.0),
            ripple * libm::sinf(phase + 2.0 * PI / 3.0),
        ],
        encoder_count: (1000 + jitter) as u16,
        bus_voltage_v: BUS_V + 0.5 * libm::sinf(0.37 * phase),
        terminal_position_m: None,
        load_cell_force_n: None,
        home_switch: None,
        power_stage_temperature_c: None,
    }
}

/// Enable with the default parameters and run one second (20 000 periods) of
/// a nominal synthetic sequence: the bridge stays on, every duty is finite
/// and in [0, 1], and nothing faults.
fn closed_loop_smoke_nominal_inputs() -> Outcome {
    // The synthetic currents do not follow the reference: no load to
    // preload at Enable (the hold current would read as an open phase).
    let mut p = ControlParams::DEFAULT.commissioned();
    p.startup.expected_load_force_n = 0.0;
    let mut c = Controller::new(p);
    check!(c.faults().is_empty(), "{:?}", c.faults());
    check!(c.mode() == Mode::Disabled, "{:?}", c.mode());
    // One sample first so the encoder tracker has its starting count.
    let out = c.step(&synthetic_sample(0));
    check!(!out.enable, "bridge on before Enable: {:?}", out);
    let r = c.command(Command::Enable);
    check!(r.is_ok(), "{:?}", r);
    let periods = 20_000u32;
    for k in 1..=periods {
        let out = c.step(&synthetic_sample(k));
        check!(duties_ok(&out), "period {}: {:?}", k, out);
        check!(
            out.enable,
            "period {}: bridge off, faults {:?}",
            k,
            c.faults()
        );
        check!(c.faults().is_empty(), "period {}: {:?}", k, c.faults());
    }
    check!(c.mode() == Mode::Running, "{:?}", c.mode());
    let t = c.telemetry();
    check!(t.faults.is_empty(), "{:?}", t.faults);
    check_close!(t.time_s, periods as f32 / 20_000.0, 1e-3);
    check!(
        t.motor_position_m.abs() < 1e-6,
        "held position {} m",
        t.motor_position_m
    );
    Ok(())
}

/// DESIGN §3: a fault switches the bridge off at once and stays latched
/// until an explicit clear finds its cause gone.
fn fault_latches_until_cleared() -> Outcome {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    let nominal = SensorSample::idle(BUS_V);
    c.step(&nominal);
    check!(c.command(Command::Enable).is_ok());
    check!(c.step(&nominal).enable);

    let over = SensorSample::idle(ControlParams::DEFAULT.faults.bus_overvoltage_v + 5.0);
    let out = c.step(&over);
    // Not driving: the braking short circuit (all low sides on) while the
    // brake closes, then all switches open.
    check!(!out.enable || out.duty == [0.0; 3], "bridge still driving during overvoltage: {:?}", out);
    check!(!out.brake_release, "brake not applied: {:?}", out);
    check!(duties_ok(&out), "{:?}", out);
    check!(
        c.faults().contains(FaultSet::BUS_OVERVOLTAGE),
        "{:?}",
        c.faults()
    );
    check!(c.mode() == Mode::Fault, "{:?}", c.mode());

    // Cause present: clearing is refused, enabling too.
    let r = c.command(Command::ClearFaults);
    check!(
        matches!(r, Err(CommandError::CauseStillPresent(f)) if f.contains(FaultSet::BUS_OVERVOLTAGE)),
        "{:?}",
        r
    );
    // Cause gone: still latched, bridge still off, until cleared.
    for k in 0..1000 {
        let out = c.step(&nominal);
        check!(!out.enable || (k < 600 && out.duty == [0.0; 3]), "re-armed by itself: {:?}", out);
    }
    check!(
        c.faults().contains(FaultSet::BUS_OVERVOLTAGE),
        "{:?}",
        c.faults()
    );
    check!(matches!(
        c.command(Command::Enable),
        Err(CommandError::Faulted(_))
    ));
    let r = c.command(Command::ClearFaults);
    check!(r.is_ok(), "{:?}", r);
    check!(c.faults().is_empty(), "{:?}", c.faults());
    check!(c.command(Command::Enable).is_ok());
    check!(c.step(&nominal).enable);
    Ok(())
}

/// NaN in a sample: bridge off, finite duties, `NON_FINITE_INPUT` latched.
fn non_finite_sample_turns_bridge_off() -> Outcome {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    let nominal = SensorSample::idle(BUS_V);
    c.step(&nominal);
    check!(c.command(Command::Enable).is_ok());
    let mut bad = nominal;
    bad.phase_current_a[1] = f32::NAN;
    let out = c.step(&bad);
    check!(!out.enable && duties_ok(&out), "{:?}", out);
    check!(
        c.faults().contains(FaultSet::NON_FINITE_INPUT),
        "{:?}",
        c.faults()
    );
    Ok(())
}

/// Parameters that fail validation give a controller that never enables.
fn invalid_params_never_enable() -> Outcome {
    let mut p = ControlParams::DEFAULT;
    p.motor.inductance_q_h = -1.0;
    check!(Controller::try_new(p).is_err());
    let mut c = Controller::new(p.commissioned());
    check!(
        c.faults().contains(FaultSet::INVALID_PARAMS),
        "{:?}",
        c.faults()
    );
    check!(c.command(Command::Enable).is_err());
    check!(c.command(Command::ClearFaults).is_err());
    let out = c.step(&SensorSample::idle(BUS_V));
    check!(!out.enable && duties_ok(&out), "{:?}", out);
    Ok(())
}

/// The 16-bit counter wraps (both ways) at 2400 rpm without an encoder-jump
/// fault; the tracked position and speed follow the unwrapped count.
fn encoder_wraps_without_fault() -> Outcome {
    let p = ControlParams::DEFAULT;
    let metres_per_count = p.drive_train.screw_lead_m / p.encoder.counts_per_rev as f32;
    let rad_per_count = 2.0 * PI / p.encoder.counts_per_rev as f32;
    let step = 20i32; // counts per 50 µs period: 400 000 counts/s = 2400 rpm
    let periods = 4000i32; // 80 000 counts: the counter wraps at least once
    for (start_raw, dir, home_m) in [(65_000u16, 1i32, 0.0f32), (100u16, -1i32, 0.25f32)] {
        let mut c = Controller::new(p.commissioned());
        c.step(&SensorSample {
            encoder_count: start_raw,
            ..SensorSample::idle(BUS_V)
        });
        let r = c.command(Command::SetHome { position_m: home_m });
        check!(r.is_ok(), "{:?}", r);
        for k in 1..=periods {
            let raw = (start_raw as i32 + dir * step * k) as u16;
            c.step(&SensorSample {
                encoder_count: raw,
                ..SensorSample::idle(BUS_V)
            });
            check!(
                c.faults().is_empty(),
                "dir {}, period {}: {:?}",
                dir,
                k,
                c.faults()
            );
        }
        let expected_m = home_m + (dir * step * periods) as f32 * metres_per_count;
        check_close!(
            c.motor_position_m(),
            expected_m,
            2.0 * metres_per_count,
            "dir {}",
            dir
        );
        let expected_speed = (dir * step) as f32 * rad_per_count * p.rates.pwm_frequency_hz;
        check_close!(
            c.speed_rad_s(),
            expected_speed,
            1e-3 * expected_speed.abs(),
            "dir {}",
            dir
        );
    }
    Ok(())
}

/// The whole cascade closed through a rigid plant: a 10 mm jerk-limited move
/// ends within 20 µm of its target at rest, with the bridge on throughout,
/// valid duties every period and no fault (so the following error stayed
/// under its 5 mm trip).
fn closed_loop_move_on_rigid_plant() -> Outcome {
    let p = ControlParams::DEFAULT;
    let mut plant = RigidPlant::new(p, BUS_V);
    let mut c = Controller::new(p.commissioned());
    c.step(&plant.sample());
    let home_m = 0.1;
    let r = c.command(Command::SetHome { position_m: home_m });
    check!(r.is_ok(), "{:?}", r);
    check!(c.command(Command::Enable).is_ok());
    let target_m = home_m + 0.01;
    let r = c.command(Command::MoveTo {
        position_m: target_m,
    });
    check!(r.is_ok(), "{:?}", r);
    let periods = (0.6 * p.rates.pwm_frequency_hz) as u32;
    let mut out = PwmCommand::OFF;
    for k in 0..periods {
        plant.advance(&out);
        out = c.step(&plant.sample());
        check!(c.faults().is_empty(), "period {}: {:?}", k, c.faults());
        check!(out.enable && duties_ok(&out), "period {}: {:?}", k, out);
    }
    check!(!c.move_in_progress());
    let plant_m = home_m + plant.angle_rad * p.metres_per_rad();
    check_close!(plant_m, target_m, 20e-6, "plant position");
    check_close!(c.motor_position_m(), target_m, 20e-6, "tracked position");
    check!(
        plant.speed_rad_s.abs() < 0.5,
        "still moving at {} rad/s",
        plant.speed_rad_s
    );
    Ok(())
}

/// A standing board condition (here: no hardware overcurrent break, as
/// the ESC1 reports a failed comparator self-test) latches its named fault
/// at once: Enable is refused, and ClearFaults too while the board says it
/// stands; once the board reports it gone, a clear lets the drive enable.
fn board_condition_refuses_enable_while_it_stands() -> Outcome {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    let nominal = SensorSample::idle(BUS_V);
    c.report_board_condition(FaultSet::NO_HARDWARE_BREAK, true);
    check!(c.faults().contains(FaultSet::NO_HARDWARE_BREAK), "{:?}", c.faults());
    for _ in 0..100 {
        check!(!c.step(&nominal).enable, "bridge on without the hardware break");
    }
    let r = c.command(Command::Enable);
    check!(matches!(r, Err(CommandError::Faulted(f)) if f.contains(FaultSet::NO_HARDWARE_BREAK)), "{:?}", r);
    let r = c.command(Command::ClearFaults);
    check!(
        matches!(r, Err(CommandError::CauseStillPresent(f)) if f.contains(FaultSet::NO_HARDWARE_BREAK)),
        "{:?}",
        r
    );
    c.step(&nominal);
    check!(c.faults().contains(FaultSet::NO_HARDWARE_BREAK), "{:?}", c.faults());
    // Only the board's own conditions go through this door.
    c.report_board_condition(FaultSet::OVERCURRENT, true);
    check!(!c.faults().contains(FaultSet::OVERCURRENT), "{:?}", c.faults());

    c.report_board_condition(FaultSet::NO_HARDWARE_BREAK, false);
    c.step(&nominal);
    check!(c.faults().contains(FaultSet::NO_HARDWARE_BREAK), "cleared by itself: {:?}", c.faults());
    let r = c.command(Command::ClearFaults);
    check!(r.is_ok(), "{:?}", r);
    check!(c.command(Command::Enable).is_ok());
    check!(c.step(&nominal).enable);
    Ok(())
}

/// `next_period_is_current_only` foretells the next step's kind: the board
/// serves bulk requests only before a current-only step. The controller
/// counts periods from 1 at its first step; speed ticks fall on multiples
/// of the speed divider (position ticks are speed ticks too). Checked over
/// two position periods, running and disabled (the count runs in every
/// mode).
fn next_period_kind_is_foretold() -> Outcome {
    let p = ControlParams::DEFAULT.commissioned();
    let div = p.rates.speed_loop_divider;
    check!(div >= 2, "speed divider {}", div);
    let mut c = Controller::new(p);
    let nominal = SensorSample::idle(BUS_V);
    for tick in 1..=(2 * p.rates.position_loop_divider + 3) {
        if tick == p.rates.position_loop_divider {
            let _ = c.command(Command::Enable);
        }
        let current_only = tick % div != 0;
        check!(
            c.next_period_is_current_only() == current_only,
            "tick {}: foretold {}, the step is {}",
            tick,
            c.next_period_is_current_only(),
            if current_only { "current-only" } else { "a speed tick" }
        );
        c.step(&nominal);
    }
    Ok(())
}

test_main!(
    next_period_kind_is_foretold,
    board_condition_refuses_enable_while_it_stands,
    closed_loop_smoke_nominal_inputs,
    fault_latches_until_cleared,
    non_finite_sample_turns_bridge_off,
    invalid_params_never_enable,
    encoder_wraps_without_fault,
    closed_loop_move_on_rigid_plant,
);
