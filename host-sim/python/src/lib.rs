//! `servo_drive._native`: the host tool's client (`host_sim::tool`) for
//! Python. Plain values cross the boundary (numbers, strings, lists, JSON
//! text); the Python layer (`servo_drive`) turns them into numpy arrays,
//! typed objects and its own exception types. Every error leaves here as
//! `NativeError` whose one argument is JSON: `kind` (the Python exception
//! class), `message`, and where known `reason` (the drive's), `field`, `row`.

use anyhow::anyhow;
use host_sim::config::RigConfig;
use host_sim::tool::client::{self, describe, Client, Endpoint};
use host_sim::tool::stream::{self, Row, StreamLimits};
use host_sim::tool::test::{self as drive_test, Spec, Target};
use host_sim::tool::{self, params as tparams, view};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use servo_core::protocol::{
    self, CaptureTrigger, DriveCommand, DriveFrame, Error as DriveErr, Info, Reply, Request, TelemetryField, PARAMS_SCHEMA_HASH,
    SCHEMA_HASH,
};
use servo_core::ControlParams;
use std::time::{Duration, Instant};

mod functions;
use functions::*;

create_exception!(_native, NativeError, PyException);

fn raise(kind: &str, message: impl Into<String>, extra: serde_json::Value) -> PyErr {
    let mut v = serde_json::json!({ "kind": kind, "message": message.into() });
    if let (Some(o), serde_json::Value::Object(e)) = (v.as_object_mut(), extra) {
        o.extend(e);
    }
    NativeError::new_err(v.to_string())
}

/// A failure of the link or of this side: a dropped connection, a drive
/// that stopped answering, or anything else, by its cause.
fn link_err(e: anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    let io = e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some());
    let kind = if msg.contains("closed the connection") || io {
        "ConnectionLost"
    } else if msg.contains("no reply to") {
        "DriveTimeout"
    } else {
        "DriveError"
    };
    raise(kind, msg, serde_json::json!({}))
}

/// A refusal by the drive: the Python class by what was refused, the
/// drive's reason code, and the parameter it names.
fn refused(what: &str, e: &DriveErr) -> PyErr {
    let message = format!("{what}: refused: {}", describe(e));
    let (kind, reason, field): (&str, String, Option<String>) = match e {
        DriveErr::InvalidParam { index, reason } => ("ParameterRejected", format!("{reason:?}"), Some(client::param_path(*index))),
        DriveErr::WrongType { index, .. } => ("ParameterRejected", "WrongType".into(), Some(client::param_path(*index))),
        DriveErr::NeedsBridgeOff { index } => ("ParameterRejected", "NeedsBridgeOff".into(), Some(client::param_path(*index))),
        DriveErr::UnknownParam { index } => ("UnknownParameter", "UnknownParam".into(), Some(client::param_path(*index))),
        DriveErr::Command(c) => ("CommandRefused", format!("{c:?}"), None),
        DriveErr::Stream { reason } | DriveErr::Capture { reason } | DriveErr::Test { reason } | DriveErr::Telemetry { reason } => {
            ("Refused", format!("{reason:?}"), None)
        }
        DriveErr::ControlledByAnotherClient => ("Refused", "ControlledByAnotherClient".into(), None),
        other => ("Refused", format!("{other:?}"), None),
    };
    raise(kind, message, serde_json::json!({ "reason": reason, "field": field }))
}

fn observer_json(s: &protocol::ObserverStatus) -> String {
    json_text(&serde_json::json!({
        "source": format!("{:?}", s.source).to_lowercase(),
        "inputs": s.inputs,
        "hidden": s.hidden,
        "words": s.words,
        "structure_hash": client::hex(&s.structure_hash),
        "words_crc": format!("{:08x}", s.words_crc),
    }))
}

fn json_text(v: &serde_json::Value) -> String {
    v.to_string()
}

/// A connected drive (TCP or serial), the schema checked.
#[pyclass(unsendable, module = "servo_drive._native")]
pub struct NativeDrive {
    c: Option<Client>,
    where_: String,
}

