//! The drive's side of the protocol: one request in, at most one reply out.
//!
//! Every request is checked whole before anything is applied, and a refusal
//! says what and why ([`Error`]); nothing is applied partially. Transports
//! (USART, FDCAN, the simulator's TCP) feed bytes to [`Server::receive`] or
//! whole frames to [`Server::handle_bytes`], send back what they return,
//! and send [`Server::telemetry_frame`] at [`Server::telemetry_rate_hz`].

// Replies are values on the stack, sized by the wire format; no boxing here.
#![allow(clippy::result_large_err)]


use core::borrow::Borrow;

use super::drive::{CaptureReply, DriveAccess, DriveStatus, ParamStore};
use super::frame::{decode, Feed, FrameReader};
use super::messages::*;
use super::params::PARAM_COUNT;
use crate::params::leaves::{self, LeafError};
use crate::capture::CaptureRequest;
use crate::params::Value;
use crate::motion::stream::step_disagreement_m;
use crate::reason::Reason;
use crate::test_signals::TestSignal;
use super::{PARAMS_SCHEMA_HASH, SCHEMA_HASH};
use crate::controller::{ApplyError, Command, CommandError};
use crate::params::{record, ControlParams, ParamError, ValidatedParams};
use crate::telemetry::{Mode, Telemetry};

/// Who the drive is, for `Info`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    pub firmware_version: &'static str,
    pub git_hash: &'static str,
    pub board: &'static str,
}

/// Position periods of slack on a stream point's jump bound: the drive
/// clock the server reads is cut at the position rate and may lag the ISR
/// by one period.
const STREAM_SLACK_PERIODS: f32 = 2.0;

/// The previous accepted stream point.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LastPoint {
    time_s: f32,
    position_m: f32,
    velocity_m_s: f32,
    /// `motion::stream::step_disagreement_m` after this point.
    disagreement_m: f32,
}

/// The protocol server: telemetry configuration and the stream's last
/// point are its only state. `P` holds the image defaults: the set itself,
/// or a `&'static` to it (the board's, in flash: the server then lives in
/// the main task's future without a 464-byte copy of it in RAM).
#[derive(Debug)]
pub struct Server<P = ValidatedParams> {
    identity: Identity,
    defaults: P,
    telemetry_fields: u32,
    telemetry_rate_hz: u16,
    last_point: Option<LastPoint>,
    boot_record: BootRecord,
    stream_period_s: f32,
}

/// `s` as reply text, cut at [`TEXT_MAX`] (on a character boundary).
pub fn text(s: &str) -> Text {
    // One copy of the bytes up to the cut (not a push per decoded
    // character: a third of the code).
    let mut end = s.len().min(TEXT_MAX);
    while !s.is_char_boundary(end) {
        end = end.saturating_sub(1);
    }
    let mut t = Text::new();
    let _ = t.push_str(s.get(..end).unwrap_or(""));
    t
}

/// A validation refusal: the field by its leaf index (the host shows its
/// path) and why.
fn invalid_param(e: ParamError) -> Error {
    Error::InvalidParam { index: e.leaf, reason: e.reason }
}

fn stream_error(reason: Reason) -> Error {
    Error::Stream { reason }
}

/// Why the controller refused a stream point, for `Error::Stream`.
fn stream_refusal(e: CommandError) -> Reason {
    match e {
        CommandError::Faulted(_) | CommandError::CauseStillPresent(_) => Reason::RefusedFaultsLatched,
        CommandError::NotRunning => Reason::RefusedNotRunning,
        CommandError::NotDisabled => Reason::RefusedNotDisabled,
        CommandError::Busy => Reason::RefusedMoveInProgress,
        CommandError::NotFinite => Reason::RefusedNotFinite,
        CommandError::OutOfRange => Reason::RefusedOutOfRange,
        CommandError::BusLow => Reason::RefusedBusLow,
        CommandError::NotCalibrated => Reason::RefusedNotCalibrated,
        CommandError::NotCommutated => Reason::RefusedNotCommutated,
        CommandError::NotHomed => Reason::RefusedNotHomed,
    }
}

