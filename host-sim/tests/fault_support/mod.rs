//! Helpers shared by the fault-injection tests (`tests/fault_*.rs`).
#![allow(dead_code)]

use host_sim::config::RigConfig;
use host_sim::fault_injection::{run, Expect, Outcome, Scenario};
use servo_core::{FaultSet, Mode};

pub fn rig() -> RigConfig {
    RigConfig::nominal().expect("the shipped rig loads")
}

/// Runs a scenario and asserts its whole expectation: the fault bits, the
/// reaction, the detection bound, the current margin, the stroke and no
/// non-finite value anywhere.
pub fn run_meeting(sc: &Scenario) -> Outcome {
    let o = run(sc).expect("scenario runs");
    o.assert_meets(&sc.expect);
    o
}

/// Runs a scenario and asserts `e` instead of its own expectation (what the
/// present core achieves where the catalog states a stricter requirement).
pub fn run_meeting_instead(sc: &Scenario, e: &Expect) -> Outcome {
    let o = run(sc).expect("scenario runs");
    o.assert_meets(e);
    o
}

/// After the latch, the bridge goes off one period later (the duties act
/// one period after the step) and stays off to the end.
pub fn assert_bridge_off_after_latch(o: &Outcome) {
    let latch = o.latch_period.expect("a fault latched") as usize;
    let off = o.bridge_off_period.expect("the bridge went off") as usize;
    assert!(off <= latch + 1, "{}: bridge off at period {off}, latch at {latch}", o.name);
    assert!(o.records[off..].iter().all(|r| !r.bridge_on), "{}: the bridge came back on", o.name);
    assert!(o.records[latch..].iter().all(|r| r.mode == Mode::Fault), "{}: left the Fault mode", o.name);
}

/// A controlled stop: the bridge stays on from the latch to the end, the
/// drive stays in `Stopping`, and the rod ends at rest.
pub fn assert_controlled_stop_to_rest(o: &Outcome, max_end_speed_m_s: f64) {
    let latch = o.latch_period.expect("a fault latched") as usize;
    assert!(o.records[latch + 1..].iter().all(|r| r.bridge_on), "{}: the bridge went off in a controlled stop", o.name);
    assert!(o.records[latch..].iter().all(|r| r.mode == Mode::Stopping), "{}: left the controlled stop", o.name);
    assert!(
        o.rod_speed_end_m_s.abs() < max_end_speed_m_s,
        "{}: rod still moving at {} m/s at the end",
        o.name,
        o.rod_speed_end_m_s
    );
}

/// The expectation with a different reaction and bound (any fault).
pub fn any_fault(reaction: Mode, within_periods: u64, base: &Expect) -> Expect {
    Expect { faults: FaultSet::NONE, reaction: Some(reaction), within_periods, ..*base }
}

/// PWM periods in `seconds` at the rig's PWM rate.
pub fn periods(rig: &RigConfig, seconds: f32) -> u64 {
    (seconds * rig.control.rates.pwm_frequency_hz).round() as u64
}
