//! Streamed setpoints through the full plant: a sine streamed at 1 kHz and
//! at 100 Hz is tracked; a stream that stops ends in a controlled stop;
//! bad setpoints are refused or bounded and reported.

use host_sim::config::RigConfig;
use host_sim::sim::{holding_vertical, ClosedLoop};
use servo_core::{Command, CommandError, CommandOutcome, Controller, FaultSet, LimitFlags, Mode};
use std::f64::consts::TAU;

const X0_M: f64 = 0.25;

/// The rated payload hanging vertically at 250 mm, enabled and settled.
fn holding() -> ClosedLoop {
    holding_vertical(X0_M, 5, None).unwrap()
}

/// Streams `x0 + a sin(2π f t)` (velocity included) every `every` PWM
/// periods for `seconds`; returns the motor-side tracking error (reference −
/// motor side, telemetry at 1 kHz) RMS and max, metres.
fn stream_sine(cl: &mut ClosedLoop, every: u64, seconds: f64) -> (f64, f64) {
    let (a, f) = (0.01, 0.5);
    let dt = f64::from(cl.controller.params().pwm_period_s());
    let n = (seconds / dt) as u64;
    let mut errs = vec![];
    for k in 0..n {
        if k % every == 0 {
            let t = k as f64 * dt;
            let x = X0_M + a * (TAU * f * t).sin();
            let v = a * TAU * f * (TAU * f * t).cos();
            let r = cl.controller.command(Command::Stream { position_m: x as f32, velocity_m_s: v as f32, force_n: None });
            assert_eq!(r, Ok(CommandOutcome::Accepted), "setpoint {k}");
        }
        let tel = cl.step();
        if k % 20 == 0 && k as f64 * dt > 0.5 {
            errs.push(f64::from(tel.position_reference_m - tel.motor_position_m));
        }
        assert!(tel.faults.is_empty(), "period {k}: {:?}", tel.faults);
    }
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    let max = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    (rms, max)
}

#[test]
fn a_streamed_sine_is_tracked_at_1_khz_and_at_100_hz() {
    for every in [20u64, 200] {
        let mut cl = holding();
        let (rms, max) = stream_sine(&mut cl, every, 3.0);
        println!("setpoints every {every} periods: tracking RMS {:.2} µm, max {:.2} µm", rms * 1e6, max * 1e6);
        // The paper run's planned moves track at ≈ 3 µm RMS, 18 µm max on
        // this rig; a stream of the same kind of motion is held to the
        // same order.
        assert!(rms < 10e-6 && max < 50e-6, "every {every}: RMS {rms:e}, max {max:e}");
        cl.controller.command(Command::StreamEnd).unwrap();
        for _ in 0..2000 {
            cl.step();
        }
        assert!(cl.controller.faults().is_empty() && !cl.controller.move_in_progress());
    }
}

#[test]
fn a_stream_that_stops_ends_in_a_controlled_stop_after_its_timeout() {
    let mut cl = holding();
    stream_sine(&mut cl, 20, 1.0);
    let timeout = f64::from(cl.controller.params().stream.timeout_s);
    let dt = f64::from(cl.controller.params().pwm_period_s());
    let mut latched = None;
    for k in 0..((timeout + 0.1) / dt) as u64 {
        let tel = cl.step();
        if latched.is_none() && tel.faults.contains(FaultSet::STREAM_TIMEOUT) {
            latched = Some(k as f64 * dt);
        }
    }
    let t = latched.expect("stream_timeout latched");
    println!("stream_timeout after {:.1} ms (timeout {:.0} ms)", t * 1e3, timeout * 1e3);
    assert!(t >= timeout && t <= timeout + 0.003, "latched after {t} s");
    for _ in 0..10_000 {
        cl.step();
    }
    assert_eq!(cl.controller.mode(), Mode::Stopping);
    assert!(cl.plant.state().v_rod_m_s.abs() < 1e-3, "rod still moving");
}

#[test]
fn bad_setpoints_are_refused_or_bounded_and_reported() {
    let mut cl = holding();
    let nan = Command::Stream { position_m: f32::NAN, velocity_m_s: 0.0, force_n: None };
    assert_eq!(cl.controller.command(nan), Err(CommandError::NotFinite));
    let inf_force = Command::Stream { position_m: 0.25, velocity_m_s: 0.0, force_n: Some(f32::INFINITY) };
    assert_eq!(cl.controller.command(inf_force), Err(CommandError::NotFinite));
    let beyond = Command::Stream { position_m: 0.9, velocity_m_s: 5.0, force_n: None };
    assert_eq!(cl.controller.command(beyond), Ok(CommandOutcome::ClampedToStroke { position_m: 0.5 }));
    // Reported in the next telemetry record (cut at the position rate).
    let mut limits = LimitFlags::NONE;
    for _ in 0..20 {
        limits.insert(cl.step().limits);
    }
    assert!(limits.contains(LimitFlags::STROKE) && limits.contains(LimitFlags::SPEED), "{limits:?}");
    let stroke_max = f64::from(cl.controller.params().limits.stroke_max_m);
    for _ in 0..20_000 {
        let tel = cl.step();
        assert!(f64::from(tel.position_command_m) <= stroke_max + 1e-6);
        if !tel.faults.is_empty() {
            break;
        }
    }
    // Not homed: refused with the step missing.
    let rig = RigConfig::nominal().unwrap();
    let mut p = rig.control;
    p.startup.commutation_known = true;
    let mut c = Controller::new(p);
    c.step(&servo_core::SensorSample::idle(48.0));
    c.command(Command::Enable).unwrap();
    let sp = Command::Stream { position_m: 0.1, velocity_m_s: 0.0, force_n: None };
    assert_eq!(c.command(sp), Err(CommandError::NotHomed));
}
