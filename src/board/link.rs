//! How thread mode and the PWM interrupt talk: requests in, replies and
//! snapshots out, all through the lock-free mailbox of the control core
//! (`servo_core::mailbox`). Nothing here masks an interrupt, so thread mode
//! (the main task, the logger, embassy) can never delay the current loop.
//!
//! - **Requests** ([`Request`]) go in through a one-element slot. The
//!   interrupt drains it at the start of its period, acts, and puts the
//!   [`Reply`] in the reply slot in the same period. A request the interrupt
//!   has not taken when the caller gives up is withdrawn, so it never acts
//!   late; each request carries a sequence number that its reply echoes, so
//!   a reply that arrives after the caller gave up is recognised and dropped.
//! - **Snapshots** ([`Snapshot`]: board status, calibration progress, the
//!   drive's telemetry) come out through a triple buffer the interrupt
//!   publishes into every [`SNAPSHOT_EVERY_PERIODS`] periods and right after
//!   each request; thread mode reads the newest whole one whenever it likes.
//! - **The controller** is moved into the interrupt once, through a
//!   [`Handoff`]; from then on only the interrupt touches it.
//!
//! Board-independent: a board module's interrupt uses [`IsrLink`], `main`
//! and the on-board tests use [`ThreadLink`] (through the board's `Board`).

use cortex_m::peripheral::DWT;
use servo_core::mailbox::{Handoff, Slot, SlotReceiver, SlotSender, TripleBuffer, TripleReader, TripleWriter};
use servo_core::controller::ApplyError;
use servo_core::protocol::drive::on_controller;
use servo_core::capture::{CaptureLayout, CaptureStore};
use servo_core::params::ValidatedParams;
use servo_core::protocol::{CaptureReply, CaptureRequest, CaptureStatus, Reason, TestSignal};
use servo_core::{Command, CommandError, CommandOutcome, ControlParams, Controller, FaultSet, LimitFlags, Mode, Readiness, Telemetry};

use super::BoardStatus;

/// The interrupt publishes a snapshot every this many PWM periods (1 kHz at
/// 20 kHz): 20× the 50 Hz telemetry rate, so thread mode never reads one
/// older than 1 ms, while the copy (≈ 130 bytes) costs the interrupt only a
/// twentieth of its price per period.
pub const SNAPSHOT_EVERY_PERIODS: u32 = 20;

/// What thread mode asks of the interrupt.
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub enum Request {
    /// Start summing `samples` raw phase-current codes with the bridge off.
    BeginOffsetCalibration { samples: u32 },
    /// Convert with these zero-current codes from now on and run the drive
    /// (the controller, once installed, is stepped from the next period).
    UseOffsets { offset_codes: [f32; 3] },
    /// Clear the board's latched hardware overcurrent trip if no comparator
    /// is high any more.
    ClearHardwareTrip,
    /// A command for the drive (`Controller::command`).
    Drive(Command),
    /// Copy the controller's parameters into the parameter-out slot
    /// (≈ 600 bytes, only in the period that serves this request).
    ReadParams,
    /// Apply the set waiting in the parameter-in slot
    /// (`Controller::apply_params`, between two steps: the whole set or
    /// nothing).
    ApplyParams,
    /// Serve the capture or test-signal request waiting in the bulk-in slot
    /// ([`BulkIn::Capture`], [`BulkIn::Test`]); the answer goes to the
    /// bulk-out slot.
    Bulk,
}

/// The interrupt's answer to one [`Request`].
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub enum Reply {
    /// Board request done.
    Done,
    /// The request does not fit the interrupt's present state (e.g. offsets
    /// before a calibration finished): nothing changed.
    Refused,
    /// Whether the hardware trip is clear now.
    HardwareTrip { cleared: bool },
    /// The drive's answer.
    Drive(Result<CommandOutcome, CommandError>),
    /// No controller is installed yet: the command went nowhere.
    NoDrive,
    /// `ApplyParams`: the controller's answer.
    Applied(Result<(), ApplyError>),
    /// `Bulk`: the answer is in the bulk-out slot.
    Bulk,
}

