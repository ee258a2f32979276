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

/// A one-way step meets the load's inertia through the screw's efficiency
/// law (the nut's friction `μ r |F_ax|`): lifting `J_rot + (1 + μ) m r²`,
/// lowering `J_rot + (1 − μ) m r²`; the rod's anti-resonance stays and its
/// resonance is the two-mass closed form `ω_a √(J'/J_rot)`.
#[test]
fn a_step_meets_the_load_inertia_through_the_screw_efficiency() {
    let (j_rot, m, r, k, c, mu) = (1.06e-4, 35.0, 0.005 / TAU, 4.0e7, 2.0e3, 1.0 / 9.0);
    let mr2 = m * r * r;
    let j = j_rot + mr2;
    let mut p = plant();
    p.inertia_kg_m2 = j;
    p.rod_mode = Some(host_sim::tuning::design::RodMode::new(k, c, m, j, j_rot));
    p.load_inertia_kg_m2 = mr2;
    p.screw_mu = mu;
    p.load_sign = 1.1;
    let wa = (k / m).sqrt();
    for (dir, jt) in [(1.0, j_rot + (1.0 + mu) * mr2), (-1.0, j_rot + (1.0 - mu) * mr2)] {
        let q = p.for_step(dir);
        assert!((q.inertia_kg_m2 - jt).abs() < 1e-12, "{dir}: {} vs {jt}", q.inertia_kg_m2);
        let md = q.rod_mode.unwrap();
        assert!((TAU * md.antiresonance_hz - wa).abs() < 1e-9 * wa);
        let wr = wa * (jt / j_rot).sqrt();
        assert!((TAU * md.resonance_hz - wr).abs() < 1e-9 * wr, "{dir}: {} vs {}", TAU * md.resonance_hz, wr);
        let za = c / (2.0 * (k * m).sqrt());
        assert!((md.zeta_r - za * (jt / j_rot).sqrt()).abs() < 1e-12);
    }
    // Unloaded: no direction, the plant as it is.
    p.load_sign = 0.0;
    assert_eq!(p.for_step(1.0).inertia_kg_m2, j);
}
