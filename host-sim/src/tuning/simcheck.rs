//! The proposal on the full plant before it goes to a drive: the core's own
//! test signals (`Controller::start_test`) and capture store, in process,
//! through `sim::ClosedLoop`, sampled as the host tool samples a drive.

use crate::tool::analysis::{frf_figures, h1, step_figures, FrfFigures, StepFigures};
use super::identify::Capture;
use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{commissioned_control, ClosedLoop};
use anyhow::{anyhow, bail, Result};
use servo_core::capture::CaptureStore;
use servo_core::protocol::{heapless, CaptureConfig, CaptureState, CaptureTrigger, ChirpTarget, Signal, TestSignal};
use servo_core::{Command, ControlParams, Controller, Mode};
use std::f64::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Loop {
    Current,
    Speed,
    Position,
}

/// One test: a step (`chirp` None) or a log chirp `(from, to)` Hz.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TestSpec {
    pub target: Loop,
    pub amplitude: f64,
    pub duration_s: f64,
    pub chirp: Option<(f64, f64)>,
    /// Capture decimation (PWM periods per sample).
    pub decimation: u16,
    pub signals: Vec<&'static str>,
}

fn signal(n: &str) -> Signal {
    match n {
        "current_q" => Signal::CurrentQ,
        "current_q_reference" => Signal::CurrentQReference,
        "voltage_q" => Signal::VoltageQ,
        "speed" => Signal::Speed,
        "speed_reference" => Signal::SpeedReference,
        "motor_position" => Signal::MotorPosition,
        "position_command" => Signal::PositionCommand,
        _ => unreachable!("signal {n}"),
    }
}

impl TestSpec {
    /// A step as `host-sim drive step` captures it: reference, response and
    /// two more, at the loop's own rate (coarser if the store needs it).
    pub fn step(target: Loop, amplitude: f64, duration_s: f64) -> Self {
        let (signals, base): (Vec<&'static str>, u16) = match target {
            Loop::Current => (vec!["current_q_reference", "current_q", "voltage_q", "speed"], 1),
            Loop::Speed => (vec!["speed_reference", "speed", "current_q", "motor_position"], 4),
            Loop::Position => (vec!["position_command", "motor_position", "speed", "current_q"], 20),
        };
        let max = (servo_core::capture::CAPTURE_STORE_CELLS / 4) as f64;
        let periods = 1.1 * duration_s * 20_000.0;
        let decimation = base.max((periods / max).ceil() as u16);
        TestSpec { target, amplitude, duration_s, chirp: None, decimation, signals }
    }

    /// A chirp: reference and response only (twice the samples), as the
    /// host tool's `drive chirp`.
    pub fn chirp(target: Loop, amplitude: f64, from_hz: f64, to_hz: f64, duration_s: f64, decimation: u16) -> Self {
        let signals = match target {
            Loop::Current => vec!["current_q_reference", "current_q"],
            Loop::Speed => vec!["speed_reference", "speed"],
            Loop::Position => vec!["position_command", "motor_position"],
        };
        TestSpec { target, amplitude, duration_s, chirp: Some((from_hz, to_hz)), decimation, signals }
    }

    fn test_signal(&self) -> TestSignal {
        let (a, d) = (self.amplitude as f32, self.duration_s as f32);
        match (self.chirp, self.target) {
            (None, Loop::Current) => TestSignal::CurrentStep { axis_q: true, amplitude_a: a, duration_s: d },
            (None, Loop::Speed) => TestSignal::SpeedStep { amplitude_rad_s: a, duration_s: d },
            (None, Loop::Position) => TestSignal::PositionStep { distance_m: a, duration_s: d },
            (Some((f0, f1)), t) => TestSignal::Chirp {
                target: match t {
                    Loop::Current => ChirpTarget::Current,
                    Loop::Speed => ChirpTarget::Speed,
                    Loop::Position => ChirpTarget::Position,
                },
                amplitude: a,
                start_hz: f0 as f32,
                end_hz: f1 as f32,
                duration_s: d,
            },
        }
    }

    fn capture_config(&self, pwm_hz: f64) -> Result<CaptureConfig> {
        let max = servo_core::capture::CAPTURE_STORE_CELLS / self.signals.len();
        let periods = 1.1 * self.duration_s * pwm_hz;
        let samples = ((periods / f64::from(self.decimation)).ceil() as usize).clamp(64, max);
        if let Some((_, to)) = self.chirp {
            if pwm_hz / f64::from(self.decimation) < 2.5 * to {
                bail!("chirp to {to} Hz sampled at {} Hz", pwm_hz / f64::from(self.decimation));
            }
        }
        let sig: Vec<Signal> = self.signals.iter().map(|n| signal(n)).collect();
        Ok(CaptureConfig {
            signals: heapless::Vec::from_slice(&sig).map_err(|_| anyhow!("at most 4 signals"))?,
            decimation: self.decimation,
            samples: samples as u16,
            pre_trigger: (samples / 11) as u16,
            trigger: CaptureTrigger::TestStart,
        })
    }
}

/// A captured test: the capture (t = 0 at the trigger sample) and its
/// trigger index.
#[derive(Clone, Debug)]
pub struct Captured {
    pub capture: Capture,
    pub trigger_index: usize,
}

