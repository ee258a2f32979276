//! The host tool's command line: where the drive is and what to ask it.

use crate::drive::Pace;
use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use super::client::{Client, Endpoint};
use super::test;
use std::path::PathBuf;
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
    #[arg(long, global = true, default_value_t = 2.0, allow_negative_numbers = true, value_parser = seconds_positive)]
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
        #[arg(long, default_value_t = 0.25, allow_negative_numbers = true, value_parser = finite)]
        initial_position_m: f64,
        /// Fast pacing: simulated seconds per stream frame (default: one
        /// position-loop period, i.e. a 1 kHz stream).
        #[arg(long, allow_negative_numbers = true, value_parser = seconds_positive)]
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
        #[arg(long, default_value_t = 20.0, allow_negative_numbers = true, value_parser = positive)]
        rate_hz: f64,
        /// End after this many seconds (0: until q).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = seconds_or_zero)]
        seconds: f64,
    },
    /// Record every telemetry field to a CSV.
    Telemetry {
        #[arg(long)]
        csv: PathBuf,
        /// Records per second, 1 … 1000 (the position-loop rate).
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u16).range(1..=1000))]
        rate_hz: u16,
        #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = seconds_positive)]
        seconds: f64,
    },
    #[command(subcommand)]
    Param(ParamCmd),
    /// The observer's weights: status, upload, back to the compiled model.
    #[command(subcommand)]
    Observer(ObserverCmd),
    /// Identify the cylinder on the drive: `identify stiffness`.
    #[command(subcommand)]
    Identify(IdentifyCmd),
    /// enable | disable | calibrate | align | home | startup | stop | clear-faults | comp on|off
    Cmd { name: String, arg: Option<String> },
    /// A planned move to POSITION_M.
    Move {
        #[arg(allow_negative_numbers = true, value_parser = finite)]
        position_m: f64,
    },
    /// A planned move by DISTANCE_M from where the reference is.
    Jog {
        #[arg(allow_negative_numbers = true, value_parser = finite)]
        distance_m: f64,
    },
    /// Declares the present position to be POSITION_M (homes the axis on a
    /// rig with a known reference).
    SetHome {
        #[arg(allow_negative_numbers = true, value_parser = finite)]
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
        #[arg(allow_negative_numbers = true, value_parser = finite)]
        amplitude: f64,
        #[arg(long, default_value_t = 0.1, allow_negative_numbers = true, value_parser = seconds_positive)]
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
        #[arg(long, allow_negative_numbers = true, value_parser = finite)]
        amplitude: f64,
        #[arg(long, allow_negative_numbers = true, value_parser = positive)]
        from: f64,
        #[arg(long, allow_negative_numbers = true, value_parser = positive)]
        to: f64,
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = seconds_positive)]
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
        #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u16).range(1..))]
        samples: u16,
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
        decimation: u16,
        #[arg(long, default_value = "command")]
        trigger: String,
        #[arg(long, default_value_t = 0)]
        pre_trigger: u16,
        #[arg(long, default_value = "capture.csv")]
        out: PathBuf,
        /// Seconds to wait for the trigger.
        #[arg(long, default_value_t = 30.0, allow_negative_numbers = true, value_parser = seconds_positive)]
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
        /// moves first (docs/tuning-family.md, "The torque filter per unit").
        #[arg(long, requires = "family")]
        tune_filter: bool,
    },
    /// How long `stream FILE --asap` takes: a 20 s, 1 kHz trajectory sent
    /// by a `drive stream` process to a fast-paced simulated drive; wall
    /// time, points/s and the bar in summary.json; exits 1 above the bar.
    BenchAsap {
        #[arg(long, default_value = "out/bench-asap")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Length of the trajectory, s.
        #[arg(long, default_value_t = 20.0, allow_negative_numbers = true, value_parser = seconds_positive)]
        seconds: f64,
        /// Its setpoint rate, Hz (the drive is served at the same rate).
        #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true, value_parser = positive)]
        rate_hz: f64,
    },
    /// How often `watch` refreshes beside a controlling client: a simulated
    /// drive in real time, the view drawn off-screen.
    BenchWatch {
        #[arg(long, default_value = "out/bench-watch")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// The rate `watch` is asked for, Hz (its default).
        #[arg(long, default_value_t = 20.0, allow_negative_numbers = true, value_parser = positive)]
        rate_hz: f64,
        #[arg(long, default_value_t = 3.0, allow_negative_numbers = true, value_parser = seconds_positive)]
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
pub enum IdentifyCmd {
    /// The cylinder's axial stiffness against its rig file's design: a
    /// current step above the hold current makes the load ring at the axial
    /// mode (captured a few times), the same probe runs on the design
    /// simulated at the payload the hold current says; the compliance ratio
    /// (f_design / f)² with its uncertainty, and the shipped observer
    /// weights scaled by it, go to OUT/stiffness.json. Refuses a probe it
    /// cannot read, saying why. The drive must be enabled, holding its load
    /// with the rod vertical, away from the stroke's ends.
    Stiffness {
        /// The rig file the cylinder was built to; default: the shipped rig.
        #[arg(long)]
        params: Option<PathBuf>,
        #[arg(long, default_value = "out/stiffness")]
        out: PathBuf,
        /// Upload the scaled weights as the observer's (the bridge is
        /// switched off first; stored in flash, verified by CRC).
        #[arg(long)]
        upload: bool,
        /// The step from the hold current, A (positive: the load is thrown
        /// up; a step down lets it fall and the speed loop faults when it
        /// takes over again).
        #[arg(long, default_value_t = crate::trainer::stiffness::STEP_A, allow_negative_numbers = true, value_parser = step_current)]
        step_a: f64,
        /// Probes (their spread is part of the uncertainty).
        #[arg(long, default_value_t = crate::trainer::stiffness::REPEATS, value_parser = clap::builder::TypedValueParser::map(clap::value_parser!(u16).range(2..=10), usize::from))]
        repeats: usize,
    },
}

/// A probe step, A: nonzero and at most 20 A from the hold current (the
/// drive refuses one beyond its current limit anyway).
fn step_current(text: &str) -> Result<f64, String> {
    let v = number(text)?;
    if v != 0.0 && v.abs() <= 20.0 {
        Ok(v)
    } else {
        Err(format!("{v} A: a step of 0 < |step| <= 20 A"))
    }
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

/// The longest time an argument may give, s (a day): beyond it a wait is a
/// typo, and `Duration` cannot hold an unbounded one.
const SECONDS_MAX: f64 = 86_400.0;

fn number(text: &str) -> Result<f64, String> {
    let v: f64 = text.trim().parse().map_err(|_| format!("`{text}` is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("`{text}` is not a finite number"))
    }
}

/// A finite number (positions, amplitudes: the drive bounds them further).
pub fn finite(text: &str) -> Result<f64, String> {
    number(text)
}

/// A finite number above zero (rates, frequencies).
pub fn positive(text: &str) -> Result<f64, String> {
    let v = number(text)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not above zero"))
    }
}

/// A time above zero and at most a day, s.
pub fn seconds_positive(text: &str) -> Result<f64, String> {
    let v = positive(text)?;
    if v <= SECONDS_MAX {
        Ok(v)
    } else {
        Err(format!("{v} s is beyond a day ({SECONDS_MAX} s)"))
    }
}

/// A time from zero to a day, s (zero: no end).
pub fn seconds_or_zero(text: &str) -> Result<f64, String> {
    let v = number(text)?;
    if (0.0..=SECONDS_MAX).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} s is not within 0 … {SECONDS_MAX} s"))
    }
}
