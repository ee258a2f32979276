//! The host tool (`host-sim drive …`): talks the drive protocol to a board
//! over a serial port or to the simulated drive over TCP, with the same
//! commands either way. docs/host-tool.md lists them.

pub mod analysis;
pub mod bench;
pub mod bench_family;
pub mod bench_gain;
pub mod client;
pub mod config_file;
pub mod observer;
pub mod params;
pub mod scope;
pub mod stream;
pub mod stream_loss;
pub mod test;
pub mod view;
pub mod watch_bench;

use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use client::{Client, Endpoint};
use servo_core::protocol::{
    CaptureTrigger, DriveCommand, Reply, Request, Value,
};
use servo_core::ControlParams;
use std::path::PathBuf;

pub use scope::{capture, capture_with, signal_by_name, signal_name, CaptureData, SIGNAL_NAMES};
use std::time::Duration;

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
    /// Who the drive is, its schema, mode, faults and saved record.
    Info,
    /// Mode, faults by name, readiness, position, speed, currents, bus,
    /// temperatures, the saved record, and the next command to try.
    /// Exits non-zero while faults are latched.
    Status {
        #[arg(long)]
        json: bool,
    },
    /// A live view of the drive (read-only; q or Esc ends it).
    Watch {
        /// Refresh rate, Hz.
        #[arg(long, default_value_t = 20.0)]
        rate_hz: f64,
        /// End after this many seconds (0: until q).
        #[arg(long, default_value_t = 0.0)]
        seconds: f64,
    },
    /// Record every telemetry field to a CSV.
    Telemetry {
        #[arg(long)]
        csv: PathBuf,
        #[arg(long, default_value_t = 100)]
        rate_hz: u16,
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
    },
    #[command(subcommand)]
    Param(ParamCmd),
    /// The observer's weights: status, upload, back to the compiled model.
    #[command(subcommand)]
    Observer(ObserverCmd),
    /// enable | disable | calibrate | align | home | startup | stop | clear-faults | comp on|off
    Cmd { name: String, arg: Option<String> },
    /// A planned move to POSITION_M.
    Move {
        #[arg(allow_negative_numbers = true)]
        position_m: f64,
    },
    /// A planned move by DISTANCE_M from where the reference is.
    Jog {
        #[arg(allow_negative_numbers = true)]
        distance_m: f64,
    },
    /// Declares the present position to be POSITION_M (homes the axis on a
    /// rig with a known reference).
    SetHome {
        #[arg(allow_negative_numbers = true)]
        position_m: f64,
    },
    /// Stream setpoints from a CSV (t_s, position_m, velocity_m_s[, force_n]).
    Stream {
        file: PathBuf,
        /// Send back to back instead of at the CSV's times (for a
        /// fast-paced simulated drive, which takes them at its own rate).
        #[arg(long)]
        asap: bool,
        /// Where the tracking figures go (summary.json).
        #[arg(long, default_value = "out/stream")]
        out: PathBuf,
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
    /// A stream cut at 0.1 m/s and at the top stream speed, the client
    /// stopping and the client killed: the stop's figures.
    BenchStreamLoss {
        #[arg(long, default_value = "out/bench-stream-loss")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// The paper run's motor-side reference streamed at 1 kHz through a
    /// simulated drive over TCP; tracking figures and the capture figure.
    BenchStream {
        #[arg(long, default_value = "out/bench-stream")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// The stream on every rig of a family (`host-sim rigs`): a row per
        /// rig and the worst case in summary.json, family.md; fails when a
        /// rig does.
        #[arg(long, conflicts_with = "params")]
        family: Option<PathBuf>,
        /// With --family: choose each rig's torque filter by its own test
        /// moves first (docs/tuning.md, "The torque filter per unit").
        #[arg(long, requires = "family")]
        tune_filter: bool,
    },
    /// How often `watch` refreshes beside a controlling client: a simulated
    /// drive in real time, the view drawn off-screen.
    BenchWatch {
        #[arg(long, default_value = "out/bench-watch")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// The rate `watch` is asked for, Hz (its default).
        #[arg(long, default_value_t = 20.0)]
        rate_hz: f64,
        #[arg(long, default_value_t = 3.0)]
        seconds: f64,
    },
}

#[derive(Subcommand)]
pub enum ObserverCmd {
    /// Which weights the observer runs (compiled or uploaded) and their CRC.
    Status,
    /// Upload a trainer's model.json as the observer's weights: checked by
    /// the drive, stored in flash with the present parameters, run at once
    /// (bridge off). A refused block names its part; nothing changes.
    Upload { model: PathBuf },
    /// Back to the weights compiled into the image (stored as such).
    Compiled,
}

#[derive(Subcommand)]
pub enum ParamCmd {
    /// Every parameter, `path = value` (enums by name).
    List,
    Get { path: String },
    Set {
        path: String,
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
    /// Writes the present set to flash.
    Save,
    /// Applies the saved record; a bad record is refused, nothing changed.
    Load,
    /// Applies the image's defaults (flash untouched until `save`).
    Defaults,
    /// Every parameter to a TOML file (the rig file's `[control]` layout).
    Export { file: PathBuf },
    /// Sets the parameters a TOML file gives (all of them or some).
    Import { file: PathBuf },
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
        DriveCmd::BenchStreamLoss { out, params } => {
            let s = stream_loss::run(&RigConfig::load_or_nominal(params.as_ref())?, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            Ok(())
        }
        DriveCmd::BenchStream { out, family: Some(dir), tune_filter, .. } => {
            let rigs = crate::rigs::load_family(&dir)?;
            let s = bench_family::run_family(&rigs, &dir, tune_filter, &out)?;
            print!("{}", std::fs::read_to_string(out.join("family.md"))?);
            println!("worst: {}", serde_json::to_string_pretty(&s["worst"])?);
            println!("{} of {} rigs pass; wrote {}/{{summary.json, family.md}} and a folder per rig", s["rigs_passed"], s["rigs"], out.display());
            if s["rigs_passed"] != s["rigs"] {
                bail!("drive bench-stream: rigs failed: {}", s["rigs_failed"]);
            }
            Ok(())
        }
        DriveCmd::BenchStream { out, params, family: None, .. } => {
            let s = bench::run(&RigConfig::load_or_nominal(params.as_ref())?, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            Ok(())
        }
        DriveCmd::BenchWatch { out, params, rate_hz, seconds } => {
            let s = watch_bench::run(&RigConfig::load_or_nominal(params.as_ref())?, &out, rate_hz, seconds)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            if s["refresh_ok"] != serde_json::Value::Bool(true) {
                bail!("`watch` refreshed at {} Hz, below {} Hz: {}", s["refresh_hz"], watch_bench::REFRESH_MIN_HZ, out.join("summary.json").display());
            }
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
        DriveCmd::Status { json } => {
            let s = view::status(c)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&view::status_json(&s))?);
            } else {
                let per_rad = fetch_one_f32(c, "drive_train.screw_lead_m").map(|l| l / std::f32::consts::TAU);
                for (k, v) in view::status_lines(&s, per_rad) {
                    println!("{k:<12} {v}");
                }
            }
            if s.faults != 0 {
                bail!("faults latched: {}; next: {}", view::fault_names(s.faults).join(", "), view::next_step(&s));
            }
        }
        DriveCmd::Watch { rate_hz, seconds } => {
            let n = view::watch(c, rate_hz, seconds)?;
            eprintln!("{n} refreshes");
        }
        DriveCmd::Telemetry { csv, rate_hz, seconds } => {
            let n = view::telemetry_csv(c, &csv, rate_hz, seconds)?;
            println!("{n} records → {}", csv.display());
            if n == 0 {
                bail!("no telemetry arrived in {seconds} s");
            }
        }
        DriveCmd::Observer(o) => {
            let s = match o {
                ObserverCmd::Status => observer::status(c)?,
                ObserverCmd::Upload { model } => {
                    let (w, source) = observer::read_model_file(&model)?;
                    observer::upload(c, &w, source).with_context(|| format!("uploading {} (trained on the {})", model.display(), source.name()))?
                }
                ObserverCmd::Compiled => observer::use_compiled(c)?,
            };
            println!("{}", observer::describe_status(&s));
        }
        DriveCmd::Param(p) => match p {
            ParamCmd::List => {
                for line in config_file::list_lines(&param_list(c)?) {
                    println!("{line}");
                }
            }
            ParamCmd::Get { path } => {
                let full = params::full_path(&path);
                println!("{}", params::value_text_at(&full, &param_get(c, &path)?));
            }
            ParamCmd::Set { path, value } => {
                let full = params::full_path(&path);
                println!("{full} = {}", params::value_text_at(&full, &param_set(c, &path, &value)?));
            }
            ParamCmd::Save => {
                c.ask(Request::Save)?;
                println!("saved");
            }
            ParamCmd::Load => match c.ask(Request::Load)? {
                Reply::Loaded { note, .. } => println!("loaded: {note}"),
                r => bail!("Load answered with {r:?}"),
            },
            ParamCmd::Defaults => {
                c.ask(Request::Defaults)?;
                println!("image defaults applied (`param save` writes them to flash)");
            }
            ParamCmd::Export { file } => {
                let n = config_file::export(c, &file)?;
                println!("{n} parameters → {}", file.display());
            }
            ParamCmd::Import { file } => {
                let changed = config_file::import(c, &file)?;
                println!("{} parameters changed from {} ({})", changed.len(), file.display(), changed.join(", "));
            }
        },
        DriveCmd::Cmd { name, arg } => println!("{}", reply_text(&command(c, &name, arg.as_deref())?)),
        DriveCmd::Move { position_m } => println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::MoveTo { position_m: position_m as f32 }))?)),
        DriveCmd::Jog { distance_m } => println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::Jog { distance_m: distance_m as f32 }))?)),
        DriveCmd::SetHome { position_m } => {
            println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::SetHome { position_m: position_m as f32 }))?))
        }
        DriveCmd::Stream { file, asap, out } => {
            let rows = stream::read_csv(&file)?;
            let p = fetch_params(c, &ControlParams::default())?;
            let period = c.info.as_ref().map_or(0.0, |i| i.stream_period_s);
            let name = file.display().to_string();
            stream::check_rows(&name, &rows, &stream::StreamLimits::of(&p, period))?;
            let r = stream::send_with(c, &rows, !asap, true)?;
            for g in r.grouped() {
                eprintln!("{name}: {g}");
            }
            if let Some(row) = r.aborted_at_row {
                eprintln!("{name}: the drive stopped taking points at row {row}; sending ended there");
            }
            let fig = |x: Option<f64>| x.map_or("–".to_string(), |v| format!("{v:.1}"));
            println!(
                "{} of {} points sent over {:.3} s ({:.3} s wall), {} refused or bounded; following error RMS {} µm, max {} µm ({} records)",
                r.sent,
                r.rows,
                r.duration_s,
                r.wall_s,
                r.refusals.len(),
                fig(r.tracking_rms_um),
                fig(r.tracking_max_um),
                r.telemetry_records
            );
            std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
            let summary = out.join("summary.json");
            let json = serde_json::json!({
                "file": name,
                "rows": r.rows,
                "sent": r.sent,
                "duration_s": r.duration_s,
                "wall_s": r.wall_s,
                "refusals": r.refusals.len(),
                "refusal_runs": r.grouped(),
                "aborted_at_row": r.aborted_at_row,
                "tracking_rms_um": r.tracking_rms_um,
                "tracking_max_um": r.tracking_max_um,
                "telemetry_records": r.telemetry_records,
                "faults": r.faults,
            });
            std::fs::write(&summary, serde_json::to_string_pretty(&json)?)?;
            println!("figures → {}", summary.display());
            if !r.faults.is_empty() {
                bail!("{}", stream::fault_advice(&name, &r.faults));
            }
            if let Some(first) = r.grouped().first() {
                bail!("{name}: {} points refused or bounded (first: {first})", r.refusals.len());
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
        DriveCmd::Serve { .. } | DriveCmd::Log { .. } | DriveCmd::BenchStream { .. } | DriveCmd::BenchStreamLoss { .. } | DriveCmd::BenchWatch { .. } => {
            bail!("not a command for a connected drive")
        }
    }
    Ok(())
}