/// What travels in the bulk-in slot (thread mode → interrupt): the large or
/// rare request payloads, kept out of [`Request`] so the request slot the
/// interrupt checks every period stays a few bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum BulkIn {
    /// A whole validated set for `ApplyParams`.
    Params(ValidatedParams),
    /// A capture request (`Request::Bulk`), the core's own type; thread
    /// mode serves `Read` from the store instead (see
    /// [`BulkIn::CaptureLayout`]).
    Capture(CaptureRequest),
    /// The layout of a done capture (`Controller::capture_layout`): thread
    /// mode then reads the store itself, the interrupt writes nothing to it
    /// until the next `Configure`.
    CaptureLayout,
    /// Start a test signal (`Request::Bulk`).
    Test(TestSignal),
}

/// What travels in the bulk-out slot (interrupt → thread mode).
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum BulkOut {
    /// `ReadParams`: the controller's set.
    Params(ControlParams),
    /// Configured, triggered, test started.
    Done,
    CaptureStatus(CaptureStatus),
    CaptureLayout(CaptureLayout),
    /// Refused, with the reason (a code: one byte across the slot).
    Refused(Reason),
}

/// A request or reply with the caller's sequence number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope<T> {
    pub seq: u32,
    pub body: T,
}

/// What the interrupt is doing with the samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, defmt::Format)]
pub enum IsrPhase {
    /// Bridge off, nothing converted (before the offset calibration, or
    /// after it failed).
    #[default]
    Idle,
    /// Bridge off, summing raw current codes.
    Calibrating,
    /// Converting and stepping the controller (bridge off until one is
    /// installed and asks for it).
    Running,
}

/// Progress of the current-offset calibration, as raw sums.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, defmt::Format)]
pub struct CalibrationSums {
    pub sum: [u32; 3],
    pub count: u32,
    pub target: u32,
}

/// What thread mode sees of the interrupt's side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// Publications so far (wraps).
    pub seq: u32,
    pub phase: IsrPhase,
    pub calibration: CalibrationSums,
    pub offset_codes: [f32; 3],
    pub status: BoardStatus,
    /// Whether a controller is installed: until then `drive_record` is
    /// not the drive's. Kept apart from the record (not an `Option`) so that
    /// [`Snapshot::INITIAL`] is all zero bytes and `SNAPSHOTS` lives in
    /// `.bss`: an `Option`'s `None` would be a non-zero niche value, and the
    /// three initial copies would then take 400 bytes of flash (`.data`).
    pub(crate) drive_installed: bool,
    /// The drive's telemetry and whether a move is in progress.
    pub(crate) drive_record: (Telemetry, bool),
    /// A test signal is running (`Controller::test_running`).
    pub test_running: bool,
}

impl Snapshot {
    pub const INITIAL: Self = Self {
        seq: 0,
        phase: IsrPhase::Idle,
        calibration: CalibrationSums { sum: [0; 3], count: 0, target: 0 },
        offset_codes: [0.0; 3],
        status: BoardStatus {
            bus_voltage_v: 0.0,
            temperature_c: 0.0,
            hw_overcurrent_armed: false,
            hw_overcurrent_tripped: false,
        },
        drive_installed: false,
        drive_record: (
            Telemetry {
                time_s: 0.0,
                mode: Mode::Disabled,
                position_reference_m: 0.0,
                position_command_m: 0.0,
                position_shift_m: 0.0,
                motor_position_m: 0.0,
                motor_angle_rad: 0.0,
                speed_reference_rad_s: 0.0,
                speed_rad_s: 0.0,
                current_d_a: 0.0,
                current_q_a: 0.0,
                current_q_reference_a: 0.0,
                voltage_d_v: 0.0,
                voltage_q_v: 0.0,
                bus_voltage_v: 0.0,
                terminal_position_m: None,
                load_force_estimate_n: 0.0,
                faults: FaultSet::NONE,
                limits: LimitFlags::NONE,
                readiness: Readiness::NONE,
            },
            false,
        ),
        test_running: false,
    };

