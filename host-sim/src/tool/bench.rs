//! `drive bench-stream`: the paper run's motor-side reference, streamed at
//! 1 kHz through a simulated drive over TCP (fast pacing: exactly 1 ms of
//! simulated time per frame), and the tracking it achieves; plus the
//! capture figure (signals × samples at the PWM rate); and a speed-loop
//! gain changed mid-move through the protocol (`bench_gain`).

use super::client::{Client, Endpoint};
use super::stream::{self, Row};
use super::test::wait_running;
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use crate::scenario::{run_stroke_cycle, StrokeCycle};
use anyhow::{bail, Result};
use servo_core::protocol::{CaptureTrigger, DriveCommand, Request, Signal, TelemetryField};
use std::path::Path;
use std::time::{Duration, Instant};

/// The paper cycle's position reference at the position-loop rate, with
/// its velocity (central differences), as stream rows.
pub fn paper_reference(rig: &RigConfig) -> Result<Vec<Row>> {
    let trace = run_stroke_cycle(rig, &StrokeCycle::paper(1))?;
    if let Some(why) = trace.aborted {
        bail!("the paper run behind the reference stopped: {why}");
    }
    let x: Vec<f64> = trace.telemetry.iter().map(|t| f64::from(t.position_reference_m)).collect();
    let dt = f64::from(rig.control.rates.position_loop_divider) / f64::from(rig.control.rates.pwm_frequency_hz);
    let v_max = f64::from(rig.control.trajectory.max_velocity_m_s);
    Ok((0..x.len())
        .map(|k| {
            let v = if k == 0 || k + 1 == x.len() { 0.0 } else { (x[k + 1] - x[k - 1]) / (2.0 * dt) };
            // The S-curve cruises at exactly the limit; differences of its
            // f32 samples overshoot it by rounding (≈1e-5 m/s), which the
            // drive would refuse.
            let v = v.clamp(-v_max, v_max);
            Row { t_s: k as f64 * dt, position_m: x[k], velocity_m_s: v, force_n: None }
        })
        .collect())
}

pub fn run(rig: &RigConfig, out: &Path) -> Result<serde_json::Value> {
    let mut s = stream_and_capture(rig, out)?;
    s["gain_change_mid_move"] = super::bench_gain::run(rig)?;
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&s)?)?;
    Ok(s)
}

/// The stream's tracking and the capture figure (no summary written).
pub fn stream_and_capture(rig: &RigConfig, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let rows = paper_reference(rig)?;
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Fast;
    o.commissioned = true;
    o.initial_position_m = rows[0].position_m;
    // A stream stalls only if this host does; be generous.
    o.stream_idle_s = 2.0;
    let (addr, stop, h) = drive::spawn_local(o)?;
    let result = (|| -> Result<serde_json::Value> {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.timeout = Duration::from_secs(10);
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        let fields = (1 << TelemetryField::PositionReference as u32) | (1 << TelemetryField::MotorPosition as u32) | (1 << TelemetryField::Faults as u32);
        c.ask(Request::Telemetry { fields, rate_hz: 1000 })?;
        c.poll(Duration::from_millis(20))?;
        c.telemetry.clear();
        let t0 = Instant::now();
        let report = stream::send(&mut c, &rows, false)?;
        let wall = t0.elapsed().as_secs_f64();
        c.ask(Request::Telemetry { fields: 0, rate_hz: 0 })?;
        let tel: Vec<_> = c.telemetry.drain(..).collect();
        // While streaming: one record per frame (fast pacing), the first
        // `rows.len()` after the stream started.
        let n = tel.len().min(rows.len());
        let errs: Vec<f64> = tel[..n].iter().map(|t| f64::from(t.values[0]) - f64::from(t.values[1])).collect();
        // The Faults field carries the bits in the f32's bit pattern.
        let faults = tel.iter().map(|t| t.values[2].to_bits()).fold(0, |a, b| a | b);
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len().max(1) as f64).sqrt();
        let max = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        // The capture figure: 4 signals × the buffer at the PWM rate.
        // As many samples as the board's store holds for 4 signals.
        let samples = (servo_core::capture::CAPTURE_STORE_CELLS / 4) as u16;
        let tc = Instant::now();
        let cap = super::capture(
            &mut c,
            &[Signal::CurrentQ, Signal::CurrentQReference, Signal::Speed, Signal::MotorPosition],
            samples,
            1,
            0,
            CaptureTrigger::Command,
            Duration::from_secs(30),
        )?;
        let upload_s = tc.elapsed().as_secs_f64();
        cap.write_csv(&out.join("capture.csv"))?;
        Ok(serde_json::json!({
            "stream_points": rows.len(),
            "stream_rate_hz": 1.0 / (rows[1].t_s - rows[0].t_s),
            "stream_duration_s": report.duration_s,
            "wall_s": wall,
            "refusals": report.refusals.len(),
            "refusal_runs": report.grouped().into_iter().take(10).collect::<Vec<_>>(),
            "telemetry_records": n,
            "faults": servo_core::FaultSet::from_bits_retain(faults).names().collect::<Vec<_>>(),
            "motor_tracking_rms_um": rms * 1e6,
            "motor_tracking_max_um": max * 1e6,
            "bar": { "rms_um": 5.0, "max_um": 50.0 },
            "meets_bar": rms <= 5e-6 && max <= 50e-6,
            "capture": {
                "signals": cap.names.len(),
                "samples": cap.len(),
                "rate_hz": 1.0 / cap.dt_s,
                "wall_s": upload_s,
                "store_cells": servo_core::capture::CAPTURE_STORE_CELLS,
            },
        }))
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = h.join();
    result
}
