//! The host tool against the simulated drive, end to end over TCP: the
//! drive runs in a thread on an ephemeral port (fast pacing), the tool's
//! own functions talk to it.

mod drive_support;

use drive_support::Drive;
use host_sim::config::RigConfig;
use host_sim::tool::client::Client;
use host_sim::tool::{self, stream};
use servo_core::protocol::{self, CaptureTrigger, DriveCommand, Error, Reply, Request, Signal, StreamPoint, Value};
use std::time::Duration;

fn enabled(c: &mut Client) {
    c.ask(Request::Command(DriveCommand::Enable)).unwrap();
    tool::test::wait_running(c).unwrap();
}

#[test]
fn connect_checks_the_schema_and_info_names_the_drive() {
    let d = Drive::start(None);
    let mut c = d.connect();
    let info = tool::info_json(&mut c).unwrap();
    assert_eq!(info["schema_hash"], tool::client::hex(&protocol::SCHEMA_HASH));
    assert_eq!(info["pwm_frequency_hz"], 20000.0);
    // A drive of another schema is refused, naming both hashes.
    let mut other = c.info.clone().unwrap();
    other.schema_hash[0] ^= 0xff;
    let e = tool::client::check_schema(&other).unwrap_err().to_string();
    assert!(e.contains(&tool::client::hex(&other.schema_hash)) && e.contains(&tool::client::hex(&protocol::SCHEMA_HASH)), "{e}");
}

#[test]
fn a_gain_set_and_saved_survives_a_restart_of_the_drive() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("flash.bin");
    {
        let d = Drive::start(Some(store.clone()));
        let mut c = d.connect();
        let kp = tool::param_get(&mut c, "control.speed_pi.kp").unwrap();
        assert!(matches!(kp, Value::F32(x) if x > 0.0), "{kp:?}");
        assert_eq!(tool::param_set(&mut c, "control.speed_pi.kp", "0.375").unwrap(), Value::F32(0.375));
        c.ask(Request::Save).unwrap();
        // Defaults: back to the image's value until loaded again.
        c.ask(Request::Defaults).unwrap();
        assert_eq!(tool::param_get(&mut c, "speed_pi.kp").unwrap(), kp);
    }
    let d = Drive::start(Some(store));
    let mut c = d.connect();
    // The board loads its record at start-up; `Load` does it on request.
    assert_eq!(tool::param_get(&mut c, "speed_pi.kp").unwrap(), Value::F32(0.375));
    c.ask(Request::Defaults).unwrap();
    assert!(matches!(c.ask(Request::Load).unwrap(), Reply::Loaded { from_flash: true, .. }));
    assert_eq!(tool::param_get(&mut c, "speed_pi.kp").unwrap(), Value::F32(0.375));
    // Saving needs the bridge off.
    enabled(&mut c);
    assert_eq!(c.request(Request::Save).unwrap(), Reply::Error(Error::BridgeOn));
    // Every parameter is listed with a value.
    let all = tool::param_list(&mut c).unwrap();
    assert!(all.len() > 100 && all.iter().any(|(p, _)| p == "control.speed_pi.kp"), "{}", all.len());
}

#[test]
fn bad_input_gets_error_replies() {
    let d = Drive::start(None);
    let mut c = d.connect();
    // A corrupted frame: one flipped bit breaks the CRC.
    let mut buf = [0u8; protocol::FRAME_MAX];
    let frame = protocol::encode(&protocol::RequestFrame { seq: 9, request: Request::Status }, &mut buf).unwrap().to_vec();
    let mut bad = frame.clone();
    bad[2] ^= 0x10;
    c.send_raw(&bad).unwrap();
    c.poll(Duration::from_millis(200)).unwrap();
    let u = c.unsolicited.drain(..).collect::<Vec<_>>();
    assert!(
        u.iter().any(|u| u.seq == 0 && matches!(u.error, Reply::Error(Error::Frame(_)))),
        "{u:?}"
    );
    // … and the link still works afterwards.
    assert!(matches!(c.ask(Request::Status).unwrap(), Reply::Status(_)));
    // Unknown path, NaN, a value of the wrong type.
    let e = tool::param_get(&mut c, "speed_pi.nope").unwrap_err().to_string();
    assert!(e.contains("no parameter `control.speed_pi.nope`"), "{e}");
    let e = tool::param_set(&mut c, "speed_pi.kp", "NaN").unwrap_err().to_string();
    assert!(e.contains("finite"), "{e}");
    let r = c.request(Request::ParamSet { index: servo_core::leaf!(speed_pi.kp), value: Value::Bool(true) }).unwrap();
    assert!(matches!(r, Reply::Error(Error::WrongType { .. })), "{r:?}");
    // A NaN stream point is refused with its seq.
    enabled(&mut c);
    let seq = c.send(Request::Stream(StreamPoint { position_m: f32::NAN, velocity_m_s: 0.0, force_n: None })).unwrap();
    c.poll(Duration::from_millis(200)).unwrap();
    assert!(
        c.unsolicited.iter().any(|u| u.seq == seq && matches!(&u.error, Reply::Error(Error::Stream { reason }) if reason.text().contains("not finite"))),
        "{:?}",
        c.unsolicited
    );
    // A raw client without the schema check still gets answers.
    let mut r = d.raw();
    drop(c);
    assert!(matches!(r.request(Request::Info).unwrap(), Reply::Info(_)));
}

