//! The host side of the drive protocol: a link (serial port or TCP), frames
//! in and out, requests matched to replies by `seq`, timeouts, and the
//! schema check at connect.

use anyhow::{anyhow, bail, Context, Result};
use servo_core::protocol::{
    self, DriveFrame, Error, Feed, FrameReader, Info, Reply, Request, RequestFrame, TelemetryFrame, FRAME_MAX,
    PARAMS_SCHEMA_HASH, SCHEMA_HASH,
};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

/// A byte link to a drive.
pub trait Link: Read + Write + Send {
    /// How long a read waits for bytes; zero: not at all (a look).
    fn set_read_wait(&mut self, wait: Duration) -> std::io::Result<()>;
}

impl Link for std::net::TcpStream {
    fn set_read_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        if wait.is_zero() {
            self.set_nonblocking(true)
        } else {
            self.set_nonblocking(false)?;
            self.set_read_timeout(Some(wait))
        }
    }
}

impl Link for Box<dyn serialport::SerialPort> {
    fn set_read_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        self.set_timeout(wait).map_err(std::io::Error::other)
    }
}

/// How long a read waits while a reply is awaited.
const READ_WAIT: Duration = Duration::from_millis(5);

/// Where the drive is.
#[derive(Clone, Debug)]
pub enum Endpoint {
    Serial { port: String, baud: u32 },
    Tcp(String),
}

impl Endpoint {
    pub fn open(&self) -> Result<Box<dyn Link>> {
        Ok(match self {
            Endpoint::Serial { port, baud } => Box::new(
                serialport::new(port, *baud)
                    .timeout(READ_WAIT)
                    .open()
                    .with_context(|| format!("opening serial port {port} at {baud} Bd; check the cable and the port name (ls /dev/ttyACM*)"))?,
            ),
            Endpoint::Tcp(addr) => {
                let s = std::net::TcpStream::connect(addr)
                    .with_context(|| format!("connecting to {addr}; is a drive serving there (`host-sim drive serve --listen {addr}`)?"))?;
                s.set_nodelay(true)?;
                s.set_read_timeout(Some(READ_WAIT))?;
                Box::new(s)
            }
        })
    }
}

/// A reply that arrived for no pending request: a refused stream point (its
/// seq), or a frame the drive could not read (seq 0).
#[derive(Clone, Debug)]
pub struct Unsolicited {
    pub seq: u16,
    pub error: Reply,
}

pub struct Client {
    link: Box<dyn Link>,
    reader: FrameReader,
    seq: u16,
    pub timeout: Duration,
    /// Telemetry frames received so far (drained by the caller).
    pub telemetry: VecDeque<TelemetryFrame>,
    pub unsolicited: Vec<Unsolicited>,
    pub info: Option<Info>,
    rx: Vec<u8>,
}

impl Client {
    /// Wraps a link without the schema check (tests of bad input).
    pub fn raw(link: Box<dyn Link>) -> Self {
        Self {
            link,
            reader: FrameReader::new(),
            seq: 0,
            timeout: Duration::from_secs(2),
            telemetry: VecDeque::new(),
            unsolicited: Vec::new(),
            info: None,
            rx: vec![0; 4096],
        }
    }

    /// Opens the link, asks `Info` and refuses a drive of another schema.
    pub fn connect(ep: &Endpoint) -> Result<Self> {
        let mut c = Self::raw(ep.open()?);
        // A board may hold half a frame from an earlier session: a lone
        // delimiter ends it.
        c.link.write_all(&[0])?;
        let info = match c.request(Request::Info)? {
            Reply::Info(i) => i,
            other => bail!("Info answered with {other:?}"),
        };
        check_schema(&info)?;
        c.info = Some(info);
        Ok(c)
    }

    /// Sends one request without waiting; returns its seq.
    pub fn send(&mut self, request: Request) -> Result<u16> {
        self.seq = self.seq.wrapping_add(1);
        if self.seq == 0 {
            self.seq = 1; // 0 is the drive's "unknown seq"
        }
        let mut buf = [0u8; FRAME_MAX];
        let frame = RequestFrame { seq: self.seq, request };
        let bytes = protocol::encode(&frame, &mut buf).ok_or_else(|| anyhow!("request too large: {frame:?}"))?;
        self.link.write_all(bytes)?;
        Ok(self.seq)
    }

