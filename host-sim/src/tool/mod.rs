//! The host tool (`host-sim drive …`): talks the drive protocol to a board
//! over a serial port or to the simulated drive over TCP, with the same
//! commands either way. docs/host-tool.md lists them.

pub mod analysis;
pub mod bench;
pub mod bench_gain;
pub mod client;
pub mod params;
pub mod stream;
pub mod test;

use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use client::{Client, Endpoint};
use servo_core::protocol::{
    CaptureConfig, CaptureRequest, CaptureState, CaptureTrigger, DriveCommand, Reply, Request, Signal, Value,
};
use servo_core::ControlParams;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Args, Clone, Debug)]
pub struct ConnectArgs {
    /// Serial port of a board (e.g. /dev/ttyACM0).
    #[arg(long, global = true, conflicts_with = "tcp")]
    pub port: Option<String>,
    #[arg(long, global = true, default_value_t = 115_200)]
    pub baud: u32,
    /// A simulated drive (`host-sim drive serve`), e.g. 127.0.0.1:7700.
    #[arg(long, global = true)]
    pub tcp: Option<String>,
    /// Seconds to wait for each reply.
    #[arg(long, global = true, default_value_t = 2.0)]
    pub timeout_s: f64,
}

impl ConnectArgs {
    pub fn endpoint(&self) -> Result<Endpoint> {
        match (&self.port, &self.tcp) {
            (Some(p), _) => Ok(Endpoint::Serial { port: p.clone(), baud: self.baud }),
            (None, Some(t)) => Ok(Endpoint::Tcp(t.clone())),
            (None, None) => bail!("say where the drive is: --port /dev/ttyACM0 or --tcp 127.0.0.1:PORT"),
        }
    }
    pub fn connect(&self) -> Result<Client> {
        let mut c = Client::connect(&self.endpoint()?)?;
        c.timeout = Duration::from_secs_f64(self.timeout_s);
        Ok(c)
    }
}

#[derive(Args)]
pub struct DriveArgs {
    #[command(flatten)]
    pub conn: ConnectArgs,
    #[command(subcommand)]
    pub cmd: DriveCmd,
}

