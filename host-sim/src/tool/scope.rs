//! The drive's scope from the host: signals by name, arming a capture,
//! waiting for its trigger and uploading it in chunks (`capture`,
//! `capture_with`), and the uploaded record (`CaptureData`).

use anyhow::{anyhow, bail, Context, Result};
use servo_core::protocol::{CaptureConfig, CaptureRequest, CaptureState, CaptureTrigger, Reply, Request, Signal};
use std::time::{Duration, Instant};

use super::client::Client;

pub const SIGNAL_NAMES: &[(&str, Signal)] = &[
    ("current_d", Signal::CurrentD),
    ("current_q", Signal::CurrentQ),
    ("current_q_reference", Signal::CurrentQReference),
    ("current_d_reference", Signal::CurrentDReference),
    ("voltage_d", Signal::VoltageD),
    ("voltage_q", Signal::VoltageQ),
    ("speed", Signal::Speed),
    ("speed_reference", Signal::SpeedReference),
    ("motor_position", Signal::MotorPosition),
    ("position_command", Signal::PositionCommand),
    ("position_reference", Signal::PositionReference),
    ("bus_voltage", Signal::BusVoltage),
    ("phase_current_a", Signal::PhaseCurrentA),
    ("phase_current_b", Signal::PhaseCurrentB),
    ("phase_current_c", Signal::PhaseCurrentC),
    ("electrical_angle", Signal::ElectricalAngle),
];

pub fn signal_by_name(n: &str) -> Result<Signal> {
    SIGNAL_NAMES.iter().find(|(s, _)| *s == n).map(|(_, s)| *s).ok_or_else(|| {
        anyhow!("unknown signal `{n}`; one of {}", SIGNAL_NAMES.iter().map(|(s, _)| *s).collect::<Vec<_>>().join(", "))
    })
}

pub fn signal_name(s: Signal) -> &'static str {
    SIGNAL_NAMES.iter().find(|(_, x)| *x == s).map_or("?", |(n, _)| n)
}

/// An uploaded capture.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaptureData {
    pub names: Vec<String>,
    pub dt_s: f64,
    pub trigger_index: usize,
    /// `values[signal][sample]`
    pub values: Vec<Vec<f64>>,
}

impl CaptureData {
    pub fn len(&self) -> usize {
        self.values.first().map_or(0, Vec::len)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Time of sample `k`, zero at the trigger.
    pub fn t(&self, k: usize) -> f64 {
        (k as f64 - self.trigger_index as f64) * self.dt_s
    }
    pub fn write_csv(&self, path: &std::path::Path) -> Result<()> {
        if let Some(d) = path.parent() {
            std::fs::create_dir_all(d).ok();
        }
        let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
        let mut h = vec!["t_s".to_string()];
        h.extend(self.names.iter().cloned());
        w.write_record(&h)?;
        for k in 0..self.len() {
            let mut r = vec![format!("{}", self.t(k))];
            r.extend(self.values.iter().map(|v| format!("{}", v[k])));
            w.write_record(&r)?;
        }
        w.flush()?;
        Ok(())
    }
}

fn drive_time(c: &mut Client) -> Result<f64> {
    match c.ask(Request::Status)? {
        Reply::Status(s) => Ok(f64::from(s.time_s)),
        r => bail!("unexpected {r:?}"),
    }
}

/// Arms a capture (`Configure`), lets `start` trigger it (a `Test` request,
/// `CaptureRequest::Trigger`, …), waits for `Done` and uploads it.
pub fn capture_with(
    c: &mut Client,
    cfg: CaptureConfig,
    start: impl FnOnce(&mut Client) -> Result<()>,
    wait: Duration,
) -> Result<CaptureData> {
    let names: Vec<String> = cfg.signals.iter().map(|s| signal_name(*s).to_string()).collect();
    let trigger = cfg.trigger;
    let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
    let pre_s = f64::from(cfg.pre_trigger) * f64::from(cfg.decimation) / pwm;
    c.ask(Request::Capture(CaptureRequest::Configure(cfg)))?;
    if trigger == CaptureTrigger::Command {
        // Let the pre-trigger history fill (drive time), then trigger.
        let t0 = drive_time(c)?;
        let started = Instant::now();
        while drive_time(c)? < t0 + pre_s + 0.002 && started.elapsed() < wait {
            c.poll(Duration::from_millis(1))?;
            c.telemetry.clear();
        }
        c.ask(Request::Capture(CaptureRequest::Trigger))?;
    }
    start(c)?;
    let t0 = Instant::now();
    let status = loop {
        match c.ask(Request::Capture(CaptureRequest::Status))? {
            Reply::CaptureStatus(s) if s.state == CaptureState::Done => break s,
            Reply::CaptureStatus(_) => {}
            r => bail!("unexpected {r:?}"),
        }
        if t0.elapsed() > wait {
            bail!("the capture did not complete within {:.1} s", wait.as_secs_f64());
        }
        c.poll(Duration::from_millis(10))?;
        c.telemetry.clear();
    };
    let mut values = vec![Vec::with_capacity(usize::from(status.samples)); names.len()];
    for (signal, v) in values.iter_mut().enumerate() {
        let mut start = 0u16;
        while start < status.samples {
            let count = (status.samples - start).min(servo_core::protocol::CAPTURE_CHUNK_MAX as u16) as u8;
            match c.ask(Request::Capture(CaptureRequest::Read { signal: signal as u8, start, count }))? {
                Reply::CaptureData { values: chunk, .. } => {
                    if chunk.is_empty() {
                        bail!("empty capture chunk at {start}");
                    }
                    v.extend(chunk.iter().map(|x| f64::from(*x)));
                    start += chunk.len() as u16;
                }
                r => bail!("unexpected {r:?}"),
            }
        }
    }
    Ok(CaptureData { names, dt_s: f64::from(status.sample_period_s), trigger_index: usize::from(status.trigger_index), values })
}

pub fn capture(
    c: &mut Client,
    signals: &[Signal],
    samples: u16,
    decimation: u16,
    pre_trigger: u16,
    trigger: CaptureTrigger,
    wait: Duration,
) -> Result<CaptureData> {
    let cfg = CaptureConfig {
        signals: servo_core::capture::SignalList::from_slice(signals).map_err(|_| anyhow!("at most {} signals", servo_core::protocol::CAPTURE_SIGNALS_MAX))?,
        decimation,
        samples,
        pre_trigger,
        trigger,
    };
    capture_with(c, cfg, |_| Ok(()), wait)
}
