//! Compact `memcpy`, `__aeabi_memclr4/8` and `memcmp` for the image.
//!
//! compiler_builtins' are built for speed: `memcpy` alone is 730 B (every
//! alignment case unrolled), `__aeabi_memcpy4` 156 B, `__aeabi_memclr4`
//! and `__aeabi_memclr8` 174 B each. These are a word loop when source and
//! destination are both word-aligned (every struct copy in the image: the
//! parameter set, the controller's records, the snapshot) and a byte loop
//! otherwise, ≈ 80 B in all; `memcmp` (116 B there; its callers are the
//! flash record's magic and the server's schema checks) a byte loop. compiler_builtins defines its memory routines
//! as weak symbols, so the linker takes these.
//!
//! Cost: a word takes one `ldr`/`str` pair and a compare and branch, about
//! twice the cycles of compiler_builtins' unrolled loop. None of them is in
//! `current_period`; the PWM interrupt's only call is the snapshot's
//! 76-byte clear every 20th period (≈ 40 cycles more, 0.25 µs at 170 MHz),
//! the rest are thread-mode copies (parameter sets, replies) and the
//! speed and position periods' record copies.
//!
//! Written in assembly: in Rust, LLVM would recognise the loops as
//! `memcpy`/`memset` and call them, that is themselves.

core::arch::global_asm!(
    ".section .text.memcpy,\"ax\",%progbits",
    ".thumb",
    ".global memcpy",
    ".type memcpy,%function",
    ".thumb_func",
    // r0 = destination (returned), r1 = source, r2 = length.
    "memcpy:",
    "    mov   r12, r0",
    "    orr   r3, r0, r1",
    "    tst   r3, #3",
    "    bne   2f",
    "1:  cmp   r2, #4",
    "    blo   2f",
    "    ldr   r3, [r1], #4",
    "    str   r3, [r12], #4",
    "    subs  r2, r2, #4",
    "    b     1b",
    "2:  cbz   r2, 4f",
    "3:  ldrb  r3, [r1], #1",
    "    strb  r3, [r12], #1",
    "    subs  r2, r2, #1",
    "    bne   3b",
    "4:  bx    lr",
    ".size memcpy, . - memcpy",
    ".global __aeabi_memcpy",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".thumb_set __aeabi_memcpy, memcpy",
    ".thumb_set __aeabi_memcpy4, memcpy",
    ".thumb_set __aeabi_memcpy8, memcpy",
    "",
    ".section .text.__aeabi_memclr4,\"ax\",%progbits",
    ".global __aeabi_memclr4",
    ".type __aeabi_memclr4,%function",
    ".thumb_func",
    // r0 = destination (word-aligned), r1 = length.
    "__aeabi_memclr4:",
    "    movs  r2, #0",
    "1:  cmp   r1, #4",
    "    blo   2f",
    "    str   r2, [r0], #4",
    "    subs  r1, r1, #4",
    "    b     1b",
    "2:  cbz   r1, 4f",
    "3:  strb  r2, [r0], #1",
    "    subs  r1, r1, #1",
    "    bne   3b",
    "4:  bx    lr",
    ".size __aeabi_memclr4, . - __aeabi_memclr4",
    ".global __aeabi_memclr8",
    ".thumb_set __aeabi_memclr8, __aeabi_memclr4",
    "",
    ".section .text.memcmp,\"ax\",%progbits",
    ".global memcmp",
    ".type memcmp,%function",
    ".thumb_func",
    // r0, r1 = the two blocks, r2 = length; the first differing bytes'
    // difference (as unsigned bytes), 0 if none.
    "memcmp:",
    "    cbz   r2, 2f",
    "1:  ldrb  r3, [r0], #1",
    "    ldrb  r12, [r1], #1",
    "    subs  r3, r3, r12",
    "    bne   3f",
    "    subs  r2, r2, #1",
    "    bne   1b",
    "2:  movs  r0, #0",
    "    bx    lr",
    "3:  mov   r0, r3",
    "    bx    lr",
    ".size memcmp, . - memcmp",
);
