//! Property tests on the control core: whatever the samples and commands,
//! the duties stay in [0, 1], nothing the core outputs or keeps is NaN, and
//! every limit holds. Also the building blocks alone: SVPWM, PI, S-curve,
//! the stroke clamp, the I²t model, the observer's forward pass.

use proptest::prelude::*;
use servo_core::foc::{svpwm, AlphaBeta};
use servo_core::motion::ScurveMove;
use servo_core::params::{PiGains, TrajectoryParams};
use servo_core::pi::Pi;
use servo_core::protection::{clamp_to_stroke, ThermalModel};
use servo_core::{Command, ControlParams, Controller, FaultSet, Mode, SensorSample, Telemetry};

const INV_SQRT3: f32 = 0.577_350_26;

/// One period's input: a sample and maybe a command before it.
#[derive(Clone, Debug)]
struct Period {
    currents: [f32; 3],
    /// Counter step since the last period.
    encoder_step: i32,
    bus_v: f32,
    terminal_m: Option<f32>,
    load_n: Option<f32>,
    command: Option<Command>,
}

fn any_command(finite_only: bool) -> impl Strategy<Value = Command> {
    let value = if finite_only { (-10.0f32..10.0).boxed() } else { prop_oneof![-10.0f32..10.0, any::<f32>()].boxed() };
    let shift = if finite_only { (-0.01f32..0.01).boxed() } else { prop_oneof![-0.01f32..0.01, any::<f32>()].boxed() };
    prop_oneof![
        Just(Command::Enable),
        Just(Command::Disable),
        Just(Command::ClearFaults),
        Just(Command::Align),
        value.clone().prop_map(|x| Command::MoveTo { position_m: x }),
        (0.0f32..0.5).prop_map(|x| Command::MoveTo { position_m: x }),
        value.prop_map(|x| Command::SetHome { position_m: x }),
        shift.prop_map(|x| Command::SetPositionShift { shift_m: x }),
        any::<bool>().prop_map(|on| Command::SetCompensation { enabled: on }),
    ]
}

fn finite_period() -> impl Strategy<Value = Period> {
    (
        [-60.0f32..60.0, -60.0f32..60.0, -60.0f32..60.0],
        // Mostly what a motor can do in 50 µs, sometimes a jump.
        prop_oneof![8 => -600i32..600, 1 => -32_000i32..32_000],
        prop_oneof![8 => 30.0f32..65.0, 1 => 0.0f32..80.0],
        proptest::option::of(-1.0f32..1.0),
        proptest::option::of(-1.0e4f32..1.0e4),
        proptest::option::weighted(0.02, any_command(true)),
    )
        .prop_map(|(currents, encoder_step, bus_v, terminal_m, load_n, command)| Period {
            currents,
            encoder_step,
            bus_v,
            terminal_m,
            load_n,
            command,
        })
}

/// Any f32 at all, NaN and infinities included, now and then.
fn wild_f32(range: std::ops::Range<f32>) -> impl Strategy<Value = f32> {
    prop_oneof![20 => range, 1 => any::<f32>(), 1 => Just(f32::NAN), 1 => Just(f32::INFINITY), 1 => Just(f32::NEG_INFINITY)]
}

fn wild_period() -> impl Strategy<Value = Period> {
    (
        [wild_f32(-60.0..60.0), wild_f32(-60.0..60.0), wild_f32(-60.0..60.0)],
        any::<i16>().prop_map(i32::from),
        wild_f32(0.0..80.0),
        proptest::option::of(wild_f32(-1.0..1.0)),
        proptest::option::of(wild_f32(-1.0e4..1.0e4)),
        proptest::option::weighted(0.03, any_command(false)),
    )
        .prop_map(|(currents, encoder_step, bus_v, terminal_m, load_n, command)| Period {
            currents,
            encoder_step,
            bus_v,
            terminal_m,
            load_n,
            command,
        })
}

fn telemetry_finite(t: &Telemetry) -> Result<(), String> {
    let f = [
        ("time_s", t.time_s),
        ("position_reference_m", t.position_reference_m),
        ("position_command_m", t.position_command_m),
        ("motor_position_m", t.motor_position_m),
        ("motor_angle_rad", t.motor_angle_rad),
        ("speed_reference_rad_s", t.speed_reference_rad_s),
        ("speed_rad_s", t.speed_rad_s),
        ("current_d_a", t.current_d_a),
        ("current_q_a", t.current_q_a),
        ("current_q_reference_a", t.current_q_reference_a),
        ("voltage_d_v", t.voltage_d_v),
        ("voltage_q_v", t.voltage_q_v),
        ("bus_voltage_v", t.bus_voltage_v),
        ("load_force_estimate_n", t.load_force_estimate_n),
    ];
    match f.iter().find(|(_, v)| !v.is_finite()) {
        Some((n, v)) => Err(format!("telemetry.{n} = {v}")),
        None => Ok(()),
    }
}

