//! The core's scope through the full plant: pre-trigger ring and trigger
//! index, decimation timing, a fault triggering a capture, values back
//! within their stated resolution, and the refusals of bad configurations.
//!
//! The bus voltage of each sample is set to a ramp (`step_with`), so a
//! recorded bus value names the PWM period it was taken in.

use host_sim::config::RigConfig;
use host_sim::sim::{holding_vertical, ClosedLoop};
use servo_core::capture::{resolution, CaptureStore, SignalList};
use servo_core::protocol::{CaptureConfig, CaptureState, CaptureTrigger, Signal};
use servo_core::{Controller, FaultSet, Mode, SensorSample};

const X0_M: f64 = 0.25;

fn store() -> &'static CaptureStore {
    Box::leak(Box::new(CaptureStore::new()))
}

/// The rated payload hanging vertically at 250 mm, enabled and settled,
/// with a capture store attached.
fn holding() -> ClosedLoop {
    holding_vertical(X0_M, 5, Some(store())).unwrap()
}

fn config(signals: &[Signal], decimation: u16, samples: u16, pre_trigger: u16, trigger: CaptureTrigger) -> CaptureConfig {
    CaptureConfig { signals: SignalList::from_slice(signals).unwrap(), decimation, samples, pre_trigger, trigger }
}

/// Bus voltage of the sample in period `k` (counted from 0 at the first
/// ramped step): 40 V + 5 mV·(k mod 3000), inside the bus window; 5 mV a
/// period is 3.5 codes of the bus scale (1.44 mV), so rounding to the
/// nearest 5 mV tells the periods apart.
fn ramp_v(k: u64) -> f32 {
    40.0 + 0.005 * (k % 3000) as f32
}

/// Steps with the ramped bus until the capture is done; `trigger_at`
/// calls `capture_trigger` before that period. Returns the periods run.
fn run_ramped(cl: &mut ClosedLoop, trigger_at: Option<u64>, max: u64) -> u64 {
    for k in 0..max {
        if Some(k) == trigger_at {
            cl.controller.capture_trigger().unwrap();
        }
        let v = ramp_v(k);
        cl.step_with(|s| s.bus_voltage_v = v);
        if cl.controller.capture_status().state == CaptureState::Done {
            return k + 1;
        }
    }
    panic!("capture not done after {max} periods: {:?}", cl.controller.capture_status());
}

/// The period a recorded bus value names (mod 3000).
fn period_of(v: f32) -> i64 {
    ((f64::from(v) - 40.0) / 0.005).round() as i64
}

fn read_all(c: &Controller, signal: u8) -> std::vec::Vec<f32> {
    let n = c.capture_status().samples as usize;
    let mut out = vec![0.0f32; n];
    let mut start = 0;
    while start < n {
        let end = (start + 64).min(n);
        let got = c.capture_read(signal, start as u16, &mut out[start..end]).unwrap();
        assert!(got > 0);
        start += got;
    }
    out
}