impl NativeDrive {
    fn c(&mut self) -> PyResult<&mut Client> {
        self.c.as_mut().ok_or_else(|| raise("ConnectionLost", format!("the connection to {} is closed", self.where_), serde_json::json!({})))
    }

    fn ask(&mut self, request: Request) -> PyResult<Reply> {
        let what = client::request_text(&request);
        let c = self.c()?;
        match Python::with_gil(|py| py.allow_threads(|| c.request(request))).map_err(link_err)? {
            Reply::Error(e) => Err(refused(&what, &e)),
            r => Ok(r),
        }
    }

    fn index(path: &str) -> PyResult<u16> {
        tool::param_index(path).map_err(|e| raise("UnknownParameter", format!("{e:#}"), serde_json::json!({ "field": tparams::full_path(path) })))
    }

    fn get_value(&mut self, path: &str) -> PyResult<protocol::Value> {
        let index = Self::index(path)?;
        match self.ask(Request::ParamGet { index })? {
            Reply::Param { value, .. } => Ok(value),
            r => Err(raise("DriveError", format!("ParamGet answered with {r:?}"), serde_json::json!({}))),
        }
    }
}

fn value_json(path: &str, v: &protocol::Value) -> serde_json::Value {
    match v {
        protocol::Value::F32(x) => serde_json::json!(x),
        protocol::Value::U32(x) => serde_json::json!(x),
        protocol::Value::I32(x) => serde_json::json!(x),
        protocol::Value::Bool(b) => serde_json::json!(b),
        protocol::Value::Variant(_) => serde_json::json!(tparams::value_text_at(path, v)),
    }
}

fn kind_name(k: protocol::ValueKind) -> &'static str {
    match k {
        protocol::ValueKind::F32 => "float",
        protocol::ValueKind::U32 => "uint",
        protocol::ValueKind::I32 => "int",
        protocol::ValueKind::Bool => "bool",
        protocol::ValueKind::Variant => "enum",
    }
}

fn target_of(name: &str) -> PyResult<Target> {
    Ok(match name {
        "current" => Target::Current,
        "speed" => Target::Speed,
        "position" => Target::Position,
        n => return Err(raise("ValueError", format!("unknown test target `{n}`: current, speed or position"), serde_json::json!({ "field": "target" }))),
    })
}

fn capture_tuple(d: tool::CaptureData) -> (Vec<String>, f64, usize, Vec<Vec<f64>>) {
    (d.names, d.dt_s, d.trigger_index, d.values)
}

#[pymethods]
impl NativeDrive {
    /// Opens `target` (`host:port` for `tcp`, a port name for `serial`),
    /// asks `Info` and refuses a drive of another schema.
    #[new]
    #[pyo3(signature = (transport, target, baud = 115_200, timeout_s = 2.0))]
    fn new(transport: &str, target: &str, baud: u32, timeout_s: f64) -> PyResult<Self> {
        let ep = match transport {
            "tcp" => Endpoint::Tcp(target.to_string()),
            "serial" => Endpoint::Serial { port: target.to_string(), baud },
            t => return Err(raise("ValueError", format!("unknown transport `{t}`: tcp or serial"), serde_json::json!({}))),
        };
        // Without the GIL: a drive served by this Python process answers meanwhile.
        let opened = Python::with_gil(|py| {
            py.allow_threads(|| -> anyhow::Result<_> {
                let link = ep.open().map_err(|e| e.context("connect"))?;
                let mut c = Client::raw(link);
                c.timeout = Duration::from_secs_f64(timeout_s.max(0.01));
                // A board may hold half a frame from an earlier session.
                c.send_raw(&[0])?;
                let reply = c.request(Request::Info)?;
                Ok((c, reply))
            })
        });
        let (mut c, reply) = opened.map_err(|e| {
            if e.to_string() == "connect" {
                let text = format!("{e:#}");
                raise("ConnectError", text.strip_prefix("connect: ").unwrap_or(&text), serde_json::json!({}))
            } else {
                link_err(e)
            }
        })?;
        let info = match reply {
            Reply::Info(i) => i,
            other => return Err(raise("ConnectError", format!("Info answered with {other:?}"), serde_json::json!({}))),
        };
        check_schema(&info)?;
        c.info = Some(info);
        Ok(Self { c: Some(c), where_: target.to_string() })
    }

