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
fn a_value_off_by_a_unit_is_refused_naming_its_own_field() {
    // A lead in millimetres, a payload in grams: each named as itself, not
    // as the stiff rate it would make the integrator face.
    for (edit, field, bound) in [
        (("\nlead_m = 0.005", "\nlead_m = 5.0"), "plant.screw.lead_m", "<= 0.1 m"),
        (("payload_mass_kg = 136.5", "payload_mass_kg = 136500.0"), "plant.rod.payload_mass_kg", "rated thrust"),
    ] {
        let text = DEFAULT_RIG_TOML.replace(edit.0, edit.1);
        assert_ne!(text, DEFAULT_RIG_TOML, "the test's edit must hit the file");
        let err = RigConfig::from_toml(&text, "units.toml").unwrap_err().to_string();
        assert!(err.starts_with(&format!("units.toml: {field}")) && err.contains(bound), "{err}");
    }
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

mod family {
    use host_sim::config::{RigConfig, DEFAULT_RIG_TOML};
    use host_sim::rigs::{load_family, write_family, FamilySpec, C7_LEAD_ERROR_M_PER_M};

    fn within(x: f64, base: f64, lo: f64, hi: f64, what: &str) {
        let r = x / base;
        assert!(r >= lo - 1e-12 && r <= hi + 1e-12, "{what}: ×{r} outside [{lo}, {hi}]");
    }

    #[test]
    fn a_drawn_family_loads_stays_within_its_tolerances_and_repeats_from_its_seed() {
        let dir = tempfile::tempdir().unwrap();
        let spec = FamilySpec::default();
        let list = write_family(DEFAULT_RIG_TOML, "params/rig.toml", &spec, 12, 5, true, dir.path()).unwrap();
        assert_eq!(list.len(), 17);
        let rigs = load_family(dir.path()).unwrap();
        assert_eq!(rigs.len(), 17);
        let base = RigConfig::nominal().unwrap().plant;
        for r in &rigs {
            let p = &r.rig.plant;
            let n = &r.name;
            within(p.deformation.screw_axial.youngs_modulus_pa, base.deformation.screw_axial.youngs_modulus_pa, 0.85, 1.15, n);
            within(p.coupling.torsional_stiffness_n_m_rad, base.coupling.torsional_stiffness_n_m_rad, 0.85, 1.15, n);
            within(p.rod.coulomb_friction_n, base.rod.coulomb_friction_n, 0.7, 1.3, n);
            within(p.rod.viscous_friction_n_s_m, base.rod.viscous_friction_n_s_m, 0.7, 1.3, n);
            let mu = |eta: f64| (1.0 - eta) / eta;
            within(mu(p.screw.efficiency), mu(base.screw.efficiency), 0.7, 1.3, n);
            within(p.rod.payload_mass_kg, base.rod.payload_mass_kg, 0.02, 1.10, n);
            within(p.motor.rotor_inertia_kg_m2, base.motor.rotor_inertia_kg_m2, 0.9, 1.1, n);
            within(p.motor.phase_resistance_ohm, base.motor.phase_resistance_ohm, 0.9, 1.4, n);
            within(p.motor.inductance_q_h, base.motor.inductance_q_h, 0.9, 1.1, n);
            within(p.motor.flux_linkage_wb, base.motor.flux_linkage_wb, 0.9, 1.03, n);
            assert!(p.screw.lead_error_m_per_m.abs() <= C7_LEAD_ERROR_M_PER_M, "{n}");
            assert!((0.0..std::f64::consts::TAU).contains(&p.sensors.encoder_zero_rad), "{n}");
            // The drive's belief is the base's, but for the load the user
            // states: the rig's weight at its tilt.
            let mut control = r.rig.control;
            let weight = (p.moving_mass_kg() * 9.81) as f32;
            assert!((control.startup.expected_load_force_n - weight).abs() <= 1e-3 * weight, "{n}");
            control.startup.expected_load_force_n = 1380.0;
            assert_eq!(control, RigConfig::nominal().unwrap().control, "{n}");
        }
        // Drawn rigs differ from each other; the corners are what they say.
        assert_ne!(rigs[0].rig.plant, rigs[1].rig.plant);
        let corner = |name: &str| &rigs.iter().find(|r| r.name == name).unwrap().rig.plant;
        assert!((corner("corner_softer").coupling.torsional_stiffness_n_m_rad - 0.85 * 6000.0).abs() < 1e-9);
        assert!((corner("corner_stiffer").deformation.contact.coefficient_m_per_n2_3 - 4.29e-7 / 1.15).abs() < 1e-18);
        assert!((corner("corner_heavier").rod.payload_mass_kg - 1.1 * 136.5).abs() < 1e-9);
        assert!((corner("corner_friction").rod.static_friction_n - 1.3 * 45.0).abs() < 1e-9);
        let c = corner("corner_combined");
        assert!((c.rod.payload_mass_kg - 1.1 * 136.5).abs() < 1e-9 && (c.rod.coulomb_friction_n - 39.0).abs() < 1e-9);
        assert!((c.coupling.torsional_stiffness_n_m_rad - 5100.0).abs() < 1e-9);
        // Documented: each changed value says so, the header says what the rig is.
        let text = std::fs::read_to_string(dir.path().join("rig_001.toml")).unwrap();
        assert!(text.starts_with("# Rig `rig_001`"), "{}", &text[..200]);
        assert!(text.contains("payload_mass_kg = ") && text.contains("# family draw: base 136.5"));
        // The same seed writes the same files.
        let again = tempfile::tempdir().unwrap();
        write_family(DEFAULT_RIG_TOML, "params/rig.toml", &spec, 12, 5, true, again.path()).unwrap();
        for r in &rigs {
            let name = format!("{}.toml", r.name);
            assert_eq!(std::fs::read(dir.path().join(&name)).unwrap(), std::fs::read(again.path().join(&name)).unwrap());
        }
    }

    #[test]
    fn a_family_folder_without_a_manifest_refuses_a_stray_file_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_family(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no rig files"), "{e}");
        std::fs::write(dir.path().join("rig_a.toml"), DEFAULT_RIG_TOML).unwrap();
        assert_eq!(load_family(dir.path()).unwrap().len(), 1);
        std::fs::write(dir.path().join("rig_b.toml.bak"), DEFAULT_RIG_TOML).unwrap();
        let e = load_family(dir.path()).unwrap_err().to_string();
        assert!(e.contains("rig_b.toml.bak") && e.contains("not a rig file"), "{e}");
    }

    #[test]
    fn a_family_request_that_cannot_be_met_is_refused_naming_the_option() {
        let dir = tempfile::tempdir().unwrap();
        let go = |spec: FamilySpec, count: usize, corners: bool| {
            write_family(DEFAULT_RIG_TOML, "params/rig.toml", &spec, count, 1, corners, dir.path()).unwrap_err().to_string()
        };
        let e = go(FamilySpec::default(), 0, false);
        assert!(e.starts_with("--count:"), "{e}");
        let e = go(FamilySpec { stiffness_tol: 1.0, ..Default::default() }, 3, true);
        assert!(e.starts_with("--stiffness-tol:"), "{e}");
        let e = go(FamilySpec { payload_min: 0.5, payload_max: 0.4, ..Default::default() }, 3, true);
        assert!(e.starts_with("--payload-max:"), "{e}");
        // A payload beyond what the motor holds at its continuous current.
        let e = go(FamilySpec { payload_max: 1.5, ..Default::default() }, 3, true);
        assert!(e.starts_with("--payload-max:") && e.contains("plant.rod.payload_mass_kg"), "{e}");
        // Each end alone is valid, together they are not: both named.
        let e = go(FamilySpec { flux_min: 0.8, payload_max: 1.25, ..Default::default() }, 3, true);
        assert!(e.starts_with("--payload-max with --flux-min:"), "{e}");
        assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none(), "nothing written on a refusal");
    }
}