#[test]
fn the_pre_trigger_ring_keeps_the_samples_before_a_command_trigger() {
    let mut cl = holding();
    let cfg = config(&[Signal::CurrentQ, Signal::BusVoltage], 1, 600, 200, CaptureTrigger::Command);
    cl.controller.capture_configure(&cfg).unwrap();
    assert_eq!(cl.controller.capture_status().state, CaptureState::Armed);
    // 1500 periods armed: the 600-frame ring wraps twice before the trigger.
    let trigger_at = 1500;
    let ran = run_ramped(&mut cl, Some(trigger_at), 5000);
    let st = cl.controller.capture_status();
    println!("status {st:?}, done after {ran} periods");
    assert_eq!((st.trigger_index, st.samples, st.signals), (200, 600, 2));
    assert!((f64::from(st.sample_period_s) - 50e-6).abs() < 1e-9);
    // Post-trigger samples: 400, the trigger's included; done in its last period.
    assert_eq!(ran, trigger_at + 400);
    let bus = read_all(&cl.controller, 1);
    for (i, &v) in bus.iter().enumerate() {
        let expected = trigger_at as i64 - 200 + i as i64;
        assert_eq!(period_of(v), expected, "sample {i}: {v} V");
    }
    // Values within half a code of what was sampled.
    let lsb = resolution(Signal::BusVoltage, cl.controller.params());
    println!("bus voltage code {:.3} mV", lsb * 1e3);
    for (i, &v) in bus.iter().enumerate() {
        let truth = ramp_v(trigger_at - 200 + i as u64);
        // Half a code, and the f32 rounding of the conversions (a few µV).
        assert!((v - truth).abs() <= 0.5 * lsb + 1e-5, "sample {i}: {v} vs {truth}");
    }
    // Reads beyond the record or of a signal not captured are refused.
    let mut out = [0.0f32; 8];
    assert!(cl.controller.capture_read(2, 0, &mut out).is_err());
    assert!(cl.controller.capture_read(0, 600, &mut out).is_err());
    assert_eq!(cl.controller.capture_read(0, 596, &mut out), Ok(4));
    // The held q current (the payload's weight) is what was captured.
    let iq = read_all(&cl.controller, 0);
    let mean = iq.iter().map(|&x| f64::from(x)).sum::<f64>() / iq.len() as f64;
    let hold = f64::from(cl.controller.telemetry().current_q_a);
    assert!((mean - hold).abs() < 0.5, "captured i_q mean {mean} A, telemetry {hold} A");
}

#[test]
fn a_trigger_before_the_ring_is_full_keeps_what_there_is() {
    let mut cl = holding();
    let cfg = config(&[Signal::BusVoltage], 1, 1000, 500, CaptureTrigger::Command);
    cl.controller.capture_configure(&cfg).unwrap();
    let ran = run_ramped(&mut cl, Some(120), 5000);
    let st = cl.controller.capture_status();
    // 120 samples (periods 0..119) before the trigger, 500 after.
    assert_eq!((st.trigger_index, st.samples), (120, 620));
    assert_eq!(ran, 120 + 500);
    let bus = read_all(&cl.controller, 0);
    for (i, &v) in bus.iter().enumerate() {
        assert_eq!(period_of(v), i as i64, "sample {i}");
    }
}

/// A trigger is taken when it is given: the status says so at once, with
/// the samples kept so far as the trigger index, and a second trigger is
/// refused; the next sample on the decimation grid is the trigger sample.
#[test]
fn a_command_trigger_is_taken_at_once_and_its_sample_is_the_next() {
    let mut cl = holding();
    let cfg = config(&[Signal::BusVoltage], 3, 100, 50, CaptureTrigger::Command);
    cl.controller.capture_configure(&cfg).unwrap();
    // Periods 0..=9 sampled at 0, 3, 6, 9.
    for k in 0..10 {
        let v = ramp_v(k);
        cl.step_with(|s| s.bus_voltage_v = v);
    }
    cl.controller.capture_trigger().unwrap();
    let st = cl.controller.capture_status();
    assert_eq!((st.state, st.trigger_index), (CaptureState::Triggered, 4));
    assert_eq!(cl.controller.capture_trigger().map_err(|r| r.text()), Err("capture not armed"));
    // From period 10 on: the trigger sample is period 12's.
    for k in 10..10 + 3 * 50 {
        let v = ramp_v(k);
        cl.step_with(|s| s.bus_voltage_v = v);
    }
    let st = cl.controller.capture_status();
    assert_eq!((st.state, st.trigger_index, st.samples), (CaptureState::Done, 4, 54));
    let bus = read_all(&cl.controller, 0);
    let periods: std::vec::Vec<i64> = bus.iter().map(|&v| period_of(v)).collect();
    assert_eq!(&periods[..6], &[0, 3, 6, 9, 12, 15]);
    assert_eq!(periods[53], 12 + 3 * 49);
}

