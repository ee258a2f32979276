//! The power-up suite on a small sample (the full one is
//! `host-sim power-up --out DIR`): power-ups under the rated vertical load
//! from random rotor angles, encoder zeros and amplifier offsets, every
//! failure case, and ten homings on one rig.

use host_sim::config::RigConfig;
use host_sim::power_up::{homing_repeatability, run_case, suite, Failure};
use rayon::prelude::*;

#[test]
fn power_ups_and_failures_meet_the_issue_bars() {
    let rig = RigConfig::nominal().unwrap();
    let cases = suite(3, 0.01, 0.05, rig.plant.screw.lead_m, 7);
    let rows = cases.par_iter().map(|c| run_case(&rig, c)).collect::<anyhow::Result<Vec<_>>>().unwrap();
    for r in &rows {
        println!("{:28} passed {} {:?} movement {:.4} mm drop {:.4} mm offset {:?}° sag {:?} µm ready {:?} s", r.name, r.passed, r.faults, r.rod_movement_max_mm, r.rod_drop_max_mm, r.electrical_offset_error_deg, r.enable_sag_um, r.time_to_ready_s);
    }
    for r in &rows {
        assert!(r.passed, "{}: {}", r.name, r.verdict);
        if r.failure == Failure::None {
            // The bars themselves, so a change of `judge` cannot loosen them.
            assert!(r.rod_movement_max_mm <= 0.1 && r.electrical_offset_error_deg.unwrap() <= 5.0);
            assert!(r.enable_sag_um.unwrap() <= 10.0);
        } else {
            assert!(r.bridge_off_at_end && r.brake_closed_at_end && r.rod_drop_max_mm <= 0.5, "{}", r.name);
        }
    }
}

#[test]
fn ten_homings_land_within_2_um() {
    let rig = RigConfig::nominal().unwrap();
    let case = &suite(1, 0.02, 0.04, rig.plant.screw.lead_m, 11)[0];
    let zeros = homing_repeatability(&rig, case, 10).unwrap();
    let lo = zeros.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = zeros.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    println!("user zero on the motor side: {zeros:?}; spread {:.3} µm", (hi - lo) * 1e6);
    assert_eq!(zeros.len(), 10);
    assert!((hi - lo) * 1e6 <= 2.0, "homing spread {:.3} µm", (hi - lo) * 1e6);
}

/// The commutation check holds on the rigs a second unit could be (the
/// family's five corners): a right pole count reads within ±5 % of 1, a
/// wrong one (the drive believes 5, the motor has 4: 1.25) is caught at
/// the midpoint threshold, and a mirrored phase sequence is caught (its
/// hold is an unstable balance) before the rod drops 0.5 mm. A stored
/// offset a quarter or half an electrical turn off, which no check sees, is
/// caught by the torque-to-motion watch with the rod dropping ≤ 0.5 mm from
/// where it rested (the heavier corner dropped 0.547 mm with short-circuit
/// braking alone after a half-turn error); the good power-up reaches ready
/// and its `Disable` / `Enable` raises nothing.
#[test]
fn the_commutation_check_keeps_its_margin_on_the_family_corners() {
    let base = RigConfig::nominal().unwrap();
    let cases = suite(1, 0.01, 0.05, base.plant.screw.lead_m, 3);
    let picked: Vec<_> = cases
        .iter()
        .filter(|c| {
            matches!(
                c.failure,
                Failure::None | Failure::WrongPolePairs | Failure::SwappedPhases | Failure::OffsetQuarterTurnOff | Failure::OffsetQuarterTurnBack | Failure::OffsetHalfTurnOff
            )
        })
        .collect();
    let corners = host_sim::rigs::Draw::corners(&host_sim::rigs::FamilySpec::default());
    let base = &base;
    let picked = &picked;
    let runs: Vec<_> = corners.iter().flat_map(|(name, d)| picked.iter().map(move |c| (*name, d.apply(base), *c))).collect();
    let rows = runs.par_iter().map(|(n, rig, c)| run_case(rig, c).map(|r| (*n, r))).collect::<anyhow::Result<Vec<_>>>().unwrap();
    for (rig, r) in &rows {
        println!("{rig:16} {:14} ratio {:.4} drop {:.4} mm {:?}", r.name, r.rotation_ratio, r.rod_drop_max_mm, r.faults);
        assert!(r.passed, "{rig} {}: {}", r.name, r.verdict);
        assert!(r.rod_drop_max_mm <= 0.5, "{rig} {}", r.name);
        match r.failure {
            Failure::None => {
                assert!((r.rotation_ratio - 1.0).abs() <= 0.05, "{rig}: ratio {}", r.rotation_ratio);
                assert!(r.faults.is_empty() && !r.bridge_off_at_end, "{rig}: after Disable / Enable {:?}", r.faults);
            }
            Failure::WrongPolePairs => assert!(r.rotation_ratio > 0.5 * (1.0 + 5.0 / 4.0), "{rig}: ratio {}", r.rotation_ratio),
            // Caught either by the rotation's sign or, where the mirrored
            // hold tipped at once, by the runaway watch; a wrong stored
            // offset by the torque-to-motion watch.
            _ => assert!(r.faults.contains(&"wrong_direction"), "{rig}: {:?}", r.faults),
        }
    }
}

