//! What a fault scenario is: where the drive starts ([`Setup`]), what is
//! injected and commanded, and what it must show ([`Expect`]).

use super::injection::{CommandAt, Injection, Timed};
use crate::config::RigConfig;
use crate::plant::PlantParams;
use servo_core::{ControlParams, FaultSet, Mode};

/// Where and how the drive starts.
#[derive(Clone, Debug)]
pub struct Setup {
    pub control: ControlParams,
    pub plant: PlantParams,
    /// Motor-side start position (the drive is homed there), metres.
    pub position_m: f64,
    /// Tilt from horizontal; 90° = vertical, rod up, gravity opposing extension.
    pub tilt_deg: f64,
    pub seed: u64,
    /// The board's comparator overcurrent break (true phase current,
    /// independent of the core); `None`: not fitted.
    pub hardware_ocp_a: Option<f64>,
    /// Independent watchdog timeout (firmware: `WATCHDOG_TIMEOUT_MS`).
    pub watchdog_timeout_s: f64,
}

impl Setup {
    /// The shipped rig, vertical at rated load, homed mid-stroke, with the
    /// B-G431B-ESC1's 45 A comparator break and the firmware's 100 ms
    /// watchdog.
    pub fn nominal(rig: &RigConfig) -> Self {
        Self {
            control: rig.control,
            plant: rig.plant.clone(),
            position_m: 0.25,
            tilt_deg: 90.0,
            seed: 1,
            hardware_ocp_a: Some(45.0),
            watchdog_timeout_s: 0.100,
        }
    }

    pub fn pwm_period_s(&self) -> f64 {
        1.0 / f64::from(self.control.rates.pwm_frequency_hz)
    }
}

/// What a scenario must show. A test asserts every line of it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Expect {
    /// Fault bits that must be latched at the end of the run (empty with a
    /// reaction: any fault will do).
    pub faults: FaultSet,
    /// The mode right after the first latch: `Fault` (bridge off) or
    /// `Stopping` (controlled stop, bridge on). `None`: the drive must ride
    /// through without any fault.
    pub reaction: Option<Mode>,
    /// The first fault latches at most this many PWM periods after the
    /// first period that carried the fault.
    pub within_periods: u64,
    /// The true phase current may exceed `limits.current_max_a` by this
    /// much, for at most one PWM period in a row.
    pub current_margin_a: f64,
    /// The true motor-side and rod positions stay inside the stroke widened
    /// by this much.
    pub stroke_margin_m: f64,
    /// The rod's speed after the latch stays below this (a controlled stop
    /// must not let the load run); `None`: not judged.
    pub rod_speed_after_latch_max_m_s: Option<f64>,
    /// The motor side never gets further than this from where it was at the
    /// latch (a stop that holds, or hands a load it cannot hold to the brake
    /// in time); `None`: not judged.
    pub travel_after_latch_max_m: Option<f64>,
    /// After the latch the rod is never faster than it struck an obstacle
    /// (`Outcome::impact_speed_m_s`): it rings on the contact, fed by the
    /// impact and decaying; faster means it is driven or falling.
    pub rod_no_faster_than_impact: bool,
    /// The run ends with the rod at rest, either held by the loops
    /// (`Stopping`) or on the brake with the bridge off (`Fault`,
    /// `Disabled`): a stop that ends, not one still losing to the load.
    pub ends_at_rest: bool,
}

/// A named fault scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    pub name: &'static str,
    /// One line: what is injected and what the drive should do.
    pub what: &'static str,
    pub setup: Setup,
    pub injections: Vec<Timed>,
    /// Commands given during the run (motion, and command-level faults).
    pub commands: Vec<CommandAt>,
    pub duration_s: f64,
    /// When the fault starts, if it is a command (NaN reference, jump); by
    /// default the earliest injection window.
    pub fault_at_s: Option<f64>,
    pub expect: Expect,
}

impl Scenario {
    /// When the fault starts: `fault_at_s`, else the earliest injection
    /// window. An obstacle counts from the first contact instead, and a
    /// stuck current sensor from the first period its reading is wrong by
    /// more than the current-sum bound (see `run`): until then it reads what
    /// flows, and nothing can tell it from a working one.
    pub fn fault_start_s(&self) -> Option<f64> {
        self.fault_at_s.or_else(|| {
            self.injections
                .iter()
                .filter(|t| !matches!(t.injection, Injection::Obstacle { .. } | Injection::CurrentStuck { .. }))
                .map(|t| t.window.start_s)
                .reduce(f64::min)
        })
    }
}
