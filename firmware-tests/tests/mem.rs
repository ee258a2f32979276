//! The image's compact memory and division routines (`src/mem.rs`,
//! `src/udiv.rs`, assembly) on the target, against references that cannot
//! call them: byte loops through volatile accesses (LLVM does not turn
//! those into `memcpy`) and, for the division, the identity
//! `q·b + r = a, r < b` (a multiplication never calls a routine).
//!
//! Linked here exactly as in the image: their symbols are strong,
//! compiler_builtins' weak, so every copy in this test binary, the
//! harness's included, runs through them too.
#![no_std]
#![no_main]

#[path = "../../src/mem.rs"]
mod mem;
#[path = "../../src/udiv.rs"]
mod udiv;

use core::ptr::{read_volatile, write_volatile};
use firmware_tests::{check, test_main, Outcome};

extern "C" {
    fn memcpy(dst: *mut u8, src: *const u8, n: usize) -> *mut u8;
    fn __aeabi_memclr4(dst: *mut u8, n: usize);
    fn __aeabi_memclr8(dst: *mut u8, n: usize);
    fn memcmp(a: *const u8, b: *const u8, n: usize) -> i32;
    fn __udivmoddi4(a: u64, b: u64, rem: *mut u64) -> u64;
}

/// xorshift32: deterministic test bytes.
struct Rng(u32);
impl Rng {
    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
    fn next_u64(&mut self) -> u64 {
        (u64::from(self.next()) << 32) | u64::from(self.next())
    }
}

#[repr(C, align(8))]
struct Buf([u8; 96]);

fn fill(b: &mut Buf, rng: &mut Rng) {
    for i in 0..b.0.len() {
        // SAFETY: in bounds of `b`.
        unsafe { write_volatile(b.0.as_mut_ptr().add(i), rng.next() as u8) };
    }
}

fn at(b: &Buf, i: usize) -> u8 {
    // SAFETY: callers index inside the 96 bytes.
    unsafe { read_volatile(b.0.as_ptr().add(i)) }
}

/// Every source and destination alignment (0–3) and length 0–70: the copy
/// lands byte for byte, nothing outside it is touched, `dst` is returned.
fn memcpy_every_alignment_and_length() -> Outcome {
    let mut rng = Rng(0x1234_5678);
    let (mut src, mut dst, mut before) = (Buf([0; 96]), Buf([0; 96]), Buf([0; 96]));
    for s_off in 0..4 {
        for d_off in 0..4 {
            for n in 0..=70 {
                fill(&mut src, &mut rng);
                fill(&mut dst, &mut rng);
                for i in 0..96 {
                    // SAFETY: in bounds.
                    unsafe { write_volatile(before.0.as_mut_ptr().add(i), at(&dst, i)) };
                }
                // SAFETY: both ranges lie inside their 96-byte buffers.
                let r = unsafe { memcpy(dst.0.as_mut_ptr().add(d_off), src.0.as_ptr().add(s_off), n) };
                check!(r == dst.0.as_mut_ptr().wrapping_add(d_off), "returned pointer, {} {} {}", s_off, d_off, n);
                for i in 0..96 {
                    let want = if i >= d_off && i < d_off + n { at(&src, s_off + i - d_off) } else { at(&before, i) };
                    check!(at(&dst, i) == want, "memcpy s{} d{} n{}: byte {}", s_off, d_off, n, i);
                }
            }
        }
    }
    Ok(())
}

