//! What one fault run recorded, every PWM period, and the figures a safety
//! case reads from it.

use super::scenario::Expect;
use anyhow::Result;
use servo_core::{Command, CommandError, CommandOutcome, FaultSet, LimitFlags, Mode};

/// A motor side slower than this at the end of a run is at rest (creep on
/// the brake or in the loops' hold is far below it; a load still winning
/// is tens of mm/s and more).
const END_REST_SPEED_M_S: f64 = 0.002;
/// The window at the end of a run judged for rest.
const END_REST_WINDOW_S: f64 = 0.05;

/// One PWM period of the record.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct PeriodRecord {
    /// Start of the period.
    pub time_s: f64,
    /// Largest |true phase current| over the period's integration steps.
    pub peak_phase_current_a: f64,
    pub motor_side_position_m: f64,
    pub rod_position_m: f64,
    pub rod_speed_m_s: f64,
    /// Latched after this period's step.
    pub faults: FaultSet,
    pub mode: Mode,
    /// The bridge was driving the motor during this period (the plant's
    /// truth): switching, other than the short circuit below.
    pub bridge_on: bool,
    /// All three low sides on (active short circuit after a bridge-off
    /// fault, while the brake closes): braking, not driving.
    pub short_circuit: bool,
}

/// A command and what the drive answered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandRecord {
    pub at_s: f64,
    pub command: Command,
    pub result: Result<CommandOutcome, CommandError>,
}

/// Everything measured in one run.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub name: &'static str,
    pub pwm_period_s: f64,
    /// Limit the current is judged against (`limits.current_max_a`).
    pub current_limit_a: f64,
    pub stroke_m: (f64, f64),
    /// First period that carried the fault.
    pub fault_period: Option<u64>,
    /// First period after which a fault was latched.
    pub latch_period: Option<u64>,
    /// The bits latched in that period.
    pub first_faults: FaultSet,
    /// Faults latched before the fault was injected (a broken scenario).
    pub faults_before_fault: FaultSet,
    /// Mode right after the first latch.
    pub reaction: Option<Mode>,
    /// First period after the latch in which the bridge was really off.
    pub bridge_off_period: Option<u64>,
    pub final_faults: FaultSet,
    /// Every bit latched at some point of the run (a clear does not remove
    /// it from here).
    pub seen_faults: FaultSet,
    pub final_mode: Mode,
    /// Largest true phase current over the run, and from the fault on.
    pub peak_current_a: f64,
    pub peak_current_after_fault_a: f64,
    /// Longest run of consecutive periods with the true current above
    /// `current_limit_a + margin`, for each margin asked in `runs_over`.
    pub current_trace: Vec<f64>,
    pub motor_side_range_m: (f64, f64),
    pub rod_range_m: (f64, f64),
    /// Motor-side travel from the latch to the end of the run.
    pub travel_after_latch_m: Option<f64>,
    /// Largest rod speed after the latch.
    pub rod_speed_after_latch_max_m_s: Option<f64>,
    /// The rod's speed when it first touched an obstacle.
    pub impact_speed_m_s: Option<f64>,
    pub rod_speed_end_m_s: f64,
    /// First non-finite value found (where, which period).
    pub non_finite: Option<(u64, String)>,
    /// Duties returned by the core outside [0, 1] (or NaN).
    pub duty_out_of_range: u64,
    /// Limit flags seen in any telemetry record.
    pub limits_seen: LimitFlags,
    /// The board's comparator break tripped (period).
    pub hardware_ocp_period: Option<u64>,
    /// A watchdog reset happened (period).
    pub watchdog_reset_period: Option<u64>,
    pub commands: Vec<CommandRecord>,
    pub records: Vec<PeriodRecord>,
}

impl Outcome {
    /// PWM periods from the first period that carried the fault to the step
    /// that latched it (0: the same period's step).
    pub fn detection_periods(&self) -> Option<u64> {
        Some(self.latch_period?.saturating_sub(self.fault_period?))
    }

