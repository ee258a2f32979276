//! The parameters as one flash record:
//!
//! | bytes | content |
//! |---|---|
//! | 4 | magic `CSP1` |
//! | 8 | `PARAMS_SCHEMA_HASH` (the layout of `ControlParams`) |
//! | 2 | body length, little-endian |
//! | n | `postcard(ControlParams)` |
//! | 4 | CRC-32 (ISO-HDLC) of everything before it, little-endian |
//!
//! A record is used only whole: the CRC, the schema hash, the length, the
//! decoding (no trailing bytes) and `ControlParams::validate` must all pass,
//! or [`decode`] says which did not and nothing is applied.

use crc::{Crc, CRC_32_ISO_HDLC};

use super::{ControlParams, ParamError, ValidatedParams};
use crate::protocol::PARAMS_SCHEMA_HASH;

pub const MAGIC: [u8; 4] = *b"CSP1";
/// Largest record; `ControlParams` encodes to well under this (a test
/// checks the margin).
pub const RECORD_MAX: usize = 1024;
const HEADER: usize = 4 + 8 + 2;
const CRC_BYTES: usize = 4;
const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

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
    /// The body is not a `ControlParams` (or has bytes left over).
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
    let n = postcard::to_slice(p, body).map_err(|_| RecordError::TooLarge)?.len();
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
    let (p, rest) = postcard::take_from_bytes::<ControlParams>(body).map_err(|_| RecordError::Decode)?;
    if !rest.is_empty() {
        return Err(RecordError::Decode);
    }
    ValidatedParams::new(p).map_err(RecordError::Invalid)
}