/// The unit whose short circuit sinks fastest: the heaviest payload, the
/// hottest winding, the weakest magnet and the least friction the family
/// allows. Short-circuit braking holds a load torque `T` only at
/// `ω = T R / (1.5 p² ψ²)`, so its sink speed scales with payload × R / ψ²
/// (1.9 times the nominal rig's here); through the brake's 25 ms engage
/// time that alone drops it more than 0.5 mm. Every offset error must
/// still be caught and held within the bound, both quarter turns, half a
/// turn and the wrong pole count, and a good power-up and its Disable /
/// Enable must raise nothing.
#[test]
fn offset_errors_are_held_within_the_bound_on_the_fastest_sinking_unit() {
    let base = RigConfig::nominal().unwrap();
    let spec = host_sim::rigs::FamilySpec::default();
    let f = 1.0 - spec.friction_tol;
    let draw = host_sim::rigs::Draw {
        payload: spec.payload_max,
        resistance: spec.resistance_max,
        flux: spec.flux_min,
        coulomb: f,
        viscous: f,
        screw_mu: f,
        ..host_sim::rigs::Draw::BASE
    };
    let sink_factor = draw.payload * draw.resistance / (draw.flux * draw.flux);
    assert!(sink_factor >= 1.5, "sink factor {sink_factor}");
    let rig = draw.apply(&base);
    let cases = suite(1, 0.01, 0.05, rig.plant.screw.lead_m, 4);
    let picked: Vec<_> = cases
        .iter()
        .filter(|c| {
            matches!(
                c.failure,
                Failure::None
                    | Failure::WrongPolePairs
                    | Failure::OffsetQuarterTurnOff
                    | Failure::OffsetQuarterTurnBack
                    | Failure::OffsetHalfTurnOff
            )
        })
        .collect();
    assert_eq!(picked.len(), 5);
    let rows = picked.par_iter().map(|c| run_case(&rig, c)).collect::<anyhow::Result<Vec<_>>>().unwrap();
    for r in &rows {
        println!("sink factor {sink_factor:.2} {:24} drop {:.4} mm {:?} {}", r.name, r.rod_drop_max_mm, r.faults, r.verdict);
        // `passed` includes the named fault, the bridge off, the brake
        // closed, the drop bound and the stored offset given back bit for
        // bit.
        assert!(r.passed, "{}: {}", r.name, r.verdict);
        assert!(r.rod_drop_max_mm <= 0.5, "{}", r.name);
        if r.failure == Failure::None {
            assert!(r.faults.is_empty() && !r.bridge_off_at_end && r.enable_sag_um.is_some(), "{:?}", r.faults);
        }
    }
}

/// A near-empty rod (2 % of the rated payload) with a stored offset a
/// quarter turn off: the motor makes no torque, and a load that light
/// never shows it once the brake lets go (friction holds the rod still, the
/// loops look settled) until homing asks for a move and the rod falls. The
/// offset must be caught by a check that does not lean on the load, before
/// the brake opens: each offset error is named, the rod drops at most
/// 0.5 mm, and the stored offset comes back unchanged.
#[test]
fn a_light_rod_with_a_wrong_stored_offset_is_caught_before_the_brake_opens() {
    let base = RigConfig::nominal().unwrap();
    let rig = host_sim::rigs::Draw { payload: 0.02, ..host_sim::rigs::Draw::BASE }.apply(&base);
    let cases = suite(0, 0.01, 0.05, rig.plant.screw.lead_m, 2280);
    let picked: Vec<_> = cases.iter().filter(|c| c.failure.offset_error_rad().is_some()).collect();
    assert_eq!(picked.len(), 3);
    let rows = picked.par_iter().map(|c| run_case(&rig, c)).collect::<anyhow::Result<Vec<_>>>().unwrap();
    for r in &rows {
        println!("payload 2 % {:24} drop {:.4} mm movement {:.4} mm {:?} {}", r.name, r.rod_drop_max_mm, r.rod_movement_max_mm, r.faults, r.verdict);
    }
    for r in &rows {
        assert!(r.passed, "{}: {}", r.name, r.verdict);
        assert!(r.faults == ["wrong_direction"] && r.rod_drop_max_mm <= 0.5, "{} {:?}", r.name, r.faults);
    }
}