    /// Closes the link (the drive sees the client go: a stream stops).
    fn close(&mut self) {
        self.c = None;
    }

    #[getter]
    fn timeout_s(&mut self) -> PyResult<f64> {
        Ok(self.c()?.timeout.as_secs_f64())
    }

    #[setter]
    fn set_timeout_s(&mut self, t: f64) -> PyResult<()> {
        if !(t.is_finite() && t > 0.0 && t <= 86_400.0) {
            return Err(raise("InputError", format!("`timeout_s` = {t}: a time above 0 and at most a day (86400 s) is needed"), serde_json::json!({ "field": "timeout_s" })));
        }
        self.c()?.timeout = Duration::from_secs_f64(t);
        Ok(())
    }

    /// Info as JSON text.
    fn info(&mut self) -> PyResult<String> {
        let i = match self.ask(Request::Info)? {
            Reply::Info(i) => i,
            r => return Err(raise("DriveError", format!("Info answered with {r:?}"), serde_json::json!({}))),
        };
        Ok(json_text(&serde_json::json!({
            "board": i.board.as_str(),
            "firmware_version": i.firmware_version.as_str(),
            "git_hash": i.git_hash.as_str(),
            "schema_hash": client::hex(&i.schema_hash),
            "params_schema_hash": client::hex(&i.params_schema_hash),
            "protocol_version": i.protocol_version,
            "mode": format!("{:?}", i.mode),
            "faults": view::fault_names(i.faults),
            "pwm_frequency_hz": i.pwm_frequency_hz,
            "boot_record": view::boot_record_text(&i.boot_record),
            "stream_period_s": if i.stream_period_s > 0.0 { Some(i.stream_period_s) } else { None },
        })))
    }

    /// Status as JSON text.
    fn status(&mut self) -> PyResult<String> {
        match self.ask(Request::Status)? {
            Reply::Status(s) => Ok(json_text(&view::status_json(&s))),
            r => Err(raise("DriveError", format!("Status answered with {r:?}"), serde_json::json!({}))),
        }
    }

    /// A parameter's value (JSON text: a number, a bool or an enum's name).
    fn param_get(&mut self, path: &str) -> PyResult<String> {
        let v = self.get_value(path)?;
        Ok(json_text(&value_json(&tparams::full_path(path), &v)))
    }

    /// Sets a parameter from its text (`0.5`, `true`, an enum's name);
    /// returns the value as applied (JSON text).
    fn param_set(&mut self, path: &str, text: &str) -> PyResult<String> {
        let full = tparams::full_path(path);
        let index = Self::index(path)?;
        let kind = protocol::params::kind(&full).map_err(|e| raise("UnknownParameter", format!("`{full}`: {e:?}"), serde_json::json!({ "field": full })))?;
        let value = tparams::parse_value_at(&full, kind, text)
            .map_err(|e| raise("ParameterRejected", format!("`{full}`: {e}; nothing was sent"), serde_json::json!({ "field": full, "reason": "WrongType" })))?;
        match self.ask(Request::ParamSet { index, value })? {
            Reply::Param { value, .. } => Ok(json_text(&value_json(&full, &value))),
            r => Err(raise("DriveError", format!("ParamSet answered with {r:?}"), serde_json::json!({}))),
        }
    }

    /// Every parameter: JSON list of {path, value}.
    fn param_list(&mut self) -> PyResult<String> {
        let list = tool::param_list(self.c()?).map_err(link_err)?;
        Ok(json_text(&serde_json::Value::Array(
            list.iter().map(|(p, v)| serde_json::json!({ "path": p, "value": value_json(p, v) })).collect(),
        )))
    }

    fn param_save(&mut self) -> PyResult<()> {
        self.ask(Request::Save).map(|_| ())
    }

