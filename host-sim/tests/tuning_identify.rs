//! Identification on the simulator: speed steps each way recover the
//! rig's inertia (rotor + screw + reflected moving mass), Coulomb friction
//! and load; a q-current step recovers R and L.

use host_sim::config::RigConfig;
use host_sim::diagnose::residual::Physics;
use host_sim::tuning::identify::{identify_mechanics, nominal_mech, MechOptions};
use host_sim::tuning::{identify, simulate_identification_captures};

#[test]
fn explore_filter() {
    let rig = RigConfig::nominal().unwrap();
    let (speed, _cur) = simulate_identification_captures(&rig, 1).unwrap();
    let ph = Physics::from_rig(&rig);
    let nom = nominal_mech(&ph, ph.m_moving * ph.gravity);
    println!("nominal {nom:?}");
    for f in [2.0, 4.0, 8.0, 12.0, 20.0, 40.0] {
        for ms in [0.5, 1.0, 3.0] {
            let o = MechOptions { filter_hz: f, rest_speed_rad_s: ms, ..Default::default() };
            let m = identify_mechanics(&speed, 0.105, 0.005 / std::f64::consts::TAU, &o).unwrap();
            println!("f {f} ms {ms}: J {:.4e} ± {:.1e}  B {:.2e}  Tc {:.4}  load {:.4}  r2 {:.5}", m.inertia_kg_m2.value, m.inertia_kg_m2.std_err, m.viscous_n_m_s_rad.value, m.coulomb_n_m.as_ref().unwrap().value, m.load_n_m.value, m.fit.r2);
        }
    }
    let _ = identify;
}

#[test]
fn explore_elec() {
    let rig = RigConfig::nominal().unwrap();
    let (_s, cur) = simulate_identification_captures(&rig, 1).unwrap();
    for f in [300.0, 600.0, 1000.0, 2000.0, 4000.0, 1e9] {
        let e = host_sim::tuning::identify::identify_electrical(&cur, 4.0, 5e-5, f).unwrap();
        println!("f {f}: R {:.4} ± {:.4}  L {:.4e} ± {:.1e} psi {:?} r2 {:.4}", e.resistance_ohm.value, e.resistance_ohm.std_err, e.inductance_h.value, e.inductance_h.std_err, e.flux_linkage_wb.map(|x| x.value), e.fit.r2);
    }
}
