//! No accepted value switches a protection off: every protection threshold
//! pushed to the widest value the parameter ranges and the set's own
//! validation accept (the least sensitive setting a user can reach), and
//! the protections still trip, in the plant: every fault scenario of the
//! reliability table still latches its fault, and a stream that stops
//! still decelerates to rest and latches `stream_timeout`.

use host_sim::config::RigConfig;
use host_sim::fault_injection::injection::Injection;
use host_sim::fault_injection::{catalog, runner};
use host_sim::sim::{commissioned_control, ClosedLoop};
use servo_core::params::{leaves, ranges, ControlParams};
use servo_core::protocol::Value;
use servo_core::{Command, Controller, FaultSet};

/// The thresholds that make their protection less sensitive as they grow
/// (trip levels, trip times, tolerated errors and gaps).
const WIDER_IS_LESS_SENSITIVE: &[&str] = &[
    "control.faults.overcurrent_trip_a",
    "control.faults.bus_overvoltage_v",
    "control.faults.encoder_max_step_counts",
    "control.faults.encoder_max_innovation_counts",
    "control.faults.position_following_error_m",
    "control.faults.stroke_overtravel_m",
    "control.faults.speed_following_error_rad_s",
    "control.faults.speed_following_time_s",
    "control.faults.encoder_lost_speed_rad_s",
    "control.faults.encoder_lost_time_s",
    "control.faults.current_sum_max_a",
    "control.faults.current_sum_periods",
    "control.faults.stop_following_error_m",
    "control.faults.open_phase_window_s",
    "control.faults.open_phase_current_a",
    "control.power_stage.temperature_trip_c",
    "control.power_stage.emf_speed_mismatch_rad_s",
    "control.power_stage.emf_mismatch_time_s",
    "control.stream.period_max_s",
    "control.stream.timeout_s",
    "control.stream.velocity_mismatch_max_m_s",
];

fn index(path: &str) -> usize {
    (0..leaves::LEAF_COUNT).find(|&i| leaves::path(i) == path).unwrap_or_else(|| panic!("no leaf {path}"))
}

fn as_f64(v: Value) -> f64 {
    match v {
        Value::F32(x) => f64::from(x),
        Value::U32(x) => f64::from(x),
        v => panic!("{v:?}"),
    }
}

fn with(p: &ControlParams, i: usize, x: f64) -> ControlParams {
    let mut q = *p;
    let v = match leaves::get(p, i).unwrap() {
        Value::F32(_) => Value::F32(x as f32),
        Value::U32(_) => Value::U32(x.min(f64::from(u32::MAX)) as u32),
        v => panic!("{v:?}"),
    };
    leaves::set(&mut q, i, v).unwrap();
    q
}

/// Leaf `i` raised to the largest value `validate` accepts, the others as
/// in `p` (bisection between the value in force and the unit's bound).
fn widest_of(p: &ControlParams, i: usize) -> ControlParams {
    let now = as_f64(leaves::get(p, i).unwrap());
    let bound = f64::from(ranges::leaf_bound(i, p).unwrap()).min(1e9);
    if with(p, i, bound).validate().is_ok() {
        return with(p, i, bound);
    }
    let (mut lo, mut hi) = (now, bound);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if with(p, i, mid).validate().is_ok() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    with(p, i, lo)
}

/// Every threshold of the list at its widest accepted value, in turn.
fn widest(base: ControlParams) -> ControlParams {
    let mut p = base;
    for path in WIDER_IS_LESS_SENSITIVE {
        p = widest_of(&p, index(path));
    }
    p.validate().expect("the widest set is itself accepted");
    p
}

/// A protection may take up to its widest accepted time (1 s, the
/// `ProtectionTime` bound) to act: each scenario runs that much longer.
const SLOWEST_PROTECTION_S: f64 = 1.0;

