//! The simulated drive: the control core against the plant, serving the
//! drive protocol (`servo_core::protocol`) over a local TCP socket, so the
//! host tool talks to it exactly as to a board.
//!
//! - `SimDrive`: one closed loop (`sim::ClosedLoop`), the core's protocol
//!   `Server` (the same request handling the firmware runs), and what the
//!   board's main task adds around them: `DriveAccess` on the controller
//!   between two steps, the parameter store (`store`: a file for the flash
//!   record), telemetry at the configured rate, the capture buffer.
//! - `serve`: accepts one client at a time (sequential connections), reads
//!   frames with `FrameReader`, answers, and paces the simulation (`Pace`).
//!
//! Capture and test signals are the core's (`Controller::capture_*`,
//! `start_test`, through `protocol::drive::on_controller` as on the board),
//! with a capture store of the board's size.

pub mod store;

use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{commissioned_control, ClosedLoop};
use anyhow::{anyhow, Context, Result};
use servo_core::controller::ApplyError;
use servo_core::params::{record, ValidatedParams};
use servo_core::protocol::drive::{on_controller, CaptureReply, DriveAccess, DriveStatus};
use servo_core::protocol::server::{Identity, Server};
use servo_core::protocol::{
    self, CaptureRequest, DriveFrame, Error, Feed, FrameReader, Reply, Request, RequestFrame, TelemetryFrame, TestSignal,
    FRAME_MAX,
};
use servo_core::{Command, CommandError, CommandOutcome, ControlParams};
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

/// `DriveAccess` on the simulated controller, between two steps.
struct Access<'a> {
    cl: &'a mut ClosedLoop,
    rating: servo_core::params::PowerStageRating,
}

impl DriveAccess for Access<'_> {
    fn status(&self) -> DriveStatus {
        DriveStatus { telemetry: self.cl.controller.telemetry(), test_running: self.cl.controller.test_running() }
    }
    fn params(&self) -> ControlParams {
        *self.cl.controller.params()
    }
    fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
        self.cl.controller.command(cmd)
    }
    fn apply_params(&mut self, params: &ValidatedParams) -> Result<(), ApplyError> {
        if let Some(leaf) = self.rating.exceeded_by(params.get()) {
            return Err(ApplyError::BeyondHardware { leaf });
        }
        self.cl.controller.apply_params(params)
    }
    fn capture(&mut self, request: &CaptureRequest) -> Result<CaptureReply, servo_core::protocol::Reason> {
        on_controller::capture(&mut self.cl.controller, request)
    }
    fn test_signal(&mut self, signal: &TestSignal) -> Result<(), servo_core::protocol::Reason> {
        on_controller::test_signal(&mut self.cl.controller, signal)
    }
}

/// One simulated drive: the closed loop, the protocol server and what the
/// board adds around them.
pub struct SimDrive {
    pub cl: ClosedLoop,
    opts: DriveOptions,
    server: Server,
    store: store::FileStore,
    telemetry_next: u64,
    divider: u64,
    /// A stream is live: fast pacing advances by stream frames only.
    stream_live: bool,
    /// What happened to the saved record at start (for the log).
    pub boot_note: String,
}

