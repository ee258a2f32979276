//! Friction in steady motion: the screw's efficiency as load-dependent
//! Coulomb friction gives the forward efficiency η lifting and the
//! catalogue back-drive efficiency 2 − 1/η lowering; with every other
//! friction term on, the motor torque matches the closed-form balance.

mod plant_support;

use std::f64::consts::FRAC_PI_2;

use host_sim::plant::{Plant, PlantParams};
use plant_support::run_aligned;

const BUS_V: f64 = 48.0;

/// Runs at constant q-voltage `holding + du` until steady; returns the plant.
fn steady(p: PlantParams, du: f64) -> Plant {
    let mut plant = Plant::new(p, 1);
    plant.set_initial_state(2.0 * std::f64::consts::TAU, FRAC_PI_2);
    let u_q = plant.params().motor.phase_resistance_ohm * plant.state().i_q_a + du;
    run_aligned(&mut plant, 0.0, u_q, BUS_V, 0.25);
    plant
}

#[test]
fn screw_efficiency_forward_and_back_drive() {
    // Only the screw's load-dependent friction: no viscous, drag or rod friction.
    let mut p = PlantParams::default();
    p.motor.viscous_friction_n_m_s_rad = 0.0;
    p.screw.viscous_friction_n_m_s_rad = 0.0;
    p.screw.preload_drag_torque_n_m = 0.0;
    p.rod.viscous_friction_n_s_m = 0.0;
    p.rod.coulomb_friction_n = 0.0;
    p.rod.static_friction_n = 0.0;
    let eta = p.screw.efficiency;
    let weight = p.moving_mass_kg() * p.load.gravity_m_s2;
    let ideal = p.metres_per_rad() * weight; // frictionless holding torque

    let lifting = steady(p.clone(), 3.0);
    let s = lifting.state();
    assert!(s.v_rod_m_s > 0.01 && s.rod_acceleration_m_s2.abs() < 1e-3, "steady lift");
    let forward = ideal / s.motor_torque_n_m;
    assert!((forward - eta).abs() < 1e-5, "forward efficiency {forward} vs {eta}");

    let lowering = steady(p, -3.0);
    let s = lowering.state();
    assert!(s.v_rod_m_s < -0.01 && s.rod_acceleration_m_s2.abs() < 1e-3, "steady lowering");
    let back = s.motor_torque_n_m / ideal;
    assert!((back - (2.0 - 1.0 / eta)).abs() < 1e-5, "back-drive efficiency {back} vs {}", 2.0 - 1.0 / eta);
}

#[test]
fn steady_torque_matches_the_full_friction_balance() {
    for du in [3.0, -3.0] {
        let p = PlantParams::default();
        let plant = steady(p.clone(), du);
        let s = plant.state();
        assert!(s.rod_acceleration_m_s2.abs() < 1e-3, "steady");
        let (w, v) = (s.omega_m_rad_s, s.v_rod_m_s);
        let r = p.metres_per_rad();
        let rod = &p.rod;
        // Rod: seal/guide friction with Stribeck, tanh regularised.
        let stribeck = rod.coulomb_friction_n
            + (rod.static_friction_n - rod.coulomb_friction_n) * (-(v / rod.stribeck_velocity_m_s).powi(2)).exp();
        let f_rod = rod.viscous_friction_n_s_m * v + stribeck * (v / p.friction.regularisation_velocity_m_s).tanh();
        let f_ax = s.load_force_n + f_rod;
        assert!((s.axial_force_n - f_ax).abs() < 1e-3, "nut force {} vs {f_ax}", s.axial_force_n);
        // Screw: viscous + (drag + r μ |F|) sgn(ω); motor: viscous.
        let mu = (1.0 - p.screw.efficiency) / p.screw.efficiency;
        let sgn = (w * r / p.friction.regularisation_velocity_m_s).tanh();
        let torque = p.motor.viscous_friction_n_m_s_rad * w
            + p.screw.viscous_friction_n_m_s_rad * w
            + (p.screw.preload_drag_torque_n_m + r * mu * f_ax.abs()) * sgn
            + r * f_ax;
        assert!(
            (s.motor_torque_n_m - torque).abs() < 1e-5 * torque.abs(),
            "du = {du}: T_e {} vs {torque} at ω = {w}",
            s.motor_torque_n_m
        );
    }
}