    pub fn detection_s(&self) -> Option<f64> {
        self.detection_periods().map(|n| n as f64 * self.pwm_period_s)
    }

    /// Periods from the fault to the first period the bridge was off.
    pub fn bridge_off_periods(&self) -> Option<u64> {
        Some(self.bridge_off_period?.saturating_sub(self.fault_period?))
    }

    /// Longest run of consecutive periods with |i| above `limit + margin`.
    pub fn longest_run_over(&self, margin_a: f64) -> u64 {
        let bound = self.current_limit_a + margin_a;
        let mut longest = 0;
        let mut run = 0;
        for i in &self.current_trace {
            if *i > bound {
                run += 1;
                longest = longest.max(run);
            } else {
                run = 0;
            }
        }
        longest
    }

    /// How far the true motor-side or rod position went beyond the stroke
    /// (0 if never).
    pub fn stroke_excess_m(&self) -> f64 {
        let (lo, hi) = self.stroke_m;
        let worst_lo = self.motor_side_range_m.0.min(self.rod_range_m.0);
        let worst_hi = self.motor_side_range_m.1.max(self.rod_range_m.1);
        (lo - worst_lo).max(worst_hi - hi).max(0.0)
    }

    /// The farthest the motor side got from where it was at the latch.
    pub fn excursion_after_latch_m(&self) -> Option<f64> {
        let latch = self.latch_period? as usize;
        let x0 = self.records.get(latch)?.motor_side_position_m;
        Some(self.records[latch..].iter().map(|r| (r.motor_side_position_m - x0).abs()).fold(0.0, f64::max))
    }

    /// Why the run does not end at rest, held by the loops or on the brake
    /// with the bridge off (`None`: it does). At rest: the motor side (what
    /// the loops or the brake hold) moved less than `END_REST_SPEED_M_S`
    /// times `END_REST_WINDOW_S` over the run's last window; a heavy payload
    /// may still ring on the structure's compliance above a held motor side.
    pub fn not_at_rest_at_end(&self) -> Option<String> {
        let last = self.records.last()?;
        let from = last.time_s - END_REST_WINDOW_S;
        let window = self.records.iter().rev().take_while(|r| r.time_s >= from).map(|r| r.motor_side_position_m);
        let (lo, hi) = window.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
        if hi - lo > END_REST_SPEED_M_S * END_REST_WINDOW_S {
            return Some(format!("motor side still moving at the end ({:.2} mm over the last {:.0} ms)", (hi - lo) * 1e3, END_REST_WINDOW_S * 1e3));
        }
        match (last.mode, last.bridge_on) {
            (Mode::Stopping, true) | (Mode::Fault | Mode::Disabled, false) => None,
            (m, on) => Some(format!("ends in {m:?} with the bridge {}, neither held nor on the brake", if on { "on" } else { "off" })),
        }
    }

