//! Standstill under gravity (force and torque balance, deformation as the
//! terminal error) and the energy balance of a moving, lossy drive.

mod plant_support;

use host_sim::plant::{Plant, PlantParams};
use plant_support::{aligned_duties, noiseless, PWM_PERIOD_S};

const BUS_V: f64 = 48.0;

fn holding_duties(plant: &Plant) -> [f64; 3] {
    // At rest the holding current needs only u_q = R i_q.
    let u_q = plant.params().motor.phase_resistance_ohm * plant.state().i_q_a;
    aligned_duties(plant, 0.0, u_q, PWM_PERIOD_S)
}

fn assert_static_balance(plant: &Plant, tilt_rad: f64) {
    let p = plant.params();
    let s = plant.state();
    let r = p.metres_per_rad();
    let load = p.moving_mass_kg() * p.load.gravity_m_s2 * tilt_rad.sin();
    assert!((s.load_force_n - load).abs() < 1e-9 * load.abs());
    // The nut carries the load; the screw, coupling and motor carry r·F.
    assert!((s.axial_force_n - load).abs() < 1e-6 * load.abs(), "axial {} vs {load}", s.axial_force_n);
    assert!((s.coupling_torque_n_m - r * load).abs() < 1e-6 * r * load.abs());
    assert!((s.motor_torque_n_m - r * load).abs() < 1e-6 * r * load.abs());
    assert!((s.i_q_a - plant.holding_current_a(load)).abs() < 1e-9);
    // The terminal lags the motor side by exactly the static deformation.
    let expected = -plant.static_deflection(load, s.x_rod_m).terminal_total_m();
    assert!((s.terminal_error_m - expected).abs() < 1e-9, "terminal error {:e} vs {expected:e}", s.terminal_error_m);
    assert!(s.rod_acceleration_m_s2.abs() < 1e-6, "at rest: a = {}", s.rod_acceleration_m_s2);
}

#[test]
fn construction_is_a_static_equilibrium_under_rated_gravity() {
    let plant = Plant::new(PlantParams::default(), 1);
    let s = plant.state();
    assert_eq!(s.theta_m_rad, 0.0);
    assert_eq!(s.motor_side_position_m, 0.0);
    assert_static_balance(&plant, std::f64::consts::FRAC_PI_2);
    // Rated load, vertical: 1.38 kN, compressing the drive train by ≈0.19 mm at x ≈ 0.
    assert!((s.axial_force_n - 1380.0).abs() < 1.0);
    assert!(s.terminal_error_m < -0.15e-3 && s.terminal_error_m > -0.25e-3, "{:e}", s.terminal_error_m);
}

#[test]
fn held_load_does_not_move_and_stays_balanced() {
    for &(pos_m, tilt_deg) in &[(0.0, 90.0), (0.25, 120.0), (0.45, 60.0)] {
        let mut plant = Plant::new(PlantParams::default(), 1);
        let lead = plant.params().screw.lead_m;
        let tilt = f64::to_radians(tilt_deg);
        plant.set_initial_state(pos_m * 2.0 * std::f64::consts::PI / lead, tilt);
        let before = plant.state().clone();
        assert!((before.motor_side_position_m - pos_m).abs() < 1e-12);
        for _ in 0..2000 {
            let d = holding_duties(&plant);
            plant.advance_duties(Some(d), BUS_V, PWM_PERIOD_S);
        }
        let after = plant.state();
        assert!((after.x_rod_m - before.x_rod_m).abs() < 1e-10, "drift {:e} m", after.x_rod_m - before.x_rod_m);
        assert!(after.omega_m_rad_s.abs() < 1e-6);
        assert_static_balance(&plant, tilt);
    }
}

#[test]
fn load_cell_reads_the_payload_weight_at_rest() {
    let mut plant = Plant::new(PlantParams::default(), 11);
    let p = plant.params().clone();
    let tilt = f64::to_radians(75.0);
    plant.set_external_force_n(200.0);
    plant.set_initial_state(0.0, tilt);
    let expected = p.rod.payload_mass_kg * p.load.gravity_m_s2 * tilt.sin() + 200.0;
    assert!((plant.state().load_cell_force_n - expected).abs() < 1e-6);
    let n = 4000;
    let mean: f64 = (0..n).map(|_| f64::from(plant.sample().load_cell_force_n.unwrap_or(f32::NAN))).sum::<f64>() / n as f64;
    // Mean of n samples of σ = 2 N noise: 5σ/√n ≈ 0.16 N.
    assert!((mean - expected).abs() < 5.0 * p.sensors.load_cell_noise_n / (n as f64).sqrt(), "{mean} vs {expected}");
}

/// `dE/dt = P_electrical + P_load − P_dissipated + P_parametric` integrated over a run
/// with motion, friction, saliency (L_d ≠ L_q, so the reluctance torque
/// must match the voltage equations) and a tilt change. A sign or factor
/// error anywhere in the drive train breaks the balance by O(1).
#[test]
fn energy_is_conserved_along_a_lossy_motion() {
    let mut p = noiseless(PlantParams::default());
    p.motor.inductance_d_h = 0.30e-3;
    p.motor.inductance_q_h = 0.40e-3;
    let mut plant = Plant::new(p, 5);
    plant.set_initial_state(2.0 * std::f64::consts::PI * 20.0, std::f64::consts::FRAC_PI_2);
    let i_hold = plant.state().i_q_a;
    let r_s = plant.params().motor.phase_resistance_ohm;
    let e0 = plant.energy_audit();
    let quarter = PWM_PERIOD_S / 4.0;
    let mut net_in = 0.0;
    let mut throughput = 0.0;
    for k in 0..4000 {
        if k == 2000 {
            plant.set_tilt_rad(f64::to_radians(60.0));
        }
        // Lift, then let part of the load back-drive (u_q below holding).
        let u_q = if k < 2400 { r_s * i_hold + 5.0 } else { r_s * i_hold - 2.0 };
        let d = aligned_duties(&plant, -0.5, u_q, PWM_PERIOD_S);
        // Inputs jump at a period boundary: apply them (zero duration) and
        // restart the trapezoid from the powers they give.
        plant.advance_duties(Some(d), BUS_V, 0.0);
        let mut prev = plant.energy_audit();
        for _ in 0..4 {
            plant.advance_duties(Some(d), BUS_V, quarter);
            let now = plant.energy_audit();
            let p0 = prev.electrical_input_w + prev.load_input_w - prev.dissipation_w + prev.parametric_w;
            let p1 = now.electrical_input_w + now.load_input_w - now.dissipation_w + now.parametric_w;
            net_in += 0.5 * (p0 + p1) * quarter;
            throughput += 0.5 * (prev.electrical_input_w.abs() + now.electrical_input_w.abs()) * quarter;
            prev = now;
        }
    }
    let stored = plant.energy_audit().stored_j - e0.stored_j;
    assert!(plant.state().v_rod_m_s.abs() > 0.01, "the rod must be moving");
    assert!(throughput > 10.0, "meaningful electrical throughput: {throughput} J");
    let mismatch = (stored - net_in).abs();
    // The trapezoid's own error is ≈2e-6 of the throughput; dropping any one
    // loss term (even the structural damping, or the parametric term) costs
    // more than 1e-5.
    assert!(mismatch < 1e-5 * throughput, "ΔE {stored} J vs ∫P {net_in} J (throughput {throughput} J)");
}
