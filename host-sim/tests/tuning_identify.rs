//! Identification on the simulator: speed steps each way (±20, ±50 rad/s,
//! captured as `drive step speed` captures them) recover the rig's inertia
//! (rotor + screw + reflected moving mass), viscous and Coulomb friction
//! and the gravity load; a q-current step recovers R and L.

use host_sim::config::RigConfig;
use host_sim::diagnose::residual::Physics;
use host_sim::tuning::identify::nominal_mech;
use host_sim::tuning::{identify, simulate_identification_captures};

#[test]
fn speed_steps_recover_inertia_friction_and_load_and_a_current_step_r_and_l() {
    let rig = RigConfig::nominal().unwrap();
    let (speed, cur) = simulate_identification_captures(&rig, 1).unwrap();
    let (m, e) = identify(&speed, Some(&cur), &rig.control).unwrap();
    let ph = Physics::from_rig(&rig);
    let nom = nominal_mech(&ph, ph.m_moving * ph.gravity);
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    println!("J {:?} (rig {:.4e})", m.inertia_kg_m2, nom.inertia_kg_m2);
    println!("B {:?} (rig {:.3e}), Tc {:?} (rig {:.4}), load {:?} (rig {:.4}), r2 {}", m.viscous_n_m_s_rad, nom.viscous_n_m_s_rad, m.coulomb_n_m, nom.coulomb_n_m, m.load_n_m, nom.load_n_m, m.fit.r2);
    let e = e.unwrap();
    println!("R {:?} L {:?} psi {:?}", e.resistance_ohm, e.inductance_h, e.flux_linkage_wb);
    assert!(rel(m.inertia_kg_m2.value, nom.inertia_kg_m2) < 0.05, "inertia within 5 %");
    assert!((m.inertia_kg_m2.value - nom.inertia_kg_m2).abs() < 3.0 * m.inertia_kg_m2.std_err, "inside 3 standard errors");
    assert!(rel(m.coulomb_n_m.as_ref().unwrap().value, nom.coulomb_n_m) < 0.03, "Coulomb within 3 %");
    assert!(rel(m.load_n_m.value, nom.load_n_m) < 0.01, "load within 1 %");
    assert!(rel(m.viscous_n_m_s_rad.value, nom.viscous_n_m_s_rad) < 0.25, "viscous within 25 %");
    assert!(m.fit.r2 > 0.999);
    assert!(rel(e.inductance_h.value, 0.35e-3) < 0.03, "L within 3 %");
    assert!(rel(e.resistance_ohm.value, 0.12) < 0.02, "R within 2 % (from the standstill: see docs/tuning.md)");
}
