//! `drive step` and `drive chirp`: a core test signal with a capture around
//! it, the figures, a plot, and the simulator's prediction for the same
//! gains (the drive's parameters fetched with `param get`) on the rig.

use super::analysis::{frf_figures, h1, step_figures, Frf, FrfFigures, StepFigures};
use super::client::{describe, request_text, Client};
use super::{capture_with, fetch_params, CaptureData};
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use crate::report::plots::{line_chart, Series};
use anyhow::{bail, Result};
use servo_core::protocol::{
    CaptureConfig, CaptureTrigger, ChirpTarget, DriveCommand, Error, Reply, Request, Signal, TestSignal,
};
use servo_core::Reason;
use std::path::Path;
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Target {
    Current,
    /// A current step on the d axis: no torque, so the rotor stands and
    /// no back-EMF enters the voltage (the winding's R and L alone).
    CurrentD,
    Speed,
    Position,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Spec {
    pub target: Target,
    pub chirp: Option<(f64, f64)>,
    pub amplitude: f64,
    pub duration_s: f64,
}

impl Spec {
    pub fn step(target: Target, amplitude: f64, duration_s: f64) -> Self {
        Self { target, chirp: None, amplitude, duration_s }
    }
    pub fn chirp(target: Target, amplitude: f64, from: f64, to: f64, duration_s: f64) -> Self {
        Self { target, chirp: Some((from, to)), amplitude, duration_s }
    }

    pub fn signal(&self) -> TestSignal {
        let (a, d) = (self.amplitude as f32, self.duration_s as f32);
        match (self.chirp, self.target) {
            (None, Target::Current) => TestSignal::CurrentStep { axis_q: true, amplitude_a: a, duration_s: d },
            (None, Target::CurrentD) => TestSignal::CurrentStep { axis_q: false, amplitude_a: a, duration_s: d },
            (None, Target::Speed) => TestSignal::SpeedStep { amplitude_rad_s: a, duration_s: d },
            (None, Target::Position) => TestSignal::PositionStep { distance_m: a, duration_s: d },
            (Some((f0, f1)), t) => TestSignal::Chirp {
                target: match t {
                    Target::Current | Target::CurrentD => ChirpTarget::Current,
                    Target::Speed => ChirpTarget::Speed,
                    Target::Position => ChirpTarget::Position,
                },
                amplitude: a,
                start_hz: f0 as f32,
                end_hz: f1 as f32,
                duration_s: d,
            },
        }
    }

    /// (reference, response) signals of the loop under test.
    pub fn signals(&self) -> [Signal; 4] {
        match self.target {
            Target::Current => [Signal::CurrentQReference, Signal::CurrentQ, Signal::VoltageQ, Signal::Speed],
            Target::CurrentD => [Signal::CurrentDReference, Signal::CurrentD, Signal::VoltageD, Signal::Speed],
            // The q voltage rather than the position (the speed is there):
            // it carries the back-EMF, so `tune identify` finds the magnets'
            // flux from a drive's own speed steps.
            Target::Speed => [Signal::SpeedReference, Signal::Speed, Signal::CurrentQ, Signal::VoltageQ],
            Target::Position => [Signal::PositionCommand, Signal::MotorPosition, Signal::Speed, Signal::CurrentQ],
        }
    }

    /// Sampling. A step: 4 signals, the loop's own rate (current: every
    /// PWM period, speed: every 4th, position: every 20th), decimated more if
    /// 1.1 × the duration would not fit the drive's capture store
    /// (`CAPTURE_STORE_CELLS` shared by the signals). A chirp: only reference
    /// and response (twice the samples), sampled at least 2.5 × its end
    /// frequency; refused with the longest duration that fits otherwise. A
    /// tenth of the record lies before the trigger.
    pub fn capture_config(&self, pwm_hz: f64) -> Result<CaptureConfig> {
        if self.chirp.is_some() && self.target == Target::CurrentD {
            bail!("a chirp runs on the q current (`chirp current`); `current-d` is a step target only");
        }
        let base: u16 = match self.target {
            Target::Current | Target::CurrentD => 1,
            Target::Speed => 4,
            Target::Position => 20,
        };
        let signals: &[Signal] = if self.chirp.is_some() { &self.signals()[..2] } else { &self.signals() };
        let max_samples = (servo_core::capture::CAPTURE_STORE_CELLS / signals.len()) as f64;
        let periods = 1.1 * self.duration_s * pwm_hz;
        let mut decimation = base.max((periods / max_samples).ceil().min(f64::from(u16::MAX)) as u16);
        if let Some((_, to_hz)) = self.chirp {
            let fastest = ((pwm_hz / (2.5 * to_hz)).floor() as u16).max(1);
            if decimation > fastest {
                let longest = max_samples * f64::from(fastest) / pwm_hz / 1.1;
                bail!(
                    "a chirp to {to_hz} Hz needs a sample every {fastest} PWM periods; the capture store holds {max_samples} samples of 2 signals, {longest:.3} s at that rate: use --duration <= {longest:.3} or a lower --to"
                );
            }
            decimation = decimation.max(1);
        }
        let samples = ((periods / f64::from(decimation)).ceil()).clamp(64.0, max_samples) as u16;
        Ok(CaptureConfig {
            signals: servo_core::capture::SignalList::from_slice(signals).expect("at most 4 signals"),
            decimation,
            samples,
            pre_trigger: samples / 11,
            trigger: CaptureTrigger::TestStart,
        })
    }
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Figures {
    pub step: Option<StepFigures>,
    pub frf: Option<FrfFigures>,
}

fn figures(spec: &Spec, cap: &CaptureData) -> (Figures, Option<Frf>) {
    let y = &cap.values[1];
    match spec.chirp {
        None => {
            let t0 = cap.trigger_index as f64 * cap.dt_s;
            (Figures { step: Some(step_figures(y, cap.dt_s, t0, spec.amplitude)), frf: None }, None)
        }
        Some((f0, f1)) => {
            let k0 = cap.trigger_index;
            let frf = h1(&cap.values[0][k0..], &y[k0..], cap.dt_s, 1024);
            (Figures { step: None, frf: Some(frf_figures(&frf, f0, f1)) }, Some(frf))
        }
    }
}

/// Runs the test on a connected drive (which must be able to take it:
/// enabled, and for current/speed tests the load blocked or braked).
pub fn capture_test(c: &mut Client, spec: &Spec, pwm_hz: f64) -> Result<CaptureData> {
    let cfg = spec.capture_config(pwm_hz)?;
    let test = spec.signal();
    let wait = Duration::from_secs_f64(10.0 + 20.0 * spec.duration_s);
    capture_with(c, cfg, move |c| start_test(c, test), wait)
}

/// Starts a test, waiting out the brake's release and the first hold after
/// `Enable`: the drive refuses a test while its brake still opens
/// (`brake.release_time_s` of drive time) and until the loops have held the
/// rod still once, which a test sent right after `Enable` meets.
fn start_test(c: &mut Client, test: TestSignal) -> Result<()> {
    let started = Instant::now();
    loop {
        match c.request(Request::Test(test))? {
            Reply::Error(Error::Test { reason: Reason::BrakeOpening | Reason::AxisNotYetSettled }) if started.elapsed() < BRAKE_WAIT_MAX => {
                c.poll(Duration::from_millis(5))?;
                c.telemetry.clear();
            }
            Reply::Error(e) => bail!("{}: refused: {}", request_text(&Request::Test(test)), describe(&e)),
            _ => return Ok(()),
        }
    }
}

/// Wall time a test waits for the brake to open and the axis to hold still
/// before the refusal is the answer (preload, release and the first settle
/// take a fraction of a second of drive time).
const BRAKE_WAIT_MAX: Duration = Duration::from_secs(10);

/// The same test on a fresh simulated drive with `params` (fast pacing,
/// commissioned, enabled at `position_m`).
pub fn predict(rig: &RigConfig, params: servo_core::ControlParams, position_m: f64, spec: &Spec) -> Result<CaptureData> {
    let mut rig = rig.clone();
    rig.control = params;
    let mut o = DriveOptions::new(rig);
    o.pace = Pace::Fast;
    o.commissioned = true;
    o.initial_position_m = position_m;
    let (addr, stop, h) = drive::spawn_local(o)?;
    let r = (|| {
        let mut c = Client::connect(&super::client::Endpoint::Tcp(addr.to_string()))?;
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
        capture_test(&mut c, spec, pwm)
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = h.join();
    r
}

pub fn wait_running(c: &mut Client) -> Result<()> {
    for _ in 0..500 {
        if let Reply::Status(s) = c.ask(Request::Status)? {
            if s.mode == servo_core::Mode::Running {
                return Ok(());
            }
            if s.faults != 0 {
                bail!("faults latched: {:?}", servo_core::FaultSet::from_bits_retain(s.faults).names().collect::<Vec<_>>());
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    bail!("the drive did not reach Running")
}

/// The whole `step`/`chirp` command: writes capture.csv, prediction.csv,
/// response.png (and bode.png for a chirp) and summary.json to `out`.
pub fn run(c: &mut Client, rig: &RigConfig, spec: &Spec, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
    let params = fetch_params(c, &rig.control)?;
    let position = match c.ask(Request::Status)? {
        Reply::Status(_) => None::<f64>,
        _ => None,
    };
    let measured = capture_test(c, spec, pwm)?;
    measured.write_csv(&out.join("capture.csv"))?;
    let x0 = position.unwrap_or_else(|| measured.values[1].first().copied().unwrap_or(0.0));
    let x0 = if spec.target == Target::Position { x0 } else { 0.25 };
    let predicted = predict(rig, params, x0, spec);
    let (fm, frf_m) = figures(spec, &measured);
    let mut summary = serde_json::json!({ "test": spec, "measured": fm, "sample_period_s": measured.dt_s, "samples": measured.len() });
    let mut series = vec![
        Series { name: "reference", points: (0..measured.len()).map(|k| (measured.t(k), measured.values[0][k])).collect() },
        Series { name: "measured", points: (0..measured.len()).map(|k| (measured.t(k), measured.values[1][k])).collect() },
    ];
    let mut frf_p = None;
    match &predicted {
        Ok(p) => {
            p.write_csv(&out.join("prediction.csv"))?;
            let (fp, f) = figures(spec, p);
            frf_p = f;
            summary["predicted"] = serde_json::to_value(fp)?;
            series.push(Series { name: "simulator", points: (0..p.len()).map(|k| (p.t(k), p.values[1][k])).collect() });
        }
        Err(e) => summary["predicted"] = serde_json::json!({ "unavailable": format!("{e:#}") }),
    }
    line_chart(&out.join("response.png"), "measured vs simulator", "time from test start [s]", "response", &series)?;
    if let Some(m) = frf_m {
        let mut s = vec![Series { name: "measured |T| dB", points: m.freq_hz.iter().zip(&m.gain_db).map(|(f, g)| (*f, *g)).collect() }];
        if let Some(p) = frf_p {
            s.push(Series { name: "simulator |T| dB", points: p.freq_hz.iter().zip(&p.gain_db).map(|(f, g)| (*f, *g)).collect() });
        }
        line_chart(&out.join("bode.png"), "closed-loop gain (H1)", "frequency [Hz]", "gain [dB]", &s)?;
    }
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    Ok(summary)
}
