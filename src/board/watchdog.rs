//! The independent watchdog (IWDG, clocked by the 32 kHz LSI, which no
//! software fault can stop). Common to the STM32G4 family.
//!
//! `main` starts it right after bring-up, before the current offsets are
//! measured and so before the bridge can first be enabled, and feeds it only
//! when the current-loop interrupt has run since the last feed. A hung ISR, a
//! hung executor or a dead ADC trigger all end in a reset: TIM1's outputs
//! reset to disabled (bridge off), the brake pin stops toggling (brake
//! closed), and after it the controller latches `WATCHDOG_RESET`, nothing is
//! started (a latched fault refuses even `startup.run_at_power_up`) and the drive waits for a
//! command and an explicit clear.

use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};

/// LSI 32 kHz / 32 = 1 kHz counter: one reload count per millisecond.
const PRESCALER: Pr = Pr::DIVIDE_BY32;
const TICKS_PER_MS: u32 = 1;

/// True if the last reset came from the IWDG. Clears the reset flags, so call
/// it once, at start-up.
pub fn take_reset_cause() -> bool {
    let by_watchdog = pac::RCC.csr().read().iwdgrstf();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    by_watchdog
}

/// Starts the watchdog with a timeout of `timeout_ms` (≤ 4095 ms). It cannot
/// be stopped again until reset; halting the core in a debugger freezes it.
pub fn start(timeout_ms: u32) {
    pac::DBGMCU.apb1lfzr().modify(|w| w.set_iwdg(true));
    let iwdg = pac::IWDG;
    iwdg.kr().write(|w| w.set_key(Key::START));
    iwdg.kr().write(|w| w.set_key(Key::ENABLE));
    iwdg.pr().write(|w| w.set_pr(PRESCALER));
    iwdg.rlr().write(|w| w.set_rl((timeout_ms * TICKS_PER_MS).min(0x0FFF) as u16));
    // Wait for the prescaler and reload to reach the LSI domain (a few LSI
    // cycles, once at start-up, never on the control path).
    while iwdg.sr().read().pvu() || iwdg.sr().read().rvu() {}
    iwdg.kr().write(|w| w.set_key(Key::RESET));
}

/// Reloads the counter.
pub fn feed() {
    pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
}
