//! Power-stage faults: an open phase, bus sag, dip and surge, and what the
//! bridge's safe states do to a vertical rated load.

mod fault_support;

use fault_support::*;
use host_sim::fault_injection::{catalog, CommandAt};
use host_sim::plant::{Drive, Plant, PlantParams};
use servo_core::{Command, CommandError, CommandOutcome, FaultSet, Mode, PwmCommand};
use std::f64::consts::{FRAC_PI_2, TAU};

const PWM_PERIOD_S: f64 = 50e-6;
const BUS_V: f64 = 48.0;

/// Vertical, rated load, at rest at 250 mm (holding current flowing), with
/// no holding brake: what the power stage alone can do (the brake's own
/// tests are in plant_brake.rs).
fn held_plant() -> Plant {
    let mut params = PlantParams::default();
    params.brake.fitted = false;
    let mut plant = Plant::new(params, 1);
    let lead = plant.params().screw.lead_m;
    plant.set_initial_state(0.25 * TAU / lead, FRAC_PI_2);
    plant
}

fn peak(plant: &Plant) -> f64 {
    plant.state().phase_current_a.iter().fold(0.0, |m: f64, i| m.max(i.abs()))
}

#[test]
fn an_open_phase_carries_no_current_and_leaves_one_current_path() {
    let mut plant = held_plant();
    plant.set_open_phase(Some(0));
    // Phase a is cut: with any duties, i_a stays zero and i_b = −i_c.
    for k in 0..400 {
        let t = k as f64 * PWM_PERIOD_S;
        let duty = [0.5 + 0.3 * (800.0 * t).sin(), 0.5 + 0.2 * (800.0 * t + 2.0).sin(), 0.5 - 0.1 * (500.0 * t).cos()];
        plant.advance_duties(Some(duty), BUS_V, PWM_PERIOD_S);
        let [a, b, c] = plant.state().phase_current_a;
        assert!(a.abs() < 1e-9, "i_a = {a} at step {k}");
        assert!((b + c).abs() < 1e-9, "i_b + i_c = {} at step {k}", b + c);
    }
    // The b–c path still carries current (the bridge still acts).
    assert!(peak(&plant) > 1.0);
    // And with the switches off the open phase's diodes cannot conduct.
    for _ in 0..2000 {
        plant.advance(&PwmCommand::OFF, BUS_V, PWM_PERIOD_S);
        assert!(plant.state().phase_current_a[0].abs() < 1e-9);
        if let Drive::Diodes(legs) = plant.drive() {
            assert_eq!(legs[0], host_sim::plant::Leg::Open);
        }
    }
    plant.set_open_phase(None);
    assert_eq!(plant.open_phase(), None);
}

/// An open phase latches `OPEN_PHASE` within the 5 ms the catalog allows
/// (the per-phase check judges 2 ms windows), the controlled stop brings the
/// rod to rest on the two phases left, and then (stop category 1) the brake
/// takes the load and the bridge goes off: the rod ends held, not sinking.
#[test]
fn an_open_phase_stops_then_hands_the_load_to_the_brake() {
    let rig = rig();
    let sc = catalog::open_phase(&rig);
    let o = run_meeting(&sc);
    assert_eq!(o.first_faults, FaultSet::OPEN_PHASE, "{}", o.brief());
    assert!(o.travel_after_latch_m.unwrap().abs() < 0.005, "{}", o.brief());
    assert_eq!(o.final_mode, Mode::Fault, "{}", o.brief());
    assert!(o.rod_speed_end_m_s.abs() < 1e-4, "{}", o.brief());
    let latch = o.latch_period.unwrap() as usize;
    // Bridge on through the stop, off at the end.
    assert!(o.records[latch + 1..latch + 20].iter().all(|r| r.bridge_on), "{}", o.brief());
    assert!(!o.records.last().unwrap().bridge_on, "{}", o.brief());
}

#[test]
fn an_open_phase_latches_within_5_ms() {
    run_meeting(&catalog::open_phase(&rig()));
}

