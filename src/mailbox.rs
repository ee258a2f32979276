//! Lock-free hand-over between thread mode and the PWM interrupt.
//!
//! The current loop runs in the highest-priority interrupt. Nothing it
//! shares with thread mode may be guarded by masking interrupts, because a
//! mask held by thread mode (or by a logger inside it) would delay the
//! sampling-to-duty path by however long thread mode holds it. So every
//! exchange here is made of atomics alone: a side never waits for the other,
//! and a side that is preempted half-way leaves the other side a consistent
//! view.
//!
//! Three shapes cover what the firmware exchanges:
//!
//! - [`Slot`]: one value at a time from one producer to one consumer
//!   (commands in, their outcomes back). `try_put` refuses while the
//!   previous value has not been taken, so nothing is ever overwritten; the
//!   producer may withdraw a value the consumer has not started taking.
//! - [`TripleBuffer`]: the newest value from one writer to one reader
//!   (telemetry out). The writer never waits or fails; the reader always
//!   gets a whole value, the newest one published. Three buffers make both
//!   sides wait-free and free of torn reads without a retry loop: the writer
//!   owns one buffer, the reader another, and they swap ownership of the
//!   third with one atomic exchange. (A seqlock would need a retry in the
//!   reader and a racy copy of the data; the third buffer costs only memory.)
//! - [`Handoff`]: a value moved once from one context to another and owned
//!   there for ever (the controller and the interrupt's own state, installed
//!   before the interrupt uses them).
//!
//! Single producer / single consumer is enforced by types: `split` hands out
//! the two ends once, and each end is used through `&mut`.
//!
//! `no_std`, no allocation, no panic path, no arithmetic that can overflow;
//! generic over the payload (`T: Copy` for the two channels, so a value is
//! copied in and out and never dropped in a shared buffer). Needs
//! compare-and-swap atomics on `u8`/`bool` (all ARMv7-M and hosted targets).

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

// ---------------------------------------------------------------------------
// Slot: one value at a time, one producer, one consumer.

/// Slot states. The producer writes only in `SLOT_EMPTY`; the consumer
/// reads only in `SLOT_TAKING`, which it enters from `SLOT_FULL`; the
/// producer may withdraw a value only from `SLOT_FULL`, i.e. before the
/// consumer started reading it.
const SLOT_EMPTY: u8 = 0;
const SLOT_FULL: u8 = 1;
const SLOT_TAKING: u8 = 2;

/// A single-element single-producer/single-consumer channel.
///
/// The state hands the buffer back and forth: the producer writes only while
/// it is empty and marks it full with `Release` after writing; the consumer
/// claims a full buffer (`Acquire`, so the write is visible), reads it and
/// marks it empty with `Release`. The producer can take back a value the
/// consumer has not claimed yet ([`SlotSender::try_withdraw`]), so a request
/// that timed out is never acted on late. At any instant exactly one side may
/// touch the buffer.
pub struct Slot<T> {
    state: AtomicU8,
    split: AtomicBool,
    value: UnsafeCell<MaybeUninit<T>>,
}

// SAFETY: the buffer is accessed by one side at a time, as handed over by
// `state` (see the type's documentation); `T: Send` because values cross
// contexts.
unsafe impl<T: Send> Sync for Slot<T> {}

impl<T> core::fmt::Debug for Slot<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Slot").field("state", &self.state.load(Ordering::Relaxed)).finish()
    }
}

impl<T: Copy> Default for Slot<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy> Slot<T> {
    /// An empty slot (usable in a `static`).
    pub const fn new() -> Self {
        Self {
            state: AtomicU8::new(SLOT_EMPTY),
            split: AtomicBool::new(false),
            value: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }

    /// The producer and consumer ends. `None` after the first call: there is
    /// only ever one of each.
    pub fn split(&self) -> Option<(SlotSender<'_, T>, SlotReceiver<'_, T>)> {
        if self.split.swap(true, Ordering::AcqRel) {
            return None;
        }
        Some((SlotSender { slot: self }, SlotReceiver { slot: self }))
    }
}

/// The producing end of a [`Slot`].
pub struct SlotSender<'a, T> {
    slot: &'a Slot<T>,
}

impl<T> core::fmt::Debug for SlotSender<'_, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SlotSender").finish_non_exhaustive()
    }
}

