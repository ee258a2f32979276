//! `param export FILE` / `param import FILE`: the drive's parameters as a
//! TOML `[control]` table, the rig file's own layout (enums by name), and
//! back.

use super::client::{describe, param_path, Client};
use super::params::{value_text_at, variant_index};
use super::{fetch_params, param_index};
use anyhow::{anyhow, bail, Context, Result};
use servo_core::params::{ControlParams, ValidatedParams};
use servo_core::protocol::{self, Error, Reply, Request, Value, ValueKind};
use std::path::Path;

#[derive(serde::Serialize)]
struct Export {
    control: ControlParams,
}

/// Writes every parameter of the drive to `path` as `[control]` TOML.
pub fn export(c: &mut Client, path: &Path) -> Result<usize> {
    let p = fetch_params(c, &ControlParams::default())?;
    let who = c.info.as_ref().map(|i| format!("{} firmware {} {}", i.board, i.firmware_version, i.git_hash)).unwrap_or_default();
    let body = toml::to_string(&Export { control: p }).context("serialising the parameters")?;
    let text = format!("# Drive parameters ({who}), `host-sim drive param export`.\n# `host-sim drive param import FILE` sets them back.\n\n{body}");
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d).ok();
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(protocol::params::PARAM_COUNT)
}

/// The leaves a TOML file gives: (path, value), each checked against the
/// leaf's type; errors name the file and the path.
pub fn read_leaves(path: &Path) -> Result<Vec<(String, Value)>> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {name}"))?;
    let table: toml::Table = text.parse().map_err(|e| anyhow!("{name}: not TOML: {e}"))?;
    let mut out = Vec::new();
    let mut errors = Vec::new();
    fn walk(prefix: &str, t: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
        for (k, v) in t {
            let p = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
            match v {
                toml::Value::Table(sub) => walk(&p, sub, out),
                v => out.push((p, v.clone())),
            }
        }
    }
    let mut raw = Vec::new();
    walk("", &table, &mut raw);
    for (p, v) in raw {
        let Some(index) = protocol::params::index_of(&p) else {
            errors.push(format!("{name}: `{p}`: no such parameter{} (`param list` shows them)", suggestion(&p)));
            continue;
        };
        let Some((_, kind)) = protocol::params::name(index) else {
            errors.push(format!("{name}: `{p}`: no such parameter"));
            continue;
        };
        let value = match (kind, &v) {
            (ValueKind::F32, toml::Value::Float(x)) => Some(Value::F32(*x as f32)),
            (ValueKind::F32, toml::Value::Integer(x)) => Some(Value::F32(*x as f32)),
            (ValueKind::U32, toml::Value::Integer(x)) => u32::try_from(*x).ok().map(Value::U32),
            (ValueKind::I32, toml::Value::Integer(x)) => i32::try_from(*x).ok().map(Value::I32),
            (ValueKind::Bool, toml::Value::Boolean(b)) => Some(Value::Bool(*b)),
            (ValueKind::Variant, toml::Value::String(s)) => variant_index(&p, s).map(Value::Variant),
            _ => None,
        };
        match value {
            Some(Value::F32(x)) if !x.is_finite() => errors.push(format!("{name}: `{p}`: {v} is not a finite number")),
            Some(value) => out.push((p, value)),
            None => errors.push(format!("{name}: `{p}`: {v} is not {}", kind_text(&p, kind))),
        }
    }
    if out.is_empty() && errors.is_empty() {
        bail!("{name}: no parameters (a `[control.…]` table of `path = value` lines, as `param export` writes); nothing was sent to the drive");
    }
    if !errors.is_empty() {
        bail!("{}\nnothing was sent to the drive", errors.join("\n"));
    }
    Ok(out)
}

