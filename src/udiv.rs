//! A size-optimised `__udivmoddi4` (u64 division with remainder).
//!
//! The image's only 64-bit division is embassy-stm32's CAN receive
//! timestamp (`Registers::calc_timestamp` → `Duration::from_nanos`, a
//! division by 1000 in the FDCAN interrupt, at most once per received
//! frame). compiler_builtins' version is 0.9 KB (`u64_div_rem`, built for
//! speed); this one is a shift-and-subtract loop of ≈ 60 bytes, at most 64
//! iterations (≈ 0.5 µs at 170 MHz), and the control core and the PWM
//! interrupt never divide 64-bit integers. compiler_builtins' `__aeabi_uldivmod`
//! (the ARM entry point, its assembly wrapper) calls this symbol, which the
//! linker takes from here, before the library's.
//!
//! Division by zero returns quotient `u64::MAX` and the dividend as the
//! remainder (Rust checks the divisor before it divides, so it never asks).

/// `a / b`, with `a % b` stored through `rem` when it is not null.
///
/// # Safety
/// `rem` is null or valid for a write of one `u64` (the C ABI of libgcc's
/// and compiler-rt's `__udivmoddi4`).
#[no_mangle]
pub unsafe extern "C" fn __udivmoddi4(a: u64, b: u64, rem: *mut u64) -> u64 {
    let (q, r) = divmod(a, b);
    if !rem.is_null() {
        // SAFETY: non-null, valid for one write by the function's contract.
        unsafe { rem.write(r) };
    }
    q
}

/// Restoring division, one quotient bit per step, starting at the
/// dividend's highest set bit.
#[inline(always)]
fn divmod(a: u64, b: u64) -> (u64, u64) {
    if b == 0 {
        return (u64::MAX, a);
    }
    if a < b {
        return (0, a);
    }
    let mut q: u64 = 0;
    let mut r: u64 = 0;
    let mut i = 64 - a.leading_zeros();
    while i > 0 {
        i -= 1;
        // The bit shifted out of `r` (set only when `b` > 2^63) means
        // r ≥ b as well.
        let carry = r >> 63;
        r = (r << 1) | ((a >> i) & 1);
        q <<= 1;
        if carry != 0 || r >= b {
            r = r.wrapping_sub(b);
            q |= 1;
        }
    }
    (q, r)
}
