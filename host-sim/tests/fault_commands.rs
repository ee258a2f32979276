//! Command-level faults: reference jumps, NaN references, setpoints outside
//! the stroke, bad parameters at load time, and the acknowledge rules.

mod fault_support;

use fault_support::*;
use host_sim::config::RigConfig;
use host_sim::fault_injection::catalog;
use servo_core::{Command, CommandError, CommandOutcome, LimitFlags};

#[test]
fn a_reference_jump_is_planned_not_stepped_and_an_oversized_shift_is_refused() {
    let rig = rig();
    let o = run_meeting(&catalog::reference_jump(&rig));
    assert_eq!(o.command_result(catalog::FAULT_AT_S), Some(Ok(CommandOutcome::Accepted)));
    let shifts: Vec<_> = o.commands.iter().filter(|c| matches!(c.command, Command::SetPositionShift { .. })).collect();
    assert_eq!(shifts[0].result, Ok(CommandOutcome::Accepted));
    assert_eq!(shifts[1].result, Err(CommandError::OutOfRange));
    // 200 mm in one command: the S-curve took it at the trajectory limits,
    // so the rod never overshot the target by more than the accepted shift.
    let max_shift = f64::from(rig.control.faults.observer_shift_max_m);
    assert!(o.motor_side_range_m.1 < 0.45 + max_shift + 1e-4, "{}", o.brief());
    assert!(o.motor_side_range_m.0 > 0.25 - 1e-3, "{}", o.brief());
}

#[test]
fn nan_and_infinite_references_are_refused_and_nothing_moves() {
    let o = run_meeting(&catalog::nan_reference(&rig()));
    let refused: Vec<_> = o.commands.iter().filter(|c| c.result == Err(CommandError::NotFinite)).collect();
    assert_eq!(refused.len(), 5, "{:?}", o.commands);
    // The one finite move ran to its end and no NaN reached the loops.
    assert!((o.records.last().unwrap().motor_side_position_m - catalog::MOVE_TO_M).abs() < 5e-4, "{}", o.brief());
}

#[test]
fn setpoints_outside_the_stroke_are_clamped_reported_and_never_exceeded() {
    let rig = rig();
    let o = run_meeting(&catalog::out_of_stroke_setpoint(&rig));
    let l = &rig.control.limits;
    assert_eq!(o.command_result(0.4), Some(Ok(CommandOutcome::ClampedToStroke { position_m: l.stroke_max_m })));
    assert_eq!(o.command_result(2.2), Some(Ok(CommandOutcome::ClampedToStroke { position_m: l.stroke_min_m })));
    assert!(o.limits_seen.contains(LimitFlags::STROKE));
    // The motor side reached both ends and never went past them by more
    // than the loop's tracking error.
    let (lo, hi) = o.motor_side_range_m;
    assert!(lo > f64::from(l.stroke_min_m) - 1e-4 && lo < f64::from(l.stroke_min_m) + 1e-3, "{}", o.brief());
    assert!(hi < f64::from(l.stroke_max_m) + 1e-4 && hi > f64::from(l.stroke_max_m) - 1e-3, "{}", o.brief());
}

fn rig_with(field_line: &str, replacement: &str) -> anyhow::Result<RigConfig> {
    let text = host_sim::config::DEFAULT_RIG_TOML;
    assert!(text.contains(field_line), "rig.toml has `{field_line}`");
    RigConfig::from_toml(&text.replacen(field_line, replacement, 1), "test.toml")
}

#[test]
fn out_of_range_parameters_are_refused_at_load_time_by_name() {
    let cases = [
        ("kp = 0.46675092", "kp = -0.46675092", "control.speed_pi.kp"),
        ("\ncurrent_max_a = 36.0", "\ncurrent_max_a = 38.0", "control.limits.current_max_a"),
        ("bus_overvoltage_v = 60.0", "bus_overvoltage_v = 70.0", "control.faults.bus_overvoltage_v"),
        ("\novercurrent_trip_a = 45.0", "\novercurrent_trip_a = nan", "control.faults.overcurrent_trip_a"),
    ];
    for (line, bad, field) in cases {
        let e = rig_with(line, bad).expect_err(bad).to_string();
        assert!(e.contains(field), "`{bad}`: {e}");
        assert!(e.contains("test.toml"), "{e}");
    }
}

#[test]
fn an_overcurrent_trip_above_the_inverter_rating_is_refused() {
    let p = rig().control;
    assert!(p.faults.overcurrent_trip_a <= p.ratings.inverter_peak_current_a, "shipped params: trip {} A > inverter {} A", p.faults.overcurrent_trip_a, p.ratings.inverter_peak_current_a);
}
