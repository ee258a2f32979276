//! Every parameter leaf has a physical range: the shipped sets lie inside
//! theirs, and no value the ranges accept drives the current to its limit
//! at rest or switches a protection off (a property over the leaves).

use host_sim::config::RigConfig;
use servo_core::params::ranges::{self, Unit};
use servo_core::params::{leaves, ControlParams};
use servo_core::protocol::{Value, ValueKind};

fn rigs() -> Vec<(String, ControlParams)> {
    let mut v = vec![("ControlParams::DEFAULT".to_string(), ControlParams::DEFAULT)];
    for f in ["params/rig.toml", "params/platform.toml"] {
        if let Ok(r) = RigConfig::load(std::path::Path::new(f)) {
            v.push((f.to_string(), r.control));
        }
    }
    v
}

#[test]
fn the_shipped_sets_lie_inside_every_range() {
    for (name, p) in rigs() {
        for i in 0..leaves::LEAF_COUNT {
            let bound = ranges::leaf_bound(i, &p).unwrap();
            let size = match leaves::get(&p, i).unwrap() {
                Value::F32(x) => x.abs(),
                Value::U32(x) => x as f32,
                _ => 0.0,
            };
            println!("{name}: {} = {size} (bound {bound}, {:?})", leaves::path(i), ranges::UNITS[i]);
            assert!(size <= bound, "{name}: {} = {size} beyond {bound}", leaves::path(i));
        }
        let (wc, ws, wp) = ranges::crossovers_rad_s(&p);
        println!("{name}: crossovers current {:.0} Hz, speed {:.1} Hz, position {:.1} Hz", wc / 6.283, ws / 6.283, wp / 6.283);
        p.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// Largest q current over 0.3 s at rest, holding the rated payload, with
/// set `p` (commissioned, homed, enabled); `None` if it will not run.
fn hold_current_max(p: ControlParams) -> Option<(f32, u32)> {
    let rig = RigConfig::nominal().unwrap();
    let mut plant = host_sim::plant::Plant::new(rig.plant.clone(), 3);
    plant.set_initial_state((0.25 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), std::f64::consts::FRAC_PI_2);
    let c = servo_core::Controller::try_new(host_sim::sim::commissioned_control(p, &plant)).ok()?;
    let mut cl = host_sim::sim::ClosedLoop::new(c, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.controller.command(servo_core::Command::SetHome { position_m: 0.25 }).ok()?;
    cl.controller.command(servo_core::Command::Enable).ok()?;
    let mut iq: f32 = 0.0;
    let mut faults = 0;
    for k in 0..6000 {
        let t = cl.step();
        if k > 2000 {
            iq = iq.max(t.current_q_reference_a.abs());
        }
        faults |= t.faults.bits();
    }
    Some((iq, faults))
}

#[test]
fn no_accepted_value_drives_the_current_to_its_limit_at_rest() {
    let base = RigConfig::nominal().unwrap().control;
    let (nominal, _) = hold_current_max(base).unwrap();
    let mut tried = 0;
    for i in 0..leaves::LEAF_COUNT {
        if !matches!(leaves::leaf(i).unwrap().kind, ValueKind::F32) || ranges::UNITS[i] == Unit::Free && !leaves::path(i).contains("_pi.") && !leaves::path(i).contains("position_kp") {
            continue;
        }
        let Value::F32(d) = leaves::get(&base, i).unwrap() else { continue };
        let bound = ranges::leaf_bound(i, &base).unwrap();
        // From the default up to the largest value the range accepts.
        for v in [d * 10.0, d * 1e3, bound.min(1e30) * 0.999 * d.signum(), 1e30] {
            let mut p = base;
            leaves::set(&mut p, i, Value::F32(v)).unwrap();
            if p.validate().is_err() {
                continue;
            }
            let Some((iq, faults)) = hold_current_max(p) else { continue };
            tried += 1;
            let limit = p.limits.current_max_a.min(base.limits.current_max_a);
            assert!(
                iq < 0.9 * limit,
                "{} = {v} accepted, yet the q current reaches {iq:.1} A at rest (limit {limit} A, nominal {nominal:.1} A, faults {faults:#x})",
                leaves::path(i)
            );
        }
    }
    println!("{tried} accepted values held at rest; nominal |i_q| {nominal:.2} A");
    assert!(tried > 50);
}