#[test]
fn decimation_spaces_the_samples_by_its_periods() {
    let mut cl = holding();
    let d = 7u16;
    let cfg = config(&[Signal::BusVoltage, Signal::Speed, Signal::MotorPosition, Signal::CurrentQ], d, 1024, 100, CaptureTrigger::Command);
    cl.controller.capture_configure(&cfg).unwrap();
    let trigger_at = 1000;
    let ran = run_ramped(&mut cl, Some(trigger_at), 20_000);
    let st = cl.controller.capture_status();
    assert_eq!((st.trigger_index, st.samples, st.signals), (100, 1024, 4));
    assert!((f64::from(st.sample_period_s) - f64::from(d) / 20_000.0).abs() < 1e-9);
    let bus = read_all(&cl.controller, 0);
    // Samples on the grid of the configure (periods d−1, 2d−1, …: the first
    // is taken in the first period after it), the trigger sample the first
    // on the grid at or after the trigger.
    let grid_phase = 0;
    // The ramp wraps every 3000 periods: unwrap it.
    let mut periods = vec![period_of(bus[0])];
    for w in bus.windows(2) {
        let mut d = period_of(w[1]) - period_of(w[0]);
        if d < 0 {
            d += 3000;
        }
        periods.push(periods.last().unwrap() + d);
    }
    let t = periods[100];
    assert!(t >= trigger_at as i64 && t < trigger_at as i64 + i64::from(d), "trigger sample in period {t}");
    assert_eq!((t - grid_phase) % i64::from(d), 0, "trigger sample off the grid");
    for w in periods.windows(2) {
        assert_eq!(w[1] - w[0], i64::from(d));
    }
    assert_eq!(ran as i64, t + 1 + (1024 - 100 - 1) * i64::from(d));
    // The position, as captured, at the stated resolution.
    let x = read_all(&cl.controller, 2);
    let lsb = resolution(Signal::MotorPosition, cl.controller.params());
    println!("position code {:.2} µm, speed code {:.4} rad/s", lsb * 1e6, resolution(Signal::Speed, cl.controller.params()));
    let held = f64::from(cl.controller.motor_position_m());
    assert!(x.iter().all(|&v| (f64::from(v) - held).abs() < 20e-6 + f64::from(lsb)), "held position {held}");
}

#[test]
fn a_fault_triggers_a_capture_armed_for_it() {
    let mut cl = holding();
    // Every 2nd period, 300 of 1000 samples before the trigger: 15 ms
    // before the fault, 35 ms after.
    let signals = [Signal::BusVoltage, Signal::PhaseCurrentA, Signal::PhaseCurrentB, Signal::PhaseCurrentC];
    cl.controller.capture_configure(&config(&signals, 2, 1000, 300, CaptureTrigger::Fault)).unwrap();
    // A fault-armed capture waits through quiet periods.
    for _ in 0..2000 {
        cl.step_with(|s| s.bus_voltage_v = 48.0);
    }
    assert_eq!(cl.controller.capture_status().state, CaptureState::Armed);
    // The bus jumps above the 60 V trip in period 500.
    let trip_v = 61.5f32;
    let mut fault_period = None;
    for k in 0..5000u64 {
        let v = if k >= 500 { trip_v } else { 48.0 };
        cl.step_with(|s| s.bus_voltage_v = v);
        if fault_period.is_none() && cl.controller.faults().contains(FaultSet::BUS_OVERVOLTAGE) {
            fault_period = Some(k);
            assert_eq!(cl.controller.mode(), Mode::Fault);
        }
        if cl.controller.capture_status().state == CaptureState::Done {
            break;
        }
    }
    assert_eq!(fault_period, Some(500), "the trip latches in the period the bus crossed");
    let st = cl.controller.capture_status();
    assert_eq!((st.state, st.trigger_index, st.samples), (CaptureState::Done, 300, 1000));
    let bus = read_all(&cl.controller, 0);
    let lsb = resolution(Signal::BusVoltage, cl.controller.params());
    // The trigger sample is the first at or after the fault's period (on
    // the grid of 2): the bus is at the trip value there, at 48 V before.
    assert!((bus[300] - trip_v).abs() < lsb, "trigger sample {} V", bus[300]);
    assert!((bus[299] - 48.0).abs() < lsb, "sample before the trigger {} V", bus[299]);
    assert!(bus[..300].iter().all(|&v| (v - 48.0).abs() < lsb), "pre-trigger samples at 48 V");
    assert!(bus[300..].iter().all(|&v| (v - trip_v).abs() < lsb));
    // The current vector's magnitude, sqrt(2/3 Σi²): the hold current
    // before the fault; the bridge short-circuits the winding while the
    // brake closes (30 ms), then is off.
    let (a, b, c) = (read_all(&cl.controller, 1), read_all(&cl.controller, 2), read_all(&cl.controller, 3));
    let mag: std::vec::Vec<f32> = (0..a.len()).map(|i| ((a[i] * a[i] + b[i] * b[i] + c[i] * c[i]) * 2.0 / 3.0).sqrt()).collect();
    let before = mag[..300].iter().sum::<f32>() / 300.0;
    let last = mag[950..].iter().fold(0.0f32, |m, &v| m.max(v));
    let hold = cl.controller.params().startup.expected_load_force_n * cl.controller.params().metres_per_rad()
        / cl.controller.params().torque_constant_n_m_a();
    println!("|i| before the fault {before:.2} A (load alone {hold:.2} A), 33–35 ms after {last:.3} A");
    assert!((before - hold).abs() < 0.25 * hold, "hold current {before} A");
    assert!(last < 0.2, "current after the bridge went off {last} A");
}

