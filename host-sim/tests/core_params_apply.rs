//! `Controller::apply_params` and `Command::Stop` on the full plant: a
//! speed-loop gain changed mid-move is bumpless (the q current moves by
//! less than 10 % of the rated current), structure changes need the bridge
//! off, a commanded stop decelerates to rest and holds.

use host_sim::config::RigConfig;
use host_sim::sim::{holding_vertical, ClosedLoop};
use servo_core::controller::ApplyError;
use servo_core::params::ValidatedParams;
use servo_core::{Command, Controller, Mode, Readiness};

const X0_M: f64 = 0.25;

fn holding() -> ClosedLoop {
    holding_vertical(X0_M, 5, None).unwrap()
}

/// The benchmark's gain change (`drive bench-stream`, `gain_change_mid_move`):
/// `ParamSet control.speed_pi.kp|ki` ×2 and ×½ through the core Server,
/// accelerating and cruising in a 100 mm move under the rated load.
#[test]
fn a_speed_gain_changed_mid_move_does_not_bump_the_current() {
    let rig = RigConfig::nominal().unwrap();
    let s = host_sim::tool::bench_gain::run(&rig).unwrap();
    let cases = s["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 8);
    for c in cases {
        assert_eq!(c["identical_before_change"], true, "deterministic up to the change: {c}");
        assert!(c["peak_pct_of_rated"].as_f64().unwrap() < 10.0, "{c}");
    }
    // Doubling kp mid-move must actually change the current (the change
    // reached the controller): more than the noise floor, less than the bar.
    let kp2 = cases.iter().find(|c| c["path"] == "control.speed_pi.kp" && c["factor"] == 2.0).unwrap();
    assert!(kp2["peak_current_change_a"].as_f64().unwrap() > 0.01, "{kp2}");
    assert_eq!(s["meets_bar"], true);
}

#[test]
fn structure_changes_need_the_bridge_off_and_forget_commutation() {
    let mut cl = holding();
    let mut p = *cl.controller.params();
    p.motor.pole_pairs = 5;
    let v = ValidatedParams::new(p).unwrap();
    let before = *cl.controller.params();
    assert_eq!(cl.controller.apply_params(&v), Err(ApplyError::NeedsBridgeOff { leaf: servo_core::leaf!(motor.pole_pairs) }));
    assert_eq!(*cl.controller.params(), before, "nothing applied");
    // A live change with the bridge on is applied.
    let mut live = before;
    live.trajectory.max_velocity_m_s = 0.1;
    cl.controller.apply_params(&ValidatedParams::new(live).unwrap()).unwrap();
    assert_eq!(cl.controller.params().trajectory.max_velocity_m_s, 0.1);
    // Bridge off: applied; the offset belongs to the old pole count.
    let rig = RigConfig::nominal().unwrap();
    let mut c = Controller::new(rig.control);
    c.step(&servo_core::SensorSample::idle(48.0));
    let mut q = *c.params();
    q.startup.commutation_known = true;
    c.apply_params(&ValidatedParams::new(q).unwrap()).unwrap();
    assert!(c.readiness().contains(Readiness::COMMUTATED));
    q.startup.commutation_known = false;
    q.motor.pole_pairs = 5;
    c.apply_params(&ValidatedParams::new(q).unwrap()).unwrap();
    assert!(!c.readiness().contains(Readiness::COMMUTATED));
    assert_eq!(c.params().motor.pole_pairs, 5);
}

#[test]
fn a_commanded_stop_decelerates_to_rest_and_holds() {
    let mut cl = holding();
    cl.controller.command(Command::MoveTo { position_m: (X0_M + 0.2) as f32 }).unwrap();
    for _ in 0..6_000 {
        cl.step();
    }
    let v0 = cl.plant.state().v_rod_m_s;
    assert!(v0 > 0.1, "cruising: {v0}");
    let x0 = cl.plant.state().motor_side_position_m;
    assert_eq!(cl.controller.command(Command::Stop), Ok(servo_core::CommandOutcome::Accepted));
    let decel = f64::from(cl.controller.params().faults.stop_deceleration_m_s2);
    let mut stopped_at = None;
    for k in 0..10_000 {
        let t = cl.step();
        assert!(t.faults.is_empty(), "{:?}", t.faults);
        assert_eq!(t.mode, Mode::Running);
        if stopped_at.is_none() && !cl.controller.move_in_progress() {
            stopped_at = Some(k);
        }
    }
    let k = stopped_at.expect("at rest");
    let x1 = cl.plant.state().motor_side_position_m;
    println!(
        "stop from {:.3} m/s: at rest after {:.1} ms, {:.2} mm on (v²/2a = {:.2} mm)",
        v0,
        k as f64 / 20.0,
        (x1 - x0) * 1e3,
        v0 * v0 / (2.0 * decel) * 1e3
    );
    assert!(cl.plant.state().v_rod_m_s.abs() < 1e-3);
    assert!((x1 - x0) < 1.5 * v0 * v0 / (2.0 * decel) + 1e-3);
    // Ready for the next move.
    assert!(cl.controller.command(Command::MoveTo { position_m: X0_M as f32 }).is_ok());
    // Stopping a stream.
    let mut cl = holding();
    for k in 0..4_000 {
        // 0.1 m/s for 200 ms, a setpoint every millisecond.
        let x = X0_M + 0.1 * (k as f64 * 50e-6);
        if k % 20 == 0 {
            cl.controller.command(Command::Stream { position_m: x as f32, velocity_m_s: 0.1, force_n: None }).unwrap();
        }
        assert!(cl.step().faults.is_empty());
    }
    assert!(cl.plant.state().v_rod_m_s > 0.05);
    cl.controller.command(Command::Stop).unwrap();
    for _ in 0..20_000 {
        let t = cl.step();
        assert!(t.faults.is_empty(), "{:?}", t.faults);
    }
    assert!(!cl.controller.move_in_progress());
    assert!(cl.plant.state().v_rod_m_s.abs() < 1e-3);
}
