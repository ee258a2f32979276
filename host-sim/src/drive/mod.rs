//! The simulated drive: the control core against the plant, serving the
//! drive protocol (`servo_core::protocol`) over a local TCP socket, so the
//! host tool talks to it exactly as to a board.
//!
//! - `SimDrive`: one closed loop (`sim::ClosedLoop`) plus what the board's
//!   main task adds around the core: the request dispatch, telemetry at the
//!   requested rate, the capture buffer and the parameter store (a file).
//! - `serve`: accepts one client at a time (sequential connections), reads
//!   frames with `FrameReader`, answers, and paces the simulation (`Pace`).
//!
//! Interim seams until the core branches are merged (docs/host-tool.md):
//! parameter paths (`params`, replaced by the core `Server`'s miniconf
//! paths), `Controller::apply_params` (sets take effect on the next start
//! of the drive until then), the capture buffer (`capture`, replaced by
//! `Controller::capture_*`) and test signals (refused until
//! `Controller::start_test`).

pub mod capture;
pub mod params;
pub mod store;

use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{commissioned_control, ClosedLoop};
use anyhow::{anyhow, Context, Result};
use servo_core::protocol::{
    self, heapless, CommandReport, DriveCommand, DriveFrame, Error, Feed, FrameReader, Info, Reply, Request,
    RequestFrame, Status, TelemetryFrame, FRAME_MAX, SCHEMA_HASH,
};
use servo_core::{Command, ControlParams, Controller};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How simulated time relates to the wall clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Pace {
    /// Simulated time follows the wall clock (as a board would).
    Realtime,
    /// As fast as the host computes while a client is connected; while a
    /// stream is live, exactly one stream period per stream frame
    /// (deterministic whatever the host's scheduling); paused with no client.
    Fast,
}

/// Everything `host-sim drive serve` is told.
#[derive(Clone, Debug)]
pub struct DriveOptions {
    pub rig: RigConfig,
    pub pace: Pace,
    /// The flash record stands in here; `None`: Save/Load refused.
    pub store: Option<PathBuf>,
    /// Start commissioned and homed at `initial_position_m` (as the
    /// simulator's experiments do) instead of like a fresh board (nothing
    /// known until `StartUp`).
    pub commissioned: bool,
    /// Rod position at start, metres.
    pub initial_position_m: f64,
    /// Fast pacing: simulated time one stream frame advances.
    pub stream_period_s: f64,
    /// Fast pacing: a stream counts as ended after this long without a
    /// frame (wall clock); the simulation then runs free again.
    pub stream_idle_s: f64,
    pub seed: u64,
}

impl DriveOptions {
    pub fn new(rig: RigConfig) -> Self {
        let stream_period_s =
            f64::from(rig.control.rates.position_loop_divider) / f64::from(rig.control.rates.pwm_frequency_hz);
        Self {
            rig,
            pace: Pace::Realtime,
            store: None,
            commissioned: false,
            initial_position_m: 0.25,
            stream_period_s,
            stream_idle_s: 0.25,
            seed: 1,
        }
    }
}

/// One simulated drive: the closed loop and what the board adds around it.
pub struct SimDrive {
    pub cl: ClosedLoop,
    opts: DriveOptions,
    /// The parameter set the host sees (`ParamGet`/`ParamSet`/`Save`).
    params: ControlParams,
    store: store::FileStore,
    capture: capture::Capture,
    telemetry_fields: u32,
    telemetry_every: u64,
    telemetry_next: u64,
    divider: u64,
    /// A stream is live: fast pacing advances by stream frames only.
    stream_live: bool,
    /// Sets applied to the controller still waiting for `apply_params`.
    pub pending_apply: bool,
}

