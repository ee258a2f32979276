//! The file format of one golden table, and how a target value is compared
//! with the host's.
//!
//! A table is little-endian 32-bit words: a 6-word header
//! `"GLDN", version, family id, rows, input words, output words`, then
//! `rows × (input words + output words)`. An `f32` is stored as its bits, a
//! flag as 0/1, an integer as itself, so the host's values arrive on the
//! target exactly.

/// First header word: `b"GLDN"` read as little-endian.
pub const MAGIC: u32 = u32::from_le_bytes(*b"GLDN");
/// Bumped when the layout of any family changes.
pub const VERSION: u32 = 1;
/// Header words.
pub const HEADER_WORDS: usize = 6;

/// How a column is compared between the host and the target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tol {
    /// Bit for bit: flags, modes, fault bits, integers.
    Exact,
    /// `f32`, equal within this many units in the last place (or both NaN).
    Ulps(u32),
    /// `f32`, `|target − host| ≤` this absolute bound (or both NaN).
    Abs(f32),
}

/// One output column.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Column {
    pub name: &'static str,
    /// `true` for an `f32` column (statistics in ulps), `false` for integers.
    pub float: bool,
    pub tol: Tol,
}

impl Column {
    pub const fn f32(name: &'static str, tol: Tol) -> Self {
        Self {
            name,
            float: true,
            tol,
        }
    }

    pub const fn exact(name: &'static str) -> Self {
        Self {
            name,
            float: false,
            tol: Tol::Exact,
        }
    }
}

/// Distance in units in the last place between two `f32` bit patterns
/// (0 for identical values, including +0/−0 and two NaNs; `u32::MAX` if only
/// one is NaN).
pub fn ulps(a_bits: u32, b_bits: u32) -> u32 {
    let (a, b) = (f32::from_bits(a_bits), f32::from_bits(b_bits));
    if a.is_nan() || b.is_nan() {
        return if a.is_nan() && b.is_nan() {
            0
        } else {
            u32::MAX
        };
    }
    if a == b {
        return 0;
    }
    // Map the sign-magnitude bits onto a monotonic integer line.
    fn key(bits: u32) -> i64 {
        if bits & 0x8000_0000 != 0 {
            -((bits & 0x7FFF_FFFF) as i64)
        } else {
            bits as i64
        }
    }
    let d = (key(a_bits) - key(b_bits)).unsigned_abs();
    if d > u32::MAX as u64 {
        u32::MAX
    } else {
        d as u32
    }
}

/// Whether the target's word agrees with the host's under `col.tol`.
pub fn agrees(col: &Column, host: u32, target: u32) -> bool {
    match col.tol {
        Tol::Exact => host == target,
        Tol::Ulps(n) => ulps(host, target) <= n,
        Tol::Abs(t) => {
            let (h, g) = (f32::from_bits(host), f32::from_bits(target));
            (h.is_nan() && g.is_nan()) || (h - g).abs() <= t
        }
    }
}

/// A table read from its bytes.
#[derive(Clone, Copy, Debug)]
pub struct Table<'a> {
    bytes: &'a [u8],
    pub family: u32,
    pub rows: usize,
    pub in_words: usize,
    pub out_words: usize,
}

impl<'a> Table<'a> {
    /// Checks the header and the length.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, &'static str> {
        let word = |i: usize| -> Option<u32> {
            let b = bytes.get(4 * i..4 * i + 4)?;
            Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        if word(0) != Some(MAGIC) {
            return Err("not a golden table (magic)");
        }
        if word(1) != Some(VERSION) {
            return Err("golden table version differs from this code: regenerate (bash firmware-tests/golden.sh)");
        }
        let (family, rows, iw, ow) = match (word(2), word(3), word(4), word(5)) {
            (Some(f), Some(r), Some(i), Some(o)) => (f, r as usize, i as usize, o as usize),
            _ => return Err("truncated header"),
        };
        if bytes.len() != 4 * (HEADER_WORDS + rows * (iw + ow)) {
            return Err("length does not match the header");
        }
        Ok(Self {
            bytes,
            family,
            rows,
            in_words: iw,
            out_words: ow,
        })
    }

    fn word(&self, index: usize) -> u32 {
        let b = &self.bytes[4 * index..4 * index + 4];
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// Input word `col` of row `row`.
    pub fn input(&self, row: usize, col: usize) -> u32 {
        self.word(HEADER_WORDS + row * (self.in_words + self.out_words) + col)
    }

    /// Output word `col` of row `row` (the host's value).
    pub fn output(&self, row: usize, col: usize) -> u32 {
        self.word(HEADER_WORDS + row * (self.in_words + self.out_words) + self.in_words + col)
    }
}

/// The header of a table, for the writer.
pub fn header(family: u32, rows: usize, in_words: usize, out_words: usize) -> [u32; HEADER_WORDS] {
    [
        MAGIC,
        VERSION,
        family,
        rows as u32,
        in_words as u32,
        out_words as u32,
    ]
}
