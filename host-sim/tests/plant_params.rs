//! The rig file: parses, equals the built-in default, agrees with what the
//! controller believes, and refuses bad values naming the field.

mod plant_support;

use host_sim::plant::{Plant, PlantParams};
use plant_support::{rig_toml_path, rig_toml_plant_and_rest};
use servo_core::ControlParams;

#[test]
fn rig_toml_parses_validates_and_equals_default() {
    let loaded = PlantParams::load(&rig_toml_path()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(loaded, PlantParams::default());
    assert_eq!(PlantParams::default().validate(), Ok(()));
}

#[test]
fn plant_defaults_match_the_controllers_beliefs() {
    let p = PlantParams::default();
    let c = ControlParams::DEFAULT;
    let close = |a: f64, b: f32, rel: f64| (a - f64::from(b)).abs() <= rel * a.abs();
    assert_eq!(p.motor.pole_pairs, c.motor.pole_pairs);
    assert!(close(p.motor.phase_resistance_ohm, c.motor.phase_resistance_ohm, 1e-6));
    assert!(close(p.motor.inductance_d_h, c.motor.inductance_d_h, 1e-6));
    assert!(close(p.motor.inductance_q_h, c.motor.inductance_q_h, 1e-6));
    assert!(close(p.motor.flux_linkage_wb, c.motor.flux_linkage_wb, 1e-6));
    assert!(close(p.screw.lead_m, c.drive_train.screw_lead_m, 1e-6));
    assert!(close(p.screw.efficiency, c.drive_train.screw_efficiency, 1e-6));
    let rotating = p.motor_side_inertia_kg_m2() + p.screw.inertia_kg_m2;
    assert!(close(rotating, c.drive_train.rotating_inertia_kg_m2, 1e-6), "rotating inertia {rotating}");
    assert!(close(p.moving_mass_kg(), c.drive_train.moving_mass_kg, 1e-6));
    // Every viscous term reflected to the motor shaft adds up to the
    // controller's single coefficient (within 2 %).
    let r = p.metres_per_rad();
    let viscous = p.motor.viscous_friction_n_m_s_rad
        + p.screw.viscous_friction_n_m_s_rad
        + p.rod.viscous_friction_n_s_m * r * r;
    assert!(close(viscous, c.drive_train.viscous_friction_n_m_s_rad, 0.02), "viscous {viscous}");
    assert_eq!(p.sensors.encoder_counts_per_rev, c.encoder.counts_per_rev);
    assert!(close(p.integration.pwm_frequency_hz, c.rates.pwm_frequency_hz, 1e-9));
    // Rated thrust is the payload weight standing vertical (Table 1: 1.38 kN).
    let weight = p.moving_mass_kg() * p.load.gravity_m_s2;
    assert!((weight - 1380.0).abs() < 1.0, "weight {weight}");
}

/// The rig file with exactly one occurrence of `from` in its `[plant]`
/// part replaced (the `[control]` tables are left as they are).
fn rig_with(from: &str, to: &str) -> String {
    let (plant, rest) = rig_toml_plant_and_rest();
    assert_eq!(plant.matches(from).count(), 1, "pattern {from:?} must occur once in [plant]");
    plant.replacen(from, to, 1) + &rest
}

fn refusal(text: &str) -> (String, String) {
    let e = PlantParams::from_toml_str(text).expect_err("must be refused");
    (e.field, e.reason)
}

#[test]
fn negative_zero_and_non_finite_values_are_refused_by_name() {
    let (field, reason) = refusal(&rig_with("phase_resistance_ohm = 0.12", "phase_resistance_ohm = -0.12"));
    assert_eq!(field, "plant.motor.phase_resistance_ohm");
    assert_eq!(reason, "must be > 0");

    let (field, _) = refusal(&rig_with("inertia_kg_m2 = 0.74e-4", "inertia_kg_m2 = 0.0"));
    assert_eq!(field, "plant.screw.inertia_kg_m2");

    let (field, reason) = refusal(&rig_with("flux_linkage_wb = 0.0175", "flux_linkage_wb = nan"));
    assert_eq!(field, "plant.motor.flux_linkage_wb");
    assert_eq!(reason, "must be finite");

    let (field, reason) = refusal(&rig_with("coulomb_friction_n = 30.0", "coulomb_friction_n = -1.0"));
    assert_eq!(field, "plant.rod.coulomb_friction_n");
    assert_eq!(reason, "must be >= 0");

    let (field, _) = refusal(&rig_with("efficiency = 0.9", "efficiency = 1.2"));
    assert_eq!(field, "plant.screw.efficiency");

    let (field, _) = refusal(&rig_with("static_friction_n = 45.0", "static_friction_n = 20.0"));
    assert_eq!(field, "plant.rod.static_friction_n");
}

#[test]
fn missing_and_unknown_fields_are_refused_by_dotted_path() {
    let (field, reason) = refusal(&rig_with("phase_resistance_ohm = 0.12\n", ""));
    assert_eq!(field, "plant.motor");
    assert!(reason.contains("missing field `phase_resistance_ohm`"), "{reason}");

    let (field, reason) =
        refusal(&rig_with("phase_resistance_ohm = 0.12\n", "phase_resistance_ohm = 0.12\nresistence = 1.0\n"));
    assert!(field.starts_with("plant.motor"), "{field}");
    assert!(reason.contains("unknown field `resistence`"), "{reason}");

    let (field, reason) = refusal(&rig_with("pole_pairs = 4", "pole_pairs = 4.5"));
    assert_eq!(field, "plant.motor.pole_pairs");
    assert!(reason.contains("invalid type"), "{reason}");

    let (field, _) = refusal("[control]\nx = 1\n");
    assert_eq!(field, "plant");
}

#[test]
fn other_tables_in_the_rig_file_are_left_alone() {
    // The controller's [control] tables live in the same file; the plant
    // loader neither reads nor judges them (nor any other table).
    let (plant, _) = rig_toml_plant_and_rest();
    let text = format!("{plant}\n[control]\nanything = 1\n[scenario.x]\ny = \"z\"\n");
    assert_eq!(PlantParams::from_toml_str(&text), Ok(PlantParams::default()));
}

#[test]
fn the_plant_chooses_its_substeps_and_the_file_sets_a_minimum() {
    let (field, reason) = refusal(&rig_with("substeps_per_pwm_period = 1", "substeps_per_pwm_period = 0"));
    assert_eq!(field, "plant.integration.substeps_per_pwm_period");
    assert!(reason.contains("1..="), "{reason}");

    // A friction regularisation ten times sharper makes the screw's tanh
    // region ten times steeper: the rig loads, and the plant takes the
    // steps the rule asks for (rate·h <= 2.5 for a relaxation) without a
    // hand edit of the file.
    let sharp = rig_with("regularisation_velocity_m_s = 1.0e-4", "regularisation_velocity_m_s = 1.0e-5");
    let p = PlantParams::from_toml_str(&sharp).unwrap_or_else(|e| panic!("must load: {e}"));
    assert_eq!(p.integration.substeps_per_pwm_period, 1);
    let rates = p.fastest_rates_per_s();
    let screw = rates.iter().find(|(n, _)| *n == "screw friction regularisation").unwrap().1;
    let expected = (screw / (2.5 * 20_000.0)).ceil() as u32;
    assert!(expected > 1);
    assert_eq!(p.substeps(), expected);
    assert!(screw * p.max_step_s() <= 2.5);
    // One substep fewer would break the rule: the choice is the fewest.
    assert!(screw / (20_000.0 * f64::from(expected - 1)) > 2.5);
    Plant::try_new(p.clone(), 1).unwrap_or_else(|e| panic!("must construct: {e}"));

    // The file's value is a minimum: asking for more is kept.
    let more = sharp.replacen("substeps_per_pwm_period = 1\n", "substeps_per_pwm_period = 32\n", 1);
    assert_eq!(PlantParams::from_toml_str(&more).unwrap().substeps(), 32);

    // The shipped rig at 2 % payload: the rod's regularisation needs two
    // steps per period (once a construction panic).
    let mut light = PlantParams::default();
    light.rod.payload_mass_kg *= 0.02;
    assert_eq!(light.validate(), Ok(()));
    assert_eq!(light.substeps(), 2);
    Plant::try_new(light, 1).unwrap_or_else(|e| panic!("2 % payload must construct: {e}"));

    // A rate no affordable step resolves is refused, naming the field
    // that makes it and the bound.
    let (field, reason) =
        refusal(&rig_with("regularisation_velocity_m_s = 1.0e-4", "regularisation_velocity_m_s = 1.0e-8"));
    assert_eq!(field, "plant.friction.regularisation_velocity_m_s");
    assert!(reason.contains("at most 64") && reason.contains("must be <="), "{reason}");
}

#[test]
fn physical_bounds_are_refused_naming_the_field_and_the_bound() {
    let (field, reason) = refusal(&rig_with("efficiency = 0.9", "efficiency = 0.45"));
    assert_eq!(field, "plant.screw.efficiency");
    assert!(reason.contains("self-locking") && reason.contains("> 0.5"), "{reason}");

    let (field, reason) = refusal(&rig_with("lead_error_m_per_m = 0.0", "lead_error_m_per_m = 0.01"));
    assert_eq!(field, "plant.screw.lead_error_m_per_m");
    assert!(reason.contains("1e-3"), "{reason}");

    let (field, _) = refusal(&rig_with("holding_torque_n_m = 2.5", "holding_torque_n_m = -2.5"));
    assert_eq!(field, "plant.brake.holding_torque_n_m");
    let (field, _) = refusal(&rig_with("engage_time_s = 0.025", "engage_time_s = -0.025"));
    assert_eq!(field, "plant.brake.engage_time_s");
    let (field, _) = refusal(&rig_with("encoder_zero_rad = 0.0", "encoder_zero_rad = inf"));
    assert_eq!(field, "plant.sensors.encoder_zero_rad");
}

#[test]
fn try_new_refuses_invalid_parameters() {
    let mut p = PlantParams::default();
    p.deformation.contact.preload_n = 0.0;
    let e = Plant::try_new(p, 1).expect_err("zero preload gives infinite contact compliance slope");
    assert_eq!(e.to_string(), "plant.deformation.contact.preload_n: must be > 0");
}