fn fetch_one_f32(c: &mut Client, path: &str) -> Option<f32> {
    match param_get(c, path).ok()? {
        Value::F32(v) => Some(v),
        _ => None,
    }
}

/// A successful reply in words.
pub fn reply_text(r: &Reply) -> String {
    match r {
        Reply::Command(servo_core::protocol::CommandReport::Accepted) => "accepted".into(),
        Reply::Command(servo_core::protocol::CommandReport::ClampedToStroke { position_m }) => {
            format!("accepted, clamped to the stroke: {position_m} m")
        }
        Reply::Ok => "done".into(),
        r => format!("{r:?}"),
    }
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
        "boot_record": view::boot_record_text(&i.boot_record),
        "stream_period_s": if i.stream_period_s > 0.0 { Some(i.stream_period_s) } else { None },
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
    // The type from the leaf table both ends share (the schema hash was
    // checked at connect): no round trip to learn it.
    param_index(path)?;
    let kind = servo_core::protocol::params::kind(&params::full_path(path)).map_err(|_| anyhow!("no parameter `{path}`"))?;
    let value = params::parse_value_at(&params::full_path(path), kind, text).map_err(|e| anyhow!("{path}: {e}; nothing was sent"))?;
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
        (n, a) => bail!(
            "unknown command `{n}{}`: enable, disable, calibrate, align, home, startup, stop, clear-faults, comp on|off (moves: `move`, `jog`, `set-home`)",
            a.map(|a| format!(" {a}")).unwrap_or_default()
        ),
    };
    c.ask(Request::Command(cmd))
}