impl SimDrive {
    /// Starts like a board: the saved record, if there is a usable one,
    /// replaces the image's defaults (the rig file's `[control]`).
    pub fn new(opts: DriveOptions) -> Result<Self> {
        let store = store::FileStore { path: opts.store.clone() };
        let rig = &opts.rig;
        let mut plant = Plant::new(rig.plant.clone(), opts.seed);
        let x0 = opts.initial_position_m;
        plant.set_initial_state((x0 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), 90f64.to_radians());
        // Powered up as a board is: brake closed, bridge off.
        plant.engage_brake();
        // The image's defaults; commissioned: offset and reference known.
        let defaults = if opts.commissioned { commissioned_control(rig.control, &plant) } else { rig.control };
        let defaults = ValidatedParams::new(defaults).map_err(|e| anyhow!("control parameters: {e}"))?;
        let (mut params, boot_note) = match store.read() {
            Ok(Some(bytes)) => match record::decode(&bytes) {
                Ok(p) => (*p.get(), "saved record loaded".to_string()),
                Err(e) => (*defaults.get(), format!("saved record not used ({}); image defaults", e.reason())),
            },
            Ok(None) => (*defaults.get(), "no saved record; image defaults".to_string()),
            Err(e) => (*defaults.get(), format!("store: {e}; image defaults")),
        };
        if opts.commissioned {
            // Facts of this rig and power cycle, not settings a record carries.
            let d = defaults.get();
            params.startup.commutation_known = d.startup.commutation_known;
            params.startup.homed = d.startup.homed;
            params.encoder.electrical_offset_rad = d.encoder.electrical_offset_rad;
        }
        // Like the board at power-up: lowered to the power stage's rating,
        // and said so.
        let (params, lowered) = rig.plant.inverter.rating().lower(params);
        let boot_note = match lowered.first_leaf() {
            Some(_) => format!("{boot_note}; lowered to the power stage's rating: {lowered:?}"),
            None => boot_note,
        };
        let controller = servo_core::Controller::try_new(params).map_err(|e| anyhow!("control parameters: {e}"))?;
        let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
        cl.override_pending(servo_core::PwmCommand::OFF);
        // The board's capture store is a `static`; one per simulated drive.
        cl.controller.attach_capture_store(Box::leak(Box::new(servo_core::capture::CaptureStore::new())));
        if opts.commissioned {
            cl.controller
                .command(Command::SetHome { position_m: x0 as f32 })
                .map_err(|e| anyhow!("SetHome: {e:?}"))?;
        }
        let identity = Identity {
            firmware_version: env!("CARGO_PKG_VERSION"),
            git_hash: match option_env!("HOST_SIM_GIT_HASH") {
                Some(h) => h,
                None => "host-sim",
            },
            board: "host-sim simulated drive",
        };
        let divider = u64::from(params.rates.position_loop_divider);
        Ok(Self {
            cl,
            opts,
            server: Server::new(identity, defaults),
            store,
            telemetry_next: 0,
            divider,
            stream_live: false,
            boot_note,
        })
    }

    pub fn params(&self) -> &ControlParams {
        self.cl.controller.params()
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
        let rate = self.server.telemetry_rate_hz();
        let k = self.cl.periods();
        if rate > 0 && k >= self.telemetry_next && k.is_multiple_of(self.divider) {
            let every = (self.pwm_hz() / f64::from(rate)).round().max(1.0) as u64;
            self.telemetry_next = k + every;
            return Some(self.server.telemetry_frame(&self.cl.controller.telemetry()));
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

    /// Handles one request through the core's server; `None`: no reply (an
    /// accepted stream point).
    pub fn handle(&mut self, frame: &RequestFrame) -> Option<DriveFrame> {
        let was_on = self.server.telemetry_rate_hz() > 0;
        let mut access = Access { cl: &mut self.cl, rating: self.opts.rig.plant.inverter.rating() };
        let out = self.server.handle(frame, &mut access, &mut self.store);
        match &frame.request {
            Request::Stream(_) if out.is_none() => self.stream_live = true,
            Request::Stream(_) => {}
            Request::Status | Request::Info | Request::Capture(_) | Request::Telemetry { .. } => {}
            _ => self.stream_live = false,
        }
        if !was_on && self.server.telemetry_rate_hz() > 0 {
            self.telemetry_next = self.cl.periods();
        }
        out
    }

    /// A reply to a frame that did not decode.
    pub fn frame_error(e: protocol::FrameError) -> DriveFrame {
        DriveFrame::Reply { seq: 0, reply: Reply::Error(Error::Frame(e)) }
    }
}

/// A stop flag for `serve` (tests stop their in-process drive with it).
pub type StopFlag = Arc<AtomicBool>;

/// Serves clients one after another until `stop` is set.
pub fn serve(listener: TcpListener, opts: DriveOptions, stop: StopFlag) -> Result<()> {
    let mut drive = SimDrive::new(opts.clone())?;
    eprintln!("drive: {}", drive.boot_note);
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
                Err(e) => send(&mut wr, &SimDrive::frame_error(e))?,
                Ok(frame) => {
                    let is_stream = matches!(frame.request, Request::Stream(_));
                    let live_before = drive.stream_live;
                    let reply = drive.handle(&frame);
                    if is_stream && fast && (drive.stream_live || live_before) {
                        // The frame was applied at a position-loop boundary
                        // (the drive always rests on one); advance exactly one
                        // stream period of simulated time, refused or not, so
                        // the drive's clock keeps the stream's timeline.
                        last_stream_frame = Instant::now();
                        for _ in 0..stream_periods {
                            tlm.extend(drive.step());
                        }
                        if !drive.cl.periods().is_multiple_of(drive.divider) {
                            drive.step_to_boundary(&mut tlm);
                        }
                    }
                    if let Some(reply) = reply {
                        send(&mut wr, &reply)?;
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
