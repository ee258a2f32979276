//! The platform's setpoint stream over CAN FD: one frame carries the
//! setpoints of all six legs for one 1 kHz period; each drive reads its own
//! slot (`control.stream.leg_index`). A second, short frame ends the stream
//! (a controlled stop) for the legs it names.
//!
//! One definition for both ends: the platform controller (host) encodes
//! with [`encode_setpoints`] / [`encode_stop`], the drive decodes with
//! [`decode`]. `no_std`, no allocation, no panic path.
//!
//! # Layout (little-endian throughout)
//!
//! **Setpoints**: standard identifier [`SETPOINT_ID`] (0x100), CAN FD with
//! bit-rate switching, 64 data bytes (DLC 15).
//!
//! | bytes | field | unit / meaning |
//! |---|---|---|
//! | 0 | kind | [`KIND_SETPOINTS`] (0xC1: setpoints, layout 1) |
//! | 1 | leg mask | bit i set: leg i's slot carries a setpoint; bits 6–7 zero, not all zero |
//! | 2–3 | sequence | u16, +1 per frame (wraps); a drive refuses one not newer than the last |
//! | 4 + 10·i … | leg i (0…5) | position i32 (nm), velocity i24 (µm/s), force i24 (0.1 N; 0x800000 = none) |
//!
//! Ranges: position ±[`POSITION_MAX_M`] (2 m), velocity ±[`VELOCITY_MAX_M_S`]
//! (8 m/s), force ±[`FORCE_MAX_N`] (800 kN). The reserved codes
//! (`i32::MIN` for a position, 0x800000 for a velocity) are refused.
//!
//! **Stop** (stream end): identifier [`STOP_ID`] (0x080, wins arbitration
//! over setpoints), 8 data bytes (classic CAN or CAN FD): kind
//! [`KIND_STOP`] (0xC2), leg mask (as above), sequence, four zero bytes.
//!
//! The CAN frame's own CRC (17/21 bits in CAN FD) guards the bytes; the
//! checks here refuse a frame of another layout, length or range.

use crate::math;

/// Standard (11-bit) identifier of the setpoint frame.
pub const SETPOINT_ID: u16 = 0x100;
/// Standard identifier of the stop (stream-end) frame: lower than
/// [`SETPOINT_ID`], so it wins arbitration.
pub const STOP_ID: u16 = 0x080;
/// Legs of the platform, i.e. slots per setpoint frame.
pub use crate::params::LEGS;
/// Data bytes of a setpoint frame (CAN FD, DLC 15).
pub const SETPOINT_LEN: usize = 64;
/// Data bytes of a stop frame.
pub const STOP_LEN: usize = 8;
/// First byte of a setpoint frame: kind and layout version.
pub const KIND_SETPOINTS: u8 = 0xC1;
/// First byte of a stop frame.
pub const KIND_STOP: u8 = 0xC2;
/// Bytes per leg slot.
pub const SLOT_LEN: usize = 10;
/// Bytes before the first slot.
pub const HEADER_LEN: usize = 4;
/// All six legs.
pub const ALL_LEGS: u8 = 0b0011_1111;

/// Position unit: 1 nm.
pub const POSITION_UNITS_PER_M: f32 = 1.0e9;
/// Velocity unit: 1 µm/s.
pub const VELOCITY_UNITS_PER_M_S: f32 = 1.0e6;
/// Force unit: 0.1 N.
pub const FORCE_UNITS_PER_N: f32 = 10.0;
/// Largest |position| carried (i32 nm holds 2.147 m).
pub const POSITION_MAX_M: f32 = 2.0;
/// Largest |velocity| carried (i24 µm/s holds 8.388 m/s).
pub const VELOCITY_MAX_M_S: f32 = 8.0;
/// Largest |force| carried (i24 0.1 N holds 838 kN).
pub const FORCE_MAX_N: f32 = 800_000.0;
/// The i24 code for "no force feed-forward" (and never a velocity).
const I24_NONE: i32 = -0x80_0000;

/// One leg's setpoint, as `Request::Stream` carries it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegSetpoint {
    pub position_m: f32,
    pub velocity_m_s: f32,
    pub force_n: Option<f32>,
}

