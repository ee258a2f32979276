//! A mock drive and an in-memory store for the protocol tests.
#![allow(dead_code)]

use servo_core::controller::ApplyError;
use servo_core::params::ValidatedParams;
use servo_core::protocol::*;
use servo_core::{Command, CommandError, CommandOutcome, ControlParams, Mode, Readiness, Telemetry};

/// Keeps what a controller would: mode, readiness, parameters; records
/// every command and every applied set.
#[derive(Debug, Clone)]
pub struct MockDrive {
    pub params: ControlParams,
    pub mode: Mode,
    pub readiness: Readiness,
    pub time_s: f32,
    pub position_reference_m: f32,
    pub commands: Vec<Command>,
    pub applied: usize,
    /// The next command is refused with this.
    pub refuse: Option<CommandError>,
    pub captures: usize,
    pub tests: usize,
    /// A power stage's rating, checked with the core's check as a board's
    /// and the simulated drive's `DriveAccess` do: a set asking more is refused.
    pub rating: Option<servo_core::params::PowerStageRating>,
    /// The weights the observer runs (`Command::SetObserverWeights`).
    pub observer: &'static servo_core::observer::block::Weights,
}

impl MockDrive {
    pub fn new() -> Self {
        Self {
            params: ControlParams::DEFAULT,
            mode: Mode::Disabled,
            readiness: Readiness::ALL,
            time_s: 1.0,
            position_reference_m: 0.25,
            commands: vec![],
            applied: 0,
            refuse: None,
            captures: 0,
            tests: 0,
            rating: None,
            observer: &servo_core::observer::block::COMPILED,
        }
    }

    pub fn running() -> Self {
        let mut d = Self::new();
        d.mode = Mode::Running;
        d
    }
}

impl DriveAccess for MockDrive {
    fn status(&self) -> DriveStatus {
        let telemetry = Telemetry {
            time_s: self.time_s,
            mode: self.mode,
            readiness: self.readiness,
            position_reference_m: self.position_reference_m,
            ..Telemetry::default()
        };
        DriveStatus { telemetry, test_running: false }
    }

    fn params(&self) -> ControlParams {
        self.params
    }

    fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
        if let Some(e) = self.refuse.take() {
            return Err(e);
        }
        self.commands.push(cmd);
        match cmd {
            Command::Enable => self.mode = Mode::Running,
            Command::Disable => self.mode = Mode::Disabled,
            Command::Stream { position_m, .. } => self.position_reference_m = position_m,
            Command::SetObserverWeights { weights } => self.observer = weights,
            _ => {}
        }
        Ok(CommandOutcome::Accepted)
    }

    fn apply_params(&mut self, p: &ValidatedParams) -> Result<(), ApplyError> {
        if let Some(leaf) = self.rating.and_then(|r| r.exceeded_by(p.get())) {
            return Err(ApplyError::BeyondHardware { leaf });
        }
        if !matches!(self.mode, Mode::Disabled | Mode::Fault) {
            if let Some(field) = self.params.bridge_off_change(p.get()) {
                return Err(ApplyError::NeedsBridgeOff { leaf: field });
            }
        }
        self.params = *p.get();
        self.applied += 1;
        Ok(())
    }

    fn capture(&mut self, request: &CaptureRequest) -> Result<CaptureReply, servo_core::protocol::Reason> {
        self.captures += 1;
        match request {
            CaptureRequest::Read { signal, start, count } => {
                let values = heapless::Vec::from_iter((0..*count).map(f32::from));
                Ok(CaptureReply::Data { signal: *signal, start: *start, values })
            }
            _ => Ok(CaptureReply::Ok),
        }
    }

    fn test_signal(&mut self, _: &TestSignal) -> Result<(), servo_core::protocol::Reason> {
        self.tests += 1;
        Ok(())
    }

    fn observer_weights(&self) -> &'static servo_core::observer::block::Weights {
        self.observer
    }
}

/// A store in memory; `fail` makes every call fail.
#[derive(Debug, Clone, Default)]
pub struct MemStore {
    pub record: Vec<u8>,
    pub fail: bool,
    pub staging: servo_core::observer::block::Staging,
}

impl ParamStore for MemStore {
    fn save(&mut self, record: &[u8]) -> Result<(), Text> {
        if self.fail {
            return Err(server::text("flash write failed"));
        }
        self.record = record.to_vec();
        Ok(())
    }

    fn load(&mut self, buf: &mut [u8]) -> Result<usize, Text> {
        if self.fail {
            return Err(server::text("flash read failed"));
        }
        let n = self.record.len();
        buf.get_mut(..n).ok_or_else(|| server::text("record too long"))?.copy_from_slice(&self.record);
        Ok(n)
    }

    fn observer_staging(&mut self) -> Option<&mut servo_core::observer::block::Staging> {
        Some(&mut self.staging)
    }

    fn stored_observer(&mut self) -> Result<Option<&'static servo_core::observer::block::Weights>, Text> {
        let d = servo_core::params::record::decode_record(&self.record).map_err(|e| server::text(e.reason()))?;
        Ok(d.observer.and_then(|s| s.weights.ok()).map(|w| &*Box::leak(Box::new(w))))
    }
}

pub fn server() -> Server {
    let id = Identity { firmware_version: "0.1.0", git_hash: "test", board: "mock" };
    Server::new(id, ValidatedParams::new(ControlParams::DEFAULT).unwrap())
}

/// The reply to `request` (seq 1), through encode → FrameReader → decode.
pub fn ask(srv: &mut Server, drive: &mut MockDrive, store: &mut MemStore, request: Request) -> Option<Reply> {
    let mut buf = [0u8; FRAME_MAX];
    let bytes = encode(&RequestFrame { seq: 1, request }, &mut buf).expect("request fits").to_vec();
    let mut reader = FrameReader::new();
    let mut out = None;
    for b in bytes {
        if let Some(f) = srv.receive(&mut reader, b, drive, store) {
            assert!(out.is_none(), "one reply per request");
            out = Some(f);
        }
    }
    out.map(|f| match f {
        DriveFrame::Reply { seq, reply } => {
            assert_eq!(seq, 1);
            reply
        }
        DriveFrame::Telemetry(_) => panic!("telemetry as a reply"),
    })
}

/// The leaf index of `s`, as the host tool resolves it.
pub fn idx(s: &str) -> u16 {
    servo_core::protocol::params::index_of(s).unwrap() as u16
}

/// CRC-32 (ISO-HDLC), bit by bit: the record's and the frames' check,
/// written out independently of the `crc` crate the core uses.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}