impl SimDrive {
    /// Starts like a board: the saved record (if any) replaces the image's
    /// defaults (the rig file's `[control]`).
    pub fn new(opts: DriveOptions) -> Result<Self> {
        let store = store::FileStore { path: opts.store.clone() };
        let mut params = opts.rig.control;
        let mut loaded = false;
        if opts.store.is_some() {
            if let Some(p) = store.load().map_err(|e| anyhow!("--store: {e}"))? {
                params = p;
                loaded = true;
            }
        }
        let rig = &opts.rig;
        let mut plant = Plant::new(rig.plant.clone(), opts.seed);
        let x0 = opts.initial_position_m;
        plant.set_initial_state((x0 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), 90f64.to_radians());
        // Powered up as a board is: brake closed, bridge off.
        plant.engage_brake();
        // The commissioning bits (commutation, homing) are facts about the
        // rig, not parameters a record carries over.
        let mut run = params;
        if opts.commissioned {
            run = commissioned_control(params, &plant);
            if !loaded {
                params = run;
            }
        }
        let controller = Controller::try_new(run).map_err(|e| anyhow!("control parameters: {e}"))?;
        let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
        cl.override_pending(servo_core::PwmCommand::OFF);
        if opts.commissioned {
            cl.controller
                .command(Command::SetHome { position_m: x0 as f32 })
                .map_err(|e| anyhow!("SetHome: {e:?}"))?;
        }
        let divider = u64::from(run.rates.position_loop_divider);
        Ok(Self {
            cl,
            opts,
            params,
            store,
            capture: capture::Capture::default(),
            telemetry_fields: 0,
            telemetry_every: 0,
            telemetry_next: 0,
            divider,
            stream_live: false,
            pending_apply: false,
        })
    }

    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    pub fn stream_live(&self) -> bool {
        self.stream_live
    }

    pub fn pwm_hz(&self) -> f64 {
        f64::from(self.cl.controller.params().rates.pwm_frequency_hz)
    }

    /// One PWM period; a telemetry frame if one is due.
    pub fn step(&mut self) -> Option<TelemetryFrame> {
        self.cl.step();
        self.capture.sample(&self.cl);
        let k = self.cl.periods();
        if self.telemetry_every > 0 && k >= self.telemetry_next {
            self.telemetry_next = k + self.telemetry_every;
            return Some(self.telemetry_frame());
        }
        None
    }

    /// Steps to the next position-loop boundary (at least one period).
    pub fn step_to_boundary(&mut self, out: &mut Vec<TelemetryFrame>) {
        loop {
            out.extend(self.step());
            if self.cl.periods().is_multiple_of(self.divider) {
                break;
            }
        }
    }

    fn telemetry_frame(&self) -> TelemetryFrame {
        let t = self.cl.controller.telemetry();
        let all = [
            t.position_reference_m,
            t.position_command_m,
            t.position_shift_m,
            t.motor_position_m,
            t.speed_reference_rad_s,
            t.speed_rad_s,
            t.current_d_a,
            t.current_q_a,
            t.current_q_reference_a,
            t.voltage_d_v,
            t.voltage_q_v,
            t.bus_voltage_v,
            t.terminal_position_m.unwrap_or(f32::NAN),
            t.load_force_estimate_n,
            t.mode as u8 as f32,
            t.faults.bits() as f32,
            f32::from(t.readiness.0),
        ];
        let mut values = heapless::Vec::new();
        for (i, v) in all.iter().enumerate() {
            if self.telemetry_fields & (1 << i) != 0 {
                let _ = values.push(*v);
            }
        }
        TelemetryFrame { time_s: self.cl.time_s() as f32, fields: self.telemetry_fields, values }
    }

    fn status(&self) -> Status {
        let c = &self.cl.controller;
        Status {
            mode: c.mode(),
            faults: c.faults().bits(),
            readiness: c.readiness().0,
            time_s: self.cl.time_s() as f32,
            test_running: false,
        }
    }

