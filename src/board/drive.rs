//! The protocol server's view of the drive on a board
//! ([`servo_core::protocol::DriveAccess`]), over the lock-free link to the
//! PWM interrupt (`link`): status from the interrupt's newest snapshot;
//! commands, parameter reads and whole parameter sets through the request
//! slot, each answered by the interrupt in the period that takes it
//! (thread mode spins for the answer, bounded, nothing masked).
//!
//! Board-independent: works on any [`ServoBoard`].

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicPtr, Ordering};

use servo_core::controller::ApplyError;
use servo_core::observer::block::{Weights, COMPILED};
use servo_core::params::ValidatedParams;
use servo_core::protocol::drive::read_chunk;
use servo_core::protocol::{CaptureReply, CaptureRequest, DriveAccess, DriveStatus, Reason, TestSignal};
use servo_core::{Command, CommandError, CommandOutcome, ControlParams, Mode, Readiness};

use super::link::{BulkIn, BulkOut, Reply, CAPTURE};
use super::ServoBoard;

/// Thread mode's copy of the controller's parameters, kept across
/// requests. Only thread mode changes the set (`apply_params`, which updates
/// the copy); the core changes it on its own only when a start-up step
/// completes (commutation measures `encoder.electrical_offset_rad`), which
/// shows as a change of readiness or mode in the snapshot. So the copy is
/// read back from the interrupt (`ReadParams`, a ≈ 600-byte copy in one
/// period) only when readiness or mode moved since it was taken: a stream
/// of setpoints at 1 kHz costs the interrupt no parameter copy at all.
pub struct ParamsCache {
    params: RefCell<ControlParams>,
    /// Readiness and mode when `params` was read; `None`: read again.
    stamp: Cell<Option<(Readiness, Mode)>>,
}

impl ParamsCache {
    pub fn new(params: ControlParams) -> Self {
        Self { params: RefCell::new(params), stamp: Cell::new(None) }
    }

    /// This drive's slot in the CAN setpoint frame (`control.stream.leg_index`).
    pub fn leg_index(&self) -> u32 {
        self.params.try_borrow().map_or(0, |p| p.stream.leg_index)
    }

    /// Whether this drive terminates the CAN bus (`control.stream.can_termination`).
    pub fn can_termination(&self) -> bool {
        self.params.try_borrow().is_ok_and(|p| p.stream.can_termination)
    }

    fn get(&self) -> ControlParams {
        self.params.try_borrow().map(|p| *p).unwrap_or(ControlParams::DEFAULT)
    }

    fn set(&self, params: ControlParams, stamp: Option<(Readiness, Mode)>) {
        if let Ok(mut p) = self.params.try_borrow_mut() {
            *p = params;
            self.stamp.set(stamp);
        }
    }
}

/// The observer weights the controller was last told to run (null: the
/// compiled ones). Set when the interrupt accepted the command.
static OBSERVER: AtomicPtr<Weights> = AtomicPtr::new(core::ptr::null_mut());

/// Records that the controller runs `w` (`Command::SetObserverWeights`
/// accepted, or given at power-up).
pub fn note_observer(w: &'static Weights) {
    OBSERVER.store(core::ptr::from_ref(w).cast_mut(), Ordering::Relaxed);
}

/// The drive as the server sees it, for the duration of one request.
pub struct BoardDrive<'a, B: ServoBoard> {
    board: RefCell<&'a mut B>,
    cache: &'a ParamsCache,
}

impl<'a, B: ServoBoard> BoardDrive<'a, B> {
    pub fn new(board: &'a mut B, cache: &'a ParamsCache) -> Self {
        Self { board: RefCell::new(board), cache }
    }
}

