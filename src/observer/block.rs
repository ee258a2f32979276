//! The observer's weights as a parameter block: what a host uploads, what
//! the flash record keeps after the parameters, and what the drive checks
//! before it runs them.
//!
//! The block is the model's `f32` words in a fixed order ([`Part`] order:
//! input ranges and scales, centres row by row, widths, decays, output
//! weights, linear term, bias, output scale and offset), preceded by the
//! structure hash of the network it was trained for and of the force input
//! it was trained on ([`structure_hash`]). A block is used
//! whole or not at all: [`validate`] names the first part that is wrong and
//! the running weights stay as they were.
//!
//! A block has four inputs (the paper's static map, 75 words: the compiled
//! model and every block uploaded before the fifth input existed) or five
//! (with the direction of travel, 87 words); the input count is part of
//! its shape and of its structure hash. Either runs in the five-slot
//! network ([`super::lift`]): the drive keeps and runs every model in that
//! layout, and the host sees the block in its own.
//!
//! The words travel and are stored as their bit patterns, and the forward
//! pass is the same function for the compiled and the uploaded model, so a
//! prediction from uploaded weights is bit for bit the one of the same
//! weights compiled in.

use super::model::HIDDEN;
use super::{RbfModel, NETWORK_INPUTS as INPUTS, NETWORK_INPUT_NAMES as INPUT_NAMES, STATIC_INPUTS};
use crate::reason::Reason;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// The model the firmware runs: the compiled one or an uploaded block, in
/// the network's five input slots.
pub type Weights = RbfModel<INPUTS, HIDDEN>;

/// The compiled model at one address (a `const` has none: each `&MODEL`
/// may be another copy), so "runs the compiled weights" is a pointer
/// comparison and a reference to it is what the controller starts with.
pub static COMPILED: Weights = super::lift(&super::model::MODEL);

/// Words of a block with `inputs` inputs: 4 per input (min, max, scale,
/// linear), `inputs + 3` per hidden unit (centre, width, decay, weight),
/// bias, output scale, offset.
pub const fn words_for(inputs: usize) -> usize {
    4usize.saturating_mul(inputs).saturating_add(HIDDEN.saturating_mul(inputs.saturating_add(3))).saturating_add(3)
}

/// Words of a five-input block: the layout the drive stores and runs.
pub const WORDS: usize = words_for(INPUTS);

/// Words of a four-input block.
pub const WORDS_STATIC: usize = words_for(STATIC_INPUTS);

/// The input counts a block may have.
pub const fn input_count_ok(inputs: usize) -> bool {
    inputs == STATIC_INPUTS || inputs == INPUTS
}

/// Words one upload chunk carries at most (a frame stays under
/// `protocol::FRAME_MAX`).
pub const CHUNK_WORDS: usize = 32;

/// FNV-1a (64 bit) of `bytes`, continuing from `h`.
const fn fnv1a(mut h: u64, mut bytes: &[u8]) -> u64 {
    while let [b, rest @ ..] = bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
        bytes = rest;
    }
    h
}

/// What the observer's force input was while a model's data were logged:
/// the load cell, or the drive's current-based estimate
/// (`control.compensation.force_from_estimate`). The two read the same load
/// apart by the friction and filtering in between, so weights run only on
/// the input they were trained on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[serde(rename_all = "snake_case")]
pub enum ForceSource {
    LoadCell,
    Estimate,
}

impl ForceSource {
    /// The force input `control.compensation.force_from_estimate` selects.
    pub const fn selected(force_from_estimate: bool) -> Self {
        if force_from_estimate {
            Self::Estimate
        } else {
            Self::LoadCell
        }
    }

    /// As the trainer's `model.json` and the docs write it.
    pub const fn name(self) -> &'static str {
        match self {
            Self::LoadCell => "load_cell",
            Self::Estimate => "estimate",
        }
    }

    const fn other(self) -> Self {
        match self {
            Self::LoadCell => Self::Estimate,
            Self::Estimate => Self::LoadCell,
        }
    }

    /// Why weights trained on `self` are refused where the other runs.
    const fn mismatch(self) -> Reason {
        match self {
            Self::LoadCell => Reason::ObserverTrainedOnLoadCell,
            Self::Estimate => Reason::ObserverTrainedOnEstimate,
        }
    }
}

