//! The proposal on the full plant before it goes to a drive: the core's own
//! test signals (`Controller::start_test`) and capture store, in process,
//! through `sim::ClosedLoop`, sampled as the host tool samples a drive.

use super::design::{DesignPlant, Margins};
use super::identify::Capture;
use super::measure::{log_grid, step_figures_in, Response};
use crate::tool::analysis::StepFigures;
use nalgebra::Complex;
use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{commissioned_control, ClosedLoop};
use anyhow::{anyhow, bail, Result};
use servo_core::capture::CaptureStore;
use servo_core::reason::Reason;
use servo_core::protocol::{CaptureConfig, CaptureState, CaptureTrigger, ChirpTarget, Signal, TestSignal};
use servo_core::{Command, ControlParams, Controller, Mode};
use std::f64::consts::PI;

/// How long a check waits for the drive to settle after Enable before a
/// test, seconds (the host tool waits as long on a board).
const SETTLE_WAIT_MAX_S: f64 = 10.0;

type C64 = Complex<f64>;

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
    /// A current step on the d axis (no torque, so no motion and no
    /// back-EMF: the current PI alone, as it serves both axes).
    pub axis_d: bool,
}

fn signal(n: &str) -> Signal {
    match n {
        "current_q" => Signal::CurrentQ,
        "current_q_reference" => Signal::CurrentQReference,
        "current_d" => Signal::CurrentD,
        "current_d_reference" => Signal::CurrentDReference,
        "voltage_d" => Signal::VoltageD,
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
        TestSpec { target, amplitude, duration_s, chirp: None, decimation, signals, axis_d: false }
    }

    /// A d-axis current step, captured every PWM period: reference,
    /// response, voltage and speed.
    pub fn current_step_d(amplitude: f64, duration_s: f64) -> Self {
        let signals = vec!["current_d_reference", "current_d", "voltage_d", "speed"];
        TestSpec { signals, axis_d: true, ..Self::step(Loop::Current, amplitude, duration_s) }
    }

    /// A chirp: reference, response and the loop's controller output (the
    /// q voltage, the q-current reference, the speed reference), from which
    /// the open loop `L = C·P` is measured (`measure`).
    pub fn chirp(target: Loop, amplitude: f64, from_hz: f64, to_hz: f64, duration_s: f64, decimation: u16) -> Self {
        let signals = match target {
            Loop::Current => vec!["current_q_reference", "current_q", "voltage_q"],
            Loop::Speed => vec!["speed_reference", "speed", "current_q_reference"],
            Loop::Position => vec!["position_command", "motor_position", "speed_reference"],
        };
        TestSpec { target, amplitude, duration_s, chirp: Some((from_hz, to_hz)), decimation, signals, axis_d: false }
    }

    fn test_signal(&self) -> TestSignal {
        let (a, d) = (self.amplitude as f32, self.duration_s as f32);
        match (self.chirp, self.target) {
            (None, Loop::Current) => TestSignal::CurrentStep { axis_q: !self.axis_d, amplitude_a: a, duration_s: d },
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
            signals: servo_core::capture::SignalList::from_slice(&sig).map_err(|_| anyhow!("at most 4 signals"))?,
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
        let tel = cl.step();
        if !tel.faults.is_empty() {
            bail!("faults before the test started: {:?}", tel.faults.names().collect::<Vec<_>>());
        }
    }
    // As the host tool does on a board: a drive that is still taking the
    // load over from the brake refuses a test until the loops have held the
    // rod still once; wait that out (bounded), never a test on the hand-over.
    let wait_max = (SETTLE_WAIT_MAX_S * pwm) as u64;
    let mut waited = 0u64;
    loop {
        match cl.controller.start_test(spec.test_signal()) {
            Ok(()) => break,
            Err(Reason::BrakeOpening | Reason::AxisNotYetSettled) if waited < wait_max => {
                let tel = cl.step();
                if !tel.faults.is_empty() {
                    bail!("faults while waiting to start the test: {:?}", tel.faults.names().collect::<Vec<_>>());
                }
                waited += 1;
            }
            Err(e) => bail!("test refused: {e}"),
        }
    }
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
        let tel = cl.step();
        if !tel.faults.is_empty() {
            bail!("faults as the test ended: {:?}", tel.faults.names().collect::<Vec<_>>());
        }
    }
    for _ in 0..4000 {
        let tel = cl.step();
        if !tel.faults.is_empty() {
            bail!("faults while settling after the test: {:?}", tel.faults.names().collect::<Vec<_>>());
        }
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
    /// The closed loop's −3 dB frequency (`measure::Response::bandwidth_3db_hz`
    /// against 0 dB).
    pub bandwidth_3db_hz: Option<f64>,
    /// Gain of the closed loop at the chirp's lowest frequency, dB.
    pub low_frequency_gain_db: Option<f64>,
    /// Margins of the measured open loop `L = C·Y/U`.
    pub margins: Option<Margins>,
    /// The measured closed loop on the grid (Hz, dB, degrees).
    pub frf: Option<Vec<(f64, f64, f64)>>,
}

/// The loop's regulator as the core computes it, from its output `u` back to
/// the fed-back error: the current PI (per PWM period), the speed PI and the
/// torque filter (per speed period), the position P (rad/s per metre).
pub fn regulator(target: Loop, p: &ControlParams, plant: &DesignPlant, w: f64) -> C64 {
    match target {
        Loop::Current => {
            let t = plant.t_pwm();
            let z = C64::new((w * t).cos(), (w * t).sin());
            C64::from(f64::from(p.current_pi.kp)) + z * (f64::from(p.current_pi.ki) * t) / (z - 1.0)
        }
        Loop::Speed => plant.speed_pi(f64::from(p.speed_pi.kp), f64::from(p.speed_pi.ki), w) * plant.torque_filter(w),
        Loop::Position => C64::from(f64::from(p.position_kp_per_s) / f64::from(p.metres_per_rad())),
    }
}

pub fn figures(spec: &TestSpec, c: &Captured, p: &ControlParams) -> TestFigures {
    let cap = &c.capture;
    let (x, y) = (&cap.columns[0], &cap.columns[1]);
    let t0 = c.trigger_index as f64 * cap.dt_s;
    match spec.chirp {
        None => TestFigures {
            step: Some(step_figures_in(y, cap.dt_s, t0, spec.duration_s, spec.amplitude)),
            bandwidth_3db_hz: None,
            low_frequency_gain_db: None,
            margins: None,
            frf: None,
        },
        Some((f0, f1)) => {
            let grid = log_grid(f0, f1, 240);
            let rest = c.trigger_index;
            let t = Response::ratio(x, y, rest, cap.dt_s, grid.clone());
            let plant = DesignPlant::from_params(p, f64::from(p.reflected_inertia_kg_m2()), 0.0);
            let margins = cap.columns.get(2).map(|u| {
                let pl = Response::ratio(u, y, rest, cap.dt_s, grid.clone());
                let l = Response {
                    h: pl.h.iter().zip(&grid).map(|(h, f)| h * regulator(spec.target, p, &plant, std::f64::consts::TAU * f)).collect(),
                    freq_hz: grid.clone(),
                };
                l.margins()
            });
            let g = t.gain_db();
            TestFigures {
                step: None,
                bandwidth_3db_hz: t.bandwidth_3db_hz(1.0),
                low_frequency_gain_db: g.first().copied(),
                margins,
                frf: Some(grid.iter().zip(&g).zip(&t.h).map(|((f, g), h)| (*f, *g, h.arg().to_degrees())).collect()),
            }
        }
    }
}