impl<B: ServoBoard> DriveAccess for BoardDrive<'_, B> {
    fn status(&self) -> DriveStatus {
        let Ok(mut board) = self.board.try_borrow_mut() else {
            return DriveStatus::default();
        };
        let snapshot = board.snapshot();
        match snapshot.drive() {
            Some((telemetry, _moving)) => DriveStatus { telemetry, test_running: snapshot.test_running },
            None => DriveStatus::default(),
        }
    }

    fn params(&self) -> ControlParams {
        if let Ok(mut board) = self.board.try_borrow_mut() {
            let stamp = board.snapshot().drive().map(|(t, _)| (t.readiness, t.mode));
            if stamp.is_none() || stamp != self.cache.stamp.get() {
                if let Ok(p) = board.read_params() {
                    self.cache.set(p, stamp);
                }
            }
        }
        self.cache.get()
    }

    fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
        match self.board.get_mut().call(super::link::Request::Drive(cmd)) {
            Ok(Reply::Drive(r)) => {
                if let (Ok(_), Command::SetObserverWeights { weights }) = (&r, cmd) {
                    note_observer(weights);
                }
                r
            }
            // No controller yet: it is installed once the current offsets
            // are measured.
            Ok(Reply::NoDrive) => Err(CommandError::NotCalibrated),
            // The interrupt did not answer in time (or answered something
            // else): the command did not act, or its outcome is unknown.
            _ => Err(CommandError::Busy),
        }
    }

    fn observer_weights(&self) -> &'static Weights {
        let p = OBSERVER.load(Ordering::Relaxed);
        // SAFETY: null or a `&'static Weights` stored by `note_observer`.
        unsafe { p.cast_const().as_ref() }.unwrap_or(&COMPILED)
    }

    fn apply_params(&mut self, params: &ValidatedParams) -> Result<(), ApplyError> {
        // At power-up a saved set is lowered to the board's ratings (and the
        // log says so); a set sent or loaded while running is refused
        // instead, naming the leaf: nothing is clamped behind the user.
        if let Some(leaf) = self.board.get_mut().rating().exceeded_by(params.get()) {
            return Err(ApplyError::BeyondHardware { leaf });
        }
        match self.board.get_mut().apply_params(params) {
            Ok(r) => {
                if r.is_ok() {
                    let stamp = self.cache.stamp.get();
                    self.cache.set(*params.get(), stamp);
                }
                r
            }
            Err(_) => Err(ApplyError::NoAnswer),
        }
    }

    fn capture(&mut self, request: &CaptureRequest) -> Result<CaptureReply, Reason> {
        // `Read` in thread mode, straight from the store: the layout of the
        // done capture comes from the interrupt (one request), the values
        // from `CAPTURE`, which the interrupt no longer writes once the
        // capture is done (until the next `Configure`, which only this
        // thread sends). No per-chunk decoding in the interrupt.
        if let CaptureRequest::Read { signal, start, count } = *request {
            return self.read_capture(signal, start, count);
        }
        match self.bulk(BulkIn::Capture(*request))? {
            BulkOut::Done => Ok(CaptureReply::Ok),
            BulkOut::CaptureStatus(s) => Ok(CaptureReply::Status(s)),
            _ => Err(Reason::NoAnswer),
        }
    }

    fn test_signal(&mut self, signal: &TestSignal) -> Result<(), Reason> {
        match self.bulk(BulkIn::Test(*signal))? {
            BulkOut::Done => Ok(()),
            _ => Err(Reason::NoAnswer),
        }
    }
}

impl<B: ServoBoard> BoardDrive<'_, B> {
    /// One request through the bulk slots; a refusal's reason, or the link's
    /// failure, as the error.
    #[inline(never)]
    fn bulk(&mut self, payload: BulkIn) -> Result<BulkOut, Reason> {
        match self.board.get_mut().bulk(payload) {
            Ok(BulkOut::Refused(why)) => Err(why),
            Ok(out) => Ok(out),
            Err(_) => Err(Reason::NoAnswer),
        }
    }

    #[inline(never)]
    fn read_capture(&mut self, signal: u8, start: u16, count: u8) -> Result<CaptureReply, Reason> {
        let BulkOut::CaptureLayout(layout) = self.bulk(BulkIn::CaptureLayout)? else {
            return Err(Reason::NoAnswer);
        };
        read_chunk(signal, start, count, |out| CAPTURE.read(&layout, signal, start, out))
    }
}
