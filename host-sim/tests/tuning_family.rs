//! The torque filter per unit: the test moves find a window that moves
//! with the drive train's stiffness, and the corner chosen in it carries
//! the paper's run on the family's softer and stiffer corners, where the
//! shipped corner (150 Hz) or a corner that suits the stiffer one (250 Hz)
//! fails on one of them.

use host_sim::config::RigConfig;
use host_sim::report::metrics::paper_summary;
use host_sim::rigs::{Draw, FamilySpec};
use host_sim::scenario::family::{TRACKING_MAX_MAX_UM, TRACKING_RMS_MAX_UM};
use host_sim::scenario::{run_stroke_cycle, StrokeCycle};
use host_sim::tuning::filter::retune;

fn corner(name: &str) -> RigConfig {
    let spec = FamilySpec::default();
    let (_, d) = Draw::corners(&spec).into_iter().find(|(n, _)| *n == name).expect("a corner of that name");
    d.apply(&RigConfig::nominal().unwrap())
}

fn paper_rms_max(rig: &RigConfig) -> (f64, f64) {
    let cycle = StrokeCycle::paper(3);
    let t = run_stroke_cycle(rig, &cycle).unwrap();
    if t.aborted.is_some() {
        return (f64::INFINITY, f64::INFINITY);
    }
    let s = paper_summary(&t, 3, cycle.settle_s);
    (s.motor_tracking_rms_um, s.motor_tracking_max_um)
}

fn with_filter(rig: &RigConfig, hz: f32) -> RigConfig {
    let mut r = rig.clone();
    r.control.torque_filter_hz = hz;
    r
}

#[test]
fn the_torque_filter_follows_the_drive_trains_stiffness_and_carries_the_paper_run() {
    let (soft, stiff) = (corner("corner_softer"), corner("corner_stiffer"));
    let meets = |(rms, max): (f64, f64)| rms <= TRACKING_RMS_MAX_UM && max <= TRACKING_MAX_MAX_UM;
    // No fixed corner of the two the earlier work tried carries both.
    assert!(!meets(paper_rms_max(&stiff)), "the shipped 150 Hz was expected to ring on the stiffer corner");
    assert!(!meets(paper_rms_max(&with_filter(&soft, 250.0))), "250 Hz was expected to ring on the softer corner");
    let (soft_t, cs) = retune(&soft, 5).unwrap();
    let (stiff_t, ct) = retune(&stiff, 5).unwrap();
    println!("softer: window {:?}, chose {} Hz; stiffer: window {:?}, chose {} Hz", cs.window_hz, cs.torque_filter_hz, ct.window_hz, ct.torque_filter_hz);
    // The window moves up with the stiffness (the torsional resonance does).
    assert!(ct.window_hz.1 > cs.window_hz.1, "upper edges {:?} vs {:?}", ct.window_hz, cs.window_hz);
    assert!(ct.window_hz.0 >= cs.window_hz.0, "lower edges {:?} vs {:?}", ct.window_hz, cs.window_hz);
    // The choice sits inside, at least one grid step from each edge where
    // the window allows.
    for c in [&cs, &ct] {
        assert!(c.window_hz.0 <= c.torque_filter_hz && c.torque_filter_hz <= c.window_hz.1);
        if c.window_hz.1 - c.window_hz.0 >= 50.0 {
            assert!(c.torque_filter_hz > c.window_hz.0 && c.torque_filter_hz < c.window_hz.1, "{c:?}");
        }
    }
    // The paper's run (another trajectory, tilting, and another noise seed
    // than the test moves) meets its bars on both with the chosen corner.
    for (name, r) in [("softer", &soft_t), ("stiffer", &stiff_t)] {
        let (rms, max) = paper_rms_max(r);
        println!("{name}: paper run {rms:.2} µm RMS, {max:.1} µm max at {} Hz", r.control.torque_filter_hz);
        assert!(meets((rms, max)), "{name}: {rms:.2} µm RMS, {max:.1} µm max");
    }
}