    /// The drive's telemetry and whether a move is in progress; `None` until
    /// the controller is installed.
    pub fn drive(&self) -> Option<(Telemetry, bool)> {
        if self.drive_installed { Some(self.drive_record) } else { None }
    }
}

static REQUESTS: Slot<Envelope<Request>> = Slot::new();
static REPLIES: Slot<Envelope<Reply>> = Slot::new();
static SNAPSHOTS: TripleBuffer<Snapshot> = TripleBuffer::new(Snapshot::INITIAL);
/// Parameter sets, capture and test requests in and out: apart from
/// `REQUESTS` so that a request (and the interrupt's check for one, every
/// period) stays a few bytes, and the ≈ 460-byte copy happens only in the
/// period that needs it. One slot each way serves parameters, captures and
/// test signals (thread mode waits for one reply at a time).
static BULK_IN: Slot<BulkIn> = Slot::new();
static BULK_OUT: Slot<BulkOut> = Slot::new();
/// The capture store (8 KiB of `.bss`): the interrupt writes it through the
/// controller (`Controller::attach_capture_store`, before the controller is
/// installed); thread mode reads a done capture straight from it
/// (`BulkIn::CaptureLayout`), since the interrupt writes nothing to it once the
/// capture is done and until the next configure.
pub static CAPTURE: CaptureStore = CaptureStore::new();
/// The controller, moved into the interrupt once.
static CONTROLLER: Handoff<Controller> = Handoff::new();

/// The interrupt's ends of the link.
pub struct IsrLink {
    requests: SlotReceiver<'static, Envelope<Request>>,
    replies: SlotSender<'static, Envelope<Reply>>,
    snapshots: TripleWriter<'static, Snapshot>,
    bulk_in: SlotReceiver<'static, BulkIn>,
    bulk_out: SlotSender<'static, BulkOut>,
    controller: Option<&'static mut Controller>,
    published_seq: u32,
}

/// Thread mode's ends of the link.
pub struct ThreadLink {
    requests: SlotSender<'static, Envelope<Request>>,
    replies: SlotReceiver<'static, Envelope<Reply>>,
    snapshots: TripleReader<'static, Snapshot>,
    bulk_in: SlotSender<'static, BulkIn>,
    bulk_out: SlotReceiver<'static, BulkOut>,
    next_seq: u32,
}

/// Both ends, created once (`None` on a second call: the board is brought
/// up once per reset).
pub fn split() -> Option<(ThreadLink, IsrLink)> {
    let (req_tx, req_rx) = REQUESTS.split()?;
    let (rep_tx, rep_rx) = REPLIES.split()?;
    let (snap_w, snap_r) = SNAPSHOTS.split()?;
    let (pin_tx, pin_rx) = BULK_IN.split()?;
    let (pout_tx, pout_rx) = BULK_OUT.split()?;
    Some((
        ThreadLink { requests: req_tx, replies: rep_rx, snapshots: snap_r, bulk_in: pin_tx, bulk_out: pout_rx, next_seq: 0 },
        IsrLink {
            requests: req_rx,
            replies: rep_tx,
            snapshots: snap_w,
            bulk_in: pin_rx,
            bulk_out: pout_tx,
            controller: None,
            published_seq: 0,
        },
    ))
}

/// Moves the controller into the interrupt; it is stepped from the first
/// period after the interrupt picks it up. Gives it back if one was
/// installed already.
// Giving the controller back on refusal is the point (no allocator to box it).
#[allow(clippy::result_large_err)]
pub fn install_controller(controller: Controller) -> Result<(), Controller> {
    CONTROLLER.put(controller)
}

impl IsrLink {
    /// The next request, if thread mode posted one.
    #[inline(always)]
    pub fn take_request(&mut self) -> Option<Envelope<Request>> {
        self.requests.try_take()
    }

