//! The rig file: what the simulator tunes is what the firmware ships.

use host_sim::config::{RigConfig, DEFAULT_RIG_TOML};
use servo_core::ControlParams;

#[test]
fn shipped_control_table_is_the_firmware_default() {
    let rig = RigConfig::nominal().expect("shipped rig parses and validates");
    assert_eq!(rig.control, ControlParams::DEFAULT, "params/rig.toml [control] drifted from src/params/mod.rs");
}

#[test]
fn a_bad_control_field_is_refused_with_its_name() {
    let text = DEFAULT_RIG_TOML.replace("\nki = 753.98224", "\nki = -1.0");
    assert_ne!(text, DEFAULT_RIG_TOML, "the test's edit must hit the file");
    let err = RigConfig::from_toml(&text, "bad.toml").unwrap_err().to_string();
    assert!(err.contains("bad.toml") && err.contains("control.current_pi.ki"), "{err}");
}

#[test]
fn an_unknown_or_missing_field_is_refused_with_its_name() {
    let text = DEFAULT_RIG_TOML.replace("[control.load_estimate]\nfilter_hz", "[control.load_estimate]\nfilter_hertz");
    assert_ne!(text, DEFAULT_RIG_TOML, "the test's edit must hit the file");
    let err = RigConfig::from_toml(&text, "typo.toml").unwrap_err().to_string();
    assert!(err.contains("typo.toml") && err.contains("filter_hertz"), "{err}");
    let text = DEFAULT_RIG_TOML.replace("\ntorque_filter_hz = 150.0", "");
    assert_ne!(text, DEFAULT_RIG_TOML, "the test's edit must hit the file");
    let err = RigConfig::from_toml(&text, "missing.toml").unwrap_err().to_string();
    assert!(err.contains("torque_filter_hz"), "{err}");
}

#[test]
fn a_payload_beyond_what_the_motor_and_brake_hold_is_refused_naming_the_bound() {
    let rig = RigConfig::nominal().unwrap();
    // Holding the weight F against the screw's back-drive torque
    // F L/2π (2 − 1/η) within the winding's continuous current: with
    // K_t = 1.5·4·0.0175 and 12 A, F <= 1.26 / (0.005/2π · 0.8889) N.
    let k_t = 1.5 * 4.0 * 0.0175;
    let f_max = k_t * 12.0 / (0.005 / std::f64::consts::TAU * (2.0 - 1.0 / 0.9));
    let (kg, by) = rig.payload_max_kg();
    assert!((kg - (f_max / 9.81 - 4.2)).abs() < 1e-6, "{kg} vs {}", f_max / 9.81 - 4.2);
    assert!(by.contains("continuous_current_a"), "{by}");
    // The rated payload and 110 % of it (the family's heaviest) hold.
    assert!(kg > 1.1 * 136.5);
    let text = DEFAULT_RIG_TOML.replace("payload_mass_kg = 136.5", "payload_mass_kg = 200.0");
    assert_ne!(text, DEFAULT_RIG_TOML);
    let err = RigConfig::from_toml(&text, "heavy.toml").unwrap_err().to_string();
    assert!(err.contains("heavy.toml") && err.contains("plant.rod.payload_mass_kg") && err.contains("rated thrust"), "{err}");
    assert!(err.contains(&format!("<= {kg:.1} kg")), "{err}");
    // A worn brake is the tighter bound: named as such.
    let text = DEFAULT_RIG_TOML.replace("holding_torque_n_m = 2.5\nrelease_time_s = 0.04", "holding_torque_n_m = 0.9\nrelease_time_s = 0.04");
    assert_ne!(text, DEFAULT_RIG_TOML);
    let err = RigConfig::from_toml(&text, "worn.toml").unwrap_err().to_string();
    assert!(err.contains("plant.brake.holding_torque_n_m"), "{err}");
}

#[test]
fn a_light_payload_that_needs_more_substeps_loads_and_runs() {
    // 2 % of the rated payload: the rod friction's regularisation rate
    // needs two RK4 steps per PWM period; the plant takes them itself.
    let text = DEFAULT_RIG_TOML.replace("payload_mass_kg = 136.5", "payload_mass_kg = 2.73");
    let rig = RigConfig::from_toml(&text, "light.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rig.plant.substeps(), 2);
    host_sim::plant::Plant::try_new(rig.plant, 1).unwrap_or_else(|e| panic!("{e}"));
}
