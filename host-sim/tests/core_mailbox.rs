//! The lock-free hand-over between thread mode and the PWM interrupt
//! (`servo_core::mailbox`): single-threaded semantics, then two real threads
//! hammering each channel to catch torn or lost values.
//!
//! Run alone: `cd host-sim && cargo test --release --test core_mailbox`.

use servo_core::mailbox::{Handoff, Slot, TripleBuffer};
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;

/// A payload whose fields are all derived from one counter, so a value
/// assembled from two different writes (a torn read) is detectable.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Frame {
    seq: u64,
    words: [u64; 15],
    value: f32,
}

impl Frame {
    fn new(seq: u64) -> Self {
        let mut words = [0u64; 15];
        for (i, w) in words.iter_mut().enumerate() {
            *w = seq.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(i as u32);
        }
        Self { seq, words, value: seq as f32 }
    }

    fn is_whole(&self) -> bool {
        *self == Frame::new(self.seq)
    }
}

#[test]
fn slot_hands_one_value_at_a_time() {
    let slot: Slot<u32> = Slot::new();
    let (mut tx, mut rx) = slot.split().unwrap();
    assert!(slot.split().is_none(), "only one pair of ends");
    assert_eq!(rx.try_take(), None);
    assert!(tx.is_empty());
    assert_eq!(tx.try_put(7), Ok(()));
    assert!(!tx.is_empty());
    assert_eq!(tx.try_put(8), Err(8), "a full slot refuses, nothing overwritten");
    assert_eq!(rx.try_take(), Some(7));
    assert_eq!(rx.try_take(), None);
    assert_eq!(tx.try_put(9), Ok(()));
    assert_eq!(rx.try_take(), Some(9));
}

#[test]
fn slot_value_can_be_withdrawn_until_taken() {
    let slot: Slot<u32> = Slot::new();
    let (mut tx, mut rx) = slot.split().unwrap();
    assert_eq!(tx.try_withdraw(), None, "nothing to withdraw");
    tx.try_put(1).unwrap();
    assert_eq!(tx.try_withdraw(), Some(1));
    assert!(tx.is_empty());
    assert_eq!(rx.try_take(), None, "a withdrawn value is never taken");
    tx.try_put(2).unwrap();
    assert_eq!(rx.try_take(), Some(2));
    assert_eq!(tx.try_withdraw(), None, "a taken value cannot be withdrawn");
}

#[test]
fn triple_buffer_gives_the_newest_value() {
    let tb = TripleBuffer::new(0u32);
    let (mut w, mut r) = tb.split().unwrap();
    assert!(tb.split().is_none());
    assert_eq!(r.read(), 0, "initial value before any publication");
    assert!(!r.has_fresh());
    w.publish(1);
    w.publish(2);
    w.publish(3);
    assert!(r.has_fresh());
    assert_eq!(r.read(), 3, "only the newest survives");
    assert!(!r.has_fresh());
    assert_eq!(r.read(), 3, "re-reading gives the same value");
    for i in 4..100 {
        w.publish(i);
        assert_eq!(r.read(), i);
    }
}

#[test]
fn handoff_is_put_once_and_claimed_once() {
    let h: Handoff<Vec<u8>> = Handoff::new();
    assert!(h.claim().is_none(), "nothing to claim yet");
    assert!(!h.is_filled());
    assert!(h.put(vec![1, 2, 3]).is_ok());
    assert!(h.is_filled());
    assert_eq!(h.put(vec![4]), Err(vec![4]), "a second put is refused");
    let v = h.claim().unwrap();
    v.push(4);
    assert_eq!(v, &vec![1, 2, 3, 4]);
    assert!(h.claim().is_none(), "claimed only once");
}

/// Values pushed through each channel by the stress tests. A slot needs a
/// round trip per value, so its tests yield while waiting (the machine may
/// have fewer free cores than threads) and use a tenth of the count.
const STRESS_ITERATIONS: u64 = 2_000_000;
const SLOT_STRESS_ITERATIONS: u64 = STRESS_ITERATIONS / 10;

#[test]
fn slot_under_two_threads_loses_nothing_and_tears_nothing() {
    let slot: &'static Slot<Frame> = Box::leak(Box::new(Slot::new()));
    let (mut tx, mut rx) = slot.split().unwrap();
    let producer = thread::spawn(move || {
        let mut seq = 0;
        while seq < SLOT_STRESS_ITERATIONS {
            if tx.try_put(Frame::new(seq)).is_ok() {
                seq += 1;
            } else {
                thread::yield_now();
            }
        }
    });
    let mut expected = 0;
    while expected < SLOT_STRESS_ITERATIONS {
        match rx.try_take() {
            Some(f) => {
                assert!(f.is_whole(), "torn value {f:?}");
                assert_eq!(f.seq, expected, "values lost or reordered");
                expected += 1;
            }
            None => thread::yield_now(),
        }
    }
    producer.join().unwrap();
    assert_eq!(rx.try_take(), None);
}