    /// Applies the saved record; returns the drive's note.
    fn param_load(&mut self) -> PyResult<String> {
        match self.ask(Request::Load)? {
            Reply::Loaded { note, from_flash } => Ok(json_text(&serde_json::json!({ "from_flash": from_flash, "note": note.as_str() }))),
            _ => Ok(json_text(&serde_json::json!({ "from_flash": true, "note": "" }))),
        }
    }

    /// Which observer weights run (JSON: source, shape, words CRC).
    fn observer_status(&mut self) -> PyResult<String> {
        match self.ask(Request::Observer(protocol::ObserverRequest::Status))? {
            Reply::Observer(s) => Ok(observer_json(&s)),
            r => Err(raise("DriveError", format!("observer status answered with {r:?}"), serde_json::json!({}))),
        }
    }

    /// Uploads a trainer's model.json as the observer's weights (checked,
    /// stored with the parameters, run; verified by CRC). A refusal names
    /// the part.
    fn upload_observer(&mut self, path: &str) -> PyResult<String> {
        let (w, source) = tool::observer::read_model_file(std::path::Path::new(path))
            .map_err(|e| raise("ObserverRejected", format!("{e:#}"), serde_json::json!({ "field": path })))?;
        let c = self.c()?;
        let s = Python::with_gil(|py| py.allow_threads(|| tool::observer::upload(c, &w, source)))
            .map_err(|e| raise("ObserverRejected", format!("{e:#}"), serde_json::json!({})))?;
        Ok(observer_json(&s))
    }

    /// Back to the compiled observer weights (stored as such).
    fn use_compiled_observer(&mut self) -> PyResult<String> {
        match self.ask(Request::Observer(protocol::ObserverRequest::UseCompiled))? {
            Reply::Observer(s) => Ok(observer_json(&s)),
            r => Err(raise("DriveError", format!("observer compiled answered with {r:?}"), serde_json::json!({}))),
        }
    }

    fn param_defaults(&mut self) -> PyResult<()> {
        self.ask(Request::Defaults).map(|_| ())
    }

    /// Writes every parameter to a TOML file (the rig file's `[control]`).
    fn param_export(&mut self, path: &str) -> PyResult<usize> {
        host_sim::tool::config_file::export(self.c()?, std::path::Path::new(path)).map_err(|e| raise("DriveError", format!("{e:#}"), serde_json::json!({})))
    }

    /// Applies a TOML file's parameters (all or none); returns the paths set.
    fn param_import(&mut self, path: &str) -> PyResult<Vec<String>> {
        host_sim::tool::config_file::import(self.c()?, std::path::Path::new(path))
            .map_err(|e| raise("ParameterRejected", format!("{e:#}"), serde_json::json!({ "file": path })))
    }

    /// A command by name; `arg` is the position or distance (m) of
    /// `move`, `jog` and `set-home`. Returns JSON {outcome, position_m}.
    #[pyo3(signature = (name, arg = None))]
    fn command(&mut self, name: &str, arg: Option<f64>) -> PyResult<String> {
        let need = |a: Option<f64>| {
            a.map(|x| x as f32).ok_or_else(|| raise("ValueError", format!("`{name}` needs a distance or position in metres"), serde_json::json!({ "field": name })))
        };
        let cmd = match name {
            "enable" => DriveCommand::Enable,
            "disable" => DriveCommand::Disable,
            "calibrate" => DriveCommand::Calibrate,
            "align" => DriveCommand::Align,
            "home" => DriveCommand::Home,
            "startup" => DriveCommand::StartUp,
            "stop" => DriveCommand::Stop,
            "clear-faults" => DriveCommand::ClearFaults,
            "move" => DriveCommand::MoveTo { position_m: need(arg)? },
            "jog" => DriveCommand::Jog { distance_m: need(arg)? },
            "set-home" => DriveCommand::SetHome { position_m: need(arg)? },
            "compensation-on" => DriveCommand::SetCompensation { enabled: true },
            "compensation-off" => DriveCommand::SetCompensation { enabled: false },
            n => {
                return Err(raise(
                    "ValueError",
                    format!("unknown command `{n}`: enable, disable, calibrate, align, home, startup, stop, clear-faults, move, jog, set-home, compensation-on, compensation-off"),
                    serde_json::json!({ "field": "command" }),
                ))
            }
        };
        Ok(json_text(&match self.ask(Request::Command(cmd))? {
            Reply::Command(protocol::CommandReport::ClampedToStroke { position_m }) => serde_json::json!({ "outcome": "clamped_to_stroke", "position_m": position_m }),
            _ => serde_json::json!({ "outcome": "accepted", "position_m": null }),
        }))
    }

