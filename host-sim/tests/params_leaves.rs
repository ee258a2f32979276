//! The drive's leaf table (`params::leaves`: offset and type per index)
//! against the `miniconf` tree (paths and the derived typed lookup): for
//! every one of the leaves, a value written through one is read back
//! through the other, and the path the server resolves is the tree's.

mod protocol_support;

use protocol_support::crc32;
use servo_core::params::leaves::{self, LEAF_COUNT};
use servo_core::params::record::{self, RecordError, RECORD_MAX};
use servo_core::protocol::params::{self as paths, tree};
use servo_core::protocol::{Value, ValueKind};
use servo_core::ControlParams;

/// A value of `kind` that differs from `old` (and from the defaults' values
/// of the other leaves, for floats: `i` makes it unique).
fn other_value(kind: ValueKind, old: Value, i: usize) -> Value {
    match (kind, old) {
        (ValueKind::F32, Value::F32(v)) => Value::F32(v + 1000.0 + i as f32),
        (ValueKind::U32, Value::U32(v)) => Value::U32(v + 1000 + i as u32),
        (ValueKind::I32, Value::I32(v)) => Value::I32(v - 1000 - i as i32),
        (ValueKind::Bool, Value::Bool(v)) => Value::Bool(!v),
        (ValueKind::Variant, Value::Variant(v)) => Value::Variant(1 - v),
        other => panic!("leaf {i}: kind and value disagree: {other:?}"),
    }
}

#[test]
fn table_and_tree_agree_on_every_leaf() {
    assert_eq!(LEAF_COUNT, paths::PARAM_COUNT);
    assert_eq!(LEAF_COUNT, 122);
    let base = ControlParams::DEFAULT;
    for i in 0..LEAF_COUNT {
        let (path, kind) = paths::name(i).unwrap();
        assert_eq!(paths::index_of(&path), Some(i), "{path}");
        assert_eq!(leaves::path(i), path.as_str(), "the table's own path list");
        let old = leaves::get(&base, i).unwrap();
        assert_eq!(tree::get(&base, &path), Some(old), "{path}: read through both");
        let new = other_value(kind, old, i);

        // Set through the table, read through the tree: only this leaf moved.
        let mut p = base;
        leaves::set(&mut p, i, new).unwrap();
        assert_eq!(tree::get(&p, &path), Some(new), "{path}: table -> tree");
        let mut back = p;
        assert!(tree::set(&mut back, &path, old), "{path}");
        assert_eq!(back, base, "{path}: the table wrote another field");

        // Set through the tree, read through the table (and the path API).
        let mut q = base;
        assert!(tree::set(&mut q, &path, new), "{path}");
        assert_eq!(leaves::get(&q, i), Some(new), "{path}: tree -> table");
        assert_eq!(paths::get(&q, &path), Ok(new), "{path}");
        assert_eq!(q, p, "{path}");

        // The record's word round-trips the leaf.
        let mut r = base;
        leaves::from_word(&mut r, i, leaves::to_word(&p, i).unwrap()).unwrap();
        assert_eq!(r, p, "{path}: record word");
    }
    assert_eq!(leaves::get(&base, LEAF_COUNT), None);
    assert!(leaves::set(&mut base.clone(), LEAF_COUNT, Value::F32(1.0)).is_err());
}

#[test]
fn groups_unknown_names_and_extra_segments_are_not_leaves() {
    for p in [
        "control",
        "control.",
        "control.speed_pi",
        "control.speed_pi.kq",
        "speed_pi.kp",
        "control.speed_pi.kp.x",
        "controlx.speed_pi.kp",
        "",
    ] {
        assert_eq!(paths::index_of(p), None, "{p}");
    }
}

#[test]
fn a_record_word_that_is_not_a_value_of_its_leaf_is_refused() {
    let bool_leaf = (0..LEAF_COUNT).find(|&i| leaves::leaf(i).unwrap().kind == ValueKind::Bool).unwrap();
    let variant_leaf = (0..LEAF_COUNT).find(|&i| leaves::leaf(i).unwrap().kind == ValueKind::Variant).unwrap();
    let mut p = ControlParams::DEFAULT;
    assert!(leaves::from_word(&mut p, bool_leaf, 2).is_err());
    assert!(leaves::from_word(&mut p, variant_leaf, 2).is_err());
    assert!(leaves::from_word(&mut p, variant_leaf, 256).is_err());
    assert_eq!(p, ControlParams::DEFAULT, "nothing written");
    // Within a whole record (CRC recomputed): refused as not decoding.
    let mut buf = [0u8; RECORD_MAX];
    let mut rec = record::encode(&ControlParams::DEFAULT, None, &mut buf).unwrap().to_vec();
    let at = 16 + 4 * bool_leaf;
    rec[at] = 7;
    let n = rec.len() - 4;
    let crc = crc32(&rec[..n]);
    rec[n..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(record::decode(&rec), Err(RecordError::Decode));
}


/// The single-leaf checks are packed rows (offset, leaf, check in 16
/// bits): a NaN put into any `f32` leaf through the leaf table is refused
/// as "must be finite" naming that very leaf, or not by a finiteness check
/// at all (the leaf has no rule); and enough leaves are covered that a
/// broken unpacking could not hide.
#[test]
fn a_nan_in_any_float_leaf_is_refused_naming_that_leaf() {
    let mut named = 0;
    for i in 0..LEAF_COUNT {
        let mut p = ControlParams::DEFAULT;
        if !matches!(leaves::get(&p, i), Some(Value::F32(_))) {
            continue;
        }
        leaves::set(&mut p, i, Value::F32(f32::NAN)).unwrap();
        match p.validate() {
            Err(e) if e.reason == servo_core::protocol::Reason::MustBeFinite => {
                assert_eq!(usize::from(e.leaf), i, "NaN in {} named {}", leaves::path(i), e.field());
                named += 1;
            }
            Err(_) => {}
            Ok(()) => panic!("NaN in {} validates", leaves::path(i)),
        }
    }
    println!("{named} float leaves refuse NaN by name");
    assert!(named >= 80, "{named}");
}