/// The reaction's angles, alone: a missing torque turns by the quarter the
/// back-EMF's d part points to (`e_d = −ω_e ψ sin δ`), a reversal seen on
/// that trial by half a turn more, a reversed torque by half a turn at once;
/// a verdict after that, or a missing torque on the trial, ends the hold;
/// the user's offset comes back bit for bit, angles kept within ±π.
#[test]
fn the_watch_turns_by_the_emf_then_by_half_a_turn_and_gives_the_offset_back() {
    use servo_core::protection::TorqueWatch;
    use std::f32::consts::{FRAC_PI_2, PI};
    let user = 0.123_456_7_f32;
    for (emf_d, speed, quarter) in [(0.4, 10.0, -FRAC_PI_2), (-0.4, 10.0, FRAC_PI_2), (0.4, -10.0, FRAC_PI_2), (-0.4, -10.0, -FRAC_PI_2)] {
        let mut w = TorqueWatch::new();
        w.arm();
        let trial = w.turn(false, user, emf_d, speed).unwrap();
        assert_eq!(trial, user + quarter, "emf {emf_d} speed {speed}");
        assert!(w.turned() && w.watching());
        // The trial reversed the torque: the other quarter.
        let other = w.turn(true, trial, emf_d, speed).unwrap();
        assert!((other - (user - quarter)).abs() < 1e-6, "{other}");
        assert!(w.turn(true, other, emf_d, speed).is_none() && w.turn(false, other, emf_d, speed).is_none());
        assert_eq!(w.end_turn().to_bits(), user.to_bits());
        assert!(!w.turned() && !w.watching());
        // A trial that leaves the torque missing: no more angles to try.
        let mut w = TorqueWatch::new();
        w.arm();
        w.turn(false, user, emf_d, speed).unwrap();
        assert!(w.turn(false, trial, emf_d, speed).is_none());
        assert_eq!(w.end_turn().to_bits(), user.to_bits());
    }
    // Reversed at once: half a turn, wrapped into ±π, then nothing more.
    let mut w = TorqueWatch::new();
    w.arm();
    let half = w.turn(true, 3.0, 0.0, 0.0).unwrap();
    assert!((half - (3.0 - PI)).abs() < 1e-6 && half.abs() <= PI);
    assert!(w.turn(true, half, 0.0, 0.0).is_none());
    assert_eq!(w.end_turn().to_bits(), 3.0_f32.to_bits());
    let mut w = TorqueWatch::new();
    let q = w.turn(false, 3.0, -1.0, 1.0).unwrap();
    assert!((q - (3.0 + FRAC_PI_2 - 2.0 * PI)).abs() < 1e-6, "{q}");
}

/// A unit whose hold, after homing near the retracted end, rings on the
/// rod's axial mode instead of settling: K_t/J about 11 % above what the
/// drive believes (flux +1.7 %, inertia −8 %, as held-out rig 2221/017; a
/// light payload raises it further). Near the retracted end the structure
/// is stiffest and the axial mode highest (about 90 Hz), where the shipped
/// 150 Hz torque filter's lag takes the hold's margin: it rings at about
/// ±50 µm and ±27 A of q current.
fn ringing_unit(payload: f64) -> RigConfig {
    let draw = host_sim::rigs::Draw {
        stiffness: 1.0788,
        coulomb: 0.9036,
        viscous: 1.0464,
        screw_mu: 0.8367,
        payload,
        inertia: 0.9186,
        resistance: 1.0484,
        inductance: 1.0365,
        flux: 1.0173,
        lead_error_m_per_m: -0.9588e-4,
        ..host_sim::rigs::Draw::BASE
    };
    draw.apply(&RigConfig::nominal().unwrap())
}