/// Writes a CSV stream: `x0 + a sin(2π f t)` at 1 kHz, plus `jump_m` from
/// row `jump_at` on.
fn sine_csv(path: &std::path::Path, seconds: f64, jump: Option<(usize, f64)>) {
    let (x0, a, f) = (0.25, 0.005, 1.0);
    let mut s = String::from("t_s,position_m,velocity_m_s\n");
    for k in 0..(seconds * 1000.0) as usize {
        let t = k as f64 * 1e-3;
        let w = std::f64::consts::TAU * f;
        let extra = jump.filter(|(at, _)| k >= *at).map_or(0.0, |(_, j)| j);
        s += &format!("{t},{},{}\n", x0 + a * (w * t).sin() + extra, a * w * (w * t).cos());
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_csv_trajectory_streams_and_is_tracked() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("sine.csv");
    sine_csv(&file, 1.0, None);
    let rows = stream::read_csv(&file).unwrap();
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let fields = (1 << protocol::TelemetryField::PositionReference as u32) | (1 << protocol::TelemetryField::MotorPosition as u32);
    c.ask(Request::Telemetry { fields, rate_hz: 1000 }).unwrap();
    c.telemetry.clear();
    let r = stream::send(&mut c, &rows, false).unwrap();
    assert!(r.refusals.is_empty(), "{:?}", r.refusals);
    let tel: Vec<_> = c.telemetry.drain(..).collect();
    // Fast pacing: one telemetry record per 1 ms stream frame.
    assert!(tel.len() >= rows.len(), "{} records for {} frames", tel.len(), rows.len());
    let errs: Vec<f64> = tel[200..rows.len()].iter().map(|t| f64::from(t.values[0] - t.values[1])).collect();
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    let max = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    println!("streamed sine: tracking RMS {:.2} µm, max {:.2} µm", rms * 1e6, max * 1e6);
    assert!(rms < 10e-6 && max < 50e-6, "RMS {rms:e} max {max:e}");
    // The drive's clock moved exactly one stream period per frame.
    let dt = tel[rows.len() - 1].time_s - tel[0].time_s;
    assert!((f64::from(dt) - (rows.len() - 1) as f64 * 1e-3).abs() < 1e-4, "{dt}");
}

#[test]
fn a_stream_that_jumps_beyond_the_speed_limit_is_refused_at_its_row() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("jump.csv");
    // 20 mm in one millisecond: 20 m/s asked, far beyond the limit.
    sine_csv(&file, 0.4, Some((200, 0.02)));
    let rows = stream::read_csv(&file).unwrap();
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let speed_max = match tool::param_get(&mut c, "limits.speed_max_rad_s").unwrap() {
        Value::F32(x) => x,
        v => panic!("{v:?}"),
    };
    c.ask(Request::Telemetry { fields: 1 << protocol::TelemetryField::Speed as u32, rate_hz: 1000 }).unwrap();
    let r = stream::send(&mut c, &rows, false).unwrap();
    println!("refusals: {:?}, aborted at {:?}", r.grouped(), r.aborted_at_row);
    let w = c.telemetry.iter().map(|t| t.values[0].abs()).fold(0.0f32, f32::max);
    println!("peak speed {w} rad/s (limit {speed_max})");
    assert!(w <= speed_max * 1.05, "{w} > {speed_max}");
    let st = match c.ask(Request::Status).unwrap() {
        Reply::Status(s) => s,
        r => panic!("{r:?}"),
    };
    println!("faults: {:?}", servo_core::FaultSet::from_bits_retain(st.faults).names().collect::<Vec<_>>());
    // The core server refuses the first point of the jump, by its row.
    let (row, why) = r.refusals.first().expect("the jump was refused");
    assert_eq!(*row, 201, "{why}");
    assert!(why.contains("jump beyond control.trajectory.max_velocity_m_s"), "{why}");
    // Sending stops soon after the drive stops taking points.
    if let Some(row) = r.aborted_at_row {
        assert!(r.sent < rows.len() && row < rows.len(), "{row}");
    }
}