    /// Handles one request; `None`: no reply (an accepted stream point).
    pub fn handle(&mut self, req: Request) -> Option<Reply> {
        let text = |s: &str| -> protocol::Text {
            let mut t = heapless::String::new();
            for ch in s.chars() {
                if t.push(ch).is_err() {
                    break;
                }
            }
            t
        };
        let path_of = |s: &str| -> protocol::Path {
            let mut t = heapless::String::new();
            for ch in s.chars() {
                if t.push(ch).is_err() {
                    break;
                }
            }
            t
        };
        let bridge_on = || !matches!(self.cl.controller.mode(), servo_core::Mode::Disabled | servo_core::Mode::Fault);
        let reply = match req {
            Request::Info => Reply::Info(Info {
                firmware_version: text(env!("CARGO_PKG_VERSION")),
                git_hash: text(option_env!("HOST_SIM_GIT_HASH").unwrap_or("host-sim")),
                schema_hash: SCHEMA_HASH,
                board: text("host-sim simulated drive"),
                mode: self.cl.controller.mode(),
                faults: self.cl.controller.faults().bits(),
                pwm_frequency_hz: self.pwm_hz() as f32,
            }),
            Request::Status => Reply::Status(self.status()),
            Request::ParamCount => Reply::ParamCount { count: params::leaves(&self.params).len() as u16 },
            Request::ParamName { index } => match params::leaves(&self.params).get(usize::from(index)) {
                Some((p, kind)) => {
                    // `control.` + path, unless that overflows PATH_MAX.
                    let full = format!("control.{p}");
                    let path = if full.len() <= protocol::PATH_MAX { full } else { p.clone() };
                    Reply::ParamName { index, path: path_of(&path), kind: *kind }
                }
                None => Reply::Error(Error::UnknownPath { path: path_of(&format!("#{index}")) }),
            },
            Request::ParamGet { path } => match params::get(&self.params, &path) {
                Ok(value) => Reply::Param { path, value },
                Err(_) => Reply::Error(Error::UnknownPath { path }),
            },
            Request::ParamSet { path, value } => match params::set(&self.params, &path, value) {
                Ok(p) => {
                    self.params = p;
                    self.pending_apply = true;
                    let value = params::get(&self.params, &path).unwrap_or(value);
                    Reply::Param { path, value }
                }
                Err(params::PathError::Unknown) => Reply::Error(Error::UnknownPath { path }),
                Err(params::PathError::WrongType(expected)) => Reply::Error(Error::WrongType { path, expected }),
                Err(params::PathError::Invalid(reason)) => Reply::Error(Error::InvalidParam { field: path, reason: text(&reason) }),
            },
            Request::Save if bridge_on() => Reply::Error(Error::BridgeOn),
            Request::Save => match self.store.save(&self.params) {
                Ok(()) => Reply::Ok,
                Err(e) => Reply::Error(Error::Storage { reason: text(&e) }),
            },
            Request::Load if bridge_on() => Reply::Error(Error::BridgeOn),
            Request::Load => match self.store.load() {
                Ok(Some(p)) => {
                    self.params = p;
                    self.pending_apply = true;
                    Reply::Loaded { from_flash: true, note: text("saved record applied") }
                }
                Ok(None) => Reply::Error(Error::Storage { reason: text("no saved record") }),
                Err(e) => Reply::Error(Error::Storage { reason: text(&e) }),
            },
            Request::Defaults => {
                self.params = self.opts.rig.control;
                self.pending_apply = true;
                Reply::Ok
            }
            Request::Command(cmd) => {
                self.stream_live = false;
                let core = match cmd {
                    DriveCommand::Enable => Command::Enable,
                    DriveCommand::Disable => Command::Disable,
                    DriveCommand::Calibrate => Command::Calibrate,
                    DriveCommand::Align => Command::Align,
                    DriveCommand::Home => Command::Home,
                    DriveCommand::StartUp => Command::StartUp,
                    DriveCommand::MoveTo { position_m } => Command::MoveTo { position_m },
                    DriveCommand::Jog { distance_m } => Command::Jog { distance_m },
                    DriveCommand::SetHome { position_m } => Command::SetHome { position_m },
                    // Interim: the core ends a stream and holds; a stop of a
                    // planned move waits for the core server's `Stop`.
                    DriveCommand::Stop => Command::StreamEnd,
                    DriveCommand::ClearFaults => Command::ClearFaults,
                    DriveCommand::SetCompensation { enabled } => Command::SetCompensation { enabled },
                    DriveCommand::SetPositionShift { shift_m } => Command::SetPositionShift { shift_m },
                };
                match self.cl.controller.command(core) {
                    Ok(o) => Reply::Command(CommandReport::from(o)),
                    Err(e) => Reply::Error(Error::Command(e)),
                }
            }
            Request::Stream(p) => {
                let cmd = Command::Stream { position_m: p.position_m, velocity_m_s: p.velocity_m_s, force_n: p.force_n };
                match self.cl.controller.command(cmd) {
                    Ok(servo_core::CommandOutcome::Accepted) => {
                        self.stream_live = true;
                        return None;
                    }
                    Ok(servo_core::CommandOutcome::ClampedToStroke { position_m }) => {
                        self.stream_live = true;
                        Reply::Error(Error::Stream { reason: text(&format!("clamped to stroke at {position_m} m")) })
                    }
                    Err(e) => Reply::Error(Error::Command(e)),
                }
            }
            Request::Telemetry { fields, rate_hz } => {
                if rate_hz == 0 {
                    self.telemetry_every = 0;
                } else {
                    let every = (self.pwm_hz() / f64::from(rate_hz)).round().max(1.0) as u64;
                    self.telemetry_every = every;
                    self.telemetry_next = self.cl.periods();
                }
                self.telemetry_fields = fields & ((1 << protocol::TelemetryField::COUNT) - 1);
                Reply::Ok
            }
            Request::Capture(c) => {
                let pwm = self.pwm_hz() as f32;
                let r = match c {
                    protocol::CaptureRequest::Configure(cfg) => self.capture.configure(cfg, pwm).map(|_| Reply::CaptureStatus(self.capture.status())),
                    protocol::CaptureRequest::Trigger => self.capture.trigger().map(|_| Reply::Ok),
                    protocol::CaptureRequest::Status => Ok(Reply::CaptureStatus(self.capture.status())),
                    protocol::CaptureRequest::Read { signal, start, count } => {
                        let count = count.min(protocol::CAPTURE_CHUNK_MAX as u8);
                        self.capture.read(signal, start, count).map(|v| Reply::CaptureData {
                            signal,
                            start,
                            values: heapless::Vec::from_slice(&v).unwrap_or_default(),
                        })
                    }
                };
                r.unwrap_or_else(|e| Reply::Error(Error::Capture { reason: text(&e) }))
            }
            Request::Test(_) => Reply::Error(Error::Test { reason: text("needs the core's start_test (core-scope)") }),
        };
        Some(reply)
    }
}

