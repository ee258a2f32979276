//! The parameters, and the observer's weights when a block was uploaded,
//! as one flash record (version 3, magic `CSP3`):
//!
//! | bytes | content |
//! |---|---|
//! | 4 | magic `CSP3` |
//! | 8 | `PARAMS_SCHEMA_HASH` (the layout of `ControlParams`) |
//! | 2 | parameter body length, little-endian |
//! | 2 | observer words: 0 (the compiled model) or `observer::block::WORDS` (the five-slot layout, whatever the block's input count) |
//! | n | the leaves in path order, 4 bytes each, little-endian (`params::leaves`) |
//! | 8 | observer structure hash, of the parameters' force input (only with observer words) |
//! | 4·w | the observer block's words, `f32` little-endian (only with observer words) |
//! | 4 | CRC-32 (ISO-HDLC) of everything before it, little-endian |
//!
//! The header is 16 bytes, so the observer's words sit 4-byte aligned and a
//! board may run them in place from flash.
//!
//! A record is used only whole: the CRC, the schema hash, the lengths, the
//! decoding (every word a value of its leaf's type) and
//! `ControlParams::validate` must all pass, or [`decode`] says which did
//! not and nothing is applied. The observer section is checked as an upload
//! is (`observer::block::validate`, against the record's own
//! `faults.observer_shift_max_m`); a section this firmware's network cannot
//! run (another structure hash after a firmware update) leaves the
//! parameters usable and the compiled model running, and says so. A
//! section of the four-input layout (75 words, written before the network
//! had a fifth input slot) is such a section: upload the weights again.
//!
//! Older versions: a `CSP2` record (the same without the observer count and
//! section) is still read, with the compiled model; a `CSP1` record
//! (`postcard(ControlParams)`, ≈ 7 KB of serde code in the image) is refused
//! by its magic.

use super::leaves::{self, LEAF_COUNT};
use crate::observer::block::{self, BlockError, ForceSource, Weights, WORDS};
use super::{ControlParams, ParamError, ValidatedParams};
use crc::{Crc, NoTable, CRC_32_ISO_HDLC};
use postcard_schema::key::Key;

/// Hash of the parameter set's layout: a record with another is never
/// loaded.
pub const PARAMS_SCHEMA_HASH: [u8; 8] = Key::for_path::<ControlParams>("cylinder-servo/params").to_bytes();

/// The record's CRC-32 (ISO-HDLC), bit by bit: no 1 KiB table in flash for
/// a check that runs once per load or save.
const CRC: Crc<u32, NoTable> = Crc::<u32, NoTable>::new(&CRC_32_ISO_HDLC);

pub const MAGIC: [u8; 4] = *b"CSP3";
/// The previous version: parameters only (14-byte header).
pub const MAGIC_V2: [u8; 4] = *b"CSP2";
/// Largest record; `ControlParams` and an observer block encode to well
/// under this (a test checks the margin).
pub const RECORD_MAX: usize = 1024;
const HEADER: usize = 4 + 8 + 2 + 2;
const HEADER_V2: usize = 4 + 8 + 2;
/// The observer section: structure hash and words.
const OBSERVER_BYTES: usize = 8 + WORDS * 4;
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
    /// The observer section's word count is neither 0 nor this
    /// firmware's block size.
    ObserverLength,
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
            Self::ObserverLength => "record's observer section has another size",
            Self::TooLarge => "parameters exceed the record size",
        }
    }
}

/// Writes `p`, and `observer` when the drive runs uploaded weights, as a
/// record into `buf`; returns the record.
pub fn encode<'a>(p: &ControlParams, observer: Option<&Weights>, buf: &'a mut [u8; RECORD_MAX]) -> Result<&'a [u8], RecordError> {
    let obs_bytes = if observer.is_some() { OBSERVER_BYTES } else { 0 };
    let end = HEADER.saturating_add(BODY).saturating_add(obs_bytes);
    let total = end.saturating_add(CRC_BYTES);
    if total > RECORD_MAX {
        return Err(RecordError::TooLarge);
    }
    let body = buf.get_mut(HEADER..HEADER.saturating_add(BODY)).ok_or(RecordError::TooLarge)?;
    for (i, slot) in body.chunks_exact_mut(WORD).enumerate() {
        slot.copy_from_slice(&leaves::to_word(p, i).ok_or(RecordError::TooLarge)?.to_le_bytes());
    }
    let len = u16::try_from(BODY).map_err(|_| RecordError::TooLarge)?;
    let obs_words: u16 = if observer.is_some() { u16::try_from(WORDS).map_err(|_| RecordError::TooLarge)? } else { 0 };
    let mut header = [0u8; HEADER];
    let (len_le, obs_le) = (len.to_le_bytes(), obs_words.to_le_bytes());
    let fields = MAGIC.iter().chain(PARAMS_SCHEMA_HASH.iter()).chain(len_le.iter()).chain(obs_le.iter());
    for (slot, b) in header.iter_mut().zip(fields) {
        *slot = *b;
    }
    buf.get_mut(..HEADER).ok_or(RecordError::TooLarge)?.copy_from_slice(&header);
    if let Some(m) = observer {
        let at = HEADER.saturating_add(BODY);
        let sec = buf.get_mut(at..end).ok_or(RecordError::TooLarge)?;
        let (hash, words) = sec.split_at_mut(8);
        let source = ForceSource::selected(p.compensation.force_from_estimate);
        hash.copy_from_slice(&block::structure_hash_for(block::inputs_of(m), source));
        for (slot, w) in words.chunks_exact_mut(WORD).zip(block::to_words(m).iter()) {
            slot.copy_from_slice(&w.to_le_bytes());
        }
    }
    let crc = CRC.checksum(buf.get(..end).ok_or(RecordError::TooLarge)?);
    buf.get_mut(end..total).ok_or(RecordError::TooLarge)?.copy_from_slice(&crc.to_le_bytes());
    buf.get(..total).ok_or(RecordError::TooLarge)
}