/// Sets the file's parameters on the drive: checked whole first (types,
/// ranges, the set as a whole), then the changed leaves set one by one,
/// in as many passes as the set's own order needs; a refusal rolls back
/// what was set. Returns the leaves changed.
pub fn import(c: &mut Client, path: &Path) -> Result<Vec<String>> {
    let leaves = read_leaves(path)?;
    let live = fetch_params(c, &ControlParams::default())?;
    let mut target = live;
    for (p, v) in &leaves {
        protocol::params::set(&mut target, p, *v).map_err(|e| anyhow!("{}: `{p}`: {e:?}", path.display()))?;
    }
    if let Err(e) = ValidatedParams::new(target) {
        let p = param_path(e.leaf);
        bail!("{}: `{p}`: {}; nothing was sent to the drive", path.display(), e.reason);
    }
    let mut pending: Vec<(String, Value, Value)> = leaves
        .iter()
        .filter_map(|(p, v)| {
            let old = protocol::params::get(&live, p).ok()?;
            (old != *v).then(|| (p.clone(), *v, old))
        })
        .collect();
    let mut done: Vec<(String, Value)> = Vec::new();
    while !pending.is_empty() {
        let before = done.len();
        let mut next = Vec::new();
        let mut last_refusal = String::new();
        for (p, v, old) in pending.drain(..) {
            match c.request(Request::ParamSet { index: param_index(&p)?, value: v })? {
                Reply::Param { .. } => done.push((p, old)),
                // Perhaps valid only once another leaf of the file is in.
                Reply::Error(e @ Error::InvalidParam { .. }) => {
                    last_refusal = format!("`{p}`: {}", describe(&e));
                    next.push((p, v, old));
                }
                Reply::Error(e) => {
                    let why = describe(&e);
                    rollback(c, &done);
                    bail!("{}: `{p}`: {why}; the {} leaves set before it were set back", path.display(), done.len());
                }
                r => bail!("ParamSet {p}: unexpected {r:?}"),
            }
        }
        if !next.is_empty() && done.len() == before {
            rollback(c, &done);
            bail!("{}: the drive refused {last_refusal}; the {} leaves set before were set back", path.display(), done.len());
        }
        pending = next;
    }
    Ok(done.into_iter().map(|(p, _)| p).collect())
}

fn rollback(c: &mut Client, done: &[(String, Value)]) {
    for (p, old) in done.iter().rev() {
        if let Ok(index) = param_index(p) {
            let _ = c.request(Request::ParamSet { index, value: *old });
        }
    }
}

/// `param list` lines: `path = value`, enums by name.
pub fn list_lines(list: &[(String, Value)]) -> Vec<String> {
    list.iter().map(|(p, v)| format!("{p} = {}", value_text_at(p, v))).collect()
}

/// What a leaf of `kind` takes, in words (enums: their names).
fn kind_text(path: &str, kind: ValueKind) -> String {
    match kind {
        ValueKind::F32 => "a number".into(),
        ValueKind::U32 => "an unsigned integer".into(),
        ValueKind::I32 => "an integer".into(),
        ValueKind::Bool => "true or false".into(),
        ValueKind::Variant => {
            let names: Vec<String> = (0..=u8::MAX).map_while(|i| super::params::variant_name(path, i)).collect();
            format!("one of \"{}\"", names.join("\", \""))
        }
    }
}

/// `: did you mean `…`?` for a path one typo (or the `control.` table)
/// away from a parameter; else nothing.
pub fn suggestion(path: &str) -> String {
    let under_control = format!("control.{path}");
    if protocol::params::index_of(&under_control).is_some() {
        return format!(": the parameters are under `[control]`: `{under_control}`");
    }
    let best = (0..protocol::params::PARAM_COUNT)
        .filter_map(|i| u16::try_from(i).ok().map(param_path))
        .map(|c| (edit_distance(path, &c), c))
        .min_by_key(|(d, _)| *d);
    match best {
        // Up to two edits, or a quarter of the path for long ones.
        Some((d, c)) if d <= 2.max(path.len() / 4) => format!(": did you mean `{c}`?"),
        _ => String::new(),
    }
}

/// Levenshtein distance over characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}
