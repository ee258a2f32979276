//! Framing: postcard, then a CRC-32, then COBS with a zero delimiter.
//!
//! COBS makes every frame end at the next zero byte, so a receiver that
//! joins mid-stream or loses a byte resynchronises at the next delimiter.
//! The CRC catches what COBS cannot (a flipped bit that leaves valid COBS),
//! and decoding refuses trailing bytes, so a frame is taken whole or not at
//! all. Nothing here panics or allocates: the parser's property test feeds
//! it 10⁶ random and mutated frames.

use crc::{Crc, NoTable, CRC_32_ISO_HDLC};
use serde::{de::DeserializeOwned, Serialize};

use super::messages::FrameError;

/// Largest encoded frame, delimiter included. A receiver drops a longer run
/// of bytes (reporting [`FrameError::TooLong`]) and resynchronises at the
/// next zero.
pub const FRAME_MAX: usize = 320;

/// Bit by bit, without the crate's 1 KiB lookup table: frames are at most
/// 320 bytes and checked in thread mode, where ≈ 40 cycles a byte do not
/// matter, and the table was 1.6 % of the image's flash. The same CRC.
const CRC: Crc<u32, NoTable> = Crc::<u32, NoTable>::new(&CRC_32_ISO_HDLC);
const CRC_BYTES: usize = 4;

/// Encodes `msg` into `buf` as one frame ending with its zero delimiter;
/// returns the frame. `None` if it does not fit (a message type larger than
/// [`FRAME_MAX`] is a bug the protocol tests catch).
pub fn encode<'a, T: Serialize>(msg: &T, buf: &'a mut [u8]) -> Option<&'a [u8]> {
    let mut raw = [0u8; FRAME_MAX];
    // postcard's own CRC flavour would use the table-driven digest: the
    // CRC is appended here instead (the same bytes: little-endian, last).
    let n = postcard::to_slice(msg, &mut raw).ok()?.len();
    let crc = CRC.checksum(raw.get(..n)?).to_le_bytes();
    let end = n.checked_add(CRC_BYTES)?;
    raw.get_mut(n..end)?.copy_from_slice(&crc);
    let body = raw.get(..end)?;
    if cobs::max_encoding_length(body.len()) >= FRAME_MAX {
        return None;
    }
    let n = cobs::try_encode(body, buf).ok()?;
    *buf.get_mut(n)? = 0;
    buf.get(..=n)
}

/// Decodes one frame: `frame` holds the bytes up to, not including, the zero
/// delimiter (as [`FrameReader`] hands them out); it is decoded in place.
pub fn decode<T: DeserializeOwned>(frame: &mut [u8]) -> Result<T, FrameError> {
    if frame.len() >= FRAME_MAX {
        return Err(FrameError::TooLong);
    }
    let n = cobs_decode_in_place(frame).ok_or(FrameError::Cobs)?;
    let bytes = frame.get(..n).ok_or(FrameError::Cobs)?;
    if bytes.len() < CRC_BYTES {
        return Err(FrameError::Truncated);
    }
    let (body, crc_bytes) = bytes.split_at(bytes.len().saturating_sub(CRC_BYTES));
    let mut crc_le = [0u8; CRC_BYTES];
    crc_le.copy_from_slice(crc_bytes);
    if CRC.checksum(body) != u32::from_le_bytes(crc_le) {
        return Err(FrameError::Crc);
    }
    let (msg, rest) = postcard::take_from_bytes::<T>(body).map_err(|_| FrameError::Decode)?;
    if !rest.is_empty() {
        return Err(FrameError::Trailing);
    }
    Ok(msg)
}

/// COBS-decodes `buf` in place; the decoded length, or `None` if it is not
/// valid COBS (a zero inside, a code running past the end). Written out
/// with checked accesses (the `cobs` crate's decoder indexes, which the
/// panic-never proof cannot see through); the same result otherwise.
fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let n = buf.len();
    let (mut src, mut dst) = (0usize, 0usize);
    while src < n {
        let code = usize::from(*buf.get(src)?);
        if code == 0 {
            return None;
        }
        src = src.saturating_add(1);
        let end = src.saturating_add(code).saturating_sub(1);
        if end > n {
            return None;
        }
        while src < end {
            let b = *buf.get(src)?;
            if b == 0 {
                return None;
            }
            *buf.get_mut(dst)? = b;
            src = src.saturating_add(1);
            dst = dst.saturating_add(1);
        }
        if code != 0xFF && src < n {
            *buf.get_mut(dst)? = 0;
            dst = dst.saturating_add(1);
        }
    }
    Some(dst)
}

/// Collects bytes from a transport into frames. Feed it what arrives; it
/// returns each complete frame (without its delimiter) or the reason a run
/// of bytes was dropped.
#[derive(Debug)]
pub struct FrameReader {
    buf: [u8; FRAME_MAX],
    len: usize,
    overflowed: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

/// What one byte completed.
#[derive(Debug, PartialEq, Eq)]
pub enum Feed<'a> {
    /// Nothing yet.
    Pending,
    /// A frame's bytes (COBS-encoded, delimiter stripped): pass to [`decode`].
    Frame(&'a mut [u8]),
    /// A run longer than [`FRAME_MAX`] ended; it was dropped.
    Dropped(FrameError),
}

impl FrameReader {
    pub const fn new() -> Self {
        Self { buf: [0; FRAME_MAX], len: 0, overflowed: false }
    }

    pub fn push(&mut self, byte: u8) -> Feed<'_> {
        if byte == 0 {
            let len = core::mem::replace(&mut self.len, 0);
            if core::mem::replace(&mut self.overflowed, false) {
                return Feed::Dropped(FrameError::TooLong);
            }
            if len == 0 {
                // Back-to-back delimiters: a sender flushing the line.
                return Feed::Pending;
            }
            return match self.buf.get_mut(..len) {
                Some(frame) => Feed::Frame(frame),
                None => Feed::Dropped(FrameError::TooLong),
            };
        }
        match self.buf.get_mut(self.len) {
            Some(slot) if !self.overflowed => {
                *slot = byte;
                self.len = self.len.saturating_add(1);
            }
            _ => self.overflowed = true,
        }
        Feed::Pending
    }
}