#[test]
fn a_bus_sag_latches_undervoltage_at_the_next_sample() {
    let o = run_meeting(&catalog::bus_sag(&rig()));
    // The bus changes during a period; the ADC sees it at the next sample.
    assert_eq!(o.detection_periods(), Some(1));
    assert_bridge_off_after_latch(&o);
}

#[test]
fn a_bus_undervoltage_cannot_be_cleared_while_the_bus_is_low() {
    let rig = rig();
    let mut sc = catalog::bus_sag(&rig);
    sc.commands.push(CommandAt { at_s: 0.52, command: Command::ClearFaults });
    let o = host_sim::fault_injection::run(&sc).unwrap();
    assert!(matches!(o.command_result(0.52), Some(Err(CommandError::CauseStillPresent(_)))), "{:?}", o.commands);
}

#[test]
fn a_bus_dip_inside_the_trip_is_ridden_through() {
    run_meeting(&catalog::bus_dip(&rig()));
}

#[test]
fn a_bus_surge_latches_overvoltage_and_clears_only_after_it() {
    let rig = rig();
    let mut sc = catalog::bus_surge(&rig);
    sc.commands.push(CommandAt { at_s: 0.51, command: Command::ClearFaults });
    sc.commands.push(CommandAt { at_s: 0.60, command: Command::Enable });
    sc.commands.push(CommandAt { at_s: 0.61, command: Command::ClearFaults });
    sc.commands.push(CommandAt { at_s: 0.62, command: Command::Enable });
    let o = run_meeting(&sc);
    assert_eq!(o.detection_periods(), Some(1));
    assert!(matches!(o.command_result(0.51), Some(Err(CommandError::CauseStillPresent(f))) if f.contains(FaultSet::BUS_OVERVOLTAGE)));
    assert!(matches!(o.command_result(0.60), Some(Err(CommandError::Faulted(_)))));
    assert_eq!(o.command_result(0.61), Some(Ok(CommandOutcome::Accepted)));
    assert_eq!(o.command_result(0.62), Some(Ok(CommandOutcome::Accepted)));
    assert_eq!(o.final_mode, Mode::Running);
}

/// The bridge-off reaction with a vertical rated load: the freewheel
/// diodes brake only above the line-to-line EMF threshold, so the payload
/// falls at ≈0.38 m/s and reaches the retracted end stop from 250 mm in
/// under 0.8 s. This is why every bridge-off fault needs a holding brake
/// (or a short-circuit brake, below) on a vertical axis.
#[test]
fn bridge_off_lets_a_vertical_rated_load_fall_to_the_end_stop() {
    let mut plant = held_plant();
    let mut reached_s = None;
    for k in 0..20_000 {
        plant.advance(&PwmCommand::OFF, BUS_V, PWM_PERIOD_S);
        if reached_s.is_none() && plant.state().x_rod_m < 0.0 {
            reached_s = Some(k as f64 * PWM_PERIOD_S);
        }
    }
    let t = reached_s.expect("the rod left the stroke");
    assert!(t < 0.8, "reached 0 mm after {t} s");
    let stop = plant.params().stroke.retracted_stop_m;
    let x = plant.state().x_rod_m;
    assert!((x - stop).abs() < 0.5e-3, "rests on the end stop at {stop} m: {x} m");
}