    /// The rules of `expect` this run broke, in words (empty: all kept).
    pub fn violations(&self, e: &Expect) -> Vec<String> {
        let mut v = vec![];
        if !self.faults_before_fault.is_empty() {
            v.push(format!("faults {} latched before the fault was injected", names(self.faults_before_fault)));
        }
        if e.reaction.is_none() {
            if !self.final_faults.is_empty() || self.latch_period.is_some() {
                v.push(format!("expected to ride through, but {} latched", names(self.first_faults.union(self.final_faults))));
            }
        } else {
            if !self.seen_faults.contains(e.faults) {
                v.push(format!("expected {} latched, got {}", names(e.faults), names(self.seen_faults)));
            }
            match self.detection_periods() {
                Some(n) if n <= e.within_periods => {}
                Some(n) => v.push(format!("latched after {n} periods, bound {}", e.within_periods)),
                None => v.push("no fault latched".into()),
            }
            if self.reaction != e.reaction {
                v.push(format!("reaction {:?}, expected {:?}", self.reaction, e.reaction));
            }
        }
        let run = self.longest_run_over(e.current_margin_a);
        if run > 1 {
            v.push(format!(
                "true phase current above {:.1} A for {run} consecutive periods (peak {:.1} A)",
                self.current_limit_a + e.current_margin_a,
                self.peak_current_a
            ));
        }
        let excess = self.stroke_excess_m();
        if excess > e.stroke_margin_m {
            v.push(format!(
                "stroke exceeded by {:.2} mm (motor side {:.4}..{:.4} m, rod {:.4}..{:.4} m), allowed {:.2} mm",
                excess * 1e3,
                self.motor_side_range_m.0,
                self.motor_side_range_m.1,
                self.rod_range_m.0,
                self.rod_range_m.1,
                e.stroke_margin_m * 1e3
            ));
        }
        if let (Some(bound), Some(v_max)) = (e.rod_speed_after_latch_max_m_s, self.rod_speed_after_latch_max_m_s) {
            if v_max > bound {
                v.push(format!("rod reached {v_max:.3} m/s after the latch, bound {bound} m/s"));
            }
        }
        if let (Some(bound), Some(travel)) = (e.travel_after_latch_max_m, self.excursion_after_latch_m()) {
            if travel > bound {
                v.push(format!("motor side travelled {:.2} mm from where it was at the latch, bound {:.2} mm", travel * 1e3, bound * 1e3));
            }
        }
        if e.ends_at_rest {
            if let Some(why) = self.not_at_rest_at_end() {
                v.push(why);
            }
        }
        if e.rod_no_faster_than_impact {
            match (self.impact_speed_m_s, self.rod_speed_after_latch_max_m_s) {
                (Some(impact), Some(v_max)) if v_max > impact => {
                    v.push(format!("rod reached {v_max:.3} m/s after the latch, faster than its {impact:.3} m/s impact"))
                }
                (None, _) => v.push("the rod never touched the obstacle".into()),
                _ => {}
            }
        }
        if let Some((period, what)) = &self.non_finite {
            v.push(format!("non-finite {what} at period {period}"));
        }
        if self.duty_out_of_range > 0 {
            v.push(format!("{} duties outside [0, 1]", self.duty_out_of_range));
        }
        v
    }

    /// Panics with every broken rule (for tests).
    pub fn assert_meets(&self, e: &Expect) {
        let v = self.violations(e);
        assert!(v.is_empty(), "scenario `{}`:\n  {}\n{}", self.name, v.join("\n  "), self.brief());
    }

    /// A short human-readable account.
    pub fn brief(&self) -> String {
        format!(
            "{}: detection {:?} periods, bridge off after {:?} periods, first {} → {:?}, final {} / {:?}, peak {:.1} A \
             (after fault {:.1} A), motor side {:.4}..{:.4} m, rod {:.4}..{:.4} m, travel after latch {:?} m, \
             rod speed end {:.4} m/s, hw OCP {:?}, non-finite {:?}",
            self.name,
            self.detection_periods(),
            self.bridge_off_periods(),
            names(self.first_faults),
            self.reaction,
            names(self.final_faults),
            self.final_mode,
            self.peak_current_a,
            self.peak_current_after_fault_a,
            self.motor_side_range_m.0,
            self.motor_side_range_m.1,
            self.rod_range_m.0,
            self.rod_range_m.1,
            self.travel_after_latch_m,
            self.rod_speed_end_m_s,
            self.hardware_ocp_period,
            self.non_finite,
        )
    }

    /// The answer to the command given at `at_s` (first match).
    pub fn command_result(&self, at_s: f64) -> Option<Result<CommandOutcome, CommandError>> {
        self.commands.iter().find(|c| (c.at_s - at_s).abs() < 1e-9).map(|c| c.result)
    }
}

/// Fault names joined by `|`, "none" if empty.
pub fn names(f: FaultSet) -> String {
    if f.is_empty() {
        return "none".into();
    }
    f.names().collect::<Vec<_>>().join("|")
}