impl<T: Copy> SlotSender<'_, T> {
    /// Puts `value` in the slot, or gives it back if the previous one has not
    /// been taken yet (nothing is overwritten).
    pub fn try_put(&mut self, value: T) -> Result<(), T> {
        if self.slot.state.load(Ordering::Acquire) != SLOT_EMPTY {
            return Err(value);
        }
        // SAFETY: the slot is empty, so the consumer will not touch the
        // buffer until we mark it full below; we are the only producer
        // (`&mut self`), and the consumer's last read finished before its
        // Release store of EMPTY, seen above with Acquire.
        unsafe { (*self.slot.value.get()).write(value) };
        self.slot.state.store(SLOT_FULL, Ordering::Release);
        Ok(())
    }

    /// Takes back the value put last if the consumer has not started taking
    /// it; `None` if the slot is empty or the consumer already has it.
    pub fn try_withdraw(&mut self) -> Option<T> {
        if self
            .slot
            .state
            .compare_exchange(SLOT_FULL, SLOT_EMPTY, Ordering::AcqRel, Ordering::Relaxed)
            .is_err()
        {
            return None;
        }
        // SAFETY: we moved FULL→EMPTY before the consumer claimed it, so the
        // consumer never read it, and only we write (`&mut self`); the value
        // is the one our last `try_put` initialised.
        Some(unsafe { (*self.slot.value.get()).assume_init() })
    }

    /// True once the consumer has taken the last value put (or it was
    /// withdrawn).
    pub fn is_empty(&self) -> bool {
        self.slot.state.load(Ordering::Acquire) == SLOT_EMPTY
    }
}

/// The consuming end of a [`Slot`].
pub struct SlotReceiver<'a, T> {
    slot: &'a Slot<T>,
}

impl<T> core::fmt::Debug for SlotReceiver<'_, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SlotReceiver").finish_non_exhaustive()
    }
}

impl<T: Copy> SlotReceiver<'_, T> {
    /// Takes the value if there is one.
    pub fn try_take(&mut self) -> Option<T> {
        if self
            .slot
            .state
            .compare_exchange(SLOT_FULL, SLOT_TAKING, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
        {
            return None;
        }
        // SAFETY: we moved FULL→TAKING (Acquire: the producer's write is
        // visible); the producer neither writes nor withdraws until we mark
        // the slot empty; the value was initialised by `try_put`.
        let value = unsafe { (*self.slot.value.get()).assume_init() };
        self.slot.state.store(SLOT_EMPTY, Ordering::Release);
        Some(value)
    }
}

// ---------------------------------------------------------------------------
// TripleBuffer: newest value, one writer, one reader, both wait-free.

/// Index bits of the shared state (which buffer is the "middle" one).
const INDEX_MASK: u8 = 0b011;
/// Set when the middle buffer holds a value the reader has not seen.
const FRESH: u8 = 0b100;

/// Three buffers: the writer's back buffer, the reader's front buffer and a
/// middle one exchanged between them through one atomic byte (its index plus
/// a "fresh" flag).
pub struct TripleBuffer<T> {
    middle: AtomicU8,
    split: AtomicBool,
    buffers: [UnsafeCell<T>; 3],
}

// SAFETY: each buffer is owned by exactly one side at a time, ownership
// moving only through the atomic exchange of `middle` (AcqRel on both sides).
unsafe impl<T: Send> Sync for TripleBuffer<T> {}

impl<T> core::fmt::Debug for TripleBuffer<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TripleBuffer").field("middle", &self.middle.load(Ordering::Relaxed)).finish()
    }
}

impl<T: Copy> TripleBuffer<T> {
    /// All three buffers hold `initial`; the reader sees it until the first
    /// publication.
    pub const fn new(initial: T) -> Self {
        Self {
            // Writer starts on buffer 1, the middle is 0, the reader on 2:
            // with a zero `initial` the whole buffer is zero bytes (`.bss`,
            // no flash for initial values).
            middle: AtomicU8::new(0),
            split: AtomicBool::new(false),
            buffers: [UnsafeCell::new(initial), UnsafeCell::new(initial), UnsafeCell::new(initial)],
        }
    }

    /// The writer and reader ends. `None` after the first call.
    pub fn split(&self) -> Option<(TripleWriter<'_, T>, TripleReader<'_, T>)> {
        if self.split.swap(true, Ordering::AcqRel) {
            return None;
        }
        Some((TripleWriter { tb: self, back: 1 }, TripleReader { tb: self, front: 2 }))
    }

    /// Buffer `index` (0..=2; anything else maps to 2, which cannot happen
    /// and keeps the access free of a bounds-check panic).
    fn buffer(&self, index: u8) -> *mut T {
        let [a, b, c] = &self.buffers;
        match index & INDEX_MASK {
            0 => a.get(),
            1 => b.get(),
            _ => c.get(),
        }
    }
}

/// The writing end of a [`TripleBuffer`].
pub struct TripleWriter<'a, T> {
    tb: &'a TripleBuffer<T>,
    back: u8,
}