fn bridge_off(status: &DriveStatus) -> bool {
    matches!(status.telemetry.mode, Mode::Disabled | Mode::Fault)
}

fn reply(seq: u16, reply: Reply) -> DriveFrame {
    DriveFrame::Reply { seq, reply }
}

impl<P: Borrow<ValidatedParams>> Server<P> {
    /// A server for a drive whose image defaults are `defaults` (what
    /// `Defaults` restores and a failed `Load` falls back to).
    pub const fn new(identity: Identity, defaults: P) -> Self {
        Self { identity, defaults, telemetry_fields: 0, telemetry_rate_hz: 0, last_point: None, boot_record: BootRecord::Unknown, stream_period_s: 0.0 }
    }

    /// What became of the saved record at power-up (`Info`, `Status`).
    pub fn set_boot_record(&mut self, b: BootRecord) {
        self.boot_record = b;
    }

    /// The stream period this drive expects (`Info`); 0: any.
    pub fn set_stream_period_s(&mut self, s: f32) {
        self.stream_period_s = s;
    }

    /// One byte from the transport: the reply when it completed a frame,
    /// `Error::Frame` (seq 0) when it ended a bad one.
    pub fn receive<D: DriveAccess, S: ParamStore>(&mut self, reader: &mut FrameReader, byte: u8, drive: &mut D, store: &mut S) -> Option<DriveFrame> {
        match reader.push(byte) {
            Feed::Pending => None,
            Feed::Frame(bytes) => self.handle_bytes(bytes, drive, store),
            Feed::Dropped(e) => Some(reply(0, Reply::Error(Error::Frame(e)))),
        }
    }

    /// One frame as [`FrameReader`] hands it out (COBS bytes, no
    /// delimiter; decoded in place): its reply, or `Error::Frame` with seq 0
    /// when it does not decode.
    pub fn handle_bytes<D: DriveAccess, S: ParamStore>(&mut self, frame: &mut [u8], drive: &mut D, store: &mut S) -> Option<DriveFrame> {
        match decode::<RequestFrame>(frame) {
            Ok(request) => self.handle(&request, drive, store),
            Err(e) => Some(reply(0, Reply::Error(Error::Frame(e)))),
        }
    }

    /// One decoded request: its reply, or `None` for an accepted
    /// `Request::Stream` (answered only when refused).
    pub fn handle<D: DriveAccess, S: ParamStore>(&mut self, frame: &RequestFrame, drive: &mut D, store: &mut S) -> Option<DriveFrame> {
        let seq = frame.seq;
        let out = match &frame.request {
            Request::Stream(point) => match self.stream(point, drive) {
                Ok(()) => return None,
                Err(e) => Err(e),
            },
            Request::Info => Ok(self.info(drive)),
            Request::Status => Ok(self.status(drive)),
            Request::ParamCount => Ok(Reply::ParamCount { count: u16::try_from(PARAM_COUNT).unwrap_or(u16::MAX) }),
            Request::ParamGet { index } => leaves::get(&drive.params(), usize::from(*index))
                .map(|value| Reply::Param { index: *index, value })
                .ok_or(Error::UnknownParam { index: *index }),
            Request::ParamSet { index, value } => Self::param_set(*index, *value, drive),
            Request::Save => Self::save(drive, store),
            Request::Load => self.load(drive, store),
            Request::Defaults => self.defaults(drive),
            Request::Command(c) => self.command(*c, drive),
            Request::Telemetry { fields, rate_hz } => self.configure_telemetry(*fields, *rate_hz, drive),
            Request::Capture(c) => Self::capture(c, drive),
            Request::Test(t) => Self::test(t, drive),
            Request::Observer(o) => super::observer::handle(o, drive, store),
        };
        Some(reply(seq, out.unwrap_or_else(Reply::Error)))
    }