/// The structure hash of this firmware's network with its first `inputs`
/// inputs (4 or 5) trained on `source`: FNV-1a over its kind, those inputs
/// by name and order, the input and hidden counts, and, for the estimate,
/// the force source. The four-input load cell's hash is the one without a
/// force-source part, as firmware before the force source was hashed wrote
/// it, so blocks of that firmware keep their hash.
pub const fn structure_hash_for(inputs: usize, source: ForceSource) -> [u8; 8] {
    let mut h = fnv1a(0xcbf2_9ce4_8422_2325, b"gaussian-rbf+linear;output=terminal_error_m;inputs=");
    let mut names: &[&str] = &INPUT_NAMES;
    let mut n = 0;
    while let [name, rest @ ..] = names {
        if n >= inputs {
            break;
        }
        h = fnv1a(h, name.as_bytes());
        h = fnv1a(h, b",");
        names = rest;
        n = n.saturating_add(1);
    }
    h = fnv1a(h, &(inputs as u32).to_le_bytes());
    h = fnv1a(h, &(HIDDEN as u32).to_le_bytes());
    if let ForceSource::Estimate = source {
        h = fnv1a(h, b";force_source=estimate");
    }
    h.to_le_bytes()
}

/// The four-input structure hash on `source` (the compiled model's shape).
pub const fn structure_hash(source: ForceSource) -> [u8; 8] {
    structure_hash_for(STATIC_INPUTS, source)
}

/// The four-input network trained on the load cell. A block trained for
/// another network carries another hash and is refused.
pub const STRUCTURE_HASH: [u8; 8] = structure_hash(ForceSource::LoadCell);

/// The same network trained on the drive's force estimate.
pub const STRUCTURE_HASH_ESTIMATE: [u8; 8] = structure_hash(ForceSource::Estimate);

/// A block's hash checked against this network with `inputs` inputs on the
/// drive's force input `source`: another network, or the right network
/// trained on the other force input (named).
fn check_hash(structure_hash: &[u8; 8], inputs: usize, source: ForceSource) -> Result<(), BlockError> {
    if *structure_hash == structure_hash_for(inputs, source) {
        return Ok(());
    }
    let other = source.other();
    let reason = if *structure_hash == structure_hash_for(inputs, other) { other.mismatch() } else { Reason::ObserverStructureHash };
    Err(err(Part::StructureHash, 0, reason))
}

/// Whether the fifth input slot of `m` is unused (a four-input model).
fn fifth_unused(m: &Weights) -> bool {
    let last = INPUTS.saturating_sub(1);
    let zero = |a: &[f32; INPUTS]| a.get(last).is_some_and(|v| v.to_bits() == 0);
    zero(&m.input_min)
        && zero(&m.input_max)
        && zero(&m.input_scale)
        && zero(&m.linear)
        && m.centres.iter().all(|c| c.get(last).is_some_and(|v| v.to_bits() == (-1.0f32).to_bits()))
}

/// The inputs `m` uses: 4 when its fifth slot is unused, else 5.
pub fn inputs_of(m: &Weights) -> usize {
    if fifth_unused(m) {
        STATIC_INPUTS
    } else {
        INPUTS
    }
}

/// The parts of a block, in word order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Part {
    /// The declared input and hidden counts (and the number of words).
    Shape,
    StructureHash,
    InputMin,
    InputMax,
    InputScale,
    Centres,
    Widths,
    Log2Decay,
    Weights,
    Linear,
    Bias,
    OutputScale,
    OutputOffset,
    /// The whole model: its prediction somewhere in the trained range.
    Prediction,
}

impl Part {
    /// The part's name as the docs and the host tool write it.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Shape => "shape",
            Self::StructureHash => "structure_hash",
            Self::InputMin => "input_min",
            Self::InputMax => "input_max",
            Self::InputScale => "input_scale",
            Self::Centres => "centres",
            Self::Widths => "widths",
            Self::Log2Decay => "log2_decay",
            Self::Weights => "weights",
            Self::Linear => "linear",
            Self::Bias => "bias",
            Self::OutputScale => "output_scale",
            Self::OutputOffset => "output_offset",
            Self::Prediction => "prediction",
        }
    }
}

/// Why a block was refused: the part, the element in it (input, unit or
/// `unit * INPUTS + input` for the centres; 0 for a scalar) and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BlockError {
    pub part: Part,
    pub index: u16,
    pub reason: Reason,
}

const fn err(part: Part, index: usize, reason: Reason) -> BlockError {
    BlockError { part, index: if index > u16::MAX as usize { u16::MAX } else { index as u16 }, reason }
}