/// Active short circuit (all three low-side switches on): the motor brakes
/// itself through its own resistance, with no sensor and no control loop.
/// The rated load then sinks at the speed where the short-circuit torque
/// `1.5 p ψ i_q`, `i_q = −ω_e ψ R / (R² + (ω_e L)²)`, balances the back-driven
/// load torque: closed form below, ≈12 mm/s, thirty times slower than the
/// bridge-off fall.
#[test]
fn short_circuit_braking_lets_a_vertical_rated_load_sink_at_the_closed_form_speed() {
    let mut plant = held_plant();
    let p = plant.params().clone();
    let asc = PwmCommand { duty: [0.0; 3], enable: true, brake_release: true };
    let mut max_current: f64 = 0.0;
    for _ in 0..20_000 {
        plant.advance(&asc, BUS_V, PWM_PERIOD_S);
        max_current = max_current.max(peak(&plant));
    }
    let w_sim = plant.state().omega_m_rad_s;

    // Steady state with ω < 0 (sinking), every Stribeck term long gone.
    let r = p.metres_per_rad();
    let pp = f64::from(p.motor.pole_pairs);
    let (rs, l, psi) = (p.motor.phase_resistance_ohm, p.motor.inductance_q_h, p.motor.flux_linkage_wb);
    let mu = (1.0 - p.screw.efficiency) / p.screw.efficiency;
    let load = p.moving_mass_kg() * p.load.gravity_m_s2;
    let residual = |w: f64| {
        let we = pp * w;
        let iq = -we * psi * rs / (rs * rs + we * we * l * l);
        let te = 1.5 * pp * psi * iq;
        let v = r * w;
        let f_ax = load + p.rod.viscous_friction_n_s_m * v - p.rod.coulomb_friction_n;
        let t_c = r * f_ax + p.screw.viscous_friction_n_m_s_rad * w - (p.screw.preload_drag_torque_n_m + r * mu * f_ax);
        te - t_c - p.motor.viscous_friction_n_m_s_rad * w
    };
    let (mut lo, mut hi) = (-200.0, -1e-6);
    assert!(residual(lo) > 0.0 && residual(hi) < 0.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 { lo = mid } else { hi = mid }
    }
    let w_closed = 0.5 * (lo + hi);
    assert!((w_sim - w_closed).abs() < 0.01 * w_closed.abs(), "sim {w_sim} rad/s, closed form {w_closed} rad/s");
    let v = r * w_sim;
    assert!(v < 0.0 && v > -0.02, "sinks at {v} m/s");
    assert!(max_current < 15.0, "short-circuit current {max_current} A");
}

#[test]

fn a_bridge_off_fault_keeps_a_vertical_load_inside_the_stroke() {
    let rig = rig();
    let mut sc = catalog::bus_sag(&rig);
    sc.duration_s = 2.0;
    run_meeting(&sc);
}

/// A nearly empty rod (2 % payload) cruising asks only its friction, about
/// 1 A, under the open-phase detector's demand floor: the d-axis probe must
/// lengthen the current vector so that the lost phase is still caught
/// within the catalogue's 5 ms and named, with the controlled stop.
#[test]
fn an_open_phase_on_a_nearly_empty_rod_latches_within_5_ms() {
    let base = rig();
    let light = [
        ("payload 2 %", host_sim::rigs::Draw { payload: 0.02, ..host_sim::rigs::Draw::BASE }.apply(&base)),
        seen_family_rigs().pop().expect("the 2 % seen rig"),
    ];
    for (name, rig) in light {
        let o = run_meeting(&catalog::open_phase(&rig));
        assert_eq!(o.first_faults, FaultSet::OPEN_PHASE, "{name}: {}", o.brief());
    }
}

/// A mid-payload unit (family 2161 rig_009, 33.5 %) whose torque dips after
/// the break swing the q reference across the probe's length, so the probe
/// switches on and off and turns the reference vector: a window judging the
/// phase on its mean demand then found the floor missed where the phase's
/// zero crossing fell mid-window, and latched after 119 periods. Judged
/// only where it is asked, the phase is caught within the bound.
#[test]
fn an_open_phase_is_caught_within_5_ms_when_the_reference_swings() {
    use host_sim::rigs::Draw;
    let rig = Draw {
        coulomb: 0.8339852062605246,
        encoder_zero_rad: 2.470333235543879,
        flux: 0.9306563953187439,
        inductance: 1.0364587659357694,
        inertia: 1.0277410947207128,
        lead_error_m_per_m: 0.00013995223980490054,
        payload: 0.33538298137709965,
        resistance: 1.1203141308828746,
        screw_mu: 0.7068531447203943,
        stiffness: 0.980892460438567,
        viscous: 1.191253488379856,
    }
    .apply(&rig());
    let o = run_meeting(&catalog::open_phase(&rig));
    assert_eq!(o.first_faults, FaultSet::OPEN_PHASE, "{}", o.brief());
}

