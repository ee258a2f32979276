//! Parameter paths on the host: the dotted leaves of `control.*` (as the rig
//! file names them), read and written through the serde form of
//! `ControlParams`.
//!
//! Interim: the core's `Server` (branch core-server) owns the paths on the
//! board (miniconf); the simulated drive uses this until it is merged, and
//! the host tool uses it for the offline prediction.

use servo_core::protocol::{Value, ValueKind};
use servo_core::ControlParams;

/// Every leaf as (path without the `control.` prefix, kind), in a stable
/// order (struct field order).
pub fn leaves(p: &ControlParams) -> Vec<(String, ValueKind)> {
    let v = serde_json::to_value(p).expect("params serialise");
    let mut out = Vec::new();
    walk("", &v, &mut out);
    out
}

fn walk(prefix: &str, v: &serde_json::Value, out: &mut Vec<(String, ValueKind)>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let p = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                walk(&p, x, out);
            }
        }
        other => {
            if let Some(kind) = kind_of(other) {
                out.push((prefix.to_string(), kind));
            }
        }
    }
}

fn kind_of(v: &serde_json::Value) -> Option<ValueKind> {
    match v {
        serde_json::Value::Bool(_) => Some(ValueKind::Bool),
        serde_json::Value::Number(n) if n.is_u64() => Some(ValueKind::U32),
        serde_json::Value::Number(n) if n.is_i64() => Some(ValueKind::I32),
        serde_json::Value::Number(_) => Some(ValueKind::F32),
        serde_json::Value::String(_) => Some(ValueKind::Variant),
        _ => None,
    }
}

/// Strips an optional leading `control.`.
pub fn normalise(path: &str) -> &str {
    path.strip_prefix("control.").unwrap_or(path)
}

fn lookup<'a>(v: &'a mut serde_json::Value, path: &str) -> Option<&'a mut serde_json::Value> {
    let mut cur = v;
    for part in normalise(path).split('.') {
        cur = cur.as_object_mut()?.get_mut(part)?;
    }
    (!cur.is_object()).then_some(cur)
}

/// Variant names of the enum parameters, by index (as `Value::Variant`).
fn variants(path: &str) -> &'static [&'static str] {
    match normalise(path) {
        "homing.method" => &["HardStop", "Switch"],
        _ => &[],
    }
}

#[derive(Debug, PartialEq)]
pub enum PathError {
    Unknown,
    WrongType(ValueKind),
    Invalid(String),
}

pub fn get(p: &ControlParams, path: &str) -> Result<Value, PathError> {
    let mut v = serde_json::to_value(p).expect("params serialise");
    let leaf = lookup(&mut v, path).ok_or(PathError::Unknown)?;
    Ok(match leaf {
        serde_json::Value::Bool(b) => Value::Bool(*b),
        serde_json::Value::Number(n) if n.is_u64() => Value::U32(n.as_u64().unwrap_or(0) as u32),
        serde_json::Value::Number(n) if n.is_i64() => Value::I32(n.as_i64().unwrap_or(0) as i32),
        serde_json::Value::Number(n) => Value::F32(n.as_f64().unwrap_or(f64::NAN) as f32),
        serde_json::Value::String(s) => Value::Variant(variants(path).iter().position(|x| x == s).unwrap_or(0) as u8),
        _ => return Err(PathError::Unknown),
    })
}

/// A copy of `p` with `path` set to `value`, validated as a whole set.
pub fn set(p: &ControlParams, path: &str, value: Value) -> Result<ControlParams, PathError> {
    let mut v = serde_json::to_value(p).expect("params serialise");
    let leaf = lookup(&mut v, path).ok_or(PathError::Unknown)?;
    let kind = kind_of(leaf).ok_or(PathError::Unknown)?;
    let new = match (kind, value) {
        (ValueKind::F32, Value::F32(x)) => {
            if !x.is_finite() {
                return Err(PathError::Invalid("not finite".into()));
            }
            serde_json::json!(x)
        }
        // An integer given for a float parameter is taken as that number.
        (ValueKind::F32, Value::U32(x)) => serde_json::json!(x as f32),
        (ValueKind::F32, Value::I32(x)) => serde_json::json!(x as f32),
        (ValueKind::U32, Value::U32(x)) => serde_json::json!(x),
        (ValueKind::I32, Value::I32(x)) => serde_json::json!(x),
        (ValueKind::I32, Value::U32(x)) if x <= i32::MAX as u32 => serde_json::json!(x),
        (ValueKind::Bool, Value::Bool(b)) => serde_json::json!(b),
        (ValueKind::Variant, Value::Variant(i)) => match variants(path).get(usize::from(i)) {
            Some(name) => serde_json::json!(name),
            None => return Err(PathError::Invalid(format!("variant {i} out of range"))),
        },
        (k, _) => return Err(PathError::WrongType(k)),
    };
    *leaf = new;
    let out: ControlParams = serde_json::from_value(v).map_err(|e| PathError::Invalid(e.to_string()))?;
    out.validate().map_err(|e| PathError::Invalid(format!("{e}")))?;
    Ok(out)
}

/// Parses a value typed as the parameter is (`true`, `12`, `0.5`, `-3`).
pub fn parse_value(kind: ValueKind, text: &str) -> Result<Value, String> {
    let t = text.trim();
    let bad = |what: &str| format!("`{text}` is not {what}");
    Ok(match kind {
        ValueKind::F32 => Value::F32(t.parse::<f32>().map_err(|_| bad("a number"))?),
        ValueKind::U32 => Value::U32(t.parse::<u32>().map_err(|_| bad("an unsigned integer"))?),
        ValueKind::I32 => Value::I32(t.parse::<i32>().map_err(|_| bad("an integer"))?),
        ValueKind::Bool => Value::Bool(match t {
            "true" | "1" | "on" => true,
            "false" | "0" | "off" => false,
            _ => return Err(bad("a boolean")),
        }),
        ValueKind::Variant => Value::Variant(t.parse::<u8>().map_err(|_| bad("a variant index"))?),
    })
}

pub fn value_text(v: &Value) -> String {
    match v {
        Value::F32(x) => format!("{x}"),
        Value::U32(x) => format!("{x}"),
        Value::I32(x) => format!("{x}"),
        Value::Bool(b) => format!("{b}"),
        Value::Variant(i) => format!("{i}"),
    }
}

/// Writes `value` into `p` (a typed value as `get` returns it).
pub fn value_f64(v: &Value) -> f64 {
    match v {
        Value::F32(x) => f64::from(*x),
        Value::U32(x) => f64::from(*x),
        Value::I32(x) => f64::from(*x),
        Value::Bool(b) => f64::from(u8::from(*b)),
        Value::Variant(i) => f64::from(*i),
    }
}