    /// Writes raw bytes (tests of corrupted frames).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<()> {
        self.link.write_all(bytes)?;
        Ok(())
    }

    /// Reads what has arrived (waiting at most the link's read timeout);
    /// replies go to `on_reply`, telemetry to the queue.
    fn pump(&mut self, mut on_reply: impl FnMut(u16, Reply)) -> Result<()> {
        let n = match self.link.read(&mut self.rx) {
            Ok(0) => bail!("the drive closed the connection"),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted) => 0,
            Err(e) => return Err(e).context("reading from the drive"),
        };
        for i in 0..n {
            let b = self.rx[i];
            let frame: Result<DriveFrame, _> = match self.reader.push(b) {
                Feed::Pending => continue,
                Feed::Dropped(e) => Err(e),
                Feed::Frame(f) => protocol::decode(f),
            };
            match frame {
                Ok(DriveFrame::Telemetry(t)) => {
                    self.telemetry.push_back(t);
                }
                Ok(DriveFrame::Reply { seq, reply }) => on_reply(seq, reply),
                Err(e) => eprintln!("warning: dropped a frame from the drive: {e:?}"),
            }
        }
        Ok(())
    }

    /// Reads for up to `d`, collecting telemetry and unsolicited replies;
    /// `Duration::ZERO`: only what has arrived, without waiting.
    pub fn poll(&mut self, d: Duration) -> Result<()> {
        let t0 = Instant::now();
        let mut got = Vec::new();
        if d.is_zero() {
            self.link.set_read_wait(Duration::ZERO)?;
            let r = self.pump(|seq, reply| got.push(Unsolicited { seq, error: reply }));
            self.link.set_read_wait(READ_WAIT)?;
            r?;
        } else {
            loop {
                self.pump(|seq, reply| got.push(Unsolicited { seq, error: reply }))?;
                if t0.elapsed() >= d {
                    break;
                }
            }
        }
        self.unsolicited.extend(got);
        Ok(())
    }

    /// Sends `request` and waits for the reply with its seq.
    pub fn request(&mut self, request: Request) -> Result<Reply> {
        let what = format!("{request:?}");
        let seq = self.send(request)?;
        let t0 = Instant::now();
        let mut answer = None;
        let mut other = Vec::new();
        while answer.is_none() {
            if t0.elapsed() > self.timeout {
                self.unsolicited.extend(other);
                bail!(
                    "no reply to {what} (seq {seq}) within {:.1} s: the drive is not answering; check it is powered and the link (cable, --baud, --tcp address), then retry; `--timeout-s` waits longer",
                    self.timeout.as_secs_f64()
                );
            }
            self.pump(|s, r| if s == seq { answer = Some(r) } else { other.push(Unsolicited { seq: s, error: r }) })?;
        }
        self.unsolicited.extend(other);
        Ok(answer.expect("set"))
    }

    /// `request`, with `Reply::Error` turned into an error naming it.
    pub fn ask(&mut self, request: Request) -> Result<Reply> {
        let what = request_text(&request);
        match self.request(request)? {
            Reply::Error(e) => Err(anyhow!("{what}: refused: {}", describe(&e))),
            r => Ok(r),
        }
    }
}

pub fn check_schema(info: &Info) -> Result<()> {
    if info.schema_hash != SCHEMA_HASH {
        bail!(
            "schema mismatch: the drive ({}, firmware {} {}) speaks schema {}, this tool {}; build both from the same protocol definition",
            info.board,
            info.firmware_version,
            info.git_hash,
            hex(&info.schema_hash),
            hex(&SCHEMA_HASH)
        );
    }
    // Parameters cross by index; this tool turns paths into indices and
    // back with its own copy of the parameter tree, valid only for the
    // same layout.
    if info.params_schema_hash != PARAMS_SCHEMA_HASH {
        bail!(
            "parameter schema mismatch: the drive ({}, firmware {} {}) has parameter layout {}, this tool {}; build both from the same ControlParams",
            info.board,
            info.firmware_version,
            info.git_hash,
            hex(&info.params_schema_hash),
            hex(&PARAMS_SCHEMA_HASH)
        );
    }
    Ok(())
}

/// The dotted path of parameter `index` (from this tool's copy of the tree,
/// the drive's own after `check_schema`).
pub fn param_path(index: u16) -> String {
    match protocol::params::name(usize::from(index)) {
        Some((path, _)) => path.to_string(),
        None => format!("control[{index}]"),
    }
}