    /// Answers a request. Thread mode waits for at most one reply at a time,
    /// so the slot is free; if it is not (a stale reply nobody collected), the
    /// new one is dropped and the caller times out.
    #[inline(always)]
    pub fn reply(&mut self, seq: u32, body: Reply) {
        let _ = self.replies.try_put(Envelope { seq, body });
    }

    /// Serves `ReadParams` / `ApplyParams` / `Bulk` (called only for those
    /// requests: the copies cost nothing in other periods). `Bulk` goes
    /// through `servo_core::protocol::drive::on_controller`, the mapping the
    /// simulator uses too.
    #[inline(never)]
    pub fn serve_bulk(&mut self, request: Request) -> Reply {
        if self.controller().is_none() {
            // A payload nobody will serve.
            let _ = self.bulk_in.try_take();
            return Reply::NoDrive;
        }
        let Some(c) = self.controller.as_deref_mut() else { return Reply::NoDrive };
        let out = match (request, self.bulk_in.try_take()) {
            (Request::ReadParams, _) => BulkOut::Params(*c.params()),
            (Request::ApplyParams, Some(BulkIn::Params(p))) => return Reply::Applied(c.apply_params(&p)),
            (Request::Bulk, Some(BulkIn::Test(t))) => match on_controller::test_signal(c, &t) {
                Ok(()) => BulkOut::Done,
                Err(e) => BulkOut::Refused(e),
            },
            // The same mapping as the simulated drive's; thread mode sends
            // no `Read` (it reads the store), so no data comes back here.
            (Request::Bulk, Some(BulkIn::Capture(request))) => match on_controller::capture(c, &request) {
                Ok(CaptureReply::Ok) => BulkOut::Done,
                Ok(CaptureReply::Status(s)) => BulkOut::CaptureStatus(s),
                Ok(CaptureReply::Data { .. }) => BulkOut::Refused(Reason::NoAnswer),
                Err(e) => BulkOut::Refused(e),
            },
            (Request::Bulk, Some(BulkIn::CaptureLayout)) => c.capture_layout().map(BulkOut::CaptureLayout).unwrap_or_else(BulkOut::Refused),
            _ => return Reply::Refused,
        };
        // A stale answer nobody collected is replaced.
        let _ = self.bulk_out.try_withdraw();
        match self.bulk_out.try_put(out) {
            Ok(()) => Reply::Bulk,
            Err(_) => Reply::Refused,
        }
    }

    /// The controller, once installed (an atomic load per period until then).
    #[inline(always)]
    pub fn controller(&mut self) -> Option<&mut Controller> {
        if self.controller.is_none() {
            self.controller = CONTROLLER.claim();
        }
        self.controller.as_deref_mut()
    }

    /// Publishes a snapshot of the board's side; the drive's part (telemetry,
    /// move in progress) and the sequence number are added here.
    #[inline(always)]
    pub fn publish(&mut self, mut snapshot: Snapshot) {
        self.published_seq = self.published_seq.wrapping_add(1);
        snapshot.seq = self.published_seq;
        if let Some(c) = self.controller.as_deref() {
            snapshot.drive_installed = true;
            snapshot.drive_record = (c.telemetry(), c.move_in_progress());
            snapshot.test_running = c.test_running();
        }
        self.snapshots.publish(snapshot);
    }
}

/// Why a request got no answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum LinkError {
    /// The interrupt did not take the request in time (it is not running);
    /// the request was withdrawn and will never act.
    NotTaken,
    /// The interrupt took the request but no reply came in time: the
    /// request may have acted; its late reply is recognised and dropped.
    NoReply,
    /// The interrupt answered `Reply::Refused`: the request does not fit its
    /// present state (used by helpers that expect `Reply::Done`).
    Refused,
}

