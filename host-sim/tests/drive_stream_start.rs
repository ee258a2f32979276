//! How `drive stream` starts: the drive starts every stream from rest where
//! its position reference is, so a trajectory whose first row moves, or
//! lies away from that reference, starts with a lurch. The tool refuses
//! both before sending anything, naming the file, row 1 and the field; the
//! same rows sent without the check show the lurch it prevents (following
//! error beyond the stream's 50 µm bound), and the fixes the message names
//! (start from rest, `move` there first) stream within it. A drive that is
//! not running is named before anything is sent.

mod drive_support;

use drive_support::Drive;
use host_sim::tool::stream::{self, Row};
use host_sim::tool::{stream_cmd, test::wait_running};
use servo_core::protocol::{DriveCommand, Reply, Request};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The stream's following-error bound, m (the stream-loss benchmark's).
const BOUND_UM: f64 = 50.0;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("drive_stream_start_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_csv(path: &Path, rows: &[Row]) {
    let mut text = String::from("t_s,position_m,velocity_m_s\n");
    for r in rows {
        text.push_str(&format!("{},{},{}\n", r.t_s, r.position_m, r.velocity_m_s));
    }
    std::fs::write(path, text).unwrap();
}

/// 0.5 s at 1 kHz from `x0`: at `v0` throughout, or from rest accelerating
/// at 2 m/s² to `v0` (`from_rest`).
fn rows(x0: f64, v0: f64, from_rest: bool) -> Vec<Row> {
    let a = 2.0 * v0.signum();
    let t_acc = if from_rest { v0.abs() / 2.0 } else { 0.0 };
    (0..=500)
        .map(|k| {
            let t = k as f64 * 1e-3;
            let (x, v) = if t < t_acc { (x0 + 0.5 * a * t * t, a * t) } else { (x0 + 0.5 * a * t_acc * t_acc + v0 * (t - t_acc), v0) };
            Row { t_s: t, position_m: x, velocity_m_s: v, force_n: None }
        })
        .collect()
}

fn enabled(d: &Drive) -> host_sim::tool::client::Client {
    let mut c = d.connect();
    c.timeout = Duration::from_secs(10);
    c.ask(Request::Command(DriveCommand::Enable)).unwrap();
    wait_running(&mut c).unwrap();
    c
}

#[test]
fn a_trajectory_that_starts_moving_is_refused_and_would_have_lurched() {
    let d = Drive::start(None);
    let mut c = enabled(&d);
    let out = dir("moving");
    let x0 = stream::reference_position(&mut c).unwrap();
    // The case the tool used to send silently: 0.079 m/s from the first row.
    let moving = rows(x0, 0.079, false);
    let csv = out.join("moving.csv");
    write_csv(&csv, &moving);
    let e = format!("{:#}", stream_cmd::run(&mut c, &csv, true, &out.join("s1")).unwrap_err());
    assert!(e.contains("moving.csv:1:velocity_m_s") && e.contains("0.079 m/s") && e.contains("from rest") && e.contains("nothing was sent"), "{e}");
    assert!(!out.join("s1").join("summary.json").exists(), "a refused stream wrote figures");
    // Sent anyway, the lurch is real.
    let r = stream::send_with(&mut c, &moving, false, true).unwrap();
    let lurch = r.tracking_max_um.unwrap();
    assert!(lurch > 4.0 * BOUND_UM, "0.079 m/s from rest: {lurch} µm");
    // From rest, the same speed: accepted and within the bound.
    let x1 = stream::reference_position(&mut c).unwrap();
    let calm = rows(x1, 0.079, true);
    let csv = out.join("calm.csv");
    write_csv(&csv, &calm);
    stream_cmd::run(&mut c, &csv, true, &out.join("s2")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("s2").join("summary.json")).unwrap()).unwrap();
    let max = s["tracking_max_um"].as_f64().unwrap();
    assert!(max < BOUND_UM, "from rest: {max} µm (the moving start: {lurch} µm)");
    // Just inside the start bound: accepted, and its lurch within the bound.
    let x2 = stream::reference_position(&mut c).unwrap();
    let slow = rows(x2, 0.9 * stream::START_VELOCITY_MAX_M_S, false);
    let csv = out.join("slow.csv");
    write_csv(&csv, &slow);
    stream_cmd::run(&mut c, &csv, true, &out.join("s3")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("s3").join("summary.json")).unwrap()).unwrap();
    let max = s["tracking_max_um"].as_f64().unwrap();
    assert!(max < BOUND_UM, "starting at {} m/s: {max} µm", 0.9 * stream::START_VELOCITY_MAX_M_S);
}

#[test]
fn a_first_point_away_from_the_reference_is_refused_until_the_rod_is_moved_there() {
    let d = Drive::start(None);
    let mut c = enabled(&d);
    let out = dir("offset");
    let x0 = stream::reference_position(&mut c).unwrap();
    let away = rows(x0 + 0.001, 0.0, false);
    let csv = out.join("away.csv");
    write_csv(&csv, &away);
    let e = format!("{:#}", stream_cmd::run(&mut c, &csv, true, &out.join("s1")).unwrap_err());
    assert!(e.contains("away.csv:1:position_m") && e.contains("1.000 mm") && e.contains("`move ") && e.contains("nothing was sent"), "{e}");
    // Sent anyway, the rod jumps the millimetre in one setpoint interval.
    let r = stream::send_with(&mut c, &away, false, true).unwrap();
    let jump = r.tracking_max_um.unwrap();
    assert!(jump > 10.0 * BOUND_UM, "1 mm from the reference: {jump} µm");
    // The fix the message names: `move` to the first point, then stream.
    let target = x0 + 0.002;
    assert!(matches!(c.ask(Request::Command(DriveCommand::MoveTo { position_m: target as f32 })).unwrap(), Reply::Command(_)));
    let t0 = Instant::now();
    while (stream::reference_position(&mut c).unwrap() - target).abs() > 1e-7 {
        assert!(t0.elapsed() < Duration::from_secs(5), "the move did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(100));
    let there = rows(target, 0.0, false);
    let csv = out.join("there.csv");
    write_csv(&csv, &there);
    stream_cmd::run(&mut c, &csv, true, &out.join("s2")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("s2").join("summary.json")).unwrap()).unwrap();
    let max = s["tracking_max_um"].as_f64().unwrap();
    assert!(max < BOUND_UM, "after `move`: {max} µm");
}

#[test]
fn a_drive_that_is_not_running_is_named_before_anything_is_sent() {
    let d = Drive::start(None);
    let mut c = d.connect();
    let out = dir("disabled");
    let csv = out.join("rest.csv");
    write_csv(&csv, &rows(0.25, 0.0, false));
    let e = format!("{:#}", stream_cmd::run(&mut c, &csv, true, &out.join("s")).unwrap_err());
    assert!(e.contains("rest.csv") && e.contains("Disabled") && e.contains("cmd enable") && e.contains("nothing was sent"), "{e}");
}