/// Word-aligned clears of every length 0–70 (both entry points): zeros
/// inside, nothing touched outside.
fn memclr_every_length() -> Outcome {
    let mut rng = Rng(0x9E37_79B9);
    let (mut dst, mut before) = (Buf([0; 96]), Buf([0; 96]));
    for entry in 0..2 {
        for off in [0usize, 4, 8] {
            for n in 0..=70 {
                fill(&mut dst, &mut rng);
                for i in 0..96 {
                    // SAFETY: in bounds.
                    unsafe { write_volatile(before.0.as_mut_ptr().add(i), at(&dst, i)) };
                }
                // SAFETY: inside the buffer, word-aligned (`off` a multiple of 4, the buffer 8-aligned).
                unsafe {
                    if entry == 0 {
                        __aeabi_memclr4(dst.0.as_mut_ptr().add(off), n)
                    } else {
                        __aeabi_memclr8(dst.0.as_mut_ptr().add(off), n)
                    }
                };
                for i in 0..96 {
                    let want = if i >= off && i < off + n { 0 } else { at(&before, i) };
                    check!(at(&dst, i) == want, "memclr{} off{} n{}: byte {}", 4 + 4 * entry, off, n, i);
                }
            }
        }
    }
    Ok(())
}

/// Equal blocks compare 0 at every length; a difference at any position,
/// with bytes on both sides of 0x80, gives the sign of the unsigned byte
/// comparison.
fn memcmp_sign_of_the_first_difference() -> Outcome {
    let mut rng = Rng(0x0BAD_F00D);
    let (mut a, mut b) = (Buf([0; 96]), Buf([0; 96]));
    for n in 0..=40 {
        fill(&mut a, &mut rng);
        for i in 0..96 {
            // SAFETY: in bounds.
            unsafe { write_volatile(b.0.as_mut_ptr().add(i), at(&a, i)) };
        }
        // SAFETY: `n` ≤ 40 < 96.
        check!(unsafe { memcmp(a.0.as_ptr(), b.0.as_ptr(), n) } == 0, "equal, n {}", n);
        for pos in 0..n {
            for (x, y) in [(0x01u8, 0xFFu8), (0xFF, 0x01), (0x7F, 0x80), (0x80, 0x7F), (0x00, 0x01)] {
                // SAFETY: `pos` < `n` ≤ 40.
                unsafe {
                    write_volatile(a.0.as_mut_ptr().add(pos), x);
                    write_volatile(b.0.as_mut_ptr().add(pos), y);
                }
                // SAFETY: as above.
                let r = unsafe { memcmp(a.0.as_ptr(), b.0.as_ptr(), n) };
                check!((r < 0) == (x < y) && r != 0, "n {} pos {}: {:#x} vs {:#x} gave {}", n, pos, x, y, r);
                // SAFETY: as above.
                unsafe { write_volatile(b.0.as_mut_ptr().add(pos), x) };
            }
        }
    }
    Ok(())
}

/// 20 000 random pairs over every magnitude (32-bit and 64-bit dividends
/// and divisors) and the edges: `q·b + r = a` with `r < b`.
fn udivmoddi4_quotient_and_remainder() -> Outcome {
    let mut rng = Rng(0xC0FF_EE11);
    let edges = [
        (0u64, 1u64),
        (1, 1),
        (u64::MAX, 1),
        (u64::MAX, u64::MAX),
        (u64::MAX, 2),
        (u64::MAX - 1, u64::MAX),
        (1 << 32, (1 << 32) - 1),
        (123_456_789_000, 1000),
        (999, 1000),
        (1 << 63, 3),
    ];
    let mut k = 0;
    while k < 20_000 + edges.len() {
        let (a, b) = match edges.get(k) {
            Some(&e) => e,
            None => {
                let (sa, sb) = (rng.next() % 64, rng.next() % 64);
                (rng.next_u64() >> sa, (rng.next_u64() >> sb).max(1))
            }
        };
        let mut r = 0u64;
        // SAFETY: `r` is a valid place for the remainder.
        let q = unsafe { __udivmoddi4(a, b, &mut r) };
        check!(r < b, "{} / {}: remainder {}", a, b, r);
        let (qb, over) = q.overflowing_mul(b);
        check!(!over && qb.checked_add(r) == Some(a), "{} / {}: q {} r {}", a, b, q, r);
        k += 1;
    }
    Ok(())
}

test_main!(
    memcpy_every_alignment_and_length,
    memclr_every_length,
    memcmp_sign_of_the_first_difference,
    udivmoddi4_quotient_and_remainder
);