#[test]
fn rows_recorded_at_100_hz_sent_at_the_drives_1_khz_are_refused_by_the_drive_at_their_row_with_the_figure() {
    // 20 mm/s at 100 Hz: 0.2 mm a row, within the jump bound at 1 ms a
    // frame, but ten times the speed the velocity column states. The
    // tool's own check would refuse the file before sending (the drive
    // says it expects 1 kHz); sent anyway, the drive refuses it itself.
    let rows: Vec<stream::Row> = (0..300)
        .map(|k| stream::Row { t_s: k as f64 * 0.01, position_m: 0.25 + 0.02 * k as f64 * 0.01, velocity_m_s: 0.02, force_n: None })
        .collect();
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let r = stream::send(&mut c, &rows, false).unwrap();
    println!("refusals: {:?}", r.grouped());
    let (row, why) = r.refusals.first().expect("refused by the drive");
    assert!(*row > 1 && *row <= 50, "row {row}: {why}");
    assert!(why.contains("velocity_m_s disagrees with the position steps") && why.contains("m/s against 0.0500 m/s"), "{why}");
}

#[test]
fn stream_csv_errors_name_file_row_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.csv");
    std::fs::write(&file, "t_s,position_m,velocity_m_s\n0,0.25,0\n0.001,abc,0\n0.001,0.25,NaN\n").unwrap();
    let e = stream::read_csv(&file).unwrap_err().to_string();
    let name = file.display().to_string();
    assert!(e.contains(&format!("{name}:2:position_m")), "{e}");
    assert!(e.contains(&format!("{name}:3:velocity_m_s")), "{e}");
    std::fs::write(&file, "t_s,position_m\n0,0.25\n").unwrap();
    assert!(stream::read_csv(&file).unwrap_err().to_string().contains("no `velocity_m_s` column"));
}

#[test]
fn a_capture_is_armed_triggered_and_uploaded() {
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let cap = tool::capture(
        &mut c,
        &[Signal::CurrentQ, Signal::Speed, Signal::MotorPosition, Signal::BusVoltage],
        500,
        2,
        50,
        CaptureTrigger::Command,
        Duration::from_secs(20),
    )
    .unwrap();
    assert_eq!(cap.values.len(), 4);
    assert_eq!(cap.len(), 500);
    assert!((cap.dt_s - 1e-4).abs() < 1e-9, "{}", cap.dt_s);
    assert!(cap.values[3].iter().all(|v| (*v - 48.0).abs() < 5.0), "bus {:?}", &cap.values[3][..5]);
    assert!(cap.values[2].iter().all(|x| (*x - 0.25).abs() < 1e-3), "position");
}

#[test]
fn a_step_test_is_captured_analysed_and_predicted() {
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let dir = tempfile::tempdir().unwrap();
    let rig = RigConfig::nominal().unwrap();
    let spec = tool::test::Spec::step(tool::test::Target::Position, 0.001, 0.2);
    let s = tool::test::run(&mut c, &rig, &spec, dir.path()).unwrap();
    println!("{}", serde_json::to_string_pretty(&s).unwrap());
    for f in ["capture.csv", "prediction.csv", "response.png", "summary.json"] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
    // A 1 mm position step: the motor side gets there, settles, and the
    // simulator (same rig, same gains) predicts it closely.
    let m = &s["measured"]["step"];
    let p = &s["predicted"]["step"];
    let change = m["final_value"].as_f64().unwrap() - m["initial"].as_f64().unwrap();
    assert!((change - 0.001).abs() < 5e-5, "{m}");
    let (rm, rp) = (m["rise_time_s"].as_f64().unwrap(), p["rise_time_s"].as_f64().unwrap());
    assert!(rm > 0.0 && rm < 0.1 && (rm - rp).abs() < 0.005, "{rm} vs {rp}");
    assert!(m["settling_time_s"].as_f64().unwrap() < 0.2, "{m}");
    // A chirp on the position loop: FRF figures from H1.
    let spec = tool::test::Spec::chirp(tool::test::Target::Position, 0.0002, 1.0, 100.0, 1.0);
    let s = tool::test::run(&mut c, &rig, &spec, dir.path()).unwrap();
    let f = &s["measured"]["frf"];
    println!("{f}");
    assert!(f["bandwidth_3db_hz"].as_f64().unwrap() > 3.0, "{f}");
    assert!(f["phase_margin_deg"].as_f64().unwrap() > 45.0, "{f}");
    assert!(dir.path().join("bode.png").exists());
    // A chirp too long for the capture store is refused with what fits.
    let spec = tool::test::Spec::chirp(tool::test::Target::Current, 1.0, 50.0, 3000.0, 1.0);
    let e = tool::test::capture_test(&mut c, &spec, 20_000.0).unwrap_err().to_string();
    assert!(e.contains("--duration <="), "{e}");
}