#[test]
fn slot_with_withdrawals_under_two_threads_hands_each_value_to_exactly_one_side() {
    // The producer withdraws every third value if it can; each value must end
    // up either taken (whole, in order) or withdrawn, never both, never lost.
    let slot: &'static Slot<Frame> = Box::leak(Box::new(Slot::new()));
    let (mut tx, mut rx) = slot.split().unwrap();
    let done: &'static AtomicBool = Box::leak(Box::new(AtomicBool::new(false)));
    let producer = thread::spawn(move || {
        let mut withdrawn = Vec::new();
        let mut seq = 0;
        while seq < SLOT_STRESS_ITERATIONS {
            if tx.try_put(Frame::new(seq)).is_err() {
                thread::yield_now();
                continue;
            }
            if seq % 3 == 0 {
                if let Some(f) = tx.try_withdraw() {
                    assert!(f.is_whole() && f.seq == seq, "withdrew something else: {f:?}");
                    withdrawn.push(seq);
                }
            }
            seq += 1;
        }
        while !tx.is_empty() {
            thread::yield_now();
        }
        done.store(true, Ordering::Release);
        withdrawn
    });
    let mut taken = Vec::new();
    loop {
        let finished = done.load(Ordering::Acquire);
        if let Some(f) = rx.try_take() {
            assert!(f.is_whole(), "torn value {f:?}");
            if let Some(&last) = taken.last() {
                assert!(f.seq > last, "reordered: {} after {last}", f.seq);
            }
            taken.push(f.seq);
        } else if finished {
            break;
        } else {
            thread::yield_now();
        }
    }
    let withdrawn = producer.join().unwrap();
    assert_eq!(taken.len() + withdrawn.len(), SLOT_STRESS_ITERATIONS as usize, "values lost or duplicated");
    let mut all: Vec<u64> = taken.iter().chain(withdrawn.iter()).copied().collect();
    all.sort_unstable();
    all.dedup();
    assert_eq!(all.len(), SLOT_STRESS_ITERATIONS as usize, "a value both taken and withdrawn");
    println!("slot with withdrawals: {} taken, {} withdrawn", taken.len(), withdrawn.len());
    assert!(!withdrawn.is_empty() && taken.len() > withdrawn.len());
}

#[test]
fn triple_buffer_under_two_threads_never_tears_and_never_goes_back() {
    let tb: &'static TripleBuffer<Frame> = Box::leak(Box::new(TripleBuffer::new(Frame::new(0))));
    let (mut w, mut r) = tb.split().unwrap();
    let done: &'static AtomicBool = Box::leak(Box::new(AtomicBool::new(false)));
    let writer = thread::spawn(move || {
        for seq in 1..=STRESS_ITERATIONS {
            w.publish(Frame::new(seq));
        }
        done.store(true, Ordering::Release);
    });
    let mut last = 0;
    let mut reads = 0u64;
    let mut distinct = 0u64;
    loop {
        let finished = done.load(Ordering::Acquire);
        let f = r.read();
        assert!(f.is_whole(), "torn value {f:?}");
        assert!(f.seq >= last, "went back from {last} to {}", f.seq);
        if f.seq != last {
            distinct += 1;
        }
        last = f.seq;
        reads += 1;
        if finished {
            break;
        }
    }
    writer.join().unwrap();
    assert_eq!(r.read().seq, STRESS_ITERATIONS, "the last publication is what remains");
    println!("triple buffer: {reads} reads, {distinct} distinct values seen, none torn");
    assert!(distinct > 1, "the reader ran concurrently with the writer");
}

#[test]
fn handoff_claimed_by_exactly_one_of_many_threads() {
    for _ in 0..200 {
        let h: &'static Handoff<u64> = Box::leak(Box::new(Handoff::new()));
        let claimers: Vec<_> = (0..4)
            .map(|_| {
                thread::spawn(move || loop {
                    if let Some(v) = h.claim() {
                        assert_eq!(*v, 42);
                        return true;
                    }
                    if h.is_filled() {
                        // Filled, and someone else won (or will win) the claim.
                        return h.claim().is_some();
                    }
                    std::hint::spin_loop();
                })
            })
            .collect();
        h.put(42).unwrap();
        let winners = claimers.into_iter().map(|t| t.join().unwrap()).filter(|&won| won).count();
        assert_eq!(winners, 1);
    }
}
