//! The fault scenarios of the reliability table (`docs/reliability.md`).
//!
//! Every scenario runs the shipped rig in its worst orientation: vertical,
//! rated load (1.38 kN of gravity on the rod), homed mid-stroke at 250 mm.
//! The loops take the load over in the first 0.3 s; most faults are injected
//! at 0.5 s, 0.2 s into a move to 350 mm, when the rod cruises at its
//! 0.2 m/s maximum (the worst moment for encoder and phase faults: the rotor
//! turns at 251 rad/s). Faults that only matter at rest are injected while
//! holding.
//!
//! Each scenario states what it must show ([`Expect`]); the tests in
//! `tests/fault_*.rs` assert it, `host-sim faults` reports it.

use super::injection::{CommandAt, Injection, Timed, Window};
use super::scenario::{Expect, Scenario, Setup};
use crate::config::RigConfig;
use servo_core::{Command, FaultSet, Mode};

mod firmware;
mod motion;
mod power;
mod sensors;

pub use firmware::*;
pub use motion::*;
pub use power::*;
pub use sensors::*;

/// The loops have taken the load over.
pub const SETTLE_S: f64 = 0.3;

/// The standard move starts here...
pub const MOVE_AT_S: f64 = 0.3;

/// ...from 250 mm to here.
pub const MOVE_TO_M: f64 = 0.35;

/// The fault comes 0.2 s into the move: cruising at 0.2 m/s.
pub const FAULT_AT_S: f64 = 0.5;

/// The current may exceed `limits.current_max_a` (36 A) by this much for at
/// most one period: up to the 45 A overcurrent trip (the core's and the
/// board comparator's).
pub const CURRENT_MARGIN_A: f64 = 9.0;

/// A controlled stop lands within `faults.stroke_soft_margin_m` (2 mm) of
/// the stroke ends; the rod may sit up to 0.4 mm behind the motor side
/// under load (deformation). 2.5 mm in all.
pub const STROKE_MARGIN_M: f64 = 0.0025;

fn expect(faults: FaultSet, reaction: Mode, within_periods: u64) -> Expect {
    Expect {
        faults,
        reaction: Some(reaction),
        within_periods,
        current_margin_a: CURRENT_MARGIN_A,
        stroke_margin_m: STROKE_MARGIN_M,
        rod_speed_after_latch_max_m_s: None,
        travel_after_latch_max_m: None,
        rod_no_faster_than_impact: false,
        ends_at_rest: false,
    }
}

fn ride_through() -> Expect {
    Expect {
        faults: FaultSet::NONE,
        reaction: None,
        within_periods: 0,
        current_margin_a: CURRENT_MARGIN_A,
        stroke_margin_m: STROKE_MARGIN_M,
        rod_speed_after_latch_max_m_s: None,
        travel_after_latch_max_m: None,
        rod_no_faster_than_impact: false,
        ends_at_rest: false,
    }
}

fn moving() -> Vec<CommandAt> {
    vec![CommandAt { at_s: MOVE_AT_S, command: Command::MoveTo { position_m: MOVE_TO_M as f32 } }]
}

fn at(start_s: f64, injection: Injection) -> Timed {
    Timed { window: Window::from(start_s), injection }
}

fn during(start_s: f64, end_s: f64, injection: Injection) -> Timed {
    Timed { window: Window::new(start_s, end_s), injection }
}

fn one_period(setup: &Setup, start_s: f64, injection: Injection) -> Timed {
    Timed { window: Window::one_period(start_s, setup.pwm_period_s()), injection }
}

fn base(rig: &RigConfig) -> Setup {
    Setup::nominal(rig)
}

/// Every scenario of the table, in table order.
pub fn all(rig: &RigConfig) -> Vec<Scenario> {
    vec![
        noise_burst(rig),
        noise_spike(rig),
        current_sensor_stuck_high(rig),
        current_sensor_stuck_zero(rig),
        current_sensor_offset(rig),
        nan_current_sample(rig),
        nan_bus_sample(rig),
        encoder_glitch(rig),
        encoder_miscount(rig),
        encoder_dropout(rig),
        open_phase(rig),
        bus_sag(rig),
        bus_dip(rig),
        bus_surge(rig),
        load_spike(rig),
        load_beyond_rating(rig),
        stall(rig),
        thermal_overload(rig),
        soft_limit(rig),
        observer_out_of_bounds(rig),
        reference_jump(rig),
        nan_reference(rig),
        out_of_stroke_setpoint(rig),
        isr_overrun(rig),
        core_hang(rig),
        encoder_dropout_at_standstill(rig),
        power_stage_hot(rig),
        power_stage_overtemp(rig),
        regeneration_on_a_high_bus(rig),
    ]
}

/// The scenario of this name.
pub fn by_name(rig: &RigConfig, name: &str) -> Option<Scenario> {
    all(rig).into_iter().find(|s| s.name == name)
}
