//! The simulated drive: the control core against the plant, serving the
//! drive protocol (`servo_core::protocol`) over a local TCP socket, so the
//! host tool talks to it exactly as to a board.
//!
//! - `SimDrive`: one closed loop (`sim::ClosedLoop`), the core's protocol
//!   `Server` (the same request handling the firmware runs), and what the
//!   board's main task adds around them: `DriveAccess` on the controller
//!   between two steps, the parameter store (`store`: a file for the flash
//!   record), telemetry at the configured rate, the capture buffer.
//! - `serve`: any number of clients at once, one of them in control
//!   (`serve.rs`), frames read with `FrameReader`, the simulation paced
//!   (`Pace`).
//!
//! Capture and test signals are the core's (`Controller::capture_*`,
//! `start_test`, through `protocol::drive::on_controller` as on the board),
//! with a capture store of the board's size.

pub mod serve;
pub mod store;

use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{commissioned_control, ClosedLoop};
use anyhow::{anyhow, Result};
use servo_core::controller::ApplyError;
use servo_core::params::{record, ValidatedParams};
use servo_core::protocol::drive::{on_controller, CaptureReply, DriveAccess, DriveStatus, ParamStore};
use servo_core::protocol::server::{Identity, Server};
use servo_core::protocol::{self, CaptureRequest, DriveFrame, Error, Reply, Request, RequestFrame, TelemetryFrame, TestSignal};
use servo_core::{Command, CommandError, CommandOutcome, ControlParams};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// How simulated time relates to the wall clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Pace {
    /// Simulated time follows the wall clock (as a board would).
    Realtime,
    /// As fast as the host computes while a client is connected; while a
    /// stream is live, exactly one stream period per stream frame
    /// (deterministic whatever the host's scheduling); with no client, the
    /// wall clock (start-up and moves go on between two tool commands).
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
    /// Every position period's state, for benchmarks (`TraceRow`).
    pub trace: Option<Trace>,
}

/// A drive's state at one position-loop period (benchmarks read it).
#[derive(Clone, Copy, Debug)]
pub struct TraceRow {
    pub time_s: f64,
    pub position_reference_m: f32,
    /// The reference plus the observer's and any external shift.
    pub position_command_m: f32,
    pub motor_position_m: f32,
    pub speed_reference_rad_s: f32,
    pub current_q_a: f32,
    /// Motor speed as rod speed, m/s.
    pub speed_m_s: f32,
    pub faults: u32,
    pub mode: servo_core::Mode,
    /// A stream point accepted in this period: its position.
    pub stream_point_m: Option<f32>,
}

pub type Trace = Arc<Mutex<Vec<TraceRow>>>;

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
            trace: None,
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
    fn temperatures(&self) -> (f32, Option<f32>) {
        (self.cl.controller.thermal_level(), self.cl.controller.power_stage_temperature_c())
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
    fn observer_weights(&self) -> &'static servo_core::observer::block::Weights {
        self.cl.controller.observer_weights()
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
    identity: Identity,
    defaults: ValidatedParams,
    pending_point_m: Option<f32>,
    boot_record: servo_core::protocol::BootRecord,
}