/// On the shipped filter that unit must not be reported ready: the hold
/// after homing never settles, and `StartUp` ends in `lifecycle_timeout`
/// with the bridge off and the brake closed. Before the settle check it
/// was reported ready while it rang.
///
/// A user who clears the fault and enables anyway gets the ringing hold;
/// `Disable` then closes the brake on it, so the q current of any one
/// period is a sample of the swing, not the load. The next `Enable` must
/// still pre-load the load's torque: with a sampled swing for a preload
/// (3 A for a 10 A load) the brake carried the rest and the rod sagged
/// about 0.1 mm when it let go. The bar is the suite's 10 µm.
#[test]
fn a_hold_that_rings_after_homing_is_refused_not_ready_and_enable_still_preloads_the_load() {
    use host_sim::plant::Plant;
    use host_sim::sim::ClosedLoop;
    use servo_core::{Command, Controller, FaultSet, Mode, Readiness};
    let rig = ringing_unit(1.0);
    let case = &suite(1, 0.01, 0.03, rig.plant.screw.lead_m, 17)[0];
    let mut plant = Plant::try_new(rig.plant.clone(), case.seed).unwrap();
    plant.set_initial_state(case.rotor_angle_rad, std::f64::consts::FRAC_PI_2);
    plant.engage_brake();
    plant.bench_sensors_mut().encoder_zero_rad = case.encoder_zero_rad;
    let mut cl = ClosedLoop::new(Controller::try_new(rig.control).unwrap(), plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.override_pending(servo_core::PwmCommand::OFF);
    cl.controller.power_up().unwrap();
    let periods = |s: f64| (s / f64::from(rig.control.pwm_period_s())).ceil() as u64;
    cl.controller.command(Command::StartUp).unwrap();
    let mut homed_at = None;
    for _ in 0..periods(30.0) {
        cl.step();
        let c = &cl.controller;
        assert!(
            !(c.faults().is_empty() && c.mode() == Mode::Running && c.readiness() == Readiness::ALL),
            "reported ready at {:.2} s on a ringing hold",
            cl.time_s()
        );
        if homed_at.is_none() && c.readiness().contains(Readiness::HOMED) {
            homed_at = Some(cl.time_s());
        }
        if !c.faults().is_empty() {
            break;
        }
    }
    let homed_at = homed_at.expect("homing never found the stop");
    assert_eq!(cl.controller.faults(), FaultSet::LIFECYCLE_TIMEOUT);
    // Refused within the settle timeout after the back-off, not at once.
    let refused_after_s = cl.time_s() - homed_at;
    println!("homed at {homed_at:.2} s, refused {refused_after_s:.2} s later");
    assert!(refused_after_s > f64::from(rig.control.commutation.settle_timeout_s), "{refused_after_s}");
    for _ in 0..periods(0.5) {
        cl.step();
    }
    assert!(!cl.pending_command().enable && cl.plant.state().brake_engaged, "bridge off and brake closed after the refusal");
    assert!(!cl.controller.readiness().contains(Readiness::HOMED), "a refused settle leaves the drive un-homed");

    cl.controller.command(Command::ClearFaults).unwrap();
    cl.controller.command(Command::Enable).unwrap();
    for _ in 0..periods(0.8) {
        cl.step();
    }
    cl.controller.command(Command::Disable).unwrap();
    for _ in 0..periods(0.3) {
        cl.step();
    }
    assert_eq!(cl.controller.mode(), Mode::Disabled);
    let before = cl.plant.state().x_rod_m;
    cl.controller.command(Command::Enable).unwrap();
    let mut sag = 0.0f64;
    for _ in 0..periods(0.5) {
        cl.step();
        sag = sag.max((cl.plant.state().x_rod_m - before).abs());
    }
    println!("enable sag after a ringing hold: {:.2} µm", sag * 1e6);
    assert!(sag * 1e6 <= 10.0, "enable sag {:.1} µm", sag * 1e6);
}

/// The same unit commissioned: its torque filter chosen by its own test
/// moves (`tune filter`) moves the corner above the mode's reach, and every
/// power-up is ready with a quiet hold: the position error's peak-to-peak
/// within the torque watch's 10 µm travel and the q current's within 2 A,
/// at a light and at the rated payload.
#[test]
fn the_same_unit_with_its_own_filter_is_ready_with_a_quiet_hold() {
    for payload in [0.4873, 1.0] {
        let (rig, choice) = host_sim::tuning::filter::retune(&ringing_unit(payload), 1).unwrap();
        let cases: Vec<_> = suite(2, 0.01, 0.05, rig.plant.screw.lead_m, 17).into_iter().filter(|c| c.failure == Failure::None).collect();
        let rows = cases.par_iter().map(|c| run_case(&rig, c)).collect::<anyhow::Result<Vec<_>>>().unwrap();
        for r in &rows {
            println!(
                "payload {payload} filter {} Hz {:14} hold {:?} µm {:?} A sag {:?} µm {}",
                choice.torque_filter_hz, r.name, r.hold_error_pp_um, r.hold_current_pp_a, r.enable_sag_um, r.verdict
            );
            assert!(r.passed, "{}: {}", r.name, r.verdict);
            assert!(r.hold_error_pp_um.unwrap() <= 10.0 && r.hold_current_pp_a.unwrap() <= 2.0, "{}", r.name);
        }
    }
}
