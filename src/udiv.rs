//! A size-optimised `__udivmoddi4` (u64 division with remainder).
//!
//! The image's only 64-bit division is embassy-stm32's CAN receive
//! timestamp (`Registers::calc_timestamp` → `Duration::from_nanos`, a
//! division by 1000 in the FDCAN interrupt, once per received frame).
//! compiler_builtins' version is 0.9 KB (`u64_div_rem`, built for speed);
//! this one is a shift-and-subtract loop of ≈ 70 bytes: one quotient bit per
//! iteration, 32 iterations when the dividend fits 32 bits (the timestamp's
//! does: ≈ 2 µs at 170 MHz, in the FDCAN interrupt, below the PWM
//! interrupt's priority), 64 otherwise. The control core and the PWM
//! interrupt never divide 64-bit integers. compiler_builtins'
//! `__aeabi_uldivmod` (the ARM entry point, its assembly wrapper) calls
//! this symbol, which the linker takes from here (compiler_builtins' is
//! weak).
//!
//! In assembly so that nothing in it can turn back into a call to a
//! division routine. `__udivmoddi4(a: u64, b: u64, rem: *mut u64) -> u64`
//! (AAPCS: `a` in r0:r1, `b` in r2:r3, `rem` on the stack). Division by
//! zero is never asked (Rust checks the divisor before it divides); it
//! would give ones in the quotient bits computed and the dividend as the
//! remainder.

core::arch::global_asm!(
    ".section .text.__udivmoddi4,\"ax\",%progbits",
    ".thumb",
    ".global __udivmoddi4",
    ".type __udivmoddi4,%function",
    ".thumb_func",
    "__udivmoddi4:",
    "    push  {{r4, r5, r6, r7, lr}}",
    "    ldr   r7, [sp, #20]",
    // r5:r4 = running remainder, r1:r0 = dividend shifting out / quotient in.
    "    movs  r4, #0",
    "    movs  r5, #0",
    "    movs  r6, #64",
    "    cbnz  r1, 1f",
    "    mov   r1, r0",
    "    movs  r0, #0",
    "    movs  r6, #32",
    "1:  adds  r0, r0, r0",
    "    adcs  r1, r1, r1",
    "    adcs  r4, r4, r4",
    "    adcs  r5, r5, r5",
    // A bit out of the remainder (only when b > 2^63) means it is ≥ b.
    "    bcs   2f",
    "    subs  r12, r4, r2",
    "    sbcs  lr, r5, r3",
    "    bcc   3f",
    "    b     4f",
    "2:  subs  r12, r4, r2",
    "    sbc   lr, r5, r3",
    "4:  mov   r4, r12",
    "    mov   r5, lr",
    "    orr   r0, r0, #1",
    "3:  subs  r6, r6, #1",
    "    bne   1b",
    "    cbz   r7, 5f",
    "    strd  r4, r5, [r7]",
    "5:  pop   {{r4, r5, r6, r7, pc}}",
    ".size __udivmoddi4, . - __udivmoddi4",
);
