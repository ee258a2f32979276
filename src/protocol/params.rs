//! Parameters by dotted path: `control.speed_pi.kp` is the field
//! `ControlParams::speed_pi.kp` (the `control.` prefix is the rig file's
//! `[control]` table, so a path here is a path there).
//!
//! The paths come from `miniconf::Tree`, derived on `ControlParams` and its
//! sub-structs: adding a field adds its path, its index and its type
//! without a table to keep in step. Values are read and written through
//! `TreeAny` (a typed reference to the leaf), so no codec runs here.

use core::any::Any;

use miniconf::{ConstPathIter, Internal, Schema, TreeAny, TreeSchema};

use super::messages::{Path, Value, ValueKind};
use crate::params::{ControlParams, HomingMethod};

/// The table the paths start with.
pub const PREFIX: &str = "control";

/// Number of leaves (parameters) of `ControlParams`.
pub const PARAM_COUNT: usize = ControlParams::SCHEMA.shape().count.get();

// Every path fits a `Path` with its prefix.
const _: () = assert!(PREFIX.len() + ControlParams::SCHEMA.max_length(".") <= super::messages::PATH_MAX);

/// Why a path could not be read or written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathError {
    /// No leaf at this path (a group like `control.motor` is not a leaf).
    Unknown,
    /// The leaf has this type, not the value's.
    WrongType(ValueKind),
    /// An enum parameter has no variant with this index.
    NoSuchVariant,
}

/// The key cursor for `path`, if it starts with `control.`.
fn keys(path: &str) -> Option<ConstPathIter<'_, '.'>> {
    let rest = path.strip_prefix(PREFIX)?;
    if !rest.starts_with('.') {
        return None;
    }
    // `root` skips the first segment (`control`, checked above).
    Some(ConstPathIter::root(path))
}

fn kind_of(any: &dyn Any) -> Option<ValueKind> {
    if any.is::<f32>() {
        Some(ValueKind::F32)
    } else if any.is::<u32>() {
        Some(ValueKind::U32)
    } else if any.is::<i32>() {
        Some(ValueKind::I32)
    } else if any.is::<bool>() {
        Some(ValueKind::Bool)
    } else if any.is::<HomingMethod>() {
        Some(ValueKind::Variant)
    } else {
        None
    }
}

fn value_of(any: &dyn Any) -> Option<Value> {
    if let Some(v) = any.downcast_ref::<f32>() {
        Some(Value::F32(*v))
    } else if let Some(v) = any.downcast_ref::<u32>() {
        Some(Value::U32(*v))
    } else if let Some(v) = any.downcast_ref::<i32>() {
        Some(Value::I32(*v))
    } else if let Some(v) = any.downcast_ref::<bool>() {
        Some(Value::Bool(*v))
    } else {
        any.downcast_ref::<HomingMethod>().map(|m| Value::Variant(homing_method_index(*m)))
    }
}

const fn homing_method_index(m: HomingMethod) -> u8 {
    match m {
        HomingMethod::HardStop => 0,
        HomingMethod::Switch => 1,
    }
}

const fn homing_method(index: u8) -> Option<HomingMethod> {
    match index {
        0 => Some(HomingMethod::HardStop),
        1 => Some(HomingMethod::Switch),
        _ => None,
    }
}

/// The leaf at `path` of `p`. Reads go through the mutable lookup too (on
/// a copy): `ref_any_by_key` and `mut_any_by_key` are each ≈ 4.6 KB of
/// derived code in the image, and one lookup serves all three uses.
fn leaf<'a>(p: &'a mut ControlParams, path: &str) -> Result<&'a mut dyn Any, PathError> {
    let keys = keys(path).ok_or(PathError::Unknown)?;
    p.mut_any_by_key(keys).map_err(|_| PathError::Unknown)
}

/// The value at `path`.
pub fn get(p: &ControlParams, path: &str) -> Result<Value, PathError> {
    let mut copy = *p;
    value_of(leaf(&mut copy, path)?).ok_or(PathError::Unknown)
}

/// The type of the parameter at `path`.
pub fn kind(path: &str) -> Result<ValueKind, PathError> {
    let mut copy = ControlParams::DEFAULT;
    kind_of(leaf(&mut copy, path)?).ok_or(PathError::Unknown)
}

/// Writes `value` at `path` (no validation: that is the caller's, on the
/// whole set). Nothing changes on an error.
pub fn set(p: &mut ControlParams, path: &str, value: Value) -> Result<(), PathError> {
    let any = leaf(p, path)?;
    let expected = kind_of(any).ok_or(PathError::Unknown)?;
    let wrong = PathError::WrongType(expected);
    match value {
        Value::F32(v) => *any.downcast_mut::<f32>().ok_or(wrong)? = v,
        Value::U32(v) => *any.downcast_mut::<u32>().ok_or(wrong)? = v,
        Value::I32(v) => *any.downcast_mut::<i32>().ok_or(wrong)? = v,
        Value::Bool(v) => *any.downcast_mut::<bool>().ok_or(wrong)? = v,
        Value::Variant(i) => {
            let slot = any.downcast_mut::<HomingMethod>().ok_or(wrong)?;
            *slot = homing_method(i).ok_or(PathError::NoSuchVariant)?;
        }
    }
    Ok(())
}

/// Path and type of leaf `index` (0-based, depth-first in declaration
/// order: stable for a schema hash).
pub fn name(index: usize) -> Option<(Path, ValueKind)> {
    let mut path = Path::new();
    path.push_str(PREFIX).ok()?;
    let mut left = index;
    if !nth_leaf(ControlParams::SCHEMA, &mut left, &mut path) {
        return None;
    }
    let kind = kind(&path).ok()?;
    Some((path, kind))
}

/// Leaves under `schema` (`Shape::count` without its `unwrap`s at run time).
fn leaf_count(schema: &'static Schema) -> usize {
    match schema.internal() {
        None => 1,
        Some(Internal::Named(children)) => children.iter().map(|c| leaf_count(c.schema())).sum(),
        Some(Internal::Numbered(children)) => children.iter().map(|c| leaf_count(c.schema())).sum(),
        Some(Internal::Homogeneous(h)) => h.len().get().saturating_mul(leaf_count(h.schema())),
    }
}

/// Walks `schema` depth-first, counting `left` down over its leaves, and
/// appends the names on the way to leaf number `left` to `path`. Written
/// out (rather than `Schema::nodes`) so that no indexing or `unreachable!`
/// of the iterator is on the protocol's path (panic-never proof).
fn nth_leaf(schema: &'static Schema, left: &mut usize, path: &mut Path) -> bool {
    let Some(Internal::Named(children)) = schema.internal() else {
        // A leaf (or a numbered node, which `ControlParams` has none of).
        return false;
    };
    for child in children.iter() {
        let leaves = leaf_count(child.schema());
        if *left >= leaves {
            *left = left.saturating_sub(leaves);
            continue;
        }
        if path.push('.').is_err() || path.push_str(child.name()).is_err() {
            return false;
        }
        return child.schema().is_leaf() || nth_leaf(child.schema(), left, path);
    }
    false
}
