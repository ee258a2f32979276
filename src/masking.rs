//! How thread mode masks interrupts: by priority (BASEPRI), never all of
//! them (PRIMASK).
//!
//! This is the image's `critical-section` implementation, used by embassy
//! (time driver, executor queues), defmt-rtt (one per log frame) and anything
//! else that calls `critical_section::with`. It raises BASEPRI to
//! [`MASK_BASEPRI`], which masks every interrupt at NVIC priority 1 or lower
//! (numerically ≥ 1: the time driver at 4, DMA at 2) and leaves priority 0 —
//! the PWM interrupt, alone at that level — running. So no critical section,
//! however long, delays the current loop.
//!
//! That is sound only if nothing at priority 0 besides the PWM interrupt
//! shares data with a critical section, and the PWM interrupt itself takes
//! none: it owns its state outright and talks to thread mode through the
//! lock-free `board::link` (no `critical_section`, no defmt in it).
//! [`unmasked_interrupt`] checks the first half at start-up.
//!
//! Priority arithmetic on the STM32G4 (Cortex-M4, 4 priority bits): NVIC
//! priority `n` is stored as `n << 4` in the top nibble of the IPR byte;
//! BASEPRI = `b` (non-zero) masks every exception whose stored priority is
//! ≥ `b`; BASEPRI = 0 masks nothing. So BASEPRI = 1 << 4 = 0x10 masks levels
//! 1..=15 and not level 0. `BASEPRI_MAX` only ever raises the mask, so nested
//! sections (and sections entered from an interrupt at priority ≥ 1) keep the
//! stronger one; release writes back what acquire found.

use core::sync::atomic::{compiler_fence, Ordering};

use cortex_m::register::{basepri, basepri_max};

/// Priority bits the STM32G4's NVIC implements.
const NVIC_PRIO_BITS: u8 = 4;
/// The first priority level a critical section masks: 1, one below the PWM
/// interrupt's 0.
const MASKED_FROM_LEVEL: u8 = 1;
/// BASEPRI while in a critical section: masks levels 1..=15, never level 0.
pub const MASK_BASEPRI: u8 = MASKED_FROM_LEVEL << (8 - NVIC_PRIO_BITS);

struct BasepriCriticalSection;
critical_section::set_impl!(BasepriCriticalSection);

// SAFETY: on one core, raising BASEPRI to MASK_BASEPRI stops every interrupt
// that may run code guarded by a critical section (all of them sit at level
// ≥ 1, checked by `unmasked_interrupt` at start-up; the PWM interrupt at 0
// takes no critical section). Acquire returns the previous BASEPRI and
// release restores it, so nesting works.
unsafe impl critical_section::Impl for BasepriCriticalSection {
    // Out of line: ≈ 13 critical sections in the image (embassy's mutexes,
    // wakers, the time queue, defmt-rtt); inlined, each carried its own copy.
    #[inline(never)]
    unsafe fn acquire() -> critical_section::RawRestoreState {
        let previous = basepri::read();
        basepri_max::write(MASK_BASEPRI);
        // The msr is `nomem` to the compiler: keep guarded accesses after it.
        compiler_fence(Ordering::SeqCst);
        previous
    }

    #[inline(never)]
    unsafe fn release(previous: critical_section::RawRestoreState) {
        compiler_fence(Ordering::SeqCst);
        // SAFETY: restores what `acquire` found (0 outside any section).
        unsafe { basepri::write(previous) };
    }
}

/// The first enabled interrupt, other than `pwm_irq`, that a critical
/// section would not mask (its priority is above [`MASK_BASEPRI`]), if any.
/// Every such interrupt breaks the critical section's guarantee; call this
/// once everything is enabled.
pub fn unmasked_interrupt(pwm_irq: u16) -> Option<u16> {
    // SAFETY: read-only access to the NVIC's enable and priority registers.
    let nvic = unsafe { &*cortex_m::peripheral::NVIC::PTR };
    for (word, iser) in nvic.iser.iter().enumerate() {
        let enabled = iser.read();
        for bit in 0..32u16 {
            let irq = (word as u16) * 32 + bit;
            if enabled & (1 << bit) == 0 || irq == pwm_irq {
                continue;
            }
            let priority = nvic.ipr.get(usize::from(irq)).map_or(0, |p| p.read());
            if priority < MASK_BASEPRI {
                return Some(irq);
            }
        }
    }
    None
}
