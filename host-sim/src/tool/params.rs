//! Parameter values as a person types and reads them.

use servo_core::protocol::{Value, ValueKind};

/// `PATH` with the `control.` prefix the drive's paths carry (the rig
/// file's table); given with or without it.
pub fn full_path(path: &str) -> String {
    if path.starts_with("control.") {
        path.to_string()
    } else {
        format!("control.{path}")
    }
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

/// The serde name of variant `index` of the enum leaf at `path` (as the rig
/// file writes it, e.g. `HardStop`), found by setting it on a copy of the
/// defaults and reading the serialised field back.
pub fn variant_name(path: &str, index: u8) -> Option<String> {
    let mut p = servo_core::params::ControlParams::default();
    servo_core::protocol::params::set(&mut p, path, Value::Variant(index)).ok()?;
    let json = serde_json::to_value(p).ok()?;
    let mut at = &json;
    for part in path.trim_start_matches("control.").split('.') {
        at = at.get(part)?;
    }
    at.as_str().map(str::to_string)
}

/// The variant index named `name` (or given as its index) for `path`.
pub fn variant_index(path: &str, name: &str) -> Option<u8> {
    if let Ok(i) = name.parse::<u8>() {
        return variant_name(path, i).map(|_| i);
    }
    (0..=u8::MAX).map_while(|i| variant_name(path, i).map(|n| (i, n))).find(|(_, n)| n == name).map(|(i, _)| i)
}

/// A value as `param list` prints it: enums by name.
pub fn value_text_at(path: &str, v: &Value) -> String {
    match v {
        Value::Variant(i) => variant_name(path, *i).unwrap_or_else(|| format!("{i}")),
        v => value_text(v),
    }
}

/// Parses `text` for the leaf at `path`: enums by name or index.
pub fn parse_value_at(path: &str, kind: ValueKind, text: &str) -> Result<Value, String> {
    if kind == ValueKind::Variant {
        let names: Vec<String> = (0..=u8::MAX).map_while(|i| variant_name(path, i)).collect();
        return variant_index(path, text.trim())
            .map(Value::Variant)
            .ok_or_else(|| format!("`{text}` is not one of {}", names.join(", ")));
    }
    parse_value(kind, text)
}
