//! The simulated drive with several clients: one controls, the others read
//! and are refused control by name; the parameter set exported to TOML and
//! imported back unchanged (enums by name); a stream CSV of the wrong rate
//! or with a velocity that disagrees with its steps is refused by row.

use host_sim::config::RigConfig;
use host_sim::drive::{self, DriveOptions, Pace};
use host_sim::tool::client::{Client, Endpoint};
use host_sim::tool::{config_file, stream};
use servo_core::protocol::{DriveCommand, Error, Reply, Request};
use std::sync::atomic::Ordering;

#[test]
fn one_client_controls_the_others_read_and_are_refused_by_name() {
    let mut o = DriveOptions::new(RigConfig::nominal().unwrap());
    o.pace = Pace::Fast;
    o.commissioned = true;
    let (addr, stop, h) = drive::spawn_local(o).unwrap();
    let ep = Endpoint::Tcp(addr.to_string());
    let mut a = Client::connect(&ep).unwrap();
    let mut b = Client::connect(&ep).unwrap();
    // Reading locks nobody out; the first change takes control.
    assert!(matches!(b.request(Request::Status).unwrap(), Reply::Status(_)));
    assert!(matches!(a.request(Request::Command(DriveCommand::Enable)).unwrap(), Reply::Command(_)));
    let r = b.request(Request::Command(DriveCommand::Disable)).unwrap();
    assert_eq!(r, Reply::Error(Error::ControlledByAnotherClient));
    assert!(host_sim::tool::client::describe(&Error::ControlledByAnotherClient).contains("busy: controlled by another client"));
    assert!(matches!(b.request(Request::Status).unwrap(), Reply::Status(s) if s.mode != servo_core::Mode::Disabled));
    // The controller leaves: the other may take control.
    drop(a);
    std::thread::sleep(std::time::Duration::from_millis(50));
    assert!(matches!(b.request(Request::Command(DriveCommand::Disable)).unwrap(), Reply::Command(_)));

    // Export, change a gain, import: the gain is back, enums by name.
    let dir = std::env::temp_dir().join(format!("drive_clients_{}", std::process::id()));
    let file = dir.join("params.toml");
    config_file::export(&mut b, &file).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains("method = \"HardStop\""), "{text}");
    let kp = host_sim::tool::param_get(&mut b, "speed_pi.kp").unwrap();
    host_sim::tool::param_set(&mut b, "speed_pi.kp", "0.3").unwrap();
    let changed = config_file::import(&mut b, &file).unwrap();
    assert_eq!(changed, vec!["control.speed_pi.kp".to_string()]);
    assert_eq!(host_sim::tool::param_get(&mut b, "speed_pi.kp").unwrap(), kp);
    // A bad file is refused naming the path, nothing sent.
    std::fs::write(&file, "[control.trajectory]\nmax_velocity_m_s = 1000.0\n").unwrap();
    let e = config_file::import(&mut b, &file).unwrap_err().to_string();
    assert!(e.contains("control.trajectory.max_velocity_m_s") && e.contains("nothing was sent"), "{e}");

    // A 100 Hz CSV against a drive that expects 1 kHz, and a 20 mm jump.
    let p = host_sim::tool::fetch_params(&mut b, &servo_core::ControlParams::default()).unwrap();
    let period = b.info.as_ref().unwrap().stream_period_s;
    let limits = stream::StreamLimits::of(&p, period);
    let row = |t: f64, x: f64, v: f64| stream::Row { t_s: t, position_m: x, velocity_m_s: v, force_n: None };
    let slow: Vec<_> = (0..10).map(|k| row(k as f64 * 0.01, 0.25 + 0.001 * k as f64, 0.1)).collect();
    let e = stream::check_rows("slow.csv", &slow, &limits).unwrap_err().to_string();
    assert!(e.contains("slow.csv:2:t_s") && e.contains("10.000 ms") && e.contains("1.000 ms"), "{e}");
    let mut jump: Vec<_> = (0..10).map(|k| row(k as f64 * 0.001, 0.25, 0.0)).collect();
    jump[5].position_m += 0.02;
    let e = stream::check_rows("jump.csv", &jump, &limits).unwrap_err().to_string();
    assert!(e.contains("jump.csv:6:velocity_m_s") && e.contains("20.000 mm"), "{e}");
    stop.store(true, Ordering::Relaxed);
    h.join().unwrap().unwrap();
}

#[test]
fn watch_draws_the_mode_beside_the_controlling_client_and_takes_no_control() {
    let mut o = DriveOptions::new(RigConfig::nominal().unwrap());
    o.pace = Pace::Fast;
    o.commissioned = true;
    let (addr, stop, h) = drive::spawn_local(o).unwrap();
    let ep = Endpoint::Tcp(addr.to_string());
    let mut control = Client::connect(&ep).unwrap();
    control.ask(Request::Command(DriveCommand::Enable)).unwrap();
    host_sim::tool::test::wait_running(&mut control).unwrap();
    let mut watcher = Client::connect(&ep).unwrap();
    let screen = |t: &ratatui::Terminal<ratatui::backend::TestBackend>| -> String {
        t.backend().buffer().content().iter().map(|c| c.symbol()).collect()
    };
    let mut term = ratatui::Terminal::new(ratatui::backend::TestBackend::new(100, 30)).unwrap();
    let run = host_sim::tool::view::watch_on(&mut term, &mut watcher, 20.0, 0.3, false).unwrap();
    // One status request per frame, each drawn: the frame count and the
    // intervals agree, whatever the host's timing.
    assert!(run.frames >= 2 && run.intervals_s.len() == run.frames - 1, "{run:?}");
    let s = screen(&term);
    assert!(s.contains("Running") && s.contains("position"), "{s}");
    // A fault shows by name in the next frame; the watcher never took
    // control: the controlling client still commands.
    control.ask(Request::Command(DriveCommand::Disable)).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(100));
    host_sim::tool::view::watch_on(&mut term, &mut watcher, 20.0, 0.1, false).unwrap();
    assert!(!screen(&term).contains("Running"), "{}", screen(&term));
    assert!(matches!(control.request(Request::Command(DriveCommand::Enable)).unwrap(), Reply::Command(_)));
    drop((control, watcher));
    stop.store(true, Ordering::Relaxed);
    h.join().unwrap().unwrap();
}

#[test]
fn a_refused_request_is_named_as_the_user_typed_it() {
    use host_sim::tool::client::request_text;
    use servo_core::protocol::Value;
    let kp = servo_core::protocol::params::index_of("control.speed_pi.kp").unwrap() as u16;
    assert_eq!(request_text(&Request::ParamSet { index: kp, value: Value::F32(1e30) }), "param set control.speed_pi.kp 1e30");
    assert_eq!(request_text(&Request::ParamSet { index: kp, value: Value::F32(0.4) }), "param set control.speed_pi.kp 0.4");
    assert_eq!(request_text(&Request::Load), "param load");
    assert_eq!(request_text(&Request::Command(DriveCommand::Enable)), "cmd enable");
    assert_eq!(request_text(&Request::Command(DriveCommand::MoveTo { position_m: -0.1 })), "move -0.1");
    assert_eq!(request_text(&Request::Command(DriveCommand::ClearFaults)), "cmd clear-faults");
}
