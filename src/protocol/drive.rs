//! What the protocol server needs from whoever owns a transport: the drive
//! ([`DriveAccess`]) and somewhere to keep the parameters ([`ParamStore`]).
//!
//! The firmware implements `DriveAccess` over its lock-free link to the PWM
//! interrupt (`board/link.rs`, `mailbox.rs`): snapshots come from the
//! triple buffer the ISR publishes, commands and parameter sets go through
//! the mailbox and the ISR applies them before its next step. The simulator
//! implements it directly on a `Controller` between two steps.

use heapless::Vec;

use super::messages::{Text, CAPTURE_CHUNK_MAX};
use crate::capture::{CaptureRequest, CaptureStatus};
use crate::test_signals::TestSignal;
use crate::reason::Reason;
use crate::controller::{ApplyError, Command, CommandError, CommandOutcome};
use crate::observer::block::{Staging, Weights};
use crate::params::{ControlParams, ValidatedParams};
use crate::telemetry::Telemetry;

/// A snapshot of the drive for `Status`, `Info` and the stream checks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveStatus {
    /// The last telemetry record (cut every position period): mode,
    /// faults, readiness, the drive clock `time_s`, positions.
    pub telemetry: Telemetry,
    /// A test signal (`Request::Test`) is running.
    pub test_running: bool,
}

/// A capture request's answer, as the controller side gives it.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum CaptureReply {
    /// Done (configured, triggered).
    Ok,
    Status(CaptureStatus),
    /// `count` samples of one signal from sample `start` (at most
    /// [`CAPTURE_CHUNK_MAX`]).
    Data { signal: u8, start: u16, values: Vec<f32, CAPTURE_CHUNK_MAX> },
}

/// The drive as a transport's owner offers it to the server.
///
/// Every method returns at once (no waiting for a period): the server runs
/// in thread context, between the PWM interrupt's steps.
pub trait DriveAccess {
    /// The latest snapshot. On the board it may lag the ISR by one
    /// position period; the server's checks allow for that.
    fn status(&self) -> DriveStatus;

    /// Temperatures for `Status`: the I²t model's normalised winding
    /// level (NaN if not known) and the power stage's, if measured.
    fn temperatures(&self) -> (f32, Option<f32>) {
        (f32::NAN, None)
    }

    /// The parameters the controller runs with now, including what it
    /// measured itself (`encoder.electrical_offset_rad` after commutation):
    /// a `ParamSet` is staged on this copy, so a stale one would undo a
    /// measurement.
    fn params(&self) -> ControlParams;

    /// `Controller::command`, with its answer. On the board: through the
    /// mailbox, the ISR's answer awaited (it comes within one period).
    fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError>;

    /// `Controller::apply_params`: the whole validated set applied between
    /// two periods, or refused whole (a field that needs the bridge off
    /// while it is on). Never partially.
    fn apply_params(&mut self, params: &ValidatedParams) -> Result<(), ApplyError>;

    /// A capture request (`CaptureRequest`), passed to the controller's
    /// capture buffer. Contract for the implementer:
    /// - `Configure` arms a capture with these signals, decimation, length,
    ///   pre-trigger and trigger, replacing any earlier one (`Ok`), or is
    ///   refused whole with the reason (`Err`): too many samples for the
    ///   buffer, a capture running, …;
    /// - `Trigger` fires an armed `Command` trigger (`Ok`), else `Err`;
    /// - `Status` answers `CaptureReply::Status`;
    /// - `Read` answers `CaptureReply::Data` with at most `count` samples
    ///   (≤ [`CAPTURE_CHUNK_MAX`]) from `start`, or `Err` when there is no
    ///   finished record or the range lies outside it.
    ///
    /// The server checks the request's shape first (non-empty signals,
    /// decimation ≥ 1, pre-trigger ≤ samples, `count` ≤ chunk).
    fn capture(&mut self, request: &CaptureRequest) -> Result<CaptureReply, Reason>;

    /// Starts a test signal generated in the core (exact timing). `Ok` once
    /// it runs; `Err` with the reason when refused (wrong mode, not
    /// enabled, amplitude beyond a limit, another test running). The server
    /// checks first that every number is finite and durations and
    /// frequencies are positive.
    fn test_signal(&mut self, signal: &TestSignal) -> Result<(), Reason>;

    /// The weights the observer runs (`Controller::observer_weights`).
    fn observer_weights(&self) -> &'static Weights;
}

/// Where the parameter record lives: flash on the board (two pages used in
/// turn, `board::b_g431b_esc1::comms::FlashStore`; the server refuses
/// `Save`/`Load` with the bridge on, because a flash erase stalls the
/// instruction fetch of the PWM interrupt), a file in the simulator.
pub trait ParamStore {
    /// Stores `record` (see `params::record`), replacing the previous one.
    fn save(&mut self, record: &[u8]) -> Result<(), Text>;

    /// Reads the stored record into `buf`; its length, 0 when nothing is
    /// stored. A record longer than `buf` is an error.
    fn load(&mut self, buf: &mut [u8]) -> Result<usize, Text>;

    /// Where an observer block is gathered while it is uploaded (one
    /// buffer beside the store); `None`: this store takes no weights.
    fn observer_staging(&mut self) -> Option<&mut Staging> {
        None
    }

    /// The observer weights of the record just saved or loaded, where the
    /// controller may run them from for as long as that record is stored
    /// (in place in flash on the board; a copy in the simulator). `None`:
    /// the record holds none, or this store cannot give them.
    fn stored_observer(&mut self) -> Result<Option<&'static Weights>, Text> {
        Ok(None)
    }
}

/// One chunk of a done capture as a reply: at most [`CAPTURE_CHUNK_MAX`]
/// values of `signal` from sample `start`, read by `read` (the controller's
/// capture, or the board's store straight from thread mode): the one read
/// path of the simulated drive and the board.
pub fn read_chunk(
    signal: u8,
    start: u16,
    count: u8,
    read: impl FnOnce(&mut [f32]) -> Result<usize, Reason>,
) -> Result<CaptureReply, Reason> {
    let mut buf = [0.0f32; CAPTURE_CHUNK_MAX];
    let want = usize::from(count).min(CAPTURE_CHUNK_MAX);
    let n = read(buf.get_mut(..want).unwrap_or(&mut []))?;
    let values = Vec::from_slice(buf.get(..n).unwrap_or(&[])).map_err(|_| Reason::ChunkTooLong)?;
    Ok(CaptureReply::Data { signal, start, values })
}

/// The capture and test requests on a [`Controller`] that the caller owns
/// between two steps: the one mapping the simulator and the board's
/// interrupt-side request handler share, so both answer alike.
pub mod on_controller {
    use super::CaptureReply;
    use crate::controller::Controller;
    use crate::capture::CaptureRequest;
    use crate::test_signals::TestSignal;
    use crate::reason::Reason;

    pub fn capture(c: &mut Controller, request: &CaptureRequest) -> Result<CaptureReply, Reason> {
        match request {
            CaptureRequest::Configure(config) => c.capture_configure(config).map(|()| CaptureReply::Ok),
            CaptureRequest::Trigger => c.capture_trigger().map(|()| CaptureReply::Ok),
            CaptureRequest::Status => Ok(CaptureReply::Status(c.capture_status())),
            CaptureRequest::Read { signal, start, count } => {
                super::read_chunk(*signal, *start, *count, |out| c.capture_read(*signal, *start, out))
            }
        }
    }

    pub fn test_signal(c: &mut Controller, signal: &TestSignal) -> Result<(), Reason> {
        c.start_test(*signal)
    }
}