/// The probe fills the current vector up to 3 demand floors with d
/// current of the flux-weakening sign, and nothing beyond: none once q alone
/// is that long, none when the vector would not fit the current limit.
#[test]
fn the_open_phase_probe_fills_the_vector_to_its_length_and_no_more() {
    use servo_core::protection::open_phase::{probe_current_d_a, PROBE_VECTOR_PER_FLOOR};
    let f = servo_core::ControlParams::DEFAULT.faults;
    let target = PROBE_VECTOR_PER_FLOOR * f.open_phase_current_a;
    for q in [0.0f32, 0.3, -1.0, 1.5, -2.9] {
        let d = probe_current_d_a(&f, q, 10.0);
        assert!(d < 0.0, "q {q}: d {d}");
        assert!(((d * d + q * q).sqrt() - target).abs() < 1e-5, "q {q}: |i| {}", (d * d + q * q).sqrt());
    }
    assert_eq!(probe_current_d_a(&f, target * 1.01, 10.0), 0.0);
    assert_eq!(probe_current_d_a(&f, 0.5, target * 0.99), 0.0);
    assert_eq!(probe_current_d_a(&f, f32::NAN, 10.0), 0.0);
}

/// A window centred on phase a's zero crossing, a 1.8-floor vector turning
/// 2.2 rad through it in 11 samples: the phase's mean demand over the
/// window is 0.89 floors, under the floor, yet it is asked for more than the
/// floor in 6 of the 11 samples, on either side. An empty
/// phase a is named open; the same window with phase a carrying its
/// reference is not.
#[test]
fn the_open_phase_window_judges_a_phase_where_it_is_asked() {
    use servo_core::protection::OpenPhaseMonitor;
    let f = servo_core::ControlParams::DEFAULT.faults;
    let n = 11u32;
    let amplitude_a = 1.8 * f.open_phase_current_a;
    let window = |empty: bool| {
        let mut m = OpenPhaseMonitor::new();
        let mut verdict = None;
        let mut mean_demand_a = 0.0;
        for k in 0..n {
            // Phase a's angle runs through its zero crossing mid-window.
            let th = -1.1 + 2.2 * (k as f32 + 0.5) / n as f32;
            let r = [amplitude_a * th.sin(), amplitude_a * (th - 2.094_395).sin(), amplitude_a * (th + 2.094_395).sin()];
            mean_demand_a += r[0].abs() / n as f32;
            let meas = if empty { [0.0, r[1] - r[0] / 2.0, r[2] - r[0] / 2.0] } else { r };
            verdict = m.update(&f, n, r, meas);
        }
        (verdict, mean_demand_a)
    };
    let (open, mean_demand_a) = window(true);
    assert!(mean_demand_a < f.open_phase_current_a, "the window's mean demand {mean_demand_a} A is under the floor");
    assert_eq!(open, Some(true), "an empty phase asked for the floor on either side of its zero crossing");
    assert_eq!(window(false).0, Some(false), "a working phase is not called open");
}

/// A lost encoder at standstill on a nearly empty rod (2.8 % payload) is
/// named `encoder_lost`, never `open_phase`: the frozen angle leaves the
/// held current a stationary vector, so a phase can sit near zero while the
/// reference turns past it; a lowered demand floor once called that open.
#[test]
fn a_lost_encoder_at_standstill_on_a_nearly_empty_rod_is_not_an_open_phase() {
    let rig = host_sim::rigs::Draw { payload: 0.028, ..host_sim::rigs::Draw::BASE }.apply(&rig());
    let o = run_meeting(&catalog::encoder_dropout_at_standstill(&rig));
    assert!(!o.first_faults.contains(FaultSet::OPEN_PHASE), "{}", o.brief());
}

