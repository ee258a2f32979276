//! `drive identify stiffness` end to end on a simulated drive of a unit
//! softer than its rig file: the probe through the protocol, the ratio
//! against the truth, the scaled weights uploaded and run (by CRC), and
//! the probes it refuses, each with its reason.

mod drive_support;

use drive_support::Drive;
use host_sim::config::RigConfig;
use host_sim::rigs::Draw;
use host_sim::tool::observer;
use host_sim::tool::stiffness::{run, ProbeOptions};
use servo_core::observer::block::COMPILED;
use servo_core::protocol::observer::words_crc;
use servo_core::protocol::{DriveCommand, ObserverSource, Request};

fn enabled(d: &Drive) -> host_sim::tool::client::Client {
    let mut c = d.connect();
    c.ask(Request::Command(DriveCommand::Enable)).unwrap();
    host_sim::tool::test::wait_running(&mut c).unwrap();
    c
}

#[test]
fn a_softer_unit_is_identified_and_runs_the_scaled_weights() {
    let design = RigConfig::nominal().unwrap();
    let soft = Draw { stiffness: 0.85, ..Draw::BASE };
    let out = std::env::temp_dir().join(format!("drive_stiffness_{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let d = Drive::start_rig(soft.apply(&design), Some(out.join("flash.bin")), 0.25);
    let mut c = enabled(&d);
    let s = run(&mut c, &design, &ProbeOptions::default(), true, &out).unwrap();
    let ratio = s["identified"]["measured_ratio"].as_f64().unwrap();
    let applied = s["identified"]["compliance_ratio"].as_f64().unwrap();
    let u = s["identified"]["ratio_uncertainty"].as_f64().unwrap();
    let truth = 1.0 / 0.85;
    assert!((ratio / truth - 1.0).abs() < 0.05, "ratio {ratio} against {truth}");
    assert!((ratio - truth).abs() <= 2.0 * u, "ratio {ratio} ± {u} against {truth}");
    assert_eq!(applied, ratio);
    // The drive runs the compiled weights scaled by the ratio, word for word.
    let mut want = COMPILED;
    want.output_scale = (f64::from(want.output_scale) * applied) as f32;
    want.output_offset = (f64::from(want.output_offset) * applied) as f32;
    let st = observer::status(&mut c).unwrap();
    assert_eq!(st.source, ObserverSource::Uploaded);
    assert_eq!(st.words_crc, words_crc(&want));
    assert_eq!(s["weights"]["words_crc"].as_str().unwrap(), format!("{:08x}", words_crc(&want)));
    // The captures and the record are written.
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("stiffness.json")).unwrap()).unwrap();
    // Equal to the printed figures up to the last digit of the decimal
    // text (serde_json's default float parse may differ from it by an ulp).
    for k in ["measured_ratio", "compliance_ratio", "ratio_uncertainty", "mode_hz", "design_mode_hz"] {
        let (a, b) = (j["identified"][k].as_f64().unwrap(), s["identified"][k].as_f64().unwrap());
        assert!((a - b).abs() <= 1e-12 * b.abs(), "{k}: {a} in the file, {b} returned");
    }
    for k in 1..=3 {
        assert!(out.join(format!("probe_{k}.csv")).exists());
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn a_probe_it_cannot_run_is_refused_with_the_reason() {
    let design = RigConfig::nominal().unwrap();
    let out = std::env::temp_dir().join(format!("drive_stiffness_refused_{}", std::process::id()));
    // Not enabled: nothing holds the load.
    let d = Drive::start(None);
    let mut c = d.connect();
    let e = format!("{:#}", run(&mut c, &design, &ProbeOptions::default(), false, &out).unwrap_err());
    assert!(e.contains("cmd enable"), "{e}");
    // Too near the stroke's end for the probe's motion.
    drop(c);
    drop(d);
    let d = Drive::start_rig(design.clone(), None, 0.01);
    let mut c = enabled(&d);
    let e = format!("{:#}", run(&mut c, &design, &ProbeOptions::default(), false, &out).unwrap_err());
    assert!(e.contains("drive move"), "{e}");
    // A step down lets the load fall: the drive faults and the tool says so.
    drop(c);
    drop(d);
    let d = Drive::start(None);
    let mut c = enabled(&d);
    let e = format!("{:#}", run(&mut c, &design, &ProbeOptions { step_a: -6.0, ..Default::default() }, false, &out).unwrap_err());
    assert!(e.contains("speed_following"), "{e}");
    let _ = std::fs::remove_dir_all(&out);
}
