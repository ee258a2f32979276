//! `drive bench-stream-loss`: a stream cut mid-motion, against a simulated
//! drive over TCP (fast pacing, lock-step), at 0.1 m/s and at the top
//! stream speed (`trajectory.max_velocity_m_s`), two ways: the client
//! stops sending but stays connected, and the client process is killed
//! (its socket closes). Read from the drive's own position-period trace:
//! the motor never turns back, the following error during the stop, where
//! the rod comes to rest against `v²/(2·a_stop) + 1 mm` past the last
//! point, and when `stream_timeout` is latched.

use super::client::{Client, Endpoint};
use super::stream::{self, Row};
use super::test::wait_running;
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace, TraceRow};
use anyhow::{bail, Context, Result};
use servo_core::protocol::{DriveCommand, Request};
use servo_core::FaultSet;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Acceleration of the ramp up to the stream speed, m/s².
const RAMP_ACCELERATION_M_S2: f64 = 2.0;
/// Start of the ramp, m.
const START_M: f64 = 0.1;
/// Following-error bound during the stop, m.
pub const FOLLOWING_BOUND_M: f64 = 50e-6;
/// Rest within `v²/(2·a_stop)` plus this, m.
pub const REST_MARGIN_M: f64 = 1e-3;

/// A 1 kHz ramp: accelerate to `v`, then cruise for `cruise_s`.
pub fn ramp_rows(v: f64, cruise_s: f64, dt: f64) -> Vec<Row> {
    let t_acc = v / RAMP_ACCELERATION_M_S2;
    let n = ((t_acc + cruise_s) / dt).round() as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 * dt;
            let (x, vel) = if t < t_acc {
                (START_M + 0.5 * RAMP_ACCELERATION_M_S2 * t * t, RAMP_ACCELERATION_M_S2 * t)
            } else {
                (START_M + 0.5 * v * t_acc + v * (t - t_acc), v)
            };
            Row { t_s: t, position_m: x, velocity_m_s: vel, force_n: None }
        })
        .collect()
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Case {
    pub cut: &'static str,
    pub speed_m_s: f64,
    pub last_point_m: f64,
    /// Drive time from the last point to `stream_timeout`, s.
    pub latched_after_s: Option<f64>,
    /// Largest motor speed against the stream's direction from the last
    /// point to the latch, m/s at the rod.
    pub reverse_speed_max_m_s: f64,
    pub following_max_um: f64,
    /// Where the rod rests 0.2 s after the latch, past the last point, mm.
    pub rest_past_last_point_mm: f64,
    /// `v²/(2·a_stop) + 1 mm`.
    pub rest_bound_mm: f64,
    pub no_reversal: bool,
    pub following_ok: bool,
    pub rest_ok: bool,
}

fn analyse(cut: &'static str, v: f64, a_stop: f64, trace: &[TraceRow]) -> Result<Case> {
    let last = trace.iter().rposition(|r| r.stream_point_m.is_some()).context("no stream point reached the drive")?;
    let last_point_m = f64::from(trace[last].stream_point_m.unwrap_or(0.0));
    let latch = trace[last..].iter().position(|r| FaultSet::from_bits_retain(r.faults).contains(FaultSet::STREAM_TIMEOUT)).map(|i| last + i);
    let end = latch.unwrap_or(trace.len() - 1);
    let window = &trace[last..=end];
    let reverse = window.iter().map(|r| -f64::from(r.speed_m_s) * v.signum()).fold(0.0f64, f64::max);
    let following = window.iter().map(|r| f64::from(r.position_reference_m - r.motor_position_m).abs()).fold(0.0f64, f64::max);
    let dt = trace.get(1).map_or(1e-3, |r| r.time_s - trace[0].time_s);
    let rest_at = (end + (0.2 / dt) as usize).min(trace.len() - 1);
    let rest = (f64::from(trace[rest_at].motor_position_m) - last_point_m) * v.signum();
    let bound = v * v / (2.0 * a_stop) + REST_MARGIN_M;
    Ok(Case {
        cut,
        speed_m_s: v,
        last_point_m,
        latched_after_s: latch.map(|l| trace[l].time_s - trace[last].time_s),
        reverse_speed_max_m_s: reverse,
        following_max_um: following * 1e6,
        rest_past_last_point_mm: rest * 1e3,
        rest_bound_mm: bound * 1e3,
        // 1 mm/s: the speed estimate's noise at rest.
        no_reversal: reverse < 1e-3,
        following_ok: following <= FOLLOWING_BOUND_M,
        rest_ok: rest >= 0.0 && rest <= bound,
    })
}

fn start_drive(rig: &RigConfig, trace: drive::Trace) -> Result<(std::net::SocketAddr, drive::StopFlag, std::thread::JoinHandle<Result<()>>)> {
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Fast;
    o.commissioned = true;
    o.initial_position_m = START_M;
    o.trace = Some(trace);
    drive::spawn_local(o)
}

fn enable(addr: &std::net::SocketAddr) -> Result<()> {
    let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
    c.timeout = Duration::from_secs(10);
    c.ask(Request::Command(DriveCommand::Enable))?;
    wait_running(&mut c)
}