/// Runs a sequence and checks every property after every period.
fn check_sequence(start_count: u16, periods: &[Period], all_finite: bool) -> Result<(), TestCaseError> {
    let p = ControlParams::DEFAULT;
    let mut c = Controller::new(p.commissioned());
    // Start the way the firmware does: homed inside the stroke, enabled.
    let _ = c.command(Command::SetHome { position_m: 0.25 });
    let _ = c.command(Command::Enable);
    let mut count = start_count;
    let i_limit = p.current_limit_a() * (1.0 + 1e-5);
    let w_limit = p.limits.speed_max_rad_s * (1.0 + 1e-5);
    for (k, per) in periods.iter().enumerate() {
        if let Some(cmd) = per.command {
            let r = c.command(cmd);
            let nan_arg = match cmd {
                Command::MoveTo { position_m: x } | Command::SetHome { position_m: x } => !x.is_finite(),
                Command::SetPositionShift { shift_m } => !shift_m.is_finite(),
                _ => false,
            };
            if nan_arg {
                prop_assert!(r.is_err(), "{cmd:?} accepted: {r:?}");
            }
        }
        count = count.wrapping_add(per.encoder_step as u16);
        let s = SensorSample {
            phase_current_a: per.currents,
            encoder_count: count,
            bus_voltage_v: per.bus_v,
            terminal_position_m: per.terminal_m,
            load_cell_force_n: per.load_n,
            home_switch: None,
            power_stage_temperature_c: None,
        };
        let out = c.step(&s);
        for d in out.duty {
            prop_assert!((0.0..=1.0).contains(&d), "period {k}: duty {d}");
        }
        let mode = c.mode();
        let faults = c.faults();
        // After a bridge-off fault the only switching allowed is the short
        // circuit that brakes the motor while the holding brake closes.
        let short_circuit = out.enable && out.duty == [0.0; 3] && !out.brake_release;
        if mode == Mode::Disabled {
            prop_assert!(!out.enable, "period {k}: bridge on in {mode:?}");
        }
        if mode == Mode::Fault {
            prop_assert!(!out.enable || short_circuit, "period {k}: bridge driving in {mode:?}: {out:?}");
            prop_assert!(!out.brake_release, "period {k}: brake open in {mode:?}");
        }
        if !faults.is_empty() {
            prop_assert!(
                matches!(mode, Mode::Fault | Mode::Stopping | Mode::Braking),
                "period {k}: faults {faults:?} in {mode:?}"
            );
        }
        if !faults.difference(FaultSet::CONTROLLED_STOP).is_empty() {
            prop_assert!(!out.enable || short_circuit, "period {k}: bridge driving with {faults:?}");
        }
        let sample_finite = per.currents.iter().all(|x| x.is_finite())
            && per.bus_v.is_finite()
            && per.terminal_m.is_none_or(f32::is_finite)
            && per.load_n.is_none_or(f32::is_finite);
        if !sample_finite {
            prop_assert!(faults.contains(FaultSet::NON_FINITE_INPUT), "period {k}: non-finite sample accepted");
            prop_assert!(!out.enable);
        }
        let t = c.telemetry();
        telemetry_finite(&t).map_err(|e| TestCaseError::fail(format!("period {k}: {e}")))?;
        prop_assert!(c.motor_position_m().is_finite() && c.speed_rad_s().is_finite());
        prop_assert!(c.thermal_level().is_finite() && c.thermal_level() >= 0.0);
        // The limits, as the telemetry reports them.
        prop_assert!(t.current_q_reference_a.abs() <= i_limit, "period {k}: i_q ref {}", t.current_q_reference_a);
        prop_assert!(t.speed_reference_rad_s.abs() <= w_limit, "period {k}: ω ref {}", t.speed_reference_rad_s);
        // What the position loop acts on (with the bridge off the command
        // just follows the measured position, wherever that is).
        if matches!(t.mode, Mode::Running | Mode::Stopping) {
            prop_assert!(
                (p.limits.stroke_min_m..=p.limits.stroke_max_m).contains(&t.position_command_m),
                "period {k}: position command {} in {:?}",
                t.position_command_m,
                t.mode
            );
        }
        let v_max = p.limits.max_modulation * INV_SQRT3 * t.bus_voltage_v.max(0.0) * (1.0 + 1e-4) + 1e-4;
        let v = (t.voltage_d_v * t.voltage_d_v + t.voltage_q_v * t.voltage_q_v).sqrt();
        if all_finite && t.mode != Mode::Fault && t.mode != Mode::Disabled {
            prop_assert!(v <= v_max, "period {k}: |u_dq| {v} above {v_max}");
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// For any finite inputs: duties in [0, 1], nothing non-finite, every
    /// limit holds, faults and modes consistent.
    #[test]
    fn step_keeps_every_bound_for_finite_inputs(
        start in any::<u16>(),
        periods in proptest::collection::vec(finite_period(), 1..1500),
    ) {
        check_sequence(start, &periods, true)?;
    }

    /// Even with NaN and infinities in the samples and the commands: the
    /// duties stay in [0, 1], outputs stay finite, a non-finite sample
    /// latches `NON_FINITE_INPUT` and turns the bridge off, and NaN
    /// arguments are refused.
    #[test]
    fn step_survives_non_finite_inputs(
        start in any::<u16>(),
        periods in proptest::collection::vec(wild_period(), 1..600),
    ) {
        check_sequence(start, &periods, false)?;
    }

    /// SVPWM: any finite request gives duties in [0, 1] whose applied vector
    /// (from the leg differences) never leaves the V_bus/√3 circle, equals
    /// the request inside it, and keeps its direction outside it.
    #[test]
    fn svpwm_duties_stay_in_range_and_apply_the_request(
        alpha in -1000.0f32..1000.0,
        beta in -1000.0f32..1000.0,
        bus in 1.0f32..100.0,
    ) {
        let out = svpwm(AlphaBeta { alpha, beta }, bus);
        for d in out.duty {
            prop_assert!((0.0..=1.0).contains(&d), "duty {d}");
        }
        let [a, b, c] = out.duty;
        let applied_alpha = (2.0 * a - b - c) / 3.0 * bus;
        let applied_beta = (b - c) * INV_SQRT3 * bus;
        let mag = (applied_alpha * applied_alpha + applied_beta * applied_beta).sqrt();
        let vmax = bus * INV_SQRT3;
        prop_assert!(mag <= vmax * (1.0 + 1e-5) + 1e-5, "|v| {mag} > {vmax}");
        let req = (alpha * alpha + beta * beta).sqrt();
        let tol = 1e-5 * bus + 1e-5 * req;
        if req < vmax * (1.0 - 1e-4) {
            prop_assert!(!out.limited);
            prop_assert!((applied_alpha - alpha).abs() <= tol && (applied_beta - beta).abs() <= tol,
                "applied ({applied_alpha}, {applied_beta}) for ({alpha}, {beta})");
        } else if req > vmax * (1.0 + 1e-4) {
            prop_assert!(out.limited);
            // Same direction: cross product ≈ 0, dot product > 0.
            let cross = applied_alpha * beta - applied_beta * alpha;
            prop_assert!(cross.abs() <= 1e-4 * mag * req + 1e-4, "direction changed");
            prop_assert!(applied_alpha * alpha + applied_beta * beta > 0.0);
        }
    }

    /// A non-finite request or bus gives zero volts (50 % everywhere).
    #[test]
    fn svpwm_refuses_non_finite_requests(alpha in any::<f32>(), beta in any::<f32>(), bus in any::<f32>()) {
        let out = svpwm(AlphaBeta { alpha, beta }, bus);
        for d in out.duty {
            prop_assert!((0.0..=1.0).contains(&d), "duty {d}");
        }
        if !(alpha.is_finite() && beta.is_finite() && bus.is_finite() && bus > 0.0) {
            prop_assert_eq!(out.duty, [0.5; 3]);
        }
    }

    /// PI: the output always lies in [lo, hi] and the integrator stays
    /// finite and inside [lo − ff, hi − ff], whatever the error sequence
    /// and the (possibly moving) limits.
    #[test]
    fn pi_output_stays_inside_its_limits(
        kp in 0.0f32..100.0,
        ki in 0.0f32..1.0e5,
        steps in proptest::collection::vec((-1.0e3f32..1.0e3, -50.0f32..50.0, 0.0f32..100.0, -20.0f32..20.0), 1..400),
    ) {
        let gains = PiGains { kp, ki };
        let mut pi = Pi::new();
        for (error, centre, half_width, ff) in steps {
            let (lo, hi) = (centre - half_width, centre + half_width);
            let out = pi.update(&gains, error, ff, lo, hi, 50e-6);
            prop_assert!(out.value >= lo && out.value <= hi, "{} outside [{lo}, {hi}]", out.value);
            prop_assert!(pi.integral().is_finite());
            prop_assert!(pi.integral() >= lo - ff - 1e-3 && pi.integral() <= hi - ff + 1e-3,
                "integral {} outside [{}, {}]", pi.integral(), lo - ff, hi - ff);
        }
    }

    /// S-curve: between its ends, never past them, within the velocity and
    /// acceleration limits, continuous, and at rest at the end.
    #[test]
    fn scurve_stays_between_its_ends_and_inside_its_limits(
        start in 0.0f32..0.5,
        end in 0.0f32..0.5,
        v in 0.01f32..0.5,
        a in 0.1f32..10.0,
        j in 1.0f32..200.0,
    ) {
        let limits = TrajectoryParams { max_velocity_m_s: v, max_acceleration_m_s2: a, max_jerk_m_s3: j };
        let m = ScurveMove::plan(start, end, &limits);
        let total = m.duration_s();
        prop_assert!(total.is_finite() && total >= 0.0);
        let (lo, hi) = (start.min(end), start.max(end));
        let dt = 1e-3f32;
        let n = (total / dt).ceil() as usize + 2;
        let mut prev = m.sample(0.0).position_m;
        for k in 0..=n {
            let s = m.sample(k as f32 * dt);
            prop_assert!(s.position_m >= lo - 1e-5 && s.position_m <= hi + 1e-5, "p {} outside [{lo}, {hi}]", s.position_m);
            prop_assert!(s.velocity_m_s.abs() <= v * 1.001 + 1e-6, "v {}", s.velocity_m_s);
            prop_assert!(s.acceleration_m_s2.abs() <= a * 1.001 + 1e-5, "a {}", s.acceleration_m_s2);
            prop_assert!((s.position_m - prev).abs() <= v * dt * 1.01 + 1e-5, "jump {} → {}", prev, s.position_m);
            prev = s.position_m;
        }
        let last = m.sample(total + 1.0);
        prop_assert!((last.position_m - end).abs() < 1e-5);
        prop_assert_eq!(last.velocity_m_s, 0.0);
    }

    /// The stroke clamp: always inside, and says so exactly when it acted.
    #[test]
    fn stroke_clamp_is_inside_and_reported(x in -10.0f32..10.0) {
        let p = ControlParams::DEFAULT.limits;
        let (c, clamped) = clamp_to_stroke(x, p.stroke_min_m, p.stroke_max_m);
        prop_assert!((p.stroke_min_m..=p.stroke_max_m).contains(&c));
        prop_assert_eq!(clamped, c != x);
    }

    /// I²t: the level stays finite and non-negative, and the folded-back
    /// limit lies between the continuous current and the peak.
    #[test]
    fn thermal_model_stays_bounded(currents in proptest::collection::vec(wild_f32(0.0..60.0), 1..500)) {
        let p = ControlParams::DEFAULT;
        let mut m = ThermalModel::new();
        for i in currents {
            m.update(&p.thermal, i * i, p.speed_period_s() * 1000.0);
            prop_assert!(m.level().is_finite() && m.level() >= 0.0);
            let lim = m.current_limit_a(&p.thermal, p.current_limit_a());
            prop_assert!(lim >= p.thermal.continuous_current_a - 1e-4 && lim <= p.current_limit_a() + 1e-4);
        }
    }

    /// The observer's forward pass: finite for any input (clamped to its
    /// trained range); valid for finite inputs, flagged invalid for NaN.
    #[test]
    fn observer_prediction_is_finite_for_finite_inputs(x in [wild_f32(-1.0e4..1.0e4), wild_f32(-10.0..10.0), wild_f32(-1.0..1.0), wild_f32(-1.0e5..1.0e5)]) {
        let pred = servo_core::observer::evaluate(&servo_core::observer::model::MODEL, x);
        prop_assert!(pred.value_m.is_finite(), "{pred:?} for {x:?}");
        if x.iter().all(|v| v.is_finite()) {
            prop_assert!(pred.valid, "{pred:?} for {x:?}");
        }
        if x.iter().any(|v| v.is_nan()) {
            prop_assert!(!pred.valid, "{pred:?} for {x:?}");
        }
    }
}
