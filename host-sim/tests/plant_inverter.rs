//! The inverter with its switches off: freewheel diodes only.

mod plant_support;

use std::f64::consts::{FRAC_PI_2, TAU};

use host_sim::plant::{Drive, Leg, Plant, PlantParams};
use plant_support::PWM_PERIOD_S;
use servo_core::PwmCommand;

const BUS_V: f64 = 48.0;

/// Vertical, rated load, held at 450 mm, then PWM off: the load falls (no
/// holding brake on this rig; the inverter's diodes are under test).
fn falling_plant() -> Plant {
    let mut params = PlantParams::default();
    params.brake.fitted = false;
    let mut plant = Plant::new(params, 1);
    let lead = plant.params().screw.lead_m;
    plant.set_initial_state(0.45 * TAU / lead, FRAC_PI_2);
    plant
}

#[test]
fn switching_off_drives_the_current_to_zero_through_the_diodes() {
    let mut plant = falling_plant();
    let i0 = plant.state().i_q_a;
    let l = plant.params().motor.inductance_q_h;
    assert!(i0 > 10.0, "holding current {i0}");
    // Two phases in series (2L) against ≈ V_bus: the current reaches zero in
    // about 2 L I / V_bus (the back-EMF is still negligible).
    let t_decay = 2.0 * l * i0 / BUS_V;
    let mut t = 0.0;
    let mut returned_j = 0.0;
    while t < 1.5 * t_decay {
        let before = plant.energy_audit().electrical_input_w;
        plant.advance(&PwmCommand::OFF, BUS_V, PWM_PERIOD_S / 4.0);
        returned_j -= 0.5 * (before + plant.energy_audit().electrical_input_w) * PWM_PERIOD_S / 4.0;
        t += PWM_PERIOD_S / 4.0;
    }
    let s = plant.state();
    assert_eq!(s.phase_current_a, [0.0; 3], "all diodes blocking after {t} s");
    assert_eq!(plant.drive(), Drive::Diodes([Leg::Open; 3]));
    assert!(!s.inverter_enabled);
    // The magnetic energy went back into the bus (minus copper loss).
    let magnetic = 0.75 * l * i0 * i0;
    assert!(returned_j > 0.5 * magnetic && returned_j < magnetic, "returned {returned_j} J of {magnetic} J");
}

#[test]
fn below_the_bus_voltage_the_back_emf_drives_no_current() {
    let mut plant = falling_plant();
    let p = plant.params().clone();
    let k_e = f64::from(p.motor.pole_pairs) * p.motor.flux_linkage_wb;
    // Line-to-line peak back-EMF √3 p ψ ω reaches the bus at this speed.
    let w_threshold = BUS_V / (3f64.sqrt() * k_e);
    plant.advance(&PwmCommand::OFF, BUS_V, 0.5e-3);
    let mut coasted = 0;
    for _ in 0..4000 {
        plant.advance(&PwmCommand::OFF, BUS_V, PWM_PERIOD_S);
        let s = plant.state();
        if s.omega_m_rad_s.abs() < 0.98 * w_threshold {
            assert_eq!(s.phase_current_a, [0.0; 3], "ω = {} < threshold {w_threshold}", s.omega_m_rad_s);
            assert_eq!(s.motor_torque_n_m, 0.0);
            coasted += 1;
        }
    }
    assert!(coasted > 100, "the fall must pass through the coasting range");
}

/// Past the threshold the diodes rectify and brake the fall. The speed
/// settles where the six-pulse bridge's DC output equals the bus:
/// `(3√2/π) V_LL,rms − (3/π) ω_e L I_dc − 2 R I_dc = V_bus`, with the
/// commutation-overlap drop `(3/π) ω_e L I_dc` (standard rectifier theory),
/// and `I_dc` the mean current into the bus.
#[test]
fn overspeed_is_braked_by_diode_rectification_into_the_bus() {
    let mut plant = falling_plant();
    let p = plant.params().clone();
    let pp = f64::from(p.motor.pole_pairs);
    let k_e = pp * p.motor.flux_linkage_wb;
    let w_threshold = BUS_V / (3f64.sqrt() * k_e);
    // Fall for 0.3 s (≈ 0.1 m), then average over 0.1 s.
    plant.advance(&PwmCommand::OFF, BUS_V, 0.3);
    let n = 2000;
    let (mut w_sum, mut p_sum) = (0.0, 0.0);
    for _ in 0..n {
        plant.advance(&PwmCommand::OFF, BUS_V, PWM_PERIOD_S);
        w_sum += plant.state().omega_m_rad_s;
        p_sum += plant.energy_audit().electrical_input_w;
    }
    let w = (w_sum / n as f64).abs();
    let p_bus = -p_sum / n as f64;
    let s = plant.state();
    assert!(s.omega_m_rad_s < 0.0 && s.v_rod_m_s < 0.0, "falling");
    assert!(s.x_rod_m > 0.05, "still inside the stroke");
    assert!(w > w_threshold, "rectification starts only above {w_threshold} rad/s: ω = {w}");
    assert!(p_bus > 100.0, "the fall pumps energy into the bus: {p_bus} W");
    let i_dc = p_bus / BUS_V;
    let w_e = pp * w;
    let v_ll_rms = 3f64.sqrt() * w_e * p.motor.flux_linkage_wb / 2f64.sqrt();
    let v_dc = 3.0 * 2f64.sqrt() / std::f64::consts::PI * v_ll_rms
        - 3.0 / std::f64::consts::PI * w_e * p.motor.inductance_q_h * i_dc
        - 2.0 * p.motor.phase_resistance_ohm * i_dc;
    assert!((v_dc - BUS_V).abs() < 0.03 * BUS_V, "bridge output {v_dc} V at ω = {w} rad/s, I_dc = {i_dc} A");
}

#[test]
fn out_of_range_duties_saturate_and_are_counted() {
    let mut plant = Plant::new(PlantParams::default(), 1);
    plant.advance(&PwmCommand { duty: [1.2, 0.5, f32::NAN], enable: true, brake_release: true }, BUS_V, PWM_PERIOD_S);
    assert_eq!(plant.state().duty_saturation_count, 2);
    assert_eq!(plant.drive(), Drive::Pwm([1.0, 0.5, 0.0]));
    // Phase-to-neutral voltages of duties (1, 0.5, 0): (+24, 0, −24) V.
    let v = plant.state().phase_voltage_v;
    assert!((v[0] - 24.0).abs() < 1e-12 && v[1].abs() < 1e-12 && (v[2] + 24.0).abs() < 1e-12);
}
