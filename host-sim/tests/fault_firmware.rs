//! Firmware-level faults: an ISR overrun reported by the board, and a hung
//! ISR that only the independent watchdog ends.

mod fault_support;

use fault_support::*;
use host_sim::fault_injection::{catalog, run};
use servo_core::{Command, CommandError, CommandOutcome, ControlParams, Controller, FaultSet, Mode, SensorSample};

#[test]
fn an_isr_overrun_switches_the_bridge_off_at_the_next_period() {
    let o = run_meeting(&catalog::isr_overrun(&rig()));
    assert_eq!(o.detection_periods(), Some(0));
    assert_eq!(o.bridge_off_periods(), Some(1));
    assert_bridge_off_after_latch(&o);
}

/// A hung ISR leaves the timer applying its last duties: at 0.2 m/s the
/// rotor turns on under a frozen voltage vector and the current climbs. The
/// board's 45 A comparator break ends it within a couple of milliseconds;
/// the watchdog resets the chip at its timeout and the new controller
/// latches `WATCHDOG_RESET`.
#[test]
fn a_hung_isr_is_bounded_by_the_comparator_and_ended_by_the_watchdog() {
    let rig = rig();
    let sc = catalog::core_hang(&rig);
    let o = run_meeting(&sc);
    let timeout = (sc.setup.watchdog_timeout_s / o.pwm_period_s).round() as u64;
    assert_eq!(o.detection_periods(), Some(timeout));
    let ocp = o.hardware_ocp_period.expect("the comparator tripped") - o.fault_period.unwrap();
    assert!(ocp < 100, "comparator after {ocp} periods");
    assert!(o.peak_current_after_fault_a < 45.0 * 1.1, "{}", o.brief());
    assert!(o.final_faults.contains(FaultSet::WATCHDOG_RESET));
}

/// Without the comparator break the same hang drives well over 100 A into
/// the motor before the watchdog bites: the comparator is what bounds a
/// hung ISR, so the firmware must refuse to run with it disarmed.
#[test]
fn without_the_comparator_a_hung_isr_is_unbounded_for_the_watchdog_timeout() {
    let mut sc = catalog::core_hang(&rig());
    sc.setup.hardware_ocp_a = None;
    let o = run(&sc).unwrap();
    assert!(o.peak_current_after_fault_a > 90.0, "{}", o.brief());
}

#[test]
fn after_a_watchdog_reset_the_drive_waits_for_an_explicit_clear() {
    let mut c = Controller::new(ControlParams::DEFAULT.commissioned());
    c.report_watchdog_reset();
    assert_eq!(c.mode(), Mode::Fault);
    assert!(matches!(c.command(Command::Enable), Err(CommandError::Faulted(f)) if f == FaultSet::WATCHDOG_RESET));
    for _ in 0..100 {
        assert!(!c.step(&SensorSample::idle(48.0)).enable);
    }
    assert_eq!(c.command(Command::ClearFaults), Ok(CommandOutcome::Accepted));
    assert_eq!(c.mode(), Mode::Disabled);
    assert_eq!(c.command(Command::Enable), Ok(CommandOutcome::Accepted));
    assert!(c.step(&SensorSample::idle(48.0)).enable);
}