    fn info<D: DriveAccess>(&self, drive: &D) -> Reply {
        let t = drive.status().telemetry;
        Reply::Info(Info {
            firmware_version: text(self.identity.firmware_version),
            git_hash: text(self.identity.git_hash),
            schema_hash: SCHEMA_HASH,
            params_schema_hash: PARAMS_SCHEMA_HASH,
            board: text(self.identity.board),
            mode: t.mode,
            faults: t.faults.bits(),
            pwm_frequency_hz: drive.params().rates.pwm_frequency_hz,
            boot_record: self.boot_record,
            stream_period_s: self.stream_period_s,
            protocol_version: super::PROTOCOL_VERSION,
        })
    }

    fn status<D: DriveAccess>(&self, drive: &D) -> Reply {
        let s = drive.status();
        let t = s.telemetry;
        let (winding_thermal_level, power_stage_temperature_c) = drive.temperatures();
        Reply::Status(Status {
            mode: t.mode,
            faults: t.faults.bits(),
            readiness: t.readiness.bits(),
            time_s: t.time_s,
            test_running: s.test_running,
            position_m: t.motor_position_m,
            speed_rad_s: t.speed_rad_s,
            current_d_a: t.current_d_a,
            current_q_a: t.current_q_a,
            bus_voltage_v: t.bus_voltage_v,
            winding_thermal_level,
            power_stage_temperature_c,
            boot_record: self.boot_record,
        })
    }

    /// Staged on a copy, validated whole, then applied: nothing partial.
    fn param_set<D: DriveAccess>(index: u16, value: Value, drive: &mut D) -> Result<Reply, Error> {
        let present = drive.params();
        let mut staged = present;
        let i = usize::from(index);
        if let (Value::F32(v), Some(_)) = (value, leaves::leaf(i)) {
            if !v.is_finite() {
                return Err(Error::InvalidParam { index, reason: Reason::MustBeFinite });
            }
        }
        leaves::set(&mut staged, i, value).map_err(|e| match e {
            LeafError::Unknown => Error::UnknownParam { index },
            LeafError::WrongType(expected) => Error::WrongType { index, expected },
            LeafError::NoSuchVariant => Error::InvalidParam { index, reason: Reason::NoSuchVariant },
        })?;
        let validated = ValidatedParams::new(staged).map_err(invalid_param)?;
        // Uploaded weights were checked against the force input they run
        // on; another input would feed them a force they never saw.
        let force_changes = present.compensation.force_from_estimate != staged.compensation.force_from_estimate;
        if force_changes && !crate::protocol::observer::is_compiled(drive.observer_weights()) {
            return Err(Error::InvalidParam { index, reason: Reason::ObserverWeightsForOtherForce });
        }
        if !bridge_off(&drive.status()) && present.bridge_off_change(&staged).is_some() {
            return Err(Error::NeedsBridgeOff { index });
        }
        drive.apply_params(&validated).map_err(|e| match e {
            ApplyError::NeedsBridgeOff { .. } => Error::NeedsBridgeOff { index },
            ApplyError::NoAnswer => Error::Busy,
            ApplyError::BeyondHardware { leaf } => Error::InvalidParam { index: leaf, reason: Reason::BeyondHardwareRating },
        })?;
        let value = leaves::get(&staged, i).ok_or(Error::UnknownParam { index })?;
        Ok(Reply::Param { index, value })
    }

    fn save<D: DriveAccess, S: ParamStore>(drive: &mut D, store: &mut S) -> Result<Reply, Error> {
        if !bridge_off(&drive.status()) {
            return Err(Error::BridgeOn);
        }
        let weights = drive.observer_weights();
        let uploaded = !crate::protocol::observer::is_compiled(weights);
        super::observer::store_record(&drive.params(), uploaded.then_some(weights), drive, store)?;
        Ok(Reply::Ok)
    }

