//! The emulated target itself: what every other test binary relies on.
#![no_std]
#![no_main]

use firmware_tests::{check, test_main, Outcome};

/// cortex-m-rt's reset handler grants CP10/CP11 full access on `-eabihf`
/// targets (CPACR bits 20–23 = 0b1111) before `main`; without that the first
/// floating-point instruction of the core would be a UsageFault.
fn fpu_enabled_at_reset() -> Outcome {
    // SAFETY: CPACR (0xE000_ED88) is a always-readable SCB register.
    let cpacr = unsafe { core::ptr::read_volatile(0xE000_ED88 as *const u32) };
    check!((cpacr >> 20) & 0xF == 0xF, "CPACR = {:#010x}", cpacr);
    // And the FPU computes: a value the compiler cannot fold.
    let x = unsafe { core::ptr::read_volatile(&2.0f32) };
    let y = x * x + 0.5 * x;
    check!(y == 5.0, "2·2 + 0.5·2 = {}", y);
    Ok(())
}

/// The binary was linked with this crate's memory.x (mps2-an386), not the
/// STM32 one: code in SSRAM1 from 0x0, stack in SSRAM2/3 at 0x2000_0000.
fn linked_for_mps2_an386() -> Outcome {
    let code = fpu_enabled_at_reset as *const () as usize;
    check!(code < 0x0040_0000, "code at {:#010x}", code);
    let local = 0u32;
    let stack = &local as *const u32 as usize;
    check!(
        (0x2000_0000..0x2040_0000).contains(&stack),
        "stack at {:#010x}",
        stack
    );
    Ok(())
}

test_main!(fpu_enabled_at_reset, linked_for_mps2_an386);
