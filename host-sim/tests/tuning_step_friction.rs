//! The speed step's design model with the friction the identification finds
//! and the drive's feedforward of it, against the full plant and against
//! the friction law's own consequences.

use host_sim::config::RigConfig;
use host_sim::rigs::{Draw, FamilySpec};
use host_sim::tuning::design::{DesignPlant, StepFriction};
use host_sim::tuning::model::{self, Gains, StepKind};
use host_sim::tuning::simcheck::Loop;
use host_sim::tuning::{self, cli::bench_cases, Identified};

fn corner(name: &str) -> RigConfig {
    let spec = FamilySpec::default();
    let (_, d) = Draw::corners(&spec).into_iter().find(|(n, _)| *n == name).expect("a corner of that name");
    d.apply(&RigConfig::nominal().unwrap())
}

/// The 12 Hz / 5 % speed ask on `rig`: (full plant's overshoot, the design
/// model's prediction with friction, the same gains' frictionless model).
fn speed_step_on(rig: &RigConfig) -> (f64, f64, f64) {
    let (speed, cur) = tuning::simulate_identification_captures(rig, 1).unwrap();
    let (m, e) = tuning::identify(&speed, Some(&cur), &rig.control).unwrap();
    let id = Identified::from_fits(&m, e.as_ref());
    let case = bench_cases().into_iter().find(|c| c.name == "c300_s12_os5_p2").unwrap();
    let prop = tuning::propose(rig, Some(&id), case.asked, false).unwrap();
    let checked = tuning::check(rig, prop.params, &case.asked, 1).unwrap();
    let step = checked.iter().find(|c| c.target == Loop::Speed && c.spec.chirp.is_none()).unwrap();
    let sim = step.figures.step.as_ref().unwrap().overshoot_pct;
    let g = Gains { current: (prop.current.kp, prop.current.ki), speed: (prop.speed.kp, prop.speed.ki), position_kp: prop.position.kp };
    let a = step.spec.amplitude;
    let dur = model::speed_step_duration_s(case.asked.speed_bw_hz);
    let os = |p: &DesignPlant| model::overshoot_pct(&model::step_response(p, &g, StepKind::Speed, a, dur), a);
    let mut bare = prop.plant.clone();
    bare.step_friction = None;
    (sim, os(&prop.plant), os(&bare))
}

/// On the friction corner (Coulomb, seal stiction and screw friction ×1.3,
/// rated payload) the model with the identified friction and the drive's
/// feedforwards predicts the full plant's speed overshoot within half a
/// point, where the frictionless model with the same gains misses it by
/// more (the viscous feedforward and the Coulomb friction against a
/// feedforward that lags it are what it leaves out). On a light unit (7 %
/// payload, friction a large share of its load) the plant reads below the
/// model by more than that, unexplained (docs/tuning.md), but inside the
/// ask's band.
#[test]
fn the_speed_step_model_with_friction_predicts_the_full_plant() {
    let light = Draw { payload: 0.07, ..Draw::BASE }.apply(&RigConfig::nominal().unwrap());
    for (name, rig, within) in [("corner_friction", corner("corner_friction"), 0.5), ("light", light, 1.0)] {
        let (sim, with, bare) = speed_step_on(&rig);
        println!("{name}: full plant {sim:.2} %, model with friction {with:.2} %, frictionless {bare:.2} %");
        assert!((sim - with).abs() <= within, "{name}: the model with friction says {with:.2} %, the plant {sim:.2} %");
        assert!((with - 5.0).abs() <= 0.1, "{name}: the design missed its own ask: {with:.2} %");
        if name == "corner_friction" {
            assert!((sim - bare).abs() > 2.0 * (sim - with).abs(), "{name}: the frictionless model was expected to miss more: {bare:.2} % against {sim:.2} %");
        }
    }
}

fn rigid_plant() -> DesignPlant {
    let p = RigConfig::nominal().unwrap().control;
    let mut d = DesignPlant::from_params(&p, 2.0e-4, 2.0e-4);
    d.speed_setpoint_weight = 0.5;
    d
}