    /// The stored record if it is whole and of this schema, else the image
    /// defaults; the reply says which and why.
    fn load<D: DriveAccess, S: ParamStore>(&mut self, drive: &mut D, store: &mut S) -> Result<Reply, Error> {
        if !bridge_off(&drive.status()) {
            return Err(Error::BridgeOn);
        }
        let mut buf = [0u8; record::RECORD_MAX];
        // A record that cannot be used is refused and nothing changes: the
        // live set may hold unsaved gains.
        let n = store.load(&mut buf).map_err(|reason| Error::Storage { reason })?;
        let d = record::decode_record(buf.get(..n).unwrap_or(&[])).map_err(|e| match e {
            record::RecordError::Invalid(pe) => invalid_param(pe),
            e => Error::Storage { reason: text(e.reason()) },
        })?;
        self.apply_whole(d.params, drive)?;
        let note = super::observer::run_stored(d.observer, drive, store);
        Ok(Reply::Loaded { from_flash: true, note })
    }

    fn defaults<D: DriveAccess>(&mut self, drive: &mut D) -> Result<Reply, Error> {
        if !bridge_off(&drive.status()) {
            return Err(Error::BridgeOn);
        }
        self.apply_whole(*self.defaults.borrow(), drive)?;
        Ok(Reply::Ok)
    }

    /// A whole set (`Load`, `Defaults`). On an incremental encoder the
    /// electrical offset is a measurement of this power cycle, not a
    /// setting: the present one is kept, so a commutated drive stays so.
    fn apply_whole<D: DriveAccess>(&mut self, set: ValidatedParams, drive: &mut D) -> Result<(), Error> {
        let mut p: ControlParams = *set.get();
        if !p.startup.commutation_known {
            p.encoder.electrical_offset_rad = drive.params().encoder.electrical_offset_rad;
        }
        let set = ValidatedParams::new(p).map_err(invalid_param)?;
        self.last_point = None;
        drive.apply_params(&set).map_err(|e| match e {
            ApplyError::NeedsBridgeOff { leaf } => Error::NeedsBridgeOff { index: leaf },
            ApplyError::NoAnswer => Error::Busy,
            ApplyError::BeyondHardware { leaf } => Error::InvalidParam { index: leaf, reason: Reason::BeyondHardwareRating },
        })
    }

    fn command<D: DriveAccess>(&mut self, c: DriveCommand, drive: &mut D) -> Result<Reply, Error> {
        let cmd = match c {
            DriveCommand::Enable => Command::Enable,
            DriveCommand::Disable => Command::Disable,
            DriveCommand::Calibrate => Command::Calibrate,
            DriveCommand::Align => Command::Align,
            DriveCommand::Home => Command::Home,
            DriveCommand::StartUp => Command::StartUp,
            DriveCommand::MoveTo { position_m } => Command::MoveTo { position_m },
            DriveCommand::Jog { distance_m } => Command::Jog { distance_m },
            DriveCommand::SetHome { position_m } => Command::SetHome { position_m },
            DriveCommand::Stop => Command::Stop,
            DriveCommand::ClearFaults => Command::ClearFaults,
            DriveCommand::SetCompensation { enabled } => Command::SetCompensation { enabled },
            DriveCommand::SetPositionShift { shift_m } => Command::SetPositionShift { shift_m },
        };
        if !matches!(c, DriveCommand::SetCompensation { .. } | DriveCommand::SetPositionShift { .. }) {
            // Anything else ends (or never was part of) a stream.
            self.last_point = None;
        }
        drive.command(cmd).map(|o| Reply::Command(o.into())).map_err(Error::Command)
    }

