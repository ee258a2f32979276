//! Six closed-loop legs (real control core + full plant each) under the
//! plate: at rest after a move every motor side sits on its target, and
//! each rod sits off it by a deformation whose sign is the sign of that
//! leg's drive-train load (compression shortens the leg; the load is the
//! plate's leg force plus the rod and upper leg's own weight).

use host_sim::config::RigConfig;
use host_sim::platform::six_legs::{run_moves, RigSpread};
use host_sim::platform::table4::PAPER_SETS;
use host_sim::platform::Platform;

#[test]
fn legs_reach_table4_lengths_and_deform_with_their_loads() {
    let p = Platform::paper();
    let rig = RigConfig::nominal().unwrap();
    let target = PAPER_SETS[1].given_mm.map(|v| v * 1e-3);
    let run = run_moves(&p, &rig, &RigSpread::NONE, &[target], false, 3).unwrap();
    let m = &run.moves[0];
    for i in 0..6 {
        assert!(m.motor_side_error_um[i].abs() < 5.0, "leg {}: motor side {} µm", i + 1, m.motor_side_error_um[i]);
        let deformation = m.terminal_error_um[i] - m.motor_side_error_um[i];
        let load = m.drive_train_load_n[i];
        assert!((load - m.leg_forces_n[i]).abs() < 200.0, "leg {}: the rod's own weight is ~150 N at most", i + 1);
        if load.abs() > 20.0 {
            assert!(deformation * load < 0.0, "leg {}: {deformation} µm under {load} N", i + 1);
        }
    }
    // The pose error is what forward kinematics makes of those rod errors:
    // it cannot exceed the largest leg error by more than the geometry's
    // amplification, and it is not zero.
    let pos = m.pose_error_position_mm.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!(pos > 0.0 && pos < 1.0, "{pos} mm");
}

#[test]
fn a_stiffer_leg_deforms_less_under_the_same_load() {
    // Two runs, same loads (the references and so the plate dynamics are
    // the same); leg 1 10 % stiffer in the second: its deformation must
    // shrink by about 1/1.1 (the preloaded contacts are nonlinear, so
    // within a few per cent of that).
    let p = Platform::paper();
    let rig = RigConfig::nominal().unwrap();
    let target = PAPER_SETS[0].given_mm.map(|v| v * 1e-3);
    let mut stiff = RigSpread::NONE;
    stiff.stiffness_scale[0] = 1.1;
    let a = run_moves(&p, &rig, &RigSpread::NONE, &[target], false, 3).unwrap();
    let b = run_moves(&p, &rig, &stiff, &[target], false, 3).unwrap();
    let def = |r: &host_sim::platform::six_legs::SixLegRun| r.moves[0].terminal_error_um[0] - r.moves[0].motor_side_error_um[0];
    let ratio = def(&b) / def(&a);
    assert!((ratio - 1.0 / 1.1).abs() < 0.03, "deformation ratio {ratio}");
}