/// Part of word `i` of a block with `inputs` inputs, and its index in the
/// part.
pub fn part_of(i: usize, inputs: usize) -> (Part, usize) {
    let spans: [(Part, usize); 11] = [
        (Part::InputMin, inputs),
        (Part::InputMax, inputs),
        (Part::InputScale, inputs),
        (Part::Centres, HIDDEN.saturating_mul(inputs)),
        (Part::Widths, HIDDEN),
        (Part::Log2Decay, HIDDEN),
        (Part::Weights, HIDDEN),
        (Part::Linear, inputs),
        (Part::Bias, 1),
        (Part::OutputScale, 1),
        (Part::OutputOffset, 1),
    ];
    let mut start = 0usize;
    for (part, n) in spans {
        let end = start.saturating_add(n);
        if i < end {
            return (part, i.saturating_sub(start));
        }
        start = end;
    }
    (Part::Shape, i)
}

/// The model's words in block order, in the five-slot layout the drive
/// stores and runs.
pub fn to_words(m: &Weights) -> [f32; WORDS] {
    to_block_words(m, INPUTS).0
}

/// The model's words as a block of its first `inputs` inputs (the first
/// `n` of the array, `n` returned): what a host uploads, and what the
/// drive's CRC in the status covers.
pub fn to_block_words(m: &Weights, inputs: usize) -> ([f32; WORDS], usize) {
    let mut out = [0.0f32; WORDS];
    let n = inputs.min(INPUTS);
    fn first(a: &[f32; INPUTS], n: usize) -> core::iter::Take<core::iter::Copied<core::slice::Iter<'_, f32>>> {
        a.iter().copied().take(n)
    }
    let centres = m.centres.iter().flat_map(move |c| c.iter().copied().take(n));
    let src = first(&m.input_min, n)
        .chain(first(&m.input_max, n))
        .chain(first(&m.input_scale, n))
        .chain(centres)
        .chain(m.widths.iter().copied())
        .chain(m.log2_decay.iter().copied())
        .chain(m.weights.iter().copied())
        .chain(first(&m.linear, n))
        .chain(core::iter::once(m.bias))
        .chain(core::iter::once(m.output_scale))
        .chain(core::iter::once(m.output_offset));
    let mut count = 0usize;
    for (o, v) in out.iter_mut().zip(src) {
        *o = v;
        count = count.saturating_add(1);
    }
    (out, count)
}

/// The model of a five-input block's words (no checks: see [`validate`]).
pub fn from_words(w: &[f32; WORDS]) -> Weights {
    from_block_words(w, INPUTS)
}

/// The model of a block of `inputs` inputs (its words first in `w`), in
/// the five-slot layout: slots past `inputs` unused, as [`super::lift`]
/// leaves them. No checks: see [`validate`].
pub fn from_block_words(w: &[f32], inputs: usize) -> Weights {
    let n = inputs.min(INPUTS);
    let mut m = Weights {
        input_min: [0.0; INPUTS],
        input_max: [0.0; INPUTS],
        input_scale: [0.0; INPUTS],
        centres: [[0.0; INPUTS]; HIDDEN],
        widths: [0.0; HIDDEN],
        log2_decay: [0.0; HIDDEN],
        weights: [0.0; HIDDEN],
        linear: [0.0; INPUTS],
        bias: 0.0,
        output_scale: 0.0,
        output_offset: 0.0,
    };
    for c in m.centres.iter_mut() {
        *c = [-1.0; INPUTS];
    }
    let mut words = w.iter().copied();
    let mut fill = |dst: &mut [f32]| {
        for d in dst.iter_mut() {
            *d = words.next().unwrap_or(0.0);
        }
    };
    fn used(a: &mut [f32; INPUTS], n: usize) -> &mut [f32] {
        a.get_mut(..n).unwrap_or(&mut [])
    }
    fill(used(&mut m.input_min, n));
    fill(used(&mut m.input_max, n));
    fill(used(&mut m.input_scale, n));
    for c in m.centres.iter_mut() {
        fill(used(c, n));
    }
    fill(&mut m.widths);
    fill(&mut m.log2_decay);
    fill(&mut m.weights);
    fill(used(&mut m.linear, n));
    let mut tail = [0.0f32; 3];
    fill(&mut tail);
    let [bias, scale, offset] = tail;
    m.bias = bias;
    m.output_scale = scale;
    m.output_offset = offset;
    m
}

/// `a` and `b` agree within `rel` of `b` (both finite).
fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * b.abs()
}

/// Relative tolerance of the derived words (`input_scale`, `log2_decay`):
/// the generator rounds them once from `f64`, the check recomputes in `f32`.
const DERIVED_REL: f32 = 1e-5;

