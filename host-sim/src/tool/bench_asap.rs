//! `drive bench-asap`: how long `drive stream FILE --asap` takes to send a
//! 20 s, 1 kHz trajectory to a fast-paced simulated drive. The tool runs
//! as a user runs it, a separate `host-sim drive --tcp … stream` process,
//! against a drive served over TCP (fast pacing, commissioned, enabled),
//! so the figure includes the protocol, the socket and the drive's own
//! computing, as a user's session does. The stream's `wall_s` (first point
//! to the end of the stream, from the tool's own summary.json) is the
//! figure held against the bar; the whole process's time is reported
//! beside it (connect, the parameter fetch and the CSV checks included).

use super::client::{Client, Endpoint};
use super::test::wait_running;
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use anyhow::{bail, Context, Result};
use servo_core::protocol::{DriveCommand, Request};
use std::path::Path;
use std::time::{Duration, Instant};

/// The bar on the stream's wall time for a 20 s, 1 kHz file, s.
pub const WALL_BAR_S: f64 = 1.0;
/// Where the trajectory starts (and where the drive holds the rod), m.
const START_M: f64 = 0.25;
/// Amplitude of the cosine, m: the rod goes out 2 × this and back.
const AMPLITUDE_M: f64 = 0.05;
/// Period of the cosine, s (a quarter of the default 20 s file's length).
const PERIOD_S: f64 = 4.0;

/// The trajectory file: `x = START + A(1 − cos ωt)`, `v = Aω sin ωt`,
/// starting and ending at rest.
pub fn write_trajectory(path: &Path, seconds: f64, rate_hz: f64) -> Result<usize> {
    let w = std::f64::consts::TAU / PERIOD_S;
    let n = (seconds * rate_hz).round() as usize;
    let mut text = String::from("t_s,position_m,velocity_m_s\n");
    for k in 0..=n {
        let t = k as f64 / rate_hz;
        let x = START_M + AMPLITUDE_M * (1.0 - (w * t).cos());
        let v = AMPLITUDE_M * w * (w * t).sin();
        text.push_str(&format!("{t:.6},{x:.7},{v:.7}\n"));
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(n + 1)
}

pub fn run(rig: &RigConfig, out: &Path, seconds: f64, rate_hz: f64) -> Result<serde_json::Value> {
    if !(seconds > 0.0 && seconds <= 600.0) {
        bail!("--seconds {seconds}: give 0 < seconds ≤ 600");
    }
    let (slowest_hz, fastest_hz) = (1.0 / f64::from(rig.control.stream.period_max_s), 1.0 / f64::from(rig.control.position_period_s()));
    let tol = super::stream::PERIOD_TOLERANCE;
    if !(rate_hz >= slowest_hz * (1.0 - tol) && rate_hz <= fastest_hz * (1.0 + tol)) {
        bail!(
            "--rate-hz {rate_hz}: the drive takes {:.0} … {:.0} Hz (control.stream.period_max_s … the position-loop rate)",
            slowest_hz, fastest_hz
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let csv = out.join("trajectory.csv");
    let points = write_trajectory(&csv, seconds, rate_hz)?;
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Fast;
    o.commissioned = true;
    o.initial_position_m = START_M;
    o.stream_period_s = 1.0 / rate_hz;
    let (addr, stop, h) = drive::spawn_local(o)?;
    let result = (|| -> Result<(f64, std::process::Output)> {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.timeout = Duration::from_secs(10);
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        // The tool takes control: this client lets go first.
        drop(c);
        let t0 = Instant::now();
        let output = std::process::Command::new(std::env::current_exe()?)
            .args(["drive", "--tcp", &addr.to_string(), "stream"])
            .arg(&csv)
            .arg("--asap")
            .arg("--out")
            .arg(out.join("stream"))
            .output()
            .context("running `host-sim drive stream`")?;
        Ok((t0.elapsed().as_secs_f64(), output))
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().map_err(|_| anyhow::anyhow!("drive thread panicked"))??;
    let (process_wall_s, output) = result?;
    let said = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    if !output.status.success() {
        bail!("`drive stream {} --asap` failed ({}):\n{said}", csv.display(), output.status);
    }
    let stream_summary = out.join("stream").join("summary.json");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stream_summary).with_context(|| format!("reading {}", stream_summary.display()))?)?;
    let wall_s = s["wall_s"].as_f64().context("the stream's summary.json has no wall_s")?;
    let sent = s["sent"].as_u64().context("the stream's summary.json has no sent")? as usize;
    let pass = wall_s <= WALL_BAR_S && sent == points;
    let summary = serde_json::json!({
        "command": "drive --tcp ADDR stream trajectory.csv --asap, against a fast-paced simulated drive",
        "trajectory_s": seconds,
        "rate_hz": rate_hz,
        "points": points,
        "sent": sent,
        "wall_s": wall_s,
        "points_per_s": sent as f64 / wall_s,
        "process_wall_s": process_wall_s,
        "bar_wall_s": WALL_BAR_S,
        "pass": pass,
        "tracking_rms_um": s["tracking_rms_um"],
        "tracking_max_um": s["tracking_max_um"],
        "refusals": s["refusals"],
        "faults": s["faults"],
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    if !pass {
        bail!(
            "{sent} of {points} points sent in {wall_s:.3} s against a bar of {WALL_BAR_S} s: {}",
            out.join("summary.json").display()
        );
    }
    Ok(summary)
}
