//! Helpers shared by the plant integration tests.
#![allow(dead_code)]

use host_sim::plant::inverter::duties_for_dq;
use host_sim::plant::{Plant, PlantParams};

pub const PWM_PERIOD_S: f64 = 50e-6;

pub fn rig_toml_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("params").join("rig.toml")
}

pub fn rig_toml_text() -> String {
    std::fs::read_to_string(rig_toml_path()).expect("params/rig.toml is readable")
}

/// The rig file split into its `[plant.*]` part and the rest (the
/// controller's `[control]` tables and anything else), which may repeat
/// field names such as `phase_resistance_ohm`.
pub fn rig_toml_plant_and_rest() -> (String, String) {
    let text = rig_toml_text();
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let t = line.trim_start();
        if t.starts_with('[') && !t.starts_with("[plant") {
            return (text[..offset].to_string(), text[offset..].to_string());
        }
        offset += line.len();
    }
    (text, String::new())
}

/// Duties applying `(u_d, u_q)` in the rotor frame, aimed at the electrical
/// angle the rotor will have in the middle of the coming period (an ideal
/// voltage-mode FOC with perfect angle knowledge).
pub fn aligned_duties(plant: &Plant, u_d: f64, u_q: f64, period_s: f64) -> [f64; 3] {
    let s = plant.state();
    let p = f64::from(plant.params().motor.pole_pairs);
    let theta_e = p * (s.theta_m_rad + 0.5 * period_s * s.omega_m_rad_s);
    duties_for_dq(u_d, u_q, theta_e, s.bus_voltage_v)
}

/// Runs `duration_s` applying `(u_d, u_q)` aligned each PWM period.
pub fn run_aligned(plant: &mut Plant, u_d: f64, u_q: f64, bus_v: f64, duration_s: f64) {
    let periods = (duration_s / PWM_PERIOD_S).round() as usize;
    for _ in 0..periods {
        let d = aligned_duties(plant, u_d, u_q, PWM_PERIOD_S);
        plant.advance_duties(Some(d), bus_v, PWM_PERIOD_S);
    }
}

/// Default parameters with every Coulomb and Stribeck friction removed and
/// η = 1: only viscous terms remain, so steady states have closed forms.
pub fn viscous_only(mut p: PlantParams) -> PlantParams {
    p.screw.efficiency = 1.0;
    p.screw.preload_drag_torque_n_m = 0.0;
    p.rod.coulomb_friction_n = 0.0;
    p.rod.static_friction_n = 0.0;
    p
}

/// Default parameters with noise switched off (quantisation stays).
pub fn noiseless(mut p: PlantParams) -> PlantParams {
    p.sensors.current_noise_a = 0.0;
    p.sensors.bus_voltage_noise_v = 0.0;
    p.sensors.load_cell_noise_n = 0.0;
    p
}