pub fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// A request as the user asked it: a parameter by its path, a command by
/// name (the Rust form only for the rest).
pub fn request_text(r: &Request) -> String {
    match r {
        Request::ParamSet { index, value } => format!("param set {} {}", param_path(*index), value_text(value)),
        Request::ParamGet { index } => format!("param get {}", param_path(*index)),
        Request::Command(c) => command_text(c),
        Request::Save => "param save".into(),
        Request::Load => "param load".into(),
        Request::Defaults => "param defaults".into(),
        Request::Test(t) => test_text(t),
        Request::Capture(servo_core::capture::CaptureRequest::Configure(c)) => format!(
            "capture --signals {} --samples {} --decimation {} --pre-trigger {} --trigger {}",
            c.signals.iter().map(|s| super::scope::signal_name(*s)).collect::<Vec<_>>().join(","),
            c.samples,
            c.decimation,
            c.pre_trigger,
            match c.trigger {
                servo_core::capture::CaptureTrigger::Command => "command",
                servo_core::capture::CaptureTrigger::Fault => "fault",
                servo_core::capture::CaptureTrigger::TestStart => "test",
            }
        ),
        other => format!("{other:?}"),
    }
}

/// A command as the tool's user types it.
fn command_text(c: &protocol::DriveCommand) -> String {
    use protocol::DriveCommand;
    match c {
        DriveCommand::Enable => "cmd enable".into(),
        DriveCommand::Disable => "cmd disable".into(),
        DriveCommand::Calibrate => "cmd calibrate".into(),
        DriveCommand::Align => "cmd align".into(),
        DriveCommand::Home => "cmd home".into(),
        DriveCommand::StartUp => "cmd startup".into(),
        DriveCommand::Stop => "cmd stop".into(),
        DriveCommand::ClearFaults => "cmd clear-faults".into(),
        DriveCommand::SetCompensation { enabled } => format!("cmd comp {}", if *enabled { "on" } else { "off" }),
        DriveCommand::MoveTo { position_m } => format!("move {position_m}"),
        DriveCommand::Jog { distance_m } => format!("jog {distance_m}"),
        DriveCommand::SetHome { position_m } => format!("set-home {position_m}"),
        DriveCommand::SetPositionShift { shift_m } => format!("SetPositionShift {{ shift_m: {shift_m} }}"),
    }
}

/// A test signal as the tool's `step` / `chirp` command gives it.
fn test_text(t: &servo_core::test_signals::TestSignal) -> String {
    use servo_core::test_signals::{ChirpTarget, TestSignal as T};
    match t {
        T::CurrentStep { axis_q: true, amplitude_a, duration_s } => format!("step current {amplitude_a} --duration {duration_s}"),
        T::CurrentStep { axis_q: false, amplitude_a, duration_s } => format!("step current {amplitude_a} --duration {duration_s} (d axis)"),
        T::SpeedStep { amplitude_rad_s, duration_s } => format!("step speed {amplitude_rad_s} --duration {duration_s}"),
        T::PositionStep { distance_m, duration_s } => format!("step position {distance_m} --duration {duration_s}"),
        T::Chirp { target, amplitude, start_hz, end_hz, duration_s } => {
            let t = match target {
                ChirpTarget::Current => "current",
                ChirpTarget::Speed => "speed",
                ChirpTarget::Position => "position",
            };
            format!("chirp {t} --amplitude {amplitude} --from {start_hz} --to {end_hz} --duration {duration_s}")
        }
    }
}

fn value_text(v: &servo_core::protocol::Value) -> String {
    use servo_core::protocol::Value as V;
    match v {
        V::F32(x) if *x != 0.0 && !(1e-4..1e6).contains(&x.abs()) => format!("{x:e}"),
        V::F32(x) => format!("{x}"),
        V::U32(x) => format!("{x}"),
        V::I32(x) => format!("{x}"),
        V::Bool(x) => format!("{x}"),
        V::Variant(x) => format!("variant {x}"),
    }
}