impl SimDrive {
    /// Starts like a board: the saved record, if there is a usable one,
    /// replaces the image's defaults (the rig file's `[control]`).
    pub fn new(opts: DriveOptions) -> Result<Self> {
        let mut store = store::FileStore::new(opts.store.clone());
        let rig = &opts.rig;
        let mut plant = Plant::new(rig.plant.clone(), opts.seed);
        let x0 = opts.initial_position_m;
        plant.set_initial_state((x0 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), 90f64.to_radians());
        // Powered up as a board is: brake closed, bridge off.
        plant.engage_brake();
        // The image's defaults; commissioned: offset and reference known.
        let defaults = if opts.commissioned { commissioned_control(rig.control, &plant) } else { rig.control };
        let defaults = ValidatedParams::new(defaults).map_err(|e| anyhow!("control parameters: {e}"))?;
        use servo_core::protocol::{BootRecord, RecordRejection};
        let mut boot_weights = None;
        let (mut params, boot_note, boot_record) = match store.read() {
            Ok(Some(bytes)) => match record::decode_record(&bytes) {
                Ok(d) => {
                    let mut note = "saved record loaded".to_string();
                    match d.observer.map(|s| s.weights) {
                        None => {}
                        Some(Ok(_)) => match store.stored_observer() {
                            Ok(w) => {
                                boot_weights = w;
                                note.push_str(" with its observer weights");
                            }
                            Err(e) => note.push_str(&format!("; observer weights not used ({e}): compiled weights")),
                        },
                        Some(Err(e)) => note.push_str(&format!(
                            "; observer weights refused ({}: {}): compiled weights",
                            e.part.name(),
                            e.reason.text()
                        )),
                    }
                    (*d.params.get(), note, BootRecord::Loaded)
                }
                Err(e) => (*defaults.get(), format!("saved record not used ({}); image defaults", e.reason()), BootRecord::of_error(&e)),
            },
            Ok(None) => (*defaults.get(), "no saved record; image defaults".to_string(), BootRecord::NoRecord),
            Err(e) => (
                *defaults.get(),
                format!("store: {e}; image defaults"),
                BootRecord::Rejected { why: RecordRejection::Storage, leaf: u16::MAX },
            ),
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
        if let Some(w) = boot_weights {
            cl.controller.command(Command::SetObserverWeights { weights: w }).map_err(|e| anyhow!("observer weights: {e:?}"))?;
        }
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
        let server = Self::server_of(identity, defaults, boot_record, &opts);
        Ok(Self {
            cl,
            opts,
            server,
            store,
            telemetry_next: 0,
            divider,
            stream_live: false,
            boot_note,
            identity,
            defaults,
            pending_point_m: None,
            boot_record,
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

    /// A protocol server of this drive (one per client: each has its own
    /// telemetry and stream state).
    pub fn new_server(&self) -> Server {
        Self::server_of(self.identity, self.defaults, self.boot_record, &self.opts)
    }

    fn server_of(identity: Identity, defaults: ValidatedParams, boot: servo_core::protocol::BootRecord, opts: &DriveOptions) -> Server {
        let mut s = Server::new(identity, defaults);
        s.set_boot_record(boot);
        if opts.pace == Pace::Fast {
            // Lock-step: one frame, one stream period of drive time.
            s.set_stream_period_s(opts.stream_period_s as f32);
        }
        s
    }

    pub fn divider(&self) -> u64 {
        self.divider
    }

    pub fn options(&self) -> &DriveOptions {
        &self.opts
    }

    pub fn set_stream_live(&mut self, live: bool) {
        self.stream_live = live;
    }

    /// One PWM period; a telemetry frame of the in-process server if one
    /// is due.
    pub fn step(&mut self) -> Option<TelemetryFrame> {
        self.cl.step();
        if self.cl.periods().is_multiple_of(self.divider) {
            self.record_trace();
        }
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

    fn record_trace(&mut self) {
        let Some(trace) = &self.opts.trace else { return };
        let t = self.cl.controller.telemetry();
        let row = TraceRow {
            time_s: self.cl.time_s(),
            position_reference_m: t.position_reference_m,
            position_command_m: t.position_command_m,
            motor_position_m: t.motor_position_m,
            speed_reference_rad_s: t.speed_reference_rad_s,
            current_q_a: t.current_q_a,
            speed_m_s: t.speed_rad_s * self.cl.controller.params().metres_per_rad(),
            faults: t.faults.bits(),
            mode: t.mode,
            stream_point_m: self.pending_point_m.take(),
        };
        if let Ok(mut v) = trace.lock() {
            v.push(row);
        }
    }

    /// Handles one request through the core's server; `None`: no reply (an
    /// accepted stream point).
    pub fn handle(&mut self, frame: &RequestFrame) -> Option<DriveFrame> {
        let was_on = self.server.telemetry_rate_hz() > 0;
        let mut server = std::mem::replace(&mut self.server, Server::new(self.identity, self.defaults));
        let out = self.handle_with(&mut server, frame);
        self.server = server;
        if !was_on && self.server.telemetry_rate_hz() > 0 {
            self.telemetry_next = self.cl.periods();
        }
        out
    }

    /// Handles one request through `server` (a client's).
    pub fn handle_with(&mut self, server: &mut Server, frame: &RequestFrame) -> Option<DriveFrame> {
        let mut access = Access { cl: &mut self.cl, rating: self.opts.rig.plant.inverter.rating() };
        let out = server.handle(frame, &mut access, &mut self.store);
        match &frame.request {
            Request::Stream(p) if out.is_none() => {
                self.stream_live = true;
                self.pending_point_m = Some(p.position_m);
            }
            Request::Stream(_) => {}
            r if is_read_only(r) => {}
            _ => self.stream_live = false,
        }
        out
    }

    /// A reply to a frame that did not decode.
    pub fn frame_error(e: protocol::FrameError) -> DriveFrame {
        DriveFrame::Reply { seq: 0, reply: Reply::Error(Error::Frame(e)) }
    }
}

pub use serve::{serve, spawn_local, StopFlag};

/// Requests that change nothing on the drive: any client may send them,
/// also while another one controls it.
pub fn is_read_only(r: &Request) -> bool {
    use servo_core::protocol::CaptureRequest as C;
    matches!(
        r,
        Request::Info
            | Request::Status
            | Request::ParamCount
            | Request::ParamGet { .. }
            | Request::Telemetry { .. }
            | Request::Capture(C::Status | C::Read { .. })
            | Request::Observer(servo_core::protocol::ObserverRequest::Status)
    )
}