#[derive(Subcommand)]
pub enum DriveCmd {
    /// Serve a simulated drive (core + plant) on a TCP socket.
    Serve {
        #[arg(long, default_value = "127.0.0.1:7700")]
        listen: String,
        /// Rig file; default: the shipped rig.
        #[arg(long)]
        params: Option<PathBuf>,
        #[arg(long, value_enum, default_value_t = Pace::Realtime)]
        pace: Pace,
        /// Parameter store (the board's flash record).
        #[arg(long)]
        store: Option<PathBuf>,
        /// Start commissioned and homed (as the simulator's experiments do);
        /// default: like a fresh board, `cmd startup` first.
        #[arg(long)]
        commissioned: bool,
        /// Rod position at start, metres.
        #[arg(long, default_value_t = 0.25)]
        initial_position_m: f64,
        /// Fast pacing: simulated seconds per stream frame (default: one
        /// position-loop period, i.e. a 1 kHz stream).
        #[arg(long)]
        stream_period_s: Option<f64>,
    },
    /// Who the drive is, its schema, mode and faults.
    Info,
    /// Mode, faults, readiness, drive time.
    Status,
    #[command(subcommand)]
    Param(ParamCmd),
    /// enable | disable | calibrate | align | home | startup | stop | clear-faults | comp on|off
    Cmd { name: String, arg: Option<String> },
    /// A planned move to POSITION_M.
    Move { position_m: f64 },
    /// Stream setpoints from a CSV (t_s, position_m, velocity_m_s[, force_n]).
    Stream {
        file: PathBuf,
        /// Send back to back instead of at the CSV's times (for a
        /// fast-paced simulated drive).
        #[arg(long)]
        asap: bool,
    },
    /// A step test: capture, summary, plot, simulator prediction.
    Step {
        #[arg(value_enum)]
        target: test::Target,
        amplitude: f64,
        #[arg(long, default_value_t = 0.1)]
        duration: f64,
        #[arg(long, default_value = "out/step")]
        out: PathBuf,
        /// Rig for the prediction; default: the shipped rig.
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// A logarithmic chirp: FRF (H1), bandwidth, margins, prediction.
    Chirp {
        #[arg(value_enum)]
        target: test::Target,
        #[arg(long)]
        amplitude: f64,
        #[arg(long)]
        from: f64,
        #[arg(long)]
        to: f64,
        #[arg(long, default_value_t = 1.0)]
        duration: f64,
        #[arg(long, default_value = "out/chirp")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// Arm a capture, wait for its trigger, upload it to CSV.
    Capture {
        /// Comma-separated signal names (e.g. current_q,speed).
        #[arg(long, value_delimiter = ',')]
        signals: Vec<String>,
        #[arg(long, default_value_t = 1000)]
        samples: u16,
        #[arg(long, default_value_t = 1)]
        decimation: u16,
        #[arg(long, default_value = "command")]
        trigger: String,
        #[arg(long, default_value_t = 0)]
        pre_trigger: u16,
        #[arg(long, default_value = "capture.csv")]
        out: PathBuf,
        /// Seconds to wait for the trigger.
        #[arg(long, default_value_t = 30.0)]
        wait_s: f64,
    },
    /// Convert the firmware's defmt log (probe-rs text) to the diagnose CSV.
    Log {
        input: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// The paper run's motor-side reference streamed at 1 kHz through a
    /// simulated drive over TCP; tracking figures and the capture figure.
    BenchStream {
        #[arg(long, default_value = "out/bench-stream")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
pub enum ParamCmd {
    List,
    Get { path: String },
    Set { path: String, value: String },
    Save,
    Load,
    Defaults,
}

pub fn run_cli(a: DriveArgs) -> Result<()> {
    match a.cmd {
        DriveCmd::Serve { listen, params, pace, store, commissioned, initial_position_m, stream_period_s } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let mut o = DriveOptions::new(rig);
            o.pace = pace;
            o.store = store;
            o.commissioned = commissioned;
            o.initial_position_m = initial_position_m;
            if let Some(s) = stream_period_s {
                o.stream_period_s = s;
            }
            let l = std::net::TcpListener::bind(&listen).with_context(|| format!("binding {listen}"))?;
            eprintln!("drive: serving on {} ({pace:?} pacing)", l.local_addr()?);
            drive::serve(l, o, Default::default())
        }
        DriveCmd::Log { input, out } => {
            let log = crate::diagnose::log::read_any(&input)?;
            for i in &log.issues {
                eprintln!("{i}");
            }
            log.write_csv(&out)?;
            println!("{} rows → {}", log.len(), out.display());
            Ok(())
        }
        DriveCmd::BenchStream { out, params } => {
            let s = bench::run(&RigConfig::load_or_nominal(params.as_ref())?, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            Ok(())
        }
        cmd => {
            let mut c = a.conn.connect()?;
            run_on(&mut c, cmd)
        }
    }
}

fn run_on(c: &mut Client, cmd: DriveCmd) -> Result<()> {
    match cmd {
        DriveCmd::Info => println!("{}", serde_json::to_string_pretty(&info_json(c)?)?),
        DriveCmd::Status => println!("{:?}", c.ask(Request::Status)?),
        DriveCmd::Param(p) => match p {
            ParamCmd::List => {
                for (path, v) in param_list(c)? {
                    println!("{path} = {}", params::value_text(&v));
                }
            }
            ParamCmd::Get { path } => println!("{}", params::value_text(&param_get(c, &path)?)),
            ParamCmd::Set { path, value } => println!("{path} = {}", params::value_text(&param_set(c, &path, &value)?)),
            ParamCmd::Save => println!("{:?}", c.ask(Request::Save)?),
            ParamCmd::Load => println!("{:?}", c.ask(Request::Load)?),
            ParamCmd::Defaults => println!("{:?}", c.ask(Request::Defaults)?),
        },
        DriveCmd::Cmd { name, arg } => println!("{:?}", command(c, &name, arg.as_deref())?),
        DriveCmd::Move { position_m } => println!("{:?}", c.ask(Request::Command(DriveCommand::MoveTo { position_m: position_m as f32 }))?),
        DriveCmd::Stream { file, asap } => {
            let rows = stream::read_csv(&file)?;
            let r = stream::send(c, &rows, !asap)?;
            for g in r.grouped() {
                eprintln!("{}: {g}", file.display());
            }
            if let Some(row) = r.aborted_at_row {
                eprintln!("{}: the drive stopped taking points at row {row}; sending ended there", file.display());
            }
            println!("{} of {} points sent over {:.3} s ({:.3} s wall), {} refused or bounded", r.sent, r.rows, r.duration_s, r.wall_s, r.refusals.len());
            if r.aborted_at_row.is_some() {
                bail!("stream aborted");
            }
        }
        DriveCmd::Step { target, amplitude, duration, out, params } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let spec = test::Spec::step(target, amplitude, duration);
            let s = test::run(c, &rig, &spec, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
        }
        DriveCmd::Chirp { target, amplitude, from, to, duration, out, params } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let spec = test::Spec::chirp(target, amplitude, from, to, duration);
            let s = test::run(c, &rig, &spec, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
        }
        DriveCmd::Capture { signals, samples, decimation, trigger, pre_trigger, out, wait_s } => {
            let sigs = signals.iter().map(|s| signal_by_name(s)).collect::<Result<Vec<_>>>()?;
            let trig = match trigger.as_str() {
                "command" => CaptureTrigger::Command,
                "fault" => CaptureTrigger::Fault,
                "test" => CaptureTrigger::TestStart,
                t => bail!("--trigger: `{t}`; one of command, fault, test"),
            };
            let cap = capture(c, &sigs, samples, decimation, pre_trigger, trig, Duration::from_secs_f64(wait_s))?;
            cap.write_csv(&out)?;
            println!("{} signals × {} samples at {:.1} Hz → {}", cap.names.len(), cap.len(), 1.0 / cap.dt_s, out.display());
        }
        DriveCmd::Serve { .. } | DriveCmd::Log { .. } | DriveCmd::BenchStream { .. } => unreachable!(),
    }
    Ok(())
}

pub fn info_json(c: &mut Client) -> Result<serde_json::Value> {
    let i = match c.ask(Request::Info)? {
        Reply::Info(i) => i,
        r => bail!("unexpected {r:?}"),
    };
    Ok(serde_json::json!({
        "board": i.board.as_str(),
        "firmware_version": i.firmware_version.as_str(),
        "git_hash": i.git_hash.as_str(),
        "schema_hash": client::hex(&i.schema_hash),
        "params_schema_hash": client::hex(&i.params_schema_hash),
        "mode": format!("{:?}", i.mode),
        "faults": servo_core::FaultSet::from_bits_retain(i.faults).names().collect::<Vec<_>>(),
        "pwm_frequency_hz": i.pwm_frequency_hz,
    }))
}

pub fn param_list(c: &mut Client) -> Result<Vec<(String, Value)>> {
    let n = match c.ask(Request::ParamCount)? {
        Reply::ParamCount { count } => count,
        r => bail!("unexpected {r:?}"),
    };
    // The names are this tool's (the connect checked the layout is the
    // drive's); the count is the drive's, as a second check.
    if usize::from(n) != servo_core::protocol::params::PARAM_COUNT {
        bail!("the drive has {n} parameters, this tool {}", servo_core::protocol::params::PARAM_COUNT);
    }
    let mut out = Vec::new();
    for index in 0..n {
        let path = client::param_path(index);
        out.push((path.clone(), param_get(c, &path)?));
    }
    Ok(out)
}

/// The index of parameter `p` (`control.` optional): the drive addresses
/// parameters by index, the tool resolves the path.
pub fn param_index(p: &str) -> Result<u16> {
    let full = params::full_path(p);
    servo_core::protocol::params::index_of(&full)
        .and_then(|i| u16::try_from(i).ok())
        .ok_or_else(|| anyhow!("no parameter `{full}`"))
}

pub fn param_get(c: &mut Client, path: &str) -> Result<Value> {
    match c.ask(Request::ParamGet { index: param_index(path)? })? {
        Reply::Param { value, .. } => Ok(value),
        r => bail!("unexpected {r:?}"),
    }
}

/// Reads the parameter first to learn its type, then sets `text` as that type.
pub fn param_set(c: &mut Client, path: &str, text: &str) -> Result<Value> {
    let kind = match param_get(c, path)? {
        Value::F32(_) => servo_core::protocol::ValueKind::F32,
        Value::U32(_) => servo_core::protocol::ValueKind::U32,
        Value::I32(_) => servo_core::protocol::ValueKind::I32,
        Value::Bool(_) => servo_core::protocol::ValueKind::Bool,
        Value::Variant(_) => servo_core::protocol::ValueKind::Variant,
    };
    let value = params::parse_value(kind, text).map_err(|e| anyhow!("{path}: {e}"))?;
    param_set_value(c, path, value)
}

pub fn param_set_value(c: &mut Client, path: &str, value: Value) -> Result<Value> {
    match c.ask(Request::ParamSet { index: param_index(path)?, value })? {
        Reply::Param { value, .. } => Ok(value),
        r => bail!("unexpected {r:?}"),
    }
}

/// The drive's whole parameter set, read leaf by leaf onto `base`.
pub fn fetch_params(c: &mut Client, base: &ControlParams) -> Result<ControlParams> {
    let mut p = *base;
    for (path, v) in param_list(c)? {
        servo_core::protocol::params::set(&mut p, &path, v).map_err(|e| anyhow!("{path}: {e:?}"))?;
    }
    Ok(p)
}

pub fn command(c: &mut Client, name: &str, arg: Option<&str>) -> Result<Reply> {
    let cmd = match (name, arg) {
        ("enable", _) => DriveCommand::Enable,
        ("disable", _) => DriveCommand::Disable,
        ("calibrate", _) => DriveCommand::Calibrate,
        ("align", _) => DriveCommand::Align,
        ("home", _) => DriveCommand::Home,
        ("startup", _) => DriveCommand::StartUp,
        ("stop", _) => DriveCommand::Stop,
        ("clear-faults", _) => DriveCommand::ClearFaults,
        ("comp", Some("on")) => DriveCommand::SetCompensation { enabled: true },
        ("comp", Some("off")) => DriveCommand::SetCompensation { enabled: false },
        (n, a) => bail!("unknown command `{n}{}`: enable, disable, calibrate, align, home, startup, stop, clear-faults, comp on|off", a.map(|a| format!(" {a}")).unwrap_or_default()),
    };
    c.ask(Request::Command(cmd))
}

pub const SIGNAL_NAMES: &[(&str, Signal)] = &[
    ("current_d", Signal::CurrentD),
    ("current_q", Signal::CurrentQ),
    ("current_q_reference", Signal::CurrentQReference),
    ("current_d_reference", Signal::CurrentDReference),
    ("voltage_d", Signal::VoltageD),
    ("voltage_q", Signal::VoltageQ),
    ("speed", Signal::Speed),
    ("speed_reference", Signal::SpeedReference),
    ("motor_position", Signal::MotorPosition),
    ("position_command", Signal::PositionCommand),
    ("position_reference", Signal::PositionReference),
    ("bus_voltage", Signal::BusVoltage),
    ("phase_current_a", Signal::PhaseCurrentA),
    ("phase_current_b", Signal::PhaseCurrentB),
    ("phase_current_c", Signal::PhaseCurrentC),
    ("electrical_angle", Signal::ElectricalAngle),
];

pub fn signal_by_name(n: &str) -> Result<Signal> {
    SIGNAL_NAMES.iter().find(|(s, _)| *s == n).map(|(_, s)| *s).ok_or_else(|| {
        anyhow!("unknown signal `{n}`; one of {}", SIGNAL_NAMES.iter().map(|(s, _)| *s).collect::<Vec<_>>().join(", "))
    })
}

pub fn signal_name(s: Signal) -> &'static str {
    SIGNAL_NAMES.iter().find(|(_, x)| *x == s).map_or("?", |(n, _)| n)
}

/// An uploaded capture.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaptureData {
    pub names: Vec<String>,
    pub dt_s: f64,
    pub trigger_index: usize,
    /// `values[signal][sample]`
    pub values: Vec<Vec<f64>>,
}

impl CaptureData {
    pub fn len(&self) -> usize {
        self.values.first().map_or(0, Vec::len)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Time of sample `k`, zero at the trigger.
    pub fn t(&self, k: usize) -> f64 {
        (k as f64 - self.trigger_index as f64) * self.dt_s
    }
    pub fn write_csv(&self, path: &std::path::Path) -> Result<()> {
        if let Some(d) = path.parent() {
            std::fs::create_dir_all(d).ok();
        }
        let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
        let mut h = vec!["t_s".to_string()];
        h.extend(self.names.iter().cloned());
        w.write_record(&h)?;
        for k in 0..self.len() {
            let mut r = vec![format!("{}", self.t(k))];
            r.extend(self.values.iter().map(|v| format!("{}", v[k])));
            w.write_record(&r)?;
        }
        w.flush()?;
        Ok(())
    }
}

fn drive_time(c: &mut Client) -> Result<f64> {
    match c.ask(Request::Status)? {
        Reply::Status(s) => Ok(f64::from(s.time_s)),
        r => bail!("unexpected {r:?}"),
    }
}

/// Arms a capture (`Configure`), lets `start` trigger it (a `Test` request,
/// `CaptureRequest::Trigger`, …), waits for `Done` and uploads it.
pub fn capture_with(
    c: &mut Client,
    cfg: CaptureConfig,
    start: impl FnOnce(&mut Client) -> Result<()>,
    wait: Duration,
) -> Result<CaptureData> {
    let names: Vec<String> = cfg.signals.iter().map(|s| signal_name(*s).to_string()).collect();
    let trigger = cfg.trigger;
    let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
    let pre_s = f64::from(cfg.pre_trigger) * f64::from(cfg.decimation) / pwm;
    c.ask(Request::Capture(CaptureRequest::Configure(cfg)))?;
    if trigger == CaptureTrigger::Command {
        // Let the pre-trigger history fill (drive time), then trigger.
        let t0 = drive_time(c)?;
        let started = Instant::now();
        while drive_time(c)? < t0 + pre_s + 0.002 && started.elapsed() < wait {
            c.poll(Duration::from_millis(1))?;
            c.telemetry.clear();
        }
        c.ask(Request::Capture(CaptureRequest::Trigger))?;
    }
    start(c)?;
    let t0 = Instant::now();
    let status = loop {
        match c.ask(Request::Capture(CaptureRequest::Status))? {
            Reply::CaptureStatus(s) if s.state == CaptureState::Done => break s,
            Reply::CaptureStatus(_) => {}
            r => bail!("unexpected {r:?}"),
        }
        if t0.elapsed() > wait {
            bail!("the capture did not complete within {:.1} s", wait.as_secs_f64());
        }
        c.poll(Duration::from_millis(10))?;
        c.telemetry.clear();
    };
    let mut values = vec![Vec::with_capacity(usize::from(status.samples)); names.len()];
    for (signal, v) in values.iter_mut().enumerate() {
        let mut start = 0u16;
        while start < status.samples {
            let count = (status.samples - start).min(servo_core::protocol::CAPTURE_CHUNK_MAX as u16) as u8;
            match c.ask(Request::Capture(CaptureRequest::Read { signal: signal as u8, start, count }))? {
                Reply::CaptureData { values: chunk, .. } => {
                    if chunk.is_empty() {
                        bail!("empty capture chunk at {start}");
                    }
                    v.extend(chunk.iter().map(|x| f64::from(*x)));
                    start += chunk.len() as u16;
                }
                r => bail!("unexpected {r:?}"),
            }
        }
    }
    Ok(CaptureData { names, dt_s: f64::from(status.sample_period_s), trigger_index: usize::from(status.trigger_index), values })
}

pub fn capture(
    c: &mut Client,
    signals: &[Signal],
    samples: u16,
    decimation: u16,
    pre_trigger: u16,
    trigger: CaptureTrigger,
    wait: Duration,
) -> Result<CaptureData> {
    let cfg = CaptureConfig {
        signals: servo_core::protocol::heapless::Vec::from_slice(signals).map_err(|_| anyhow!("at most {} signals", servo_core::protocol::CAPTURE_SIGNALS_MAX))?,
        decimation,
        samples,
        pre_trigger,
        trigger,
    };
    capture_with(c, cfg, |_| Ok(()), wait)
}