/// One case of the slow-loop sweep: the dq reference steps between levels
/// at the given speed periods, the healthy loop follows it as a first-order
/// lag at `loop_bandwidth_rad_s` one PWM period late, the rotor turns at
/// `electrical_speed_rad_s`. `open_a` empties phase a. Returns the speed
/// period of the first open verdict.
fn slow_loop_first_open(
    follow_gain: f32,
    loop_bandwidth_rad_s: f64,
    electrical_speed_rad_s: f64,
    angle0_rad: f64,
    steps: &[(u32, f64)],
    open_a: bool,
) -> Option<u32> {
    use servo_core::foc::transforms::{inverse_clarke, inverse_park, SinCos};
    use servo_core::foc::Dq;
    use servo_core::protection::OpenPhaseMonitor;
    let p = servo_core::ControlParams::DEFAULT;
    let t_pwm = 1.0 / f64::from(p.rates.pwm_frequency_hz);
    let per_speed = p.rates.speed_loop_divider;
    let window = (p.faults.open_phase_window_s / p.speed_period_s()).ceil() as u32;
    let decay = (-loop_bandwidth_rad_s * t_pwm).exp();
    let mut m = OpenPhaseMonitor::new();
    let (mut i_q, mut q_ref, mut q_late) = (steps[0].1, steps[0].1, steps[0].1);
    let end = steps.last().map_or(0, |s| s.0) + 8 * window;
    for k in 0..end {
        if let Some(s) = steps.iter().find(|s| s.0 == k) {
            q_ref = s.1;
        }
        for _ in 0..per_speed {
            // The bridge acts one period after the loop asks.
            i_q = q_late + (i_q - q_late) * decay;
            q_late = q_ref;
        }
        let angle = angle0_rad + electrical_speed_rad_s * f64::from(k * per_speed) * t_pwm;
        let sc = SinCos { sin: angle.sin() as f32, cos: angle.cos() as f32 };
        let mut meas = inverse_clarke(inverse_park(Dq { d: 0.0, q: i_q as f32 }, sc));
        if open_a {
            meas = [0.0, meas[1] + meas[0] / 2.0, meas[2] + meas[0] / 2.0];
        }
        let expected = m.expected_phase_current_a(follow_gain, Dq { d: 0.0, q: q_ref as f32 }, sc);
        if m.update(&p.faults, window, expected, meas) == Some(true) {
            return Some(k);
        }
    }
    None
}

/// A current loop tuned slow (300 Hz, as the tuning bench asks) lags a
/// speed step's torque reversals: across reversals between ±0.5 and ±10 A,
/// every step time within a window, rotor angles round the turn and speeds
/// up to a cruise, a working phase is never called open. An empty phase
/// under the same references is still found within two windows once the
/// reference holds.
#[test]
fn a_slow_current_loop_through_torque_reversals_is_not_an_open_phase() {
    use servo_core::protection::open_phase::follow_gain;
    let p = servo_core::ControlParams::DEFAULT;
    let w_loop = std::f64::consts::TAU * 300.0;
    let kp = p.motor.inductance_q_h * w_loop as f32;
    let gain = follow_gain(kp, p.motor.inductance_q_h, p.speed_period_s());
    let window = (p.faults.open_phase_window_s / p.speed_period_s()).ceil() as u32;
    let levels = [-10.0, -3.0, -1.5, -0.5, 0.5, 1.5, 3.0, 10.0];
    let (mut cases, mut raw_false) = (0, 0);
    for &from in &levels {
        for &to in &levels {
            if from == to {
                continue;
            }
            for offset in 0..window {
                for a in 0..12 {
                    for w_e in [0.0, 60.0, 600.0] {
                        let angle = a as f64 * std::f64::consts::TAU / 12.0 + 0.1;
                        let steps = [(0, from), (3 * window + offset, to)];
                        cases += 1;
                        let healthy = slow_loop_first_open(gain, w_loop, w_e, angle, &steps, false);
                        assert_eq!(healthy, None, "{from} A → {to} A at +{offset}, angle {angle:.2} rad, {w_e} rad/s");
                        raw_false += usize::from(slow_loop_first_open(1.0, w_loop, w_e, angle, &steps, false).is_some());
                        // Phase a asked at least 1.5 floors once the step settles.
                        let asked_a = (to * (angle + w_e * 0.0).sin()).abs();
                        if w_e == 0.0 && asked_a >= 1.5 * f64::from(p.faults.open_phase_current_a) {
                            let found = slow_loop_first_open(gain, w_loop, w_e, angle, &steps, true);
                            let settle = 3 * window + offset + 2 * window;
                            assert!(found.is_some_and(|k| k <= settle.max(2 * window)), "empty phase a, {to} A: {found:?}");
                        }
                    }
                }
            }
        }
    }
    println!("{cases} cases; the raw reference calls a working phase open in {raw_false}");
}