/// The rated payload hanging vertically at `x0_m`, commissioned, enabled
/// and settled, with a capture store: as `drive serve --commissioned`.
pub fn holding(rig: &RigConfig, control: ControlParams, x0_m: f64, seed: u64) -> Result<ClosedLoop> {
    let mut plant = Plant::new(rig.plant.clone(), seed);
    plant.set_initial_state((x0_m - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), PI / 2.0);
    let mut controller =
        Controller::try_new(commissioned_control(control, &plant)).map_err(|e| anyhow!("parameters: {e:?}"))?;
    controller.attach_capture_store(Box::leak(Box::new(CaptureStore::new())));
    let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.controller.command(Command::SetHome { position_m: x0_m as f32 }).map_err(|e| anyhow!("{e:?}"))?;
    cl.controller.command(Command::Enable).map_err(|e| anyhow!("{e:?}"))?;
    for _ in 0..6000 {
        cl.step();
    }
    if cl.controller.mode() != Mode::Running {
        bail!("the simulated drive did not reach Running: {:?}", cl.controller.telemetry().faults);
    }
    Ok(cl)
}

/// Runs one test on a holding loop and uploads its capture.
pub fn run_test(cl: &mut ClosedLoop, spec: &TestSpec) -> Result<Captured> {
    let pwm = f64::from(cl.controller.params().rates.pwm_frequency_hz);
    let cfg = spec.capture_config(pwm)?;
    cl.controller.capture_configure(&cfg).map_err(|e| anyhow!("capture: {e}"))?;
    // Fill the pre-trigger ring, then start.
    for _ in 0..(u64::from(cfg.pre_trigger) * u64::from(cfg.decimation) + 4) {
        cl.step();
    }
    cl.controller.start_test(spec.test_signal()).map_err(|e| anyhow!("test refused: {e}"))?;
    let max = (3.0 * spec.duration_s * pwm) as u64 + 400_000;
    for _ in 0..max {
        let tel = cl.step();
        if !tel.faults.is_empty() {
            bail!("faults during the test: {:?}", tel.faults.names().collect::<Vec<_>>());
        }
        if cl.controller.capture_status().state == CaptureState::Done {
            break;
        }
    }
    let st = cl.controller.capture_status();
    if st.state != CaptureState::Done {
        bail!("capture not done");
    }
    // Let the test end before the next one.
    while cl.controller.test_running() {
        cl.step();
    }
    for _ in 0..4000 {
        cl.step();
    }
    let n = st.samples as usize;
    let mut cols = Vec::new();
    for s in 0..spec.signals.len() {
        let mut v = vec![0.0f32; n];
        let mut start = 0;
        while start < n {
            let end = (start + 64).min(n);
            start += cl.controller.capture_read(s as u8, start as u16, &mut v[start..end]).map_err(|e| anyhow!("{e}"))?;
        }
        cols.push(v.into_iter().map(f64::from).collect::<Vec<_>>());
    }
    let dt = f64::from(cfg.decimation) / pwm;
    let names = spec.signals.iter().map(|s| s.to_string()).collect();
    Ok(Captured { capture: Capture::new("simulated", dt, names, cols), trigger_index: st.trigger_index as usize })
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct TestFigures {
    pub step: Option<StepFigures>,
    pub frf: Option<FrfFigures>,
    /// The −3 dB frequency interpolated between FRF bins (the host tool's
    /// `bandwidth_3db_hz` is the first bin below).
    pub bandwidth_3db_interp_hz: Option<f64>,
}

pub fn figures(spec: &TestSpec, c: &Captured) -> TestFigures {
    let cap = &c.capture;
    let (x, y) = (&cap.columns[0], &cap.columns[1]);
    match spec.chirp {
        None => {
            let t0 = c.trigger_index as f64 * cap.dt_s;
            TestFigures { step: Some(step_figures(y, cap.dt_s, t0, spec.amplitude)), frf: None, bandwidth_3db_interp_hz: None }
        }
        Some((f0, f1)) => {
            let k0 = c.trigger_index;
            let frf = h1(&x[k0..], &y[k0..], cap.dt_s, 1024);
            let figs = frf_figures(&frf, f0, f1);
            let idx: Vec<usize> = (0..frf.freq_hz.len())
                .filter(|&k| frf.freq_hz[k] >= f0 && frf.freq_hz[k] <= f1 && frf.coherence[k] >= 0.8)
                .collect();
            let interp = idx.first().and_then(|&first| {
                let g0 = frf.gain_db[first];
                idx.windows(2).find(|w| frf.gain_db[w[1]] < g0 - 3.0).map(|w| {
                    let (a, b) = (frf.gain_db[w[0]] - (g0 - 3.0), frf.gain_db[w[1]] - (g0 - 3.0));
                    let s = a / (a - b);
                    frf.freq_hz[w[0]] + s * (frf.freq_hz[w[1]] - frf.freq_hz[w[0]])
                })
            });
            TestFigures { step: None, frf: Some(figs), bandwidth_3db_interp_hz: interp }
        }
    }
}
