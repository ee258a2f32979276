//! The messages of the drive protocol: what a host may ask, what the drive
//! answers. One definition for the firmware, the simulated drive and the
//! host tool; the schema hash in [`super::SCHEMA_HASH`] changes with any of
//! these types, so two ends built from different definitions refuse each
//! other at `Info` instead of misreading fields.
//!
//! Units are SI and in the field names, as everywhere in the core.

use heapless::{String, Vec};
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use crate::controller::{CommandError, CommandOutcome};
use crate::capture::{CaptureRequest, CaptureStatus};
use crate::observer::block::{BlockError, CHUNK_WORDS};
use crate::params::value::{Value, ValueKind};
use crate::reason::Reason;
use crate::test_signals::TestSignal;
use crate::telemetry::Mode;

/// Longest dotted parameter path
/// (`control.drive_train.friction_feedforward_speed_rad_s` is 52; checked
/// at compile time in `params.rs`).
pub const PATH_MAX: usize = 64;
/// Longest free text in a reply (a version string, a storage error's
/// reason; refusals carry a [`Reason`] code).
pub const TEXT_MAX: usize = 96;
/// Samples per `CaptureData` reply (per signal row-major chunk), chosen so a
/// reply stays under [`super::FRAME_MAX`] bytes.
pub const CAPTURE_CHUNK_MAX: usize = 64;
/// Values one telemetry frame carries at most.
pub const TELEMETRY_VALUES_MAX: usize = 24;

pub type Path = String<PATH_MAX>;
pub type Text = String<TEXT_MAX>;

/// Host → drive. `seq` is echoed in the reply, so a host can match replies
/// to requests and see one that was lost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct RequestFrame {
    pub seq: u16,
    pub request: Request,
}

/// Drive → host: a reply to one request, or a frame the drive sends by
/// itself (telemetry at the configured rate).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
#[allow(clippy::large_enum_variant)]
pub enum DriveFrame {
    Reply { seq: u16, reply: Reply },
    Telemetry(TelemetryFrame),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Request {
    /// Who the drive is, and which schema it speaks. A host checks
    /// `schema_hash` before anything else.
    Info,
    /// Mode, faults, readiness and the drive clock.
    Status,
    /// Number of parameters (leaves of `control.*`).
    ParamCount,
    /// Parameter `index`: 0-based, the path order of `ControlParams`'s
    /// tree. The host resolves a dotted path (`control.speed_pi.kp`) to
    /// its index, and an index to its path and type, with its own copy of
    /// this crate (`protocol::params::index_of` and `name`) once `Info`
    /// showed the drive's `params_schema_hash` equal to its own: the drive
    /// holds no names (≈ 6 KB of the image).
    ParamGet { index: u16 },
    /// Validated as a whole set (the field named on refusal) and applied
    /// between periods; gains apply bumplessly while running, structure
    /// (rates, pole pairs, encoder) only with the bridge off.
    ParamSet { index: u16, value: Value },
    /// Write the present parameters to flash. Refused while the bridge is on.
    Save,
    /// Read the saved parameters from flash and apply them. Refused while the
    /// bridge is on.
    Load,
    /// Back to the image's defaults (flash untouched until `Save`).
    Defaults,
    Command(DriveCommand),
    /// One streamed setpoint. Answered only when refused (bandwidth: up to
    /// 1 kHz); the host sees refusals as `Reply::Error` with this frame's seq.
    Stream(StreamPoint),
    /// Telemetry: which fields (bit i = [`TelemetryField`] i) and how often.
    /// `rate_hz` 0 stops it.
    Telemetry { fields: u32, rate_hz: u16 },
    Capture(CaptureRequest),
    /// Start a test signal generated in the core (exact timing).
    Test(TestSignal),
    /// The observer's weights: read which run, upload a block, or go back
    /// to the compiled model.
    Observer(ObserverRequest),
}

/// The observer weight block (`observer::block`), uploaded in chunks:
/// `Begin`, `Write` in order from word 0, `Commit`. A refusal names the
/// part ([`Error::ObserverBlock`]) and the running weights stay.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum ObserverRequest {
    /// Which weights run ([`Reply::Observer`]).
    Status,
    /// Starts an upload (forgetting an unfinished one). Shape and
    /// structure hash are checked here.
    Begin { inputs: u16, hidden: u16, words: u16, structure_hash: [u8; 8] },
    /// Words `start..start + words.len()` of the block, in order (a chunk
    /// sent again is taken again).
    Write { start: u16, words: Vec<f32, CHUNK_WORDS> },
    /// Checks the whole block, stores it in flash with the present
    /// parameters (as `Save`) and runs it. Bridge off.
    Commit,
    /// Back to the compiled model, stored as such with the present
    /// parameters. Bridge off.
    UseCompiled,
}