/// A decoded frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CanMessage {
    /// One period's setpoints; `None` for a leg whose mask bit is clear.
    Setpoints { seq: u16, legs: [Option<LegSetpoint>; LEGS] },
    /// End the stream of the legs in `legs` (bit i = leg i): controlled stop.
    Stop { seq: u16, legs: u8 },
}

impl CanMessage {
    pub fn seq(&self) -> u16 {
        match self {
            Self::Setpoints { seq, .. } | Self::Stop { seq, .. } => *seq,
        }
    }
}

/// Why a frame was refused, or a setpoint could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CanError {
    /// Not one of this layout's identifiers.
    UnknownId,
    /// Data length other than the identifier's.
    Length,
    /// First byte is not the identifier's kind (another layout version).
    Kind,
    /// Leg mask empty, or bits 6–7 set.
    LegMask,
    /// A non-zero byte where zero is required.
    Reserved,
    /// Leg `leg`'s value is not finite, beyond the layout's range, or a
    /// reserved code.
    OutOfRange { leg: u8 },
}

/// `value × scale`, rounded, if finite and |value| ≤ `max`.
fn to_fixed(value: f32, scale: f32, max: f32) -> Option<i32> {
    if value.is_finite() && value.abs() <= max {
        Some(math::round(value * scale) as i32)
    } else {
        None
    }
}

fn i24_bytes(v: i32) -> [u8; 3] {
    let [a, b, c, _] = v.to_le_bytes();
    [a, b, c]
}

fn i24_from(a: u8, b: u8, c: u8) -> i32 {
    // Sign-extend from bit 23.
    i32::from_le_bytes([a, b, c, 0]).wrapping_shl(8).wrapping_shr(8)
}

/// Mask bit of each leg.
const LEG_BIT: [u8; LEGS] = [1, 2, 4, 8, 16, 32];

/// One slot's bytes.
fn encode_slot(sp: &LegSetpoint, leg: u8) -> Result<[u8; SLOT_LEN], CanError> {
    let bad = CanError::OutOfRange { leg };
    let pos = to_fixed(sp.position_m, POSITION_UNITS_PER_M, POSITION_MAX_M).ok_or(bad)?;
    let vel = to_fixed(sp.velocity_m_s, VELOCITY_UNITS_PER_M_S, VELOCITY_MAX_M_S).ok_or(bad)?;
    let force = match sp.force_n {
        Some(f) => to_fixed(f, FORCE_UNITS_PER_N, FORCE_MAX_N).ok_or(bad)?,
        None => I24_NONE,
    };
    let [p0, p1, p2, p3] = pos.to_le_bytes();
    let [v0, v1, v2] = i24_bytes(vel);
    let [f0, f1, f2] = i24_bytes(force);
    Ok([p0, p1, p2, p3, v0, v1, v2, f0, f1, f2])
}

/// One slot's setpoint, range-checked.
fn decode_slot(slot: &[u8], leg: u8) -> Result<LegSetpoint, CanError> {
    let bad = CanError::OutOfRange { leg };
    let &[p0, p1, p2, p3, v0, v1, v2, f0, f1, f2] = slot else {
        return Err(CanError::Length);
    };
    let pos = i32::from_le_bytes([p0, p1, p2, p3]);
    let vel = i24_from(v0, v1, v2);
    let force = i24_from(f0, f1, f2);
    if pos == i32::MIN || vel == I24_NONE {
        return Err(bad);
    }
    let position_m = pos as f32 / POSITION_UNITS_PER_M;
    let velocity_m_s = vel as f32 / VELOCITY_UNITS_PER_M_S;
    let force_n = if force == I24_NONE { None } else { Some(force as f32 / FORCE_UNITS_PER_N) };
    // The ranges the encoder accepts: a code beyond them comes from another
    // encoder, or a corrupt one.
    let within = |v: f32, max: f32| v.abs() <= max * 1.000_001;
    if !within(position_m, POSITION_MAX_M) || !within(velocity_m_s, VELOCITY_MAX_M_S) {
        return Err(bad);
    }
    if force_n.is_some_and(|f| !within(f, FORCE_MAX_N)) {
        return Err(bad);
    }
    Ok(LegSetpoint { position_m, velocity_m_s, force_n })
}

