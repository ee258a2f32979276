//! The host tool against the mistakes a bench makes, run as a user runs it
//! (the `host-sim` binary against a simulated drive over TCP): every one
//! gets an error naming the file, row, field or argument and a non-zero
//! exit, never a panic (exit 101), and nothing reaches the drive. Ctrl-C
//! during a stream ends it with a stop and a report, not a lost stream.

mod drive_support;

use drive_support::Drive;
use host_sim::tool::stream::{self, Row};
use servo_core::protocol::{DriveCommand, Reply, Request};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("drive_bad_input_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn tool(d: &Drive, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim")).args(["drive", "--tcp", &d.addr.to_string()]).args(args).env_remove("RUST_BACKTRACE").output().unwrap()
}

fn said(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn status(d: &Drive) -> servo_core::protocol::Status {
    match d.connect().request(Request::Status).unwrap() {
        Reply::Status(s) => s,
        r => panic!("{r:?}"),
    }
}

#[test]
fn numbers_that_are_not_finite_or_in_range_are_named_never_a_panic() {
    let d = Drive::start(None);
    for (args, flag) in [
        (&["--timeout-s", "nan", "status"][..], "--timeout-s"),
        (&["--timeout-s", "inf", "status"], "--timeout-s"),
        (&["--timeout-s", "-1", "status"], "--timeout-s"),
        (&["capture", "--signals", "speed", "--wait-s", "nan"], "--wait-s"),
        (&["capture", "--signals", "speed", "--samples", "0"], "--samples"),
        (&["step", "position", "0.001", "--duration", "nan"], "--duration"),
        (&["telemetry", "--csv", "/dev/null", "--rate-hz", "0"], "--rate-hz"),
        (&["telemetry", "--csv", "/dev/null", "--seconds", "1e300"], "--seconds"),
        (&["chirp", "position", "--amplitude", "0.0002", "--from", "0", "--to", "100"], "--from"),
    ] {
        let o = tool(&d, args);
        let text = said(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {text}");
        assert!(text.contains(&format!("'{flag} <")), "{args:?} does not name {flag}: {text}");
    }
}

#[test]
fn a_move_outside_the_stroke_is_refused_before_the_rod_moves_with_the_unit_named() {
    let d = Drive::start(None);
    assert!(tool(&d, &["cmd", "enable"]).status.success());
    std::thread::sleep(Duration::from_millis(300));
    let before = status(&d).position_m;
    let o = tool(&d, &["move", "250"]);
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains("move 250") && text.contains("outside the stroke") && text.contains("millimetres? positions are in metres: 0.25 m") && text.contains("nothing was sent"), "{text}");
    let o = tool(&d, &["jog", "5"]);
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains("jog 5") && text.contains("distances are in metres: 0.005 m"), "{text}");
    std::thread::sleep(Duration::from_millis(200));
    assert!((status(&d).position_m - before).abs() < 20e-6, "the rod moved");
    // Within the stroke the move goes, and a refused test names the command as typed.
    assert!(tool(&d, &["move", "0.26"]).status.success());
    let text = said(&tool(&d, &["step", "position", "1e30"]));
    assert!(text.contains("step position 1000000000000000000000000000000 --duration 0.1: refused"), "{text}");
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

#[test]
fn csv_mistakes_are_named_by_file_row_and_field() {
    let d = dir("csv");
    let err = |name: &str, text: &str| {
        let p = d.join(name);
        write(&p, text);
        format!("{:#}", stream::read_csv(&p).unwrap_err())
    };
    let e = err("empty.csv", "");
    assert!(e.contains("empty.csv: empty: no header row"), "{e}");
    let e = err("dup.csv", "t_s,position_m,velocity_m_s,position_m\n0,0.25,0,0.3\n");
    assert!(e.contains("dup.csv") && e.contains("`position_m` twice (columns 2 and 4)"), "{e}");
    let e = err("deg.csv", "t_s,position_deg,velocity_m_s\n0,14.3,0\n");
    assert!(e.contains("no `position_m` column") && e.contains("the header has: t_s, position_deg, velocity_m_s"), "{e}");
    let e = err("short.csv", "t_s,position_m,velocity_m_s\n0,0.25,0\n0.001,0.25\n0.002,0.25,0,9\n");
    assert!(e.contains("short.csv:2: 2 fields, the header has 3") && e.contains("short.csv:3: 4 fields"), "{e}");
    let e = format!("{:#}", stream::read_csv(&d).unwrap_err());
    assert!(e.contains(&d.display().to_string()), "a folder given as the CSV: {e}");

    // Units: millimetres for metres, mm/s for m/s, milliseconds for seconds.
    let p = servo_core::ControlParams::default();
    let limits = stream::StreamLimits::of(&p, 1e-3);
    let row = |t: f64, x: f64, v: f64| Row { t_s: t, position_m: x, velocity_m_s: v, force_n: None };
    let mm: Vec<_> = (0..3).map(|k| row(k as f64 * 1e-3, 250.0, 0.0)).collect();
    let e = stream::check_rows("mm.csv", &mm, &limits).unwrap_err().to_string();
    assert!(e.contains("mm.csv:1:position_m") && e.contains("millimetres? positions are in metres: 0.25 m"), "{e}");
    let mm_s: Vec<_> = (0..3).map(|k| row(k as f64 * 1e-3, 0.25 + 0.05 * k as f64 * 1e-3, 50.0)).collect();
    let e = stream::check_rows("mms.csv", &mm_s, &limits).unwrap_err().to_string();
    assert!(e.contains("mms.csv:1:velocity_m_s") && e.contains("mm/s? the column is in m/s"), "{e}");
    // A velocity column in mm/s on a slow move: the steps disagree by 1000 ×.
    let slow: Vec<_> = (0..3).map(|k| row(k as f64 * 1e-3, 0.25 + 0.05 * k as f64 * 1e-3, 50.0 * (k.min(1) as f64))).collect();
    let e = stream::check_rows("slow.csv", &slow, &limits).unwrap_err().to_string();
    assert!(e.contains("slow.csv:3:velocity_m_s: the position step") && e.contains("(mm/s? the column is in m/s)"), "{e}");
    let ms: Vec<_> = (0..3).map(|k| row(k as f64, 0.25, 0.0)).collect();
    let e = stream::check_rows("ms.csv", &ms, &limits).unwrap_err().to_string();
    assert!(e.contains("ms.csv:2:t_s") && e.contains("t_s in milliseconds?") && !e.contains("--stream-period-s"), "{e}");
}

#[test]
fn ctrl_c_mid_stream_ends_it_with_a_stop_and_says_so() {
    let d = Drive::start(None);
    let out = dir("ctrlc");
    let csv = out.join("long.csv");
    host_sim::tool::bench_asap::write_trajectory(&csv, 10.0, 1000.0).unwrap();
    let mut c = d.connect();
    c.timeout = Duration::from_secs(10);
    c.ask(Request::Command(DriveCommand::Enable)).unwrap();
    host_sim::tool::test::wait_running(&mut c).unwrap();
    drop(c);
    // Paced at the CSV's times: 10 s, interrupted after about one.
    let child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["drive", "--tcp", &d.addr.to_string(), "stream"])
        .arg(&csv)
        .arg("--out")
        .arg(out.join("s"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1200));
    // The shell's own `kill`: no procps needed.
    assert!(Command::new("sh").args(["-c", &format!("kill -INT {}", child.id())]).status().unwrap().success());
    let o = child.wait_with_output().unwrap();
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains("long.csv: interrupted (Ctrl-C) before row") && text.contains("the drive holds"), "{text}");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("s").join("summary.json")).unwrap()).unwrap();
    let row = s["interrupted_at_row"].as_u64().unwrap();
    assert!(row > 100 && row < 10_000, "interrupted at row {row}");
    // A stop, not a lost stream: no fault, still running, holding still.
    std::thread::sleep(Duration::from_millis(300));
    let st = status(&d);
    assert_eq!(st.faults, 0, "faults latched after Ctrl-C: {:?}", servo_core::FaultSet::from_bits_retain(st.faults));
    assert_eq!(st.mode, servo_core::Mode::Running);
    assert!(st.speed_rad_s.abs() < 1.0, "still moving: {} rad/s", st.speed_rad_s);
}