impl ThreadLink {
    /// Posts `request` and waits for its reply, at most `timeout_cycles` CPU
    /// cycles (DWT). The wait spins in thread mode with nothing masked: the
    /// interrupt answers within one PWM period, so this is ≈ 50 µs at most.
    pub fn call(&mut self, request: Request, timeout_cycles: u32) -> Result<Reply, LinkError> {
        let t0 = DWT::cycle_count();
        // Each spin takes more than one cycle, so counting spins bounds the
        // wait even if the DWT counter was never started.
        let mut spins: u32 = 0;
        let mut expired = || {
            spins = spins.saturating_add(1);
            spins > timeout_cycles || DWT::cycle_count().wrapping_sub(t0) > timeout_cycles
        };
        // Drop a stale reply left by an earlier call that timed out.
        let _ = self.replies.try_take();
        self.next_seq = self.next_seq.wrapping_add(1);
        let seq = self.next_seq;
        let mut envelope = Envelope { seq, body: request };
        loop {
            match self.requests.try_put(envelope) {
                Ok(()) => break,
                Err(back) if !expired() => envelope = back,
                Err(_) => return Err(LinkError::NotTaken),
            }
        }
        loop {
            match self.replies.try_take() {
                Some(reply) if reply.seq == seq => return Ok(reply.body),
                Some(_) => {}
                None if expired() => {
                    // Take the request back if the interrupt has not started
                    // on it: a command that timed out must not act later.
                    return Err(match self.requests.try_withdraw() {
                        Some(_) => LinkError::NotTaken,
                        None => LinkError::NoReply,
                    });
                }
                None => core::hint::spin_loop(),
            }
        }
    }

    /// The controller's parameters as it runs them now (`ReadParams`).
    pub fn read_params(&mut self, timeout_cycles: u32) -> Result<ControlParams, LinkError> {
        match self.exchange(Request::ReadParams, None, timeout_cycles)? {
            BulkOut::Params(p) => Ok(p),
            _ => Err(LinkError::Refused),
        }
    }

    /// Hands `params` to the interrupt, which applies them between two
    /// steps (`ApplyParams`); the controller's answer.
    pub fn apply_params(&mut self, params: &ValidatedParams, timeout_cycles: u32) -> Result<Result<(), ApplyError>, LinkError> {
        match self.post_bulk(Request::ApplyParams, Some(BulkIn::Params(*params)), timeout_cycles)? {
            Reply::Applied(r) => Ok(r),
            _ => Err(LinkError::Refused),
        }
    }

    /// Hands `payload` to the interrupt (`Request::Bulk`) and returns what it
    /// put in the bulk-out slot.
    pub fn bulk(&mut self, payload: BulkIn, timeout_cycles: u32) -> Result<BulkOut, LinkError> {
        self.exchange(Request::Bulk, Some(payload), timeout_cycles)
    }

    fn exchange(&mut self, request: Request, payload: Option<BulkIn>, timeout_cycles: u32) -> Result<BulkOut, LinkError> {
        // An answer left by a call that timed out.
        let _ = self.bulk_out.try_take();
        match self.post_bulk(request, payload, timeout_cycles)? {
            Reply::Bulk => self.bulk_out.try_take().ok_or(LinkError::NoReply),
            _ => Err(LinkError::Refused),
        }
    }

    #[inline(never)]
    fn post_bulk(&mut self, request: Request, payload: Option<BulkIn>, timeout_cycles: u32) -> Result<Reply, LinkError> {
        // A payload left by a call that timed out before the interrupt took it.
        let _ = self.bulk_in.try_withdraw();
        if let Some(p) = payload {
            if self.bulk_in.try_put(p).is_err() {
                return Err(LinkError::NotTaken);
            }
        }
        let result = self.call(request, timeout_cycles);
        // Not taken: take the payload back, so it never acts late.
        let _ = self.bulk_in.try_withdraw();
        result
    }

    /// The newest snapshot the interrupt published.
    pub fn snapshot(&mut self) -> Snapshot {
        self.snapshots.read()
    }
}