    /// Checked against the limits and the previous point, then handed to
    /// `Command::Stream`.
    fn stream<D: DriveAccess>(&mut self, sp: &StreamPoint, drive: &mut D) -> Result<(), Error> {
        let p = drive.params();
        let t = drive.status().telemetry;
        if !sp.position_m.is_finite() {
            return Err(stream_error(Reason::PositionNotFinite));
        }
        if !sp.velocity_m_s.is_finite() {
            return Err(stream_error(Reason::VelocityNotFinite));
        }
        if sp.force_n.is_some_and(|f| !f.is_finite()) {
            return Err(stream_error(Reason::ForceNotFinite));
        }
        if sp.force_n.is_some_and(|f| f.abs() > p.thrust_peak_n()) {
            return Err(stream_error(Reason::ForceBeyondThrust));
        }
        if sp.position_m < p.limits.stroke_min_m {
            return Err(stream_error(Reason::BelowStrokeMin));
        }
        if sp.position_m > p.limits.stroke_max_m {
            return Err(stream_error(Reason::BeyondStrokeMax));
        }
        let v_max = p.trajectory.max_velocity_m_s;
        if sp.velocity_m_s.abs() > v_max {
            return Err(stream_error(Reason::BeyondMaxVelocity));
        }
        if !t.faults.is_empty() {
            // A latched fault (a lost stream's `stream_timeout` among them)
            // is why no point is taken: named before the gap or jump a
            // paused client's next points would otherwise be refused for.
            self.last_point = None;
            return Err(stream_error(Reason::RefusedFaultsLatched));
        }
        let period_max = p.stream.period_max_s;
        let (from_m, interval_s, disagreement_m) = match self.last_point {
            Some(last) => {
                let gap = t.time_s - last.time_s;
                if gap > p.stream.timeout_s {
                    self.last_point = None;
                    return Err(stream_error(Reason::StreamGap));
                }
                let window_s = p.stream.timeout_s;
                let mean_v = 0.5 * (sp.velocity_m_s + last.velocity_m_s);
                let d = step_disagreement_m(last.disagreement_m, sp.position_m - last.position_m, mean_v, gap, window_s);
                (last.position_m, crate::math::clamp(gap, 0.0, period_max), d)
            }
            // The first point is reached from the reference over the
            // longest interval; it has no step to agree with.
            None => (t.position_reference_m, period_max, 0.0),
        };
        let reach = v_max * (interval_s + STREAM_SLACK_PERIODS * p.position_period_s());
        if !((sp.position_m - from_m).abs() <= reach) {
            return Err(stream_error(Reason::StreamJump));
        }
        let measured_m_s = disagreement_m / p.stream.timeout_s;
        let bound_m_s = p.stream.velocity_mismatch_max_m_s;
        if !(measured_m_s.abs() <= bound_m_s) {
            // Not taken: the next point is checked against the last one
            // taken, and the stream, starved, decelerates to rest.
            let interval_s = self.last_point.map_or(0.0, |l| t.time_s - l.time_s);
            return Err(Error::StreamDisagrees { reason: Reason::VelocityDisagreesWithSteps, measured_m_s, bound_m_s, interval_s });
        }
        let cmd = Command::Stream { position_m: sp.position_m, velocity_m_s: sp.velocity_m_s, force_n: sp.force_n };
        match drive.command(cmd) {
            Ok(_) => {
                self.last_point = Some(LastPoint { time_s: t.time_s, position_m: sp.position_m, velocity_m_s: sp.velocity_m_s, disagreement_m });
                Ok(())
            }
            Err(e) => {
                self.last_point = None;
                Err(stream_error(stream_refusal(e)))
            }
        }
    }

