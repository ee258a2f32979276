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