    /// Waits until the drive is Running (after `enable`).
    fn wait_running(&mut self) -> PyResult<()> {
        drive_test::wait_running(self.c()?).map_err(|e| raise("CommandRefused", format!("{e:#}"), serde_json::json!({})))
    }

    /// Checks rows against the drive's limits (stroke, speed, force, rate,
    /// velocity against position steps); JSON list of problems
    /// {row (0-based), field, message}; empty: fit to send.
    #[pyo3(signature = (t, position, velocity, force = None))]
    fn stream_check(&mut self, t: Vec<f64>, position: Vec<f64>, velocity: Vec<f64>, force: Option<Vec<f64>>) -> PyResult<String> {
        let rows = rows_of(&t, &position, &velocity, force.as_deref());
        let c = self.c()?;
        let p = tool::fetch_params(c, &ControlParams::default()).map_err(link_err)?;
        let period = c.info.as_ref().map_or(0.0, |i| i.stream_period_s);
        // The first point against where the drive's reference rests: a stream
        // starts from rest there.
        let mut limits = StreamLimits::of(&p, period);
        limits.start_reference_m = Some(stream::reference_position(c).map_err(link_err)?);
        let problems = match stream::check_rows("array", &rows, &limits) {
            Ok(()) => vec![],
            Err(e) => format!("{e:#}")
                .lines()
                .filter_map(|l| {
                    let rest = l.strip_prefix("array:")?;
                    let (row, rest) = rest.split_once(':')?;
                    let (field, msg) = rest.split_once(": ")?;
                    let row: usize = row.parse().ok()?;
                    // check_rows counts from 1 (a CSV's data rows); arrays from 0.
                    Some(serde_json::json!({ "row": row - 1, "field": field, "message": msg.replace(&format!("row {}", row - 1), &format!("row {}", row.saturating_sub(2))) }))
                })
                .collect(),
        };
        Ok(json_text(&serde_json::Value::Array(problems)))
    }

    /// Sends the rows as stream points (`paced`: at their times; else back to
    /// back) and ends with Stop. JSON report: refusals as [row (0-based),
    /// reason], tracking RMS/max (µm) from telemetry when `track`.
    #[pyo3(signature = (t, position, velocity, force = None, paced = true, track = true))]
    fn stream(&mut self, t: Vec<f64>, position: Vec<f64>, velocity: Vec<f64>, force: Option<Vec<f64>>, paced: bool, track: bool) -> PyResult<String> {
        let rows = rows_of(&t, &position, &velocity, force.as_deref());
        let c = self.c()?;
        let t0 = Instant::now();
        // Without the GIL: other Python threads run while the points go out.
        let r = Python::with_gil(|py| py.allow_threads(|| stream::send_with(c, &rows, paced, track))).map_err(|e| {
            let mut err = link_err(e);
            // Where the stream was when the link went.
            Python::with_gil(|py| {
                let v = err.value(py).to_string();
                if let Ok(mut j) = serde_json::from_str::<serde_json::Value>(&v) {
                    j["elapsed_s"] = serde_json::json!(t0.elapsed().as_secs_f64());
                    err = NativeError::new_err(j.to_string());
                }
            });
            err
        })?;
        let refusals: Vec<serde_json::Value> = r.refusals.iter().map(|(row, why)| serde_json::json!([row.checked_sub(1), why])).collect();
        Ok(json_text(&serde_json::json!({
            "rows": r.rows,
            "sent": r.sent,
            "duration_s": r.duration_s,
            "wall_s": r.wall_s,
            "refusals": refusals,
            "aborted_at_row": r.aborted_at_row.map(|x| x.saturating_sub(1)),
            "tracking_rms_um": r.tracking_rms_um,
            "tracking_max_um": r.tracking_max_um,
            "telemetry_records": r.telemetry_records,
            "tracking_trace": r.tracking_trace,
            "faults": r.faults,
        })))
    }