/// A stop flag for `serve` (tests stop their in-process drive with it).
pub type StopFlag = Arc<AtomicBool>;

/// Serves clients one after another until `stop` is set.
pub fn serve(listener: TcpListener, opts: DriveOptions, stop: StopFlag) -> Result<()> {
    let mut drive = SimDrive::new(opts.clone())?;
    listener.set_nonblocking(true)?;
    let started = Instant::now();
    let mut sim_offset_s = 0.0;
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((sock, peer)) => {
                eprintln!("drive: client {peer} connected");
                if let Err(e) = session(&mut drive, sock, &stop) {
                    eprintln!("drive: client {peer}: {e:#}");
                }
                sim_offset_s = drive.cl.time_s() - started.elapsed().as_secs_f64();
                eprintln!("drive: client {peer} gone at t = {:.3} s", drive.cl.time_s());
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                if opts.pace == Pace::Realtime {
                    // No client: the drive runs on as a board would.
                    let mut sink = Vec::new();
                    advance_realtime(&mut drive, started, sim_offset_s, &mut sink);
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            Err(e) => return Err(e).context("accept"),
        }
    }
    Ok(())
}

fn advance_realtime(drive: &mut SimDrive, started: Instant, offset_s: f64, out: &mut Vec<TelemetryFrame>) {
    let target = started.elapsed().as_secs_f64() + offset_s;
    // Bounded catch-up so a slow host still answers requests.
    let mut n = 0;
    while drive.cl.time_s() < target && n < 100 {
        drive.step_to_boundary(out);
        n += 1;
    }
}

