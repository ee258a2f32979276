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