/// The client sends the ramp up to the cut and then nothing, connected.
fn cut_by_silence(rig: &RigConfig, v: f64) -> Result<Vec<TraceRow>> {
    let trace: drive::Trace = Arc::new(Mutex::new(Vec::new()));
    let (addr, stop, h) = start_drive(rig, trace.clone())?;
    let run = (|| -> Result<()> {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.timeout = Duration::from_secs(10);
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        let rows = ramp_rows(v, 0.2, 1e-3);
        for r in &rows {
            let p = servo_core::protocol::StreamPoint { position_m: r.position_m as f32, velocity_m_s: r.velocity_m_s as f32, force_n: None };
            c.send(Request::Stream(p))?;
        }
        // Silence, still connected: the drive leaves lock-step after its
        // idle time and runs on.
        std::thread::sleep(Duration::from_millis(1500));
        c.request(Request::Status)?;
        Ok(())
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().map_err(|_| anyhow::anyhow!("drive thread panicked"))??;
    run?;
    let t = trace.lock().map_err(|_| anyhow::anyhow!("trace lock"))?.clone();
    Ok(t)
}

/// A `host-sim drive stream` process sends the ramp at its times and is
/// killed mid-cruise.
fn cut_by_kill(rig: &RigConfig, v: f64, dir: &Path) -> Result<Vec<TraceRow>> {
    let trace: drive::Trace = Arc::new(Mutex::new(Vec::new()));
    let (addr, stop, h) = start_drive(rig, trace.clone())?;
    let run = (|| -> Result<()> {
        enable(&addr)?;
        let rows = ramp_rows(v, 1.2, 1e-3);
        let csv = dir.join(format!("ramp_{v}.csv"));
        let mut w = csv::Writer::from_path(&csv)?;
        w.write_record(["t_s", "position_m", "velocity_m_s"])?;
        for r in &rows {
            w.write_record([r.t_s.to_string(), r.position_m.to_string(), r.velocity_m_s.to_string()])?;
        }
        w.flush()?;
        let exe = std::env::current_exe()?;
        let mut child = std::process::Command::new(exe)
            .args(["drive", "--tcp", &addr.to_string(), "stream"])
            .arg(&csv)
            .arg("--out")
            .arg(dir.join("killed-client"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .context("starting the streaming client")?;
        // Mid-cruise: past the ramp-up, well before the end.
        let t0 = Instant::now();
        std::thread::sleep(Duration::from_secs_f64(v / RAMP_ACCELERATION_M_S2 + 0.5));
        child.kill().context("killing the streaming client")?;
        child.wait()?;
        let killed_at = t0.elapsed().as_secs_f64();
        std::thread::sleep(Duration::from_millis(800));
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.request(Request::Status)?;
        eprintln!("bench-stream-loss: client killed {killed_at:.2} s after it started");
        Ok(())
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().map_err(|_| anyhow::anyhow!("drive thread panicked"))??;
    run?;
    let t = trace.lock().map_err(|_| anyhow::anyhow!("trace lock"))?.clone();
    Ok(t)
}

/// The drive's trace from 50 ms before the last point to 0.3 s after it.
fn write_trace(trace: &[TraceRow], path: &Path) -> Result<()> {
    let last = trace.iter().rposition(|r| r.stream_point_m.is_some()).unwrap_or(0);
    let from = last.saturating_sub(50);
    let to = (last + 300).min(trace.len());
    let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
    w.write_record([
        "time_s",
        "since_last_point_s",
        "position_reference_m",
        "position_command_m",
        "motor_position_m",
        "speed_m_s",
        "speed_reference_rad_s",
        "current_q_a",
        "faults",
    ])?;
    let t0 = trace.get(last).map_or(0.0, |r| r.time_s);
    for r in trace.get(from..to).unwrap_or(&[]) {
        w.write_record([
            r.time_s.to_string(),
            (r.time_s - t0).to_string(),
            r.position_reference_m.to_string(),
            r.position_command_m.to_string(),
            r.motor_position_m.to_string(),
            r.speed_m_s.to_string(),
            r.speed_reference_rad_s.to_string(),
            r.current_q_a.to_string(),
            r.faults.to_string(),
        ])?;
    }
    w.flush()?;
    Ok(())
}

pub fn run(rig: &RigConfig, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let a_stop = f64::from(rig.control.faults.stop_deceleration_m_s2);
    let v_top = f64::from(rig.control.trajectory.max_velocity_m_s);
    // The ramp's rows must pass the tool's own checks.
    let limits = stream::StreamLimits::of(&rig.control, 1e-3);
    let mut cases = Vec::new();
    for v in [0.1, v_top] {
        stream::check_rows("ramp", &ramp_rows(v, 1.2, 1e-3), &limits)?;
        let silence = cut_by_silence(rig, v)?;
        write_trace(&silence, &out.join(format!("trace_silence_{v:.3}.csv")))?;
        cases.push(analyse("client stops sending", v, a_stop, &silence)?);
        let killed = cut_by_kill(rig, v, out)?;
        write_trace(&killed, &out.join(format!("trace_killed_{v:.3}.csv")))?;
        cases.push(analyse("client killed", v, a_stop, &killed)?);
    }
    let all = |f: fn(&Case) -> bool| cases.iter().all(f);
    let summary = serde_json::json!({
        "stop_deceleration_m_s2": a_stop,
        "top_stream_speed_m_s": v_top,
        "bounds": {
            "reverse_speed_m_s": 1e-3,
            "following_um": FOLLOWING_BOUND_M * 1e6,
            "rest": "v^2/(2 a_stop) + 1 mm past the last point",
        },
        "cases": cases,
        "no_reversal": all(|c| c.no_reversal),
        "following_ok": all(|c| c.following_ok),
        "rest_ok": all(|c| c.rest_ok),
        "latched_every_time": all(|c| c.latched_after_s.is_some()),
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    if cases.iter().any(|c| c.latched_after_s.is_none()) {
        bail!("stream_timeout was not latched in every case: {}", out.join("summary.json").display());
    }
    Ok(summary)
}