    /// A capture of `signals` (names), armed then triggered by command (or
    /// by `trigger` = "fault" / "test_start"), uploaded.
    #[pyo3(signature = (signals, samples, decimation = 1, pre_trigger = 0, trigger = "command", wait_s = 10.0))]
    fn capture(
        &mut self,
        signals: Vec<String>,
        samples: u16,
        decimation: u16,
        pre_trigger: u16,
        trigger: &str,
        wait_s: f64,
    ) -> PyResult<(Vec<String>, f64, usize, Vec<Vec<f64>>)> {
        let sig = signals
            .iter()
            .map(|s| tool::signal_by_name(s).map_err(|e| raise("ValueError", format!("{e:#}"), serde_json::json!({ "field": s }))))
            .collect::<PyResult<Vec<_>>>()?;
        let trig = match trigger {
            "command" => CaptureTrigger::Command,
            "fault" => CaptureTrigger::Fault,
            "test_start" => CaptureTrigger::TestStart,
            t => return Err(raise("ValueError", format!("unknown trigger `{t}`: command, fault or test_start"), serde_json::json!({ "field": "trigger" }))),
        };
        let c = self.c()?;
        if !(wait_s.is_finite() && wait_s > 0.0 && wait_s <= 86_400.0) {
            return Err(raise("InputError", format!("`wait_s` = {wait_s}: a time above 0 and at most a day (86400 s) is needed"), serde_json::json!({ "field": "wait_s" })));
        }
        let wait = Duration::from_secs_f64(wait_s);
        Python::with_gil(|py| py.allow_threads(|| tool::capture(c, &sig, samples, decimation, pre_trigger, trig, wait)))
            .map(capture_tuple)
            .map_err(capture_err)
    }

    /// A step (`chirp_hz` None) or chirp test generated in the core, with the
    /// capture around it (reference, response and two more signals).
    #[pyo3(signature = (target, amplitude, duration_s, chirp_hz = None))]
    fn test(&mut self, target: &str, amplitude: f64, duration_s: f64, chirp_hz: Option<(f64, f64)>) -> PyResult<(Vec<String>, f64, usize, Vec<Vec<f64>>)> {
        let spec = spec_of(target_of(target)?, amplitude, duration_s, chirp_hz);
        let c = self.c()?;
        let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
        Python::with_gil(|py| py.allow_threads(|| drive_test::capture_test(c, &spec, pwm))).map(capture_tuple).map_err(capture_err)
    }

    /// The same test on a fresh simulated drive (the shipped rig, or `rig`)
    /// with this drive's parameters, from `position_m`: the model's answer.
    #[pyo3(signature = (target, amplitude, duration_s, chirp_hz = None, position_m = 0.25, rig = None))]
    fn predict(
        &mut self,
        target: &str,
        amplitude: f64,
        duration_s: f64,
        chirp_hz: Option<(f64, f64)>,
        position_m: f64,
        rig: Option<std::path::PathBuf>,
    ) -> PyResult<(Vec<String>, f64, usize, Vec<Vec<f64>>)> {
        let spec = spec_of(target_of(target)?, amplitude, duration_s, chirp_hz);
        let rig = RigConfig::load_or_nominal(rig.as_ref()).map_err(|e| raise("DriveError", format!("{e:#}"), serde_json::json!({})))?;
        let params = tool::fetch_params(self.c()?, &rig.control).map_err(link_err)?;
        Python::with_gil(|py| py.allow_threads(|| drive_test::predict(&rig, params, position_m, &spec))).map(capture_tuple).map_err(capture_err)
    }

