//! The PMSM and averaged inverter against closed forms.

mod plant_support;

use host_sim::plant::inverter::duties_for_dq;
use host_sim::plant::{Plant, PlantParams};
use plant_support::{run_aligned, viscous_only, PWM_PERIOD_S};

const BUS_V: f64 = 48.0;

/// With no axial load and i_q = 0 the rotor makes no torque and stays put:
/// a d-axis voltage step then sees a pure R-L circuit,
/// `i_d(t) = (V/R)(1 − e^{−t R/L_d})`.
#[test]
fn d_axis_voltage_step_follows_the_rl_closed_form() {
    let p = PlantParams::default();
    let (r, l) = (p.motor.phase_resistance_ohm, p.motor.inductance_d_h);
    let mut plant = Plant::new(p, 7);
    plant.set_initial_state(0.0, 0.0); // horizontal: no load, no holding current
    let u_d = 1.5;
    let duty = duties_for_dq(u_d, 0.0, 0.0, BUS_V);
    let mut t = 0.0;
    for _ in 0..200 {
        plant.advance_duties(Some(duty), BUS_V, PWM_PERIOD_S);
        t += PWM_PERIOD_S;
        let s = plant.state();
        let expected = u_d / r * (1.0 - (-t * r / l).exp());
        assert!((s.i_d_a - expected).abs() < 1e-9 * (u_d / r), "t={t}: i_d {} vs {expected}", s.i_d_a);
        assert!(s.i_q_a.abs() < 1e-12, "no q current: {}", s.i_q_a);
        assert!(s.theta_m_rad.abs() < 1e-15 && s.omega_m_rad_s.abs() < 1e-15, "rotor must stay put");
        // Phase a carries the whole d current at θ_e = 0; b and c split its return.
        let [a, b, c] = s.phase_current_a;
        assert!((a - s.i_d_a).abs() < 1e-12 && (b + 0.5 * s.i_d_a).abs() < 1e-12 && (c + 0.5 * s.i_d_a).abs() < 1e-12);
    }
}

/// The same step at an arbitrary rotor angle: the Park transform uses the
/// true electrical angle p·θ_m, so the current lands on the d axis and the
/// phase currents are `i_d cos(θ_e − k 2π/3)`.
#[test]
fn park_frame_follows_the_true_electrical_angle() {
    let p = PlantParams::default();
    let (r, l) = (p.motor.phase_resistance_ohm, p.motor.inductance_d_h);
    let pole_pairs = f64::from(p.motor.pole_pairs);
    let mut plant = Plant::new(p, 7);
    let theta_m = 0.37;
    plant.set_initial_state(theta_m, 0.0);
    let theta_e = pole_pairs * theta_m;
    let duty = duties_for_dq(2.0, 0.0, theta_e, BUS_V);
    let t = 40.0 * PWM_PERIOD_S;
    plant.advance_duties(Some(duty), BUS_V, t);
    let s = plant.state();
    let expected = 2.0 / r * (1.0 - (-t * r / l).exp());
    assert!((s.i_d_a - expected).abs() < 1e-9 * expected);
    assert!(s.i_q_a.abs() < 1e-9 * expected);
    for k in 0..3 {
        let phase = theta_e - k as f64 * 2.0 * std::f64::consts::PI / 3.0;
        assert!((s.phase_current_a[k] - expected * phase.cos()).abs() < 1e-9 * expected);
    }
}

/// A constant q-voltage on an unloaded, viscous-only drive settles where
/// the steady d-q equations and the torque balance close:
/// `0 = −R i_d + ω_e L_q i_q`, `u_q = R i_q + ω_e (L_d i_d + ψ)`,
/// `1.5 p ψ i_q = B ω_m` with `B = B_m + B_s + B_n (L/2π)²`.
#[test]
fn constant_q_voltage_settles_at_the_dc_motor_speed() {
    let p = viscous_only(PlantParams::default());
    let m = p.motor.clone();
    let r = p.metres_per_rad();
    let b = m.viscous_friction_n_m_s_rad + p.screw.viscous_friction_n_m_s_rad + p.rod.viscous_friction_n_s_m * r * r;
    let pp = f64::from(m.pole_pairs);
    let k_t = 1.5 * pp * m.flux_linkage_wb;
    let u_q = 6.0;
    // Residual of the q equation at speed ω, using i_q = Bω/K_t and i_d from the d equation.
    let residual = |w: f64| {
        let w_e = pp * w;
        let i_q = b * w / k_t;
        let i_d = w_e * m.inductance_q_h * i_q / m.phase_resistance_ohm;
        m.phase_resistance_ohm * i_q + w_e * (m.inductance_d_h * i_d + m.flux_linkage_wb) - u_q
    };
    let (mut lo, mut hi) = (0.0, u_q / (pp * m.flux_linkage_wb));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 { hi = mid } else { lo = mid }
    }
    let w_expected = 0.5 * (lo + hi);

    let mut plant = Plant::new(p, 3);
    plant.set_initial_state(0.0, 0.0);
    run_aligned(&mut plant, 0.0, u_q, BUS_V, 0.3);
    let s = plant.state();
    assert!((s.omega_m_rad_s - w_expected).abs() < 1e-4 * w_expected, "ω {} vs {w_expected}", s.omega_m_rad_s);
    assert!((s.i_q_a - b * w_expected / k_t).abs() < 1e-3 * (b * w_expected / k_t), "i_q {}", s.i_q_a);
    // The rod follows the screw at r ω.
    assert!((s.v_rod_m_s - r * w_expected).abs() < 1e-4 * r * w_expected);
}