/// One line for a refusal: what, why, and the command to try next.
pub fn describe(e: &Error) -> String {
    match e {
        Error::Frame(f) => format!("the drive could not read a frame ({f:?}); check the link (--baud, cable) and retry"),
        Error::UnknownParam { index } => format!("no parameter `{}` on this drive; `param list` shows them", param_path(*index)),
        Error::WrongType { index, expected } => format!("`{}` takes a {expected:?} value; `param get {}` shows one", param_path(*index), param_path(*index)),
        Error::InvalidParam { index, reason } => {
            format!("`{}`: {reason}; nothing was changed (`param get {}` shows the value in force)", param_path(*index), param_path(*index))
        }
        Error::NeedsBridgeOff { index } => format!("`{}` changes only with the bridge off: `cmd disable` first", param_path(*index)),
        Error::Telemetry { reason } => format!("telemetry: {reason}"),
        Error::BridgeOn => "refused while the bridge is on: `cmd disable` first".into(),
        Error::Storage { reason } => format!("storage: {reason}; nothing was changed"),
        Error::Command(c) => describe_command(c),
        Error::Stream { reason } => format!("stream: {reason}{}", stream_hint(*reason)),
        Error::Capture { reason } => format!("capture: {reason}"),
        Error::Test { reason } => format!("test: {reason}"),
        Error::ObserverBlock(b) => format!(
            "observer weights refused: {}{}: {}; the running weights are unchanged",
            b.part.name(),
            if matches!(b.part, servo_core::observer::block::Part::Bias | servo_core::observer::block::Part::OutputScale | servo_core::observer::block::Part::OutputOffset | servo_core::observer::block::Part::StructureHash) { String::new() } else { format!("[{}]", b.index) },
            b.reason
        ),
        Error::ObserverStore { reason } => format!("observer weights: {reason}; the running weights are unchanged"),
        Error::Busy => "busy with a request of this kind; retry".into(),
        Error::StreamDisagrees { reason, measured_m_s, bound_m_s, interval_s } => format!(
            "stream: {reason}: {measured_m_s:+.4} m/s against {bound_m_s:.4} m/s ({:.3} ms since the last point taken); check the velocity column's units and that the CSV's rate is the one the points are sent at (`drive info` shows the drive's stream period)",
            interval_s * 1e3
        ),
        Error::ControlledByAnotherClient => "busy: controlled by another client; this one may only read (info, status, param get/list, watch, telemetry) until that one disconnects".into(),
    }
}

fn stream_hint(r: servo_core::protocol::Reason) -> &'static str {
    use servo_core::protocol::Reason as R;
    match r {
        R::RefusedFaultsLatched => "; `status` names them: `cmd clear-faults`, then `cmd enable`",
        R::RefusedNotRunning => "; `cmd enable` first (`status` shows the mode and any faults: `cmd clear-faults` clears them)",
        R::RefusedNotHomed => "; `cmd startup` (or `cmd home`) first",
        R::RefusedNotCommutated | R::RefusedNotCalibrated => "; `cmd startup` first",
        R::RefusedMoveInProgress => "; wait for the move (`status`) or `cmd stop`",
        R::StreamGap => "; start the stream again (its first point is reached from where the rod is)",
        _ => "",
    }
}

/// A refused command, with the command to try next.
pub fn describe_command(c: &servo_core::CommandError) -> String {
    use servo_core::CommandError as E;
    let names = |f: &servo_core::FaultSet| f.names().collect::<Vec<_>>().join(", ");
    match c {
        E::Faulted(f) => format!("faults latched ({}): `cmd clear-faults`, then `cmd enable`", names(f)),
        E::CauseStillPresent(f) => format!("faults whose cause is still present ({}): `status` shows the readouts; remove the cause, then `cmd clear-faults`", names(f)),
        E::NotRunning => "the drive is not running: `cmd enable` (if `status` shows faults, `cmd clear-faults` first)".into(),
        E::NotDisabled => "needs the bridge off: `cmd disable` first".into(),
        E::Busy => "a move or start-up step is in progress: wait for it (`status`) or `cmd stop`".into(),
        E::NotFinite => "an argument is not a finite number".into(),
        E::OutOfRange => "an argument is beyond its bound: positions within control.limits.stroke_min_m … stroke_max_m (`set-home` with the bridge on: within the stroke ± control.faults.stroke_overtravel_m), forces within the motor's peak thrust".into(),
        E::BusLow => "the bus voltage is below control.faults.bus_undervoltage_v: check the supply (`status` shows it)".into(),
        E::NotCalibrated => "current offsets not calibrated: `cmd startup` (or `cmd calibrate`) first".into(),
        E::NotCommutated => "the motor is not commutated: `cmd startup` (calibration, commutation, homing) first".into(),
        E::NotHomed => "the axis is not homed: `cmd startup` or `cmd home` (or `set-home POSITION_M` on a rig with a known reference) first".into(),
    }
}
