//! Identification from a drive's own captures: the host tool's `step speed`
//! and `step current-d` against the simulated drive over TCP, each capture
//! read back from its `capture.csv` as a bench user's would be, give the
//! unit's magnet flux (not the drive's belief) and its winding.

use host_sim::config::RigConfig;
use host_sim::drive::{self, DriveOptions, Pace};
use host_sim::tool::client::{Client, Endpoint};
use host_sim::tool::test::{self, Spec, Target};
use host_sim::tuning::{self, identify::Capture};
use servo_core::protocol::{DriveCommand, Request};
use std::sync::atomic::Ordering;

#[test]
fn the_flux_is_identified_from_the_tools_own_speed_steps() {
    // A unit whose magnets carry 7 % less flux than the drive believes.
    let mut rig = RigConfig::nominal().unwrap();
    rig.plant.motor.flux_linkage_wb *= 0.93;
    let truth = rig.plant.motor.flux_linkage_wb;
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Fast;
    o.commissioned = true;
    let (addr, stop, h) = drive::spawn_local(o).unwrap();
    let mut c = Client::connect(&Endpoint::Tcp(addr.to_string())).unwrap();
    c.ask(Request::Command(DriveCommand::Enable)).unwrap();
    test::wait_running(&mut c).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let capture = |c: &mut Client, spec: &Spec, name: &str| {
        let out = dir.path().join(name);
        test::run(c, &rig, spec, &out).unwrap();
        Capture::read_csv(&out.join("capture.csv")).unwrap()
    };
    let speed: Vec<Capture> =
        [20.0, -20.0, 50.0, -50.0].iter().map(|a| capture(&mut c, &Spec::step(Target::Speed, *a, 0.25), &format!("speed_{a}"))).collect();
    let current = capture(&mut c, &Spec::step(Target::CurrentD, 8.0, 0.02), "current");
    stop.store(true, Ordering::Relaxed);
    h.join().unwrap().unwrap();
    assert!(speed[0].get("voltage_q").is_some(), "the speed step captures the q voltage: {:?}", speed[0].names);
    let (_, e) = tuning::identify(&speed, Some(&current), &rig.control).unwrap();
    let e = e.expect("the winding from the d-current step");
    let psi = e.flux_linkage_wb.as_ref().expect("the flux from the speed steps' q voltage").value;
    let belief = f64::from(rig.control.motor.flux_linkage_wb);
    println!("ψ identified {psi:.5} Wb, unit {truth:.5}, drive's belief {belief:.5}; R {:.4} Ω, L {:.3e} H", e.resistance_ohm.value, e.inductance_h.value);
    assert!((psi / truth - 1.0).abs() < 0.01, "ψ {psi} against the unit's {truth}");
    assert!((psi / belief - 1.0).abs() > 0.05, "ψ {psi} is the belief, not the unit's");
}