    fn configure_telemetry<D: DriveAccess>(&mut self, fields: u32, rate_hz: u16, drive: &D) -> Result<Reply, Error> {
        if fields >> TelemetryField::COUNT != 0 {
            return Err(Error::Telemetry { reason: Reason::TelemetryFieldBits });
        }
        // PWM rate over the divider: exact for whole rates (1 / 0.001f32 is
        // 999.99994, which refused a 1 kHz request).
        let r = drive.params().rates;
        let position_rate_hz = r.pwm_frequency_hz / r.position_loop_divider as f32;
        if f32::from(rate_hz) > position_rate_hz {
            return Err(Error::Telemetry { reason: Reason::TelemetryRateTooHigh });
        }
        self.telemetry_fields = fields;
        self.telemetry_rate_hz = rate_hz;
        Ok(Reply::Ok)
    }

    fn capture<D: DriveAccess>(c: &CaptureRequest, drive: &mut D) -> Result<Reply, Error> {
        let refuse = |reason: Reason| Err(Error::Capture { reason });
        match c {
            CaptureRequest::Configure(cfg) => {
                if cfg.signals.is_empty() {
                    return refuse(Reason::NoSignals);
                }
                if cfg.decimation == 0 {
                    return refuse(Reason::DecimationMustBePositive);
                }
                if cfg.samples == 0 {
                    return refuse(Reason::SamplesMustBePositive);
                }
                if cfg.pre_trigger > cfg.samples {
                    return refuse(Reason::PreTriggerBeyondSamples);
                }
            }
            CaptureRequest::Read { count, .. } if usize::from(*count) > CAPTURE_CHUNK_MAX => {
                return refuse(Reason::CountBeyondChunk);
            }
            _ => {}
        }
        match drive.capture(c) {
            Ok(CaptureReply::Ok) => Ok(Reply::Ok),
            Ok(CaptureReply::Status(s)) => Ok(Reply::CaptureStatus(s)),
            Ok(CaptureReply::Data { signal, start, values }) => Ok(Reply::CaptureData { signal, start, values }),
            Err(reason) => Err(Error::Capture { reason }),
        }
    }

    fn test<D: DriveAccess>(t: &TestSignal, drive: &mut D) -> Result<Reply, Error> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        let ok = match *t {
            TestSignal::CurrentStep { amplitude_a, duration_s, .. } => amplitude_a.is_finite() && positive(duration_s),
            TestSignal::SpeedStep { amplitude_rad_s, duration_s } => amplitude_rad_s.is_finite() && positive(duration_s),
            TestSignal::PositionStep { distance_m, duration_s } => distance_m.is_finite() && positive(duration_s),
            TestSignal::Chirp { amplitude, start_hz, end_hz, duration_s, .. } => {
                amplitude.is_finite() && positive(start_hz) && positive(end_hz) && positive(duration_s)
            }
        };
        if !ok {
            return Err(Error::Test { reason: Reason::TestArguments });
        }
        drive.test_signal(t).map(|()| Reply::Ok).map_err(|reason| Error::Test { reason })
    }

    /// Telemetry fields (bit i = [`TelemetryField`] i); 0 when off.
    pub fn telemetry_fields(&self) -> u32 {
        self.telemetry_fields
    }

    /// How often the transport sends [`Server::telemetry_frame`]; 0: not.
    pub fn telemetry_rate_hz(&self) -> u16 {
        self.telemetry_rate_hz
    }

    /// The configured fields of `t`, in bit order. `Faults` carries the
    /// fault bits in the `f32`'s bit pattern (`f32::from_bits`: bit 28
    /// does not fit a float's mantissa); `Mode` and `Readiness` are small
    /// integers as floats; `TerminalPosition` is NaN without a scale.
    pub fn telemetry_frame(&self, t: &Telemetry) -> TelemetryFrame {
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
            f32::from_bits(t.faults.bits()),
            f32::from(t.readiness.bits()),
        ];
        let mut values = heapless::Vec::new();
        for (bit, v) in all.iter().enumerate() {
            if self.telemetry_fields & (1 << bit) != 0 && values.push(*v).is_err() {
                break;
            }
        }
        TelemetryFrame { time_s: t.time_s, fields: self.telemetry_fields, values }
    }
}