/// The 64 data bytes of a setpoint frame for [`SETPOINT_ID`]. Refuses a
/// leg whose value is not finite or out of the layout's range, and a frame
/// with no leg at all.
pub fn encode_setpoints(seq: u16, legs: &[Option<LegSetpoint>; LEGS]) -> Result<[u8; SETPOINT_LEN], CanError> {
    let mut out = [0u8; SETPOINT_LEN];
    let (head, body) = out.split_at_mut(HEADER_LEN);
    let mut mask = 0u8;
    for (((leg, slot), bit), i) in legs.iter().zip(body.chunks_exact_mut(SLOT_LEN)).zip(LEG_BIT).zip(0u8..) {
        if let Some(sp) = leg {
            slot.copy_from_slice(&encode_slot(sp, i)?);
            mask |= bit;
        }
    }
    if mask == 0 {
        return Err(CanError::LegMask);
    }
    let [s0, s1] = seq.to_le_bytes();
    head.copy_from_slice(&[KIND_SETPOINTS, mask, s0, s1]);
    Ok(out)
}

/// The 8 data bytes of a stop frame for [`STOP_ID`].
pub fn encode_stop(seq: u16, legs: u8) -> Result<[u8; STOP_LEN], CanError> {
    if legs == 0 || legs & !ALL_LEGS != 0 {
        return Err(CanError::LegMask);
    }
    let [s0, s1] = seq.to_le_bytes();
    Ok([KIND_STOP, legs, s0, s1, 0, 0, 0, 0])
}

/// Kind checked; (mask, seq, the bytes after the header).
fn header(data: &[u8], kind: u8) -> Result<(u8, u16, &[u8]), CanError> {
    let Some((&[k, mask, s0, s1], rest)) = data.split_first_chunk::<HEADER_LEN>() else {
        return Err(CanError::Length);
    };
    if k != kind {
        return Err(CanError::Kind);
    }
    if mask == 0 || mask & !ALL_LEGS != 0 {
        return Err(CanError::LegMask);
    }
    Ok((mask, u16::from_le_bytes([s0, s1]), rest))
}

/// A received frame, checked whole: identifier, length, kind, mask,
/// reserved bytes and every slot's codes.
pub fn decode(id: u16, data: &[u8]) -> Result<CanMessage, CanError> {
    match id {
        SETPOINT_ID => {
            if data.len() != SETPOINT_LEN {
                return Err(CanError::Length);
            }
            let (mask, seq, body) = header(data, KIND_SETPOINTS)?;
            let mut legs = [None; LEGS];
            for (((leg, slot), bit), i) in legs.iter_mut().zip(body.chunks_exact(SLOT_LEN)).zip(LEG_BIT).zip(0u8..) {
                if mask & bit == 0 {
                    if slot.iter().any(|&x| x != 0) {
                        return Err(CanError::Reserved);
                    }
                } else {
                    *leg = Some(decode_slot(slot, i)?);
                }
            }
            Ok(CanMessage::Setpoints { seq, legs })
        }
        STOP_ID => {
            if data.len() != STOP_LEN {
                return Err(CanError::Length);
            }
            let (legs, seq, rest) = header(data, KIND_STOP)?;
            if rest.iter().any(|&x| x != 0) {
                return Err(CanError::Reserved);
            }
            Ok(CanMessage::Stop { seq, legs })
        }
        _ => Err(CanError::UnknownId),
    }
}

/// Whether sequence `seq` comes after `last` (modulo 2^16, within half the
/// range): a repeated or older frame is not.
pub fn is_newer(seq: u16, last: u16) -> bool {
    (seq.wrapping_sub(last) as i16) > 0
}

/// Leg `leg`'s setpoint in a decoded setpoint frame, if it carries one.
pub fn slot(legs: &[Option<LegSetpoint>; LEGS], leg: u32) -> Option<LegSetpoint> {
    legs.get(usize::try_from(leg).unwrap_or(usize::MAX)).copied().flatten()
}

/// Whether leg `leg` is in a stop frame's mask.
pub fn names_leg(mask: u8, leg: u32) -> bool {
    LEG_BIT.get(usize::try_from(leg).unwrap_or(usize::MAX)).is_some_and(|bit| mask & bit != 0)
}
