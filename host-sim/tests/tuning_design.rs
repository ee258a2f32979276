//! The designs hit what was asked on the model they were designed for.

use host_sim::config::RigConfig;
use host_sim::tuning::design::{bandwidth_hz, design_current, design_speed, margins, DesignPlant};
use std::f64::consts::TAU;

fn plant() -> DesignPlant {
    let rig = RigConfig::nominal().unwrap();
    DesignPlant::from_params(&rig.control, 1.95e-4, 2.0e-4)
}

#[test]
fn current_pi_cancels_the_winding_pole_and_hits_the_asked_bandwidth() {
    let p = plant();
    let (kp, ki, m, bw) = design_current(&p, 1000.0).unwrap();
    assert!((ki / kp - p.r_ohm / p.l_h).abs() < 1e-9 * p.r_ohm / p.l_h, "zero on the winding pole");
    assert!((bw - 1000.0).abs() < 1.0, "−3 dB at {bw}");
    let direct = bandwidth_hz(|w| p.current_cl(kp, ki, w), 1.0, 10_000.0).unwrap();
    assert!((direct - 1000.0).abs() < 1.0);
    // Cancellation: L = (ω_c T) z⁻¹ / (z − 1) · …; the continuous reading
    // 90° − ω_c·1.5 T of the phase margin, within a few degrees.
    let wc = kp / p.l_h;
    let pm_cont = 90.0 - (wc * 1.5 / p.pwm_hz).to_degrees();
    println!("ω_c {:.0} Hz, PM {:?} (continuous reading {pm_cont:.1})", wc / TAU, m.phase_margin_deg);
    assert!((m.phase_margin_deg.unwrap() - pm_cont).abs() < 5.0);
}

#[test]
fn speed_pi_leaves_the_asked_phase_margin_at_crossover_and_the_asked_bandwidth() {
    let p = plant();
    let (ckp, cki, _, _) = design_current(&p, 1000.0).unwrap();
    for (bw, pm) in [(30.0, 60.0), (60.0, 50.0)] {
        let (kp, ki, m, got) = design_speed(&p, (ckp, cki), bw, pm).unwrap();
        println!("{bw} Hz / {pm}°: kp {kp:.4} ki {ki:.2}, crossover {:?} PM {:?} GM {:?}", m.crossover_hz, m.phase_margin_deg, m.gain_margin_db);
        assert!((got - bw).abs() < 0.01 * bw);
        assert!((m.phase_margin_deg.unwrap() - pm).abs() < 0.5, "PM {:?}", m.phase_margin_deg);
        // Independent check at the crossover: |L| = 1, ∠L = −180° + PM.
        let wc = TAU * m.crossover_hz.unwrap();
        let l = p.speed_ol((ckp, cki), (kp, ki), wc);
        assert!((l.norm() - 1.0).abs() < 0.01);
        assert!((180.0 + l.arg().to_degrees() - pm).abs() < 0.5);
        let m2 = margins(|w| p.speed_ol((ckp, cki), (kp, ki), w), 0.5, 2000.0);
        assert!(m2.gain_margin_db.unwrap() > 6.0);
    }
}