/// Which observer weights run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ObserverSource {
    /// The model compiled into the image.
    Compiled,
    /// A block uploaded and stored in flash.
    Uploaded,
}

/// The running observer weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub struct ObserverStatus {
    pub source: ObserverSource,
    pub inputs: u16,
    pub hidden: u16,
    pub words: u16,
    pub structure_hash: [u8; 8],
    /// CRC-32 (ISO-HDLC) of the running words, `f32` little-endian in
    /// block order: a host compares it with its file's.
    pub words_crc: u32,
}

/// The drive's commands, as a host names them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum DriveCommand {
    Enable,
    Disable,
    /// Current-offset calibration.
    Calibrate,
    /// Commutation (electrical offset, direction, pole pairs).
    Align,
    Home,
    /// Every start-up step still missing, in order.
    StartUp,
    MoveTo { position_m: f32 },
    Jog { distance_m: f32 },
    SetHome { position_m: f32 },
    /// A controlled stop of a move or stream; the drive then holds.
    Stop,
    ClearFaults,
    SetCompensation { enabled: bool },
    SetPositionShift { shift_m: f32 },
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct StreamPoint {
    pub position_m: f32,
    pub velocity_m_s: f32,
    pub force_n: Option<f32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Reply {
    Info(Info),
    Status(Status),
    /// Done, nothing to report.
    Ok,
    /// A command was taken; the outcome says if it was bounded.
    Command(CommandReport),
    ParamCount { count: u16 },
    /// A parameter's value (after `ParamSet`: as applied).
    Param { index: u16, value: Value },
    /// `Load`: what was applied.
    Loaded { from_flash: bool, note: Text },
    CaptureStatus(CaptureStatus),
    CaptureData { signal: u8, start: u16, values: Vec<f32, CAPTURE_CHUNK_MAX> },
    Error(Error),
    /// The running observer weights (`Request::Observer`).
    Observer(ObserverStatus),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct Info {
    pub firmware_version: Text,
    pub git_hash: Text,
    pub schema_hash: [u8; 8],
    /// `PARAMS_SCHEMA_HASH`: the parameters' layout, hence their indices,
    /// paths and types. A host names parameters only when it is its own.
    pub params_schema_hash: [u8; 8],
    pub board: Text,
    pub mode: Mode,
    pub faults: u32,
    /// PWM (current-loop) rate, for interpreting captures.
    pub pwm_frequency_hz: f32,
    /// What became of the saved parameter record at power-up.
    pub boot_record: BootRecord,
    /// The stream period this drive expects, s; 0: any interval from the
    /// position-loop period up to `control.stream.period_max_s` (measured
    /// as the points arrive).
    pub stream_period_s: f32,
    /// [`PROTOCOL_VERSION`](super::PROTOCOL_VERSION), for humans and logs;
    /// compatibility is decided by `schema_hash`.
    pub protocol_version: u16,
}

/// What became of the saved parameter record at power-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum BootRecord {
    /// The transport's owner did not say.
    Unknown,
    /// No record stored: the image's defaults run.
    NoRecord,
    /// The record was loaded.
    Loaded,
    /// A record was found and refused: the image's defaults run. `leaf`:
    /// the failing parameter for `Invalid`, else `u16::MAX`.
    Rejected { why: RecordRejection, leaf: u16 },
}

/// Why a stored record was refused (`params::record::RecordError`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum RecordRejection {
    /// The store could not be read.
    Storage,
    TooShort,
    Magic,
    Crc,
    Schema,
    Length,
    Decode,
    /// Decoded, but the set does not validate (or asks beyond the board).
    Invalid,
    TooLarge,
    /// The observer section has another size than this firmware's block.
    ObserverLength,
}