/// A client that pauses 0.5 s mid-stream: the drive stops the rod and
/// latches `stream_timeout`; the points after the pause are refused as
/// faults latched (not "not running", whose advice would be `enable`), and
/// the tool's closing error names the fault, why, and `clear-faults` then
/// `enable`.
#[test]
fn a_client_paused_mid_stream_is_told_the_fault_and_the_commands_that_resume() {
    let mut o = host_sim::drive::DriveOptions::new(RigConfig::nominal().unwrap());
    o.pace = host_sim::drive::Pace::Fast;
    o.commissioned = true;
    let (addr, stop, h) = host_sim::drive::spawn_local(o).unwrap();
    let mut c = Client::connect(&host_sim::tool::client::Endpoint::Tcp(addr.to_string())).unwrap();
    enabled(&mut c);
    let point = |k: usize| StreamPoint { position_m: 0.25 + 0.02 * k as f32 * 1e-3, velocity_m_s: 0.02, force_n: None };
    for k in 0..200 {
        c.send(Request::Stream(point(k))).unwrap();
    }
    // The pause: longer than the drive's lock-step idle time, so it runs on.
    std::thread::sleep(Duration::from_millis(500));
    for k in 700..720 {
        c.send(Request::Stream(point(k))).unwrap();
    }
    let st = match c.request(Request::Status).unwrap() {
        Reply::Status(s) => s,
        r => panic!("{r:?}"),
    };
    let faults: Vec<String> = servo_core::FaultSet::from_bits_retain(st.faults).names().map(str::to_string).collect();
    let reasons: Vec<String> = c.unsolicited.iter().map(|u| format!("{:?}", u.error)).collect();
    println!("after the pause: faults {faults:?}, refusals {reasons:?}");
    assert_eq!(faults, ["stream_timeout"]);
    assert!(!reasons.is_empty() && reasons.iter().all(|r| r.contains("RefusedFaultsLatched")), "{reasons:?}");
    let advice = stream::fault_advice("ramp.csv", &faults);
    println!("{advice}");
    assert!(advice.starts_with("ramp.csv: faults latched: stream_timeout (") && advice.contains("next: `cmd clear-faults`, then `cmd enable`"), "{advice}");
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap().unwrap();
}

/// `set-home -0.1` typed on a running drive (a sign slipped in): refused,
/// nothing changed, rather than taken and tripping the overtravel check
/// with the load dropped onto the brake.
#[test]
fn a_set_home_beyond_the_stroke_on_a_running_drive_is_refused() {
    let d = Drive::start(None);
    let mut c = d.connect();
    enabled(&mut c);
    let r = c.ask(Request::Command(DriveCommand::SetHome { position_m: -0.1 }));
    let e = r.unwrap_err().to_string();
    println!("{e}");
    assert!(e.contains("set-home -0.1") && e.contains("beyond its bound"), "{e}");
    let st = match c.ask(Request::Status).unwrap() {
        Reply::Status(s) => s,
        r => panic!("{r:?}"),
    };
    assert_eq!(st.faults, 0);
    assert_eq!(st.mode, servo_core::Mode::Running);
    // Within the stroke it is taken.
    assert!(c.ask(Request::Command(DriveCommand::SetHome { position_m: 0.2 })).is_ok());
}

#[test]
fn a_test_asked_while_the_brake_still_opens_waits_for_it() {
    // A brake that takes 3 s of drive time to open: the predicted
    // test is asked as soon as the drive reports Running, while the brake
    // still opens, and the drive refuses tests until it has.
    let rig = RigConfig::nominal().unwrap();
    let mut params = rig.control.clone();
    params.brake.release_time_s = 3.0;
    let spec = tool::test::Spec::step(tool::test::Target::Position, 0.001, 0.2);
    let cap = tool::test::predict(&rig, params, 0.25, &spec).unwrap();
    let position = &cap.values[1];
    let moved = position.last().unwrap() - position.first().unwrap();
    assert!((moved - 0.001).abs() < 1e-4, "the 1 mm step moved {moved} m");
}