/// Samples are staged as values and encoded into the ring in batches (at
/// the speed-loop tick, or 4 frames at most). With the speed loop at every
/// 8th period the staging fills between ticks, and a trigger given at an
/// odd period finds frames staged: every sample must still land in its
/// own place, the trigger sample the period after the command, and the
/// record be whole the period its last sample is taken.
#[test]
fn staged_samples_land_in_their_places_whatever_the_batch() {
    let rig = RigConfig::nominal().unwrap();
    let mut p = rig.control;
    p.rates.speed_loop_divider = 8;
    p.rates.position_loop_divider = 40;
    let mut c = Controller::try_new(p).unwrap();
    c.attach_capture_store(store());
    let signals = [Signal::BusVoltage, Signal::CurrentQ, Signal::BusVoltage];
    c.capture_configure(&config(&signals, 1, 500, 123, CaptureTrigger::Command)).unwrap();
    let trigger_at = 1001u64;
    let mut ran = None;
    for k in 0..3000u64 {
        if k == trigger_at {
            c.capture_trigger().unwrap();
        }
        c.step(&SensorSample::idle(ramp_v(k)));
        if c.capture_status().state == CaptureState::Done {
            ran = Some(k + 1);
            break;
        }
    }
    let st = c.capture_status();
    assert_eq!((st.state, st.trigger_index, st.samples), (CaptureState::Done, 123, 500));
    assert_eq!(ran, Some(trigger_at + 500 - 123));
    for slot in [0u8, 2] {
        let bus = read_all(&c, slot);
        for (i, &v) in bus.iter().enumerate() {
            assert_eq!(period_of(v), trigger_at as i64 - 123 + i as i64, "slot {slot}, sample {i}: {v} V");
        }
    }
    assert!(read_all(&c, 1).iter().all(|&i| i == 0.0), "no current flows with the bridge off");
}