/// Checks a block against this firmware's network, the drive's force input
/// `source` and its shift bound (`faults.observer_shift_max_m`), and
/// returns its model in the five-slot layout:
/// - shape: `inputs` is 4 or 5, `hidden` this network's, and the word
///   count that of `inputs` inputs;
/// - the structure hash is this network's with `inputs` inputs trained on
///   `source` (weights trained on the other force input are refused,
///   naming it);
/// - every word finite;
/// - normalisation: `input_max > input_min`, `input_scale = 2 / (max − min)`;
///   widths positive and `log2_decay = log₂e / 2σ²`; output scale positive;
/// - shift: the prediction at every corner of the trained input range and
///   at every centre lies within `shift_max_m`, and so does the offset.
pub fn validate(
    inputs: u16,
    hidden: u16,
    structure_hash: &[u8; 8],
    words: &[f32],
    shift_max_m: f32,
    source: ForceSource,
) -> Result<Weights, BlockError> {
    let n = usize::from(inputs);
    if !input_count_ok(n) {
        return Err(err(Part::Shape, 0, Reason::ObserverInputCount));
    }
    if usize::from(hidden) != HIDDEN {
        return Err(err(Part::Shape, 1, Reason::ObserverHiddenCount));
    }
    if words.len() != words_for(n) {
        return Err(err(Part::Shape, 2, Reason::ObserverWordCount));
    }
    check_hash(structure_hash, n, source)?;
    for (i, &s) in words.iter().enumerate() {
        if !s.is_finite() {
            let (part, k) = part_of(i, n);
            return Err(err(part, k, Reason::MustBeFinite));
        }
    }
    let m = from_block_words(words, n);
    let ranges = m.input_min.iter().zip(m.input_max.iter()).zip(m.input_scale.iter()).take(n);
    for (j, ((&lo, &hi), &scale)) in ranges.enumerate() {
        if !(hi > lo) {
            return Err(err(Part::InputMax, j, Reason::ObserverRangeEmpty));
        }
        let want = 2.0 / (hi - lo);
        if !want.is_finite() || !close(scale, want, DERIVED_REL) {
            return Err(err(Part::InputScale, j, Reason::ObserverScaleMismatch));
        }
    }
    for (k, (&s, &decay)) in m.widths.iter().zip(m.log2_decay.iter()).enumerate() {
        if !(s > 0.0) {
            return Err(err(Part::Widths, k, Reason::MustBePositive));
        }
        let want = core::f32::consts::LOG2_E / (2.0 * s * s);
        if !want.is_finite() || !close(decay, want, DERIVED_REL) {
            return Err(err(Part::Log2Decay, k, Reason::ObserverDecayMismatch));
        }
    }
    if !(m.output_scale > 0.0) {
        return Err(err(Part::OutputScale, 0, Reason::MustBePositive));
    }
    if !(m.output_offset.abs() <= shift_max_m) {
        return Err(err(Part::OutputOffset, 0, Reason::ObserverShiftBeyondBound));
    }
    // Corners of the trained range (bit j of `c`: input j at its max; an
    // unused slot's range is the point 0)…
    for c in 0..(1usize << n) {
        let mut x = m.input_min;
        for (j, xj) in x.iter_mut().enumerate() {
            if c & (1 << j) != 0 {
                *xj = m.input_max.get(j).copied().unwrap_or(*xj);
            }
        }
        check_shift(&m, x, shift_max_m, c)?;
    }
    // …and every centre inside it, in physical units.
    for (k, centre) in m.centres.iter().enumerate() {
        let mut x = [0.0f32; INPUTS];
        for (j, (xj, &cz)) in x.iter_mut().zip(centre.iter()).enumerate().take(n) {
            let (lo, hi) = (m.input_min.get(j).copied().unwrap_or(0.0), m.input_max.get(j).copied().unwrap_or(0.0));
            *xj = crate::math::clamp(lo + (cz + 1.0) * 0.5 * (hi - lo), lo, hi);
        }
        check_shift(&m, x, shift_max_m, (1usize << n).saturating_add(k))?;
    }
    Ok(m)
}