fn send(sock: &mut impl Write, frame: &DriveFrame) -> Result<()> {
    let mut buf = [0u8; FRAME_MAX];
    let bytes = protocol::encode(frame, &mut buf).ok_or_else(|| anyhow!("reply too large to encode: {frame:?}"))?;
    sock.write_all(bytes)?;
    Ok(())
}

fn session(drive: &mut SimDrive, sock: TcpStream, stop: &StopFlag) -> Result<()> {
    sock.set_nodelay(true)?;
    let mut rd = sock.try_clone()?;
    let mut wr = std::io::BufWriter::with_capacity(64 * 1024, sock);
    let mut reader = FrameReader::new();
    let mut buf = [0u8; 4096];
    let mut tlm = Vec::new();
    let mut last_stream_frame = Instant::now();
    let fast = drive.opts.pace == Pace::Fast;
    let stream_periods = (drive.opts.stream_period_s * drive.pwm_hz()).round().max(1.0) as u64;
    let sim_at_connect = drive.cl.time_s();
    let wall_at_connect = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        // Lock-step: wait for the next frame; otherwise only look.
        let lockstep = fast && drive.stream_live;
        if lockstep && last_stream_frame.elapsed().as_secs_f64() > drive.opts.stream_idle_s {
            drive.stream_live = false;
        }
        let lockstep = fast && drive.stream_live;
        rd.set_nonblocking(!lockstep)?;
        if lockstep {
            rd.set_read_timeout(Some(Duration::from_millis(20)))?;
        }
        let n = match rd.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => 0,
            Err(e) if e.kind() == ErrorKind::ConnectionReset => return Ok(()),
            Err(e) => return Err(e.into()),
        };
        for &b in &buf[..n] {
            let req: Result<RequestFrame, protocol::FrameError> = match reader.push(b) {
                Feed::Pending => continue,
                Feed::Dropped(e) => Err(e),
                Feed::Frame(f) => protocol::decode(f),
            };
            match req {
                Err(e) => send(&mut wr, &DriveFrame::Reply { seq: 0, reply: Reply::Error(Error::Frame(e)) })?,
                Ok(RequestFrame { seq, request }) => {
                    let is_stream = matches!(request, Request::Stream(_));
                    let reply = drive.handle(request);
                    if is_stream && fast && drive.stream_live {
                        // The frame was applied at a position-loop boundary
                        // (the drive always rests on one); advance exactly one
                        // stream period of simulated time.
                        last_stream_frame = Instant::now();
                        for _ in 0..stream_periods {
                            tlm.extend(drive.step());
                        }
                        if !drive.cl.periods().is_multiple_of(drive.divider) {
                            drive.step_to_boundary(&mut tlm);
                        }
                    }
                    if let Some(reply) = reply {
                        send(&mut wr, &DriveFrame::Reply { seq, reply })?;
                    }
                }
            }
            for t in tlm.drain(..) {
                send(&mut wr, &DriveFrame::Telemetry(t))?;
            }
        }
        // Advance the simulation.
        if fast {
            if !drive.stream_live {
                // Free running: one position period between looks at the socket.
                drive.step_to_boundary(&mut tlm);
            }
        } else {
            let target = sim_at_connect + wall_at_connect.elapsed().as_secs_f64();
            let mut k = 0;
            while drive.cl.time_s() < target && k < 50 {
                drive.step_to_boundary(&mut tlm);
                k += 1;
            }
            if drive.cl.time_s() >= target && n == 0 {
                std::thread::sleep(Duration::from_micros(300));
            }
        }
        for t in tlm.drain(..) {
            send(&mut wr, &DriveFrame::Telemetry(t))?;
        }
        wr.flush()?;
    }
}

/// Starts a drive on `127.0.0.1:0` in a thread (tests, `bench-stream`).
/// Returns the address, the stop flag and the thread.
pub fn spawn_local(opts: DriveOptions) -> Result<(std::net::SocketAddr, StopFlag, std::thread::JoinHandle<Result<()>>)> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    let addr = listener.local_addr()?;
    let stop: StopFlag = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let h = std::thread::spawn(move || serve(listener, opts, s));
    Ok((addr, stop, h))
}
