//! The paper's run, closed loop through the control core, checked against
//! what the physics and the design say it must do.

use host_sim::config::RigConfig;
use host_sim::report::metrics::paper_summary;
use host_sim::scenario::{run_stroke_cycle, Direction, StrokeCycle};

#[test]
fn paper_cycle_tracks_the_reference_and_shows_the_fig5_deformation() {
    let rig = RigConfig::nominal().unwrap();
    let cycle = StrokeCycle::paper(7);
    let trace = run_stroke_cycle(&rig, &cycle).unwrap();
    assert_eq!(trace.aborted, None);
    let s = paper_summary(&trace, 7, cycle.settle_s);

    // Both legs ran to their ends.
    let top = trace.telemetry.iter().map(|t| t.position_reference_m).fold(f32::MIN, f32::max);
    assert!((top - 0.45).abs() < 1e-6, "top {top}");
    let last = trace.truth.last().unwrap();
    assert!(last.motor_side_position_m.abs() < 50e-6, "ends at {}", last.motor_side_position_m);

    // Semi-closed loop: the motor side follows the S-curve to a few tens of
    // µm (a tenth of the deformation the observer has to remove).
    assert!(s.motor_tracking_max_um < 50.0, "{}", s.motor_tracking_max_um);
    assert!(s.motor_tracking_rms_um < 10.0, "{}", s.motor_tracking_rms_um);

    // The terminal sags under the rated load by Fig. 5's order: at most
    // ≈0.32 mm of static deformation at full stroke and rated thrust, plus the
    // dynamic share from accelerating 140 kg.
    assert!(s.terminal_error_max_mm > 0.25 && s.terminal_error_max_mm < 0.45, "{}", s.terminal_error_max_mm);

    // δ2 = F x/(E A): the sag grows along the stroke on both legs.
    for dir in [Direction::Elongation, Direction::Contraction] {
        let at = |x: f32| {
            trace
                .telemetry
                .iter()
                .zip(&trace.truth)
                .filter(|(t, r)| r.direction == dir && (t.position_reference_m - x).abs() < 0.005)
                .map(|(_, r)| r.deformation_m)
                .sum::<f64>()
        };
        assert!(at(0.40) < at(0.10), "{dir:?}: deformation does not grow along the stroke");
    }

    // Eq. 19 limits hold: current circle and speed.
    assert!(s.peak_phase_current_a <= f64::from(rig.control.limits.current_max_a) * 1.05, "{}", s.peak_phase_current_a);
    let w_max = trace.truth.iter().map(|r| r.motor_speed_rad_s.abs()).fold(0.0, f64::max);
    assert!(w_max <= f64::from(rig.control.limits.speed_max_rad_s), "{w_max}");

    // The thrust peaks above the rated 1.38 kN only by the payload's inertia
    // (2.5 m/s² on 140.7 kg ≈ 350 N) and the friction.
    assert!(s.peak_thrust_n > 1380.0 && s.peak_thrust_n < 1380.0 + 350.0 + 300.0, "{}", s.peak_thrust_n);
}

/// The observer's compensation, closed loop: the rod's terminal error
/// (scale − reference) shrinks by far more than the motor-side tracking can
/// explain, because the sag it removes is the 0.3 mm deformation itself. The
/// issue's figure (≥ 90 %) is measured by `host-sim paper --observer`; this
/// guards the behaviour with some margin for other seeds.
#[test]
fn observer_compensation_removes_most_of_the_terminal_error() {
    let rig = RigConfig::nominal().unwrap();
    let plain = StrokeCycle::paper(3);
    let compensated = StrokeCycle { compensation: true, ..plain.clone() };
    let before = run_stroke_cycle(&rig, &plain).unwrap();
    let after = run_stroke_cycle(&rig, &compensated).unwrap();
    assert_eq!(after.aborted, None);
    let f = host_sim::report::metrics::observer_figures(&before, &after, plain.settle_s);
    let reduction = 1.0 - f.terminal_error_max_mm_after / f.terminal_error_max_mm_before;
    assert!(reduction > 0.85, "max terminal error {} → {} mm ({:.1} %)", f.terminal_error_max_mm_before, f.terminal_error_max_mm_after, 100.0 * reduction);
    assert!(f.terminal_error_rms_mm_after < 0.02, "rms after {}", f.terminal_error_rms_mm_after);
}

/// Coulomb-friction feedforward: without it the speed PI has to wind the
/// friction up at every move start, and the motor lags its command while it
/// does. Same run with the feedforward off and on.
#[test]
fn friction_feedforward_cuts_the_move_start_lag() {
    let rig = RigConfig::nominal().unwrap();
    let mut off = rig.clone();
    off.control.drive_train.friction_feedforward_gain = 0.0;
    let cycle = StrokeCycle::paper(5);
    let lag = |r: &RigConfig| paper_summary(&run_stroke_cycle(r, &cycle).unwrap(), 5, cycle.settle_s).motor_tracking_max_um;
    let (with_ff, without_ff) = (lag(&rig), lag(&off));
    println!("motor tracking max: {with_ff:.1} µm with the friction feedforward, {without_ff:.1} µm without");
    assert!(with_ff < 0.8 * without_ff, "tracking max with feedforward {with_ff} µm, without {without_ff} µm");
}