#[test]
fn every_fault_scenario_still_trips_with_every_threshold_at_its_widest_accepted_value() {
    let rig = RigConfig::nominal().unwrap();
    let wide = widest(rig.control);
    for path in WIDER_IS_LESS_SENSITIVE {
        let i = index(path);
        let (from, to) = (as_f64(leaves::get(&rig.control, i).unwrap()), as_f64(leaves::get(&wide, i).unwrap()));
        println!("{path}: {from} → {to}");
        assert!(to >= from, "{path}");
    }
    let mut tripped = 0;
    let mut missed = vec![];
    for mut sc in catalog::all(&rig) {
        if sc.expect.faults.is_empty() {
            continue;
        }
        // On top of the scenario's own set (some change it).
        sc.setup.control = widest(sc.setup.control);
        sc.duration_s += SLOWEST_PROTECTION_S + 0.2;
        // A fault sized for the shipped threshold, resized beyond the widest
        // one: the protection must still act at its (new) bound.
        let wide_following_m = f64::from(sc.setup.control.faults.position_following_error_m);
        let wide_trip_c = f64::from(sc.setup.control.power_stage.temperature_trip_c);
        for t in &mut sc.injections {
            match &mut t.injection {
                Injection::Obstacle { position_m, .. } => *position_m = catalog::MOVE_TO_M - wide_following_m - 0.01,
                Injection::PowerStageTemperature { celsius } => *celsius = (wide_trip_c + 5.0) as f32,
                _ => {}
            }
        }
        let o = runner::run(&sc).unwrap();
        let expected = sc.expect.faults;
        let same = if o.seen_faults.intersects(expected) {
            "the same protection"
        } else if o.seen_faults.is_empty() {
            "nothing"
        } else {
            "another protection"
        };
        println!(
            "{}: expected {:?}, seen {:?} after {:?} s ({same})",
            sc.name,
            expected.names().collect::<Vec<_>>(),
            o.seen_faults.names().collect::<Vec<_>>(),
            o.detection_s()
        );
        // The fault is still caught: by its own protection, or, with that
        // one at its widest, by the next one in line.
        if o.seen_faults.is_empty() {
            missed.push(sc.name);
        } else {
            tripped += 1;
        }
    }
    assert!(missed.is_empty(), "nothing latched with every threshold at its widest accepted value: {missed:?}");
    // The table's faulting scenarios, all run.
    assert!(tripped >= 17, "{tripped} scenarios tripped");
}

#[test]
fn a_stream_that_stops_still_decelerates_and_latches_with_the_widest_stream_timing() {
    let rig = RigConfig::nominal().unwrap();
    let wide = widest(rig.control);
    let (x0, v) = (0.25, 0.1);
    let mut plant = host_sim::plant::Plant::try_new(rig.plant.clone(), 5).unwrap();
    plant.set_initial_state((x0 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), std::f64::consts::FRAC_PI_2);
    let c = Controller::try_new(commissioned_control(wide, &plant)).unwrap();
    let mut cl = ClosedLoop::new(c, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.controller.command(Command::SetHome { position_m: x0 as f32 }).unwrap();
    cl.controller.command(Command::Enable).unwrap();
    let dt = f64::from(wide.pwm_period_s());
    for _ in 0..(0.5 / dt) as usize {
        cl.step();
    }
    let mut x = x0;
    for k in 0..(0.3 / dt) as u64 {
        if k % 20 == 0 {
            x = x0 + v * k as f64 * dt;
            cl.controller.command(Command::Stream { position_m: x as f32, velocity_m_s: v as f32, force_n: None }).unwrap();
        }
        let t = cl.step();
        assert!(t.faults.is_empty(), "{:?}", t.faults);
    }
    // Silence: with timeout_s and period_max_s at their widest the stream
    // is still lost one measured interval after its last point, stops, and
    // latches; the drive does not run on.
    let a_stop = f64::from(wide.faults.stop_deceleration_m_s2);
    let mut latched_after = None;
    for k in 0..(1.5 / dt) as u64 {
        let t = cl.step();
        if t.faults.contains(FaultSet::STREAM_TIMEOUT) {
            latched_after = Some(k as f64 * dt);
            break;
        }
    }
    let latched_after = latched_after.expect("stream_timeout latched");
    for _ in 0..(0.2 / dt) as usize {
        cl.step();
    }
    let rest = f64::from(cl.controller.telemetry().motor_position_m);
    println!("latched {:.1} ms after the last point, rest {:.2} mm past it", latched_after * 1e3, (rest - x) * 1e3);
    assert!(latched_after < 0.1, "latched after {latched_after} s");
    assert!(rest - x <= v * v / (2.0 * a_stop) + 1e-3, "rest {rest}, last point {x}");
    assert!(cl.plant.state().v_rod_m_s.abs() < 1e-3);
}

