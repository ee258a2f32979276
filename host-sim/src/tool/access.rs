//! Parameters, commands and the drive's identity over a connected client:
//! the requests every command of the tool is built from.

use super::client::{self, Client};
use super::{params, view};
use anyhow::{anyhow, bail, Result};
use servo_core::protocol::{DriveCommand, Reply, Request, Value};
use servo_core::ControlParams;

pub fn fetch_one_f32(c: &mut Client, path: &str) -> Option<f32> {
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
        .ok_or_else(|| anyhow!("no parameter `{full}`{}; `param list` shows them", super::config_file::suggestion(&full)))
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