#[test]
fn a_parameter_file_with_a_typo_is_refused_naming_the_path_and_the_likely_one() {
    use host_sim::tool::config_file::read_leaves;
    let d = dir("toml");
    let err = |name: &str, text: &str| {
        let p = d.join(name);
        write(&p, text);
        format!("{:#}", read_leaves(&p).unwrap_err())
    };
    let e = err("typo.toml", "[control.speed_pi]\nkpp = 0.3\n");
    assert!(e.contains("typo.toml: `control.speed_pi.kpp`: no such parameter: did you mean `control.speed_pi.kp`?") && e.contains("nothing was sent"), "{e}");
    let e = err("table.toml", "[speed_pi]\nkp = 0.3\n");
    assert!(e.contains("under `[control]`: `control.speed_pi.kp`"), "{e}");
    let e = err("enum.toml", "[control.homing]\nmethod = \"hardstop\"\n");
    assert!(e.contains("`control.homing.method`: \"hardstop\" is not one of \"HardStop\", \"Switch\""), "{e}");
    let e = err("type.toml", "[control.speed_pi]\nkp = \"abc\"\n");
    assert!(e.contains("`control.speed_pi.kp`: \"abc\" is not a number"), "{e}");
    let e = err("empty.toml", "# nothing\n");
    assert!(e.contains("empty.toml: no parameters"), "{e}");
    // A sane file still reads.
    let p = d.join("ok.toml");
    write(&p, "[control.speed_pi]\nkp = 0.3\n");
    assert_eq!(read_leaves(&p).unwrap().len(), 1);
}

#[test]
fn a_simulated_drive_started_outside_its_stroke_or_rates_is_refused_not_a_panic() {
    for (args, says) in [
        (&["--initial-position-m", "10"][..], "--initial-position-m 10: outside the rig's stroke"),
        (&["--initial-position-m", "250"], "millimetres? positions are in metres: 0.25 m"),
        (&["--stream-period-s", "0.5"], "--stream-period-s 0.5: the drive interpolates streams at"),
        (&["--stream-period-s", "1e-6"], "--stream-period-s 0.000001"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["drive", "serve", "--listen", "127.0.0.1:0", "--pace", "fast", "--commissioned"])
            .args(args)
            .env_remove("RUST_BACKTRACE")
            .output()
            .unwrap();
        let text = said(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {text}");
        assert!(text.contains(says), "{args:?}: {text}");
    }
}
