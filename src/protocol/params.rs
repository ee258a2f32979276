//! Parameters by dotted path: `control.speed_pi.kp` is the field
//! `ControlParams::speed_pi.kp` (the `control.` prefix is the rig file's
//! `[control]` table, so a path here is a path there).
//!
//! The paths come from `miniconf::Tree`, derived on `ControlParams` and its
//! sub-structs: adding a field adds its path and index without a table of
//! names to keep in step. A path is resolved to its leaf index through the
//! tree's static schema (generic code over data), and the leaf is read and
//! written through `params::leaves` (offset and type per index): the
//! derived typed lookup (`TreeAny`, ≈ 5 KB in the image) is kept only as
//! the reference the table is tested against ([`tree`]).

use miniconf::{Internal, Schema, TreeSchema};

use super::messages::Path;
use crate::params::{Value, ValueKind};
use crate::params::leaves::{self, LeafError};
use crate::params::ControlParams;

/// The table the paths start with.
pub const PREFIX: &str = "control";

/// Number of leaves (parameters) of `ControlParams`.
pub const PARAM_COUNT: usize = ControlParams::SCHEMA.shape().count.get();

// The leaf table has a row for every leaf of the tree (its order and types
// are checked by a test, leaf by leaf).
const _: () = assert!(leaves::LEAF_COUNT == PARAM_COUNT);

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

/// The leaf index of `path` (`control.` then the tree's names), through
/// the tree's static schema: generic code over data, not the derived
/// per-struct lookup. `None` for an unknown path or a group.
pub fn index_of(path: &str) -> Option<usize> {
    let rest = path.strip_prefix(PREFIX)?.strip_prefix('.')?;
    let mut schema = ControlParams::SCHEMA;
    let mut index = 0usize;
    for name in rest.split('.') {
        let Some(Internal::Named(children)) = schema.internal() else {
            // Past a leaf (or a numbered node, which `ControlParams` has none of).
            return None;
        };
        let mut found = None;
        for child in children.iter() {
            if child.name() == name {
                found = Some(child.schema());
                break;
            }
            index = index.saturating_add(leaf_count(child.schema()));
        }
        schema = found?;
    }
    schema.is_leaf().then_some(index)
}

/// The value at `path`.
pub fn get(p: &ControlParams, path: &str) -> Result<Value, PathError> {
    index_of(path).and_then(|i| leaves::get(p, i)).ok_or(PathError::Unknown)
}

/// The type of the parameter at `path`.
pub fn kind(path: &str) -> Result<ValueKind, PathError> {
    index_of(path).and_then(leaves::leaf).map(|l| l.kind).ok_or(PathError::Unknown)
}

/// Writes `value` at `path` (no validation: that is the caller's, on the
/// whole set). Nothing changes on an error.
pub fn set(p: &mut ControlParams, path: &str, value: Value) -> Result<(), PathError> {
    let i = index_of(path).ok_or(PathError::Unknown)?;
    leaves::set(p, i, value).map_err(|e| match e {
        LeafError::Unknown => PathError::Unknown,
        LeafError::WrongType(k) => PathError::WrongType(k),
        LeafError::NoSuchVariant => PathError::NoSuchVariant,
    })
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
    let kind = leaves::leaf(index)?.kind;
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

/// The same leaves through the tree's own typed lookup (`TreeAny`): the
/// reference [`leaves`](crate::params::leaves) is tested against (every
/// leaf set through one and read through the other). Not used by the
/// drive, so not in the image.
pub mod tree {
    use core::any::Any;

    use miniconf::{ConstPathIter, TreeAny};

    use super::PREFIX;
    use crate::params::{ControlParams, HomingMethod};
    use crate::params::Value;

    fn leaf<'a>(p: &'a mut ControlParams, path: &str) -> Option<&'a mut dyn Any> {
        path.strip_prefix(PREFIX)?.strip_prefix('.')?;
        // `root` skips the first segment (`control`, checked above).
        p.mut_any_by_key(ConstPathIter::<'_, '.'>::root(path)).ok()
    }

    /// The value at `path`, through the tree.
    pub fn get(p: &ControlParams, path: &str) -> Option<Value> {
        let mut copy = *p;
        let any = leaf(&mut copy, path)?;
        if let Some(v) = any.downcast_ref::<f32>() {
            Some(Value::F32(*v))
        } else if let Some(v) = any.downcast_ref::<u32>() {
            Some(Value::U32(*v))
        } else if let Some(v) = any.downcast_ref::<i32>() {
            Some(Value::I32(*v))
        } else if let Some(v) = any.downcast_ref::<bool>() {
            Some(Value::Bool(*v))
        } else {
            any.downcast_ref::<HomingMethod>().map(|m| Value::Variant(*m as u8))
        }
    }

    /// Writes `value` at `path` through the tree; false if the path or the
    /// type does not match.
    pub fn set(p: &mut ControlParams, path: &str, value: Value) -> bool {
        let Some(any) = leaf(p, path) else { return false };
        match value {
            Value::F32(v) => any.downcast_mut::<f32>().map(|s| *s = v).is_some(),
            Value::U32(v) => any.downcast_mut::<u32>().map(|s| *s = v).is_some(),
            Value::I32(v) => any.downcast_mut::<i32>().map(|s| *s = v).is_some(),
            Value::Bool(v) => any.downcast_mut::<bool>().map(|s| *s = v).is_some(),
            Value::Variant(i) => {
                let m = match i {
                    0 => HomingMethod::HardStop,
                    1 => HomingMethod::Switch,
                    _ => return false,
                };
                any.downcast_mut::<HomingMethod>().map(|s| *s = m).is_some()
            }
        }
    }
}