    /// Starts telemetry of `fields` (names) at `rate_hz`; 0 stops it.
    fn telemetry_start(&mut self, fields: Vec<String>, rate_hz: u16) -> PyResult<()> {
        let mut mask = 0u32;
        for f in &fields {
            let bit = view::TELEMETRY_NAMES.iter().position(|n| n == f).ok_or_else(|| {
                raise("ValueError", format!("unknown telemetry field `{f}`; one of {}", view::TELEMETRY_NAMES.join(", ")), serde_json::json!({ "field": f }))
            })?;
            mask |= 1 << bit;
        }
        self.ask(Request::Telemetry { fields: mask, rate_hz })?;
        self.c()?.telemetry.clear();
        Ok(())
    }

    /// Telemetry records received within `wait_s`: (time_s, {name: value}) in arrival order.
    fn telemetry_poll(&mut self, wait_s: f64) -> PyResult<Vec<(f32, Vec<(String, f32)>)>> {
        let c = self.c()?;
        let wait = Duration::from_secs_f64(if wait_s.is_finite() { wait_s.clamp(0.0, 86_400.0) } else { 0.0 });
        Python::with_gil(|py| py.allow_threads(|| c.poll(wait))).map_err(link_err)?;
        Ok(c.telemetry
            .drain(..)
            .map(|t| {
                let names = (0..TelemetryField::COUNT).filter(|b| t.fields & (1 << b) != 0).map(|b| view::TELEMETRY_NAMES[b as usize].to_string());
                (t.time_s, names.zip(t.values.iter().copied()).collect())
            })
            .collect())
    }
}

fn capture_err(e: anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    if msg.contains("refused") {
        raise("Refused", msg, serde_json::json!({}))
    } else {
        link_err(e)
    }
}

fn spec_of(target: Target, amplitude: f64, duration_s: f64, chirp_hz: Option<(f64, f64)>) -> Spec {
    match chirp_hz {
        Some((a, b)) => Spec::chirp(target, amplitude, a, b, duration_s),
        None => Spec::step(target, amplitude, duration_s),
    }
}

fn rows_of(t: &[f64], position: &[f64], velocity: &[f64], force: Option<&[f64]>) -> Vec<Row> {
    (0..t.len())
        .map(|k| Row { t_s: t[k], position_m: position[k], velocity_m_s: velocity[k], force_n: force.map(|f| f[k]) })
        .collect()
}

fn check_schema(info: &Info) -> PyResult<()> {
    for (what, drive, ours) in [("schema", info.schema_hash, SCHEMA_HASH), ("parameter schema", info.params_schema_hash, PARAMS_SCHEMA_HASH)] {
        if drive != ours {
            return Err(raise(
                "SchemaMismatch",
                format!(
                    "{what} mismatch: the drive ({}, firmware {} {}) speaks {what} {}, this package {}; build both from the same protocol definition",
                    info.board,
                    info.firmware_version,
                    info.git_hash,
                    client::hex(&drive),
                    client::hex(&ours)
                ),
                serde_json::json!({ "drive_hash": client::hex(&drive), "package_hash": client::hex(&ours), "field": what }),
            ));
        }
    }
    Ok(())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("NativeError", m.py().get_type::<NativeError>())?;
    m.add_class::<NativeDrive>()?;
    m.add_function(wrap_pyfunction!(param_paths, m)?)?;
    m.add_function(wrap_pyfunction!(signal_names, m)?)?;
    m.add_function(wrap_pyfunction!(schema_hashes, m)?)?;
    m.add_function(wrap_pyfunction!(defaults, m)?)?;
    m.add_function(wrap_pyfunction!(paper_reference, m)?)?;
    m.add_function(wrap_pyfunction!(encode_info_reply, m)?)?;
    m.add_function(wrap_pyfunction!(step_figures, m)?)?;
    m.add_function(wrap_pyfunction!(frf_h1, m)?)?;
    m.add("HOST_SIM_TARGET_DIR", concat!(env!("CARGO_MANIFEST_DIR"), "/../target"))?;
    Ok(())
}