/// A record's observer section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverSection {
    /// The block, checked (`observer::block::validate`), or why this
    /// firmware cannot run it.
    pub weights: Result<Weights, BlockError>,
    /// Byte offset of the first word in the record (4-byte aligned).
    pub words_offset: usize,
}

/// A decoded record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decoded {
    pub params: ValidatedParams,
    /// `None`: the record holds no weights (the compiled model runs).
    pub observer: Option<ObserverSection>,
    /// The record's version (2 or 3).
    pub version: u8,
}

/// Reads a record: the parameters, validated, or why not (the observer
/// section, if any, is checked by [`decode_record`]).
pub fn decode(record: &[u8]) -> Result<ValidatedParams, RecordError> {
    decode_record(record).map(|d| d.params)
}

/// Reads a record: parameters and observer section.
pub fn decode_record(record: &[u8]) -> Result<Decoded, RecordError> {
    if record.is_empty() {
        return Err(RecordError::Empty);
    }
    if record.len() < HEADER_V2 + CRC_BYTES {
        return Err(RecordError::TooShort);
    }
    let (covered, crc_bytes) = record.split_at(record.len().saturating_sub(CRC_BYTES));
    let version = match covered.get(..4) {
        Some(m) if m == MAGIC => 3,
        Some(m) if m == MAGIC_V2 => 2,
        _ => return Err(RecordError::Magic),
    };
    let mut crc = [0u8; CRC_BYTES];
    crc.copy_from_slice(crc_bytes);
    if CRC.checksum(covered) != u32::from_le_bytes(crc) {
        return Err(RecordError::Crc);
    }
    if covered.get(4..12) != Some(&PARAMS_SCHEMA_HASH[..]) {
        return Err(RecordError::Schema);
    }
    let u16_at = |at: usize| -> Result<usize, RecordError> {
        let mut b = [0u8; 2];
        b.copy_from_slice(covered.get(at..at.saturating_add(2)).ok_or(RecordError::TooShort)?);
        Ok(usize::from(u16::from_le_bytes(b)))
    };
    let len = u16_at(12)?;
    let (header, obs_words) = if version == 3 { (HEADER, u16_at(14)?) } else { (HEADER_V2, 0) };
    let obs_bytes = match obs_words {
        0 => 0,
        WORDS => OBSERVER_BYTES,
        block::WORDS_STATIC => 8usize.saturating_add(block::WORDS_STATIC.saturating_mul(WORD)),
        _ => return Err(RecordError::ObserverLength),
    };
    let rest = covered.get(header..).ok_or(RecordError::TooShort)?;
    if len.saturating_add(obs_bytes) != rest.len() {
        return Err(RecordError::Length);
    }
    let (body, section) = rest.split_at(len);
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
    let params = ValidatedParams::new(p).map_err(RecordError::Invalid)?;
    let observer = (obs_bytes != 0).then(|| {
        let (hash, bytes) = section.split_at(8.min(section.len()));
        let mut h = [0u8; 8];
        h.copy_from_slice(hash.get(..8).unwrap_or(&[0; 8]));
        let mut words = [0.0f32; WORDS];
        for (w, b) in words.iter_mut().zip(bytes.chunks_exact(WORD)) {
            let mut x = [0u8; WORD];
            x.copy_from_slice(b);
            *w = f32::from_le_bytes(x);
        }
        let source = ForceSource::selected(params.get().compensation.force_from_estimate);
        let weights = if obs_words == WORDS {
            block::validate_stored(&h, &words, params.get().faults.observer_shift_max_m, source)
        } else {
            // The four-input layout cannot run in place in the five-slot
            // network: the parameters apply, the compiled model runs.
            Err(BlockError { part: block::Part::Shape, index: 2, reason: crate::reason::Reason::ObserverWordCount })
        };
        ObserverSection { weights, words_offset: header.saturating_add(BODY).saturating_add(8) }
    });
    Ok(Decoded { params, observer, version })
}
