//! `drive bench-stream-loss`: a stream cut mid-motion, against a simulated
//! drive over TCP (fast pacing, lock-step), raising and lowering the rated
//! payload, with setpoints at 1 kHz and at the slowest rate the drive
//! interpolates (`stream.period_max_s`), at 0.1 m/s and at the top stream
//! speed (`trajectory.max_velocity_m_s`), two ways: the client stops
//! sending but stays connected, and the client process is killed (its
//! socket closes). Read from the drive's own position-period trace: the
//! motor never turns back, the following error during the stop, where the
//! rod comes to rest against `v²/(2·a_stop) + 1 mm` past the last point,
//! and when `stream_timeout` is latched.

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
/// Start of a raising ramp, m (a lowering one starts this far from the
/// other end of the stroke).
const START_M: f64 = 0.1;
/// The fastest setpoint rate covered, Hz (the slowest is the drive's own
/// `stream.period_max_s`).
const FAST_RATE_HZ: f64 = 1000.0;
/// Following-error bound during the stop, m.
pub const FOLLOWING_BOUND_M: f64 = 50e-6;
/// Rest within `v²/(2·a_stop)` plus this, m.
pub const REST_MARGIN_M: f64 = 1e-3;

/// A ramp from `start_m` sampled every `dt`: accelerate to `v` (signed),
/// then cruise for `cruise_s`.
pub fn ramp_rows(start_m: f64, v: f64, cruise_s: f64, dt: f64) -> Vec<Row> {
    let t_acc = v.abs() / RAMP_ACCELERATION_M_S2;
    let a = RAMP_ACCELERATION_M_S2 * v.signum();
    let n = ((t_acc + cruise_s) / dt).round() as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 * dt;
            let (x, vel) = if t < t_acc { (start_m + 0.5 * a * t * t, a * t) } else { (start_m + 0.5 * v * t_acc + v * (t - t_acc), v) };
            Row { t_s: t, position_m: x, velocity_m_s: vel, force_n: None }
        })
        .collect()
}

/// One cut: which way, how fast, at which setpoint rate.
#[derive(Clone, Copy, Debug)]
struct Run {
    /// Signed: positive raises the payload.
    velocity_m_s: f64,
    period_s: f64,
    start_m: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Case {
    pub cut: &'static str,
    /// `raising` or `lowering` the payload.
    pub direction: &'static str,
    pub setpoint_rate_hz: f64,
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

fn analyse(cut: &'static str, run: &Run, a_stop: f64, trace: &[TraceRow]) -> Result<Case> {
    let v = run.velocity_m_s;
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
        direction: if v > 0.0 { "raising" } else { "lowering" },
        setpoint_rate_hz: (1.0 / run.period_s).round(),
        speed_m_s: v.abs(),
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

fn start_drive(rig: &RigConfig, run: &Run, trace: drive::Trace) -> Result<(std::net::SocketAddr, drive::StopFlag, std::thread::JoinHandle<Result<()>>)> {
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Fast;
    o.commissioned = true;
    o.initial_position_m = run.start_m;
    o.stream_period_s = run.period_s;
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
fn cut_by_silence(rig: &RigConfig, run: &Run) -> Result<Vec<TraceRow>> {
    let trace: drive::Trace = Arc::new(Mutex::new(Vec::new()));
    let (addr, stop, h) = start_drive(rig, run, trace.clone())?;
    let result = (|| -> Result<()> {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.timeout = Duration::from_secs(10);
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        let rows = ramp_rows(run.start_m, run.velocity_m_s, 0.2, run.period_s);
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
    result?;
    let t = trace.lock().map_err(|_| anyhow::anyhow!("trace lock"))?.clone();
    Ok(t)
}

/// A `host-sim drive stream` process sends the ramp at its times and is
/// killed mid-cruise.
fn cut_by_kill(rig: &RigConfig, run: &Run, dir: &Path) -> Result<Vec<TraceRow>> {
    let trace: drive::Trace = Arc::new(Mutex::new(Vec::new()));
    let (addr, stop, h) = start_drive(rig, run, trace.clone())?;
    let v = run.velocity_m_s;
    let result = (|| -> Result<()> {
        enable(&addr)?;
        let rows = ramp_rows(run.start_m, v, 1.2, run.period_s);
        let csv = dir.join(format!("ramp_{}.csv", label(run)));
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
        std::thread::sleep(Duration::from_secs_f64(v.abs() / RAMP_ACCELERATION_M_S2 + 0.5));
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
    result?;
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

/// `raising_1000hz_0.200`: names a run's files.
fn label(run: &Run) -> String {
    let way = if run.velocity_m_s > 0.0 { "raising" } else { "lowering" };
    format!("{way}_{:.0}hz_{:.3}", 1.0 / run.period_s, run.velocity_m_s.abs())
}

pub fn run(rig: &RigConfig, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let a_stop = f64::from(rig.control.faults.stop_deceleration_m_s2);
    let v_top = f64::from(rig.control.trajectory.max_velocity_m_s);
    let slowest_period_s = f64::from(rig.control.stream.period_max_s);
    let l = &rig.control.limits;
    let (lo, hi) = (f64::from(l.stroke_min_m), f64::from(l.stroke_max_m));
    let mut cases = Vec::new();
    for period_s in [1.0 / FAST_RATE_HZ, slowest_period_s] {
        // The ramp's rows must pass the tool's own checks.
        let limits = stream::StreamLimits::of(&rig.control, period_s as f32);
        for v in [0.1, v_top, -0.1, -v_top] {
            let start_m = if v > 0.0 { lo + START_M } else { hi - START_M };
            let run = Run { velocity_m_s: v, period_s, start_m };
            stream::check_rows("ramp", &ramp_rows(start_m, v, 1.2, period_s), &limits)?;
            let silence = cut_by_silence(rig, &run)?;
            write_trace(&silence, &out.join(format!("trace_silence_{}.csv", label(&run))))?;
            cases.push(analyse("client stops sending", &run, a_stop, &silence)?);
            let killed = cut_by_kill(rig, &run, out)?;
            write_trace(&killed, &out.join(format!("trace_killed_{}.csv", label(&run))))?;
            cases.push(analyse("client killed", &run, a_stop, &killed)?);
        }
    }
    let all = |f: fn(&Case) -> bool| cases.iter().all(f);
    let summary = serde_json::json!({
        "stop_deceleration_m_s2": a_stop,
        "top_stream_speed_m_s": v_top,
        "setpoint_rates_hz": [FAST_RATE_HZ, (1.0 / slowest_period_s).round()],
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
        "every_bar_met": all(|c| c.no_reversal && c.following_ok && c.rest_ok && c.latched_after_s.is_some()),
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    let missed: Vec<String> = cases
        .iter()
        .filter(|c| !(c.no_reversal && c.following_ok && c.rest_ok && c.latched_after_s.is_some()))
        .map(|c| format!("{} {} m/s at {} Hz, {}", c.direction, c.speed_m_s, c.setpoint_rate_hz, c.cut))
        .collect();
    if !missed.is_empty() {
        bail!("a bar was missed ({}): {}", missed.join("; "), out.join("summary.json").display());
    }
    Ok(summary)
}