impl BootRecord {
    /// A decode's outcome as a boot report.
    pub fn of_error(e: &crate::params::record::RecordError) -> Self {
        use crate::params::record::RecordError as E;
        let (why, leaf) = match e {
            E::Empty => return Self::NoRecord,
            E::TooShort => (RecordRejection::TooShort, u16::MAX),
            E::Magic => (RecordRejection::Magic, u16::MAX),
            E::Crc => (RecordRejection::Crc, u16::MAX),
            E::Schema => (RecordRejection::Schema, u16::MAX),
            E::Length => (RecordRejection::Length, u16::MAX),
            E::Decode => (RecordRejection::Decode, u16::MAX),
            E::Invalid(p) => (RecordRejection::Invalid, p.leaf),
            E::TooLarge => (RecordRejection::TooLarge, u16::MAX),
            E::ObserverLength => (RecordRejection::ObserverLength, u16::MAX),
        };
        Self::Rejected { why, leaf }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct Status {
    pub mode: Mode,
    pub faults: u32,
    /// `Readiness` bits: 1 calibrated, 2 commutated, 4 homed.
    pub readiness: u8,
    pub time_s: f32,
    pub test_running: bool,
    /// Motor-side position, m (the encoder's, on the rod's scale).
    pub position_m: f32,
    /// Motor speed, rad/s.
    pub speed_rad_s: f32,
    pub current_d_a: f32,
    pub current_q_a: f32,
    pub bus_voltage_v: f32,
    /// Winding temperature of the I²t model, normalised (1 = the
    /// continuous rating's); NaN if the drive does not say.
    pub winding_thermal_level: f32,
    /// Power-stage temperature, °C, if measured.
    pub power_stage_temperature_c: Option<f32>,
    pub boot_record: BootRecord,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum CommandReport {
    Accepted,
    ClampedToStroke { position_m: f32 },
}

impl From<CommandOutcome> for CommandReport {
    fn from(o: CommandOutcome) -> Self {
        match o {
            CommandOutcome::Accepted => Self::Accepted,
            CommandOutcome::ClampedToStroke { position_m } => Self::ClampedToStroke { position_m },
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct TelemetryFrame {
    pub time_s: f32,
    /// The `fields` mask of the `Telemetry` request; `values` in bit order.
    pub fields: u32,
    pub values: Vec<f32, TELEMETRY_VALUES_MAX>,
}

/// Why a request was refused. Nothing of it was applied.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Error {
    /// The frame could not be read (see [`FrameError`]); its seq is unknown,
    /// so the reply carries seq 0.
    Frame(FrameError),
    /// No parameter with this index.
    UnknownParam { index: u16 },
    /// The value has another type than the parameter.
    WrongType { index: u16, expected: ValueKind },
    /// The set would not validate: the field (its index; the host shows
    /// its path) and why (NaN, out of range…).
    InvalidParam { index: u16, reason: Reason },
    /// This parameter changes only with the bridge off.
    NeedsBridgeOff { index: u16 },
    /// The telemetry request asks for fields or a rate the drive has not.
    Telemetry { reason: Reason },
    /// Save or load refused while the bridge is on.
    BridgeOn,
    /// Flash storage failed, or held no usable record (what and why).
    Storage { reason: Text },
    /// The controller refused the command.
    Command(CommandError),
    /// A stream point beyond a limit, or a stream in the wrong state.
    Stream { reason: Reason },
    /// Capture or test request not possible now, or out of range.
    Capture { reason: Reason },
    Test { reason: Reason },
    /// The drive is busy with a request of this kind (e.g. a save running).
    Busy,
    /// Another client controls the drive: this one may only read (info,
    /// status, parameters, telemetry, capture status and data) until that
    /// one disconnects.
    ControlledByAnotherClient,
    /// An observer weight block refused: the part, the element, why.
    /// The running weights are unchanged.
    ObserverBlock(BlockError),
    /// Observer weights are not taken by this drive's store, or the store
    /// could not give back what it wrote.
    ObserverStore { reason: Text },
    /// A stream point whose figures disagree with the stream so far
    /// (`VelocityDisagreesWithSteps`): what was measured, the bound it
    /// passed (both m/s) and the interval since the previous point on the
    /// drive's clock, s.
    StreamDisagrees { reason: Reason, measured_m_s: f32, bound_m_s: f32, interval_s: f32 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum FrameError {
    /// Longer than [`super::FRAME_MAX`] before its delimiter.
    TooLong,
    /// Not valid COBS.
    Cobs,
    /// Shorter than the CRC.
    Truncated,
    /// CRC-32 mismatch.
    Crc,
    /// Valid CRC but not a message of this schema.
    Decode,
    /// Bytes left after the message.
    Trailing,
}

/// The telemetry fields, bit positions of `Request::Telemetry { fields }`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
#[repr(u8)]
pub enum TelemetryField {
    PositionReference = 0,
    PositionCommand,
    PositionShift,
    MotorPosition,
    SpeedReference,
    Speed,
    CurrentD,
    CurrentQ,
    CurrentQReference,
    VoltageD,
    VoltageQ,
    BusVoltage,
    TerminalPosition,
    LoadForceEstimate,
    Mode,
    Faults,
    Readiness,
}

impl TelemetryField {
    pub const COUNT: u32 = 17;
}