fn gains(d: &DesignPlant) -> Gains {
    let cur = (d.l_h * 2000.0, d.r_ohm * 2000.0);
    Gains { current: cur, speed: (0.15, 4.0), position_kp: 0.0 }
}

/// Static friction holds at rest: a breakaway level above what the step's
/// torque reaches keeps the rotor still. Coulomb friction matched by the
/// feedforward leaves the frictionless response but for the feedforward's
/// delay: the friction is there at once, the fed-forward current arrives
/// through the torque filter and the current loop, so the rotor lacks at
/// most the Coulomb torque over that delay, `T_c τ / J` of speed.
#[test]
fn static_friction_holds_and_a_matched_feedforward_cancels_coulomb() {
    let d = DesignPlant { viscous_n_m_s_rad: 0.0, ..rigid_plant() };
    let g = gains(&d);
    let (a, dur, tc) = (20.0, 0.3, 0.2);
    let matched = DesignPlant {
        step_friction: Some(StepFriction { coulomb_n_m: tc, feedforward_coulomb_n_m: tc, feedforward_ramp_rad_s: 1.0, ..StepFriction::default() }),
        ..d.clone()
    };
    let (ym, yf) = (model::step_response(&matched, &g, StepKind::Speed, a, dur), model::step_response(&d, &g, StepKind::Speed, a, dur));
    let worst = ym.iter().zip(&yf).map(|(m, f)| (m - f).abs()).fold(0.0, f64::max);
    // The delay: the Butterworth filter's group delay at DC (√2/ω_f), one
    // speed period's hold, the current loop's 1/ω_c and 1.5 PWM periods.
    let tau = std::f64::consts::SQRT_2 / (std::f64::consts::TAU * d.torque_filter_hz) + d.t_speed() + 1.0 / 2000.0 + 1.5 * d.t_pwm();
    let bound = tc * tau / d.inertia_kg_m2;
    println!("matched feedforward: largest difference {worst:.3} rad/s, bound T_c τ/J = {bound:.3} rad/s");
    assert!(worst <= bound && worst > 0.0, "matched feedforward: largest difference {worst:.3} rad/s against T_c τ/J = {bound:.3} rad/s");
    let os = |y: &[f64]| model::overshoot_pct(y, a);
    println!("overshoot: matched {:.2} %, frictionless {:.2} %", os(&ym), os(&yf));
    // Unmatched: without the feedforward the loop winds up the Coulomb
    // torque itself: a slower start than the matched one.
    let unfed = DesignPlant { step_friction: Some(StepFriction { coulomb_n_m: tc, ..StepFriction::default() }), ..d.clone() };
    let yu = model::step_response(&unfed, &g, StepKind::Speed, a, dur);
    let k10 = (0.01 * d.pwm_hz) as usize;
    assert!(yu[k10] < ym[k10] - 0.05 * a, "at 10 ms: {:.2} unfed against {:.2} fed", yu[k10], ym[k10]);
    // Held: a breakaway of 5 N·m, more than kp b a = 1.5 A (0.16 N·m) plus
    // the integral's first 20 ms: the rotor does not move in that time.
    let held = DesignPlant {
        step_friction: Some(StepFriction { coulomb_n_m: 0.2, breakaway_excess_n_m: 4.8, stribeck_rad_s: 2.0, ..StepFriction::default() }),
        ..d.clone()
    };
    let yh = model::step_response(&held, &g, StepKind::Speed, a, 0.02);
    // Friction that carried part of the load at rest leaves the hold current
    // short of it by as much: a torque the integral winds up after the start,
    // while the rotor already turns — a lower peak than from a settled hold.
    let rest = DesignPlant { step_friction: Some(StepFriction { rest_n_m: 0.5 * tc, ..matched.step_friction.unwrap() }), ..d.clone() };
    let yr = model::step_response(&rest, &g, StepKind::Speed, a, dur);
    assert!(os(&yr) < os(&ym) - 0.2, "a hold short by friction at rest: {:.2} % against {:.2} % from the settled hold", os(&yr), os(&ym));
    assert!(yh.iter().all(|w| w.abs() < 1e-2), "the rotor moved against its static friction: {:.3}", yh.iter().fold(0.0f64, |m, w| m.max(w.abs())));
}