#[test]
fn bad_configurations_are_refused_with_a_reason() {
    let rig = RigConfig::nominal().unwrap();
    let mut c = Controller::try_new(rig.control).unwrap();
    let good = config(&[Signal::CurrentQ], 1, 1000, 100, CaptureTrigger::Command);
    assert_eq!(c.capture_configure(&good).map_err(|r| r.text()), Err("no capture store attached"));
    c.attach_capture_store(store());
    let cases = [
        (config(&[], 1, 1000, 0, CaptureTrigger::Command), "no signals"),
        (config(&[Signal::CurrentQ], 0, 1000, 0, CaptureTrigger::Command), "decimation 0"),
        (config(&[Signal::CurrentQ], 1, 1, 0, CaptureTrigger::Command), "fewer than 2 samples"),
        (
            config(&[Signal::CurrentQ, Signal::CurrentD, Signal::Speed, Signal::MotorPosition], 1, 1025, 0, CaptureTrigger::Command),
            "samples x signals beyond the 4096-value buffer",
        ),
        (config(&[Signal::CurrentQ, Signal::Speed], 1, 2049, 0, CaptureTrigger::Command), "samples x signals beyond the 4096-value buffer"),
        (config(&[Signal::CurrentQ], 1, 1000, 1000, CaptureTrigger::Command), "pre-trigger not below samples"),
    ];
    for (cfg, reason) in cases {
        assert_eq!(c.capture_configure(&cfg).map_err(|r| r.text()), Err(reason), "{cfg:?}");
        assert_eq!(c.capture_status().state, CaptureState::Idle);
    }
    // The largest ones fit: 4 × 1024, 1 × 4096.
    let four = config(&[Signal::CurrentQ, Signal::CurrentD, Signal::Speed, Signal::MotorPosition], 1, 1024, 1023, CaptureTrigger::Command);
    assert_eq!(c.capture_configure(&four), Ok(()));
    assert_eq!(c.capture_configure(&config(&[Signal::BusVoltage], 65535, 4096, 0, CaptureTrigger::Fault)), Ok(()));
    let mut out = [0.0f32; 4];
    assert_eq!(c.capture_read(0, 0, &mut out).map_err(|r| r.text()), Err("capture not done"));
    // Not armed: no trigger.
    let mut idle = Controller::try_new(rig.control).unwrap();
    assert_eq!(idle.capture_trigger().map_err(|r| r.text()), Err("capture not armed"));
}

/// The board serves a bulk request (a parameter set: the longest request)
/// only where `next_period_serves_bulk` says so, so that it never shares a
/// period with a capture's batch: the record's end, or a full staging
/// between speed ticks. Foretold right for every end over short records at
/// decimations 1 and 3 (with a speed divider of 8, the staging fills
/// between ticks at decimation 1), and never false where neither a speed
/// tick nor a batch is due (a request waits at most two periods).
#[test]
fn bulk_requests_are_held_back_from_a_captures_batch() {
    let rig = RigConfig::nominal().unwrap();
    let mut p = rig.control;
    p.rates.speed_loop_divider = 8;
    p.rates.position_loop_divider = 40;
    for decimation in [1u16, 3] {
        let mut c = Controller::try_new(p).unwrap();
        c.attach_capture_store(store());
        let (mut ends, mut served, mut held_in_a_row, mut held_max) = (0, 0, 0, 0);
        for k in 0..4000u64 {
            if matches!(c.capture_status().state, CaptureState::Idle | CaptureState::Done) {
                c.capture_configure(&config(&[Signal::CurrentQ, Signal::Speed], decimation, 37, 0, CaptureTrigger::Command)).unwrap();
                c.capture_trigger().unwrap();
            }
            let serves = c.next_period_serves_bulk();
            let before = c.capture_status().state;
            c.step(&SensorSample::idle(ramp_v(k)));
            if before == CaptureState::Triggered && c.capture_status().state == CaptureState::Done {
                ends += 1;
                assert!(!serves, "decimation {decimation}: a request was allowed into the period of a capture's end (period {k})");
            }
            served += u32::from(serves);
            held_in_a_row = if serves { 0 } else { held_in_a_row + 1 };
            held_max = held_max.max(held_in_a_row);
        }
        println!("decimation {decimation}: {ends} ends, {served} of 4000 periods serve, at most {held_max} held in a row");
        assert!(ends >= 20, "{ends}");
        assert!(served > 2500, "{served}");
        assert!(held_max <= 2, "a request waited {held_max} periods");
    }
}