impl<T> core::fmt::Debug for TripleWriter<'_, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TripleWriter").field("back", &self.back).finish()
    }
}

impl<T: Copy> TripleWriter<'_, T> {
    /// Makes `value` the newest one. Never waits, never fails.
    pub fn publish(&mut self, value: T) {
        // SAFETY: the back buffer is owned by the writer alone until it is
        // exchanged below.
        unsafe { self.tb.buffer(self.back).write(value) };
        // Release: the reader that takes this buffer sees the write above.
        // Acquire: the buffer we get back was released by the reader's swap,
        // so its last read of it is complete before we overwrite it.
        let previous = self.tb.middle.swap(self.back | FRESH, Ordering::AcqRel);
        self.back = previous & INDEX_MASK;
    }
}

/// The reading end of a [`TripleBuffer`].
pub struct TripleReader<'a, T> {
    tb: &'a TripleBuffer<T>,
    front: u8,
}

impl<T> core::fmt::Debug for TripleReader<'_, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TripleReader").field("front", &self.front).finish()
    }
}

impl<T: Copy> TripleReader<'_, T> {
    /// True if a value newer than the last one read has been published.
    pub fn has_fresh(&self) -> bool {
        self.tb.middle.load(Ordering::Relaxed) & FRESH != 0
    }

    /// The newest value published (or the last one read, or the initial
    /// value, if nothing newer exists). Never waits, never torn.
    pub fn read(&mut self) -> T {
        if self.has_fresh() {
            let previous = self.tb.middle.swap(self.front, Ordering::AcqRel);
            self.front = previous & INDEX_MASK;
        }
        // SAFETY: the front buffer is owned by the reader alone; it was
        // released by the writer's swap (seen with Acquire above).
        unsafe { self.tb.buffer(self.front).read() }
    }
}

// ---------------------------------------------------------------------------
// Handoff: a value moved once into another context and owned there.

const EMPTY: u8 = 0;
const WRITING: u8 = 1;
const READY: u8 = 2;
const CLAIMED: u8 = 3;

/// A place for one value, filled once by one context and then claimed once
/// by another, which owns it from then on (`&mut` for the lifetime of the
/// `Handoff`, i.e. for ever when it is a `static`).
///
/// States move only forward: empty → writing → ready → claimed. `put`
/// fails unless empty, `claim` succeeds only on ready and only once; so the
/// value is never accessed from two places.
pub struct Handoff<T> {
    state: AtomicU8,
    value: UnsafeCell<MaybeUninit<T>>,
}

// SAFETY: the value is written only between EMPTY→WRITING and →READY by the
// single `put` that won the exchange, and accessed after READY→CLAIMED only
// by the single caller that won that exchange.
unsafe impl<T: Send> Sync for Handoff<T> {}

impl<T> core::fmt::Debug for Handoff<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Handoff").field("state", &self.state.load(Ordering::Relaxed)).finish()
    }
}

impl<T> Default for Handoff<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> Handoff<T> {
    /// An empty hand-off (usable in a `static`).
    pub const fn new() -> Self {
        Self { state: AtomicU8::new(EMPTY), value: UnsafeCell::new(MaybeUninit::uninit()) }
    }

    /// Stores `value` for the other side, or gives it back if something was
    /// stored already.
    pub fn put(&self, value: T) -> Result<(), T> {
        if self.state.compare_exchange(EMPTY, WRITING, Ordering::Acquire, Ordering::Relaxed).is_err() {
            return Err(value);
        }
        // SAFETY: we won EMPTY→WRITING: no one else writes, and `claim` does
        // not touch the value before READY.
        unsafe { (*self.value.get()).write(value) };
        self.state.store(READY, Ordering::Release);
        Ok(())
    }

    /// True once a value has been put (claimed or not).
    pub fn is_filled(&self) -> bool {
        matches!(self.state.load(Ordering::Acquire), READY | CLAIMED)
    }

    /// Exclusive access to the stored value, granted once: `None` before a
    /// value is ready and on every call after the first successful one.
    // `&self` → `&mut T` is the point of this type: the state machine, not
    // the borrow checker, guarantees the reference is handed out once.
    #[allow(clippy::mut_from_ref)]
    pub fn claim(&self) -> Option<&mut T> {
        if self.state.compare_exchange(READY, CLAIMED, Ordering::Acquire, Ordering::Relaxed).is_err() {
            return None;
        }
        // SAFETY: READY (seen with Acquire) means the value is initialised
        // and its write visible; winning READY→CLAIMED makes this the only
        // reference ever handed out.
        Some(unsafe { (*self.value.get()).assume_init_mut() })
    }
}
