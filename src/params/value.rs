//! A parameter's value and type, as the leaf table and the record hold it.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// A parameter's value, typed as the parameter is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Value {
    F32(f32),
    U32(u32),
    I32(i32),
    Bool(bool),
    /// An enum parameter by variant index (e.g. `homing.method`: 0 hard stop,
    /// 1 switch).
    Variant(u8),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ValueKind {
    F32,
    U32,
    I32,
    Bool,
    Variant,
}

