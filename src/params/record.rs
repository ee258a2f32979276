//! The parameters as one flash record:
//!
//! | bytes | content |
//! |---|---|
//! | 4 | magic `CSP2` |
//! | 8 | `PARAMS_SCHEMA_HASH` (the layout of `ControlParams`) |
//! | 2 | body length, little-endian |
//! | n | the leaves in path order, 4 bytes each, little-endian (`params::leaves`) |
//! | 4 | CRC-32 (ISO-HDLC) of everything before it, little-endian |
//!
//! A record is used only whole: the CRC, the schema hash, the length, the
//! decoding (every word a value of its leaf's type) and
//! `ControlParams::validate` must all pass, or [`decode`] says which did
//! not and nothing is applied.
//!
//! The body is the leaf table's words, not `postcard(ControlParams)` (the
//! `CSP1` records): the serde code of the whole struct cost ≈ 7 KB of the
//! image, the table walk a few hundred bytes. The schema hash still covers
//! the layout: the table follows the struct's declaration order, which the
//! hash covers too. A `CSP1` record is refused by its magic.


use super::leaves::{self, LEAF_COUNT};
use super::{ControlParams, ParamError, ValidatedParams};
use crc::{Crc, NoTable, CRC_32_ISO_HDLC};
use postcard_schema::key::Key;

/// Hash of the parameter set's layout: a record with another is never
/// loaded.
pub const PARAMS_SCHEMA_HASH: [u8; 8] = Key::for_path::<ControlParams>("cylinder-servo/params").to_bytes();

/// The record's CRC-32 (ISO-HDLC), bit by bit: no 1 KiB table in flash for
/// a check that runs once per load or save.
const CRC: Crc<u32, NoTable> = Crc::<u32, NoTable>::new(&CRC_32_ISO_HDLC);

pub const MAGIC: [u8; 4] = *b"CSP2";
/// Largest record; `ControlParams` encodes to well under this (a test
/// checks the margin).
pub const RECORD_MAX: usize = 1024;
const HEADER: usize = 4 + 8 + 2;
const CRC_BYTES: usize = 4;
/// Bytes per leaf in the body.
const WORD: usize = 4;
const BODY: usize = LEAF_COUNT * WORD;

/// Why a record was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// No record stored.
    Empty,
    /// Shorter than header and CRC.
    TooShort,
    /// Does not start with the magic: not a parameter record.
    Magic,
    /// CRC mismatch: the record is corrupted.
    Crc,
    /// Written by a firmware with another parameter layout.
    Schema,
    /// The length field disagrees with the record's size.
    Length,
    /// The body is not one word per leaf, or a word is not a value of its
    /// leaf's type.
    Decode,
    /// Decoded, but the set does not validate.
    Invalid(ParamError),
    /// The set does not fit [`RECORD_MAX`] (a build problem).
    TooLarge,
}

impl RecordError {
    /// One line for a reply's note.
    pub const fn reason(&self) -> &'static str {
        match self {
            Self::Empty => "no record stored",
            Self::TooShort => "record truncated",
            Self::Magic => "not a parameter record",
            Self::Crc => "record CRC mismatch",
            Self::Schema => "record of another parameter schema",
            Self::Length => "record length mismatch",
            Self::Decode => "record does not decode",
            Self::Invalid(_) => "record does not validate",
            Self::TooLarge => "parameters exceed the record size",
        }
    }
}

/// Writes `p` as a record into `buf`; returns the record.
pub fn encode<'a>(p: &ControlParams, buf: &'a mut [u8; RECORD_MAX]) -> Result<&'a [u8], RecordError> {
    let (head, rest) = buf.split_at_mut(HEADER);
    let body_room = rest.len().saturating_sub(CRC_BYTES);
    let body = rest.get_mut(..body_room).ok_or(RecordError::TooLarge)?;
    let body = body.get_mut(..BODY).ok_or(RecordError::TooLarge)?;
    for (i, slot) in body.chunks_exact_mut(WORD).enumerate() {
        slot.copy_from_slice(&leaves::to_word(p, i).ok_or(RecordError::TooLarge)?.to_le_bytes());
    }
    let n = BODY;
    let len = u16::try_from(n).map_err(|_| RecordError::TooLarge)?;
    let mut header = [0u8; HEADER];
    for (slot, b) in header.iter_mut().zip(MAGIC.iter().chain(PARAMS_SCHEMA_HASH.iter()).chain(len.to_le_bytes().iter())) {
        *slot = *b;
    }
    head.copy_from_slice(&header);
    let end = HEADER.saturating_add(n);
    let total = end.saturating_add(CRC_BYTES);
    let crc = CRC.checksum(buf.get(..end).ok_or(RecordError::TooLarge)?);
    buf.get_mut(end..total).ok_or(RecordError::TooLarge)?.copy_from_slice(&crc.to_le_bytes());
    buf.get(..total).ok_or(RecordError::TooLarge)
}

/// Reads a record: the parameters, validated, or why not.
pub fn decode(record: &[u8]) -> Result<ValidatedParams, RecordError> {
    if record.is_empty() {
        return Err(RecordError::Empty);
    }
    if record.len() < HEADER + CRC_BYTES {
        return Err(RecordError::TooShort);
    }
    let (covered, crc_bytes) = record.split_at(record.len().saturating_sub(CRC_BYTES));
    if covered.get(..4) != Some(&MAGIC[..]) {
        return Err(RecordError::Magic);
    }
    let mut crc = [0u8; CRC_BYTES];
    crc.copy_from_slice(crc_bytes);
    if CRC.checksum(covered) != u32::from_le_bytes(crc) {
        return Err(RecordError::Crc);
    }
    if covered.get(4..12) != Some(&PARAMS_SCHEMA_HASH[..]) {
        return Err(RecordError::Schema);
    }
    let mut len = [0u8; 2];
    len.copy_from_slice(covered.get(12..14).ok_or(RecordError::TooShort)?);
    let body = covered.get(HEADER..).ok_or(RecordError::TooShort)?;
    if usize::from(u16::from_le_bytes(len)) != body.len() {
        return Err(RecordError::Length);
    }
    if body.len() != BODY {
        return Err(RecordError::Decode);
    }
    // Every leaf is overwritten: the defaults only give the struct its
    // initial (valid) enum and bool values.
    let mut p = ControlParams::DEFAULT;
    for (i, word) in body.chunks_exact(WORD).enumerate() {
        let mut w = [0u8; WORD];
        w.copy_from_slice(word);
        leaves::from_word(&mut p, i, u32::from_le_bytes(w)).map_err(|_| RecordError::Decode)?;
    }
    ValidatedParams::new(p).map_err(RecordError::Invalid)
}