/// Checks a model kept in the five-slot layout (a stored record's words)
/// as the block it was uploaded as: four inputs when `structure_hash` is a
/// four-input hash and the fifth slot is unused, else five.
pub fn validate_stored(structure_hash: &[u8; 8], words: &[f32; WORDS], shift_max_m: f32, source: ForceSource) -> Result<Weights, BlockError> {
    let m = from_words(words);
    let four = [ForceSource::LoadCell, ForceSource::Estimate].iter().any(|&s| *structure_hash == structure_hash_for(STATIC_INPUTS, s));
    let n = if four && fifth_unused(&m) { STATIC_INPUTS } else { INPUTS };
    let (w, len) = to_block_words(&m, n);
    validate(n as u16, HIDDEN as u16, structure_hash, w.get(..len).unwrap_or(&[]), shift_max_m, source)
}

fn check_shift(m: &Weights, x: [f32; INPUTS], shift_max_m: f32, point: usize) -> Result<(), BlockError> {
    let p = super::evaluate(m, x);
    if !p.valid || !(p.value_m.abs() <= shift_max_m) {
        return Err(err(Part::Prediction, point, Reason::ObserverShiftBeyondBound));
    }
    Ok(())
}

/// A block being uploaded: the words received so far. Chunks come in
/// order; one sent again (a lost reply) is taken again; `Commit` needs
/// every word.
#[derive(Clone, Debug, PartialEq)]
pub struct Staging {
    pub inputs: u16,
    pub hidden: u16,
    pub structure_hash: [u8; 8],
    pub words: [f32; WORDS],
    /// Words `0..received` are in.
    received: u16,
    /// `Begin` was accepted.
    open: bool,
}

impl Default for Staging {
    fn default() -> Self {
        Self::new()
    }
}

impl Staging {
    pub const fn new() -> Self {
        Self { inputs: 0, hidden: 0, structure_hash: [0; 8], words: [0.0; WORDS], received: 0, open: false }
    }

    /// Starts an upload, forgetting any unfinished one. The shape and the
    /// hash (against the drive's force input `source`) are checked here
    /// already, so a wrong block is refused before its words are sent.
    pub fn begin(&mut self, inputs: u16, hidden: u16, words: u16, structure_hash: [u8; 8], source: ForceSource) -> Result<(), BlockError> {
        self.open = false;
        self.received = 0;
        let n = usize::from(inputs);
        if !input_count_ok(n) {
            return Err(err(Part::Shape, 0, Reason::ObserverInputCount));
        }
        if usize::from(hidden) != HIDDEN {
            return Err(err(Part::Shape, 1, Reason::ObserverHiddenCount));
        }
        if usize::from(words) != words_for(n) {
            return Err(err(Part::Shape, 2, Reason::ObserverWordCount));
        }
        check_hash(&structure_hash, n, source)?;
        self.inputs = inputs;
        self.hidden = hidden;
        self.structure_hash = structure_hash;
        self.open = true;
        Ok(())
    }

    /// Words `start..start + values.len()`.
    pub fn write(&mut self, start: u16, values: &[f32]) -> Result<(), BlockError> {
        if !self.open {
            return Err(err(Part::Shape, 0, Reason::ObserverNoUpload));
        }
        if start > self.received {
            let (part, k) = part_of(usize::from(self.received), usize::from(self.inputs));
            return Err(err(part, k, Reason::ObserverWordMissing));
        }
        let start = usize::from(start);
        let end = start.saturating_add(values.len());
        if end > self.len() {
            return Err(err(Part::Shape, 2, Reason::ObserverWordCount));
        }
        let Some(dst) = self.words.get_mut(start..end) else {
            return Err(err(Part::Shape, 2, Reason::ObserverWordCount));
        };
        dst.copy_from_slice(values);
        self.received = self.received.max(u16::try_from(end).unwrap_or(u16::MAX));
        Ok(())
    }

    /// Words of the block being uploaded.
    fn len(&self) -> usize {
        words_for(usize::from(self.inputs))
    }

    /// The first word not yet received, if any.
    pub fn missing(&self) -> Option<usize> {
        let n = usize::from(self.received);
        (n < self.len()).then_some(n)
    }

    /// Every word there: the block validated, and the upload closed
    /// whatever the outcome (a refused block is sent again from `Begin`).
    pub fn commit(&mut self, shift_max_m: f32, source: ForceSource) -> Result<Weights, BlockError> {
        if !self.open {
            return Err(err(Part::Shape, 0, Reason::ObserverNoUpload));
        }
        if let Some(i) = self.missing() {
            let (part, k) = part_of(i, usize::from(self.inputs));
            return Err(err(part, k, Reason::ObserverWordMissing));
        }
        self.open = false;
        let words = self.words.get(..self.len()).unwrap_or(&[]);
        validate(self.inputs, self.hidden, &self.structure_hash, words, shift_max_m, source)
    }
}
